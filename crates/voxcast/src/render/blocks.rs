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

/// The finer block edge the CPU renderer takes by default on sparse data
/// for the marchers that only skip with blocks, and `adaptive+grouped`
/// ([`Renderer::block_size_for`](super::Renderer::block_size_for)).
pub const SPARSE_BLOCK: usize = 4;

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

/// The change of `n·l` per voxel that [`BlockGrid::classified_change`]
/// allows for with shading: a normal turning by about 15° per voxel
/// (sin 15° ≈ 0.26). Calibrated on the shaded smoke of the office and FDS
/// scenes (docs/methods.md): a full turn per voxel kept 49–52 dB but
/// refined every dense block.
const TURN: f32 = 0.25;

/// Range maxima of a table in O(1) per query (a sparse table: level `l`
/// holds the maximum of every run of `2^l` entries).
struct RangeMax {
    levels: Vec<Vec<f32>>,
}

impl RangeMax {
    fn new(v: Vec<f32>) -> RangeMax {
        let mut levels = vec![v];
        let mut w = 1;
        while 2 * w <= levels[0].len() {
            let prev = levels.last().expect("level 0 exists");
            let next = (0..prev.len() - w)
                .map(|i| prev[i].max(prev[i + w]))
                .collect();
            levels.push(next);
            w *= 2;
        }
        RangeMax { levels }
    }

    /// The largest entry of `a..=b` (`a ≤ b`).
    fn max(&self, a: usize, b: usize) -> f32 {
        let l = (b - a + 1).ilog2() as usize;
        let t = &self.levels[l];
        t[a].max(t[b + 1 - (1 << l)])
    }
}

/// What the eye sees of a table entry: the opacity of one unit length,
/// `α = 1 − e^(−σ)`, and the linear colour premultiplied by it.
fn classified(lut: &Lut, i: usize) -> [f32; 4] {
    let e = lut.entry(i);
    let a = 1.0 - (-lut.sigma(i)).exp();
    [e[0] * a, e[1] * a, e[2] * a, a]
}

impl BlockGrid {
    /// Per block, a bound on how much the *classified* signal — the
    /// opacity of one unit length and the colour premultiplied by it, the
    /// largest change of any of the four — changes per voxel step inside
    /// the block: the block's largest partial derivative of the normalised
    /// field (`max_gradient`, [`BuildMaxGradient`]) times the steepest slope
    /// of the classified table over the block's value range, and never more
    /// than the table's total variation over that range (a sharp but low
    /// step of the transfer function costs no more than its height). Empty
    /// blocks get 0, and so does a block whose values the transfer function
    /// maps to one colour and opacity — whatever their gradient. `adaptive`
    /// takes its `k` from this: O(blocks) per render, after an O(table)
    /// set-up, so it is recomputed whenever the transfer function changes,
    /// like [`BlockGrid::empty_flags`].
    ///
    /// With shading (`shade` > 0: the diffuse and specular weights, the
    /// share of a sample's colour the normal decides), the colour also
    /// changes as the normal turns, which the transfer function does not
    /// show: the bound is raised to `shade × 0.25 ×` the block's
    /// largest opacity. Thin haze keeps
    /// its long steps; a block dense enough to show a lit surface gets the
    /// fine ones, where rays terminate within a few samples anyway.
    pub fn classified_change(
        &self,
        lut: &Lut,
        max_gradient: &[f32],
        empty: &[bool],
        shade: f32,
    ) -> Vec<f32> {
        let n = LUT_SIZE;
        let q: Vec<[f32; 4]> = (0..n).map(|i| classified(lut, i)).collect();
        // Largest channel change from entry i to i + 1, and its prefix sums
        // (the total variation along the table).
        let slope: Vec<f32> = q
            .windows(2)
            .map(|w| {
                (0..4)
                    .map(|c| (w[1][c] - w[0][c]).abs())
                    .fold(0.0, f32::max)
            })
            .collect();
        let mut tv = Vec::with_capacity(n);
        tv.push(0.0f64);
        for s in &slope {
            tv.push(tv.last().expect("pushed") + *s as f64);
        }
        let steepest = RangeMax::new(slope);
        let densest = RangeMax::new(q.iter().map(|e| e[3]).collect());
        // From "below the table" (nothing) to entry 0.
        let from_none = q[0].iter().fold(0.0f32, |m, &x| m.max(x));
        self.range
            .iter()
            .zip(max_gradient)
            .zip(empty)
            .map(|((&[lo, hi], &k), &e)| {
                if e || hi.is_nan() {
                    return 0.0;
                }
                let (Some(a), Some(b)) = (Lut::index(lo.max(0.0)), Lut::index(hi)) else {
                    return 0.0;
                };
                let jump = if lo < 0.0 { from_none } else { 0.0 };
                let lit = shade * TURN * densest.max(a, b);
                if b <= a {
                    return jump.max(lit);
                }
                let per_voxel = k * steepest.max(a, b - 1) * (n - 1) as f32;
                (per_voxel.min((tv[b] - tv[a]) as f32) + jump).max(lit)
            })
            .collect()
    }
}

