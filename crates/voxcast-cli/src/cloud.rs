//! `voxcast cloud`: runs the S3 particle-system cloud and writes its frames
//! to a frame folder (series.toml + one NRRD per frame).

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use voxcast::volume::series::SeriesWriter;
use voxcast_sim::cloud::{CloudOptions, CloudSim, CloudType};

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

fn parse_grid(s: &str) -> Result<[usize; 3]> {
    let v: Vec<usize> = s
        .split([',', 'x'])
        .map(|p| p.trim().parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--grid {s}: expected three whole numbers X,Y,Z"))?;
    match v[..] {
        [x, y, z] => Ok([x, y, z]),
        _ => bail!("--grid {s}: expected three numbers X,Y,Z"),
    }
}

pub fn run(a: CloudArgs) -> Result<()> {
    let options = CloudOptions {
        kind: CloudType::parse(&a.kind)?,
        grid: parse_grid(&a.grid)?,
        seed: a.seed,
        frames: a.frames,
    };
    let (mut sim, what) = match &a.from_wrf {
        Some(path) => {
            let opts = voxcast::io::OpenOptions {
                variable: Some(a.var.clone().unwrap_or_else(|| "QCLOUD".into())),
                time: a.time.map(f64::from),
                ..Default::default()
            };
            let field = voxcast::io::open(path, &opts)
                .with_context(|| format!("reading the cloud field from {}", path.display()))?;
            let name = field.name.clone().unwrap_or_else(|| "field".into());
            let sim = CloudSim::from_field(options, &field)?;
            (sim, format!("cloud from {name} of {}", path.display()))
        }
        None => {
            let sim = CloudSim::new(options)?;
            let what = format!("{} cloud", sim.options.kind.name());
            (sim, what)
        }
    };
    let title = format!("{what}, seed {}", a.seed);
    let mut writer = SeriesWriter::create(&a.output, Some(title.clone()), Some("frame".into()))?;
    if a.raw {
        writer = writer.raw();
    }
    let (steps_before, frames) = sim.schedule();
    let bar = if a.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(frames as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("cloud {bar:40.cyan/blue} {pos}/{len} frames {elapsed}<{eta}")
            .expect("valid template"),
    );
    for _ in 0..steps_before.saturating_sub(1) {
        sim.step();
    }
    let mut last = None;
    for f in 0..frames {
        let counts = sim.step();
        let vol = sim.density()?;
        writer.push(&vol, f as f64)?;
        bar.inc(1);
        last = Some(counts);
    }
    bar.finish_and_clear();
    if !a.quiet {
        let c = sim.counts;
        eprintln!(
            "wrote {} frames of a {} to {} ({} puffs; N_frame {}, N_max {}, N_min {}, N_ext {}, t_v {}, t_e {}; {} particles at the end)",
            frames,
            title,
            writer.dir().display(),
            sim.puffs.len(),
            c.n_frame,
            c.n_max,
            c.n_min,
            c.n_ext,
            c.t_v,
            c.t_e,
            last.map(|l| l.total).unwrap_or(0)
        );
    }
    Ok(())
}
