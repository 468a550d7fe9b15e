//! SMOKE3D `.s3d` files: frame headers, the RLE decoder, and the map from
//! a stored byte to a physical value (soot extinction, HRRPUV, temperature).

use super::data::{le_f32, le_i32, open_data, pick_time, read_at};
use super::model::Smoke3d;
use crate::error::{Error, Result};
use std::path::Path;

/// HRRPUV that maps to byte 254 in SMOKE3D files (FDS HRRPUV_MAX_SMV), kW/m³.
const HRRPUV_MAX_SMV: f32 = 1200.0;
/// Temperatures mapped to bytes 0 and 254 (FDS TMPA, TEMP_MAX_SMV), °C.
const TEMP_MIN_SMV: f32 = 20.0;
const TEMP_MAX_SMV: f32 = 2000.0;

/// One decoded SMOKE3D frame.
#[derive(Clone, Debug)]
pub struct S3dFrame {
    /// Time of this frame, s.
    pub time: f32,
    /// Index of this frame in the file.
    pub index: usize,
    /// The times of all frames in the file.
    pub times: Vec<f32>,
    /// Node bounds from the header: i1 i2 j1 j2 k1 k2.
    pub bounds: [usize; 6],
    /// Node counts.
    pub dims: [usize; 3],
    /// The decoded bytes, i fastest.
    pub bytes: Vec<u8>,
}

/// Decodes FDS/Smokeview RLE: `0xFF value count` is a run, anything else a
/// literal. The output must be exactly `nin` bytes.
pub fn decode_rle(input: &[u8], nin: usize) -> std::result::Result<Vec<u8>, String> {
    let mut out = Vec::with_capacity(nin);
    let mut i = 0;
    while i < input.len() {
        let b = input[i];
        if b == 0xFF {
            if i + 2 >= input.len() {
                return Err(format!("RLE run at byte {i} is cut off"));
            }
            let (v, n) = (input[i + 1], input[i + 2] as usize);
            if out.len() + n > nin {
                return Err(format!("RLE data decodes to more than {nin} values"));
            }
            out.resize(out.len() + n, v);
            i += 3;
        } else {
            if out.len() >= nin {
                return Err(format!("RLE data decodes to more than {nin} values"));
            }
            out.push(b);
            i += 1;
        }
    }
    if out.len() != nin {
        return Err(format!(
            "RLE data decodes to {} values, expected {nin}",
            out.len()
        ));
    }
    Ok(out)
}

/// Reads the frame of the `.s3d` file at `path` nearest to `time` (the last
/// one when `None`). Only that frame is decoded; the others are skipped.
pub fn read_s3d_frame(path: &Path, time: Option<f64>) -> Result<S3dFrame> {
    read_s3d(path, time, true)
}

/// The times of all frames of an `.s3d` file (headers only, nothing decoded).
pub fn s3d_times(path: &Path) -> Result<Vec<f32>> {
    Ok(read_s3d(path, None, false)?.times)
}

