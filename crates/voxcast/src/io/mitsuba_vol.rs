//! Mitsuba's binary grid volume (`.vol`, the `gridvolume` format of
//! Mitsuba 0.6 and the `volgrid` files Mitsuba 3 reads): a 48-byte header
//! and the voxels, little-endian.
//!
//! | bytes | field |
//! |---|---|
//! | 0–2 | `VOL` |
//! | 3 | version, 3 |
//! | 4–7 | encoding (i32): 1 = float32 (the only one read here) |
//! | 8–19 | x, y, z resolution (i32) |
//! | 20–23 | channels (i32): 1 = a density grid |
//! | 24–47 | bounding box xmin, ymin, zmin, xmax, ymax, zmax (f32) |
//! | 48– | `((z·ny + y)·nx + x)·channels + c`, f32 |
//!
//! The grid's samples sit on the box's corners and span it (Mitsuba 0.6's
//! `(p − min)/(max − min)·(res − 1)` lookup), so the spacing is
//! `(max − min)/(res − 1)` and the origin is `min`.

use super::util::{check_dims, file_len, read_head, read_payload};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume};
use glam::Vec3;
use std::path::Path;

/// Size of the header.
pub const HEADER: usize = 48;

/// True when `head` starts like a Mitsuba `.vol` file.
pub fn is_vol(head: &[u8]) -> bool {
    head.len() >= 4 && &head[..3] == b"VOL"
}

/// Reads a Mitsuba `.vol` file.
pub fn read(path: &Path) -> Result<Volume> {
    let head = read_head(path, HEADER)?;
    if head.len() < HEADER {
        return Err(Error::format(
            path,
            "header",
            format!(
                "a .vol header has {HEADER} bytes, the file has only {}",
                head.len()
            ),
        ));
    }
    if &head[..3] != b"VOL" {
        return Err(Error::format(
            path,
            "magic",
            "expected the bytes `VOL` at the start of a Mitsuba volume",
        ));
    }
    if head[3] != 3 {
        return Err(Error::unsupported(
            path,
            format!("version {} (only version 3 is defined)", head[3]),
        ));
    }
    let i32_at = |o: usize| i32::from_le_bytes([head[o], head[o + 1], head[o + 2], head[o + 3]]);
    let f32_at = |o: usize| f32::from_le_bytes([head[o], head[o + 1], head[o + 2], head[o + 3]]);
    let encoding = i32_at(4);
    if encoding != 1 {
        return Err(Error::unsupported(
            path,
            format!(
                "encoding {encoding} (only 1 = float32 is read; 2 = float16, 3 = uint8 and 4 = quantised are not)"
            ),
        ));
    }
    let res = [i32_at(8), i32_at(12), i32_at(16)];
    if res.iter().any(|&r| r < 1) {
        return Err(Error::format(
            path,
            "resolution",
            format!("{res:?}: each must be at least 1"),
        ));
    }
    let channels = i32_at(20);
    if channels != 1 {
        return Err(Error::unsupported(
            path,
            format!("channels {channels}: only single-channel (density) grids are read"),
        ));
    }
    let lo = Vec3::new(f32_at(24), f32_at(28), f32_at(32));
    let hi = Vec3::new(f32_at(36), f32_at(40), f32_at(44));
    if !(lo.is_finite() && hi.is_finite()) || (0..3).any(|a| hi[a] < lo[a]) {
        return Err(Error::format(
            path,
            "bbox",
            format!("min {lo} max {hi}: expected finite numbers with min ≤ max"),
        ));
    }
    if let Some(a) = (0..3).find(|&a| hi[a] == lo[a] && res[a] > 1) {
        return Err(Error::format(
            path,
            "bbox",
            format!(
                "min {lo} max {hi}: flat along {} although the resolution there is {}: the samples would have no spacing",
                ["x", "y", "z"][a],
                res[a]
            ),
        ));
    }
    let dims = res.map(|r| r as u64);
    let (_, n_bytes) = check_dims(path, "resolution", dims, ScalarType::F32)?;
    let len = file_len(path)?;
    if len - HEADER as u64 > n_bytes {
        // Trailing bytes usually mean the resolution or channels are wrong.
        return Err(Error::format(
            path,
            "resolution",
            format!(
                "{res:?} × 1 channel needs {n_bytes} bytes of float32 but the file holds {} after the header",
                len - HEADER as u64
            ),
        ));
    }
    let data = read_payload(
        path,
        HEADER as u64,
        n_bytes,
        ScalarType::F32,
        false,
        false,
        "data",
    )?;
    let dims = dims.map(|d| d as usize);
    let spacing = Vec3::new(
        spacing_of(lo.x, hi.x, dims[0]),
        spacing_of(lo.y, hi.y, dims[1]),
        spacing_of(lo.z, hi.z, dims[2]),
    );
    let mut v = Volume::new(dims, spacing, lo, data)
        .map_err(|e| Error::format(path, "data", e.to_string()))?;
    v.name = Some("density".into());
    Ok(v)
}

