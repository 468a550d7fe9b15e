//! `voxcast cloud`: runs the S3 particle-system cloud and writes its frames
//! to a frame folder (series.toml + one NRRD per frame).

use crate::args::CloudArgs;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use voxcast::io::SeriesWriter;
use voxcast_sim::cloud::{CloudOptions, CloudSim, CloudType};

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
