//! voxcast-bench — how fast each sampling method is, and how good its
//! picture: the measurements the seed papers' tables and figures make
//! (SPEC.md), made again on this renderer.
//!
//! * This file and its parts: `voxcast bench`, every method on one scene
//!   against a converged reference — S0's samples-and-time table (uniform,
//!   Zeng's threshold ranges, the block-adaptive sampling), S3's fps table
//!   (uniform, importance, LOD decimation).
//! * [`bench_frames`]: `voxcast bench-frames`, the frame rate of every method
//!   frame by frame over a series (S0's Table 3 and Fig. 14).
//! * [`ttq`]: time to quality, the fair comparison of Riemann-sum marchers
//!   with S1's Monte-Carlo ones (each method's cost to reach a PSNR).
//! * [`quality`]: `--quality DB`, the setting of a method that reaches a
//!   target PSNR, chosen from a low-resolution pilot (`voxcast render` and
//!   `voxcast bench` use it).
//! * [`chart`]: the two reports as PNG charts (plotters, with an embedded
//!   font).
//!
//! It depends on the core (`voxcast`) for scenes, the renderer and the
//! metrics; the core does not depend on it.
//!
//! # `voxcast bench`: sampling methods compared on one scene
//!
//! Every method renders the same volume, transfer function, camera and image
//! size through one [`Renderer`](voxcast::render::Renderer) (its derived structures are built once, so
//! the times measure rendering, not set-up). For each method the report gives
//! the work done (samples, trilinear interpolations), the wall-clock time of
//! `repeat` renders after `warmup` untimed ones (median, min, max), the
//! speed-up over `uniform`, and the error against a **reference render**:
//! PSNR and SSIM ([`voxcast::metrics`]) against the same scene rendered with
//! the uniform marcher at 1/16 voxel, without early ray termination, without
//! empty-space skipping (so the reference does not rely on any of the
//! accelerations being measured), without jitter or grouping.
//!
//! The reference is expensive, so it is cached as a linear float EXR (exact)
//! in [`default_cache_dir`], named by a stable hash ([`reference_key`]) of
//! everything that determines it: the resolved reference scene (transfer
//! function inline), the volume's dims, spacing, origin, type and voxels, and
//! the library version.
//!
//! Times are wall-clock milliseconds measured with [`Instant`](std::time::Instant) around
//! [`Renderer::render`](voxcast::render::Renderer::render) (which includes baking the transfer-function table
//! and fitting the camera, both negligible). Renders of the methods are
//! interleaved round by round, so a slow spell of a shared machine spreads
//! over all methods instead of penalising one.
//!
//! The parts: `reference.rs` the reference render's parameters, cache key
//! and cache files; `runner.rs` the run ([`run`], [`run_on`]); `report.rs`
//! what a run reports (the JSON of `--json`); `table.rs` the report as a
//! Markdown or plain-text table. This file holds the configuration.

pub mod bench_frames;
pub mod chart;
pub mod quality;
mod reference;
mod report;
mod runner;
mod table;
pub mod ttq;

pub use reference::{fnv1a64, reference_key, reference_params, Fnv1a, REFERENCE_STEP};
pub use report::{
    input_label, BenchReport, CacheStatus, Machine, Measured, MethodResult, ReferenceInfo, RunInfo,
    SceneInfo,
};
pub use runner::{run, run_cancellable, run_on, MethodRenderer};
pub use table::{markdown, text_table};

use std::path::PathBuf;
use voxcast::error::{Error, Result};
use voxcast::render::{Method, MethodSpec, RenderParams};

