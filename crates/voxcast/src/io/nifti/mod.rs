//! The NIfTI family: NIfTI-1 and NIfTI-2 single files (`.nii`, `.nii.gz`)
//! and header/image pairs (`.hdr` + `.img`, either gzipped; `ni1`/`ni2`
//! magic), and Analyze 7.5 pairs (a 348-byte `.hdr` without the NIfTI
//! magic), in either byte order. The three headers are parsed here (see
//! `header.rs`); the voxels are read by `io/stored.rs` after the sizes the
//! header claims have been checked against the file, so a lying header
//! cannot make us allocate. One path for all three:
//!
//! * dims: `dim[1..=3]`; `dim[0]` may be 1 to 7 as long as every dimension
//!   past the third is 1 (a 4D file with one time point is a 3D volume).
//! * spacing: `|pixdim[1..=3]|`, which must be positive and finite (a 0 or
//!   NaN is an error, except on an axis one voxel thick, where it becomes 1).
//! * origin (NIfTI): the qform offset (`qoffset_x/y/z`) when
//!   `qform_code > 0`, else the sform translation when `sform_code > 0`,
//!   else 0. Rotations and axis flips of the qform/sform are not applied
//!   (voxcast volumes are axis aligned), and spacing and origin stay in the
//!   file's units (`xyzt_units`, nearly always mm).
//! * origin (Analyze): Analyze 7.5 has no origin; SPM keeps the origin
//!   voxel (1-based) in the first three shorts of `originator`. When any of
//!   them is set, voxel 0 is at `(1 − originator)·spacing` (SPM's
//!   convention, without the left–right flip SPM's default affine adds);
//!   when none is, the origin is 0 (SPM and nibabel would centre the volume
//!   instead).
//! * scalars: uint8, int16, uint16 and float32 are kept as they are; int8
//!   becomes i16; int32, uint32, int64 and uint64 become i16 or u16 when all
//!   values fit, else f32; float64 becomes f32.
//! * `scl_slope`/`scl_inter` are applied when the slope is finite and not 0
//!   and the pair is not (1, 0) (integral scaling of integers gives i16 when
//!   it fits, else f32). In Analyze the same bytes are SPM's scale factor
//!   (`funused1`) and SPM2's intercept (`funused2`), applied the same way.
//! * name: `intent_name`, when set.
//!
//! Not supported: 4D and higher (more than one volume), complex, RGB/RGBA,
//! 1-bit and float128 data, extensions (skipped).

mod header;
#[cfg(test)]
mod tests;

use super::stored::{open_stream, read_voxels, Layout, Stored};
use crate::error::{Error, Result};
use crate::volume::Volume;
use glam::Vec3;
use header::{Header, Kind, NIFTI1_SIZE, NIFTI2_SIZE};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Maps a NIfTI (or Analyze) datatype code; known codes voxcast cannot show
/// are `Unsupported`, unknown ones a format error.
fn stored_type(path: &Path, code: i16) -> Result<Stored> {
    Ok(match code {
        2 => Stored::U8,
        4 => Stored::I16,
        8 => Stored::I32,
        16 => Stored::F32,
        64 => Stored::F64,
        256 => Stored::I8,
        512 => Stored::U16,
        768 => Stored::U32,
        1024 => Stored::I64,
        1280 => Stored::U64,
        1 => {
            return Err(Error::unsupported(
                path,
                "datatype 1 (1-bit binary): convert it to uint8 first, e.g. with nibabel",
            ))
        }
        32 | 1792 | 2048 => {
            return Err(Error::unsupported(
                path,
                format!("datatype {code} (complex): voxcast shows real scalars only"),
            ))
        }
        128 | 2304 => {
            return Err(Error::unsupported(
                path,
                format!("datatype {code} (RGB/RGBA colour): voxcast shows scalars only"),
            ))
        }
        1536 => return Err(Error::unsupported(path, "datatype 1536 (float128)")),
        _ => {
            return Err(Error::format(
                path,
                "datatype",
                format!(
                    "unknown code {code} (codes: 2 uint8, 4 int16, 8 int32, 16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32, 1024 int64, 1280 uint64)"
                ),
            ))
        }
    })
}

fn lower_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// True for `x.hdr` and `x.hdr.gz`.
fn is_hdr_name(path: &Path) -> bool {
    let n = lower_name(path);
    n.ends_with(".hdr") || n.ends_with(".hdr.gz")
}

/// The header of an image file named by the user (`x.img` → `x.hdr`);
/// any other path is returned as it is.
pub(crate) fn header_path(path: &Path) -> Result<PathBuf> {
    let n = lower_name(path);
    let cut = if n.ends_with(".img.gz") {
        7
    } else if n.ends_with(".img") {
        4
    } else {
        return Ok(path.to_path_buf());
    };
    let s = path.to_string_lossy();
    let stem = &s[..s.len() - cut];
    [".hdr", ".hdr.gz", ".HDR"]
        .iter()
        .map(|e| PathBuf::from(format!("{stem}{e}")))
        .find(|p| p.is_file())
        .ok_or_else(|| {
            Error::format(
                path,
                "header",
                format!("an Analyze/NIfTI image file is read with its header, but there is no {stem}.hdr beside it"),
            )
        })
}

