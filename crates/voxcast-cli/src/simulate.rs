//! `voxcast simulate smoke`: runs the smoke simulator into a frame folder.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::PathBuf;
use voxcast_sim::{self as sim, SmokeScene};

pub const SIMULATE_HELP: &str = "\
Examples:
  voxcast simulate smoke --scene room --frames 300 -o room/
  voxcast simulate smoke --scene office --frames 800 -o office/ --grid 96,64,48
  voxcast simulate smoke --scene corridor --save-scene corridor.toml   # write the preset, run nothing
  voxcast simulate smoke --scene my_room.toml --frames 200 -o mine/
  voxcast render room/ --time 20 -o room-200.png   # a frame (nearest time; default the last)
  voxcast animate room/ -o room.gif";

#[derive(Args)]
pub struct SimulateArgs {
    #[command(subcommand)]
    pub kind: SimKind,
}

#[derive(Subcommand)]
pub enum SimKind {
    /// Smoke from a fire in a room (Fedkiw, Stam & Jensen 2001): buoyant hot
    /// smoke rises, pools under the ceiling into a layer that thickens
    /// downward, runs down the walls and fills the room.
    #[command(after_long_help = SMOKE_HELP)]
    Smoke(SmokeArgs),
}

const SMOKE_HELP: &str = "\
The solver: a MAC grid; smoke density moved by a conservative limited upwind
flux (mass = injected − outflow), temperature and velocity by semi-Lagrangian
back-tracing; Boussinesq buoyancy (density pulls down, heat lifts), vorticity
confinement, and a pressure projection by multigrid-preconditioned conjugate
gradients to the scene's `tolerance` (relative max-norm residual). Obstacles
are solid cells (no flow through), openings are cells at ambient pressure
where smoke leaves.

The output folder holds one NRRD per frame (smoke density, metres), the
manifest series.toml (frame times in seconds), geometry.toml (the furniture
as boxes and the floor as a plane, for the renderer; the walls are the
volume's bounds and are not written, so that they never hide the smoke),
scene.toml (the scene, to run again) and simulation.json (per-frame wall
time, CG iterations, mass, injected, outflow).

A scene file (TOML) gives grid, cell_size (m), dt (s), steps_per_frame,
alpha, beta, vorticity, cooling, seed, tolerance, [source] (center, radius,
density_rate, temperature, flicker), [[obstacle]] and [[opening]] boxes
(min, max in metres; name, color). Start from a preset: --save-scene.";

#[derive(Args)]
pub struct SmokeArgs {
    /// A preset (room, office, corridor) or a scene TOML file.
    #[arg(long, value_name = "PRESET|FILE", default_value = "room")]
    pub scene: String,
    /// Frames to write.
    #[arg(long, value_name = "N", default_value_t = 300)]
    pub frames: usize,
    /// Override the grid (cells X,Y,Z); the cell size is scaled so the room
    /// keeps its size (by the x ratio).
    #[arg(long, value_name = "X,Y,Z")]
    pub grid: Option<String>,
    /// Override the seed of the fire's flicker.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Output frame folder (new or empty, or a previous series to replace).
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
    /// Write the scene (after overrides) as TOML and exit unless -o is given.
    #[arg(long, value_name = "FILE")]
    pub save_scene: Option<PathBuf>,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
}

pub fn run(a: SimulateArgs) -> Result<()> {
    match a.kind {
        SimKind::Smoke(s) => smoke(s),
    }
}

fn smoke(a: SmokeArgs) -> Result<()> {
    let mut scene = SmokeScene::load(&a.scene)?;
    if let Some(g) = &a.grid {
        let v: Vec<usize> = g
            .split(',')
            .map(|p| p.trim().parse())
            .collect::<std::result::Result<_, _>>()
            .map_err(|_| anyhow::anyhow!("--grid {g}: expected three cell counts X,Y,Z"))?;
        if v.len() != 3 {
            bail!("--grid {g}: expected three cell counts X,Y,Z");
        }
        // Keep the room's physical size: scale the cell by the x ratio.
        scene.cell_size *= scene.grid[0] as f32 / v[0] as f32;
        scene.grid = [v[0], v[1], v[2]];
    }
    if let Some(s) = a.seed {
        scene.seed = s;
    }
    scene
        .validate()
        .map_err(|(f, m)| anyhow::anyhow!("scene field `{f}`: {m}"))?;
    if let Some(f) = &a.save_scene {
        let text = scene.to_toml();
        voxcast::files::write_file(f, |w| {
            use std::io::Write;
            w.write_all(
                b"# voxcast smoke scene: `voxcast simulate smoke --scene THIS_FILE -o DIR`\n",
            )?;
            w.write_all(text.as_bytes())
        })?;
        if !a.quiet {
            eprintln!("wrote {}", f.display());
        }
    }
    let Some(out) = a.output else {
        if a.save_scene.is_some() {
            return Ok(());
        }
        bail!("give an output folder with -o DIR (or --save-scene FILE to write the scene only)");
    };
    let bar = ProgressBar::with_draw_target(Some(a.frames as u64), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(
            "simulating {bar:40.cyan/blue} {pos}/{len} frames {elapsed}<{eta} {msg}",
        )
        .expect("valid template"),
    );
    if std::io::stderr().is_terminal() && !a.quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let [nx, ny, nz] = scene.grid;
    if !a.quiet {
        eprintln!(
            "{}: {nx}×{ny}×{nz} cells of {} m, dt {} s × {} steps per frame, {} frames → {}",
            if scene.title.is_empty() {
                "smoke"
            } else {
                &scene.title
            },
            scene.cell_size,
            scene.dt,
            scene.steps_per_frame,
            a.frames,
            out.display()
        );
    }
    let stats = sim::simulate_smoke(&scene, a.frames, &out, |s| {
        bar.set_position(s.frame as u64 + 1);
        bar.set_message(format!(
            "t {:.1} s, {:.0} ms/frame, {} CG it",
            s.time, s.step_ms, s.cg_iterations
        ));
    })
    .with_context(|| format!("simulating into {}", out.display()))?;
    bar.finish_and_clear();
    if !a.quiet {
        let n = stats.len() as f64;
        let ms: f64 = stats.iter().map(|s| s.step_ms).sum::<f64>() / n;
        let wr: f64 = stats.iter().map(|s| s.write_ms).sum::<f64>() / n;
        let it: f64 = stats.iter().map(|s| s.cg_iterations as f64).sum::<f64>() / n;
        let last = stats.last().expect("frames > 0");
        eprintln!(
            "wrote {} frames to {}: {:.1} ms/frame simulating ({:.2} frames/s), {:.1} ms writing, {:.1} CG iterations per frame; smoke mass {:.4} = injected {:.4} − outflow {:.4} ({:+.2e})",
            stats.len(),
            out.display(),
            ms,
            1e3 / ms,
            wr,
            it,
            last.mass,
            last.injected,
            last.outflow,
            last.mass - (last.injected - last.outflow)
        );
    }
    Ok(())
}
