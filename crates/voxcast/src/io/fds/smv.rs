//! The Smokeview `.smv` index parser: GRID, PDIM, TRNX/Y/Z, OBST, XYZ,
//! SMOKF3D, SLCF/SLCC and PL3D blocks.

use super::model::{Mesh, Obstruction, Plot3d, Quantity, Slice, Smoke3d, Smv};
use crate::error::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// Largest `.smv` file read (text; real ones are kilobytes to a few MB).
const MAX_SMV_BYTES: u64 = 256 << 20;

fn is_keyword_line(l: &str) -> bool {
    l.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
}

/// Parses the `.smv` file at `path`.
pub fn parse_smv(path: &Path) -> Result<Smv> {
    let len = crate::io::util::file_len(path)?;
    if len > MAX_SMV_BYTES {
        return Err(Error::format(
            path,
            "size",
            format!("{len} bytes is too large for a .smv index file"),
        ));
    }
    let bytes = crate::files::read_bytes(path, u64::MAX)?;
    let text = String::from_utf8_lossy(&bytes);
    parse_smv_text(path, &text)
}

struct Lines<'a> {
    path: &'a Path,
    lines: Vec<&'a str>,
    pos: usize,
}

impl<'a> Lines<'a> {
    /// The next line, as data of `field`.
    fn next(&mut self, field: &str) -> Result<&'a str> {
        let l = self.lines.get(self.pos).copied().ok_or_else(|| {
            Error::format(
                self.path,
                field,
                format!("the file ends inside the {field} block"),
            )
        })?;
        self.pos += 1;
        Ok(l)
    }

    fn field(&self, kw: &str) -> String {
        format!("{kw} (line {})", self.pos)
    }

    /// A data line with a file name or label (trimmed).
    fn text(&mut self, field: &str) -> Result<String> {
        Ok(self.next(field)?.trim().to_string())
    }

    fn quantity(&mut self, field: &str) -> Result<Quantity> {
        Ok(Quantity {
            long: self.text(field)?,
            short: self.text(field)?,
            units: self.text(field)?,
        })
    }
}

fn nums<T: std::str::FromStr>(path: &Path, field: &str, s: &str, min: usize) -> Result<Vec<T>> {
    let v: Vec<T> = s
        .split_whitespace()
        .map_while(|t| t.parse::<T>().ok())
        .collect();
    if v.len() < min {
        return Err(Error::format(
            path,
            field,
            format!("expected at least {min} numbers, found `{}`", s.trim()),
        ));
    }
    Ok(v)
}

fn mesh_index(path: &Path, field: &str, s: &str, n_meshes: usize) -> Result<usize> {
    let m: i64 = s
        .trim()
        .parse()
        .map_err(|_| Error::format(path, field, format!("`{}` is not a mesh number", s.trim())))?;
    if m < 1 || m as usize > n_meshes.max(1) {
        return Err(Error::format(
            path,
            field,
            format!("mesh {m} does not exist ({n_meshes} GRID entries)"),
        ));
    }
    Ok(m as usize - 1)
}

/// The time in a PLOT3D file name `…_<int>p<2 digits>.q`.
pub fn time_from_q_name(name: &str) -> Option<f64> {
    let stem = name.trim().strip_suffix(".q")?;
    let (_, t) = stem.rsplit_once('_')?;
    let (i, f) = t.split_once('p')?;
    let neg = i.starts_with('-') || i.starts_with('m');
    let i = i.trim_start_matches(['-', 'm']);
    if i.is_empty() || !i.bytes().all(|c| c.is_ascii_digit()) || f.is_empty() {
        return None;
    }
    if !f.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    let v: f64 = format!("{i}.{f}").parse().ok()?;
    Some(if neg { -v } else { v })
}

