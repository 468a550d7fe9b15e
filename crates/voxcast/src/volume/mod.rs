//! The volume: a regular grid of scalars with dims, spacing and origin, x
//! varying fastest. Readers and generators produce it; nothing downstream
//! needs to know where it came from.

pub mod chunked;
mod grid;
mod stats;
mod voxels;

pub use chunked::{ChunkRange, ChunkedSource, Level, MemorySource};
pub use grid::{Grid, GridVisitor, Voxel, VoxelKind};
pub use stats::{Histogram, ValueStats};
pub use voxels::Voxels;

use crate::error::{Error, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Scalar types a volume may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScalarType {
    U8,
    U16,
    I16,
    F32,
}

impl ScalarType {
    /// Bytes per voxel.
    pub fn size(self) -> usize {
        match self {
            ScalarType::U8 => 1,
            ScalarType::U16 | ScalarType::I16 => 2,
            ScalarType::F32 => 4,
        }
    }

    /// The name used on the command line and in scene files (`u8`, `u16`, `i16`, `f32`).
    pub fn name(self) -> &'static str {
        match self {
            ScalarType::U8 => "u8",
            ScalarType::U16 => "u16",
            ScalarType::I16 => "i16",
            ScalarType::F32 => "f32",
        }
    }

    /// Parses `u8`, `u16`, `i16`, `f32` (and a few common synonyms).
    pub fn parse(s: &str) -> Option<ScalarType> {
        match s.trim().to_ascii_lowercase().as_str() {
            "u8" | "uint8" | "uchar" | "unsigned char" | "uint8_t" => Some(ScalarType::U8),
            "u16" | "uint16" | "ushort" | "unsigned short" | "uint16_t" => Some(ScalarType::U16),
            "i16" | "int16" | "short" | "signed short" | "int16_t" => Some(ScalarType::I16),
            "f32" | "float" | "float32" => Some(ScalarType::F32),
            _ => None,
        }
    }
}

impl std::fmt::Display for ScalarType {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The voxel values, in their stored type, x fastest, then y, then z.
#[derive(Clone, Debug, PartialEq)]
pub enum VoxelData {
    U8(Voxels<u8>),
    U16(Voxels<u16>),
    I16(Voxels<i16>),
    F32(Voxels<f32>),
}

impl VoxelData {
    /// Number of voxels.
    pub fn len(&self) -> usize {
        match self {
            VoxelData::U8(v) => v.len(),
            VoxelData::U16(v) => v.len(),
            VoxelData::I16(v) => v.len(),
            VoxelData::F32(v) => v.len(),
        }
    }

    /// True when there are no voxels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The stored type.
    pub fn scalar_type(&self) -> ScalarType {
        match self {
            VoxelData::U8(_) => ScalarType::U8,
            VoxelData::U16(_) => ScalarType::U16,
            VoxelData::I16(_) => ScalarType::I16,
            VoxelData::F32(_) => ScalarType::F32,
        }
    }

    /// The same values behind an `Arc` ([`Voxels::into_shared`]): clones
    /// share them instead of copying.
    pub fn into_shared(self) -> VoxelData {
        match self {
            VoxelData::U8(v) => VoxelData::U8(v.into_shared()),
            VoxelData::U16(v) => VoxelData::U16(v.into_shared()),
            VoxelData::I16(v) => VoxelData::I16(v.into_shared()),
            VoxelData::F32(v) => VoxelData::F32(v.into_shared()),
        }
    }

    /// Value of voxel `index` as f32.
    pub fn get(&self, index: usize) -> f32 {
        match self {
            VoxelData::U8(v) => v[index] as f32,
            VoxelData::U16(v) => v[index] as f32,
            VoxelData::I16(v) => v[index] as f32,
            VoxelData::F32(v) => v[index],
        }
    }

    /// Decodes `bytes` (exactly `n × size` of them) of type `ty` with the
    /// given endianness.
    pub fn from_bytes(ty: ScalarType, bytes: &[u8], big_endian: bool) -> VoxelData {
        macro_rules! conv {
            ($t:ty, $n:expr, $var:ident) => {{
                let v: Vec<$t> = bytes
                    .chunks_exact($n)
                    .map(|c| {
                        let a: [u8; $n] = c.try_into().unwrap();
                        if big_endian {
                            <$t>::from_be_bytes(a)
                        } else {
                            <$t>::from_le_bytes(a)
                        }
                    })
                    .collect();
                VoxelData::$var(v.into())
            }};
        }
        match ty {
            ScalarType::U8 => VoxelData::U8(bytes.to_vec().into()),
            ScalarType::U16 => conv!(u16, 2, U16),
            ScalarType::I16 => conv!(i16, 2, I16),
            ScalarType::F32 => conv!(f32, 4, F32),
        }
    }

