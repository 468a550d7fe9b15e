//! `mpirun -np N voxcast render …` (cargo feature `mpi`): sort-last
//! parallel rendering ([`voxcast::render::sortlast`]) over MPI. Every
//! process opens the input (a Zarr store is read chunk by chunk, so each
//! reads only its part and the ghost layer around it; any other input is
//! read whole by each), renders its part with the out-of-core ray caster,
//! and the parts are composited by radix-k; process 0 writes the outputs.
//! `animate` spreads whole frames over the processes and splits the frames
//! of a last, partial round over groups of processes ([`animate`]);
//! process 0 writes them in order.
//! An error on any process ends all of them (`MPI_Abort`) with its message.

use crate::args::{BenchArgs, DeviceArg, RenderArgs};
use anyhow::{bail, Context, Result};
use mpi::topology::{Communicator, SimpleCommunicator};
use mpi::traits::{CommunicatorCollectives, Destination, Source};
use std::io::Write;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::Instant;
use voxcast::io::zarr::ZarrStore;
use voxcast::render::outofcore::{self, human_bytes, OutOfCore, OutOfCoreParams};
use voxcast::render::sortlast::{self, Exchange};
use voxcast::volume::{ChunkedSource, MemorySource};

mod animate;
pub use animate::animate;

/// Chunk edge a volume read whole is cut into for the split.
const MEMORY_CHUNK: u32 = 32;

/// MPI, when this process was started by an MPI launcher (`mpirun`,
/// `srun`); `None` for a plain start, which then runs as always.
pub fn start() -> Option<mpi::environment::Universe> {
    let launched = ["OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    if !launched {
        return None;
    }
    // The processes of one machine share its cores: each takes its share
    // of threads, unless RAYON_NUM_THREADS says otherwise.
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = (cores / local_processes() as usize).max(1);
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global();
    }
    mpi::initialize_with_threading(mpi::Threading::Funneled).map(|(u, _)| u)
}

/// The processes on this machine (Open MPI says; 1 where unknown).
fn local_processes() -> u64 {
    std::env::var("OMPI_COMM_WORLD_LOCAL_SIZE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1u64)
        .max(1)
}

/// Reports `e` naming the process, and ends every process (`MPI_Abort`)
/// where there are several: the others may be waiting on this one.
pub fn fail(world: &SimpleCommunicator, e: &anyhow::Error) -> ! {
    use std::io::Write;
    let (rank, size) = (world.rank(), world.size());
    // One write, so the processes' lines do not interleave.
    let line = format!("error (process {rank} of {size}): {e:#}\n");
    let _ = std::io::stderr().write_all(line.as_bytes());
    if size > 1 {
        world.abort(1)
    }
    std::process::exit(1)
}

/// The compositing messages over an MPI communicator.
struct MpiExchange<'w> {
    world: &'w SimpleCommunicator,
}

impl Exchange for MpiExchange<'_> {
    fn rank(&self) -> usize {
        self.world.rank() as usize
    }
    fn size(&self) -> usize {
        self.world.size() as usize
    }
    fn exchange(
        &self,
        tag: u32,
        peers: &[usize],
        out: Vec<Vec<f32>>,
    ) -> voxcast::Result<Vec<Vec<f32>>> {
        let me = self.rank();
        let tag = tag as i32;
        Ok(mpi::request::scope(|scope| {
            // Post every send, then receive: no order of the group can
            // deadlock.
            let sends: Vec<_> = peers
                .iter()
                .zip(&out)
                .filter(|(p, _)| **p != me)
                .map(|(&p, v)| {
                    self.world
                        .process_at_rank(p as i32)
                        .immediate_send_with_tag(scope, &v[..], tag)
                })
                .collect();
            let got = peers
                .iter()
                .map(|&p| {
                    if p == me {
                        Vec::new()
                    } else {
                        self.world
                            .process_at_rank(p as i32)
                            .receive_vec_with_tag::<f32>(tag)
                            .0
                    }
                })
                .collect();
            for s in sends {
                s.wait();
            }
            got
        }))
    }
    fn barrier(&self) -> voxcast::Result<()> {
        self.world.barrier();
        Ok(())
    }
    fn gather(&self, tag: u32, data: Vec<f32>) -> voxcast::Result<Option<Vec<Vec<f32>>>> {
        let tag = tag as i32;
        if self.rank() != 0 {
            self.world.process_at_rank(0).send_with_tag(&data[..], tag);
            return Ok(None);
        }
        let mut all = vec![data];
        for p in 1..self.size() {
            all.push(
                self.world
                    .process_at_rank(p as i32)
                    .receive_vec_with_tag::<f32>(tag)
                    .0,
            );
        }
        Ok(Some(all))
    }
}

