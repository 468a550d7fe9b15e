//! MINC-2 volumes (`.mnc`, HDF5), behind this crate's feature `minc`:
//! libnetcdf (the `netcdf` crate, shared with the `wrf` feature) opens
//! MINC-2's HDF5 layout, so no HDF5 binding of our own is needed. Without
//! the feature a `.mnc` file is refused by `voxcast::io::open`, naming the
//! feature to enable and a converter. (MINC-1 files are NetCDF-3: they are
//! not read.)
//!
//! * layout: `/minc-2.0/image/0/image`, whose `dimorder` attribute names its
//!   dimensions slowest first; exactly `xspace`, `yspace` and `zspace`, in
//!   any order (a time or vector dimension is refused). The volume is
//!   reordered so that voxcast's x, y, z are `xspace`, `yspace`, `zspace`.
//! * spacing: `|step|` of `/minc-2.0/dimensions/{x,y,z}space` (1 when
//!   absent); origin: their `start` (0 when absent) — the position of voxel
//!   0 along each axis. `direction_cosines` and the flip of a negative step
//!   are not applied (voxcast volumes are axis aligned).
//! * values: integer voxels are normalised to real values as libminc does,
//!   `real = image-min + (v − vmin)·(image-max − image-min)/(vmax − vmin)`,
//!   with `image-min`/`image-max` per slice (their `dimorder` is the image's
//!   slowest dimensions) or scalar, and `[vmin, vmax]` the image's
//!   `valid_range` or else the full range of its type; the result is f32.
//!   Without `image-min`/`image-max` (or for float voxels) the stored values
//!   are kept: u8, i16 and u16 as they are, other types as f32.

use glam::Vec3;
use netcdf::types::{FloatType, IntType, NcVariableType};
use netcdf::AttributeValue;
use std::path::Path;
use voxcast::error::{Error, Result};
use voxcast::io::util::{file_len, MAX_DEFLATE_RATIO};
use voxcast::volume::{checked_voxel_count, Volume, VoxelData};

const AXES: [&str; 3] = ["xspace", "yspace", "zspace"];

fn nc_err(path: &Path, field: &str, e: netcdf::Error) -> Error {
    Error::format(path, field, e.to_string())
}

/// What the header says, checked.
struct Header {
    /// Image dimension names and lengths, slowest first.
    order: Vec<(String, usize)>,
    /// Per voxcast axis: length, start, step.
    axes: [(usize, f64, f64); 3],
    ty: NcVariableType,
    valid_range: Option<[f64; 2]>,
    /// `image-min`/`image-max` values and their dimorder.
    scale: Option<(Vec<f64>, Vec<f64>, Vec<String>)>,
}

fn att_f64s(a: AttributeValue) -> Option<Vec<f64>> {
    Some(match a {
        AttributeValue::Double(x) => vec![x],
        AttributeValue::Doubles(x) => x,
        AttributeValue::Float(x) => vec![x as f64],
        AttributeValue::Floats(x) => x.into_iter().map(f64::from).collect(),
        AttributeValue::Int(x) => vec![x as f64],
        AttributeValue::Ints(x) => x.into_iter().map(f64::from).collect(),
        AttributeValue::Short(x) => vec![x as f64],
        AttributeValue::Shorts(x) => x.into_iter().map(f64::from).collect(),
        _ => return None,
    })
}

fn att_str(v: &netcdf::Variable, name: &str) -> Option<String> {
    match v.attribute(name)?.value().ok()? {
        AttributeValue::Str(s) => Some(s),
        _ => None,
    }
}

fn att_num(v: &netcdf::Variable, name: &str) -> Option<Vec<f64>> {
    att_f64s(v.attribute(name)?.value().ok()?)
}

fn dimorder(v: &netcdf::Variable) -> Vec<String> {
    att_str(v, "dimorder")
        .unwrap_or_default()
        .split(',')
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .collect()
}

