//! `mpirun -np N voxcast animate …`: the frames of a series shared among
//! the processes.
//!
//! A frame rendered whole by one process needs no compositing, no ghost
//! layer and no restriction on the method, so whole frames are spread over
//! the processes, `N` at a time. Only a last, partial round of `T < N`
//! frames leaves `N − T` processes idle; each of its frames can instead be
//! split over a group of `⌊N / T⌋` processes and composited (sort-last,
//! [`voxcast::render::sortlast`]). Whether that is faster depends on the
//! case — a split part costs the out-of-core engine's per-pixel and
//! per-brick overhead on every process, and a split frame is rendered
//! without early ray termination — so with `--mpi-frames auto` (the
//! default) a pilot decides: one such frame at a quarter of the pixels,
//! whole and split; a frame too quick to gain is not timed split. The pilot
//! and the choice are reported. A split frame differs from the whole one by
//! at most what early ray termination drops (`--ert`; 58 dB on the teapot
//! CT at the default 0.99, 79 dB on a cloud), as the one-process render
//! with `--ert 1` would. `spread` never splits, `split` always splits
//! the last round's frames. A frame is split only when its scene can be (a
//! method that decides along the whole ray, or opaque geometry, keeps it
//! whole).

use super::{default_budget, gather_figures, max_of, memory_source, sum_of, MpiExchange};
use crate::args::{AnimateArgs, MpiFrames};
use anyhow::{bail, Context, Result};
use mpi::topology::{Color, Communicator, SimpleCommunicator};
use mpi::traits::{CommunicatorCollectives, Destination, Root, Source};
use std::sync::atomic::AtomicBool;
use std::time::Instant;
use voxcast::io::series::Series;
use voxcast::render::outofcore::{OutOfCore, OutOfCoreParams};
use voxcast::render::sortlast;
use voxcast::scene::Scene;

/// Tags of a frame's pixels and figures sent to process 0.
const FRAME_PIXELS: i32 = 10;
const FRAME_FIGURES: i32 = 11;

/// Who renders one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Job {
    /// Rendered whole by this process.
    Whole(usize),
    /// Split over processes `first .. first + size` and composited; `first`
    /// gets the image.
    Split { first: usize, size: usize },
}

impl Job {
    /// Whether process `p` takes part.
    fn has(self, p: usize) -> bool {
        match self {
            Job::Whole(q) => p == q,
            Job::Split { first, size } => (first..first + size).contains(&p),
        }
    }
    /// The process that ends up with the frame.
    fn holder(self) -> usize {
        match self {
            Job::Whole(q) => q,
            Job::Split { first, .. } => first,
        }
    }
}

/// The job of each of `frames` frames (in order) on `n` processes; frames
/// are split only when `splittable`.
pub(crate) fn plan(frames: usize, n: usize, how: MpiFrames, splittable: bool) -> Vec<Job> {
    let whole = |pos: usize| Job::Whole(pos % n);
    if n == 1 || !splittable {
        return (0..frames).map(whole).collect();
    }
    match how {
        MpiFrames::Spread => (0..frames).map(whole).collect(),
        MpiFrames::Auto | MpiFrames::Split => {
            let full = frames / n * n;
            let size = match frames - full {
                0 => 0,
                tail => n / tail,
            };
            (0..frames)
                .map(|pos| {
                    if pos < full || size < 2 {
                        whole(pos)
                    } else {
                        Job::Split {
                            first: (pos - full) * size,
                            size,
                        }
                    }
                })
                .collect()
        }
    }
}

/// Why the scene's frames cannot be split, if they cannot.
fn unsplittable(scene: &Scene) -> Result<Option<String>> {
    if let Err(e) = sortlast::check_params(&scene.render) {
        return Ok(Some(e.to_string()));
    }
    if scene.load_geometry()?.is_some() {
        return Ok(Some(
            "the scene has opaque geometry, which a split frame does not render".into(),
        ));
    }
    Ok(None)
}

/// `n` and the noun: `one` when n is 1, else `many`.
fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

