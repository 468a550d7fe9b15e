//! WRF (Weather Research and Forecasting model) output: `wrfout` NetCDF-4
//! files, the weather data S3 fills its clouds from. Behind this crate's
//! feature `wrf` (the `netcdf` crate over the system's libnetcdf).
//!
//! What is read: a mass-grid 4D variable `(Time, bottom_top, south_north,
//! west_east)` — QCLOUD by default, or a sum such as `QCLOUD+QICE` — at one
//! time index (`--time INDEX`). WRF's vertical coordinate is terrain-
//! following (eta), so each column's true heights come from the geopotential,
//! `z = (PH + PHB) / g` on the staggered levels (`bottom_top_stag`), averaged
//! to the mass levels; the column is then resampled linearly onto a regular
//! vertical grid from the lowest to the highest mass level of the domain.
//! Horizontal spacing is the file's `DX`, `DY` (metres).

use glam::Vec3;
use std::path::Path;
use voxcast::error::{Error, Result};
use voxcast::io::OpenOptions;
use voxcast::volume::{Volume, VoxelData};

/// Standard gravity used by WRF for geopotential (m s⁻²).
pub const G: f32 = 9.81;

const MASS_DIMS: [&str; 4] = ["Time", "bottom_top", "south_north", "west_east"];

fn nc_err(path: &Path, field: &str, e: netcdf::Error) -> Error {
    Error::format(path, field, e.to_string())
}

fn open(path: &Path) -> Result<netcdf::File> {
    // The C library opens the path itself: record it as an input and
    // refuse a device or a pipe first.
    voxcast::files::open(path)?;
    netcdf::open(path)
        .map_err(|e| Error::format(path, "file", format!("not a readable NetCDF file: {e}")))
}

/// Names of the mass-grid 4D variables (what `--var` can name).
fn mass_variables(f: &netcdf::File) -> Vec<String> {
    let mut v: Vec<String> = f
        .variables()
        .filter(|v| {
            let d: Vec<String> = v.dimensions().iter().map(|d| d.name()).collect();
            d == MASS_DIMS
        })
        .map(|v| v.name())
        .collect();
    v.sort();
    v
}

/// The `Times` strings of the file at `path`, one per time index.
pub fn times(path: &Path) -> Result<Vec<String>> {
    let f = open(path)?;
    times_of(path, &f)
}

/// The `Times` strings (one per time index).
fn times_of(path: &Path, f: &netcdf::File) -> Result<Vec<String>> {
    let n = f.dimension_len("Time").unwrap_or(0);
    let Some(v) = f.variable("Times") else {
        return Ok((0..n).map(|i| format!("index {i}")).collect());
    };
    let raw = v.get_raw_values(..).map_err(|e| nc_err(path, "Times", e))?;
    let len = raw.len() / n.max(1);
    Ok(raw
        .chunks(len.max(1))
        .take(n)
        .map(|c| {
            String::from_utf8_lossy(c)
                .trim_end_matches('\0')
                .trim()
                .to_string()
        })
        .collect())
}

/// One time of a 4D variable, as `[nz][ny][nx]` f32 (x fastest), with
/// its dims `[nx, ny, nz]`.
fn var_at(path: &Path, f: &netcdf::File, name: &str, t: usize) -> Result<(Vec<f32>, [usize; 3])> {
    let v = f.variable(name).ok_or_else(|| {
        Error::format(
            path,
            name,
            format!(
                "no such variable (the file's 3D fields: {})",
                mass_variables(f).join(", ")
            ),
        )
    })?;
    let d = v.dimensions();
    if d.len() != 4 || d[0].name() != "Time" {
        return Err(Error::format(
            path,
            name,
            "expected dimensions (Time, z, y, x)",
        ));
    }
    let dims = [d[3].len(), d[2].len(), d[1].len()];
    let data: Vec<f32> = v
        .get_values::<f32, _>((t, .., .., ..))
        .map_err(|e| nc_err(path, name, e))?;
    if data.len() != dims[0] * dims[1] * dims[2] {
        return Err(Error::format(
            path,
            name,
            "size does not match its dimensions",
        ));
    }
    Ok((data, dims))
}

