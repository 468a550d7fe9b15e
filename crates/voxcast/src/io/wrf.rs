//! WRF (Weather Research and Forecasting model) output: `wrfout` NetCDF-4
//! files, the weather data S3 fills its clouds from. The reader itself
//! is in the crate `voxcast-native-io` (feature `wrf`, over the system's
//! libnetcdf), installed through `io::external`; here are the file tests and
//! the entry points that call it.
//!
//! What is read: a mass-grid 4D variable `(Time, bottom_top, south_north,
//! west_east)` — QCLOUD by default, or a sum such as `QCLOUD+QICE` — at one
//! time index (`--time INDEX`). WRF's vertical coordinate is terrain-
//! following (eta), so each column's true heights come from the geopotential,
//! `z = (PH + PHB) / g` on the staggered levels (`bottom_top_stag`), averaged
//! to the mass levels; the column is then resampled linearly onto a regular
//! vertical grid from the lowest to the highest mass level of the domain.
//! Horizontal spacing is the file's `DX`, `DY` (metres).

use crate::error::{Error, Result};
use crate::io::external;
use crate::io::OpenOptions;
use crate::volume::Volume;
use std::path::Path;

/// True when `name` looks like WRF/NetCDF output by its name.
pub fn is_wrf_name(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    n.ends_with(".nc") || n.ends_with(".nc4") || n.starts_with("wrfout")
}

/// True when `head` starts with the HDF5 (NetCDF-4) or classic NetCDF magic.
pub fn is_netcdf_magic(head: &[u8]) -> bool {
    head.starts_with(b"\x89HDF\r\n\x1a\n")
        || head.starts_with(b"CDF\x01")
        || head.starts_with(b"CDF\x02")
}

/// The installed reader, or what a user without it is told.
fn reader(path: &Path) -> Result<external::WrfReader> {
    external::installed().wrf.ok_or_else(|| {
        Error::unsupported(
            path,
            "WRF/NetCDF input needs voxcast built with `--features wrf` (and the system libraries: apt-get install libnetcdf-dev libhdf5-dev)",
        )
    })
}

/// Reads the variable `opts.variable` (default QCLOUD; `A+B` sums) at time
/// index `opts.time` (default 0), resampled to a regular height grid.
pub fn read(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    (reader(path)?.read)(path, opts)
}

/// Lines describing the file for `voxcast info`: variables and times.
pub fn summary(path: &Path) -> Result<Vec<String>> {
    (reader(path)?.summary)(path)
}

/// The `Times` strings of the file, one per time index.
pub fn times(path: &Path) -> Result<Vec<String>> {
    (reader(path)?.times)(path)
}
