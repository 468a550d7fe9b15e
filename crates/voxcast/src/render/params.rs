//! What a render is asked for, apart from the volume, the transfer
//! function and the camera: the method (where samples go, as the command
//! line writes it), the compositing order, the inner loop, and every
//! parameter ([`RenderParams`]), with the checks a user's numbers get.

use super::{blocks, light, lod, medium, AdaptiveParams, OpticalModel, ThresholdParams};
use crate::error::{Error, Result};
use crate::volume::Volume;
use serde::{Deserialize, Serialize};

/// Where samples go along the ray (DESIGN.md axis 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Equal steps of `step` voxels (S4).
    #[default]
    Uniform,
    /// S0's block-adaptive steps driven by what the eye sees (the default
    /// adaptive method): per block, `k` is a bound on the change of the
    /// *classified* signal (opacity and premultiplied colour of a voxel's
    /// length) per voxel step, so a steep gradient the transfer function
    /// hides costs nothing and a gentle one across a sharp edge gets the
    /// finest step; the step keeps that change below
    /// [`AdaptiveParams::tolerance`], and grouped reuse (`+grouped`) is
    /// capped where it would exceed it.
    Adaptive,
    /// S0 exactly (eqs. 1–6): a step per block from the frequency
    /// `F = k·|MN|/|MS|`, with `k` the largest partial derivative of the raw
    /// field at the block's midpoint.
    AdaptiveS0,
    /// S0's frequency with `k` the block's largest gradient magnitude instead
    /// of the midpoint's (the midpoint can miss a thin feature).
    AdaptiveMax,
    /// Zeng et al. 2018: the step depends on the value range the current
    /// sample falls into.
    Threshold,
    /// Uniform steps from one random offset per ray (a golden-ratio sequence
    /// over the `spp` passes): no wood grain.
    Jitter,
    /// S1: one random position in each step interval.
    Stratified,
    /// S1 eqs. 5–6: ⌈L/step⌉ uniformly random positions on the whole ray.
    Mc,
    /// S1 eq. 7: stratified positions from a pdf following the TF opacity of
    /// the blocks the ray crosses and the light that can reach them,
    /// weighted by 1/(n·p(x)) (a step that varies from block to block).
    Importance,
    /// Optical model 4: single scattering of the lights with shadows, in a
    /// physically based medium (`[render.medium]`, `[[render.lights]]`).
    SingleScatter,
    /// Optical model 5: volumetric path tracing (delta tracking, ratio
    /// tracking, next-event estimation, Russian roulette, majorant grid).
    Path,
    /// S3: octree traversal skipping empty subtrees, with equidistant
    /// decimation of the uniform samples per leaf (odd spacings where the
    /// contribution is high, even where it is low).
    Lod,
}

impl Method {
    pub const ALL: [Method; 12] = [
        Method::Uniform,
        Method::Adaptive,
        Method::AdaptiveS0,
        Method::AdaptiveMax,
        Method::Threshold,
        Method::Jitter,
        Method::Stratified,
        Method::Mc,
        Method::Importance,
        Method::SingleScatter,
        Method::Path,
        Method::Lod,
    ];

    /// The physically based integrators (`render/path.rs`).
    pub fn is_physical(self) -> bool {
        matches!(self, Method::SingleScatter | Method::Path)
    }

    /// The methods whose sample positions are random (S1), which
    /// progressive `spp` passes average.
    pub fn is_stochastic(self) -> bool {
        matches!(
            self,
            Method::Jitter
                | Method::Stratified
                | Method::Mc
                | Method::Importance
                | Method::SingleScatter
                | Method::Path
        )
    }

    /// The marchers of `render/stochastic.rs`.
    pub fn is_monte_carlo(self) -> bool {
        matches!(self, Method::Stratified | Method::Mc | Method::Importance)
    }

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Uniform => "uniform",
            Method::Adaptive => "adaptive",
            Method::AdaptiveS0 => "adaptive-s0",
            Method::AdaptiveMax => "adaptive-max",
            Method::Threshold => "threshold",
            Method::Jitter => "jitter",
            Method::Stratified => "stratified",
            Method::Mc => "mc",
            Method::Importance => "importance",
            Method::SingleScatter => "single-scatter",
            Method::Path => "path",
            Method::Lod => "lod",
        }
    }

    /// Parses a method name.
    pub fn parse(s: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name() == s)
    }

    /// The method's number, the same on every back end: its place in
    /// [`Method::ALL`]. The GPU shader's `M_…` constants are generated from
    /// it (`voxcast-gpu`'s `params.rs`), so no number is written twice.
    pub fn code(self) -> u32 {
        Method::ALL
            .iter()
            .position(|&m| m == self)
            .expect("ALL lists every method") as u32
    }
}

