//! Blinn–Phong in the packets, and shading deferred until a full
//! vector of samples waits for it.
//!
//! Compositing front to back adds each sample's colour times the
//! transmittance before it, and the transmittance depends on opacities
//! only, never on shading. So a visible sample's opacity is composited at
//! once, while its colour — the gradient's six trilinear fetches and the
//! lighting — can wait: the sample goes into a queue with its weight
//! (transmittance × emission weight), and whenever `N` samples wait, one
//! full vector shades them and adds each to its own lane's colour. In
//! the lock-step loop the visible lanes of an iteration are about half
//! of them (54 % on the teapot CT); the queue makes every shading lane
//! count. The step-per-block marches composite a sample's colour at more
//! than one step (S0's grouped reuse; a run's last sample, scaled once its
//! stretch is known), and so does grouped `threshold`: there each lane's
//! last evaluated sample waits in a slot ([`Slots`]) that sums its
//! weights, and goes to the queue when the lane evaluates its next one.
//! Their scalar walk (`adaptive-s0`) composites a run's end itself and
//! shades at once.

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

/// Room for a vector's worth of waiting samples plus one more push.
const CAP: usize = 32;

/// The samples waiting for their shading, and what each lane's shaded
/// samples have added up to so far.
pub(super) struct Deferred {
    /// Samples waiting (at most `N − 1` between pushes).
    n: usize,
    p: [[f32; CAP]; 3],
    /// Transmittance before the sample × the emission weight.
    w: [f32; CAP],
    al: [f32; CAP],
    /// The premultiplied colour.
    q: [[f32; CAP]; 3],
    lane: [i32; CAP],
    /// The lane masks (bits) of the pushes whose samples wait, oldest
    /// first, in a ring from `head`: a push queues its lanes in increasing
    /// order, so a batch is a run of pushes, and each push's shaded
    /// samples go back to their lanes by one expand ([`Deferred::add`]).
    /// A push split across two batches keeps the lanes still waiting.
    pushes: [u32; CAP],
    head: usize,
    /// Pushes waiting (at most `CAP − 1`: each has a sample waiting).
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

impl Deferred {
    pub(super) fn new() -> Self {
        Self {
            n: 0,
            p: [[0.0; CAP]; 3],
            w: [0.0; CAP],
            al: [0.0; CAP],
            q: [[0.0; CAP]; 3],
            lane: [0; CAP],
            pushes: [0; CAP],
            head: 0,
            np: 0,
            acc: [[0.0; LANES]; 3],
        }
    }

    /// Queues the samples of lanes `m` (`S::N` ≤ `LANES`); true when a
    /// vector's worth waits (then [`Deferred::take`] before the next
    /// push).
    ///
    /// # Safety
    /// The width's instructions; fewer than `S::N` samples waiting.
    #[inline(always)]
    pub(super) unsafe fn push<S: Simd>(
        &mut self,
        m: S::M,
        p: [S::F; 3],
        w: S::F,
        al: S::F,
        q: [S::F; 3],
    ) -> bool {
        debug_assert!(self.n < S::N && 2 * S::N <= CAP);
        let n = self.n;
        S::compress_at(self.p[0].as_mut_ptr().add(n), m, p[0]);
        S::compress_at(self.p[1].as_mut_ptr().add(n), m, p[1]);
        S::compress_at(self.p[2].as_mut_ptr().add(n), m, p[2]);
        S::compress_at(self.w.as_mut_ptr().add(n), m, w);
        S::compress_at(self.al.as_mut_ptr().add(n), m, al);
        S::compress_at(self.q[0].as_mut_ptr().add(n), m, q[0]);
        S::compress_at(self.q[1].as_mut_ptr().add(n), m, q[1]);
        S::compress_at(self.q[2].as_mut_ptr().add(n), m, q[2]);
        S::compress_at_i(self.lane.as_mut_ptr().add(n), m, S::iota());
        let bits = S::bits(m);
        if bits != 0 {
            self.pushes[(self.head + self.np) % CAP] = bits;
            self.np += 1;
        }
        self.n = n + bits.count_ones() as usize;
        self.n >= S::N
    }

    /// Samples waiting.
    pub(super) fn waiting(&self) -> usize {
        self.n
    }

    /// The first `min(waiting, N)` samples as a vector (lanes past them
    /// masked out: zero weight, lane 0), moving the rest to the
    /// front.
    ///
    /// # Safety
    /// The width's instructions.
    #[inline(always)]
    pub(super) unsafe fn take<S: Simd>(&mut self) -> Batch<S> {
        let k = self.n.min(S::N);
        let m = S::from_bits((1u32 << k) - 1);
        let b = Batch {
            m,
            p: [
                S::load_at(self.p[0].as_ptr()),
                S::load_at(self.p[1].as_ptr()),
                S::load_at(self.p[2].as_ptr()),
            ],
            w: S::keep(m, S::load_at(self.w.as_ptr())),
            al: S::load_at(self.al.as_ptr()),
            q: [
                S::load_at(self.q[0].as_ptr()),
                S::load_at(self.q[1].as_ptr()),
                S::load_at(self.q[2].as_ptr()),
            ],
            lane: S::keep_i(m, S::load_at_i(self.lane.as_ptr())),
            k,
        };
        if self.n > S::N {
            let n = S::N;
            for a in self.p.iter_mut().chain(&mut self.q) {
                S::store_at(a.as_mut_ptr(), S::load_at(a.as_ptr().add(n)));
            }
            S::store_at(self.w.as_mut_ptr(), S::load_at(self.w.as_ptr().add(n)));
            S::store_at(self.al.as_mut_ptr(), S::load_at(self.al.as_ptr().add(n)));
            S::store_at_i(
                self.lane.as_mut_ptr(),
                S::load_at_i(self.lane.as_ptr().add(n)),
            );
        }
        self.n -= k;
        b
    }

    /// Adds the batch's shaded colours `e` (premultiplied by opacity),
    /// times their weights, to their lanes: push by push, each push's
    /// samples (distinct lanes, in order) permuted back to their lanes and
    /// added in registers, so each lane adds its samples in the order
    /// they were queued.
    ///
    /// # Safety
    /// The width's instructions; `b` is the last [`Deferred::take`].
    #[inline(always)]
    pub(super) unsafe fn add<S: Simd>(&mut self, b: &Batch<S>, e: [S::F; 3]) {
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
