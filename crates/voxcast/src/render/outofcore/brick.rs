//! One brick of the out-of-core render: its data box copied out of the
//! cached chunks ([`BrickBuf`]), the box around its visible cells, and the
//! march of every pixel whose ray crosses it — eight pixels per SIMD packet
//! where the CPU allows, else the scalar loop ([`super::march`]).

use super::cache::{Chunk, ChunkCache};
use super::march::{self, BrickFrame, Px, RowCount};
use super::plan::LevelGeo;
use crate::error::{Error, Result};
use crate::render::composite::Weights;
use crate::render::packet::{self, ZPairs};
use crate::render::ray::Frame;
use crate::render::shading::BlinnPhong;
use crate::transfer::Lut;
use crate::volume::{ChunkRange, Grid, ScalarType, Voxel, VoxelData};
use glam::{Vec3, Vec4};
use rayon::prelude::*;
use std::sync::Arc;

/// A brick's frame before the grid is typed.
pub(super) struct FrameArgs<'a> {
    /// The brick's level, in terms of the base.
    pub(super) geo: &'a LevelGeo<'a>,
    pub(super) data_lo: Vec3,
    pub(super) own_lo: Vec3,
    pub(super) own_hi: Vec3,
    pub(super) lut: &'a Lut,
    /// The premultiplied table of one of the level's steps.
    pub(super) q: &'a [[f32; 4]; crate::transfer::LUT_SIZE],
    /// The base level's step (world units).
    pub(super) st: f32,
    pub(super) unit: f32,
    pub(super) inv_spacing: Vec3,
    pub(super) emission: f32,
    pub(super) absorption: f32,
    pub(super) stop: f32,
    pub(super) shading: Option<BlinnPhong>,
    pub(super) window: [f32; 2],
    /// The SIMD packets' instruction set, `None` for the scalar loop.
    pub(super) packets: Option<crate::render::packet::Level>,
    /// The brick's cells' skip distances and cell counts, for the packets
    /// to skip the empty cells (`None`: empty-space skipping off).
    pub(super) cells: Option<(&'a [i32], [usize; 3])>,
}

/// The brick being marched: its data box copied out of the cached chunks,
/// in the store's type, and the packets' z-paired copy of it (both reused
/// brick after brick).
pub(super) struct BrickBuf {
    data: Data,
    /// Refilled from `data` when the packets march the brick.
    z_pairs: ZPairs,
}

/// A brick's voxels in the store's type.
enum Data {
    U8(Vec<u8>),
    U16(Vec<u16>),
    I16(Vec<i16>),
    F32(Vec<f32>),
}

/// The voxel types a brick holds, with their [`VoxelData`] variant.
trait Stored: Voxel + Default {
    fn of(d: &VoxelData) -> &[Self];
    fn from_f32(v: f32) -> Self;
}

macro_rules! stored {
    ($t:ty, $var:ident) => {
        impl Stored for $t {
            fn of(d: &VoxelData) -> &[$t] {
                match d {
                    VoxelData::$var(v) => v,
                    _ => &[],
                }
            }
            fn from_f32(v: f32) -> $t {
                v as $t
            }
        }
    };
}
stored!(u8, U8);
stored!(u16, U16);
stored!(i16, I16);
stored!(f32, F32);

impl BrickBuf {
    pub(super) fn new(ty: ScalarType) -> BrickBuf {
        let data = match ty {
            ScalarType::U8 => Data::U8(Vec::new()),
            ScalarType::U16 => Data::U16(Vec::new()),
            ScalarType::I16 => Data::I16(Vec::new()),
            ScalarType::F32 => Data::F32(Vec::new()),
        };
        BrickBuf {
            data,
            z_pairs: ZPairs::None,
        }
    }

    /// Copies the data box out of its chunks; returns the value range of
    /// those chunks (`None`: nothing finite).
    pub(super) fn assemble(
        &mut self,
        geo: &LevelGeo<'_>,
        dbox: ([u64; 3], [u64; 3]),
        chunks: &[[u64; 3]],
        ranges: &[ChunkRange],
        cache: &ChunkCache<'_>,
    ) -> Result<Option<(f32, f32)>> {
        match &mut self.data {
            Data::U8(v) => fill_box(v, geo, dbox, chunks, ranges, cache),
            Data::U16(v) => fill_box(v, geo, dbox, chunks, ranges, cache),
            Data::I16(v) => fill_box(v, geo, dbox, chunks, ranges, cache),
            Data::F32(v) => fill_box(v, geo, dbox, chunks, ranges, cache),
        }
    }