/// Reads a whole numeric variable as f64 (integers convert exactly up
/// to 2^53).
fn values_f64(path: &Path, v: &netcdf::Variable, field: &str) -> Result<Vec<f64>> {
    macro_rules! get {
        ($t:ty) => {
            v.get_values::<$t, _>(..)
                .map_err(|e| nc_err(path, field, e))?
                .into_iter()
                .map(|x| x as f64)
                .collect()
        };
    }
    Ok(match v.vartype() {
        NcVariableType::Int(IntType::U8) => get!(u8),
        NcVariableType::Int(IntType::I8) => get!(i8),
        NcVariableType::Int(IntType::U16) => get!(u16),
        NcVariableType::Int(IntType::I16) => get!(i16),
        NcVariableType::Int(IntType::U32) => get!(u32),
        NcVariableType::Int(IntType::I32) => get!(i32),
        NcVariableType::Int(IntType::U64) => get!(u64),
        NcVariableType::Int(IntType::I64) => get!(i64),
        NcVariableType::Float(FloatType::F32) => get!(f32),
        NcVariableType::Float(FloatType::F64) => get!(f64),
        other => {
            return Err(Error::unsupported(
                path,
                format!("{field}: type {other:?}: voxcast reads numeric scalars"),
            ))
        }
    })
}

fn type_range(ty: &NcVariableType) -> Option<[f64; 2]> {
    Some(match ty {
        NcVariableType::Int(IntType::U8) => [0.0, u8::MAX as f64],
        NcVariableType::Int(IntType::I8) => [i8::MIN as f64, i8::MAX as f64],
        NcVariableType::Int(IntType::U16) => [0.0, u16::MAX as f64],
        NcVariableType::Int(IntType::I16) => [i16::MIN as f64, i16::MAX as f64],
        NcVariableType::Int(IntType::U32) => [0.0, u32::MAX as f64],
        NcVariableType::Int(IntType::I32) => [i32::MIN as f64, i32::MAX as f64],
        _ => return None,
    })
}

fn type_name(ty: &NcVariableType) -> String {
    match ty {
        NcVariableType::Int(t) => format!("{t:?}").to_lowercase(),
        NcVariableType::Float(t) => format!("{t:?}").to_lowercase(),
        other => format!("{other:?}"),
    }
}

fn open_file(path: &Path) -> Result<netcdf::File> {
    // The C library opens the path itself: record it as an input and
    // refuse a device or a pipe first.
    voxcast::files::open(path)?;
    netcdf::open(path).map_err(|e| {
        Error::format(
            path,
            "file",
            format!("not a readable MINC-2 (HDF5) file: {e}"),
        )
    })
}

/// The group `/minc-2.0/image/0`.
fn image_group<'f>(path: &Path, f: &'f netcdf::File) -> Result<netcdf::Group<'f>> {
    f.group("minc-2.0/image/0")
        .map_err(|e| nc_err(path, "/minc-2.0/image/0", e))?
        .ok_or_else(|| {
            Error::format(
                path,
                "/minc-2.0/image/0",
                "missing: not a MINC-2 file (MINC-1 and other HDF5 files are not read)",
            )
        })
}

