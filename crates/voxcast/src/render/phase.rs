//! Phase functions: how a participating medium redistributes the light it
//! scatters (S1: the phase function replaces the BRDF inside a volume;
//! Henyey–Greenstein, Schlick, Mie and Rayleigh are the ones it names).
//!
//! Convention: directions are *propagation* directions. `cos θ` is the cosine
//! between the direction the ray travelled (`dir`) and the direction it
//! leaves in (`new_dir`): θ = 0 is forward scattering. Every phase function
//! is normalised over the sphere, `∫ p dω = 1`, so it is its own pdf when
//! sampled exactly, and each one has `eval`, `sample` and `pdf`, as pbrt-v4's
//! `PhaseFunction` has (`p`, `Sample_p`, `PDF`).
//!
//! Each is a small `Copy` type implementing [`Phase`]; the integrators are
//! generic over it, and [`PhaseFunction`] (scene data) is matched once per
//! render to pick the monomorphised loop.

use super::rng::Rng;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::f32::consts::PI;

const INV_4PI: f32 = 1.0 / (4.0 * PI);

/// A phase function: density over the sphere of directions.
pub trait Phase: Copy + Send + Sync {
    /// `p(cos θ)` per steradian.
    fn eval(&self, cos_theta: f32) -> f32;
    /// Draws `cos θ` with density `2π·p(cos θ)` over [−1, 1].
    fn sample_cos(&self, rng: &mut Rng) -> f32;

    /// The pdf (per steradian) of sampling `new_dir` after `dir`.
    #[inline(always)]
    fn pdf(&self, dir: Vec3, new_dir: Vec3) -> f32 {
        self.eval(dir.dot(new_dir))
    }

    /// A new direction after `dir` (unit), and its pdf. Sampling is exact
    /// for every phase function here, so `eval / pdf = 1`.
    #[inline(always)]
    fn sample(&self, dir: Vec3, rng: &mut Rng) -> (Vec3, f32) {
        let c = self.sample_cos(rng).clamp(-1.0, 1.0);
        let phi = 2.0 * PI * rng.uniform();
        let new_dir = from_frame(dir, c, phi);
        (new_dir, self.eval(c))
    }
}

/// The unit vector at polar angle `acos(cos_theta)` and azimuth `phi` about
/// the unit vector `axis` (frame of Duff et al. 2017, no branches on axes).
#[inline(always)]
pub fn from_frame(axis: Vec3, cos_theta: f32, phi: f32) -> Vec3 {
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let (t, b) = axis.any_orthonormal_pair();
    (t * (sin_theta * phi.cos()) + b * (sin_theta * phi.sin()) + axis * cos_theta).normalize()
}

/// Scatters equally in all directions: `p = 1/(4π)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Isotropic;

impl Phase for Isotropic {
    #[inline(always)]
    fn eval(&self, _c: f32) -> f32 {
        INV_4PI
    }
    #[inline(always)]
    fn sample_cos(&self, rng: &mut Rng) -> f32 {
        1.0 - 2.0 * rng.uniform()
    }
}

/// Henyey & Greenstein (1941): `p = (1 − g²) / (4π (1 + g² − 2g cos θ)^{3/2})`;
/// `g` ∈ (−1, 1) is the mean cosine (forward > 0, backward < 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HenyeyGreenstein {
    pub g: f32,
}

impl Phase for HenyeyGreenstein {
    #[inline(always)]
    fn eval(&self, c: f32) -> f32 {
        let g = self.g;
        let d = (1.0 + g * g - 2.0 * g * c).max(1e-12);
        INV_4PI * (1.0 - g * g) / (d * d.sqrt())
    }
    #[inline(always)]
    fn sample_cos(&self, rng: &mut Rng) -> f32 {
        let g = self.g;
        let u = rng.uniform();
        if g.abs() < 1e-3 {
            return 1.0 - 2.0 * u;
        }
        // Inverse of the HG CDF in cos θ.
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        (1.0 + g * g - s * s) / (2.0 * g)
    }
}

/// Schlick's rational approximation of HG (Blasi, Le Saëc & Schlick 1993):
/// `p = (1 − k²) / (4π (1 − k cos θ)²)`, `k` ∈ (−1, 1); `k ≈ 1.55g − 0.55g³`
/// mimics HG with parameter `g`. Cheaper than HG (no power 3/2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Schlick {
    pub k: f32,
}

impl Schlick {
    /// The Schlick function that approximates HG with mean cosine `g`.
    pub fn from_g(g: f32) -> Schlick {
        Schlick {
            k: 1.55 * g - 0.55 * g * g * g,
        }
    }
}

