//! NIfTI-1 volumes: single-file `.nii` and `.nii.gz` (`n+1` magic) and
//! header/image pairs `.hdr` + `.img` (`ni1` magic, either gzipped), in
//! either byte order. The header is parsed by the `nifti` crate; the voxels
//! are read here, after the sizes the header claims have been checked
//! against the file, so a lying header cannot make us allocate.
//!
//! * dims: `dim[1..=3]`; `dim[0]` may be 1 to 7 as long as every dimension
//!   past the third is 1 (a 4D file with one time point is a 3D volume).
//! * spacing: `|pixdim[1..=3]|`, which must be positive and finite (a 0 or
//!   NaN is an error, except on an axis one voxel thick, where it becomes 1).
//! * origin: the qform offset (`qoffset_x/y/z`) when `qform_code > 0`, else
//!   the sform translation when `sform_code > 0`, else 0. Rotations and axis
//!   flips of the qform/sform are not applied (voxcast volumes are axis
//!   aligned), and spacing and origin stay in the file's units (`xyzt_units`,
//!   nearly always mm).
//! * scalars: uint8, int16, uint16 and float32 are kept as they are; int8
//!   becomes i16; int32, uint32, int64 and uint64 become i16 or u16 when all
//!   values fit, else f32; float64 becomes f32.
//! * `scl_slope`/`scl_inter` are applied when the slope is finite and not 0
//!   and the pair is not (1, 0) (integral scaling of integers gives i16 when
//!   it fits, else f32).
//! * name: `intent_name`, when set.
//!
//! Not supported: NIfTI-2, 4D and higher (more than one volume), complex,
//! RGB/RGBA and float128 data, extensions (skipped).

use super::util::{check_dims, file_len, read_exact_or_short, MAX_DEFLATE_RATIO};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume, VoxelData};
use glam::Vec3;
use nifti::{Endianness, NiftiHeader};
use std::io::Read;
use std::path::{Path, PathBuf};

const HEADER_SIZE: usize = 348;
const NIFTI2_HEADER_SIZE: i32 = 540;

/// How voxels are stored in the file.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Stored {
    U8,
    I8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl Stored {
    fn size(self) -> u64 {
        match self {
            Stored::U8 | Stored::I8 => 1,
            Stored::I16 | Stored::U16 => 2,
            Stored::I32 | Stored::U32 | Stored::F32 => 4,
            Stored::I64 | Stored::U64 | Stored::F64 => 8,
        }
    }
}

/// Maps a NIfTI datatype code; known codes voxcast cannot show are
/// `Unsupported`, unknown ones a format error.
fn stored_type(path: &Path, code: i16) -> Result<Stored> {
    Ok(match code {
        2 => Stored::U8,
        4 => Stored::I16,
        8 => Stored::I32,
        16 => Stored::F32,
        64 => Stored::F64,
        256 => Stored::I8,
        512 => Stored::U16,
        768 => Stored::U32,
        1024 => Stored::I64,
        1280 => Stored::U64,
        32 | 1792 | 2048 => {
            return Err(Error::unsupported(
                path,
                format!("datatype {code} (complex): voxcast shows real scalars only"),
            ))
        }
        128 | 2304 => {
            return Err(Error::unsupported(
                path,
                format!("datatype {code} (RGB/RGBA colour): voxcast shows scalars only"),
            ))
        }
        1536 => return Err(Error::unsupported(path, "datatype 1536 (float128)")),
        _ => {
            return Err(Error::format(
                path,
                "datatype",
                format!(
                    "unknown code {code} (NIfTI-1 codes: 2 uint8, 4 int16, 8 int32, 16 float32, 64 float64, 256 int8, 512 uint16, 768 uint32, 1024 int64, 1280 uint64)"
                ),
            ))
        }
    })
}

fn is_gzip(path: &Path) -> Result<bool> {
    Ok(super::util::read_head(path, 2)? == [0x1f, 0x8b])
}

