//! Transfer functions: piecewise-linear colour and opacity over the
//! normalised value (0 = low end of the window, 1 = high end).
//!
//! Opacity is given per unit length — the opacity of one voxel's thickness
//! (the smallest spacing). A renderer that takes steps of another length
//! corrects it, `α' = 1 − (1 − α)^(Δs/Δs₀)`, so the picture does not depend on
//! the step (S4; DESIGN.md "the ray loop").
//!
//! Colours are written as sRGB (as colour maps are published) and converted
//! to linear light for compositing.

use crate::error::{Error, Result};
use crate::volume::Volume;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Largest opacity per unit length; 1 would mean infinite extinction.
const MAX_ALPHA: f32 = 0.999_999;

/// Most control points per channel: more than the lookup table has entries
/// cannot change the picture, and each point costs every entry a look.
pub const MAX_POINTS: usize = LUT_SIZE;

/// A colour and opacity map over normalised values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TransferFunction {
    /// Colour control points `[value, r, g, b]`, sRGB in 0…1, sorted by value.
    pub color: Vec<[f32; 4]>,
    /// Opacity control points `[value, alpha]`, alpha per unit length (one voxel).
    pub opacity: Vec<[f32; 2]>,
    /// Window `[lo, hi]` in data units that maps to 0…1, if the map asks for
    /// one (CT presets give Hounsfield units); otherwise the data range is used.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<[f32; 2]>,
}

/// Names of the built-in presets.
pub const PRESETS: &[(&str, &str)] = &[
    ("grayscale", "black to white, opacity rising with the value"),
    (
        "ct-bone",
        "CT bone: transparent below ~150 HU, ivory bone (HU window on CT data)",
    ),
    (
        "ct-soft-tissue",
        "CT skin and soft tissue in reds, bone in ivory (HU window on CT data)",
    ),
    (
        "mri",
        "MRI: warm grey, soft ramp that hides the background noise",
    ),
    ("smoke", "smoke: grey, opacity proportional to density"),
    ("cloud", "cloud: white, opacity proportional to density"),
    (
        "fire",
        "black-body ramp (black, red, orange, yellow, white)",
    ),
    (
        "viridis",
        "the perceptual viridis colour map with a linear opacity ramp",
    ),
];

/// Viridis (matplotlib), nine stops.
const VIRIDIS: [[f32; 3]; 9] = [
    [0.267, 0.005, 0.329],
    [0.283, 0.141, 0.458],
    [0.254, 0.265, 0.530],
    [0.207, 0.372, 0.553],
    [0.164, 0.471, 0.558],
    [0.128, 0.567, 0.551],
    [0.135, 0.659, 0.518],
    [0.267, 0.749, 0.441],
    [0.993, 0.906, 0.144],
];

