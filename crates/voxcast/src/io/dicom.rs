//! Reader placeholder, being written.
use crate::error::{Error, Result};
use crate::volume::Volume;
use std::path::Path;

/// Reads the volume at `path`.
pub fn read(path: &Path) -> Result<Volume> {
    Err(Error::unsupported(path, "reader not written yet"))
}

/// True when the folder holds DICOM files.
pub fn folder_has_dicom(path: &Path) -> Result<bool> {
    let _ = path;
    Ok(false)
}