    /// The value range of each [`CELL`]³ cell of the buffer (its `dims`).
    pub(super) fn cell_ranges(&self, dims: [usize; 3]) -> CellRanges {
        match &self.data {
            Data::U8(v) => cell_ranges(v, dims),
            Data::U16(v) => cell_ranges(v, dims),
            Data::I16(v) => cell_ranges(v, dims),
            Data::F32(v) => cell_ranges(v, dims),
        }
    }

    /// Marches the pixels of `rect` through the buffer (`dims`); the
    /// packets fetch from the z-paired copy, refilled here.
    pub(super) fn march(
        &mut self,
        a: &FrameArgs<'_>,
        dims: [usize; 3],
        px: &mut [Px],
        w: u32,
        rect: [u32; 4],
    ) -> RowCount {
        let z = &mut self.z_pairs;
        match &self.data {
            Data::U8(v) => march_rows(v, a, dims, px, w, rect, z),
            Data::U16(v) => march_rows(v, a, dims, px, w, rect, z),
            Data::I16(v) => march_rows(v, a, dims, px, w, rect, z),
            Data::F32(v) => march_rows(v, a, dims, px, w, rect, z),
        }
    }
}

fn fill_box<T: Stored>(
    out: &mut Vec<T>,
    geo: &LevelGeo<'_>,
    (lo, hi): ([u64; 3], [u64; 3]),
    chunks: &[[u64; 3]],
    ranges: &[ChunkRange],
    cache: &ChunkCache<'_>,
) -> Result<Option<(f32, f32)>> {
    let d: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a]) as usize);
    // The chunks cover the box, so every voxel is written below: the
    // buffer is only resized, not cleared (a memset per brick).
    out.truncate(d[0] * d[1] * d[2]);
    out.resize(d[0] * d[1] * d[2], T::default());
    let mut range: Option<(f32, f32)> = None;
    let mut widen = |r: (f32, f32)| {
        range = Some(match range {
            Some((a, b)) => (a.min(r.0), b.max(r.1)),
            None => r,
        })
    };
    // What each chunk gives the box (fetched in order, so an error names
    // the first chunk that failed), then the copy, slice by slice in
    // parallel.
    enum Src<T> {
        Fill(T),
        Data(Arc<Chunk>, [u64; 3], [usize; 3]),
    }
    let mut parts = Vec::with_capacity(chunks.len());
    for &k in chunks {
        let (clo, chi) = geo.level.chunk_box(k);
        // The part of the chunk inside the data box.
        let a: [u64; 3] = std::array::from_fn(|i| clo[i].max(lo[i]));
        let b: [u64; 3] = std::array::from_fn(|i| chi[i].min(hi[i]));
        if (0..3).any(|i| a[i] >= b[i]) {
            continue;
        }
        let cd: [usize; 3] = std::array::from_fn(|i| (chi[i] - clo[i]) as usize);
        if let ChunkRange::Fill(v) = ranges[geo.level.chunk_index(k)] {
            if v.is_finite() {
                widen((v, v));
            }
            parts.push((a, b, Src::Fill(T::from_f32(v))));
            continue;
        }
        let chunk = cache.get((geo.lidx, k))?;
        let n = T::of(&chunk.data).len();
        if n != cd[0] * cd[1] * cd[2] {
            return Err(Error::invalid(format!(
                "level {} chunk {:?}: the store returned {} voxels of another type or shape (expected {}×{}×{})",
                geo.lidx, k, chunk.data.len(), cd[0], cd[1], cd[2]
            )));
        }
        if let Some(r) = chunk.range {
            widen(r);
        }
        parts.push((a, b, Src::Data(chunk, clo, cd)));
    }
    out.par_chunks_mut(d[0] * d[1])
        .enumerate()
        .for_each(|(zi, slab)| {
            let z = lo[2] + zi as u64;
            for (a, b, src) in &parts {
                if z < a[2] || z >= b[2] {
                    continue;
                }
                let n = (b[0] - a[0]) as usize;
                for y in a[1]..b[1] {
                    let o = (y - lo[1]) as usize * d[0] + (a[0] - lo[0]) as usize;
                    match src {
                        Src::Fill(v) => slab[o..o + n].fill(*v),
                        Src::Data(chunk, clo, cd) => {
                            let s = ((z - clo[2]) as usize * cd[1] + (y - clo[1]) as usize) * cd[0]
                                + (a[0] - clo[0]) as usize;
                            slab[o..o + n].copy_from_slice(&T::of(&chunk.data)[s..s + n]);
                        }
                    }
                }
            }
        });
    Ok(range)
}

