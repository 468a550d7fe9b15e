//! The ray loop's contract (DESIGN.md, "The ray loop: three independent
//! choices"): what every ray of a render shares ([`Frame`]), one ray in
//! voxel space ([`Segment`]), and the three choices as traits —
//!
//! * [`Marcher`]: *where samples go* (`march/steps.rs`, `march/threshold.rs`,
//!   `stochastic.rs`, `lod.rs`);
//! * [`Sampler`]: *how a value is reconstructed* and classified (trilinear,
//!   or S0's grouped reuse; with or without shading — `sample.rs`);
//! * [`Composite`]: *what a sample contributes* (front to back with early
//!   termination, or back to front; the optical model — `composite.rs`).
//!
//! `trace.rs` runs one ray generic over the three; the renderer picks the
//! types once per render with a `match`, so the per-sample loop is one
//! monomorphised loop with no flag, `Option` or `match` on the method in it.
//! Nothing here allocates, dispatches dynamically or takes a lock.

use crate::transfer::{Lut, LUT_SIZE};
use crate::volume::{Grid, Voxel};
use glam::{Vec3, Vec4};

/// What every ray of a render (and pass) shares, whatever the method.
pub(super) struct Frame<'a, T> {
    pub grid: &'a Grid<'a, T>,
    pub lut: &'a Lut,
    /// Box through the voxel centres, in voxel coordinates.
    pub box_lo: Vec3,
    pub box_hi: Vec3,
    pub origin_w: Vec3,
    pub inv_spacing: Vec3,
    /// Base step in world units.
    pub step: f32,
    /// Unit length (the smallest spacing) in world units.
    pub unit: f32,
    /// Empty-space skipping on.
    pub skip_empty: bool,
    /// Block grid: edge in cells, counts, and emptiness under the TF.
    pub block_size: usize,
    pub block_counts: [usize; 3],
    pub empty: &'a [bool],
    /// With empty-space skipping: the box (voxel coordinates) around the
    /// blocks that are not empty, outside which a ray has nothing to march;
    /// `None` without skipping.
    pub occupied: Option<(Vec3, Vec3)>,
    /// Seed of the random methods (jitter, stochastic marchers).
    pub seed: u64,
}

// Manual impls: a derive would demand `T: Copy`, but only references to T
// are held.
impl<T> Clone for Frame<'_, T> {
    fn clone(&self) -> Self {
        *self
    }
}
impl<T> Copy for Frame<'_, T> {}

impl<T> Frame<'_, T> {
    /// Whether voxel-space point `p` lies in a block that is empty under
    /// the transfer function.
    #[inline(always)]
    pub fn in_empty_block(&self, p: Vec3) -> bool {
        let b = self.block_size as f32;
        let c = self.block_counts;
        let ix = ((p.x / b) as usize).min(c[0] - 1);
        let iy = ((p.y / b) as usize).min(c[1] - 1);
        let iz = ((p.z / b) as usize).min(c[2] - 1);
        self.empty[ix + c[0] * (iy + c[1] * iz)]
    }
}

/// One ray, clipped to the volume: `o + d·t` in voxel coordinates with `t`
/// in world units.
#[derive(Clone, Copy, Debug)]
pub(super) struct Segment {
    pub o: Vec3,
    pub d: Vec3,
    /// Towards the eye (world units), for shading.
    pub view: Vec3,
    /// Entry and exit (the exit clamped to an opaque surface).
    pub t_in: f32,
    pub t_out: f32,
    /// Start of the sample grid `t₀ + n·step`: `t_in`, plus the jitter
    /// offset where the method jitters.
    pub t0: f32,
    /// The stretch that meets blocks that are not empty (the whole ray
    /// without skipping): a block walk starts and ends there.
    pub walk: (f32, f32),
    pub pixel: (u32, u32),
    /// Pass of a progressive (multi-`spp`) render.
    pub pass: u32,
}

