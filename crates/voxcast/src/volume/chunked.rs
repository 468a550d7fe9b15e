//! Chunked, multi-resolution volumes: what an out-of-core renderer needs
//! from a store (OME-Zarr, or a volume in memory cut into chunks) without
//! holding it whole. A [`ChunkedSource`] has levels (0 the finest, each
//! next one half the size), each cut into chunks of one shape; the
//! renderer asks for one chunk at a time and for what a chunk holds before
//! reading it (a missing chunk is all fill value; a store may know each
//! chunk's value range), so empty chunks are skipped without decoding.
//!
//! Coordinates are voxel indices `(x, y, z)`, x fastest in memory, as in
//! [`Volume`]; a level's voxel `i` sits at world `origin + i ⊙ spacing`.

use super::{ScalarType, Volume, VoxelData};
use crate::error::{Error, Result};
use glam::Vec3;

/// One resolution level of a chunked volume.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// Voxels along x, y, z.
    pub dims: [u64; 3],
    /// Distance between voxel centres (world units).
    pub spacing: Vec3,
    /// World position of voxel (0, 0, 0)'s centre.
    pub origin: Vec3,
    /// Chunk shape (x, y, z) in voxels; the last chunk on an axis may be cut
    /// short by `dims`.
    pub chunk: [u32; 3],
}

impl Level {
    /// Chunks along x, y, z.
    pub fn chunk_counts(&self) -> [u64; 3] {
        std::array::from_fn(|a| self.dims[a].div_ceil(self.chunk[a] as u64))
    }

    /// Chunks in the level, or `None` past 2⁶⁴ (a store's metadata may
    /// claim any shape).
    pub fn chunk_total(&self) -> Option<u64> {
        let n = self.chunk_counts();
        n[0].checked_mul(n[1])?.checked_mul(n[2])
    }

    /// Chunk number `i`, counting x fastest.
    pub fn chunk_at(&self, i: u64) -> [u64; 3] {
        let n = self.chunk_counts();
        [i % n[0], (i / n[0]) % n[1], i / n[0] / n[1]]
    }

    /// The number of chunk `c`, counting x fastest (as [`Level::chunk_at`]).
    pub fn chunk_index(&self, c: [u64; 3]) -> usize {
        let n = self.chunk_counts();
        (c[0] + n[0] * (c[1] + n[1] * c[2])) as usize
    }

    /// The voxel box `[lo, hi)` of chunk `c`, cut by the level's dims.
    pub fn chunk_box(&self, c: [u64; 3]) -> ([u64; 3], [u64; 3]) {
        let lo: [u64; 3] = std::array::from_fn(|a| c[a] * self.chunk[a] as u64);
        let hi = std::array::from_fn(|a| (lo[a] + self.chunk[a] as u64).min(self.dims[a]));
        (lo, hi)
    }

    /// Bytes of one full chunk of type `ty`.
    pub fn chunk_bytes(&self, ty: ScalarType) -> u64 {
        self.chunk.iter().map(|&c| c as u64).product::<u64>() * ty.size() as u64
    }

    /// Bytes of the whole level of type `ty`.
    /// Saturating: a store's metadata may claim any shape.
    pub fn bytes(&self, ty: ScalarType) -> u64 {
        let size = ty.size() as u64;
        self.dims.iter().fold(size, |b, &d| b.saturating_mul(d))
    }
}

/// What a chunk holds, as far as the store knows without decoding it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChunkRange {
    /// The chunk is not stored: every voxel is this fill value.
    Fill(f32),
    /// Stored, with values in `min ..= max` (NaN excluded).
    Range(f32, f32),
    /// Stored; its values are known only by reading it.
    Unknown,
}

