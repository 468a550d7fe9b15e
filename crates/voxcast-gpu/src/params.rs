//! The contract between the Rust side and the shader, written once, here:
//!
//! * [`Params`], the uniform block of one render. The Rust struct is the
//!   definition; the WGSL `struct Params` is generated from it
//!   ([`prelude`]), member by member with the same names and doc lines, and
//!   a test (`layout_matches_naga`) checks every member's offset and size
//!   against naga's layout of the compiled shader, so the two cannot drift.
//! * The numbers the shader compares with: method codes
//!   ([`Method::code`], `M_UNIFORM`…), optical models (`OPTICAL_…`),
//!   the flag bits (`F_…`), the records' sizes and the table size, all
//!   generated as WGSL `const`s from the Rust values.
//!
//! The shader files in `shader/` use these names and define none of them.

use voxcast::render::{Method, OpticalModel};
use voxcast::transfer::LUT_SIZE;

/// A Rust type with the same size and alignment as a WGSL type in a uniform
/// buffer (checked by the layout test).
pub(crate) trait Wgsl {
    const TYPE: &'static str;
}

macro_rules! wgsl_types {
    ($($t:ty => $name:literal),* $(,)?) => {
        $(impl Wgsl for $t { const TYPE: &'static str = $name; })*
    };
}

wgsl_types! {
    f32 => "f32", u32 => "u32", i32 => "i32",
    [f32; 2] => "vec2<f32>", [f32; 3] => "vec3<f32>", [f32; 4] => "vec4<f32>",
    [u32; 2] => "vec2<u32>", [u32; 3] => "vec3<u32>", [u32; 4] => "vec4<u32>",
}

/// One member of a generated WGSL struct.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Member {
    pub(crate) name: &'static str,
    pub(crate) wgsl: &'static str,
    pub(crate) offset: usize,
    pub(crate) size: usize,
    pub(crate) doc: &'static str,
}

/// Defines a `#[repr(C)]` Pod struct and the table of its members
/// (`MEMBERS`) from which its WGSL twin is written.
macro_rules! uniform_struct {
    (
        $(#[doc = $sdoc:literal])*
        pub(crate) struct $name:ident {
            $( $(#[doc = $doc:literal])* $field:ident : $ty:ty, )*
        }
    ) => {
        $(#[doc = $sdoc])*
        #[repr(C)]
        #[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
        pub(crate) struct $name {
            $( $(#[doc = $doc])* pub(crate) $field: $ty, )*
        }

        impl $name {
            /// The members in order, for the WGSL struct and the layout test.
            pub(crate) const MEMBERS: &'static [Member] = &[
                $( Member {
                    name: stringify!($field),
                    wgsl: <$ty as Wgsl>::TYPE,
                    offset: std::mem::offset_of!($name, $field),
                    size: std::mem::size_of::<$ty>(),
                    doc: concat!("" $(, $doc, "\n")*),
                }, )*
            ];
        }
    };
}

uniform_struct! {
    /// The uniform block of one render (binding 0, `P` in the shader). Rows
    /// of 16 bytes: a `vec3` and a scalar, or four scalars; the `_pad`
    /// members fill the last row.
    pub(crate) struct Params {
        // Camera (camera.rs `Camera::fit`), as the CPU frames it.
        /// Eye position (world).
        eye: [f32; 3],
        /// 0 perspective, 1 orthographic.
        orthographic: u32,
        /// Unit view direction.
        forward: [f32; 3],
        /// Half width of the image plane (tan(fov/2)·aspect, or world units).
        half_width: f32,
        /// Unit right vector.
        right: [f32; 3],
        /// Half height of the image plane.
        half_height: f32,
        /// Unit up vector.
        up: [f32; 3],
        /// Base step, in voxels (`RenderParams::step`).
        step: f32,
        // The volume (volume/grid.rs).
        /// World position of voxel (0, 0, 0).
        origin: [f32; 3],
        /// The smallest voxel spacing: one voxel step in world units.
        unit: f32,
        /// 1 / spacing, per axis.
        inv_spacing: [f32; 3],
        /// Stored texel → normalised value: scale…
        value_scale: f32,
        /// dims − 1, per axis (the clamp of `Grid::sample`).
        grid_max: [f32; 3],
        /// …and offset.
        value_offset: f32,
        /// The box rays are clipped to (voxels, `Volume::sample_box`).
        box_lo: [f32; 3],
        /// Early ray termination opacity (1 turns it off).
        ert: f32,
        /// Far corner of that box.
        box_hi: [f32; 3],
        /// S0's reference frequency k_ref of the adaptive levels.
        k_ref: f32,
        /// Voxels per axis.
        dims: [u32; 3],
        /// Edge of a block of the block grid, in voxels.
        block_size: u32,
        /// Blocks per axis.
        block_counts: [u32; 3],
        /// `Method::code` of the method (`M_…`).
        method: u32,
        /// Bricks per axis (upload.rs `Bricking`).
        bricks: [u32; 3],
        /// Their product.
        brick_count: u32,
        /// Cells per brick, per axis.
        brick_cells: [u32; 3],
        /// `F_…` bits.
        flags: u32,
        // The image and its passes.
        /// Image width, pixels.
        width: u32,
        /// Image height, pixels.
        height: u32,
        /// Passes of the whole render (`spp` for the stochastic methods).
        passes: u32,
        /// The first pass of this dispatch…
        first_pass: u32,
        /// The seed, as (low, high) 32-bit halves.
        seed: [u32; 2],
        /// `splitmix(seed)`, the PCG streams' increment base.
        seed_mixed: [u32; 2],
        /// …and the pass after its last.
        end_pass: u32,
        /// Adaptive levels: the finest…
        level_lo: i32,
        /// …and the coarsest (the fixed level of the other methods).
        level_hi: i32,
        /// `OPTICAL_…` code of the optical model.
        optical: u32,
        /// Threshold method (Zeng et al.): range bound a…
        thresh_lo: f32,
        /// …bound b…
        thresh_hi: f32,
        /// …and the steps (voxels) below a, …
        thresh_step0: f32,
        /// …between a and b…
        thresh_step1: f32,
        // Opaque geometry and lights (scene.rs): records in `records`.
        /// Shape records (`SHAPE_WORDS` vec4 each).
        shapes: u32,
        /// Smoke shadows on the shapes (0 or 1).
        shadows: u32,
        /// Light records (`LIGHT_WORDS` vec4 each), after the shapes.
        lights: u32,
        /// Phase function: 0 isotropic, 1 HG, 2 Schlick, 3 Rayleigh, 4 Mie.
        phase: u32,
        /// Towards the surfaces' key light.
        surf_dir: [f32; 3],
        /// The phase function's parameter (g or k).
        phase_g: f32,
        /// Surface Blinn–Phong: ambient, diffuse, specular, shininess.
        surf_k: [f32; 4],
        // The medium of the physically based methods (path.rs, medium.rs).
        /// World → voxel offset of the medium box.
        med_offset: [f32; 3],
        /// σ_t at density 1.
        sigma_t: f32,
        /// World → voxel scale.
        med_scale: [f32; 3],
        /// The global majorant.
        majorant: f32,
        /// The box's far corner (voxels).
        med_hi: [f32; 3],
        /// 1: the global majorant; 0: the majorant grid.
        global_majorant: u32,
        /// Single-scattering albedo.
        med_albedo: [f32; 3],
        /// 1 when an environment or sky light is present.
        infinite_lights: u32,
        /// …and above b.
        thresh_step2: f32,
        _pad0: u32,
        _pad1: u32,
        _pad2: u32,
    }
}

/// Defines the flag bits and their WGSL names.
macro_rules! flags {
    ($($(#[doc = $doc:literal])* $name:ident = $bit:literal),* $(,)?) => {
        $( $(#[doc = $doc])* pub(crate) const $name: u32 = $bit; )*
        /// (WGSL name, bit) of every flag.
        const FLAGS: &[(&str, u32)] = &[$((concat!("F_", stringify!($name)), $bit)),*];
    };
}

flags! {
    /// Blinn–Phong shading of the samples.
    SHADING = 1,
    /// S0's grouped interpolation.
    GROUPED = 2,
    /// A random start offset per ray and pass.
    JITTER = 4,
    /// Empty-space skipping over the block grid.
    SKIP = 8,
}

/// `vec4` records per shape and per light in the scene buffer.
pub(crate) const SHAPE_WORDS: usize = 6;
pub(crate) const LIGHT_WORDS: usize = 4;

/// The `OPTICAL_…` code of an optical model: its place in
/// [`OpticalModel::ALL`].
pub(crate) fn optical_code(m: OpticalModel) -> u32 {
    OpticalModel::ALL
        .iter()
        .position(|&o| o == m)
        .expect("ALL lists every model") as u32
}

/// `NAME` of a kebab-case name: upper case, `-` → `_`.
fn constant(name: &str) -> String {
    name.to_uppercase().replace('-', "_")
}

/// The WGSL declaration of a struct from its members.
fn wgsl_struct(name: &str, members: &[Member]) -> String {
    let mut s = format!("struct {name} {{\n");
    for m in members {
        for line in m.doc.lines() {
            s += &format!("    //{line}\n");
        }
        // The Rust offsets, which the layout test holds naga's to.
        s += &format!(
            "    {}: {}, // bytes {}..{}\n",
            m.name,
            m.wgsl,
            m.offset,
            m.offset + m.size
        );
    }
    s + "};\n"
}

/// The WGSL that every shader file builds on: `struct Params` and the
/// constants, generated from the Rust definitions above.
pub(crate) fn prelude() -> String {
    let mut s =
        String::from("// Generated from crates/voxcast-gpu/src/params.rs: do not edit.\n\n");
    s += &wgsl_struct("Params", Params::MEMBERS);
    s += "\n// Method::code\n";
    for m in Method::ALL {
        s += &format!("const M_{}: u32 = {}u;\n", constant(m.name()), m.code());
    }
    s += "\n// OpticalModel\n";
    for m in OpticalModel::ALL {
        s += &format!(
            "const OPTICAL_{}: u32 = {}u;\n",
            constant(m.name()),
            optical_code(m)
        );
    }
    s += "\n// Params::flags\n";
    for (name, bit) in FLAGS {
        s += &format!("const {name}: u32 = {bit}u;\n");
    }
    s += &format!(
        "\nconst SHAPE_WORDS: u32 = {SHAPE_WORDS}u;\nconst LIGHT_WORDS: u32 = {LIGHT_WORDS}u;\nconst LUT_SIZE: u32 = {LUT_SIZE}u;\n\n"
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generated `struct Params`, as naga lays it out in the uniform
    /// address space of the whole shader, has the Rust struct's members at
    /// the same offsets with the same sizes, and the same total size.
    #[test]
    fn layout_matches_naga() {
        let source = crate::renderer::shader_source();
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("layout");
        let (handle, ty) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some("Params"))
            .expect("struct Params in the shader");
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            panic!("Params is not a struct");
        };
        assert_eq!(members.len(), Params::MEMBERS.len());
        for (m, r) in members.iter().zip(Params::MEMBERS) {
            assert_eq!(m.name.as_deref(), Some(r.name));
            assert_eq!(m.offset as usize, r.offset, "offset of {}", r.name);
            assert_eq!(
                layouter[m.ty].size as usize, r.size,
                "size of {} ({})",
                r.name, r.wgsl
            );
        }
        assert_eq!(*span as usize, std::mem::size_of::<Params>());
        assert_eq!(
            layouter[handle].size as usize,
            std::mem::size_of::<Params>()
        );
        // The uniform address space wants 16-byte rows.
        assert_eq!(std::mem::size_of::<Params>() % 16, 0);
    }

    /// The whole shader validates (naga's validator, as wgpu runs it), with
    /// the generated prelude.
    #[test]
    fn shader_validates() {
        let source = crate::renderer::shader_source();
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(&source)));
    }

    /// Every method and optical model has its own code; the flags are
    /// distinct bits.
    #[test]
    fn codes_are_distinct() {
        let mut codes: Vec<u32> = Method::ALL.iter().map(|m| m.code()).collect();
        codes.dedup();
        assert_eq!(codes, (0..Method::ALL.len() as u32).collect::<Vec<_>>());
        let optical: Vec<u32> = OpticalModel::ALL.iter().map(|&m| optical_code(m)).collect();
        assert_eq!(optical, vec![0, 1, 2]);
        let mut all = 0;
        for (_, bit) in FLAGS {
            assert_eq!(bit.count_ones(), 1);
            assert_eq!(all & bit, 0);
            all |= bit;
        }
    }

    /// The generated struct names every Rust member with its WGSL type.
    #[test]
    fn prelude_declares_members() {
        let p = prelude();
        assert!(p.contains("struct Params {\n"));
        assert!(p.contains("    eye: vec3<f32>, // bytes 0..12\n"));
        assert!(p.contains("    seed: vec2<u32>, // bytes 224..232\n"));
        assert!(p.contains("const M_SINGLE_SCATTER: u32 = 9u;"));
        assert!(p.contains("const F_SKIP: u32 = 8u;"));
    }
}
