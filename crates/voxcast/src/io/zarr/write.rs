//! Writing OME-Zarr multiscale pyramids (`voxcast convert`), streaming:
//! the finest level arrives in slabs of whole z slices
//! ([`PyramidWriter::push`]); each level writes a row of chunks as soon as
//! it holds one and hands the 2×2×2 means of its slices
//! ([`crate::volume::chunked::downsample2_data`]) to the next, so no level is
//! ever held whole. Zarr v3 with OME-Zarr 0.5 metadata, or Zarr v2 with
//! OME-Zarr 0.4; chunks compressed by zstd, blosc (zstd, byte shuffle) or
//! gzip. A chunk that holds only the fill value is not written (Zarr's
//! rule: it reads back as the fill value). Each level's per-chunk value
//! ranges go to the sidecar [`super::RANGES_FILE`].

use super::ranges::{ranges_bytes, RANGES_FILE};
use crate::error::{Error, Result};
use crate::volume::chunked::{downsample2_data, half_dims};
use crate::volume::{ScalarType, Volume, VoxelData};
use glam::Vec3;
use rayon::prelude::*;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use zarrs::array::{Array, ArrayMetadata};
use zarrs::filesystem::FilesystemStore;
use zarrs::storage::storage_adapter::performance_metrics::PerformanceMetricsStorageAdapter;

type Storage = PerformanceMetricsStorageAdapter<FilesystemStore>;

/// The Zarr version (and with it the OME-Zarr version) to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ZarrFormat {
    /// Zarr v2 with OME-Zarr 0.4 metadata (`.zgroup`, `.zattrs`, `.zarray`).
    V2,
    /// Zarr v3 with OME-Zarr 0.5 metadata (`zarr.json`).
    V3,
}

/// How chunks are compressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compression {
    /// zstd at this level (1–22).
    Zstd(i32),
    /// Blosc with zstd inside and byte shuffle, at this level (0–9).
    Blosc(u8),
    /// gzip at this level (0–9).
    Gzip(u32),
    /// Raw bytes.
    None,
}

impl Compression {
    /// Parses `zstd`, `zstd:5`, `blosc`, `blosc:9`, `gzip`, `gzip:6`, `none`.
    pub fn parse(s: &str) -> std::result::Result<Compression, String> {
        let (name, level) = match s.split_once(':') {
            Some((n, l)) => (
                n,
                Some(
                    l.parse::<i32>()
                        .map_err(|_| format!("{s}: the level after ':' must be a whole number"))?,
                ),
            ),
            None => (s, None),
        };
        let check = |lo: i32, hi: i32, d: i32| -> std::result::Result<i32, String> {
            let l = level.unwrap_or(d);
            if (lo..=hi).contains(&l) {
                Ok(l)
            } else {
                Err(format!("{s}: {name}'s level must be in {lo}…{hi}"))
            }
        };
        match name {
            "zstd" => Ok(Compression::Zstd(check(1, 22, 3)?)),
            "blosc" => Ok(Compression::Blosc(check(0, 9, 5)? as u8)),
            "gzip" => Ok(Compression::Gzip(check(0, 9, 5)? as u32)),
            "none" if level.is_none() => Ok(Compression::None),
            _ => Err(format!(
                "{s}: expected zstd, blosc, gzip or none, optionally with a level (zstd:3)"
            )),
        }
    }
}

/// How to write a store.
#[derive(Clone, Debug, PartialEq)]
pub struct WriteOptions {
    /// Chunk shape (x, y, z) in voxels.
    pub chunk: [u32; 3],
    /// Levels in all (level 0 and its halvings); `None`: until a level fits
    /// in one chunk (at most 12).
    pub levels: Option<usize>,
    pub format: ZarrFormat,
    pub compression: Compression,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            chunk: [64; 3],
            levels: None,
            format: ZarrFormat::V3,
            compression: Compression::Zstd(3),
        }
    }
}

