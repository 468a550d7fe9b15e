//! The transfer-function editor's model, without a window: control points
//! added, moved and removed, presets, the table the renderer bakes, and the
//! data histogram (log-scaled counts) drawn behind the points.
//!
//! Points live over the normalised value 0…1 (the scene's window), as in
//! [`TransferFunction`]; opacity is per unit length (one voxel), colour sRGB.
//! Every edit keeps the points sorted and in range, so the map is always
//! valid and can be rendered at once.

use voxcast::transfer::TransferFunction;
use voxcast::volume::Volume;

/// Which curve a control point belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Curve {
    Opacity,
    Color,
}

/// The edited transfer function.
#[derive(Clone, Debug, PartialEq)]
pub struct TfModel {
    tf: TransferFunction,
}

impl TfModel {
    /// Starts from `tf` (its window, if any, is dropped: the viewer keeps
    /// the data window itself).
    pub fn new(tf: &TransferFunction) -> TfModel {
        let mut tf = tf.clone();
        tf.window = None;
        let mut m = TfModel { tf };
        m.normalise();
        m
    }

    /// The map as the renderer takes it.
    pub fn tf(&self) -> &TransferFunction {
        &self.tf
    }

    /// Opacity points `[value, alpha]`.
    pub fn opacity(&self) -> &[[f32; 2]] {
        &self.tf.opacity
    }

    /// Colour points `[value, r, g, b]`.
    pub fn color(&self) -> &[[f32; 4]] {
        &self.tf.color
    }

    /// Number of points of `curve`.
    pub fn len(&self, curve: Curve) -> usize {
        match curve {
            Curve::Opacity => self.tf.opacity.len(),
            Curve::Color => self.tf.color.len(),
        }
    }

    /// Adds an opacity point at value `x` with opacity `a` (both clamped to
    /// 0…1); returns its index.
    pub fn add_opacity(&mut self, x: f32, a: f32) -> usize {
        let p = [clamp01(x), clamp01(a)];
        let i = self.tf.opacity.partition_point(|q| q[0] <= p[0]);
        self.tf.opacity.insert(i, p);
        i
    }

    /// Adds a colour point at value `x`, with the colour the map has there
    /// now (so adding a point changes nothing until it is edited).
    pub fn add_color(&mut self, x: f32) -> usize {
        let x = clamp01(x);
        let c = self.tf.color_at(x);
        let i = self.tf.color.partition_point(|q| q[0] <= x);
        self.tf.color.insert(i, [x, c[0], c[1], c[2]]);
        i
    }

    /// Moves opacity point `i` to `(x, a)`. The value is kept between the
    /// neighbours' values, so the order (and the index) never changes.
    pub fn move_opacity(&mut self, i: usize, x: f32, a: f32) {
        if i >= self.tf.opacity.len() {
            return;
        }
        let x = self.between(Curve::Opacity, i, x);
        self.tf.opacity[i] = [x, clamp01(a)];
    }

    /// Moves colour point `i` to value `x` (kept between its neighbours).
    pub fn move_color(&mut self, i: usize, x: f32) {
        if i >= self.tf.color.len() {
            return;
        }
        self.tf.color[i][0] = self.between(Curve::Color, i, x);
    }

    /// Sets the sRGB colour of colour point `i`.
    pub fn set_color(&mut self, i: usize, rgb: [f32; 3]) {
        if let Some(p) = self.tf.color.get_mut(i) {
            p[1..].copy_from_slice(&rgb.map(clamp01));
        }
    }

    /// Removes point `i` of `curve`; the last point of a curve stays (a map
    /// needs one). Returns whether a point was removed.
    pub fn remove(&mut self, curve: Curve, i: usize) -> bool {
        if self.len(curve) <= 1 || i >= self.len(curve) {
            return false;
        }
        match curve {
            Curve::Opacity => {
                self.tf.opacity.remove(i);
            }
            Curve::Color => {
                self.tf.color.remove(i);
            }
        }
        true
    }

    /// Replaces the points by the preset `name`'s; returns the preset (with
    /// its own window, which the caller applies to the data), or `None` for
    /// an unknown name.
    pub fn set_preset(&mut self, name: &str) -> Option<TransferFunction> {
        let p = TransferFunction::preset(name)?;
        *self = TfModel::new(&p);
        Some(p)
    }

    /// The table a renderer bakes: `n ≥ 2` entries over 0…1, each sRGB
    /// colour and opacity per unit length at `i / (n − 1)`.
    pub fn table(&self, n: usize) -> Vec<[f32; 4]> {
        let n = n.max(2);
        (0..n)
            .map(|i| {
                let v = i as f32 / (n - 1) as f32;
                let c = self.tf.color_at(v);
                [c[0], c[1], c[2], self.tf.opacity_at(v)]
            })
            .collect()
    }