impl TransferFunction {
    /// A built-in preset by name (see [`PRESETS`]).
    pub fn preset(name: &str) -> Option<TransferFunction> {
        let hu = Some([-1024.0, 3071.0]);
        // Normalised position of a Hounsfield value in the CT window.
        let h = |v: f32| (v + 1024.0) / 4095.0;
        let tf = match name {
            "grayscale" | "gray" | "grey" => TransferFunction {
                color: vec![[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]],
                opacity: vec![[0.0, 0.0], [1.0, 0.3]],
                window: None,
            },
            "ct-bone" => TransferFunction {
                color: vec![
                    [h(150.0), 0.55, 0.25, 0.15],
                    [h(400.0), 0.90, 0.82, 0.68],
                    [h(1500.0), 1.0, 1.0, 0.95],
                ],
                opacity: vec![[h(150.0), 0.0], [h(400.0), 0.4], [h(1500.0), 0.9]],
                window: hu,
            },
            "ct-soft-tissue" => TransferFunction {
                color: vec![
                    [h(-500.0), 0.55, 0.25, 0.15],
                    [h(-100.0), 0.85, 0.55, 0.45],
                    [h(100.0), 0.80, 0.30, 0.25],
                    [h(300.0), 0.95, 0.90, 0.80],
                    [h(1500.0), 1.0, 1.0, 0.95],
                ],
                opacity: vec![
                    [h(-500.0), 0.0],
                    [h(-200.0), 0.02],
                    [h(100.0), 0.08],
                    [h(300.0), 0.5],
                    [h(1500.0), 0.9],
                ],
                window: hu,
            },
            "mri" => TransferFunction {
                color: vec![
                    [0.0, 0.0, 0.0, 0.0],
                    [0.3, 0.55, 0.42, 0.35],
                    [0.7, 0.92, 0.85, 0.78],
                    [1.0, 1.0, 1.0, 1.0],
                ],
                opacity: vec![[0.0, 0.0], [0.12, 0.0], [0.4, 0.08], [1.0, 0.35]],
                window: None,
            },
            "smoke" => TransferFunction {
                color: vec![[0.0, 0.55, 0.55, 0.55], [1.0, 0.25, 0.25, 0.25]],
                opacity: vec![[0.0, 0.0], [1.0, 0.35]],
                window: None,
            },
            "cloud" => TransferFunction {
                color: vec![[0.0, 1.0, 1.0, 1.0], [1.0, 0.95, 0.96, 1.0]],
                opacity: vec![[0.0, 0.0], [1.0, 0.25]],
                window: None,
            },
            "fire" => TransferFunction {
                color: vec![
                    [0.0, 0.0, 0.0, 0.0],
                    [0.3, 0.7, 0.05, 0.0],
                    [0.6, 1.0, 0.5, 0.0],
                    [0.85, 1.0, 0.9, 0.2],
                    [1.0, 1.0, 1.0, 1.0],
                ],
                opacity: vec![[0.0, 0.0], [0.1, 0.0], [1.0, 0.4]],
                window: None,
            },
            "viridis" => TransferFunction {
                color: VIRIDIS
                    .iter()
                    .enumerate()
                    .map(|(i, c)| [i as f32 / 8.0, c[0], c[1], c[2]])
                    .collect(),
                opacity: vec![[0.0, 0.0], [1.0, 0.3]],
                window: None,
            },
            _ => return None,
        };
        Some(tf)
    }

    /// A map chosen from the data's histogram: the dominant low-value peak
    /// (air, empty space) is made transparent, opacity rises from just above
    /// it to the 99.9th percentile, coloured by viridis-like warm ramp.
    /// Non-finite values are ignored.
    pub fn auto(volume: &Volume) -> TransferFunction {
        let (lo, hi) = auto_range(volume);
        let s = volume.stats();
        let width = if s.max > s.min { s.max - s.min } else { 1.0 };
        let a = ((lo - s.min) / width).clamp(0.0, 1.0);
        let b = ((hi - s.min) / width).clamp(a + 1e-3, 1.0);
        let at = |f: f32| a + (b - a) * f;
        TransferFunction {
            color: vec![
                [at(0.0), 0.60, 0.20, 0.10],
                [at(0.35), 0.90, 0.55, 0.30],
                [at(0.7), 0.97, 0.88, 0.70],
                [at(1.0), 1.0, 1.0, 0.97],
            ],
            opacity: vec![[a, 0.0], [at(0.5), 0.12], [b, 0.6]],
            window: None,
        }
    }

    /// Reads a transfer function from a TOML file:
    ///
    /// ```toml
    /// # value (0…1 over the window), r, g, b (sRGB 0…1)
    /// color = [[0.0, 0, 0, 0], [1.0, 1, 1, 1]]
    /// # value, opacity per voxel of thickness
    /// opacity = [[0.0, 0.0], [0.4, 0.0], [1.0, 0.5]]
    /// window = [-1000.0, 2000.0]   # optional, in data units
    /// ```
    pub fn from_toml_file(path: &Path) -> Result<TransferFunction> {
        let tf: TransferFunction = crate::files::read_toml(path)?;
        tf.validate()
            .map_err(|e| Error::format(path, e.field, e.message))?;
        Ok(tf)
    }

