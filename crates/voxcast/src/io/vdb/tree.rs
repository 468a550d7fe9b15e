//! Reading one grid: its compression flags and transform, the 5-4-3 tree's
//! topology (root, internal nodes, leaf masks) and the value buffers
//! (OpenVDB's `readCompressedValues` / `readData`: inactive values,
//! selection masks, half floats, zip or Blosc chunks).

use super::blosc::{blosc_decode, BloscError};
use super::cursor::Cursor;
use super::grid::{for_each_on, is_on, Grid, Leaf, Tile, ValueKind};
use super::{COMPRESS_ACTIVE_MASK, COMPRESS_BLOSC, COMPRESS_ZIP};
use crate::error::{Error, Result};
use std::io::Read;

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

pub(super) fn read_grid(r: &mut Cursor, kind: ValueKind) -> Result<Grid> {
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

/// IEEE half to single.
pub(super) fn f16_to_f32(h: u16) -> f32 {
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
