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
            use rayon::prelude::*;
            let Some((lo, hi, sum)) = v
                .par_chunks(1 << 16)
                .map(|c| {
                    let lo = c.iter().copied().min().expect("chunks are not empty");
                    let hi = c.iter().copied().max().expect("chunks are not empty");
                    let sum: i64 = c.iter().map(|&x| x.into()).sum();
                    (lo, hi, sum)
                })
                .reduce_with(|a, b| (a.0.min(b.0), a.1.max(b.1), a.2 + b.2))
            else {
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
        let mut counts = vec![0u64; bins];
        let width = if hi > lo { hi - lo } else { 1.0 };
        let k = bins as f32 / width;
        let mut add = |x: f32| {
            if x.is_finite() {
                let b = (((x - lo) * k) as usize).min(bins - 1);
                counts[b] += 1;
            }
        };
        match data {
            VoxelData::U8(v) => v.iter().for_each(|&x| add(x as f32)),
            VoxelData::U16(v) => v.iter().for_each(|&x| add(x as f32)),
            VoxelData::I16(v) => v.iter().for_each(|&x| add(x as f32)),
            VoxelData::F32(v) => v.iter().for_each(|&x| add(x)),
        }
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