    /// Checks the control points: at least one of each and at most
    /// [`MAX_POINTS`], values finite and non-decreasing, colours and
    /// opacities in 0…1, window lo < hi.
    /// The error names the field: `color`, `opacity` or `window`.
    pub fn validate(&self) -> std::result::Result<(), crate::FieldError> {
        let bad = |field: &str, m: String| Err(crate::FieldError::new(field, m));
        if self.color.is_empty() || self.opacity.is_empty() {
            let field = if self.color.is_empty() {
                "color"
            } else {
                "opacity"
            };
            return bad(
                field,
                "needs at least one `color` and one `opacity` point".into(),
            );
        }
        for (name, n) in [("color", self.color.len()), ("opacity", self.opacity.len())] {
            if n > MAX_POINTS {
                return bad(
                    name,
                    format!("{n} points: at most {MAX_POINTS} (the lookup table's resolution)"),
                );
            }
        }
        for (name, vals) in [
            (
                "color",
                self.color.iter().map(|p| p.to_vec()).collect::<Vec<_>>(),
            ),
            ("opacity", self.opacity.iter().map(|p| p.to_vec()).collect()),
        ] {
            let mut last = f32::NEG_INFINITY;
            for p in &vals {
                if p.iter().any(|x| !x.is_finite()) {
                    return bad(name, format!("point {p:?} is not finite"));
                }
                if p[0] < last {
                    return bad(
                        name,
                        format!("points must be sorted by value ({} after {last})", p[0]),
                    );
                }
                last = p[0];
                if p[1..].iter().any(|&x| !(0.0..=1.0).contains(&x)) {
                    return bad(name, format!("point {p:?}: colour/opacity must be in 0…1"));
                }
            }
        }
        if let Some([lo, hi]) = self.window {
            if !(lo.is_finite() && hi.is_finite() && lo < hi) {
                return bad("window", format!("[{lo}, {hi}] must have lo < hi"));
            }
        }
        Ok(())
    }

    /// Looks up `name` as a preset, `auto`, or a TOML file path.
    pub fn resolve(name: &str, volume: &Volume) -> Result<TransferFunction> {
        if name == "auto" {
            return Ok(TransferFunction::auto(volume));
        }
        if let Some(tf) = TransferFunction::preset(name) {
            return Ok(tf);
        }
        let p = Path::new(name);
        if p.exists() {
            return TransferFunction::from_toml_file(p);
        }
        let names: Vec<&str> = PRESETS.iter().map(|p| p.0).collect();
        Err(Error::invalid(format!(
            "transfer function `{name}`: not a preset ({}, auto) nor an existing TOML file",
            names.join(", ")
        )))
    }

    /// The data window `[lo, hi]` this map applies over `volume`: an explicit
    /// `window` argument, else the map's own window when the data are in
    /// Hounsfield units, else the data's finite range.
    pub fn window_for(&self, volume: &Volume, explicit: Option<[f32; 2]>) -> [f32; 2] {
        if let Some(w) = explicit {
            return w;
        }
        if let Some(w) = self.window {
            let hu_data = volume.units.as_deref() == Some("HU");
            if hu_data || !is_ct_window(w) {
                return w;
            }
        }
        let s = volume.stats();
        [s.min, s.max]
    }

    /// sRGB colour at normalised value `v` (clamped to the points' range).
    pub fn color_at(&self, v: f32) -> [f32; 3] {
        let p = &self.color;
        let i = p.partition_point(|q| q[0] <= v);
        if i == 0 {
            return [p[0][1], p[0][2], p[0][3]];
        }
        if i == p.len() {
            let q = p[p.len() - 1];
            return [q[1], q[2], q[3]];
        }
        let (a, b) = (p[i - 1], p[i]);
        let f = if b[0] > a[0] {
            (v - a[0]) / (b[0] - a[0])
        } else {
            1.0
        };
        [
            a[1] + (b[1] - a[1]) * f,
            a[2] + (b[2] - a[2]) * f,
            a[3] + (b[3] - a[3]) * f,
        ]
    }

    /// Opacity per unit length at normalised value `v`. Below the first point
    /// and above the last the end values hold, except that values below 0
    /// (below the window, and NaN/Inf voxels) are always transparent.
    pub fn opacity_at(&self, v: f32) -> f32 {
        if v.is_nan() || v < 0.0 {
            return 0.0;
        }
        let p = &self.opacity;
        let i = p.partition_point(|q| q[0] <= v);
        if i == 0 {
            return p[0][1];
        }
        if i == p.len() {
            return p[p.len() - 1][1];
        }
        let (a, b) = (p[i - 1], p[i]);
        let f = if b[0] > a[0] {
            (v - a[0]) / (b[0] - a[0])
        } else {
            1.0
        };
        a[1] + (b[1] - a[1]) * f
    }

    /// The smallest opacity over normalised values in `[a, b]` (a lower
    /// bound of a block's extinction, for the `importance` pdf).
    pub fn min_opacity_in(&self, a: f32, b: f32) -> f32 {
        let mut m = self.opacity_at(a).min(self.opacity_at(b));
        for q in &self.opacity {
            if q[0] > a && q[0] < b {
                m = m.min(q[1]);
            }
        }
        m
    }