    /// Applies `v·slope + intercept` and returns the result in the smallest
    /// type that holds it exactly (i16 for CT Hounsfield units, else f32).
    /// Identity scaling returns the data unchanged.
    pub fn rescaled(self, slope: f64, intercept: f64) -> VoxelData {
        fn scale<T: Copy + Into<f64> + Sync>(v: &[T], slope: f64, intercept: f64) -> VoxelData {
            use rayon::prelude::*;
            let f = |x: T| x.into() * slope + intercept;
            let integral = slope.fract() == 0.0 && intercept.fract() == 0.0;
            if integral && !v.is_empty() {
                let (lo, hi) = v.par_iter().map(|&x| (f(x), f(x))).reduce(
                    || (f64::INFINITY, f64::NEG_INFINITY),
                    |a, b| (a.0.min(b.0), a.1.max(b.1)),
                );
                if lo >= i16::MIN as f64 && hi <= i16::MAX as f64 {
                    return VoxelData::I16(
                        v.par_iter()
                            .map(|&x| f(x) as i16)
                            .collect::<Vec<_>>()
                            .into(),
                    );
                }
            }
            VoxelData::F32(
                v.par_iter()
                    .map(|&x| f(x) as f32)
                    .collect::<Vec<_>>()
                    .into(),
            )
        }
        if slope == 1.0 && intercept == 0.0 {
            return self;
        }
        match &self {
            VoxelData::U8(v) => scale(v, slope, intercept),
            VoxelData::U16(v) => scale(v, slope, intercept),
            VoxelData::I16(v) => scale(v, slope, intercept),
            VoxelData::F32(v) => {
                use rayon::prelude::*;
                VoxelData::F32(
                    v.par_iter()
                        .map(|&x| (x as f64 * slope + intercept) as f32)
                        .collect::<Vec<_>>()
                        .into(),
                )
            }
        }
    }
}

/// A regular 3D grid of scalars.
///
/// Voxel `(i, j, k)` sits at world position `origin + (i, j, k) ⊙ spacing`;
/// `i` (x) varies fastest in memory. The volume's box spans voxel centres
/// `0 ..= dims − 1` on each axis.
#[derive(Clone, Debug)]
pub struct Volume {
    dims: [usize; 3],
    spacing: Vec3,
    origin: Vec3,
    data: VoxelData,
    stats: ValueStats,
    /// Physical unit of the values when known (`"HU"` for CT after rescale).
    pub units: Option<String>,
    /// Name of the variable or field shown (e.g. `density`, `QCLOUD`).
    pub name: Option<String>,
    /// For multi-variable files: every variable the file holds.
    pub variables: Vec<String>,
    /// For sparse formats (OpenVDB): the number of active voxels.
    pub active_voxels: Option<u64>,
    /// For time series: the time of this volume (the file's units).
    pub time: Option<f64>,
    /// The length the transfer function's opacity refers to, when it is
    /// not this volume's smallest spacing: a pyramid level read whole keeps
    /// level 0's voxel, so that a coarse level is as opaque as the full
    /// resolution (as the out-of-core renderer has it). See
    /// [`Volume::opacity_unit`].
    pub opacity_unit: Option<f32>,
    /// The box the camera frames, when it is not this volume's extent: a
    /// pyramid level read whole keeps level 0's, so that the view does not
    /// move with the level (as out of core). See [`Volume::frame_bounds`].
    pub frame: Option<(Vec3, Vec3)>,
}

/// The most voxels a volume may have (2³⁴ ≈ 17 billion): beyond any file a
/// desktop renders, and far below where `usize` arithmetic overflows.
pub const MAX_VOXELS: u64 = 1 << 34;

/// Checks dims for a volume: each ≥ 1, product ≤ [`MAX_VOXELS`]. Returns the
/// voxel count. `what` names the source in the error (a file or field).
pub fn checked_voxel_count(dims: [u64; 3]) -> std::result::Result<usize, String> {
    if dims.contains(&0) {
        return Err(format!(
            "dims {}×{}×{}: every dimension must be at least 1",
            dims[0], dims[1], dims[2]
        ));
    }
    let n = dims[0]
        .checked_mul(dims[1])
        .and_then(|n| n.checked_mul(dims[2]))
        .filter(|&n| n <= MAX_VOXELS)
        .ok_or_else(|| {
            format!(
                "dims {}×{}×{}: more than {} voxels",
                dims[0], dims[1], dims[2], MAX_VOXELS
            )
        })?;
    usize::try_from(n).map_err(|_| "voxel count does not fit in memory addresses".to_string())
}

impl Volume {
    /// Makes a volume. Spacing must be positive and finite; `data` must hold
    /// exactly `dims[0]·dims[1]·dims[2]` voxels.
    pub fn new(dims: [usize; 3], spacing: Vec3, origin: Vec3, data: VoxelData) -> Result<Volume> {
        let n = checked_voxel_count(dims.map(|d| d as u64)).map_err(Error::invalid)?;
        if n != data.len() {
            return Err(Error::invalid(format!(
                "dims {}×{}×{} need {} voxels, the data holds {}",
                dims[0],
                dims[1],
                dims[2],
                n,
                data.len()
            )));
        }
        if !(spacing.is_finite() && spacing.min_element() > 0.0) {
            return Err(Error::invalid(format!(
                "spacing {} {} {}: each must be a positive finite number",
                spacing.x, spacing.y, spacing.z
            )));
        }
        if !origin.is_finite() {
            return Err(Error::invalid("origin must be finite"));
        }
        let stats = ValueStats::compute(&data);
        Ok(Volume {
            dims,
            spacing,
            origin,
            data,
            stats,
            units: None,
            name: None,
            variables: Vec::new(),
            active_voxels: None,
            time: None,
            opacity_unit: None,
            frame: None,
        })
    }