fn parse_smv_text(path: &Path, text: &str) -> Result<Smv> {
    let dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();
    let mut smv = Smv {
        path: path.to_path_buf(),
        ..Default::default()
    };
    let mut ls = Lines {
        path,
        lines: text.lines().collect(),
        pos: 0,
    };
    while ls.pos < ls.lines.len() {
        let line = ls.lines[ls.pos];
        ls.pos += 1;
        if !is_keyword_line(line) {
            continue;
        }
        let mut toks = line.split_whitespace();
        let kw = toks.next().unwrap_or("");
        let rest: Vec<&str> = toks.collect();
        match kw {
            "CHID" => smv.chid = Some(ls.text("CHID")?),
            "GRID" => {
                let f = ls.field("GRID");
                let v = nums::<i64>(path, &f, ls.next(&f)?, 3)?;
                if v[..3].iter().any(|&c| !(1..=1 << 20).contains(&c)) {
                    return Err(Error::format(
                        path,
                        f,
                        format!(
                            "cell counts {} {} {} must each be between 1 and 2^20",
                            v[0], v[1], v[2]
                        ),
                    ));
                }
                crate::volume::checked_voxel_count([v[0], v[1], v[2]].map(|c| c as u64 + 1))
                    .map_err(|m| Error::format(path, &f, m))?;
                smv.meshes.push(Mesh {
                    name: rest.join(" "),
                    cells: [v[0] as usize, v[1] as usize, v[2] as usize],
                    bounds: [0.0; 6],
                    nodes: [Vec::new(), Vec::new(), Vec::new()],
                });
            }
            "PDIM" => {
                let f = ls.field("PDIM");
                let v = nums::<f32>(path, &f, ls.next(&f)?, 6)?;
                let m = smv
                    .meshes
                    .last_mut()
                    .ok_or_else(|| Error::format(path, &f, "PDIM comes before any GRID line"))?;
                let b: [f32; 6] = [v[0], v[1], v[2], v[3], v[4], v[5]];
                if b.iter().any(|x| !x.is_finite()) || b[1] <= b[0] || b[3] <= b[2] || b[5] <= b[4]
                {
                    return Err(Error::format(
                        path,
                        f,
                        format!("bounds {b:?} must be finite with min < max on each axis"),
                    ));
                }
                m.bounds = b;
            }
            "TRNX" | "TRNY" | "TRNZ" => {
                let a = match kw {
                    "TRNX" => 0,
                    "TRNY" => 1,
                    _ => 2,
                };
                let f = ls.field(kw);
                let n = smv
                    .meshes
                    .last()
                    .ok_or_else(|| Error::format(path, &f, "TRN block before any GRID line"))?
                    .cells[a]
                    + 1;
                let noc = nums::<i64>(path, &f, ls.next(&f)?, 1)?[0];
                if noc < 0 || noc as usize > ls.lines.len() {
                    return Err(Error::format(path, f, format!("bad line count {noc}")));
                }
                ls.pos += noc as usize;
                if ls.pos + n > ls.lines.len() {
                    return Err(Error::format(
                        path,
                        f,
                        format!("the file ends before the {n} node coordinates"),
                    ));
                }
                let mut xs = Vec::with_capacity(n);
                for _ in 0..n {
                    let f = ls.field(kw);
                    let v = nums::<f64>(path, &f, ls.next(&f)?, 2)?;
                    xs.push(v[1] as f32);
                }
                smv.meshes.last_mut().expect("checked above").nodes[a] = xs;
            }
            "OBST" => {
                let f = ls.field("OBST");
                let mesh = smv
                    .meshes
                    .len()
                    .checked_sub(1)
                    .ok_or_else(|| Error::format(path, &f, "OBST before any GRID line"))?;
                let n = nums::<i64>(path, &f, ls.next(&f)?, 1)?[0];
                if n < 0 || (n as usize).saturating_mul(2) > ls.lines.len() - ls.pos {
                    return Err(Error::format(
                        path,
                        f,
                        format!("{n} obstructions announced but the file is too short"),
                    ));
                }
                let n = n as usize;
                let mut boxes = Vec::with_capacity(n);
                for _ in 0..n {
                    let f = ls.field("OBST");
                    let l = ls.next(&f)?;
                    let (nums_part, label) = match l.split_once('!') {
                        Some((a, b)) => (a, b.trim().to_string()),
                        None => (l, String::new()),
                    };
                    let v = nums::<f32>(path, &f, nums_part, 6)?;
                    boxes.push(([v[0], v[1], v[2], v[3], v[4], v[5]], label));
                }
                for (b, label) in boxes {
                    let f = ls.field("OBST");
                    let l = ls.next(&f)?;
                    let nums_part = l.split('!').next().unwrap_or("");
                    let v = nums::<f64>(path, &f, nums_part, 6)?;
                    let cells = [v[0], v[1], v[2], v[3], v[4], v[5]].map(|x| x as i64);
                    let color = if v.len() >= 12 && v[6] as i64 == -3 {
                        Some([v[8] as f32, v[9] as f32, v[10] as f32, v[11] as f32])
                    } else {
                        None
                    };
                    let min = Vec3::new(b[0], b[2], b[4]);
                    let max = Vec3::new(b[1], b[3], b[5]);
                    let size = max - min;
                    if !(min.is_finite() && max.is_finite()) || size.min_element() <= 1e-6 {
                        smv.skipped_obstructions += 1;
                        continue;
                    }
                    smv.obstructions.push(Obstruction {
                        mesh,
                        min,
                        max,
                        label,
                        color,
                        cells: Some(cells),
                    });
                }
            }
            "XYZ" => {
                let file = dir.join(ls.text("XYZ")?);
                let mesh = smv.meshes.len().saturating_sub(1);
                smv.xyz.push((mesh, file));
            }
            "SMOKF3D" | "SMOKE3D" => {
                let f = ls.field(kw);
                let mesh = mesh_index(
                    path,
                    &f,
                    rest.first().copied().unwrap_or(""),
                    smv.meshes.len(),
                )?;
                let k_m = rest
                    .get(1)
                    .and_then(|s| s.parse::<f32>().ok())
                    .filter(|k| k.is_finite())
                    .unwrap_or(0.0);
                let file = dir.join(ls.text(&f)?);
                let quantity = ls.quantity(&f)?;
                smv.smoke3d.push(Smoke3d {
                    file,
                    mesh,
                    k_m,
                    quantity,
                });
            }
            "SLCF" | "SLCC" => {
                let f = ls.field(kw);
                let mesh = mesh_index(
                    path,
                    &f,
                    rest.first().copied().unwrap_or(""),
                    smv.meshes.len(),
                )?;
                let bounds = line.split_once('&').and_then(|(_, b)| {
                    let b = b.split('!').next().unwrap_or("");
                    let v: Vec<usize> =
                        b.split_whitespace().map_while(|t| t.parse().ok()).collect();
                    (v.len() >= 6).then(|| [v[0], v[1], v[2], v[3], v[4], v[5]])
                });
                let is_3d = bounds.is_some_and(|b| b[0] < b[1] && b[2] < b[3] && b[4] < b[5]);
                let file = dir.join(ls.text(&f)?);
                let quantity = ls.quantity(&f)?;
                smv.slices.push(Slice {
                    file,
                    mesh,
                    bounds,
                    quantity,
                    is_3d,
                });
            }
            "PL3D" => {
                let f = ls.field(kw);
                let time_smv = rest
                    .first()
                    .and_then(|s| s.parse::<f64>().ok())
                    .ok_or_else(|| Error::format(path, &f, "no time after PL3D"))?;
                let mesh = mesh_index(
                    path,
                    &f,
                    rest.get(1).copied().unwrap_or(""),
                    smv.meshes.len(),
                )?;
                let name = ls.text(&f)?;
                let time = time_from_q_name(&name).unwrap_or(time_smv);
                let mut quantities = Vec::with_capacity(5);
                for _ in 0..5 {
                    quantities.push(ls.quantity(&f)?);
                }
                smv.pl3d.push(Plot3d {
                    file: dir.join(name),
                    mesh,
                    time,
                    time_smv,
                    quantities,
                });
            }
            _ => {}
        }
    }
    if smv.meshes.is_empty() {
        return Err(Error::format(
            path,
            "GRID",
            "the .smv file has no GRID line",
        ));
    }
    for m in &smv.meshes {
        if m.bounds[1] <= m.bounds[0] {
            return Err(Error::format(
                path,
                "PDIM",
                format!("mesh {} has no PDIM bounds", m.name),
            ));
        }
        for (a, ax) in ["TRNX", "TRNY", "TRNZ"].iter().enumerate() {
            if !m.nodes[a].is_empty() && m.nodes[a].len() != m.cells[a] + 1 {
                return Err(Error::format(path, *ax, "wrong number of node coordinates"));
            }
        }
    }
    Ok(smv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::fds::test_support::smv_path;

    #[test]
    fn q_file_name_times() {
        assert_eq!(time_from_q_name("room_smoke_1_20p01.q"), Some(20.01));
        assert_eq!(time_from_q_name("room_smoke_1_10p00.q"), Some(10.0));
        assert_eq!(time_from_q_name("room_smoke_1.q"), None);
    }

    #[test]
    fn smv_model() {
        let Some(p) = smv_path() else { return };
        let smv = parse_smv(&p).unwrap();
        assert_eq!(smv.chid.as_deref(), Some("room_smoke"));
        assert_eq!(smv.meshes.len(), 1);
        let m = &smv.meshes[0];
        assert_eq!(m.cells, [50, 30, 25]);
        assert_eq!(m.bounds, [0.0, 5.0, 0.0, 3.0, 0.0, 2.5]);
        assert_eq!(m.nodes[0].len(), 51);
        assert!((m.nodes[0][50] - 5.0).abs() < 1e-5);
        assert!((m.cell_size() - Vec3::splat(0.1)).abs().max_element() < 1e-6);
        assert_eq!(smv.obstructions.len(), 22);
        assert_eq!(smv.skipped_obstructions, 1);
        let top = smv
            .obstructions
            .iter()
            .find(|o| o.label == "Table top")
            .unwrap();
        assert_eq!(top.min, Vec3::new(2.0, 1.0, 0.7));
        assert_eq!(top.max, Vec3::new(3.2, 1.8, 0.8));
        assert_eq!(top.cells, Some([20, 32, 10, 18, 7, 8]));
        let c = top.color.unwrap();
        assert!((c[0] - 0.64706).abs() < 1e-5 && c[3] == 1.0);
        assert_eq!(smv.smoke3d.len(), 3);
        assert_eq!(smv.smoke3d[0].k_m, 8700.0);
        assert_eq!(smv.smoke3d[0].quantity.short, "rho_C");
        assert_eq!(smv.smoke3d[1].k_m, 0.0);
        assert_eq!(smv.smoke3d[2].quantity.units, "C");
        assert!(smv.smoke3d[0].file.ends_with("room_smoke_1_1.s3d"));
        let times: Vec<f64> = smv.pl3d.iter().map(|p| p.time).collect();
        assert_eq!(times, [10.0, 20.01, 30.01, 40.0, 50.0, 60.0]);
        assert_eq!(smv.pl3d[1].time_smv, 20.1);
        assert_eq!(smv.pl3d[0].quantities.len(), 5);
        assert_eq!(smv.pl3d[0].quantities[3].short, "ext_coef_C");
        assert_eq!(smv.slices.len(), 4);
        assert!(!smv.slices[0].is_3d && smv.slices[2].is_3d);
        assert_eq!(smv.slices[2].bounds, Some([0, 50, 0, 30, 0, 25]));
        assert_eq!(smv.xyz.len(), 1);
        let sum = smv.summary().join("\n");
        assert!(sum.contains("121 frames, 0 .. 60 s"), "{sum}");
        assert!(sum.contains("13 frames, 0 .. 60 s"), "{sum}");
        assert!(
            sum.contains("times 10, 20.01, 30.01, 40, 50, 60 s"),
            "{sum}"
        );
        assert!(sum.contains("Table top: 2..3.2"), "{sum}");
    }
}
