//! Lights for the physically based methods (`single-scatter`, `path`), in
//! the units pbrt and Mitsuba use: a directional light by its irradiance
//! (W/m² on a surface facing it), a point light by its radiant intensity
//! (W/sr, falling off as 1/r²), a constant environment by its radiance
//! (W/(m²·sr)), and a simple sky: radiance blended from the horizon to the
//! zenith by the direction's height, and a constant ground below.
//!
//! Scene TOML (`[[render.lights]]`, one table per light; world coordinates,
//! +z up):
//!
//! ```toml
//! [[render.lights]]
//! type = "directional"
//! direction = [0.3, -0.5, 0.8]   # towards the light (need not be unit)
//! irradiance = [3.0, 2.9, 2.7]
//!
//! [[render.lights]]
//! type = "point"
//! position = [0.0, 0.0, 2.0]
//! intensity = [5.0, 5.0, 5.0]
//!
//! [[render.lights]]
//! type = "environment"
//! radiance = [1.0, 1.0, 1.0]
//!
//! [[render.lights]]
//! type = "sky"
//! zenith = [0.25, 0.45, 0.9]
//! horizon = [0.8, 0.85, 0.9]
//! ground = [0.3, 0.28, 0.25]
//! ```

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// One light of a scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum Light {
    /// A light at infinity (the sun): direction towards it, irradiance.
    Directional {
        direction: [f32; 3],
        irradiance: [f32; 3],
    },
    /// An isotropic point light: position (world), intensity.
    Point {
        position: [f32; 3],
        intensity: [f32; 3],
    },
    /// The same radiance from every direction.
    Environment { radiance: [f32; 3] },
    /// Radiance `horizon + (zenith − horizon)·ω_z` above the horizon,
    /// `ground` below it.
    Sky {
        zenith: [f32; 3],
        horizon: [f32; 3],
        ground: [f32; 3],
    },
}

/// What a delta light sends to a point: unit direction towards the light,
/// distance to it (∞ for directional), and the radiance-like factor that the
/// phase function multiplies (irradiance, or intensity / r²).
#[derive(Clone, Copy, Debug)]
pub struct Incident {
    pub dir: Vec3,
    pub dist: f32,
    pub li: Vec3,
}

impl Light {
    /// The lights used when a physically based render names none: a warm
    /// sun high in the sky and a blue sky, so a cloud looks like one.
    pub fn default_sun_and_sky() -> Vec<Light> {
        vec![
            Light::Directional {
                direction: [-0.4, -0.5, 0.75],
                irradiance: [3.0, 2.85, 2.6],
            },
            Light::Sky {
                zenith: [0.18, 0.32, 0.65],
                horizon: [0.55, 0.65, 0.8],
                ground: [0.2, 0.19, 0.17],
            },
        ]
    }

    /// True for lights sampled by next-event estimation (directional, point).
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Directional { .. } | Light::Point { .. })
    }

    /// For a delta light: what reaches `p`. `None` for infinite area lights.
    #[inline]
    pub fn incident(&self, p: Vec3) -> Option<Incident> {
        match *self {
            Light::Directional {
                direction,
                irradiance,
            } => Some(Incident {
                dir: Vec3::from(direction).normalize(),
                dist: f32::INFINITY,
                li: Vec3::from(irradiance),
            }),
            Light::Point {
                position,
                intensity,
            } => {
                let v = Vec3::from(position) - p;
                let r2 = v.length_squared().max(1e-12);
                let dist = r2.sqrt();
                Some(Incident {
                    dir: v / dist,
                    dist,
                    li: Vec3::from(intensity) / r2,
                })
            }
            _ => None,
        }
    }

    /// Radiance an infinite light sends from direction `dir` (the direction
    /// one looks in); zero for delta lights.
    #[inline]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match *self {
            Light::Environment { radiance } => Vec3::from(radiance),
            Light::Sky {
                zenith,
                horizon,
                ground,
            } => {
                if dir.z >= 0.0 {
                    Vec3::from(horizon).lerp(Vec3::from(zenith), dir.z)
                } else {
                    Vec3::from(ground)
                }
            }
            _ => Vec3::ZERO,
        }
    }

    /// Checks the numbers (finite, non-negative; a direction not zero).
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        let ok = |v: &[f32; 3]| v.iter().all(|x| x.is_finite() && *x >= 0.0);
        let bad = match self {
            Light::Directional {
                direction,
                irradiance,
            } => {
                !ok(irradiance)
                    || !direction.iter().all(|x| x.is_finite())
                    || Vec3::from(*direction).length() < 1e-6
            }
            Light::Point {
                position,
                intensity,
            } => !ok(intensity) || !position.iter().all(|x| x.is_finite()),
            Light::Environment { radiance } => !ok(radiance),
            Light::Sky {
                zenith,
                horizon,
                ground,
            } => !ok(zenith) || !ok(horizon) || !ok(ground),
        };
        if bad {
            Err(crate::FieldError::new(
                "lights",
                format!("{self:?}: colours must be finite and ≥ 0, a direction non-zero"),
            ))
        } else {
            Ok(())
        }
    }
}

/// Radiance of all infinite lights from direction `dir`.
#[inline]
pub fn environment(lights: &[Light], dir: Vec3) -> Vec3 {
    lights.iter().map(|l| l.radiance(dir)).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn point_light_falls_off_as_inverse_square() {
        let l = Light::Point {
            position: [0.0, 0.0, 2.0],
            intensity: [4.0, 4.0, 4.0],
        };
        let i = l.incident(Vec3::ZERO).unwrap();
        assert!((i.li.x - 1.0).abs() < 1e-6 && (i.dist - 2.0).abs() < 1e-6);
        assert!((i.dir - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn sky_blends_and_parses() {
        let t = "type = \"sky\"\nzenith = [0.0, 0.0, 1.0]\nhorizon = [1.0, 0.0, 0.0]\nground = [0.0, 1.0, 0.0]";
        let l: Light = toml::from_str(t).unwrap();
        assert!((l.radiance(Vec3::Z) - Vec3::Z).length() < 1e-6);
        assert!((l.radiance(Vec3::X) - Vec3::X).length() < 1e-6);
        assert!((l.radiance(-Vec3::Z) - Vec3::Y).length() < 1e-6);
        assert!(!l.is_delta());
        assert!(Light::Environment {
            radiance: [-1.0, 0.0, 0.0]
        }
        .validate()
        .is_err());
    }
}
