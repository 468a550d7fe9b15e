//! The length walk: every element length a DICOM file claims is checked
//! against the bytes that remain before dicom-parser sees the file, because
//! the parser allocates (and zero-fills) whatever an element header claims,
//! up to 4 GiB, before it finds that the file is shorter.
//!
//! The walk is flat: sequences and items are walked in place, the contents
//! of an `UN` element of undefined length in Implicit VR Little Endian (as
//! the parser reads them), a deflated data set after inflating it (bounded
//! by deflate's best ratio). It also records where the pixel data is and
//! how long it is, so that Rows × Columns × frames can be checked against
//! the bytes present before anything is decoded.

use super::{DEFLATED, EXPLICIT_BE, IMPLICIT_LE, PIXEL_DATA_FIELD};
use crate::error::{Error, Result};
use crate::io::util::MAX_DEFLATE_RATIO;
use std::io::{Read, Seek};
use std::path::Path;

const UNDEFINED: u32 = u32::MAX;

/// What the walk learned about the pixel data.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum PixelExtent {
    /// No PixelData element at the top level (or the walk stopped early).
    #[default]
    Unknown,
    /// Native pixel data of this many bytes.
    Native(u64),
    /// Encapsulated pixel data: fragments (after the offset table) holding
    /// this many bytes in all.
    Encapsulated(u64),
}

/// Checks the element lengths of the DICOM bytes `r` (`len` bytes in all).
pub(crate) fn check_lengths<R: Read + Seek>(path: &Path, r: R, len: u64) -> Result<PixelExtent> {
    let mut w = Walker {
        path,
        r,
        len,
        pos: 0,
        explicit: true,
        big: false,
        pixel: PixelExtent::Unknown,
    };
    w.run()
}

struct Walker<'a, R> {
    path: &'a Path,
    r: R,
    len: u64,
    pos: u64,
    explicit: bool,
    big: bool,
    pixel: PixelExtent,
}

/// One open context of undefined length: what closes it, and the encoding
/// to return to afterwards.
#[derive(Clone, Copy)]
struct Open {
    explicit: bool,
}

