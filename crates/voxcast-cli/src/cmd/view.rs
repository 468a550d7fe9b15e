//! `voxcast view`: the viewer, scripted or not.

use crate::args::ViewArgs;
use anyhow::{bail, Result};
use std::io::Write;
use voxcast::files::Outputs;

pub fn run(a: ViewArgs) -> Result<()> {
    let scene = a.scene()?;
    let mut outputs = Outputs::new([&scene.input.path]);
    outputs.plan_optional("--screenshot", a.screenshot.as_deref(), &["png"])?;
    outputs.plan_optional("--save-scene", a.save_scene.as_deref(), &["toml"])?;
    outputs.plan_optional("--stats-json", a.stats_json.as_deref(), &[])?;
    if let Some(s) = a.orbit {
        if !(s.is_finite() && s > 0.0 && s <= 600.0) {
            bail!("--orbit {s}: expected seconds in (0, 600]");
        }
    }
    let scripted = a.screenshot.is_some() || a.exit_after_frames.is_some() || a.orbit.is_some();
    if !scripted && (a.save_scene.is_some() || a.stats_json.is_some()) {
        bail!("--save-scene and --stats-json belong to a scripted run: add --screenshot FILE, --exit-after-frames N or --orbit S (in the window, use the Save buttons)");
    }
    // The viewer draws what the GPU lacks on the CPU, frame by frame: no
    // method or geometry decides the device here.
    let device = super::device::pick_device(a.device, &[], None, false)?;
    let options = voxcast_view::ViewOptions {
        device,
        screenshot: a.screenshot.clone(),
        exit_after_frames: a.exit_after_frames,
        save_scene: a.save_scene.clone(),
        orbit: a.orbit,
        memory_budget: a.memory_budget,
    };
    let stats = voxcast_view::run(scene, options)?;
    if let Some(f) = &a.screenshot {
        eprintln!("wrote {}", f.display());
    }
    if let Some(f) = &a.save_scene {
        eprintln!("wrote {}", f.display());
    }
    if a.orbit.is_some() {
        let mut p = stats.preview_render_ms.clone();
        p.sort_by(f64::total_cmp);
        let median = p.get(p.len() / 2).copied().unwrap_or(f64::NAN);
        eprintln!(
            "{} {}×{}: {:.1} frames/s while moving ({} new images painted in {:.2} s, {:.1} UI frames/s; previews 1/{} = {}×{}, median {:.0} ms); refined image {} ms after the camera stopped (full render {} ms)",
            stats.backend,
            stats.view[0],
            stats.view[1],
            stats.fps_while_moving(),
            stats.frames_while_moving,
            stats.orbit_seconds,
            stats.ui_fps_while_moving(),
            stats.preview_divisor,
            stats.preview_size[0],
            stats.preview_size[1],
            median,
            stats
                .refined_after_stop_ms
                .map_or("?".into(), |t| format!("{t:.0}")),
            stats
                .full_render_ms
                .last()
                .map_or("?".into(), |t| format!("{t:.0}")),
        );
    }
    if !stats.levels.is_empty() {
        let shown: Vec<String> = stats.levels.iter().map(|l| l.to_string()).collect();
        eprintln!(
            "levels shown: {} (the first image {:.0} ms after the window opened, the last {:.0} ms)",
            shown.join(" → "),
            stats.first_image_ms.unwrap_or(f64::NAN),
            stats.last_image_ms
        );
    }
    if let Some(f) = &a.stats_json {
        let json = serde_json::to_string_pretty(&stats)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    outputs.commit()?;
    Ok(())
}