/// The dims of every level `opts` gives a volume of `dims`.
pub fn level_dims(dims: [u64; 3], opts: &WriteOptions) -> Vec<[u64; 3]> {
    let mut out = vec![dims];
    let fits = |d: &[u64; 3]| (0..3).all(|a| d[a] <= opts.chunk[a] as u64);
    loop {
        let last = *out.last().expect("level 0");
        let more = match opts.levels {
            Some(n) => out.len() < n,
            None => !fits(&last) && out.len() < 12,
        };
        if !more || last == [1, 1, 1] {
            break;
        }
        out.push(half_dims(last));
    }
    out
}

/// What a write did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct WriteStats {
    /// Levels written.
    pub levels: usize,
    /// Chunks written (holding more than the fill value), all levels.
    pub chunks_written: u64,
    /// Chunks of only the fill value, left unwritten.
    pub chunks_empty: u64,
    /// Bytes written to the store (compressed chunks and metadata).
    pub bytes_written: u64,
    /// Decoded bytes of level 0.
    pub bytes_level0: u64,
}

/// A voxel type the writer handles.
trait Elem: zarrs::array::Element + Copy + Send + Sync + PartialEq + Default + 'static {
    fn wrap(v: Vec<Self>) -> VoxelData;
    fn take(d: VoxelData) -> Option<Vec<Self>>;
    fn f(self) -> f32;
}

macro_rules! elem {
    ($t:ty, $var:ident) => {
        impl Elem for $t {
            fn wrap(v: Vec<Self>) -> VoxelData {
                VoxelData::$var(v.into())
            }
            fn take(d: VoxelData) -> Option<Vec<Self>> {
                match d {
                    VoxelData::$var(v) => Some(v.into_vec()),
                    _ => None,
                }
            }
            fn f(self) -> f32 {
                self as f32
            }
        }
    };
}
elem!(u8, U8);
elem!(u16, U16);
elem!(i16, I16);
elem!(f32, F32);

/// One level being written.
struct LevelWriter<T: Elem> {
    dims: [u64; 3],
    chunk: [u64; 3],
    array: Array<Storage>,
    /// Slices `[buf_z0, buf_z0 + buf.len() / area)` not yet written.
    buf: Vec<T>,
    buf_z0: u64,
    /// Slices received so far.
    received: u64,
    /// A slice (at an even z) waiting for its partner, for the next level.
    odd: Option<Vec<T>>,
    minmax: Vec<[f32; 2]>,
    written: u64,
    empty: u64,
}

impl<T: Elem> LevelWriter<T> {
    fn area(&self) -> usize {
        (self.dims[0] * self.dims[1]) as usize
    }

    fn counts(&self) -> [u64; 3] {
        std::array::from_fn(|a| self.dims[a].div_ceil(self.chunk[a]))
    }

    /// Writes every whole row of chunks the buffer holds (and the last,
    /// short one once the level is complete).
    fn flush(&mut self, path: &Path) -> Result<()> {
        let area = self.area();
        loop {
            let have = (self.buf.len() / area) as u64;
            let row = self.buf_z0 / self.chunk[2];
            let z1 = ((row + 1) * self.chunk[2]).min(self.dims[2]);
            if self.buf_z0 + have < z1 {
                return Ok(());
            }
            let n = (z1 - self.buf_z0) as usize;
            let done = self.write_row(row, &self.buf[..n * area], path)?;
            let counts = self.counts();
            for (i, mm, empty) in done {
                self.minmax[(i + counts[0] * counts[1] * row) as usize] = mm;
                if empty {
                    self.empty += 1;
                } else {
                    self.written += 1;
                }
            }
            self.buf.drain(..n * area);
            self.buf_z0 = z1;
            if z1 == self.dims[2] {
                return Ok(());
            }
        }
    }

