//! FreeSurfer MGH volumes: `.mgh`, and `.mgz` (the same, gzipped).
//!
//! The header is big-endian: `version` (1), `width`, `height`, `depth`,
//! `nframes`, `type` (0 uchar, 1 int, 3 float, 4 short), `dof` (i32 each),
//! `goodRASflag` (i16), `xsize ysize zsize` (f32), the direction cosines
//! `Mdc` (9 f32: the x, y and z axes in RAS) and the centre `c_ras` (3 f32).
//! The voxels start at byte 284, x fastest; optional tags (TR, flip angle,
//! …) that follow them are ignored.
//!
//! * dims: `width × height × depth`. A file with more than one frame is
//!   refused with the command that extracts one (a 4D NIfTI gets the same),
//!   rather than showing frame 0 of a time series as if it were the data.
//! * spacing: `|xsize|, |ysize|, |zsize|` (mm), positive and finite.
//! * origin: when `goodRASflag > 0`, the RAS position of voxel 0,
//!   `c_ras − Mdc·diag(spacing)·dims/2` (FreeSurfer's and nibabel's
//!   vox2ras translation); else 0. As for NIfTI, the rotation, permutation
//!   and flips of `Mdc` are not applied: voxcast volumes are axis aligned,
//!   so the voxel axes stay the volume's x, y, z (`voxcast info` shows the
//!   orientation, e.g. `LIA` for a conformed FreeSurfer volume).
//! * scalars: uchar → u8, short → i16, float → f32; int → i16 or u16 when
//!   every value fits, else f32.

use super::stored::{is_gzip, open_stream, read_voxels, Layout, Stored};
use crate::error::{Error, Result};
use crate::volume::Volume;
use glam::Vec3;
use std::io::Read;
use std::path::Path;

/// Byte where the voxels start.
const DATA_OFFSET: u64 = 284;
/// The header fields voxcast reads end here.
const HEADER_USED: usize = 90;

/// The header fields.
#[derive(Clone, Debug)]
struct Header {
    version: i32,
    dims: [i32; 3],
    nframes: i32,
    ty: i32,
    dof: i32,
    good_ras: i16,
    spacing: [f32; 3],
    /// x, y and z axis directions in RAS, one after the other.
    mdc: [f32; 9],
    c_ras: [f32; 3],
}

fn read_header(path: &Path) -> Result<Header> {
    let mut buf = Vec::with_capacity(HEADER_USED);
    open_stream(path)?
        .take(DATA_OFFSET)
        .read_to_end(&mut buf)
        .map_err(|e| Error::format(path, "header", format!("cannot read the header: {e}")))?;
    if buf.len() < DATA_OFFSET as usize {
        return Err(Error::format(
            path,
            "header",
            format!(
                "the file ends after {} bytes, inside the 284-byte MGH header",
                buf.len()
            ),
        ));
    }
    let i32_at = |at: usize| i32::from_be_bytes(buf[at..at + 4].try_into().unwrap());
    let f32_at = |at: usize| f32::from_be_bytes(buf[at..at + 4].try_into().unwrap());
    Ok(Header {
        version: i32_at(0),
        dims: [i32_at(4), i32_at(8), i32_at(12)],
        nframes: i32_at(16),
        ty: i32_at(20),
        dof: i32_at(24),
        good_ras: i16::from_be_bytes([buf[28], buf[29]]),
        spacing: [f32_at(30), f32_at(34), f32_at(38)],
        mdc: std::array::from_fn(|i| f32_at(42 + 4 * i)),
        c_ras: [f32_at(78), f32_at(82), f32_at(86)],
    })
}

fn stored_type(path: &Path, ty: i32) -> Result<Stored> {
    Ok(match ty {
        0 => Stored::U8,
        1 => Stored::I32,
        3 => Stored::F32,
        4 => Stored::I16,
        _ => {
            return Err(Error::format(
                path,
                "type",
                format!("{ty}: expected 0 (uchar), 1 (int), 3 (float) or 4 (short)"),
            ))
        }
    })
}

/// The checked grid: dims, type, spacing and origin.
struct Grid {
    dims: [u64; 3],
    stored: Stored,
    spacing: Vec3,
    origin: Vec3,
}

