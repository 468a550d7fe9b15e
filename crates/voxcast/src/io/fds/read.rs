//! Quantity selection (`--var`, with the `s3d:`/`sf:`/`q:` prefixes) and
//! [`read`] / [`times`]: one quantity at one time as a volume at the mesh
//! nodes.

use super::data::pick_time;
use super::model::{Plot3d, Quantity, Slice, Smoke3d, Smv};
use super::plot3d::{mask_solid_nodes, read_q_variable};
use super::s3d::{read_s3d_frame, s3d_times, s3d_value_map};
use super::slice::read_sf_frame;
use super::smv::parse_smv;
use crate::error::{Error, Result};
use crate::io::OpenOptions;
use crate::volume::{Volume, VoxelData};
use glam::Vec3;
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Source {
    Smoke3d,
    Slice,
    Plot3d,
}

impl Source {
    fn name(self) -> &'static str {
        match self {
            Source::Smoke3d => "smoke3d",
            Source::Slice => "slice",
            Source::Plot3d => "plot3d",
        }
    }
}

/// Every quantity `read` can return, as `short: LONG [units] (source)`.
pub fn quantities(smv: &Smv) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    let mut push = |q: &Quantity, src: Source| {
        let s = format!("{}: {} [{}] ({})", q.short, q.long, q.units, src.name());
        if !out.contains(&s) {
            out.push(s);
        }
    };
    for s in &smv.smoke3d {
        push(&s.quantity, Source::Smoke3d);
    }
    for s in smv.slices.iter().filter(|s| s.is_3d) {
        push(&s.quantity, Source::Slice);
    }
    for p in &smv.pl3d {
        for q in &p.quantities {
            push(q, Source::Plot3d);
        }
    }
    out
}

fn split_source(v: &str) -> (Option<Source>, &str) {
    if let Some((p, rest)) = v.split_once(':') {
        let src = match p.trim().to_ascii_lowercase().as_str() {
            "s3d" | "smoke3d" => Some(Source::Smoke3d),
            "sf" | "slice" | "slcf" => Some(Source::Slice),
            "q" | "plot3d" | "pl3d" => Some(Source::Plot3d),
            _ => None,
        };
        if src.is_some() {
            return (src, rest);
        }
    }
    (None, v)
}

fn one_mesh<T>(
    path: &Path,
    smv: &Smv,
    items: &[&T],
    mesh_of: impl Fn(&T) -> usize,
) -> Result<usize> {
    let mut ms: Vec<usize> = items.iter().map(|x| mesh_of(x)).collect();
    ms.sort_unstable();
    ms.dedup();
    if ms.len() > 1 {
        let names: Vec<&str> = ms.iter().map(|&m| smv.meshes[m].name.as_str()).collect();
        return Err(Error::unsupported(
            path,
            format!(
                "this quantity spans {} meshes ({}); merging meshes is not supported yet",
                ms.len(),
                names.join(", ")
            ),
        ));
    }
    Ok(ms[0])
}

fn mesh_volume(
    path: &Path,
    smv: &Smv,
    mesh: usize,
    bounds: [usize; 6],
    data: Vec<f32>,
) -> Result<Volume> {
    let m = &smv.meshes[mesh];
    if !m.is_uniform() {
        return Err(Error::unsupported(
            path,
            format!(
                "mesh {} has a stretched grid (TRNX/Y/Z not evenly spaced)",
                m.name
            ),
        ));
    }
    let nd = m.node_dims();
    if (0..3).any(|a| bounds[2 * a + 1] >= nd[a]) {
        return Err(Error::format(
            path,
            "bounds",
            format!(
                "node bounds {bounds:?} exceed mesh {} ({nd:?} nodes)",
                m.name
            ),
        ));
    }
    let h = m.cell_size();
    let origin = m.origin() + Vec3::new(bounds[0] as f32, bounds[2] as f32, bounds[4] as f32) * h;
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    Volume::new(dims, h, origin, VoxelData::F32(data.into()))
}

