// voxcast GPU ray caster: one invocation per pixel, the same computation as
// the CPU renderer (crates/voxcast/src/render/ray.rs, march.rs,
// stochastic.rs): same camera rays, manual trilinear reconstruction of the
// stored values (8 texel loads, clamped like Grid::sample), the same
// transfer-function table, opacity correction, block grid (3D DDA) for
// empty-space skipping, adaptive levels, grouped reuse, early ray
// termination, and the same seeded random sequences (64-bit SplitMix/PCG
// emulated with pairs of u32). Also: opaque boxes and planes (surface.rs,
// geometry/), single scattering (path.rs: delta tracking, ratio-tracked
// shadow rays, the phase functions of phase.rs, the lights of light.rs), and
// volumes split into bricks (one texture per brick, see `Bricking` in lib.rs).

struct Params {
    eye: vec4<f32>,          // xyz eye, w projection (0 perspective, 1 orthographic)
    forward: vec4<f32>,      // w: half_height·aspect
    right: vec4<f32>,        // w: half_height
    up: vec4<f32>,           // w: unused
    origin_w: vec4<f32>,     // xyz volume origin (world), w: unit (smallest spacing)
    inv_spacing: vec4<f32>,  // w: base step in voxels
    box_lo: vec4<f32>,       // w: ert
    box_hi: vec4<f32>,       // w: k_ref
    grid_max: vec4<f32>,     // dims − 1 as floats; w: value scale (texel → normalised)
    background: vec4<f32>,   // linear rgb; w: value offset
    dims: vec4<u32>,         // xyz dims; w: block size
    counts: vec4<u32>,       // xyz block counts; w: method
    size: vec4<u32>,         // width, height, passes, flags
    seed: vec4<u32>,         // seed lo, hi, splitmix(seed) lo, hi
    levels: vec4<i32>,       // level_lo, level_hi, optical model, unused
    geo: vec4<u32>,          // shapes, shadows, lights, phase kind
    surf_dir: vec4<f32>,     // towards the surfaces' key light
    surf_k: vec4<f32>,       // ambient, diffuse, specular, shininess
    med_offset: vec4<f32>,   // medium: world → voxel offset; w: σ_t scale
    med_scale: vec4<f32>,    // medium: world → voxel scale; w: phase g or k
    med_hi: vec4<f32>,       // medium box far corner (voxels); w: global majorant
    med_albedo: vec4<f32>,   // w: 1 global majorant, 0 grid
    med_flags: vec4<u32>,    // has infinite lights
    bricks: vec4<u32>,       // bricks per axis; w: count
    brick_cells: vec4<u32>,  // cells per brick per axis
    chunk: vec4<u32>,        // this dispatch's passes: first, end
    thresh: vec4<f32>,       // threshold: range bounds a, b; steps 0, 1 (voxels)
    thresh2: vec4<f32>,      // threshold: step 2 (voxels)
};

// flags
const F_SHADING: u32 = 1u;
const F_GROUPED: u32 = 2u;
const F_JITTER: u32 = 4u;
const F_SKIP: u32 = 8u;

// methods
const M_UNIFORM: u32 = 0u;
const M_ADAPTIVE: u32 = 1u;
const M_ADAPTIVE_MAX: u32 = 2u;
const M_JITTER: u32 = 3u;
const M_MC: u32 = 4u;
const M_STRATIFIED: u32 = 5u;
const M_SINGLE: u32 = 6u;
const M_THRESHOLD: u32 = 7u;

const LUT_SIZE: u32 = 4096u;
const BIG: f32 = 3.0e38;

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var vol: texture_3d<f32>;
@group(0) @binding(2) var lut: texture_1d<f32>;
@group(0) @binding(3) var<storage, read> empty: array<u32>;
@group(0) @binding(4) var<storage, read> max_grad: array<f32>;
@group(0) @binding(5) var<storage, read_write> out_px: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> out_stats: array<u32>;
@group(0) @binding(7) var<storage, read> records: array<vec4<f32>>;
@group(0) @binding(8) var<storage, read> majorant: array<f32>;
@group(0) @binding(9) var vol1: texture_3d<f32>;
@group(0) @binding(10) var vol2: texture_3d<f32>;
@group(0) @binding(11) var vol3: texture_3d<f32>;
@group(0) @binding(12) var vol4: texture_3d<f32>;
@group(0) @binding(13) var vol5: texture_3d<f32>;
@group(0) @binding(14) var vol6: texture_3d<f32>;
@group(0) @binding(15) var vol7: texture_3d<f32>;

// ---------------------------------------------------------------- 64-bit ints
// (lo, hi) pairs.

fn mul32(a: u32, b: u32) -> vec2<u32> {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let p00 = a0 * b0;
    let p01 = a0 * b1;
    let p10 = a1 * b0;
    let p11 = a1 * b1;
    let mid = (p00 >> 16u) + (p01 & 0xffffu) + (p10 & 0xffffu);
    let lo = (p00 & 0xffffu) | (mid << 16u);
    let hi = p11 + (p01 >> 16u) + (p10 >> 16u) + (mid >> 16u);
    return vec2<u32>(lo, hi);
}

fn mul64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let p = mul32(a.x, b.x);
    return vec2<u32>(p.x, p.y + a.x * b.y + a.y * b.x);
}

fn add64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let lo = a.x + b.x;
    let carry = select(0u, 1u, lo < a.x);
    return vec2<u32>(lo, a.y + b.y + carry);
}

