//! The chunk cache of the out-of-core renderer: decoded chunks under a byte
//! budget, least recently used evicted first, shared between the render and
//! the prefetcher. A chunk being read is marked so that a second asker
//! waits for it instead of reading it twice.

use crate::error::{Error, Result};
use crate::volume::{ChunkedSource, VoxelData};
use std::collections::HashMap;
use std::sync::{Arc, Condvar, Mutex};

/// A chunk: level and index (x, y, z).
pub(super) type Key = (usize, [u64; 3]);

/// A decoded chunk and the range of its values (NaN left out; `None` when
/// it holds no finite value).
pub(super) struct Chunk {
    pub data: VoxelData,
    pub range: Option<(f32, f32)>,
}

enum Slot {
    Loading,
    Ready { chunk: Arc<Chunk>, used: u64 },
}

struct Inner {
    slots: HashMap<Key, Slot>,
    bytes: u64,
    peak: u64,
    clock: u64,
    hits: u64,
    misses: u64,
    decoded: u64,
}

/// What the cache did over a render.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CacheStats {
    /// Chunk requests answered from memory.
    pub hits: u64,
    /// Chunk requests that read from the store.
    pub misses: u64,
    /// Bytes of decoded chunks read.
    pub decoded_bytes: u64,
    /// The most bytes the cache held at once.
    pub peak_bytes: u64,
}

impl CacheStats {
    /// The counts since `before` (the peak stays the cache's peak).
    pub fn since(&self, before: &CacheStats) -> CacheStats {
        CacheStats {
            hits: self.hits - before.hits,
            misses: self.misses - before.misses,
            decoded_bytes: self.decoded_bytes - before.decoded_bytes,
            peak_bytes: self.peak_bytes,
        }
    }
}

/// Decoded chunks under a byte budget.
pub(super) struct ChunkCache<'s> {
    source: &'s dyn ChunkedSource,
    budget: u64,
    inner: Mutex<Inner>,
    ready: Condvar,
}

fn bytes_of(d: &VoxelData) -> u64 {
    (d.len() * d.scalar_type().size()) as u64
}

fn range_of(d: &VoxelData) -> Option<(f32, f32)> {
    macro_rules! int {
        ($v:expr) => {{
            let lo = $v.iter().copied().min()?;
            let hi = $v.iter().copied().max()?;
            Some((lo as f32, hi as f32))
        }};
    }
    match d {
        VoxelData::U8(v) => int!(v),
        VoxelData::U16(v) => int!(v),
        VoxelData::I16(v) => int!(v),
        VoxelData::F32(v) => {
            let (lo, hi) = v
                .iter()
                .filter(|x| x.is_finite())
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            (lo <= hi).then_some((lo, hi))
        }
    }
}

