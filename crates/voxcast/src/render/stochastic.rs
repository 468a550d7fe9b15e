//! The Monte-Carlo marchers of S1: sample positions drawn at random instead
//! of on a regular grid, which trades the Riemann sum's aliasing (wood
//! grain) for noise that progressive accumulation over `spp` passes removes.
//!
//! Each estimates the optical depth `∫ σ(t) dt` of every stretch without
//! bias: a sample at `tᵢ` drawn with density `p` stands for a stretch of
//! length `Δᵢ = 1/(n·p(tᵢ))` (S1 eq. 7; eq. 6 for the uniform pdf
//! `p = 1/(b − a)`), and is composited with opacity `1 − exp(−σ(tᵢ)·Δᵢ)`.
//!
//! * `stratified`: one uniform position in each interval `[t_in + k·s,
//!   t_in + (k+1)·s)`; `Δ = s`.
//! * `mc`: `n = ⌈L/s⌉` independent uniform positions on the ray's whole
//!   `[t_in, t_out]` (S1 eqs. 5–6); `Δ = L/n`.
//! * `importance`: positions from a pdf that is constant on each block the
//!   ray crosses, `∝ σ_max^γ · T̂^β` (γ = 0.35, β = 0.3): `σ_max` the
//!   largest extinction the transfer function gives the block's values (0
//!   in transparent blocks, which get no samples), `T̂ = exp(−∫σ̄)` the
//!   light expected to reach the block, from the mean extinction `σ̄` of
//!   the blocks before it (precomputed per block once per transfer
//!   function), rounded to powers of two. The positions are
//!   *stratified* in CDF space — one random offset, equally spaced CDF
//!   values mapped through the inverse CDF — which makes `importance` a
//!   uniform march whose step `step·2^j` varies from block to block;
//!   `Δᵢ = 1/(n·p(tᵢ)) = step·2^j` (S1 eq. 7). The pdf depends only on the
//!   block grid along the ray, not on what the samples found, so the
//!   estimate stays unbiased.
//!
//! `mc` needs its positions in order along the ray for front-to-back
//! compositing; they are drawn already sorted from exponential spacings
//! (Devroye 1986, V.2): with `Eᵢ = −ln Uᵢ` and `Sₖ = E₁ + … + Eₖ`, the
//! `Sₖ/Sₙ₊₁` are exactly the order statistics of `n` uniforms. The sum
//! `Sₙ₊₁` is needed before the first position, so the spacings come in
//! chunks of [`CHUNK`]: a chunk's `m` spacings are drawn, the rest of the
//! sum, `Sₙ₊₁ − Sₘ`, is one Gamma(`n − m + 1`) variate (Marsaglia–Tsang),
//! and the remaining points are uniform order statistics on `[U₍ₘ₎, 1)`.
//! One `ln` per sample and a Gamma draw per chunk instead of a `powf` per
//! sample; no sort, no heap.

use super::march::BlockWalker;
use super::ray::{Composite, Counters, Frame, Marcher, Sampler, Segment};
use super::rng::{splitmix, Rng};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;

/// Spacings [`SortedUniforms`] draws at a time (a Gamma draw per chunk).
pub(super) const CHUNK: usize = 32;

/// `n` uniform numbers in [0, 1), produced in ascending order: exactly the
/// order statistics of `n` independent uniforms (see the module's doc).
pub(super) struct SortedUniforms {
    rng: Rng,
    /// Points not yet put in a chunk.
    left: u32,
    /// The last point of the previous chunk (0 before the first).
    base: f32,
    /// `(1 − base) / S`, S the chunk's spacings plus the rest's Gamma.
    scale: f32,
    /// Partial sums of the chunk's spacings.
    sums: [f32; CHUNK],
    /// Next index into `sums`, and the chunk's length.
    i: usize,
    m: usize,
}

impl SortedUniforms {
    pub(super) fn new(rng: Rng, n: u32) -> SortedUniforms {
        SortedUniforms {
            rng,
            left: n,
            base: 0.0,
            scale: 0.0,
            sums: [0.0; CHUNK],
            i: 0,
            m: 0,
        }
    }

