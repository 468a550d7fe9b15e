//! `voxcast bench`: sampling methods compared on one scene.
//!
//! Every method renders the same volume, transfer function, camera and image
//! size through one [`Renderer`] (its derived structures are built once, so
//! the times measure rendering, not set-up). For each method the report gives
//! the work done (samples, trilinear interpolations), the wall-clock time of
//! `repeat` renders after `warmup` untimed ones (median, min, max), the
//! speed-up over `uniform`, and the error against a **reference render**:
//! PSNR and SSIM ([`crate::metrics`]) against the same scene rendered with
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
//! Times are wall-clock milliseconds measured with [`Instant`] around
//! [`Renderer::render`] (which includes baking the transfer-function table
//! and fitting the camera, both negligible). Renders of the methods are
//! interleaved round by round, so a slow spell of a shared machine spreads
//! over all methods instead of penalising one.

use crate::error::{Error, Result};
use crate::files::write_file;
use crate::image::Image;
use crate::metrics;
use crate::render::{Method, MethodSpec, RenderParams, RenderStats, Renderer};
use crate::scene::{Prepared, Scene, BUILTIN_PREFIX};
use crate::volume::{Volume, VoxelData};
use rayon::prelude::*;
use serde::{Deserialize, Serialize, Serializer};
use std::path::{Component, Path, PathBuf};
use std::time::Instant;

/// Step of the reference render, in voxels.
pub const REFERENCE_STEP: f32 = 1.0 / 16.0;

/// The methods compared when none are named.
pub const DEFAULT_METHODS: &str = "uniform,adaptive,adaptive+grouped,threshold";

/// Bumped whenever the reference's definition or its cache format changes,
/// so that old cache entries are not reused.
const REFERENCE_FORMAT: &str = "voxcast-bench-reference 1";

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
}

impl Default for BenchConfig {
    fn default() -> Self {
        BenchConfig {
            methods: default_methods(),
            repeat: 5,
            warmup: 1,
            cache_dir: Some(default_cache_dir()),
            refresh_reference: false,
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

/// The render parameters of the reference: `base` (the scene's) with the
/// uniform marcher at [`REFERENCE_STEP`], early ray termination off, no
/// empty-space skipping, no jitter, no grouping. Everything else (size,
/// optical model, order, shading, background, seed) is the scene's.
pub fn reference_params(base: &RenderParams) -> RenderParams {
    let mut p = base.clone();
    p.method = Method::Uniform;
    p.grouped = false;
    p.step = REFERENCE_STEP;
    p.ert = 1.0;
    p.skip_empty = false;
    p.jitter = false;
    // Parameters of the other marchers do not shape the reference.
    p.adaptive = Default::default();
    p.threshold = Default::default();
    p.block_size = RenderParams::default().block_size;
    p
}

/// The parameters `spec` renders with: the scene's, with its method and
/// modifiers replaced.
pub fn method_params(base: &RenderParams, spec: &MethodSpec) -> RenderParams {
    let mut p = base.clone();
    spec.apply(&mut p);
    p
}

/// FNV-1a, 64 bit: small and stable across Rust releases and platforms
/// (unlike `DefaultHasher`), which a cache key on disk needs.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Fnv1a {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    pub fn new() -> Fnv1a {
        Fnv1a(Self::OFFSET)
    }

    pub fn write(&mut self, bytes: &[u8]) {
        let mut h = self.0;
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(Self::PRIME);
        }
        self.0 = h;
    }

    /// Writes a length-prefixed field, so that `("ab", "c")` and `("a", "bc")`
    /// hash differently.
    pub fn field(&mut self, bytes: &[u8]) {
        self.write(&(bytes.len() as u64).to_le_bytes());
        self.write(bytes);
    }

    pub fn finish(&self) -> u64 {
        self.0
    }
}

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a::new()
    }
}

/// FNV-1a 64 of `bytes`.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h = Fnv1a::new();
    h.write(bytes);
    h.finish()
}

