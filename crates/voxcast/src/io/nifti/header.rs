//! The three headers of the family, parsed here from their fixed layouts
//! into one [`Header`]: NIfTI-1 (348 bytes, magic `n+1`/`ni1` at byte 344),
//! Analyze 7.5 (the same 348 bytes without the magic; SPM's extensions) and
//! NIfTI-2 (540 bytes, magic `n+2\0\r\n\x1a\n`/`ni2…` at byte 4, 64-bit
//! dims and offsets, double-precision geometry). The byte order is the one
//! in which `sizeof_hdr` reads 348 or 540.

use crate::error::{Error, Result};
use std::path::Path;

pub(super) const NIFTI1_SIZE: usize = 348;
pub(super) const NIFTI2_SIZE: usize = 540;

/// Which header the file has.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    Nifti1,
    Nifti2,
    Analyze,
}

impl Kind {
    pub(super) fn name(self) -> &'static str {
        match self {
            Kind::Nifti1 => "NIfTI-1",
            Kind::Nifti2 => "NIfTI-2",
            Kind::Analyze => "Analyze 7.5",
        }
    }
}

/// The fields voxcast uses, widened to NIfTI-2's types.
#[derive(Clone, Debug)]
pub(super) struct Header {
    pub kind: Kind,
    pub big_endian: bool,
    /// The voxels are in a separate `.img` file (`ni1`/`ni2` magic, and
    /// always for Analyze).
    pub pair: bool,
    pub dim: [i64; 8],
    pub datatype: i16,
    pub bitpix: i16,
    pub pixdim: [f64; 8],
    pub vox_offset: f64,
    /// NIfTI `scl_slope`/`scl_inter`; for Analyze SPM's scale factor
    /// (`funused1`) and SPM2's intercept (`funused2`), same bytes.
    pub scl_slope: f64,
    pub scl_inter: f64,
    pub qform_code: i32,
    pub sform_code: i32,
    pub qoffset: [f64; 3],
    /// The translation column of the sform (`srow_x/y/z[3]`).
    pub srow_t: [f64; 3],
    pub xyzt_units: u8,
    pub intent_name: String,
    pub descrip: String,
    /// Analyze (SPM): the origin voxel, 1-based (`originator`, three i16).
    pub originator: [i16; 3],
}

/// Fixed-layout field reader in the header's byte order.
struct Fields<'a> {
    b: &'a [u8],
    be: bool,
}

impl Fields<'_> {
    fn bytes<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut a = [0u8; N];
        a.copy_from_slice(&self.b[at..at + N]);
        a
    }
    fn i16(&self, at: usize) -> i16 {
        let a = self.bytes(at);
        if self.be {
            i16::from_be_bytes(a)
        } else {
            i16::from_le_bytes(a)
        }
    }
    fn i32(&self, at: usize) -> i32 {
        let a = self.bytes(at);
        if self.be {
            i32::from_be_bytes(a)
        } else {
            i32::from_le_bytes(a)
        }
    }
    fn i64(&self, at: usize) -> i64 {
        let a = self.bytes(at);
        if self.be {
            i64::from_be_bytes(a)
        } else {
            i64::from_le_bytes(a)
        }
    }
    fn f32(&self, at: usize) -> f64 {
        let a = self.bytes(at);
        f64::from(if self.be {
            f32::from_be_bytes(a)
        } else {
            f32::from_le_bytes(a)
        })
    }
    fn f64(&self, at: usize) -> f64 {
        let a = self.bytes(at);
        if self.be {
            f64::from_be_bytes(a)
        } else {
            f64::from_le_bytes(a)
        }
    }
    fn text(&self, at: usize, len: usize) -> String {
        let raw = &self.b[at..at + len];
        let end = raw.iter().position(|&c| c == 0).unwrap_or(len);
        String::from_utf8_lossy(&raw[..end]).trim().to_string()
    }
}

const MAGIC2_TAIL: &[u8; 4] = b"\r\n\x1a\n";

/// Parses the header at the start of `buf` (up to 540 bytes read from the
/// file, inflated if it was gzip). `hdr_name` says the file is named
/// `.hdr`/`.hdr.gz`, where a 348-byte header without the NIfTI magic is
/// Analyze 7.5.
pub(super) fn parse(path: &Path, buf: &[u8], hdr_name: bool) -> Result<Header> {
    if buf.len() < 4 {
        return Err(Error::format(
            path,
            "sizeof_hdr",
            "the file is too short to hold a NIfTI or Analyze header",
        ));
    }
    let first = [buf[0], buf[1], buf[2], buf[3]];
    let (le, be) = (i32::from_le_bytes(first), i32::from_be_bytes(first));
    let (size, big_endian) = match (le, be) {
        (348 | 540, _) => (le as usize, false),
        (_, 348 | 540) => (be as usize, true),
        _ => {
            return Err(Error::format(
                path,
                "sizeof_hdr",
                format!(
                "{le} (or {be} big-endian), expected 348 (NIfTI-1, Analyze 7.5) or 540 (NIfTI-2)"
            ),
            ))
        }
    };
    if buf.len() < size {
        return Err(Error::format(
            path,
            "header",
            format!(
                "the file ends after {} bytes, inside the {size}-byte header",
                buf.len()
            ),
        ));
    }
    let f = Fields {
        b: &buf[..size],
        be: big_endian,
    };
    if size == NIFTI2_SIZE {
        parse_nifti2(path, &f, big_endian)
    } else {
        parse_348(path, &f, big_endian, hdr_name)
    }
}

