//! Zarr v2 and v3 stores with OME-Zarr multiscales metadata (0.4 and 0.5;
//! 0.1–0.3 where their axes can be told), through the `zarrs` crate:
//! local folders, codecs blosc, zstd, gzip, sharding.
//!
//! A store opens as a [`ZarrStore`]: its levels (finest first), each with
//! its voxel size from the `coordinateTransformations`, read chunk by chunk
//! ([`ChunkedSource`], for the out-of-core renderer) or whole
//! ([`ZarrStore::read_level`]). A plain Zarr array (no multiscales) is a
//! store of one level with unit spacing.
//!
//! Axes: the three `space` axes (named `x`, `y`, `z`) must be the last
//! three, in the order `z, y, x` (as OME-Zarr writes them; x is then the
//! fastest in memory, as in [`Volume`]). Leading axes (`t`, `c`) are read
//! at one index: `--time T` picks the index on `t`, `--var C` the
//! channel (an index, or a label from `omero.channels`); index 0 otherwise.
//!
//! Types: u8, u16, i16 and f32 are read as they are; i8 as i16; u32,
//! i32, u64, i64 and f64 as f32 (the only wider type a volume holds).
//!
//! Stores that `voxcast convert` writes ([`mod@write`]) keep each level's
//! per-chunk value range in a sidecar (`voxcast-chunk-ranges.bin`, beside
//! the level's array metadata), so the renderer skips transparent chunks
//! without reading them; other tools ignore it.

mod keys;
mod meta;
mod ranges;
mod summary;
pub mod write;

pub use keys::is_zarr;
use keys::{open_storage, Keys};
use meta::{
    codec_names, compose_scale, compose_translation, data_type_name, group_attributes, parse_axes,
    spatial_axes, transforms,
};
pub use ranges::RANGES_FILE;
use ranges::{read_ranges, Ranges};

use crate::error::{Error, Result};
use crate::io::OpenOptions;
use crate::volume::{ChunkRange, ChunkedSource, Level, ScalarType, Volume, VoxelData};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use zarrs::array::{Array, ArrayShardedExt, ArraySubset};
use zarrs::storage::storage_adapter::performance_metrics::PerformanceMetricsStorageAdapter;
use zarrs::storage::ReadableStorageTraits;

type Storage = PerformanceMetricsStorageAdapter<dyn ReadableStorageTraits>;

/// How a store's values are kept on disk (the volume type they are read
/// into is [`StoredType::volume_type`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StoredType {
    U8,
    U16,
    I16,
    F32,
    I8,
    U32,
    I32,
    U64,
    I64,
    F64,
}

impl StoredType {
    /// The Zarr v3 name (`uint16`, `float32`, …).
    pub fn name(self) -> &'static str {
        match self {
            StoredType::U8 => "uint8",
            StoredType::U16 => "uint16",
            StoredType::I16 => "int16",
            StoredType::F32 => "float32",
            StoredType::I8 => "int8",
            StoredType::U32 => "uint32",
            StoredType::I32 => "int32",
            StoredType::U64 => "uint64",
            StoredType::I64 => "int64",
            StoredType::F64 => "float64",
        }
    }

    /// The type the voxels are read into.
    pub fn volume_type(self) -> ScalarType {
        match self {
            StoredType::U8 => ScalarType::U8,
            StoredType::U16 => ScalarType::U16,
            StoredType::I16 | StoredType::I8 => ScalarType::I16,
            _ => ScalarType::F32,
        }
    }

    fn of(array: &Array<Storage>) -> Option<StoredType> {
        use zarrs::array::data_type as dt;
        let d = array.data_type();
        Some(if d.is::<dt::UInt8DataType>() {
            StoredType::U8
        } else if d.is::<dt::UInt16DataType>() {
            StoredType::U16
        } else if d.is::<dt::Int16DataType>() {
            StoredType::I16
        } else if d.is::<dt::Float32DataType>() {
            StoredType::F32
        } else if d.is::<dt::Int8DataType>() {
            StoredType::I8
        } else if d.is::<dt::UInt32DataType>() {
            StoredType::U32
        } else if d.is::<dt::Int32DataType>() {
            StoredType::I32
        } else if d.is::<dt::UInt64DataType>() {
            StoredType::U64
        } else if d.is::<dt::Int64DataType>() {
            StoredType::I64
        } else if d.is::<dt::Float64DataType>() {
            StoredType::F64
        } else {
            return None;
        })
    }

    /// The fill value's bytes (native endian) as a number.
    fn decode(self, b: &[u8]) -> Option<f64> {
        macro_rules! get {
            ($t:ty) => {
                <$t>::from_ne_bytes(b.try_into().ok()?) as f64
            };
        }
        Some(match self {
            StoredType::U8 => get!(u8),
            StoredType::U16 => get!(u16),
            StoredType::I16 => get!(i16),
            StoredType::F32 => get!(f32),
            StoredType::I8 => get!(i8),
            StoredType::U32 => get!(u32),
            StoredType::I32 => get!(i32),
            StoredType::U64 => get!(u64),
            StoredType::I64 => get!(i64),
            StoredType::F64 => get!(f64),
        })
    }
}

