//! Blinn–Phong in the packets, and shading deferred until a full
//! vector of samples waits for it.
//!
//! Compositing front to back adds each sample's colour times the
//! transmittance before it, and the transmittance depends on opacities
//! only, never on shading. So a visible sample's opacity is composited at
//! once, while its colour — the gradient's six trilinear fetches and the
//! lighting — can wait: the sample goes into a queue with its weight
//! (transmittance × emission weight), and whenever `N` samples wait, one
//! full vector (gathered in registers) shades them and adds each to its
//! own lane's colour. In the lock-step loop the visible lanes of an
//! iteration are about half of them (54 % on the teapot CT); the queue
//! makes every shading lane count. The step-per-block marches composite
//! a sample's colour at more than one step (S0's grouped reuse; a run's
//! last sample, scaled once its stretch is known), and so does grouped
//! `threshold`: there each lane's last evaluated sample waits in a slot
//! ([`Slots`]) that sums its weights, and goes to the queue when the
//! lane evaluates its next one. Their scalar walk (`adaptive-s0`)
//! composites a run's end itself and shades at once.

use super::simd::Simd;
use super::LANES;
use crate::render::shading::BlinnPhong;
use glam::Vec3;

/// Per lane, the last evaluated sample whose colour waits unshaded —
/// position, premultiplied colour, opacity — with the weight its colour
/// has gathered so far (the transmittance × emission weight of every step
/// it was composited at); it goes to the queue when the lane evaluates
/// its next sample, or at the end.
pub(super) struct Slots<S: Simd> {
    pub p: [S::F; 3],
    pub q: [S::F; 3],
    pub al: S::F,
    pub w: S::F,
    /// Lanes whose slot holds a visible sample.
    pub ok: S::M,
}

impl<S: Simd> Slots<S> {
    /// Empty slots.
    #[inline(always)]
    pub unsafe fn new() -> Self {
        let zero = S::splat(0.0);
        Slots {
            p: [zero; 3],
            q: [zero; 3],
            al: zero,
            w: zero,
            ok: S::from_bits(0),
        }
    }

    /// The lanes of `m` evaluated a sample (position `p`, premultiplied
    /// colour `q`, opacity `al`, visible where `ok`): it replaces their
    /// slot, with no weight yet (queue the old ones, [`Slots::weighty`],
    /// first).
    #[inline(always)]
    pub unsafe fn replace(&mut self, m: S::M, p: [S::F; 3], q: [S::F; 3], al: S::F, ok: S::M) {
        for (s, v) in self.p.iter_mut().zip(p) {
            *s = S::blend(m, *s, v);
        }
        for (s, v) in self.q.iter_mut().zip(q) {
            *s = S::blend(m, *s, v);
        }
        self.al = S::blend(m, self.al, al);
        self.w = S::blend(m, self.w, S::splat(0.0));
        self.ok = S::or(S::and(m, ok), S::but(self.ok, m));
    }

    /// The lanes of `m` whose slot holds a visible sample with weight.
    #[inline(always)]
    pub unsafe fn weighty(&self, m: S::M) -> S::M {
        S::and(S::and(m, self.ok), S::gt(self.w, S::splat(0.0)))
    }
}

/// `x^n` by repeated squaring (`n` ≤ 64).
#[inline(always)]
unsafe fn powi<S: Simd>(x: S::F, n: u32) -> S::F {
    let mut r = S::splat(1.0);
    let mut b = x;
    let mut n = n;
    while n > 0 {
        if n & 1 == 1 {
            r = r * b;
        }
        n >>= 1;
        if n > 0 {
            b = b * b;
        }
    }
    r
}

/// One channel of `BlinnPhong::shade` times the opacity α, from the
/// premultiplied colour `q = c·α` and `sa = spec·α`: `min(c·k + spec,
/// 1)·α = min(q·k + sa, α)` (α ≥ 0), or `q` where the gradient is `flat`.
#[inline(always)]
unsafe fn phong<S: Simd>(q: S::F, k: S::F, sa: S::F, flat: S::M, al: S::F) -> S::F {
    S::blend(flat, S::min(q * k + sa, al), q)
}

