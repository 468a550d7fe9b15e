//! NIST Fire Dynamics Simulator (FDS) output, opened through its Smokeview
//! index file `.smv`.
//!
//! * [`parse_smv`] reads the `.smv` text: meshes (GRID, PDIM, TRNX/Y/Z),
//!   obstructions (OBST boxes in metres, zero-volume ones skipped), SMOKE3D
//!   files (`SMOKF3D`), PLOT3D files (`PL3D`, time taken from the file name)
//!   and slices (`SLCF`/`SLCC`).
//! * [`read`] picks a quantity (`--var`, default soot density from SMOKE3D)
//!   and a time (`--time`, nearest frame, default the last one) and returns
//!   it as an f32 volume at the mesh nodes. Soot bytes are converted to the
//!   extinction coefficient in 1/m; HRRPUV and temperature bytes to kW/m³ and
//!   °C; `.q` PLOT3D and 3D `.sf` slices are read as floats.
//!
//! Every length read from a binary file is checked against the file's size
//! before anything is allocated; a truncated frame is an error naming the
//! file, the frame and the byte counts.
//!
//! A quantity can be forced to a source with a prefix: `s3d:temp`,
//! `sf:temp`, `q:temp` (also `smoke3d:`, `slice:`, `plot3d:`). Without one,
//! SMOKE3D is tried first, then 3D slices, then PLOT3D.

use super::OpenOptions;
use crate::error::{Error, Result};
use crate::volume::{Volume, VoxelData};
use glam::Vec3;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Largest `.smv` file read (text; real ones are kilobytes to a few MB).
const MAX_SMV_BYTES: u64 = 256 << 20;

/// HRRPUV that maps to byte 254 in SMOKE3D files (FDS HRRPUV_MAX_SMV), kW/m³.
const HRRPUV_MAX_SMV: f32 = 1200.0;
/// Temperatures mapped to bytes 0 and 254 (FDS TMPA, TEMP_MAX_SMV), °C.
const TEMP_MIN_SMV: f32 = 20.0;
const TEMP_MAX_SMV: f32 = 2000.0;

/// A quantity's labels as FDS writes them.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantity {
    /// e.g. `SOOT DENSITY`.
    pub long: String,
    /// e.g. `rho_C`.
    pub short: String,
    /// e.g. `kg/m3`.
    pub units: String,
}

impl Quantity {
    fn matches(&self, name: &str) -> bool {
        let n = name.trim();
        self.long.eq_ignore_ascii_case(n) || self.short.eq_ignore_ascii_case(n)
    }
}

/// One FDS mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// The GRID name, e.g. `MESH_0000001`.
    pub name: String,
    /// Cells along x, y, z (IBAR, JBAR, KBAR).
    pub cells: [usize; 3],
    /// PDIM: xmin xmax ymin ymax zmin zmax, metres.
    pub bounds: [f32; 6],
    /// Node coordinates (TRNX, TRNY, TRNZ): `cells[a] + 1` values each; empty
    /// when the `.smv` has no TRN block for this mesh.
    pub nodes: [Vec<f32>; 3],
}

impl Mesh {
    /// Node counts (IBAR+1, JBAR+1, KBAR+1).
    pub fn node_dims(&self) -> [usize; 3] {
        self.cells.map(|c| c + 1)
    }

    /// Cell size along each axis, from PDIM (uniform grids).
    pub fn cell_size(&self) -> Vec3 {
        let b = self.bounds;
        Vec3::new(
            (b[1] - b[0]) / self.cells[0] as f32,
            (b[3] - b[2]) / self.cells[1] as f32,
            (b[5] - b[4]) / self.cells[2] as f32,
        )
    }

    /// Minimum corner (PDIM).
    pub fn origin(&self) -> Vec3 {
        Vec3::new(self.bounds[0], self.bounds[2], self.bounds[4])
    }