/// Voxels per chunk of the content hash (fixed: the hash must not depend on
/// the number of threads).
const HASH_CHUNK: usize = 1 << 20;

/// A stable hash of a volume's voxels (little-endian bytes), computed per
/// chunk in parallel and combined in order.
fn voxel_hash(data: &VoxelData) -> u64 {
    fn chunks<T: Copy + Sync, const N: usize>(v: &[T], bytes: impl Fn(T) -> [u8; N] + Sync) -> u64 {
        let parts: Vec<u64> = v
            .par_chunks(HASH_CHUNK)
            .map(|c| {
                let mut h = Fnv1a::new();
                for &x in c {
                    h.write(&bytes(x));
                }
                h.finish()
            })
            .collect();
        let mut h = Fnv1a::new();
        h.write(&(v.len() as u64).to_le_bytes());
        for p in parts {
            h.write(&p.to_le_bytes());
        }
        h.finish()
    }
    match data {
        VoxelData::U8(v) => {
            // One byte per voxel: hash the bytes directly.
            chunks(v, |x| [x])
        }
        VoxelData::U16(v) => chunks(v, u16::to_le_bytes),
        VoxelData::I16(v) => chunks(v, i16::to_le_bytes),
        VoxelData::F32(v) => chunks(v, |x: f32| x.to_bits().to_le_bytes()),
    }
}

/// The cache key of the reference render of `scene`: an FNV-1a 64 hash of
/// the reference scene resolved against `prepared` (transfer function inline,
/// window fixed) as TOML — without the input's path, which does not change
/// the picture — and of the volume itself (type, dims, spacing, origin and
/// every voxel), so that an edited file, a detached data file, a slice added
/// to a folder or a changed raw layout all give a new key, while the same
/// data under another path or a touched file do not. The scene's own method,
/// step and termination do not enter: the reference replaces them.
pub fn reference_key(scene: &Scene, prepared: &Prepared) -> u64 {
    let mut s = scene.resolved(prepared);
    s.render = reference_params(&s.render);
    s.input.path.clear();
    let toml = toml::to_string(&s).unwrap_or_else(|e| format!("unserialisable scene: {e}"));
    let mut h = Fnv1a::new();
    h.field(REFERENCE_FORMAT.as_bytes());
    h.field(env!("CARGO_PKG_VERSION").as_bytes());
    h.field(toml.as_bytes());
    let v: &Volume = &prepared.volume;
    h.field(v.scalar_type().name().as_bytes());
    for d in v.dims() {
        h.write(&(d as u64).to_le_bytes());
    }
    for x in v
        .spacing()
        .to_array()
        .into_iter()
        .chain(v.origin().to_array())
    {
        h.write(&x.to_bits().to_le_bytes());
    }
    h.write(&voxel_hash(v.data()).to_le_bytes());
    // Geometry found through the input's path is not in the scene's TOML.
    if let Some(g) = &prepared.geometry {
        h.write(&g.fingerprint().to_le_bytes());
    }
    h.finish()
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
    pub os: &'static str,
    pub arch: &'static str,
}

impl Machine {
    pub fn this() -> Machine {
        Machine {
            threads: rayon::current_num_threads(),
            cpu: cpu_model(),
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
    /// Step in voxels ([`REFERENCE_STEP`]).
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
    /// The cache key, 16 hex digits ([`reference_key`]).
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
    pub voxcast_version: &'static str,
}

/// The result of [`run`]; serialises to the JSON of `voxcast bench --json`.
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

/// What the cache stores beside the EXR.
#[derive(Serialize, Deserialize)]
struct CacheMeta {
    key: String,
    format: String,
    ms: f64,
    stats: RenderStats,
    /// The reference scene, for a person reading the cache.
    scene: String,
}

fn cache_paths(dir: &Path, key: u64) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("reference-{key:016x}.exr")),
        dir.join(format!("reference-{key:016x}.json")),
    )
}

