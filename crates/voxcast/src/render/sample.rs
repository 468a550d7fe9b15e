//! How a value is reconstructed at a sample (DESIGN.md axis 2), classified
//! by the transfer function and shaded: [`Trilinear`] every time, or S0's
//! [`Grouped`] reuse; each with [`Flat`] colour or [`Phong`] shading. The
//! choices are types, so the per-sample path has no branch on them.

use super::march::group_size;
use super::ray::{Counters, Frame, Sample, Sampler};
use super::shading::BlinnPhong;
use crate::transfer::{Lut, LUT_SIZE};
use crate::volume::Voxel;
use glam::Vec3;

/// The colour a classified sample shows.
pub(super) trait Shade: Copy + Sync {
    /// Whether transparent samples are culled before shading (worth a
    /// branch only where shading costs more than compositing a zero).
    const CULL: bool;
    fn rgb<T: Voxel>(
        &self,
        f: &Frame<'_, T>,
        entry: usize,
        p: Vec3,
        view: Vec3,
        n: &mut Counters,
    ) -> Vec3;
    /// Emitted (premultiplied) colour and opacity of entry `i` from a
    /// premultiplied table `q` ([`Lut::premultiplied`]).
    #[inline(always)]
    fn emit<T: Voxel>(
        &self,
        f: &Frame<'_, T>,
        q: &[[f32; 4]; LUT_SIZE],
        i: usize,
        p: Vec3,
        view: Vec3,
        n: &mut Counters,
    ) -> (Vec3, f32) {
        let a = q[i][3];
        (self.rgb(f, i, p, view, n) * a, a)
    }
}

/// The transfer function's colour, unshaded.
#[derive(Clone, Copy)]
pub(super) struct Flat;

impl Shade for Flat {
    const CULL: bool = false;
    #[inline(always)]
    fn rgb<T: Voxel>(
        &self,
        f: &Frame<'_, T>,
        i: usize,
        _: Vec3,
        _: Vec3,
        _: &mut Counters,
    ) -> Vec3 {
        let e = f.lut.entry(i);
        Vec3::new(e[0], e[1], e[2])
    }
    #[inline(always)]
    fn emit<T: Voxel>(
        &self,
        _: &Frame<'_, T>,
        q: &[[f32; 4]; LUT_SIZE],
        i: usize,
        _: Vec3,
        _: Vec3,
        _: &mut Counters,
    ) -> (Vec3, f32) {
        let e = q[i];
        (Vec3::new(e[0], e[1], e[2]), e[3])
    }
}

/// Gradient Blinn–Phong shading with a headlight.
#[derive(Clone, Copy)]
pub(super) struct Phong(pub BlinnPhong);

impl Shade for Phong {
    const CULL: bool = true;
    #[inline(always)]
    fn rgb<T: Voxel>(
        &self,
        f: &Frame<'_, T>,
        i: usize,
        p: Vec3,
        view: Vec3,
        n: &mut Counters,
    ) -> Vec3 {
        let e = f.lut.entry(i);
        let g = f.grid.gradient(p);
        n.shaded += 1;
        self.0
            .shade(Vec3::new(e[0], e[1], e[2]), g, f.inv_spacing, view)
    }
}

/// Reconstructs, classifies and shades the sample at voxel position `p`.
#[inline(always)]
pub(super) fn evaluate<T: Voxel, Sh: Shade>(
    f: &Frame<'_, T>,
    sh: &Sh,
    p: Vec3,
    view: Vec3,
    n: &mut Counters,
) -> Sample {
    let value = f.grid.sample(p);
    n.interpolations += 1;
    // A transparent sample composites as nothing, so unshaded it is not
    // culled: on dense data the branch mispredicts more than it saves. The
    // entry's base-step opacity sits in the cache line of its colour.
    let hit = match Lut::index(value) {
        Some(i) if !Sh::CULL || f.lut.entry(i)[3] > 0.0 => Some((i, sh.rgb(f, i, p, view, n))),
        _ => None,
    };
    Sample { value, hit }
}