    /// Writes chunk row `row` from `slab` (its slices); returns each
    /// chunk's index in the row, value range and whether it held only fill.
    fn write_row(&self, row: u64, slab: &[T], path: &Path) -> Result<Vec<(u64, [f32; 2], bool)>> {
        let counts = self.counts();
        let [dx, dy, _] = self.dims.map(|d| d as usize);
        let nz = slab.len() / (dx * dy);
        let fill = T::default();
        let cells: Vec<(u64, u64)> = (0..counts[1])
            .flat_map(|cy| (0..counts[0]).map(move |cx| (cx, cy)))
            .collect();
        cells
            .par_iter()
            .map(|&(cx, cy)| {
                let x0 = (cx * self.chunk[0]) as usize;
                let y0 = (cy * self.chunk[1]) as usize;
                // Chunks are stored whole: the part past the edge is fill.
                let [cw, ch, cd] = self.chunk.map(|c| c as usize);
                let x1 = (x0 + cw).min(dx);
                let y1 = (y0 + ch).min(dy);
                let mut out = vec![fill; cw * ch * cd];
                let mut lo = f32::INFINITY;
                let mut hi = f32::NEG_INFINITY;
                let mut all_fill = true;
                for z in 0..nz {
                    for y in y0..y1 {
                        let src = &slab[(z * dy + y) * dx + x0..(z * dy + y) * dx + x1];
                        let o = (z * ch + (y - y0)) * cw;
                        out[o..o + (x1 - x0)].copy_from_slice(src);
                        for &v in src {
                            let f = v.f();
                            if f.is_finite() {
                                lo = lo.min(f);
                                hi = hi.max(f);
                            }
                            all_fill &= v == fill;
                        }
                    }
                }
                let idx = [row, cy, cx];
                if !all_fill {
                    self.array.store_chunk(&idx, out.as_slice()).map_err(|e| {
                        Error::format(
                            path,
                            format!("chunk {}", self.array.chunk_key(&idx)),
                            format!("writing: {e}"),
                        )
                    })?;
                }
                let mm = if lo <= hi { [lo, hi] } else { [f32::NAN; 2] };
                Ok((cx + counts[0] * cy, mm, all_fill))
            })
            .collect()
    }
}

/// Writes a multiscale pyramid into a new folder.
pub struct PyramidWriter {
    inner: Inner,
    path: PathBuf,
    storage: Arc<Storage>,
    received: u64,
    dims: [u64; 3],
}

enum Inner {
    U8(Vec<LevelWriter<u8>>),
    U16(Vec<LevelWriter<u16>>),
    I16(Vec<LevelWriter<i16>>),
    F32(Vec<LevelWriter<f32>>),
}