fn shr64(a: vec2<u32>, n: u32) -> vec2<u32> {
    if n == 0u {
        return a;
    }
    if n >= 32u {
        return vec2<u32>(a.y >> (n - 32u), 0u);
    }
    return vec2<u32>((a.x >> n) | (a.y << (32u - n)), a.y >> n);
}

fn shl64(a: vec2<u32>, n: u32) -> vec2<u32> {
    if n == 0u {
        return a;
    }
    if n >= 32u {
        return vec2<u32>(0u, a.x << (n - 32u));
    }
    return vec2<u32>(a.x << n, (a.y << n) | (a.x >> (32u - n)));
}

fn mix64(z0: vec2<u32>) -> vec2<u32> {
    var z = z0;
    z = mul64(z ^ shr64(z, 30u), vec2<u32>(0x1CE4E5B9u, 0xBF58476Du));
    z = mul64(z ^ shr64(z, 27u), vec2<u32>(0x133111EBu, 0x94D049BBu));
    return z ^ shr64(z, 31u);
}

fn splitmix(z: vec2<u32>) -> vec2<u32> {
    return mix64(add64(z, vec2<u32>(0x7F4A7C15u, 0x9E3779B9u)));
}

// march.rs pixel_random: uniform in [0, 1) per seed and pixel.
fn pixel_random(x: u32, y: u32) -> f32 {
    let key = mul64(vec2<u32>(y, x), vec2<u32>(0x7F4A7C15u, 0x9E3779B9u));
    let z = mix64(vec2<u32>(P.seed.x, P.seed.y) ^ key);
    return f32(z.y >> 8u) / 16777216.0;
}

// rng.rs pixel_sequence: the golden-ratio sequence rotated per pixel.
fn pixel_sequence(x: u32, y: u32, pass_i: u32) -> f32 {
    let r = pixel_random(x, y);
    // fract(pass_i·φ⁻¹) with φ⁻¹ split in two parts to keep f32 precision.
    let hi = fract(f32(pass_i) * 0.6180419921875);
    let lo = fract(f32(pass_i) * (0.6180339887498949 - 0.6180419921875));
    let v = fract(r + hi + lo);
    return min(v, 1.0 - 5.9604645e-8);
}

// rng.rs PCG32 (XSH-RR).
struct Rng {
    state: vec2<u32>,
    inc: vec2<u32>,
};

const PCG_MULT: vec2<u32> = vec2<u32>(0x4C957F2Du, 0x5851F42Du);

fn rng_next(r: ptr<function, Rng>) -> u32 {
    let old = (*r).state;
    (*r).state = add64(mul64(old, PCG_MULT), (*r).inc);
    let xs = (shr64(shr64(old, 18u) ^ old, 27u)).x;
    let rot = old.y >> 27u;
    return (xs >> rot) | (xs << ((32u - rot) & 31u));
}

fn rng_for_pixel(x: u32, y: u32, pass_i: u32) -> Rng {
    let stream = vec2<u32>(x | (y << 16u), pass_i);
    var r: Rng;
    r.state = vec2<u32>(0u, 0u);
    r.inc = shl64(splitmix(stream), 1u) | vec2<u32>(1u, 0u);
    rng_next(&r);
    r.state = add64(r.state, vec2<u32>(P.seed.z, P.seed.w));
    rng_next(&r);
    return r;
}

fn rng_uniform(r: ptr<function, Rng>) -> f32 {
    return f32(rng_next(r) >> 8u) * (1.0 / 16777216.0);
}

// --------------------------------------------------------------- the volume

// Voxel i of the brick in texture slot `slot`.
fn texel(slot: u32, i: vec3<i32>) -> f32 {
    switch slot {
        case 0u: { return textureLoad(vol, i, 0).x; }
        case 1u: { return textureLoad(vol1, i, 0).x; }
        case 2u: { return textureLoad(vol2, i, 0).x; }
        case 3u: { return textureLoad(vol3, i, 0).x; }
        case 4u: { return textureLoad(vol4, i, 0).x; }
        case 5u: { return textureLoad(vol5, i, 0).x; }
        case 6u: { return textureLoad(vol6, i, 0).x; }
        default: { return textureLoad(vol7, i, 0).x; }
    }
}

// Whether the volume is split into bricks: a pipeline constant, so an
// unbricked volume's shader has no slot switch in its texel loads (on a SIMD
// software rasteriser such as lavapipe the switch costs ~8× per sample).
override BRICKED: bool = true;