    /// The next chunk: `m` partial sums of exponential spacings, and the
    /// scale that maps them onto `[base, 1)`.
    #[inline(never)]
    fn refill(&mut self) {
        let m = (self.left as usize).min(CHUNK);
        let mut s = 0.0f32;
        for x in &mut self.sums[..m] {
            s -= self.rng.uniform_open0().ln();
            *x = s;
        }
        // The sum of the spacings of the points after this chunk, plus the
        // one after the last point: Gamma(left − m + 1).
        let rest = self.left - m as u32 + 1;
        let tail = if rest == 1 {
            -self.rng.uniform_open0().ln()
        } else {
            gamma(&mut self.rng, rest as f32)
        };
        self.scale = (1.0 - self.base) / (s + tail);
        self.left -= m as u32;
        self.i = 0;
        self.m = m;
    }
}

impl Iterator for SortedUniforms {
    type Item = f32;
    #[inline(always)]
    fn next(&mut self) -> Option<f32> {
        if self.i == self.m {
            if self.left == 0 {
                return None;
            }
            self.refill();
        }
        let u = self.base + self.scale * self.sums[self.i];
        self.i += 1;
        if self.i == self.m {
            // The next chunk's points lie above this one.
            self.base = u;
        }
        Some(u.min(1.0 - f32::EPSILON))
    }
}

/// A standard normal variate (Box–Muller).
#[inline]
fn normal(rng: &mut Rng) -> f32 {
    let r = (-2.0 * rng.uniform_open0().ln()).sqrt();
    r * (std::f32::consts::TAU * rng.uniform()).cos()
}

/// A Gamma(`a`, 1) variate for `a ≥ 1` (Marsaglia & Tsang 2000): `d·v` with
/// `v = (1 + c·x)³`, x normal, accepted when `ln u < x²/2 + d − d·v +
/// d·ln v`, written `d·(3·ln(1 + w) − 3w − 3w² − w³)` with `w = c·x` so that
/// f32 keeps its accuracy for large `d`; the squeeze `u < 1 − 0.0331·x⁴`
/// accepts most draws without a logarithm.
pub(super) fn gamma(rng: &mut Rng, a: f32) -> f32 {
    let d = a - 1.0 / 3.0;
    let c = 1.0 / (9.0 * d).sqrt();
    loop {
        let x = normal(rng);
        let w = c * x;
        if w <= -1.0 {
            continue;
        }
        let v = (1.0 + w) * (1.0 + w) * (1.0 + w);
        let u = rng.uniform_open0();
        let x2 = x * x;
        if u < 1.0 - 0.0331 * x2 * x2
            || u.ln() < 0.5 * x2 + d * (3.0 * w.ln_1p() - w * (3.0 + w * (3.0 + w)))
        {
            return d * v;
        }
    }
}

/// A uniform number for interval `k` of a ray (counter-based, so a stretch
/// can ask for any interval's position in any order).
#[inline(always)]
pub(super) fn interval_random(key: u64, k: u64) -> f32 {
    (splitmix(key ^ k.wrapping_mul(0xD6E8_FEB8_6659_FD93)) >> 40) as f32 / (1u64 << 24) as f32
}

/// `stratified`'s key for pixel `pixel`'s ray in pass `pass`: the first
/// 64 bits of the pixel's random stream.
#[inline(always)]
pub(super) fn stratified_key(seed: u64, pixel: (u32, u32), pass: u32) -> u64 {
    let mut rng = Rng::for_pixel(seed, pixel.0, pixel.1, pass);
    rng.next_u32() as u64 | (rng.next_u32() as u64) << 32
}

/// The pixel's random stream for this pass.
#[inline(always)]
fn rng<T>(f: &Frame<'_, T>, seg: &Segment) -> Rng {
    Rng::for_pixel(f.seed, seg.pixel.0, seg.pixel.1, seg.pass)
}

/// `stratified`: one uniform position in each step interval. Holds the
/// opacities of a full step.
pub(super) struct Stratified<'a> {
    pub full_alphas: &'a [f32; LUT_SIZE],
}

