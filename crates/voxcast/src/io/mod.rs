//! Readers: one file per format. [`open`] picks the reader from the path
//! (a folder, a glob, the extension) or from the file's magic bytes.
//!
//! Every reader checks the sizes its header claims against the real size of
//! the file before it allocates, and reports bad input as an [`Error`] naming
//! the file, the field and what was expected.

mod decode;
pub mod dicom;
pub mod fds;
pub mod image_stack;
pub mod metaimage;
pub mod mitsuba_vol;
pub mod nifti;
pub mod nrrd;
pub mod nrrd_write;
pub mod raw;
#[cfg(test)]
mod test_support;
pub mod util;
pub mod vdb;
pub mod vtk;
pub mod wrf;

use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Layout of a headerless raw file (`--raw-dims`, `--raw-type`, …).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawLayout {
    pub dims: [u64; 3],
    #[serde(rename = "type")]
    pub scalar_type: ScalarType,
    #[serde(default)]
    pub big_endian: bool,
    /// Bytes to skip at the start of the file.
    #[serde(default)]
    pub header_bytes: u64,
}

/// How to open an input: everything that is not in the file itself.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OpenOptions {
    /// Read the file as raw voxels with this layout (whatever its extension).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub raw: Option<RawLayout>,
    /// Override the spacing the file gives (or supply one it lacks).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spacing: Option<[f32; 3]>,
    /// The variable (grid, quantity) to read from a multi-variable file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variable: Option<String>,
    /// The time to read from a time series (the file's units, e.g. seconds).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
}

/// The formats voxcast reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Nrrd,
    MetaImage,
    Vtk,
    Nifti,
    Dicom,
    ImageStack,
    Raw,
    Vdb,
    Fds,
    /// A frame folder written by a simulator (`series.toml` + frames).
    Series,
    /// Mitsuba's binary grid (`.vol`, "VOL" version 3).
    MitsubaVol,
    /// WRF output (NetCDF-4 / NetCDF classic; needs the `wrf` feature).
    Wrf,
}

/// Decides the format of `path` from its kind (folder, glob), extension and
/// first bytes.
pub fn detect(path: &Path, opts: &OpenOptions) -> Result<Format> {
    if opts.raw.is_some() {
        return Ok(Format::Raw);
    }
    let s = path.to_string_lossy();
    if s.contains(['*', '?', '[']) && !path.exists() {
        return Ok(Format::ImageStack);
    }
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if meta.is_dir() {
        if crate::volume::Series::is_frame_folder(path) {
            return Ok(Format::Series);
        }
        return if dicom::folder_has_dicom(path)? {
            Ok(Format::Dicom)
        } else {
            Ok(Format::ImageStack)
        };
    }
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let by_ext = if name.ends_with(".nrrd") || name.ends_with(".nhdr") {
        Some(Format::Nrrd)
    } else if name.ends_with(".mhd") || name.ends_with(".mha") {
        Some(Format::MetaImage)
    } else if name.ends_with(".vtk") {
        Some(Format::Vtk)
    } else if name.ends_with(".nii") || name.ends_with(".nii.gz") {
        Some(Format::Nifti)
    } else if name.ends_with(".dcm") || name.ends_with(".dcm.gz") {
        Some(Format::Dicom)
    } else if name.ends_with(".vdb") {
        Some(Format::Vdb)
    } else if name.ends_with(".smv") {
        Some(Format::Fds)
    } else if name.ends_with(".vol") {
        Some(Format::MitsubaVol)
    } else if wrf::is_wrf_name(&name) {
        Some(Format::Wrf)
    } else {
        None
    };
    if let Some(f) = by_ext {
        return Ok(f);
    }
    let head = util::read_head(path, 352)?;
    let nifti1_magic =
        head.len() >= 348 && (&head[344..348] == b"n+1\0" || &head[344..348] == b"ni1\0");
    if name.ends_with(".hdr") && nifti1_magic {
        return Ok(Format::Nifti);
    }
    if let Some(advice) = not_read(&name) {
        return Err(Error::unsupported(path, advice));
    }
    if head.starts_with(b"NRRD") {
        Ok(Format::Nrrd)
    } else if head.starts_with(b"# vtk DataFile") {
        Ok(Format::Vtk)
    } else if nifti1_magic {
        Ok(Format::Nifti)
    } else if head.len() >= 132 && &head[128..132] == b"DICM" {
        Ok(Format::Dicom)
    } else if head.starts_with(&[0x20, 0x42, 0x44, 0x56, 0, 0, 0, 0]) {
        // OpenVDB's magic number 0x56444220 as a little-endian i64.
        Ok(Format::Vdb)
    } else if mitsuba_vol::is_vol(&head) {
        Ok(Format::MitsubaVol)
    } else if wrf::is_netcdf_magic(&head) {
        Ok(Format::Wrf)
    } else if head.starts_with(b"ObjectType") || head.starts_with(b"NDims") {
        Ok(Format::MetaImage)
    } else if head.starts_with(b"\x89PNG")
        || head.starts_with(b"II*\0")
        || head.starts_with(b"MM\0*")
    {
        Ok(Format::ImageStack)
    } else if name.ends_with(".raw") {
        Err(Error::invalid(format!(
            "{}: a raw file has no header: give its layout with --raw-dims X,Y,Z --raw-type u8|u16|i16|f32",
            path.display()
        )))
    } else {
        Err(Error::unsupported(
            path,
            "unknown format (known: .nrrd .nhdr .mhd .mha .vtk .nii .nii.gz .vdb .smv .vol .nc/wrfout_*, DICOM folders or .dcm, PNG/TIFF slice folders or globs, raw with --raw-dims)",
        ))
    }
}