/// The plan in words, for process 0 to print.
fn describe(jobs: &[Job], n: usize, ert: f32, why_whole: Option<&str>) -> String {
    let split: Vec<&Job> = jobs
        .iter()
        .filter(|j| matches!(j, Job::Split { .. }))
        .collect();
    let whole = jobs.len() - split.len();
    let mut s = format!(
        "animating {} on {}: ",
        count(jobs.len(), "frame", "frames"),
        count(n, "process", "processes")
    );
    if whole > 0 {
        s += &format!(
            "{} spread over the processes ({})",
            count(whole, "whole frame", "whole frames"),
            count(whole.div_ceil(n), "round", "rounds")
        );
    }
    if let Some(Job::Split { size, .. }) = split.first() {
        if whole > 0 {
            s += ", then ";
        }
        s += &format!(
            "{} split over {size} processes each and composited{}",
            count(split.len(), "frame", "frames"),
            if ert < 1.0 {
                ", without early ray termination"
            } else {
                ""
            }
        );
        if whole > 0 {
            s += &format!(
                " (a last round of {} would leave {} idle)",
                count(split.len(), "whole frame", "whole frames"),
                count(n - split.len(), "process", "processes")
            );
        }
    }
    if let Some(why) = why_whole {
        if n > 1 && !jobs.len().is_multiple_of(n) {
            s += &format!("; frames are not split: {why}");
        }
    }
    s
}

/// One rendered frame: its time, image and counts.
type Frame = (f64, voxcast::Image, voxcast::RenderStats);

/// Renders frame `i` as `job` says (this process takes part); `Some` on
/// the process that ends up with the image.
fn render_job(
    scene: &Scene,
    series: &Series,
    i: usize,
    job: Job,
    group: Option<&SimpleCommunicator>,
) -> Result<Option<Frame>> {
    let v = series.load(i, &scene.input.options)?;
    let time = v.time.unwrap_or(i as f64);
    let mut prepared = scene.prepare_with(v)?;
    if let Job::Whole(_) = job {
        let (image, stats) = scene.render(&prepared, &|_, _| {})?;
        return Ok(Some((time, image, stats)));
    }
    let Some(group) = group else {
        bail!("frame {i}: this process has no group to split it over");
    };
    let r = render_split(scene, &mut prepared, group)?;
    let all = gather_figures(&MpiExchange { world: group }, &r)?;
    let (Some(image), Some(all)) = (r.image, all) else {
        return Ok(None);
    };
    let mut stats = r.stats;
    let samples = sum_of(&all, |f| f.samples) as u64;
    stats.samples = samples;
    stats.interpolations = samples;
    stats.seconds = max_of(&all, |f| f.render_seconds) + max_of(&all, |f| f.composite_seconds);
    Ok(Some((time, image, stats)))
}

/// A frame (`prepared`, whose voxels move into a chunked source) split over
/// the processes of `group` and composited by the sort-last renderer.
fn render_split(
    scene: &Scene,
    prepared: &mut voxcast::scene::Prepared,
    group: &SimpleCommunicator,
) -> Result<sortlast::SortLast> {
    let src = memory_source(prepared)?;
    let ooc = OutOfCore::new(
        &src,
        OutOfCoreParams {
            budget: default_budget(),
            level: scene.input.options.level,
            lod_scale: crate::cmd::render_chunked::lod_scale(scene)?,
            ..Default::default()
        },
    );
    Ok(sortlast::render(
        &MpiExchange { world: group },
        &ooc,
        &prepared.tf,
        prepared.window,
        &scene.camera,
        &scene.render,
        false,
        &|_, _| {},
        &AtomicBool::new(false),
    )?)
}

/// How the frames are shared, the same on every process.
struct Shared {
    /// Each frame's job.
    jobs: Vec<Job>,
    /// This process's group, if it splits a frame.
    group: Option<SimpleCommunicator>,
    /// Why frames are not split, if they cannot be.
    why_whole: Option<String>,
    /// The pilot's figures and choice, on process 0.
    pilot: Option<String>,
}

