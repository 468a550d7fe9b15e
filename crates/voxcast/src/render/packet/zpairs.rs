//! The z-paired copy of a volume the packets fetch from ([`ZPairs`]): per
//! voxel, it and its +z neighbour side by side, so a trilinear fetch reads
//! two rows instead of four; on 2 MiB pages where Linux allows.

use crate::volume::{Voxel, VoxelData, VoxelKind};

/// The z-paired copy of a volume the packets fetch from, by voxel type.
/// Twice the volume's bytes, on 2 MiB pages where Linux allows; built once per
/// renderer, or refilled per brick out of core ([`ZPairs::refill`]).
pub(in crate::render) enum ZPairs {
    /// Per voxel `v(x, y, z)` and `v(x, y, z + 1)` in one `u16` (low byte
    /// first; the last slice pairs with itself), so one 32-bit gather at
    /// voxel `(x, y, z)` reads the four corners `(x, z)`, `(x, z + 1)`,
    /// `(x + 1, z)`, `(x + 1, z + 1)` of a trilinear fetch — two gathers
    /// per fetch instead of four.
    U8(Vec<u16>),
    /// Per voxel `v(x, y, z)` and `v(x, y, z + 1)` side by side (the last
    /// slice pairs with itself), so a row's four corners lie in 16
    /// contiguous bytes: a trilinear fetch reads two rows, two cache lines,
    /// where the grid itself spreads its eight corners over four (two
    /// slices, two rows each), and one 16-byte load a row (or two 64-bit
    /// gathers) instead of eight 32-bit gathers. [`super::fits`] keeps the
    /// volumes the packets march below 1 GiB, so the copy stays below
    /// 2 GiB.
    F32(Vec<[f32; 2]>),
    /// u16 and i16: per voxel the bits of `v(x, y, z)` (low half) and
    /// `v(x, y, z + 1)` (high half) in one `u32` (the last slice pairs
    /// with itself), so a row's four corners are 8 contiguous bytes: a
    /// trilinear fetch reads two rows, one 64-bit load each, where the
    /// grid takes four 32-bit ones over four cache lines.
    H16(Vec<u32>),
    None,
}

/// Per voxel of `v` (`dims`, x fastest), `pack` of `v(x, y, z)` and
/// `v(x, y, z + 1)` (the last slice paired with itself), into `out`:
/// its allocation is reused where it is large enough, else a fresh one
/// gets the huge-page hint before any page is touched.
fn paired_into<T: Copy, P>(out: &mut Vec<P>, v: &[T], dims: [usize; 3], pack: impl Fn(T, T) -> P) {
    let slice = dims[0] * dims[1];
    let last = (slice * dims[2].saturating_sub(1)).min(v.len());
    out.clear();
    if out.capacity() < v.len() {
        *out = Vec::with_capacity(v.len());
        huge_pages(out);
    }
    // Two zips of slices, no index tests: the compiler vectorises them.
    let (head, tail) = v.split_at(last);
    out.extend(
        head.iter()
            .zip(&v[slice.min(v.len())..])
            .map(|(&a, &b)| pack(a, b)),
    );
    out.extend(tail.iter().map(|&a| pack(a, a)));
}

impl ZPairs {
    /// The copy for `data` of `dims`.
    pub(in crate::render) fn of(data: &VoxelData, dims: [usize; 3]) -> ZPairs {
        let mut z = ZPairs::None;
        match data {
            VoxelData::U8(v) => z.refill(v, dims),
            VoxelData::U16(v) => z.refill(v, dims),
            VoxelData::I16(v) => z.refill(v, dims),
            VoxelData::F32(v) => z.refill(v, dims),
        }
        z
    }

    /// Makes this the copy for `data` of `dims`, reusing its allocation
    /// where it holds the same type (out of core, one copy refilled brick
    /// after brick). The one place that says which voxel types have a copy.
    pub(in crate::render) fn refill<T: Voxel>(&mut self, data: &[T], dims: [usize; 3]) {
        let old = std::mem::replace(self, ZPairs::None);
        match T::KIND {
            VoxelKind::U8 => {
                let mut out = match old {
                    ZPairs::U8(v) => v,
                    _ => Vec::new(),
                };
                let v = same::<T, u8>(data);
                paired_into(&mut out, v, dims, |a, b| a as u16 | (b as u16) << 8);
                *self = ZPairs::U8(out);
            }
            VoxelKind::F32 => {
                let mut out = match old {
                    ZPairs::F32(v) => v,
                    _ => Vec::new(),
                };
                paired_into(&mut out, same::<T, f32>(data), dims, |a, b| [a, b]);
                *self = ZPairs::F32(out);
            }
            VoxelKind::U16 | VoxelKind::I16 => {
                let mut out = match old {
                    ZPairs::H16(v) => v,
                    _ => Vec::new(),
                };
                if T::KIND == VoxelKind::U16 {
                    let v = same::<T, u16>(data);
                    paired_into(&mut out, v, dims, |a, b| a as u32 | (b as u32) << 16);
                } else {
                    let v = same::<T, i16>(data);
                    let bits = |a: i16| a as u16 as u32;
                    paired_into(&mut out, v, dims, |a, b| bits(a) | bits(b) << 16);
                }
                *self = ZPairs::H16(out);
            }
        }
    }

