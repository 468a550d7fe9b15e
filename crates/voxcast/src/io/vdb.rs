//! OpenVDB reader: scalar grids of `float` (full or saved as half floats) and
//! `double`, uncompressed, zip (zlib) or Blosc compressed, with or without
//! active-mask compression, in files of format version 222 and later (every
//! OpenVDB 3+ file). Only the standard `5_4_3` tree configuration is read.
//!
//! The chosen grid becomes a dense volume over its active bounding box:
//! inactive voxels take the grid's background value, active tiles (at any
//! level) are filled in and counted as active voxels.
//!
//! Blosc: no maintained pure-Rust Blosc crate exists (the `blosc` crates bind
//! the C library), so this file decodes the Blosc1 container itself: the
//! 16-byte header, the block offsets, per-block split streams, LZ4 raw blocks
//! (the codec OpenVDB writes) and the byte unshuffle. Other Blosc codecs
//! (BloscLZ, Zstd, …) and bit shuffle are reported as unsupported.
//!
//! Every size the file claims is checked against the bytes it holds before
//! anything is allocated; bad input is an error, never a panic.
use super::OpenOptions;
use crate::error::{Error, Result};
use crate::volume::{checked_voxel_count, Volume, VoxelData};
use glam::Vec3;
use std::io::Read;
use std::path::Path;

const MAGIC: i64 = 0x5644_4220;
const COMPRESS_ZIP: u32 = 0x1;
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
const COMPRESS_BLOSC: u32 = 0x4;

/// Bounds-checked little-endian cursor over the file's bytes.
struct Cursor<'a> {
    buf: &'a [u8],
    pos: usize,
    path: &'a Path,
}

impl<'a> Cursor<'a> {
    fn err(&self, field: &str, msg: impl Into<String>) -> Error {
        Error::format(self.path, field, msg)
    }
    fn remaining(&self) -> usize {
        self.buf.len().saturating_sub(self.pos)
    }
    fn bytes(&mut self, n: usize, field: &str) -> Result<&'a [u8]> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len());
        match end {
            Some(end) => {
                let s = &self.buf[self.pos..end];
                self.pos = end;
                Ok(s)
            }
            None => Err(self.err(
                field,
                format!(
                    "needs {n} bytes at offset {}, the file ends at {} (truncated?)",
                    self.pos,
                    self.buf.len()
                ),
            )),
        }
    }
    fn arr<const N: usize>(&mut self, field: &str) -> Result<[u8; N]> {
        let s = self.bytes(N, field)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }
    fn u8(&mut self, field: &str) -> Result<u8> {
        Ok(self.arr::<1>(field)?[0])
    }
    fn u32(&mut self, field: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.arr(field)?))
    }
    fn i32(&mut self, field: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.arr(field)?))
    }
    fn i64(&mut self, field: &str) -> Result<i64> {
        Ok(i64::from_le_bytes(self.arr(field)?))
    }
    fn f64(&mut self, field: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.arr(field)?))
    }
    fn string(&mut self, field: &str) -> Result<String> {
        let n = self.u32(field)? as usize;
        if n > self.remaining() {
            return Err(self.err(
                field,
                format!(
                    "string of {n} bytes claimed, only {} bytes left in the file",
                    self.remaining()
                ),
            ));
        }
        let s = self.bytes(n, field)?;
        Ok(String::from_utf8_lossy(s).into_owned())
    }
    fn seek(&mut self, pos: i64, field: &str) -> Result<()> {
        match usize::try_from(pos) {
            Ok(p) if p <= self.buf.len() => {
                self.pos = p;
                Ok(())
            }
            _ => Err(self.err(
                field,
                format!(
                    "offset {pos} is outside the file ({} bytes)",
                    self.buf.len()
                ),
            )),
        }
    }
    /// Skips a metadata block (count, then name, type, sized value each).
    fn skip_metadata(&mut self, field: &str) -> Result<()> {
        let count = self.u32(field)? as usize;
        if count.saturating_mul(12) > self.remaining() {
            return Err(self.err(
                field,
                format!(
                    "{count} metadata entries claimed, only {} bytes left",
                    self.remaining()
                ),
            ));
        }
        for _ in 0..count {
            self.string(field)?;
            self.string(field)?;
            let n = self.u32(field)? as usize;
            self.bytes(n, field)?;
        }
        Ok(())
    }
}

/// One grid as the file's header lists it.
#[derive(Clone, Debug)]
struct GridDesc {
    name: String,
    type_name: String,
    grid_pos: i64,
}

/// Value type of a scalar grid.
#[derive(Clone, Copy, Debug, PartialEq)]
struct ValueKind {
    /// Bytes of a full value (background, tiles, inactive values).
    size: usize,
    /// Values arrays saved as half floats.
    half: bool,
}

fn value_kind(type_name: &str) -> Option<ValueKind> {
    let (base, half) = match type_name.strip_suffix("_HalfFloat") {
        Some(b) => (b, true),
        None => (type_name, false),
    };
    match base {
        "Tree_float_5_4_3" => Some(ValueKind { size: 4, half }),
        "Tree_double_5_4_3" => Some(ValueKind { size: 8, half }),
        _ => None,
    }
}

/// A leaf (8³ voxels): its origin, value mask and 512 values (z fastest).
struct Leaf {
    origin: [i64; 3],
    mask: [u64; 8],
    values: Vec<f32>,
}

