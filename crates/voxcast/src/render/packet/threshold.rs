//! `threshold` and `lod` in the packets: each lane steps by the step of
//! the range its last value fell into (`march::Threshold`, ray by ray),
//! or of its sample's `lod` class (`LodRay::class_at`: the leaf's amount
//! of cloud through the opacity in front, looking one spacing ahead), so
//! the lanes' positions drift apart and each keeps its own `t`. Empty blocks
//! are skipped by the fixed-step loop's skip distances, and the lane then
//! starts again on the base grid `t₀ + n·step` past them, where the
//! scalar march restarts at the next block that is not empty. With S0's
//! grouped reuse (`threshold+grouped`) a lane evaluates only its groups'
//! heads (a restart starts a group) and, shaded, keeps each head in a
//! slot that gathers the weights of the samples reusing it, so a group is
//! shaded once.

#[cfg(all(packets, target_arch = "aarch64"))]
pub(super) use vector::thr_neon;
#[cfg(all(packets, target_arch = "x86_64"))]
pub(super) use vector::{thr_avx2, thr_avx2_loads, thr_avx512, thr_avx512_loads};
#[cfg(packets)]
pub(super) use vector::{ByLeaf, ByRange};

use super::{Lane, Packets, Runs, Setup};
use crate::render::march::ThresholdParams;
use crate::render::stats::RenderStats;
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec3;

/// How a `threshold` lane picks its step: by the range of its sample's
/// value, or by its sample's `lod` class.
pub(in crate::render) enum Select<'a> {
    Range(ThresholdParams),
    Lod(LodSelect<'a>),
}

/// What a `lod` lane's class reads (`LodRay::class_at`).
pub(in crate::render) struct LodSelect<'a> {
    /// Per leaf (the block grid's blocks), its amount of cloud; negative
    /// where the transfer function makes it transparent (classed sparse).
    pub amount: &'a [f32],
    /// The leaves on each axis, and 1 / their edge in cells.
    pub counts: [usize; 3],
    pub inv_leaf: f32,
    /// The contribution at or above which a leaf is `high`.
    pub threshold: f32,
    /// Front to back: classed through the opacity in front; back to front
    /// (summed front to back here) with none, as the scalar pass.
    pub front: bool,
}

/// `threshold` (or `lod`) in packets: how a step is picked, and per range
/// (class) the step and the premultiplied table.
pub(in crate::render) struct Thr<'a> {
    pub select: Select<'a>,
    /// Per range (class), the step (world units).
    pub steps: [f32; 3],
    /// The ranges' premultiplied tables, one after the other (`LUT_SIZE`
    /// rows each).
    pub tables: &'a [[f32; 4]],
    /// Extinction per unit length of every entry, for the last sample's
    /// stretch.
    pub sigma: &'a [f32; LUT_SIZE],
    /// S0's grouped reuse (`threshold+grouped`): the `k`-th sample since
    /// the ray's start or its last skip is evaluated where `k` is a
    /// multiple of its group's size (`march::group_size`), the others
    /// reuse the group head's value and colour (`sample::Grouped`).
    pub grouped: bool,
}

impl<T: Voxel, R: Runs<T>> Packets<'_, T, R> {
    /// Sets up a `threshold` ray as [`crate::render::trace::trace`] does:
    /// the lane (its first sample `k0` on the base grid, at the first
    /// block that is not empty) and where it stops: the end of its walk,
    /// and its exit (a sample whose step reaches it is the last).
    pub(super) fn thr_lane(
        &self,
        ray: (Vec3, Vec3),
        limit: f32,
        pixel: (u32, u32),
        pass: u32,
        stats: &mut RenderStats,
    ) -> Option<(Lane, [f32; 2])> {
        let Setup {
            o,
            d,
            t_in,
            t_out,
            walk,
        } = self.setup(ray, limit, stats)?;
        let t0 = self.grid_start(t_in, pixel, pass);
        let k0 = ((walk.0 - t0) / self.st).ceil().max(0.0) as u32;
        // Past the walk's end every block is empty.
        if t0 + k0 as f32 * self.st >= walk.1 {
            return None;
        }
        let lane = Lane {
            k0,
            ..Lane::walking(o, d, -ray.1, t0, t_out + (t0 - t_in))
        };
        Some((lane, [walk.1, t_out]))
    }
}