#[inline(always)]
unsafe fn dot<S: Simd>(a: [S::F; 3], b: [S::F; 3]) -> S::F {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The lighting's constants in registers.
pub(super) struct Light<S: Simd> {
    inv_sp: [S::F; 3],
    min_g2: S::F,
    amb: S::F,
    dif: S::F,
    spe: S::F,
    shin: u32,
}

impl<S: Simd> Light<S> {
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn new(bp: &BlinnPhong, inv_spacing: Vec3) -> Self {
        Self {
            inv_sp: [
                S::splat(inv_spacing.x),
                S::splat(inv_spacing.y),
                S::splat(inv_spacing.z),
            ],
            min_g2: S::splat(bp.min_gradient * bp.min_gradient),
            amb: S::splat(bp.ambient),
            dif: S::splat(bp.diffuse),
            spe: S::splat(bp.specular),
            shin: bp.shininess as u32,
        }
    }

    /// The premultiplied shaded colour of samples of premultiplied colour
    /// `q` (the table's row: colour × `al`), opacity `al` and gradient
    /// `gr` (per voxel) seen along `view`: lane by lane
    /// `BlinnPhong::shade` times `al` (to a rounding).
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn shade(
        &self,
        gr: [S::F; 3],
        q: [S::F; 3],
        al: S::F,
        view: [S::F; 3],
    ) -> [S::F; 3] {
        let flat = S::lt(dot::<S>(gr, gr), self.min_g2);
        let s = self.inv_sp;
        let gw = [gr[0] * s[0], gr[1] * s[1], gr[2] * s[2]];
        // |n·view| with n = gw/|gw|: the dot scaled once, by the
        // reciprocal root (flat lanes, where it may be ∞, are not used).
        let ndl = S::abs(dot::<S>(gw, view)) * S::rsqrt(dot::<S>(gw, gw));
        let sa = self.spe * powi::<S>(ndl, self.shin) * al;
        let k = self.amb + self.dif * ndl;
        [
            phong::<S>(q[0], k, sa, flat, al),
            phong::<S>(q[1], k, sa, flat, al),
            phong::<S>(q[2], k, sa, flat, al),
        ]
    }
}

/// Room for the pushes whose samples wait: fewer than `N` samples in the
/// queue and a full vector's in the batch being shaded, each push at
/// least one.
const CAP: usize = 2 * LANES;

/// How many vectors a waiting sample is: position (3), weight, opacity,
/// premultiplied colour (3) and its lane (as a float).
const PARTS: usize = 9;

/// The samples waiting for their shading, as vectors (fewer than `N`, on
/// the low lanes), and what each lane's shaded samples have added up to
/// so far. Not an array that pushes store into and a batch loads back: a
/// vector loaded from several pushes' stores waits for all of them to
/// reach the cache (2.9 % of the shaded teapot's frame, 7–9 % of the
/// step-per-block marches', docs/engine.md).
pub(super) struct Deferred<S: Simd> {
    /// Samples waiting.
    n: usize,
    /// Position (3), weight (transmittance before the sample × the
    /// emission weight), opacity, premultiplied colour (3), lane.
    v: [S::F; PARTS],
    /// The lane masks (bits) of the pushes whose samples wait or are
    /// being shaded, oldest first, in a ring from `head`: a push queues
    /// its lanes in increasing order, so a batch is a run of pushes, and
    /// each push's shaded samples go back to their lanes by one expand
    /// ([`Deferred::add`]). A push split across two batches keeps the
    /// lanes still waiting.
    pushes: [u32; CAP],
    head: usize,
    /// Pushes in the ring.
    np: usize,
    /// Each lane's shaded colour so far.
    pub(super) acc: [[f32; LANES]; 3],
}

/// A vector of waiting samples, taken from the queue to be shaded.
pub(super) struct Batch<S: Simd> {
    pub(super) m: S::M,
    pub(super) p: [S::F; 3],
    pub(super) al: S::F,
    pub(super) q: [S::F; 3],
    pub(super) lane: S::I,
    w: S::F,
    k: usize,
}

impl<S: Simd> Batch<S> {
    /// The first `k` lanes of `v` (a [`Deferred`]'s parts) as a batch;
    /// the others masked out (zero weight, lane 0).
    #[inline(always)]
    unsafe fn of(v: &[S::F; PARTS], k: usize) -> Self {
        let m = S::from_bits(((1u64 << k) - 1) as u32);
        Batch {
            m,
            p: [v[0], v[1], v[2]],
            w: S::keep(m, v[3]),
            al: v[4],
            q: [v[5], v[6], v[7]],
            lane: S::keep_i(m, S::to_i(v[8])),
            k,
        }
    }
}

impl<S: Simd> Deferred<S> {
    /// An empty queue.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn new() -> Self {
        Self {
            n: 0,
            v: [S::splat(0.0); PARTS],
            pushes: [0; CAP],
            head: 0,
            np: 0,
            acc: [[0.0; LANES]; 3],
        }
    }

    /// Queues the samples of lanes `m` (`S::N` ≤ `LANES`); a vector of
    /// them when `N` wait (shade it, [`Deferred::add`], before the next
    /// push).
    ///
    /// # Safety
    /// The width's instructions; the last batch added.
    #[inline(always)]
    pub(super) unsafe fn push(
        &mut self,
        m: S::M,
        p: [S::F; 3],
        w: S::F,
        al: S::F,
        q: [S::F; 3],
    ) -> Option<Batch<S>> {
        let bits = S::bits(m);
        if bits == 0 {
            return None;
        }
        debug_assert!(self.n < S::N && self.np < CAP);
        self.pushes[(self.head + self.np) % CAP] = bits;
        self.np += 1;
        let (n, c, full) = (self.n, bits.count_ones() as usize, S::N);
        let iota = S::iota();
        let new = [p[0], p[1], p[2], w, al, q[0], q[1], q[2], S::to_f(iota)];
        // The lanes of `m` in order, after the `n` waiting: lane `n + i`
        // takes `m`'s `i`-th lane.
        let order = S::set_lanes(m);
        let idx = S::permute_i(order, iota - S::splat_i(n as i32));
        let end = (n + c).min(full);
        let put = S::from_bits(((1u64 << end) - 1) as u32 & !((1u32 << n) - 1));
        let mut merged = self.v;
        for (o, &x) in merged.iter_mut().zip(&new) {
            *o = S::blend(put, *o, S::permute(x, idx));
        }
        if n + c < full {
            self.v = merged;
            self.n = n + c;
            return None;
        }
        // A full vector: the rest of `m`'s lanes start the next one.
        let idx = S::permute_i(order, iota + S::splat_i((full - n) as i32));
        for (o, &x) in self.v.iter_mut().zip(&new) {
            *o = S::permute(x, idx);
        }
        self.n = n + c - full;
        Some(Batch::of(&merged, full))
    }

    /// The samples still waiting (fewer than `N`) as a batch, emptying
    /// the queue; `None` when none wait.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn rest(&mut self) -> Option<Batch<S>> {
        let k = std::mem::take(&mut self.n);
        (k > 0).then(|| Batch::of(&self.v, k))
    }

    /// Adds the batch's shaded colours `e` (premultiplied by opacity),
    /// times their weights, to their lanes: push by push, each push's
    /// samples (distinct lanes, in order) permuted back to their lanes and
    /// added in registers, so each lane adds its samples in the order
    /// they were queued.
    ///
    /// # Safety
    /// The width's instructions; `b` is the last batch
    /// [`Deferred::push`] or [`Deferred::rest`] gave.
    #[inline(always)]
    pub(super) unsafe fn add(&mut self, b: &Batch<S>, e: [S::F; 3]) {
        let v = [e[0] * b.w, e[1] * b.w, e[2] * b.w];
        let mut acc = [
            S::load_at(self.acc[0].as_ptr()),
            S::load_at(self.acc[1].as_ptr()),
            S::load_at(self.acc[2].as_ptr()),
        ];
        let mut pos = 0;
        while pos < b.k {
            debug_assert!(self.np > 0);
            let m = self.pushes[self.head];
            let left = b.k - pos;
            let n = m.count_ones() as usize;
            let (dest, taken) = if n <= left {
                self.head = (self.head + 1) % CAP;
                self.np -= 1;
                (m, n)
            } else {
                // The push goes on into the next batch: its lowest lanes
                // are in this one.
                let mut rest = m;
                for _ in 0..left {
                    rest &= rest - 1;
                }
                self.pushes[self.head] = rest;
                (m ^ rest, left)
            };
            let idx = S::expand_order(dest, pos as i32);
            let dm = S::from_bits(dest);
            for (a, &v) in acc.iter_mut().zip(&v) {
                *a = *a + S::keep(dm, S::permute(v, idx));
            }
            pos += taken;
        }
        for (row, &a) in self.acc.iter_mut().zip(&acc) {
            S::store_at(row.as_mut_ptr(), a);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::packet::simd::at_each_width;

    type Waiting = std::collections::VecDeque<(f32, usize)>;

    /// Takes a batch: its lanes must be the oldest samples waiting (their
    /// first position coordinate, their lane); adds them to their lanes.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    unsafe fn check<S: Simd>(dq: &mut Deferred<S>, b: Batch<S>, expected: &mut Waiting) {
        let (p, lane) = (S::store(b.p[0]), S::store(S::to_f(b.lane)));
        for i in 0..b.k {
            let (want, l) = expected.pop_front().expect("a sample was pushed");
            assert_eq!(p[i], want, "sample {i} of the batch");
            assert_eq!(lane[i], l as f32, "lane of sample {i}");
        }
        dq.add(&b, [b.p[0], b.p[0], b.p[0]]);
    }

    /// Pushes pseudo-random lane masks through a queue: every sample comes
    /// out once, in the order pushed, a full vector at a time (the rest at
    /// the end), on its own lane; and each lane's added colour is the sum
    /// of its own samples.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    unsafe fn queue_keeps_order_and_lanes<S: Simd>() {
        let mut dq = Deferred::<S>::new();
        let mut expected = Waiting::new();
        let mut sums = [0.0f64; LANES];
        let mut seed = 0x2545_f491_u32;
        let full = (1u64 << S::N) as u32 - 1;
        let mut id = 0u32;
        let mut batches = 0;
        for round in 0..400 {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            // Some empty pushes, some full ones, mostly partial.
            let bits = match round % 7 {
                0 => 0,
                1 => full,
                _ => (seed >> 7) & full,
            };
            let mut p0 = S::Af::default();
            for l in 0..S::N {
                p0[l] = id as f32;
                if bits >> l & 1 == 1 {
                    expected.push_back((id as f32, l));
                    sums[l] += id as f64;
                }
                id += 1;
            }
            let zero = S::splat(0.0);
            let p = [S::load(p0), zero, zero];
            if let Some(b) = dq.push(S::from_bits(bits), p, S::splat(1.0), zero, [zero; 3]) {
                assert_eq!(b.k, S::N);
                check::<S>(&mut dq, b, &mut expected);
                batches += 1;
            }
            assert!(expected.len() < S::N, "fewer than a vector waits");
        }
        if let Some(b) = dq.rest() {
            assert_eq!(b.k, expected.len());
            check::<S>(&mut dq, b, &mut expected);
        }
        assert!(expected.is_empty() && dq.rest().is_none());
        assert!(batches > 50, "{batches} batches");
        for (l, &s) in sums.iter().enumerate().take(S::N) {
            assert_eq!(dq.acc[0][l] as f64, s, "lane {l}'s sum");
        }
    }

    #[test]
    fn the_queue_hands_out_samples_in_order_on_their_lanes_at_each_width_the_cpu_has() {
        at_each_width!(queue_keeps_order_and_lanes);
    }
}