    /// The largest opacity over normalised values in `[a, b]` (for
    /// empty-space skipping: a block is empty when this is zero).
    pub fn max_opacity_in(&self, a: f32, b: f32) -> f32 {
        let mut m = self.opacity_at(a).max(self.opacity_at(b));
        for q in &self.opacity {
            if q[0] > a && q[0] < b {
                m = m.max(q[1]);
            }
        }
        m
    }
}

/// A CT preset window is only applied to data in HU: on other data (an 8-bit
/// CT, say) the preset's points are read over the data range instead.
fn is_ct_window(w: [f32; 2]) -> bool {
    w == [-1024.0, 3071.0]
}

/// Range for the automatic map: from where the dominant low peak of the
/// histogram has fallen to 2 % of its height, to the 99.9th percentile.
fn auto_range(volume: &Volume) -> (f32, f32) {
    let h = volume.histogram(256);
    let s = volume.stats();
    let hi = h.quantile(0.999).min(s.max);
    let mode = h.mode_bin();
    let mut lo = s.min;
    if mode < h.counts.len() / 2 {
        let peak = h.counts[mode];
        let mut b = mode;
        while b + 1 < h.counts.len() && h.counts[b] * 50 > peak {
            b += 1;
        }
        lo = h.bin_value(b);
    }
    if lo >= hi {
        lo = s.min;
    }
    (lo, hi)
}

/// sRGB-encoded component to linear light.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear-light component to sRGB encoding.
pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Number of entries of a [`Lut`].
pub const LUT_SIZE: usize = 4096;

/// The transfer function baked into a table for the inner loop: linear
/// colour and extinction per unit length `σ = −ln(1 − α)`, plus the opacity
/// of one full step of length `ratio` (step / unit length), precomputed.
#[derive(Clone, Debug)]
pub struct Lut {
    /// `[r, g, b, α_step]` per entry, colour linear. Fixed-size arrays let
    /// the compiler drop the bounds checks of the clamped index.
    entries: Box<[[f32; 4]; LUT_SIZE]>,
    /// Extinction per unit length per entry.
    sigma: Box<[f32; LUT_SIZE]>,
}

impl Lut {
    /// Bakes `tf` for steps of `ratio` unit lengths.
    pub fn new(tf: &TransferFunction, ratio: f32) -> Lut {
        let mut entries = Box::new([[0.0f32; 4]; LUT_SIZE]);
        let mut sigma = Box::new([0.0f32; LUT_SIZE]);
        for i in 0..LUT_SIZE {
            let v = i as f32 / (LUT_SIZE - 1) as f32;
            let c = tf.color_at(v);
            let a = tf.opacity_at(v).clamp(0.0, MAX_ALPHA);
            let s = -(1.0 - a).ln();
            sigma[i] = s;
            // S4 opacity correction: α' = 1 − (1 − α)^(Δs/Δs₀).
            let a_step = 1.0 - (-s * ratio).exp();
            entries[i] = [
                srgb_to_linear(c[0]),
                srgb_to_linear(c[1]),
                srgb_to_linear(c[2]),
                a_step,
            ];
        }
        Lut { entries, sigma }
    }

    /// Table index of normalised value `v`, or `None` below 0 (empty; NaN).
    #[inline(always)]
    pub fn index(v: f32) -> Option<usize> {
        if v >= 0.0 {
            let x = v.min(1.0) * (LUT_SIZE - 1) as f32 + 0.5;
            // SAFETY: v ≥ 0 (so not NaN) and min(1) bounds it, so x is in
            // [0.5, LUT_SIZE − 0.5]: truncation is exact and in range.
            Some(unsafe { x.to_int_unchecked::<u32>() } as usize)
        } else {
            None
        }
    }

    /// `[r, g, b, α_step]` of entry `i`.
    #[inline(always)]
    pub fn entry(&self, i: usize) -> [f32; 4] {
        self.entries[i]
    }

    /// `[r, g, b, α_step]` of every entry.
    pub fn entries(&self) -> &[[f32; 4]; LUT_SIZE] {
        &self.entries
    }

    /// Extinction per unit length of entry `i`.
    #[inline(always)]
    pub fn sigma(&self, i: usize) -> f32 {
        self.sigma[i]
    }

    /// Extinction per unit length of every entry.
    pub fn sigmas(&self) -> &[f32; LUT_SIZE] {
        &self.sigma
    }

