//! OpenVDB reader: scalar grids of `float` (full or saved as half floats) and
//! `double`, uncompressed, zip (zlib) or Blosc compressed, with or without
//! active-mask compression, in files of format version 222 and later (every
//! OpenVDB 3+ file). Only the standard `5_4_3` tree configuration is read.
//!
//! The chosen grid becomes a dense volume over its active bounding box:
//! inactive voxels take the grid's background value, active tiles (at any
//! level) are filled in and counted as active voxels.
//!
//! Blosc: no maintained pure-Rust Blosc crate exists (the `blosc` crates bind
//! the C library), so `blosc.rs` decodes the Blosc1 container itself: the
//! 16-byte header, the block offsets, per-block split streams, LZ4 raw blocks
//! (the codec OpenVDB writes) and the byte unshuffle. Other Blosc codecs
//! (BloscLZ, Zstd, …) and bit shuffle are reported as unsupported.
//!
//! Every size the file claims is checked against the bytes it holds before
//! anything is allocated; bad input is an error, never a panic.
//!
//! The parts: `cursor.rs` the bounds-checked byte cursor, `grid.rs` the sparse
//! grid (leaves, tiles, masks) and its dense volume, `tree.rs` a grid's
//! transform, tree topology and value buffers, `blosc.rs` the Blosc1/LZ4
//! decoder. This file reads the header and picks the grid.

mod blosc;
mod cursor;
mod grid;
mod tree;

use super::OpenOptions;
use crate::error::{Error, Result};
use crate::volume::Volume;
use cursor::Cursor;
use grid::{to_volume, value_kind, Grid};
use std::path::Path;
use tree::read_grid;

const MAGIC: i64 = 0x5644_4220;
const COMPRESS_ZIP: u32 = 0x1;
const COMPRESS_ACTIVE_MASK: u32 = 0x2;
const COMPRESS_BLOSC: u32 = 0x4;

/// One grid as the file's header lists it.
#[derive(Clone, Debug)]
struct GridDesc {
    name: String,
    type_name: String,
    grid_pos: i64,
}

/// Reads `path`.
pub fn read(path: &Path, opts: &OpenOptions) -> Result<Volume> {
    let buf = crate::files::read_bytes(path, u64::MAX)?;
    let p = parse(path, &buf, opts)?;
    to_volume(path, p.name, p.grid, p.names)
}

/// What [`parse`] returns: the file's grids and the chosen one, read.
struct Parsed {
    #[cfg_attr(not(test), allow(dead_code))]
    grids: Vec<GridDesc>,
    names: Vec<String>,
    name: String,
    grid: Grid,
}