impl Phase for Schlick {
    #[inline(always)]
    fn eval(&self, c: f32) -> f32 {
        let k = self.k;
        let d = (1.0 - k * c).max(1e-12);
        INV_4PI * (1.0 - k * k) / (d * d)
    }
    #[inline(always)]
    fn sample_cos(&self, rng: &mut Rng) -> f32 {
        let k = self.k;
        let u = rng.uniform();
        if k.abs() < 1e-4 {
            return 1.0 - 2.0 * u;
        }
        // CDF (1 − k²)/(2k)·(1/(1 − kμ) − 1/(1 + k)) = u, solved for μ.
        (1.0 - (1.0 - k * k) / (2.0 * k * u + 1.0 - k)) / k
    }
}

/// Rayleigh scattering by particles much smaller than the wavelength
/// (air molecules): `p = 3 (1 + cos² θ) / (16π)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rayleigh;

impl Phase for Rayleigh {
    #[inline(always)]
    fn eval(&self, c: f32) -> f32 {
        3.0 / (16.0 * PI) * (1.0 + c * c)
    }
    #[inline(always)]
    fn sample_cos(&self, rng: &mut Rng) -> f32 {
        // CDF (μ³ + 3μ + 4)/8 = u: the depressed cubic μ³ + 3μ + q = 0 with
        // q = 4 − 8u has one real root (Cardano).
        let q = 4.0 - 8.0 * rng.uniform();
        let s = (q * q * 0.25 + 1.0).sqrt();
        (-q * 0.5 + s).cbrt() + (-q * 0.5 - s).cbrt()
    }
}

/// Mie scattering by particles about the wavelength's size (cloud droplets,
/// haze), approximated by Cornette & Shanks (1992):
/// `p = 3 (1 − g²)(1 + cos² θ) / (8π (2 + g²)(1 + g² − 2g cos θ)^{3/2})`,
/// HG with a Rayleigh-like `1 + cos² θ` factor, which puts back the
/// backward lobe HG lacks. `g` is the asymmetry parameter (for cloud
/// droplets about 0.85). Its mean cosine is not exactly `g`.
///
/// Sampled exactly by rejection from HG(g): the ratio `p_CS / p_HG =
/// 3(1 + μ²)/(2(2 + g²))` is at most `3/(2 + g²)`, so a draw is kept with
/// probability `(1 + μ²)/2` (at least 1/2: two HG draws on average).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mie {
    pub g: f32,
}

impl Phase for Mie {
    #[inline(always)]
    fn eval(&self, c: f32) -> f32 {
        let g = self.g;
        let d = (1.0 + g * g - 2.0 * g * c).max(1e-12);
        3.0 / (8.0 * PI) * (1.0 - g * g) * (1.0 + c * c) / ((2.0 + g * g) * d * d.sqrt())
    }
    #[inline(always)]
    fn sample_cos(&self, rng: &mut Rng) -> f32 {
        let hg = HenyeyGreenstein { g: self.g };
        loop {
            let c = hg.sample_cos(rng).clamp(-1.0, 1.0);
            if 2.0 * rng.uniform() <= 1.0 + c * c {
                return c;
            }
        }
    }
}

/// A phase function as written in a scene:
/// `phase = { type = "hg", g = 0.8 }`, `{ type = "isotropic" }`,
/// `{ type = "schlick", k = 0.9 }`, `{ type = "rayleigh" }`,
/// `{ type = "mie", g = 0.85 }` (Cornette–Shanks).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
#[serde(tag = "type", rename_all = "kebab-case")]
pub enum PhaseFunction {
    #[default]
    Isotropic,
    #[serde(alias = "henyey-greenstein")]
    Hg {
        g: f32,
    },
    Schlick {
        k: f32,
    },
    Rayleigh,
    Mie {
        g: f32,
    },
}

impl PhaseFunction {
    /// Parses the CLI form: `isotropic`, `hg:G`, `schlick:K`, `rayleigh`, `mie:G`.
    pub fn parse(s: &str) -> Option<PhaseFunction> {
        let (name, arg) = match s.split_once(':') {
            Some((n, a)) => (n, Some(a.trim().parse::<f32>().ok()?)),
            None => (s, None),
        };
        let p = match (name.trim(), arg) {
            ("isotropic", None) => PhaseFunction::Isotropic,
            ("hg" | "henyey-greenstein", Some(g)) => PhaseFunction::Hg { g },
            ("schlick", Some(k)) => PhaseFunction::Schlick { k },
            ("rayleigh", None) => PhaseFunction::Rayleigh,
            ("mie", Some(g)) => PhaseFunction::Mie { g },
            _ => return None,
        };
        Some(p)
    }

