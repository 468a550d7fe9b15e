//! Time to quality: how long each method takes to reach a target PSNR
//! against the converged reference — the fair way to compare a Riemann-sum
//! marcher with Monte-Carlo ones (S1 claims 68 vs 50 fps at "almost the
//! same" picture; this measures "the same").
//!
//! Every method walks a ladder of settings from cheap to dear: deterministic
//! marchers halve the step (4, 2, 1, ½, ¼, ⅛ voxel); stochastic ones try each
//! step with 1, 2, 4, … 32 samples per pixel; `single-scatter` and `path`
//! double `spp` (1 … 256). Each setting is rendered once; the cheapest that
//! reaches the target is then timed `repeat` times and its median reported.
//! The reference is the bench's (uniform, step 1/16, no early termination,
//! no skipping) for ray casting, and `reference_spp` samples per pixel of
//! the same integrator, with another seed, for the physically based ones.
//!
//! Equal time is the other half of the comparison: of the settings each
//! method tried, the one with the highest PSNR that rendered within a time
//! budget — by default the time `uniform` takes to reach the target.

use crate::{median, reference_params};
use serde::Serialize;
use voxcast::error::{Error, Result};
use voxcast::metrics;
use voxcast::render::{MethodSpec, RenderParams, Renderer};
use voxcast::scene::{Prepared, Scene};

/// What to measure.
#[derive(Clone, Debug)]
pub struct TtqConfig {
    pub methods: Vec<MethodSpec>,
    /// PSNR (dB) against the reference to reach.
    pub target_psnr: f64,
    /// Timed renders of the winning setting (median).
    pub repeat: usize,
    /// Samples per pixel of the physically based references.
    pub reference_spp: u32,
    /// The time of the equal-time comparison (seconds); `None`: the time
    /// `uniform` takes to reach the target.
    pub time_budget: Option<f64>,
}

/// One setting tried.
#[derive(Clone, Debug, Serialize)]
pub struct TtqPoint {
    pub step: f32,
    pub spp: u32,
    pub seconds: f64,
    pub samples: u64,
    pub psnr_db: f64,
}

/// One method's ladder and its time to quality.
#[derive(Clone, Debug, Serialize)]
pub struct TtqResult {
    pub method: String,
    pub points: Vec<TtqPoint>,
    /// The cheapest setting that reached the target (its median time).
    pub best: Option<TtqPoint>,
    /// Speed-up over `uniform` at the target (uniform time / this time).
    pub speedup: Option<f64>,
    /// Equal time: of the settings tried, the one with the highest PSNR
    /// that rendered within the time budget.
    pub equal_time: Option<TtqPoint>,
    /// The target met exactly: interpolated between the two settings that
    /// bracket it (see [`TtqAtTarget`]).
    pub at_target: Option<TtqAtTarget>,
    /// Speed-up over `uniform` at exactly the target PSNR (uniform's
    /// interpolated time / this method's).
    pub speedup_at_target: Option<f64>,
}

/// Equal PSNR without the ladder's rounding: the ladder moves in factors of
/// 2, so the setting a method lands on can overshoot the target by several
/// dB (uniform on the teapot: 53.1 dB for a 50-dB target), which favours
/// whichever method happens to land close to it. Of the settings tried,
/// ordered by samples, take the frontier (each more PSNR than every cheaper
/// one) and the two neighbours on it with `below.psnr < target ≤
/// above.psnr`; time both (`repeat` renders, median), and interpolate the
/// log of the samples and of the time linearly in PSNR (dB is linear in the
/// log of the step for a power-law error) to the target.
#[derive(Clone, Debug, Serialize)]
pub struct TtqAtTarget {
    /// The frontier setting just below the target (its median time).
    pub below: TtqPoint,
    /// The frontier setting just above it (its median time).
    pub above: TtqPoint,
    /// Samples and seconds at exactly the target.
    pub samples: f64,
    pub seconds: f64,
}

/// The frontier neighbours of `points` that bracket `target`: by samples,
/// each more PSNR than every cheaper setting.
pub fn bracket(points: &[TtqPoint], target: f64) -> Option<(TtqPoint, TtqPoint)> {
    let mut sorted: Vec<&TtqPoint> = points.iter().collect();
    sorted.sort_by(|a, b| {
        a.samples
            .cmp(&b.samples)
            .then(b.psnr_db.total_cmp(&a.psnr_db))
    });
    let mut frontier: Vec<&TtqPoint> = Vec::new();
    for p in sorted {
        if frontier.last().is_none_or(|l| p.psnr_db > l.psnr_db) {
            frontier.push(p);
        }
    }
    frontier
        .windows(2)
        .find(|w| w[0].psnr_db < target && target <= w[1].psnr_db)
        .map(|w| (w[0].clone(), w[1].clone()))
}

