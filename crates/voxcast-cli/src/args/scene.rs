//! The flags that define a scene ([`SceneArgs`]: input, transfer function,
//! camera, ray casting, geometry, medium) and how to open an input
//! ([`OpenArgs`]), shared by render, bench, view, animate and bench-frames.

use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;
use voxcast::camera::Projection;
use voxcast::io::{OpenOptions, RawLayout};
use voxcast::render::{MethodSpec, OpticalModel, Order, Simd};
use voxcast::scene::Scene;
use voxcast::ScalarType;

/// Options to open an input (shared by render, bench and info).
#[derive(Args, Clone, Default)]
pub struct OpenArgs {
    /// Read INPUT as raw voxels with these dims (X,Y,Z; x fastest).
    #[arg(long, value_name = "X,Y,Z", help_heading = "Input")]
    pub raw_dims: Option<String>,
    /// Raw voxel type: u8, u16, i16 or f32.
    #[arg(long, value_name = "TYPE", help_heading = "Input")]
    pub raw_type: Option<String>,
    /// Raw byte order: little or big.
    #[arg(
        long,
        value_name = "ENDIAN",
        default_value = "little",
        help_heading = "Input"
    )]
    pub raw_endian: String,
    /// Bytes to skip at the start of a raw file.
    #[arg(long, value_name = "N", default_value_t = 0, help_heading = "Input")]
    pub raw_header_bytes: u64,
    /// Voxel spacing X,Y,Z (overrides the file's).
    #[arg(long, value_name = "X,Y,Z", help_heading = "Input")]
    pub spacing: Option<String>,
    /// Variable (grid, quantity) to read from a multi-variable file.
    #[arg(long = "var", value_name = "NAME", help_heading = "Input")]
    pub variable: Option<String>,
    /// Time (in the file's units, e.g. seconds) to read from a time series.
    #[arg(long, value_name = "T", help_heading = "Input")]
    pub time: Option<f64>,
    /// Resolution level of a multi-resolution store (OME-Zarr), 0 the
    /// finest, everywhere. `render` otherwise picks the coarsest level whose
    /// voxel is no larger than a pixel where the volume is nearest (out of
    /// core: per region, coarser further off); `info` lists the levels.
    #[arg(long, value_name = "N", help_heading = "Input")]
    pub level: Option<usize>,
    /// For a multi-resolution store: scales the pixel size the levels are
    /// chosen by — 2 reads each region a level coarser (about 8× fewer
    /// voxels, faster), 0.5 a level finer (sharper where a voxel would
    /// cover about a pixel). Default 1.
    #[arg(long, value_name = "X", help_heading = "Input")]
    pub lod_scale: Option<f32>,
}

impl OpenArgs {
    pub fn options(&self) -> Result<OpenOptions> {
        let raw = match (&self.raw_dims, &self.raw_type) {
            (None, None) => None,
            (Some(d), Some(t)) => {
                let dims: [u64; 3] = triple(d, "--raw-dims")?;
                let scalar_type = ScalarType::parse(t)
                    .with_context(|| format!("--raw-type {t}: expected u8, u16, i16 or f32"))?;
                let big_endian = match self.raw_endian.as_str() {
                    "little" | "le" => false,
                    "big" | "be" => true,
                    e => bail!("--raw-endian {e}: expected little or big"),
                };
                Some(RawLayout {
                    dims,
                    scalar_type,
                    big_endian,
                    header_bytes: self.raw_header_bytes,
                })
            }
            (Some(_), None) => bail!("--raw-dims needs --raw-type (u8, u16, i16 or f32)"),
            (None, Some(_)) => bail!("--raw-type needs --raw-dims X,Y,Z"),
        };
        let spacing = match &self.spacing {
            Some(s) => {
                let v: [f32; 3] = triple(s, "--spacing")?;
                if v.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
                    bail!("--spacing {s}: each value must be a positive number");
                }
                Some(v)
            }
            None => None,
        };
        if let Some(t) = self.time {
            if !t.is_finite() {
                bail!("--time {t}: expected a finite number");
            }
        }
        if let Some(x) = self.lod_scale {
            if !(x.is_finite() && x > 0.0) {
                bail!("--lod-scale {x}: expected a positive number (1: a voxel no larger than a pixel; 2: a level coarser)");
            }
        }
        Ok(OpenOptions {
            raw,
            spacing,
            variable: self.variable.clone(),
            time: self.time,
            level: self.level,
            lod_scale: self.lod_scale,
        })
    }
}

