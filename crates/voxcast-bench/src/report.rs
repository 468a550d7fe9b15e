//! What a bench run reports: the scene, the machine, how the run was made,
//! the reference and one row per method; serialises to the JSON of
//! `voxcast bench --json`.

use serde::{Serialize, Serializer};
use std::path::{Component, Path, PathBuf};
use voxcast::scene::BUILTIN_PREFIX;

/// The scene the methods were compared on.
#[derive(Clone, Debug, Serialize)]
pub struct SceneInfo {
    /// The input as given (a path or `builtin:NAME`).
    pub input: String,
    /// A short name for titles: the builtin's name or the path's last two parts.
    pub label: String,
    pub dims: [usize; 3],
    pub scalar_type: String,
    pub width: u32,
    pub height: u32,
    /// Transfer function as named in the scene (`auto`, a preset, a file).
    pub tf: String,
    pub window: [f32; 2],
    /// The scene's step in voxels (the methods' base step).
    pub step: f32,
    pub ert: f32,
    pub shading: bool,
    pub skip_empty: bool,
    pub jitter: bool,
    pub azimuth: f32,
    pub elevation: f32,
    pub zoom: f32,
}

/// The machine the times were taken on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Rayon worker threads (`RAYON_NUM_THREADS` or the number of cores).
    pub threads: usize,
    /// CPU model, where the OS says (Linux `/proc/cpuinfo`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cpu: Option<String>,
    /// The instruction set the CPU ray packets use here (`avx512`, `avx2`),
    /// or `none` (scalar loop only); `--simd` may hold a render below it.
    pub simd: &'static str,
    pub os: &'static str,
    pub arch: &'static str,
}

impl Machine {
    pub fn this() -> Machine {
        Machine {
            threads: rayon::current_num_threads(),
            cpu: cpu_model(),
            simd: voxcast::render::simd_level(voxcast::render::Simd::Auto)
                .map_or("none", |l| l.name()),
            os: std::env::consts::OS,
            arch: std::env::consts::ARCH,
        }
    }
}

fn cpu_model() -> Option<String> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    text.lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, v)| v.split_whitespace().collect::<Vec<_>>().join(" "))
}

/// How the reference was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum CacheStatus {
    /// Read from the cache.
    Hit,
    /// Rendered, then stored in the cache.
    Miss,
    /// Rendered because `refresh_reference` asked, then stored.
    Refreshed,
    /// Rendered; no cache folder was given, or storing failed (see notes).
    Off,
}

/// The reference render.
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceInfo {
    /// Always `uniform`.
    pub method: String,
    /// Step in voxels ([`REFERENCE_STEP`](crate::REFERENCE_STEP)).
    pub step: f32,
    /// Early ray termination threshold (1: off).
    pub ert: f32,
    pub skip_empty: bool,
    pub jitter: bool,
    pub grouped: bool,
    /// Milliseconds the reference took to render (when it was rendered,
    /// possibly in an earlier run: see `cache`).
    pub ms: f64,
    pub samples: u64,
    pub interpolations: u64,
    pub rays: u64,
    /// `hit`, `miss`, `refreshed` or `off`.
    pub cache: CacheStatus,
    /// The cached EXR (linear float RGBA), when there is one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cache_file: Option<PathBuf>,
    /// The cache key, 16 hex digits ([`reference_key`](crate::reference_key)).
    pub key: String,
}

