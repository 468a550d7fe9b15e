//! `voxcast view`.

use super::device::{device_help, DeviceArg};
use super::scene::SceneArgs;
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;
use voxcast::scene::Scene;

pub const VIEW_HELP: &str = "\
A window with the volume on the left and the controls on the right:
  drag             orbit (the volume turns with the mouse)
  wheel            zoom
  shift-drag, right- or middle-drag   pan
  double-click     back to the scene's framing
While the view changes, frames are rendered at a reduced resolution sized to
keep about 20 frames per second; once it is still for 0.15 s, the full image
follows. The transfer-function editor shows the data's histogram (log counts)
over the window: click to add a point, drag to move it, right-click to remove
it; the colour bar below it works the same, and the selected colour point's
colour is picked under the editor. Series (frame folders from `voxcast
simulate`/`voxcast cloud`, FDS .smv, folders or globs of volume files) get a
time slider and play.

An OME-Zarr store opens at once at its coarsest level; finer levels are read
in the background and each replaces the one shown as it arrives (the stats bar
says which level is shown). A store whose level 0 is too large for memory
(--memory-budget) is drawn out of core on the CPU: each region at the level
its distance needs, refined as the chunks the view needs are read, nearest
and coarsest first. The view keeps turning meanwhile; no frame waits for a
read. --level N shows level N only.

`Save scene` writes a scene file that `voxcast render --scene FILE` renders to
the same image as the view (same camera, transfer function, method and
size); `screenshot` writes the view's pixels as PNG.

Scripted use (tests, pictures, measurements): with --screenshot and/or
--exit-after-frames the viewer waits until at least N frames are drawn and
the refined image is on screen, writes the screenshot (the window's pixels
cropped to the volume view) and --save-scene, and exits 0. --orbit S first
turns the camera for S seconds (30°/s) and reports the frame rate while
moving and the time to the refined image (--stats-json).

A display is needed; without one use a virtual one: `xvfb-run -a voxcast view …`
(software Vulkan: apt install mesa-vulkan-drivers xvfb xauth).

Examples:
  voxcast view ../shared/data/teapot_ct/slices --tf ct-bone
  voxcast view frames/                              # a simulated smoke series
  voxcast view --scene saved.toml                   # continue from a saved scene
  xvfb-run -a voxcast view ../shared/data/neghip/neghip.nhdr \\
      --screenshot shot.png --exit-after-frames 30 --save-scene shot.toml
  voxcast render --scene shot.toml -o same.png      # the same picture";

#[derive(Args)]
pub struct ViewArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Sampling method along rays (as for `voxcast render --method`; it can
    /// be changed in the window).
    #[arg(long, value_name = "METHOD", help_heading = "Ray casting")]
    pub method: Option<String>,
    /// Scripted: once the refined image is on screen, write the view's
    /// pixels (the window cropped to the volume view) as PNG and exit.
    #[arg(long, value_name = "FILE.png", help_heading = "Scripted use")]
    pub screenshot: Option<PathBuf>,
    /// Scripted: exit after at least N frames, once the refined image is on
    /// screen (after the screenshot, if one is asked for).
    #[arg(long, value_name = "N", help_heading = "Scripted use")]
    pub exit_after_frames: Option<u64>,
    /// Write the scene of what is on screen when a scripted run exits
    /// (`voxcast render --scene FILE` reproduces the view).
    #[arg(long, value_name = "FILE", help_heading = "Scripted use")]
    pub save_scene: Option<PathBuf>,
    /// Scripted measurement: turn the camera for this many seconds (30°/s),
    /// then wait for the refined image; reports frames per second while
    /// moving and the time to the refined image.
    #[arg(long, value_name = "SECONDS", help_heading = "Scripted use")]
    pub orbit: Option<f32>,
    /// Write what a scripted run measured as JSON.
    #[arg(long, value_name = "FILE", help_heading = "Scripted use")]
    pub stats_json: Option<PathBuf>,
    /// Which renderer draws the frames: auto (default), gpu or cpu (--help
    /// says which methods the GPU has).
    #[arg(long, value_enum, default_value = "auto", help_heading = "Device", long_help = device_help("Which renderer draws the frames (on the GPU, the methods it lacks and triangle meshes are drawn by the CPU, frame by frame). "))]
    pub device: DeviceArg,
    /// For an OME-Zarr store: the most decoded voxels held at once (e.g.
    /// 512MiB, 2GiB; default half the memory available). A store whose
    /// level 0 does not fit twice over is drawn out of core on the CPU,
    /// each region at the level it needs, refined as its chunks are read.
    #[arg(long, value_name = "BYTES", value_parser = parse_budget, help_heading = "Large volumes")]
    pub memory_budget: Option<u64>,
}

fn parse_budget(s: &str) -> std::result::Result<u64, String> {
    voxcast::render::outofcore::parse_bytes(s)
}

impl ViewArgs {
    /// The scene these flags imply; without --size or --scene the view is
    /// 800×600.
    pub fn scene(&self) -> Result<Scene> {
        let from_file = self.scene.scene.is_some();
        self.scene.scene_with(self.method.as_deref(), |scene| {
            if !from_file {
                scene.render.width = 800;
                scene.render.height = 600;
            }
        })
    }
}
