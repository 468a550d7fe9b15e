//! Reader placeholder, being written.
use crate::error::{Error, Result};
use crate::volume::Volume;
use std::path::Path;

/// Reads the volume at `path`.
pub fn read(path: &Path) -> Result<Volume> {
    Err(Error::unsupported(path, "reader not written yet"))
}