/// A reader over the file's bytes, inflated when the file is gzip.
fn open_stream(path: &Path) -> Result<Box<dyn Read>> {
    let f = crate::files::open(path)?.0;
    let f = std::io::BufReader::new(f);
    Ok(if is_gzip(path)? {
        Box::new(flate2::read::MultiGzDecoder::new(f))
    } else {
        Box::new(f)
    })
}

fn read_header(path: &Path, stream: &mut dyn Read) -> Result<NiftiHeader> {
    let mut buf = Vec::with_capacity(HEADER_SIZE);
    stream
        .take(HEADER_SIZE as u64)
        .read_to_end(&mut buf)
        .map_err(|e| Error::format(path, "header", format!("cannot read the header: {e}")))?;
    if buf.len() < 4 {
        return Err(Error::format(
            path,
            "sizeof_hdr",
            "the file is too short to hold a NIfTI header",
        ));
    }
    let size_le = i32::from_le_bytes([buf[0], buf[1], buf[2], buf[3]]);
    let size_be = i32::from_be_bytes([buf[0], buf[1], buf[2], buf[3]]);
    if size_le == NIFTI2_HEADER_SIZE || size_be == NIFTI2_HEADER_SIZE {
        return Err(Error::unsupported(
            path,
            "NIfTI-2 (540-byte header): only NIfTI-1 is read; convert it with nibabel (`python3 -c \"import nibabel as nib, sys; nib.save(nib.Nifti1Image.from_image(nib.load(sys.argv[1])), sys.argv[2])\" IN.nii OUT1.nii`)",
        ));
    }
    if size_le != HEADER_SIZE as i32 && size_be != HEADER_SIZE as i32 {
        return Err(Error::format(
            path,
            "sizeof_hdr",
            format!("{size_le} (or {size_be} big-endian), expected 348 for NIfTI-1"),
        ));
    }
    if buf.len() < HEADER_SIZE {
        return Err(Error::format(
            path,
            "header",
            format!(
                "the file ends after {} bytes, inside the 348-byte header",
                buf.len()
            ),
        ));
    }
    NiftiHeader::from_reader(&buf[..])
        .map_err(|e| Error::format(path, "magic", format!("not a NIfTI-1 header: {e}")))
}

/// The image file of a `.hdr` header (`x.hdr` → `x.img`, `x.hdr.gz` →
/// `x.img.gz`, falling back to the other compression).
fn image_file_of(path: &Path) -> Result<PathBuf> {
    let s = path.to_string_lossy();
    let lower = s.to_ascii_lowercase();
    let stem = if lower.ends_with(".hdr.gz") {
        &s[..s.len() - 7]
    } else if lower.ends_with(".hdr") {
        &s[..s.len() - 4]
    } else {
        return Err(Error::format(
            path,
            "magic",
            "`ni1` means a header whose voxels are in a separate .img file, but this file does not end in .hdr",
        ));
    };
    let candidates = [
        format!("{stem}.img"),
        format!("{stem}.img.gz"),
        format!("{stem}.IMG"),
    ];
    candidates
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
        .ok_or_else(|| {
            Error::format(
                path,
                "magic",
                format!("`ni1` header but no image file {stem}.img or {stem}.img.gz"),
            )
        })
}