/// One resolution level as stored.
#[derive(Clone, Debug)]
pub struct LevelInfo {
    /// The array's path inside the store (`0`, `s1`, …; empty for a root array).
    pub path: String,
    /// The array's whole shape, in its own axis order.
    pub shape: Vec<u64>,
    /// Its chunk (or shard) shape, in its own axis order.
    pub chunk_shape: Vec<u64>,
    /// The shard's inner chunk shape, for sharded arrays.
    pub subchunk_shape: Option<Vec<u64>>,
    /// The codecs, as the metadata names them (`zstd`, `blosc`, …).
    pub codecs: Vec<String>,
    /// Chunks stored on disk (files or shards counted), where counted.
    pub has_ranges: bool,
}

/// What a store says about itself (for `voxcast info`).
#[derive(Clone, Debug)]
pub struct StoreInfo {
    /// 2 or 3.
    pub zarr_format: u8,
    /// The OME-Zarr version of the multiscales metadata, if any.
    pub ome_version: Option<String>,
    /// Axis names and types, in the arrays' order (`t time`, `c channel`,
    /// `z space micrometer`…).
    pub axes: Vec<(String, String, Option<String>)>,
    /// The index read on each leading (non-space) axis.
    pub lead_index: Vec<u64>,
    /// Channel labels from `omero.channels`, if any.
    pub channels: Vec<String>,
    /// The data type as stored.
    pub stored: StoredType,
    /// The fill value (what a chunk never written holds).
    pub fill: f64,
    pub levels: Vec<LevelInfo>,
}

/// An open OME-Zarr / Zarr store.
pub struct ZarrStore {
    path: PathBuf,
    storage: Arc<Storage>,
    arrays: Vec<Array<Storage>>,
    levels: Vec<Level>,
    /// Inner chunk (or chunk) shape per level, spatial x, y, z.
    ranges: Vec<Option<Ranges>>,
    info: StoreInfo,
    /// The spatial axes' positions in the arrays' shape (z, y, x).
    spatial: [usize; 3],
    units: Option<String>,
    warned_missing: AtomicBool,
}

impl std::fmt::Debug for ZarrStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ZarrStore")
            .field("path", &self.path)
            .field("levels", &self.levels)
            .finish()
    }
}

fn zerr(path: &Path, what: &str, e: impl std::fmt::Display) -> Error {
    Error::format(path, what, e.to_string())
}

impl ZarrStore {
    /// Opens the store at `path` with index 0 on every leading axis.
    pub fn open(path: &Path) -> Result<ZarrStore> {
        ZarrStore::open_with(path, &OpenOptions::default())
    }

