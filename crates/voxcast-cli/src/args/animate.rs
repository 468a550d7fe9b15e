//! `voxcast animate`.

use super::scene::SceneArgs;
use clap::Args;
use std::path::PathBuf;

pub const ANIMATE_HELP: &str = "\
INPUT is a series: a frame folder written by `voxcast simulate` (series.toml),
an FDS case (.smv: the soot SMOKE3D frames, or --var QUANTITY), or a folder or
glob of volume files (one frame each, sorted by name). Every selected frame is
rendered with the same scene (transfer function, camera, method, size); the
transfer function's window is fixed from the last selected frame (unless
--window is given) so that the animation does not flicker.

Output by name: out.gif (per-frame NeuQuant palette), out.mp4 (needs ffmpeg on
PATH: raw RGB frames are piped to it; without ffmpeg nothing is written and the
command fails), or DIR/ (frame_00000.png, …). Every file is written under a
temporary name and renamed at the end.

Examples:
  voxcast animate room/ -o room.gif --tf smoke --azimuth 30 --elevation 20
  voxcast animate ../shared/data/fds_room/room_smoke.smv -o fds.gif --every 2 --fps 12
  voxcast animate office/ -o office.mp4 --frames 100..400 --method adaptive+grouped
  voxcast animate office/ -o frames/ --size 256x256 --stats-json frames.json";

#[derive(Args)]
pub struct AnimateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output: FILE.gif, FILE.mp4 (needs ffmpeg) or a folder DIR/ for PNGs.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Sampling method (as for render: uniform, adaptive, adaptive-s0,
    /// adaptive-max, threshold; +grouped, +noskip).
    #[arg(long, value_name = "METHOD", help_heading = "Ray casting")]
    pub method: Option<String>,
    /// Frames per second of the GIF/MP4.
    #[arg(long, default_value_t = 10.0, help_heading = "Frames")]
    pub fps: f64,
    /// Take every N-th frame of the selection.
    #[arg(long, value_name = "N", default_value_t = 1, help_heading = "Frames")]
    pub every: usize,
    /// Frame range A..B (B excluded; A.., ..B and A..=B also work), frame indices from 0.
    #[arg(long, value_name = "A..B", help_heading = "Frames")]
    pub frames: Option<String>,
    /// Write per-frame statistics (time, render seconds, rays, samples) as JSON.
    #[arg(long, value_name = "FILE")]
    pub stats_json: Option<PathBuf>,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
    /// Under mpirun: how the frames are shared among the processes. Whole
    /// frames are spread over the processes, N at a time; the frames of a
    /// last, partial round may instead each be split over a group of
    /// processes and composited, so that no process idles. auto: a pilot
    /// render of one such frame, whole and split, decides (and is
    /// reported); spread: never split; split: always split them.
    #[cfg(feature = "mpi")]
    #[arg(long, value_enum, value_name = "HOW", default_value_t = MpiFrames::Auto, help_heading = "Frames")]
    pub mpi_frames: MpiFrames,
}

/// How `animate` shares the frames among MPI processes (`--mpi-frames`).
#[cfg(feature = "mpi")]
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MpiFrames {
    Auto,
    Spread,
    Split,
}