    /// Checks the parameter range.
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        let ok = |x: f32| x.is_finite() && x.abs() < 0.999;
        let bad = |m: String| Err(crate::FieldError::new("phase", m));
        match *self {
            PhaseFunction::Hg { g } | PhaseFunction::Mie { g } if !ok(g) => {
                bad(format!("g = {g}: must be in (−0.999, 0.999)"))
            }
            PhaseFunction::Schlick { k } if !ok(k) => {
                bad(format!("k = {k}: must be in (−0.999, 0.999)"))
            }
            _ => Ok(()),
        }
    }
}

/// Code generic over a phase function, run with the concrete type of a
/// [`PhaseFunction`] (the one `match` per render).
pub trait PhaseVisitor {
    type Output;
    fn visit<P: Phase>(self, phase: P) -> Self::Output;
}

impl PhaseFunction {
    /// Runs `v` with the concrete phase function.
    pub fn visit<V: PhaseVisitor>(&self, v: V) -> V::Output {
        match *self {
            PhaseFunction::Isotropic => v.visit(Isotropic),
            PhaseFunction::Hg { g } => v.visit(HenyeyGreenstein { g }),
            PhaseFunction::Schlick { k } => v.visit(Schlick { k }),
            PhaseFunction::Rayleigh => v.visit(Rayleigh),
            PhaseFunction::Mie { g } => v.visit(Mie { g }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> Vec<PhaseFunction> {
        vec![
            PhaseFunction::Isotropic,
            PhaseFunction::Hg { g: 0.8 },
            PhaseFunction::Hg { g: -0.4 },
            PhaseFunction::Hg { g: 0.0 },
            PhaseFunction::Schlick { k: 0.7 },
            PhaseFunction::Schlick { k: -0.5 },
            PhaseFunction::Rayleigh,
            PhaseFunction::Mie { g: 0.85 },
            PhaseFunction::Mie { g: 0.3 },
        ]
    }

    /// ∫₋₁¹ f(μ) dμ by composite Simpson in f64 (n even).
    fn simpson(f: impl Fn(f64) -> f64, a: f64, b: f64, n: usize) -> f64 {
        let h = (b - a) / n as f64;
        let mut s = f(a) + f(b);
        for i in 1..n {
            s += f(a + i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        s * h / 3.0
    }

    struct Integral(f64);
    impl PhaseVisitor for Integral {
        type Output = f64;
        fn visit<P: Phase>(self, p: P) -> f64 {
            // The integrand is peaked for g = 0.85: substitute in the
            // angle-free variable with many intervals.
            let _ = self.0;
            2.0 * std::f64::consts::PI * simpson(|c| p.eval(c as f32) as f64, -1.0, 1.0, 200_000)
        }
    }

    #[test]
    fn every_phase_function_integrates_to_one() {
        for pf in all() {
            let i = pf.visit(Integral(0.0));
            assert!((i - 1.0).abs() < 1e-3, "{pf:?}: ∫p dω = {i}");
        }
    }

    /// Upper critical value of χ² with `k` degrees of freedom at
    /// significance ~1e-4 (Wilson–Hilferty, z = 3.719).
    fn chi2_critical(k: f64) -> f64 {
        let z = 3.719;
        k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
    }

    struct ChiSquare {
        seed: u64,
    }
    impl PhaseVisitor for ChiSquare {
        type Output = (f64, f64);
        /// Bins the sampled directions in (cos θ, φ) and compares the counts
        /// with the pdf integrated over each bin; also checks that the pdf
        /// `sample` returns equals `pdf`. Returns (χ², critical value).
        fn visit<P: Phase>(self, p: P) -> (f64, f64) {
            const NC: usize = 20;
            const NP: usize = 6;
            let n = 200_000usize;
            let dir = Vec3::new(0.3, -0.5, 0.8).normalize();
            let (t, b) = dir.any_orthonormal_pair();
            let mut counts = [[0u64; NP]; NC];
            let mut rng = Rng::new(self.seed, 1);
            for _ in 0..n {
                let (w, pdf) = p.sample(dir, &mut rng);
                assert!((w.length() - 1.0).abs() < 1e-4);
                let expect = p.pdf(dir, w);
                assert!(
                    (pdf - expect).abs() <= 1e-4 * expect.max(1.0),
                    "{pdf} vs {expect}"
                );
                let c = w.dot(dir).clamp(-1.0, 1.0);
                let phi = w.dot(b).atan2(w.dot(t)).rem_euclid(2.0 * PI);
                let ci = (((c + 1.0) * 0.5 * NC as f32) as usize).min(NC - 1);
                let pi = ((phi / (2.0 * PI) * NP as f32) as usize).min(NP - 1);
                counts[ci][pi] += 1;
            }
            let mut chi2 = 0.0;
            let mut dof = 0.0;
            for (ci, row) in counts.iter().enumerate() {
                let a = -1.0 + 2.0 * ci as f64 / NC as f64;
                let mass = 2.0
                    * std::f64::consts::PI
                    * simpson(|c| p.eval(c as f32) as f64, a, a + 2.0 / NC as f64, 2000)
                    / NP as f64;
                for &o in row {
                    let e = mass * n as f64;
                    assert!(e > 5.0, "bins too small for χ²");
                    chi2 += (o as f64 - e).powi(2) / e;
                    dof += 1.0;
                }
            }
            (chi2, chi2_critical(dof - 1.0))
        }
    }

    #[test]
    fn sampling_matches_the_pdf_chi_square() {
        for (i, pf) in all().into_iter().enumerate() {
            let (chi2, crit) = pf.visit(ChiSquare {
                seed: 11 + i as u64,
            });
            assert!(chi2 < crit, "{pf:?}: χ² = {chi2:.1} ≥ {crit:.1}");
        }
    }

    #[test]
    fn chi_square_rejects_a_wrong_sampler() {
        // The test has power: HG(0.5) sampled, HG(0.45) claimed.
        #[derive(Clone, Copy)]
        struct Liar;
        impl Phase for Liar {
            fn eval(&self, c: f32) -> f32 {
                HenyeyGreenstein { g: 0.45 }.eval(c)
            }
            fn sample_cos(&self, rng: &mut Rng) -> f32 {
                HenyeyGreenstein { g: 0.5 }.sample_cos(rng)
            }
            fn sample(&self, dir: Vec3, rng: &mut Rng) -> (Vec3, f32) {
                let c = self.sample_cos(rng);
                let w = from_frame(dir, c, 2.0 * PI * rng.uniform());
                (w, self.eval(c))
            }
        }
        let (chi2, crit) = ChiSquare { seed: 3 }.visit(Liar);
        assert!(chi2 > crit, "χ² = {chi2} should exceed {crit}");
    }

    #[test]
    fn hg_mean_cosine_is_g() {
        for g in [-0.6f32, 0.0, 0.3, 0.8, 0.95] {
            let p = HenyeyGreenstein { g };
            // By quadrature …
            let m = 2.0
                * std::f64::consts::PI
                * simpson(|c| c * p.eval(c as f32) as f64, -1.0, 1.0, 200_000);
            assert!((m - g as f64).abs() < 1e-3, "g {g}: quadrature {m}");
            // … and by sampling, within 4 standard errors.
            let mut rng = Rng::new(42, 7);
            let n = 100_000;
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let c = p.sample_cos(&mut rng) as f64;
                s += c;
                s2 += c * c;
            }
            let mean = s / n as f64;
            let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
            assert!(
                (mean - g as f64).abs() < 4.0 * se + 1e-6,
                "g {g}: {mean} ± {se}"
            );
        }
    }

    #[test]
    fn schlick_from_g_is_close_to_hg() {
        let s = Schlick::from_g(0.6);
        let m = 2.0
            * std::f64::consts::PI
            * simpson(|c| c * s.eval(c as f32) as f64, -1.0, 1.0, 200_000);
        // Blasi et al.'s fit is approximate: 0.645 for g = 0.6.
        assert!((m - 0.6).abs() < 0.05, "Schlick mean cosine {m}");
    }

    #[test]
    fn parse_and_validate() {
        assert_eq!(
            PhaseFunction::parse("hg:0.8"),
            Some(PhaseFunction::Hg { g: 0.8 })
        );
        assert_eq!(
            PhaseFunction::parse("rayleigh"),
            Some(PhaseFunction::Rayleigh)
        );
        assert_eq!(PhaseFunction::parse("mie"), None);
        assert!(PhaseFunction::Hg { g: 1.0 }.validate().is_err());
        let t: PhaseFunction = toml::from_str("type = \"hg\"\ng = 0.5").unwrap();
        assert_eq!(t, PhaseFunction::Hg { g: 0.5 });
    }
}