/// Log-linear interpolation in PSNR between `below` and `above` to `target`.
pub fn interpolate(below: &TtqPoint, above: &TtqPoint, target: f64) -> (f64, f64) {
    let f = (target - below.psnr_db) / (above.psnr_db - below.psnr_db);
    let lerp_log = |a: f64, b: f64| (a.ln() + f * (b.ln() - a.ln())).exp();
    (
        lerp_log(below.samples as f64, above.samples as f64),
        lerp_log(below.seconds, above.seconds),
    )
}

/// The report.
#[derive(Clone, Debug, Serialize)]
pub struct TtqReport {
    pub target_psnr_db: f64,
    pub width: u32,
    pub height: u32,
    pub reference_seconds: f64,
    /// The equal-time budget (seconds), when there is one.
    pub time_budget_s: Option<f64>,
    pub results: Vec<TtqResult>,
}

const STEPS: [f32; 6] = [4.0, 2.0, 1.0, 0.5, 0.25, 0.125];
const SPPS: [u32; 6] = [1, 2, 4, 8, 16, 32];

/// Runs the time-to-quality comparison; `progress(message)` is called
/// before each render.
pub fn run(
    scene: &Scene,
    prepared: &Prepared,
    config: &TtqConfig,
    progress: &dyn Fn(&str),
) -> Result<TtqReport> {
    let mut r = run_targets(scene, prepared, config, &[config.target_psnr], progress)?;
    Ok(r.remove(0))
}

