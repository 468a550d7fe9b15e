//! S3's octree + LOD "equidistant decimation" marcher (`--method lod`).
//!
//! The samples are a decimation of the uniform grid `t₀ + n·step`: from
//! each sample the ray moves on by `k` grid points, `k` the spacing of the
//! octree leaf the sample lies in. S3 keeps odd spacings (1, 3, …) where
//! the contribution is high and even spacings (2, 4, …) where it is low,
//! the spacing set by the amount of cloud. Here a leaf's contribution is
//! `w = (1 − A)·c`, `A` the opacity the ray has gathered so far and `c =
//! 1 − exp(−σ(mean)·B)` the opacity of the leaf's mean density across its
//! `B` cells (its amount of cloud):
//!
//! * `w ≥ threshold` → `high` (odd, default 3);
//! * `threshold/4 ≤ w < threshold` → `low` (even, default 4);
//! * `w < threshold/4` (thin cloud, cloud hidden behind cloud, or a
//!   transparent leaf) → `sparse` (even, default 8).
//!
//! A sample looks one spacing ahead: where the leaf there is classed
//! higher, the sample takes that leaf's (shorter) spacing, so a long step
//! out of thin cloud does not stride into the front of a dense leaf. The
//! class is decided at the sample, by the opacity in front of it, so each
//! sample's stretch is its own spacing and its opacity comes from that
//! spacing's table; only the last sample of a ray (whose stretch ends at
//! the exit) takes `1 − exp(−σ·Δs)`. Transparent leaves are skipped as the
//! other marchers skip empty blocks (the leaves are the block grid's
//! blocks), the march starting again on the base grid past them. Back to
//! front there is no opacity in front (`A` = 0): a leaf is classed by its
//! amount alone.
//!
//! Until 2026-12 the classes were decided leaf by leaf at the leaf's entry
//! (the samples of a leaf on the grid decimated by its `k`, the last one's
//! stretch closed by the next leaf's first sample): the same samples'
//! count within 7 %, PSNR 0.1–0.8 dB lower on the two clouds, and in the
//! SIMD packets a walk of every leaf that cost as much as the samples
//! (docs/clouds.md).
//!
//! The defaults were chosen on the 400×400×60 cumulus and the cloud.vdb
//! sample at 512² (docs/clouds.md). Spacings 1, 2, 4 are gentler.
//!
//! Every sample's opacity is corrected for the stretch of ray it stands for
//! (`α' = 1 − (1 − α)^(Δs/Δs₀)`, DESIGN.md), so a decimated leaf is a
//! coarser estimate of the same picture, not a different picture. With every
//! spacing 1 the samples and their opacities are those of `uniform`.

use super::march::Pick;
use super::octree::Octree;
use super::ray::Segment;
use crate::error::Result;
use crate::transfer::{Lut, LUT_SIZE};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Parameters of `lod` (`[render.lod]` in a scene file). Spacings are in
/// base steps (`--step`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct LodParams {
    /// Spacing in high-contribution leaves (S3: odd).
    pub high: u32,
    /// Spacing in low-contribution leaves (S3: even).
    pub low: u32,
    /// Spacing where the contribution is below a quarter of the threshold,
    /// and in empty leaves when skipping is off (S3: even).
    pub sparse: u32,
    /// Contribution `(1 − A)·c` at or above which a leaf counts as high.
    pub threshold: f32,
}

impl Default for LodParams {
    fn default() -> Self {
        LodParams {
            high: 3,
            low: 4,
            sparse: 8,
            threshold: 0.3,
        }
    }
}

impl LodParams {
    /// Checks the numbers a user may get wrong.
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        for (name, k) in [
            ("high", self.high),
            ("low", self.low),
            ("sparse", self.sparse),
        ] {
            if !(1..=16).contains(&k) {
                return Err(crate::FieldError::new(
                    format!("lod.{name}"),
                    format!("{k}: a spacing must be 1…16 base steps"),
                ));
            }
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0 && self.threshold <= 1.0) {
            return Err(crate::FieldError::new(
                "lod.threshold",
                format!("{}: must be in (0, 1]", self.threshold),
            ));
        }
        Ok(())
    }
}

/// What a render of `lod` derives from the octree and the transfer
/// function: per leaf its amount of cloud, and per spacing class the step
/// (world units) and the step opacities. Kept with the transfer function's
/// other tables (`TfTables::lod`) for the renders after it.
pub(super) struct LodRay {
    /// The leaves: their count on each axis, and 1 / their edge in cells.
    pub counts: [usize; 3],
    pub inv_leaf: f32,
    /// Per leaf, its amount of cloud; −1 where the transfer function hides
    /// the whole leaf (classed `sparse` as an amount of 0 would be).
    pub amount: Vec<f32>,
    pub threshold: f32,
    /// Per class, its step in unit lengths (`k · step`) and in world units.
    pub ratios: [f32; 3],
    pub steps: [f32; 3],
    pub alphas: [Box<[f32; LUT_SIZE]>; 3],
}

