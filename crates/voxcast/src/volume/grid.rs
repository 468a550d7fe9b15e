//! Typed, normalised views of a volume for the renderer's inner loop:
//! trilinear reconstruction and central-difference gradients, monomorphised
//! per scalar type so the per-sample path has no dispatch and no allocation.

use super::{Volume, VoxelData};
use glam::Vec3;

/// A stored voxel type.
pub trait Voxel: Copy + Send + Sync + 'static {
    /// Which of the stored types this is (for the SIMD ray packets, which
    /// fetch each type its own way; a constant, so the choice compiles away).
    const KIND: VoxelKind;
    fn to_f32(self) -> f32;
}

/// The stored voxel types.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VoxelKind {
    U8,
    U16,
    I16,
    F32,
}
impl Voxel for u8 {
    const KIND: VoxelKind = VoxelKind::U8;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}
impl Voxel for u16 {
    const KIND: VoxelKind = VoxelKind::U16;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}
impl Voxel for i16 {
    const KIND: VoxelKind = VoxelKind::I16;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}
impl Voxel for f32 {
    const KIND: VoxelKind = VoxelKind::F32;
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self
    }
}

/// Something that runs on a typed grid (see [`Volume::visit`]).
pub trait GridVisitor {
    type Output;
    fn visit<T: Voxel>(self, grid: &Grid<'_, T>) -> Self::Output;
}

/// A borrowed grid of `T` with the affine map to normalised values
/// (`(v − lo) / (hi − lo)`). Positions are in voxel coordinates: voxel
/// `(i, j, k)` is at `(i, j, k)`.
#[derive(Clone, Copy, Debug)]
pub struct Grid<'a, T> {
    data: &'a [T],
    dims: [usize; 3],
    /// Largest valid coordinate per axis (`dims − 1`).
    max: Vec3,
    /// Largest lower-corner index per axis (`dims − 2`, or 0 for a single slice).
    last: [usize; 3],
    /// Index offsets to the +1 neighbour per axis (0 on a one-voxel axis).
    step: [usize; 3],
    scale: f32,
    offset: f32,
}

impl<'a, T: Voxel> Grid<'a, T> {
    /// A view of `data` (x fastest) mapping `lo → 0`, `hi → 1`.
    ///
    /// # Panics
    /// If `data.len()` differs from the product of `dims` (a programming error:
    /// [`Volume`] guarantees it).
    pub fn new(data: &'a [T], dims: [usize; 3], lo: f32, hi: f32) -> Self {
        assert_eq!(data.len(), dims[0] * dims[1] * dims[2]);
        assert!(dims.iter().all(|d| (1..(1 << 31)).contains(d)));
        let width = if hi > lo { hi - lo } else { 1.0 };
        let sx = 1;
        let sy = dims[0];
        let sz = dims[0] * dims[1];
        Grid {
            data,
            dims,
            max: Vec3::new(
                (dims[0] - 1) as f32,
                (dims[1] - 1) as f32,
                (dims[2] - 1) as f32,
            ),
            last: dims.map(|d| d.saturating_sub(2)),
            step: [
                if dims[0] > 1 { sx } else { 0 },
                if dims[1] > 1 { sy } else { 0 },
                if dims[2] > 1 { sz } else { 0 },
            ],
            scale: 1.0 / width,
            offset: -lo / width,
        }
    }

    /// Grid size.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// The raw layout the SIMD ray packets fetch from: the voxels, the
    /// index step to the +1 neighbour per axis, the largest lower-corner
    /// index per axis and the largest coordinate (see [`Grid::sample`],
    /// whose arithmetic they repeat lane by lane).
    pub(crate) fn layout(&self) -> (&'a [T], [usize; 3], [usize; 3], Vec3) {
        (self.data, self.step, self.last, self.max)
    }

