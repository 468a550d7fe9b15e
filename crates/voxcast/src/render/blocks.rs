//! The block grid for empty-space skipping and the adaptive marchers: the
//! volume cut into blocks of `B³` cells, each with the range of normalised
//! values it can produce by trilinear interpolation and its largest gradient.
//!
//! Block `(bx, by, bz)` covers voxel coordinates `[bx·B, (bx+1)·B]` on x (and
//! likewise y, z): the voxels on its far faces belong to it as well as to the
//! next block, because trilinear samples inside the block read them. So a
//! sample anywhere inside the block has a value in `[min, max]`, and a block
//! whose transfer-function opacity is zero over that range contributes
//! exactly nothing: skipping it changes the speed, not the pixels.

use crate::transfer::{Lut, TransferFunction, LUT_SIZE};
use crate::volume::{Grid, GridVisitor, Voxel};
use glam::Vec3;
use rayon::prelude::*;

/// Default block edge in cells.
pub const DEFAULT_BLOCK: usize = 8;

/// Per-block value range.
#[derive(Clone, Debug)]
pub struct BlockGrid {
    /// Block edge in cells.
    pub size: usize,
    /// Number of blocks along x, y, z.
    pub counts: [usize; 3],
    /// Normalised `[min, max]` per block (x fastest).
    pub range: Vec<[f32; 2]>,
}

impl BlockGrid {
    /// Index of block `(bx, by, bz)`.
    #[inline(always)]
    pub fn index(&self, b: [usize; 3]) -> usize {
        b[0] + self.counts[0] * (b[1] + self.counts[1] * b[2])
    }

    /// The box (voxel coordinates) around the blocks that are not `empty`,
    /// within `[lo, hi]` (the ray-clipping box; a face of it on the grid's
    /// edge is kept, so nothing inside that box is lost); an empty box
    /// (`lo > hi`) when every block is empty. O(blocks).
    pub fn occupied_box(&self, empty: &[bool], lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        let [cx, cy, cz] = self.counts;
        let (mut mn, mut mx) = ([usize::MAX; 3], [0usize; 3]);
        for (i, _) in empty.iter().enumerate().filter(|(_, e)| !**e) {
            let c = [i % cx, i / cx % cy, i / (cx * cy)];
            for a in 0..3 {
                mn[a] = mn[a].min(c[a]);
                mx[a] = mx[a].max(c[a]);
            }
        }
        if mn[0] == usize::MAX {
            return (Vec3::ONE, Vec3::ZERO);
        }
        let b = self.size as f32;
        let n = [cx, cy, cz];
        let face = |a: usize| {
            let l = if mn[a] == 0 { lo[a] } else { mn[a] as f32 * b };
            let h = if mx[a] + 1 == n[a] {
                hi[a]
            } else {
                (mx[a] + 1) as f32 * b
            };
            (l.max(lo[a]), h.min(hi[a]))
        };
        let (x, y, z) = (face(0), face(1), face(2));
        (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1))
    }

    /// For each block, whether `tf` makes all of it transparent: O(blocks).
    pub fn empty_flags(&self, tf: &TransferFunction) -> Vec<bool> {
        self.range
            .iter()
            .map(|&[lo, hi]| hi < 0.0 || tf.max_opacity_in(lo, hi) <= 0.0)
            .collect()
    }
}

/// Number of blocks per axis for `dims` voxels (blocks cover the
/// `dims − 1` cells; a one-voxel axis has one block).
pub(super) fn block_counts(dims: [usize; 3], b: usize) -> [usize; 3] {
    dims.map(|d| d.saturating_sub(1).div_ceil(b).max(1))
}

/// Runs `f(voxel range lo..=hi per axis)` for every block, in parallel.
pub(super) fn per_block<R: Send>(
    dims: [usize; 3],
    b: usize,
    f: impl Fn([usize; 3], [usize; 3]) -> R + Sync,
) -> Vec<R> {
    let counts = block_counts(dims, b);
    (0..counts[0] * counts[1] * counts[2])
        .into_par_iter()
        .map(|idx| {
            let bi = [
                idx % counts[0],
                idx / counts[0] % counts[1],
                idx / (counts[0] * counts[1]),
            ];
            let lo = bi.map(|c| c * b);
            let hi = [0, 1, 2].map(|a| ((bi[a] + 1) * b).min(dims[a] - 1));
            f(lo, hi)
        })
        .collect()
}

/// Calls `f` with every stored value (not normalised) of the voxels
/// `lo..=hi`, row by row: the walk the block grid's ranges and the octree's
/// leaves share.
#[inline]
pub(crate) fn for_each_stored<T: Voxel>(
    grid: &Grid<'_, T>,
    lo: [usize; 3],
    hi: [usize; 3],
    mut f: impl FnMut(f32),
) {
    for k in lo[2]..=hi[2] {
        for j in lo[1]..=hi[1] {
            for v in &grid.row(j, k)[lo[0]..=hi[0]] {
                f(v.to_f32());
            }
        }
    }
}

/// Builds the block grid (value ranges) from a typed grid (see
/// [`crate::volume::Volume::visit`]).
pub struct BuildBlocks {
    pub size: usize,
}

