//! Helpers shared by the readers: bounded reads, size checks, decoding.

use crate::error::{Error, Result};
use crate::volume::{checked_voxel_count, ScalarType, VoxelData};
use std::io::Read;
use std::path::Path;

/// Deflate cannot compress better than about 1032:1; a gzip stream that
/// claims to inflate to more than this many times its size is lying.
pub const MAX_DEFLATE_RATIO: u64 = 1100;

/// Up to the first `n` bytes of a file.
pub fn read_head(path: &Path, n: usize) -> Result<Vec<u8>> {
    let f = crate::files::open(path)?.0;
    let mut buf = Vec::with_capacity(n);
    f.take(n as u64)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    Ok(buf)
}

/// Size of a file in bytes.
pub fn file_len(path: &Path) -> Result<u64> {
    Ok(std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len())
}

/// Checks dims from a header (`field` names them in the error) and returns
/// the voxel count and the byte count for `ty`.
pub fn check_dims(
    path: &Path,
    field: &str,
    dims: [u64; 3],
    ty: ScalarType,
) -> Result<(usize, u64)> {
    let n = checked_voxel_count(dims).map_err(|m| Error::format(path, field, m))?;
    Ok((n, n as u64 * ty.size() as u64))
}

/// Reads `n_bytes` of voxel data from `path` starting at byte `offset`,
/// gzip-compressed or not, and decodes them as `ty`. The sizes are checked
/// against the file before anything is allocated: an uncompressed payload
/// must fit in the file, a compressed one must be possible at deflate's best
/// ratio; a payload that ends early is an error naming `field`.
pub fn read_payload(
    path: &Path,
    offset: u64,
    n_bytes: u64,
    ty: ScalarType,
    big_endian: bool,
    gzip: bool,
    field: &str,
) -> Result<VoxelData> {
    let len = file_len(path)?;
    let avail = len.saturating_sub(offset);
    if offset > len {
        return Err(Error::format(
            path,
            field,
            format!("data should start at byte {offset} but the file has only {len} bytes"),
        ));
    }
    if !gzip && avail < n_bytes {
        return Err(Error::format(
            path,
            field,
            format!(
                "the header describes {n_bytes} bytes of voxels but the file holds only {avail} after byte {offset} (truncated file or wrong dims/type)"
            ),
        ));
    }
    if gzip && avail.saturating_mul(MAX_DEFLATE_RATIO) < n_bytes {
        return Err(Error::format(
            path,
            field,
            format!(
                "the header describes {n_bytes} bytes of voxels but {avail} compressed bytes cannot hold that many"
            ),
        ));
    }
    let f = open_at(path, offset)?;
    let bytes = if gzip {
        read_exact_or_short(flate2::read::MultiGzDecoder::new(f), n_bytes, path, field)?
    } else {
        read_exact_or_short(f, n_bytes, path, field)?
    };
    Ok(VoxelData::from_bytes(ty, &bytes, big_endian))
}

/// Reads `n_bytes` of gzip-compressed data starting at byte `offset` of
/// `path` (same checks as [`read_payload`]) and counts the decompressed
/// bytes that follow them, up to 1 MiB: a stream longer than the header
/// says is a wrong header or the wrong file.
pub fn read_gzip_and_count_rest(
    path: &Path,
    offset: u64,
    n_bytes: u64,
    field: &str,
) -> Result<(Vec<u8>, u64)> {
    let len = file_len(path)?;
    let avail = len.saturating_sub(offset);
    if offset > len || avail.saturating_mul(MAX_DEFLATE_RATIO) < n_bytes {
        return Err(Error::format(
            path,
            field,
            format!(
                "the header describes {n_bytes} bytes of voxels but {avail} compressed bytes after byte {offset} cannot hold that many"
            ),
        ));
    }
    let f = open_at(path, offset)?;
    let dec = flate2::read::MultiGzDecoder::new(f);
    read_and_count_rest(dec, n_bytes, path, field)
}

/// Reads `n_bytes` of bzip2-compressed data starting at byte `offset` of
/// `path` and counts the decompressed bytes that follow them (up to 1 MiB).
/// The buffer grows only as data arrives.
pub fn read_bzip2_and_count_rest(
    path: &Path,
    offset: u64,
    n_bytes: u64,
    field: &str,
) -> Result<(Vec<u8>, u64)> {
    let len = file_len(path)?;
    if offset > len {
        return Err(Error::format(
            path,
            field,
            format!("data should start at byte {offset} but the file has only {len} bytes"),
        ));
    }
    let f = open_at(path, offset)?;
    let dec = bzip2::read::MultiBzDecoder::new(std::io::BufReader::new(f));
    read_and_count_rest(dec, n_bytes, path, field)
}