    /// Whether the node coordinates are evenly spaced (true when unknown).
    fn is_uniform(&self) -> bool {
        let h = self.cell_size().to_array();
        let o = self.origin().to_array();
        (0..3).all(|a| {
            self.nodes[a]
                .iter()
                .enumerate()
                .all(|(i, &x)| (x - (o[a] + i as f32 * h[a])).abs() <= 1e-3 * h[a].abs().max(1e-6))
        })
    }
}

/// An obstruction box, world coordinates in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstruction {
    /// Index into [`Smv::meshes`].
    pub mesh: usize,
    pub min: Vec3,
    pub max: Vec3,
    /// The FDS ID (text after `!`), e.g. `Table top`.
    pub label: String,
    /// RGBA in 0..1 when the `.smv` gives it (colour index −3).
    pub color: Option<[f32; 4]>,
    /// Cell index bounds i1 i2 j1 j2 k1 k2 (solid cells i1+1..=i2, 1-based).
    pub cells: Option<[i64; 6]>,
}

/// A SMOKE3D file (`SMOKF3D`/`SMOKE3D`).
#[derive(Clone, Debug, PartialEq)]
pub struct Smoke3d {
    pub file: PathBuf,
    /// Index into [`Smv::meshes`].
    pub mesh: usize,
    /// Mass extinction coefficient K_m (m²/kg); 0 = not soot.
    pub k_m: f32,
    pub quantity: Quantity,
}

/// A PLOT3D solution file (`PL3D`).
#[derive(Clone, Debug, PartialEq)]
pub struct Plot3d {
    pub file: PathBuf,
    pub mesh: usize,
    /// Time in s, from the file name `_<int>p<2 digits>.q` when it has one
    /// (the `.smv` value loses a digit: 20.01 s is written `20.1`).
    pub time: f64,
    /// The time written in the `.smv` line.
    pub time_smv: f64,
    /// Usually 5 quantities, in file order.
    pub quantities: Vec<Quantity>,
}

/// A slice file (`SLCF`, `SLCC`).
#[derive(Clone, Debug, PartialEq)]
pub struct Slice {
    pub file: PathBuf,
    pub mesh: usize,
    /// Node index bounds i1 i2 j1 j2 k1 k2, when the `.smv` line gives them.
    pub bounds: Option<[usize; 6]>,
    pub quantity: Quantity,
    /// True when no axis of `bounds` is degenerate.
    pub is_3d: bool,
}

/// A parsed `.smv` file. File paths are resolved against its folder.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Smv {
    pub path: PathBuf,
    pub chid: Option<String>,
    pub meshes: Vec<Mesh>,
    pub obstructions: Vec<Obstruction>,
    /// Zero-volume OBST entries that were skipped (e.g. door HOLE remnants).
    pub skipped_obstructions: usize,
    pub smoke3d: Vec<Smoke3d>,
    pub pl3d: Vec<Plot3d>,
    pub slices: Vec<Slice>,
    /// PLOT3D grid files (`XYZ`), per mesh index.
    pub xyz: Vec<(usize, PathBuf)>,
}

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

fn is_keyword_line(l: &str) -> bool {
    l.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
}

