//! `voxcast bench-frames`: every method's frame rate frame by frame over a
//! series (S0 Table 3 / Fig. 14), as a table, JSON and a chart.

use super::series::{fix_transfer, scene_and_series, select};
use crate::args::BenchFramesArgs;
use anyhow::{bail, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::io::Write;
use voxcast_bench::bench_frames;

pub fn run(a: BenchFramesArgs) -> Result<()> {
    let mut methods = voxcast_bench::parse_methods(&a.methods)?;
    if a.repeat == 0 {
        bail!("--repeat 0: at least one timed render per method is needed");
    }
    // The baseline first.
    if let Some(p) = methods.iter().position(|m| m.to_string() == "uniform") {
        let u = methods.remove(p);
        methods.insert(0, u);
    }
    let (scene, series) = scene_and_series(&a.scene, None)?;
    let mut outputs = voxcast::files::Outputs::new([&scene.input.path]);
    outputs.plan_optional("--json", a.json.as_deref(), &[])?;
    outputs.plan_optional("--chart", a.chart.as_deref(), &["png"])?;
    let frames = select(a.frames.as_deref(), a.every, series.len())?;
    let scene = fix_transfer(&scene, &series, *frames.last().expect("non-empty"))?;
    let bar =
        ProgressBar::with_draw_target(Some(frames.len() as u64), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(
            "benchmarking {bar:40.cyan/blue} {pos}/{len} frames {elapsed}<{eta} {msg}",
        )
        .expect("valid template"),
    );
    if std::io::stderr().is_terminal() && !a.quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let report = bench_frames::run(
        &scene,
        &series,
        &frames,
        &methods,
        a.repeat,
        &mut |k, _, row| {
            bar.set_position(k as u64);
            let fps: Vec<String> = row
                .results
                .iter()
                .map(|r| format!("{:.0}", r.fps))
                .collect();
            bar.set_message(format!("frame {}: fps {}", row.frame, fps.join(" / ")));
        },
    )?;
    bar.finish_and_clear();
    if a.markdown {
        print!("{}", bench_frames::markdown(&report));
    } else {
        print!("{}", bench_frames::text_table(&report));
    }
    if let Some(f) = &a.json {
        let json = serde_json::to_string_pretty(&report)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    if let Some(f) = &a.chart {
        let png = voxcast_bench::chart::frames_png(&report)?;
        outputs.write(f, |w| w.write_all(&png))?;
    }
    outputs.commit()?;
    Ok(())
}
