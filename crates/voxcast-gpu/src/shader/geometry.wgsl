// Opaque boxes and planes (geometry/, render/surface.rs): hits, shadows
// and the surface colour.

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
    let base = s * SHAPE_WORDS;
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
    for (var s = 0u; s < P.shapes; s += 1u) {
        let r = shape_hit(s, o, d, 0.0, h.t);
        if r.x > 0.0 {
            h.ok = true;
            h.t = r.x;
            h.normal = r.yzw;
            h.albedo = records[s * SHAPE_WORDS + 5u].xyz;
        }
    }
    return h;
}

fn occluded(o: vec3<f32>, d: vec3<f32>) -> bool {
    for (var s = 0u; s < P.shapes; s += 1u) {
        if shape_hit(s, o, d, 0.0, BIG).x >= 0.0 {
            return true;
        }
    }
    return false;
}

// surface.rs transmittance: midpoint sums of the extinction at the base step
// from world point p along unit l to the volume's edge.
fn surface_transmittance(p: vec3<f32>, l: vec3<f32>) -> f32 {
    let o = (p - P.origin) * P.inv_spacing;
    let d = l * P.inv_spacing;
    let te = box_intersect(o, inv3(d), P.box_lo, P.box_hi);
    if !(te.y > te.x) {
        return 1.0;
    }
    let step = P.step * P.unit;
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
    return exp(-tau * ds / P.unit);
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
    let to_light = P.surf_dir;
    var light = 1.0;
    if P.shadows != 0u {
        var facing = h.normal;
        if dot(h.normal, dir) > 0.0 {
            facing = -h.normal;
        }
        if dot(facing, to_light) > 0.0 {
            let p = origin + dir * h.t + facing * (1e-3 * P.unit);
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