impl Segment {
    /// Where the stretch of the ray's last sample ends: the exit, moved on
    /// by the jitter offset `t₀ − t_in`. Each sample stands for the step
    /// after it, so a jittered grid leaves `[t_in, t₀)` uncovered at the
    /// front; the last sample covers as much past the exit, which makes the
    /// stretches add up to exactly the ray's length (an absorbing slab of
    /// length L gets `e^(−σL)` at any offset) and puts every sample inside
    /// the step-long interval `[t_in + n·s, t_in + (n+1)·s)` it stands for —
    /// jittered, stratified sampling.
    #[inline(always)]
    pub fn t_end(&self) -> f32 {
        self.t_out + (self.t0 - self.t_in)
    }
}

/// Per-ray counters, kept in registers and added to the tile's stats once.
#[derive(Default)]
pub(super) struct Counters {
    pub samples: u64,
    pub interpolations: u64,
    pub shaded: u64,
}

/// A reconstructed sample: its normalised value, and its table entry and
/// (shaded) colour — `None` below the table (empty, NaN), and for samples
/// the transfer function makes transparent where the shading culls them.
#[derive(Clone, Copy, Debug)]
pub(super) struct Sample {
    pub value: f32,
    pub hit: Option<(usize, Vec3)>,
}

/// Where samples go along the ray (DESIGN.md axis 1). A marcher owns its
/// method's per-render state (step tables, pdf, octree) and its loop over
/// the ray, generic over the other two choices.
pub(super) trait Marcher<T: Voxel>: Sync {
    /// Marches `seg`; true when the ray was terminated early.
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        s: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool;
}

/// How a value is reconstructed and classified at a sample (DESIGN.md
/// axis 2). A fresh copy per ray.
pub(super) trait Sampler<T: Voxel>: Copy + Sync {
    /// Whether a march's runs keep S0's groups: groups start afresh at
    /// each run, so blocks of one step merge into a run only where they
    /// share their group cap — never an empty block with one that shows,
    /// so that skipping an empty block changes no pixel. Otherwise all
    /// blocks of one step merge.
    const GROUPS: bool;
    /// Prepares for a ray leaving the volume at `t_out`.
    fn begin(&mut self, t_out: f32);
    /// The next sample starts a new group (after a skip).
    fn restart(&mut self);
    /// Caps the group of the samples that follow (until the next
    /// `restart`) at `cap` samples; only grouped reuse has groups.
    #[inline(always)]
    fn limit(&mut self, _cap: u32) {}
    /// The sample at voxel position `p`, the `k`-th of its march (`t` in
    /// world units).
    fn at(
        &mut self,
        f: &Frame<'_, T>,
        p: Vec3,
        t: f32,
        k: u32,
        view: Vec3,
        n: &mut Counters,
    ) -> Sample;
    /// [`Sampler::at`] through a premultiplied table `q` (one per step
    /// length; [`Lut::premultiplied`]), for the marchers whose steps come
    /// from a few fixed lengths: `(emitted colour, opacity, entry)`.
    /// `(t, k, view)` as for `at`. A grouped sampler reuses within one
    /// table only (the marcher restarts it when the table changes).
    fn at_premul(
        &mut self,
        f: &Frame<'_, T>,
        q: &[[f32; 4]; LUT_SIZE],
        p: Vec3,
        tkv: (f32, u32, Vec3),
        n: &mut Counters,
    ) -> Option<(Vec3, f32, usize)>;
}

/// What a sample contributes and how it is accumulated (DESIGN.md axis 3).
pub(super) trait Composite {
    /// Adds a sample of colour `rgb` and step opacity `alpha`; true when
    /// the ray may stop (early ray termination).
    #[inline(always)]
    fn add(&mut self, rgb: Vec3, alpha: f32) -> bool {
        self.add_premul(rgb * alpha, alpha)
    }
    /// [`Composite::add`] with the colour already multiplied by `alpha`.
    fn add_premul(&mut self, e: Vec3, alpha: f32) -> bool;
    /// The opacity gathered so far (0 where it is known only at the end).
    fn opacity(&self) -> f32;
    /// The composite, over the opaque surface colour `behind` if the ray
    /// ended on one: premultiplied linear colour and opacity.
    fn finish(self, behind: Option<Vec3>) -> Vec4;
}