impl<T: Voxel> Marcher<T> for Stratified<'_> {
    #[inline(always)]
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        smp: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        let (t_in, t_out) = (seg.t_in, seg.t_out);
        let s = f.step;
        let key = stratified_key(f.seed, seg.pixel, seg.pass);
        let last = ((t_out - t_in) / s).ceil().max(1.0) as u64 - 1;
        // Interval k's sample position and the length it stands for (the
        // last interval is cut at t_out).
        let pos = |k: u64| {
            let a = t_in + k as f32 * s;
            let len = if k == last { t_out - a } else { s };
            (a + interval_random(key, k) * len, len)
        };
        // A sample belongs to the stretch its position lies in, so skipping
        // an empty stretch drops exactly the samples that contribute nothing.
        let walker = BlockWalker::of_segment(f, seg, seg.walk.1);
        for (ta, tb, b) in walker {
            if f.skip_empty && f.empty[b] {
                continue;
            }
            let k0 = ((ta - t_in) / s).floor().max(0.0) as u64;
            let k1 = (((tb - t_in) / s).floor() as u64).min(last);
            for k in k0..=k1 {
                let (t, len) = pos(k);
                if t < ta || t >= tb {
                    continue;
                }
                n.samples += 1;
                let Some((i, rgb)) = smp.at(f, seg.o + seg.d * t, t, k as u32, seg.view, n).hit
                else {
                    continue;
                };
                let alpha = if k == last {
                    1.0 - (-f.lut.sigma(i) * len / f.unit).exp()
                } else {
                    self.full_alphas[i]
                };
                if alpha > 0.0 && c.add(rgb, alpha) {
                    return true;
                }
            }
        }
        false
    }
}

/// `mc`: ⌈L/step⌉ independent uniform positions on the whole ray (S1
/// eqs. 5–6), drawn already sorted.
pub(super) struct UniformMc;

impl<T: Voxel> Marcher<T> for UniformMc {
    #[inline(always)]
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        smp: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        let len = seg.t_out - seg.t_in;
        let count = (len / f.step).ceil().max(1.0) as u32;
        // S1 eq. 6: each of n samples of pdf 1/L weighs L/n.
        let w = len / count as f32;
        for (k, u) in SortedUniforms::new(rng(f, seg), count).enumerate() {
            let t = seg.t_in + u * len;
            let p = seg.o + seg.d * t;
            if f.skip_empty && f.in_empty_block(p) {
                continue;
            }
            n.samples += 1;
            let Some((i, rgb)) = smp.at(f, p, t, k as u32, seg.view, n).hit else {
                continue;
            };
            let alpha = 1.0 - (-f.lut.sigma(i) * w / f.unit).exp();
            if alpha > 0.0 && c.add(rgb, alpha) {
                return true;
            }
        }
        false
    }
}

/// `importance`: stratified positions from a pdf per block (see the
/// module's doc): the pdf, and per level `j` the spacing `step·2^j` (world
/// units) and the step opacity of every table entry.
pub(super) struct Importance<'a> {
    pub pdf: &'a [PdfBlock],
    pub steps: &'a [f32],
    pub alphas: &'a [Box<[f32; LUT_SIZE]>],
}

impl<T: Voxel> Marcher<T> for Importance<'_> {
    #[inline(always)]
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        smp: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        // One offset per ray; the passes follow the pixel's rotated
        // golden-ratio sequence, as `jitter`'s do.
        let xi = super::rng::pixel_sequence(f.seed, seg.pixel.0, seg.pixel.1, seg.pass);
        // BETA·log₂ e × the optical depth of the blocks' mean extinction so
        // far: the transmittance expected to reach a block is exp(−depth).
        let beta = BETA * std::f32::consts::LOG2_E;
        let mut tau = 0.0f32;
        let walker = BlockWalker::of_segment(f, seg, seg.walk.1);
        let stretches = walker.map(|(ta, tb, b)| {
            let blk = self.pdf[b];
            let j = if blk.level < 0.0 {
                NO_MASS
            } else {
                (blk.level + beta * tau).min(MAX_LEVEL as f32) as u8
            };
            tau += blk.sigma_mean * (tb - ta);
            (ta, tb, j)
        });
        let mut k = 0u32;
        systematic(stretches, self.steps, xi, |t, j| {
            n.samples += 1;
            k += 1;
            let Some((i, rgb)) = smp.at(f, seg.o + seg.d * t, t, k, seg.view, n).hit else {
                return false;
            };
            // S1 eq. 7: the sample stands for Δ = 1/(n·p(t)) = step·2^j.
            let alpha = self.alphas[j][i];
            alpha > 0.0 && c.add(rgb, alpha)
        })
    }
}