/// Edge of the cells a brick is divided into for skipping, in voxels.
const CELL: usize = 4;

/// Cells along each axis of a brick of `dims` voxels.
pub(super) fn cell_counts(dims: [usize; 3]) -> [usize; 3] {
    dims.map(|v| v.div_ceil(CELL))
}

/// A brick's cells' signed skip distances and the box (voxel coordinates
/// of the buffer) around the cells that may show, from
/// [`CellRanges::flags`].
pub(super) struct BrickFlags {
    pub(super) skip: Vec<i32>,
    /// `None`: no cell may show.
    pub(super) shown: Option<(Vec3, Vec3)>,
}

/// A brick's cells of [`CELL`]³ voxels and the range of the values a
/// sample inside each may interpolate (its own voxels and the next layer on
/// each axis). Independent of the transfer function, so a warm renderer
/// keeps them from frame to frame (see `OutOfCore`).
pub(super) struct CellRanges {
    counts: [usize; 3],
    ranges: Vec<(f32, f32)>,
}

impl CellRanges {
    /// Bytes held.
    pub(super) fn bytes(&self) -> u64 {
        (self.ranges.len() * std::mem::size_of::<(f32, f32)>()) as u64
    }

    /// Each cell's signed skip distance (negative where something in it
    /// may show; see [`crate::render::packet::skip_distances`]) and the box
    /// around the cells that may show.
    pub(super) fn flags(&self, visible: &impl Fn(f32, f32) -> bool) -> BrickFlags {
        let n = self.counts;
        let mut lo = [usize::MAX; 3];
        let mut hi = [0usize; 3];
        let mut shows = vec![false; self.ranges.len()];
        for (i, &(mn, mx)) in self.ranges.iter().enumerate() {
            if mn <= mx && visible(mn, mx) {
                shows[i] = true;
                let c = [i % n[0], (i / n[0]) % n[1], i / (n[0] * n[1])];
                for a in 0..3 {
                    lo[a] = lo[a].min(c[a]);
                    hi[a] = hi[a].max(c[a]);
                }
            }
        }
        if lo[0] == usize::MAX {
            return BrickFlags {
                skip: Vec::new(),
                shown: None,
            };
        }
        let l = Vec3::from(lo.map(|c| (c * CELL) as f32));
        let h = Vec3::from(hi.map(|c| ((c + 1) * CELL) as f32));
        let d = crate::render::packet::skip_distances(|i| !shows[i], n);
        BrickFlags {
            skip: d,
            shown: Some((l, h)),
        }
    }
}

/// The range of `it`'s pairs.
fn span(it: impl Iterator<Item = (f32, f32)>) -> (f32, f32) {
    it.fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), (c, d)| {
        (a.min(c), b.max(d))
    })
}

/// [`CellRanges`] of `data` (`d` voxels), reduced one axis at a time: x in
/// parallel over the slices, then y, then z, so each voxel is read about
/// once.
fn cell_ranges<T: Voxel>(data: &[T], d: [usize; 3]) -> CellRanges {
    let n = cell_counts(d);
    let reach = |c: usize, axis: usize| c * CELL..(c * CELL + CELL + 1).min(d[axis]);
    let mut rows = vec![(0.0f32, 0.0f32); n[0] * d[1] * d[2]];
    rows.par_chunks_mut(n[0] * d[1])
        .enumerate()
        .for_each(|(z, plane)| {
            for y in 0..d[1] {
                let row = &data[(z * d[1] + y) * d[0]..][..d[0]];
                for (cx, o) in plane[y * n[0]..][..n[0]].iter_mut().enumerate() {
                    let r = &row[reach(cx, 0)];
                    let first = r[0].to_f32();
                    let (mut mn, mut mx) = (first, first);
                    for v in &r[1..] {
                        let v = v.to_f32();
                        mn = mn.min(v);
                        mx = mx.max(v);
                    }
                    *o = (mn, mx);
                }
            }
        });
    let mut planes = vec![(0.0f32, 0.0f32); n[0] * n[1] * d[2]];
    for z in 0..d[2] {
        for cy in 0..n[1] {
            for cx in 0..n[0] {
                planes[(z * n[1] + cy) * n[0] + cx] =
                    span(reach(cy, 1).map(|y| rows[(z * d[1] + y) * n[0] + cx]));
            }
        }
    }
    let mut ranges = Vec::with_capacity(n[0] * n[1] * n[2]);
    for cz in 0..n[2] {
        for cy in 0..n[1] {
            for cx in 0..n[0] {
                ranges.push(span(
                    reach(cz, 2).map(|z| planes[(z * n[1] + cy) * n[0] + cx]),
                ));
            }
        }
    }
    CellRanges { counts: n, ranges }
}