fn header(path: &Path, f: &netcdf::File) -> Result<Header> {
    let missing = |what: &str| {
        Error::format(
            path,
            what,
            format!("no {what}: not a MINC-2 file (MINC-1 and other HDF5 files are not read)"),
        )
    };
    f.group("minc-2.0")
        .map_err(|e| nc_err(path, "/minc-2.0", e))?
        .ok_or_else(|| missing("/minc-2.0"))?;
    let img_group = image_group(path, f)?;
    let image = img_group
        .variable("image")
        .ok_or_else(|| missing("/minc-2.0/image/0/image"))?;
    let names = dimorder(&image);
    let lens: Vec<usize> = image.dimensions().iter().map(|d| d.len()).collect();
    let mut sorted = names.clone();
    sorted.sort();
    if names.len() != lens.len() || sorted != AXES {
        return Err(Error::unsupported(
            path,
            format!(
                "image dimorder `{}` ({} dimensions): voxcast reads 3D volumes of xspace, yspace and zspace",
                names.join(","),
                lens.len()
            ),
        ));
    }
    let order: Vec<(String, usize)> = names.into_iter().zip(lens).collect();
    let dims_group = f
        .group("minc-2.0/dimensions")
        .map_err(|e| nc_err(path, "/minc-2.0/dimensions", e))?;
    let mut axes = [(0usize, 0.0f64, 1.0f64); 3];
    for (a, name) in AXES.iter().enumerate() {
        let len = order
            .iter()
            .find(|(n, _)| n == name)
            .map(|o| o.1)
            .unwrap_or(0);
        let var = dims_group.as_ref().and_then(|g| g.variable(name));
        let num = |att: &str, default: f64| -> Result<f64> {
            match var.as_ref().and_then(|v| att_num(v, att)) {
                None => Ok(default),
                Some(x) if x.len() == 1 && x[0].is_finite() => Ok(x[0]),
                Some(x) => Err(Error::format(
                    path,
                    format!("{name}:{att}"),
                    format!("{x:?}: expected one finite number"),
                )),
            }
        };
        axes[a] = (len, num("start", 0.0)?, num("step", 1.0)?);
    }
    let ty = voxcast::io::util::no_panic(path, "MINC type", || Ok(image.vartype()))?;
    let valid_range = match att_num(&image, "valid_range") {
        Some(r) if r.len() == 2 && r[0].is_finite() && r[1].is_finite() && r[0] < r[1] => {
            Some([r[0], r[1]])
        }
        Some(r) => {
            return Err(Error::format(
                path,
                "image:valid_range",
                format!("{r:?}: expected two finite numbers, min < max"),
            ))
        }
        None => None,
    };
    let scale = match (
        img_group.variable("image-min"),
        img_group.variable("image-max"),
    ) {
        (Some(lo), Some(hi)) if !matches!(ty, NcVariableType::Float(_)) => {
            let order_lo = dimorder(&lo);
            // Per-slice values: a few thousand at most, bounded by the
            // image's own (checked) size.
            let n_lo: usize = lo.dimensions().iter().map(|d| d.len()).product();
            let n_hi: usize = hi.dimensions().iter().map(|d| d.len()).product();
            let slowest: Vec<String> = order.iter().map(|o| o.0.clone()).collect();
            let want: usize = order.iter().take(order_lo.len()).map(|o| o.1).product();
            if order_lo.len() > 2
                || slowest[..order_lo.len()] != order_lo[..]
                || n_lo != want
                || n_hi != want
            {
                return Err(Error::format(
                    path,
                    "image-min/image-max",
                    format!(
                        "dimorder `{}` with {n_lo}/{n_hi} values: expected the image's slowest dimensions ({})",
                        order_lo.join(","),
                        slowest.join(",")
                    ),
                ));
            }
            let lo_v = values_f64(path, &lo, "image-min")?;
            let hi_v = values_f64(path, &hi, "image-max")?;
            Some((lo_v, hi_v, order_lo))
        }
        _ => None,
    };
    Ok(Header {
        order,
        axes,
        ty,
        valid_range,
        scale,
    })
}