    /// Makes an f32 volume from a function of the voxel index (for built-in
    /// scenes and tests).
    pub fn from_fn(
        dims: [usize; 3],
        spacing: Vec3,
        f: impl Fn(usize, usize, usize) -> f32,
    ) -> Result<Volume> {
        checked_voxel_count(dims.map(|d| d as u64)).map_err(Error::invalid)?;
        let mut v = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    v.push(f(i, j, k));
                }
            }
        }
        Volume::new(dims, spacing, Vec3::ZERO, VoxelData::F32(v.into()))
    }

    /// The same volume with its voxels shared between clones
    /// ([`VoxelData::into_shared`]): cloning it then costs no copy.
    pub fn into_shared(mut self) -> Volume {
        self.data = self.data.into_shared();
        self
    }

    /// Grid size (x, y, z).
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }
    /// The box rays are clipped to, in voxel index coordinates (low and high
    /// corners): from the first to the last voxel centre, except that a
    /// one-voxel axis gets a one-voxel-thick box so it can be seen.
    pub fn sample_box(&self) -> (Vec3, Vec3) {
        let axis = |d: usize| {
            if d > 1 {
                (0.0, (d - 1) as f32)
            } else {
                (-0.5, 0.5)
            }
        };
        let [x, y, z] = self.dims.map(axis);
        (Vec3::new(x.0, y.0, z.0), Vec3::new(x.1, y.1, z.1))
    }
    /// Distance between voxel centres along x, y, z (world units, often mm).
    pub fn spacing(&self) -> Vec3 {
        self.spacing
    }
    /// The length a step's opacity is measured in: the smallest spacing,
    /// or the finer voxel this volume stands for ([`Volume::opacity_unit`]
    /// field, e.g. level 0's for a pyramid level).
    pub fn opacity_unit(&self) -> f32 {
        self.opacity_unit
            .filter(|u| u.is_finite() && *u > 0.0)
            .unwrap_or(self.spacing.min_element())
    }
    /// World position of voxel (0, 0, 0).
    pub fn origin(&self) -> Vec3 {
        self.origin
    }
    /// Overrides the spacing (e.g. from `--spacing`).
    pub fn set_spacing(&mut self, spacing: Vec3) -> Result<()> {
        if !(spacing.is_finite() && spacing.min_element() > 0.0) {
            return Err(Error::invalid(format!(
                "spacing {} {} {}: each must be a positive finite number",
                spacing.x, spacing.y, spacing.z
            )));
        }
        self.spacing = spacing;
        Ok(())
    }
    /// Overrides the origin.
    pub fn set_origin(&mut self, origin: Vec3) {
        self.origin = origin;
    }
    /// The voxel values.
    pub fn data(&self) -> &VoxelData {
        &self.data
    }
    /// The stored scalar type.
    pub fn scalar_type(&self) -> ScalarType {
        self.data.scalar_type()
    }
    /// Number of voxels.
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// True for a volume with no voxels (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// Range, non-finite count and mean of the values (computed once).
    pub fn stats(&self) -> &ValueStats {
        &self.stats
    }
    /// Linear index of voxel (i, j, k).
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }
    /// Value of voxel (i, j, k) in data units.
    pub fn value(&self, i: usize, j: usize, k: usize) -> f32 {
        self.data.get(self.index(i, j, k))
    }
    /// The box the camera is fitted to: the [`Volume::frame`] field, or
    /// [`Volume::world_bounds`].
    pub fn frame_bounds(&self) -> (Vec3, Vec3) {
        self.frame.unwrap_or_else(|| self.world_bounds())
    }
    /// World-space extent of the box through the voxel centres:
    /// `(origin, origin + (dims − 1) ⊙ spacing)`.
    pub fn world_bounds(&self) -> (Vec3, Vec3) {
        let ext = Vec3::new(
            (self.dims[0].max(1) - 1) as f32,
            (self.dims[1].max(1) - 1) as f32,
            (self.dims[2].max(1) - 1) as f32,
        ) * self.spacing;
        (self.origin, self.origin + ext)
    }
    /// A histogram of the finite values over `bins` equal bins of the range.
    pub fn histogram(&self, bins: usize) -> Histogram {
        Histogram::compute(&self.data, self.stats.min, self.stats.max, bins)
    }

    /// Calls `visitor` with a typed, normalised view of the grid: data value
    /// `lo` maps to 0 and `hi` to 1. Non-finite values map below 0 (empty).
    /// This is where the renderer's loop is monomorphised per scalar type.
    pub fn visit<V: GridVisitor>(&self, lo: f32, hi: f32, visitor: V) -> V::Output {
        grid::visit(self, lo, hi, visitor)
    }
}
