//! What a warm out-of-core renderer keeps of each brick between frames:
//! its cells' value ranges (independent of the transfer function) and,
//! while the transfer function's visible ranges stay, its cells' skip map
//! and the box around its visible cells. Within a sixteenth of the budget,
//! held beside the chunk cache.

use super::brick::{cell_counts, BrickBuf, BrickFlags, CellRanges};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// A brick: its level and the voxel box it reads.
type BrickKey = (usize, [u64; 3], [u64; 3]);

/// The cell ranges of bricks marched so far, by level and the voxel box
/// the brick reads; their flags under the transfer function of `seen`;
/// and the bytes all these hold.
#[derive(Default)]
pub(super) struct CellStore {
    ranges: HashMap<BrickKey, Arc<CellRanges>>,
    flags: HashMap<BrickKey, Arc<BrickFlags>>,
    /// What decides which cells may show (the window's bits and, per
    /// table entry, the first entry from it on with opacity), for the
    /// `flags` held, and a count of its changes (a frame keeps and reads
    /// flags only while the count is the one it started with).
    seen: Option<([u32; 2], Vec<usize>)>,
    generation: u64,
    bytes: u64,
}

/// Keeps `v` (of `size` bytes) in `map` if `bytes` stays within `cap`.
fn keep<V>(
    bytes: &mut u64,
    map: &mut HashMap<BrickKey, Arc<V>>,
    key: BrickKey,
    v: &Arc<V>,
    size: u64,
    cap: u64,
) {
    if *bytes + size <= cap {
        *bytes += size;
        map.insert(key, v.clone());
    }
}

/// Bytes a brick's flags hold.
fn flag_bytes(f: &BrickFlags) -> u64 {
    (f.skip.len() * std::mem::size_of::<i32>()) as u64
}

impl CellStore {
    /// A frame's start: `window` and `shown` decide which cells may show
    /// (see `CellStore::seen`); flags kept under others are dropped. The
    /// frame's generation, for [`CellStore::brick`].
    pub(super) fn begin(store: &Mutex<CellStore>, window: [f32; 2], shown: &[usize]) -> u64 {
        store.lock().map_or(u64::MAX, |mut store| {
            let seen = (window.map(f32::to_bits), shown.to_vec());
            if store.seen.as_ref() != Some(&seen) {
                let held: u64 = store.flags.values().map(|f| flag_bytes(f)).sum();
                store.bytes -= held;
                store.flags.clear();
                store.seen = Some(seen);
                store.generation += 1;
            }
            store.generation
        })
    }

    /// The cell counts and flags of the brick `(lidx, dbox)` now in `buf`
    /// (`dims` voxels), under `visible`: kept flags, or flags computed
    /// from the brick's cell ranges (kept ones, or computed) and kept
    /// within `cap` bytes (flags only while the store is at the frame's
    /// `generation`). Ranges are computed only where flags must be.
    pub(super) fn brick(
        store: &Mutex<CellStore>,
        (lidx, dbox): (usize, ([u64; 3], [u64; 3])),
        generation: u64,
        cap: u64,
        buf: &BrickBuf,
        dims: [usize; 3],
        visible: &impl Fn(f32, f32) -> bool,
    ) -> ([usize; 3], Arc<BrickFlags>) {
        let key = (lidx, dbox.0, dbox.1);
        let (kept, kept_flags) = store.lock().map_or((None, None), |s| {
            let flags = s.flags.get(&key).filter(|_| s.generation == generation);
            (s.ranges.get(&key).cloned(), flags.cloned())
        });
        let flags = kept_flags.unwrap_or_else(|| {
            let ranges = kept.unwrap_or_else(|| {
                let c = Arc::new(buf.cell_ranges(dims));
                if let Ok(mut s) = store.lock() {
                    let s = &mut *s;
                    keep(&mut s.bytes, &mut s.ranges, key, &c, c.bytes(), cap);
                }
                c
            });
            let f = Arc::new(ranges.flags(visible));
            if let Ok(mut s) = store.lock() {
                let s = &mut *s;
                if s.generation == generation {
                    keep(&mut s.bytes, &mut s.flags, key, &f, flag_bytes(&f), cap);
                }
            }
            f
        });
        (cell_counts(dims), flags)
    }
}