/// A renderer of voxcast: the multi-threaded CPU ray caster
/// ([`Renderer`](super::Renderer)) or the wgpu compute-shader one (the
/// `voxcast-gpu` crate). [`Backend::renders`] is the one table of what each
/// draws: the GPU crate refuses by it, and the command line, the viewer and
/// their help texts read it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    Cpu,
    Gpu,
}

impl Backend {
    /// `cpu` or `gpu`.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
        }
    }

    /// Whether this back end renders `method`. The CPU renders every method;
    /// the GPU lacks `importance`, `lod` and `path`.
    pub fn renders(self, method: Method) -> bool {
        match self {
            Backend::Cpu => true,
            Backend::Gpu => !matches!(method, Method::Importance | Method::Lod | Method::Path),
        }
    }

    /// Whether this back end draws the scene's opaque geometry: the CPU all
    /// of it; the GPU boxes and planes but not triangle meshes.
    pub fn renders_geometry(self, geometry: Option<&crate::geometry::Geometry>) -> bool {
        match self {
            Backend::Cpu => true,
            Backend::Gpu => geometry.is_none_or(|g| g.counts()[2] == 0),
        }
    }

    /// The methods this back end renders, in [`Method::ALL`]'s order.
    pub fn methods(self) -> impl Iterator<Item = Method> {
        Method::ALL.into_iter().filter(move |&m| self.renders(m))
    }

    /// The methods this back end renders, as a sentence's list
    /// (`uniform, adaptive, … and single-scatter`), for messages and help.
    pub fn method_list(self) -> String {
        let names: Vec<&str> = self.methods().map(Method::name).collect();
        match names.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => names.join(""),
        }
    }
}

/// A method as written on the command line: a marcher name optionally
/// followed by `+grouped` (S0's grouped interpolation) and/or `+noskip`
/// (empty-space skipping off), e.g. `adaptive+grouped`, `uniform+noskip`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MethodSpec {
    pub method: Method,
    pub grouped: bool,
    /// Turn empty-space skipping off (otherwise the scene's setting holds).
    pub no_skip: bool,
}

impl MethodSpec {
    /// Parses `NAME[+grouped][+noskip]`.
    pub fn parse(s: &str) -> Result<MethodSpec> {
        let mut parts = s.trim().split('+');
        let name = parts.next().unwrap_or("");
        let method = Method::parse(name).ok_or_else(|| {
            let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
            Error::invalid(format!(
                "method `{s}`: unknown sampling method `{name}` (known: {}; add +grouped for grouped interpolation, +noskip to turn empty-space skipping off)",
                names.join(", ")
            ))
        })?;
        let mut grouped = false;
        let mut no_skip = false;
        for p in parts {
            match p {
                "grouped" => grouped = true,
                "noskip" => no_skip = true,
                _ => {
                    return Err(Error::invalid(format!(
                        "method `{s}`: unknown modifier `+{p}` (known: +grouped, +noskip)"
                    )))
                }
            }
        }
        Ok(MethodSpec {
            method,
            grouped,
            no_skip,
        })
    }

    /// Sets the method and modifiers of `params`.
    pub fn apply(&self, params: &mut RenderParams) {
        params.method = self.method;
        params.grouped = self.grouped;
        if self.no_skip {
            params.skip_empty = false;
        }
    }

    /// Reads the spec back from `params`.
    pub fn of(params: &RenderParams) -> MethodSpec {
        MethodSpec {
            method: params.method,
            grouped: params.grouped,
            no_skip: !params.skip_empty,
        }
    }
}

impl std::fmt::Display for MethodSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.method.name())?;
        if self.grouped {
            f.write_str("+grouped")?;
        }
        if self.no_skip {
            f.write_str("+noskip")?;
        }
        Ok(())
    }
}

/// Compositing order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Order {
    /// Front to back, with early ray termination.
    #[default]
    FrontToBack,
    /// Back to front (no early termination possible).
    BackToFront,
}