/// Decides on every process of `world` (collectively) who renders which of
/// `frames`. With `auto`, a partial last round is split only if a pilot
/// finds it faster (see [`pilot`]).
fn share(
    a: &AnimateArgs,
    world: &SimpleCommunicator,
    scene: &Scene,
    series: &Series,
    frames: &[usize],
) -> Result<Shared> {
    let (rank, n) = (world.rank() as usize, world.size() as usize);
    let why_whole = unsplittable(scene)?;
    if a.mpi_frames == MpiFrames::Split {
        if let Some(why) = &why_whole {
            bail!("--mpi-frames split: {why}");
        }
    }
    let mut jobs = plan(frames.len(), n, a.mpi_frames, why_whole.is_none());
    let is_split = |j: &Job| matches!(j, Job::Split { .. });
    // Each process belongs to at most one group: the processes of a split
    // frame get their own communicator.
    let mut group = None;
    if jobs.iter().any(is_split) {
        let mine = jobs.iter().find_map(|j| match *j {
            Job::Split { first, .. } if j.has(rank) => Some(first),
            _ => None,
        });
        let colour = mine.map_or(Color::undefined(), |f| Color::with_value(f as i32));
        group = world.split_by_color(colour);
    }
    let mut pilot_note = None;
    if a.mpi_frames == MpiFrames::Auto {
        let first_split = jobs.iter().enumerate().find_map(|(pos, j)| match *j {
            Job::Split { size, .. } => Some((pos, size)),
            Job::Whole(_) => None,
        });
        if let Some((pos, size)) = first_split {
            let in_first = jobs[pos].has(rank);
            let times = pilot(world, scene, series, frames[pos], group.as_ref(), in_first)
                .with_context(|| format!("the pilot on frame {}", frames[pos]))?;
            let mut split = 0u8;
            if let Some(t) = times {
                let at = format!(
                    "pilot on frame {} at {}×{}",
                    frames[pos], t.size.0, t.size.1
                );
                pilot_note = Some(match t.split {
                    Some(s) => {
                        split = u8::from(t.split_is_faster());
                        format!(
                            "{at}: whole {:.3} s, split over {size} processes {s:.3} s: {}",
                            t.whole,
                            if split == 1 {
                                "the last round's frames are split"
                            } else {
                                "spreading whole frames"
                            }
                        )
                    }
                    None => format!(
                        "{at}: whole {:.3} s, so about {:.2} s at full size, too quick for splitting to pay: spreading whole frames",
                        t.whole,
                        t.whole * (scene.render.width * scene.render.height) as f64
                            / (t.size.0 * t.size.1) as f64
                    ),
                });
            }
            world.process_at_rank(0).broadcast_into(&mut split);
            if split == 0 {
                jobs = plan(frames.len(), n, MpiFrames::Spread, false);
                group = None;
            }
        }
    }
    Ok(Shared {
        jobs,
        group,
        why_whole,
        pilot: pilot_note,
    })
}

/// A whole frame estimated (from the pilot's quarter of the pixels) to
/// render faster than this, in seconds, is not split: timing a split would
/// cost about what splitting could save.
const WORTH_SPLITTING: f64 = 1.0;

/// A pilot's times, in seconds, at its size.
struct PilotTimes {
    size: (u32, u32),
    /// Frame rendered whole by process 0, as the scene says.
    whole: f64,
    /// The same split over the first group and composited, on process 0's
    /// clock; `None` when a whole frame is too quick to be worth splitting.
    split: Option<f64>,
}

impl PilotTimes {
    /// Whether splitting the last round's frames saves 5 % or more of its
    /// time (the whole rounds before it are the same either way).
    fn split_is_faster(&self) -> bool {
        self.split.is_some_and(|s| s < 0.95 * self.whole)
    }
}