/// A chunked multi-resolution volume the out-of-core renderer reads chunk
/// by chunk. Implementations must be safe to call from several threads.
pub trait ChunkedSource: Send + Sync {
    /// What to call the source in messages (a path, `builtin:NAME`).
    fn name(&self) -> String;
    /// The type every chunk is returned in.
    fn scalar_type(&self) -> ScalarType;
    /// The levels, finest first. Never empty.
    fn levels(&self) -> &[Level];
    /// What chunk `c` of `level` holds, without decoding it.
    fn chunk_range(&self, level: usize, c: [u64; 3]) -> ChunkRange;
    /// The voxels of chunk `c` of `level`, exactly the box
    /// [`Level::chunk_box`] gives (x fastest), in [`ChunkedSource::scalar_type`].
    /// A missing chunk is returned filled with the fill value.
    fn read_chunk(&self, level: usize, c: [u64; 3]) -> Result<VoxelData>;
    /// Bytes read from storage so far (compressed), where the source knows.
    fn bytes_read(&self) -> u64 {
        0
    }
    /// The range of values over the whole volume, where known without
    /// reading level 0 (metadata, or the coarsest level).
    fn value_range(&self) -> Option<[f32; 2]> {
        None
    }
}

/// A volume in memory cut into chunks, with a pyramid of 2×2×2 means: for
/// tests of the out-of-core renderer against the in-core one, and for
/// writing stores.
pub struct MemorySource {
    levels: Vec<Level>,
    volumes: Vec<Volume>,
    name: String,
    /// Every chunk's value range per level (x fastest), once
    /// [`MemorySource::with_ranges`] has measured them.
    ranges: Option<Vec<Vec<ChunkRange>>>,
}

impl MemorySource {
    /// `volume` and `extra` coarser levels (each [`downsample2`] of the one
    /// before), cut into chunks of `chunk` voxels.
    pub fn new(volume: Volume, extra: usize, chunk: [u32; 3]) -> Result<MemorySource> {
        if chunk.contains(&0) {
            return Err(Error::invalid("chunk shape: every edge must be at least 1"));
        }
        let name = volume.name.clone().unwrap_or_else(|| "memory".into());
        let mut volumes = vec![volume];
        for _ in 0..extra {
            let next = downsample2(volumes.last().expect("level 0"))?;
            volumes.push(next);
        }
        let levels = volumes
            .iter()
            .map(|v| Level {
                dims: v.dims().map(|d| d as u64),
                spacing: v.spacing(),
                origin: v.origin(),
                chunk,
            })
            .collect();
        Ok(MemorySource {
            levels,
            volumes,
            name,
            ranges: None,
        })
    }

    /// Measures every chunk's value range (one parallel pass over each
    /// level), so that [`ChunkedSource::chunk_range`] answers `Range` —
    /// as a store with a range sidecar does — instead of `Unknown`.
    pub fn with_ranges(mut self) -> MemorySource {
        use rayon::prelude::*;
        let ranges = self
            .levels
            .iter()
            .zip(&self.volumes)
            .map(|(l, vol)| {
                let counts = l.chunk_counts();
                let n = counts.iter().product::<u64>();
                (0..n)
                    .into_par_iter()
                    .map(|i| {
                        let (lo, hi) = l.chunk_box(l.chunk_at(i));
                        let data = crop(vol, lo, hi);
                        let (mut a, mut b) = (f32::INFINITY, f32::NEG_INFINITY);
                        for k in 0..data.len() {
                            let v = data.get(k);
                            if !v.is_nan() {
                                a = a.min(v);
                                b = b.max(v);
                            }
                        }
                        if a <= b {
                            ChunkRange::Range(a, b)
                        } else {
                            ChunkRange::Fill(f32::NAN)
                        }
                    })
                    .collect()
            })
            .collect();
        self.ranges = Some(ranges);
        self
    }

    /// Level `l` as a volume.
    pub fn volume(&self, l: usize) -> &Volume {
        &self.volumes[l]
    }
}