/// The vector loop (where the packets are compiled: x86-64, AArch64).
#[cfg(packets)]
mod vector {
    use super::super::fetch::{Skips, Vol};
    use super::super::shade::{Deferred, Light, Slots};
    use super::super::simd::Simd;
    #[cfg(target_arch = "aarch64")]
    use super::super::simd::W4;
    #[cfg(target_arch = "x86_64")]
    use super::super::simd::{W16, W8};
    use super::super::tail::{composite, drain_deferred, over_stretch, store_lanes};
    use super::super::vector::{queue_slots, shade_batch};
    use super::super::vwalk::{last_blocks, Rays};
    use super::super::walk::group_heads;
    use super::super::{Lane, Packets, Runs, State, LANES};
    use super::Select;
    use crate::transfer::LUT_SIZE;
    use crate::volume::Voxel;

    #[cfg(target_arch = "x86_64")]
    entry!(
        /// The `threshold` lanes' loop at AVX2: two packets of eight,
        /// fetching by the gather instructions.
        ///
        /// # Safety
        /// AVX2 and FMA present; the grid `fits`; the shading `shades`;
        /// `pk.z_pairs` is the grid's z-paired copy; `pk.thr` is set.
        pub(in crate::render::packet) thr_avx2,
        "avx2,fma",
        W8<false>,
        march<[P: Chooser] SKIP, SHADE, GROUPED>
    );
    #[cfg(target_arch = "x86_64")]
    entry!(
        /// [`thr_avx2`] fetching by scalar loads.
        ///
        /// # Safety
        /// As [`thr_avx2`].
        pub(in crate::render::packet) thr_avx2_loads,
        "avx2,fma",
        W8<true>,
        march<[P: Chooser] SKIP, SHADE, GROUPED>
    );
    #[cfg(target_arch = "x86_64")]
    entry!(
        /// [`thr_avx2`] in sixteen lanes of AVX-512 registers.
        ///
        /// # Safety
        /// As [`thr_avx2`], and AVX-512 F present.
        pub(in crate::render::packet) thr_avx512,
        "avx2,fma,avx512f",
        W16<false>,
        march<[P: Chooser] SKIP, SHADE, GROUPED>
    );
    #[cfg(target_arch = "x86_64")]
    entry!(
        /// [`thr_avx512`] fetching by scalar loads.
        ///
        /// # Safety
        /// As [`thr_avx512`].
        pub(in crate::render::packet) thr_avx512_loads,
        "avx2,fma,avx512f",
        W16<true>,
        march<[P: Chooser] SKIP, SHADE, GROUPED>
    );
    #[cfg(target_arch = "aarch64")]
    entry!(
        /// [`thr_avx2`] in four lanes of NEON registers (AArch64).
        ///
        /// # Safety
        /// The grid `fits`; the shading `shades`; `pk.z_pairs` is the
        /// grid's z-paired copy; `pk.thr` is set.
        pub(in crate::render::packet) thr_neon,
        "neon",
        W4,
        march<[P: Chooser] SKIP, SHADE, GROUPED>
    );

    /// How a loop's lanes pick their classes: by [`Ranges`] (`threshold`)
    /// or by [`Leaves`] (`lod`), at each width.
    pub(in crate::render::packet) trait Chooser {
        type In<S: Simd>: Choose<S>;
    }

    /// `threshold`: by the range of the sample's value.
    pub(in crate::render::packet) struct ByRange;
    /// `lod`: by the class of the sample's leaf.
    pub(in crate::render::packet) struct ByLeaf;

    impl Chooser for ByRange {
        type In<S: Simd> = Ranges<S>;
    }
    impl Chooser for ByLeaf {
        type In<S: Simd> = Leaves<S>;
    }

    /// A choice of class in registers of width `S`.
    pub(in crate::render::packet) trait Choose<S: Simd> {
        /// The registers of the render's selection.
        ///
        /// # Safety
        /// The width's instructions.
        unsafe fn of(select: &Select<'_>) -> Self;
        /// Each lane's class (0, 1 or 2) and step (one of `steps`) at `p`
        /// (`t` along its ray of `rays`), its value `v` seen through the
        /// opacity `a` in front.
        ///
        /// # Safety
        /// The width's instructions.
        unsafe fn pick(
            &self,
            p: [S::F; 3],
            t: S::F,
            v: S::F,
            a: S::F,
            rays: &Rays<S>,
            steps: [S::F; 3],
        ) -> (S::I, S::F);
    }

    /// `threshold`'s bounds in registers.
    pub(in crate::render::packet) struct Ranges<S: Simd> {
        b0: S::F,
        b1: S::F,
    }

    impl<S: Simd> Choose<S> for Ranges<S> {
        #[inline(always)]
        unsafe fn of(select: &Select<'_>) -> Self {
            let Select::Range(p) = select else {
                unreachable!("threshold's loop by range without ranges")
            };
            Ranges {
                b0: S::splat(p.bounds[0]),
                b1: S::splat(p.bounds[1]),
            }
        }