/// Reads a NIfTI-1 volume.
pub fn read(path: &Path) -> Result<Volume> {
    let mut stream = open_stream(path)?;
    let h = read_header(path, &mut stream)?;
    drop(stream);

    // NIfTI-1 stores dims as signed shorts; the crate hands them out as u16.
    let dim: [i16; 8] = h.dim.map(|d| d as i16);
    let ndim = dim[0];
    if !(1..=7).contains(&ndim) {
        return Err(Error::format(
            path,
            "dim",
            format!("dim[0] = {ndim}: the number of dimensions must be 1 to 7"),
        ));
    }
    let ndim = ndim as usize;
    let mut dims = [1u64; 3];
    for (i, d) in dims.iter_mut().enumerate().take(ndim.min(3)) {
        let v = dim[i + 1];
        if v <= 0 {
            return Err(Error::format(
                path,
                "dim",
                format!("dim[{}] = {v}: every dimension must be at least 1", i + 1),
            ));
        }
        *d = v as u64;
    }
    for (i, &v) in dim.iter().enumerate().take(ndim + 1).skip(4) {
        if v != 1 {
            let what = if i == 4 {
                "time points (4D series)"
            } else {
                "components"
            };
            return Err(Error::unsupported(
                path,
                format!("dim[{i}] = {v}: a file with {v} {what}; voxcast reads single 3D volumes (extract one, e.g. with `fslroi` or nibabel)"),
            ));
        }
    }

    let stored = stored_type(path, h.datatype)?;
    if h.bitpix as u64 != stored.size() * 8 {
        eprintln!(
            "warning: {}: bitpix {} does not match datatype {} ({} bits); using the datatype",
            path.display(),
            h.bitpix,
            h.datatype,
            stored.size() * 8
        );
    }

    let (data_path, min_offset) = if &h.magic == b"ni1\0" {
        (image_file_of(path)?, 0.0)
    } else {
        (path.to_path_buf(), HEADER_SIZE as f32)
    };
    let off = h.vox_offset;
    if !(off.is_finite() && off >= min_offset && off.fract() == 0.0 && off < 1e12) {
        return Err(Error::format(
            path,
            "vox_offset",
            format!("{off}: must be a whole number of bytes, at least {min_offset}"),
        ));
    }
    let offset = off as u64;

    // Guard before any allocation: the voxels the header claims must fit in
    // the file (or, gzipped, in what deflate can make of it).
    let (n, _) = check_dims(path, "dim", dims, ScalarType::U8)?;
    let n_bytes = (n as u64)
        .checked_mul(stored.size())
        .ok_or_else(|| Error::format(path, "dim", "voxel count × datatype size overflows"))?;
    let need = offset.saturating_add(n_bytes);
    let len = file_len(&data_path)?;
    let gz = is_gzip(&data_path)?;
    let describe = || {
        format!(
            "dims {}×{}×{} of {}-byte voxels ({n_bytes} bytes from byte {offset})",
            dims[0],
            dims[1],
            dims[2],
            stored.size()
        )
    };
    if !gz && len < need {
        return Err(Error::format(
            &data_path,
            "dim",
            format!(
                "{}, but the file holds only {len} bytes (truncated file or wrong dim/datatype)",
                describe()
            ),
        ));
    }
    if gz && len.saturating_mul(MAX_DEFLATE_RATIO) < need {
        return Err(Error::format(
            &data_path,
            "dim",
            format!(
                "{}, but {len} gzip-compressed bytes cannot hold that many",
                describe()
            ),
        ));
    }

    let mut stream = open_stream(&data_path)?;
    let skipped =
        std::io::copy(&mut (&mut stream).take(offset), &mut std::io::sink()).map_err(|e| {
            Error::format(
                &data_path,
                "vox_offset",
                format!("cannot read up to the voxels: {e}"),
            )
        })?;
    if skipped < offset {
        return Err(Error::format(
            &data_path,
            "vox_offset",
            format!(
                "the voxels should start at byte {offset} but the data ends after {skipped} bytes"
            ),
        ));
    }
    let bytes = read_exact_or_short(stream, n_bytes, &data_path, "dim")?;
    let big_endian = h.endianness == Endianness::Big;
    let data = decode(stored, &bytes, big_endian);
    drop(bytes);

    let (slope, inter) = (h.scl_slope as f64, h.scl_inter as f64);
    let data = if slope != 0.0 && slope.is_finite() && inter.is_finite() {
        data.rescaled(slope, inter)
    } else {
        if slope != 0.0 {
            eprintln!(
                "warning: {}: scl_slope {slope} / scl_inter {inter} are not finite: values left unscaled",
                path.display()
            );
        }
        data
    };

    let mut spacing = [1f32; 3];
    for (i, s) in spacing.iter_mut().enumerate() {
        let p = h.pixdim[i + 1].abs();
        if p.is_finite() && p > 0.0 {
            *s = p;
        } else if dims[i] > 1 {
            return Err(Error::format(
                path,
                "pixdim",
                format!(
                    "pixdim[{}] = {}: voxel spacing must be a positive finite number",
                    i + 1,
                    h.pixdim[i + 1]
                ),
            ));
        }
    }
    let (origin, field) = if h.qform_code > 0 {
        (
            Vec3::new(h.quatern_x, h.quatern_y, h.quatern_z),
            "qoffset_x/y/z",
        )
    } else if h.sform_code > 0 {
        (
            Vec3::new(h.srow_x[3], h.srow_y[3], h.srow_z[3]),
            "srow_x/y/z[3]",
        )
    } else {
        (Vec3::ZERO, "")
    };
    if !origin.is_finite() {
        return Err(Error::format(
            path,
            field,
            format!("origin {origin} is not finite"),
        ));
    }

    let dims = dims.map(|d| d as usize);
    let mut vol = Volume::new(dims, Vec3::from(spacing), origin, data)
        .map_err(|e| Error::format(path, "dim", e.to_string()))?;
    let name = String::from_utf8_lossy(&h.intent_name);
    let name = name.trim_matches(|c: char| c == '\0' || c.is_whitespace());
    if !name.is_empty() {
        vol.name = Some(name.to_string());
    }
    Ok(vol)
}

