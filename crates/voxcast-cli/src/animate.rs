//! `voxcast animate`: renders every (selected) frame of a series — a
//! simulator's frame folder, an FDS case, a folder or glob of volumes —
//! with one scene, into a GIF, an MP4 (through ffmpeg) or numbered PNGs.

use crate::args::SceneArgs;
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use voxcast::render::MethodSpec;
use voxcast::scene::Scene;
use voxcast::volume::Series;

pub const ANIMATE_HELP: &str = "\
INPUT is a series: a frame folder written by `voxcast simulate` (series.toml),
an FDS case (.smv: the soot SMOKE3D frames, or --var QUANTITY), or a folder or
glob of volume files (one frame each, sorted by name). Every selected frame is
rendered with the same scene (transfer function, camera, method, size); the
transfer function's window is fixed from the last selected frame (unless
--window is given) so that the animation does not flicker.

Output by name: out.gif (per-frame NeuQuant palette), out.mp4 (needs ffmpeg on
PATH: raw RGB frames are piped to it; without ffmpeg nothing is written and the
command fails), or DIR/ (frame_00000.png, …). Every file is written under a
temporary name and renamed at the end.

Examples:
  voxcast animate room/ -o room.gif --tf smoke --azimuth 30 --elevation 20
  voxcast animate ../shared/data/fds_room/room_smoke.smv -o fds.gif --every 2 --fps 12
  voxcast animate office/ -o office.mp4 --frames 100..400 --method adaptive+grouped
  voxcast animate office/ -o frames/ --size 256x256 --stats-json frames.json";

#[derive(Args)]
pub struct AnimateArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Output: FILE.gif, FILE.mp4 (needs ffmpeg) or a folder DIR/ for PNGs.
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Sampling method (as for render: uniform, adaptive, adaptive-max,
    /// threshold; +grouped, +noskip).
    #[arg(long, value_name = "METHOD", help_heading = "Ray casting")]
    pub method: Option<String>,
    /// Frames per second of the GIF/MP4.
    #[arg(long, default_value_t = 10.0, help_heading = "Frames")]
    pub fps: f64,
    /// Take every N-th frame of the selection.
    #[arg(long, value_name = "N", default_value_t = 1, help_heading = "Frames")]
    pub every: usize,
    /// Frame range A..B (B excluded; A.., ..B and A..=B also work), frame indices from 0.
    #[arg(long, value_name = "A..B", help_heading = "Frames")]
    pub frames: Option<String>,
    /// Write per-frame statistics (time, render seconds, rays, samples) as JSON.
    #[arg(long, value_name = "FILE")]
    pub stats_json: Option<PathBuf>,
    /// No progress bar or summary.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Parses `A..B`, `A..=B`, `A..`, `..B` into indices of a series of `n`.
pub fn select(spec: Option<&str>, every: usize, n: usize) -> Result<Vec<usize>> {
    if every == 0 {
        bail!("--every 0: expected 1 or more");
    }
    let (a, b) = match spec {
        None => (0, n),
        Some(s) => {
            let (l, r, incl) = if let Some((l, r)) = s.split_once("..=") {
                (l, r, true)
            } else if let Some((l, r)) = s.split_once("..") {
                (l, r, false)
            } else {
                bail!("--frames {s}: expected A..B (e.g. 0..100, 50.., ..=20)");
            };
            let num = |t: &str, d: usize| -> Result<usize> {
                if t.trim().is_empty() {
                    Ok(d)
                } else {
                    t.trim()
                        .parse()
                        .map_err(|_| anyhow::anyhow!("--frames {s}: `{t}` is not a frame index"))
                }
            };
            let a = num(l, 0)?;
            let b = num(r, n)? + usize::from(incl && !r.trim().is_empty());
            (a, b.min(n))
        }
    };
    let v: Vec<usize> = (a..b).step_by(every).collect();
    if v.is_empty() {
        bail!(
            "--frames {}: selects no frame of the {n} in the series",
            spec.unwrap_or("")
        );
    }
    Ok(v)
}

/// The scene and the series these flags imply; the transfer function and
/// window are fixed from the last selected frame.
pub fn scene_and_series(scene_args: &SceneArgs, method: Option<&str>) -> Result<(Scene, Series)> {
    let mut scene = scene_args.base_scene()?;
    if let Some(m) = method {
        MethodSpec::parse(m)
            .with_context(|| format!("--method {m}"))?
            .apply(&mut scene.render);
    }
    scene_args.apply(&mut scene)?;
    if scene.input.path.starts_with(voxcast::scene::BUILTIN_PREFIX) {
        bail!("give a series: a frame folder, an FDS .smv, or a folder/glob of volumes");
    }
    let path = PathBuf::from(&scene.input.path);
    let series = Series::open(&path, &scene.input.options)
        .with_context(|| format!("opening {} as a series", path.display()))?;
    Ok((scene, series))
}

/// Fixes the transfer function and window from frame `i`, so every frame
/// is drawn with the same mapping.
pub fn fix_transfer(scene: &Scene, series: &Series, i: usize) -> Result<Scene> {
    let v = series.load(i, &scene.input.options)?;
    let prepared = scene.prepare_with(v)?;
    Ok(scene.resolved(&prepared))
}

#[derive(Serialize)]
struct FrameRecord {
    frame: usize,
    time: f64,
    seconds: f64,
    rays: u64,
    samples: u64,
    interpolations: u64,
}

enum Sink {
    Gif {
        enc: gif::Encoder<std::io::BufWriter<std::fs::File>>,
        delay: u16,
    },
    Mp4 {
        child: std::process::Child,
    },
    Pngs {
        dir: PathBuf,
        n: usize,
    },
}

/// `ffmpeg` when it is on PATH.
fn find_ffmpeg() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join("ffmpeg"))
        .find(|p| p.is_file())
}

