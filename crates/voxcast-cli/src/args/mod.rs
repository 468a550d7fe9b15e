//! Command-line arguments: [`Cli`] and its [`Command`]s, one file per
//! subcommand (its flags and its long help), and `scene.rs` for the flags
//! that define a scene, shared by the commands that render. Nothing here
//! runs a command: `cmd/` does.

mod animate;
mod bench;
mod bench_frames;
mod cloud;
mod compare;
mod convert;
mod device;
mod info;
mod render;
mod scene;
mod simulate;
mod view;

pub use animate::AnimateArgs;
#[cfg(feature = "mpi")]
pub use animate::MpiFrames;
pub use bench::BenchArgs;
pub use bench_frames::BenchFramesArgs;
pub use cloud::CloudArgs;
pub use compare::CompareArgs;
pub use convert::ConvertArgs;
pub use device::DeviceArg;
pub use info::InfoArgs;
pub use render::RenderArgs;
pub use scene::SceneArgs;
pub use simulate::{SimKind, SimulateArgs, SmokeArgs};
pub use view::ViewArgs;

use clap::{Parser, Subcommand};

const ABOUT: &str = "Volume rendering by ray casting: CT/MRI scans, smoke, clouds.";

const LONG_ABOUT: &str = "\
Volume rendering by ray casting: CT/MRI scans, smoke, clouds.

Start with `voxcast render` (renders the built-in demo to render.png), then
`voxcast render YOUR_VOLUME -o out.png`. Inputs: NRRD (.nrrd/.nhdr), MetaImage
(.mhd/.mha), legacy VTK (.vtk), NIfTI (.nii/.nii.gz), DICOM folders, folders or
globs of PNG/TIFF slices, OpenVDB (.vdb), FDS cases (.smv), Mitsuba grids
(.vol), WRF output (.nc, with --features wrf), frame folders (series.toml),
raw files with --raw-dims, and builtin:NAME.

Make volumes with `voxcast simulate smoke` (a fire in a room) and `voxcast
cloud` (S3 particle clouds); turn a series into a GIF or MP4 with `voxcast
animate`; measure methods with `voxcast bench` and `voxcast bench-frames`;
explore a volume or a series interactively with `voxcast view`.";

#[derive(Parser)]
#[command(name = "voxcast", version, about = ABOUT, long_about = LONG_ABOUT)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Render a volume (or the built-in demo) to a PNG/EXR image.
    #[command(after_long_help = render::RENDER_HELP)]
    Render(Box<RenderArgs>),
    /// Compare sampling methods on one scene: work, time, and error against a reference.
    #[command(after_long_help = bench::BENCH_HELP)]
    Bench(Box<BenchArgs>),
    /// Print a volume's dims, type, spacing, value range and histogram.
    Info(InfoArgs),
    /// Compare two images: PSNR (dB) and SSIM.
    Compare(CompareArgs),
    /// Write any volume (or a built-in one of any size) as an OME-Zarr multiscale pyramid.
    #[command(after_long_help = convert::CONVERT_HELP)]
    Convert(Box<ConvertArgs>),
    /// List transfer-function presets and built-in volumes.
    Presets,
    /// Simulate smoke (a fire in a room, office or corridor) into a frame folder.
    #[command(after_long_help = simulate::SIMULATE_HELP)]
    Simulate(SimulateArgs),
    /// Render every frame of a series (frame folder, FDS case, volume files) into a GIF, MP4 or PNGs.
    #[command(after_long_help = animate::ANIMATE_HELP)]
    Animate(Box<AnimateArgs>),
    /// Frame rate of each sampling method, frame by frame over a series, with PSNR per frame.
    #[command(after_long_help = bench_frames::BENCH_FRAMES_HELP)]
    BenchFrames(Box<BenchFramesArgs>),
    /// Simulate a cloud (S3 particle system) into a frame folder.
    #[command(after_long_help = cloud::CLOUD_HELP)]
    Cloud(Box<CloudArgs>),
    /// Explore a volume in a window: orbit, zoom, edit the transfer function, play a series.
    #[command(after_long_help = view::VIEW_HELP)]
    View(Box<ViewArgs>),
}
