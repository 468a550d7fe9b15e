//! What goes into the volume textures: texels in the smallest format that
//! holds them exactly, and the split into bricks of a volume larger than
//! the device's 3D texture limit ([`Bricking`]).

use voxcast::volume::{Volume, VoxelData};

use crate::GpuError;

/// Texture slots for bricks (bindings 1 and 9…15 of the shader).
pub(crate) const MAX_BRICKS: usize = 8;

/// The texels to upload for `volume`, their format, and the map from texel
/// to normalised value.
pub(crate) fn texels(
    volume: &Volume,
    window: [f32; 2],
) -> (Vec<u8>, wgpu::TextureFormat, f32, f32) {
    let (lo, hi) = (window[0], window[1]);
    let width = if hi > lo { hi - lo } else { 1.0 };
    let (scale, offset) = (1.0 / width, -lo / width);
    let f16_exact = |v: f32| v.abs() <= 2048.0;
    match volume.data() {
        // r8unorm stores v/255.
        VoxelData::U8(d) => (
            d.to_vec(),
            wgpu::TextureFormat::R8Unorm,
            scale * 255.0,
            offset,
        ),
        VoxelData::U16(d) if d.iter().all(|&v| f16_exact(v as f32)) => (
            d.iter()
                .flat_map(|&v| f16_bits(v as f32).to_le_bytes())
                .collect(),
            wgpu::TextureFormat::R16Float,
            scale,
            offset,
        ),
        VoxelData::I16(d) if d.iter().all(|&v| f16_exact(v as f32)) => (
            d.iter()
                .flat_map(|&v| f16_bits(v as f32).to_le_bytes())
                .collect(),
            wgpu::TextureFormat::R16Float,
            scale,
            offset,
        ),
        data => {
            // NaN/Inf render as empty, as on the CPU: a value normalising to −1.
            let empty = lo - width;
            let bytes = (0..data.len())
                .flat_map(|i| {
                    let v = data.get(i);
                    (if v.is_finite() { v } else { empty }).to_le_bytes()
                })
                .collect();
            (bytes, wgpu::TextureFormat::R32Float, scale, offset)
        }
    }
}

/// IEEE half bits of an integer-valued `v` with |v| ≤ 2048 (exact).
pub(crate) fn f16_bits(v: f32) -> u16 {
    if v == 0.0 {
        return 0;
    }
    let sign = if v < 0.0 { 0x8000u16 } else { 0 };
    let a = v.abs();
    let e = a.log2().floor() as i32;
    // Integers up to 2048 are normal halves: exponent e, 10 mantissa bits.
    let m = ((a / 2f32.powi(e) - 1.0) * 1024.0).round() as u16;
    sign | (((e + 15) as u16) << 10) | m
}

/// The environment variable that lowers the 3D texture limit (voxels per
/// side) below the device's, to exercise bricking on volumes that would fit.
pub const TEXTURE_LIMIT_ENV: &str = "VOXCAST_GPU_MAX_TEXTURE_3D";

pub(crate) fn env_texture_limit() -> Option<u32> {
    std::env::var(TEXTURE_LIMIT_ENV).ok()?.trim().parse().ok()
}

/// How a volume larger than the device's 3D texture limit is split.
///
/// Design: each axis whose voxel count exceeds the limit `L` is cut into
/// `n = ⌈(dims − 1)/(L − 1)⌉` equal runs of `C = ⌈(dims − 1)/n⌉` cells; a
/// brick holds the `C + 1` voxels of its cells (the last one fewer), so
/// neighbouring bricks share one plane of voxels. Every brick is its own 3D
/// texture (no side above `L`), bound in one of `MAX_BRICKS` (8) fixed texture
/// slots (bindings 1 and 9…15: no binding-array feature needed). The shader
/// reconstructs a sample from the eight voxels of its cell, and with the
/// shared plane all eight lie in the brick that owns the cell's lower corner
/// (`⌊cell / C⌋` per axis — the page table is this division), so a bricked
/// render reads exactly the values of an unbricked one: the picture is the
/// same, seams included. Eight slots cover volumes up to about twice the
/// limit on every side (8192³ voxels at lavapipe's 4096, 4096³ at the 2048
/// of many GPUs), or eight times it along one axis; larger volumes are
/// refused with an error naming the sizes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bricking {
    /// Bricks per axis.
    pub counts: [usize; 3],
    /// Cells per brick along each axis (the last brick may have fewer).
    pub cells: [usize; 3],
}

impl Bricking {
    /// The split of a volume of `dims` voxels for a limit of `limit` (≥ 2)
    /// voxels per texture side.
    pub fn new(dims: [usize; 3], limit: usize) -> Result<Bricking, GpuError> {
        let mut counts = [1; 3];
        let mut cells = [1; 3];
        for a in 0..3 {
            let n_cells = dims[a].saturating_sub(1).max(1);
            counts[a] = n_cells.div_ceil(limit - 1);
            cells[a] = n_cells.div_ceil(counts[a]);
        }
        let total: usize = counts.iter().product();
        if total > MAX_BRICKS {
            return Err(GpuError::Unsupported(format!(
                "volume of {}×{}×{} voxels: larger than this device's 3D texture limit of {limit} per side (max_texture_dimension_3d{}) even in {MAX_BRICKS} bricks (it would need {}×{}×{}); use --device cpu or downsample the volume",
                dims[0],
                dims[1],
                dims[2],
                if env_texture_limit().is_some() {
                    format!(", or {TEXTURE_LIMIT_ENV}")
                } else {
                    String::new()
                },
                counts[0],
                counts[1],
                counts[2]
            )));
        }
        Ok(Bricking { counts, cells })
    }

    /// Number of bricks.
    pub fn len(&self) -> usize {
        self.counts.iter().product()
    }

    /// Always false: a volume is at least one brick.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Brick coordinates in slot order (x fastest).
    pub(crate) fn all(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        let [nx, ny, nz] = self.counts;
        (0..nz).flat_map(move |k| (0..ny).flat_map(move |j| (0..nx).map(move |i| [i, j, k])))
    }

    /// First voxel and voxel counts of brick `b` of a volume of `dims`.
    pub(crate) fn extent(&self, b: [usize; 3], dims: [usize; 3]) -> ([usize; 3], [usize; 3]) {
        let mut lo = [0; 3];
        let mut size = [0; 3];
        for a in 0..3 {
            lo[a] = b[a] * self.cells[a];
            let hi = (lo[a] + self.cells[a]).min(dims[a] - 1);
            size[a] = hi - lo[a] + 1;
        }
        (lo, size)
    }
}

#[cfg(test)]
mod tests {
    use super::f16_bits;

    #[test]
    fn half_bits_of_integers() {
        assert_eq!(f16_bits(0.0), 0);
        assert_eq!(f16_bits(1.0), 0x3C00);
        assert_eq!(f16_bits(3.0), 0x4200);
        assert_eq!(f16_bits(2047.0), 0x67FF);
        assert_eq!(f16_bits(2048.0), 0x6800);
        assert_eq!(f16_bits(-1024.0), 0xE400);
        assert_eq!(f16_bits(-1.0), 0xBC00);
    }
}
