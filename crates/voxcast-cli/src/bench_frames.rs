//! `voxcast bench-frames`: every method's frame rate frame by frame over a
//! series (S0 Table 3 / Fig. 14), as a table, JSON and a chart.

use crate::animate::{fix_transfer, scene_and_series, select};
use crate::args::SceneArgs;
use anyhow::{bail, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::io::Write;
use std::path::PathBuf;
use voxcast_bench::bench_frames;

pub const BENCH_FRAMES_HELP: &str = "\
Each selected frame of the series is loaded, its converged reference rendered
(uniform at 1/16 voxel, no early termination, no empty-space skipping), then
every method rendered --repeat times (methods interleaved, after one untimed
render each; the fastest render counts, since other load on the machine only
ever adds time). The table gives per frame each method's time, frame rate
and PSNR against the reference, then per method the mean frame rate and the
speed-up over uniform (mean of the per-frame ratios, min–max). The transfer
function's window is fixed from the last selected frame.

Examples:
  voxcast bench-frames ../shared/data/fds_room/room_smoke.smv --every 10 --size 256x256 --tf smoke
  voxcast bench-frames office/ --every 50 --markdown --chart fps.png --json fps.json";

#[derive(Args)]
pub struct BenchFramesArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Methods, comma-separated (uniform is added first when missing: the baseline).
    #[arg(
        long,
        value_name = "LIST",
        default_value = "uniform,threshold,adaptive+grouped"
    )]
    pub methods: String,
    /// Take every N-th frame of the selection.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub every: usize,
    /// Frame range A..B (B excluded; A.., ..B, A..=B).
    #[arg(long, value_name = "A..B")]
    pub frames: Option<String>,
    /// Timed renders per method and frame (the fastest counts).
    #[arg(long, value_name = "N", default_value_t = 3)]
    pub repeat: usize,
    /// Write the report as JSON.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Draw frame rate against frame, one line per method, as a PNG.
    #[arg(long, value_name = "FILE.png")]
    pub chart: Option<PathBuf>,
    /// Print the table as Markdown.
    #[arg(long)]
    pub markdown: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

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
    if let Some(f) = &a.json {
        outputs.plan("--json", f, &[])?;
    }
    if let Some(f) = &a.chart {
        outputs.plan("--chart", f, &["png"])?;
    }
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
