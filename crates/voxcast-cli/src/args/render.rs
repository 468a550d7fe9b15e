//! `voxcast render`.

use super::device::{device_help, DeviceArg, GpuFilterArg};
use super::scene::SceneArgs;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use voxcast::scene::Scene;

pub const RENDER_HELP: &str = "\
Examples:
  voxcast render                                   # the built-in demo → render.png
  voxcast render ../shared/data/teapot_ct/slices -o teapot.png --azimuth 30 --elevation 20
  voxcast render ct_folder/ --tf ct-bone -o bone.png
  voxcast render vol.raw --raw-dims 256,256,128 --raw-type u16 --spacing 0.5,0.5,1
  voxcast render --scene saved.toml -o again.png   # reproduce a saved render
  voxcast render ../shared/data/fds_room/room_smoke.smv --time 30 --shadows on
                                                   # FDS soot over the room's obstructions
  voxcast render frames/ --geometry room.toml      # smoke over boxes, planes, OBJ meshes
  mpirun -np 8 voxcast render big.zarr -o big.png  # split over 8 processes, composited
                                                   # (build with --features mpi; docs/mpi.md)

Axes: at azimuth 0, elevation 0 the camera looks along +y with +x to the right
and +z up; positive azimuth orbits counter-clockwise seen from +z.";

#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output image (.png, or .exr for linear float).
    #[arg(short, long, value_name = "FILE")]
    pub output: Option<PathBuf>,
    /// Write the scene this command implies, to reproduce the image later.
    #[arg(long, value_name = "FILE")]
    pub save_scene: Option<PathBuf>,
    /// Also write the linear float image as OpenEXR.
    #[arg(long, value_name = "FILE.exr")]
    pub float_out: Option<PathBuf>,
    /// Write the render statistics as JSON (rays, samples, interpolations, seconds, …).
    #[arg(long, value_name = "FILE")]
    pub stats_json: Option<PathBuf>,
    /// No messages on stderr.
    #[arg(short, long)]
    pub quiet: bool,
    /// Sampling method along rays: uniform (equal steps), adaptive (S0's
    /// block-adaptive steps from what the transfer function shows: a step per
    /// block that keeps the change of classified opacity and colour per
    /// sample under [render.adaptive] tolerance, 0.3 by default),
    /// adaptive-s0 (S0 exactly: the step from the raw derivative at the
    /// block's midpoint and the distance), adaptive-max (S0's formula from the
    /// block's largest derivative) or
    /// threshold (Zeng 2018: the step follows the value's range); the
    /// Monte-Carlo marchers of S1 (use with --spp N): jitter (one random
    /// offset per ray), stratified (one random position per step), mc
    /// (uniformly random positions, S1 eq. 5–6), importance (S1 eq. 7: a
    /// step that grows in faint and shadowed blocks, from one random offset); the physically based
    /// integrators single-scatter (optical model 4: lights with shadows) and
    /// path (model 5: volumetric path tracing), which ignore the transfer
    /// function and use the medium options below; lod (S3: octree, empty
    /// subtrees skipped, every k-th uniform sample with k odd where a leaf
    /// contributes much, even where little); append
    /// +grouped for S0's grouped interpolation, +noskip to turn empty-space
    /// skipping off (e.g. adaptive+grouped). Parameters: [render.adaptive],
    /// [render.threshold] and [render.lod] in a scene file.
    #[arg(long, value_name = "METHOD", help_heading = "Ray casting")]
    pub method: Option<String>,
    /// Pick the sampling for a target image quality instead of --step: a
    /// PSNR in dB against a converged reference (30 rough, 40 good, 50 hard
    /// to tell apart). A low-resolution pilot (about 128×128, the same
    /// camera) renders the reference and searches one factor on every length
    /// the method samples with (the step, adaptive's tolerance, threshold's
    /// steps), then early ray termination is tightened so it cannot cap the
    /// PSNR. Says what it chose; --save-scene keeps the setting, so the
    /// pilot runs once. Not for single-scatter and path (use --spp).
    #[arg(long, value_name = "DB", help_heading = "Ray casting")]
    pub quality: Option<f64>,
    /// Where to render: cpu, gpu or auto (--help says which methods the GPU
    /// has).
    #[arg(long, value_enum, default_value = "cpu", help_heading = "Device", long_help = device_help(""))]
    pub device: DeviceArg,
    /// How the GPU reconstructs a sample: auto (hardware on a hardware GPU,
    /// exact on a software one), exact (eight loads and the CPU's
    /// arithmetic) or hardware (the texture unit's trilinear filter with its
    /// 8-bit weights: 1.5–3.4× faster on an H100, PSNR within 0.2 dB).
    #[arg(long, value_enum, default_value = "auto", help_heading = "Device")]
    pub gpu_filter: GpuFilterArg,
    /// For a chunked store (OME-Zarr): the most decoded voxels held at once
    /// (e.g. 512MiB, 2GiB; default half the memory available). A level that
    /// fits is read whole and rendered as usual; a larger one is rendered
    /// out of core, chunk by chunk, never holding more than this, each
    /// region at the coarsest level whose voxel is no larger than a pixel
    /// there (finer near the eye; `--level N` reads one level).
    #[arg(long, value_name = "BYTES", value_parser = parse_budget, help_heading = "Large volumes")]
    pub memory_budget: Option<u64>,
    /// Render a chunked store out of core even where its level fits the
    /// budget.
    #[arg(long, help_heading = "Large volumes")]
    pub out_of_core: bool,
    /// Under mpirun: tint each process's part of the volume with its own
    /// colour, to see how the volume was split (as ParaView colours by
    /// process).
    #[cfg(feature = "mpi")]
    #[arg(long, help_heading = "Large volumes")]
    pub show_parts: bool,
}

fn parse_budget(s: &str) -> Result<u64, String> {
    voxcast::render::outofcore::parse_bytes(s)
}

impl RenderArgs {
    /// The scene these flags imply.
    pub fn scene(&self) -> Result<Scene> {
        self.scene.scene_with(self.method.as_deref(), |_| {})
    }
}
