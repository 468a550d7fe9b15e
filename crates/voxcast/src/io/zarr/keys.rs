//! Where a store's keys come from — a folder's files, or a zip file's
//! entries (OME-Zarr's zipped stores, `.ozx`, or any `.zip`) — and reading
//! its metadata through them, so both kinds go through one path.

use super::zerr;
use crate::error::{Error, Result};
use serde_json::Value;
use std::path::Path;
use std::sync::Arc;
use zarrs::filesystem::FilesystemStore;
use zarrs::storage::{ReadableStorageTraits, StoreKey};

/// The files that mark a Zarr store or array at its root.
const MARKERS: [&str; 3] = ["zarr.json", ".zgroup", ".zarray"];

/// True if `path` is a Zarr store or array: a folder holding `zarr.json`
/// (v3), `.zgroup` or `.zarray` (v2), or a zip file (`.zip`, `.ozx`) with
/// one of them at its root.
pub fn is_zarr(path: &Path) -> bool {
    matches!(open_storage(path), Ok(Some(s)) if Keys { root: path, storage: s.as_ref() }.is_store())
}

/// A file name a zipped store has: `.zip` or `.ozx` (OME-Zarr's).
fn is_zip_name(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("zip") || e.eq_ignore_ascii_case("ozx"))
}

/// The keys under `path`: a folder's files, or a zip file's entries (an
/// error where the zip cannot be read); `None` for anything else.
pub(super) fn open_storage(path: &Path) -> Result<Option<Arc<dyn ReadableStorageTraits>>> {
    if path.is_dir() {
        let fs = FilesystemStore::new(path).map_err(|e| zerr(path, "store", e))?;
        return Ok(Some(Arc::new(fs)));
    }
    if !(path.is_file() && is_zip_name(path)) {
        return Ok(None);
    }
    let (dir, name) = match (path.parent(), path.file_name().and_then(|n| n.to_str())) {
        (Some(d), Some(n)) if d.as_os_str().is_empty() => (Path::new("."), n),
        (Some(d), Some(n)) => (d, n),
        _ => return Err(Error::unsupported(path, "not a zip file name")),
    };
    let fs = FilesystemStore::new(dir).map_err(|e| zerr(path, "store", e))?;
    let key = StoreKey::new(name).map_err(|e| zerr(path, "file name", e))?;
    let zip = zarrs_zip::ZipStorageAdapter::new(Arc::new(fs), key)
        .map_err(|e| Error::format(path, "zip", e.to_string()))?;
    Ok(Some(Arc::new(zip)))
}

/// A store's keys, read for its metadata (the folder's files, or a zip
/// file's entries); `root` names the store in messages.
pub(super) struct Keys<'a> {
    pub root: &'a Path,
    pub storage: &'a dyn ReadableStorageTraits,
}

impl Keys<'_> {
    /// Whether a store or array starts here (one of the markers).
    pub fn is_store(&self) -> bool {
        MARKERS.iter().any(|m| self.exists(m))
    }

    /// Whether the store has key `k`.
    pub fn exists(&self, k: &str) -> bool {
        self.size(k).is_some()
    }

    /// The size of key `k`, where it is there.
    pub fn size(&self, k: &str) -> Option<u64> {
        StoreKey::new(k)
            .ok()
            .and_then(|k| self.storage.size_key(&k).ok().flatten())
    }

    /// The bytes of key `k`.
    pub fn bytes(&self, k: &str) -> Result<Vec<u8>> {
        let p = self.root.join(k);
        let key = StoreKey::new(k).map_err(|e| Error::format(&p, "key", e.to_string()))?;
        match self.storage.get(&key) {
            Ok(Some(b)) => Ok(b.to_vec()),
            Ok(None) => Err(Error::io(
                &p,
                std::io::Error::new(std::io::ErrorKind::NotFound, "not in the store"),
            )),
            Err(e) => Err(Error::format(&p, "read", e.to_string())),
        }
    }

    /// Key `k` as JSON (at most 64 MiB).
    pub fn json(&self, k: &str) -> Result<Value> {
        let p = self.root.join(k);
        let n = self.size(k).unwrap_or(0);
        if n > 64 << 20 {
            return Err(Error::format(
                &p,
                "size",
                format!("{n} bytes of JSON metadata (at most 64 MiB)"),
            ));
        }
        let bytes = self.bytes(k)?;
        serde_json::from_slice(&bytes).map_err(|e| Error::format(&p, "JSON", e.to_string()))
    }
}