/// Decodes the voxel bytes into the narrowest voxcast type that holds them.
fn decode(stored: Stored, b: &[u8], big_endian: bool) -> VoxelData {
    macro_rules! values {
        ($t:ty, $n:expr) => {
            b.chunks_exact($n).map(|c| {
                let mut a = [0u8; $n];
                a.copy_from_slice(c);
                if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }
            })
        };
    }
    match stored {
        Stored::U8 => VoxelData::from_bytes(ScalarType::U8, b, big_endian),
        Stored::I16 => VoxelData::from_bytes(ScalarType::I16, b, big_endian),
        Stored::U16 => VoxelData::from_bytes(ScalarType::U16, b, big_endian),
        Stored::F32 => VoxelData::from_bytes(ScalarType::F32, b, big_endian),
        Stored::I8 => VoxelData::I16(b.iter().map(|&v| v as i8 as i16).collect()),
        Stored::F64 => VoxelData::F32(values!(f64, 8).map(|v| v as f32).collect()),
        Stored::I32 => narrow_ints(|| values!(i32, 4).map(i64::from)),
        Stored::U32 => narrow_ints(|| values!(u32, 4).map(i64::from)),
        Stored::I64 => narrow_ints(|| values!(i64, 8)),
        // u64 beyond i64::MAX saturates; such values are far outside what
        // f32 shows exactly anyway.
        Stored::U64 => {
            narrow_ints(|| values!(u64, 8).map(|v| i64::try_from(v).unwrap_or(i64::MAX)))
        }
    }
}