    /// Every entry premultiplied for a step of `ratio` unit lengths:
    /// `[r·α, g·α, b·α, α]` with `α = 1 − exp(−σ·ratio)` — the one load per
    /// sample of the unshaded ray loop.
    pub fn premultiplied(&self, ratio: f32) -> Box<[[f32; 4]; LUT_SIZE]> {
        let mut q = Box::new([[0.0f32; 4]; LUT_SIZE]);
        for ((q, e), s) in q.iter_mut().zip(self.entries.iter()).zip(self.sigma.iter()) {
            let a = 1.0 - (-s * ratio).exp();
            *q = [e[0] * a, e[1] * a, e[2] * a, a];
        }
        q
    }

    /// The opacity of every entry for a step of `ratio` unit lengths, for
    /// marchers that take steps of several fixed lengths.
    pub fn alphas(&self, ratio: f32) -> Box<[f32; LUT_SIZE]> {
        let mut a = Box::new([0.0f32; LUT_SIZE]);
        for (a, s) in a.iter_mut().zip(self.sigma.iter()) {
            *a = 1.0 - (-s * ratio).exp();
        }
        a
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn more_points_than_the_lut_has_entries_are_refused() {
        let mut tf = TransferFunction::preset("grayscale").unwrap();
        let n = MAX_POINTS + 1;
        tf.opacity = (0..n).map(|i| [i as f32 / n as f32, 0.5]).collect();
        let e = tf.validate().unwrap_err().to_string();
        assert!(e.contains("at most 4096"), "{e}");
        tf.opacity.truncate(MAX_POINTS);
        tf.validate().unwrap();
    }
    use super::*;

    #[test]
    fn presets_are_valid() {
        for (name, _) in PRESETS {
            let tf = TransferFunction::preset(name).unwrap();
            tf.validate().unwrap();
        }
    }

    #[test]
    fn piecewise_linear_lookup() {
        let tf = TransferFunction {
            color: vec![[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 0.5, 0.0]],
            opacity: vec![[0.2, 0.0], [0.6, 0.8]],
            window: None,
        };
        assert_eq!(tf.opacity_at(0.1), 0.0);
        assert!((tf.opacity_at(0.4) - 0.4).abs() < 1e-6);
        assert_eq!(tf.opacity_at(0.9), 0.8);
        assert_eq!(tf.opacity_at(-0.1), 0.0);
        assert_eq!(tf.opacity_at(f32::NAN), 0.0);
        assert!((tf.color_at(0.5)[1] - 0.25).abs() < 1e-6);
        assert_eq!(tf.max_opacity_in(0.0, 0.2), 0.0);
        assert!(tf.max_opacity_in(0.0, 0.3) > 0.1);
    }

    #[test]
    fn opacity_correction_composes() {
        // Two half steps must absorb exactly what one full step absorbs.
        let tf = TransferFunction::preset("grayscale").unwrap();
        let full = Lut::new(&tf, 1.0);
        let half = Lut::new(&tf, 0.5);
        let i = LUT_SIZE - 1;
        let a1 = full.entry(i)[3];
        let ah = half.entry(i)[3];
        assert!((1.0 - (1.0 - ah) * (1.0 - ah) - a1).abs() < 1e-6);
        assert!((a1 - 0.3).abs() < 1e-6);
    }

    #[test]
    fn toml_round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("tf.toml");
        std::fs::write(&p, "color = [[0.0, 0, 0, 0], [1.0, 1, 1, 1]]\nopacity = [[0.0, 0.0], [1.0, 0.5]]\nwindow = [-100.0, 100.0]\n").unwrap();
        let tf = TransferFunction::from_toml_file(&p).unwrap();
        assert_eq!(tf.window, Some([-100.0, 100.0]));
        std::fs::write(
            &p,
            "color = [[0.5, 0, 0, 0], [0.1, 1, 1, 1]]\nopacity = [[0.0, 0.0]]\n",
        )
        .unwrap();
        let e = TransferFunction::from_toml_file(&p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tf.toml") && e.contains("sorted"), "{e}");
        std::fs::write(&p, "color = 3\n").unwrap();
        assert!(TransferFunction::from_toml_file(&p).is_err());
    }

    #[test]
    fn srgb_round_trip() {
        for i in 0..=20 {
            let c = i as f32 / 20.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-5);
        }
    }
}