/// The default memory budget of a process: the machine's default shared by
/// the processes on it.
fn default_budget() -> u64 {
    outofcore::default_budget() / local_processes()
}

/// The scene's input as a chunked source, the scene prepared (its transfer
/// function and window), and whether the input is a store: a Zarr store is
/// read chunk by chunk; any other input is read whole and cut into chunks.
fn open(
    scene: &voxcast::scene::Scene,
) -> Result<(Box<dyn ChunkedSource>, voxcast::scene::Prepared, bool)> {
    let path = Path::new(&scene.input.path);
    let zarr =
        !scene.input.path.starts_with(voxcast::builtin::PREFIX) && voxcast::io::zarr::is_zarr(path);
    if zarr {
        let store = ZarrStore::open_with(path, &scene.input.options)?;
        let (prepared, _) = super::render_chunked::prepare_from_proxy(scene, &store)?;
        Ok((Box::new(store), prepared, true))
    } else {
        let mut prepared = scene.prepare()?;
        let src = memory_source(&mut prepared)?;
        Ok((Box::new(src), prepared, false))
    }
}

/// A volume read whole, cut into chunks for the split: the voxels move
/// behind an `Arc`, shared by the prepared scene and the source instead of
/// copied.
fn memory_source(prepared: &mut voxcast::scene::Prepared) -> Result<MemorySource> {
    let tiny = voxcast::Volume::new(
        [1, 1, 1],
        glam::Vec3::ONE,
        glam::Vec3::ZERO,
        voxcast::VoxelData::U8(vec![0u8].into()),
    )?;
    let volume = std::mem::replace(&mut prepared.volume, tiny).into_shared();
    prepared.volume = volume.clone();
    Ok(MemorySource::new(volume, 0, [MEMORY_CHUNK; 3])?.with_ranges())
}

/// One process's figures of a render, sent to process 0 as `f32`s.
#[derive(Clone, Copy, serde::Serialize)]
struct Figures {
    render_seconds: f64,
    composite_seconds: f64,
    bytes_sent: f64,
    visible_chunks: f64,
    samples: f64,
    bytes_read: f64,
    wait_seconds: f64,
}

impl Figures {
    fn of(r: &sortlast::SortLast) -> Figures {
        let s = &r.sort_last;
        Figures {
            render_seconds: s.render_seconds,
            composite_seconds: s.composite.seconds,
            bytes_sent: s.composite.bytes_sent as f64,
            visible_chunks: s.weight as f64,
            samples: r.stats.samples as f64,
            bytes_read: s.out_of_core.bytes_read as f64,
            wait_seconds: s.wait_seconds,
        }
    }

    fn to_message(self) -> Vec<f32> {
        [
            self.render_seconds,
            self.composite_seconds,
            self.bytes_sent,
            self.visible_chunks,
            self.samples,
            self.bytes_read,
            self.wait_seconds,
        ]
        .map(|v| v as f32)
        .to_vec()
    }

    fn from_message(v: &[f32]) -> Result<Figures> {
        let &[render_seconds, composite_seconds, bytes_sent, visible_chunks, samples, bytes_read, wait_seconds] =
            v
        else {
            bail!("a process sent {} figures, expected 7", v.len());
        };
        let f = |x: f32| x as f64;
        Ok(Figures {
            render_seconds: f(render_seconds),
            composite_seconds: f(composite_seconds),
            bytes_sent: f(bytes_sent),
            visible_chunks: f(visible_chunks),
            samples: f(samples),
            bytes_read: f(bytes_read),
            wait_seconds: f(wait_seconds),
        })
    }
}