impl GridVisitor for BuildBlocks {
    type Output = BlockGrid;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> BlockGrid {
        let b = self.size.max(1);
        let dims = grid.dims();
        let (scale, offset) = grid.scale_offset();
        let range = per_block(dims, b, |lo, hi| {
            let (mut mn, mut mx) = (f32::INFINITY, f32::NEG_INFINITY);
            for_each_stored(grid, lo, hi, |v| {
                mn = mn.min(v);
                mx = mx.max(v);
            });
            // Raw stored values normalised at the end (scale > 0).
            [mn * scale + offset, mx * scale + offset]
        });
        BlockGrid {
            size: b,
            counts: block_counts(dims, b),
            range,
        }
    }
}

/// The mean extinction per unit length over each block's voxels, `σ` read
/// from `sigma` (a [`crate::transfer::Lut`]'s table) at each voxel's value
/// (0 below the transfer function's domain): what a ray crossing the block
/// meets on average (for the `importance` pdf).
pub struct BuildMeanSigma<'a> {
    pub size: usize,
    pub sigma: &'a [f32; LUT_SIZE],
}

impl GridVisitor for BuildMeanSigma<'_> {
    type Output = Vec<f32>;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Vec<f32> {
        let b = self.size.max(1);
        let dims = grid.dims();
        let (scale, offset) = grid.scale_offset();
        per_block(dims, b, |lo, hi| {
            let mut sum = 0.0f64;
            let mut count = 0usize;
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    let row = &grid.row(j, k)[lo[0]..=hi[0]];
                    let mut s = 0.0f32;
                    for v in row {
                        if let Some(i) = Lut::index(v.to_f32() * scale + offset) {
                            s += self.sigma[i];
                        }
                    }
                    sum += s as f64;
                    count += row.len();
                }
            }
            (sum / count.max(1) as f64) as f32
        })
    }
}

/// The largest central-difference gradient component, `max(|∂f/∂x|,
/// |∂f/∂y|, |∂f/∂z|)` of the normalised field per voxel, over each block's
/// voxels (for `adaptive-max`; built on first use).
pub struct BuildMaxGradient {
    pub size: usize,
}

impl GridVisitor for BuildMaxGradient {
    type Output = Vec<f32>;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Vec<f32> {
        let b = self.size.max(1);
        let dims = grid.dims();
        let (scale, _) = grid.scale_offset();
        per_block(dims, b, |lo, hi| {
            let mut g = 0.0f32;
            for k in lo[2]..=hi[2] {
                let (k0, k1) = (k.saturating_sub(1), (k + 1).min(dims[2] - 1));
                let kz = 1.0 / (k1 - k0).max(1) as f32;
                for j in lo[1]..=hi[1] {
                    let (j0, j1) = (j.saturating_sub(1), (j + 1).min(dims[1] - 1));
                    let jy = 1.0 / (j1 - j0).max(1) as f32;
                    let row = grid.row(j, k);
                    let (ry0, ry1) = (grid.row(j0, k), grid.row(j1, k));
                    let (rz0, rz1) = (grid.row(j, k0), grid.row(j, k1));
                    for i in lo[0]..=hi[0] {
                        // Central differences, one-sided at the faces.
                        let (i0, i1) = (i.saturating_sub(1), (i + 1).min(dims[0] - 1));
                        let gx = (row[i1].to_f32() - row[i0].to_f32()) / (i1 - i0).max(1) as f32;
                        let gy = (ry1[i].to_f32() - ry0[i].to_f32()) * jy;
                        let gz = (rz1[i].to_f32() - rz0[i].to_f32()) * kz;
                        g = g.max(gx.abs()).max(gy.abs()).max(gz.abs());
                    }
                }
            }
            g * scale
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::Volume;
    use glam::Vec3;

    #[test]
    fn blocks_bound_every_trilinear_sample() {
        let vol = Volume::from_fn([19, 11, 7], Vec3::ONE, |i, j, k| {
            ((i * 31 + j * 17 + k * 7) % 23) as f32
        })
        .unwrap();
        let s = *vol.stats();
        let blocks = vol.visit(s.min, s.max, BuildBlocks { size: 4 });
        assert_eq!(blocks.counts, [5, 3, 2]);
        struct Check<'a>(&'a BlockGrid);
        impl GridVisitor for Check<'_> {
            type Output = ();
            fn visit<T: Voxel>(self, grid: &Grid<'_, T>) {
                let b = self.0;
                for n in 0..5000 {
                    let f = |m: u32| ((n as u32).wrapping_mul(m) % 1000) as f32 / 1000.0;
                    let p = Vec3::new(f(7919) * 18.0, f(104_729) * 10.0, f(1_299_709) * 6.0);
                    let bi = [
                        ((p.x / 4.0) as usize).min(4),
                        ((p.y / 4.0) as usize).min(2),
                        ((p.z / 4.0) as usize).min(1),
                    ];
                    let [lo, hi] = b.range[b.index(bi)];
                    let v = grid.sample(p);
                    assert!(
                        v >= lo - 1e-6 && v <= hi + 1e-6,
                        "{p} {v} not in [{lo}, {hi}]"
                    );
                }
            }
        }
        vol.visit(s.min, s.max, Check(&blocks));
    }
}