/// Level of a block the `importance` pdf gives no mass (transparent).
pub(super) const NO_MASS: u8 = u8::MAX;
/// Coarsest level of the `importance` pdf: spacing `step·2^MAX_LEVEL`.
pub(super) const MAX_LEVEL: u8 = 5;

/// Exponent of the `importance` pdf's extinction term: density
/// `∝ σ_max^GAMMA` (1 would be proportional to the extinction bound; on the
/// teapot and the lung CT 0.35 gave the best time to quality, see
/// docs/monte-carlo.md, "The `importance` pdf").
pub(super) const GAMMA: f32 = 0.35;
/// Exponent of its transmittance term: density `∝ T̂^BETA`, with `T̂ =
/// exp(−∫σ̄)` the light expected to reach a block (σ̄ the blocks' mean
/// extinction). It is an estimate, not a bound: a ray through a gap of a
/// dense block gets more light than `T̂` says, and then its samples behind
/// are too sparse, which costs variance (never bias); a small exponent
/// keeps that cheap. 0.3 was the best of 0.1–0.5 on the teapot and the lung
/// CT (docs/monte-carlo.md); the lower bound `exp(−∫σ_min)` with exponent 1
/// that this replaces saved fewer samples.
pub(super) const BETA: f32 = 0.3;

/// One block of the `importance` pdf (two floats in this order: the
/// packets' walks gather them).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(super) struct PdfBlock {
    /// `γ·log₂(σ_top/σ_max)` (≥ 0): the block's level before attenuation;
    /// negative where the TF makes the block transparent (no mass).
    pub level: f32,
    /// The mean extinction over the block's voxels, per world length.
    pub sigma_mean: f32,
}

/// The `importance` pdf, block by block, from the extinction range the TF
/// gives each block's value range `[lo, hi]` and the block's mean
/// extinction `mean` (per unit length; [`super::blocks::BuildMeanSigma`]);
/// `unit_inv`: 1 / unit length.
pub(super) fn pdf_blocks(
    range: &[[f32; 2]],
    tf: &crate::transfer::TransferFunction,
    unit_inv: f32,
    mean: &[f32],
) -> Vec<PdfBlock> {
    let sigma = |a: f32| -(1.0 - a.clamp(0.0, 0.9999)).ln();
    let max: Vec<f32> = range
        .iter()
        .map(|&[lo, hi]| {
            if hi < 0.0 {
                0.0
            } else {
                sigma(tf.max_opacity_in(lo.max(0.0), hi.min(1.0)))
            }
        })
        .collect();
    let top = max.iter().fold(0.0f32, |a, &b| a.max(b));
    max.iter()
        .zip(mean)
        .map(|(&m, &mean)| {
            if m > 0.0 && top > 0.0 {
                PdfBlock {
                    level: (top / m).log2() * GAMMA,
                    sigma_mean: mean * unit_inv,
                }
            } else {
                PdfBlock {
                    level: -1.0,
                    sigma_mean: 0.0,
                }
            }
        })
        .collect()
}