/// Formats a user may expect that voxcast does not read, by file name: what
/// to convert them with.
fn not_read(name: &str) -> Option<&'static str> {
    if name.ends_with(".mnc") || name.ends_with(".mnc2") {
        Some("MINC (.mnc) is not read: convert it to NIfTI with `mnc2nii IN.mnc OUT.nii` (minc-tools) or nibabel (`python3 -c \"import nibabel as nib, sys; nib.save(nib.Nifti1Image.from_image(nib.load(sys.argv[1])), sys.argv[2])\" IN.mnc OUT.nii.gz`)")
    } else if name.ends_with(".mgh") || name.ends_with(".mgz") {
        Some("FreeSurfer MGH/MGZ is not read: convert it with `mri_convert IN.mgz OUT.nii.gz` (FreeSurfer) or nibabel (`python3 -c \"import nibabel as nib, sys; nib.save(nib.Nifti1Image.from_image(nib.load(sys.argv[1])), sys.argv[2])\" IN.mgz OUT.nii.gz`)")
    } else if name.ends_with(".hdr") || name.ends_with(".img") {
        Some("Analyze 7.5 (.hdr/.img without the NIfTI magic) is not read: convert it with nibabel (`python3 -c \"import nibabel as nib, sys; nib.save(nib.Nifti1Image.from_image(nib.load(sys.argv[1])), sys.argv[2])\" IN.hdr OUT.nii.gz`) or `fslchfiletype NIFTI_GZ IN.hdr`")
    } else {
        None
    }
}

/// Opens any supported input as a volume.
pub fn open(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let mut vol = match detect(path, opts)? {
        Format::Nrrd => nrrd::read(path)?,
        Format::MetaImage => metaimage::read(path)?,
        Format::Vtk => vtk::read(path)?,
        Format::Nifti => nifti::read(path)?,
        Format::Dicom => dicom::read(path, opts)?,
        Format::ImageStack => image_stack::read(path)?,
        Format::Raw => raw::read(path, opts.raw.as_ref().expect("detect checked raw"))?,
        Format::Vdb => vdb::read(path, opts)?,
        Format::Fds => fds::read(path, opts)?,
        Format::Wrf => wrf::read(path, opts)?,
        Format::Series => {
            // One frame of the series: the nearest to `--time`, else the last.
            let s = crate::volume::Series::open_folder(path)?;
            let i = opts.time.map(|t| s.nearest(t)).unwrap_or(s.len() - 1);
            s.load(i, opts)?
        }
        Format::MitsubaVol => mitsuba_vol::read(path)?,
    };
    if let Some(s) = opts.spacing {
        vol.set_spacing(Vec3::from(s))?;
    }
    Ok(vol)
}

#[cfg(test)]
mod detect_tests {
    use super::*;

    #[test]
    fn formats_not_read_are_named_with_a_converter() {
        let dir = tempfile::tempdir().unwrap();
        let opts = OpenOptions::default();
        let mut hdf5 = b"\x89HDF\r\n\x1a\n".to_vec();
        hdf5.resize(400, 0);
        for (name, bytes, says) in [
            ("brain.mnc", hdf5.clone(), ["MINC", "mnc2nii"]),
            (
                "brain.mgz",
                vec![0x1f, 0x8b, 8, 0],
                ["MGH/MGZ", "mri_convert"],
            ),
            ("brain.hdr", vec![0u8; 348], ["Analyze 7.5", "nibabel"]),
        ] {
            let p = dir.path().join(name);
            std::fs::write(&p, &bytes).unwrap();
            let e = detect(&p, &opts).unwrap_err();
            let s = e.to_string();
            assert!(matches!(e, Error::Unsupported { .. }), "{s}");
            assert!(
                s.contains(name) && says.iter().all(|w| s.contains(w)),
                "{s}"
            );
        }
        // A NIfTI-1 pair header (.hdr with the `ni1` magic) is NIfTI.
        let mut h = vec![0u8; 348];
        h[344..348].copy_from_slice(b"ni1\0");
        let p = dir.path().join("pair.hdr");
        std::fs::write(&p, &h).unwrap();
        assert_eq!(detect(&p, &opts).unwrap(), Format::Nifti);
    }
}