/// Reads a cached reference; `None` when absent or unusable.
fn load_cached(dir: &Path, key: u64, width: u32, height: u32) -> Option<(Image, CacheMeta)> {
    let (exr, json) = cache_paths(dir, key);
    let meta: CacheMeta = serde_json::from_str(&std::fs::read_to_string(json).ok()?).ok()?;
    if meta.key != format!("{key:016x}") || meta.format != REFERENCE_FORMAT {
        return None;
    }
    let img = Image::read(&exr).ok()?;
    ((img.width, img.height) == (width, height)).then_some((img, meta))
}

fn store_cached(dir: &Path, key: u64, img: &Image, meta: &CacheMeta) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (exr, json) = cache_paths(dir, key);
    img.write_exr(&exr)?;
    let text = serde_json::to_string_pretty(meta)
        .map_err(|e| Error::invalid(format!("cache metadata: {e}")))?;
    write_file(&json, |w| {
        use std::io::Write;
        writeln!(w, "{text}")
    })?;
    Ok(exr)
}

struct Slot {
    spec: MethodSpec,
    added: bool,
    params: RenderParams,
    times: Vec<f64>,
    stats: Option<RenderStats>,
    /// PSNR and SSIM of the first image against the reference (each image
    /// is compared as soon as it exists, so none is kept).
    error_metrics: Option<(f64, f64)>,
    error: Option<String>,
}