/// Systematic (stratified) sampling of a piecewise-constant pdf along a
/// ray: `stretches` are consecutive `(t_a, t_b, level)` pieces, the density
/// on a piece is `1/steps[level]` samples per unit length (none on a
/// [`NO_MASS`] piece), and the samples sit at the CDF values `k + ξ`,
/// `k = 0, 1, …` — one random offset `ξ ∈ [0, 1)` per ray, equally spaced
/// points in CDF space mapped through the inverse CDF. On a piece that is
/// a uniform march of spacing `steps[level]`, carried over from piece to
/// piece, so a sample costs O(1) (no search, no `powf`). A sample at level
/// `j` stands for `Δ = 1/(n·p) = steps[j]`; since every CDF value is hit
/// with uniform probability, `E[Σ f(tₖ)·Δₖ] = ∫ f dt` for any `f` that is 0
/// where the pdf is (unbiased, S1 eq. 7). `visit(t, level)` is called for
/// each sample in order; the march stops when it returns true.
#[inline(always)]
pub(super) fn systematic(
    stretches: impl Iterator<Item = (f32, f32, u8)>,
    steps: &[f32],
    xi: f32,
    mut visit: impl FnMut(f32, usize) -> bool,
) -> bool {
    // CDF distance (in samples) from the current piece's start to the next sample.
    let mut ahead = xi;
    for (ta, tb, j) in stretches {
        if j == NO_MASS {
            continue;
        }
        let j = j as usize;
        let s = steps[j];
        let mut t = ta + ahead * s;
        while t < tb {
            if visit(t, j) {
                return true;
            }
            t += s;
        }
        ahead = (t - tb) / s;
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pieces of a ray with pdf levels, one of them without mass.
    const PIECES: [(f32, f32, u8); 5] = [
        (0.0, 3.0, 0),
        (3.0, 5.0, NO_MASS),
        (5.0, 9.0, 2),
        (9.0, 9.5, 1),
        (9.5, 14.0, 0),
    ];
    const STEPS: [f32; 3] = [0.3, 0.6, 1.2];

    /// `1 + sin t` where the pdf has mass, 0 elsewhere.
    fn f(t: f32) -> f64 {
        if (3.0..5.0).contains(&t) {
            0.0
        } else {
            1.0 + (t as f64).sin()
        }
    }

    /// Mean and standard error over `n` random offsets of `Σ f(tₖ)·w(level)`.
    fn estimate(n: usize, weight: impl Fn(usize) -> f64) -> (f64, f64) {
        let mut rng = Rng::new(11, 4);
        let (mut s, mut s2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let mut sum = 0.0f64;
            systematic(PIECES.into_iter(), &STEPS, rng.uniform(), |t, j| {
                sum += f(t) * weight(j);
                false
            });
            s += sum;
            s2 += sum * sum;
        }
        let mean = s / n as f64;
        (mean, ((s2 / n as f64 - mean * mean) / n as f64).sqrt())
    }

    #[test]
    fn systematic_sampling_is_unbiased() {
        let antiderivative = |t: f64| t - t.cos();
        let exact =
            antiderivative(3.0) - antiderivative(0.0) + antiderivative(14.0) - antiderivative(5.0);
        // Weights 1/(n·p) = the level's spacing: the expectation is the integral.
        let (mean, se) = estimate(20_000, |j| STEPS[j] as f64);
        assert!(se > 0.0 && se < 0.01, "se {se}");
        assert!(
            (mean - exact).abs() < 3.0 * se + 1e-5 * exact,
            "{mean} ± {se} vs {exact}"
        );
        // The test can tell: one weight for all levels (ignoring the pdf) is off.
        let (wrong, _) = estimate(20_000, |_| STEPS[0] as f64);
        assert!((wrong - exact).abs() > 100.0 * se, "{wrong} vs {exact}");
    }

    #[test]
    fn systematic_samples_follow_the_pdf() {
        let mut ts: Vec<(f32, usize)> = Vec::new();
        systematic(PIECES.into_iter(), &STEPS, 0.25, |t, j| {
            ts.push((t, j));
            false
        });
        // In order, none where the pdf is 0, spaced by the level's step
        // inside a piece, and the first at ξ·step.
        assert_eq!(ts[0], (0.25 * 0.3, 0));
        assert!(ts.windows(2).all(|w| w[0].0 < w[1].0));
        assert!(ts.iter().all(|&(t, _)| !(3.0..5.0).contains(&t)));
        for w in ts.windows(2).filter(|w| w[0].1 == w[1].1) {
            let gap = w[1].0 - w[0].0;
            let piece = PIECES
                .iter()
                .find(|p| p.0 <= w[0].0 && w[0].0 < p.1)
                .unwrap();
            if piece.0 <= w[1].0 && w[1].0 < piece.1 {
                assert!((gap - STEPS[w[0].1]).abs() < 1e-5, "{w:?}");
            }
        }
        // The expected count is the CDF's total mass: 3/0.3 + 4/1.2 + 0.5/0.6 + 4.5/0.3.
        let mass = 10.0 + 4.0 / 1.2 + 0.5 / 0.6 + 15.0;
        assert!(
            (ts.len() as f32 - mass).abs() <= 1.0,
            "{} vs {mass}",
            ts.len()
        );
        // Stopping early stops.
        let mut count = 0;
        assert!(systematic(PIECES.into_iter(), &STEPS, 0.5, |_, _| {
            count += 1;
            count == 3
        }));
        assert_eq!(count, 3);
    }

    /// Kolmogorov–Smirnov distance of `xs` (mapped by the CDF under test, so
    /// uniform when it fits) from the uniform distribution.
    fn ks(mut xs: Vec<f64>) -> f64 {
        xs.sort_by(f64::total_cmp);
        let n = xs.len() as f64;
        xs.iter()
            .enumerate()
            .map(|(i, &x)| (x - i as f64 / n).max((i + 1) as f64 / n - x))
            .fold(0.0, f64::max)
    }

    /// KS bound at significance 10⁻⁴ (`√(ln(2·10⁴)/2) / √N`).
    fn ks_bound(n: usize) -> f64 {
        2.23 / (n as f64).sqrt()
    }

    #[test]
    fn sorted_uniforms_are_sorted_uniform_order_statistics() {
        let mut seed = 0;
        for n in [1u32, 2, 7, 31, 32, 33, 64, 65, 100, 1000] {
            let draws = (120_000 / n as usize).max(4_000);
            // All the points pooled (the order statistics of iid uniforms,
            // pooled, are iid uniforms), the smallest, the largest, and the
            // gap across the first chunk boundary, each mapped to a
            // uniform by its exact CDF: U₍₁₎ and U₍ₖ₊₁₎ − U₍ₖ₎ are Beta(1, n),
            // U₍ₙ₎ is Beta(n, 1).
            let (mut all, mut lo, mut hi, mut gap) = (vec![], vec![], vec![], vec![]);
            // Mean and mean square of U₍ₖ₎ at k = CHUNK + 1 (Beta(k, n + 1 − k)).
            let (mut m1, mut m2) = (0.0f64, 0.0f64);
            let beta1n = |x: f32| 1.0 - (1.0 - x as f64).powi(n as i32);
            for _ in 0..draws {
                seed += 1;
                let u: Vec<f32> = SortedUniforms::new(Rng::new(seed, 77), n).collect();
                assert_eq!(u.len(), n as usize);
                assert!(u.windows(2).all(|w| w[0] <= w[1]), "n {n}: not sorted");
                assert!(u.iter().all(|x| (0.0..1.0).contains(x)), "n {n}: {u:?}");
                all.extend(u.iter().map(|&x| x as f64));
                lo.push(beta1n(u[0]));
                hi.push((u[n as usize - 1] as f64).powi(n as i32));
                if n as usize > CHUNK {
                    gap.push(beta1n(u[CHUNK] - u[CHUNK - 1]));
                    let x = u[CHUNK] as f64;
                    m1 += x;
                    m2 += x * x;
                }
            }
            for (name, xs) in [("all", all), ("min", lo), ("max", hi), ("gap", gap)] {
                if xs.is_empty() {
                    continue;
                }
                let (d, bound) = (ks(xs.clone()), ks_bound(xs.len()));
                assert!(d < bound, "n {n} {name}: KS {d:.5} ≥ {bound:.5}");
            }
            if n as usize > CHUNK {
                let (k, n1) = ((CHUNK + 1) as f64, n as f64 + 1.0);
                let mean = k / n1;
                let var = k * (n1 - k) / (n1 * n1 * (n1 + 1.0));
                let got = m1 / draws as f64;
                let got_var = m2 / draws as f64 - got * got;
                let se = (var / draws as f64).sqrt();
                assert!((got - mean).abs() < 4.0 * se, "n {n}: mean {got} vs {mean}");
                assert!(
                    (got_var / var - 1.0).abs() < 0.1,
                    "n {n}: var {got_var} vs {var}"
                );
            }
        }
        // The test can tell: points a little off uniform, or the chunk's
        // spacings normalised by their own sum (the last point of every
        // chunk at its end), fail it.
        let xs: Vec<f64> = (0..20_000)
            .map(|i| SortedUniforms::new(Rng::new(i, 78), 10).collect::<Vec<_>>())
            .flat_map(|u| u.into_iter().map(|x| (x as f64).powf(1.03)))
            .collect();
        assert!(ks(xs.clone()) > ks_bound(xs.len()));
        let xs: Vec<f64> = (0..20_000)
            .flat_map(|i| {
                let mut r = Rng::new(i, 79);
                let mut s = 0.0;
                let e: Vec<f64> = (0..10)
                    .map(|_| {
                        s -= (r.uniform_open0() as f64).ln();
                        s
                    })
                    .collect();
                e.into_iter().map(move |x| x / s)
            })
            .collect();
        assert!(ks(xs.clone()) > ks_bound(xs.len()));
    }

    #[test]
    fn gamma_moments() {
        let mut rng = Rng::new(5, 6);
        for a in [1.0f32, 2.0, 9.5, 33.0, 1000.0, 100_000.0] {
            let n = 100_000;
            let xs: Vec<f64> = (0..n).map(|_| gamma(&mut rng, a) as f64).collect();
            let mean = xs.iter().sum::<f64>() / n as f64;
            let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
            let skew =
                xs.iter().map(|x| (x - mean).powi(3)).sum::<f64>() / n as f64 / var.powf(1.5);
            let a = a as f64;
            // Mean a, variance a, skewness 2/√a; standard errors √(a/n),
            // ≈ a·√(2/n) and ≈ √(6/n).
            assert!(
                (mean - a).abs() < 4.0 * (a / n as f64).sqrt(),
                "a {a}: mean {mean}"
            );
            assert!(
                (var - a).abs() < 4.0 * a * (2.0 / n as f64).sqrt() * (1.0 + 3.0 / a),
                "a {a}: var {var}"
            );
            assert!(
                (skew - 2.0 / a.sqrt()).abs() < 4.0 * (6.0 / n as f64).sqrt() * (1.0 + 4.0 / a),
                "a {a}: skew {skew}"
            );
        }
    }

    #[test]
    fn pdf_levels_follow_the_extinction() {
        let tf = crate::transfer::TransferFunction {
            color: vec![[0.0, 1.0, 1.0, 1.0]],
            opacity: vec![[0.0, 0.0], [1.0, 0.9]],
            window: None,
        };
        // Dense, transparent, faint (σ_max 1/16 of the top), attenuating;
        // mean extinctions per unit length, the unit 0.5 world lengths.
        let blocks = pdf_blocks(
            &[[0.5, 1.0], [-1.0, -1.0], [0.0, 0.0], [0.0, 0.14]],
            &tf,
            2.0,
            &[1.2, 0.0, 0.0, 0.05],
        );
        assert_eq!(blocks[0].level, 0.0);
        assert_eq!(blocks[0].sigma_mean, 2.4, "{:?}", blocks[0]);
        assert!(blocks[1].level < 0.0 && blocks[2].level < 0.0);
        assert_eq!(blocks[1].sigma_mean, 0.0);
        assert!(
            blocks[3].level > 0.0 && blocks[3].sigma_mean == 0.1,
            "{:?}",
            blocks[3]
        );
    }
}