    /// Opens the store at `path`; `opts.time` picks the index on a `t`
    /// axis and `opts.variable` the channel.
    pub fn open_with(path: &Path, opts: &OpenOptions) -> Result<ZarrStore> {
        // Opened once (a zip file's directory is read here); a zip file
        // that cannot be read says why.
        let not_a_store = || {
            Error::unsupported(
                path,
                "not a Zarr store: expected a folder with zarr.json (Zarr v3), .zgroup or .zarray (Zarr v2), or a .zip/.ozx file with one of them at its root",
            )
        };
        let Some(keys) = open_storage(path)? else {
            return Err(not_a_store());
        };
        let storage = Arc::new(PerformanceMetricsStorageAdapter::new(keys.clone()));
        let keys = Keys {
            root: path,
            storage: keys.as_ref(),
        };
        if !keys.is_store() {
            return Err(not_a_store());
        }
        let zarr_format = if keys.exists("zarr.json") { 3 } else { 2 };
        let root_is_array = keys.exists(".zarray") || {
            zarr_format == 3 && keys.json("zarr.json")?["node_type"] == "array"
        };
        // (array path, scale, translation) per level, and the axes.
        let mut datasets: Vec<(String, Vec<f64>, Vec<f64>)> = Vec::new();
        let mut axes: Vec<(String, String, Option<String>)> = Vec::new();
        let mut ome_version = None;
        let mut channels = Vec::new();
        if root_is_array {
            datasets.push((String::new(), Vec::new(), Vec::new()));
        } else {
            let attrs = group_attributes(&keys, zarr_format)?;
            let (ms, version) = if let Some(ome) = attrs.get("ome") {
                (ome.get("multiscales"), ome.get("version"))
            } else {
                (attrs.get("multiscales"), None)
            };
            let ms = ms.and_then(|m| m.get(0)).ok_or_else(|| {
                Error::format(
                    path,
                    "multiscales",
                    "the group has no OME-Zarr multiscales metadata; open one of its arrays by its path (e.g. STORE.zarr/0)",
                )
            })?;
            ome_version = version
                .or_else(|| ms.get("version"))
                .and_then(|v| v.as_str())
                .map(str::to_string);
            axes = parse_axes(path, ms.get("axes"))?;
            let (gs, gt) = transforms(path, "multiscales[0].coordinateTransformations", ms)?;
            let list = ms
                .get("datasets")
                .and_then(|d| d.as_array())
                .filter(|d| !d.is_empty())
                .ok_or_else(|| {
                    Error::format(path, "multiscales[0].datasets", "expected a non-empty list")
                })?;
            for (i, d) in list.iter().enumerate() {
                let field = format!("multiscales[0].datasets[{i}]");
                let p = d.get("path").and_then(|p| p.as_str()).ok_or_else(|| {
                    Error::format(path, format!("{field}.path"), "expected a string")
                })?;
                if p.is_empty() || p.split('/').any(|s| s == ".." || s == ".") {
                    return Err(Error::format(
                        path,
                        format!("{field}.path"),
                        format!("{p:?}: expected a path inside the store"),
                    ));
                }
                let (s, t) = transforms(path, &format!("{field}.coordinateTransformations"), d)?;
                // The multiscale's own transformations apply after the dataset's.
                let scale = compose_scale(&s, &gs);
                let trans = compose_translation(&t, &gs, &gt);
                datasets.push((p.to_string(), scale, trans));
            }
            if let Some(chs) = attrs
                .get("omero")
                .or_else(|| attrs.get("ome").and_then(|o| o.get("omero")))
                .and_then(|o| o.get("channels"))
                .and_then(|c| c.as_array())
            {
                channels = chs
                    .iter()
                    .map(|c| {
                        c.get("label")
                            .and_then(|l| l.as_str())
                            .unwrap_or("")
                            .to_string()
                    })
                    .collect();
            }
        }
        let mut arrays = Vec::new();
        for (p, _, _) in &datasets {
            let node = format!("/{p}");
            let a = Array::open(storage.clone(), &node).map_err(|e| {
                zerr(
                    &path.join(p),
                    if zarr_format == 3 {
                        "zarr.json"
                    } else {
                        ".zarray"
                    },
                    e,
                )
            })?;
            arrays.push(a);
        }
        let nd = arrays[0].dimensionality();
        if axes.is_empty() {
            // A plain array, or OME-Zarr 0.1/0.2 without axes: the last
            // three are z, y, x.
            let names = ["t", "c", "z", "y", "x"];
            if !(3..=5).contains(&nd) {
                return Err(Error::unsupported(
                    path,
                    format!("an array of {nd} dimensions: a volume needs 3 (z, y, x), with at most t and c before them"),
                ));
            }
            axes = names[5 - nd..]
                .iter()
                .map(|n| {
                    let kind = match *n {
                        "t" => "time",
                        "c" => "channel",
                        _ => "space",
                    };
                    (n.to_string(), kind.to_string(), None)
                })
                .collect();
        }
        if axes.len() != nd {
            return Err(Error::format(
                path,
                "multiscales[0].axes",
                format!("{} axes for arrays of {nd} dimensions", axes.len()),
            ));
        }
        let spatial = spatial_axes(path, &axes)?;
        // The index on each leading axis.
        let mut lead_index = Vec::new();
        for (a, (name, kind, _)) in axes.iter().enumerate().take(nd - 3) {
            let n = arrays[0].shape()[a];
            let i = if kind == "time" || name == "t" {
                match opts.time {
                    Some(t) if t >= 0.0 && t.fract() == 0.0 => t as u64,
                    Some(t) => {
                        return Err(Error::invalid(format!(
                            "--time {t}: {} has a t axis of {n} steps; give an index 0…{}",
                            path.display(),
                            n - 1
                        )))
                    }
                    None => 0,
                }
            } else if kind == "channel" || name == "c" {
                match &opts.variable {
                    Some(v) => match v.parse::<u64>() {
                        Ok(i) => i,
                        Err(_) => channels
                            .iter()
                            .position(|c| c == v)
                            .map(|i| i as u64)
                            .ok_or_else(|| {
                                Error::invalid(format!(
                                    "--var {v}: {} has no such channel (channels: {})",
                                    path.display(),
                                    if channels.is_empty() {
                                        format!("0…{}", n - 1)
                                    } else {
                                        channels.join(", ")
                                    }
                                ))
                            })?,
                    },
                    None => 0,
                }
            } else {
                0
            };
            if i >= n {
                return Err(Error::invalid(format!(
                    "{}: axis {name} has {n} entries; index {i} is past its end",
                    path.display()
                )));
            }
            lead_index.push(i);
        }
        let stored = StoredType::of(&arrays[0]).ok_or_else(|| {
            Error::unsupported(
                path.join(&datasets[0].0),
                format!(
                    "data type {}: voxcast reads (u)int8/16/32/64 and float32/64",
                    data_type_name(arrays[0].metadata())
                ),
            )
        })?;
        let fill = stored
            .decode(arrays[0].fill_value().as_ne_bytes())
            .unwrap_or(0.0);
        let mut levels = Vec::new();
        let mut infos = Vec::new();
        let mut ranges = Vec::new();
        let mut units = None;
        for (l, ((p, scale, trans), a)) in datasets.iter().zip(&arrays).enumerate() {
            let apath = path.join(p);
            if a.dimensionality() != nd {
                return Err(Error::format(
                    &apath,
                    "shape",
                    format!("{} dimensions where level 0 has {nd}", a.dimensionality()),
                ));
            }
            if StoredType::of(a) != Some(stored) {
                return Err(Error::format(
                    &apath,
                    "data_type",
                    format!(
                        "{} where level 0 is {}",
                        data_type_name(a.metadata()),
                        stored.name()
                    ),
                ));
            }
            let shape = a.shape().to_vec();
            let zero = vec![0u64; nd];
            let chunk: Vec<u64> = a
                .chunk_shape(&zero)
                .map_err(|e| zerr(&apath, "chunk_grid", e))?
                .iter()
                .map(|c| c.get())
                .collect();
            let sub: Option<Vec<u64>> = if a.is_sharded() {
                a.subchunk_shape()
                    .map(|s| s.iter().map(|c| c.get()).collect())
            } else {
                None
            };
            let grid = sub.clone().unwrap_or_else(|| chunk.clone());
            let [zi, yi, xi] = spatial;
            let dims = [shape[xi], shape[yi], shape[zi]];
            if dims.contains(&0) {
                return Err(Error::format(&apath, "shape", "an axis of length 0"));
            }
            let cs = [grid[xi], grid[yi], grid[zi]];
            // Checked: three axes of 2²² already overflow 64 bits.
            let size = stored.volume_type().size() as u64;
            let cbytes = cs.iter().try_fold(size, |b, &c| b.checked_mul(c));
            if cs.iter().any(|&c| c > u32::MAX as u64) || cbytes.is_none_or(|b| b > (4u64 << 30)) {
                let decoded = cbytes.map_or("over 2⁶⁴".to_string(), |b| b.to_string());
                return Err(Error::unsupported(
                    &apath,
                    format!(
                        "chunks of {}×{}×{} voxels ({decoded} bytes decoded): voxcast reads chunks of up to 4 GiB",
                        cs[0], cs[1], cs[2]
                    ),
                ));
            }
            let at = |v: &Vec<f64>, i: usize, d: f64| v.get(i).copied().unwrap_or(d);
            let spacing = Vec3::new(
                at(scale, xi, 1.0) as f32,
                at(scale, yi, 1.0) as f32,
                at(scale, zi, 1.0) as f32,
            );
            if !(spacing.is_finite() && spacing.min_element() > 0.0) {
                return Err(Error::format(
                    path,
                    format!("multiscales[0].datasets[{l}].coordinateTransformations"),
                    format!(
                        "scale {} {} {} (x y z): each must be a positive finite number",
                        spacing.x, spacing.y, spacing.z
                    ),
                ));
            }
            let origin = Vec3::new(
                at(trans, xi, 0.0) as f32,
                at(trans, yi, 0.0) as f32,
                at(trans, zi, 0.0) as f32,
            );
            if l > 0 {
                let prev: &Level = &levels[l - 1];
                if (0..3).any(|k| dims[k] > prev.dims[k]) {
                    return Err(Error::format(
                        path,
                        format!("multiscales[0].datasets[{l}]"),
                        format!(
                            "level {l} ({}×{}×{}) is larger than level {} ({}×{}×{}): levels must go from finest to coarsest",
                            dims[0], dims[1], dims[2], l - 1, prev.dims[0], prev.dims[1], prev.dims[2]
                        ),
                    ));
                }
            }
            let level = Level {
                dims,
                spacing,
                origin,
                chunk: cs.map(|c| c as u32),
            };
            // The renderer keeps a few bytes per chunk of a level; a
            // store of more chunks than 2³² (a petabyte in chunks of 64³
            // bytes) is refused, which also keeps the chunks' numbers in
            // 64 bits.
            if level.chunk_total().is_none_or(|n| n > 1 << 32) {
                let n = level.chunk_counts();
                return Err(Error::unsupported(
                    &apath,
                    format!(
                        "{}×{}×{} chunks of {}×{}×{} voxels: voxcast reads levels of up to 2³² chunks",
                        n[0], n[1], n[2], cs[0], cs[1], cs[2]
                    ),
                ));
            }
            levels.push(level);
            let r = read_ranges(&keys, p, &levels[l]);
            infos.push(LevelInfo {
                path: p.clone(),
                shape,
                chunk_shape: chunk,
                subchunk_shape: sub,
                codecs: codec_names(a.metadata()),
                has_ranges: r.is_some(),
            });
            ranges.push(r);
            if units.is_none() {
                units = axes[xi].2.clone();
            }
        }
        let info = StoreInfo {
            zarr_format,
            ome_version,
            axes,
            lead_index,
            channels,
            stored,
            fill,
            levels: infos,
        };
        Ok(ZarrStore {
            path: path.to_path_buf(),
            storage,
            arrays,
            levels,
            ranges,
            info,
            spatial,
            units,
            warned_missing: AtomicBool::new(false),
        })
    }

