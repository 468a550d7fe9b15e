//! `--quality DB`: the sampling setting that reaches a target PSNR against
//! the reference, found from a cheap pilot, so nobody tunes `step`,
//! `tolerance` or `k_ref` by hand.
//!
//! PSNR is the mean over rays of the squared error, and a render with the
//! same camera at a lower resolution casts a sparser set of the same rays:
//! a pilot of about 128×128 pixels estimates the full image's PSNR without
//! rendering it. The pilot renders the reference at the pilot size (uniform
//! at 1/16 voxel, no early termination, no skipping — the bench's), then
//! searches one knob, a factor `2^−q` on every length the method samples
//! with:
//!
//! * the base `step` (all methods; the stochastic ones keep their `spp`);
//! * `adaptive`'s `tolerance` with it (up to 1), so every block keeps its
//!   level (`tolerance / step` is unchanged) and only the lengths change;
//! * `threshold`'s three steps, and `adaptive`'s `min_step`/`max_step` when
//!   set.
//!
//! PSNR rises smoothly with `q` (about 6 dB per halving), so a secant search
//! on the bracket (regula falsi) lands within [`TOLERANCE_DB`] of the
//! target in 3–6 pilot renders. Early ray termination is tightened so that
//! it cannot cap the PSNR below the target: the light it drops is at most
//! half the error the target allows (`ert ≥ 1 − 10^(−DB/20)/2`).

use serde::Serialize;
use voxcast::error::{Error, Result};
use voxcast::image::Image;
use voxcast::metrics;
use voxcast::render::{Method, RenderParams, RenderStats};

use crate::reference::{reference_params, REFERENCE_STEP};

/// The pilot's size: about this many pixels, the image's aspect kept.
pub const PILOT_PIXELS: u32 = 128 * 128;
/// The search stops within this many dB of the target.
pub const TOLERANCE_DB: f64 = 0.25;
/// A trial this close below the target still counts as reaching it: PSNR
/// against the step is not smooth at this scale (a small volume at a
/// coarse step moves ±0.5 dB between neighbouring steps), and the pilot
/// estimates the full image's PSNR to about as much.
const ACCEPT_DB: f64 = 0.5;
/// Pilot renders at most (the reference not counted).
const MAX_TRIALS: usize = 8;
/// The first guess of dB gained per halving of the lengths.
const DB_PER_HALVING: f64 = 6.0;
/// Coarsest factor: 2^3 = 8 times the given lengths.
const Q_MIN: f64 = -3.0;

/// One pilot render.
#[derive(Clone, Debug, Serialize)]
pub struct Trial {
    /// The factor on the lengths (`2^−q`).
    pub scale: f64,
    pub psnr_db: f64,
    pub samples: u64,
    pub ms: f64,
}

/// The setting `--quality` chose, and how.
#[derive(Clone, Debug, Serialize)]
pub struct QualityChoice {
    pub target_db: f64,
    /// The factor applied to the method's lengths.
    pub scale: f64,
    /// The chosen base step (voxels).
    pub step: f32,
    /// The chosen `adaptive` tolerance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f32>,
    /// The chosen `threshold` steps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub threshold_steps: Option<[f32; 3]>,
    /// Early ray termination used (1: off).
    pub ert: f32,
    pub pilot_width: u32,
    pub pilot_height: u32,
    /// The pilot's PSNR at the chosen setting: the prediction.
    pub pilot_psnr_db: f64,
    /// False when even the finest setting tried stays below the target (the
    /// finest is chosen).
    pub reached: bool,
    /// Every pilot render, in order.
    pub trials: Vec<Trial>,
    /// The pilot's whole time, reference included.
    pub pilot_ms: f64,
    /// The render parameters chosen (full size).
    #[serde(skip)]
    pub params: RenderParams,
}

impl QualityChoice {
    /// The setting in a few words: `step 0.31, tolerance 0.093, ERT 0.997`.
    pub fn setting(&self) -> String {
        let mut s = format!("step {}", round3(self.step));
        if let Some(t) = self.tolerance {
            s.push_str(&format!(", tolerance {}", round3(t)));
        }
        if let Some(t) = self.threshold_steps {
            s.push_str(&format!(
                ", steps {}/{}/{}",
                round3(t[0]),
                round3(t[1]),
                round3(t[2])
            ));
        }
        if self.ert < 1.0 {
            s.push_str(&format!(", ERT {}", round3(self.ert)));
        }
        s
    }