/// Parses `a,b,c`.
fn triple<T: std::str::FromStr + Copy>(s: &str, flag: &str) -> Result<[T; 3]> {
    let v: Vec<T> = s
        .split(',')
        .map(|p| p.trim().parse::<T>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("{flag} {s}: expected three numbers separated by commas"))?;
    if v.len() != 3 {
        bail!("{flag} {s}: expected three numbers separated by commas");
    }
    Ok([v[0], v[1], v[2]])
}

/// Everything that defines a scene, shared by `render` and `bench`: the
/// input and how to open it, the transfer function, the camera and the ray
/// casting parameters. A `--scene` file is the starting point; flags given
/// override it.
#[derive(Args)]
pub struct SceneArgs {
    /// Volume: a file, folder, glob, or builtin:NAME (default: builtin:demo).
    pub input: Option<String>,
    /// Start from a scene file (flags given here override it).
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,

    #[command(flatten)]
    pub open: OpenArgs,

    /// Transfer function: a preset (see `voxcast presets`), auto, or a TOML file.
    #[arg(long, value_name = "NAME|FILE", help_heading = "Transfer function")]
    pub tf: Option<String>,
    /// Data values mapped to the ends of the transfer function (e.g. -1000,2000 HU).
    #[arg(
        long,
        value_name = "LO,HI",
        allow_hyphen_values = true,
        help_heading = "Transfer function"
    )]
    pub window: Option<String>,

    /// Image size (default 512x512).
    #[arg(long, value_name = "WxH", help_heading = "Camera")]
    pub size: Option<String>,
    /// Orbit angle about +z in degrees.
    #[arg(long, allow_hyphen_values = true, help_heading = "Camera")]
    pub azimuth: Option<f32>,
    /// Angle above the xy plane in degrees.
    #[arg(long, allow_hyphen_values = true, help_heading = "Camera")]
    pub elevation: Option<f32>,
    /// Magnification relative to the automatic framing.
    #[arg(long, help_heading = "Camera")]
    pub zoom: Option<f32>,
    /// Vertical field of view in degrees (perspective).
    #[arg(long, help_heading = "Camera")]
    pub fov: Option<f32>,
    /// Orthographic projection instead of perspective.
    #[arg(long, help_heading = "Camera")]
    pub ortho: bool,

    /// Step length in voxels (default 0.5).
    #[arg(long, help_heading = "Ray casting")]
    pub step: Option<f32>,
    /// Early ray termination threshold (default 0.99; 1 disables).
    #[arg(long, help_heading = "Ray casting")]
    pub ert: Option<f32>,
    /// Compositing order. Both give the same picture (early termination
    /// and `lod`'s visibility decimation need front to back: back to front
    /// spaces each lod leaf by its own amount of cloud).
    #[arg(long, value_enum, help_heading = "Ray casting")]
    pub order: Option<OrderArg>,
    /// Optical model.
    #[arg(long, value_enum, help_heading = "Ray casting")]
    pub optical: Option<OpticalArg>,
    /// CPU inner loop: `auto` marches sixteen rays per SIMD packet (one
    /// AVX-512 register, or two of AVX2) where the CPU has AVX2, for
    /// uniform, jitter, importance, stratified, mc, the adaptive methods,
    /// uniform and threshold (grouped or not) and lod, in both orders (back
    /// to front summed front to back without early termination); `avx2`
    /// keeps the
    /// packets to AVX2, fetching with its gather instructions; `avx2-loads`
    /// to AVX2 fetching with scalar loads; `avx512` and `avx512-loads` the
    /// same at AVX-512. `auto` picks the loads on AMD and on Intel's
    /// Skylake to Ice Lake (whose gathers are slower), the gathers on other
    /// Intel CPUs; `voxcast bench` prints the level. On AArch64 `auto`
    /// runs the packets in NEON registers (four lanes) and the x86 levels
    /// run the scalar loop. `scalar` always runs the scalar loop (the same
    /// picture).
    #[arg(long, value_enum, help_heading = "Ray casting")]
    pub simd: Option<SimdArg>,
    /// Gradient (Blinn–Phong) shading: on or off (default on).
    #[arg(long, value_name = "on|off", help_heading = "Ray casting")]
    pub shading: Option<String>,
    /// Empty-space skipping over fully transparent blocks: on or off (default on).
    #[arg(long, value_name = "on|off", help_heading = "Ray casting")]
    pub skip_empty: Option<String>,
    /// Edge of the empty-space-skipping blocks in cells: smaller blocks skip
    /// more tightly and cost more DDA steps. By default 8, and 4 for
    /// uniform, jitter, stratified, mc (not +grouped) and adaptive+grouped
    /// where the transfer function leaves 4³ blocks showing under 85 % of
    /// what 8³ blocks show (sparse data; the first four's pictures do not
    /// depend on it, adaptive+grouped's levels get finer). The other
    /// methods keep 8.
    #[arg(long, value_name = "N", help_heading = "Ray casting")]
    pub block_size: Option<u32>,
    /// A start offset per pixel against wood-grain artefacts (rings where a
    /// fixed step meets a surface): on or off (default on). The offsets are
    /// independent per pixel (seeded by --seed) and follow the golden ratio
    /// over --spp passes, so the error of a coarse step becomes fine noise
    /// that passes average away.
    #[arg(long, value_name = "on|off", help_heading = "Ray casting")]
    pub jitter: Option<String>,
    /// Background: black, white, R,G,B (0…1) or #rrggbb.
    #[arg(long, value_name = "COLOR", help_heading = "Ray casting")]
    pub background: Option<String>,
    /// Random seed (stochastic methods and jitter).
    #[arg(long, help_heading = "Ray casting")]
    pub seed: Option<u64>,

    /// Opaque geometry the smoke is composited over (rays stop at the first
    /// surface): a geometry TOML file of boxes, planes and OBJ meshes in the
    /// volume's world coordinates; `auto` (the default) takes what comes
    /// with the input — geometry.toml in the input's folder (written by
    /// `voxcast simulate`) or the OBST boxes of an FDS .smv; `none` turns
    /// all geometry off.
    #[arg(long, value_name = "FILE|auto|none", help_heading = "Geometry")]
    pub geometry: Option<String>,
    /// Shadows on the geometry: the key light is dimmed by the smoke between
    /// the surface and the light (Beer–Lambert) and blocked by other shapes:
    /// on or off (default off).
    #[arg(long, value_name = "on|off", help_heading = "Geometry")]
    pub shadows: Option<String>,
    /// Direction towards the key light that lights the geometry, in world
    /// coordinates, e.g. 0,0,1 for straight above (default: above and to
    /// the left, behind the camera).
    #[arg(
        long,
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        help_heading = "Geometry"
    )]
    pub light: Option<String>,
    /// Samples per pixel of the stochastic methods (jitter, stratified, mc,
    /// importance, single-scatter, path): each pass draws new random
    /// positions and the passes are averaged, so noise falls as 1/√N.
    #[arg(long, value_name = "N", help_heading = "Ray casting")]
    pub spp: Option<u32>,

    /// Phase function of the medium (single-scatter, path): isotropic,
    /// hg:G (Henyey–Greenstein, mean cosine G), schlick:K, rayleigh, or
    /// mie:G (Cornette–Shanks). Default hg:0.8.
    #[arg(
        long,
        value_name = "SPEC",
        help_heading = "Medium (single-scatter, path)"
    )]
    pub phase: Option<String>,
    /// Single-scattering albedo σs/σt: one value or R,G,B (default 0.95).
    #[arg(
        long,
        value_name = "A|R,G,B",
        help_heading = "Medium (single-scatter, path)"
    )]
    pub albedo: Option<String>,
    /// Extinction per world unit at density 1 (the density is the value
    /// mapped through --window to 0…1). Default 10.
    #[arg(
        long,
        value_name = "SIGMA",
        help_heading = "Medium (single-scatter, path)"
    )]
    pub extinction: Option<f32>,
    /// Free-flight sampling bound: grid (per-block maxima walked by DDA,
    /// the default) or global (one maximum).
    #[arg(
        long,
        value_name = "grid|global",
        help_heading = "Medium (single-scatter, path)"
    )]
    pub majorant: Option<String>,
    /// Longest path, in scattering events (default 256).
    #[arg(long, value_name = "N", help_heading = "Medium (single-scatter, path)")]
    pub max_depth: Option<u32>,
    /// Light the medium by a constant environment of this radiance instead
    /// of the default sun and sky (lights of a scene file are kept).
    #[arg(
        long,
        value_name = "L|R,G,B",
        help_heading = "Medium (single-scatter, path)"
    )]
    pub env: Option<String>,
}