/// An active tile: a cube of `dim`³ voxels at `origin`, all of `value`.
struct Tile {
    origin: [i64; 3],
    dim: i64,
    value: f32,
}

/// The sparse content of one grid.
struct Grid {
    background: f32,
    leaves: Vec<Leaf>,
    tiles: Vec<Tile>,
    /// World = index · scale + translation.
    scale: [f64; 3],
    translation: [f64; 3],
    /// Offset of the grid's compression flags.
    #[cfg_attr(not(test), allow(dead_code))]
    compression_pos: usize,
    /// Compressed chunks read: (offset of the size, end, uncompressed bytes).
    #[cfg_attr(not(test), allow(dead_code))]
    chunks: Vec<(usize, usize, usize)>,
}

impl Grid {
    fn active_count(&self) -> Option<u64> {
        let mut n: u64 = 0;
        for l in &self.leaves {
            n = n.checked_add(l.mask.iter().map(|w| w.count_ones() as u64).sum())?;
        }
        for t in &self.tiles {
            let d = u64::try_from(t.dim).ok()?;
            n = n.checked_add(d.checked_mul(d)?.checked_mul(d)?)?;
        }
        Some(n)
    }
    /// Inclusive bounding box of the active voxels.
    fn active_bbox(&self) -> Option<([i64; 3], [i64; 3])> {
        let mut lo = [i64::MAX; 3];
        let mut hi = [i64::MIN; 3];
        let mut any = false;
        let mut add = |a: [i64; 3], b: [i64; 3]| {
            any = true;
            for c in 0..3 {
                lo[c] = lo[c].min(a[c]);
                hi[c] = hi[c].max(b[c]);
            }
        };
        for l in &self.leaves {
            for_each_on(&l.mask, |i| {
                let p = leaf_coord(l.origin, i);
                add(p, p);
            });
        }
        for t in &self.tiles {
            add(t.origin, t.origin.map(|o| o + t.dim - 1));
        }
        any.then_some((lo, hi))
    }
}

fn leaf_coord(origin: [i64; 3], i: usize) -> [i64; 3] {
    let i = i as i64;
    [
        origin[0] + (i >> 6),
        origin[1] + ((i >> 3) & 7),
        origin[2] + (i & 7),
    ]
}

fn for_each_on(mask: &[u64], mut f: impl FnMut(usize)) {
    for (w, &word) in mask.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let b = bits.trailing_zeros() as usize;
            f(w * 64 + b);
            bits &= bits - 1;
        }
    }
}

fn is_on(mask: &[u64], i: usize) -> bool {
    mask.get(i / 64).is_some_and(|w| (w >> (i % 64)) & 1 == 1)
}

/// Reads `path`.
pub fn read(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let buf = crate::files::read_bytes(path, u64::MAX)?;
    let p = parse(path, &buf, opts)?;
    to_volume(path, p.name, p.grid, p.names)
}

/// What [`parse`] returns: the file's grids and the chosen one, read.
struct Parsed {
    #[cfg_attr(not(test), allow(dead_code))]
    grids: Vec<GridDesc>,
    names: Vec<String>,
    name: String,
    grid: Grid,
}