/// Number of blocks per axis for `dims` voxels (blocks cover the
/// `dims − 1` cells; a one-voxel axis has one block).
pub(super) fn block_counts(dims: [usize; 3], b: usize) -> [usize; 3] {
    dims.map(|d| d.saturating_sub(1).div_ceil(b).max(1))
}

/// Block `c`'s voxels along an axis of `d` voxels with blocks of `b` cells:
/// `c·b ..= min((c+1)·b, d−1)` (the far face shared with the next block).
fn block_span(c: usize, b: usize, d: usize) -> (usize, usize) {
    (c * b, ((c + 1) * b).min(d - 1))
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
            let span = [0, 1, 2].map(|a| block_span(bi[a], b, dims[a]));
            f(span.map(|s| s.0), span.map(|s| s.1))
        })
        .collect()
}

/// Calls `f` with every stored value (not normalised) of the voxels
/// `lo..=hi`, row by row: the octree's leaves' walk.
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
    /// A row of blocks along x at a time (one task each): the elementwise
    /// minimum and maximum of its voxel rows — long and contiguous, so
    /// vectorised — then each block's over its stretch of those. The voxels
    /// are read once per row of blocks they belong to (a face's twice), not
    /// in short runs of `B + 1` per block: on a 256³ u8 volume, two
    /// threads, 17.5 → 3.3 ms for 8³ blocks and 20.8 → 6.3 ms for 4³
    /// (docs/engine.md).
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> BlockGrid {
        let b = self.size.max(1);
        let dims = grid.dims();
        let counts = block_counts(dims, b);
        let (scale, offset) = grid.scale_offset();
        let rows: Vec<Vec<[f32; 2]>> = (0..counts[1] * counts[2])
            .into_par_iter()
            .map_init(
                || (vec![0.0f32; dims[0]], vec![0.0f32; dims[0]]),
                |(mn, mx), r| {
                    let ((j0, j1), (k0, k1)) = (
                        block_span(r % counts[1], b, dims[1]),
                        block_span(r / counts[1], b, dims[2]),
                    );
                    mn.fill(f32::INFINITY);
                    mx.fill(f32::NEG_INFINITY);
                    for k in k0..=k1 {
                        for j in j0..=j1 {
                            for ((lo, hi), v) in
                                mn.iter_mut().zip(mx.iter_mut()).zip(grid.row(j, k))
                            {
                                let v = v.to_f32();
                                *lo = lo.min(v);
                                *hi = hi.max(v);
                            }
                        }
                    }
                    (0..counts[0])
                        .map(|bx| {
                            let (i0, i1) = block_span(bx, b, dims[0]);
                            let lo = mn[i0..=i1].iter().fold(f32::INFINITY, |m, &v| m.min(v));
                            let hi = mx[i0..=i1].iter().fold(f32::NEG_INFINITY, |m, &v| m.max(v));
                            // Raw stored values normalised at the end (scale > 0).
                            [lo * scale + offset, hi * scale + offset]
                        })
                        .collect()
                },
            )
            .collect();
        BlockGrid {
            size: b,
            counts,
            range: rows.concat(),
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
    /// A row of blocks (one `y`, `z` block index) at a time: each voxel
    /// row's largest component per voxel, over the whole `x` extent (a
    /// long loop the compiler vectorises), is kept per `x` in `line`, and
    /// each block then takes the largest over its `x` range. The same
    /// voxels as one block at a time, each row once per block row instead
    /// of once per block, and no division per voxel: 4.4× faster on the
    /// teapot CT, where it was an eighth of a first `adaptive` render.
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Vec<f32> {
        let b = self.size.max(1);
        let dims = grid.dims();
        let (scale, _) = grid.scale_offset();
        let counts = block_counts(dims, b);
        let n = dims[0];
        let rows: Vec<Vec<f32>> = (0..counts[1] * counts[2])
            .into_par_iter()
            .map(|r| {
                let (by, bz) = (r % counts[1], r / counts[1]);
                let mut line = vec![0.0f32; n];
                for k in bz * b..=((bz + 1) * b).min(dims[2] - 1) {
                    let (k0, k1) = (k.saturating_sub(1), (k + 1).min(dims[2] - 1));
                    let kz = 1.0 / (k1 - k0).max(1) as f32;
                    for j in by * b..=((by + 1) * b).min(dims[1] - 1) {
                        let (j0, j1) = (j.saturating_sub(1), (j + 1).min(dims[1] - 1));
                        let jy = 1.0 / (j1 - j0).max(1) as f32;
                        let around = [
                            grid.row(j, k),
                            grid.row(j0, k),
                            grid.row(j1, k),
                            grid.row(j, k0),
                            grid.row(j, k1),
                        ];
                        row_max_gradient(&mut line, around, jy, kz);
                    }
                }
                (0..counts[0])
                    .map(|bx| {
                        let (lo, hi) = (bx * b, ((bx + 1) * b).min(n - 1));
                        line[lo..=hi].iter().fold(0.0f32, |g, &v| g.max(v)) * scale
                    })
                    .collect()
            })
            .collect();
        rows.concat()
    }
}

/// `line[i] = max(line[i], |∂f/∂x|, |∂f/∂y|, |∂f/∂z|)` of the stored
/// values at each voxel `i` of `row`: central differences, one-sided at
/// the faces (`ry0`, `ry1` the rows at `j − 1`, `j + 1` clamped, `jy` one
/// over their distance; `rz0`, `rz1`, `kz` the same in `z`).
#[inline]
fn row_max_gradient<T: Voxel>(
    line: &mut [f32],
    [row, ry0, ry1, rz0, rz1]: [&[T]; 5],
    jy: f32,
    kz: f32,
) {
    let n = line.len();
    let at = |i: usize, gx: f32| {
        let gy = (ry1[i].to_f32() - ry0[i].to_f32()) * jy;
        let gz = (rz1[i].to_f32() - rz0[i].to_f32()) * kz;
        gx.abs().max(gy.abs()).max(gz.abs())
    };
    // The faces: one-sided (a one-voxel row: zero).
    let (i0, i1) = (0, 1.min(n - 1));
    line[0] = line[0].max(at(0, row[i1].to_f32() - row[i0].to_f32()));
    if n > 1 {
        let gx = row[n - 1].to_f32() - row[n - 2].to_f32();
        line[n - 1] = line[n - 1].max(at(n - 1, gx));
    }
    if n > 2 {
        // Inside: `(f(i + 1) − f(i − 1))·½`, exactly the division by 2.
        let m = n - 1;
        let it = line[1..m]
            .iter_mut()
            .zip(row[..m - 1].iter().zip(&row[2..]))
            .zip(ry0[1..m].iter().zip(&ry1[1..m]))
            .zip(rz0[1..m].iter().zip(&rz1[1..m]));
        for (((o, (l, r)), (y0, y1)), (z0, z1)) in it {
            let gx = (r.to_f32() - l.to_f32()) * 0.5;
            let gy = (y1.to_f32() - y0.to_f32()) * jy;
            let gz = (z1.to_f32() - z0.to_f32()) * kz;
            *o = o.max(gx.abs()).max(gy.abs()).max(gz.abs());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::render::march::classified_level;

    /// Three 8³ blocks along x: the first a steep ramp over values the
    /// transfer function maps to one opacity and colour, the second a
    /// steep fall joining it to the third, a gentle ramp across the
    /// transfer function's sharp edge at 0.3.
    fn edge_scene() -> (BlockGrid, Vec<f32>, Lut, Vec<bool>) {
        let vol = Volume::from_fn([25, 9, 9], Vec3::ONE, |i, _, _| {
            let x = i as f32 / 8.0;
            if i <= 8 {
                0.5 + 0.5 * x
            } else if i <= 16 {
                1.0 - 0.75 * (x - 1.0)
            } else {
                0.25 + 0.1 * (x - 2.0)
            }
        })
        .unwrap();
        let tf = TransferFunction {
            color: vec![[0.0, 1.0, 0.8, 0.6]],
            opacity: vec![[0.0, 0.0], [0.29, 0.0], [0.31, 0.5], [1.0, 0.5]],
            window: None,
        };
        let grid = vol.visit(0.0, 1.0, BuildBlocks { size: 8 });
        let maxg = vol.visit(0.0, 1.0, BuildMaxGradient { size: 8 });
        let empty = grid.empty_flags(&tf);
        (grid, maxg, Lut::new(&tf, 0.5), empty)
    }

    #[test]
    fn classified_change_follows_what_the_transfer_function_shows() {
        let (grid, maxg, lut, empty) = edge_scene();
        assert_eq!(grid.counts, [3, 1, 1]);
        // The raw field is steeper in the first block than in the third.
        assert!(maxg[0] > maxg[2], "{maxg:?}");
        let k = grid.classified_change(&lut, &maxg, &empty, 0.0);
        // One opacity and colour over the first block's values: no change,
        // whatever the gradient.
        assert_eq!(k[0], 0.0, "{k:?}");
        // Across the edge: bounded by the edge's height (α 0 → 0.5)...
        assert!(k[2] > 0.1 && k[2] <= 0.5 + 1e-4, "{k:?}");
        // ... and by gradient × the edge's slope (25 per unit value).
        assert!(k[2] <= maxg[2] * 25.0 * 1.05, "{k:?} {maxg:?}");
        // An empty block has none.
        let all_empty = vec![true; 3];
        assert_eq!(
            grid.classified_change(&lut, &maxg, &all_empty, 1.0),
            [0.0, 0.0, 0.0]
        );
        // Shaded, the flat block's lit surface counts: its opacity (0.5).
        let lit = grid.classified_change(&lut, &maxg, &empty, 1.0);
        assert!(
            (lit[0] - 0.5 * TURN).abs() < 1e-3 && lit[2] >= k[2],
            "{lit:?}"
        );
    }

    #[test]
    fn a_flat_block_gets_the_coarsest_level_and_an_edge_the_finest() {
        let (grid, maxg, lut, empty) = edge_scene();
        let k = grid.classified_change(&lut, &maxg, &empty, 0.0);
        let p = crate::render::RenderParams::default();
        let levels = p.adaptive.levels(p.step);
        let k_ref = p.adaptive.tolerance / p.step;
        assert_eq!(classified_level(k[0], k_ref, 1.5, levels), (levels.1, 3));
        let (j, cap) = classified_level(k[2], k_ref, 1.5, levels);
        assert_eq!((j, cap), (levels.0, 1), "k {}", k[2]);
        // A block with a tenth of the tolerance's change per base step gets
        // a coarser step and may group (step 2^j, groups of ⌊x/2^j⌋).
        let (j, cap) = classified_level(0.1 * k_ref, k_ref, 1.0, levels);
        assert_eq!((j, cap), (levels.1, 2));
        // However little it changes, a group spans at most two of the
        // coarsest steps (`x` = 100 base steps would allow three).
        assert_eq!(levels.1, 2);
        let (j, cap) = classified_level(0.01 * k_ref, k_ref, 1.0, levels);
        assert_eq!((j, cap), (levels.1, 2));
    }
    use crate::volume::Volume;
    use glam::Vec3;

    /// Two volumes of `dims`: f32 voxels from `v`, and u8 ones of a
    /// scrambled ramp.
    fn f32_and_u8(dims: [usize; 3], v: impl Fn(usize, usize, usize) -> f32) -> [Volume; 2] {
        let bytes: Vec<u8> = (0..dims[0] * dims[1] * dims[2])
            .map(|x| (x * 73 % 251) as u8)
            .collect();
        [
            Volume::from_fn(dims, Vec3::ONE, v).unwrap(),
            Volume::new(
                dims,
                Vec3::ONE,
                Vec3::ZERO,
                crate::volume::VoxelData::U8(bytes.into()),
            )
            .unwrap(),
        ]
    }

    /// [`BuildBlocks`] as it was, one block at a time.
    struct NaiveBlocks(usize);

    impl GridVisitor for NaiveBlocks {
        type Output = Vec<[f32; 2]>;
        fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Vec<[f32; 2]> {
            let (scale, offset) = grid.scale_offset();
            per_block(grid.dims(), self.0, |lo, hi| {
                let (mut mn, mut mx) = (f32::INFINITY, f32::NEG_INFINITY);
                for_each_stored(grid, lo, hi, |v| {
                    mn = mn.min(v);
                    mx = mx.max(v);
                });
                [mn * scale + offset, mx * scale + offset]
            })
        }
    }

    /// The rows-of-blocks build gives every block the range block by block
    /// gave, bit for bit: thin and odd shapes, u8 and f32 (NaNs included),
    /// block sizes that divide the cells and that do not.
    #[test]
    fn the_block_ranges_are_the_block_by_block_ones() {
        let v = |i: usize, j: usize, k: usize| {
            if (i * 7 + j * 3 + k).is_multiple_of(41) {
                f32::NAN
            } else {
                ((i * 37 + j * 11 + k * 5) % 29) as f32 - (i * j) as f32 * 0.37
            }
        };
        for dims in [
            [1, 1, 1],
            [2, 1, 3],
            [3, 4, 1],
            [19, 11, 7],
            [33, 9, 17],
            [17, 17, 17],
        ] {
            for b in [2, 4, 8, 16] {
                for vol in &f32_and_u8(dims, v) {
                    let s = *vol.stats();
                    let fast = vol.visit(s.min, s.max, BuildBlocks { size: b });
                    let slow = vol.visit(s.min, s.max, NaiveBlocks(b));
                    assert_eq!(fast.counts, block_counts(dims, b));
                    assert_eq!(fast.range.len(), slow.len(), "{dims:?} {b}");
                    for (x, y) in fast.range.iter().zip(&slow) {
                        assert_eq!(
                            x.map(f32::to_bits),
                            y.map(f32::to_bits),
                            "{dims:?} {b}: {x:?} {y:?}"
                        );
                    }
                }
            }
        }
    }

    /// [`BuildMaxGradient`] as it was, one block and one voxel at a time.
    struct NaiveMaxGradient(usize);

    impl GridVisitor for NaiveMaxGradient {
        type Output = Vec<f32>;
        fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Vec<f32> {
            let dims = grid.dims();
            let (scale, _) = grid.scale_offset();
            per_block(dims, self.0, |lo, hi| {
                let mut g = 0.0f32;
                for k in lo[2]..=hi[2] {
                    let (k0, k1) = (k.saturating_sub(1), (k + 1).min(dims[2] - 1));
                    for j in lo[1]..=hi[1] {
                        let (j0, j1) = (j.saturating_sub(1), (j + 1).min(dims[1] - 1));
                        for i in lo[0]..=hi[0] {
                            let (i0, i1) = (i.saturating_sub(1), (i + 1).min(dims[0] - 1));
                            let d =
                                |a: T, b: T, n: usize| (a.to_f32() - b.to_f32()) / n.max(1) as f32;
                            let gx = d(grid.row(j, k)[i1], grid.row(j, k)[i0], i1 - i0);
                            let gy = d(grid.row(j1, k)[i], grid.row(j0, k)[i], j1 - j0);
                            let gz = d(grid.row(j, k1)[i], grid.row(j, k0)[i], k1 - k0);
                            g = g.max(gx.abs()).max(gy.abs()).max(gz.abs());
                        }
                    }
                }
                g * scale
            })
        }
    }

    /// The row-at-a-time largest gradient is the voxel-at-a-time one, bit
    /// for bit: thin and odd shapes, u8 and f32, two block sizes.
    #[test]
    fn the_largest_gradient_per_block_is_the_voxel_by_voxel_one() {
        let v = |i: usize, j: usize, k: usize| {
            ((i * 37 + j * 11 + k * 5) % 29) as f32 + (i * j) as f32 * 0.37
        };
        for dims in [[1, 1, 1], [2, 1, 3], [3, 4, 1], [19, 11, 7], [33, 9, 17]] {
            for b in [4, 8] {
                for vol in &f32_and_u8(dims, v) {
                    let s = *vol.stats();
                    let fast = vol.visit(s.min, s.max, BuildMaxGradient { size: b });
                    let slow = vol.visit(s.min, s.max, NaiveMaxGradient(b));
                    assert_eq!(fast.len(), slow.len(), "{dims:?} {b}");
                    for (x, y) in fast.iter().zip(&slow) {
                        assert_eq!(x.to_bits(), y.to_bits(), "{dims:?} {b}: {fast:?} {slow:?}");
                    }
                    assert!(dims[0] * dims[1] * dims[2] == 1 || slow.iter().any(|&g| g > 0.0));
                }
            }
        }
    }

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