    /// The store's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What the metadata says.
    pub fn info(&self) -> &StoreInfo {
        &self.info
    }

    /// The unit of the spatial axes (`micrometer`), if given.
    pub fn units(&self) -> Option<&str> {
        self.units.as_deref()
    }

    /// The array subset of the voxel box `[lo, hi)` (x, y, z) on `level`.
    fn subset(&self, lo: [u64; 3], hi: [u64; 3]) -> ArraySubset {
        let nd = self.info.axes.len();
        let mut r: Vec<std::ops::Range<u64>> =
            self.info.lead_index.iter().map(|&i| i..i + 1).collect();
        r.resize(nd, 0..0);
        let [zi, yi, xi] = self.spatial;
        r[xi] = lo[0]..hi[0];
        r[yi] = lo[1]..hi[1];
        r[zi] = lo[2]..hi[2];
        ArraySubset::new_with_ranges(&r)
    }

    /// The voxels of the box `[lo, hi)` of `level`, x fastest.
    pub fn read_box(&self, level: usize, lo: [u64; 3], hi: [u64; 3]) -> Result<VoxelData> {
        let a = &self.arrays[level];
        let s = self.subset(lo, hi);
        let what = || {
            format!(
                "level {level} ({}), voxels x {}…{}, y {}…{}, z {}…{}",
                self.array_label(level),
                lo[0],
                hi[0],
                lo[1],
                hi[1],
                lo[2],
                hi[2]
            )
        };
        macro_rules! get {
            ($t:ty) => {
                a.retrieve_array_subset::<Vec<$t>>(&s)
                    .map_err(|e| Error::format(&self.path, what(), e.to_string()))?
            };
        }
        macro_rules! wide {
            ($t:ty) => {
                VoxelData::F32(
                    get!($t)
                        .into_iter()
                        .map(|v| v as f32)
                        .collect::<Vec<_>>()
                        .into(),
                )
            };
        }
        Ok(match self.info.stored {
            StoredType::U8 => VoxelData::U8(get!(u8).into()),
            StoredType::U16 => VoxelData::U16(get!(u16).into()),
            StoredType::I16 => VoxelData::I16(get!(i16).into()),
            StoredType::F32 => VoxelData::F32(get!(f32).into()),
            StoredType::I8 => VoxelData::I16(
                get!(i8)
                    .into_iter()
                    .map(i16::from)
                    .collect::<Vec<_>>()
                    .into(),
            ),
            StoredType::U32 => wide!(u32),
            StoredType::I32 => wide!(i32),
            StoredType::U64 => wide!(u64),
            StoredType::I64 => wide!(i64),
            StoredType::F64 => wide!(f64),
        })
    }

