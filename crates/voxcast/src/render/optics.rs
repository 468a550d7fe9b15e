//! What a sample contributes: the optical models of Max (1995), as listed in
//! S4. Each model turns a sample's colour and step opacity into the light it
//! emits towards the eye and the fraction of light it absorbs; compositing
//! is the same *over* operator for all of them.

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// The optical model (scene and CLI name in kebab case).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum OpticalModel {
    /// Cold black particles that only absorb: the picture is the background
    /// seen through the volume.
    AbsorptionOnly,
    /// Glowing transparent gas: light adds up, nothing is hidden.
    EmissionOnly,
    /// Particles that both emit (their TF colour) and absorb (the default).
    #[default]
    EmissionAbsorption,
}

impl OpticalModel {
    pub const ALL: [OpticalModel; 3] = [
        OpticalModel::AbsorptionOnly,
        OpticalModel::EmissionOnly,
        OpticalModel::EmissionAbsorption,
    ];
    pub fn name(self) -> &'static str {
        match self {
            OpticalModel::AbsorptionOnly => "absorption-only",
            OpticalModel::EmissionOnly => "emission-only",
            OpticalModel::EmissionAbsorption => "emission-absorption",
        }
    }
}

/// A sample's contribution: premultiplied emitted colour and absorbed
/// fraction, for one step of the ray.
pub trait Optics: Copy + Send + Sync {
    fn contribution(rgb: Vec3, alpha: f32) -> (Vec3, f32);
}

#[derive(Clone, Copy)]
pub struct AbsorptionOnly;
impl Optics for AbsorptionOnly {
    #[inline(always)]
    fn contribution(_rgb: Vec3, alpha: f32) -> (Vec3, f32) {
        (Vec3::ZERO, alpha)
    }
}

#[derive(Clone, Copy)]
pub struct EmissionOnly;
impl Optics for EmissionOnly {
    #[inline(always)]
    fn contribution(rgb: Vec3, alpha: f32) -> (Vec3, f32) {
        (rgb * alpha, 0.0)
    }
}

#[derive(Clone, Copy)]
pub struct EmissionAbsorption;
impl Optics for EmissionAbsorption {
    #[inline(always)]
    fn contribution(rgb: Vec3, alpha: f32) -> (Vec3, f32) {
        (rgb * alpha, alpha)
    }
}

/// Front-to-back accumulation (S4): `C += (1 − A)·e; A += (1 − A)·a`.
#[inline(always)]
pub fn over_front(acc_c: &mut Vec3, acc_a: &mut f32, e: Vec3, a: f32) {
    let t = 1.0 - *acc_a;
    *acc_c += e * t;
    *acc_a += a * t;
}

/// Back-to-front accumulation (S4): `C = e + (1 − a)·C; A = a + (1 − a)·A`.
#[inline(always)]
pub fn over_back(acc_c: &mut Vec3, acc_a: &mut f32, e: Vec3, a: f32) {
    *acc_c = e + *acc_c * (1.0 - a);
    *acc_a = a + *acc_a * (1.0 - a);
}
