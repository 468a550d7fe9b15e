//! An octree over the normalised density (S3): leaves are the blocks of the
//! block grid (`B³` cells, far faces included, so a leaf's `[min, max]`
//! bounds every trilinear sample inside it), and each parent merges up to
//! 2×2×2 children, up to a single root. Every node keeps min, max and mean.
//!
//! The LOD marcher ([`super::lod`]) walks the leaves front to back, skips
//! whole empty subtrees at once, and picks its decimation spacing in a leaf
//! from the leaf's contribution.

use crate::volume::{Grid, GridVisitor, Voxel};
use glam::Vec3;

/// Statistics of one node, normalised to the data window.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    pub min: f32,
    pub max: f32,
    pub mean: f32,
}

/// One level of the tree: `counts` nodes per axis, x fastest.
#[derive(Clone, Debug)]
pub struct Level {
    pub counts: [usize; 3],
    pub nodes: Vec<Node>,
}

/// The octree; `levels[0]` are the leaves, the last level is the root.
#[derive(Clone, Debug)]
pub struct Octree {
    /// Leaf edge in cells.
    pub leaf: usize,
    pub levels: Vec<Level>,
}

impl Octree {
    /// Emptiness of every node of every level from the leaves' emptiness
    /// (a node is empty when all its children are).
    pub fn empty_levels(&self, leaf_empty: &[bool]) -> Vec<Vec<bool>> {
        let mut out = vec![leaf_empty.to_vec()];
        for l in 1..self.levels.len() {
            let (child, cc) = (&out[l - 1], self.levels[l - 1].counts);
            let pc = self.levels[l].counts;
            let mut e = vec![true; pc[0] * pc[1] * pc[2]];
            for z in 0..cc[2] {
                for y in 0..cc[1] {
                    for x in 0..cc[0] {
                        if !child[x + cc[0] * (y + cc[1] * z)] {
                            e[x / 2 + pc[0] * (y / 2 + pc[1] * (z / 2))] = false;
                        }
                    }
                }
            }
            out.push(e);
        }
        out
    }

    /// Index at `level` of the ancestor of leaf `(x, y, z)`.
    #[inline]
    pub fn ancestor(&self, level: usize, leaf: [usize; 3]) -> usize {
        let c = self.levels[level].counts;
        let [x, y, z] = leaf.map(|v| v >> level);
        x + c[0] * (y + c[1] * z)
    }

    /// Box of the node at `level` that holds leaf `leaf`, in voxel
    /// coordinates.
    #[inline]
    pub fn node_box(&self, level: usize, leaf: [usize; 3]) -> (Vec3, Vec3) {
        let edge = (self.leaf << level) as f32;
        let c = leaf.map(|v| (v >> level) as f32);
        let lo = Vec3::from(c) * edge;
        (lo, lo + Vec3::splat(edge))
    }

    /// Leaf coordinates of leaf index `i`.
    #[inline]
    pub fn leaf_coords(&self, i: usize) -> [usize; 3] {
        let c = self.levels[0].counts;
        [i % c[0], i / c[0] % c[1], i / (c[0] * c[1])]
    }
}

/// Builds the octree with leaves of `leaf` cells (see
/// [`crate::volume::Volume::visit`]).
pub struct BuildOctree {
    pub leaf: usize,
}