    fn array_label(&self, level: usize) -> String {
        let p = &self.info.levels[level].path;
        if p.is_empty() {
            "the root array".into()
        } else {
            format!("array {p}")
        }
    }

    /// Level `level` read whole, as a volume (chunks decoded in parallel).
    pub fn read_level(&self, level: usize) -> Result<Volume> {
        let l = self.levels.get(level).ok_or_else(|| {
            Error::invalid(format!(
                "{}: no level {level} (levels 0…{})",
                self.path.display(),
                self.levels.len() - 1
            ))
        })?;
        crate::volume::checked_voxel_count(l.dims)
            .map_err(|m| Error::format(&self.path, format!("level {level}"), m))?;
        let data = match self.read_box(level, [0; 3], l.dims) {
            Ok(d) => d,
            // Find the chunk at fault, so the error names its file.
            Err(e) => {
                let n = l.chunk_counts();
                for z in 0..n[2] {
                    for y in 0..n[1] {
                        for x in 0..n[0] {
                            self.read_chunk(level, [x, y, z])?;
                        }
                    }
                }
                return Err(e);
            }
        };
        let mut v = Volume::new(l.dims.map(|d| d as usize), l.spacing, l.origin, data)?;
        v.name = Some(self.path.display().to_string());
        v.units = None;
        // Opacity per level-0 voxel and the camera on level 0's box, as
        // out of core: a coarse level looks like the full resolution.
        v.opacity_unit = Some(self.levels[0].spacing.min_element());
        v.frame = Some(crate::render::outofcore::world_bounds(&self.levels));
        Ok(v)
    }