/// Reads one quantity at one time from the FDS case indexed by the `.smv`
/// file `path`.
pub fn read(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let smv = parse_smv(path)?;
    let all = quantities(&smv);
    let want = opts
        .variable
        .as_deref()
        .map(str::trim)
        .filter(|v| !v.is_empty());
    let (src, name) = match want {
        Some(v) => split_source(v),
        None => (None, ""),
    };
    let unknown = || {
        Error::format(
            path,
            "variable",
            format!(
                "no quantity `{}` in this case; available: {}",
                want.unwrap_or(""),
                if all.is_empty() {
                    "none".to_string()
                } else {
                    all.join("; ")
                }
            ),
        )
    };

    // SMOKE3D
    if src.is_none() || src == Some(Source::Smoke3d) {
        let hits: Vec<&Smoke3d> = smv
            .smoke3d
            .iter()
            .filter(|s| {
                if want.is_none() || is_soot_alias(name) {
                    s.k_m > 0.0
                } else {
                    s.quantity.matches(name)
                }
            })
            .collect();
        if !hits.is_empty() {
            let mesh = one_mesh(path, &smv, &hits, |s| s.mesh)?;
            let s = hits[0];
            let frame =
                read_s3d_frame(&s.file, opts.time).map_err(|e| missing(path, &s.file, e))?;
            let dx = smv.meshes[mesh].cell_size().x;
            let (map, units) = s3d_value_map(s, dx);
            let data: Vec<f32> = frame.bytes.iter().map(|&b| map(b)).collect();
            let mut v = mesh_volume(path, &smv, mesh, frame.bounds, data)?;
            v.name = Some(s.quantity.long.clone());
            v.units = units;
            v.time = Some(f32_time(frame.time));
            v.variables = all;
            return Ok(v);
        }
        if want.is_none() {
            return Err(Error::format(
                path,
                "SMOKF3D",
                format!(
                    "no soot SMOKE3D file (K_m > 0) to show by default; choose one with --var: {}",
                    all.join("; ")
                ),
            ));
        }
    }
    // 3D slices
    if src.is_none() || src == Some(Source::Slice) {
        let hits: Vec<&Slice> = smv
            .slices
            .iter()
            .filter(|s| s.is_3d && s.quantity.matches(name))
            .collect();
        if !hits.is_empty() {
            let mesh = one_mesh(path, &smv, &hits, |s| s.mesh)?;
            let s = hits[0];
            let f = read_sf_frame(&s.file, opts.time).map_err(|e| missing(path, &s.file, e))?;
            let t = f.time;
            let mut values = f.values;
            if f.bounds
                .iter()
                .enumerate()
                .all(|(a, &b)| b < smv.meshes[mesh].node_dims()[a / 2])
            {
                mask_solid_nodes(&smv, mesh, f.bounds, &mut values);
            }
            let mut v = mesh_volume(path, &smv, mesh, f.bounds, values)?;
            v.name = Some(s.quantity.long.clone());
            v.units = Some(s.quantity.units.clone());
            v.time = Some(f32_time(t));
            v.variables = all;
            return Ok(v);
        }
    }
    // PLOT3D
    if src.is_none() || src == Some(Source::Plot3d) {
        let hits: Vec<(&Plot3d, usize)> = smv
            .pl3d
            .iter()
            .filter_map(|p| {
                p.quantities
                    .iter()
                    .position(|q| q.matches(name))
                    .map(|n| (p, n))
            })
            .collect();
        if !hits.is_empty() {
            let ps: Vec<&Plot3d> = hits.iter().map(|h| h.0).collect();
            let mesh = one_mesh(path, &smv, &ps, |p| p.mesh)?;
            let times: Vec<f64> = ps.iter().map(|p| p.time).collect();
            let i = pick_time(path, &times, opts.time)?;
            let (p, n) = hits[i];
            let m = &smv.meshes[mesh];
            let nd = m.node_dims();
            let mut data =
                read_q_variable(&p.file, nd, n).map_err(|e| missing(path, &p.file, e))?;
            let bounds = [0, nd[0] - 1, 0, nd[1] - 1, 0, nd[2] - 1];
            mask_solid_nodes(&smv, mesh, bounds, &mut data);
            let mut v = mesh_volume(path, &smv, mesh, bounds, data)?;
            v.name = Some(p.quantities[n].long.clone());
            v.units = Some(p.quantities[n].units.clone());
            v.time = Some(p.time);
            v.variables = all;
            return Ok(v);
        }
    }
    Err(unknown())
}