/// Spacing of `n` samples spanning `[lo, hi]` (1 when degenerate).
fn spacing_of(lo: f32, hi: f32, n: usize) -> f32 {
    let s = if n > 1 {
        (hi - lo) / (n - 1) as f32
    } else {
        hi - lo
    };
    if s > 0.0 && s.is_finite() {
        s
    } else {
        1.0
    }
}

/// Writes a single-channel float32 `.vol` (for tests and conversions).
pub fn encode(dims: [usize; 3], lo: [f32; 3], hi: [f32; 3], values: &[f32]) -> Vec<u8> {
    let mut b = Vec::with_capacity(HEADER + values.len() * 4);
    b.extend_from_slice(b"VOL");
    b.push(3);
    b.extend_from_slice(&1i32.to_le_bytes());
    for d in dims {
        b.extend_from_slice(&(d as i32).to_le_bytes());
    }
    b.extend_from_slice(&1i32.to_le_bytes());
    for x in lo.iter().chain(hi.iter()) {
        b.extend_from_slice(&x.to_le_bytes());
    }
    for v in values {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_support::{err_naming, never_panics, write};

    fn sample() -> Vec<u8> {
        let values: Vec<f32> = (0..4 * 3 * 2).map(|i| i as f32 * 0.5).collect();
        encode([4, 3, 2], [-1.0, 0.0, 2.0], [2.0, 1.0, 4.0], &values)
    }

    #[test]
    fn reads_values_layout_and_box() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(dir.path(), "a.vol", &sample());
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [4, 3, 2]);
        // x fastest, as in voxcast.
        assert_eq!(v.value(1, 0, 0), 0.5);
        assert_eq!(v.value(0, 1, 0), 2.0);
        assert_eq!(v.value(3, 2, 1), 11.5);
        assert_eq!(v.origin(), Vec3::new(-1.0, 0.0, 2.0));
        assert_eq!(v.spacing(), Vec3::new(1.0, 0.5, 2.0));
        let (_, hi) = v.world_bounds();
        assert!((hi - Vec3::new(2.0, 1.0, 4.0)).length() < 1e-6);
        // Picked by extension and by magic through io::open.
        let v2 = crate::io::open(&p, &Default::default()).unwrap();
        assert_eq!(v2.dims(), [4, 3, 2]);
        let q = write(dir.path(), "noext", &sample());
        assert_eq!(
            crate::io::open(&q, &Default::default()).unwrap().dims(),
            [4, 3, 2]
        );
    }

    #[test]
    fn a_flat_bounding_box_is_refused_naming_bbox() {
        let dir = tempfile::tempdir().unwrap();
        let values = vec![0.0f32; 4 * 3 * 2];
        // y is flat but has 3 samples.
        let b = encode([4, 3, 2], [-1.0, 5.0, 2.0], [2.0, 5.0, 4.0], &values);
        let p = write(dir.path(), "flat.vol", &b);
        let s = err_naming(read(&p), "flat.vol", "bbox");
        assert!(s.contains("flat along y"), "{s}");
        // One sample on a flat axis is a single slice: read.
        let b = encode([4, 3, 1], [-1.0, 0.0, 2.0], [2.0, 1.0, 2.0], &values[..12]);
        let p = write(dir.path(), "slice.vol", &b);
        assert_eq!(read(&p).unwrap().dims(), [4, 3, 1]);
    }

    #[test]
    fn truncated_and_bad_headers_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let b = sample();
        let p = write(dir.path(), "t.vol", &b[..b.len() - 4]);
        err_naming(read(&p), "t.vol", "data");
        let p = write(dir.path(), "h.vol", &b[..20]);
        err_naming(read(&p), "h.vol", "header");
        let mut big = b.clone();
        big[8..12].copy_from_slice(&1_000_000i32.to_le_bytes());
        let p = write(dir.path(), "big.vol", &big);
        err_naming(read(&p), "big.vol", "data");
        let mut neg = b.clone();
        neg[12..16].copy_from_slice(&(-3i32).to_le_bytes());
        let p = write(dir.path(), "neg.vol", &neg);
        err_naming(read(&p), "neg.vol", "resolution");
        let mut rgb = b.clone();
        rgb[20..24].copy_from_slice(&3i32.to_le_bytes());
        let p = write(dir.path(), "rgb.vol", &rgb);
        let e = read(&p).unwrap_err().to_string();
        assert!(e.contains("rgb.vol") && e.contains("channels"), "{e}");
        let mut extra = b.clone();
        extra.extend_from_slice(&[0; 8]);
        let p = write(dir.path(), "x.vol", &extra);
        err_naming(read(&p), "x.vol", "resolution");
        never_panics(read, dir.path(), "f.vol", &b, HEADER);
    }
}