/// `v` or `r,g,b`.
fn one_or_three(s: &str, flag: &str) -> Result<[f32; 3]> {
    if let Ok(v) = s.trim().parse::<f32>() {
        return Ok([v; 3]);
    }
    triple(s, flag)
}

#[derive(clap::ValueEnum, Clone, Copy)]
pub enum OrderArg {
    FrontToBack,
    BackToFront,
}

#[derive(clap::ValueEnum, Clone, Copy)]
pub enum SimdArg {
    Auto,
    Avx2,
    Avx2Loads,
    Avx512,
    Avx512Loads,
    Scalar,
}

#[derive(clap::ValueEnum, Clone, Copy)]
pub enum OpticalArg {
    AbsorptionOnly,
    EmissionOnly,
    EmissionAbsorption,
}

fn on_off(flag: &str, s: &str) -> Result<bool> {
    Ok(match s {
        "on" | "true" | "yes" => true,
        "off" | "false" | "no" => false,
        _ => bail!("--{flag} {s}: expected on or off"),
    })
}

impl SceneArgs {
    /// The scene to start from: the `--scene` file, or the default scene
    /// (the demo in its own three-quarter view when no input is given).
    pub fn base_scene(&self) -> Result<Scene> {
        let mut scene = match &self.scene {
            Some(p) => Scene::load(p)?,
            None => Scene::default(),
        };
        if self.scene.is_none() && self.input.is_none() {
            // The demo's own three-quarter view (flags given still override it).
            scene.camera.azimuth = 30.0;
            scene.camera.elevation = 20.0;
            scene.camera.zoom = 1.6;
        }
        Ok(scene)
    }

