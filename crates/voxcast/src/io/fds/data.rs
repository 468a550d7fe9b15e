//! Helpers shared by the binary data readers (SMOKE3D, PLOT3D, slices):
//! little-endian fields, reads checked against the file's size, and the
//! frame nearest a requested time.

use crate::error::{Error, Result};
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

pub(super) fn le_i32(b: &[u8], off: usize) -> i32 {
    i32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

pub(super) fn le_f32(b: &[u8], off: usize) -> f32 {
    f32::from_le_bytes([b[off], b[off + 1], b[off + 2], b[off + 3]])
}

pub(super) fn open_data(
    path: &Path,
    what: &str,
    smv: &Path,
) -> Result<(BufReader<std::fs::File>, u64)> {
    let (f, len) = crate::files::open(path)
        .map_err(|e| Error::format(smv, what, format!("cannot open the data file: {e}")))?;
    Ok((BufReader::new(f), len))
}

pub(super) fn read_at(
    r: &mut BufReader<std::fs::File>,
    path: &Path,
    len: u64,
    off: u64,
    n: usize,
    field: &str,
) -> Result<Vec<u8>> {
    if off.checked_add(n as u64).is_none_or(|end| end > len) {
        return Err(Error::format(
            path,
            field,
            format!(
                "needs bytes {off}..{} but the file has only {len} (truncated file?)",
                off.saturating_add(n as u64)
            ),
        ));
    }
    r.seek(SeekFrom::Start(off))
        .map_err(|e| Error::io(path, e))?;
    let mut buf = vec![0u8; n];
    r.read_exact(&mut buf).map_err(|e| Error::io(path, e))?;
    Ok(buf)
}

/// The index of the time nearest `want` (the last when `None`). A time
/// further than one mean frame interval outside the range is an error.
pub(super) fn pick_time(path: &Path, times: &[f64], want: Option<f64>) -> Result<usize> {
    let n = times.len();
    let Some(t) = want else {
        return Ok(n - 1);
    };
    let (lo, hi) = times
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    let tol = if n > 1 {
        (hi - lo) / (n - 1) as f64
    } else {
        1e-6 + 1e-3 * hi.abs()
    };
    if !t.is_finite() || t < lo - tol || t > hi + tol {
        return Err(Error::format(
            path,
            "time",
            format!("t = {t} is outside the {n} frames of this file: {lo} .. {hi} s"),
        ));
    }
    let mut best = 0;
    for (i, &x) in times.iter().enumerate() {
        if (x - t).abs() < (times[best] - t).abs() {
            best = i;
        }
    }
    Ok(best)
}