fn read_s3d(path: &Path, time: Option<f64>, decode: bool) -> Result<S3dFrame> {
    let (mut r, len) = open_data(path, "SMOKF3D", path)?;
    let h = read_at(&mut r, path, len, 0, 40, "header")?;
    if le_i32(&h, 0) != 32 || le_i32(&h, 36) != 32 {
        return Err(Error::format(
            path,
            "header",
            format!(
                "record markers {} and {} should be 32 (not a little-endian SMOKE3D file?)",
                le_i32(&h, 0),
                le_i32(&h, 36)
            ),
        ));
    }
    if le_i32(&h, 4) != 1 {
        return Err(Error::unsupported(
            path,
            format!("endian flag {} (expected 1)", le_i32(&h, 4)),
        ));
    }
    if le_i32(&h, 8) != 0 {
        return Err(Error::unsupported(
            path,
            format!("SMOKE3D version {} (only 0 = RLE is read)", le_i32(&h, 8)),
        ));
    }
    let b: Vec<i32> = (0..6).map(|a| le_i32(&h, 12 + 4 * a)).collect();
    if (0..3).any(|a| b[2 * a] < 0 || b[2 * a + 1] < b[2 * a]) {
        return Err(Error::format(
            path,
            "header",
            format!("node bounds {b:?} must satisfy 0 <= i1 <= i2 etc."),
        ));
    }
    let bounds = [0, 1, 2, 3, 4, 5].map(|a| b[a] as usize);
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    let nin_expected = crate::volume::checked_voxel_count(dims.map(|d| d as u64))
        .map_err(|m| Error::format(path, "header", m))?;

    // Scan frame headers.
    let mut frames: Vec<(f32, u64, usize)> = Vec::new();
    let mut off = 40u64;
    while off < len {
        let k = frames.len();
        let field = format!("frame {k}");
        let fh = read_at(&mut r, path, len, off, 32, &field)?;
        if le_i32(&fh, 0) != 4
            || le_i32(&fh, 8) != 4
            || le_i32(&fh, 12) != 8
            || le_i32(&fh, 24) != 8
        {
            return Err(Error::format(
                path,
                field,
                format!("bad record markers at byte {off}"),
            ));
        }
        let t = le_f32(&fh, 4);
        let nin = le_i32(&fh, 16);
        let nout = le_i32(&fh, 20);
        if nin < 0 || nin as usize != nin_expected {
            return Err(Error::format(
                path,
                field,
                format!("nin = {nin}, expected {nin_expected} nodes"),
            ));
        }
        if nout < 0 || le_i32(&fh, 28) != nout {
            return Err(Error::format(
                path,
                field,
                format!(
                    "nout = {nout} and its record marker {} disagree",
                    le_i32(&fh, 28)
                ),
            ));
        }
        let end = off + 36 + nout as u64;
        if end > len {
            return Err(Error::format(
                path,
                field,
                format!(
                    "frame at t = {t} s needs bytes {off}..{end} but the file has only {len} (truncated file?)"
                ),
            ));
        }
        frames.push((t, off, nout as usize));
        off = end;
    }
    if frames.is_empty() {
        return Err(Error::format(path, "frames", "the file holds no frame"));
    }
    let times: Vec<f32> = frames.iter().map(|f| f.0).collect();
    let index = pick_time(
        path,
        &times.iter().map(|&t| t as f64).collect::<Vec<_>>(),
        time,
    )?;
    let (t, foff, nout) = frames[index];
    let field = format!("frame {index}");
    if !decode {
        return Ok(S3dFrame {
            time: t,
            index,
            times,
            bounds,
            dims,
            bytes: Vec::new(),
        });
    }
    // A 3-byte run holds at most 254 values: bound the output by the input.
    if nin_expected as u64 > nout as u64 * 85 {
        return Err(Error::format(
            path,
            &field,
            format!("{nout} RLE bytes cannot hold {nin_expected} values"),
        ));
    }
    let data = read_at(&mut r, path, len, foff + 32, nout + 4, &field)?;
    if le_i32(&data, nout) != nout as i32 {
        return Err(Error::format(path, &field, "bad closing record marker"));
    }
    let bytes =
        decode_rle(&data[..nout], nin_expected).map_err(|m| Error::format(path, &field, m))?;
    Ok(S3dFrame {
        time: t,
        index,
        times,
        bounds,
        dims,
        bytes,
    })
}

/// Converts a SMOKE3D byte to a physical value. Soot (`k_m > 0`): the byte
/// is 254 × the opacity of one cell width `dx`, so the extinction coefficient
/// is `−ln(1 − b/254)/dx` (1/m). HRRPUV and temperature use FDS's linear maps.
pub(super) fn s3d_value_map(s: &Smoke3d, dx: f32) -> (Box<dyn Fn(u8) -> f32>, Option<String>) {
    let long = s.quantity.long.to_ascii_uppercase();
    if s.k_m > 0.0 {
        (
            Box::new(move |b| soot_extinction(b, dx)),
            Some("1/m".into()),
        )
    } else if long == "HRRPUV" {
        (
            Box::new(|b| b as f32 * HRRPUV_MAX_SMV / 254.0),
            Some(s.quantity.units.clone()),
        )
    } else if long == "TEMPERATURE" {
        (
            Box::new(|b| TEMP_MIN_SMV + b as f32 * (TEMP_MAX_SMV - TEMP_MIN_SMV) / 254.0),
            Some(s.quantity.units.clone()),
        )
    } else {
        (Box::new(|b| b as f32), None)
    }
}