/// Everything measured for one method.
#[derive(Clone, Debug, Serialize)]
pub struct Measured {
    pub samples: u64,
    pub interpolations: u64,
    pub gradient_interpolations: u64,
    pub rays: u64,
    pub rays_hit: u64,
    pub early_terminated: u64,
    pub ms_median: f64,
    pub ms_min: f64,
    pub ms_max: f64,
    /// Every timed render, in order.
    pub ms_per_repeat: Vec<f64>,
    /// Median milliseconds the GPU spent in the compute passes (timestamp
    /// queries; upload and read-back excluded); absent on the CPU or
    /// without timestamps.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub device_ms_median: Option<f64>,
    /// The device's milliseconds per timed render, in order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub device_ms_per_repeat: Vec<f64>,
    /// Median time of `uniform` over this method's.
    pub speedup_vs_uniform: f64,
    /// This method's samples over `uniform`'s.
    pub samples_vs_uniform: f64,
    /// This method's interpolations over `uniform`'s.
    pub interpolations_vs_uniform: f64,
    /// PSNR in dB against the reference; infinite for an identical image,
    /// written as JSON `null` (with `identical: true`).
    #[serde(serialize_with = "finite_or_null")]
    pub psnr_db: f64,
    /// True when the image equals the reference (PSNR infinite).
    pub identical: bool,
    /// SSIM against the reference (1 for identical images).
    pub ssim: f64,
    /// The SIMD level the CPU ray loop ran at (`avx2`, `avx512`); absent
    /// where the scalar loop ran, and on the GPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub simd: Option<&'static str>,
    /// Where empty-space skipping was on but the renderer left it out (the
    /// transfer function hides too few blocks for it to pay): the share of
    /// blocks it hides.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub skipping_left_out: Option<f32>,
    /// The edge of the blocks the CPU marchers skipped with (0: none, as
    /// on the GPU).
    #[serde(skip_serializing_if = "voxcast::render::stats::is_zero")]
    pub block_size: u32,
}

/// One method's row.
#[derive(Clone, Debug, Serialize)]
pub struct MethodResult {
    /// As given: `adaptive+grouped`.
    pub name: String,
    /// The marcher: `adaptive`.
    pub method: String,
    pub grouped: bool,
    /// True when the user's list lacked `uniform` and it was added as the
    /// baseline.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub added_as_baseline: bool,
    /// The setting `--quality` chose for it, and the pilot's evidence.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<crate::quality::QualityChoice>,
    /// The measurements; absent when the method failed.
    #[serde(flatten)]
    pub measured: Option<Measured>,
    /// Why the method failed to render, if it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// How the run was made.
#[derive(Clone, Debug, Serialize)]
pub struct RunInfo {
    pub repeat: usize,
    pub warmup: usize,
    /// Milliseconds to build the renderer's derived structures (once).
    pub setup_ms: f64,
    /// What the times measure.
    pub timer: &'static str,
    /// Where the methods were rendered (`cpu`, or the GPU adapter).
    pub device: String,
    /// The inner loop asked for (`--simd`: `auto`, `avx2`, `scalar`).
    pub simd: voxcast::render::Simd,
    pub voxcast_version: &'static str,
}

/// The result of [`run`](crate::run); serialises to the JSON of `voxcast bench --json`.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    pub scene: SceneInfo,
    pub machine: Machine,
    pub run: RunInfo,
    pub reference: ReferenceInfo,
    pub methods: Vec<MethodResult>,
    /// Things worth knowing (uniform added, duplicates dropped, cache trouble).
    pub notes: Vec<String>,
}

impl BenchReport {
    /// The methods that failed, with their errors.
    pub fn failures(&self) -> Vec<(&str, &str)> {
        self.methods
            .iter()
            .filter_map(|m| m.error.as_deref().map(|e| (m.name.as_str(), e)))
            .collect()
    }
}

fn finite_or_null<S: Serializer>(x: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if x.is_finite() {
        s.serialize_f64(*x)
    } else {
        s.serialize_none()
    }
}

/// A short name of an input for titles: `builtin:sphere` → `sphere`,
/// `…/teapot_ct/slices` → `teapot_ct/slices`.
pub fn input_label(input: &str) -> String {
    if let Some(n) = input.strip_prefix(BUILTIN_PREFIX) {
        return n.to_string();
    }
    let parts: Vec<String> = Path::new(input)
        .components()
        .filter_map(|c| match c {
            Component::Normal(s) => Some(s.to_string_lossy().into_owned()),
            _ => None,
        })
        .collect();
    let n = parts.len();
    if n == 0 {
        input.to_string()
    } else {
        parts[n.saturating_sub(2)..].join("/")
    }
}