impl GridVisitor for BuildOctree {
    type Output = Octree;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Octree {
        let b = self.leaf.max(1);
        let dims = grid.dims();
        let (scale, offset) = grid.scale_offset();
        // The same blocks as the block grid (empty-space skipping), so a
        // leaf's range is its block's range.
        let counts = super::blocks::block_counts(dims, b);
        let leaves: Vec<Node> = super::blocks::per_block(dims, b, |lo, hi| {
            let (mut mn, mut mx, mut sum, mut n) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f64, 0u64);
            super::blocks::for_each_stored(grid, lo, hi, |v| {
                mn = mn.min(v);
                mx = mx.max(v);
                sum += v as f64;
                n += 1;
            });
            Node {
                min: mn * scale + offset,
                max: mx * scale + offset,
                mean: (sum / n.max(1) as f64) as f32 * scale + offset,
            }
        });
        let mut levels = vec![Level {
            counts,
            nodes: leaves,
        }];
        while levels
            .last()
            .is_some_and(|l| l.counts.iter().any(|&c| c > 1))
        {
            let child = levels.last().expect("non-empty");
            let cc = child.counts;
            let pc = cc.map(|c| c.div_ceil(2));
            let mut nodes = vec![
                Node {
                    min: f32::INFINITY,
                    max: f32::NEG_INFINITY,
                    mean: 0.0,
                };
                pc[0] * pc[1] * pc[2]
            ];
            let mut n = vec![0u32; nodes.len()];
            for z in 0..cc[2] {
                for y in 0..cc[1] {
                    for x in 0..cc[0] {
                        let c = child.nodes[x + cc[0] * (y + cc[1] * z)];
                        let pi = x / 2 + pc[0] * (y / 2 + pc[1] * (z / 2));
                        let p = &mut nodes[pi];
                        p.min = p.min.min(c.min);
                        p.max = p.max.max(c.max);
                        p.mean += c.mean;
                        n[pi] += 1;
                    }
                }
            }
            for (p, n) in nodes.iter_mut().zip(n) {
                p.mean /= n.max(1) as f32;
            }
            levels.push(Level { counts: pc, nodes });
        }
        Octree { leaf: b, levels }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::blocks::BuildBlocks;
    use crate::volume::Volume;

    #[test]
    fn leaves_match_the_block_grid_and_parents_bound_children() {
        let vol = Volume::from_fn([37, 21, 13], Vec3::ONE, |i, j, k| {
            ((i * 13 + j * 7 + k * 29) % 31) as f32 * if i > 20 { 0.0 } else { 1.0 }
        })
        .unwrap();
        let s = *vol.stats();
        let tree = vol.visit(s.min, s.max, BuildOctree { leaf: 4 });
        let blocks = vol.visit(s.min, s.max, BuildBlocks { size: 4 });
        assert_eq!(tree.levels[0].counts, blocks.counts);
        for (n, r) in tree.levels[0].nodes.iter().zip(&blocks.range) {
            assert_eq!([n.min, n.max], *r);
            assert!(n.mean >= n.min && n.mean <= n.max);
        }
        // Counts halve up to a single root that spans the data range.
        assert_eq!(tree.levels.last().unwrap().counts, [1, 1, 1]);
        let root = tree.levels.last().unwrap().nodes[0];
        assert_eq!((root.min, root.max), (0.0, 1.0));
        for l in 1..tree.levels.len() {
            let (cc, pc) = (tree.levels[l - 1].counts, tree.levels[l].counts);
            for z in 0..cc[2] {
                for y in 0..cc[1] {
                    for x in 0..cc[0] {
                        let c = tree.levels[l - 1].nodes[x + cc[0] * (y + cc[1] * z)];
                        let p = tree.levels[l].nodes[x / 2 + pc[0] * (y / 2 + pc[1] * (z / 2))];
                        assert!(p.min <= c.min && p.max >= c.max);
                    }
                }
            }
        }
        // Emptiness: the x > 20 half is zero; a parent is empty only when
        // all its children are.
        let leaf_empty: Vec<bool> = tree.levels[0].nodes.iter().map(|n| n.max <= 0.0).collect();
        let e = tree.empty_levels(&leaf_empty);
        assert!(leaf_empty.iter().any(|&x| x) && leaf_empty.iter().any(|&x| !x));
        assert!(!e.last().unwrap()[0]);
        for (i, &le) in leaf_empty.iter().enumerate() {
            let c = tree.leaf_coords(i);
            if !le {
                for (l, el) in e.iter().enumerate() {
                    assert!(!el[tree.ancestor(l, c)]);
                }
            }
        }
    }
}
