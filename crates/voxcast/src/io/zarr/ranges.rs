//! The sidecar `voxcast convert` writes beside each level: every chunk's
//! value range, so the renderer skips transparent chunks unread.

use super::keys::Keys;
use crate::volume::Level;

/// The file beside each level's array metadata that holds its chunks'
/// value ranges (stores written by `voxcast convert`).
pub const RANGES_FILE: &str = "voxcast-chunk-ranges.bin";
/// The sidecar's first 8 bytes.
const RANGES_MAGIC: &[u8; 8] = b"VXCRNG01";

/// Chunk value ranges from the sidecar: per chunk (x fastest) min and max.
pub(super) struct Ranges {
    pub counts: [u64; 3],
    pub minmax: Vec<[f32; 2]>,
}

/// The sidecar of chunk ranges beside an array, if present and of the
/// level's chunk grid.
pub(super) fn read_ranges(keys: &Keys<'_>, array: &str, l: &Level) -> Option<Ranges> {
    let k = if array.is_empty() {
        RANGES_FILE.to_string()
    } else {
        format!("{}/{RANGES_FILE}", array.trim_end_matches('/'))
    };
    let p = keys.root.join(&k);
    let len = keys.size(&k)?;
    let counts = l.chunk_counts();
    // Checked: the chunk counts come from the store's metadata.
    let want = counts
        .iter()
        .try_fold(8u64, |b, &n| b.checked_mul(n))
        .and_then(|b| b.checked_add(32));
    if want != Some(len) {
        eprintln!(
            "warning: {}: {} bytes where the level's {}×{}×{} chunks need {}; ignored (chunks will be read to learn their values)",
            p.display(),
            len,
            counts[0],
            counts[1],
            counts[2],
            want.map_or("over 2⁶⁴".to_string(), |w| w.to_string())
        );
        return None;
    }
    let bytes = keys.bytes(&k).ok()?;
    if &bytes[..8] != RANGES_MAGIC {
        return None;
    }
    let u = |i: usize| u64::from_le_bytes(bytes[8 + 8 * i..16 + 8 * i].try_into().unwrap());
    if [u(0), u(1), u(2)] != counts {
        return None;
    }
    let minmax = bytes[32..]
        .chunks_exact(8)
        .map(|c| {
            [
                f32::from_le_bytes(c[..4].try_into().unwrap()),
                f32::from_le_bytes(c[4..].try_into().unwrap()),
            ]
        })
        .collect();
    Some(Ranges { counts, minmax })
}

/// The sidecar's bytes for chunk ranges (x fastest).
pub(crate) fn ranges_bytes(counts: [u64; 3], minmax: &[[f32; 2]]) -> Vec<u8> {
    let mut out = Vec::with_capacity(32 + minmax.len() * 8);
    out.extend_from_slice(RANGES_MAGIC);
    for c in counts {
        out.extend_from_slice(&c.to_le_bytes());
    }
    for m in minmax {
        out.extend_from_slice(&m[0].to_le_bytes());
        out.extend_from_slice(&m[1].to_le_bytes());
    }
    out
}

impl Ranges {
    /// Chunk `c`'s min and max.
    pub fn get(&self, c: [u64; 3]) -> Option<[f32; 2]> {
        let i = c[0] + self.counts[0] * (c[1] + self.counts[1] * c[2]);
        self.minmax.get(i as usize).copied()
    }
}