/// [`run`] for several targets at once (`config.target_psnr` is ignored):
/// one reference and one ladder per method, walked at each step until the
/// highest target is reached; each setting is timed once however many
/// targets use it. One report per target, in the order given.
pub fn run_targets(
    scene: &Scene,
    prepared: &Prepared,
    config: &TtqConfig,
    targets: &[f64],
    progress: &dyn Fn(&str),
) -> Result<Vec<TtqReport>> {
    if targets.is_empty() {
        return Err(Error::invalid("no target PSNR"));
    }
    if let Some(t) = config.time_budget {
        if !(t.is_finite() && t > 0.0) {
            return Err(Error::invalid(format!(
                "time budget {t}: must be a positive number of seconds"
            )));
        }
    }
    for &t in targets {
        if !(t.is_finite() && t > 0.0) {
            return Err(Error::invalid(format!(
                "target PSNR {t}: must be a positive number of dB"
            )));
        }
    }
    let top = targets.iter().copied().fold(f64::MIN, f64::max);
    let renderer = Renderer::new(&prepared.volume, prepared.window)?;
    let render = |p: &RenderParams| renderer.render(&prepared.tf, &scene.camera, p, &|_, _| {});
    let physical = config.methods.iter().any(|m| m.method.is_physical());
    let base = &scene.render;
    let ref_params = if physical {
        let mut p = base.clone();
        let spec = config
            .methods
            .iter()
            .find(|m| m.method.is_physical())
            .expect("checked");
        spec.apply(&mut p);
        p.spp = config.reference_spp;
        p.seed = base.seed.wrapping_add(0x5EED);
        p
    } else {
        reference_params(base)
    };
    progress("reference");
    let (reference, ref_stats) = render(&ref_params)?;
    // Every method's ladder, walked until the highest target.
    let mut ladders: Vec<Vec<TtqPoint>> = Vec::new();
    for spec in &config.methods {
        let mut points = Vec::new();
        let mut ladder: Vec<(f32, u32)> = Vec::new();
        if spec.method.is_physical() {
            ladder.extend((0..=8).map(|k| (base.step, 1u32 << k)));
        } else if spec.method.is_stochastic() {
            for s in STEPS {
                ladder.extend(SPPS.iter().map(|&n| (s, n)));
            }
        } else {
            ladder.extend(STEPS.iter().map(|&s| (s, 1)));
        }
        let mut done_step = f32::NAN;
        for (step, spp) in ladder {
            if step == done_step {
                // More spp at a step that already reached the target only costs more.
                continue;
            }
            let mut p = base.clone();
            spec.apply(&mut p);
            p.step = step;
            p.spp = spp;
            progress(&format!("{spec} step {step} spp {spp}"));
            let (img, st) = render(&p)?;
            let psnr = metrics::psnr(&img, &reference)?;
            points.push(TtqPoint {
                step,
                spp,
                seconds: st.seconds,
                samples: st.samples,
                psnr_db: psnr,
            });
            if psnr >= top {
                done_step = step;
                if !spec.method.is_stochastic() || spec.method.is_physical() {
                    break;
                }
            }
        }
        ladders.push(points);
    }
    // Timed settings (median of `repeat` renders), per method, shared by
    // the targets.
    let mut timings: Vec<Vec<TtqPoint>> = vec![Vec::new(); config.methods.len()];
    let mut reports = Vec::new();
    for &target in targets {
        let mut results = Vec::new();
        for (mi, spec) in config.methods.iter().enumerate() {
            let points = &ladders[mi];
            let best = points
                .iter()
                .filter(|p| p.psnr_db >= target)
                .min_by(|a, b| a.seconds.total_cmp(&b.seconds))
                .cloned();
            // A setting timed: the median of `--repeat` renders, once per setting.
            let mut timed = |pt: &TtqPoint| -> Result<TtqPoint> {
                if let Some(t) = timings[mi]
                    .iter()
                    .find(|t| t.step == pt.step && t.spp == pt.spp)
                {
                    return Ok(t.clone());
                }
                let mut p = base.clone();
                spec.apply(&mut p);
                p.step = pt.step;
                p.spp = pt.spp;
                progress(&format!("{spec} timing step {} spp {}", pt.step, pt.spp));
                let mut times = Vec::new();
                for _ in 0..config.repeat.max(1) {
                    times.push(render(&p)?.1.seconds);
                }
                let t = TtqPoint {
                    seconds: median(&times),
                    ..pt.clone()
                };
                timings[mi].push(t.clone());
                Ok(t)
            };
            let best = best.as_ref().map(&mut timed).transpose()?;
            // The bracketing settings, reusing the best one's timing.
            let at_target = match bracket(points, target) {
                Some((lo, hi)) => {
                    let (below, above) = (timed(&lo)?, timed(&hi)?);
                    let (samples, seconds) = interpolate(&below, &above, target);
                    Some(TtqAtTarget {
                        below,
                        above,
                        samples,
                        seconds,
                    })
                }
                None => None,
            };
            results.push(TtqResult {
                method: spec.to_string(),
                points: points.clone(),
                best,
                speedup: None,
                equal_time: None,
                at_target,
                speedup_at_target: None,
            });
        }
        let uniform = results
            .iter()
            .find(|r| r.method == "uniform")
            .and_then(|r| r.best.as_ref().map(|b| b.seconds));
        let budget = config.time_budget.or(uniform);
        let uniform_at_target = results
            .iter()
            .find(|r| r.method == "uniform")
            .and_then(|r| r.at_target.as_ref().map(|a| a.seconds));
        for (mi, r) in results.iter_mut().enumerate() {
            r.speedup_at_target = match (uniform_at_target, &r.at_target) {
                (Some(u), Some(a)) if a.seconds > 0.0 => Some(u / a.seconds),
                _ => None,
            };
            r.speedup = match (uniform, &r.best) {
                (Some(u), Some(b)) if b.seconds > 0.0 => Some(u / b.seconds),
                _ => None,
            };
            // The timed settings count with their median, the others with
            // their one render.
            let timed = &timings[mi];
            r.equal_time = budget.and_then(|t| {
                r.points
                    .iter()
                    .map(|p| {
                        timed
                            .iter()
                            .find(|b| b.step == p.step && b.spp == p.spp)
                            .unwrap_or(p)
                            .clone()
                    })
                    .filter(|p| p.seconds <= t)
                    .max_by(|a, b| a.psnr_db.total_cmp(&b.psnr_db))
            });
        }
        reports.push(TtqReport {
            target_psnr_db: target,
            width: base.width,
            height: base.height,
            reference_seconds: ref_stats.seconds,
            time_budget_s: budget,
            results,
        });
    }
    Ok(reports)
}