impl<'s> ChunkCache<'s> {
    pub fn new(source: &'s dyn ChunkedSource, budget: u64) -> Self {
        ChunkCache {
            source,
            budget,
            inner: Mutex::new(Inner {
                slots: HashMap::new(),
                bytes: 0,
                peak: 0,
                clock: 0,
                hits: 0,
                misses: 0,
                decoded: 0,
            }),
            ready: Condvar::new(),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Whether chunk `k` is in memory (or on its way).
    pub fn has(&self, k: Key) -> bool {
        self.lock().slots.contains_key(&k)
    }

    /// Chunk `k` if it is in memory (marked as just used), without
    /// reading.
    pub fn peek(&self, k: Key) -> Option<Arc<Chunk>> {
        let mut g = self.lock();
        g.clock += 1;
        let now = g.clock;
        match g.slots.get_mut(&k) {
            Some(Slot::Ready { chunk, used }) => {
                *used = now;
                Some(chunk.clone())
            }
            _ => None,
        }
    }

    /// The bytes of decoded chunks it keeps.
    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// Chunk `k`, from memory or read from the source.
    pub fn get(&self, k: Key) -> Result<Arc<Chunk>> {
        let mut g = self.lock();
        loop {
            g.clock += 1;
            let now = g.clock;
            match g.slots.get_mut(&k) {
                Some(Slot::Ready { chunk, used }) => {
                    *used = now;
                    let c = chunk.clone();
                    g.hits += 1;
                    return Ok(c);
                }
                Some(Slot::Loading) => {
                    g = self.ready.wait(g).unwrap_or_else(|e| e.into_inner());
                }
                None => break,
            }
        }
        g.slots.insert(k, Slot::Loading);
        g.misses += 1;
        drop(g);
        let read = self.source.read_chunk(k.0, k.1);
        let mut g = self.lock();
        let out = match read {
            Ok(data) => {
                let n = bytes_of(&data);
                let range = range_of(&data);
                let chunk = Arc::new(Chunk { data, range });
                g.decoded += n;
                g.bytes += n;
                g.clock += 1;
                let used = g.clock;
                g.slots.insert(
                    k,
                    Slot::Ready {
                        chunk: chunk.clone(),
                        used,
                    },
                );
                Self::evict(&mut g, self.budget);
                g.peak = g.peak.max(g.bytes);
                Ok(chunk)
            }
            Err(e) => {
                g.slots.remove(&k);
                Err(e)
            }
        };
        drop(g);
        self.ready.notify_all();
        out
    }

    /// Drops least recently used chunks nobody holds until the cache is
    /// within `budget` (or nothing more can go).
    fn evict(g: &mut Inner, budget: u64) {
        while g.bytes > budget {
            let victim = g
                .slots
                .iter()
                .filter_map(|(k, s)| match s {
                    Slot::Ready { chunk, used } if Arc::strong_count(chunk) == 1 => {
                        Some((*used, *k, bytes_of(&chunk.data)))
                    }
                    _ => None,
                })
                .min_by_key(|v| v.0);
            match victim {
                Some((_, k, n)) => {
                    g.slots.remove(&k);
                    g.bytes -= n;
                }
                None => break,
            }
        }
    }

    pub fn stats(&self) -> CacheStats {
        let g = self.lock();
        CacheStats {
            hits: g.hits,
            misses: g.misses,
            decoded_bytes: g.decoded,
            peak_bytes: g.peak,
        }
    }
}

/// A budget below what one brick needs, as an error naming both.
pub(super) fn too_small(budget: u64, need: u64, what: &str) -> Error {
    Error::invalid(format!(
        "--memory-budget {}: below one brick ({what} need {}); raise the budget",
        human_bytes(budget),
        human_bytes(need)
    ))
}

/// `1.5 GiB`, `512 MiB`, `64 KiB`, `100 B`.
pub fn human_bytes(n: u64) -> String {
    const U: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = n as f64;
    let mut i = 0;
    while v >= 1024.0 && i < U.len() - 1 {
        v /= 1024.0;
        i += 1;
    }
    if i == 0 {
        format!("{n} B")
    } else {
        format!("{v:.1} {}", U[i])
    }
}

/// Parses a byte count: `2GiB`, `512MiB`, `1.5G`, `800M`, `4096` (bytes).
/// Decimal suffixes (`GB`) and binary ones (`GiB`, `G`) are both 1024-based
/// here, as `free -h` and `top` show memory.
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let v: f64 = num
        .parse()
        .map_err(|_| format!("{s:?}: expected a size such as 2GiB, 512MiB or 800M"))?;
    let mul: u64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        "t" | "tb" | "tib" => 1 << 40,
        u => return Err(format!("{s:?}: unknown unit {u:?} (use KiB, MiB, GiB)")),
    };
    let b = v * mul as f64;
    if !(b.is_finite() && b >= 1.0) {
        return Err(format!("{s:?}: must be at least 1 byte"));
    }
    Ok(b as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_print() {
        assert_eq!(parse_bytes("2GiB").unwrap(), 2 << 30);
        assert_eq!(parse_bytes("512M").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("1.5g").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("4096").unwrap(), 4096);
        assert!(parse_bytes("lots").is_err());
        assert!(parse_bytes("2 parsecs").is_err());
        assert_eq!(human_bytes(3 << 29), "1.5 GiB");
    }
}
