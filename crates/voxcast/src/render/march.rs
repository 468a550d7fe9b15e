//! Where samples go along a ray (the marcher; DESIGN.md axis 1).
//!
//! A marcher yields sample positions as `(t, Δs)`: the ray parameter of the
//! sample (world units from the ray origin) and the length of ray it stands
//! for. The compositor corrects opacity by `Δs`, so marchers with varying
//! steps change the cost, not the picture.

use glam::Vec3;

/// Entry and exit parameters of a ray with an axis-aligned box, or `None`
/// when it misses. `inv_dir` is `1 / dir` per component (±∞ for 0).
#[inline]
pub fn intersect_box(origin: Vec3, inv_dir: Vec3, lo: Vec3, hi: Vec3) -> Option<(f32, f32)> {
    let t0 = (lo - origin) * inv_dir;
    let t1 = (hi - origin) * inv_dir;
    // `min`/`max` ignore a NaN (0·∞ on a slab plane), which keeps that axis
    // from deciding the interval.
    let tmin = t0.min(t1);
    let tmax = t0.max(t1);
    let enter = tmin.x.max(tmin.y).max(tmin.z).max(0.0);
    let exit = tmax.x.min(tmax.y).min(tmax.z);
    (exit > enter).then_some((enter, exit))
}

/// A stream of samples along one ray.
pub trait Marcher {
    /// The next sample `(t, Δs)`, front to back.
    fn next_sample(&mut self) -> Option<(f32, f32)>;
}

/// Equal steps (S4): `t = t_enter + n·Δ`, `n = 0, 1, …` while inside; the last
/// sample stands for the remaining stretch only, so a ray through a
/// homogeneous medium integrates exactly its length.
#[derive(Clone, Copy, Debug)]
pub struct Uniform {
    t0: f32,
    t_exit: f32,
    step: f32,
    n: u32,
    count: u32,
}

impl Uniform {
    /// Samples from `t_enter` to `t_exit` at spacing `step` (> 0).
    #[inline]
    pub fn new(t_enter: f32, t_exit: f32, step: f32) -> Uniform {
        let len = (t_exit - t_enter).max(0.0);
        let count = (len / step).ceil() as u32;
        Uniform {
            t0: t_enter,
            t_exit,
            step,
            n: 0,
            count,
        }
    }

    /// Number of samples this ray will take.
    pub fn len(&self) -> u32 {
        self.count
    }

    /// True when the ray takes no sample.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

impl Marcher for Uniform {
    #[inline(always)]
    fn next_sample(&mut self) -> Option<(f32, f32)> {
        if self.n >= self.count {
            return None;
        }
        let t = self.t0 + self.n as f32 * self.step;
        self.n += 1;
        let ds = if self.n == self.count {
            (self.t_exit - t).clamp(0.0, self.step)
        } else {
            self.step
        };
        Some((t, ds))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_covers_the_ray_exactly() {
        let mut m = Uniform::new(2.0, 7.3, 0.5);
        let mut total = 0.0;
        let mut last_t = -1.0;
        let mut n = 0;
        while let Some((t, ds)) = m.next_sample() {
            assert!(t > last_t);
            last_t = t;
            total += ds;
            n += 1;
        }
        assert_eq!(n, 11);
        assert!((total - 5.3).abs() < 1e-5);
    }

    #[test]
    fn box_hits_and_misses() {
        let inv = |d: Vec3| Vec3::ONE / d;
        let (lo, hi) = (Vec3::ZERO, Vec3::splat(10.0));
        let (a, b) = intersect_box(Vec3::new(5.0, -5.0, 5.0), inv(Vec3::Y), lo, hi).unwrap();
        assert!((a - 5.0).abs() < 1e-6 && (b - 15.0).abs() < 1e-6);
        assert!(intersect_box(Vec3::new(15.0, -5.0, 5.0), inv(Vec3::Y), lo, hi).is_none());
        // Starting inside: enter at 0.
        let (a, _) = intersect_box(Vec3::splat(5.0), inv(Vec3::X), lo, hi).unwrap();
        assert_eq!(a, 0.0);
        // Pointing away.
        assert!(intersect_box(Vec3::new(5.0, -5.0, 5.0), inv(-Vec3::Y), lo, hi).is_none());
    }
}