impl ChunkedSource for MemorySource {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn scalar_type(&self) -> ScalarType {
        self.volumes[0].scalar_type()
    }
    fn levels(&self) -> &[Level] {
        &self.levels
    }
    fn chunk_range(&self, level: usize, c: [u64; 3]) -> ChunkRange {
        let Some(r) = self.ranges.as_ref().and_then(|r| r.get(level)) else {
            return ChunkRange::Unknown;
        };
        let l = &self.levels[level];
        let n = l.chunk_counts();
        if (0..3).any(|a| c[a] >= n[a]) {
            return ChunkRange::Unknown;
        }
        r[l.chunk_index(c)]
    }
    fn read_chunk(&self, level: usize, c: [u64; 3]) -> Result<VoxelData> {
        let l = self
            .levels
            .get(level)
            .ok_or_else(|| Error::invalid(format!("{}: no level {level}", self.name)))?;
        if (0..3).any(|a| c[a] >= l.chunk_counts()[a]) {
            return Err(Error::invalid(format!(
                "{}: level {level} has no chunk {:?}",
                self.name, c
            )));
        }
        let (lo, hi) = l.chunk_box(c);
        Ok(crop(&self.volumes[level], lo, hi))
    }
    fn value_range(&self) -> Option<[f32; 2]> {
        let s = self.volumes[0].stats();
        Some([s.min, s.max])
    }
}

/// The voxels of `vol` in the box `[lo, hi)` (which must lie inside it),
/// x fastest.
pub fn crop(vol: &Volume, lo: [u64; 3], hi: [u64; 3]) -> VoxelData {
    let d = vol.dims();
    let [x0, y0, z0] = lo.map(|v| v as usize);
    let [x1, y1, z1] = hi.map(|v| v as usize);
    macro_rules! go {
        ($v:expr, $var:ident) => {{
            let mut out = Vec::with_capacity((x1 - x0) * (y1 - y0) * (z1 - z0));
            for z in z0..z1 {
                for y in y0..y1 {
                    let row = (z * d[1] + y) * d[0];
                    out.extend_from_slice(&$v[row + x0..row + x1]);
                }
            }
            VoxelData::$var(out.into())
        }};
    }
    match vol.data() {
        VoxelData::U8(v) => go!(v, U8),
        VoxelData::U16(v) => go!(v, U16),
        VoxelData::I16(v) => go!(v, I16),
        VoxelData::F32(v) => go!(v, F32),
    }
}

/// The dims of the next coarser level: half of each, rounded up (an axis of
/// one voxel stays one).
pub fn half_dims(dims: [u64; 3]) -> [u64; 3] {
    dims.map(|d| d.div_ceil(2))
}

/// The next coarser level of `vol`: each voxel the mean of the (up to)
/// 2×2×2 voxels it covers, in the same type (integers rounded to nearest).
/// Spacing doubles; the origin moves to the centre of the first 2×2×2
/// block, so the level covers the same world box (OME-Zarr's
/// `coordinateTransformations` say the same: scale ×2, translation
/// `+spacing/2`). An axis of one voxel keeps its spacing and origin.
pub fn downsample2(vol: &Volume) -> Result<Volume> {
    let d = vol.dims();
    let nd = half_dims(d.map(|v| v as u64)).map(|v| v as usize);
    let factor = Vec3::from(std::array::from_fn::<f32, 3, _>(|a| {
        if d[a] > 1 {
            2.0
        } else {
            1.0
        }
    }));
    let spacing = vol.spacing() * factor;
    let origin = vol.origin() + vol.spacing() * (factor - Vec3::ONE) * 0.5;
    let data = downsample2_data(vol.data(), d);
    let mut out = Volume::new(nd, spacing, origin, data)?;
    out.name = vol.name.clone();
    out.units = vol.units.clone();
    Ok(out)
}