/// Parses the header, picks the grid and reads it.
fn parse(path: &Path, buf: &[u8], opts: &OpenOptions) -> Result<Parsed> {
    let mut r = Cursor { buf, pos: 0, path };
    let magic = r.i64("magic")?;
    if magic != MAGIC {
        return Err(r.err(
            "magic",
            format!("{magic:#x}, expected {MAGIC:#x} (\" BDV\"): not an OpenVDB file"),
        ));
    }
    let version = r.u32("file_version")?;
    if version < 222 {
        return Err(Error::unsupported(
            path,
            format!(
                "OpenVDB file format version {version} (only 222 and later, OpenVDB 3+, are read)"
            ),
        ));
    }
    let _lib_major = r.u32("library_version")?;
    let _lib_minor = r.u32("library_version")?;
    let has_offsets = r.u8("has_grid_offsets")?;
    r.bytes(36, "uuid")?;
    r.skip_metadata("file metadata")?;
    let count = r.u32("grid_count")? as usize;
    // A descriptor takes at least 36 bytes.
    if count.saturating_mul(36) > r.remaining() {
        return Err(r.err(
            "grid_count",
            format!(
                "{count} grids claimed, only {} bytes left in the file",
                r.remaining()
            ),
        ));
    }
    if has_offsets == 0 {
        return Err(Error::unsupported(
            path,
            "OpenVDB file without grid offsets (written to a stream)",
        ));
    }
    let mut grids = Vec::new();
    for _ in 0..count {
        let mut name = r.string("grid_name")?;
        if let Some(i) = name.find('\u{1e}') {
            name.truncate(i);
        }
        let type_name = r.string("grid_type")?;
        let _parent = r.string("instance_parent")?;
        let grid_pos = r.i64("grid_pos")?;
        let _block_pos = r.i64("block_pos")?;
        let end_pos = r.i64("end_pos")?;
        grids.push(GridDesc {
            name,
            type_name,
            grid_pos,
        });
        r.seek(end_pos, "end_pos")?;
    }
    let names: Vec<String> = grids.iter().map(|g| g.name.clone()).collect();
    let list = || {
        grids
            .iter()
            .map(|g| format!("{} ({})", g.name, g.type_name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = if let Some(v) = &opts.variable {
        grids.iter().find(|g| &g.name == v).ok_or_else(|| {
            Error::format(
                path,
                "grid",
                format!("no grid named {v:?}; the file holds: {}", list()),
            )
        })?
    } else {
        grids
            .iter()
            .find(|g| g.name == "density" && value_kind(&g.type_name).is_some())
            .or_else(|| grids.iter().find(|g| value_kind(&g.type_name).is_some()))
            .ok_or_else(|| {
                Error::unsupported(
                    path,
                    format!("no float or double grid in the file; it holds: {}", list()),
                )
            })?
    };
    let kind = value_kind(&chosen.type_name).ok_or_else(|| {
        Error::unsupported(
            path,
            format!(
                "grid {:?} has type {:?}; only scalar float/double trees 5_4_3 are read",
                chosen.name, chosen.type_name
            ),
        )
    })?;
    r.seek(chosen.grid_pos, "grid_pos")?;
    let grid = read_grid(&mut r, kind)?;
    let name = chosen.name.clone();
    Ok(Parsed {
        grids,
        names,
        name,
        grid,
    })
}

struct Ctx {
    kind: ValueKind,
    compression: u32,
    background: f32,
    /// Compressed chunks read: (offset of the size, end, uncompressed bytes).
    chunks: Vec<(usize, usize, usize)>,
}

fn value(r: &mut Cursor, kind: ValueKind, field: &str) -> Result<f32> {
    if kind.size == 8 {
        Ok(r.f64(field)? as f32)
    } else {
        Ok(f32::from_le_bytes(r.arr(field)?))
    }
}

fn read_grid(r: &mut Cursor, kind: ValueKind) -> Result<Grid> {
    let compression_pos = r.pos;
    let compression = r.u32("grid compression")?;
    if compression & !(COMPRESS_ZIP | COMPRESS_ACTIVE_MASK | COMPRESS_BLOSC) != 0 {
        return Err(r.err(
            "grid compression",
            format!("unknown flags {compression:#x}"),
        ));
    }
    r.skip_metadata("grid metadata")?;
    let (scale, translation) = read_transform(r)?;
    let buffer_count = r.u32("buffer_count")?;
    if buffer_count != 1 {
        return Err(Error::unsupported(
            r.path,
            format!("tree with {buffer_count} buffers per leaf (expected 1)"),
        ));
    }
    let background = value(r, kind, "background")?;
    let mut ctx = Ctx {
        kind,
        compression,
        background,
        chunks: Vec::new(),
    };
    let num_tiles = r.u32("root tile count")? as usize;
    let num_children = r.u32("root child count")? as usize;
    let tile_bytes = 12 + kind.size + 1;
    if num_tiles.saturating_mul(tile_bytes) > r.remaining()
        || num_children.saturating_mul(12 + 8192) > r.remaining()
    {
        return Err(r.err(
            "root",
            format!(
                "{num_tiles} tiles and {num_children} children claimed, only {} bytes left",
                r.remaining()
            ),
        ));
    }
    let mut leaves = Vec::new();
    let mut tiles = Vec::new();
    for _ in 0..num_tiles {
        let o = [
            r.i32("root tile")? as i64,
            r.i32("root tile")? as i64,
            r.i32("root tile")? as i64,
        ];
        let v = value(r, kind, "root tile")?;
        let active = r.u8("root tile")?;
        if active != 0 {
            tiles.push(Tile {
                origin: o,
                dim: 4096,
                value: v,
            });
        }
    }
    for _ in 0..num_children {
        let o = [
            r.i32("root child")? as i64,
            r.i32("root child")? as i64,
            r.i32("root child")? as i64,
        ];
        read_internal(r, &mut ctx, o, 5, 7, &mut leaves, &mut tiles)?;
    }
    // Leaf buffers, in the order of the topology.
    for leaf in leaves.iter_mut() {
        r.bytes(64, "leaf value mask")?;
        leaf.values = read_compressed(r, &mut ctx, 512, &leaf.mask, "leaf values")?;
    }
    Ok(Grid {
        background: ctx.background,
        leaves,
        tiles,
        scale,
        translation,
        compression_pos,
        chunks: ctx.chunks,
    })
}

/// Reads an internal node's topology (`log2` its own size in children,
/// `child_log2` the total size of a child in voxels); children of total size
/// 8 are leaves.
fn read_internal(
    r: &mut Cursor,
    ctx: &mut Ctx,
    origin: [i64; 3],
    log2: u32,
    child_log2: u32,
    leaves: &mut Vec<Leaf>,
    tiles: &mut Vec<Tile>,
) -> Result<()> {
    let n = 1usize << (3 * log2);
    let words = n / 64;
    let child_mask = read_mask(r, words, "internal child mask")?;
    let value_mask = read_mask(r, words, "internal value mask")?;
    let values = read_compressed(r, ctx, n, &value_mask, "internal tile values")?;
    let coord = |i: usize| -> [i64; 3] {
        let i = i as i64;
        let m = (1i64 << log2) - 1;
        [
            origin[0] + ((i >> (2 * log2)) << child_log2),
            origin[1] + (((i >> log2) & m) << child_log2),
            origin[2] + ((i & m) << child_log2),
        ]
    };
    for_each_on(&value_mask, |i| {
        if !is_on(&child_mask, i) {
            tiles.push(Tile {
                origin: coord(i),
                dim: 1 << child_log2,
                value: values.get(i).copied().unwrap_or(0.0),
            });
        }
    });
    let mut children = Vec::new();
    for_each_on(&child_mask, |i| children.push(i));
    for i in children {
        let o = coord(i);
        if child_log2 == 3 {
            let m = read_mask(r, 8, "leaf value mask")?;
            let mut mask = [0u64; 8];
            mask.copy_from_slice(&m);
            leaves.push(Leaf {
                origin: o,
                mask,
                values: Vec::new(),
            });
        } else {
            read_internal(r, ctx, o, 4, 3, leaves, tiles)?;
        }
    }
    Ok(())
}

fn read_mask(r: &mut Cursor, words: usize, field: &str) -> Result<Vec<u64>> {
    let b = r.bytes(words * 8, field)?;
    Ok(b.chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect())
}

/// OpenVDB's `readCompressedValues`: the metadata byte, inactive values, the
/// selection mask, then the (active or all) values.
fn read_compressed(
    r: &mut Cursor,
    ctx: &mut Ctx,
    count: usize,
    value_mask: &[u64],
    field: &str,
) -> Result<Vec<f32>> {
    let meta = r.u8(field)?;
    if meta > 6 {
        return Err(r.err(
            field,
            format!("compression metadata byte {meta}, expected 0…6"),
        ));
    }
    let bg = ctx.background;
    let mut inactive1 = bg;
    let mut inactive0 = if meta == 0 { bg } else { -bg };
    if meta == 2 || meta == 4 || meta == 5 {
        inactive0 = value(r, ctx.kind, field)?;
        if meta == 5 {
            inactive1 = value(r, ctx.kind, field)?;
        }
    }
    let selection = if (3..=5).contains(&meta) {
        Some(read_mask(r, value_mask.len(), field)?)
    } else {
        None
    };
    let mask_compressed = ctx.compression & COMPRESS_ACTIVE_MASK != 0;
    let stored = if mask_compressed && meta != 6 {
        value_mask.iter().map(|w| w.count_ones() as usize).sum()
    } else {
        count
    };
    let esize = if ctx.kind.half { 2 } else { ctx.kind.size };
    // OpenVDB's HalfReader/HalfWriter skip empty arrays entirely (no size).
    let raw = if ctx.kind.half && stored == 0 {
        Vec::new()
    } else {
        read_data(r, ctx, stored, esize, field)?
    };
    let vals: Vec<f32> = match esize {
        2 => raw
            .chunks_exact(2)
            .map(|c| f16_to_f32(u16::from_le_bytes([c[0], c[1]])))
            .collect(),
        4 => raw
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        _ => raw
            .chunks_exact(8)
            .map(|c| {
                let mut a = [0u8; 8];
                a.copy_from_slice(c);
                f64::from_le_bytes(a) as f32
            })
            .collect(),
    };
    if stored == count {
        return Ok(vals);
    }
    let mut out = Vec::with_capacity(count);
    let mut it = vals.into_iter();
    for i in 0..count {
        if is_on(value_mask, i) {
            out.push(it.next().unwrap_or(bg));
        } else if selection.as_deref().is_some_and(|s| is_on(s, i)) {
            out.push(inactive1);
        } else {
            out.push(inactive0);
        }
    }
    Ok(out)
}

/// OpenVDB's `readData`: `n` elements of `esize` bytes, Blosc, zip or raw.
fn read_data(
    r: &mut Cursor,
    ctx: &mut Ctx,
    n: usize,
    esize: usize,
    field: &str,
) -> Result<Vec<u8>> {
    let nbytes = n
        .checked_mul(esize)
        .ok_or_else(|| r.err(field, "size overflows"))?;
    if ctx.compression & (COMPRESS_BLOSC | COMPRESS_ZIP) == 0 {
        return Ok(r.bytes(nbytes, field)?.to_vec());
    }
    let chunk_start = r.pos;
    let claimed = r.i64(field)?;
    if claimed <= 0 {
        let raw = claimed.checked_neg().and_then(|v| usize::try_from(v).ok());
        if raw != Some(nbytes) {
            return Err(r.err(
                field,
                format!(
                    "uncompressed chunk of {} bytes, expected {nbytes}",
                    -(claimed as i128)
                ),
            ));
        }
        let raw = r.bytes(nbytes, field)?.to_vec();
        ctx.chunks.push((chunk_start, r.pos, nbytes));
        return Ok(raw);
    }
    let clen = usize::try_from(claimed).unwrap_or(usize::MAX);
    let chunk = r.bytes(clen, field)?;
    ctx.chunks.push((chunk_start, r.pos, nbytes));
    if ctx.compression & COMPRESS_BLOSC != 0 {
        blosc_decode(chunk, nbytes).map_err(|m| match m {
            BloscError::Bad(m) => r.err(field, format!("Blosc chunk: {m}")),
            BloscError::Unsupported(m) => Error::unsupported(r.path, m),
        })
    } else {
        let mut out = Vec::with_capacity(nbytes.min(chunk.len().saturating_mul(1100)));
        let mut dec = flate2::read::ZlibDecoder::new(chunk).take(nbytes as u64 + 1);
        dec.read_to_end(&mut out)
            .map_err(|e| r.err(field, format!("zip chunk: {e}")))?;
        if out.len() != nbytes {
            return Err(r.err(
                field,
                format!(
                    "zip chunk inflates to {} bytes, expected {nbytes}",
                    out.len()
                ),
            ));
        }
        Ok(out)
    }
}

/// Reads the grid's transform; returns (scale, translation).
fn read_transform(r: &mut Cursor) -> Result<([f64; 3], [f64; 3])> {
    let map = r.string("transform map type")?;
    let v3 = |r: &mut Cursor| -> Result<[f64; 3]> {
        Ok([
            r.f64("transform")?,
            r.f64("transform")?,
            r.f64("transform")?,
        ])
    };
    let (scale, translation) = match map.as_str() {
        "UniformScaleMap" | "ScaleMap" => {
            let s = v3(r)?;
            for _ in 0..4 {
                v3(r)?;
            }
            (s, [0.0; 3])
        }
        "UniformScaleTranslateMap" | "ScaleTranslateMap" => {
            let t = v3(r)?;
            let s = v3(r)?;
            for _ in 0..4 {
                v3(r)?;
            }
            (s, t)
        }
        "TranslationMap" => ([1.0; 3], v3(r)?),
        "AffineMap" => {
            let mut m = [0f64; 16];
            for x in m.iter_mut() {
                *x = r.f64("transform")?;
            }
            // Row-vector convention: translation in the last row.
            let off = [1, 2, 3, 4, 6, 7, 8, 9, 11];
            if off.iter().any(|&i| m[i] != 0.0) || m[15] != 1.0 {
                return Err(Error::unsupported(
                    r.path,
                    "AffineMap with rotation, shear or projection",
                ));
            }
            ([m[0], m[5], m[10]], [m[12], m[13], m[14]])
        }
        other => {
            return Err(Error::unsupported(
                r.path,
                format!("transform map {other:?} (only scale/translate maps are read)"),
            ))
        }
    };
    if scale.iter().chain(&translation).any(|x| !x.is_finite()) || scale.iter().any(|&s| s <= 0.0) {
        return Err(Error::unsupported(
            r.path,
            format!("transform scale {scale:?}: only positive finite scales are read"),
        ));
    }
    Ok((scale, translation))
}

/// Makes the dense volume from the sparse grid.
fn to_volume(path: &Path, name: String, grid: Grid, names: Vec<String>) -> Result<Volume> {
    let active = grid
        .active_count()
        .ok_or_else(|| Error::format(path, "tree", "active voxel count overflows"))?;
    let (lo, hi) = grid.active_bbox().ok_or_else(|| {
        Error::format(path, "tree", format!("grid {name:?} has no active voxels"))
    })?;
    let mut dims = [0u64; 3];
    for c in 0..3 {
        dims[c] = hi[c]
            .checked_sub(lo[c])
            .and_then(|d| d.checked_add(1))
            .and_then(|d| u64::try_from(d).ok())
            .ok_or_else(|| Error::format(path, "tree", "bounding box overflows"))?;
    }
    let n = checked_voxel_count(dims).map_err(|m| {
        Error::unsupported(
            path,
            format!("grid {name:?}: dense active bounding box {m}"),
        )
    })?;
    let d = dims.map(|x| x as usize);
    let mut data = Vec::new();
    data.try_reserve_exact(n).map_err(|_| {
        Error::unsupported(
            path,
            format!("grid {name:?}: cannot allocate the dense {n}-voxel bounding box"),
        )
    })?;
    data.resize(n, grid.background);
    let idx = |p: [i64; 3]| -> usize {
        let x = (p[0] - lo[0]) as usize;
        let y = (p[1] - lo[1]) as usize;
        let z = (p[2] - lo[2]) as usize;
        x + d[0] * (y + d[1] * z)
    };
    for t in &grid.tiles {
        for z in t.origin[2]..t.origin[2] + t.dim {
            for y in t.origin[1]..t.origin[1] + t.dim {
                for x in t.origin[0]..t.origin[0] + t.dim {
                    data[idx([x, y, z])] = t.value;
                }
            }
        }
    }
    for l in &grid.leaves {
        for_each_on(&l.mask, |i| {
            if let Some(&v) = l.values.get(i) {
                data[idx(leaf_coord(l.origin, i))] = v;
            }
        });
    }
    let spacing = Vec3::new(
        grid.scale[0] as f32,
        grid.scale[1] as f32,
        grid.scale[2] as f32,
    );
    let origin = Vec3::new(
        (lo[0] as f64 * grid.scale[0] + grid.translation[0]) as f32,
        (lo[1] as f64 * grid.scale[1] + grid.translation[1]) as f32,
        (lo[2] as f64 * grid.scale[2] + grid.translation[2]) as f32,
    );
    let mut vol = Volume::new(d, spacing, origin, VoxelData::F32(data))
        .map_err(|e| Error::format(path, "grid", e.to_string()))?;
    vol.active_voxels = Some(active);
    vol.name = Some(name);
    vol.variables = names;
    Ok(vol)
}

/// IEEE half to single.
fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h >> 15) as u32) << 31;
    let exp = ((h >> 10) & 0x1f) as u32;
    let man = (h & 0x3ff) as u32;
    if exp == 0 {
        let v = man as f32 * (1.0 / 16_777_216.0);
        if sign != 0 {
            -v
        } else {
            v
        }
    } else if exp == 31 {
        f32::from_bits(sign | 0x7f80_0000 | (man << 13))
    } else {
        f32::from_bits(sign | ((exp + 112) << 23) | (man << 13))
    }
}