/// The times of the quantity [`read`] picks for `opts.variable` (the soot
/// SMOKE3D file by default), so that a series can walk the case frame by
/// frame. Only headers are scanned (one slice frame is decoded for its
/// time list).
pub fn times(path: &Path, opts: &OpenOptions) -> Result<Vec<f64>> {
    let smv = parse_smv(path)?;
    let want = opts
        .variable
        .as_deref()
        .map(str::trim)
        .filter(|v| !v.is_empty());
    let (src, name) = match want {
        Some(v) => split_source(v),
        None => (None, ""),
    };
    let to64 = |t: Vec<f32>| t.into_iter().map(f32_time).collect::<Vec<f64>>();
    if src.is_none() || src == Some(Source::Smoke3d) {
        let hit = smv.smoke3d.iter().find(|s| {
            if want.is_none() || is_soot_alias(name) {
                s.k_m > 0.0
            } else {
                s.quantity.matches(name)
            }
        });
        if let Some(s) = hit {
            return Ok(to64(
                s3d_times(&s.file).map_err(|e| missing(path, &s.file, e))?,
            ));
        }
    }
    if want.is_some() && (src.is_none() || src == Some(Source::Slice)) {
        if let Some(s) = smv
            .slices
            .iter()
            .find(|s| s.is_3d && s.quantity.matches(name))
        {
            let f = read_sf_frame(&s.file, None).map_err(|e| missing(path, &s.file, e))?;
            return Ok(to64(f.times));
        }
    }
    if want.is_some() && (src.is_none() || src == Some(Source::Plot3d)) {
        let mut t: Vec<f64> = smv
            .pl3d
            .iter()
            .filter(|p| p.quantities.iter().any(|q| q.matches(name)))
            .map(|p| p.time)
            .collect();
        if !t.is_empty() {
            t.sort_by(f64::total_cmp);
            t.dedup();
            return Ok(t);
        }
    }
    // Nothing matched: `read` gives the error that lists the quantities.
    read(path, opts).map(|v| vec![v.time.unwrap_or(0.0)])
}

/// An f32 time as the f64 with the same shortest decimal form (30.008783,
/// not 30.0087833404541).
fn f32_time(t: f32) -> f64 {
    t.to_string().parse().unwrap_or(t as f64)
}

/// `--var soot` / `smoke`: the soot SMOKE3D file (the one with K_m > 0).
fn is_soot_alias(name: &str) -> bool {
    let n = name.trim();
    n.eq_ignore_ascii_case("soot") || n.eq_ignore_ascii_case("smoke")
}