fn time_index(path: &Path, f: &netcdf::File, opts: &OpenOptions) -> Result<usize> {
    let n = f.dimension_len("Time").unwrap_or(0);
    if n == 0 {
        return Err(Error::format(path, "Time", "the file holds no time"));
    }
    let t = opts.time.unwrap_or(0.0);
    if !(t >= 0.0 && t.fract() == 0.0 && (t as usize) < n) {
        return Err(Error::format(
            path,
            "Time",
            format!(
                "--time {t}: a WRF file's --time is a time index, 0…{} here",
                n - 1
            ),
        ));
    }
    Ok(t as usize)
}

/// The variable (or `A+B` sum) at time index `t` on WRF's own grid
/// (eta levels), with dims `[nx, ny, nz]`.
pub fn read_native(path: &Path, spec: &str, t: usize) -> Result<(Vec<f32>, [usize; 3])> {
    let f = open(path)?;
    native(path, &f, spec, t)
}

fn native(path: &Path, f: &netcdf::File, spec: &str, t: usize) -> Result<(Vec<f32>, [usize; 3])> {
    let mut sum: Option<(Vec<f32>, [usize; 3])> = None;
    for name in spec.split('+').map(str::trim) {
        let (d, dims) = var_at(path, f, name, t)?;
        if !{
            let v = f.variable(name).expect("read above");
            v.dimensions().iter().map(|d| d.name()).eq(MASS_DIMS)
        } {
            return Err(Error::format(
                path,
                name,
                format!(
                    "not on the mass grid (Time, bottom_top, south_north, west_east); mass-grid fields: {}",
                    mass_variables(f).join(", ")
                ),
            ));
        }
        sum = Some(match sum {
            None => (d, dims),
            Some((mut s, sd)) => {
                for (a, b) in s.iter_mut().zip(&d) {
                    *a += b;
                }
                (s, sd)
            }
        });
    }
    sum.ok_or_else(|| Error::invalid("--var: no variable named"))
}

/// True heights (m) of the mass levels, `[nz][ny][nx]`: the staggered
/// geopotential heights `(PH + PHB)/g` averaged to the mass levels.
pub fn column_heights(path: &Path, t: usize) -> Result<(Vec<f32>, [usize; 3])> {
    let f = open(path)?;
    heights(path, &f, t)
}

fn heights(path: &Path, f: &netcdf::File, t: usize) -> Result<(Vec<f32>, [usize; 3])> {
    let (ph, ds) = var_at(path, f, "PH", t)?;
    let (phb, _) = var_at(path, f, "PHB", t)?;
    if ds[2] < 2 {
        return Err(Error::format(
            path,
            "PH",
            "needs at least two staggered levels",
        ));
    }
    let (nx, ny, nz) = (ds[0], ds[1], ds[2] - 1);
    let plane = nx * ny;
    let mut z = vec![0f32; plane * nz];
    for k in 0..nz {
        for i in 0..plane {
            let lo = (ph[k * plane + i] + phb[k * plane + i]) / G;
            let hi = (ph[(k + 1) * plane + i] + phb[(k + 1) * plane + i]) / G;
            z[k * plane + i] = 0.5 * (lo + hi);
        }
    }
    Ok((z, [nx, ny, nz]))
}

fn global_f32(f: &netcdf::File, name: &str) -> Option<f32> {
    match f.attribute(name)?.value().ok()? {
        netcdf::AttributeValue::Float(v) => Some(v),
        netcdf::AttributeValue::Double(v) => Some(v as f32),
        netcdf::AttributeValue::Floats(v) => v.first().copied(),
        netcdf::AttributeValue::Doubles(v) => v.first().map(|&x| x as f32),
        _ => None,
    }
}