pub fn run(a: AnimateArgs) -> Result<()> {
    let (scene, series) = scene_and_series(&a.scene, a.method.as_deref())?;
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 100.0) {
        bail!("--fps {}: expected 0 < fps ≤ 100", a.fps);
    }
    let frames = select(a.frames.as_deref(), a.every, series.len())?;
    let out = &a.output;
    let ext = out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let as_dir = ext.is_empty() || out.to_string_lossy().ends_with('/') || out.is_dir();
    let input = &scene.input.path;
    let mut outputs = voxcast::files::Outputs::new([input]);
    if as_dir {
        voxcast::files::check_folder("-o", out, &[input])?;
    } else if ext != "gif" && ext != "mp4" {
        bail!(
            "{}: output must end in .gif or .mp4, or be a folder (DIR/) for PNGs",
            out.display()
        );
    } else {
        outputs.plan("-o", out, &["gif", "mp4"])?;
    }
    if let Some(f) = &a.stats_json {
        outputs.plan("--stats-json", f, &[])?;
    }
    let ffmpeg = if ext == "mp4" && !as_dir {
        Some(find_ffmpeg().context(
            "ffmpeg is not on PATH: MP4 needs it (install ffmpeg, or write .gif or a folder of PNGs); nothing was written",
        )?)
    } else {
        None
    };
    let scene = fix_transfer(&scene, &series, *frames.last().expect("non-empty"))?;
    outputs.check()?;
    let (w, h) = (scene.render.width, scene.render.height);
    // The GIF or MP4 is written under a temporary name until it is whole.
    let tmp = if as_dir {
        PathBuf::new()
    } else {
        outputs.stage(out)?
    };
    let mut sink = if as_dir {
        if out.exists() {
            let foreign = std::fs::read_dir(out)
                .with_context(|| format!("reading {}", out.display()))?
                .filter_map(|e| e.ok())
                .any(|e| {
                    let n = e.file_name().to_string_lossy().into_owned();
                    !(n.starts_with("frame_") && n.ends_with(".png"))
                });
            if foreign {
                bail!(
                    "{}: the folder holds files other than frame_*.png; give an empty or new folder",
                    out.display()
                );
            }
        } else {
            std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        }
        Sink::Pngs {
            dir: out.clone(),
            n: 0,
        }
    } else if let Some(ff) = ffmpeg {
        let child = std::process::Command::new(ff)
            .args([
                "-loglevel",
                "error",
                "-y",
                "-f",
                "rawvideo",
                "-pix_fmt",
                "rgb24",
                "-s",
            ])
            .arg(format!("{w}x{h}"))
            .arg("-r")
            .arg(format!("{}", a.fps))
            .args([
                "-i", "-", "-an", "-c:v", "libx264", "-pix_fmt", "yuv420p", "-vf",
            ])
            // yuv420p needs even sizes.
            .arg("pad=ceil(iw/2)*2:ceil(ih/2)*2")
            .args(["-f", "mp4"])
            .arg(&tmp)
            .stdin(std::process::Stdio::piped())
            .spawn()
            .context("starting ffmpeg")?;
        Sink::Mp4 { child }
    } else {
        if w > u16::MAX as u32 || h > u16::MAX as u32 {
            bail!("GIF frames are at most 65535 pixels wide and high");
        }
        let f =
            std::fs::File::create(&tmp).with_context(|| format!("creating {}", tmp.display()))?;
        let mut enc = gif::Encoder::new(std::io::BufWriter::new(f), w as u16, h as u16, &[])?;
        enc.set_repeat(gif::Repeat::Infinite)?;
        Sink::Gif {
            enc,
            delay: (100.0 / a.fps).round().max(2.0) as u16,
        }
    };

    let bar =
        ProgressBar::with_draw_target(Some(frames.len() as u64), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(
            "animating {bar:40.cyan/blue} {pos}/{len} frames {elapsed}<{eta} {msg}",
        )
        .expect("valid template"),
    );
    if std::io::stderr().is_terminal() && !a.quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let mut records = Vec::with_capacity(frames.len());
    let result = (|| -> Result<()> {
        for &i in &frames {
            let v = series.load(i, &scene.input.options)?;
            let time = v.time.unwrap_or(i as f64);
            let prepared = scene.prepare_with(v)?;
            let (image, stats) = scene.render(&prepared, &|_, _| {})?;
            let rgb = image.to_srgb8();
            match &mut sink {
                Sink::Gif { enc, delay } => {
                    // NeuQuant palette per frame (speed 10: good quality, quick).
                    let mut f = gif::Frame::from_rgb_speed(w as u16, h as u16, &rgb, 10);
                    f.delay = *delay;
                    enc.write_frame(&f)?;
                }
                Sink::Mp4 { child } => {
                    child
                        .stdin
                        .as_mut()
                        .context("ffmpeg's input")?
                        .write_all(&rgb)
                        .context("piping a frame to ffmpeg")?;
                }
                Sink::Pngs { dir, n } => {
                    image.write_png(&dir.join(format!("frame_{:05}.png", *n)))?;
                    *n += 1;
                }
            }
            records.push(FrameRecord {
                frame: i,
                time,
                seconds: stats.seconds,
                rays: stats.rays,
                samples: stats.samples,
                interpolations: stats.interpolations,
            });
            bar.inc(1);
            bar.set_message(format!(
                "t {time:.2}: {:.0} ms, {} samples",
                stats.seconds * 1e3,
                stats.samples
            ));
        }
        Ok(())
    })();
    bar.finish_and_clear();
    let finish = match sink {
        Sink::Gif { enc, .. } => result.and_then(|_| {
            let mut w = enc.into_inner()?;
            w.flush()?;
            w.get_ref().sync_all()?;
            Ok(())
        }),
        Sink::Mp4 { mut child } => {
            drop(child.stdin.take());
            let st = child.wait().context("waiting for ffmpeg")?;
            result.and_then(|_| {
                if st.success() {
                    Ok(())
                } else {
                    bail!("ffmpeg failed ({st})")
                }
            })
        }
        Sink::Pngs { .. } => result,
    };
    // On an error the outputs are dropped unwritten (temporary files too).
    finish?;
    if let Some(f) = &a.stats_json {
        let json = serde_json::to_string_pretty(&records)?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    outputs.commit()?;
    if !a.quiet {
        let total: f64 = records.iter().map(|r| r.seconds).sum();
        let samples: u64 = records.iter().map(|r| r.samples).sum();
        eprintln!(
            "wrote {} ({} frames, {w}×{h}, {} fps): rendering {:.2} s in all, {:.1} ms and {:.2} M samples per frame",
            out.display(),
            records.len(),
            a.fps,
            total,
            total * 1e3 / records.len() as f64,
            samples as f64 / records.len() as f64 / 1e6
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::select;

    #[test]
    fn frame_selection() {
        assert_eq!(select(None, 1, 4).unwrap(), vec![0, 1, 2, 3]);
        assert_eq!(select(Some("1..3"), 1, 10).unwrap(), vec![1, 2]);
        assert_eq!(select(Some("1..=3"), 1, 10).unwrap(), vec![1, 2, 3]);
        assert_eq!(select(Some("5.."), 2, 10).unwrap(), vec![5, 7, 9]);
        assert_eq!(select(Some("..3"), 1, 10).unwrap(), vec![0, 1, 2]);
        assert_eq!(select(Some("0..100"), 50, 10).unwrap(), vec![0]);
        assert!(select(Some("20..30"), 1, 10).is_err());
        assert!(select(Some("x..3"), 1, 10).is_err());
        assert!(select(None, 0, 10).is_err());
    }
}