// Grid::sample: trilinear, coordinates clamped to the grid.
fn sample(p0: vec3<f32>) -> f32 {
    let p = min(max(p0, vec3<f32>(0.0)), P.grid_max.xyz);
    let dims = vec3<i32>(P.dims.xyz);
    let last = max(dims - vec3<i32>(2), vec3<i32>(0));
    let i = min(vec3<i32>(p), last);
    let f = p - vec3<f32>(i);
    let j0 = min(i + vec3<i32>(1), dims - vec3<i32>(1));
    // The brick owning the cell holds all eight voxels (bricks share a plane).
    var slot = 0u;
    var org = vec3<i32>(0);
    if BRICKED && P.bricks.w > 1u {
        let b = min(vec3<u32>(i) / P.brick_cells.xyz, P.bricks.xyz - vec3<u32>(1u));
        slot = b.x + P.bricks.x * (b.y + P.bricks.y * b.z);
        org = vec3<i32>(b * P.brick_cells.xyz);
    }
    let a = i - org;
    let j = j0 - org;
    if !BRICKED {
        let d000 = textureLoad(vol, vec3<i32>(a.x, a.y, a.z), 0).x;
        let d100 = textureLoad(vol, vec3<i32>(j.x, a.y, a.z), 0).x;
        let d010 = textureLoad(vol, vec3<i32>(a.x, j.y, a.z), 0).x;
        let d110 = textureLoad(vol, vec3<i32>(j.x, j.y, a.z), 0).x;
        let d001 = textureLoad(vol, vec3<i32>(a.x, a.y, j.z), 0).x;
        let d101 = textureLoad(vol, vec3<i32>(j.x, a.y, j.z), 0).x;
        let d011 = textureLoad(vol, vec3<i32>(a.x, j.y, j.z), 0).x;
        let d111 = textureLoad(vol, vec3<i32>(j.x, j.y, j.z), 0).x;
        let e00 = d000 + (d100 - d000) * f.x;
        let e10 = d010 + (d110 - d010) * f.x;
        let e01 = d001 + (d101 - d001) * f.x;
        let e11 = d011 + (d111 - d011) * f.x;
        let e0 = e00 + (e10 - e00) * f.y;
        let e1 = e01 + (e11 - e01) * f.y;
        return (e0 + (e1 - e0) * f.z) * P.grid_max.w + P.background.w;
    }
    let c000 = texel(slot, vec3<i32>(a.x, a.y, a.z));
    let c100 = texel(slot, vec3<i32>(j.x, a.y, a.z));
    let c010 = texel(slot, vec3<i32>(a.x, j.y, a.z));
    let c110 = texel(slot, vec3<i32>(j.x, j.y, a.z));
    let c001 = texel(slot, vec3<i32>(a.x, a.y, j.z));
    let c101 = texel(slot, vec3<i32>(j.x, a.y, j.z));
    let c011 = texel(slot, vec3<i32>(a.x, j.y, j.z));
    let c111 = texel(slot, vec3<i32>(j.x, j.y, j.z));
    let c00 = c000 + (c100 - c000) * f.x;
    let c10 = c010 + (c110 - c010) * f.x;
    let c01 = c001 + (c101 - c001) * f.x;
    let c11 = c011 + (c111 - c011) * f.x;
    let c0 = c00 + (c10 - c00) * f.y;
    let c1 = c01 + (c11 - c01) * f.y;
    return (c0 + (c1 - c0) * f.z) * P.grid_max.w + P.background.w;
}

fn gradient(p: vec3<f32>) -> vec3<f32> {
    let gx = sample(p + vec3<f32>(1.0, 0.0, 0.0)) - sample(p - vec3<f32>(1.0, 0.0, 0.0));
    let gy = sample(p + vec3<f32>(0.0, 1.0, 0.0)) - sample(p - vec3<f32>(0.0, 1.0, 0.0));
    let gz = sample(p + vec3<f32>(0.0, 0.0, 1.0)) - sample(p - vec3<f32>(0.0, 0.0, 1.0));
    return vec3<f32>(gx, gy, gz) * 0.5;
}

// ------------------------------------------------------------- per-ray state

var<private> acc_c: vec3<f32>;
var<private> acc_a: f32;
var<private> n_samples: u32;
var<private> n_interp: u32;
var<private> n_shaded: u32;
var<private> view: vec3<f32>;

// Lut::index: −1 for transparent-below-domain values.
fn lut_index(v: f32) -> i32 {
    if v >= 0.0 {
        return i32(min(v, 1.0) * f32(LUT_SIZE - 1u) + 0.5);
    }
    return -1;
}

fn lut_entry(i: i32) -> vec4<f32> {
    return textureLoad(lut, i, 0);
}

// BlinnPhong::shade with the default weights and a headlight.
fn shade(rgb: vec3<f32>, g: vec3<f32>) -> vec3<f32> {
    if dot(g, g) < 1e-6 {
        return rgb;
    }
    let n = normalize(g * P.inv_spacing.xyz);
    let ndl = abs(dot(n, view));
    let spec = pow(ndl, 24.0);
    return min(rgb * (0.25 + 0.75 * ndl) + vec3<f32>(0.25 * spec), vec3<f32>(1.0));
}

struct Eval {
    entry: i32,   // −1: transparent
    rgb: vec3<f32>,
};

// ray.rs evaluate: reconstruct, classify, shade.
fn evaluate(p: vec3<f32>) -> Eval {
    let v = sample(p);
    n_interp += 1u;
    return classify(p, v);
}

// Classifies and shades the reconstructed value v at p.
fn classify(p: vec3<f32>, v: f32) -> Eval {
    var e: Eval;
    e.entry = -1;
    let i = lut_index(v);
    if i < 0 {
        return e;
    }
    let t = lut_entry(i);
    if t.w <= 0.0 {
        return e;
    }
    var rgb = t.xyz;
    if (P.size.w & F_SHADING) != 0u {
        rgb = shade(rgb, gradient(p));
        n_shaded += 1u;
    }
    e.entry = i;
    e.rgb = rgb;
    return e;
}

// Acc::add, front to back; true when the ray may stop.
fn add(rgb: vec3<f32>, alpha: f32) -> bool {
    var em = rgb * alpha;
    var ab = alpha;
    let model = P.levels.z;
    if model == 0 {
        em = vec3<f32>(0.0);
    } else if model == 1 {
        ab = 0.0;
    }
    let t = 1.0 - acc_a;
    acc_c += em * t;
    acc_a += ab * t;
    let ert = P.box_lo.w;
    return acc_a >= ert && ert < 1.0;
}

fn alpha_for(entry: i32, len_world: f32) -> f32 {
    return 1.0 - exp(-lut_entry(entry).w * len_world / P.origin_w.w);
}