    /// `x` clamped to 0…1 and between the values of point `i`'s neighbours.
    fn between(&self, curve: Curve, i: usize, x: f32) -> f32 {
        let vals: Vec<f32> = match curve {
            Curve::Opacity => self.tf.opacity.iter().map(|p| p[0]).collect(),
            Curve::Color => self.tf.color.iter().map(|p| p[0]).collect(),
        };
        let lo = if i > 0 { vals[i - 1] } else { 0.0 };
        let hi = if i + 1 < vals.len() { vals[i + 1] } else { 1.0 };
        clamp01(x).clamp(lo, hi.max(lo))
    }

    /// Puts points inside 0…1 (presets and files may reach outside) and
    /// sorted.
    fn normalise(&mut self) {
        for p in &mut self.tf.opacity {
            p[0] = clamp01(p[0]);
            p[1] = clamp01(p[1]);
        }
        for p in &mut self.tf.color {
            for c in p.iter_mut() {
                *c = clamp01(*c);
            }
        }
        self.tf.opacity.sort_by(|a, b| a[0].total_cmp(&b[0]));
        self.tf.color.sort_by(|a, b| a[0].total_cmp(&b[0]));
    }
}

fn clamp01(x: f32) -> f32 {
    if x.is_nan() {
        0.0
    } else {
        x.clamp(0.0, 1.0)
    }
}

/// Voxel counts over the window in equal bins, and their log scale for
/// drawing (empty space would otherwise flatten everything else).
#[derive(Clone, Debug, PartialEq)]
pub struct LogHistogram {
    /// Voxels per bin; values outside the window (and NaN) are not counted.
    pub counts: Vec<u64>,
    /// `ln(1 + count) / ln(1 + max count)` per bin, 0…1.
    pub heights: Vec<f32>,
}

impl LogHistogram {
    /// Counts the voxels of `volume` in `bins` bins over `window`.
    pub fn new(volume: &Volume, window: [f32; 2], bins: usize) -> LogHistogram {
        let bins = bins.max(1);
        let mut counts = vec![0u64; bins];
        let [lo, hi] = window;
        let scale = if hi > lo {
            bins as f32 / (hi - lo)
        } else {
            0.0
        };
        let data = volume.data();
        for i in 0..data.len() {
            let v = data.get(i);
            if !(v >= lo && v <= hi) {
                continue;
            }
            let b = (((v - lo) * scale) as usize).min(bins - 1);
            counts[b] += 1;
        }
        LogHistogram::from_counts(counts)
    }

    /// The log heights of `counts`.
    pub fn from_counts(counts: Vec<u64>) -> LogHistogram {
        let max = counts.iter().copied().max().unwrap_or(0);
        let norm = ((1 + max) as f64).ln();
        let heights = counts
            .iter()
            .map(|&c| {
                if max == 0 {
                    0.0
                } else {
                    (((1 + c) as f64).ln() / norm) as f32
                }
            })
            .collect();
        LogHistogram { counts, heights }
    }
}

