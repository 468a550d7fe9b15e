//! `voxcast animate`: renders every (selected) frame of a series — a
//! simulator's frame folder, an FDS case, a folder or glob of volumes —
//! with one scene, into a GIF, an MP4 (through ffmpeg) or numbered PNGs.

use super::series::{fix_transfer, scene_and_series, select};
use crate::args::AnimateArgs;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;
use std::io::{IsTerminal, Write};
use std::path::PathBuf;
use voxcast::io::series::Series;
use voxcast::scene::Scene;

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

/// Hands each rendered frame (its index, time, image and counts) to the
/// output, in order.
pub type Emit<'a> =
    dyn FnMut(usize, f64, &voxcast::Image, &voxcast::RenderStats) -> Result<()> + 'a;

/// Renders `frames` of `series` with `scene`, in order, handing each to
/// `emit`.
pub type Frames<'a> = dyn FnMut(&Scene, &Series, &[usize], &mut Emit<'_>) -> Result<()> + 'a;

pub fn run(a: AnimateArgs) -> Result<()> {
    #[cfg(feature = "mpi")]
    if a.mpi_frames != crate::args::MpiFrames::Auto {
        bail!("--mpi-frames: frames are shared among processes only under mpirun (mpirun -np N voxcast animate …)");
    }
    run_with(&a, &mut |scene, series, frames, emit| {
        for &i in frames {
            let v = series.load(i, &scene.input.options)?;
            let time = v.time.unwrap_or(i as f64);
            let prepared = scene.prepare_with(v)?;
            let (image, stats) = scene.render(&prepared, &|_, _| {})?;
            emit(i, time, &image, &stats)?;
        }
        Ok(())
    })
}

/// The scene, the series and the frames `a` selects, with the transfer
/// function fixed over the series (as [`run_with`] makes them).
#[cfg(feature = "mpi")]
pub fn plan(a: &AnimateArgs) -> Result<(Scene, Series, Vec<usize>)> {
    let (scene, series) = scene_and_series(&a.scene, a.method.as_deref())?;
    let frames = select(a.frames.as_deref(), a.every, series.len())?;
    let scene = fix_transfer(&scene, &series, *frames.last().expect("non-empty"))?;
    Ok((scene, series, frames))
}

/// `voxcast animate` with the frames rendered by `render` (here, or spread
/// over MPI processes).
pub fn run_with(a: &AnimateArgs, render: &mut Frames<'_>) -> Result<()> {
    let (scene, series) = scene_and_series(&a.scene, a.method.as_deref())?;
    if !(a.fps.is_finite() && a.fps > 0.0 && a.fps <= 100.0) {
        bail!("--fps {}: expected 0 < fps ≤ 100", a.fps);
    }
    let frames = select(a.frames.as_deref(), a.every, series.len())?;
    let out = &a.output;
    let a = &a;
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
    outputs.plan_optional("--stats-json", a.stats_json.as_deref(), &[])?;
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
    let result = render(&scene, &series, &frames, &mut |i, time, image, stats| {
        {
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
    });
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