/// Wide integers (label maps are often int32) in i16 or u16 when every value
/// fits, else f32. `values` is called twice (range, then conversion) so no
/// 64-bit copy of the volume is ever held.
fn narrow_ints<I: Iterator<Item = i64>>(values: impl Fn() -> I) -> VoxelData {
    let (lo, hi) = values().fold((0i64, 0i64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo >= i16::MIN as i64 && hi <= i16::MAX as i64 {
        VoxelData::I16(values().map(|x| x as i16).collect())
    } else if lo >= 0 && hi <= u16::MAX as i64 {
        VoxelData::U16(values().map(|x| x as u16).collect())
    } else {
        VoxelData::F32(values().map(|x| x as f32).collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    /// The fields a test sets in a hand-written 348-byte NIfTI-1 header.
    struct Hdr {
        dim: [i16; 8],
        datatype: i16,
        bitpix: i16,
        pixdim: [f32; 8],
        vox_offset: f32,
        slope: f32,
        inter: f32,
        qform_code: i16,
        qoffset: [f32; 3],
        sform_code: i16,
        srow_t: [f32; 3],
        intent_name: &'static [u8],
        magic: &'static [u8; 4],
        big_endian: bool,
    }

    impl Default for Hdr {
        fn default() -> Self {
            Hdr {
                dim: [3, 4, 3, 2, 1, 1, 1, 1],
                datatype: 2,
                bitpix: 8,
                pixdim: [1.0, 0.5, 0.75, 2.0, 1.0, 0.0, 0.0, 0.0],
                vox_offset: 352.0,
                slope: 0.0,
                inter: 0.0,
                qform_code: 0,
                qoffset: [0.0; 3],
                sform_code: 0,
                srow_t: [0.0; 3],
                intent_name: b"",
                magic: b"n+1\0",
                big_endian: false,
            }
        }
    }

    impl Hdr {
        /// The header bytes (348) plus the 4-byte extension flag (zeros).
        fn bytes(&self) -> Vec<u8> {
            let mut b = vec![0u8; 352];
            let be = self.big_endian;
            let mut put = |at: usize, v: &[u8]| b[at..at + v.len()].copy_from_slice(v);
            macro_rules! num {
                ($v:expr) => {
                    if be {
                        $v.to_be_bytes()
                    } else {
                        $v.to_le_bytes()
                    }
                };
            }
            put(0, &num!(348i32));
            put(38, b"r");
            for (i, d) in self.dim.iter().enumerate() {
                put(40 + 2 * i, &num!(*d));
            }
            put(70, &num!(self.datatype));
            put(72, &num!(self.bitpix));
            for (i, p) in self.pixdim.iter().enumerate() {
                put(76 + 4 * i, &num!(*p));
            }
            put(108, &num!(self.vox_offset));
            put(112, &num!(self.slope));
            put(116, &num!(self.inter));
            put(123, &[2]); // xyzt_units: mm
            put(148, b"voxcast test");
            put(252, &num!(self.qform_code));
            put(254, &num!(self.sform_code));
            for (i, q) in self.qoffset.iter().enumerate() {
                put(268 + 4 * i, &num!(*q));
            }
            // srow_x/y/z = identity with translation srow_t.
            for r in 0..3 {
                let mut row = [0f32; 4];
                row[r] = 1.0;
                row[3] = self.srow_t[r];
                for (c, v) in row.iter().enumerate() {
                    put(280 + 16 * r + 4 * c, &num!(*v));
                }
            }
            put(328, self.intent_name);
            put(344, self.magic);
            b
        }
    }

    fn write(dir: &Path, name: &str, h: &Hdr, data: &[u8], gzip: bool) -> PathBuf {
        let p = dir.join(name);
        let mut bytes = h.bytes();
        bytes.extend_from_slice(data);
        if gzip {
            let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
            enc.write_all(&bytes).unwrap();
            bytes = enc.finish().unwrap();
        }
        std::fs::write(&p, bytes).unwrap();
        p
    }

    fn le<T: Copy>(v: &[T], f: impl Fn(T) -> Vec<u8>) -> Vec<u8> {
        v.iter().flat_map(|x| f(*x)).collect()
    }

    #[test]
    fn uint8_dims_spacing_origin_values() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            qform_code: 1,
            qoffset: [10.0, -20.0, 30.5],
            intent_name: b"density",
            ..Default::default()
        };
        let data: Vec<u8> = (0..24).map(|i| i * 10).collect();
        let p = write(dir.path(), "v.nii", &h, &data, false);
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [4, 3, 2]);
        assert_eq!(v.scalar_type(), ScalarType::U8);
        assert_eq!(v.spacing(), Vec3::new(0.5, 0.75, 2.0));
        assert_eq!(v.origin(), Vec3::new(10.0, -20.0, 30.5));
        assert_eq!(v.name.as_deref(), Some("density"));
        // x fastest: index = i + 4 (j + 3 k).
        assert_eq!(v.value(0, 0, 0), 0.0);
        assert_eq!(v.value(3, 0, 0), 30.0);
        assert_eq!(v.value(1, 2, 1), 10.0 * (1 + 4 * (2 + 3)) as f32);
        assert_eq!(v.value(3, 2, 1), 230.0);
    }

    #[test]
    fn gzip_reads_the_same_and_goes_through_open() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            datatype: 4,
            bitpix: 16,
            ..Default::default()
        };
        let vals: Vec<i16> = (0..24).map(|i| i * 100 - 1200).collect();
        let p = write(
            dir.path(),
            "v.nii.gz",
            &h,
            &le(&vals, |x| x.to_le_bytes().to_vec()),
            true,
        );
        let v = crate::io::open(&p, &Default::default()).unwrap();
        assert_eq!(v.dims(), [4, 3, 2]);
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.data(), &VoxelData::I16(vals));
    }

    #[test]
    fn scaling_is_applied() {
        let dir = tempfile::tempdir().unwrap();
        // Integral scaling of int16 stays i16 (as CT HU would).
        let h = Hdr {
            datatype: 4,
            bitpix: 16,
            slope: 2.0,
            inter: -100.0,
            ..Default::default()
        };
        let vals: Vec<i16> = (0..24).collect();
        let p = write(
            dir.path(),
            "a.nii",
            &h,
            &le(&vals, |x| x.to_le_bytes().to_vec()),
            false,
        );
        let v = read(&p).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.value(3, 2, 1), 23.0 * 2.0 - 100.0);
        // A fractional slope gives f32.
        let h = Hdr {
            datatype: 512,
            bitpix: 16,
            slope: 0.5,
            inter: 1.0,
            ..Default::default()
        };
        let vals: Vec<u16> = (0..24).map(|i| i * 1000).collect();
        let p = write(
            dir.path(),
            "b.nii",
            &h,
            &le(&vals, |x| x.to_le_bytes().to_vec()),
            false,
        );
        let v = read(&p).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!(v.value(1, 0, 0), 501.0);
        assert_eq!(v.value(3, 2, 1), 23000.0 * 0.5 + 1.0);
        // (1, 0) and slope 0 leave the data alone.
        for (slope, inter) in [(1.0, 0.0), (0.0, 5.0)] {
            let h = Hdr {
                datatype: 512,
                bitpix: 16,
                slope,
                inter,
                ..Default::default()
            };
            let p = write(
                dir.path(),
                "c.nii",
                &h,
                &le(&vals, |x| x.to_le_bytes().to_vec()),
                false,
            );
            let v = read(&p).unwrap();
            assert_eq!(v.data(), &VoxelData::U16(vals.clone()), "{slope} {inter}");
        }
    }

    #[test]
    fn big_endian_file() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            datatype: 16,
            bitpix: 32,
            big_endian: true,
            ..Default::default()
        };
        let vals: Vec<f32> = (0..24).map(|i| i as f32 * 0.25 - 1.0).collect();
        let p = write(
            dir.path(),
            "be.nii",
            &h,
            &le(&vals, |x| x.to_be_bytes().to_vec()),
            false,
        );
        let v = read(&p).unwrap();
        assert_eq!(v.spacing(), Vec3::new(0.5, 0.75, 2.0));
        assert_eq!(v.data(), &VoxelData::F32(vals));
    }

    #[test]
    fn other_datatypes_are_converted() {
        let dir = tempfile::tempdir().unwrap();
        let case = |datatype: i16, bitpix: i16, data: Vec<u8>| {
            let h = Hdr {
                datatype,
                bitpix,
                ..Default::default()
            };
            read(&write(dir.path(), "t.nii", &h, &data, false)).unwrap()
        };
        let i8s: Vec<i8> = (0..24).map(|i| i * 5 - 60).collect();
        let v = case(256, 8, le(&i8s, |x| x.to_le_bytes().to_vec()));
        assert_eq!(
            v.data(),
            &VoxelData::I16(i8s.iter().map(|&x| x as i16).collect())
        );
        let f64s: Vec<f64> = (0..24).map(|i| i as f64 / 3.0).collect();
        let v = case(64, 64, le(&f64s, |x| x.to_le_bytes().to_vec()));
        assert_eq!(
            v.data(),
            &VoxelData::F32(f64s.iter().map(|&x| x as f32).collect())
        );
        // A small int32 label map fits i16; large uint32 values need f32.
        let labels: Vec<i32> = (0..24).map(|i| i % 5 - 1).collect();
        let v = case(8, 32, le(&labels, |x| x.to_le_bytes().to_vec()));
        assert_eq!(
            v.data(),
            &VoxelData::I16(labels.iter().map(|&x| x as i16).collect())
        );
        let big: Vec<u32> = (0..24).map(|i| i * 1_000_000).collect();
        let v = case(768, 32, le(&big, |x| x.to_le_bytes().to_vec()));
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!(v.value(3, 2, 1), 23_000_000.0);
    }

    #[test]
    fn single_slice_and_4d_with_one_volume() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            dim: [2, 4, 3, 0, 0, 0, 0, 0],
            pixdim: [1.0, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0],
            ..Default::default()
        };
        let v = read(&write(dir.path(), "2d.nii", &h, &[7u8; 12], false)).unwrap();
        assert_eq!(v.dims(), [4, 3, 1]);
        assert_eq!(v.spacing(), Vec3::new(0.5, 0.5, 1.0));
        let h = Hdr {
            dim: [4, 4, 3, 2, 1, 1, 1, 1],
            ..Default::default()
        };
        let v = read(&write(dir.path(), "4d.nii", &h, &[1u8; 24], false)).unwrap();
        assert_eq!(v.dims(), [4, 3, 2]);
        let h = Hdr {
            dim: [4, 4, 3, 2, 5, 1, 1, 1],
            ..Default::default()
        };
        let e = read(&write(dir.path(), "4d5.nii", &h, &[1u8; 120], false)).unwrap_err();
        assert!(
            matches!(e, Error::Unsupported { .. }) && e.to_string().contains("dim[4] = 5"),
            "{e}"
        );
    }

    #[test]
    fn sform_translation_when_no_qform() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            sform_code: 2,
            srow_t: [-90.0, 126.0, -72.0],
            ..Default::default()
        };
        let v = read(&write(dir.path(), "s.nii", &h, &[0u8; 24], false)).unwrap();
        assert_eq!(v.origin(), Vec3::new(-90.0, 126.0, -72.0));
    }

    #[test]
    fn header_image_pair() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            magic: b"ni1\0",
            vox_offset: 0.0,
            ..Default::default()
        };
        let hdr = dir.path().join("pair.hdr");
        std::fs::write(&hdr, &h.bytes()[..348]).unwrap();
        std::fs::write(dir.path().join("pair.img"), (0..24u8).collect::<Vec<_>>()).unwrap();
        let v = crate::io::open(&hdr, &Default::default()).unwrap();
        assert_eq!(v.dims(), [4, 3, 2]);
        assert_eq!(v.value(3, 2, 1), 23.0);
    }

    #[test]
    fn a_billion_voxels_in_a_small_file_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            dim: [3, 1000, 1000, 1000, 1, 1, 1, 1],
            ..Default::default()
        };
        for gz in [false, true] {
            let name = if gz { "big.nii.gz" } else { "big.nii" };
            let p = write(dir.path(), name, &h, &[0u8; 600], gz);
            assert!(file_len(&p).unwrap() < 1024);
            let s = read(&p).unwrap_err().to_string();
            assert!(
                s.contains(name) && s.contains("`dim`") && s.contains("1000000000"),
                "{s}"
            );
        }
    }

    #[test]
    fn truncated_data_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            datatype: 4,
            bitpix: 16,
            ..Default::default()
        };
        let s = read(&write(dir.path(), "t.nii", &h, &[0u8; 40], false))
            .unwrap_err()
            .to_string();
        assert!(
            s.contains("t.nii") && s.contains("`dim`") && s.contains("truncated"),
            "{s}"
        );
        // Gzip: the size check passes, the stream ends early.
        let s = read(&write(dir.path(), "t.nii.gz", &h, &[0u8; 40], true))
            .unwrap_err()
            .to_string();
        assert!(
            s.contains("t.nii.gz") && s.contains("`dim`") && s.contains("ends after 40 bytes"),
            "{s}"
        );
    }

    #[test]
    fn unknown_and_unsupported_datatypes() {
        let dir = tempfile::tempdir().unwrap();
        let h = Hdr {
            datatype: 999,
            ..Default::default()
        };
        let s = read(&write(dir.path(), "u.nii", &h, &[0u8; 24], false))
            .unwrap_err()
            .to_string();
        assert!(
            s.contains("u.nii") && s.contains("`datatype`") && s.contains("999"),
            "{s}"
        );
        let h = Hdr {
            datatype: 32,
            bitpix: 64,
            ..Default::default()
        };
        let e = read(&write(dir.path(), "c.nii", &h, &[0u8; 192], false)).unwrap_err();
        assert!(
            matches!(e, Error::Unsupported { .. }) && e.to_string().contains("complex"),
            "{e}"
        );
    }

    #[test]
    fn bad_header_fields_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let mut pd = Hdr::default().pixdim;
        for bad in [0.0, f32::NAN, f32::INFINITY] {
            pd[2] = bad;
            let h = Hdr {
                pixdim: pd,
                ..Default::default()
            };
            let s = read(&write(dir.path(), "p.nii", &h, &[0u8; 24], false))
                .unwrap_err()
                .to_string();
            assert!(s.contains("p.nii") && s.contains("`pixdim`"), "{s}");
        }
        // Negative pixdim (a flipped axis) is read as its size.
        let h = Hdr {
            pixdim: [-1.0, -0.5, 0.75, 2.0, 0.0, 0.0, 0.0, 0.0],
            ..Default::default()
        };
        assert_eq!(
            read(&write(dir.path(), "n.nii", &h, &[0u8; 24], false))
                .unwrap()
                .spacing()
                .x,
            0.5
        );
        for (dim, what) in [
            ([3, 4, -3, 2, 1, 1, 1, 1], "dim[2] = -3"),
            ([0, 4, 3, 2, 1, 1, 1, 1], "dim[0] = 0"),
            ([3, 4, 0, 2, 1, 1, 1, 1], "dim[2] = 0"),
        ] {
            let h = Hdr {
                dim,
                ..Default::default()
            };
            let s = read(&write(dir.path(), "d.nii", &h, &[0u8; 24], false))
                .unwrap_err()
                .to_string();
            assert!(s.contains("`dim`") && s.contains(what), "{s}");
        }
        let h = Hdr {
            vox_offset: 100.0,
            ..Default::default()
        };
        let s = read(&write(dir.path(), "o.nii", &h, &[0u8; 24], false))
            .unwrap_err()
            .to_string();
        assert!(s.contains("`vox_offset`"), "{s}");
        // Not NIfTI at all, too short, NIfTI-2.
        std::fs::write(dir.path().join("x.nii"), vec![7u8; 400]).unwrap();
        let s = read(&dir.path().join("x.nii")).unwrap_err().to_string();
        assert!(s.contains("x.nii") && s.contains("`sizeof_hdr`"), "{s}");
        std::fs::write(dir.path().join("s.nii"), 348i32.to_le_bytes()).unwrap();
        let s = read(&dir.path().join("s.nii")).unwrap_err().to_string();
        assert!(s.contains("s.nii") && s.contains("348-byte header"), "{s}");
        let mut b = Hdr::default().bytes();
        b[..4].copy_from_slice(&540i32.to_le_bytes());
        std::fs::write(dir.path().join("n2.nii"), b).unwrap();
        let e = read(&dir.path().join("n2.nii")).unwrap_err();
        assert!(
            matches!(e, Error::Unsupported { .. }) && e.to_string().contains("NIfTI-2"),
            "{e}"
        );
        let mut b = Hdr::default().bytes();
        b[344..348].copy_from_slice(b"abc\0");
        b.extend_from_slice(&[0u8; 24]);
        std::fs::write(dir.path().join("m.nii"), b).unwrap();
        let s = read(&dir.path().join("m.nii")).unwrap_err().to_string();
        assert!(s.contains("m.nii") && s.contains("`magic`"), "{s}");
    }
}
