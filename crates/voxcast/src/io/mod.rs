//! Readers: one file per format. [`open`] picks the reader from the path
//! (a folder, a glob, the extension) or from the file's magic bytes.
//!
//! Every reader checks the sizes its header claims against the real size of
//! the file before it allocates, and reports bad input as an [`Error`] naming
//! the file, the field and what was expected.

mod decode;
pub mod dicom;
pub mod external;
pub mod fds;
pub mod image_stack;
pub mod metaimage;
pub mod mgh;
pub mod minc;
pub mod mitsuba_vol;
pub mod nifti;
pub mod nrrd;
pub mod nrrd_write;
pub mod raw;
pub mod series;
mod stored;
#[cfg(test)]
mod test_support;
pub mod util;
pub mod vdb;
pub mod vtk;
pub mod wrf;
pub mod zarr;

pub use series::{Series, SeriesWriter};

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
    /// The resolution level of a multi-resolution store (OME-Zarr), 0 the
    /// finest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<usize>,
    /// Scales the pixel size a store's level is chosen by (where `level`
    /// is not given): 2 reads levels a step coarser (faster), 0.5 a step
    /// finer; 1 when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lod_scale: Option<f32>,
}

impl OpenOptions {
    /// `lod_scale`, 1 where not given; a scene file may hold any number,
    /// so it is checked here.
    pub fn lod_scale(&self) -> Result<f32> {
        match self.lod_scale {
            None => Ok(1.0),
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            Some(x) => Err(Error::invalid(format!(
                "lod_scale {x}: expected a positive number (1: a voxel no larger than a pixel; 2: a level coarser)"
            ))),
        }
    }
}

/// The formats voxcast reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Nrrd,
    MetaImage,
    Vtk,
    /// NIfTI-1, NIfTI-2 and Analyze 7.5 (one reader for the family).
    Nifti,
    /// FreeSurfer MGH/MGZ.
    Mgh,
    /// MINC-2 (HDF5; needs the reader of voxcast-native-io, feature `minc`).
    Minc,
    Dicom,
    ImageStack,
    Raw,
    Vdb,
    Fds,
    /// A frame folder written by a simulator (`series.toml` + frames).
    Series,
    /// Mitsuba's binary grid (`.vol`, "VOL" version 3).
    MitsubaVol,
    /// WRF output (NetCDF-4 / NetCDF classic; needs the reader of
    /// voxcast-native-io, feature `wrf`).
    Wrf,
    /// A Zarr v2/v3 store or array, OME-Zarr multiscales.
    Zarr,
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
        if zarr::is_zarr(path) {
            return Ok(Format::Zarr);
        }
        if crate::io::Series::is_frame_folder(path) {
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
    } else if [".nii", ".nii.gz", ".hdr", ".hdr.gz", ".img", ".img.gz"]
        .iter()
        .any(|e| name.ends_with(e))
    {
        Some(Format::Nifti)
    } else if name.ends_with(".mgh") || name.ends_with(".mgz") {
        Some(Format::Mgh)
    } else if name.ends_with(".mnc") || name.ends_with(".mnc2") {
        Some(Format::Minc)
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
    } else if name.ends_with(".zip") || name.ends_with(".ozx") {
        // A zipped Zarr store; any other zip file is refused by the
        // store's reader, naming what it lacks.
        Some(Format::Zarr)
    } else {
        None
    };
    if let Some(f) = by_ext {
        return Ok(f);
    }
    let head = util::read_head(path, 352)?;
    let nifti1_magic =
        head.len() >= 348 && (&head[344..348] == b"n+1\0" || &head[344..348] == b"ni1\0");
    let nifti2_magic = head.len() >= 12 && &head[4..12] == b"n+2\0\r\n\x1a\n";
    if head.starts_with(b"NRRD") {
        Ok(Format::Nrrd)
    } else if head.starts_with(b"# vtk DataFile") {
        Ok(Format::Vtk)
    } else if nifti1_magic || nifti2_magic {
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
            "unknown format (known: .nrrd .nhdr .mhd .mha .vtk .nii .nii.gz .hdr/.img .mgh .mgz .mnc .vdb .smv .vol .nc/wrfout_*, DICOM folders or .dcm, Zarr/OME-Zarr folders (or .zip/.ozx), PNG/TIFF slice folders or globs, raw with --raw-dims)",
        ))
    }
}