impl<R: Read + Seek> Walker<'_, R> {
    fn read<const N: usize>(&mut self) -> Option<[u8; N]> {
        if self.len.saturating_sub(self.pos) < N as u64 {
            return None;
        }
        let mut b = [0u8; N];
        self.r.read_exact(&mut b).ok()?;
        self.pos += N as u64;
        Some(b)
    }

    fn skip(&mut self, n: u64) -> Result<()> {
        self.r
            .seek_relative(n as i64)
            .map_err(|e| Error::io(self.path, e))?;
        self.pos += n;
        Ok(())
    }

    fn u16(&self, b: [u8; 2], big: bool) -> u16 {
        if big {
            u16::from_be_bytes(b)
        } else {
            u16::from_le_bytes(b)
        }
    }

    fn u32(&self, b: [u8; 4]) -> u32 {
        if self.big {
            u32::from_be_bytes(b)
        } else {
            u32::from_le_bytes(b)
        }
    }

    fn too_long(&self, g: u16, e: u16, n: u32) -> Error {
        let field = if (g, e) == (0x7FE0, 0x0010) {
            PIXEL_DATA_FIELD.to_string()
        } else {
            format!("({g:04X},{e:04X})")
        };
        Error::format(
            self.path,
            field,
            format!(
                "the element claims {n} bytes but only {} remain in the file (truncated or corrupt file)",
                self.len - self.pos
            ),
        )
    }

    fn check(&self, g: u16, e: u16, n: u32) -> Result<()> {
        if n as u64 > self.len - self.pos {
            return Err(self.too_long(g, e, n));
        }
        Ok(())
    }

    fn run(&mut self) -> Result<PixelExtent> {
        let Some(head) = self.read::<132>() else {
            return Ok(PixelExtent::Unknown);
        };
        if &head[128..132] == b"DICM" {
            // Preamble and magic: the meta group follows.
        } else if &head[..4] == b"DICM" {
            // No preamble: the magic at byte 0 (dicom-object accepts it).
            self.r
                .seek(std::io::SeekFrom::Start(4))
                .map_err(|e| Error::io(self.path, e))?;
            self.pos = 4;
        } else if head[..2] == [2, 0] {
            self.r.rewind().map_err(|e| Error::io(self.path, e))?;
            self.pos = 0;
        } else {
            return Ok(PixelExtent::Unknown);
        }
        // The file meta group: always Explicit VR Little Endian.
        let mut ts = String::new();
        loop {
            let start = self.pos;
            let Some(b) = self.read::<4>() else {
                return Ok(self.pixel);
            };
            if u16::from_le_bytes([b[0], b[1]]) != 2 {
                self.r
                    .seek_relative(-4)
                    .map_err(|e| Error::io(self.path, e))?;
                self.pos = start;
                break;
            }
            let e = u16::from_le_bytes([b[2], b[3]]);
            let Some((vr, n)) = self.explicit_header(false) else {
                return Ok(self.pixel);
            };
            if n == UNDEFINED {
                // Not valid in the meta group; the parser will say so.
                return Ok(self.pixel);
            }
            self.check(2, e, n)?;
            let _ = vr;
            if e == 0x0010 && n <= 64 {
                let mut v = vec![0u8; n as usize];
                if self.r.read_exact(&mut v).is_err() {
                    return Ok(self.pixel);
                }
                self.pos += n as u64;
                ts = String::from_utf8_lossy(&v)
                    .trim_end_matches(['\0', ' '])
                    .to_string();
            } else {
                self.skip(n as u64)?;
            }
        }
        match ts.as_str() {
            IMPLICIT_LE => self.explicit = false,
            EXPLICIT_BE => self.big = true,
            DEFLATED => return self.inflated(),
            _ => {}
        }
        self.data_set()
    }

    /// A deflated data set: inflated into memory (at most deflate's best
    /// ratio times the compressed bytes), then walked.
    fn inflated(&mut self) -> Result<PixelExtent> {
        let left = self.len - self.pos;
        let cap = left.saturating_mul(MAX_DEFLATE_RATIO).min(4 << 30);
        let mut buf = Vec::new();
        let dec = flate2::read::DeflateDecoder::new(&mut self.r);
        if let Err(e) = dec.take(cap).read_to_end(&mut buf) {
            return Err(Error::format(
                self.path,
                "deflated data set",
                format!("cannot inflate: {e}"),
            ));
        }
        let n = buf.len() as u64;
        let mut inner = Walker {
            path: self.path,
            r: std::io::Cursor::new(buf),
            len: n,
            pos: 0,
            explicit: true,
            big: false,
            pixel: PixelExtent::Unknown,
        };
        inner.data_set()
    }

    /// Reads the VR and the length of an explicit-VR element header.
    fn explicit_header(&mut self, big: bool) -> Option<([u8; 2], u32)> {
        let vr = self.read::<2>()?;
        // Same rule as dicom-encoding: these VRs have a 2-byte length,
        // every other one (unknown VRs too, read as UN) a 4-byte length.
        let short = matches!(
            &vr,
            b"AE"
                | b"AS"
                | b"AT"
                | b"CS"
                | b"DA"
                | b"DS"
                | b"DT"
                | b"FL"
                | b"FD"
                | b"IS"
                | b"LO"
                | b"LT"
                | b"PN"
                | b"SH"
                | b"SL"
                | b"SS"
                | b"ST"
                | b"TM"
                | b"UI"
                | b"UL"
                | b"US"
        );
        let n = if short {
            let b = self.read::<2>()?;
            self.u16(b, big) as u32
        } else {
            self.read::<2>()?;
            let b = self.read::<4>()?;
            if big {
                u32::from_be_bytes(b)
            } else {
                u32::from_le_bytes(b)
            }
        };
        Some((vr, n))
    }

    fn data_set(&mut self) -> Result<PixelExtent> {
        // Open contexts of undefined length (sequences, items, UN values);
        // a sequence delimiter closes the innermost sequence.
        let mut open: Vec<Open> = Vec::new();
        let mut in_fragments = false;
        let mut fragments = 0u64;
        let mut first_fragment = true;
        loop {
            let Some(b) = self.read::<4>() else {
                return Ok(self.pixel);
            };
            let (g, e) = (
                self.u16([b[0], b[1]], self.big),
                self.u16([b[2], b[3]], self.big),
            );
            if g == 0xFFFE {
                let Some(nb) = self.read::<4>() else {
                    return Ok(self.pixel);
                };
                let n = self.u32(nb);
                match e {
                    // A fragment of encapsulated pixel data holds bytes, an
                    // item of a sequence holds elements (walked in place).
                    0xE000 if in_fragments => {
                        self.check(g, e, n)?;
                        self.skip(n as u64)?;
                        if !first_fragment {
                            fragments += n as u64;
                        }
                        first_fragment = false;
                    }
                    0xE000 => {
                        if n != UNDEFINED {
                            self.check(g, e, n)?;
                        }
                    }
                    0xE0DD if in_fragments => {
                        in_fragments = false;
                        if open.is_empty() {
                            self.pixel = PixelExtent::Encapsulated(fragments);
                        }
                    }
                    0xE0DD => {
                        if let Some(o) = open.pop() {
                            self.explicit = o.explicit;
                        }
                    }
                    0xE00D => {}
                    // Any other (FFFE,xxxx) is read as a value of that length.
                    _ if n == UNDEFINED => return Ok(self.pixel),
                    _ => {
                        self.check(g, e, n)?;
                        self.skip(n as u64)?;
                    }
                }
                continue;
            }
            let (vr, n) = if self.explicit {
                match self.explicit_header(self.big) {
                    Some((vr, n)) => (Some(vr), n),
                    None => return Ok(self.pixel),
                }
            } else {
                let Some(nb) = self.read::<4>() else {
                    return Ok(self.pixel);
                };
                (None, self.u32(nb))
            };
            let is_pixel_data = (g, e) == (0x7FE0, 0x0010);
            if let Some(size) = vr.as_ref().and_then(fixed_size) {
                // A binary number whose length is not a multiple of its size
                // throws the parser off the element boundaries (found by
                // fuzzing: it then reads a bogus length and allocates it).
                if n != UNDEFINED && n % size != 0 {
                    return Err(Error::format(
                        self.path,
                        format!("({g:04X},{e:04X})"),
                        format!(
                            "a {} value of {n} bytes: must be a multiple of {size}",
                            String::from_utf8_lossy(vr.as_ref().expect("some"))
                        ),
                    ));
                }
            }
            if n == UNDEFINED {
                match vr.as_ref() {
                    _ if is_pixel_data => {
                        in_fragments = true;
                        fragments = 0;
                        first_fragment = true;
                    }
                    Some(b"SQ") | None => open.push(Open {
                        explicit: self.explicit,
                    }),
                    Some(b"UN") => {
                        // Read by the parser as an implicit-VR sequence.
                        open.push(Open {
                            explicit: self.explicit,
                        });
                        self.explicit = false;
                    }
                    // Any other VR of undefined length: the parser refuses it.
                    _ => return Ok(self.pixel),
                }
                continue;
            }
            self.check(g, e, n)?;
            if vr.as_ref() == Some(b"SQ") {
                continue;
            }
            if vr.is_none() && n >= 8 && !is_pixel_data {
                // Implicit VR does not say which elements are sequences; a
                // value that starts with an item tag is one, walked in place.
                let Some(peek) = self.read::<4>() else {
                    return Ok(self.pixel);
                };
                self.r
                    .seek_relative(-4)
                    .map_err(|e| Error::io(self.path, e))?;
                self.pos -= 4;
                let item = if self.big {
                    [0xFF, 0xFE, 0xE0, 0x00]
                } else {
                    [0xFE, 0xFF, 0x00, 0xE0]
                };
                if peek == item {
                    continue;
                }
            }
            if is_pixel_data && open.is_empty() {
                self.pixel = PixelExtent::Native(n as u64);
            }
            self.skip(n as u64)?;
        }
    }
}

/// Bytes per value of the binary-number VRs.
fn fixed_size(vr: &[u8; 2]) -> Option<u32> {
    match vr {
        b"SS" | b"US" => Some(2),
        b"SL" | b"UL" | b"FL" | b"AT" => Some(4),
        b"FD" | b"SV" | b"UV" => Some(8),
        _ => None,
    }
}