/// Renders every method of `config` on `scene` (already loaded as
/// `prepared`), the reference (or reads it from the cache), and compares.
/// `progress` is called after every tile of every render, from the render's
/// threads.
///
/// Invalid parameters fail before anything renders. A method whose render
/// fails is reported with its error and the others still run; the baseline
/// `uniform` failing fails the run.
pub fn run(
    scene: &Scene,
    prepared: &Prepared,
    config: &BenchConfig,
    progress: &(dyn Fn(&Progress<'_>) + Sync),
) -> Result<BenchReport> {
    run_on(scene, prepared, config, progress, None)
}

/// A back end that renders the methods under test in place of the CPU
/// [`Renderer`] (the GPU renderer of `voxcast-gpu`); the reference is always
/// the CPU's, so the PSNR column also measures the back end's parity.
pub trait MethodRenderer: Sync {
    /// Renders the prepared scene's volume with `params` (and the scene's
    /// transfer function and camera).
    fn render(&self, params: &RenderParams) -> Result<(Image, RenderStats)>;
    /// The device in words, for the report.
    fn device(&self) -> String;
}

/// [`run`] with the methods rendered by `methods_on` (`None`: the CPU).
pub fn run_on(
    scene: &Scene,
    prepared: &Prepared,
    config: &BenchConfig,
    progress: &(dyn Fn(&Progress<'_>) + Sync),
    methods_on: Option<&dyn MethodRenderer>,
) -> Result<BenchReport> {
    if config.repeat == 0 {
        return Err(Error::invalid("repeat must be at least 1"));
    }
    if config.methods.is_empty() {
        return Err(Error::invalid("no method to measure"));
    }
    let mut notes = Vec::new();
    let baseline = MethodSpec {
        method: Method::Uniform,
        grouped: false,
        no_skip: false,
    };
    let mut specs: Vec<(MethodSpec, bool)> = Vec::new();
    for s in &config.methods {
        if specs.iter().any(|(t, _)| t == s) {
            notes.push(format!("`{s}` was named twice; it is measured once"));
        } else {
            specs.push((*s, false));
        }
    }
    if !specs.iter().any(|(s, _)| *s == baseline) {
        specs.insert(0, (baseline, true));
        notes.push("`uniform` was added: it is the baseline of the speed-ups".into());
    }
    let mut slots = Vec::with_capacity(specs.len());
    for (spec, added) in specs {
        let params = method_params(&scene.render, &spec);
        params
            .validate()
            .map_err(|e| Error::invalid(format!("method `{spec}`: {e}")))?;
        slots.push(Slot {
            spec,
            added,
            params,
            times: Vec::new(),
            stats: None,
            error_metrics: None,
            error: None,
        });
    }
    let ref_params = reference_params(&scene.render);
    ref_params.validate()?;

    let t = Instant::now();
    let renderer =
        Renderer::new(&prepared.volume, prepared.window)?.with_geometry(prepared.geometry.clone());
    let setup_ms = t.elapsed().as_secs_f64() * 1e3;

    let key = reference_key(scene, prepared);
    let cached = match &config.cache_dir {
        Some(dir) if !config.refresh_reference => {
            load_cached(dir, key, ref_params.width, ref_params.height)
        }
        _ => None,
    };
    let renders = usize::from(cached.is_none()) + slots.len() * (config.warmup + config.repeat);
    let render_one = |index: usize, task: &str, params: &RenderParams| {
        let tick = |done: usize, total: usize| {
            progress(&Progress {
                task,
                render: index,
                renders,
                done,
                total,
            })
        };
        let t = Instant::now();
        let r = renderer.render(&prepared.tf, &scene.camera, params, &tick);
        let ms = t.elapsed().as_secs_f64() * 1e3;
        r.map(|(img, stats)| (img, stats, ms))
    };
    let render_method = |index: usize, task: &str, params: &RenderParams| match methods_on {
        None => render_one(index, task, params),
        Some(m) => {
            let t = Instant::now();
            let r = m.render(params);
            let ms = t.elapsed().as_secs_f64() * 1e3;
            progress(&Progress {
                task,
                render: index,
                renders,
                done: 1,
                total: 1,
            });
            r.map(|(img, stats)| (img, stats, ms))
        }
    };
    if let Some(m) = methods_on {
        notes.push(format!(
            "methods rendered on {}; the reference on the CPU",
            m.device()
        ));
    }
    let mut index = 0usize;

    // The reference.
    let (ref_image, ref_ms, ref_stats, cache, cache_file) = match cached {
        Some((img, meta)) => (
            img,
            meta.ms,
            meta.stats,
            CacheStatus::Hit,
            config.cache_dir.as_ref().map(|d| cache_paths(d, key).0),
        ),
        None => {
            let (img, stats, ms) = render_one(index, "reference", &ref_params)
                .map_err(|e| Error::invalid(format!("reference render: {e}")))?;
            index += 1;
            let (cache, file) = match &config.cache_dir {
                Some(dir) => {
                    let mut s = scene.resolved(prepared);
                    s.render = ref_params.clone();
                    let meta = CacheMeta {
                        key: format!("{key:016x}"),
                        format: REFERENCE_FORMAT.into(),
                        ms,
                        stats,
                        scene: toml::to_string(&s).unwrap_or_default(),
                    };
                    match store_cached(dir, key, &img, &meta) {
                        Ok(f) if config.refresh_reference => (CacheStatus::Refreshed, Some(f)),
                        Ok(f) => (CacheStatus::Miss, Some(f)),
                        Err(e) => {
                            notes.push(format!("the reference could not be cached: {e}"));
                            (CacheStatus::Off, None)
                        }
                    }
                }
                None => (CacheStatus::Off, None),
            };
            (img, ms, stats, cache, file)
        }
    };

    // Warm-up, then the timed rounds, methods interleaved.
    let rounds = (0..config.warmup)
        .map(|_| None)
        .chain((0..config.repeat).map(Some));
    for round in rounds {
        for slot in slots.iter_mut() {
            if slot.error.is_some() {
                index += 1;
                continue;
            }
            let task = match round {
                None => format!("{} (warm-up)", slot.spec),
                Some(r) => format!("{} {}/{}", slot.spec, r + 1, config.repeat),
            };
            let result = render_method(index, &task, &slot.params);
            index += 1;
            match result {
                Ok((img, stats, ms)) => {
                    if round.is_some() {
                        slot.times.push(ms);
                    }
                    if slot.error_metrics.is_none() {
                        let psnr = metrics::psnr(&img, &ref_image)?;
                        let ssim = metrics::ssim(&img, &ref_image)?;
                        slot.error_metrics = Some((psnr, ssim));
                        slot.stats = Some(stats);
                    }
                }
                Err(e) => {
                    if slot.spec == baseline {
                        return Err(Error::invalid(format!("method `uniform`: {e}")));
                    }
                    slot.error = Some(e.to_string());
                    slot.error_metrics = None;
                    slot.stats = None;
                }
            }
        }
    }

    let base = slots
        .iter()
        .find(|s| s.spec == baseline)
        .expect("the baseline is in the list");
    let base_ms = median(&base.times);
    let base_stats = base.stats.expect("the baseline rendered");
    let ratio = |a: u64, b: u64| if b > 0 { a as f64 / b as f64 } else { f64::NAN };
    let mut methods = Vec::with_capacity(slots.len());
    for slot in &slots {
        let measured = match (slot.error_metrics, &slot.stats, &slot.error) {
            (Some((psnr, ssim)), Some(st), None) => {
                let ms_median = median(&slot.times);
                Some(Measured {
                    samples: st.samples,
                    interpolations: st.interpolations,
                    gradient_interpolations: st.gradient_interpolations,
                    rays: st.rays,
                    rays_hit: st.rays_hit,
                    early_terminated: st.early_terminated,
                    ms_median,
                    ms_min: slot.times.iter().copied().fold(f64::INFINITY, f64::min),
                    ms_max: slot.times.iter().copied().fold(0.0, f64::max),
                    ms_per_repeat: slot.times.clone(),
                    speedup_vs_uniform: base_ms / ms_median,
                    samples_vs_uniform: ratio(st.samples, base_stats.samples),
                    interpolations_vs_uniform: ratio(st.interpolations, base_stats.interpolations),
                    psnr_db: psnr,
                    identical: psnr.is_infinite(),
                    ssim,
                })
            }
            _ => None,
        };
        methods.push(MethodResult {
            name: slot.spec.to_string(),
            method: slot.spec.method.name().to_string(),
            grouped: slot.spec.grouped,
            added_as_baseline: slot.added,
            measured,
            error: slot.error.clone(),
        });
    }

    let v = &prepared.volume;
    let r = &scene.render;
    Ok(BenchReport {
        scene: SceneInfo {
            input: scene.input.path.clone(),
            label: input_label(&scene.input.path),
            dims: v.dims(),
            scalar_type: v.scalar_type().name().to_string(),
            width: r.width,
            height: r.height,
            tf: if scene.transfer.map.is_some() {
                "inline".into()
            } else {
                scene.transfer.tf.clone()
            },
            window: prepared.window,
            step: r.step,
            ert: r.ert,
            shading: r.shading,
            skip_empty: r.skip_empty,
            jitter: r.jitter,
            azimuth: scene.camera.azimuth,
            elevation: scene.camera.elevation,
            zoom: scene.camera.zoom,
        },
        machine: Machine::this(),
        run: RunInfo {
            repeat: config.repeat,
            warmup: config.warmup,
            setup_ms,
            timer: if methods_on.is_some() {
                "wall-clock ms around the back end's render (upload of the camera and transfer function, compute, read-back), renderer built once"
            } else {
                "wall-clock ms around Renderer::render, renderer built once"
            },
            device: methods_on.map_or_else(|| "cpu".to_string(), |m| m.device()),
            voxcast_version: env!("CARGO_PKG_VERSION"),
        },
        reference: ReferenceInfo {
            method: ref_params.method.name().into(),
            step: ref_params.step,
            ert: ref_params.ert,
            skip_empty: ref_params.skip_empty,
            jitter: ref_params.jitter,
            grouped: ref_params.grouped,
            ms: ref_ms,
            samples: ref_stats.samples,
            interpolations: ref_stats.interpolations,
            rays: ref_stats.rays,
            cache,
            cache_file,
            key: format!("{key:016x}"),
        },
        methods,
        notes,
    })
}

/// `1234567` → `1,234,567`.
fn grouped_int(n: u64) -> String {
    let s = n.to_string();
    // The leading group has 1 to 3 digits, every later one 3.
    let (head, rest) = s.split_at((s.len() - 1) % 3 + 1);
    let mut out = head.to_string();
    for group in rest.as_bytes().chunks(3) {
        out.push(',');
        out.push_str(std::str::from_utf8(group).expect("ASCII digits"));
    }
    out
}

fn fmt_ms(ms: f64) -> String {
    if ms >= 100.0 {
        format!("{ms:.0}")
    } else if ms >= 10.0 {
        format!("{ms:.1}")
    } else {
        format!("{ms:.2}")
    }
}

fn fmt_psnr(m: &Measured) -> String {
    if m.psnr_db.is_finite() {
        format!("{:.2}", m.psnr_db)
    } else {
        "∞".into()
    }
}

const HEADER: [&str; 7] = [
    "method",
    "samples",
    "interpolations",
    "ms (median [min–max])",
    "speed-up",
    "PSNR dB",
    "SSIM",
];

/// The table's cells, one row per method.
fn rows(report: &BenchReport) -> Vec<[String; 7]> {
    report
        .methods
        .iter()
        .map(|m| match &m.measured {
            Some(x) => [
                m.name.clone(),
                grouped_int(x.samples),
                grouped_int(x.interpolations),
                format!(
                    "{} [{}–{}]",
                    fmt_ms(x.ms_median),
                    fmt_ms(x.ms_min),
                    fmt_ms(x.ms_max)
                ),
                format!("{:.2}×", x.speedup_vs_uniform),
                fmt_psnr(x),
                format!("{:.4}", x.ssim),
            ],
            None => [
                m.name.clone(),
                format!("failed: {}", m.error.as_deref().unwrap_or("no measurement")),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
            ],
        })
        .collect()
}

/// The lines that say what was measured where.
fn preamble(r: &BenchReport) -> Vec<String> {
    let s = &r.scene;
    let onoff = |b: bool| if b { "on" } else { "off" };
    let ert = if s.ert >= 1.0 {
        "off".to_string()
    } else {
        format!("{}", s.ert)
    };
    let mut machine = format!("{} rayon threads", r.machine.threads);
    if let Some(cpu) = &r.machine.cpu {
        machine.push_str(&format!(", {cpu}"));
    }
    let reference = &r.reference;
    vec![
        format!(
            "Scene: {} ({}×{}×{} {}), {}×{} image, tf {} (window {} … {}), step {} voxel, ERT {}, shading {}, empty-space skipping {}.",
            s.input,
            s.dims[0],
            s.dims[1],
            s.dims[2],
            s.scalar_type,
            s.width,
            s.height,
            s.tf,
            s.window[0],
            s.window[1],
            s.step,
            ert,
            onoff(s.shading),
            onoff(s.skip_empty)
        ),
        format!(
            "Machine: {machine}; median of {} timed renders after {} warm-up, voxcast {}.",
            r.run.repeat, r.run.warmup, r.run.voxcast_version
        ),
        format!(
            "Reference: uniform, step 1/{} voxel, ERT off, no empty-space skipping ({} samples, {} ms, cache {}).",
            (1.0 / reference.step).round(),
            grouped_int(reference.samples),
            fmt_ms(reference.ms),
            match reference.cache {
                CacheStatus::Hit => "hit",
                CacheStatus::Miss => "miss",
                CacheStatus::Refreshed => "refreshed",
                CacheStatus::Off => "off",
            }
        ),
    ]
}

/// The report as a Markdown table (for the README), with the scene, the
/// machine and the reference stated above it.
pub fn markdown(report: &BenchReport) -> String {
    let mut out = String::new();
    for l in preamble(report) {
        out.push_str(&l);
        out.push_str("\n\n");
    }
    out.push_str(&format!("| {} |\n", HEADER.join(" | ")));
    out.push_str("|---|---:|---:|---:|---:|---:|---:|\n");
    for row in rows(report) {
        let cells: Vec<String> = row.iter().map(|c| c.replace('|', "\\|")).collect();
        out.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    for n in &report.notes {
        out.push_str(&format!("\nNote: {n}\n"));
    }
    out
}

/// The report as an aligned plain-text table.
pub fn text_table(report: &BenchReport) -> String {
    let rows = rows(report);
    let width = |i: usize| {
        rows.iter()
            .filter(|r| r[2].chars().count() > 0 || i == 0)
            .map(|r| r[i].chars().count())
            .chain([HEADER[i].chars().count()])
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..7).map(width).collect();
    let line = |cells: &[String]| {
        let mut s = String::new();
        for (i, c) in cells.iter().enumerate() {
            let pad = widths[i].saturating_sub(c.chars().count());
            if i > 0 {
                s.push_str("  ");
            }
            if i == 0 {
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            } else {
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            }
        }
        s.trim_end().to_string()
    };
    let mut out = String::new();
    for l in preamble(report) {
        out.push_str(&l);
        out.push('\n');
    }
    out.push('\n');
    let header: Vec<String> = HEADER.iter().map(|h| h.to_string()).collect();
    out.push_str(&line(&header));
    out.push('\n');
    for row in &rows {
        if row[2].is_empty() {
            // A failed method: name, then the message.
            out.push_str(&format!("{:w$}  {}\n", row[0], row[1], w = widths[0]));
        } else {
            out.push_str(&line(row));
            out.push('\n');
        }
    }
    for n in &report.notes {
        out.push_str(&format!("note: {n}\n"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        // From the FNV reference (Fowler, Noll, Vo): these values must never
        // change, or every cached reference would silently be orphaned.
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
        // Streaming equals one shot.
        let mut h = Fnv1a::new();
        h.write(b"foo");
        h.write(b"bar");
        assert_eq!(h.finish(), fnv1a64(b"foobar"));
        // Length-prefixed fields keep boundaries apart.
        let field2 = |a: &[u8], b: &[u8]| {
            let mut h = Fnv1a::new();
            h.field(a);
            h.field(b);
            h.finish()
        };
        assert_ne!(field2(b"ab", b"c"), field2(b"a", b"bc"));
    }

    #[test]
    fn voxel_hash_is_chunking_independent_of_threads_and_sees_every_voxel() {
        let n = HASH_CHUNK * 2 + 17;
        let a = VoxelData::U16((0..n).map(|i| (i * 7 % 65_521) as u16).collect());
        let h1 = voxel_hash(&a);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(pool.install(|| voxel_hash(&a)), h1);
        let VoxelData::U16(mut v) = a else {
            unreachable!()
        };
        v[n - 1] ^= 1;
        assert_ne!(voxel_hash(&VoxelData::U16(v)), h1);
        // The same bytes as another type differ (the type is in the key, but
        // the data alone differs too in length).
        let b = VoxelData::U8(vec![1, 2, 3]);
        assert_ne!(voxel_hash(&b), voxel_hash(&VoxelData::U8(vec![1, 2, 4])));
    }

    #[test]
    fn reference_key_depends_on_what_shapes_the_reference_only() {
        let mut scene = Scene::default();
        scene.input.path = "builtin:sphere".into();
        scene.render.width = 32;
        scene.render.height = 24;
        let prepared = scene.prepare().unwrap();
        let k = reference_key(&scene, &prepared);
        // Stable: the same inputs give the same key, every time.
        assert_eq!(k, reference_key(&scene.clone(), &scene.prepare().unwrap()));
        // What the reference replaces does not count.
        let mut s = scene.clone();
        s.render.step = 0.9;
        s.render.ert = 0.5;
        s.render.method = Method::Threshold;
        s.render.grouped = true;
        s.render.jitter = true;
        s.render.skip_empty = false;
        assert_eq!(reference_key(&s, &prepared), k);
        // Nor the input's path when the data are the same.
        let mut s = scene.clone();
        s.input.path = "elsewhere/sphere.nrrd".into();
        assert_eq!(reference_key(&s, &prepared), k);
        // What shapes the picture does.
        let mut s = scene.clone();
        s.camera.azimuth = 10.0;
        assert_ne!(reference_key(&s, &prepared), k);
        let mut s = scene.clone();
        s.render.width = 33;
        assert_ne!(reference_key(&s, &prepared), k);
        let mut s = scene.clone();
        s.transfer.window = Some([0.1, 0.9]);
        let p = s.prepare().unwrap();
        assert_ne!(reference_key(&s, &p), k);
        // And so does one voxel.
        let v = &prepared.volume;
        let mut data: Vec<f32> = (0..v.len()).map(|i| v.data().get(i)).collect();
        data[v.len() / 2] += 0.25;
        let edited = Volume::new(v.dims(), v.spacing(), v.origin(), VoxelData::F32(data)).unwrap();
        let p = Prepared {
            volume: edited,
            tf: prepared.tf.clone(),
            window: prepared.window,
            geometry: None,
        };
        assert_ne!(reference_key(&scene, &p), k);
    }

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

    #[test]
    fn labels_and_numbers() {
        assert_eq!(input_label("builtin:demo"), "demo");
        assert_eq!(
            input_label("../shared/data/teapot_ct/slices"),
            "teapot_ct/slices"
        );
        assert_eq!(input_label("vol.nrrd"), "vol.nrrd");
        assert_eq!(grouped_int(0), "0");
        assert_eq!(grouped_int(999), "999");
        assert_eq!(grouped_int(1000), "1,000");
        assert_eq!(grouped_int(28_901_234), "28,901,234");
    }

    #[test]
    fn run_measures_every_method_and_caches_the_reference() {
        let dir = tempfile::tempdir().unwrap();
        let mut scene = Scene::default();
        scene.input.path = "builtin:sphere".into();
        scene.render.width = 24;
        scene.render.height = 16;
        let prepared = scene.prepare().unwrap();
        let config = BenchConfig {
            methods: parse_methods("adaptive,uniform+grouped").unwrap(),
            repeat: 2,
            warmup: 0,
            cache_dir: Some(dir.path().to_path_buf()),
            refresh_reference: false,
        };
        let calls = std::sync::atomic::AtomicUsize::new(0);
        let last = std::sync::Mutex::new((0, 0));
        let progress = |p: &Progress<'_>| {
            calls.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            assert!(p.render < p.renders && p.done <= p.total);
            *last.lock().unwrap() = (p.render, p.renders);
        };
        let r = run(&scene, &prepared, &config, &progress).unwrap();
        // uniform added first as the baseline, then the two named.
        let names: Vec<&str> = r.methods.iter().map(|m| m.name.as_str()).collect();
        assert_eq!(names[0], "uniform");
        assert!(r.methods[0].added_as_baseline);
        assert_eq!(names.len(), 3);
        assert!(!r.notes.is_empty());
        assert_eq!(r.reference.cache, CacheStatus::Miss);
        assert!(calls.into_inner() > 0);
        // 1 reference + 3 methods × 2 timed renders; the last is the last.
        assert_eq!(*last.lock().unwrap(), (6, 7));
        let u = r.methods[0].measured.as_ref().unwrap();
        assert_eq!(u.speedup_vs_uniform, 1.0);
        assert_eq!(u.ms_per_repeat.len(), 2);
        assert!(u.ms_min <= u.ms_median && u.ms_median <= u.ms_max);
        assert!(u.samples > 0 && u.psnr_db > 20.0 && u.ssim > 0.5);
        // The second run reads the reference back, bit for bit.
        let again = run(&scene, &prepared, &config, &|_| {}).unwrap();
        assert_eq!(again.reference.cache, CacheStatus::Hit);
        assert_eq!(again.reference.samples, r.reference.samples);
        let u2 = again.methods[0].measured.as_ref().unwrap();
        assert_eq!(u2.psnr_db, u.psnr_db);
        let md = markdown(&again);
        assert!(md.contains("| method | samples |"), "{md}");
        assert!(text_table(&again).contains("speed-up"));
        let json = serde_json::to_value(&again).unwrap();
        assert!(json["methods"][0]["psnr_db"].is_number());
    }
}
