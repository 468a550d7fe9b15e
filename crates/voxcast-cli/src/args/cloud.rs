//! `voxcast cloud`.

use clap::Args;
use std::path::PathBuf;

pub const CLOUD_HELP: &str = "\
The cloud is a particle system (paper S3): puffs (centre, radius) are filled
frame by frame with particles — N_frame + rand·N_max candidates per frame,
each kept only inside its puff's sphere — until the cloud saturates; it then
changes slowly (dead particles replaced, at most N_min new ones a frame) and
finally dissipates, N_ext·rand particles a frame removed from the thin edge
towards the dense core. The particles are splatted into a density grid
(values 0…1, z up) with a smooth kernel, and fBm + Worley noise erodes the
edges into wisps.

--frames 1 (the default) writes the cloud at saturation; --frames N writes
the whole life cycle: about 40 % growth, 25 % slow change, 35 % fading.

Examples:
  voxcast cloud --type cumulus -o cumulus/
  voxcast render cumulus/ --tf cloud -o cumulus.png --elevation 25
  voxcast cloud --type stratus --frames 30 --grid 200,200,40 -o stratus/
  voxcast render stratus/ --time 12 --tf cloud -o stratus12.png
  voxcast cloud --from-wrf ../shared/data/wrf_katrina/mercator_sample.nc --time 2 -o katrina/
    (needs a build with --features wrf)";

#[derive(Args)]
pub struct CloudArgs {
    /// Cloud type: cumulus (heaped puffs with flat bases), stratus (a flat
    /// layer) or altocumulus (many small patchy puffs).
    #[arg(long = "type", value_name = "TYPE", default_value = "cumulus")]
    pub kind: String,
    /// Frames to write (1: the saturated cloud; more: its life cycle).
    #[arg(long, default_value_t = 1)]
    pub frames: u32,
    /// Density grid size X,Y,Z (z up); the paper's is 400,400,60.
    #[arg(long, value_name = "X,Y,Z", default_value = "400,400,60")]
    pub grid: String,
    /// Random seed (the same seed gives the same cloud).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output frame folder (created; an existing one must be empty or hold
    /// a series, whose frames are replaced).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// The paper's path: seed the particles where a weather model has cloud
    /// water — a WRF wrfout file (build with --features wrf) or any volume
    /// voxcast reads; each cell above 1 % of the maximum becomes a puff
    /// whose particles' density follows the value. --type is then ignored.
    #[arg(long, value_name = "FILE")]
    pub from_wrf: Option<PathBuf>,
    /// With --from-wrf: the variable, or a sum such as QCLOUD+QICE
    /// (default QCLOUD).
    #[arg(long, value_name = "NAME")]
    pub var: Option<String>,
    /// With --from-wrf: the time index to read (default 0).
    #[arg(long, value_name = "INDEX")]
    pub time: Option<u32>,
    /// Write frames uncompressed (faster, larger).
    #[arg(long)]
    pub raw: bool,
    /// No messages on stderr.
    #[arg(short, long)]
    pub quiet: bool,
}