impl PyramidWriter {
    /// Creates the store at `path` (a folder that must not exist yet) for a
    /// volume of `dims` voxels of `ty`, with level 0's `spacing` and
    /// `origin`, and writes its metadata.
    pub fn create(
        path: &Path,
        dims: [u64; 3],
        spacing: Vec3,
        origin: Vec3,
        ty: ScalarType,
        name: &str,
        opts: &WriteOptions,
    ) -> Result<PyramidWriter> {
        crate::volume::checked_voxel_count(dims).map_err(Error::invalid)?;
        if opts.chunk.contains(&0) {
            return Err(Error::invalid("--chunk: every edge must be at least 1"));
        }
        if opts.chunk.iter().map(|&c| c as u64).product::<u64>() * ty.size() as u64 > 1 << 30 {
            return Err(Error::invalid(format!(
                "--chunk {}×{}×{}: chunks of {ty} over 1 GiB",
                opts.chunk[0], opts.chunk[1], opts.chunk[2]
            )));
        }
        if opts.levels == Some(0) {
            return Err(Error::invalid("--levels: at least 1"));
        }
        std::fs::create_dir(path).map_err(|e| Error::io(path, e))?;
        let fs =
            FilesystemStore::new(path).map_err(|e| Error::format(path, "store", e.to_string()))?;
        let storage = Arc::new(PerformanceMetricsStorageAdapter::new(Arc::new(fs)));
        let dims_l = level_dims(dims, opts);
        let chunk = opts.chunk.map(|c| c as u64);
        let mut datasets = Vec::new();
        let mut arrays = Vec::new();
        // Each level covers the same world box: spacing ×2 and the first
        // voxel at the centre of the 2×2×2 it averages, step by step as
        // `downsample2` does (an axis of one voxel keeps its spacing).
        let (mut s, mut o) = (spacing, origin);
        for (l, d) in dims_l.iter().enumerate() {
            if l > 0 {
                let prev = dims_l[l - 1];
                let f = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
                    if prev[a] > 1 {
                        2.0
                    } else {
                        1.0
                    }
                }));
                o += s * (f - Vec3::ONE) * 0.5;
                s *= f;
            }
            datasets.push(json!({
                "path": l.to_string(),
                "coordinateTransformations": [
                    {"type": "scale", "scale": [s.z, s.y, s.x]},
                    {"type": "translation", "translation": [o.z, o.y, o.x]},
                ]
            }));
            let meta = array_metadata(*d, chunk, ty, opts)?;
            let array = Array::new_with_metadata(storage.clone(), &format!("/{l}"), meta)
                .map_err(|e| Error::format(path, format!("level {l}"), e.to_string()))?;
            array
                .store_metadata()
                .map_err(|e| Error::format(path, format!("level {l}"), e.to_string()))?;
            arrays.push((*d, array));
        }
        let axes = json!([
            {"name": "z", "type": "space"},
            {"name": "y", "type": "space"},
            {"name": "x", "type": "space"},
        ]);
        let voxcast = json!({ "chunk_ranges": RANGES_FILE, "source": name });
        match opts.format {
            ZarrFormat::V3 => {
                let ms = json!([{ "name": name, "axes": axes, "datasets": datasets }]);
                let group = json!({
                    "zarr_format": 3,
                    "node_type": "group",
                    "attributes": {
                        "ome": {"version": "0.5", "multiscales": ms},
                        "voxcast": voxcast,
                    }
                });
                write_json(&path.join("zarr.json"), &group)?;
            }
            ZarrFormat::V2 => {
                let ms =
                    json!([{ "version": "0.4", "name": name, "axes": axes, "datasets": datasets }]);
                write_json(&path.join(".zgroup"), &json!({"zarr_format": 2}))?;
                write_json(
                    &path.join(".zattrs"),
                    &json!({"multiscales": ms, "voxcast": voxcast}),
                )?;
            }
        }
        macro_rules! levels {
            ($t:ty) => {
                arrays
                    .into_iter()
                    .map(|(d, array)| {
                        let counts: [u64; 3] = std::array::from_fn(|a| d[a].div_ceil(chunk[a]));
                        LevelWriter::<$t> {
                            dims: d,
                            chunk,
                            array,
                            buf: Vec::new(),
                            buf_z0: 0,
                            received: 0,
                            odd: None,
                            minmax: vec![[f32::NAN; 2]; counts.iter().product::<u64>() as usize],
                            written: 0,
                            empty: 0,
                        }
                    })
                    .collect()
            };
        }
        let inner = match ty {
            ScalarType::U8 => Inner::U8(levels!(u8)),
            ScalarType::U16 => Inner::U16(levels!(u16)),
            ScalarType::I16 => Inner::I16(levels!(i16)),
            ScalarType::F32 => Inner::F32(levels!(f32)),
        };
        Ok(PyramidWriter {
            inner,
            path: path.to_path_buf(),
            storage,
            received: 0,
            dims,
        })
    }

    /// The next slices of level 0 (whole x–y slices, z in order).
    pub fn push(&mut self, slab: VoxelData) -> Result<()> {
        let area = (self.dims[0] * self.dims[1]) as usize;
        if !slab.len().is_multiple_of(area) {
            return Err(Error::invalid(format!(
                "a slab of {} voxels is not whole slices of {}×{}",
                slab.len(),
                self.dims[0],
                self.dims[1]
            )));
        }
        let n = (slab.len() / area) as u64;
        if self.received + n > self.dims[2] {
            return Err(Error::invalid("more slices than the volume has"));
        }
        self.received += n;
        macro_rules! go {
            ($levels:expr, $t:ty) => {{
                let v = <$t>::take(slab)
                    .ok_or_else(|| Error::invalid("a slab of another type than the store's"))?;
                push_level($levels, 0, v, &self.path)
            }};
        }
        match &mut self.inner {
            Inner::U8(l) => go!(l, u8),
            Inner::U16(l) => go!(l, u16),
            Inner::I16(l) => go!(l, i16),
            Inner::F32(l) => go!(l, f32),
        }
    }

    /// Slices received so far.
    pub fn received(&self) -> u64 {
        self.received
    }

    /// Writes the sidecars once every slice has arrived.
    pub fn finish(self) -> Result<WriteStats> {
        if self.received != self.dims[2] {
            return Err(Error::invalid(format!(
                "{}: {} of {} slices written",
                self.path.display(),
                self.received,
                self.dims[2]
            )));
        }
        macro_rules! go {
            ($levels:expr) => {{
                let mut stats = WriteStats {
                    levels: $levels.len(),
                    ..Default::default()
                };
                for (l, lw) in $levels.iter().enumerate() {
                    let bytes = ranges_bytes(lw.counts(), &lw.minmax);
                    let p = self.path.join(l.to_string()).join(RANGES_FILE);
                    std::fs::write(&p, bytes).map_err(|e| Error::io(&p, e))?;
                    stats.chunks_written += lw.written;
                    stats.chunks_empty += lw.empty;
                }
                stats
            }};
        }
        let mut stats = match &self.inner {
            Inner::U8(l) => go!(l),
            Inner::U16(l) => go!(l),
            Inner::I16(l) => go!(l),
            Inner::F32(l) => go!(l),
        };
        stats.bytes_written = self.storage.bytes_written() as u64;
        stats.bytes_level0 = self.dims.iter().product::<u64>()
            * match &self.inner {
                Inner::U8(_) => 1,
                Inner::U16(_) | Inner::I16(_) => 2,
                Inner::F32(_) => 4,
            };
        Ok(stats)
    }
}

