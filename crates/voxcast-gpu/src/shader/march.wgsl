// Where samples go: the block DDA (render/blocks.rs BlockWalker) and the
// marchers (render/march/mod.rs and steps.rs, render/march/threshold.rs, render/stochastic.rs).

// ------------------------------------------------------------ the block DDA

struct Walker {
    t: f32,
    t_out: f32,
    block: vec3<i32>,
    step: vec3<i32>,
    t_max: vec3<f32>,
    o: vec3<f32>,
    inv_d: vec3<f32>,
};

// BlockWalker's crossing: the far plane of block c along one axis, as
// (plane − o)·(1/d), so a boundary has the same bits from any start.
fn crossing(c: i32, step: i32, b: f32, o: f32, inv_d: f32) -> f32 {
    if step > 0 {
        return (f32(c + 1) * b - o) * inv_d;
    }
    if step < 0 {
        return (f32(c) * b - o) * inv_d;
    }
    return BIG;
}

fn walker_new(o: vec3<f32>, d: vec3<f32>, t_in: f32, t_out: f32) -> Walker {
    var w: Walker;
    let b = f32(P.block_size);
    let p = o + d * t_in;
    w.t = t_in;
    w.t_out = t_out;
    w.o = o;
    w.inv_d = 1.0 / d;
    for (var a = 0; a < 3; a += 1) {
        let n = i32(P.block_counts[a]);
        let q = p[a] / b;
        var c: i32;
        if d[a] < 0.0 {
            c = i32(ceil(q)) - 1;
        } else {
            c = i32(floor(q));
        }
        c = clamp(c, 0, n - 1);
        w.block[a] = c;
        w.step[a] = 0;
        if d[a] > 0.0 {
            w.step[a] = 1;
        } else if d[a] < 0.0 {
            w.step[a] = -1;
        }
        w.t_max[a] = crossing(c, w.step[a], b, o[a], w.inv_d[a]);
    }
    return w;
}

struct Stretch {
    ta: f32,
    tb: f32,
    index: u32,
};

// Iterator::next of BlockWalker; call only while w.t < w.t_out.
fn walker_next(w: ptr<function, Walker>) -> Stretch {
    var a = 2;
    if (*w).t_max.x <= (*w).t_max.y && (*w).t_max.x <= (*w).t_max.z {
        a = 0;
    } else if (*w).t_max.y <= (*w).t_max.z {
        a = 1;
    }
    let t_exit = max(min((*w).t_max[a], (*w).t_out), (*w).t);
    let bl = (*w).block;
    var s: Stretch;
    s.index = u32(bl.x) + P.block_counts.x * (u32(bl.y) + P.block_counts.y * u32(bl.z));
    s.ta = (*w).t;
    s.tb = t_exit;
    (*w).t = t_exit;
    (*w).block[a] += (*w).step[a];
    (*w).t_max[a] = crossing((*w).block[a], (*w).step[a], f32(P.block_size), (*w).o[a], (*w).inv_d[a]);
    if (*w).block[a] < 0 || (*w).block[a] >= i32(P.block_counts[a]) {
        (*w).t = (*w).t_out;
    }
    return s;
}

// ---------------------------------------------------------------- marchers

