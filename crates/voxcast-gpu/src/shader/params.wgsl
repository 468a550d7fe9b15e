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
// volumes split into bricks (one texture per brick, see `Bricking` in
// upload.rs).
//
// The shader is the concatenation of the files in this folder, in the
// order renderer.rs lists them (WGSL has no imports): this one (parameters,
// constants, bindings), random, volume, march, geometry, scatter, main.

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
