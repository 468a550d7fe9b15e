// SplitMix64 and PCG32 on pairs of u32 (render/rng.rs): the per-pixel
// start jitter and the stochastic methods' random numbers.

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

// render/march/mod.rs pixel_random: uniform in [0, 1) per seed and pixel.
fn pixel_random(x: u32, y: u32) -> f32 {
    let key = mul64(vec2<u32>(y, x), vec2<u32>(0x7F4A7C15u, 0x9E3779B9u));
    let z = mix64(P.seed ^ key);
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
    r.state = add64(r.state, P.seed_mixed);
    rng_next(&r);
    return r;
}

fn rng_uniform(r: ptr<function, Rng>) -> f32 {
    return f32(rng_next(r) >> 8u) * (1.0 / 16777216.0);
}