enum BloscError {
    Bad(String),
    Unsupported(String),
}

/// Decodes one Blosc1 frame to exactly `expected` bytes (OpenVDB pads tiny
/// buffers before compressing, so the frame may hold more).
fn blosc_decode(src: &[u8], expected: usize) -> std::result::Result<Vec<u8>, BloscError> {
    let bad = |m: String| BloscError::Bad(m);
    if src.len() < 16 {
        return Err(bad(format!(
            "{} bytes, shorter than the 16-byte header",
            src.len()
        )));
    }
    let flags = src[2];
    let typesize = src[3] as usize;
    let rd = |o: usize| u32::from_le_bytes([src[o], src[o + 1], src[o + 2], src[o + 3]]) as usize;
    let nbytes = rd(4);
    let blocksize = rd(8);
    let cbytes = rd(12);
    if cbytes > src.len() {
        return Err(bad(format!(
            "claims {cbytes} bytes, the chunk holds {}",
            src.len()
        )));
    }
    if nbytes < expected || nbytes > expected.max(1024) {
        return Err(bad(format!("holds {nbytes} bytes, expected {expected}")));
    }
    let src = &src[..cbytes];
    let mut out = vec![0u8; nbytes];
    if flags & 0x2 != 0 {
        // Stored (memcpyed).
        let end = 16usize
            .checked_add(nbytes)
            .filter(|&e| e <= src.len())
            .ok_or_else(|| bad("stored chunk is truncated".into()))?;
        out.copy_from_slice(&src[16..end]);
        out.truncate(expected);
        return Ok(out);
    }
    if flags & 0x4 != 0 {
        return Err(BloscError::Unsupported("Blosc bit shuffle".into()));
    }
    let codec = flags >> 5;
    if codec != 1 {
        let name = match codec {
            0 => "BloscLZ",
            2 => "Snappy",
            3 => "zlib",
            4 => "Zstd",
            _ => "unknown",
        };
        return Err(BloscError::Unsupported(format!(
            "Blosc codec {name} (only LZ4 is read)"
        )));
    }
    if nbytes == 0 {
        return Ok(out);
    }
    if blocksize == 0 || typesize == 0 {
        return Err(bad("block size or type size 0".into()));
    }
    let nblocks = nbytes.div_ceil(blocksize);
    let starts_end = nblocks
        .checked_mul(4)
        .and_then(|b| b.checked_add(16))
        .filter(|&e| e <= src.len())
        .ok_or_else(|| bad(format!("{nblocks} blocks do not fit the chunk")))?;
    let shuffle = flags & 0x1 != 0 && typesize > 1;
    let dont_split = flags & 0x10 != 0;
    let mut tmp = vec![0u8; blocksize.min(nbytes)];
    for j in 0..nblocks {
        let start = rd(16 + 4 * j);
        if start < starts_end || start >= src.len() {
            return Err(bad(format!(
                "block {j} starts at {start}, outside the chunk"
            )));
        }
        let bstart = j * blocksize;
        let bsize = blocksize.min(nbytes - bstart);
        let leftover = bsize < blocksize;
        let rule = if !dont_split && typesize <= 16 && bsize / typesize >= 128 && !leftover {
            typesize
        } else {
            1
        };
        let dst = if shuffle {
            &mut tmp[..bsize]
        } else {
            &mut out[bstart..bstart + bsize]
        };
        let mut ok = false;
        for ns in [rule, if rule == 1 { typesize } else { 1 }] {
            if ns > 0 && bsize % ns == 0 && decode_block(&src[start..], dst, ns) {
                ok = true;
                break;
            }
        }
        if !ok {
            return Err(bad(format!("block {j} does not decode")));
        }
        if shuffle {
            let ne = bsize / typesize;
            let o = &mut out[bstart..bstart + bsize];
            for t in 0..typesize {
                for i in 0..ne {
                    o[i * typesize + t] = tmp[t * ne + i];
                }
            }
            let tail = ne * typesize;
            o[tail..].copy_from_slice(&tmp[tail..bsize]);
        }
    }
    out.truncate(expected);
    Ok(out)
}