/// Hands `slices` to level `l`: buffered and written by whole rows of
/// chunks, and their 2×2×2 means handed to level `l + 1`.
fn push_level<T: Elem>(
    levels: &mut [LevelWriter<T>],
    l: usize,
    slices: Vec<T>,
    path: &Path,
) -> Result<()> {
    let (this, rest) = levels.split_at_mut(l + 1);
    let lw = &mut this[l];
    let area = lw.area();
    let n = (slices.len() / area) as u64;
    let z_start = lw.received;
    lw.received += n;
    let complete = lw.received == lw.dims[2];
    // The next level's share: pairs of slices starting at even z.
    let down = if rest.is_empty() {
        None
    } else {
        let mut pairs: Vec<T> = Vec::new();
        let mut first = 0usize;
        if let Some(odd) = lw.odd.take() {
            pairs.extend_from_slice(&odd);
            pairs.extend_from_slice(&slices[..area.min(slices.len())]);
            first = 1;
        } else {
            debug_assert!(z_start.is_multiple_of(2));
        }
        let left = n as usize - first.min(n as usize);
        let even = left / 2 * 2;
        pairs.extend_from_slice(&slices[first * area..(first + even) * area]);
        if left % 2 == 1 {
            let last = &slices[(first + even) * area..(first + even + 1) * area];
            if complete {
                pairs.extend_from_slice(last);
            } else {
                lw.odd = Some(last.to_vec());
            }
        }
        if pairs.is_empty() {
            None
        } else {
            let nz = pairs.len() / area;
            let d = [lw.dims[0] as usize, lw.dims[1] as usize, nz];
            let half = downsample2_data(&T::wrap(pairs), d);
            Some(T::take(half).expect("same type"))
        }
    };
    if lw.buf.is_empty() {
        lw.buf = slices;
        lw.buf_z0 = z_start;
    } else {
        lw.buf.extend_from_slice(&slices);
    }
    lw.flush(path)?;
    if let Some(d) = down {
        push_level(levels, l + 1, d, path)?;
    }
    Ok(())
}

