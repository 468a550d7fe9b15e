//! The packets' empty-space map: per block, how far the empty space
//! around it reaches, so a lane in an empty block jumps over the whole
//! empty cube around it in one step instead of one block per step.
//!
//! The value of an empty block is its chessboard (L∞) distance, in
//! blocks, to the nearest block that is not empty: `D > 0` where every
//! block within `D − 1` of it, on every axis, is empty. A lane at block `b` may therefore go on to the far face of the
//! cube of blocks `b − (D − 1) … b + (D − 1)` without passing a sample
//! that could show: the empty-space distance maps of Cohen & Sheffer
//! ("Proximity clouds", 1994), as GPU ray casters use them (Deakin &
//! Knackstedt 2020), here in the block grid's units.
//!
//! The same holds the other way round for the blocks that are not empty
//! ([`skip_distances`]): `−D` where every block within `D − 1` of it can
//! show, so a lane there samples on to the far face of that cube without
//! asking the map again — on a dense volume the lanes test the map about
//! once per cube instead of at every sample.

/// The distance of each empty block (`empty(i)` true) of a grid of
/// `counts` blocks (x fastest) to the nearest block that is not empty,
/// and minus the distance of each block that is not empty to the nearest
/// empty one, both capped at [`FAR`]. Two raster passes over the 26
/// neighbours for each (the chamfer transform, exact for the chessboard
/// distance).
pub(in crate::render) fn skip_distances(
    empty: impl Fn(usize) -> bool,
    counts: [usize; 3],
) -> Vec<i32> {
    let n = counts.iter().product::<usize>();
    let mut d: Vec<i32> = (0..n).map(|i| -(empty(i) as i32)).collect();
    let mut full: Vec<i32> = d.iter().map(|&v| (v == 0) as i32).collect();
    distances_in_place(&mut d, counts);
    distances_in_place(&mut full, counts);
    for (d, f) in d.iter_mut().zip(full) {
        if *d == 0 {
            *d = -f;
        }
    }
    d
}

/// The empty blocks' distances of [`skip_distances`] in place: `d` holds
/// 0 for a block that is not empty (which keeps it) and anything else for
/// an empty one, and gets the distances.
///
/// The passes run on a copy with a border of one block at [`FAR`] all
/// round, so that every block has its 26 neighbours at fixed offsets and
/// the loop tests no bounds (the border lowers no distance): 4³ blocks of
/// a 256³ volume, 262 144 of them, took 34 ms of CPU with the tests and
/// take 7 ms without (docs/engine.md).
fn distances_in_place(d: &mut [i32], [nx, ny, nz]: [usize; 3]) {
    let [px, py, pz] = [nx + 2, ny + 2, nz + 2];
    let row = move |y: usize, z: usize| 1 + px * (y + 1 + py * (z + 1));
    let mut p = vec![FAR; px * py * pz];
    for z in 0..nz {
        for y in 0..ny {
            let (src, at) = (&d[nx * (y + ny * z)..][..nx], row(y, z));
            for (o, &v) in p[at..at + nx].iter_mut().zip(src) {
                *o = if v != 0 { FAR } else { 0 };
            }
        }
    }
    // Forward: the 13 neighbours before a block in raster order; then
    // backward: the 13 after it.
    sweep(&mut p, [nx, ny, nz], true);
    sweep(&mut p, [nx, ny, nz], false);
    for z in 0..nz {
        for y in 0..ny {
            let at = row(y, z);
            d[nx * (y + ny * z)..][..nx].copy_from_slice(&p[at..at + nx]);
        }
    }
}

/// One raster pass of the chamfer transform over the bordered copy `d` of
/// a grid of `[nx, ny, nz]` blocks: each block takes the smallest of its
/// distance and its 13 neighbours' (those before it in the pass's order)
/// plus one.
fn sweep(d: &mut [i32], [nx, ny, nz]: [usize; 3], forward: bool) {
    let [px, py] = [nx + 2, ny + 2];
    let sign = if forward { 1 } else { -1 };
    let offsets = BEFORE.map(|(dx, dy, dz)| sign * (dx + px as isize * (dy + py as isize * dz)));
    let ordered = |i: usize, c: usize| if forward { i } else { c - 1 - i };
    for z in (0..nz).map(|i| ordered(i, nz)) {
        for y in (0..ny).map(|i| ordered(i, ny)) {
            let row = 1 + px * (y + 1 + py * (z + 1));
            for x in (0..nx).map(|i| ordered(i, nx)) {
                let i = row + x;
                if d[i] == 0 {
                    continue;
                }
                let mut m = d[i];
                for o in offsets {
                    m = m.min(d[i.wrapping_add_signed(o)] + 1);
                }
                d[i] = m;
            }
        }
    }
}

/// The distance given where no block in reach is visible (a grid of
/// nothing but empty blocks): farther than any grid is wide.
pub(in crate::render) const FAR: i32 = 1 << 20;

/// The neighbours `(dx, dy, dz)` that come before a block in raster order
/// (x fastest).
const BEFORE: [(isize, isize, isize); 13] = [
    (-1, -1, -1),
    (0, -1, -1),
    (1, -1, -1),
    (-1, 0, -1),
    (0, 0, -1),
    (1, 0, -1),
    (-1, 1, -1),
    (0, 1, -1),
    (1, 1, -1),
    (-1, -1, 0),
    (0, -1, 0),
    (1, -1, 0),
    (-1, 0, 0),
];

#[cfg(test)]
mod tests {
    use super::*;

    /// The distances equal the brute-force chessboard distance to the
    /// nearest block of the other kind (negated for the visible blocks),
    /// on random grids of every density.
    #[test]
    fn distances_are_the_chessboard_distances_to_the_nearest_block_of_the_other_kind() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rand = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (counts, density) in [
            ([7, 5, 6], 2),
            ([9, 9, 9], 40),
            ([16, 3, 11], 200),
            ([1, 1, 12], 8),
            ([4, 4, 4], 1000),
            ([12, 10, 9], 985),
        ] {
            let n = counts.iter().product::<usize>();
            let empty: Vec<bool> = (0..n).map(|_| rand() % 1000 >= density).collect();
            let d = skip_distances(|i| empty[i], counts);
            let pos = |i: usize| {
                [
                    (i % counts[0]) as i32,
                    (i / counts[0] % counts[1]) as i32,
                    (i / (counts[0] * counts[1])) as i32,
                ]
            };
            for (i, &di) in d.iter().enumerate() {
                let p = pos(i);
                // Empty blocks: the distance to the nearest visible one;
                // visible blocks: minus the distance to the nearest empty.
                let want = (0..n)
                    .filter(|&j| empty[j] != empty[i])
                    .map(|j| {
                        let q = pos(j);
                        (0..3).map(|a| (p[a] - q[a]).abs()).max().unwrap()
                    })
                    .min()
                    .unwrap_or(FAR);
                let want = if empty[i] { want } else { -want };
                assert_eq!(di, want, "block {p:?} of {counts:?}");
            }
        }
    }
}
