//! Helpers shared by the readers' tests.

use crate::error::Result;
use crate::volume::Volume;
use std::path::{Path, PathBuf};

/// The error of `r`, which must name `file` and `field`.
pub(crate) fn err_naming(r: Result<Volume>, file: &str, field: &str) -> String {
    let s = match r {
        Ok(v) => panic!("expected an error naming {field}, read {:?}", v.dims()),
        Err(e) => e.to_string(),
    };
    assert!(s.contains(file), "error does not name {file}: {s}");
    assert!(s.contains(field), "error does not name {field}: {s}");
    s
}

/// Truncates `base` at every length and overwrites every byte of its first
/// `head` bytes with awkward characters: `read` must never panic.
pub(crate) fn never_panics(
    read: fn(&Path) -> Result<Volume>,
    dir: &Path,
    name: &str,
    base: &[u8],
    head: usize,
) {
    let p = dir.join(name);
    for cut in 0..base.len() {
        std::fs::write(&p, &base[..cut]).unwrap();
        let _ = read(&p);
    }
    for i in 0..head.min(base.len()) {
        for c in [
            b'0', b'9', b'-', b' ', b'\n', b':', b'=', b'(', b'%', b'#', 0xff,
        ] {
            let mut m = base.to_vec();
            m[i] = c;
            std::fs::write(&p, &m).unwrap();
            let _ = read(&p);
        }
    }
}

/// Writes `bytes` to `dir/name` and returns the path.
pub(crate) fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}
