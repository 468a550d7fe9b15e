// The volume and one sample: trilinear reconstruction across bricks
// (volume/grid.rs Grid::sample), the gradient, the transfer-function table,
// shading (render/shading.rs), compositing and the per-ray state
// (render/composite.rs, render/sample.rs).

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

// Whether the texture unit filters (`Filter::Hardware`: one fetch in place of
// eight loads; its weights have the hardware's precision, 8 fractional bits
// on NVIDIA), for an unbricked volume in a filterable format only.
override HW_FILTER: bool = false;

// Grid::sample: trilinear, coordinates clamped to the grid.
fn sample(p0: vec3<f32>) -> f32 {
    let p = min(max(p0, vec3<f32>(0.0)), P.grid_max);
    if HW_FILTER {
        // Texel centres sit at (i + 0.5) / n; the clamp above keeps the
        // fetch between the first and last centres, as the CPU clamps.
        let uvw = (p + vec3<f32>(0.5)) / vec3<f32>(P.dims);
        return textureSampleLevel(vol, vol_sampler, uvw, 0.0).x * P.value_scale + P.value_offset;
    }
    let dims = vec3<i32>(P.dims);
    let last = max(dims - vec3<i32>(2), vec3<i32>(0));
    let i = min(vec3<i32>(p), last);
    let f = p - vec3<f32>(i);
    let j0 = min(i + vec3<i32>(1), dims - vec3<i32>(1));
    // The brick owning the cell holds all eight voxels (bricks share a plane).
    var slot = 0u;
    var org = vec3<i32>(0);
    if BRICKED && P.brick_count > 1u {
        let b = min(vec3<u32>(i) / P.brick_cells, P.bricks - vec3<u32>(1u));
        slot = b.x + P.bricks.x * (b.y + P.bricks.y * b.z);
        org = vec3<i32>(b * P.brick_cells);
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
        return (e0 + (e1 - e0) * f.z) * P.value_scale + P.value_offset;
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
    return (c0 + (c1 - c0) * f.z) * P.value_scale + P.value_offset;
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
    let n = normalize(g * P.inv_spacing);
    let ndl = abs(dot(n, view));
    let spec = pow(ndl, 24.0);
    return min(rgb * (0.25 + 0.75 * ndl) + vec3<f32>(0.25 * spec), vec3<f32>(1.0));
}

struct Eval {
    entry: i32,   // −1: transparent
    rgb: vec3<f32>,
    sigma: f32,   // the entry's extinction, kept so compositing need not load it again
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
    if has_flag(F_SHADING) {
        rgb = shade(rgb, gradient(p));
        n_shaded += 1u;
    }
    e.entry = i;
    e.rgb = rgb;
    e.sigma = t.w;
    return e;
}

// Acc::add, front to back; true when the ray may stop.
fn add(rgb: vec3<f32>, alpha: f32) -> bool {
    var em = rgb * alpha;
    var ab = alpha;
    let model = optical_model();
    if model == OPTICAL_ABSORPTION_ONLY {
        em = vec3<f32>(0.0);
    } else if model == OPTICAL_EMISSION_ONLY {
        ab = 0.0;
    }
    let t = 1.0 - acc_a;
    acc_c += em * t;
    acc_a += ab * t;
    let ert = P.ert;
    return acc_a >= ert && ert < 1.0;
}

fn alpha_for(entry: i32, len_world: f32) -> f32 {
    return 1.0 - exp(-lut_entry(entry).w * len_world / P.unit);
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
        return clamp(i32(round_away(log2(P.k_ref / f))), P.level_lo, P.level_hi);
    }
    return P.level_hi;
}

fn safe_inv(d: f32) -> f32 {
    if d == 0.0 {
        return BIG;
    }
    return 1.0 / d;
}