/// Reads a MINC-2 volume.
pub fn read(path: &Path) -> Result<Volume> {
    let f = open_file(path)?;
    let h = header(path, &f)?;
    let dims = h.axes.map(|a| a.0 as u64);
    let n = checked_voxel_count(dims).map_err(|m| Error::format(path, "image", m))?;
    // HDF5 chunks may be deflated: the voxels cannot be more than
    // deflate's best ratio of the file.
    let len = file_len(path)?;
    let bytes = (n as u64).saturating_mul(match h.ty {
        NcVariableType::Int(IntType::U8 | IntType::I8) => 1,
        NcVariableType::Int(IntType::U16 | IntType::I16) => 2,
        NcVariableType::Int(IntType::U64 | IntType::I64)
        | NcVariableType::Float(FloatType::F64) => 8,
        _ => 4,
    });
    if len.saturating_mul(MAX_DEFLATE_RATIO) < bytes {
        return Err(Error::format(
            path,
            "image",
            format!(
                "dims {}×{}×{} ({bytes} bytes), but a {len}-byte file cannot hold that many",
                dims[0], dims[1], dims[2]
            ),
        ));
    }
    let img_group = image_group(path, &f)?;
    let image = img_group
        .variable("image")
        .ok_or_else(|| Error::format(path, "image", "the image variable vanished"))?;
    let stored = values_f64(path, &image, "image")?;
    if stored.len() != n {
        return Err(Error::format(
            path,
            "image",
            format!("{} values for {n} voxels", stored.len()),
        ));
    }
    // Strides of x, y, z in the file's order (slowest first).
    let mut stride = [0usize; 3];
    let mut s = 1usize;
    for (name, len) in h.order.iter().rev() {
        let a = AXES.iter().position(|x| x == name).unwrap_or(0);
        stride[a] = s;
        s *= len;
    }
    let per_slice = h.scale.as_ref().map(|(lo, _, _)| n / lo.len().max(1));
    let range = h.valid_range.or_else(|| type_range(&h.ty));
    let real = |file_index: usize| -> f64 {
        let v = stored[file_index];
        match (&h.scale, per_slice, range) {
            (Some((lo, hi, _)), Some(ps), Some([vmin, vmax])) => {
                let s = file_index / ps;
                lo[s] + (v - vmin) * (hi[s] - lo[s]) / (vmax - vmin)
            }
            _ => v,
        }
    };
    let [nx, ny, nz] = dims.map(|d| d as usize);
    let mut out = Vec::with_capacity(n);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                out.push(real(i * stride[0] + j * stride[1] + k * stride[2]));
            }
        }
    }
    drop(stored);
    let scaled = h.scale.is_some() && range.is_some();
    let data = match h.ty {
        NcVariableType::Int(IntType::U8) if !scaled => {
            VoxelData::U8(out.iter().map(|&x| x as u8).collect())
        }
        NcVariableType::Int(IntType::I16) if !scaled => {
            VoxelData::I16(out.iter().map(|&x| x as i16).collect())
        }
        NcVariableType::Int(IntType::U16) if !scaled => {
            VoxelData::U16(out.iter().map(|&x| x as u16).collect())
        }
        _ => VoxelData::F32(out.iter().map(|&x| x as f32).collect()),
    };
    let spacing = h.axes.map(|a| a.2.abs() as f32);
    for (a, &s) in spacing.iter().enumerate() {
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::format(
                path,
                format!("{}:step", AXES[a]),
                format!(
                    "{}: voxel spacing must be a positive finite number",
                    h.axes[a].2
                ),
            ));
        }
    }
    let origin = Vec3::new(h.axes[0].1 as f32, h.axes[1].1 as f32, h.axes[2].1 as f32);
    Volume::new([nx, ny, nz], Vec3::from(spacing), origin, data)
        .map_err(|e| Error::format(path, "image", e.to_string()))
}

/// Lines describing the file for `voxcast info`.
pub fn summary(path: &Path) -> Result<Vec<String>> {
    let f = open_file(path)?;
    let h = header(path, &f)?;
    let order: Vec<String> = h.order.iter().map(|(n, l)| format!("{n} {l}")).collect();
    let mut lines = vec![
        format!("format      MINC-2 (HDF5), image type {}", type_name(&h.ty)),
        format!("dimorder    {} (slowest first)", order.join(", ")),
    ];
    for (a, name) in AXES.iter().enumerate() {
        lines.push(format!(
            "{name:<11} start {} step {}",
            h.axes[a].1, h.axes[a].2
        ));
    }
    let range = h.valid_range.or_else(|| type_range(&h.ty));
    lines.push(match (&h.scale, range) {
        (Some((lo, _, order)), Some([a, b])) => format!(
            "scaling     image-min/image-max {} ({} values), voxel range {a} … {b}",
            if order.is_empty() {
                "scalar".to_string()
            } else {
                format!("per {}", order.join(","))
            },
            lo.len()
        ),
        _ => "scaling     none (stored values)".to_string(),
    });
    Ok(lines)
}