    /// One line for the user: the setting and the evidence for it.
    pub fn describe(&self) -> String {
        let verdict = if self.reached {
            format!("predicts {:.1} dB", self.pilot_psnr_db)
        } else {
            format!(
                "NOT reached: the finest setting tried gives {:.1} dB (lower the target, or raise --ert)",
                self.pilot_psnr_db
            )
        };
        format!(
            "--quality {} dB: {} — a {}×{} pilot against the reference {} after {} renders ({:.2} s)",
            self.target_db,
            self.setting(),
            self.pilot_width,
            self.pilot_height,
            verdict,
            self.trials.len(),
            self.pilot_ms / 1e3
        )
    }
}

fn round3(x: f32) -> f32 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let mag = 10f32.powi(2 - x.abs().log10().floor() as i32);
    (x * mag).round() / mag
}

/// The pilot's size for a `width`×`height` image: about `pixels` pixels
/// with the same aspect, never larger than the image.
pub fn pilot_size(width: u32, height: u32, pixels: u32) -> (u32, u32) {
    let r = (pixels as f64 / (width as f64 * height as f64))
        .sqrt()
        .min(1.0);
    // At least 8 pixels a side where the image has them.
    let side = |n: u32| ((n as f64 * r).round() as u32).clamp(8.min(n), n.max(1));
    (side(width), side(height))
}

/// `base` with every length the method samples with multiplied by `f`.
pub fn scaled(base: &RenderParams, f: f32) -> RenderParams {
    let mut p = base.clone();
    p.step = base.step * f;
    if p.method == Method::Adaptive {
        // At most 1 (all the opacity a sample can change); past that only
        // the step grows.
        p.adaptive.tolerance = (base.adaptive.tolerance * f).min(1.0);
    }
    p.adaptive.min_step = base.adaptive.min_step.map(|s| s * f);
    p.adaptive.max_step = base.adaptive.max_step.map(|s| s * f);
    if p.method == Method::Threshold {
        p.threshold.steps = base.threshold.steps.map(|s| s * f);
    }
    p
}

/// The early ray termination for a target: at most half the allowed RMS
/// error of light left behind, or the given one when it is stricter.
pub fn ert_for(target_db: f64, ert: f32) -> f32 {
    if ert >= 1.0 {
        return ert;
    }
    let allowed = 0.5 * 10f64.powf(-target_db / 20.0);
    ert.max((1.0 - allowed) as f32)
}

