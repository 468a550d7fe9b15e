//! `voxcast convert`: any input (or a built-in volume of any size) to an
//! OME-Zarr multiscale pyramid, slab by slab, into a temporary folder that
//! is renamed when complete.

use crate::args::ConvertArgs;
use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;
use voxcast::io::zarr::write::{
    level_dims, write_volume, Compression, PyramidWriter, WriteOptions, ZarrFormat,
};
use voxcast::render::outofcore::human_bytes;
use voxcast::scene::Scene;
use voxcast::volume::ChunkedSource;
use voxcast::ScalarType;

pub fn run(a: ConvertArgs) -> Result<()> {
    let chunk = parse_chunk(&a.chunk)?;
    let format = match a.zarr_version {
        2 => ZarrFormat::V2,
        3 => ZarrFormat::V3,
        v => bail!("--zarr-version {v}: expected 2 or 3"),
    };
    let compression =
        Compression::parse(&a.compression).map_err(|m| anyhow::anyhow!("--compression {m}"))?;
    if a.levels == Some(0) {
        bail!("--levels 0: a store has at least one level");
    }
    let opts = WriteOptions {
        chunk,
        levels: a.levels,
        format,
        compression,
    };
    let out = &a.output;
    check_output(out, &a.input, a.overwrite)?;
    let stream = Stream::for_input(&a)?;
    // Everything is written under a temporary name beside the output and
    // renamed when complete.
    let tmp = temp_beside(out, "partial")?;
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template(
            "writing {bar:40.cyan/blue} {pos}/{len} slices {elapsed}<{eta} {msg}",
        )
        .expect("valid template"),
    );
    if std::io::stderr().is_terminal() && !a.quiet {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let start = Instant::now();
    let result = (|| -> Result<(voxcast::io::zarr::write::WriteStats, [u64; 3], f64)> {
        match stream {
            Some(src) => {
                let (dims, ty) = (src.dims, src.ty);
                let levels = level_dims(dims, &opts);
                if !a.quiet {
                    eprintln!(
                        "{} {} at {}×{}×{} {ty} ({}) slab by slab into {} levels of {}×{}×{} chunks",
                        if matches!(src.kind, Kind::Builtin(_)) { "generating" } else { "streaming" },
                        a.input,
                        dims[0],
                        dims[1],
                        dims[2],
                        human_bytes(dims.iter().product::<u64>() * ty.size() as u64),
                        levels.len(),
                        chunk[0],
                        chunk[1],
                        chunk[2]
                    );
                }
                let mut w = PyramidWriter::create(
                    &tmp,
                    dims,
                    src.spacing,
                    src.origin,
                    ty,
                    &a.input,
                    &opts,
                )?;
                bar.set_length(dims[2]);
                // Slabs of at most 64 MiB, whole slices.
                let area = dims[0] * dims[1] * ty.size() as u64;
                let step = ((64u64 << 20) / area).max(1);
                let mut z = 0;
                while z < dims[2] {
                    let z1 = (z + step).min(dims[2]);
                    w.push(src.slab(z, z1)?)?;
                    z = z1;
                    bar.set_position(z);
                    bar.set_message(rate(z * area, start));
                }
                Ok((w.finish()?, dims, 0.0))
            }
            None => {
                let t = Instant::now();
                let mut scene = Scene::default();
                scene.input.path = a.input.clone();
                scene.input.options = a.open.options()?;
                let vol = scene.load_volume()?;
                let read_s = t.elapsed().as_secs_f64();
                let d = vol.dims().map(|v| v as u64);
                if !a.quiet {
                    eprintln!(
                        "read {} — {}×{}×{} {} ({}) in {read_s:.2} s; writing {} levels of {}×{}×{} chunks",
                        a.input,
                        d[0],
                        d[1],
                        d[2],
                        vol.scalar_type(),
                        human_bytes(vol.len() as u64 * vol.scalar_type().size() as u64),
                        level_dims(d, &opts).len(),
                        chunk[0],
                        chunk[1],
                        chunk[2]
                    );
                }
                bar.set_length(d[2]);
                let area = d[0] * d[1] * vol.scalar_type().size() as u64;
                let stats = write_volume(&vol, &tmp, &opts, &|z, _| {
                    bar.set_position(z);
                    bar.set_message(rate(z * area, start));
                })?;
                Ok((stats, d, read_s))
            }
        }
    })();
    bar.finish_and_clear();
    let (stats, dims, read_s) = match result {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_dir_all(&tmp);
            return Err(e);
        }
    };
    if let Err(e) = replace(&tmp, out) {
        let _ = std::fs::remove_dir_all(&tmp);
        return Err(e);
    }
    let secs = start.elapsed().as_secs_f64();
    if !a.quiet {
        let write_s = secs - read_s;
        eprintln!(
            "wrote {} — {} levels, level 0 {}×{}×{}: {} chunks ({} of only zeros not written), {} on disk from {} ({:.1}×) in {secs:.1} s ({:.0} MB/s of input{})",
            out.display(),
            stats.levels,
            dims[0],
            dims[1],
            dims[2],
            stats.chunks_written,
            stats.chunks_empty,
            human_bytes(stats.bytes_written),
            human_bytes(stats.bytes_level0),
            stats.bytes_level0 as f64 / stats.bytes_written.max(1) as f64,
            stats.bytes_level0 as f64 / 1e6 / write_s.max(1e-9),
            if read_s > 0.0 {
                format!(", after {read_s:.1} s reading")
            } else {
                String::new()
            }
        );
    }
    Ok(())
}