/// [`evaluate`] from a premultiplied table: `(emitted colour, opacity,
/// entry)`, or `None` below the table (or transparent, where culled).
#[inline(always)]
pub(super) fn evaluate_premul<T: Voxel, Sh: Shade>(
    f: &Frame<'_, T>,
    sh: &Sh,
    q: &[[f32; 4]; LUT_SIZE],
    p: Vec3,
    view: Vec3,
    n: &mut Counters,
) -> Option<(Vec3, f32, usize)> {
    let value = f.grid.sample(p);
    n.interpolations += 1;
    let i = Lut::index(value)?;
    if Sh::CULL && q[i][3] <= 0.0 {
        return None;
    }
    let (e, a) = sh.emit(f, q, i, p, view, n);
    Some((e, a, i))
}

/// Trilinear reconstruction at every sample.
#[derive(Clone, Copy)]
pub(super) struct Trilinear<Sh>(pub Sh);

impl<T: Voxel, Sh: Shade> Sampler<T> for Trilinear<Sh> {
    const GROUPS: bool = false;
    #[inline(always)]
    fn begin(&mut self, _: f32) {}
    #[inline(always)]
    fn restart(&mut self) {}
    #[inline(always)]
    fn at(
        &mut self,
        f: &Frame<'_, T>,
        p: Vec3,
        _: f32,
        _: u32,
        view: Vec3,
        n: &mut Counters,
    ) -> Sample {
        evaluate(f, &self.0, p, view, n)
    }
    #[inline(always)]
    fn at_premul(
        &mut self,
        f: &Frame<'_, T>,
        q: &[[f32; 4]; LUT_SIZE],
        p: Vec3,
        (_, _, view): (f32, u32, Vec3),
        n: &mut Counters,
    ) -> Option<(Vec3, f32, usize)> {
        evaluate_premul(f, &self.0, q, p, view, n)
    }
}

/// S0 grouped interpolation: samples in the nearest third of the ray are
/// reconstructed, farther ones reuse the sample of their group's head
/// (groups of 2 in the middle third, 3 in the farthest: the `k`-th sample
/// of a march is a head when `k` is a multiple of its group size, and the
/// first sample of a block, or after a skip, always is — so skipping an
/// empty block changes no pixel).
#[derive(Clone, Copy)]
pub(super) struct Grouped<Sh> {
    shade: Sh,
    t_out: f32,
    fresh: bool,
    /// The marcher's cap on the group ([`Sampler::limit`]).
    cap: u32,
    last: Sample,
    last_premul: Option<(Vec3, f32, usize)>,
}

impl<Sh> Grouped<Sh> {
    pub fn new(shade: Sh) -> Self {
        Grouped {
            shade,
            t_out: 0.0,
            fresh: true,
            cap: u32::MAX,
            last: Sample {
                value: 0.0,
                hit: None,
            },
            last_premul: None,
        }
    }
}

impl<T: Voxel, Sh: Shade> Sampler<T> for Grouped<Sh> {
    const GROUPS: bool = true;
    #[inline(always)]
    fn begin(&mut self, t_out: f32) {
        self.t_out = t_out;
        self.fresh = true;
        self.cap = u32::MAX;
    }
    #[inline(always)]
    fn restart(&mut self) {
        self.fresh = true;
    }
    #[inline(always)]
    fn limit(&mut self, cap: u32) {
        self.cap = cap;
    }
    #[inline(always)]
    fn at(
        &mut self,
        f: &Frame<'_, T>,
        p: Vec3,
        t: f32,
        k: u32,
        view: Vec3,
        n: &mut Counters,
    ) -> Sample {
        if self.fresh || k.is_multiple_of(group_size(t, self.t_out).min(self.cap)) {
            self.fresh = false;
            self.last = evaluate(f, &self.shade, p, view, n);
        }
        self.last
    }
    #[inline(always)]
    fn at_premul(
        &mut self,
        f: &Frame<'_, T>,
        q: &[[f32; 4]; LUT_SIZE],
        p: Vec3,
        (t, k, view): (f32, u32, Vec3),
        n: &mut Counters,
    ) -> Option<(Vec3, f32, usize)> {
        if self.fresh || k.is_multiple_of(group_size(t, self.t_out).min(self.cap)) {
            self.fresh = false;
            self.last_premul = evaluate_premul(f, &self.shade, q, p, view, n);
        }
        self.last_premul
    }
}