/// Parses the header, picks the grid and reads it.
fn parse(path: &Path, buf: &[u8], opts: &OpenOptions) -> Result<Parsed> {
    let mut r = Cursor { buf, pos: 0, path };
    let magic = r.i64("magic")?;
    if magic != MAGIC {
        return Err(r.err(
            "magic",
            format!("{magic:#x}, expected {MAGIC:#x} (\" BDV\"): not an OpenVDB file"),
        ));
    }
    let version = r.u32("file_version")?;
    if version < 222 {
        return Err(Error::unsupported(
            path,
            format!(
                "OpenVDB file format version {version} (only 222 and later, OpenVDB 3+, are read)"
            ),
        ));
    }
    let _lib_major = r.u32("library_version")?;
    let _lib_minor = r.u32("library_version")?;
    let has_offsets = r.u8("has_grid_offsets")?;
    r.bytes(36, "uuid")?;
    r.skip_metadata("file metadata")?;
    let count = r.u32("grid_count")? as usize;
    // A descriptor takes at least 36 bytes.
    if count.saturating_mul(36) > r.remaining() {
        return Err(r.err(
            "grid_count",
            format!(
                "{count} grids claimed, only {} bytes left in the file",
                r.remaining()
            ),
        ));
    }
    if has_offsets == 0 {
        return Err(Error::unsupported(
            path,
            "OpenVDB file without grid offsets (written to a stream)",
        ));
    }
    let mut grids = Vec::new();
    for _ in 0..count {
        let mut name = r.string("grid_name")?;
        if let Some(i) = name.find('\u{1e}') {
            name.truncate(i);
        }
        let type_name = r.string("grid_type")?;
        let _parent = r.string("instance_parent")?;
        let grid_pos = r.i64("grid_pos")?;
        let _block_pos = r.i64("block_pos")?;
        let end_pos = r.i64("end_pos")?;
        grids.push(GridDesc {
            name,
            type_name,
            grid_pos,
        });
        r.seek(end_pos, "end_pos")?;
    }
    let names: Vec<String> = grids.iter().map(|g| g.name.clone()).collect();
    let list = || {
        grids
            .iter()
            .map(|g| format!("{} ({})", g.name, g.type_name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let chosen = if let Some(v) = &opts.variable {
        grids.iter().find(|g| &g.name == v).ok_or_else(|| {
            Error::format(
                path,
                "grid",
                format!("no grid named {v:?}; the file holds: {}", list()),
            )
        })?
    } else {
        grids
            .iter()
            .find(|g| g.name == "density" && value_kind(&g.type_name).is_some())
            .or_else(|| grids.iter().find(|g| value_kind(&g.type_name).is_some()))
            .ok_or_else(|| {
                Error::unsupported(
                    path,
                    format!("no float or double grid in the file; it holds: {}", list()),
                )
            })?
    };
    let kind = value_kind(&chosen.type_name).ok_or_else(|| {
        Error::unsupported(
            path,
            format!(
                "grid {:?} has type {:?}; only scalar float/double trees 5_4_3 are read",
                chosen.name, chosen.type_name
            ),
        )
    })?;
    r.seek(chosen.grid_pos, "grid_pos")?;
    let grid = read_grid(&mut r, kind)?;
    let name = chosen.name.clone();
    Ok(Parsed {
        grids,
        names,
        name,
        grid,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::data_path;
    use blosc::{blosc_decode, lz4_block};
    use grid::for_each_on;
    use tree::f16_to_f32;

    fn load(rel: &str, var: Option<&str>) -> Option<(Volume, Grid)> {
        let p = data_path(rel)?;
        let buf = std::fs::read(&p).unwrap();
        let opts = OpenOptions {
            variable: var.map(String::from),
            ..Default::default()
        };
        let grid = parse(&p, &buf, &opts).unwrap().grid;
        let t = std::time::Instant::now();
        let vol = read(&p, &opts).unwrap();
        eprintln!("{rel}: read in {:?}", t.elapsed());
        Some((vol, grid))
    }

    /// (min, max, mean) over the active voxels.
    fn active_stats(g: &Grid) -> (f32, f32, f64) {
        let (mut lo, mut hi, mut sum, mut n) = (f32::MAX, f32::MIN, 0f64, 0u64);
        for l in &g.leaves {
            for_each_on(&l.mask, |i| {
                let v = l.values[i];
                lo = lo.min(v);
                hi = hi.max(v);
                sum += v as f64;
                n += 1;
            });
        }
        for t in &g.tiles {
            let c = (t.dim * t.dim * t.dim) as u64;
            lo = lo.min(t.value);
            hi = hi.max(t.value);
            sum += t.value as f64 * c as f64;
            n += c;
        }
        (lo, hi, sum / n as f64)
    }

    #[test]
    fn smoke_half_float_blosc() {
        let Some((vol, g)) = load("smoke_vdb/smoke.vdb", None) else {
            return;
        };
        assert_eq!(vol.active_voxels, Some(1_049_275));
        assert_eq!(vol.name.as_deref(), Some("density"));
        assert_eq!(vol.variables, vec!["density".to_string()]);
        let (lo, hi, mean) = active_stats(&g);
        eprintln!(
            "smoke: dims {:?} spacing {} origin {} min {lo} max {hi} mean {mean}",
            vol.dims(),
            vol.spacing(),
            vol.origin()
        );
        assert_eq!(vol.dims(), [111, 222, 112]);
        assert!((vol.spacing().x - 0.476).abs() < 1e-3);
        assert!(lo > 0.0 && lo < 2e-5, "min {lo}");
        assert!((hi - 5.715).abs() < 2e-3, "max {hi}");
        assert!((mean - 0.163).abs() < 1e-3, "mean {mean}");
    }

    #[test]
    fn cloud_float_blosc() {
        let Some((vol, g)) = load("cloud_vdb/cloud.vdb", Some("density")) else {
            return;
        };
        assert_eq!(vol.active_voxels, Some(690_249));
        assert_eq!(vol.variables, vec!["density".to_string()]);
        let (lo, hi, mean) = active_stats(&g);
        eprintln!(
            "cloud: dims {:?} spacing {} origin {} min {lo} max {hi} mean {mean}",
            vol.dims(),
            vol.spacing(),
            vol.origin()
        );
        assert_eq!(vol.dims(), [150, 101, 174]);
        assert!((vol.spacing().x - 0.01).abs() < 1e-6);
        assert!(lo > 0.0 && lo < 2e-8, "min {lo}");
        assert!((hi - 1.007).abs() < 1e-3, "max {hi}");
        assert!((mean - 0.63).abs() < 5e-3, "mean {mean}");
    }

    #[test]
    fn unknown_grid_lists_the_grids() {
        let Some(p) = data_path("cloud_vdb/cloud.vdb") else {
            return;
        };
        let opts = OpenOptions {
            variable: Some("temperature".into()),
            ..Default::default()
        };
        let e = read(&p, &opts).unwrap_err().to_string();
        assert!(e.contains("temperature") && e.contains("density"), "{e}");
    }

    fn read_bytes(bytes: &[u8]) -> Result<Volume> {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.vdb");
        std::fs::write(&p, bytes).unwrap();
        read(&p, &OpenOptions::default())
    }

    #[test]
    fn truncated_files_are_errors() {
        let Some(p) = data_path("smoke_vdb/smoke.vdb") else {
            return;
        };
        let buf = std::fs::read(&p).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("cut.vdb");
        let mut cuts: Vec<usize> = (0..600).collect();
        cuts.extend((1..200).map(|k| buf.len() * k / 200));
        cuts.extend([buf.len() - 1, buf.len() - 8]);
        for cut in cuts {
            std::fs::write(&q, &buf[..cut]).unwrap();
            assert!(read(&q, &OpenOptions::default()).is_err(), "cut {cut}");
        }
    }

    #[test]
    fn corrupt_bytes_never_panic() {
        let Some(p) = data_path("cloud_vdb/cloud.vdb") else {
            return;
        };
        let buf = std::fs::read(&p).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let q = dir.path().join("bad.vdb");
        // Flip bytes across the header, topology and some buffers.
        let mut at: Vec<usize> = (8..0x1c0).collect();
        at.extend((1..300).map(|k| buf.len() * k / 300));
        for (n, &i) in at.iter().enumerate() {
            let mut b = buf.clone();
            b[i] ^= if n % 2 == 0 { 0xff } else { 0x80 };
            std::fs::write(&q, &b).unwrap();
            let _ = read(&q, &OpenOptions::default());
        }
    }

    #[test]
    fn wrong_magic_and_absurd_counts() {
        let e = read_bytes(b"NOT A VDB FILE AT ALL")
            .unwrap_err()
            .to_string();
        assert!(e.contains("magic"), "{e}");
        let mut h = Vec::new();
        h.extend_from_slice(&MAGIC.to_le_bytes());
        h.extend_from_slice(&224u32.to_le_bytes());
        h.extend_from_slice(&[10, 0, 0, 0, 0, 0, 0, 0, 1]);
        h.extend_from_slice(&[b'0'; 36]);
        // Absurd metadata count.
        let mut a = h.clone();
        a.extend_from_slice(&u32::MAX.to_le_bytes());
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("metadata"), "{e}");
        // Absurd grid count.
        let mut a = h.clone();
        a.extend_from_slice(&0u32.to_le_bytes());
        a.extend_from_slice(&0x7fff_ffffu32.to_le_bytes());
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("grid_count"), "{e}");
        // Absurd string length.
        let mut a = h.clone();
        a.extend_from_slice(&0u32.to_le_bytes());
        a.extend_from_slice(&1u32.to_le_bytes());
        a.extend_from_slice(&0xffff_fff0u32.to_le_bytes());
        a.extend_from_slice(&[0u8; 64]);
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("grid_name"), "{e}");
        // Old format version.
        let mut a = h.clone();
        a[8..12].copy_from_slice(&200u32.to_le_bytes());
        let e = read_bytes(&a).unwrap_err().to_string();
        assert!(e.contains("unsupported"), "{e}");
    }

    /// Rewrites a Blosc file with zip (`zip`) or no compression, keeping the
    /// active-mask compression: the same grid must come back.
    fn transcode(path: &Path, zip: bool) -> Vec<u8> {
        let buf = std::fs::read(path).unwrap();
        let parsed = parse(path, &buf, &OpenOptions::default()).unwrap();
        assert_eq!(parsed.grids.len(), 1);
        let g = parsed.grid;
        let mut out = buf[..g.compression_pos].to_vec();
        out.extend_from_slice(
            &(COMPRESS_ACTIVE_MASK | if zip { COMPRESS_ZIP } else { 0 }).to_le_bytes(),
        );
        let mut at = g.compression_pos + 4;
        for &(s, e, n) in &g.chunks {
            out.extend_from_slice(&buf[at..s]);
            let c = i64::from_le_bytes(buf[s..s + 8].try_into().unwrap());
            let raw = if c <= 0 {
                buf[s + 8..e].to_vec()
            } else {
                match blosc_decode(&buf[s + 8..e], n) {
                    Ok(v) => v,
                    Err(_) => panic!("blosc chunk at {s}"),
                }
            };
            if zip {
                let mut z =
                    flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
                std::io::Write::write_all(&mut z, &raw).unwrap();
                let z = z.finish().unwrap();
                out.extend_from_slice(&(z.len() as i64).to_le_bytes());
                out.extend_from_slice(&z);
            } else {
                out.extend_from_slice(&raw);
            }
            at = e;
        }
        out.extend_from_slice(&buf[at..]);
        // The descriptor's end offset sits just before the grid.
        let end = out.len() as i64;
        out[g.compression_pos - 8..g.compression_pos].copy_from_slice(&end.to_le_bytes());
        out
    }

    #[test]
    fn zip_and_uncompressed_match_blosc() {
        for rel in ["smoke_vdb/smoke.vdb", "cloud_vdb/cloud.vdb"] {
            let Some(p) = data_path(rel) else {
                return;
            };
            let want = read(&p, &OpenOptions::default()).unwrap();
            for zip in [true, false] {
                let bytes = transcode(&p, zip);
                let got = read_bytes(&bytes).unwrap();
                assert_eq!(got.dims(), want.dims(), "{rel} zip={zip}");
                assert_eq!(got.active_voxels, want.active_voxels, "{rel} zip={zip}");
                assert!(got.data() == want.data(), "{rel} zip={zip}: values differ");
            }
        }
    }

    #[test]
    fn lz4_and_half_basics() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        // "abcabcabcabc": 3 literals then a match of 9 at offset 3.
        let src = [0x35, b'a', b'b', b'c', 3, 0];
        let mut dst = [0u8; 12];
        // Last sequence must be literals: our decoder accepts a trailing match too.
        assert_eq!(lz4_block(&src, &mut dst), None); // ends without final literals → runs past src
        let src = [0x35, b'a', b'b', b'c', 3, 0, 0x10, b'x'];
        let mut dst = [0u8; 13];
        assert_eq!(lz4_block(&src, &mut dst), Some(13));
        assert_eq!(&dst, b"abcabcabcabcx");
    }
}