/// Extinction coefficient (1/m) of a soot byte for cell width `dx`.
pub fn soot_extinction(b: u8, dx: f32) -> f32 {
    // 254 would be fully opaque; keep it finite.
    let a = (b.min(253) as f64) / 254.0;
    ((1.0 - a).ln().abs() / dx as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::fds::test_support::{copy_case, smv_path};

    #[test]
    fn rle_decodes_runs_and_literals() {
        assert_eq!(
            decode_rle(&[1, 0xFF, 7, 4, 2], 6).unwrap(),
            [1, 7, 7, 7, 7, 2]
        );
        assert!(decode_rle(&[0xFF, 7, 200], 6).is_err());
        assert!(decode_rle(&[1, 2], 3).is_err());
        assert!(decode_rle(&[0xFF, 7], 3).is_err());
    }

    #[test]
    fn extinction_of_a_known_byte() {
        // b = 127: half the light lost over one 0.1 m cell: ln 2 / 0.1.
        let s = soot_extinction(127, 0.1);
        assert!((s - (2f32).ln() / 0.1).abs() < 1e-4, "{s}");
        assert_eq!(soot_extinction(0, 0.1), 0.0);
        assert!(soot_extinction(254, 0.1).is_finite());
        // sigma = K_m * rho: byte 181 ≈ 1.4e-3 kg/m3 at K_m = 8700.
        let rho = soot_extinction(181, 0.1) / 8700.0;
        assert!((rho - 1.4e-3).abs() < 0.1e-3, "{rho}");
    }

    #[test]
    fn soot_bytes_at_30s_match_format_md() {
        let Some(p) = smv_path() else { return };
        let s3d = p.parent().unwrap().join("room_smoke_1_1.s3d");
        let f = read_s3d_frame(&s3d, Some(30.0)).unwrap();
        assert_eq!(f.times.len(), 121);
        assert!((f.time - 30.0).abs() < 0.3, "{}", f.time);
        assert_eq!(f.dims, [51, 31, 26]);
        let n = f.bytes.len() as f64;
        let min = *f.bytes.iter().min().unwrap();
        let max = *f.bytes.iter().max().unwrap();
        let mean = f.bytes.iter().map(|&b| b as f64).sum::<f64>() / n;
        let nz = f.bytes.iter().filter(|&&b| b > 0).count() as f64 / n;
        assert_eq!((min, max), (0, 167));
        assert!((mean - 41.9).abs() < 0.05, "{mean}");
        assert!((nz - 0.69).abs() < 0.005, "{nz}");
        let last = read_s3d_frame(&s3d, None).unwrap();
        assert_eq!(last.index, 120);
        assert_eq!(*last.bytes.iter().max().unwrap(), 175);
        let mean = last.bytes.iter().map(|&b| b as f64).sum::<f64>() / n;
        assert!((mean - 47.7).abs() < 0.05, "{mean}");
    }

    #[test]
    fn corrupt_headers_never_panic() {
        let Some(p) = smv_path() else { return };
        let dir = copy_case(&p);
        let s3d = dir.path().join("room_smoke_1_1.s3d");
        let bytes = std::fs::read(&s3d).unwrap();
        for off in 0..120 {
            for v in [0u8, 0x7f, 0xff] {
                let mut b = bytes[..200_000].to_vec();
                b[off] = v;
                std::fs::write(&s3d, &b).unwrap();
                let _ = read_s3d_frame(&s3d, Some(0.0));
            }
        }
    }
}