fn array_metadata(
    d: [u64; 3],
    chunk: [u64; 3],
    ty: ScalarType,
    opts: &WriteOptions,
) -> Result<ArrayMetadata> {
    let shape = [d[2], d[1], d[0]];
    let chunks = [chunk[2], chunk[1], chunk[0]];
    let fill: Value = if ty == ScalarType::F32 {
        json!(0.0)
    } else {
        json!(0)
    };
    let v = match opts.format {
        ZarrFormat::V3 => {
            let mut codecs = vec![json!({"name": "bytes", "configuration": {"endian": "little"}})];
            match opts.compression {
                Compression::Zstd(l) => codecs.push(
                    json!({"name": "zstd", "configuration": {"level": l, "checksum": false}}),
                ),
                Compression::Blosc(l) => codecs.push(json!({"name": "blosc", "configuration": {
                    "cname": "zstd", "clevel": l, "shuffle": "shuffle", "typesize": ty.size(), "blocksize": 0}})),
                Compression::Gzip(l) => {
                    codecs.push(json!({"name": "gzip", "configuration": {"level": l}}))
                }
                Compression::None => {}
            }
            let dt = match ty {
                ScalarType::U8 => "uint8",
                ScalarType::U16 => "uint16",
                ScalarType::I16 => "int16",
                ScalarType::F32 => "float32",
            };
            json!({
                "zarr_format": 3,
                "node_type": "array",
                "shape": shape,
                "data_type": dt,
                "chunk_grid": {"name": "regular", "configuration": {"chunk_shape": chunks}},
                "chunk_key_encoding": {"name": "default", "configuration": {"separator": "/"}},
                "fill_value": fill,
                "codecs": codecs,
                "dimension_names": ["z", "y", "x"],
            })
        }
        ZarrFormat::V2 => {
            let compressor = match opts.compression {
                Compression::Zstd(l) => json!({"id": "zstd", "level": l}),
                Compression::Blosc(l) => {
                    json!({"id": "blosc", "cname": "zstd", "clevel": l, "shuffle": 1, "blocksize": 0})
                }
                Compression::Gzip(l) => json!({"id": "gzip", "level": l}),
                Compression::None => Value::Null,
            };
            let dt = match ty {
                ScalarType::U8 => "|u1",
                ScalarType::U16 => "<u2",
                ScalarType::I16 => "<i2",
                ScalarType::F32 => "<f4",
            };
            json!({
                "zarr_format": 2,
                "shape": shape,
                "chunks": chunks,
                "dtype": dt,
                "compressor": compressor,
                "fill_value": fill,
                "order": "C",
                "filters": null,
                "dimension_separator": "/",
            })
        }
    };
    let meta = match opts.format {
        ZarrFormat::V3 => serde_json::from_value(v).map(ArrayMetadata::V3),
        ZarrFormat::V2 => serde_json::from_value(v).map(ArrayMetadata::V2),
    };
    meta.map_err(|e| Error::invalid(format!("array metadata: {e}")))
}

fn write_json(p: &Path, v: &Value) -> Result<()> {
    let text = serde_json::to_string_pretty(v).expect("JSON");
    std::fs::write(p, text).map_err(|e| Error::io(p, e))
}

/// Writes `vol` as a pyramid at `path` (which must not exist), slab by slab;
/// `progress(done, total)` counts level-0 slices.
pub fn write_volume(
    vol: &Volume,
    path: &Path,
    opts: &WriteOptions,
    progress: &dyn Fn(u64, u64),
) -> Result<WriteStats> {
    let d = vol.dims().map(|v| v as u64);
    let name = vol.name.clone().unwrap_or_else(|| "volume".into());
    let mut w = PyramidWriter::create(
        path,
        d,
        vol.spacing(),
        vol.origin(),
        vol.scalar_type(),
        &name,
        opts,
    )?;
    let step = opts.chunk[2] as u64;
    let mut z = 0;
    while z < d[2] {
        let z1 = (z + step).min(d[2]);
        let slab = crate::volume::chunked::crop(vol, [0, 0, z], [d[0], d[1], z1]);
        w.push(slab)?;
        z = z1;
        progress(z, d[2]);
    }
    w.finish()
}