/// The report as a Markdown table.
pub fn markdown(r: &TtqReport) -> String {
    let mut s = format!(
        "Time to reach {:.1} dB PSNR against the reference ({}×{}):\n\n| method | setting | PSNR (dB) | time (s) | samples | speed-up vs uniform |\n|---|---|---:|---:|---:|---:|\n",
        r.target_psnr_db, r.width, r.height
    );
    for m in &r.results {
        match &m.best {
            Some(b) => {
                s += &format!(
                    "| {} | step {} spp {} | {:.2} | {:.4} | {} | {} |\n",
                    m.method,
                    b.step,
                    b.spp,
                    b.psnr_db,
                    b.seconds,
                    b.samples,
                    m.speedup
                        .map(|x| format!("{x:.2}×"))
                        .unwrap_or_else(|| "—".into())
                )
            }
            None => {
                let top = m
                    .points
                    .iter()
                    .map(|p| p.psnr_db)
                    .fold(f64::NEG_INFINITY, f64::max);
                s += &format!(
                    "| {} | not reached (best {:.2} dB) | — | — | — | — |\n",
                    m.method, top
                )
            }
        }
    }
    if r.results.iter().any(|m| m.at_target.is_some()) {
        s += &format!(
            "\nEqual PSNR, interpolated: samples and time at exactly {:.1} dB, log-linear in PSNR between the two settings that bracket it (each timed, median):\n\n| method | between | samples | time (s) | speed-up vs uniform |\n|---|---|---:|---:|---:|\n",
            r.target_psnr_db
        );
        for m in &r.results {
            s += &match &m.at_target {
                Some(a) => format!(
                    "| {} | step {} spp {} ({:.2} dB, {:.4} s) – step {} spp {} ({:.2} dB, {:.4} s) | {:.0} | {:.4} | {} |\n",
                    m.method,
                    a.below.step,
                    a.below.spp,
                    a.below.psnr_db,
                    a.below.seconds,
                    a.above.step,
                    a.above.spp,
                    a.above.psnr_db,
                    a.above.seconds,
                    a.samples,
                    a.seconds,
                    m.speedup_at_target
                        .map(|x| format!("{x:.2}×"))
                        .unwrap_or_else(|| "—".into())
                ),
                None => format!("| {} | no bracketing settings | — | — | — |\n", m.method),
            };
        }
    }
    if let Some(t) = r.time_budget_s {
        s += &format!(
            "\nEqual time: the best PSNR each method reached within {t:.4} s (the settings above, each rendered once):\n\n| method | setting | time (s) | PSNR (dB) |\n|---|---|---:|---:|\n"
        );
        for m in &r.results {
            s += &match &m.equal_time {
                Some(p) => format!(
                    "| {} | step {} spp {} | {:.4} | {:.2} |\n",
                    m.method, p.step, p.spp, p.seconds, p.psnr_db
                ),
                None => format!("| {} | none within the budget | — | — |\n", m.method),
            };
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pt(step: f32, samples: u64, seconds: f64, psnr_db: f64) -> TtqPoint {
        TtqPoint {
            step,
            spp: 1,
            seconds,
            samples,
            psnr_db,
        }
    }

    #[test]
    fn bracket_takes_the_frontier_neighbours_of_the_target() {
        let points = [
            pt(2.0, 100, 1.0, 40.0),
            // More samples but no better: off the frontier.
            pt(2.0, 250, 2.5, 39.0),
            pt(1.0, 200, 2.0, 46.0),
            pt(0.5, 400, 4.0, 52.0),
            pt(0.25, 800, 8.0, 56.0),
        ];
        let (lo, hi) = bracket(&points, 50.0).unwrap();
        assert_eq!((lo.samples, hi.samples), (200, 400));
        // Exactly on a setting: that setting is the upper end.
        let (lo, hi) = bracket(&points, 52.0).unwrap();
        assert_eq!((lo.samples, hi.samples), (200, 400));
        // Out of reach, or reached by the cheapest: no bracket.
        assert!(bracket(&points, 60.0).is_none());
        assert!(bracket(&points, 30.0).is_none());
    }

    #[test]
    fn interpolation_is_log_linear_in_psnr() {
        let (a, b) = (pt(1.0, 200, 2.0, 46.0), pt(0.5, 800, 8.0, 52.0));
        let (s, t) = interpolate(&a, &b, 49.0);
        assert!(
            (s - 400.0).abs() < 1e-6 && (t - 4.0).abs() < 1e-9,
            "{s} {t}"
        );
        let (s, t) = interpolate(&a, &b, 52.0);
        assert!((s - 800.0).abs() < 1e-6 && (t - 8.0).abs() < 1e-9);
    }
}