    /// The stored values of row `(·, j, k)` (x varying).
    #[inline]
    pub fn row(&self, j: usize, k: usize) -> &'a [T] {
        let start = self.dims[0] * (j + self.dims[1] * k);
        &self.data[start..start + self.dims[0]]
    }

    /// The affine map from stored to normalised values: `v·scale + offset`.
    pub fn scale_offset(&self) -> (f32, f32) {
        (self.scale, self.offset)
    }

    /// Normalised value of voxel `(i, j, k)`.
    #[inline(always)]
    pub fn voxel(&self, i: usize, j: usize, k: usize) -> f32 {
        self.data[i + self.dims[0] * (j + self.dims[1] * k)].to_f32() * self.scale + self.offset
    }

    /// Trilinearly reconstructed normalised value at `p` (voxel coordinates);
    /// positions outside the grid are clamped to its boundary.
    #[inline(always)]
    pub fn sample(&self, p: Vec3) -> f32 {
        let (base, f) = self.locate(p);
        // SAFETY: `locate` returns a cell's lower corner.
        unsafe { self.cell(base, f) * self.scale + self.offset }
    }

    /// The cell of `p` clamped into the grid: the index of its lower
    /// corner and the fractions within it.
    #[inline(always)]
    fn locate(&self, p: Vec3) -> (usize, Vec3) {
        // `max` before `min`: f32::max returns the non-NaN operand, so a NaN
        // coordinate becomes 0 and every coordinate ends up in [0, dims − 1].
        let p = p.max(Vec3::ZERO).min(self.max);
        // SAFETY: each coordinate is finite, ≥ 0 and ≤ dims − 1 < 2³¹ (see
        // above), so the unchecked conversion is exact truncation. It saves
        // the saturation logic of `as`, a third of this function's cost.
        let (ix, iy, iz) = unsafe {
            (
                (p.x.to_int_unchecked::<i32>() as usize).min(self.last[0]),
                (p.y.to_int_unchecked::<i32>() as usize).min(self.last[1]),
                (p.z.to_int_unchecked::<i32>() as usize).min(self.last[2]),
            )
        };
        let f = Vec3::new(p.x - ix as f32, p.y - iy as f32, p.z - iz as f32);
        (ix + self.dims[0] * (iy + self.dims[1] * iz), f)
    }

    /// The trilinear value, in stored units, of the cell whose lower corner
    /// is voxel `base`, at fractions `f`.
    ///
    /// # Safety
    /// `base` is a cell's lower corner: its voxel's index is ≤ `last` on
    /// every axis.
    #[inline(always)]
    unsafe fn cell(&self, base: usize, f: Vec3) -> f32 {
        let [dx, dy, dz] = self.step;
        let d = self.data;
        // SAFETY: ix ≤ dims[0]−1 and ix+dx ≤ dims[0]−1 (dx is 0 on a one-voxel
        // axis), likewise for y and z, so every index is < data.len(), which
        // `new` checked equals dims[0]·dims[1]·dims[2].
        let (c000, c100, c010, c110, c001, c101, c011, c111) = unsafe {
            (
                d.get_unchecked(base).to_f32(),
                d.get_unchecked(base + dx).to_f32(),
                d.get_unchecked(base + dy).to_f32(),
                d.get_unchecked(base + dx + dy).to_f32(),
                d.get_unchecked(base + dz).to_f32(),
                d.get_unchecked(base + dx + dz).to_f32(),
                d.get_unchecked(base + dy + dz).to_f32(),
                d.get_unchecked(base + dx + dy + dz).to_f32(),
            )
        };
        // Seven lerps (S0 eqs. 7–9).
        let c00 = c000 + (c100 - c000) * f.x;
        let c10 = c010 + (c110 - c010) * f.x;
        let c01 = c001 + (c101 - c001) * f.x;
        let c11 = c011 + (c111 - c011) * f.x;
        let c0 = c00 + (c10 - c00) * f.y;
        let c1 = c01 + (c11 - c01) * f.y;
        c0 + (c1 - c0) * f.z
    }

    /// Central-difference gradient of the normalised field at `p`, per voxel:
    /// the difference of the samples one voxel on either side on each axis.
    /// Inside (a cell on both sides of `p`'s own, on every axis) those are
    /// the neighbouring cells at `p`'s own fractions, so `p` is located once,
    /// not six times; near a face, six clamped samples.
    #[inline(always)]
    pub fn gradient(&self, p: Vec3) -> Vec3 {
        // ⌊p⌋ ≥ 1 and ⌊p⌋ + 2 ≤ dims − 1, i.e. 1 ≤ p < last (a NaN fails).
        let inside = |x: f32, a: usize| x >= 1.0 && x < self.last[a] as f32;
        if inside(p.x, 0) && inside(p.y, 1) && inside(p.z, 2) {
            let (base, f) = self.locate(p);
            let [dx, dy, dz] = self.step;
            // SAFETY: inside, the cells at base ± step have their lower
            // corners at ⌊p⌋ ± 1 on one axis, in 0..=last.
            let (gx, gy, gz) = unsafe {
                (
                    self.cell(base + dx, f) - self.cell(base - dx, f),
                    self.cell(base + dy, f) - self.cell(base - dy, f),
                    self.cell(base + dz, f) - self.cell(base - dz, f),
                )
            };
            return Vec3::new(gx, gy, gz) * (0.5 * self.scale);
        }
        let gx = self.sample(p + Vec3::X) - self.sample(p - Vec3::X);
        let gy = self.sample(p + Vec3::Y) - self.sample(p - Vec3::Y);
        let gz = self.sample(p + Vec3::Z) - self.sample(p - Vec3::Z);
        Vec3::new(gx, gy, gz) * 0.5
    }
}