/// Renders frame `i` at a quarter of the pixels (samples per ray, which
/// decide how much a split saves, do not change with the size): whole on
/// process 0 and, unless that is quick (under [`WORTH_SPLITTING`] at full
/// size), split over `group` when `in_group`, all processes waiting at a
/// barrier first so that the group starts together. The times on process
/// 0; `None` elsewhere. Called by every process of `world`.
fn pilot(
    world: &SimpleCommunicator,
    scene: &Scene,
    series: &Series,
    i: usize,
    group: Option<&SimpleCommunicator>,
    in_group: bool,
) -> Result<Option<PilotTimes>> {
    let rank = world.rank();
    let mut small = scene.clone();
    small.render.width = (scene.render.width / 2).max(16);
    small.render.height = (scene.render.height / 2).max(16);
    let size = (small.render.width, small.render.height);
    let quarter = (size.0 * size.1) as f64 / (scene.render.width * scene.render.height) as f64;
    let mut prepared = if rank == 0 || in_group {
        Some(small.prepare_with(series.load(i, &scene.input.options)?)?)
    } else {
        None
    };
    let mut whole = 0.0;
    let mut go = 0u8;
    if let (0, Some(p)) = (rank, prepared.as_ref()) {
        let t = Instant::now();
        small.render(p, &|_, _| {})?;
        whole = t.elapsed().as_secs_f64();
        go = u8::from(whole / quarter >= WORTH_SPLITTING);
    }
    world.process_at_rank(0).broadcast_into(&mut go);
    let mut split = None;
    if go == 1 {
        world.barrier();
        let t = Instant::now();
        if let (true, Some(group), Some(p)) = (in_group, group, prepared.as_mut()) {
            render_split(&small, p, group)?;
        }
        split = Some(t.elapsed().as_secs_f64());
    }
    Ok((rank == 0).then_some(PilotTimes { size, whole, split }))
}

