//! Value statistics and histograms of a volume.

use super::VoxelData;
use serde::Serialize;

/// Range and counts of a volume's values.
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct ValueStats {
    /// Smallest finite value (0 when there is none).
    pub min: f32,
    /// Largest finite value (0 when there is none).
    pub max: f32,
    /// Mean of the finite values.
    pub mean: f64,
    /// Number of NaN values.
    pub nan: usize,
    /// Number of ±Inf values.
    pub inf: usize,
}

impl ValueStats {
    pub(super) fn compute(data: &VoxelData) -> ValueStats {
        /// Integer voxels: min, max and an exact integer sum (the mean is
        /// the same f64 a float sum would give: every partial sum is an
        /// integer below 2⁵³), in parallel chunks that vectorise.
        fn ints<T: Copy + Into<i64> + Ord + Send + Sync>(v: &[T]) -> ValueStats {
            let per_chunk = |c: &[T]| {
                let lo = c.iter().copied().min().expect("chunks are not empty");
                let hi = c.iter().copied().max().expect("chunks are not empty");
                let sum: i64 = c.iter().map(|&x| x.into()).sum();
                (lo, hi, sum)
            };
            let merge = |a: (T, T, i64), b: (T, T, i64)| (a.0.min(b.0), a.1.max(b.1), a.2 + b.2);
            let Some((lo, hi, sum)) = chunked(v, per_chunk, merge) else {
                return ValueStats {
                    min: 0.0,
                    max: 0.0,
                    mean: 0.0,
                    nan: 0,
                    inf: 0,
                };
            };
            ValueStats {
                min: lo.into() as f32,
                max: hi.into() as f32,
                mean: sum as f64 / v.len() as f64,
                nan: 0,
                inf: 0,
            }
        }
        match data {
            VoxelData::U8(v) => ints(v),
            VoxelData::U16(v) => ints(v),
            VoxelData::I16(v) => ints(v),
            VoxelData::F32(v) => {
                let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f64);
                let (mut nan, mut inf, mut n) = (0, 0, 0usize);
                for &x in v {
                    if x.is_nan() {
                        nan += 1;
                    } else if x.is_infinite() {
                        inf += 1;
                    } else {
                        lo = lo.min(x);
                        hi = hi.max(x);
                        sum += x as f64;
                        n += 1;
                    }
                }
                if n == 0 {
                    (lo, hi) = (0.0, 0.0);
                }
                ValueStats {
                    min: lo,
                    max: hi,
                    mean: if n > 0 { sum / n as f64 } else { 0.0 },
                    nan,
                    inf,
                }
            }
        }
    }

    /// NaN plus Inf count.
    pub fn non_finite(&self) -> usize {
        self.nan + self.inf
    }
}

/// `per_chunk` of each chunk of 2¹⁶ values of `v`, in parallel, the
/// results merged (in any grouping); `None` for no values.
fn chunked<T: Sync, A: Send>(
    v: &[T],
    per_chunk: impl Fn(&[T]) -> A + Sync + Send,
    merge: impl Fn(A, A) -> A + Sync + Send,
) -> Option<A> {
    use rayon::prelude::*;
    v.par_chunks(1 << 16).map(per_chunk).reduce_with(merge)
}

/// Counts of the finite values in equal bins over `[lo, hi]`.
#[derive(Clone, Debug, Serialize)]
pub struct Histogram {
    pub lo: f32,
    pub hi: f32,
    pub counts: Vec<u64>,
}

impl Histogram {
    pub(super) fn compute(data: &VoxelData, lo: f32, hi: f32, bins: usize) -> Histogram {
        let bins = bins.max(1);
        let width = if hi > lo { hi - lo } else { 1.0 };
        let k = bins as f32 / width;
        let bin = |x: f32| {
            x.is_finite()
                .then(|| (((x - lo) * k) as usize).min(bins - 1))
        };
        /// Counts per bin of `v`, in parallel chunks summed at the end.
        fn counted<T: Copy + Sync>(
            v: &[T],
            bins: usize,
            bin: impl Fn(T) -> Option<usize> + Sync + Send,
        ) -> Vec<u64> {
            let per_chunk = |chunk: &[T]| {
                let mut c = vec![0u64; bins];
                for &x in chunk {
                    if let Some(b) = bin(x) {
                        c[b] += 1;
                    }
                }
                c
            };
            let merge = |mut a: Vec<u64>, b: Vec<u64>| {
                a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                a
            };
            chunked(v, per_chunk, merge).unwrap_or_else(|| vec![0u64; bins])
        }
        let counts = match data {
            // Bytes: how many of each value, then each value's count to its
            // bin (the same bin as value by value).
            VoxelData::U8(v) => {
                let per_value = counted(v, 256, |x: u8| Some(x as usize));
                let mut counts = vec![0u64; bins];
                for (x, &c) in per_value.iter().enumerate() {
                    if let Some(b) = bin(x as f32) {
                        counts[b] += c;
                    }
                }
                counts
            }
            VoxelData::U16(v) => counted(v, bins, |x: u16| bin(x as f32)),
            VoxelData::I16(v) => counted(v, bins, |x: i16| bin(x as f32)),
            VoxelData::F32(v) => counted(v, bins, bin),
        };
        Histogram { lo, hi, counts }
    }