        /// `ThresholdParams::range`: 0 below the first bound, 1 below the
        /// second, else 2 (NaN too).
        #[inline(always)]
        unsafe fn pick(
            &self,
            _p: [S::F; 3],
            _t: S::F,
            v: S::F,
            _a: S::F,
            _rays: &Rays<S>,
            steps: [S::F; 3],
        ) -> (S::I, S::F) {
            let (lt0, lt1) = (S::lt(v, self.b0), S::lt(v, self.b1));
            let r = S::blend_i(
                lt0,
                S::blend_i(lt1, S::splat_i(2), S::splat_i(1)),
                S::splat_i(0),
            );
            (
                r,
                S::blend(lt0, S::blend(lt1, steps[2], steps[1]), steps[0]),
            )
        }
    }

    /// What `lod`'s classes read in registers: the leaves' grid and
    /// amounts, the contributions of `high` and `low`, and the lanes that
    /// see the opacity in front.
    pub(in crate::render::packet) struct Leaves<S: Simd> {
        amount: *const f32,
        last: [S::I; 3],
        ncx: S::I,
        ncy: S::I,
        inv_leaf: S::F,
        th: S::F,
        quarter: S::F,
        front: S::M,
    }

    impl<S: Simd> Leaves<S> {
        /// `LodRay::leaf`: the leaf at `p` (clamped into the grid).
        #[inline(always)]
        unsafe fn leaf(&self, p: [S::F; 3]) -> S::I {
            // (No closure: it would not inherit the loop's target
            // features, and each intrinsic would become a call.)
            let z = S::splat_i(0);
            let x = S::min_i(S::max_i(S::to_i(p[0] * self.inv_leaf), z), self.last[0]);
            let y = S::min_i(S::max_i(S::to_i(p[1] * self.inv_leaf), z), self.last[1]);
            let w = S::min_i(S::max_i(S::to_i(p[2] * self.inv_leaf), z), self.last[2]);
            x + S::mullo(self.ncx, y + S::mullo(self.ncy, w))
        }

        /// `LodRay::class`: 0 (high), 1 (low) or 2 (sparse) by the
        /// contribution `(1 − a)·am` of the leaf at `p`.
        #[inline(always)]
        unsafe fn class(&self, p: [S::F; 3], a: S::F) -> S::F {
            let am = S::gather_f::<4>(self.amount, self.leaf(p));
            let w = (S::splat(1.0) - a) * am;
            let c = S::blend(S::ge(w, self.quarter), S::splat(2.0), S::splat(1.0));
            S::blend(S::ge(w, self.th), c, S::splat(0.0))
        }
    }

    impl<S: Simd> Choose<S> for Leaves<S> {
        #[inline(always)]
        unsafe fn of(select: &Select<'_>) -> Self {
            let Select::Lod(l) = select else {
                unreachable!("threshold's loop by leaf without leaves")
            };
            let c = l.counts;
            Leaves {
                amount: l.amount.as_ptr(),
                last: last_blocks::<S>(c),
                ncx: S::splat_i(c[0] as i32),
                ncy: S::splat_i(c[1] as i32),
                inv_leaf: S::splat(l.inv_leaf),
                th: S::splat(l.threshold),
                quarter: S::splat(0.25 * l.threshold),
                front: S::from_bits(if l.front { u32::MAX >> (32 - S::N) } else { 0 }),
            }
        }

        /// `LodRay::class_at`: the leaf's class, or the class of the leaf
        /// one spacing ahead where that is higher.
        #[inline(always)]
        unsafe fn pick(
            &self,
            p: [S::F; 3],
            t: S::F,
            _v: S::F,
            a: S::F,
            &Rays { o, d, .. }: &Rays<S>,
            steps: [S::F; 3],
        ) -> (S::I, S::F) {
            let a = S::keep(self.front, a);
            let c = self.class(p, a);
            let t2 = t + step_of::<S>(c, steps);
            let p2 = [o[0] + d[0] * t2, o[1] + d[1] * t2, o[2] + d[2] * t2];
            let c = S::min(c, self.class(p2, a));
            (S::to_i(c), step_of::<S>(c, steps))
        }
    }

    /// The step of class `c` (0, 1 or 2).
    #[inline(always)]
    unsafe fn step_of<S: Simd>(c: S::F, steps: [S::F; 3]) -> S::F {
        let one = S::splat(1.0);
        S::blend(
            S::eq(c, S::splat(0.0)),
            S::blend(S::eq(c, one), steps[2], steps[1]),
            steps[0],
        )
    }

