// The entry point: one invocation per pixel (render/trace.rs), the
// workgroup's statistics.

// ------------------------------------------------------------------- entry

var<workgroup> wg_stats: array<atomic<u32>, 6>;

fn intersect_box(o: vec3<f32>, inv_d: vec3<f32>) -> vec2<f32> {
    let t0 = (P.box_lo - o) * inv_d;
    let t1 = (P.box_hi - o) * inv_d;
    let tmin = min(t0, t1);
    let tmax = max(t0, t1);
    let enter = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    let exit = min(min(tmax.x, tmax.y), tmax.z);
    return vec2<f32>(enter, exit);
}

@compute @workgroup_size(WG_X, WG_Y, 1)
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
    let width = P.width;
    let height = P.height;
    // This dispatch renders passes first…end − 1 of P.passes, adding to the
    // sums the dispatches before it left in out_px (the host divides).
    let first = P.first_pass;
    let end = P.end_pass;
    let passes = end - first;
    let method = method_code();
    let idx = gid.y * width + gid.x;
    var rays = 0u;
    var hits = 0u;
    var terminated = 0u;
    n_samples = 0u;
    n_interp = 0u;
    n_shaded = 0u;
    if gid.x < width && gid.y < height && method == M_SINGLE_SCATTER {
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
        let o = (origin - P.origin) * P.inv_spacing;
        let d = dir * P.inv_spacing;
        let inv_d = inv3(d);
        var te = intersect_box(o, inv_d);
        // The first opaque surface ends the ray (surface.rs).
        var hit: Hit;
        hit.ok = false;
        var surf = vec3<f32>(0.0);
        if any_shapes() {
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
            let step = P.step * P.unit;
            for (var pass_i = first; pass_i < end; pass_i += 1u) {
                acc_c = vec3<f32>(0.0);
                acc_a = 0.0;
                var t0 = te.x;
                if has_flag(F_JITTER) {
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