// ray.rs march_blocks: uniform, jitter and the adaptive marchers.
fn march_blocks(o: vec3<f32>, d: vec3<f32>, t0: f32, t_in: f32, t_out: f32) -> bool {
    var pend = false;
    var pend_t = 0.0;
    var pend_entry = 0;
    var pend_rgb = vec3<f32>(0.0);
    let method = method_code();
    let grouped = has_flag(F_GROUPED);
    let skip = has_flag(F_SKIP);
    let unit = P.unit;
    var w = walker_new(o, d, t_in, t_out);
    // Grouped reuse (steps.rs `RunWalk::next`): the groups of a block go on
    // from the last block's where it continues it (the same level and cap,
    // its first sample the one after the other's last, nothing skipped
    // between: `prev_k1` is NONE after a skip); elsewhere the block's first
    // sample starts a group.
    var last: Eval;
    last.entry = -1;
    let NONE = 0xffffffffu;
    var prev_j = 0;
    var prev_cap = 0u;
    var prev_k1 = NONE;
    loop {
        if w.t >= w.t_out {
            break;
        }
        let st = walker_next(&w);
        let ta = st.ta;
        let tb = st.tb;
        let is_empty = empty[st.index] != 0u;
        var j = 0;
        // steps.rs `Classified`: the cap of grouped reuse in this block.
        var cap = 3u;
        if method == M_ADAPTIVE || method == M_ADAPTIVE_S0 || method == M_ADAPTIVE_MAX {
            if is_empty {
                j = P.level_hi;
            } else if method == M_ADAPTIVE_S0 {
                let tm = 0.5 * (ta + tb);
                let g = gradient(o + d * tm);
                n_interp += 6u;
                let k = max(max(abs(g.x), abs(g.y)), abs(g.z));
                j = level(k, t_out, tm);
            } else if method == M_ADAPTIVE {
                let k = max_grad[st.index];
                if k <= 0.0 {
                    j = P.level_hi;
                } else {
                    let tm = 0.5 * (ta + tb);
                    let x = P.k_ref / (k * t_out / max(tm, 1e-6));
                    j = clamp(i32(round_away(log2(x))), P.level_lo, P.level_hi);
                    // steps.rs `group_cap`: within two coarsest steps.
                    let reach = min(x, exp2(f32(P.level_hi + 1)));
                    cap = u32(clamp(floor(reach / exp2(f32(j))), 1.0, 3.0));
                }
            } else {
                j = level(max_grad[st.index], t_out, 0.5 * (ta + tb));
            }
        }
        if is_empty {
            // A cap no visible block has (the vector walk's 4, the scalar
            // walk's u32::MAX): a group never spans an empty block and a
            // visible one, so skipping changes no pixel.
            cap = 4u;
        }
        let ratio = P.step * exp2(f32(j));
        let s = ratio * unit;
        let n0 = max(ceil((ta - t0) / s), 0.0);
        let n1 = max(ceil((tb - t0) / s), 0.0);
        if n1 <= n0 {
            continue;
        }
        let k0 = u32(n0);
        let k1 = u32(n1);
        let t_first = t0 + n0 * s;
        if pend {
            pend = false;
            let alpha = alpha_for(pend_entry, t_first - pend_t);
            if alpha > 0.0 && add(pend_rgb, alpha) {
                return true;
            }
        }
        if is_empty && skip {
            prev_k1 = NONE;
            continue;
        }
        let goes_on = j == prev_j && cap == prev_cap && k0 == prev_k1;
        prev_j = j;
        prev_cap = cap;
        prev_k1 = k1;
        for (var k = k0; k < k1; k += 1u) {
            let t = t0 + f32(k) * s;
            n_samples += 1u;
            let head = !grouped || (k == k0 && !goes_on) || (k % min(group_size(t, t_out), cap)) == 0u;
            if head {
                last = evaluate(o + d * t);
            }
            if last.entry < 0 {
                continue;
            }
            if k + 1u < k1 {
                let alpha = 1.0 - exp(-last.sigma * ratio);
                if alpha > 0.0 && add(last.rgb, alpha) {
                    return true;
                }
            } else {
                pend = true;
                pend_t = t;
                pend_entry = last.entry;
                pend_rgb = last.rgb;
            }
        }
    }
    if pend {
        // Segment::t_end: the exit moved on by the jitter offset.
        let alpha = alpha_for(pend_entry, max(t_out + (t0 - t_in), pend_t) - pend_t);
        return alpha > 0.0 && add(pend_rgb, alpha);
    }
    return false;
}

