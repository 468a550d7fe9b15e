//! [`Smv::summary`]: what `voxcast info` prints of an FDS case — meshes,
//! quantities with their times, PLOT3D times and obstructions — scanning
//! the data files' frame headers (apart from the model, which reads none).

use super::model::Smv;
use super::s3d::s3d_times;
use super::slice::read_sf_frame;
use std::path::Path;

impl Smv {
    /// A human-readable description: meshes, quantities with their times,
    /// PLOT3D times and obstructions. Data files are only scanned (frame
    /// headers), not decoded; a file that cannot be read is reported inline.
    pub fn summary(&self) -> Vec<String> {
        let mut out = Vec::new();
        let name = |p: &Path| {
            p.file_name()
                .map(|n| n.to_string_lossy().to_string())
                .unwrap_or_default()
        };
        let range = |t: &[f32]| match (t.first(), t.last()) {
            (Some(a), Some(b)) => format!("{} frames, {a} .. {b} s", t.len()),
            _ => "no frames".to_string(),
        };
        for m in &self.meshes {
            let b = m.bounds;
            let h = m.cell_size();
            out.push(format!(
                "mesh {}: {}×{}×{} cells of {}×{}×{} m, x {}..{} y {}..{} z {}..{} m",
                m.name,
                m.cells[0],
                m.cells[1],
                m.cells[2],
                h.x,
                h.y,
                h.z,
                b[0],
                b[1],
                b[2],
                b[3],
                b[4],
                b[5]
            ));
        }
        for s in &self.smoke3d {
            let t = s3d_times(&s.file)
                .map(|t| range(&t))
                .unwrap_or_else(|e| e.to_string());
            out.push(format!(
                "smoke3d {}: {} [{}]{}, {} ({})",
                s.quantity.short,
                s.quantity.long,
                s.quantity.units,
                if s.k_m > 0.0 {
                    format!(", K_m = {} m2/kg", s.k_m)
                } else {
                    String::new()
                },
                t,
                name(&s.file)
            ));
        }
        for s in &self.slices {
            let t = if s.is_3d {
                read_sf_frame(&s.file, None)
                    .map(|f| range(&f.times))
                    .unwrap_or_else(|e| e.to_string())
            } else {
                "2D, not readable as a volume".to_string()
            };
            out.push(format!(
                "slice {}: {} [{}], nodes {}, {} ({})",
                s.quantity.short,
                s.quantity.long,
                s.quantity.units,
                s.bounds
                    .map(|b| format!("{}..{} {}..{} {}..{}", b[0], b[1], b[2], b[3], b[4], b[5]))
                    .unwrap_or_else(|| "unknown".into()),
                t,
                name(&s.file)
            ));
        }
        if let Some(p) = self.pl3d.first() {
            let times: Vec<String> = self.pl3d.iter().map(|p| p.time.to_string()).collect();
            let qs: Vec<&str> = p.quantities.iter().map(|q| q.short.as_str()).collect();
            out.push(format!(
                "plot3d {}: times {} s",
                qs.join(", "),
                times.join(", ")
            ));
        }
        out.push(format!(
            "obstructions: {} ({} zero-volume skipped)",
            self.obstructions.len(),
            self.skipped_obstructions
        ));
        for o in &self.obstructions {
            out.push(format!(
                "  {}: {}..{} × {}..{} × {}..{} m",
                o.label, o.min.x, o.max.x, o.min.y, o.max.y, o.min.z, o.max.z
            ));
        }
        out
    }
}