    /// Applies the flags given on the command line to `scene`.
    pub fn apply(&self, scene: &mut Scene) -> Result<()> {
        if let Some(i) = &self.input {
            scene.input.path = i.clone();
        }
        let o = self.open.options()?;
        if o.raw.is_some() {
            scene.input.options.raw = o.raw;
        }
        if o.spacing.is_some() {
            scene.input.options.spacing = o.spacing;
        }
        if o.variable.is_some() {
            scene.input.options.variable = o.variable;
        }
        if o.time.is_some() {
            scene.input.options.time = o.time;
        }
        if o.level.is_some() {
            scene.input.options.level = o.level;
        }
        if o.lod_scale.is_some() {
            scene.input.options.lod_scale = o.lod_scale;
        }
        if let Some(tf) = &self.tf {
            scene.transfer.tf = tf.clone();
            scene.transfer.map = None;
        }
        if let Some(w) = &self.window {
            let v: Vec<f32> = w
                .split(',')
                .map(|p| p.trim().parse())
                .collect::<std::result::Result<_, _>>()
                .map_err(|_| anyhow::anyhow!("--window {w}: expected LO,HI"))?;
            let [lo, hi] = v[..] else {
                bail!("--window {w}: expected LO,HI");
            };
            scene.transfer.window = Some([lo, hi]);
        }
        let (c, r) = (&mut scene.camera, &mut scene.render);
        if let Some(s) = &self.size {
            let (w, h) = s
                .split_once(['x', 'X'])
                .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)))
                .with_context(|| format!("--size {s}: expected WIDTHxHEIGHT, e.g. 512x512"))?;
            r.width = w;
            r.height = h;
        }
        if let Some(v) = self.azimuth {
            c.azimuth = v;
        }
        if let Some(v) = self.elevation {
            c.elevation = v;
        }
        if let Some(v) = self.zoom {
            c.zoom = v;
        }
        if let Some(v) = self.fov {
            c.fov = v;
        }
        if self.ortho {
            c.projection = Projection::Orthographic;
        }
        if let Some(v) = self.step {
            r.step = v;
        }
        if let Some(v) = self.ert {
            r.ert = v;
        }
        if let Some(v) = self.order {
            r.order = match v {
                OrderArg::FrontToBack => Order::FrontToBack,
                OrderArg::BackToFront => Order::BackToFront,
            };
        }
        if let Some(v) = self.optical {
            r.optical = match v {
                OpticalArg::AbsorptionOnly => OpticalModel::AbsorptionOnly,
                OpticalArg::EmissionOnly => OpticalModel::EmissionOnly,
                OpticalArg::EmissionAbsorption => OpticalModel::EmissionAbsorption,
            };
        }
        if let Some(v) = self.simd {
            r.simd = match v {
                SimdArg::Auto => Simd::Auto,
                SimdArg::Avx2 => Simd::Avx2,
                SimdArg::Avx2Loads => Simd::Avx2Loads,
                SimdArg::Avx512 => Simd::Avx512,
                SimdArg::Avx512Loads => Simd::Avx512Loads,
                SimdArg::Scalar => Simd::Scalar,
            };
        }
        if let Some(s) = &self.shading {
            r.shading = on_off("shading", s)?;
        }
        if let Some(b) = self.block_size {
            r.block_size = Some(b);
        }
        if let Some(s) = &self.skip_empty {
            r.skip_empty = on_off("skip-empty", s)?;
        }
        if let Some(s) = &self.jitter {
            r.jitter = on_off("jitter", s)?;
        }
        if let Some(b) = &self.background {
            r.background = parse_color(b)?;
        }
        if let Some(s) = self.seed {
            r.seed = s;
        }
        if let Some(n) = self.spp {
            r.spp = n;
        }
        if let Some(ph) = &self.phase {
            r.medium.phase =
                voxcast::render::phase::PhaseFunction::parse(ph).with_context(|| {
                    format!("--phase {ph}: expected isotropic, hg:G, schlick:K, rayleigh or mie:G")
                })?;
        }
        if let Some(a) = &self.albedo {
            r.medium.albedo = one_or_three(a, "--albedo")?;
        }
        if let Some(e) = self.extinction {
            r.medium.scale = e;
        }
        if let Some(m) = &self.majorant {
            r.medium.majorant = match m.as_str() {
                "grid" => voxcast::render::medium::MajorantKind::Grid,
                "global" => voxcast::render::medium::MajorantKind::Global,
                _ => bail!("--majorant {m}: expected grid or global"),
            };
        }
        if let Some(n) = self.max_depth {
            r.medium.max_depth = n;
        }
        if let Some(e) = &self.env {
            let radiance = one_or_three(e, "--env")?;
            r.lights
                .retain(|l| !matches!(l, voxcast::render::light::Light::Environment { .. }));
            r.lights
                .push(voxcast::render::light::Light::Environment { radiance });
        }
        self.apply_geometry(scene)?;
        // One set of rules for flags and scene files: the library's.
        // The error names the flag that set the field, else the field.
        if let Some(e) = scene.problem() {
            match self.flag_for(&e.field) {
                Some(flag) => bail!("{flag} {}", e.message),
                None => bail!("{e}"),
            }
        }
        Ok(())
    }

    /// The flag that set a scene field, when it was given.
    fn flag_for(&self, field: &str) -> Option<&'static str> {
        let given = match field {
            "camera.azimuth" => ("--azimuth", self.azimuth.is_some()),
            "camera.elevation" => ("--elevation", self.elevation.is_some()),
            "camera.zoom" => ("--zoom", self.zoom.is_some()),
            "camera.fov" => ("--fov", self.fov.is_some()),
            "transfer.window" => ("--window", self.window.is_some()),
            "input.spacing" => ("--spacing", self.open.spacing.is_some()),
            "geometry.light" => ("--light", self.light.is_some()),
            "render.size" => ("--size", self.size.is_some()),
            "render.step" => ("--step", self.step.is_some()),
            "render.ert" => ("--ert", self.ert.is_some()),
            "render.block_size" => ("--block-size", self.block_size.is_some()),
            "render.spp" => ("--spp", self.spp.is_some()),
            "render.background" => ("--background", self.background.is_some()),
            "render.medium.scale" => ("--extinction", self.extinction.is_some()),
            "render.medium.albedo" => ("--albedo", self.albedo.is_some()),
            "render.medium.max_depth" => ("--max-depth", self.max_depth.is_some()),
            "render.medium.phase" => ("--phase", self.phase.is_some()),
            "render.lights" => ("--env", self.env.is_some()),
            _ => return None,
        };
        given.1.then_some(given.0)
    }

    /// Applies `--geometry`, `--shadows` and `--light`.
    fn apply_geometry(&self, scene: &mut Scene) -> Result<()> {
        let g = &mut scene.geometry;
        match self.geometry.as_deref() {
            None => {}
            Some("none") => {
                g.auto = false;
                g.file = None;
                g.boxes.clear();
                g.planes.clear();
                g.meshes.clear();
            }
            Some("auto") => {
                g.auto = true;
                g.file = None;
            }
            Some(f) => {
                if !std::path::Path::new(f).is_file() {
                    bail!("--geometry {f}: no such file (expected a geometry TOML file, auto or none)");
                }
                g.file = Some(f.to_string());
            }
        }
        if let Some(s) = &self.shadows {
            g.shadows = on_off("shadows", s)?;
        }
        if let Some(l) = &self.light {
            g.light = Some(triple(l, "--light")?);
        }
        Ok(())
    }

    /// The base scene with the flags applied.
    pub fn scene(&self) -> Result<Scene> {
        self.scene_with(None, |_| {})
    }

    /// The base scene, then `defaults` (a command's own defaults), then
    /// `--method` (a command's own flag), then the other flags.
    pub fn scene_with(
        &self,
        method: Option<&str>,
        defaults: impl FnOnce(&mut Scene),
    ) -> Result<Scene> {
        let mut scene = self.base_scene()?;
        defaults(&mut scene);
        if let Some(m) = method {
            MethodSpec::parse(m)
                .with_context(|| format!("--method {m}"))?
                .apply(&mut scene.render);
        }
        self.apply(&mut scene)?;
        Ok(scene)
    }
}

/// `black`, `white`, `R,G,B` in 0…1, or `#rrggbb`.
fn parse_color(s: &str) -> Result<[f32; 3]> {
    match s {
        "black" => return Ok([0.0; 3]),
        "white" => return Ok([1.0; 3]),
        "gray" | "grey" => return Ok([0.5; 3]),
        _ => {}
    }
    if let Some(hex) = s.strip_prefix('#') {
        if hex.len() == 6 {
            if let Ok(v) = u32::from_str_radix(hex, 16) {
                return Ok([(v >> 16) & 255, (v >> 8) & 255, v & 255].map(|c| c as f32 / 255.0));
            }
        }
        bail!("--background {s}: expected #rrggbb");
    }
    let v: [f32; 3] = triple(s, "--background")?;
    if v.iter().any(|c| !(0.0..=1.0).contains(c)) {
        bail!("--background {s}: components must be in 0…1");
    }
    Ok(v)
}