/// `path` opened as an input and positioned at byte `offset`.
fn open_at(path: &Path, offset: u64) -> Result<std::fs::File> {
    let mut f = crate::files::open(path)?.0;
    std::io::Seek::seek(&mut f, std::io::SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    Ok(f)
}

/// Reads `n` bytes from the decoder `dec`, then counts the decoded bytes
/// that follow them, up to 1 MiB.
fn read_and_count_rest(
    mut dec: impl Read,
    n: u64,
    path: &Path,
    field: &str,
) -> Result<(Vec<u8>, u64)> {
    let bytes = read_exact_or_short(&mut dec, n, path, field)?;
    let rest = std::io::copy(&mut dec.take(1 << 20), &mut std::io::sink())
        .map_err(|e| Error::format(path, field, format!("cannot decode the data: {e}")))?;
    Ok((bytes, rest))
}

/// Reads exactly `n` bytes from `r`, growing the buffer only as data arrives
/// (so a lying header cannot make us allocate what is not there).
pub fn read_exact_or_short(r: impl Read, n: u64, path: &Path, field: &str) -> Result<Vec<u8>> {
    let mut buf = Vec::with_capacity(n.min(64 << 20) as usize);
    r.take(n)
        .read_to_end(&mut buf)
        .map_err(|e| Error::format(path, field, format!("cannot decode the data: {e}")))?;
    if (buf.len() as u64) < n {
        return Err(Error::format(
            path,
            field,
            format!(
                "the data ends after {} bytes but the header describes {n} (truncated file or wrong dims/type)",
                buf.len()
            ),
        ));
    }
    Ok(buf)
}

/// Runs a third-party decoder on a user's file, turning a panic inside it
/// (a bug of that crate on malformed input, e.g. the `tiff` crate indexing
/// an empty strip table) into an error naming the file: user files are
/// untrusted input and must not take the program down.
pub fn no_panic<T>(path: &Path, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|_| {
        Err(Error::format(
            path,
            what,
            format!("the {what} decoder failed on this file (malformed or unsupported data)"),
        ))
    })
}

/// Parses exactly `N` whitespace- or comma-separated numbers.
pub fn parse_numbers<T: std::str::FromStr, const N: usize>(
    path: &Path,
    field: &str,
    s: &str,
) -> Result<[T; N]> {
    let parts: Vec<&str> = s
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|p| !p.is_empty())
        .collect();
    if parts.len() != N {
        return Err(Error::format(
            path,
            field,
            format!("expected {N} numbers, found `{}`", s.trim()),
        ));
    }
    let mut out = Vec::with_capacity(N);
    for p in parts {
        out.push(p.parse::<T>().map_err(|_| {
            Error::format(
                path,
                field,
                format!("`{p}` is not a valid number (in `{}`)", s.trim()),
            )
        })?);
    }
    out.try_into()
        .map_err(|_| Error::format(path, field, "wrong number of values"))
}

/// Sorts strings in natural order: runs of digits compare as numbers, so
/// `slice2` < `slice10`.
pub fn natural_cmp(a: &str, b: &str) -> std::cmp::Ordering {
    use std::cmp::Ordering;
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let na = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let nb = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let (da, db) = (&a[..na], &b[..nb]);
                let ta = trim_zeros(da);
                let tb = trim_zeros(db);
                let ord = ta
                    .len()
                    .cmp(&tb.len())
                    .then_with(|| ta.cmp(tb))
                    .then(na.cmp(&nb));
                if ord != Ordering::Equal {
                    return ord;
                }
                a = &a[na..];
                b = &b[nb..];
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                a = &a[1..];
                b = &b[1..];
            }
        }
    }
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let z = d.iter().take_while(|&&c| c == b'0').count();
    &d[z..]
}

/// Number of indices in `min, min+step, … max` (the file-name patterns of
/// NRRD's and MetaImage's multi-file data), or `None` when they go nowhere.
pub(crate) fn pattern_count(min: i64, max: i64, step: i64) -> Option<u64> {
    if step == 0 {
        return None;
    }
    let span = max.checked_sub(min)?;
    if span != 0 && (span < 0) != (step < 0) {
        return None;
    }
    u64::try_from(span.checked_div(step)?).ok()?.checked_add(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order() {
        let mut v = vec!["s10.png", "s2.png", "s1.png", "s02.png", "a.png"];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(v, ["a.png", "s1.png", "s2.png", "s02.png", "s10.png"]);
    }

    #[test]
    fn lying_gzip_size_is_refused_before_allocating() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.gz");
        std::fs::write(&p, [0u8; 1000]).unwrap();
        let e = read_payload(&p, 0, 1 << 30, ScalarType::U8, false, true, "data").unwrap_err();
        assert!(e.to_string().contains("cannot hold"), "{e}");
    }
}