    /// Number of values counted.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// Value at the lower edge of bin `b`.
    pub fn bin_value(&self, b: usize) -> f32 {
        self.lo + (self.hi - self.lo) * b as f32 / self.counts.len() as f32
    }

    /// The value below which a fraction `q` (0…1) of the counted values lie
    /// (upper edge of the bin where the cumulative count reaches it).
    pub fn quantile(&self, q: f64) -> f32 {
        let total = self.total();
        if total == 0 {
            return self.lo;
        }
        let target = (q.clamp(0.0, 1.0) * total as f64).ceil() as u64;
        let mut acc = 0;
        for (b, &c) in self.counts.iter().enumerate() {
            acc += c;
            if acc >= target.max(1) {
                return self.bin_value(b + 1);
            }
        }
        self.hi
    }

    /// Index of the most populated bin.
    pub fn mode_bin(&self) -> usize {
        self.counts
            .iter()
            .enumerate()
            .max_by_key(|&(i, &c)| (c, std::cmp::Reverse(i)))
            .map(|(i, _)| i)
            .unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram in parallel chunks (through a per-value count for
    /// bytes) counts what a serial pass value by value counts.
    #[test]
    fn histograms_in_parallel_chunks_equal_a_serial_pass() {
        let serial = |xs: &[f32], lo: f32, hi: f32, bins: usize| {
            let mut c = vec![0u64; bins];
            let k = bins as f32 / if hi > lo { hi - lo } else { 1.0 };
            for &x in xs.iter().filter(|x| x.is_finite()) {
                c[(((x - lo) * k) as usize).min(bins - 1)] += 1;
            }
            c
        };
        let n = 200_003;
        let bytes: Vec<u8> = (0..n).map(|i| (i * 7919 % 251) as u8).collect();
        let words: Vec<i16> = (0..n).map(|i| (i * 7919 % 60_001) as i16).collect();
        let mut floats: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin() * 40.0).collect();
        floats[5] = f32::NAN;
        floats[n - 1] = f32::INFINITY;
        for (bins, lo, hi) in [(256, 0.0, 250.0), (7, 3.0, 200.0), (100, 10.0, 10.0)] {
            let as_f = |v: &[u8]| v.iter().map(|&x| x as f32).collect::<Vec<_>>();
            let h = Histogram::compute(&VoxelData::U8(bytes.clone().into()), lo, hi, bins);
            assert_eq!(h.counts, serial(&as_f(&bytes), lo, hi, bins), "u8 {bins}");
            let wf: Vec<f32> = words.iter().map(|&x| x as f32).collect();
            let (wlo, whi) = (lo * 100.0 - 30_000.0, hi * 100.0);
            let h = Histogram::compute(&VoxelData::I16(words.clone().into()), wlo, whi, bins);
            assert_eq!(h.counts, serial(&wf, wlo, whi, bins), "i16 {bins}");
            let h = Histogram::compute(&VoxelData::F32(floats.clone().into()), -lo, hi / 5.0, bins);
            assert_eq!(h.counts, serial(&floats, -lo, hi / 5.0, bins), "f32 {bins}");
            assert_eq!(h.total(), n as u64 - 2, "NaN and ∞ are not counted");
        }
    }

    #[test]
    fn integer_stats_in_parallel_chunks_equal_a_serial_float_pass() {
        // Several chunks, a last one short, extremes far from the first.
        let n = 3 * (1 << 16) + 12_345;
        let v: Vec<i16> = (0..n)
            .map(|i| ((i as i64 * 7919 % 65_521) - 32_000) as i16)
            .collect();
        let s = ValueStats::compute(&VoxelData::I16(v.clone().into()));
        let lo = v.iter().map(|&x| x as f64).fold(f64::INFINITY, f64::min);
        let hi = v
            .iter()
            .map(|&x| x as f64)
            .fold(f64::NEG_INFINITY, f64::max);
        let sum: f64 = v.iter().map(|&x| x as f64).sum();
        assert_eq!((s.min, s.max), (lo as f32, hi as f32));
        assert_eq!(s.mean, sum / n as f64, "the mean to the last bit");
        let u: Vec<u8> = vec![];
        assert_eq!(ValueStats::compute(&VoxelData::U8(u.into())).max, 0.0);
    }
}