/// Which inner loop runs where both could.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Simd {
    /// SIMD ray packets where the CPU has them and the render is one they
    /// cover (fixed step, trilinear, flat or Phong, front to back), compiled
    /// for the best instruction set the CPU has (AVX-512, else AVX2 + FMA;
    /// NEON on AArch64); the scalar loop otherwise.
    #[default]
    Auto,
    /// The packets compiled for AVX2 + FMA even where the CPU has AVX-512
    /// (to compare the two, and to test each), fetching by the AVX2
    /// gathers.
    Avx2,
    /// The AVX2 packets fetching by scalar loads (what `Auto` picks on
    /// AMD CPUs without AVX-512).
    Avx2Loads,
    /// The packets compiled for AVX-512, fetching by its gathers (what
    /// `Auto` picks on Intel CPUs with AVX-512); the scalar loop where the
    /// CPU has no AVX-512.
    Avx512,
    /// The AVX-512 packets fetching by scalar loads (what `Auto` picks on
    /// AMD CPUs with AVX-512); the scalar loop where the CPU has none.
    Avx512Loads,
    /// The scalar loop always (the reference the packets are tested
    /// against).
    Scalar,
}

impl Simd {
    fn is_auto(&self) -> bool {
        *self == Simd::Auto
    }
}

/// Everything about a render that is not the volume, the transfer function
/// or the camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[serde(default)]
pub struct RenderParams {
    pub width: u32,
    pub height: u32,
    pub method: Method,
    /// Step length in voxels (of the smallest spacing).
    pub step: f32,
    /// Early ray termination: stop when accumulated opacity reaches this
    /// (1 disables).
    pub ert: f32,
    pub order: Order,
    pub optical: OpticalModel,
    /// Gradient Blinn–Phong shading.
    pub shading: bool,
    /// Background colour, sRGB 0…1.
    pub background: [f32; 3],
    /// Seed for the stochastic methods and jitter (the same scene and seed
    /// give the same image).
    pub seed: u64,
    /// S0 grouped interpolation: farther samples reuse the value of the
    /// first sample of their group of 2 or 3.
    pub grouped: bool,
    /// Empty-space skipping over blocks whose values are all transparent.
    pub skip_empty: bool,
    /// A start offset in [0, Δ) per pixel, against wood-grain artefacts (on
    /// by default): independent per pixel, a golden-ratio sequence over the
    /// passes, seeded by `seed` ([`crate::render::rng::pixel_sequence`]).
    pub jitter: bool,
    /// Parameters of `adaptive` and `adaptive-max`.
    pub adaptive: AdaptiveParams,
    /// Parameters of `threshold`.
    pub threshold: ThresholdParams,
    /// Edge of the blocks for empty-space skipping and the adaptive
    /// marchers, in cells (2…64); `None` (the default): the method's own
    /// ([`RenderParams::block_size_or_default`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub block_size: Option<u32>,
    /// Samples (passes) per pixel of the stochastic methods, averaged
    /// progressively; each pass draws new random positions.
    pub spp: u32,
    /// Lights of `single-scatter` and `path` (none: a default sun and sky).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lights: Vec<light::Light>,
    /// The medium of `single-scatter` and `path`.
    pub medium: medium::MediumParams,
    /// Parameters of `lod` (S3).
    pub lod: lod::LodParams,
    /// SIMD ray packets or the scalar loop (the same picture).
    #[serde(skip_serializing_if = "Simd::is_auto")]
    pub simd: Simd,
}

impl Default for RenderParams {
    fn default() -> Self {
        RenderParams {
            width: 512,
            height: 512,
            method: Method::Uniform,
            step: 0.5,
            ert: 0.99,
            order: Order::FrontToBack,
            optical: OpticalModel::EmissionAbsorption,
            shading: true,
            background: [0.0, 0.0, 0.0],
            seed: 0,
            grouped: false,
            skip_empty: true,
            jitter: true,
            adaptive: AdaptiveParams::default(),
            threshold: ThresholdParams::default(),
            block_size: None,
            spp: 1,
            lights: Vec::new(),
            medium: medium::MediumParams::default(),
            lod: lod::LodParams::default(),
            simd: Simd::Auto,
        }
    }
}