impl LodRay {
    /// The leaves are the block grid's blocks (`empty` per block whether
    /// the transfer function hides it); `step` the base step in voxels and
    /// `unit` the world length of a voxel.
    pub fn new(
        tree: &Octree,
        lut: &Lut,
        empty: &[bool],
        params: &LodParams,
        step: f32,
        unit: f32,
    ) -> LodRay {
        let b = tree.leaf as f32;
        let amount = tree.levels[0]
            .nodes
            .iter()
            .zip(empty)
            .map(|(n, &e)| match Lut::index(n.mean) {
                _ if e => -1.0,
                Some(i) => 1.0 - (-lut.sigma(i) * b).exp(),
                None => 0.0,
            })
            .collect();
        let ratios = [params.high, params.low, params.sparse].map(|k| k as f32 * step);
        LodRay {
            counts: tree.levels[0].counts,
            inv_leaf: 1.0 / b,
            amount,
            threshold: params.threshold,
            ratios,
            steps: ratios.map(|r| r * unit),
            alphas: ratios.map(|r| lut.alphas(r)),
        }
    }

    /// The spacing class of a leaf of amount `am` seen through opacity `a`.
    #[inline(always)]
    fn class(&self, am: f32, a: f32) -> usize {
        let w = (1.0 - a) * am;
        if w >= self.threshold {
            0
        } else if w >= 0.25 * self.threshold {
            1
        } else {
            2
        }
    }

    /// The leaf at grid position `p` (clamped into the grid).
    #[inline(always)]
    fn leaf(&self, p: Vec3) -> usize {
        let c = self.counts;
        let at = |a: usize| ((p[a] * self.inv_leaf) as usize).min(c[a] - 1);
        at(0) + c[0] * (at(1) + c[1] * at(2))
    }

    /// The spacing class of the sample at `t` (at grid position `p`) seen
    /// through opacity `a`: its leaf's, or that of the leaf one of its
    /// spacings ahead where that one is classed higher.
    #[inline(always)]
    pub fn class_at(&self, p: Vec3, t: f32, seg: &Segment, a: f32) -> usize {
        let c = self.class(self.amount[self.leaf(p)], a);
        if c == 0 {
            return 0;
        }
        let ahead = seg.o + seg.d * (t + self.steps[c]);
        c.min(self.class(self.amount[self.leaf(ahead)], a))
    }
}

/// `lod` picks a sample's class before sampling, from where it lies and
/// the opacity in front ([`LodRay::class_at`]), and so marches as every
/// `Pick` does (`march::Threshold`'s walk, the step from each sample its
/// class's spacing; see the module's doc).
impl Pick for LodRay {
    #[inline(always)]
    fn steps(&self) -> &[f32; 3] {
        &self.steps
    }
    #[inline(always)]
    fn alphas(&self, class: usize) -> &[f32; LUT_SIZE] {
        &self.alphas[class]
    }
    #[inline(always)]
    fn before(&self, p: Vec3, t: f32, seg: &Segment, a: f32) -> usize {
        self.class_at(p, t, seg, a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row of four leaves of 8 cells, the third dense, the others
    /// without cloud; spacings 1.5, 2 and 4 (world units, one per cell).
    fn row() -> LodRay {
        LodRay {
            counts: [4, 1, 1],
            inv_leaf: 1.0 / 8.0,
            amount: vec![0.0, 0.0, 0.9, 0.0],
            threshold: 0.3,
            ratios: [3.0, 4.0, 8.0],
            steps: [1.5, 2.0, 4.0],
            alphas: [0; 3].map(|_| Box::new([0.0; LUT_SIZE])),
        }
    }

    fn along_x() -> Segment {
        Segment {
            o: Vec3::new(0.0, 4.0, 4.0),
            d: Vec3::X,
            view: -Vec3::X,
            t_in: 0.0,
            t_out: 32.0,
            t0: 0.0,
            walk: (0.0, 32.0),
            pixel: (0, 0),
            pass: 0,
        }
    }

    #[test]
    fn a_sample_takes_the_spacing_of_a_denser_leaf_one_spacing_ahead() {
        let (lod, seg) = (row(), along_x());
        let at = |x: f32, a: f32| lod.class_at(seg.o + seg.d * x, x, &seg, a);
        // Thin cloud ahead too: sparse.
        assert_eq!(at(10.0, 0.0), 2);
        // The dense leaf (from x = 16) lies one sparse spacing ahead: high.
        assert_eq!(at(13.0, 0.0), 0);
        // Inside it: high; seen through 90 % opacity its contribution
        // 0.09 is low (between 0.075 and 0.3), ahead of it too.
        assert_eq!(at(17.0, 0.0), 0);
        assert_eq!(at(17.0, 0.9), 1);
        assert_eq!(at(13.0, 0.9), 1);
        // Past it, nothing ahead: sparse again; and a position off the
        // grid is clamped into its edge leaves.
        assert_eq!(at(25.0, 0.0), 2);
        assert_eq!(lod.leaf(Vec3::new(-3.0, 4.0, 4.0)), 0);
        assert_eq!(lod.leaf(Vec3::new(40.0, 4.0, 4.0)), 3);
    }
}