fn round_away(x: f32) -> f32 {
    return sign(x) * floor(abs(x) + 0.5);
}

fn group_size(t: f32, t_exit: f32) -> u32 {
    if t <= t_exit / 3.0 {
        return 1u;
    }
    if t <= t_exit * (2.0 / 3.0) {
        return 2u;
    }
    return 3u;
}

fn level(k: f32, t_out: f32, tm: f32) -> i32 {
    let f = k * t_out / max(tm, 1e-6);
    if f > 0.0 {
        return clamp(i32(round_away(log2(P.box_hi.w / f))), P.levels.x, P.levels.y);
    }
    return P.levels.y;
}

fn safe_inv(d: f32) -> f32 {
    if d == 0.0 {
        return BIG;
    }
    return 1.0 / d;
}

// ------------------------------------------------------------ the block DDA

struct Walker {
    t: f32,
    t_out: f32,
    block: vec3<i32>,
    step: vec3<i32>,
    t_max: vec3<f32>,
    t_delta: vec3<f32>,
};

fn walker_new(o: vec3<f32>, d: vec3<f32>, t_in: f32, t_out: f32) -> Walker {
    var w: Walker;
    let b = f32(P.dims.w);
    let p = o + d * t_in;
    w.t = t_in;
    w.t_out = t_out;
    for (var a = 0; a < 3; a += 1) {
        let n = i32(P.counts[a]);
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
        w.t_max[a] = BIG;
        w.t_delta[a] = BIG;
        if d[a] > 0.0 {
            w.step[a] = 1;
            w.t_max[a] = (f32(c + 1) * b - o[a]) / d[a];
            w.t_delta[a] = b / d[a];
        } else if d[a] < 0.0 {
            w.step[a] = -1;
            w.t_max[a] = (f32(c) * b - o[a]) / d[a];
            w.t_delta[a] = -b / d[a];
        }
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
    s.index = u32(bl.x) + P.counts.x * (u32(bl.y) + P.counts.y * u32(bl.z));
    s.ta = (*w).t;
    s.tb = t_exit;
    (*w).t = t_exit;
    (*w).t_max[a] += (*w).t_delta[a];
    (*w).block[a] += (*w).step[a];
    if (*w).block[a] < 0 || (*w).block[a] >= i32(P.counts[a]) {
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
    let method = P.counts.w;
    let grouped = (P.size.w & F_GROUPED) != 0u;
    let skip = (P.size.w & F_SKIP) != 0u;
    let unit = P.origin_w.w;
    var w = walker_new(o, d, t_in, t_out);
    loop {
        if w.t >= w.t_out {
            break;
        }
        let st = walker_next(&w);
        let ta = st.ta;
        let tb = st.tb;
        let is_empty = empty[st.index] != 0u;
        var j = 0;
        if method == M_ADAPTIVE || method == M_ADAPTIVE_MAX {
            if is_empty {
                j = P.levels.y;
            } else if method == M_ADAPTIVE {
                let tm = 0.5 * (ta + tb);
                let g = gradient(o + d * tm);
                n_interp += 6u;
                let k = max(max(abs(g.x), abs(g.y)), abs(g.z));
                j = level(k, t_out, tm);
            } else {
                j = level(max_grad[st.index], t_out, 0.5 * (ta + tb));
            }
        }
        let ratio = P.inv_spacing.w * exp2(f32(j));
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
            continue;
        }
        var last: Eval;
        last.entry = -1;
        for (var k = k0; k < k1; k += 1u) {
            let t = t0 + f32(k) * s;
            n_samples += 1u;
            let head = !grouped || k == k0 || (k % group_size(t, t_out)) == 0u;
            if head {
                last = evaluate(o + d * t);
            }
            if last.entry < 0 {
                continue;
            }
            if k + 1u < k1 {
                let alpha = 1.0 - exp(-lut_entry(last.entry).w * ratio);
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
        let alpha = alpha_for(pend_entry, max(t_out, pend_t) - pend_t);
        return alpha > 0.0 && add(pend_rgb, alpha);
    }
    return false;
}

// ray.rs march_threshold (Zeng et al. 2018): the step after each sample
// follows the range its (head) value falls in; skipping an empty block
// restarts the march on the base grid t0 + n·step.
fn march_threshold(o: vec3<f32>, d: vec3<f32>, t0: f32, t_in: f32, t_out: f32) -> bool {
    let grouped = (P.size.w & F_GROUPED) != 0u;
    let skip = (P.size.w & F_SKIP) != 0u;
    let unit = P.origin_w.w;
    let step = P.inv_spacing.w * unit;
    var t = t0;
    var head_value = 0.0;
    var head = Eval(-1, vec3<f32>(0.0));
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
            var r_step = P.thresh2.x;
            if head_value < P.thresh.x {
                r_step = P.thresh.z;
            } else if head_value < P.thresh.y {
                r_step = P.thresh.w;
            }
            let s = r_step * unit;
            if head.entry >= 0 {
                var alpha: f32;
                if t + s <= t_out {
                    alpha = 1.0 - exp(-lut_entry(head.entry).w * r_step);
                } else {
                    alpha = alpha_for(head.entry, t_out - t);
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
    let b = f32(P.dims.w);
    let c = P.counts.xyz;
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

// stochastic.rs uniform_mc: ⌈L/step⌉ sorted uniform positions (S1 eqs. 5–6).
fn march_mc(o: vec3<f32>, d: vec3<f32>, t_in: f32, t_out: f32, px: vec2<u32>, pass_i: u32) -> bool {
    var rng = rng_for_pixel(px.x, px.y, pass_i);
    let step = P.inv_spacing.w * P.origin_w.w;
    let len = t_out - t_in;
    let count = u32(max(ceil(len / step), 1.0));
    let w = len / f32(count);
    let skip = (P.size.w & F_SKIP) != 0u;
    var cur = 1.0;
    for (var left = count; left > 0u; left -= 1u) {
        cur *= pow(1.0 - rng_uniform(&rng), 1.0 / f32(left));
        let u = clamp(1.0 - cur, 0.0, 1.0 - 1.1920929e-7);
        let p = o + d * (t_in + u * len);
        if skip && in_empty_block(p) {
            continue;
        }
        if mc_sample(p, w) {
            return true;
        }
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
    let unit = P.origin_w.w;
    let s = P.inv_spacing.w * unit;
    let klo = rng_next(&rng);
    let khi = rng_next(&rng);
    let key = vec2<u32>(klo, khi);
    let last = u32(max(ceil((t_out - t_in) / s), 1.0)) - 1u;
    let skip = (P.size.w & F_SKIP) != 0u;
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
                alpha = 1.0 - exp(-lut_entry(e.entry).w * P.inv_spacing.w);
            }
            if alpha > 0.0 && add(e.rgb, alpha) {
                return true;
            }
        }
    }
    return false;
}

// ------------------------------------------------------- opaque geometry

fn box_intersect(o: vec3<f32>, inv_d: vec3<f32>, lo: vec3<f32>, hi: vec3<f32>) -> vec2<f32> {
    let t0 = (lo - o) * inv_d;
    let t1 = (hi - o) * inv_d;
    let tmin = min(t0, t1);
    let tmax = max(t0, t1);
    let enter = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    let exit = min(min(tmax.x, tmax.y), tmax.z);
    return vec2<f32>(enter, exit);
}

fn inv3(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(safe_inv(d.x), safe_inv(d.y), safe_inv(d.z));
}

struct Hit {
    ok: bool,
    t: f32,
    normal: vec3<f32>,
    albedo: vec3<f32>,
};

// shapes.rs Aabb::hit / Plane::hit for shape record `s`: (t, normal) in
// x and yzw, t < 0 for a miss.
fn shape_hit(s: u32, o: vec3<f32>, d: vec3<f32>, t_min: f32, t_max: f32) -> vec4<f32> {
    let base = s * 6u;
    let head = records[base];
    let miss = vec4<f32>(-1.0, 0.0, 0.0, 0.0);
    if head.x == 0.0 {
        let inv_d = inv3(d);
        let t0 = (records[base + 1u].xyz - o) * inv_d;
        let t1 = (records[base + 2u].xyz - o) * inv_d;
        let lo = min(t0, t1);
        let hi = max(t0, t1);
        let near = max(lo.x, max(lo.y, lo.z));
        let far = min(hi.x, min(hi.y, hi.z));
        if near > far {
            return miss;
        }
        var t: f32;
        var v: vec3<f32>;
        if near > t_min {
            t = near;
            v = lo;
        } else if far > t_min {
            t = far;
            v = hi;
        } else {
            return miss;
        }
        if t >= t_max {
            return miss;
        }
        var n = vec3<f32>(0.0);
        var axis = 2;
        if v.x == t {
            axis = 0;
        } else if v.y == t {
            axis = 1;
        }
        n[axis] = select(1.0, -1.0, d[axis] > 0.0);
        return vec4<f32>(t, n);
    }
    let point = records[base + 1u].xyz;
    let normal = records[base + 2u].xyz;
    let den = dot(normal, d);
    if den >= 0.0 {
        return miss;
    }
    let t = dot(normal, point - o) / den;
    if !(t > t_min && t < t_max) {
        return miss;
    }
    if head.x == 1.0 {
        let q = o + d * t - point;
        if abs(dot(q, records[base + 3u].xyz)) > head.y || abs(dot(q, records[base + 4u].xyz)) > head.z {
            return miss;
        }
    }
    return vec4<f32>(t, normal);
}

// Geometry::hit: the nearest shape (bounded ones first, then the infinite
// planes, each tested only closer than the best so far).
fn geometry_hit(o: vec3<f32>, d: vec3<f32>) -> Hit {
    var h: Hit;
    h.ok = false;
    h.t = BIG;
    for (var s = 0u; s < P.geo.x; s += 1u) {
        let r = shape_hit(s, o, d, 0.0, h.t);
        if r.x > 0.0 {
            h.ok = true;
            h.t = r.x;
            h.normal = r.yzw;
            h.albedo = records[s * 6u + 5u].xyz;
        }
    }
    return h;
}

fn occluded(o: vec3<f32>, d: vec3<f32>) -> bool {
    for (var s = 0u; s < P.geo.x; s += 1u) {
        if shape_hit(s, o, d, 0.0, BIG).x >= 0.0 {
            return true;
        }
    }
    return false;
}

// surface.rs transmittance: midpoint sums of the extinction at the base step
// from world point p along unit l to the volume's edge.
fn surface_transmittance(p: vec3<f32>, l: vec3<f32>) -> f32 {
    let o = (p - P.origin_w.xyz) * P.inv_spacing.xyz;
    let d = l * P.inv_spacing.xyz;
    let te = box_intersect(o, inv3(d), P.box_lo.xyz, P.box_hi.xyz);
    if !(te.y > te.x) {
        return 1.0;
    }
    let step = P.inv_spacing.w * P.origin_w.w;
    let n = max(ceil((te.y - te.x) / step), 1.0);
    let ds = (te.y - te.x) / n;
    var tau = 0.0;
    let count = u32(n);
    for (var k = 0u; k < count; k += 1u) {
        let i = lut_index(sample(o + d * (te.x + (f32(k) + 0.5) * ds)));
        if i >= 0 {
            tau += lut_entry(i).w;
        }
    }
    n_interp += count;
    return exp(-tau * ds / P.origin_w.w);
}

fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let len = length(v);
    if len > 0.0 {
        return v * (1.0 / len);
    }
    return vec3<f32>(0.0);
}

// surface.rs shade + SurfaceLight::shade: the lit linear colour of the hit.
fn surface_colour(origin: vec3<f32>, dir: vec3<f32>, h: Hit) -> vec3<f32> {
    let to_light = P.surf_dir.xyz;
    var light = 1.0;
    if P.geo.y != 0u {
        var facing = h.normal;
        if dot(h.normal, dir) > 0.0 {
            facing = -h.normal;
        }
        if dot(facing, to_light) > 0.0 {
            let p = origin + dir * h.t + facing * (1e-3 * P.origin_w.w);
            if occluded(p, to_light) {
                light = 0.0;
            } else {
                light = surface_transmittance(p, to_light);
            }
        }
    }
    var n = h.normal;
    if dot(n, dir) > 0.0 {
        n = -n;
    }
    let k = P.surf_k;
    let ndl = dot(n, to_light);
    if ndl <= 0.0 {
        return h.albedo * k.x;
    }
    let hv = normalize_or_zero(to_light - dir);
    let c = max(dot(n, hv), 0.0);
    var spec = 0.0;
    if c > 0.0 {
        spec = pow(c, k.w);
    }
    return min(h.albedo * (k.x + k.y * ndl * light) + vec3<f32>(k.z * spec * light), vec3<f32>(1.0));
}

// ------------------------------------------------------ single scattering

const PI: f32 = 3.14159265358979323846;
const INV_4PI: f32 = 0.079577471545947667884;

fn phase_eval(c: f32) -> f32 {
    let kind = P.geo.w;
    let g = P.med_scale.w;
    if kind == 1u {
        let d = max(1.0 + g * g - 2.0 * g * c, 1e-12);
        return INV_4PI * (1.0 - g * g) / (d * sqrt(d));
    } else if kind == 2u {
        let d = max(1.0 - g * c, 1e-12);
        return INV_4PI * (1.0 - g * g) / (d * d);
    } else if kind == 3u {
        return 3.0 / (16.0 * PI) * (1.0 + c * c);
    } else if kind == 4u {
        let d = max(1.0 + g * g - 2.0 * g * c, 1e-12);
        return 3.0 / (8.0 * PI) * (1.0 - g * g) * (1.0 + c * c) / ((2.0 + g * g) * d * sqrt(d));
    }
    return INV_4PI;
}

fn hg_sample_cos(g: f32, rng: ptr<function, Rng>) -> f32 {
    let u = rng_uniform(rng);
    if abs(g) < 1e-3 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    return (1.0 + g * g - s * s) / (2.0 * g);
}

fn cube_root(x: f32) -> f32 {
    if x == 0.0 {
        return 0.0;
    }
    return sign(x) * pow(abs(x), 1.0 / 3.0);
}

fn phase_sample_cos(rng: ptr<function, Rng>) -> f32 {
    let kind = P.geo.w;
    let g = P.med_scale.w;
    if kind == 1u {
        return hg_sample_cos(g, rng);
    } else if kind == 2u {
        let u = rng_uniform(rng);
        if abs(g) < 1e-4 {
            return 1.0 - 2.0 * u;
        }
        return (1.0 - (1.0 - g * g) / (2.0 * g * u + 1.0 - g)) / g;
    } else if kind == 3u {
        let q = 4.0 - 8.0 * rng_uniform(rng);
        let s = sqrt(q * q * 0.25 + 1.0);
        return cube_root(-q * 0.5 + s) + cube_root(-q * 0.5 - s);
    } else if kind == 4u {
        loop {
            let c = clamp(hg_sample_cos(g, rng), -1.0, 1.0);
            if 2.0 * rng_uniform(rng) <= 1.0 + c * c {
                return c;
            }
        }
    }
    return 1.0 - 2.0 * rng_uniform(rng);
}

fn normalize_exact(v: vec3<f32>) -> vec3<f32> {
    return v * (1.0 / sqrt(dot(v, v)));
}

// phase.rs from_frame with glam's any_orthonormal_pair (Duff et al. 2017).
fn from_frame(axis: vec3<f32>, c: f32, phi: f32) -> vec3<f32> {
    let sin_t = sqrt(max(1.0 - c * c, 0.0));
    let sgn = select(1.0, -1.0, (bitcast<u32>(axis.z) & 0x80000000u) != 0u);
    let a = -1.0 / (sgn + axis.z);
    let b = axis.x * axis.y * a;
    let t = vec3<f32>(1.0 + sgn * axis.x * axis.x * a, sgn * b, -sgn * axis.x);
    let bb = vec3<f32>(b, sgn + axis.y * axis.y * a, -axis.y);
    return normalize_exact(t * (sin_t * cos(phi)) + bb * (sin_t * sin(phi)) + axis * c);
}

// light.rs environment: radiance of the infinite lights from direction d.
fn environment(d: vec3<f32>) -> vec3<f32> {
    var l = vec3<f32>(0.0);
    let base = P.geo.x * 6u;
    for (var i = 0u; i < P.geo.z; i += 1u) {
        let r = base + i * 4u;
        let kind = records[r].x;
        if kind == 2.0 {
            l += records[r + 1u].xyz;
        } else if kind == 3.0 {
            if d.z >= 0.0 {
                l += records[r + 2u].xyz * (1.0 - d.z) + records[r + 1u].xyz * d.z;
            } else {
                l += records[r + 3u].xyz;
            }
        }
    }
    return l;
}

struct Medium {
    ok: bool,
    o: vec3<f32>,
    d: vec3<f32>,
    a: f32,
    b: f32,
};

// MediumCtx::enter: the world ray in voxel coordinates and its stretch in
// the medium's box.
fn medium_enter(o: vec3<f32>, d: vec3<f32>, t_max: f32) -> Medium {
    var m: Medium;
    m.o = (o - P.med_offset.xyz) * P.med_scale.xyz;
    m.d = d * P.med_scale.xyz;
    let te = box_intersect(m.o, inv3(m.d), vec3<f32>(0.0), P.med_hi.xyz);
    m.a = te.x;
    m.b = min(te.y, t_max);
    m.ok = te.y > te.x && m.b > m.a;
    return m;
}

var<private> trk_tr: f32;
var<private> trk_t: f32;

// One majorant segment of Majorant::walk with the tracker's callback:
// delta tracking (ratio = false; the collision in trk_t) or ratio tracking
// (the transmittance in trk_tr). True when the tracker stops.
fn segment(m: Medium, ta: f32, tb: f32, s: f32, ratio: bool, rng: ptr<function, Rng>) -> bool {
    if s <= 0.0 {
        return false;
    }
    var t = ta;
    loop {
        t -= log(1.0 - rng_uniform(rng)) / s;
        if t >= tb {
            return false;
        }
        n_samples += 1u;
        n_interp += 1u;
        let sigma = P.med_offset.w * clamp(sample(m.o + m.d * t), 0.0, 1.0);
        if ratio {
            trk_tr *= 1.0 - sigma / s;
            if trk_tr < 0.1 {
                if rng_uniform(rng) < 0.5 {
                    trk_tr = 0.0;
                    return true;
                }
                trk_tr *= 2.0;
            }
        } else if rng_uniform(rng) * s < sigma {
            trk_t = t;
            return true;
        }
    }
    return false;
}

// delta_track / ratio_track on the world ray o + d·t, t ≤ t_max.
fn track(o: vec3<f32>, d: vec3<f32>, t_max: f32, ratio: bool, rng: ptr<function, Rng>) -> bool {
    trk_tr = 1.0;
    trk_t = -1.0;
    let m = medium_enter(o, d, t_max);
    if !m.ok {
        return false;
    }
    if P.med_albedo.w != 0.0 {
        return segment(m, m.a, m.b, P.med_hi.w, ratio, rng);
    }
    var w = walker_new(m.o, m.d, m.a, m.b);
    loop {
        if w.t >= w.t_out {
            break;
        }
        let st = walker_next(&w);
        if segment(m, st.ta, st.tb, majorant[st.index], ratio, rng) {
            return true;
        }
    }
    return false;
}

// path.rs Integrator::li with `single`: one real collision by delta
// tracking, next-event estimation to the delta lights, one phase-sampled
// shadow ray for the infinite lights.
fn li_single(o: vec3<f32>, d: vec3<f32>, rng: ptr<function, Rng>) -> vec3<f32> {
    if !track(o, d, BIG, false, rng) {
        return environment(d);
    }
    let p = o + d * trk_t;
    let beta = P.med_albedo.xyz;
    var l = vec3<f32>(0.0);
    let base = P.geo.x * 6u;
    for (var i = 0u; i < P.geo.z; i += 1u) {
        let r = base + i * 4u;
        let kind = records[r].x;
        var dir: vec3<f32>;
        var dist: f32;
        var li: vec3<f32>;
        if kind == 0.0 {
            dir = records[r + 1u].xyz;
            dist = BIG;
            li = records[r + 2u].xyz;
        } else if kind == 1.0 {
            let v = records[r + 1u].xyz - p;
            let r2 = max(dot(v, v), 1e-12);
            dist = sqrt(r2);
            dir = v / dist;
            li = records[r + 2u].xyz / r2;
        } else {
            continue;
        }
        let ph = phase_eval(dot(d, dir));
        if ph > 0.0 && max(li.x, max(li.y, li.z)) > 0.0 {
            track(p, dir, dist, true, rng);
            l += beta * li * (ph * trk_tr);
        }
    }
    let c = clamp(phase_sample_cos(rng), -1.0, 1.0);
    let phi = 2.0 * PI * rng_uniform(rng);
    let nd = from_frame(d, c, phi);
    let pdf = phase_eval(c);
    var weight = 0.0;
    if pdf > 0.0 {
        weight = phase_eval(dot(d, nd)) / pdf;
    }
    if P.med_flags.x != 0u {
        track(p, nd, BIG, true, rng);
        l += beta * environment(nd) * (weight * trk_tr);
    }
    return l;
}

// Camera::ray_at (world origin and unit direction) through (px, py).
struct CamRay {
    o: vec3<f32>,
    d: vec3<f32>,
};

fn camera_ray(px: f32, py: f32) -> CamRay {
    let width = f32(P.size.x);
    let height = f32(P.size.y);
    let sx = (2.0 * px / width - 1.0) * P.forward.w;
    let sy = (1.0 - 2.0 * py / height) * P.right.w;
    var r: CamRay;
    r.o = P.eye.xyz;
    r.d = P.forward.xyz;
    if P.eye.w == 0.0 {
        r.d = normalize(P.forward.xyz + P.right.xyz * sx + P.up.xyz * sy);
    } else {
        r.o = P.eye.xyz + P.right.xyz * sx + P.up.xyz * sy;
    }
    return r;
}

// ------------------------------------------------------------------- entry

var<workgroup> wg_stats: array<atomic<u32>, 6>;

fn intersect_box(o: vec3<f32>, inv_d: vec3<f32>) -> vec2<f32> {
    let t0 = (P.box_lo.xyz - o) * inv_d;
    let t1 = (P.box_hi.xyz - o) * inv_d;
    let tmin = min(t0, t1);
    let tmax = max(t0, t1);
    let enter = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    let exit = min(min(tmax.x, tmax.y), tmax.z);
    return vec2<f32>(enter, exit);
}

@compute @workgroup_size(8, 8, 1)
fn main(
    @builtin(global_invocation_id) gid: vec3<u32>,
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
) {
    if lid < 6u {
        atomicStore(&wg_stats[lid], 0u);
    }
    workgroupBarrier();
    let width = P.size.x;
    let height = P.size.y;
    // This dispatch renders passes first…end − 1 of P.size.z, adding to the
    // sums the dispatches before it left in out_px (the host divides).
    let first = P.chunk.x;
    let end = P.chunk.y;
    let passes = end - first;
    let method = P.counts.w;
    let idx = gid.y * width + gid.x;
    var rays = 0u;
    var hits = 0u;
    var terminated = 0u;
    n_samples = 0u;
    n_interp = 0u;
    n_shaded = 0u;
    if gid.x < width && gid.y < height && method == M_SINGLE {
        // path.rs render: spp camera rays with a random position in the pixel.
        var sum = vec3<f32>(0.0);
        if first > 0u {
            sum = out_px[idx].xyz;
        }
        for (var pass_i = first; pass_i < end; pass_i += 1u) {
            var rng = rng_for_pixel(gid.x, gid.y, pass_i);
            let u = rng_uniform(&rng);
            let v = rng_uniform(&rng);
            let r = camera_ray(f32(gid.x) + u, f32(gid.y) + v);
            if medium_enter(r.o, r.d, BIG).ok {
                hits += 1u;
            }
            sum += li_single(r.o, r.d, &rng);
        }
        rays = passes;
        out_px[idx] = vec4<f32>(sum, 1.0);
    } else if gid.x < width && gid.y < height {
        // Camera::ray_at through the pixel centre.
        let r = camera_ray(f32(gid.x) + 0.5, f32(gid.y) + 0.5);
        let origin = r.o;
        let dir = r.d;
        view = -dir;
        let o = (origin - P.origin_w.xyz) * P.inv_spacing.xyz;
        let d = dir * P.inv_spacing.xyz;
        let inv_d = inv3(d);
        var te = intersect_box(o, inv_d);
        // The first opaque surface ends the ray (surface.rs).
        var hit: Hit;
        hit.ok = false;
        var surf = vec3<f32>(0.0);
        if P.geo.x > 0u {
            hit = geometry_hit(origin, dir);
            if hit.ok {
                // The same every pass; the CPU shades (and counts) per pass.
                let before = n_interp;
                surf = surface_colour(origin, dir, hit);
                n_interp = before + (n_interp - before) * passes;
            }
        }
        var sum = vec4<f32>(0.0);
        if first > 0u {
            sum = out_px[idx];
        }
        rays = passes;
        if te.y > te.x && !(hit.ok && hit.t <= te.x) {
            if hit.ok {
                te.y = min(te.y, hit.t);
            }
            hits = passes;
            let step = P.inv_spacing.w * P.origin_w.w;
            for (var pass_i = first; pass_i < end; pass_i += 1u) {
                acc_c = vec3<f32>(0.0);
                acc_a = 0.0;
                var t0 = te.x;
                if (P.size.w & F_JITTER) != 0u {
                    t0 = te.x + pixel_sequence(gid.x, gid.y, pass_i) * step;
                }
                var stop = false;
                if method == M_MC {
                    stop = march_mc(o, d, te.x, te.y, gid.xy, pass_i);
                } else if method == M_STRATIFIED {
                    stop = march_stratified(o, d, te.x, te.y, gid.xy, pass_i);
                } else if method == M_THRESHOLD {
                    stop = march_threshold(o, d, t0, te.x, te.y);
                } else {
                    stop = march_blocks(o, d, t0, te.x, te.y);
                }
                if stop {
                    terminated += 1u;
                }
                if hit.ok {
                    // Acc::finish: the surface behind, opaque.
                    let t = 1.0 - acc_a;
                    acc_c += surf * t;
                    acc_a += t;
                }
                sum += vec4<f32>(acc_c, acc_a);
            }
        } else if hit.ok {
            for (var pass_i = first; pass_i < end; pass_i += 1u) {
                sum += vec4<f32>(surf, 1.0);
            }
        }
        out_px[idx] = sum;
    }
    atomicAdd(&wg_stats[0], rays);
    atomicAdd(&wg_stats[1], hits);
    atomicAdd(&wg_stats[2], n_samples);
    atomicAdd(&wg_stats[3], n_interp);
    atomicAdd(&wg_stats[4], n_shaded);
    atomicAdd(&wg_stats[5], terminated);
    workgroupBarrier();
    if lid < 6u {
        let wg = wid.y * nwg.x + wid.x;
        let v = atomicLoad(&wg_stats[lid]);
        if first > 0u {
            out_stats[wg * 6u + lid] += v;
        } else {
            out_stats[wg * 6u + lid] = v;
        }
    }
}