/// [`downsample2`] of raw voxels of dims `d` (x fastest).
pub fn downsample2_data(data: &VoxelData, d: [usize; 3]) -> VoxelData {
    use rayon::prelude::*;
    let nd = half_dims(d.map(|v| v as u64)).map(|v| v as usize);
    macro_rules! go {
        ($v:expr, $var:ident, $t:ty, $round:path) => {{
            let v: &[$t] = $v;
            let mut out: Vec<$t> = vec![Default::default(); nd[0] * nd[1] * nd[2]];
            out.par_chunks_mut(nd[0] * nd[1])
                .enumerate()
                .for_each(|(k, slab)| {
                    let zs = [2 * k, (2 * k + 1).min(d[2] - 1)];
                    for j in 0..nd[1] {
                        let ys = [2 * j, (2 * j + 1).min(d[1] - 1)];
                        for i in 0..nd[0] {
                            let xs = [2 * i, (2 * i + 1).min(d[0] - 1)];
                            let mut sum = 0f64;
                            let mut n = 0u32;
                            for (zi, &z) in zs.iter().enumerate() {
                                if zi == 1 && z == zs[0] {
                                    continue;
                                }
                                for (yi, &y) in ys.iter().enumerate() {
                                    if yi == 1 && y == ys[0] {
                                        continue;
                                    }
                                    for (xi, &x) in xs.iter().enumerate() {
                                        if xi == 1 && x == xs[0] {
                                            continue;
                                        }
                                        sum += v[x + d[0] * (y + d[1] * z)] as f64;
                                        n += 1;
                                    }
                                }
                            }
                            slab[i + nd[0] * j] = $round(sum / n as f64);
                        }
                    }
                });
            VoxelData::$var(out.into())
        }};
    }
    match data {
        VoxelData::U8(v) => go!(v, U8, u8, mean::u8),
        VoxelData::U16(v) => go!(v, U16, u16, mean::u16),
        VoxelData::I16(v) => go!(v, I16, i16, mean::i16),
        VoxelData::F32(v) => go!(v, F32, f32, mean::f32),
    }
}

/// A mean back in the stored type (integers rounded to nearest).
mod mean {
    pub fn u8(m: f64) -> u8 {
        m.round() as u8
    }
    pub fn u16(m: f64) -> u16 {
        m.round() as u16
    }
    pub fn i16(m: f64) -> i16 {
        m.round() as i16
    }
    pub fn f32(m: f64) -> f32 {
        m as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsampling_averages_2x2x2_and_keeps_the_world_box() {
        let v = Volume::from_fn([5, 4, 1], Vec3::new(1.0, 2.0, 3.0), |i, j, _| {
            (i + 10 * j) as f32
        })
        .unwrap();
        let h = downsample2(&v).unwrap();
        assert_eq!(h.dims(), [3, 2, 1]);
        // (0,0): mean of x 0..2, y 0..2 = (0+1+10+11)/4.
        assert_eq!(h.value(0, 0, 0), 5.5);
        // The odd last column averages x = 4 only.
        assert_eq!(h.value(2, 1, 0), (24.0 + 34.0) / 2.0);
        assert_eq!(h.spacing(), Vec3::new(2.0, 4.0, 3.0));
        assert_eq!(h.origin(), Vec3::new(0.5, 1.0, 0.0));
    }

    #[test]
    fn memory_chunks_cover_the_volume_exactly() {
        let v =
            Volume::from_fn([7, 5, 3], Vec3::ONE, |i, j, k| (i + 7 * (j + 5 * k)) as f32).unwrap();
        let s = MemorySource::new(v.clone(), 1, [4, 4, 2]).unwrap();
        let l = &s.levels()[0];
        assert_eq!(l.chunk_counts(), [2, 2, 2]);
        let c = s.read_chunk(0, [1, 1, 1]).unwrap();
        // x 4..7, y 4..5, z 2..3: 3 voxels, first is (4,4,2).
        assert_eq!(c.len(), 3);
        assert_eq!(c.get(0), v.value(4, 4, 2));
        assert!(s.read_chunk(0, [2, 0, 0]).is_err());
        assert_eq!(s.levels()[1].dims, [4, 3, 2]);
    }
}