impl RenderParams {
    /// The lights of `single-scatter` and `path`: the scene's, or the
    /// default sun and sky when it has none.
    pub fn lights_or_default(&self) -> std::borrow::Cow<'_, [light::Light]> {
        if self.lights.is_empty() {
            std::borrow::Cow::Owned(light::Light::default_sun_and_sky())
        } else {
            std::borrow::Cow::Borrowed(&self.lights)
        }
    }

    /// Whether this render may take its block size from the data
    /// ([`SPARSE_BLOCK`] where the data is sparse):
    /// * with skipping on, the marchers that use the blocks only to skip
    ///   (`uniform`, `jitter`, `stratified`, `mc`, not grouped): the same
    ///   picture whatever the size;
    /// * `adaptive+grouped`, with skipping on or off (so that skipping
    ///   changes its cost, not its pixels): its levels follow the blocks,
    ///   and finer ones measured faster at its defaults and about as fast
    ///   or faster at equal PSNR
    ///   (docs/methods.md, "`adaptive` at equal quality, and with finer
    ///   blocks").
    ///
    /// Every other method takes steps, groups, a pdf, a tree or a majorant
    /// from the blocks as measured at [`DEFAULT_BLOCK`], and keeps it (as
    /// does the GPU back end, for every method).
    ///
    /// [`SPARSE_BLOCK`]: blocks::SPARSE_BLOCK
    /// [`DEFAULT_BLOCK`]: blocks::DEFAULT_BLOCK
    pub fn block_size_follows_data(&self) -> bool {
        match self.method {
            Method::Uniform | Method::Jitter | Method::Stratified | Method::Mc => {
                self.skip_empty && !self.grouped
            }
            Method::Adaptive => self.grouped,
            _ => false,
        }
    }

    /// The scene's block size, or where it names none
    /// [`DEFAULT_BLOCK`](blocks::DEFAULT_BLOCK) (8). The CPU renderer
    /// refines the latter to [`SPARSE_BLOCK`](blocks::SPARSE_BLOCK) (4) for
    /// the marchers of [`RenderParams::block_size_follows_data`] where the
    /// transfer function leaves the finer blocks showing clearly less of
    /// the volume ([`Renderer::block_size_for`](super::Renderer::block_size_for)).
    pub fn block_size_or_default(&self) -> u32 {
        self.block_size.unwrap_or(blocks::DEFAULT_BLOCK as u32)
    }

    /// The reference frequency of the adaptive levels for this render's
    /// method: S0's `k_ref` (`adaptive-s0`, `adaptive-max`), or for the
    /// classified `adaptive` the tolerance per base step — the step
    /// `step · k_ref / F` is then `tolerance / k` voxels, the step at which
    /// the classified signal changes by `tolerance`. Both back ends take
    /// their levels from this one number.
    pub fn adaptive_k_ref(&self) -> f32 {
        match self.method {
            Method::Adaptive => self.adaptive.tolerance / self.step,
            _ => self.adaptive.k_ref,
        }
    }

    /// The share of a sample's colour that the normal decides under this
    /// render's shading (diffuse + specular weights; 0 unshaded), for the
    /// classified `adaptive`'s bound.
    pub fn shade_weight(&self) -> f32 {
        if self.shading {
            let bp = super::shading::BlinnPhong::default();
            bp.diffuse + bp.specular
        } else {
            0.0
        }
    }

    /// Whether the method picks a step per block (S0's levels).
    pub fn has_levels(&self) -> bool {
        matches!(
            self.method,
            Method::Adaptive | Method::AdaptiveS0 | Method::AdaptiveMax
        )
    }

    /// These parameters with their lengths in voxels (`step`, the adaptive
    /// marchers' finest and coarsest step, `threshold`'s steps) taken as
    /// lengths in `volume`'s voxels (its smallest spacing), expressed in its
    /// opacity unit ([`Volume::opacity_unit`]), the length the renderers
    /// measure steps in. The same parameters where the two are one length;
    /// for a pyramid level read whole, whose opacity unit is level 0's finer
    /// voxel, `--step 0.5` stays half a voxel *of the level*, as the
    /// out-of-core renderer steps, not half of level 0's (which took 2ⁿ
    /// times the samples at level n and sampled where out of core did not).
    pub fn in_opacity_units(&self, volume: &Volume) -> std::borrow::Cow<'_, RenderParams> {
        let s = volume.spacing().min_element() / volume.opacity_unit();
        if s == 1.0 || !s.is_finite() || s <= 0.0 {
            return std::borrow::Cow::Borrowed(self);
        }
        let mut p = self.clone();
        p.step *= s;
        p.adaptive.min_step = p.adaptive.min_step.map(|x| x * s);
        p.adaptive.max_step = p.adaptive.max_step.map(|x| x * s);
        p.threshold.steps = p.threshold.steps.map(|x| x * s);
        std::borrow::Cow::Owned(p)
    }

    /// [`RenderParams::validate`], and what depends on the volume: the
    /// physical methods' optical depth.
    pub fn validate_for(&self, volume: &Volume) -> Result<()> {
        self.validate()?;
        if self.method.is_physical() {
            self.medium
                .check_optical_depth(volume)
                .map_err(|e| e.within("render"))?;
        }
        Ok(())
    }

    /// Checks every value a user may get wrong; the error names the field
    /// (`render.step`, `render.medium.albedo`, …).
    pub fn validate(&self) -> Result<(), crate::FieldError> {
        let bad =
            |field: &str, m: String| Err(crate::FieldError::new(format!("render.{field}"), m));
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return bad(
                "size",
                format!(
                    "{}×{}: each side must be 1…16384 pixels",
                    self.width, self.height
                ),
            );
        }
        if !(self.step.is_finite() && self.step >= 1e-3 && self.step <= 64.0) {
            return bad(
                "step",
                format!("{}: must be between 0.001 and 64 voxels", self.step),
            );
        }
        if !(self.ert > 0.0 && self.ert <= 1.0) {
            return bad(
                "ert",
                format!(
                    "{}: the termination threshold must be in (0, 1] (1 disables it)",
                    self.ert
                ),
            );
        }
        if let Some(b) = self.block_size.filter(|b| !(2..=64).contains(b)) {
            return bad("block_size", format!("{b}: must be 2…64 cells"));
        }
        if !(1..=1 << 20).contains(&self.spp) {
            return bad(
                "spp",
                format!("{}: samples per pixel must be 1…1048576", self.spp),
            );
        }
        self.medium.validate().map_err(|e| e.within("render"))?;
        for l in &self.lights {
            l.validate().map_err(|e| e.within("render"))?;
        }
        let t = &self.threshold;
        if t.steps
            .iter()
            .any(|s| !(s.is_finite() && *s >= 1e-3 && *s <= 64.0))
            || t.bounds.iter().any(|b| b.is_nan())
            || t.bounds[0] > t.bounds[1]
        {
            return bad(
                "threshold",
                format!(
                    "steps {:?} must be 0.001…64 voxels and bounds {:?} ordered",
                    t.steps, t.bounds
                ),
            );
        }
        let a = &self.adaptive;
        let out =
            |s: Option<f32>| s.is_some_and(|s| !(s.is_finite() && (1e-3..=64.0).contains(&s)));
        if !(a.k_ref.is_finite() && a.k_ref > 0.0) || out(a.min_step) || out(a.max_step) {
            return bad(
                "adaptive",
                "k_ref must be positive and min/max steps 0.001…64 voxels".into(),
            );
        }
        if !(a.tolerance.is_finite() && (1e-5..=1.0).contains(&a.tolerance)) {
            return bad(
                "adaptive.tolerance",
                format!(
                    "{}: must be in 0.00001…1 (the change of classified opacity allowed per sample)",
                    a.tolerance
                ),
            );
        }
        self.lod.validate().map_err(|e| e.within("render"))?;
        if self.background.iter().any(|c| !(0.0..=1.0).contains(c)) {
            return bad(
                "background",
                format!("{:?}: each component must be in 0…1", self.background),
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_codes_are_places_in_all() {
        for (i, m) in Method::ALL.into_iter().enumerate() {
            assert_eq!(m.code(), i as u32, "{}", m.name());
        }
    }

    /// The one table: the CPU renders everything, the GPU all but three, and
    /// the list for messages reads as a sentence.
    #[test]
    fn backend_table() {
        assert_eq!(Backend::Cpu.methods().count(), Method::ALL.len());
        let gpu: Vec<&str> = Backend::Gpu.methods().map(Method::name).collect();
        assert_eq!(gpu.len(), Method::ALL.len() - 3);
        for m in [Method::Importance, Method::Lod, Method::Path] {
            assert!(!Backend::Gpu.renders(m) && Backend::Cpu.renders(m));
        }
        assert!(Backend::Gpu.renders(Method::SingleScatter));
        assert_eq!(
            Backend::Gpu.method_list(),
            "uniform, adaptive, adaptive-s0, adaptive-max, threshold, jitter, stratified, mc and single-scatter"
        );
        assert!(Backend::Gpu.renders_geometry(None));
    }
}