/// One Blosc block of `nsplits` streams, each an i32 size then LZ4 data
/// (or the raw bytes when the size equals the stream's length).
fn decode_block(src: &[u8], dst: &mut [u8], nsplits: usize) -> bool {
    let ne = dst.len() / nsplits;
    let mut pos = 0usize;
    for s in 0..nsplits {
        let Some(h) = src.get(pos..pos + 4) else {
            return false;
        };
        let cb = i32::from_le_bytes([h[0], h[1], h[2], h[3]]);
        pos += 4;
        let Ok(cb) = usize::try_from(cb) else {
            return false;
        };
        let Some(data) = pos.checked_add(cb).and_then(|e| src.get(pos..e)) else {
            return false;
        };
        pos += cb;
        let d = &mut dst[s * ne..(s + 1) * ne];
        if cb == ne {
            d.copy_from_slice(data);
        } else if lz4_block(data, d) != Some(ne) {
            return false;
        }
    }
    true
}

/// Decodes an LZ4 raw block into `dst`; returns the bytes written.
fn lz4_block(src: &[u8], dst: &mut [u8]) -> Option<usize> {
    let mut i = 0usize;
    let mut o = 0usize;
    loop {
        let token = *src.get(i)?;
        i += 1;
        let mut lit = (token >> 4) as usize;
        if lit == 15 {
            loop {
                let b = *src.get(i)?;
                i += 1;
                lit = lit.checked_add(b as usize)?;
                if b != 255 {
                    break;
                }
            }
        }
        let s = src.get(i..i.checked_add(lit)?)?;
        dst.get_mut(o..o.checked_add(lit)?)?.copy_from_slice(s);
        i += lit;
        o += lit;
        if i == src.len() {
            return Some(o);
        }
        let off = u16::from_le_bytes([*src.get(i)?, *src.get(i + 1)?]) as usize;
        i += 2;
        if off == 0 || off > o {
            return None;
        }
        let mut ml = (token & 15) as usize;
        if ml == 15 {
            loop {
                let b = *src.get(i)?;
                i += 1;
                ml = ml.checked_add(b as usize)?;
                if b != 255 {
                    break;
                }
            }
        }
        ml += 4;
        if o.checked_add(ml)? > dst.len() {
            return None;
        }
        for k in 0..ml {
            dst[o + k] = dst[o + k - off];
        }
        o += ml;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::data_path;

    fn load(rel: &str, var: Option<&str>) -> Option<(Volume, Grid)> {
        let p = data_path(rel)?;
        let buf = std::fs::read(&p).unwrap();
        let opts = OpenOptions {
            variable: var.map(String::from),
            ..Default::default()
        };
        let grid = parse(&p, &buf, &opts).unwrap().grid;
        let t = std::time::Instant::now();
        let vol = read(&p, &opts).unwrap();
        eprintln!("{rel}: read in {:?}", t.elapsed());
        Some((vol, grid))
    }

    /// (min, max, mean) over the active voxels.
    fn active_stats(g: &Grid) -> (f32, f32, f64) {
        let (mut lo, mut hi, mut sum, mut n) = (f32::MAX, f32::MIN, 0f64, 0u64);
        for l in &g.leaves {
            for_each_on(&l.mask, |i| {
                let v = l.values[i];
                lo = lo.min(v);
                hi = hi.max(v);
                sum += v as f64;
                n += 1;
            });
        }
        for t in &g.tiles {
            let c = (t.dim * t.dim * t.dim) as u64;
            lo = lo.min(t.value);
            hi = hi.max(t.value);
            sum += t.value as f64 * c as f64;
            n += c;
        }
        (lo, hi, sum / n as f64)
    }

    #[test]
    fn smoke_half_float_blosc() {
        let Some((vol, g)) = load("smoke_vdb/smoke.vdb", None) else {
            return;
        };
        assert_eq!(vol.active_voxels, Some(1_049_275));
        assert_eq!(vol.name.as_deref(), Some("density"));
        assert_eq!(vol.variables, vec!["density".to_string()]);
        let (lo, hi, mean) = active_stats(&g);
        eprintln!(
            "smoke: dims {:?} spacing {} origin {} min {lo} max {hi} mean {mean}",
            vol.dims(),
            vol.spacing(),
            vol.origin()
        );
        assert_eq!(vol.dims(), [111, 222, 112]);
        assert!((vol.spacing().x - 0.476).abs() < 1e-3);
        assert!(lo > 0.0 && lo < 2e-5, "min {lo}");
        assert!((hi - 5.715).abs() < 2e-3, "max {hi}");
        assert!((mean - 0.163).abs() < 1e-3, "mean {mean}");
    }

    #[test]
    fn cloud_float_blosc() {
        let Some((vol, g)) = load("cloud_vdb/cloud.vdb", Some("density")) else {
            return;
        };
        assert_eq!(vol.active_voxels, Some(690_249));
        assert_eq!(vol.variables, vec!["density".to_string()]);
        let (lo, hi, mean) = active_stats(&g);
        eprintln!(
            "cloud: dims {:?} spacing {} origin {} min {lo} max {hi} mean {mean}",
            vol.dims(),
            vol.spacing(),
            vol.origin()
        );
        assert_eq!(vol.dims(), [150, 101, 174]);
        assert!((vol.spacing().x - 0.01).abs() < 1e-6);
        assert!(lo > 0.0 && lo < 2e-8, "min {lo}");
        assert!((hi - 1.007).abs() < 1e-3, "max {hi}");
        assert!((mean - 0.63).abs() < 5e-3, "mean {mean}");
    }

    #[test]
    fn unknown_grid_lists_the_grids() {
        let Some(p) = data_path("cloud_vdb/cloud.vdb") else {
            return;
        };
        let opts = OpenOptions {
            variable: Some("temperature".into()),
            ..Default::default()
        };
        let e = read(&p, &opts).unwrap_err().to_string();
        assert!(e.contains("temperature") && e.contains("density"), "{e}");
    }

    fn read_bytes(bytes: &[u8]) -> Result<Volume> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.vdb");
        std::fs::write(&p, bytes).unwrap();
        read(&p, &OpenOptions::default())
    }

    #[test]
    fn truncated_files_are_errors() {
        let Some(p) = data_path("smoke_vdb/smoke.vdb") else {
            return;
        };
        let buf = std::fs::read(&p).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("cut.vdb");
        let mut cuts: Vec<usize> = (0..600).collect();
        cuts.extend((1..200).map(|k| buf.len() * k / 200));
        cuts.extend([buf.len() - 1, buf.len() - 8]);
        for cut in cuts {
            std::fs::write(&q, &buf[..cut]).unwrap();
            assert!(read(&q, &OpenOptions::default()).is_err(), "cut {cut}");
        }
    }

    #[test]
    fn corrupt_bytes_never_panic() {
        let Some(p) = data_path("cloud_vdb/cloud.vdb") else {
            return;
        };
        let buf = std::fs::read(&p).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("bad.vdb");
        // Flip bytes across the header, topology and some buffers.
        let mut at: Vec<usize> = (8..0x1c0).collect();
        at.extend((1..300).map(|k| buf.len() * k / 300));
        for (n, &i) in at.iter().enumerate() {
            let mut b = buf.clone();
            b[i] ^= if n % 2 == 0 { 0xff } else { 0x80 };
            std::fs::write(&q, &b).unwrap();
            let _ = read(&q, &OpenOptions::default());
        }
    }

    #[test]
    fn wrong_magic_and_absurd_counts() {
        let e = read_bytes(b"NOT A VDB FILE AT ALL")
            .unwrap_err()
            .to_string();
        assert!(e.contains("magic"), "{e}");
        let mut h = Vec::new();
        h.extend_from_slice(&MAGIC.to_le_bytes());
        h.extend_from_slice(&224u32.to_le_bytes());
        h.extend_from_slice(&[10, 0, 0, 0, 0, 0, 0, 0, 1]);
        h.extend_from_slice(&[b'0'; 36]);
        // Absurd metadata count.
        let mut a = h.clone();
        a.extend_from_slice(&u32::MAX.to_le_bytes());
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("metadata"), "{e}");
        // Absurd grid count.
        let mut a = h.clone();
        a.extend_from_slice(&0u32.to_le_bytes());
        a.extend_from_slice(&0x7fff_ffffu32.to_le_bytes());
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("grid_count"), "{e}");
        // Absurd string length.
        let mut a = h.clone();
        a.extend_from_slice(&0u32.to_le_bytes());
        a.extend_from_slice(&1u32.to_le_bytes());
        a.extend_from_slice(&0xffff_fff0u32.to_le_bytes());
        a.extend_from_slice(&[0u8; 64]);
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("grid_name"), "{e}");
        // Old format version.
        let mut a = h.clone();
        a[8..12].copy_from_slice(&200u32.to_le_bytes());
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("unsupported"), "{e}");
    }

    /// Rewrites a Blosc file with zip (`zip`) or no compression, keeping the
    /// active-mask compression: the same grid must come back.
    fn transcode(path: &Path, zip: bool) -> Vec<u8> {
        let buf = std::fs::read(path).unwrap();
        let parsed = parse(path, &buf, &OpenOptions::default()).unwrap();
        assert_eq!(parsed.grids.len(), 1);
        let g = parsed.grid;
        let mut out = buf[..g.compression_pos].to_vec();
        out.extend_from_slice(
            &(COMPRESS_ACTIVE_MASK | if zip { COMPRESS_ZIP } else { 0 }).to_le_bytes(),
        );
        let mut at = g.compression_pos + 4;
        for &(s, e, n) in &g.chunks {
            out.extend_from_slice(&buf[at..s]);
            let c = i64::from_le_bytes(buf[s..s + 8].try_into().unwrap());
            let raw = if c <= 0 {
                buf[s + 8..e].to_vec()
            } else {
                match blosc_decode(&buf[s + 8..e], n) {
                    Ok(v) => v,
                    Err(_) => panic!("blosc chunk at {s}"),
                }
            };
            if zip {
                let mut z =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                std::io::Write::write_all(&mut z, &raw).unwrap();
                let z = z.finish().unwrap();
                out.extend_from_slice(&(z.len() as i64).to_le_bytes());
                out.extend_from_slice(&z);
            } else {
                out.extend_from_slice(&raw);
            }
            at = e;
        }
        out.extend_from_slice(&buf[at..]);
        // The descriptor's end offset sits just before the grid.
        let end = out.len() as i64;
        out[g.compression_pos - 8..g.compression_pos].copy_from_slice(&end.to_le_bytes());
        out
    }

    #[test]
    fn zip_and_uncompressed_match_blosc() {
        for rel in ["smoke_vdb/smoke.vdb", "cloud_vdb/cloud.vdb"] {
            let Some(p) = data_path(rel) else {
                return;
            };
            let want = read(&p, &OpenOptions::default()).unwrap();
            for zip in [true, false] {
                let bytes = transcode(&p, zip);
                let got = read_bytes(&bytes).unwrap();
                assert_eq!(got.dims(), want.dims(), "{rel} zip={zip}");
                assert_eq!(got.active_voxels, want.active_voxels, "{rel} zip={zip}");
                assert!(got.data() == want.data(), "{rel} zip={zip}: values differ");
            }
        }
    }

    #[test]
    fn lz4_and_half_basics() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        // "abcabcabcabc": 3 literals then a match of 9 at offset 3.
        let src = [0x35, b'a', b'b', b'c', 3, 0];
        let mut dst = [0u8; 12];
        // Last sequence must be literals: our decoder accepts a trailing match too.
        assert_eq!(lz4_block(&src, &mut dst), None); // ends without final literals → runs past src
        let src = [0x35, b'a', b'b', b'c', 3, 0, 0x10, b'x'];
        let mut dst = [0u8; 13];
        assert_eq!(lz4_block(&src, &mut dst), Some(13));
        assert_eq!(&dst, b"abcabcabcabcx");
    }
}