fn magic_text(m: &[u8]) -> String {
    m.iter()
        .map(|&c| {
            if c.is_ascii_graphic() {
                (c as char).to_string()
            } else {
                format!("\\x{c:02x}")
            }
        })
        .collect()
}

/// NIfTI-1 or Analyze 7.5 (348 bytes).
fn parse_348(path: &Path, f: &Fields, big_endian: bool, hdr_name: bool) -> Result<Header> {
    let magic: [u8; 4] = f.bytes(344);
    let kind = match &magic {
        b"n+1\0" | b"ni1\0" => Kind::Nifti1,
        _ if hdr_name => Kind::Analyze,
        _ => {
            return Err(Error::format(
                path,
                "magic",
                format!(
                    "`{}` is not a NIfTI-1 magic (`n+1` in a .nii file, `ni1` in a .hdr/.img pair; a .hdr without it is read as Analyze 7.5)",
                    magic_text(&magic)
                ),
            ))
        }
    };
    let mut dim = [0i64; 8];
    for (i, d) in dim.iter_mut().enumerate() {
        *d = i64::from(f.i16(40 + 2 * i));
    }
    let mut pixdim = [0f64; 8];
    for (i, p) in pixdim.iter_mut().enumerate() {
        *p = f.f32(76 + 4 * i);
    }
    let analyze = kind == Kind::Analyze;
    let originator = if analyze {
        [f.i16(253), f.i16(255), f.i16(257)]
    } else {
        [0; 3]
    };
    Ok(Header {
        kind,
        big_endian,
        pair: analyze || &magic == b"ni1\0",
        dim,
        datatype: f.i16(70),
        bitpix: f.i16(72),
        pixdim,
        vox_offset: f.f32(108),
        scl_slope: f.f32(112),
        scl_inter: f.f32(116),
        qform_code: if analyze { 0 } else { i32::from(f.i16(252)) },
        sform_code: if analyze { 0 } else { i32::from(f.i16(254)) },
        qoffset: [f.f32(268), f.f32(272), f.f32(276)],
        srow_t: [f.f32(292), f.f32(308), f.f32(324)],
        xyzt_units: if analyze { 0 } else { f.b[123] },
        intent_name: if analyze {
            String::new()
        } else {
            f.text(328, 16)
        },
        descrip: f.text(148, 80),
        originator,
    })
}

/// NIfTI-2 (540 bytes).
fn parse_nifti2(path: &Path, f: &Fields, big_endian: bool) -> Result<Header> {
    let magic: [u8; 8] = f.bytes(4);
    let pair = match (&magic[..4], &magic[4..]) {
        (b"n+2\0", t) if t == MAGIC2_TAIL => false,
        (b"ni2\0", t) if t == MAGIC2_TAIL => true,
        _ => {
            return Err(Error::format(
                path,
                "magic",
                format!(
                    "`{}` is not a NIfTI-2 magic (`n+2\\0\\r\\n\\x1a\\n`, or `ni2…` for a .hdr/.img pair)",
                    magic_text(&magic)
                ),
            ))
        }
    };
    let mut dim = [0i64; 8];
    for (i, d) in dim.iter_mut().enumerate() {
        *d = f.i64(16 + 8 * i);
    }
    let mut pixdim = [0f64; 8];
    for (i, p) in pixdim.iter_mut().enumerate() {
        *p = f.f64(104 + 8 * i);
    }
    Ok(Header {
        kind: Kind::Nifti2,
        big_endian,
        pair,
        dim,
        datatype: f.i16(12),
        bitpix: f.i16(14),
        pixdim,
        // An i64 in NIfTI-2; as f64 it is exact up to 2^53, and the reader
        // refuses offsets past 1e12 anyway.
        vox_offset: f.i64(168) as f64,
        scl_slope: f.f64(176),
        scl_inter: f.f64(184),
        qform_code: f.i32(344),
        sform_code: f.i32(348),
        qoffset: [f.f64(376), f.f64(384), f.f64(392)],
        srow_t: [f.f64(424), f.f64(456), f.f64(488)],
        xyzt_units: (f.i32(500) & 0xff) as u8,
        intent_name: f.text(508, 16),
        descrip: f.text(240, 80),
        originator: [0; 3],
    })
}