/// Every process's [`Figures`] of one render, on process 0 (`None`
/// elsewhere).
fn gather_figures(ex: &MpiExchange<'_>, r: &sortlast::SortLast) -> Result<Option<Vec<Figures>>> {
    ex.gather(1000, Figures::of(r).to_message())?
        .map(|all| all.iter().map(|v| Figures::from_message(v)).collect())
        .transpose()
}

/// The largest and the sum of one figure over the processes.
fn max_of(all: &[Figures], f: impl Fn(&Figures) -> f64) -> f64 {
    all.iter().map(f).fold(0.0, f64::max)
}

fn sum_of(all: &[Figures], f: impl Fn(&Figures) -> f64) -> f64 {
    all.iter().map(f).sum()
}

/// `voxcast render` on every process of `world`.
pub fn render(a: &RenderArgs, world: &SimpleCommunicator) -> Result<()> {
    let ex = MpiExchange { world };
    let (rank, n) = (ex.rank(), ex.size());
    let lead = rank == 0 && !a.quiet;
    let scene = a.scene()?;
    if a.quality.is_some() {
        bail!("--quality: not available under MPI (the pilot renders the whole volume on one process); give --step");
    }
    if !matches!(a.device, DeviceArg::Cpu) {
        bail!("--device: under MPI, voxcast renders on the CPU of each process; leave --device at cpu");
    }
    sortlast::check_params(&scene.render)?;
    // Process 0 writes; it checks every output before any work.
    let mut planned = if rank == 0 {
        Some(super::render::plan_outputs(a, &scene)?)
    } else {
        None
    };
    let t_load = Instant::now();
    let (source, prepared, zarr) = open(&scene)?;
    if let Some((outputs, _)) = planned.as_mut() {
        outputs.check()?;
    }
    if prepared.geometry.is_some() {
        bail!("--geometry: opaque geometry is not rendered under MPI");
    }
    let ooc = OutOfCore::new(
        source.as_ref(),
        OutOfCoreParams {
            budget: a.memory_budget.unwrap_or_else(default_budget),
            level: scene.input.options.level,
            lod_scale: crate::cmd::render_chunked::lod_scale(&scene)?,
            ..Default::default()
        },
    );
    let levels = source.levels();
    if lead {
        let d = levels[0].dims;
        eprintln!(
            "opened {} on {n} process{} — {}×{}×{} {} ({:.2} s){}",
            scene.input.path,
            if n == 1 { "" } else { "es" },
            d[0],
            d[1],
            d[2],
            source.scalar_type(),
            t_load.elapsed().as_secs_f64(),
            if zarr {
                ", each reading its part's chunks"
            } else {
                ", read whole by each"
            }
        );
        if scene.render.ert < 1.0 {
            eprintln!("note: early ray termination is off under MPI (a process does not see the opacity in front of its part); the picture is the one-process render's with --ert 1");
        }
    }
    let r = sortlast::render(
        &ex,
        &ooc,
        &prepared.tf,
        prepared.window,
        &scene.camera,
        &scene.render,
        a.show_parts,
        &|_, _| {},
        &AtomicBool::new(false),
    )
    .with_context(|| format!("process {rank} of {n}"))?;
    // Every process's figures, to process 0.
    let s = &r.sort_last;
    let all = gather_figures(&ex, &r)?;
    let (Some(image), Some(all), Some((mut outputs, out))) = (r.image, all, planned) else {
        return Ok(());
    };
    let pixels = (image.width * image.height) as f64;
    let per_rank: Vec<serde_json::Value> = all
        .iter()
        .enumerate()
        .map(|(p, f)| {
            let mut v = serde_json::to_value(f).unwrap_or_default();
            if let serde_json::Value::Object(m) = &mut v {
                m.insert("rank".into(), p.into());
            }
            v
        })
        .collect();
    let sent = sum_of(&all, |f| f.bytes_sent);
    let samples = sum_of(&all, |f| f.samples);
    let slowest = max_of(&all, |f| f.render_seconds);
    let compositing = max_of(&all, |f| f.composite_seconds);
    let mut stats = r.stats;
    stats.samples = samples as u64;
    stats.interpolations = samples as u64;
    stats.seconds = slowest + compositing;
    let mut extra = serde_json::Map::new();
    extra.insert(
        "device".into(),
        format!("cpu, sort-last over {n} MPI processes").into(),
    );
    extra.insert(
        "mpi".into(),
        serde_json::json!({
            "processes": n,
            "rounds": sortlast::rounds(n),
            "level": s.out_of_core.level,
            "bytes_per_pixel": sent / pixels,
            "render_seconds_max": slowest,
            "composite_seconds_max": compositing,
            "per_process": per_rank,
        }),
    );
    super::render::write_outputs(
        a,
        &mut outputs,
        &out,
        &image,
        &stats,
        extra,
        &scene,
        &prepared,
    )?;
    outputs.commit()?;
    if !a.quiet {
        let mean = sum_of(&all, |f| f.render_seconds) / n as f64;
        eprintln!(
            "wrote {} ({}×{}) on {n} process{}: render {:.3} s (slowest; mean {:.3} s, balance {:.0} %), compositing {:.3} s in {} rounds of radix-k {:?}, {:.1} bytes per pixel sent, {} read; {} samples",
            out.display(),
            image.width,
            image.height,
            if n == 1 { "" } else { "es" },
            slowest,
            mean,
            if slowest > 0.0 { 100.0 * mean / slowest } else { 100.0 },
            compositing,
            sortlast::rounds(n).len(),
            sortlast::rounds(n),
            sent / pixels,
            human_bytes(sum_of(&all, |f| f.bytes_read) as u64),
            samples as u64,
        );
    }
    Ok(())
}