/// Parses the `.smv` file at `path`.
pub fn parse_smv(path: &Path) -> Result<Smv> {
    let len = super::util::file_len(path)?;
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

// ---------------------------------------------------------------------------
// Binary helpers

fn le_i32(b: &[u8], off: usize) -> i32 {
    i32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

fn le_f32(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

fn open_data(path: &Path, what: &str, smv: &Path) -> Result<(BufReader<std::fs::File>, u64)> {
    let (f, len) = crate::files::open(path)
        .map_err(|e| Error::format(smv, what, format!("cannot open the data file: {e}")))?;
    Ok((BufReader::new(f), len))
}

fn read_at(
    r: &mut BufReader<std::fs::File>,
    path: &Path,
    len: u64,
    off: u64,
    n: usize,
    field: &str,
) -> Result<Vec<u8>> {
    if off.checked_add(n as u64).is_none_or(|end| end > len) {
        return Err(Error::format(
            path,
            field,
            format!(
                "needs bytes {off}..{} but the file has only {len} (truncated file?)",
                off.saturating_add(n as u64)
            ),
        ));
    }
    r.seek(SeekFrom::Start(off))
        .map_err(|e| Error::io(path, e))?;
    let mut buf = vec![0u8; n];
    r.read_exact(&mut buf).map_err(|e| Error::io(path, e))?;
    Ok(buf)
}

// ---------------------------------------------------------------------------
// SMOKE3D

/// One decoded SMOKE3D frame.
#[derive(Clone, Debug)]
pub struct S3dFrame {
    /// Time of this frame, s.
    pub time: f32,
    /// Index of this frame in the file.
    pub index: usize,
    /// The times of all frames in the file.
    pub times: Vec<f32>,
    /// Node bounds from the header: i1 i2 j1 j2 k1 k2.
    pub bounds: [usize; 6],
    /// Node counts.
    pub dims: [usize; 3],
    /// The decoded bytes, i fastest.
    pub bytes: Vec<u8>,
}

/// Decodes FDS/Smokeview RLE: `0xFF value count` is a run, anything else a
/// literal. The output must be exactly `nin` bytes.
pub fn decode_rle(input: &[u8], nin: usize) -> std::result::Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(nin);
    let mut i = 0;
    while i < input.len() {
        let b = input[i];
        if b == 0xFF {
            if i + 2 >= input.len() {
                return Err(format!("RLE run at byte {i} is cut off"));
            }
            let (v, n) = (input[i + 1], input[i + 2] as usize);
            if out.len() + n > nin {
                return Err(format!("RLE data decodes to more than {nin} values"));
            }
            out.resize(out.len() + n, v);
            i += 3;
        } else {
            if out.len() >= nin {
                return Err(format!("RLE data decodes to more than {nin} values"));
            }
            out.push(b);
            i += 1;
        }
    }
    if out.len() != nin {
        return Err(format!(
            "RLE data decodes to {} values, expected {nin}",
            out.len()
        ));
    }
    Ok(out)
}

/// Reads the frame of the `.s3d` file at `path` nearest to `time` (the last
/// one when `None`). Only that frame is decoded; the others are skipped.
pub fn read_s3d_frame(path: &Path, time: Option<f64>) -> Result<S3dFrame> {
    read_s3d(path, time, true)
}

/// The times of all frames of an `.s3d` file (headers only, nothing decoded).
pub fn s3d_times(path: &Path) -> Result<Vec<f32>> {
    Ok(read_s3d(path, None, false)?.times)
}

fn read_s3d(path: &Path, time: Option<f64>, decode: bool) -> Result<S3dFrame> {
    let (mut r, len) = open_data(path, "SMOKF3D", path)?;
    let h = read_at(&mut r, path, len, 0, 40, "header")?;
    if le_i32(&h, 0) != 32 || le_i32(&h, 36) != 32 {
        return Err(Error::format(
            path,
            "header",
            format!(
                "record markers {} and {} should be 32 (not a little-endian SMOKE3D file?)",
                le_i32(&h, 0),
                le_i32(&h, 36)
            ),
        ));
    }
    if le_i32(&h, 4) != 1 {
        return Err(Error::unsupported(
            path,
            format!("endian flag {} (expected 1)", le_i32(&h, 4)),
        ));
    }
    if le_i32(&h, 8) != 0 {
        return Err(Error::unsupported(
            path,
            format!("SMOKE3D version {} (only 0 = RLE is read)", le_i32(&h, 8)),
        ));
    }
    let b: Vec<i32> = (0..6).map(|a| le_i32(&h, 12 + 4 * a)).collect();
    if (0..3).any(|a| b[2 * a] < 0 || b[2 * a + 1] < b[2 * a]) {
        return Err(Error::format(
            path,
            "header",
            format!("node bounds {b:?} must satisfy 0 <= i1 <= i2 etc."),
        ));
    }
    let bounds = [0, 1, 2, 3, 4, 5].map(|a| b[a] as usize);
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    let nin_expected = crate::volume::checked_voxel_count(dims.map(|d| d as u64))
        .map_err(|m| Error::format(path, "header", m))?;

    // Scan frame headers.
    let mut frames: Vec<(f32, u64, usize)> = Vec::new();
    let mut off = 40u64;
    while off < len {
        let k = frames.len();
        let field = format!("frame {k}");
        let fh = read_at(&mut r, path, len, off, 32, &field)?;
        if le_i32(&fh, 0) != 4
            || le_i32(&fh, 8) != 4
            || le_i32(&fh, 12) != 8
            || le_i32(&fh, 24) != 8
        {
            return Err(Error::format(
                path,
                field,
                format!("bad record markers at byte {off}"),
            ));
        }
        let t = le_f32(&fh, 4);
        let nin = le_i32(&fh, 16);
        let nout = le_i32(&fh, 20);
        if nin < 0 || nin as usize != nin_expected {
            return Err(Error::format(
                path,
                field,
                format!("nin = {nin}, expected {nin_expected} nodes"),
            ));
        }
        if nout < 0 || le_i32(&fh, 28) != nout {
            return Err(Error::format(
                path,
                field,
                format!(
                    "nout = {nout} and its record marker {} disagree",
                    le_i32(&fh, 28)
                ),
            ));
        }
        let end = off + 36 + nout as u64;
        if end > len {
            return Err(Error::format(
                path,
                field,
                format!(
                    "frame at t = {t} s needs bytes {off}..{end} but the file has only {len} (truncated file?)"
                ),
            ));
        }
        frames.push((t, off, nout as usize));
        off = end;
    }
    if frames.is_empty() {
        return Err(Error::format(path, "frames", "the file holds no frame"));
    }
    let times: Vec<f32> = frames.iter().map(|f| f.0).collect();
    let index = pick_time(
        path,
        &times.iter().map(|&t| t as f64).collect::<Vec<_>>(),
        time,
    )?;
    let (t, foff, nout) = frames[index];
    let field = format!("frame {index}");
    if !decode {
        return Ok(S3dFrame {
            time: t,
            index,
            times,
            bounds,
            dims,
            bytes: Vec::new(),
        });
    }
    // A 3-byte run holds at most 254 values: bound the output by the input.
    if nin_expected as u64 > nout as u64 * 85 {
        return Err(Error::format(
            path,
            &field,
            format!("{nout} RLE bytes cannot hold {nin_expected} values"),
        ));
    }
    let data = read_at(&mut r, path, len, foff + 32, nout + 4, &field)?;
    if le_i32(&data, nout) != nout as i32 {
        return Err(Error::format(path, &field, "bad closing record marker"));
    }
    let bytes =
        decode_rle(&data[..nout], nin_expected).map_err(|m| Error::format(path, &field, m))?;
    Ok(S3dFrame {
        time: t,
        index,
        times,
        bounds,
        dims,
        bytes,
    })
}

/// The index of the time nearest `want` (the last when `None`). A time
/// further than one mean frame interval outside the range is an error.
fn pick_time(path: &Path, times: &[f64], want: Option<f64>) -> Result<usize> {
    let n = times.len();
    let Some(t) = want else {
        return Ok(n - 1);
    };
    let (lo, hi) = times
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let tol = if n > 1 {
        (hi - lo) / (n - 1) as f64
    } else {
        1e-6 + 1e-3 * hi.abs()
    };
    if !t.is_finite() || t < lo - tol || t > hi + tol {
        return Err(Error::format(
            path,
            "time",
            format!("t = {t} is outside the {n} frames of this file: {lo} .. {hi} s"),
        ));
    }
    let mut best = 0;
    for (i, &x) in times.iter().enumerate() {
        if (x - t).abs() < (times[best] - t).abs() {
            best = i;
        }
    }
    Ok(best)
}

/// Converts a SMOKE3D byte to a physical value. Soot (`k_m > 0`): the byte
/// is 254 × the opacity of one cell width `dx`, so the extinction coefficient
/// is `−ln(1 − b/254)/dx` (1/m). HRRPUV and temperature use FDS's linear maps.
fn s3d_value_map(s: &Smoke3d, dx: f32) -> (Box<dyn Fn(u8) -> f32>, Option<String>) {
    let long = s.quantity.long.to_ascii_uppercase();
    if s.k_m > 0.0 {
        (
            Box::new(move |b| soot_extinction(b, dx)),
            Some("1/m".into()),
        )
    } else if long == "HRRPUV" {
        (
            Box::new(|b| b as f32 * HRRPUV_MAX_SMV / 254.0),
            Some(s.quantity.units.clone()),
        )
    } else if long == "TEMPERATURE" {
        (
            Box::new(|b| TEMP_MIN_SMV + b as f32 * (TEMP_MAX_SMV - TEMP_MIN_SMV) / 254.0),
            Some(s.quantity.units.clone()),
        )
    } else {
        (Box::new(|b| b as f32), None)
    }
}

/// Extinction coefficient (1/m) of a soot byte for cell width `dx`.
pub fn soot_extinction(b: u8, dx: f32) -> f32 {
    // 254 would be fully opaque; keep it finite.
    let a = (b.min(253) as f64) / 254.0;
    ((1.0 - a).ln().abs() / dx as f64) as f32
}

// ---------------------------------------------------------------------------
// PLOT3D .q and .xyz

/// Reads variable `n` (0..5) of a PLOT3D `.q` file with node dims `dims`.
pub fn read_q_variable(path: &Path, dims: [usize; 3], n: usize) -> Result<Vec<f32>> {
    let (mut r, len) = open_data(path, "PL3D", path)?;
    let h = read_at(&mut r, path, len, 0, 48, "header")?;
    if le_i32(&h, 0) != 12 || le_i32(&h, 16) != 12 || le_i32(&h, 20) != 16 || le_i32(&h, 40) != 16 {
        return Err(Error::format(
            path,
            "header",
            "bad record markers (not a PLOT3D .q file?)",
        ));
    }
    check_plot3d_dims(path, &h, dims)?;
    let np = dims[0] * dims[1] * dims[2];
    let nq = (le_i32(&h, 44).max(0) as u64) / (4 * np as u64);
    if nq == 0 || le_i32(&h, 44) as u64 != nq * 4 * np as u64 {
        return Err(Error::format(
            path,
            "data",
            format!(
                "record of {} bytes is not a whole number of variables",
                le_i32(&h, 44)
            ),
        ));
    }
    if n as u64 >= nq {
        return Err(Error::format(
            path,
            "variable",
            format!("index {n} of {nq}"),
        ));
    }
    let b = read_at(&mut r, path, len, 48 + (4 * np * n) as u64, 4 * np, "data")?;
    Ok(b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Checks the node dims in a PLOT3D header (`.q` or `.xyz`) against the mesh.
fn check_plot3d_dims(path: &Path, h: &[u8], dims: [usize; 3]) -> Result<()> {
    let d = [le_i32(h, 4), le_i32(h, 8), le_i32(h, 12)];
    if d.map(|x| x as i64) != dims.map(|x| x as i64) {
        return Err(Error::format(
            path,
            "dims",
            format!("{d:?} but the mesh has {dims:?} nodes"),
        ));
    }
    Ok(())
}

/// The iblank array of a PLOT3D `.xyz` file (0 = all 8 cells round the node are solid).
pub fn read_xyz_iblank(path: &Path, dims: [usize; 3]) -> Result<Vec<i32>> {
    let (mut r, len) = open_data(path, "XYZ", path)?;
    let h = read_at(&mut r, path, len, 0, 24, "header")?;
    check_plot3d_dims(path, &h, dims)?;
    let np = dims[0] * dims[1] * dims[2];
    let b = read_at(&mut r, path, len, 24 + 12 * np as u64, 4 * np, "iblank")?;
    Ok(b.chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Node iblank computed from the OBST cell boxes (ghost cells outside the
/// mesh copy the nearest interior cell): 0 where all 8 surrounding cells are solid.
fn iblank_from_obst(smv: &Smv, mesh: usize) -> Vec<i32> {
    let m = &smv.meshes[mesh];
    let [ci, cj, ck] = m.cells;
    let mut solid = vec![false; ci * cj * ck];
    for o in smv.obstructions.iter().filter(|o| o.mesh == mesh) {
        if let Some(c) = o.cells {
            let cl = |a: i64, n: usize| a.clamp(0, n as i64) as usize;
            for k in cl(c[4], ck)..cl(c[5], ck) {
                for j in cl(c[2], cj)..cl(c[3], cj) {
                    for i in cl(c[0], ci)..cl(c[1], ci) {
                        solid[i + ci * (j + cj * k)] = true;
                    }
                }
            }
        }
    }
    let [ni, nj, nk] = m.node_dims();
    let mut ib = vec![1; ni * nj * nk];
    for k in 0..nk {
        for j in 0..nj {
            for i in 0..ni {
                let mut all = true;
                'o: for dk in 0..2 {
                    for dj in 0..2 {
                        for di in 0..2 {
                            // Ghost cells outside the mesh copy the
                            // nearest interior cell.
                            let x = (i + di).clamp(1, ci);
                            let y = (j + dj).clamp(1, cj);
                            let z = (k + dk).clamp(1, ck);
                            if !solid[(x - 1) + ci * ((y - 1) + cj * (z - 1))] {
                                all = false;
                                break 'o;
                            }
                        }
                    }
                }
                if all {
                    ib[i + ni * (j + nj * k)] = 0;
                }
            }
        }
    }
    ib
}

// ---------------------------------------------------------------------------
// Slices

/// One frame of a `.sf` slice file.
#[derive(Clone, Debug)]
pub struct SfFrame {
    pub time: f32,
    /// The times of all complete frames.
    pub times: Vec<f32>,
    /// Node bounds i1 i2 j1 j2 k1 k2.
    pub bounds: [usize; 6],
    /// Values, i fastest.
    pub values: Vec<f32>,
}

/// Reads the frame nearest `time` (the last when `None`) of a `.sf` file;
/// only that frame's values are read.
pub fn read_sf_frame(path: &Path, time: Option<f64>) -> Result<SfFrame> {
    let (mut r, len) = open_data(path, "SLCF", path)?;
    let h = read_at(&mut r, path, len, 0, 146, "header")?;
    for k in 0..3 {
        if le_i32(&h, 38 * k) != 30 || le_i32(&h, 38 * k + 34) != 30 {
            return Err(Error::format(path, "header", "bad label record markers"));
        }
    }
    if le_i32(&h, 114) != 24 || le_i32(&h, 142) != 24 {
        return Err(Error::format(path, "header", "bad bounds record markers"));
    }
    let b: Vec<i32> = (0..6).map(|a| le_i32(&h, 118 + 4 * a)).collect();
    if (0..3).any(|a| b[2 * a] < 0 || b[2 * a + 1] < b[2 * a]) {
        return Err(Error::format(path, "bounds", format!("{b:?}")));
    }
    let bounds = [0, 1, 2, 3, 4, 5].map(|a| b[a] as usize);
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    let np = crate::volume::checked_voxel_count(dims.map(|d| d as u64))
        .map_err(|m| Error::format(path, "bounds", m))?;
    // frame = [4|t|4] (12 bytes) + [4N|data|4N] (4N+8 bytes)
    let fsize = 12 + 4 * np as u64 + 8;
    let nframes = (len - 146) / fsize;
    if nframes == 0 {
        return Err(Error::format(
            path,
            "frames",
            "the file holds no complete frame",
        ));
    }
    let mut times = Vec::with_capacity(nframes as usize);
    for k in 0..nframes {
        let off = 146 + k * fsize;
        let t = read_at(&mut r, path, len, off, 20, &format!("frame {k}"))?;
        if le_i32(&t, 0) != 4 || le_i32(&t, 8) != 4 || le_i32(&t, 12) as i64 != 4 * np as i64 {
            return Err(Error::format(
                path,
                format!("frame {k}"),
                "bad record markers",
            ));
        }
        times.push(le_f32(&t, 4));
    }
    let idx = pick_time(
        path,
        &times.iter().map(|&t| t as f64).collect::<Vec<_>>(),
        time,
    )?;
    let d = read_at(
        &mut r,
        path,
        len,
        146 + idx as u64 * fsize + 16,
        4 * np,
        "data",
    )?;
    let v = d
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(SfFrame {
        time: times[idx],
        times,
        bounds,
        values: v,
    })
}

// ---------------------------------------------------------------------------
// Quantity selection and read

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
    Volume::new(dims, h, origin, VoxelData::F32(data))
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

/// The PLOT3D/slice solid-node quirk: nodes whose 8 surrounding cells are all
/// solid hold the quantity's ambient value (air density, 1.195 kg/m³, for
/// soot DENSITY). Gives them the minimum over gas nodes instead. `bounds` are
/// the node bounds of `data` within the mesh (checked by the caller).
fn mask_solid_nodes(smv: &Smv, mesh: usize, bounds: [usize; 6], data: &mut [f32]) {
    let nd = smv.meshes[mesh].node_dims();
    let iblank = smv
        .xyz
        .iter()
        .find(|x| x.0 == mesh)
        .and_then(|x| read_xyz_iblank(&x.1, nd).ok())
        .unwrap_or_else(|| iblank_from_obst(smv, mesh));
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    if data.len() != dims[0] * dims[1] * dims[2] {
        return;
    }
    let solid = |n: usize| {
        let (i, j, k) = (
            n % dims[0],
            (n / dims[0]) % dims[1],
            n / (dims[0] * dims[1]),
        );
        let (i, j, k) = (i + bounds[0], j + bounds[2], k + bounds[4]);
        iblank[i + nd[0] * (j + nd[1] * k)] == 0
    };
    let gas_min = data
        .iter()
        .enumerate()
        .filter(|(n, _)| !solid(*n))
        .map(|(_, &v)| v)
        .fold(f32::INFINITY, f32::min);
    if gas_min.is_finite() {
        for (n, v) in data.iter_mut().enumerate() {
            if solid(n) {
                *v = gas_min;
            }
        }
    }
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

    fn smv_path() -> Option<PathBuf> {
        crate::testdata::data_path("fds_room/room_smoke.smv")
    }

    fn opts(var: Option<&str>, time: Option<f64>) -> OpenOptions {
        OpenOptions {
            variable: var.map(String::from),
            time,
            ..Default::default()
        }
    }

    /// Copies the case into a temp dir.
    fn copy_case(src: &Path) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for e in std::fs::read_dir(src.parent().unwrap()).unwrap() {
            let e = e.unwrap();
            let n = e.file_name().to_string_lossy().to_string();
            if n.ends_with(".smv") || n.ends_with("_1_1.s3d") || n.ends_with(".xyz") {
                std::fs::copy(e.path(), dir.path().join(&n)).unwrap();
            }
        }
        dir
    }

    #[test]
    fn rle_decodes_runs_and_literals() {
        assert_eq!(
            decode_rle(&[1, 0xFF, 7, 4, 2], 6).unwrap(),
            [1, 7, 7, 7, 7, 2]
        );
        assert!(decode_rle(&[0xFF, 7, 200], 6).is_err());
        assert!(decode_rle(&[1, 2], 3).is_err());
        assert!(decode_rle(&[0xFF, 7], 3).is_err());
    }

    #[test]
    fn q_file_name_times() {
        assert_eq!(time_from_q_name("room_smoke_1_20p01.q"), Some(20.01));
        assert_eq!(time_from_q_name("room_smoke_1_10p00.q"), Some(10.0));
        assert_eq!(time_from_q_name("room_smoke_1.q"), None);
    }

    #[test]
    fn extinction_of_a_known_byte() {
        // b = 127: half the light lost over one 0.1 m cell: ln 2 / 0.1.
        let s = soot_extinction(127, 0.1);
        assert!((s - (2f32).ln() / 0.1).abs() < 1e-4, "{s}");
        assert_eq!(soot_extinction(0, 0.1), 0.0);
        assert!(soot_extinction(254, 0.1).is_finite());
        // sigma = K_m * rho: byte 181 ≈ 1.4e-3 kg/m3 at K_m = 8700.
        let rho = soot_extinction(181, 0.1) / 8700.0;
        assert!((rho - 1.4e-3).abs() < 0.1e-3, "{rho}");
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

    #[test]
    fn soot_bytes_at_30s_match_format_md() {
        let Some(p) = smv_path() else { return };
        let s3d = p.parent().unwrap().join("room_smoke_1_1.s3d");
        let f = read_s3d_frame(&s3d, Some(30.0)).unwrap();
        assert_eq!(f.times.len(), 121);
        assert!((f.time - 30.0).abs() < 0.3, "{}", f.time);
        assert_eq!(f.dims, [51, 31, 26]);
        let n = f.bytes.len() as f64;
        let min = *f.bytes.iter().min().unwrap();
        let max = *f.bytes.iter().max().unwrap();
        let mean = f.bytes.iter().map(|&b| b as f64).sum::<f64>() / n;
        let nz = f.bytes.iter().filter(|&&b| b > 0).count() as f64 / n;
        assert_eq!((min, max), (0, 167));
        assert!((mean - 41.9).abs() < 0.05, "{mean}");
        assert!((nz - 0.69).abs() < 0.005, "{nz}");
        let last = read_s3d_frame(&s3d, None).unwrap();
        assert_eq!(last.index, 120);
        assert_eq!(*last.bytes.iter().max().unwrap(), 175);
        let mean = last.bytes.iter().map(|&b| b as f64).sum::<f64>() / n;
        assert!((mean - 47.7).abs() < 0.05, "{mean}");
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
    fn iblank_from_obst_matches_xyz() {
        let Some(p) = smv_path() else { return };
        let smv = parse_smv(&p).unwrap();
        let xyz = read_xyz_iblank(&smv.xyz[0].1, [51, 31, 26]).unwrap();
        assert_eq!(xyz.iter().filter(|&&b| b == 0).count(), 820);
        let ob = iblank_from_obst(&smv, 0);
        let diff = xyz.iter().zip(&ob).filter(|(a, b)| a != b).count();
        assert_eq!(diff, 0);
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
    fn corrupt_headers_never_panic() {
        let Some(p) = smv_path() else { return };
        let dir = copy_case(&p);
        let s3d = dir.path().join("room_smoke_1_1.s3d");
        let bytes = std::fs::read(&s3d).unwrap();
        for off in 0..120 {
            for v in [0u8, 0x7f, 0xff] {
                let mut b = bytes[..200_000].to_vec();
                b[off] = v;
                std::fs::write(&s3d, &b).unwrap();
                let _ = read_s3d_frame(&s3d, Some(0.0));
            }
        }
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
