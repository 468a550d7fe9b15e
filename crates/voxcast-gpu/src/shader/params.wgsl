// voxcast GPU ray caster: one invocation per pixel, the same computation as
// the CPU renderer (crates/voxcast/src/render/ray.rs, march/,
// stochastic.rs): same camera rays, manual trilinear reconstruction of the
// stored values (8 texel loads, clamped like Grid::sample), the same
// transfer-function table, opacity correction, block grid (3D DDA) for
// empty-space skipping, adaptive levels, grouped reuse, early ray
// termination, and the same seeded random sequences (64-bit SplitMix/PCG
// emulated with pairs of u32). Also: opaque boxes and planes (surface.rs,
// geometry/), single scattering (path.rs: delta tracking, ratio-tracked
// shadow rays, the phase functions of phase.rs, the lights of light.rs), and
// volumes split into bricks (one texture per brick, see `Bricking` in
// upload.rs).
//
// The shader is the concatenation of the files in this folder, in the
// order renderer.rs lists them (WGSL has no imports), after the generated
// prelude: this one (constants, bindings), random, volume, march, geometry, scatter, main.

// `struct Params` (binding 0, `P`) and the constants M_… (method codes),
// OPTICAL_…, F_… (flag bits), SHAPE_WORDS, LIGHT_WORDS and LUT_SIZE are
// generated from crates/voxcast-gpu/src/params.rs and come first.

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
// Linear under `HW_FILTER` (the texture unit's trilinear), else nearest and unused.
@group(0) @binding(16) var vol_sampler: sampler;

// Specialisation (pipeline constants, renderer.rs `Spec`): a pipeline built
// for one method, flag set and optical model lets the driver compile out
// every other path; without SPEC they are read from P at run time.
override SPEC: bool = false;
override SPEC_METHOD: u32 = 0u;
override SPEC_FLAGS: u32 = 0u;
override SPEC_OPTICAL: u32 = 0u;
override SPEC_SHAPES: bool = true;
// Invocations per workgroup (renderer.rs `env_workgroup`).
override WG_X: u32 = 8u;
override WG_Y: u32 = 8u;

fn method_code() -> u32 {
    if SPEC {
        return SPEC_METHOD;
    }
    return P.method;
}

fn has_flag(f: u32) -> bool {
    if SPEC {
        return (SPEC_FLAGS & f) != 0u;
    }
    return (P.flags & f) != 0u;
}

fn optical_model() -> u32 {
    if SPEC {
        return SPEC_OPTICAL;
    }
    return P.optical;
}

fn any_shapes() -> bool {
    if SPEC && !SPEC_SHAPES {
        return false;
    }
    return P.shapes > 0u;
}