    /// The finest level whose decoded voxels take at most `bytes`.
    pub fn finest_within(&self, bytes: u64) -> Option<usize> {
        let ty = self.scalar_type();
        (0..self.levels.len()).find(|&l| self.levels[l].bytes(ty) <= bytes)
    }

    /// A chunk not stored that the sidecar says held values was lost: says
    /// so once (Zarr's rule reads it as the fill value).
    fn warn_if_lost(&self, level: usize, c: [u64; 3]) {
        let Some(r) = &self.ranges[level] else {
            return;
        };
        let fill = self.info.fill as f32;
        let had_values = r.get(c).is_some_and(|m| !(m[0] == fill && m[1] == fill));
        if had_values && !self.warned_missing.swap(true, Ordering::Relaxed) {
            eprintln!(
                "warning: {}: level {level} ({}) chunk {:?} (x, y, z) is missing from the store though it held values when written; missing chunks render as the fill value {} (further ones are not reported)",
                self.path.display(),
                self.array_label(level),
                c,
                self.info.fill
            );
        }
    }

    /// Whether chunk `c` of `level` (in the ChunkedSource's grid) is stored.
    fn chunk_stored(&self, level: usize, c: [u64; 3]) -> Option<bool> {
        let a = &self.arrays[level];
        let li = &self.info.levels[level];
        let nd = self.info.axes.len();
        // The chunk (or shard) holding this inner chunk, in array order.
        let mut idx = vec![0u64; nd];
        for (k, &i) in self.info.lead_index.iter().enumerate() {
            idx[k] = i / li.chunk_shape[k];
        }
        let [zi, yi, xi] = self.spatial;
        let l = &self.levels[level];
        for (ax, s) in [(xi, 0), (yi, 1), (zi, 2)] {
            idx[ax] = c[s] * l.chunk[s] as u64 / li.chunk_shape[ax];
        }
        let key = a.chunk_key(&idx);
        self.storage.size_key(&key).ok().map(|s| s.is_some())
    }
}

