// Single scattering (render/path.rs): phase functions (render/phase.rs),
// lights (render/light.rs), delta and ratio tracking through the medium
// (render/medium.rs, render/majorant.rs), and the camera ray (camera.rs).

// ------------------------------------------------------ single scattering

const PI: f32 = 3.14159265358979323846;
const INV_4PI: f32 = 0.079577471545947667884;

fn phase_eval(c: f32) -> f32 {
    let kind = P.phase;
    let g = P.phase_g;
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
    let kind = P.phase;
    let g = P.phase_g;
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
    let base = P.shapes * SHAPE_WORDS;
    for (var i = 0u; i < P.lights; i += 1u) {
        let r = base + i * LIGHT_WORDS;
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
    m.o = (o - P.med_offset) * P.med_scale;
    m.d = d * P.med_scale;
    let te = box_intersect(m.o, inv3(m.d), vec3<f32>(0.0), P.med_hi);
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
        let sigma = P.sigma_t * clamp(sample(m.o + m.d * t), 0.0, 1.0);
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
    if P.global_majorant != 0u {
        return segment(m, m.a, m.b, P.majorant, ratio, rng);
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
    let beta = P.med_albedo;
    var l = vec3<f32>(0.0);
    let base = P.shapes * SHAPE_WORDS;
    for (var i = 0u; i < P.lights; i += 1u) {
        let r = base + i * LIGHT_WORDS;
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
    if P.infinite_lights != 0u {
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
    let width = f32(P.width);
    let height = f32(P.height);
    let sx = (2.0 * px / width - 1.0) * P.half_width;
    let sy = (1.0 - 2.0 * py / height) * P.half_height;
    var r: CamRay;
    r.o = P.eye;
    r.d = P.forward;
    if P.orthographic == 0u {
        r.d = normalize(P.forward + P.right * sx + P.up * sy);
    } else {
        r.o = P.eye + P.right * sx + P.up * sy;
    }
    return r;
}