fn grid(path: &Path, h: &Header) -> Result<Grid> {
    if h.version != 1 {
        return Err(Error::format(
            path,
            "version",
            format!(
                "{}: expected 1 (an MGH file starts with the big-endian int 1)",
                h.version
            ),
        ));
    }
    let names = ["width", "height", "depth"];
    let mut dims = [0u64; 3];
    for i in 0..3 {
        if h.dims[i] <= 0 {
            return Err(Error::format(
                path,
                names[i],
                format!("{}: every dimension must be at least 1", h.dims[i]),
            ));
        }
        dims[i] = h.dims[i] as u64;
    }
    if h.nframes != 1 {
        if h.nframes <= 0 {
            return Err(Error::format(
                path,
                "nframes",
                format!("{}: expected at least 1", h.nframes),
            ));
        }
        return Err(Error::unsupported(
            path,
            format!(
                "nframes = {}: a file with {} frames; voxcast reads single 3D volumes (extract one with `mri_convert --frame 0 IN.mgz OUT.mgz` or nibabel)",
                h.nframes, h.nframes
            ),
        ));
    }
    let stored = stored_type(path, h.ty)?;
    let mut spacing = [1f32; 3];
    for i in 0..3 {
        let s = h.spacing[i].abs();
        if s.is_finite() && s > 0.0 {
            spacing[i] = s;
        } else if dims[i] > 1 {
            return Err(Error::format(
                path,
                ["xsize", "ysize", "zsize"][i],
                format!(
                    "{}: voxel spacing must be a positive finite number",
                    h.spacing[i]
                ),
            ));
        }
    }
    let origin = if h.good_ras > 0 {
        // vox2ras = [Mdc·D | c_ras − Mdc·D·dims/2]; the Mdc columns are the
        // axes, stored one after the other.
        let mut p = Vec3::from(h.c_ras);
        for (j, &n) in dims.iter().enumerate() {
            let axis = Vec3::new(h.mdc[3 * j], h.mdc[3 * j + 1], h.mdc[3 * j + 2]);
            p -= axis * spacing[j] * (n as f32 / 2.0);
        }
        if !p.is_finite() {
            return Err(Error::format(
                path,
                "Mdc/c_ras",
                format!("the position of voxel 0, {p}, is not finite"),
            ));
        }
        p
    } else {
        Vec3::ZERO
    };
    Ok(Grid {
        dims,
        stored,
        spacing: Vec3::from(spacing),
        origin,
    })
}

/// Reads an MGH or MGZ volume.
pub fn read(path: &Path) -> Result<Volume> {
    let h = read_header(path)?;
    let g = grid(path, &h)?;
    let data = read_voxels(
        path,
        &Layout {
            data_path: path,
            offset: DATA_OFFSET,
            dims: g.dims,
            stored: g.stored,
            big_endian: true,
            dims_field: "width/height/depth",
            offset_field: "header",
        },
    )?;
    Volume::new(g.dims.map(|d| d as usize), g.spacing, g.origin, data)
        .map_err(|e| Error::format(path, "width/height/depth", e.to_string()))
}

/// The orientation letters of the three axes (`RAS`, `LIA`, …): each
/// axis's dominant RAS direction.
fn orientation(mdc: &[f32; 9]) -> String {
    (0..3)
        .map(|j| {
            let a = &mdc[3 * j..3 * j + 3];
            let k = (0..3)
                .max_by(|&x, &y| a[x].abs().total_cmp(&a[y].abs()))
                .unwrap_or(0);
            let (pos, neg) = [('R', 'L'), ('A', 'P'), ('S', 'I')][k];
            if a[k] >= 0.0 {
                pos
            } else {
                neg
            }
        })
        .collect()
}

/// Lines describing the header for `voxcast info`.
pub fn summary(path: &Path) -> Result<Vec<String>> {
    let h = read_header(path)?;
    let g = grid(path, &h)?;
    let kind = if is_gzip(path)? { "MGZ (gzip)" } else { "MGH" };
    let v = |a: &[f32]| {
        a.iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut lines = vec![
        format!("format      FreeSurfer {kind}, version {}", h.version),
        format!(
            "type        {} ({}), {} × {} × {}, nframes {}, dof {}",
            h.ty,
            g.stored.name(),
            h.dims[0],
            h.dims[1],
            h.dims[2],
            h.nframes,
            h.dof
        ),
        format!("spacing     {}", v(&h.spacing)),
    ];
    if h.good_ras > 0 {
        lines.push(format!(
            "Mdc         x ({}), y ({}), z ({}): {} (not applied)",
            v(&h.mdc[0..3]),
            v(&h.mdc[3..6]),
            v(&h.mdc[6..9]),
            orientation(&h.mdc)
        ));
        lines.push(format!(
            "c_ras       {}; voxel 0 at {} {} {}",
            v(&h.c_ras),
            g.origin.x,
            g.origin.y,
            g.origin.z
        ));
    } else {
        lines.push(format!(
            "goodRASflag {}: no valid geometry, origin 0",
            h.good_ras
        ));
    }
    Ok(lines)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_letters() {
        let ras = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(orientation(&ras), "RAS");
        // A conformed FreeSurfer volume: x = −R, y = −S, z = +A.
        let lia = [-1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0];
        assert_eq!(orientation(&lia), "LIA");
    }
}