/// An input read slab by slab: a built-in volume generated at any size, a
/// raw file, or a level of a Zarr store. Other readers load whole volumes.
struct Stream {
    kind: Kind,
    dims: [u64; 3],
    ty: ScalarType,
    spacing: glam::Vec3,
    origin: glam::Vec3,
}

enum Kind {
    Builtin(String),
    Raw(PathBuf, voxcast::io::RawLayout),
    Zarr(Box<voxcast::io::zarr::ZarrStore>, usize),
}

impl Stream {
    /// The streaming source for `a`'s input, or `None` for a reader that
    /// loads whole volumes.
    fn for_input(a: &ConvertArgs) -> Result<Option<Stream>> {
        let opts = a.open.options()?;
        let spacing = opts.spacing.map(glam::Vec3::from);
        if let Some(name) = a.input.strip_prefix(voxcast::builtin::PREFIX) {
            let Some(d) = &a.dims else {
                return Ok(None);
            };
            let dims: Vec<u64> = d
                .split(',')
                .map(|p| p.trim().parse::<u64>())
                .collect::<std::result::Result<_, _>>()
                .ok()
                .filter(|v: &Vec<u64>| v.len() == 3 && !v.contains(&0))
                .with_context(|| {
                    format!("--dims {d}: expected three positive whole numbers X,Y,Z")
                })?;
            let ty = ScalarType::parse(&a.scalar_type).with_context(|| {
                format!("--type {}: expected u8, u16, i16 or f32", a.scalar_type)
            })?;
            if !voxcast::builtin::SIZED.contains(&name) {
                bail!(
                    "--dims: {} is not generated at other sizes (these are: {})",
                    a.input,
                    voxcast::builtin::SIZED.join(", ")
                );
            }
            let dims = [dims[0], dims[1], dims[2]];
            voxcast::volume::checked_voxel_count(dims)
                .map_err(|m| anyhow::anyhow!("--dims {d}: {m}"))?;
            return Ok(Some(Stream {
                kind: Kind::Builtin(name.to_string()),
                dims,
                ty,
                spacing: spacing.unwrap_or(glam::Vec3::ONE),
                origin: glam::Vec3::ZERO,
            }));
        }
        if a.dims.is_some() {
            bail!("--dims is for builtin:NAME inputs (a file has its own size)");
        }
        let path = Path::new(&a.input);
        if let Some(layout) = opts.raw.clone() {
            let (_, need) =
                voxcast::io::util::check_dims(path, "--raw-dims", layout.dims, layout.scalar_type)?;
            let len = voxcast::files::regular_file(path)?.len();
            if len < layout.header_bytes.saturating_add(need) {
                bail!(
                    "{}: --raw-dims/--raw-type describe {need} bytes of voxels after byte {} but the file has {len} bytes (truncated file or wrong dims/type)",
                    path.display(),
                    layout.header_bytes
                );
            }
            return Ok(Some(Stream {
                kind: Kind::Raw(path.to_path_buf(), layout.clone()),
                dims: layout.dims,
                ty: layout.scalar_type,
                spacing: spacing.unwrap_or(glam::Vec3::ONE),
                origin: glam::Vec3::ZERO,
            }));
        }
        if voxcast::io::detect(path, &opts).ok() == Some(voxcast::io::Format::Zarr) {
            let store = voxcast::io::zarr::ZarrStore::open_with(path, &opts)?;
            let n = store.levels().len();
            let level = opts.level.unwrap_or(0);
            if level >= n {
                bail!("--level {level}: {} has levels 0…{}", path.display(), n - 1);
            }
            let l = store.levels()[level].clone();
            return Ok(Some(Stream {
                dims: l.dims,
                ty: store.scalar_type(),
                spacing: spacing.unwrap_or(l.spacing),
                origin: l.origin,
                kind: Kind::Zarr(Box::new(store), level),
            }));
        }
        Ok(None)
    }