/// `voxcast animate` on every process of `world` (see the module
/// documentation): process 0 writes the frames in order as they come.
pub fn animate(a: &AnimateArgs, world: &SimpleCommunicator) -> Result<()> {
    let (rank, n) = (world.rank() as usize, world.size() as usize);
    if rank != 0 {
        let (scene, series, frames) = super::super::animate::plan(a)?;
        let Shared { jobs, group, .. } = share(a, world, &scene, &series, &frames)?;
        for (&i, &job) in frames.iter().zip(&jobs) {
            if !job.has(rank) {
                continue;
            }
            let done = render_job(&scene, &series, i, job, group.as_ref())
                .with_context(|| format!("frame {i}"))?;
            if let Some((time, image, stats)) = done {
                let to = world.process_at_rank(0);
                to.send_with_tag(image.pixels.as_flattened(), FRAME_PIXELS);
                let figures = [
                    time,
                    stats.seconds,
                    stats.rays as f64,
                    stats.samples as f64,
                    stats.interpolations as f64,
                ];
                to.send_with_tag(&figures[..], FRAME_FIGURES);
            }
        }
        return Ok(());
    }
    let start = Instant::now();
    let mut busy = vec![0.0f64; n];
    let mut split_seconds = Vec::new();
    super::super::animate::run_with(a, &mut |scene, series, frames, emit| {
        let shared = share(a, world, scene, series, frames)?;
        let Shared { jobs, group, .. } = &shared;
        if !a.quiet {
            if let Some(p) = &shared.pilot {
                eprintln!("{p}");
            }
            eprintln!(
                "{}",
                describe(jobs, n, scene.render.ert, shared.why_whole.as_deref())
            );
        }
        for (&i, &job) in frames.iter().zip(jobs) {
            let (time, image, stats) = if job.has(0) {
                render_job(scene, series, i, job, group.as_ref())
                    .with_context(|| format!("frame {i}"))?
                    .with_context(|| format!("frame {i}: process 0 got no image"))?
            } else {
                let holder = job.holder();
                let from = world.process_at_rank(holder as i32);
                let (pixels, _) = from.receive_vec_with_tag::<f32>(FRAME_PIXELS);
                let (f, _) = from.receive_vec_with_tag::<f64>(FRAME_FIGURES);
                let (w, h) = (scene.render.width, scene.render.height);
                if pixels.len() != 4 * (w * h) as usize || f.len() != 5 {
                    bail!(
                        "frame {i}: process {holder} sent {} values for {w}×{h} pixels",
                        pixels.len()
                    );
                }
                let image = voxcast::Image {
                    width: w,
                    height: h,
                    pixels: pixels
                        .chunks_exact(4)
                        .map(|c| [c[0], c[1], c[2], c[3]])
                        .collect(),
                };
                let stats = voxcast::RenderStats {
                    seconds: f[1],
                    rays: f[2] as u64,
                    samples: f[3] as u64,
                    interpolations: f[4] as u64,
                    ..Default::default()
                };
                (f[0], image, stats)
            };
            match job {
                Job::Whole(p) => busy[p] += stats.seconds,
                Job::Split { .. } => split_seconds.push(stats.seconds),
            }
            emit(i, time, &image, &stats)?;
        }
        Ok(())
    })?;
    if !a.quiet {
        let mut s = format!(
            "{n} processes in {:.2} s wall; whole frames' rendering per process {}",
            start.elapsed().as_secs_f64(),
            busy.iter()
                .map(|s| format!("{s:.2} s"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        if !split_seconds.is_empty() {
            s += &format!(
                "; split frames {:.3} s each (slowest part and compositing, mean of {})",
                split_seconds.iter().sum::<f64>() / split_seconds.len() as f64,
                split_seconds.len()
            );
        }
        eprintln!("{s}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_last_round_is_split_only_when_the_pilot_finds_it_faster() {
        let t = |whole, split| PilotTimes {
            size: (64, 48),
            whole,
            split,
        };
        assert!(t(1.0, Some(0.6)).split_is_faster());
        // Within 5 %: not worth the compositing and the idle wait.
        assert!(!t(1.0, Some(0.97)).split_is_faster());
        assert!(!t(1.0, Some(1.4)).split_is_faster());
        // A quick frame was not timed split.
        assert!(!t(0.01, None).split_is_faster());
    }

    #[test]
    fn whole_rounds_are_spread_and_a_partial_round_is_split_in_groups() {
        use Job::*;
        // 7 frames on 3 processes: two rounds whole, the last frame over all three.
        let j = plan(7, 3, MpiFrames::Auto, true);
        assert_eq!(
            &j[..6],
            &[Whole(0), Whole(1), Whole(2), Whole(0), Whole(1), Whole(2)]
        );
        assert_eq!(j[6], Split { first: 0, size: 3 });
        // 6 frames on 4: one round whole, then 2 frames over 2 processes each.
        let j = plan(6, 4, MpiFrames::Auto, true);
        assert_eq!(j[4], Split { first: 0, size: 2 });
        assert_eq!(j[5], Split { first: 2, size: 2 });
        // 3 frames on 4: a group of 1 would be a whole frame.
        assert!(plan(3, 4, MpiFrames::Auto, true)
            .iter()
            .all(|j| matches!(j, Whole(_))));
        // A full last round, one process, or a scene that cannot be split: whole.
        assert!(plan(8, 4, MpiFrames::Auto, true)
            .iter()
            .all(|j| matches!(j, Whole(_))));
        assert!(plan(5, 1, MpiFrames::Split, true)
            .iter()
            .all(|j| *j == Whole(0)));
        assert!(plan(1, 4, MpiFrames::Auto, false)
            .iter()
            .all(|j| *j == Whole(0)));
        // Split (auto without the pilot) plans the same; spread never splits.
        assert_eq!(
            plan(5, 2, MpiFrames::Split, true),
            plan(5, 2, MpiFrames::Auto, true)
        );
        assert_eq!(
            plan(5, 2, MpiFrames::Split, true)[4],
            Split { first: 0, size: 2 }
        );
        assert_eq!(plan(1, 4, MpiFrames::Spread, true), vec![Whole(0)]);
        // Every process is in at most one group.
        for n in 1..9 {
            for f in 1..20 {
                let j = plan(f, n, MpiFrames::Auto, true);
                for p in 0..n {
                    let groups: std::collections::BTreeSet<usize> = j
                        .iter()
                        .filter_map(|j| match *j {
                            Split { first, .. } if j.has(p) => Some(first),
                            _ => None,
                        })
                        .collect();
                    assert!(
                        groups.len() <= 1,
                        "{f} frames on {n}: process {p} in {groups:?}"
                    );
                }
            }
        }
    }
}
