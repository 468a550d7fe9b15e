//! The random numbers of the Monte-Carlo methods: a small seeded PCG32
//! (O'Neill 2014) and a per-pixel rotated golden-ratio sequence for the
//! progressive marchers. Seeded, so the same scene and seed give the same
//! image on any number of threads (every pixel and pass has its own stream).

/// PCG32 (XSH-RR output, 64-bit LCG state).
#[derive(Clone, Copy, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6_364_136_223_846_793_005;

impl Rng {
    /// A generator for `seed` on stream `stream` (independent sequences).
    pub fn new(seed: u64, stream: u64) -> Rng {
        let mut r = Rng {
            state: 0,
            inc: (splitmix(stream) << 1) | 1,
        };
        r.next_u32();
        r.state = r.state.wrapping_add(splitmix(seed));
        r.next_u32();
        r
    }

    /// The stream of pixel `(x, y)` (each below 2¹⁶), pass `pass`.
    pub fn for_pixel(seed: u64, x: u32, y: u32, pass: u32) -> Rng {
        Rng::new(seed, Rng::pixel_stream(x, y, pass))
    }

    /// The stream [`Rng::for_pixel`] takes for pixel `(x, y)`, pass `pass`.
    #[inline(always)]
    pub fn pixel_stream(x: u32, y: u32, pass: u32) -> u64 {
        x as u64 | (y as u64) << 16 | (pass as u64) << 32
    }

    #[inline(always)]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    #[inline(always)]
    pub fn uniform(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// Uniform in (0, 1] (safe under `ln`).
    #[inline(always)]
    pub fn uniform_open0(&mut self) -> f32 {
        1.0 - self.uniform()
    }
}

/// SplitMix64 finaliser: spreads neighbouring seeds and streams apart.
#[inline]
pub fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Pass `pass` of a low-discrepancy sequence rotated per pixel: the
/// golden-ratio (Weyl) sequence `{r + n·φ⁻¹}` with `r` a per-pixel random
/// rotation (Cranley–Patterson). Successive passes of one pixel fill [0, 1)
/// evenly, so progressive accumulation converges faster than with
/// independent offsets, and neighbouring pixels stay decorrelated.
#[inline]
pub fn pixel_sequence(seed: u64, x: u32, y: u32, pass: u32) -> f32 {
    const INV_PHI: f64 = 0.618_033_988_749_894_9;
    let r = super::march::pixel_random(seed, x, y) as f64;
    let s = r + pass as f64 * INV_PHI;
    // `s.fract()` exactly (0 ≤ s < 2³³, so the cast truncates as `trunc`
    // does), without the libm `trunc` call that x86-64's baseline makes of
    // it: once per pixel (the call was 2.4 % of a step-32 frame).
    let v = (s - (s as u64) as f64) as f32;
    // f64 → f32 rounding can reach 1.0.
    v.min(1.0 - f32::EPSILON / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_sequence_is_the_fractional_part_bit_for_bit() {
        const INV_PHI: f64 = 0.618_033_988_749_894_9;
        for seed in [0u64, 7, u64::MAX] {
            for (x, y) in [(0u32, 0u32), (3, 9), (511, 511), (4095, 17)] {
                for pass in [0u32, 1, 2, 1000, 1 << 20, u32::MAX] {
                    let r = crate::render::march::pixel_random(seed, x, y) as f64;
                    let v =
                        ((r + pass as f64 * INV_PHI).fract() as f32).min(1.0 - f32::EPSILON / 2.0);
                    let got = pixel_sequence(seed, x, y, pass);
                    assert_eq!(
                        got.to_bits(),
                        v.to_bits(),
                        "seed {seed} pixel ({x}, {y}) pass {pass}"
                    );
                }
            }
        }
    }

    #[test]
    fn uniform_mean_and_variance() {
        let mut r = Rng::new(3, 9);
        let n = 100_000;
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let u = r.uniform() as f64;
            assert!((0.0..1.0).contains(&u));
            s += u;
            s2 += u * u;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        // SE of the mean is sqrt(1/12/n) ≈ 0.0009.
        assert!((mean - 0.5).abs() < 0.0045, "{mean}");
        assert!((var - 1.0 / 12.0).abs() < 0.002, "{var}");
    }

    #[test]
    fn streams_differ_and_repeat() {
        let a: Vec<u32> = (0..4).map(|_| Rng::new(1, 2).next_u32()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        let mut x = Rng::new(1, 2);
        let mut y = Rng::new(1, 3);
        let same = (0..64).filter(|_| x.next_u32() == y.next_u32()).count();
        assert!(same < 2);
    }

    #[test]
    fn golden_sequence_is_stratified() {
        // Any 8 consecutive passes put at most 2 points in each eighth of [0, 1).
        let mut bins = [0u32; 8];
        for p in 0..8 {
            let u = pixel_sequence(5, 10, 20, p);
            bins[(u * 8.0) as usize] += 1;
        }
        assert!(bins.iter().all(|&b| b <= 2), "{bins:?}");
    }
}