/// Reads and parses the header of `path` (gzip or not).
fn read_header(path: &Path) -> Result<Header> {
    let stream = open_stream(path)?;
    let mut buf = Vec::with_capacity(NIFTI2_SIZE);
    stream
        .take(NIFTI2_SIZE as u64)
        .read_to_end(&mut buf)
        .map_err(|e| Error::format(path, "header", format!("cannot read the header: {e}")))?;
    header::parse(path, &buf, is_hdr_name(path))
}

/// The image file of a `.hdr` header (`x.hdr` → `x.img`, `x.hdr.gz` →
/// `x.img.gz`, falling back to the other compression).
fn image_file_of(path: &Path, h: &Header) -> Result<PathBuf> {
    let s = path.to_string_lossy();
    let lower = s.to_ascii_lowercase();
    let field = if h.kind == Kind::Analyze {
        "header"
    } else {
        "magic"
    };
    let stem = if lower.ends_with(".hdr.gz") {
        &s[..s.len() - 7]
    } else if lower.ends_with(".hdr") {
        &s[..s.len() - 4]
    } else {
        return Err(Error::format(
            path,
            field,
            "`ni1`/`ni2` means a header whose voxels are in a separate .img file, but this file does not end in .hdr",
        ));
    };
    let candidates = [
        format!("{stem}.img"),
        format!("{stem}.img.gz"),
        format!("{stem}.IMG"),
    ];
    candidates
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
        .ok_or_else(|| {
            Error::format(
                path,
                field,
                format!(
                    "{} header whose voxels are in a separate file, but there is no image file {stem}.img or {stem}.img.gz",
                    h.kind.name()
                ),
            )
        })
}

/// What the header says about the grid, checked.
struct Grid {
    dims: [u64; 3],
    stored: Stored,
    data_path: PathBuf,
    offset: u64,
    spacing: Vec3,
    origin: Vec3,
    /// The field the origin came from ("" when 0).
    origin_field: &'static str,
}

fn grid(path: &Path, h: &Header) -> Result<Grid> {
    let ndim = h.dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(Error::format(
            path,
            "dim",
            format!("dim[0] = {ndim}: the number of dimensions must be 1 to 7"),
        ));
    }
    let ndim = ndim as usize;
    let mut dims = [1u64; 3];
    for (i, d) in dims.iter_mut().enumerate().take(ndim.min(3)) {
        let v = h.dim[i + 1];
        if v <= 0 {
            return Err(Error::format(
                path,
                "dim",
                format!("dim[{}] = {v}: every dimension must be at least 1", i + 1),
            ));
        }
        *d = v as u64;
    }
    for (i, &v) in h.dim.iter().enumerate().take(ndim + 1).skip(4) {
        if v != 1 {
            let what = if i == 4 {
                "time points (4D series)"
            } else {
                "components"
            };
            return Err(Error::unsupported(
                path,
                format!("dim[{i}] = {v}: a file with {v} {what}; voxcast reads single 3D volumes (extract one, e.g. with `fslroi` or nibabel)"),
            ));
        }
    }

    let stored = stored_type(path, h.datatype)?;
    let (data_path, min_offset) = if h.pair {
        (image_file_of(path, h)?, 0.0)
    } else if h.kind == Kind::Nifti2 {
        (path.to_path_buf(), NIFTI2_SIZE as f64)
    } else {
        (path.to_path_buf(), NIFTI1_SIZE as f64)
    };
    let off = h.vox_offset;
    if !(off.is_finite() && off >= min_offset && off.fract() == 0.0 && off < 1e12) {
        return Err(Error::format(
            path,
            "vox_offset",
            format!("{off}: must be a whole number of bytes, at least {min_offset}"),
        ));
    }

    let mut spacing = [1f32; 3];
    for (i, s) in spacing.iter_mut().enumerate() {
        let p = h.pixdim[i + 1].abs() as f32;
        if p.is_finite() && p > 0.0 {
            *s = p;
        } else if dims[i] > 1 {
            return Err(Error::format(
                path,
                "pixdim",
                format!(
                    "pixdim[{}] = {}: voxel spacing must be a positive finite number",
                    i + 1,
                    h.pixdim[i + 1]
                ),
            ));
        }
    }
    let spacing = Vec3::from(spacing);
    let f = |a: [f64; 3]| Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32);
    let (origin, origin_field) = if h.kind == Kind::Analyze {
        if h.originator != [0; 3] {
            let o = h.originator.map(|v| 1.0 - f64::from(v));
            (f(o) * spacing, "originator")
        } else {
            (Vec3::ZERO, "")
        }
    } else if h.qform_code > 0 {
        (f(h.qoffset), "qoffset_x/y/z")
    } else if h.sform_code > 0 {
        (f(h.srow_t), "srow_x/y/z[3]")
    } else {
        (Vec3::ZERO, "")
    };
    if !origin.is_finite() {
        return Err(Error::format(
            path,
            origin_field,
            format!("origin {origin} is not finite"),
        ));
    }
    Ok(Grid {
        dims,
        stored,
        data_path,
        offset: off as u64,
        spacing,
        origin,
        origin_field,
    })
}

