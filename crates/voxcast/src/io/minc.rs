//! MINC-2 volumes (`.mnc`, HDF5). The reader is in the crate
//! `voxcast-native-io` (feature `minc`: libnetcdf, shared with `wrf`, opens
//! MINC-2's HDF5 layout), installed through `io::external`; the default
//! build stays free of C libraries, and without the reader a `.mnc` file is
//! refused with the feature to enable and a converter. (MINC-1 files are
//! NetCDF-3: they are not read.) What the reader does:
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

use crate::error::{Error, Result};
use crate::io::external;
use crate::volume::Volume;
use std::path::Path;

/// The installed reader, or what a user without it is told.
fn reader(path: &Path) -> Result<external::MincReader> {
    external::installed().minc.ok_or_else(|| {
        Error::unsupported(
            path,
            "MINC-2 (.mnc) needs voxcast built with `--features minc` (links libnetcdf: apt-get install libnetcdf-dev libhdf5-dev); or convert it to NIfTI with `mnc2nii IN.mnc OUT.nii` (minc-tools) or nibabel (`python3 -c \"import nibabel as nib, sys; nib.save(nib.Nifti1Image.from_image(nib.load(sys.argv[1])), sys.argv[2])\" IN.mnc OUT.nii.gz`)",
        )
    })
}

/// Reads a MINC-2 volume.
pub fn read(path: &Path) -> Result<Volume> {
    (reader(path)?.read)(path)
}

/// Lines describing the file for `voxcast info`.
pub fn summary(path: &Path) -> Result<Vec<String>> {
    (reader(path)?.summary)(path)
}
