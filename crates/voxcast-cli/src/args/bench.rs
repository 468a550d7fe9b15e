//! `voxcast bench`.

use super::device::{device_help, DeviceArg, GpuFilterArg};
use super::scene::SceneArgs;
use clap::Args;
use std::path::PathBuf;

pub const BENCH_HELP: &str = "\
Every method renders the same volume, transfer function, camera and size with
one renderer; each is timed over --repeat renders after --warmup untimed ones
(methods interleaved). PSNR and SSIM are measured against a reference render:
uniform, step 1/16 voxel, no early ray termination, no empty-space skipping.
The reference is cached as EXR in $VOXCAST_CACHE (else $XDG_CACHE_HOME/voxcast,
else ~/.cache/voxcast), keyed by a hash of the scene and the voxels.
The table goes to stdout; PSNR is ∞ (JSON null, identical: true) when a
method's image equals the reference. Exit status 1 if any method fails.

Examples:
  voxcast bench ../shared/data/teapot_ct/slices --size 256x256
  voxcast bench builtin:demo --methods uniform,adaptive --repeat 3 --json b.json --chart b.png
  voxcast bench --scene saved.toml --markdown        # the README's table";

/// `voxcast bench`: the default `--methods`.
pub const DEFAULT_METHODS: &str = voxcast_bench::DEFAULT_METHODS;

#[derive(Args)]
pub struct BenchArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Methods to compare, comma-separated: uniform, adaptive, adaptive-s0,
    /// adaptive-max, threshold, jitter, stratified, mc, importance, each optionally +grouped and/or +noskip (empty-space skipping off). uniform (the baseline of the
    /// speed-ups) is added when missing.
    #[arg(long, value_name = "LIST", default_value = DEFAULT_METHODS)]
    pub methods: String,
    /// Timed renders per method (the median is reported).
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub repeat: usize,
    /// Untimed renders per method before the timed ones.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub warmup: usize,
    /// Write the report as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Draw time against PSNR, one point per method, as a PNG.
    #[arg(long, value_name = "FILE.png")]
    pub chart: Option<PathBuf>,
    /// Print the table as Markdown (for the README) instead of plain text.
    #[arg(long)]
    pub markdown: bool,
    /// Render the reference again even when it is cached (and update the cache).
    #[arg(long)]
    pub refresh_reference: bool,
    /// Time to quality instead of the table: for each method, the cheapest
    /// setting (step, and spp for stochastic methods) whose PSNR against the
    /// reference reaches DB, and its median time; speed-ups are against
    /// uniform at the same PSNR. Include single-scatter or path to compare
    /// spp against a --reference-spp render of that integrator. Several
    /// targets, comma-separated (40,45,50), share the reference and the
    /// ladders; one table each, and the JSON an array of reports.
    #[arg(long, value_name = "DB", value_delimiter = ',')]
    pub target_psnr: Vec<f64>,
    /// Compare the methods at equal quality: each renders with the setting a
    /// low-resolution pilot picks for it to reach DB dB PSNR against the
    /// reference (the step, adaptive's tolerance, threshold's steps, scaled
    /// together; early ray termination tightened so it cannot cap the PSNR);
    /// the table names each method's setting. See `voxcast render --quality`.
    #[arg(long, value_name = "DB", conflicts_with = "target_psnr")]
    pub quality: Option<f64>,
    /// With --target-psnr: also compare at equal time — for each method the
    /// highest PSNR among the settings it tried that rendered within
    /// SECONDS (default: the time uniform takes to reach the target).
    #[arg(long, value_name = "SECONDS", requires = "target_psnr")]
    pub time_budget: Option<f64>,
    /// Samples per pixel of the reference of single-scatter and path.
    #[arg(long, value_name = "N", default_value_t = 1024)]
    pub reference_spp: u32,
    /// No messages on stderr (the table still goes to stdout).
    #[arg(short, long)]
    pub quiet: bool,
    /// Where to render the methods: cpu, gpu or auto (the reference is always
    /// rendered on the CPU; --help says which methods the GPU has).
    #[arg(long, value_enum, default_value = "cpu", help_heading = "Device", long_help = device_help("Where to render the methods (the reference is always rendered on the CPU; under gpu, a method the GPU lacks is reported as failed in the table). "))]
    pub device: DeviceArg,
    /// How the GPU reconstructs a sample: auto (hardware on a hardware GPU,
    /// exact on a software one), exact (eight loads and the CPU's
    /// arithmetic) or hardware (the texture unit's trilinear filter with its
    /// 8-bit weights: 1.5–3.4× faster on an H100, PSNR within 0.2 dB).
    #[arg(long, value_enum, default_value = "auto", help_heading = "Device")]
    pub gpu_filter: GpuFilterArg,
}