    /// The loop of both widths: lane by lane `march::Threshold::march` with
    /// front-to-back compositing, from the colour and opacity in `st.acc`.
    ///
    /// # Safety
    /// As [`thr_avx2`], with the width's instructions.
    #[inline(always)]
    unsafe fn march<
        S: Simd,
        T: Voxel,
        R: Runs<T>,
        P: Chooser,
        const SKIP: bool,
        const SHADE: bool,
        const GROUPED: bool,
    >(
        pk: &Packets<'_, T, R>,
        lanes: &[Option<Lane>],
        st: &mut State<'_>,
    ) {
        debug_assert!(lanes.len() == S::N && st.acc.len() == S::N);
        let f = pk.f;
        let thr = pk.thr.as_ref().unwrap_unchecked();
        let vol = Vol::<S>::of(pk);
        // Per lane: origin, direction, grid start, view, first sample, end of
        // the walk, exit, the last stretch's end, colour and opacity.
        let mut a = [S::Af::default(); 20];
        let mut live_bits = 0u32;
        for (i, l) in lanes.iter().enumerate() {
            let Some(l) = l else { continue };
            let c = st.acc[i];
            let [stop, out] = st.ends[i];
            let v = [
                l.o.x,
                l.o.y,
                l.o.z,
                l.d.x,
                l.d.y,
                l.d.z,
                l.t0,
                l.view.x,
                l.view.y,
                l.view.z,
                l.t0 + l.k0 as f32 * pk.st,
                stop,
                out,
                l.t_end,
                c.x,
                c.y,
                c.z,
                c.w,
                // `group_size`'s thirds of the exit.
                out / 3.0,
                out * (2.0 / 3.0),
            ];
            for (k, x) in v.into_iter().enumerate() {
                a[k][i] = x;
            }
            live_bits |= 1 << i;
        }
        let o = [S::load(a[0]), S::load(a[1]), S::load(a[2])];
        let d = [S::load(a[3]), S::load(a[4]), S::load(a[5])];
        let t0 = S::load(a[6]);
        let view = [S::load(a[7]), S::load(a[8]), S::load(a[9])];
        let mut t = S::load(a[10]);
        let (t_stop, t_out, t_end) = (S::load(a[11]), S::load(a[12]), S::load(a[13]));
        let mut col = [
            S::load(a[14]),
            S::load(a[15]),
            S::load(a[16]),
            S::load(a[17]),
        ];
        let (zero, one, half) = (S::splat(0.0), S::splat(1.0), S::splat(0.5));
        let top = S::splat((LUT_SIZE - 1) as f32);
        let q = thr.tables.as_ptr() as *const f32;
        let sigma = thr.sigma.as_ptr();
        let rows = S::splat_i(4 * LUT_SIZE as i32);
        // `threshold`'s bounds, or `lod`'s leaves and class thresholds.
        let choose = <P::In<S> as Choose<S>>::of(&thr.select);
        let steps = [
            S::splat(thr.steps[0]),
            S::splat(thr.steps[1]),
            S::splat(thr.steps[2]),
        ];
        let inv_unit = S::splat(1.0 / f.unit);
        let (we, wa) = (
            S::splat(pk.weights.emission),
            S::splat(pk.weights.absorption),
        );
        let stop = S::splat(pk.stop);
        let light = Light::<S>::new(&pk.shading.unwrap_or_default(), f.inv_spacing);
        let mut dq = Deferred::<S>::new();
        // Skipping: the blocks' skip distances, and the base grid.
        let (stv, inv_st) = (S::splat(pk.st), S::splat(1.0 / pk.st));
        let inv_d = [one / d[0], one / d[1], one / d[2]];
        let skips = Skips::<S>::of(pk);
        let rays = Rays { o, d, inv_d, t0 };
        let mut live = S::from_bits(live_bits);
        let (mut cnt, mut cnt_shaded) = (S::splat_i(0), S::splat_i(0));
        // Grouped reuse: each lane's sample count since its start or its
        // last skip, whether its next sample must be evaluated, and its
        // group head's value; with shading its head waits in a slot
        // (position, colour, opacity) gathering the weights of the
        // samples that reuse it, and goes to the queue once.
        // (Groups of at most 3 samples, `group_size`'s largest.)
        let (th1, th2, three) = (S::load(a[18]), S::load(a[19]), S::splat(3.0));
        let mut kc = zero;
        let mut fresh = S::from_bits(live_bits);
        let mut head_v = zero;
        let mut cnt_interp = S::splat_i(0);
        let mut slot = Slots::<S>::new();
        loop {
            let act = S::and(live, S::lt(t, t_stop));
            if S::bits(act) == 0 {
                break;
            }
            let p = [o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t];
            let mut samp = act;
            if SKIP {
                let (skip, te) = skips.exit(&vol, p, &rays, act);
                if S::bits(skip) != 0 {
                    // Past the empty cube around the block, on the base grid
                    // (a thousandth of a step early, as the fixed step skips:
                    // a sample still inside is tested again), and at least
                    // the base grid's next sample.
                    let kn = S::ceil((te - t0) * inv_st - S::splat(1e-3));
                    // (A lane a thousandth of a step or less before a
                    // grid point counts as on it.)
                    let k1 = S::floor((t - t0) * inv_st + S::splat(1e-3)) + one;
                    t = S::blend(skip, t, t0 + S::max(kn, k1) * stv);
                    samp = S::but(act, skip);
                    if GROUPED {
                        // The march restarts past the skip: a new group.
                        kc = S::blend(skip, kc, zero);
                        fresh = S::or(fresh, skip);
                    }
                    if S::bits(samp) == 0 {
                        continue;
                    }
                }
            }
            cnt = S::count(cnt, samp);
            let (v, head) = if GROUPED {
                let head = group_heads::<S>(t, kc, th1, th2, three, samp, &mut fresh);
                kc = S::blend(samp, kc, kc + one);
                if S::bits(head) != 0 {
                    cnt_interp = S::count(cnt_interp, head);
                    head_v = S::blend(head, head_v, vol.sample::<T>(p));
                }
                (head_v, head)
            } else {
                (vol.sample::<T>(p), samp)
            };
            let (r, step) = choose.pick(p, t, v, col[3], &rays, steps);
            // `Lut::index`: below 0 (or NaN) nothing.
            let mut valid = S::and(samp, S::ge(v, zero));
            let idx = S::keep_i(valid, S::to_i(S::min(v, one) * top + half));
            let mut qv = S::rows(q, S::sll(idx, 2) + S::mullo(r, rows));
            // A sample whose step reaches the exit stands for the stretch to
            // the last one's end instead (`Segment::t_end`).
            let last = S::and(valid, S::ge(t + step, t_out));
            over_stretch::<S>(&mut qv, last, sigma, idx, t_end - t, inv_unit);
            let [qr, qg, qb, al] = qv;
            let mut e = [zero; 3];
            valid = S::and(valid, S::gt(al, zero));
            if SHADE && GROUPED {
                // Heads are shaded once, from their slot ([`Slots`]): the
                // old heads go to the queue, the new ones take their
                // place; a sample that is not its ray's last adds its
                // weight to its head's slot (the same colour), a last one
                // goes to the queue itself, at its head's position.
                if S::bits(head) != 0 {
                    let out = slot.weighty(head);
                    if S::bits(out) != 0 {
                        queue_slots::<S, T>(&mut dq, &slot, out, &vol, &light, view);
                    }
                    slot.replace(head, p, [qr, qg, qb], al, valid);
                    cnt_shaded = S::count(cnt_shaded, S::and(head, valid));
                }
                let w = we * (one - col[3]);
                let alone = S::and(valid, last);
                slot.w = S::blend(S::but(valid, last), slot.w, slot.w + w);
                if let Some(b) = dq.push(alone, slot.p, w, al, [qr, qg, qb]) {
                    shade_batch::<S, T>(&mut dq, b, &vol, &light, view);
                }
            } else if SHADE {
                if S::bits(valid) != 0 {
                    let w = we * (one - col[3]);
                    if let Some(b) = dq.push(valid, p, w, al, [qr, qg, qb]) {
                        shade_batch::<S, T>(&mut dq, b, &vol, &light, view);
                    }
                    cnt_shaded = S::count(cnt_shaded, valid);
                }
            } else {
                e = [S::keep(valid, qr), S::keep(valid, qg), S::keep(valid, qb)];
            }
            composite::<S>(&mut col, &mut live, valid, e, al, [we, wa], stop);
            t = S::blend(samp, t, t + step);
        }
        if SHADE && GROUPED {
            // The heads still in their slots.
            let out = slot.weighty(S::from_bits(u32::MAX >> (32 - S::N)));
            queue_slots::<S, T>(&mut dq, &slot, out, &vol, &light, view);
        }
        if SHADE {
            drain_deferred::<S, T>(&mut dq, &mut col, &vol, &light, view);
        }
        let interp = if GROUPED { cnt_interp } else { cnt };
        store_lanes::<S>(st, lanes, col, [cnt, cnt_shaded, interp], live);
    }
}