// ray.rs march_threshold (Zeng et al. 2018): the step after each sample
// follows the range its (head) value falls in; skipping an empty block
// restarts the march on the base grid t0 + n·step.
fn march_threshold(o: vec3<f32>, d: vec3<f32>, t0: f32, t_in: f32, t_out: f32) -> bool {
    let grouped = has_flag(F_GROUPED);
    let skip = has_flag(F_SKIP);
    let unit = P.unit;
    let step = P.step * unit;
    var t = t0;
    var head_value = 0.0;
    var head = Eval(-1, vec3<f32>(0.0), 0.0);
    var count = 0u;
    var w = walker_new(o, d, t_in, t_out);
    loop {
        if w.t >= w.t_out {
            break;
        }
        let st = walker_next(&w);
        if skip && empty[st.index] != 0u {
            continue;
        }
        if t < st.ta {
            t = t0 + ceil((st.ta - t0) / step) * step;
            count = 0u;
        }
        loop {
            if !(t < st.tb) {
                break;
            }
            n_samples += 1u;
            let is_head = !grouped || (count % group_size(t, t_out)) == 0u;
            count += 1u;
            let p = o + d * t;
            if is_head {
                head_value = sample(p);
                n_interp += 1u;
                head = classify(p, head_value);
            }
            var r_step = P.thresh_step2;
            if head_value < P.thresh_lo {
                r_step = P.thresh_step0;
            } else if head_value < P.thresh_hi {
                r_step = P.thresh_step1;
            }
            let s = r_step * unit;
            if head.entry >= 0 {
                var alpha: f32;
                if t + s < t_out {
                    alpha = 1.0 - exp(-head.sigma * r_step);
                } else {
                    alpha = alpha_for(head.entry, t_out + (t0 - t_in) - t);
                }
                if alpha > 0.0 && add(head.rgb, alpha) {
                    return true;
                }
            }
            t += s;
        }
    }
    return false;
}

fn in_empty_block(p: vec3<f32>) -> bool {
    let b = f32(P.block_size);
    let c = P.block_counts;
    let q = max(p / b, vec3<f32>(0.0));
    let i = min(vec3<u32>(q), c - vec3<u32>(1u));
    return empty[i.x + c.x * (i.y + c.y * i.z)] != 0u;
}

// Composites the sample at p standing for a stretch of `len` (world).
fn mc_sample(p: vec3<f32>, len: f32) -> bool {
    n_samples += 1u;
    let e = evaluate(p);
    if e.entry < 0 {
        return false;
    }
    let alpha = alpha_for(e.entry, len);
    return alpha > 0.0 && add(e.rgb, alpha);
}

// stochastic.rs normal: a standard normal variate (Box–Muller).
fn rng_normal(rng: ptr<function, Rng>) -> f32 {
    let r = sqrt(-2.0 * log(1.0 - rng_uniform(rng)));
    return r * cos(6.2831853 * rng_uniform(rng));
}

// ln(1 + w) to full precision for small w (Goldberg's trick; WGSL has no log1p).
fn log1p_(w: f32) -> f32 {
    let u = 1.0 + w;
    if u == 1.0 {
        return w;
    }
    return log(u) * w / (u - 1.0);
}

// stochastic.rs gamma: Gamma(a) for a ≥ 1 (Marsaglia–Tsang), the same
// draws in the same order; the loop is bounded (a draw is accepted with
// probability > 0.95, so 64 tries all failing never happens in practice).
fn rng_gamma(rng: ptr<function, Rng>, a: f32) -> f32 {
    let d = a - 1.0 / 3.0;
    let c = 1.0 / sqrt(9.0 * d);
    for (var tries = 0u; tries < 64u; tries += 1u) {
        let x = rng_normal(rng);
        let w = c * x;
        if w <= -1.0 {
            continue;
        }
        let v = (1.0 + w) * (1.0 + w) * (1.0 + w);
        let u = 1.0 - rng_uniform(rng);
        let x2 = x * x;
        if u < 1.0 - 0.0331 * x2 * x2
            || log(u) < 0.5 * x2 + d * (3.0 * log1p_(w) - w * (3.0 + w * (3.0 + w))) {
            return d * v;
        }
    }
    return d;
}