/// Reads the variable `opts.variable` (default QCLOUD; `A+B` sums) at time
/// index `opts.time` (default 0), resampled to a regular height grid.
pub fn read(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let f = open(path)?;
    let t = time_index(path, &f, opts)?;
    let spec = opts.variable.clone().unwrap_or_else(|| "QCLOUD".into());
    let (q, dims) = native(path, &f, &spec, t)?;
    let (z, zd) = heights(path, &f, t)?;
    if zd != dims {
        return Err(Error::format(
            path,
            "PH",
            format!("geopotential grid {zd:?} does not match {spec}'s {dims:?}"),
        ));
    }
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    // A regular vertical grid over the domain's mass levels, as fine as
    // the thinnest mean layer (capped at 4× the level count).
    let bottom = (0..plane).map(|i| z[i]).fold(f32::INFINITY, f32::min);
    let top = (0..plane)
        .map(|i| z[(nz - 1) * plane + i])
        .fold(f32::NEG_INFINITY, f32::max);
    let mut thin = f32::INFINITY;
    for k in 0..nz.saturating_sub(1) {
        let mean: f32 = (0..plane)
            .map(|i| z[(k + 1) * plane + i] - z[k * plane + i])
            .sum::<f32>()
            / plane as f32;
        thin = thin.min(mean);
    }
    if !(bottom.is_finite() && top > bottom && thin > 0.0) {
        return Err(Error::format(path, "PH", "heights do not increase upward"));
    }
    let nz_out = (((top - bottom) / thin).ceil() as usize + 1).clamp(nz, 4 * nz);
    let dz = (top - bottom) / (nz_out - 1) as f32;
    let mut out = vec![0f32; plane * nz_out];
    for i in 0..plane {
        let mut k = 0;
        for ko in 0..nz_out {
            let h = bottom + ko as f32 * dz;
            // Outside the column's levels (below ground, above the top):
            // no cloud.
            if h < z[i] || h > z[(nz - 1) * plane + i] {
                continue;
            }
            while k + 2 < nz && z[(k + 1) * plane + i] < h {
                k += 1;
            }
            let (z0, z1) = (z[k * plane + i], z[(k + 1).min(nz - 1) * plane + i]);
            let w = if z1 > z0 {
                ((h - z0) / (z1 - z0)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let (a, b) = (q[k * plane + i], q[(k + 1).min(nz - 1) * plane + i]);
            out[ko * plane + i] = a + (b - a) * w;
        }
    }
    let dx = global_f32(&f, "DX").filter(|v| *v > 0.0).unwrap_or(1000.0);
    let dy = global_f32(&f, "DY").filter(|v| *v > 0.0).unwrap_or(dx);
    let mut vol = Volume::new(
        [nx, ny, nz_out],
        Vec3::new(dx, dy, dz),
        Vec3::new(0.0, 0.0, bottom),
        VoxelData::F32(out.into()),
    )?;
    vol.name = Some(spec);
    vol.units = Some("kg/kg".into());
    vol.variables = mass_variables(&f);
    vol.time = Some(t as f64);
    Ok(vol)
}

/// Lines describing the file for `voxcast info`: variables and times.
pub fn summary(path: &Path) -> Result<Vec<String>> {
    let f = open(path)?;
    let mut lines = vec![format!(
        "3D fields (--var, A+B sums): {}",
        mass_variables(&f).join(", ")
    )];
    for (i, t) in times_of(path, &f)?.iter().enumerate() {
        lines.push(format!("time {i}: {t}"));
    }
    if let (Some(dx), Some(dy)) = (global_f32(&f, "DX"), global_f32(&f, "DY")) {
        lines.push(format!(
            "grid spacing {dx} × {dy} m; heights from (PH+PHB)/{G}"
        ));
    }
    Ok(lines)
}