/// Finds the coarsest setting of `params`' method whose pilot PSNR reaches
/// `target_db`, with a pilot of about `pilot_pixels` pixels
/// ([`PILOT_PIXELS`] by default). `render` renders the scene (volume,
/// transfer function, camera) with the given parameters; `progress` hears
/// what is rendered.
pub fn choose(
    params: &RenderParams,
    target_db: f64,
    pilot_pixels: u32,
    render: &dyn Fn(&RenderParams) -> Result<(Image, RenderStats)>,
    progress: &dyn Fn(&str),
) -> Result<QualityChoice> {
    if !(target_db.is_finite() && (10.0..=90.0).contains(&target_db)) {
        return Err(Error::invalid(format!(
            "--quality {target_db}: a target PSNR in dB, 10…90 (30 is rough, 40 good, 50 hard to tell from the reference)"
        )));
    }
    if params.method.is_physical() {
        return Err(Error::invalid(format!(
            "--quality with --method {}: the target is a PSNR against the ray-casting reference; \
             single-scatter and path converge with --spp instead",
            params.method.name()
        )));
    }
    let start = std::time::Instant::now();
    let (pw, ph) = pilot_size(params.width, params.height, pilot_pixels);
    let mut base = params.clone();
    base.width = pw;
    base.height = ph;
    base.ert = ert_for(target_db, params.ert);
    progress(&format!("pilot reference {pw}×{ph}"));
    let (reference, _) = render(&reference_params(&base))?;
    // Finest factor: the step stays at twice the reference's.
    let q_max = ((base.step / (2.0 * REFERENCE_STEP)) as f64)
        .log2()
        .max(0.0);
    let q_min = Q_MIN;
    let mut trials: Vec<(f64, Trial)> = Vec::new();
    let mut eval = |q: f64| -> Result<f64> {
        let f = 2f64.powf(-q);
        let p = scaled(&base, f as f32);
        p.validate()
            .map_err(|e| Error::invalid(format!("--quality at scale {f:.3}: {e}")))?;
        progress(&format!("pilot step {:.3}", p.step));
        let t = std::time::Instant::now();
        let (img, st) = render(&p)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let psnr = metrics::psnr(&img, &reference)?;
        trials.push((
            q,
            Trial {
                scale: f,
                psnr_db: psnr,
                samples: st.samples,
                ms,
            },
        ));
        // An identical image counts as far above any target.
        Ok(psnr.min(200.0))
    };
    // (q, PSNR) of the finest setting below the target and the coarsest at
    // or above it.
    let mut below: Option<(f64, f64)> = None;
    let mut above: Option<(f64, f64)> = None;
    let mut q = 0.0f64;
    for _ in 0..MAX_TRIALS {
        let p = eval(q)?;
        if p >= target_db {
            if above.is_none_or(|a| q < a.0) {
                above = Some((q, p));
            }
        } else if below.is_none_or(|b| q > b.0) {
            below = Some((q, p));
        }
        if (p - target_db).abs() <= TOLERANCE_DB {
            break;
        }
        q = match (below, above) {
            (Some(b), Some(a)) => {
                if a.0 <= b.0 || a.0 - b.0 < 0.02 {
                    // Adjacent (or PSNR not monotone here): the coarsest
                    // setting above is the answer.
                    break;
                }
                let x = b.0 + (target_db - b.1) * (a.0 - b.0) / (a.1 - b.1);
                let margin = 0.1 * (a.0 - b.0);
                x.clamp(b.0 + margin, a.0 - margin)
            }
            (None, Some(a)) => {
                if a.0 <= q_min {
                    break;
                }
                (a.0 - ((a.1 - target_db) / DB_PER_HALVING).clamp(0.25, 2.0)).max(q_min)
            }
            (Some(b), None) => {
                if b.0 >= q_max {
                    break;
                }
                (b.0 + ((target_db - b.1) / DB_PER_HALVING).clamp(0.25, 2.0)).min(q_max)
            }
            (None, None) => unreachable!("every trial is below or above"),
        };
    }
    // The coarsest setting that reaches the target (within ACCEPT_DB), else
    // the best one.
    let pick = trials
        .iter()
        .filter(|(_, t)| t.psnr_db >= target_db - ACCEPT_DB)
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(q, _)| (*q, true))
        .unwrap_or_else(|| {
            let best = trials
                .iter()
                .max_by(|a, b| a.1.psnr_db.total_cmp(&b.1.psnr_db))
                .expect("at least one trial");
            (best.0, false)
        });
    let (q, reached) = pick;
    let f = 2f64.powf(-q) as f32;
    let mut chosen = scaled(params, f);
    chosen.ert = base.ert;
    let pilot_psnr = trials
        .iter()
        .find(|(tq, _)| *tq == q)
        .map(|(_, t)| t.psnr_db)
        .unwrap_or(f64::NAN);
    Ok(QualityChoice {
        target_db,
        scale: f as f64,
        step: chosen.step,
        tolerance: (chosen.method == Method::Adaptive).then_some(chosen.adaptive.tolerance),
        threshold_steps: (chosen.method == Method::Threshold).then_some(chosen.threshold.steps),
        ert: chosen.ert,
        pilot_width: pw,
        pilot_height: ph,
        pilot_psnr_db: pilot_psnr,
        reached,
        trials: trials.into_iter().map(|(_, t)| t).collect(),
        pilot_ms: start.elapsed().as_secs_f64() * 1e3,
        params: chosen,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pilot_keeps_the_aspect_and_never_grows() {
        let n = PILOT_PIXELS;
        assert_eq!(pilot_size(512, 512, n), (128, 128));
        assert_eq!(pilot_size(1024, 512, n), (181, 91));
        assert_eq!(pilot_size(100, 50, n), (100, 50));
        assert_eq!(pilot_size(4000, 3, n), (4000, 3));
    }

    #[test]
    fn scaling_keeps_the_adaptive_levels_and_scales_every_length() {
        let mut p = RenderParams {
            method: Method::Adaptive,
            ..Default::default()
        };
        p.adaptive.max_step = Some(2.0);
        let s = scaled(&p, 0.5);
        assert_eq!(s.step, 0.25);
        assert_eq!(s.adaptive.tolerance, p.adaptive.tolerance * 0.5);
        assert_eq!(s.adaptive_k_ref(), p.adaptive_k_ref());
        assert_eq!(s.adaptive.max_step, Some(1.0));
        let t = scaled(
            &RenderParams {
                method: Method::Threshold,
                ..Default::default()
            },
            2.0,
        );
        assert_eq!(t.threshold.steps, [4.0, 2.0, 1.0]);
    }

    #[test]
    fn early_termination_never_caps_below_the_target() {
        assert!((ert_for(40.0, 0.99) - 0.995).abs() < 1e-6);
        assert_eq!(ert_for(20.0, 0.99), 0.99);
        assert_eq!(ert_for(60.0, 1.0), 1.0);
    }
}