impl ChunkedSource for ZarrStore {
    fn name(&self) -> String {
        self.path.display().to_string()
    }
    fn scalar_type(&self) -> ScalarType {
        self.info.stored.volume_type()
    }
    fn levels(&self) -> &[Level] {
        &self.levels
    }
    fn chunk_range(&self, level: usize, c: [u64; 3]) -> ChunkRange {
        if self.chunk_stored(level, c) == Some(false) {
            self.warn_if_lost(level, c);
            return ChunkRange::Fill(self.info.fill as f32);
        }
        match self.ranges[level].as_ref().and_then(|r| r.get(c)) {
            // All NaN (or no sidecar): read it to know.
            Some([lo, hi]) if !lo.is_nan() => ChunkRange::Range(lo, hi),
            _ => ChunkRange::Unknown,
        }
    }
    fn read_chunk(&self, level: usize, c: [u64; 3]) -> Result<VoxelData> {
        let l = self
            .levels
            .get(level)
            .ok_or_else(|| Error::invalid(format!("{}: no level {level}", self.path.display())))?;
        if (0..3).any(|a| c[a] >= l.chunk_counts()[a]) {
            return Err(Error::invalid(format!(
                "{}: level {level} has no chunk {:?}",
                self.path.display(),
                c
            )));
        }
        let (lo, hi) = l.chunk_box(c);
        self.read_box(level, lo, hi).map_err(|e| match e {
            Error::Format {
                path,
                field,
                message,
            } => {
                let key = {
                    let li = &self.info.levels[level];
                    let mut idx = vec![0u64; self.info.axes.len()];
                    let [zi, yi, xi] = self.spatial;
                    for (ax, s) in [(xi, 0), (yi, 1), (zi, 2)] {
                        idx[ax] = c[s] * l.chunk[s] as u64 / li.chunk_shape[ax];
                    }
                    self.arrays[level].chunk_key(&idx).to_string()
                };
                Error::Format {
                    path,
                    field: format!("{field}, chunk file {key}"),
                    message,
                }
            }
            e => e,
        })
    }
    fn bytes_read(&self) -> u64 {
        self.storage.bytes_read() as u64
    }
    fn value_range(&self) -> Option<[f32; 2]> {
        let r = self.ranges.first()?.as_ref()?;
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for m in &r.minmax {
            if !m[0].is_nan() {
                lo = lo.min(m[0]);
                hi = hi.max(m[1]);
            }
        }
        (lo <= hi).then_some([lo, hi])
    }
}

/// Reads `path` as a volume: the level `opts.level` asks for, or level 0.
/// Level 0 larger than half the memory available is refused unless asked
/// for by number, naming the levels' sizes (`voxcast render` renders it
/// out of core instead).
pub fn read(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let store = ZarrStore::open_with(path, opts)?;
    let n = store.levels().len();
    let level = match opts.level {
        Some(l) if l >= n => {
            return Err(Error::invalid(format!(
                "level {l}: {} has levels 0…{}",
                path.display(),
                n - 1
            )))
        }
        Some(l) => l,
        None => 0,
    };
    let ty = store.scalar_type();
    let need = store.levels()[level].bytes(ty);
    let avail = crate::render::outofcore::default_budget();
    if opts.level.is_none() && need > avail {
        let list: Vec<String> = store
            .levels()
            .iter()
            .enumerate()
            .map(|(i, l)| {
                format!(
                    "level {i}: {}",
                    crate::render::outofcore::human_bytes(l.bytes(ty))
                )
            })
            .collect();
        return Err(Error::invalid(format!(
            "{}: level {level} is {} decoded, more than half the memory available ({}); `voxcast render` renders it out of core, or read a coarser level with --level N ({})",
            path.display(),
            crate::render::outofcore::human_bytes(need),
            crate::render::outofcore::human_bytes(avail),
            list.join(", ")
        )));
    }
    let mut v = store.read_level(level)?;
    v.units = None;
    Ok(v)
}

#[cfg(test)]
mod tests;
