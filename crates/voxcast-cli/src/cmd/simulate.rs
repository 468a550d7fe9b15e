//! `voxcast simulate smoke`: runs the smoke simulator into a frame folder.

use crate::args::{SimKind, SimulateArgs, SmokeArgs};
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use voxcast_sim::{self as sim, SmokeScene};

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
        .map_err(|e| anyhow::anyhow!("scene field `{}`: {}", e.field, e.message))?;
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