/// `voxcast bench` on every process of `world`: each method that a
/// sort-last render can run is rendered `--warmup` times and then
/// `--repeat` times with the chunk cache warm, and process 0 prints the
/// medians — the frame (the slowest render plus compositing), each
/// process's render, the wait for the slowest, compositing, bytes sent per
/// pixel — and the PSNR against one process's render of the same method
/// (`--ert 1`, out of core).
pub fn bench(a: &BenchArgs, world: &SimpleCommunicator) -> Result<()> {
    use voxcast_bench as vb;
    let ex = MpiExchange { world };
    let (rank, n) = (ex.rank(), ex.size());
    let lead = rank == 0 && !a.quiet;
    if !a.target_psnr.is_empty() || a.quality.is_some() {
        bail!("--target-psnr, --quality: not available under MPI (their pilots render the whole volume on one process)");
    }
    if !matches!(a.device, DeviceArg::Cpu) {
        bail!("--device: under MPI, voxcast renders on the CPU of each process; leave --device at cpu");
    }
    if a.chart.is_some() {
        bail!("--chart: not drawn under MPI; use --json");
    }
    if a.repeat == 0 {
        bail!("--repeat 0: at least one timed render per method is needed");
    }
    let scene = a.scene.scene()?;
    let mut outputs = voxcast::files::Outputs::new([&scene.input.path]);
    if rank == 0 {
        outputs.plan_optional("--json", a.json.as_deref(), &[])?;
    }
    let (source, prepared, _) = open(&scene)?;
    if rank == 0 {
        outputs.check()?;
    }
    let mut methods = Vec::new();
    let mut skipped = Vec::new();
    for spec in vb::parse_methods(&a.methods)? {
        let params = vb::method_params(&scene.render, &spec);
        match sortlast::check_params(&params) {
            Ok(()) => methods.push((spec.to_string(), params)),
            Err(_) => skipped.push(spec.to_string()),
        }
    }
    if methods.is_empty() {
        bail!(
            "--methods {}: none of them runs under MPI (uniform and jitter do)",
            a.methods
        );
    }
    if lead && !skipped.is_empty() {
        eprintln!(
            "under MPI, skipped {}: they decide along the whole ray, which no process holds",
            skipped.join(", ")
        );
    }
    let ooc = OutOfCore::new(
        source.as_ref(),
        OutOfCoreParams {
            budget: default_budget(),
            level: scene.input.options.level,
            lod_scale: crate::cmd::render_chunked::lod_scale(&scene)?,
            ..Default::default()
        },
    );
    let never = AtomicBool::new(false);
    let mut rows = Vec::new();
    let mut table = String::from(
        "| method | frame (render + compositing) | render, slowest (mean) | wait | compositing | bytes sent / pixel | samples | PSNR vs 1 process |\n|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for (label, params) in &methods {
        let mut runs: Vec<Vec<Figures>> = Vec::new();
        let mut last = None;
        for k in 0..a.warmup + a.repeat {
            let r = sortlast::render(
                &ex,
                &ooc,
                &prepared.tf,
                prepared.window,
                &scene.camera,
                params,
                false,
                &|_, _| {},
                &never,
            )
            .with_context(|| format!("{label}, process {rank} of {n}"))?;
            let all = gather_figures(&ex, &r)?;
            if let (true, Some(all)) = (k >= a.warmup, all) {
                runs.push(all);
            }
            last = r.image;
        }
        if rank != 0 {
            continue;
        }
        // One process, for the picture.
        let mut one = params.clone();
        one.ert = 1.0;
        let (alone, ..) = ooc.render(
            &prepared.tf,
            prepared.window,
            &scene.camera,
            &one,
            &|_, _| {},
            &never,
        )?;
        let image = last.context("process 0 holds the image")?;
        let db = voxcast::metrics::psnr(&image, &alone)?;
        let med = |f: &dyn Fn(&[Figures]) -> f64| {
            vb::median(&runs.iter().map(|all| f(all)).collect::<Vec<_>>())
        };
        let render = med(&|all| max_of(all, |f| f.render_seconds));
        let mean = med(&|all| sum_of(all, |f| f.render_seconds) / n as f64);
        let composite = med(&|all| max_of(all, |f| f.composite_seconds));
        let wait = med(&|all| max_of(all, |f| f.wait_seconds));
        let pixels = (params.width * params.height) as f64;
        let bpp = med(&|all| sum_of(all, |f| f.bytes_sent) / pixels);
        let samples = med(&|all| sum_of(all, |f| f.samples));
        let per_process: Vec<f64> = (0..n)
            .map(|p| {
                vb::median(
                    &runs
                        .iter()
                        .map(|all| all[p].render_seconds)
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        table += &format!(
            "| {label} | {:.1} ms | {:.1} ms ({:.1}) | {:.1} ms | {:.1} ms | {bpp:.1} | {:.2} M | {} |\n",
            (render + composite) * 1e3,
            render * 1e3,
            mean * 1e3,
            wait * 1e3,
            composite * 1e3,
            samples / 1e6,
            if db.is_finite() {
                format!("{db:.1} dB")
            } else {
                "identical".into()
            }
        );
        rows.push(serde_json::json!({
            "method": label,
            "frame_seconds": render + composite,
            "render_seconds_max": render,
            "render_seconds_mean": mean,
            "render_seconds_per_process": per_process,
            "wait_seconds": wait,
            "composite_seconds": composite,
            "bytes_per_pixel": bpp,
            "samples": samples,
            "psnr_db_vs_one_process": if db.is_finite() { Some(db) } else { None },
        }));
    }
    if rank != 0 {
        return Ok(());
    }
    let mut text = format!(
        "{} on {n} MPI process{} (sort-last, radix-k {:?}), {}×{}, {} timed renders after {} warm-up, medians; early ray termination off\n",
        scene.input.path,
        if n == 1 { "" } else { "es" },
        sortlast::rounds(n),
        scene.render.width,
        scene.render.height,
        a.repeat,
        a.warmup
    );
    text += &table;
    print!("{text}");
    if let Some(f) = &a.json {
        let json = serde_json::to_string_pretty(&serde_json::json!({
            "input": scene.input.path,
            "processes": n,
            "rounds": sortlast::rounds(n),
            "width": scene.render.width,
            "height": scene.render.height,
            "repeat": a.repeat,
            "warmup": a.warmup,
            "methods": rows,
        }))?;
        outputs.write(f, |w| writeln!(w, "{json}"))?;
    }
    outputs.commit()?;
    Ok(())
}
