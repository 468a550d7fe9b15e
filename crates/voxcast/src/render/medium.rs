//! The participating medium of the physically based methods, as pbrt and
//! Mitsuba define a heterogeneous medium: a density grid (the volume's
//! values mapped through the window to 0…1) placed in a world-space box,
//! times an extinction scale `σ_t = scale · density` (per world unit), a
//! single-scattering albedo `σ_s/σ_t` and a phase function.
//!
//! ```toml
//! [render.medium]
//! scale = 20.0                       # extinction per world unit at density 1
//! albedo = [0.95, 0.95, 0.95]
//! phase = { type = "hg", g = 0.8 }
//! majorant = "grid"                  # or "global"
//! max_depth = 256
//! # box = [[-1, -1, -1], [1, 1, 1]]  # default: the volume's own extent
//! ```

use super::phase::PhaseFunction;
use serde::{Deserialize, Serialize};

/// How free-flight sampling bounds the extinction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum MajorantKind {
    /// Per-block maximum extinction, walked by a DDA (pbrt-v4's majorant
    /// grid): tentative collisions are dense only where the medium is.
    #[default]
    Grid,
    /// One maximum for the whole volume.
    Global,
}

/// The medium: see the module docs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct MediumParams {
    /// Extinction coefficient at density 1, per world unit.
    pub scale: f32,
    /// Single-scattering albedo per channel (0…1).
    pub albedo: [f32; 3],
    pub phase: PhaseFunction,
    pub majorant: MajorantKind,
    /// Longest path (scattering events) of `path`.
    pub max_depth: u32,
    /// The world box the density grid fills (default: the volume's extent).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub r#box: Option<[[f32; 3]; 2]>,
}

impl Default for MediumParams {
    fn default() -> Self {
        MediumParams {
            scale: 10.0,
            albedo: [0.95, 0.95, 0.95],
            phase: PhaseFunction::Hg { g: 0.8 },
            majorant: MajorantKind::Grid,
            max_depth: 256,
            r#box: None,
        }
    }
}

/// The largest optical depth (extinction × the diagonal of the medium's
/// box) a render accepts. Far past anything that lets light through — a
/// thick cumulus is a few hundred — while delta tracking's cost per
/// segment grows with it: beyond it, `scale` is a mistake, not a medium.
pub const MAX_OPTICAL_DEPTH: f32 = 1e6;

impl MediumParams {
    /// The medium's box in world units: its own, or the volume's extent.
    pub fn world_box(&self, volume: &crate::volume::Volume) -> (glam::Vec3, glam::Vec3) {
        match self.r#box {
            Some([lo, hi]) => (lo.into(), hi.into()),
            None => volume.world_bounds(),
        }
    }

    /// Refuses an extinction whose optical depth across the medium's box
    /// exceeds [`MAX_OPTICAL_DEPTH`], naming the largest scale that fits.
    pub fn check_optical_depth(
        &self,
        volume: &crate::volume::Volume,
    ) -> Result<(), crate::FieldError> {
        let (lo, hi) = self.world_box(volume);
        let diagonal = (hi - lo).length().max(f32::MIN_POSITIVE);
        let depth = self.scale as f64 * diagonal as f64;
        if depth > MAX_OPTICAL_DEPTH as f64 {
            return Err(crate::FieldError::new("medium.scale", format!(
                "{:e}: the optical depth across the volume (scale × its diagonal {diagonal:.4}) is {depth:.3e}, above {MAX_OPTICAL_DEPTH:.0e}: no light would get through and each path would take millions of steps; use a scale below {:.4e}",
                self.scale,
                MAX_OPTICAL_DEPTH as f64 / diagonal as f64
            )));
        }
        Ok(())
    }

    /// Checks the numbers a user may get wrong; the error's field is
    /// `medium.…`.
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        let bad = |field: &str, m: String| Err(crate::FieldError::new(field, m));
        if !(self.scale.is_finite() && self.scale >= 0.0) {
            return bad("medium.scale", format!("{}: must be ≥ 0", self.scale));
        }
        if self.albedo.iter().any(|a| !(0.0..=1.0).contains(a)) {
            return bad(
                "medium.albedo",
                format!("{:?}: each channel must be in 0…1", self.albedo),
            );
        }
        if !(1..=100_000).contains(&self.max_depth) {
            return bad(
                "medium.max_depth",
                format!("{}: must be 1…100000", self.max_depth),
            );
        }
        if let Some([lo, hi]) = self.r#box {
            if (0..3).any(|a| !(lo[a].is_finite() && hi[a].is_finite() && lo[a] < hi[a])) {
                return bad(
                    "medium.box",
                    format!(
                        "{:?}: expected [[xmin, ymin, zmin], [xmax, ymax, zmax]] with min < max",
                        [lo, hi]
                    ),
                );
            }
        }
        self.phase.validate().map_err(|e| e.within("medium"))
    }
}
