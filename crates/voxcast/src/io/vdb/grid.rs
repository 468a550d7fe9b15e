//! A grid's sparse content as read (leaves of 8³ voxels, active tiles at any
//! level, the value masks) and the dense volume made from it over the
//! active bounding box.

use crate::error::{Error, Result};
use crate::volume::{checked_voxel_count, Volume, VoxelData};
use glam::Vec3;
use std::path::Path;

/// Value type of a scalar grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ValueKind {
    /// Bytes of a full value (background, tiles, inactive values).
    pub(super) size: usize,
    /// Values arrays saved as half floats.
    pub(super) half: bool,
}

pub(super) fn value_kind(type_name: &str) -> Option<ValueKind> {
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
pub(super) struct Leaf {
    pub(super) origin: [i64; 3],
    pub(super) mask: [u64; 8],
    pub(super) values: Vec<f32>,
}

/// An active tile: a cube of `dim`³ voxels at `origin`, all of `value`.
pub(super) struct Tile {
    pub(super) origin: [i64; 3],
    pub(super) dim: i64,
    pub(super) value: f32,
}

/// The sparse content of one grid.
pub(super) struct Grid {
    pub(super) background: f32,
    pub(super) leaves: Vec<Leaf>,
    pub(super) tiles: Vec<Tile>,
    /// World = index · scale + translation.
    pub(super) scale: [f64; 3],
    pub(super) translation: [f64; 3],
    /// Offset of the grid's compression flags.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) compression_pos: usize,
    /// Compressed chunks read: (offset of the size, end, uncompressed bytes).
    #[cfg_attr(not(test), allow(dead_code))]
    pub(super) chunks: Vec<(usize, usize, usize)>,
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

pub(super) fn for_each_on(mask: &[u64], mut f: impl FnMut(usize)) {
    for (w, &word) in mask.iter().enumerate() {
        let mut bits = word;
        while bits != 0 {
            let b = bits.trailing_zeros() as usize;
            f(w * 64 + b);
            bits &= bits - 1;
        }
    }
}

pub(super) fn is_on(mask: &[u64], i: usize) -> bool {
    mask.get(i / 64).is_some_and(|w| (w >> (i % 64)) & 1 == 1)
}

/// Makes the dense volume from the sparse grid.
pub(super) fn to_volume(
    path: &Path,
    name: String,
    grid: Grid,
    names: Vec<String>,
) -> Result<Volume> {
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
    let mut vol = Volume::new(d, spacing, origin, VoxelData::F32(data.into()))
        .map_err(|e| Error::format(path, "grid", e.to_string()))?;
    vol.active_voxels = Some(active);
    vol.name = Some(name);
    vol.variables = names;
    Ok(vol)
}
