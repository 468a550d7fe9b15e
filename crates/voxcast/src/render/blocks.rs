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

use crate::transfer::TransferFunction;
use crate::volume::{Grid, GridVisitor, Voxel};
use rayon::prelude::*;

/// Default block edge in cells.
pub const DEFAULT_BLOCK: usize = 8;

/// Per-block value range and gradient bound.
#[derive(Clone, Debug)]
pub struct BlockGrid {
    /// Block edge in cells.
    pub size: usize,
    /// Number of blocks along x, y, z.
    pub counts: [usize; 3],
    /// Normalised `[min, max]` per block (x fastest).
    pub range: Vec<[f32; 2]>,
    /// Largest central-difference gradient component, `max(|∂f/∂x|, |∂f/∂y|,
    /// |∂f/∂z|)`, of the normalised field per voxel, over the block's voxels.
    pub max_gradient: Vec<f32>,
}

impl BlockGrid {
    /// Index of block `(bx, by, bz)`.
    #[inline(always)]
    pub fn index(&self, b: [usize; 3]) -> usize {
        b[0] + self.counts[0] * (b[1] + self.counts[1] * b[2])
    }

    /// For each block, whether `tf` makes all of it transparent: O(blocks).
    pub fn empty_flags(&self, tf: &TransferFunction) -> Vec<bool> {
        self.range
            .iter()
            .map(|&[lo, hi]| hi < 0.0 || tf.max_opacity_in(lo, hi) <= 0.0)
            .collect()
    }
}

/// Builds the block grid from a typed grid (see [`crate::volume::Volume::visit`]).
pub struct BuildBlocks {
    pub size: usize,
}

impl GridVisitor for BuildBlocks {
    type Output = BlockGrid;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> BlockGrid {
        let b = self.size.max(1);
        let dims = grid.dims();
        // Blocks over the cells (dims − 1 per axis; a one-voxel axis has one block).
        let counts = dims.map(|d| d.saturating_sub(1).div_ceil(b).max(1));
        let n = counts[0] * counts[1] * counts[2];
        let per_block: Vec<([f32; 2], f32)> = (0..n)
            .into_par_iter()
            .map(|i| {
                let bi = [
                    i % counts[0],
                    i / counts[0] % counts[1],
                    i / (counts[0] * counts[1]),
                ];
                let lo = bi.map(|c| c * b);
                let hi = [0, 1, 2].map(|a| ((bi[a] + 1) * b).min(dims[a] - 1));
                let mut mn = f32::INFINITY;
                let mut mx = f32::NEG_INFINITY;
                let mut g = 0.0f32;
                for k in lo[2]..=hi[2] {
                    for j in lo[1]..=hi[1] {
                        for i in lo[0]..=hi[0] {
                            let v = grid.voxel(i, j, k);
                            mn = mn.min(v);
                            mx = mx.max(v);
                            // Central differences (one-sided at the volume's faces).
                            let d = |a: usize, idx: [usize; 3]| -> f32 {
                                let mut p = idx;
                                let mut q = idx;
                                p[a] = (idx[a] + 1).min(dims[a] - 1);
                                q[a] = idx[a].saturating_sub(1);
                                let span = (p[a] - q[a]).max(1) as f32;
                                (grid.voxel(p[0], p[1], p[2]) - grid.voxel(q[0], q[1], q[2])) / span
                            };
                            let idx = [i, j, k];
                            g = g
                                .max(d(0, idx).abs())
                                .max(d(1, idx).abs())
                                .max(d(2, idx).abs());
                        }
                    }
                }
                ([mn, mx], g)
            })
            .collect();
        BlockGrid {
            size: b,
            counts,
            range: per_block.iter().map(|p| p.0).collect(),
            max_gradient: per_block.iter().map(|p| p.1).collect(),
        }
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