/// Adds the `.smv` path to an error about a data file that does not exist.
fn missing(smv: &Path, file: &Path, e: Error) -> Error {
    match e {
        Error::Format { ref message, .. } if message.starts_with("cannot open data file") => {
            Error::format(
                smv,
                "data file",
                format!(
                    "{} (named in the .smv) cannot be read: {message}",
                    file.display()
                ),
            )
        }
        e => e,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::fds::soot_extinction;
    use crate::io::fds::test_support::{copy_case, smv_path};

    fn opts(var: Option<&str>, time: Option<f64>) -> OpenOptions {
        OpenOptions {
            variable: var.map(String::from),
            time,
            ..Default::default()
        }
    }

    #[test]
    fn read_soot_volume_at_30s() {
        let Some(p) = smv_path() else { return };
        let v = read(&p, &opts(None, Some(30.0))).unwrap();
        assert_eq!(v.dims(), [51, 31, 26]);
        assert!((v.spacing() - Vec3::splat(0.1)).abs().max_element() < 1e-6);
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.units.as_deref(), Some("1/m"));
        assert_eq!(v.name.as_deref(), Some("SOOT DENSITY"));
        assert!((v.time.unwrap() - 30.0).abs() < 0.3);
        let max = v.stats().max;
        assert!(
            (max as f32 - soot_extinction(167, 0.1)).abs() < 1e-4,
            "{max}"
        );
        assert!(v
            .variables
            .iter()
            .any(|s| s.starts_with("rho_C: SOOT DENSITY")));
        assert!(v.variables.iter().any(|s| s.contains("ext_coef_C")));
        // Same through --var with the long label, any case.
        let w = read(&p, &opts(Some("soot density"), Some(30.0))).unwrap();
        assert_eq!(w.data(), v.data());
    }

    #[test]
    fn open_dispatches_smv_and_soot_alias() {
        let Some(p) = smv_path() else { return };
        let v = crate::io::open(&p, &opts(Some("SOOT"), Some(30.0))).unwrap();
        assert_eq!(v.units.as_deref(), Some("1/m"));
        assert!((v.time.unwrap() - 30.0).abs() < 0.3);
    }

    #[test]
    fn several_meshes_are_named_in_the_error() {
        let dir = tempfile::tempdir().unwrap();
        let smv = dir.path().join("two.smv");
        let mesh = |name: &str, x0: f32| {
            format!(
                "GRID {name}\n 10 10 10 0 0 0 0 0 0\nPDIM\n {x0} {} 0 1 0 1 0 0 0\n",
                x0 + 1.0
            )
        };
        let s3d =
            |m: usize| format!("SMOKF3D {m} 8700.0\n a_{m}.s3d\n SOOT DENSITY\n rho_C\n kg/m3\n");
        let text = format!(
            "{}{}{}{}",
            mesh("MESH_A", 0.0),
            mesh("MESH_B", 1.0),
            s3d(1),
            s3d(2)
        );
        std::fs::write(&smv, text).unwrap();
        let m = parse_smv(&smv).unwrap();
        assert_eq!(m.meshes.len(), 2);
        assert_eq!(m.smoke3d[1].mesh, 1);
        let e = read(&smv, &opts(None, None)).unwrap_err().to_string();
        assert!(e.contains("MESH_A") && e.contains("MESH_B"), "{e}");
        // A mesh number that does not exist.
        std::fs::write(&smv, format!("{}{}", mesh("M", 0.0), s3d(3))).unwrap();
        assert!(parse_smv(&smv).unwrap_err().to_string().contains("mesh 3"));
    }

    #[test]
    fn default_time_is_last_frame() {
        let Some(p) = smv_path() else { return };
        let v = read(&p, &opts(Some("rho_C"), None)).unwrap();
        assert!((v.time.unwrap() - 60.0).abs() < 0.01, "{:?}", v.time);
    }

    #[test]
    fn other_quantities() {
        let Some(p) = smv_path() else { return };
        let t = read(&p, &opts(Some("temp"), Some(30.0))).unwrap();
        assert_eq!(t.units.as_deref(), Some("C"));
        assert!(t.stats().min >= 19.9 && t.stats().max > 300.0);
        let h = read(&p, &opts(Some("HRRPUV"), Some(30.0))).unwrap();
        assert!((h.stats().max - 1200.0).abs() < 1.0);
        let sf = read(&p, &opts(Some("sf:rho_C"), Some(30.0))).unwrap();
        assert!(sf.stats().max < 2e-3, "{}", sf.stats().max);
        assert_eq!(sf.units.as_deref(), Some("kg/m3"));
        let sf = read(&p, &opts(Some("sf:temp"), Some(30.0))).unwrap();
        assert_eq!(sf.dims(), [51, 31, 26]);
        assert!((sf.time.unwrap() - 30.0).abs() < 0.05);
        let q = read(&p, &opts(Some("q:rho_C"), Some(30.0))).unwrap();
        assert_eq!(q.time, Some(30.01));
        assert_eq!(q.name.as_deref(), Some("SOOT DENSITY"));
        // Solid nodes no longer hold air density.
        assert!(q.stats().max < 2e-3, "{}", q.stats().max);
        assert!(q.stats().max > 1e-3);
        let e = read(&p, &opts(Some("ext_coef_C"), Some(60.0))).unwrap();
        assert_eq!(e.units.as_deref(), Some("1/m"));
    }

    #[test]
    fn time_out_of_range_is_an_error() {
        let Some(p) = smv_path() else { return };
        let e = read(&p, &opts(None, Some(1000.0))).unwrap_err().to_string();
        assert!(e.contains("1000") && e.contains("0 .. 60"), "{e}");
    }

    #[test]
    fn unknown_variable_lists_quantities() {
        let Some(p) = smv_path() else { return };
        let e = read(&p, &opts(Some("velocity"), None))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("velocity") && e.contains("rho_C") && e.contains("hrrpuv"),
            "{e}"
        );
    }

    #[test]
    fn truncated_s3d_is_an_error() {
        let Some(p) = smv_path() else { return };
        let dir = copy_case(&p);
        let s3d = dir.path().join("room_smoke_1_1.s3d");
        let bytes = std::fs::read(&s3d).unwrap();
        for cut in [bytes.len() / 2, 30, bytes.len() - 1] {
            std::fs::write(&s3d, &bytes[..cut]).unwrap();
            let e = read(&dir.path().join("room_smoke.smv"), &opts(None, Some(10.0)))
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("room_smoke_1_1.s3d") && e.contains("truncated"),
                "{e}"
            );
        }
        // Corrupt RLE data inside a frame.
        let mut b = bytes.clone();
        for x in &mut b[80..2000] {
            *x = 0xFF;
        }
        std::fs::write(&s3d, &b).unwrap();
        assert!(read(&dir.path().join("room_smoke.smv"), &opts(None, Some(0.0))).is_err());
        // Huge nout.
        let mut b = bytes.clone();
        b[60..64].copy_from_slice(&i32::MAX.to_le_bytes());
        std::fs::write(&s3d, &b).unwrap();
        assert!(read(&dir.path().join("room_smoke.smv"), &opts(None, None)).is_err());
    }

    #[test]
    fn missing_s3d_is_named() {
        let Some(p) = smv_path() else { return };
        let dir = copy_case(&p);
        std::fs::remove_file(dir.path().join("room_smoke_1_1.s3d")).unwrap();
        let e = read(&dir.path().join("room_smoke.smv"), &opts(None, None))
            .unwrap_err()
            .to_string();
        assert!(e.contains("room_smoke_1_1.s3d"), "{e}");
    }

    #[test]
    fn malformed_grid_is_an_error() {
        let Some(p) = smv_path() else { return };
        let dir = copy_case(&p);
        let smv = dir.path().join("room_smoke.smv");
        let text = std::fs::read_to_string(&smv).unwrap();
        for bad in ["    50    x    25", "", "    50    30    -1"] {
            let t = text.replacen(
                "    50    30    25     0     0     0     0     0     0",
                bad,
                1,
            );
            std::fs::write(&smv, t).unwrap();
            let e = read(&smv, &opts(None, None)).unwrap_err().to_string();
            assert!(e.contains("GRID"), "{e}");
        }
        // Truncated .smv and garbage never panic.
        for cut in (0..text.len()).step_by(997) {
            std::fs::write(&smv, &text.as_bytes()[..cut]).unwrap();
            let _ = read(&smv, &opts(None, None));
        }
    }
}