/// The index of the point nearest to `pos` within `radius` (any units, the
/// same as the points'), or `None`.
pub fn pick(points: &[[f32; 2]], pos: [f32; 2], radius: f32) -> Option<usize> {
    let mut best = None;
    let mut best_d = radius * radius;
    for (i, p) in points.iter().enumerate() {
        let d = (p[0] - pos[0]).powi(2) + (p[1] - pos[1]).powi(2);
        if d <= best_d {
            best_d = d;
            best = Some(i);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use voxcast::transfer::Lut;
    use voxcast::VoxelData;

    fn ramp() -> TfModel {
        TfModel::new(&TransferFunction {
            color: vec![[0.0, 0.0, 0.0, 0.0], [1.0, 1.0, 1.0, 1.0]],
            opacity: vec![[0.0, 0.0], [1.0, 0.5]],
            window: Some([-5.0, 5.0]),
        })
    }

    #[test]
    fn table_interpolates_the_points() {
        let mut m = ramp();
        let i = m.add_opacity(0.5, 0.9);
        assert_eq!(i, 1);
        let t = m.table(5);
        assert_eq!(t.len(), 5);
        let alpha: Vec<f32> = t.iter().map(|e| e[3]).collect();
        // 0 → 0, 0.25 → half-way to 0.9, 0.5 → 0.9, 0.75 → (0.9+0.5)/2, 1 → 0.5.
        let want = [0.0, 0.45, 0.9, 0.7, 0.5];
        for (a, w) in alpha.iter().zip(want) {
            assert!((a - w).abs() < 1e-6, "{alpha:?}");
        }
        assert!((t[2][0] - 0.5).abs() < 1e-6, "grey ramp colour");
        assert!(m.tf().validate().is_ok());
        assert_eq!(m.tf().window, None, "the viewer keeps the window");
    }

    #[test]
    fn table_matches_what_the_renderer_bakes() {
        let mut m = ramp();
        m.add_opacity(0.3, 0.05);
        let c = m.add_color(0.6);
        m.set_color(c, [1.0, 0.0, 0.0]);
        let lut = Lut::new(m.tf(), 1.0);
        let n = voxcast::transfer::LUT_SIZE;
        let t = m.table(n);
        for i in [0, 100, 1000, 2457, 3000, n - 1] {
            // Step ratio 1: the baked step opacity is the point opacity.
            assert!((lut.entry(i)[3] - t[i][3]).abs() < 1e-5, "entry {i}");
            let lin = voxcast::transfer::srgb_to_linear(t[i][0]);
            assert!((lut.entry(i)[0] - lin).abs() < 1e-5, "entry {i}");
        }
    }

    #[test]
    fn moving_keeps_the_order_and_range() {
        let mut m = ramp();
        let i = m.add_opacity(0.5, 0.2);
        m.move_opacity(i, 1.7, 3.0);
        assert_eq!(m.opacity()[i], [1.0, 1.0]);
        m.move_opacity(i, -1.0, -1.0);
        assert_eq!(m.opacity()[i], [0.0, 0.0]);
        m.move_opacity(i, 0.4, 0.3);
        m.move_opacity(0, 0.9, 0.0);
        assert_eq!(m.opacity()[0][0], 0.4, "stopped at its right neighbour");
        assert!(m.tf().validate().is_ok());
        let c = m.add_color(0.25);
        assert!(
            (m.color()[c][1] - 0.25).abs() < 1e-6,
            "new point takes the map's colour"
        );
        m.move_color(c, 2.0);
        assert_eq!(m.color()[c][0], 1.0);
        assert!(m.tf().validate().is_ok());
    }

    #[test]
    fn removing_keeps_one_point() {
        let mut m = ramp();
        assert!(m.remove(Curve::Opacity, 0));
        assert!(!m.remove(Curve::Opacity, 0), "the last point stays");
        assert!(!m.remove(Curve::Color, 5), "out of range");
        assert_eq!(m.len(Curve::Opacity), 1);
        assert!(m.tf().validate().is_ok());
    }

    #[test]
    fn presets_replace_the_points() {
        let mut m = ramp();
        let p = m.set_preset("ct-bone").unwrap();
        assert_eq!(p.window, Some([-1024.0, 3071.0]));
        assert_eq!(m.opacity(), p.opacity.as_slice());
        assert!(m.set_preset("no-such").is_none());
        assert_eq!(m.opacity(), p.opacity.as_slice(), "unchanged");
    }

    #[test]
    fn histogram_counts_the_window_and_scales_by_log() {
        // 1000 voxels: 900 at 0, 90 at 5, 10 at 9.5, and one outside.
        let mut vals = vec![0.0f32; 900];
        vals.extend(std::iter::repeat_n(5.0, 90));
        vals.extend(std::iter::repeat_n(9.5, 9));
        vals.push(20.0);
        let v = Volume::new(
            [1000, 1, 1],
            Vec3::ONE,
            Vec3::ZERO,
            VoxelData::F32(vals.into()),
        )
        .unwrap();
        let h = LogHistogram::new(&v, [0.0, 10.0], 10);
        assert_eq!(h.counts[0], 900);
        assert_eq!(h.counts[5], 90);
        assert_eq!(h.counts[9], 9);
        assert_eq!(h.counts.iter().sum::<u64>(), 999);
        assert_eq!(h.heights[0], 1.0);
        let want = (91f64.ln() / 901f64.ln()) as f32;
        assert!((h.heights[5] - want).abs() < 1e-6);
        assert_eq!(h.heights[1], 0.0);
    }

    #[test]
    fn pick_finds_the_nearest_within_the_radius() {
        let pts = [[0.0, 0.0], [0.5, 0.5], [0.52, 0.5]];
        assert_eq!(pick(&pts, [0.515, 0.5], 0.05), Some(2));
        assert_eq!(pick(&pts, [0.9, 0.9], 0.05), None);
    }
}