pub(super) fn visit<V: GridVisitor>(vol: &Volume, lo: f32, hi: f32, visitor: V) -> V::Output {
    let dims = vol.dims();
    match vol.data() {
        VoxelData::U8(d) => visitor.visit(&Grid::new(d, dims, lo, hi)),
        VoxelData::U16(d) => visitor.visit(&Grid::new(d, dims, lo, hi)),
        VoxelData::I16(d) => visitor.visit(&Grid::new(d, dims, lo, hi)),
        VoxelData::F32(d) => {
            if vol.stats().non_finite() == 0 {
                visitor.visit(&Grid::new(d, dims, lo, hi))
            } else {
                // NaN/Inf are rendered as empty: replace them by a value that
                // normalises to −1, below every transfer function's domain.
                let empty = lo - (if hi > lo { hi - lo } else { 1.0 });
                let clean: Vec<f32> = d
                    .iter()
                    .map(|&v| if v.is_finite() { v } else { empty })
                    .collect();
                visitor.visit(&Grid::new(&clean, dims, lo, hi))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `Grid::gradient` reads the neighbouring cells where the sample is a
    /// cell away from every face: it must equal six clamped samples there,
    /// and stay six samples near the faces and outside.
    #[test]
    fn gradient_is_six_samples_inside_and_near_the_faces() {
        let dims = [9usize, 7, 6];
        let n: usize = dims.iter().product();
        let data: Vec<u16> = (0..n).map(|i| ((i * 7919 + i * i) % 1000) as u16).collect();
        let g = Grid::new(&data, dims, 0.0, 1000.0);
        let mut state = 0x2545_f491u32;
        let mut r = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        let mut inside = 0;
        for _ in 0..5000 {
            // From one voxel outside to one beyond the far face.
            let p = Vec3::new(
                r() * (dims[0] + 1) as f32 - 1.0,
                r() * (dims[1] + 1) as f32 - 1.0,
                r() * (dims[2] + 1) as f32 - 1.0,
            );
            let six = Vec3::new(
                g.sample(p + Vec3::X) - g.sample(p - Vec3::X),
                g.sample(p + Vec3::Y) - g.sample(p - Vec3::Y),
                g.sample(p + Vec3::Z) - g.sample(p - Vec3::Z),
            ) * 0.5;
            let got = g.gradient(p);
            assert!(
                (got - six).abs().max_element() < 1e-5,
                "at {p}: {got} against six samples' {six}"
            );
            let a = p.to_array();
            inside += (0..3).all(|i| a[i] >= 1.0 && a[i] < (dims[i] - 2) as f32) as u32;
        }
        // Both paths ran.
        assert!(inside > 500 && inside < 4500, "{inside} of 5000 inside");
    }
}