// stochastic.rs CHUNK.
const MC_CHUNK: u32 = 32u;

// stochastic.rs uniform_mc: ⌈L/step⌉ sorted uniform positions (S1 eqs. 5–6)
// from exponential spacings, chunk by chunk as SortedUniforms draws them:
// the chunk's spacings are summed, the rest's Gamma drawn, and the
// spacings replayed from the saved generator (no array), so the random
// numbers and the positions are the CPU's.
fn march_mc(o: vec3<f32>, d: vec3<f32>, t_in: f32, t_out: f32, px: vec2<u32>, pass_i: u32) -> bool {
    var rng = rng_for_pixel(px.x, px.y, pass_i);
    let step = P.step * P.unit;
    let len = t_out - t_in;
    let count = u32(max(ceil(len / step), 1.0));
    let w = len / f32(count);
    let skip = has_flag(F_SKIP);
    var left = count;
    var base = 0.0;
    while left > 0u {
        let m = min(left, MC_CHUNK);
        var replay = rng;
        var s = 0.0;
        for (var i = 0u; i < m; i += 1u) {
            s -= log(1.0 - rng_uniform(&rng));
        }
        let rest = left - m + 1u;
        var tail: f32;
        if rest == 1u {
            tail = -log(1.0 - rng_uniform(&rng));
        } else {
            tail = rng_gamma(&rng, f32(rest));
        }
        let scale = (1.0 - base) / (s + tail);
        left -= m;
        var sum = 0.0;
        var u = base;
        for (var i = 0u; i < m; i += 1u) {
            sum -= log(1.0 - rng_uniform(&replay));
            u = base + scale * sum;
            let p = o + d * (t_in + min(u, 1.0 - 1.1920929e-7) * len);
            if skip && in_empty_block(p) {
                continue;
            }
            if mc_sample(p, w) {
                return true;
            }
        }
        base = u;
    }
    return false;
}

// stochastic.rs interval_random: counter-based uniform for interval k.
fn interval_random(key: vec2<u32>, k: u32) -> f32 {
    let z = splitmix(key ^ mul64(vec2<u32>(k, 0u), vec2<u32>(0x6659FD93u, 0xD6E8FEB8u)));
    return f32(z.y >> 8u) / 16777216.0;
}

// stochastic.rs stratified: one uniform position per step interval.
fn march_stratified(o: vec3<f32>, d: vec3<f32>, t_in: f32, t_out: f32, px: vec2<u32>, pass_i: u32) -> bool {
    var rng = rng_for_pixel(px.x, px.y, pass_i);
    let unit = P.unit;
    let s = P.step * unit;
    let klo = rng_next(&rng);
    let khi = rng_next(&rng);
    let key = vec2<u32>(klo, khi);
    let last = u32(max(ceil((t_out - t_in) / s), 1.0)) - 1u;
    let skip = has_flag(F_SKIP);
    var w = walker_new(o, d, t_in, t_out);
    loop {
        if w.t >= w.t_out {
            break;
        }
        let st = walker_next(&w);
        if skip && empty[st.index] != 0u {
            continue;
        }
        let k0 = u32(max(floor((st.ta - t_in) / s), 0.0));
        let k1 = min(u32(max(floor((st.tb - t_in) / s), 0.0)), last);
        for (var k = k0; k <= k1; k += 1u) {
            let a = t_in + f32(k) * s;
            var len = s;
            if k == last {
                len = t_out - a;
            }
            let t = a + interval_random(key, k) * len;
            if t < st.ta || t >= st.tb {
                continue;
            }
            n_samples += 1u;
            let e = evaluate(o + d * t);
            if e.entry < 0 {
                continue;
            }
            var alpha: f32;
            if k == last {
                alpha = alpha_for(e.entry, len);
            } else {
                alpha = 1.0 - exp(-e.sigma * P.step);
            }
            if alpha > 0.0 && add(e.rgb, alpha) {
                return true;
            }
        }
    }
    return false;
}