    /// The copy's first byte, for voxels of kind `kind`.
    ///
    /// # Panics
    /// Where the copy is of another kind than `kind` (a renderer's bug:
    /// the lanes would read it as the wrong type).
    pub(super) fn ptr(&self, kind: VoxelKind) -> *const u8 {
        match (self, kind) {
            (ZPairs::U8(v), VoxelKind::U8) => v.as_ptr() as *const u8,
            (ZPairs::F32(v), VoxelKind::F32) => v.as_ptr() as *const u8,
            (ZPairs::H16(v), VoxelKind::U16 | VoxelKind::I16) => v.as_ptr() as *const u8,
            _ => panic!("the packets' z-paired copy is not of the grid's voxel type"),
        }
    }
}

/// `data` as a slice of `U`, which `T::KIND` says `T` is.
///
/// # Panics
/// Where `T` is not `U` (a `Voxel` impl whose `KIND` names another type).
fn same<T: 'static, U: 'static>(data: &[T]) -> &[U] {
    assert_eq!(std::any::TypeId::of::<T>(), std::any::TypeId::of::<U>());
    // SAFETY: T and U are the same type (checked above).
    unsafe { std::slice::from_raw_parts(data.as_ptr() as *const U, data.len()) }
}

/// Asks Linux to back `v`'s (still untouched) capacity with 2 MiB pages:
/// the lanes' fetches land on scattered slices, and with 4 KiB pages a
/// volume of tens of MiB misses the TLB on most of them. A hint only (it
/// does nothing where transparent huge pages are off).
fn huge_pages<T>(v: &mut Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        const HUGE: usize = 2 << 20;
        let start = v.as_mut_ptr() as usize;
        let end = start + v.capacity() * std::mem::size_of::<T>();
        let lo = start.next_multiple_of(HUGE);
        let hi = end / HUGE * HUGE;
        if hi > lo {
            // SAFETY: [lo, hi) lies inside `v`'s allocation; MADV_HUGEPAGE
            // changes how pages are backed, never their contents.
            unsafe { libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE) };
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every voxel is paired with its +z neighbour, the last slice with
    /// itself, for u8, f32, i16 and u16, refilling one allocation with smaller and
    /// larger volumes.
    #[test]
    fn each_voxel_sits_beside_its_next_slice() {
        let mut z = ZPairs::None;
        for dims in [[3, 2, 4], [1, 1, 1], [5, 3, 1], [4, 4, 7]] {
            let n = dims.iter().product::<usize>();
            let slice = dims[0] * dims[1];
            let bytes: Vec<u8> = (0..n).map(|i| (i * 37 % 251) as u8).collect();
            let next = |i: usize| if i + slice < n { i + slice } else { i };
            z.refill(&bytes, dims);
            let ZPairs::U8(v) = &z else {
                panic!("no u8 copy")
            };
            let want: Vec<u16> = (0..n)
                .map(|i| bytes[i] as u16 | (bytes[next(i)] as u16) << 8)
                .collect();
            assert_eq!(v, &want, "u8, dims {dims:?}");
            let floats: Vec<f32> = bytes.iter().map(|&b| b as f32 * 0.5 - 3.0).collect();
            let mut f = ZPairs::None;
            f.refill(&floats, dims);
            let ZPairs::F32(v) = &f else {
                panic!("no f32 copy")
            };
            let want: Vec<[f32; 2]> = (0..n).map(|i| [floats[i], floats[next(i)]]).collect();
            assert_eq!(v, &want, "f32, dims {dims:?}");
            // The 16-bit copies: a voxel's bits low, its +z neighbour's high.
            let h16 = |z: &ZPairs, bits: &[u16], what: &str| {
                let ZPairs::H16(v) = z else {
                    panic!("no {what} copy")
                };
                let want: Vec<u32> = (0..n)
                    .map(|i| bits[i] as u32 | (bits[next(i)] as u32) << 16)
                    .collect();
                assert_eq!(v, &want, "{what}, dims {dims:?}");
            };
            let shorts: Vec<i16> = bytes.iter().map(|&b| (b as i16 - 100) * 97).collect();
            let mut h = ZPairs::None;
            h.refill(&shorts, dims);
            h16(
                &h,
                &shorts.iter().map(|&s| s as u16).collect::<Vec<_>>(),
                "i16",
            );
            let unsigned: Vec<u16> = bytes.iter().map(|&b| b as u16 * 257).collect();
            h.refill(&unsigned, dims);
            h16(&h, &unsigned, "u16");
        }
    }
}