fn march_rows<T: Stored>(
    data: &[T],
    a: &FrameArgs<'_>,
    dims: [usize; 3],
    px: &mut [Px],
    w: u32,
    [x0, x1, y0, y1]: [u32; 4],
    z_pairs: &mut ZPairs,
) -> RowCount {
    let f = BrickFrame {
        grid: Grid::new(data, dims, a.window[0], a.window[1]),
        geo: a.geo,
        data_lo: a.data_lo,
        own_lo: a.own_lo,
        own_hi: a.own_hi,
        lut: a.lut,
        q: a.q,
        st: a.st,
        unit: a.unit,
        inv_spacing: a.inv_spacing,
        emission: a.emission,
        absorption: a.absorption,
        stop: a.stop,
        shading: a.shading,
    };
    let w = w as usize;
    let rows = px[y0 as usize * w..y1 as usize * w].par_chunks_mut(w);
    let sum = |a: RowCount, b: RowCount| RowCount {
        samples: a.samples + b.samples,
        shaded: a.shaded + b.shaded,
        terminated: a.terminated + b.terminated,
    };
    let Some(level) = a.packets.filter(|_| packet::fits(&f.grid)) else {
        return rows
            .map(|row| {
                let mut n = RowCount::default();
                for p in &mut row[x0 as usize..x1 as usize] {
                    if let Some(span) = march::span(&f, p) {
                        march::march(&f, p, span, &mut n);
                    }
                }
                n
            })
            .reduce(RowCount::default, sum);
    };
    // Eight pixels per packet: the vector loop marches each ray's samples
    // inside the brick but its last one, from the colour it holds; the
    // scalar loop then takes what is left (the ray's last sample, where it
    // falls in this brick).
    // The level's step: `stride` base steps.
    let st_l = a.st * a.geo.stride as f32;
    z_pairs.refill(data, dims);
    let frame = Frame {
        grid: &f.grid,
        lut: a.lut,
        box_lo: Vec3::ZERO,
        box_hi: Vec3::from(dims.map(|d| (d - 1) as f32)),
        origin_w: Vec3::ZERO,
        inv_spacing: a.inv_spacing,
        step: st_l,
        unit: a.unit,
        skip_empty: a.cells.is_some(),
        block_size: a.cells.map_or(1, |_| CELL),
        block_counts: a.cells.map_or([1; 3], |c| c.1),
        empty: &[],
        occupied: None,
        seed: 0,
    };
    let pk: packet::Packets<'_, _> = packet::Packets {
        f: &frame,
        q: a.q,
        st: st_l,
        weights: Weights {
            emission: a.emission,
            absorption: a.absorption,
        },
        stop: a.stop,
        jitter: None,
        empty: a.cells.map(|c| c.0),
        shading: a.shading,
        z_pairs,
        level,
        imp: None,
        runs: None,
        thr: None,
        strat: None,
        surface: None,
    };
    rows.map(|row| {
        let mut n = RowCount::default();
        for group in row[x0 as usize..x1 as usize].chunks_mut(packet::LANES) {
            let mut lanes = [None; packet::LANES];
            let mut next = [0u32; packet::LANES];
            let mut acc = [Vec4::ZERO; packet::LANES];
            let mut spans = [None; packet::LANES];
            for (i, p) in group.iter().enumerate() {
                spans[i] = march::span(&f, p);
                if let Some(span) = spans[i] {
                    (lanes[i], next[i]) =
                        march::lane(&f, p, span).map_or((None, 0), |(l, n)| (Some(l), n));
                    acc[i] = p.finish();
                }
            }
            if lanes.iter().any(Option::is_some) {
                let mut count = [[0u32; 3]; packet::LANES];
                let mut alive = [false; packet::LANES];
                pk.march_lanes(&lanes, &mut acc, &mut count, &mut alive);
                for (i, p) in group.iter_mut().enumerate() {
                    if lanes[i].is_none() {
                        continue;
                    }
                    p.c = acc[i].truncate();
                    p.a = acc[i].w;
                    p.next = next[i];
                    n.samples += count[i][0] as u64;
                    n.shaded += count[i][1] as u64;
                    if !alive[i] {
                        p.live = false;
                        p.terminated = true;
                        n.terminated += 1;
                    }
                }
            }
            for (p, span) in group.iter_mut().zip(spans) {
                if let Some(span) = span {
                    march::march(&f, p, span, &mut n);
                }
            }
        }
        n
    })
    .reduce(RowCount::default, sum)
}