/// The methods compared when none are named.
pub const DEFAULT_METHODS: &str = "uniform,adaptive,adaptive+grouped,threshold";

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchConfig {
    /// Methods to compare, in order; `uniform` is added when missing (it is
    /// the baseline of the speed-ups).
    pub methods: Vec<MethodSpec>,
    /// Timed renders per method (at least 1).
    pub repeat: usize,
    /// Untimed renders per method before the timed ones.
    pub warmup: usize,
    /// Folder of cached reference renders; `None` renders the reference
    /// every time and stores nothing.
    pub cache_dir: Option<PathBuf>,
    /// Render the reference even when it is cached (and replace the cache).
    pub refresh_reference: bool,
    /// A target PSNR: every method renders with the setting
    /// [`quality::choose`] picks for it, so the speed-ups compare methods
    /// at equal quality; the report gives each method's setting.
    pub quality: Option<f64>,
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            methods: default_methods(),
            repeat: 5,
            warmup: 1,
            cache_dir: Some(default_cache_dir()),
            refresh_reference: false,
            quality: None,
        }
    }
}

/// The default methods ([`DEFAULT_METHODS`]), those that parse.
pub fn default_methods() -> Vec<MethodSpec> {
    DEFAULT_METHODS
        .split(',')
        .filter_map(|s| MethodSpec::parse(s).ok())
        .collect()
}

/// Parses a comma-separated list of methods (`uniform,adaptive+grouped`).
pub fn parse_methods(list: &str) -> Result<Vec<MethodSpec>> {
    let items: Vec<&str> = list.split(',').map(str::trim).collect();
    if items.iter().all(|s| s.is_empty()) {
        let known: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        return Err(Error::invalid(format!(
            "--methods `{list}`: no method named (known: {}; add +grouped for grouped interpolation)",
            known.join(", ")
        )));
    }
    items
        .into_iter()
        .filter(|s| !s.is_empty())
        .map(MethodSpec::parse)
        .collect()
}

/// Where cached references live: `$VOXCAST_CACHE`, else
/// `$XDG_CACHE_HOME/voxcast`, else `~/.cache/voxcast`, else
/// `voxcast-cache` in the temporary folder.
pub fn default_cache_dir() -> PathBuf {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if let Some(d) = var("VOXCAST_CACHE") {
        return PathBuf::from(d);
    }
    if let Some(d) = var("XDG_CACHE_HOME") {
        return PathBuf::from(d).join("voxcast");
    }
    if let Some(h) = var("HOME") {
        return PathBuf::from(h).join(".cache").join("voxcast");
    }
    std::env::temp_dir().join("voxcast-cache")
}

/// The parameters `spec` renders with: the scene's, with its method and
/// modifiers replaced.
pub fn method_params(base: &RenderParams, spec: &MethodSpec) -> RenderParams {
    let mut p = base.clone();
    spec.apply(&mut p);
    p
}

/// Median of `xs` (the mean of the two middle values for an even count);
/// NaN for none.
pub fn median(xs: &[f64]) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Where a run is, for a progress bar: render `render` of `renders` (from 0),
/// `done` of `total` tiles of it.
#[derive(Clone, Copy, Debug)]
pub struct Progress<'a> {
    /// What is rendering: `reference`, `adaptive (warm-up)`, `uniform 2/5`.
    pub task: &'a str,
    pub render: usize,
    pub renders: usize,
    pub done: usize,
    pub total: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_of_odd_even_and_unsorted_lists() {
        assert_eq!(median(&[3.0]), 3.0);
        assert_eq!(median(&[5.0, 1.0, 3.0]), 3.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&[2.0, 2.0, 9.0, 1.0, 2.0]), 2.0);
        assert!(median(&[]).is_nan());
    }

    #[test]
    fn methods_parse_and_unknown_names_list_the_known_ones() {
        let m = parse_methods(" uniform, adaptive+grouped ,").unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m[1].to_string(), "adaptive+grouped");
        let e = parse_methods("uniform,fastest").unwrap_err().to_string();
        assert!(e.contains("fastest") && e.contains("adaptive-max"), "{e}");
        assert!(parse_methods(" , ").is_err());
        assert!(!default_methods().is_empty());
    }
}