    /// Slices `z0..z1`, x fastest.
    fn slab(&self, z0: u64, z1: u64) -> Result<voxcast::VoxelData> {
        let d = self.dims;
        Ok(match &self.kind {
            Kind::Builtin(name) => voxcast::builtin::slab(name, d, self.ty, z0, z1)?,
            Kind::Raw(path, layout) => {
                let area = d[0] * d[1] * self.ty.size() as u64;
                voxcast::io::util::read_payload(
                    path,
                    layout.header_bytes + z0 * area,
                    (z1 - z0) * area,
                    self.ty,
                    layout.big_endian,
                    false,
                    "--raw-dims/--raw-type",
                )?
            }
            Kind::Zarr(store, level) => store.read_box(*level, [0, 0, z0], [d[0], d[1], z1])?,
        })
    }
}

fn rate(bytes: u64, start: Instant) -> String {
    format!(
        "{:.0} MB/s",
        bytes as f64 / 1e6 / start.elapsed().as_secs_f64().max(1e-9)
    )
}

fn parse_chunk(s: &str) -> Result<[u32; 3]> {
    let v: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse::<u32>())
        .collect::<std::result::Result<_, _>>()
        .ok()
        .filter(|v: &Vec<u32>| (v.len() == 1 || v.len() == 3) && !v.contains(&0))
        .with_context(|| format!("--chunk {s}: expected a positive edge N or X,Y,Z"))?;
    Ok(if v.len() == 1 {
        [v[0]; 3]
    } else {
        [v[0], v[1], v[2]]
    })
}

/// Refuses an output that is an input, holds the input, lies inside an
/// input folder, or exists (unless `--overwrite` and it is a Zarr store).
fn check_output(out: &Path, input: &str, overwrite: bool) -> Result<()> {
    voxcast::files::check_folder("-o", out, &[input])?;
    if !input.starts_with(voxcast::builtin::PREFIX) {
        if let (Ok(o), Ok(i)) = (out.canonicalize(), Path::new(input).canonicalize()) {
            if i.starts_with(&o) {
                bail!(
                    "-o {}: refusing to replace a folder that holds the input {input}",
                    out.display()
                );
            }
        }
    }
    if out.exists() || out.is_symlink() {
        if !overwrite {
            bail!(
                "-o {}: exists; give --overwrite to replace it (only a Zarr store is replaced)",
                out.display()
            );
        }
        if !voxcast::io::zarr::is_zarr(out) || out.is_symlink() {
            bail!(
                "-o {}: exists and is not a Zarr store; refusing to replace it",
                out.display()
            );
        }
    }
    match out.parent().filter(|p| !p.as_os_str().is_empty()) {
        Some(p) if !p.is_dir() => bail!(
            "-o {}: the folder {} does not exist",
            out.display(),
            p.display()
        ),
        _ => Ok(()),
    }
}

/// A name beside `out` that does not exist: `.NAME.TAG-PID-N`.
fn temp_beside(out: &Path, tag: &str) -> Result<PathBuf> {
    let name = out
        .file_name()
        .with_context(|| format!("-o {}: expected a folder name", out.display()))?
        .to_string_lossy()
        .into_owned();
    let dir = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    for n in 0..1000 {
        let p = dir.join(format!(".{name}.{tag}-{}-{n}", std::process::id()));
        if !p.exists() {
            return Ok(p);
        }
    }
    bail!("-o {}: no free temporary name beside it", out.display())
}

/// Moves the finished store `tmp` to `out`, replacing an old store only
/// once the new one is in place.
fn replace(tmp: &Path, out: &Path) -> Result<()> {
    if out.exists() {
        let old = temp_beside(out, "old")?;
        std::fs::rename(out, &old)
            .with_context(|| format!("moving the old {} aside", out.display()))?;
        if let Err(e) = std::fs::rename(tmp, out) {
            let _ = std::fs::rename(&old, out);
            return Err(e).with_context(|| format!("renaming the new store to {}", out.display()));
        }
        std::fs::remove_dir_all(&old)
            .with_context(|| format!("removing the old store (now {})", old.display()))?;
    } else {
        std::fs::rename(tmp, out)
            .with_context(|| format!("renaming the new store to {}", out.display()))?;
    }
    Ok(())
}