/// Opens any supported input as a volume.
pub fn open(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let mut vol = match detect(path, opts)? {
        Format::Nrrd => nrrd::read(path)?,
        Format::MetaImage => metaimage::read(path)?,
        Format::Vtk => vtk::read(path)?,
        Format::Nifti => nifti::read(path)?,
        Format::Mgh => mgh::read(path)?,
        Format::Minc => minc::read(path)?,
        Format::Dicom => dicom::read(path, opts)?,
        Format::ImageStack => image_stack::read(path)?,
        Format::Raw => raw::read(path, opts.raw.as_ref().expect("detect checked raw"))?,
        Format::Vdb => vdb::read(path, opts)?,
        Format::Fds => fds::read(path, opts)?,
        Format::Wrf => wrf::read(path, opts)?,
        Format::Series => {
            // One frame of the series: the nearest to `--time`, else the last.
            let s = crate::io::Series::open_folder(path)?;
            let i = opts.time.map(|t| s.nearest(t)).unwrap_or(s.len() - 1);
            s.load(i, opts)?
        }
        Format::MitsubaVol => mitsuba_vol::read(path)?,
        Format::Zarr => zarr::read(path, opts)?,
    };
    if let Some(s) = opts.spacing {
        vol.set_spacing(Vec3::from(s))?;
    }
    Ok(vol)
}

/// Header facts for `voxcast info` of the formats whose header says more
/// than the volume shows (NIfTI-1/2 and Analyze, MGH/MGZ, MINC-2): a title
/// and lines; `None` for other formats.
pub fn header_summary(
    path: &Path,
    opts: &OpenOptions,
) -> Result<Option<(&'static str, Vec<String>)>> {
    Ok(match detect(path, opts)? {
        Format::Nifti => Some(("NIfTI/Analyze header", nifti::summary(path)?)),
        Format::Mgh => Some(("MGH header", mgh::summary(path)?)),
        Format::Minc => Some(("MINC-2 header", minc::summary(path)?)),
        _ => None,
    })
}

#[cfg(test)]
mod detect_tests {
    use super::*;

    #[test]
    fn the_nifti_family_mgh_and_minc_are_detected() {
        let dir = tempfile::tempdir().unwrap();
        let opts = OpenOptions::default();
        for (name, format) in [
            ("brain.mnc", Format::Minc),
            ("brain.mgz", Format::Mgh),
            ("brain.mgh", Format::Mgh),
            ("brain.hdr", Format::Nifti),
            ("brain.img", Format::Nifti),
            ("brain.nii.gz", Format::Nifti),
        ] {
            let p = dir.path().join(name);
            std::fs::write(&p, [0u8; 8]).unwrap();
            assert_eq!(detect(&p, &opts).unwrap(), format, "{name}");
        }
        // By magic, whatever the name: NIfTI-1 (`n+1` at 344), NIfTI-2
        // (`n+2\0\r\n\x1a\n` at 4).
        let mut h = vec![0u8; 348];
        h[344..348].copy_from_slice(b"n+1\0");
        let p = dir.path().join("one.bin");
        std::fs::write(&p, &h).unwrap();
        assert_eq!(detect(&p, &opts).unwrap(), Format::Nifti);
        let mut h = vec![0u8; 540];
        h[4..12].copy_from_slice(b"n+2\0\r\n\x1a\n");
        let p = dir.path().join("two.bin");
        std::fs::write(&p, &h).unwrap();
        assert_eq!(detect(&p, &opts).unwrap(), Format::Nifti);
    }

    #[test]
    fn minc_without_the_feature_names_it_and_a_converter() {
        let dir = tempfile::tempdir().unwrap();
        let mut hdf5 = b"\x89HDF\r\n\x1a\n".to_vec();
        hdf5.resize(400, 0);
        let p = dir.path().join("brain.mnc");
        std::fs::write(&p, &hdf5).unwrap();
        let e = open(&p, &OpenOptions::default()).unwrap_err();
        let s = e.to_string();
        assert!(matches!(e, Error::Unsupported { .. }), "{s}");
        for w in ["brain.mnc", "MINC-2", "--features minc", "mnc2nii"] {
            assert!(s.contains(w), "{w}: {s}");
        }
    }
}
