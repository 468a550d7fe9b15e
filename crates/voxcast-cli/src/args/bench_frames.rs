//! `voxcast bench-frames`.

use super::scene::SceneArgs;
use clap::Args;
use std::path::PathBuf;

pub const BENCH_FRAMES_HELP: &str = "\
Each selected frame of the series is loaded, its converged reference rendered
(uniform at 1/16 voxel, no early termination, no empty-space skipping), then
every method rendered --repeat times (methods interleaved, after one untimed
render each; the fastest render counts, since other load on the machine only
ever adds time). The table gives per frame each method's time, frame rate
and PSNR against the reference, then per method the mean frame rate and the
speed-up over uniform (mean of the per-frame ratios, min–max). The transfer
function's window is fixed from the last selected frame.

Examples:
  voxcast bench-frames ../shared/data/fds_room/room_smoke.smv --every 10 --size 256x256 --tf smoke
  voxcast bench-frames office/ --every 50 --markdown --chart fps.png --json fps.json";

#[derive(Args)]
pub struct BenchFramesArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Methods, comma-separated (uniform is added first when missing: the baseline).
    #[arg(
        long,
        value_name = "LIST",
        default_value = "uniform,threshold,adaptive+grouped"
    )]
    pub methods: String,
    /// Take every N-th frame of the selection.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub every: usize,
    /// Frame range A..B (B excluded; A.., ..B, A..=B).
    #[arg(long, value_name = "A..B")]
    pub frames: Option<String>,
    /// Timed renders per method and frame (the fastest counts).
    #[arg(long, value_name = "N", default_value_t = 3)]
    pub repeat: usize,
    /// Write the report as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Draw frame rate against frame, one line per method, as a PNG.
    #[arg(long, value_name = "FILE.png")]
    pub chart: Option<PathBuf>,
    /// Print the table as Markdown.
    #[arg(long)]
    pub markdown: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}