/// Reads a NIfTI-1, NIfTI-2 or Analyze 7.5 volume (`path` may name the
/// header or, for a pair, the `.img` file).
pub fn read(path: &Path) -> Result<Volume> {
    let path = &header_path(path)?;
    let h = read_header(path)?;
    let g = grid(path, &h)?;
    if h.bitpix as u64 != g.stored.size() * 8 {
        eprintln!(
            "warning: {}: bitpix {} does not match datatype {} ({} bits); using the datatype",
            path.display(),
            h.bitpix,
            h.datatype,
            g.stored.size() * 8
        );
    }
    let data = read_voxels(
        path,
        &Layout {
            data_path: &g.data_path,
            offset: g.offset,
            dims: g.dims,
            stored: g.stored,
            big_endian: h.big_endian,
            dims_field: "dim",
            offset_field: "vox_offset",
        },
    )?;

    let (slope, inter) = (h.scl_slope, h.scl_inter);
    let data = if slope != 0.0 && slope.is_finite() && inter.is_finite() {
        data.rescaled(slope, inter)
    } else {
        if slope != 0.0 {
            eprintln!(
                "warning: {}: scl_slope {slope} / scl_inter {inter} are not finite: values left unscaled",
                path.display()
            );
        }
        data
    };

    let dims = g.dims.map(|d| d as usize);
    let mut vol = Volume::new(dims, g.spacing, g.origin, data)
        .map_err(|e| Error::format(path, "dim", e.to_string()))?;
    if !h.intent_name.is_empty() {
        vol.name = Some(h.intent_name.clone());
    }
    Ok(vol)
}

/// A NIfTI `qform_code`/`sform_code`.
fn xform_name(code: i32) -> &'static str {
    match code {
        0 => "unknown",
        1 => "scanner",
        2 => "aligned",
        3 => "Talairach",
        4 => "MNI152",
        5 => "template",
        _ => "?",
    }
}

/// The units of `xyzt_units` (space, time).
fn units(xyzt: u8) -> String {
    let space = match xyzt & 0x07 {
        1 => "m",
        2 => "mm",
        3 => "µm",
        _ => "unknown",
    };
    let time = match xyzt & 0x38 {
        8 => "s",
        16 => "ms",
        24 => "µs",
        _ => "unknown",
    };
    format!("space {space}, time {time}")
}

/// Lines describing the header for `voxcast info`: which header, byte
/// order, datatype, dims, pixdim and where the origin came from.
pub fn summary(path: &Path) -> Result<Vec<String>> {
    let path = &header_path(path)?;
    let h = read_header(path)?;
    let g = grid(path, &h)?;
    let file_of = |p: &Path| {
        p.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let layout = if h.pair {
        format!("header + image file {}", file_of(&g.data_path))
    } else {
        "single file".to_string()
    };
    let order = if h.big_endian { "big" } else { "little" };
    let gz = if super::stored::is_gzip(path)? {
        ", gzip"
    } else {
        ""
    };
    let ndim = h.dim[0].clamp(0, 7) as usize;
    let dims: Vec<String> = h.dim[1..=ndim].iter().map(|d| d.to_string()).collect();
    let pix: Vec<String> = h.pixdim[1..=ndim.min(3)]
        .iter()
        .map(|p| p.to_string())
        .collect();
    let mut lines = vec![
        format!(
            "format      {} ({layout}), {order}-endian{gz}",
            h.kind.name()
        ),
        format!(
            "datatype    {} ({}), bitpix {}, voxels from byte {}",
            h.datatype,
            g.stored.name(),
            h.bitpix,
            g.offset
        ),
        format!("dim         {}: {}", h.dim[0], dims.join(" × ")),
        format!("pixdim      {}", pix.join(" ")),
    ];
    let from = if g.origin_field.is_empty() {
        "none set: 0".to_string()
    } else {
        g.origin_field.to_string()
    };
    if h.kind == Kind::Analyze {
        lines.push(format!(
            "originator  {} {} {}  (origin from {from})",
            h.originator[0], h.originator[1], h.originator[2]
        ));
    } else {
        lines.push(format!("units       {}", units(h.xyzt_units)));
        lines.push(format!(
            "qform_code  {} ({}), sform_code {} ({}); origin from {from}",
            h.qform_code,
            xform_name(h.qform_code),
            h.sform_code,
            xform_name(h.sform_code)
        ));
    }
    if h.scl_slope != 0.0 {
        lines.push(format!("scaling     {} · v + {}", h.scl_slope, h.scl_inter));
    }
    if !h.descrip.is_empty() {
        lines.push(format!("descrip     {}", h.descrip));
    }
    Ok(lines)
}
