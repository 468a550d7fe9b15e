//! Voxels stored as one of the common binary scalar types (the NIfTI,
//! Analyze and MGH readers share this): the size the header claims is
//! checked against the file, the bytes are read (inflated when the file is
//! gzip) and decoded into the narrowest voxcast type that holds them.
//!
//! uint8, int16, uint16 and float32 are kept as they are; int8 becomes i16;
//! int32, uint32, int64 and uint64 become i16 or u16 when all values fit,
//! else f32; float64 becomes f32.

use super::util::{check_dims, file_len, read_exact_or_short, MAX_DEFLATE_RATIO};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, VoxelData};
use std::io::Read;
use std::path::Path;

/// How voxels are stored in a file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Stored {
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
    /// Bytes per voxel.
    pub(crate) fn size(self) -> u64 {
        match self {
            Stored::U8 | Stored::I8 => 1,
            Stored::I16 | Stored::U16 => 2,
            Stored::I32 | Stored::U32 | Stored::F32 => 4,
            Stored::I64 | Stored::U64 | Stored::F64 => 8,
        }
    }

    /// The usual C-like name (`uint8`, `float32`, …).
    pub(crate) fn name(self) -> &'static str {
        match self {
            Stored::U8 => "uint8",
            Stored::I8 => "int8",
            Stored::I16 => "int16",
            Stored::U16 => "uint16",
            Stored::I32 => "int32",
            Stored::U32 => "uint32",
            Stored::I64 => "int64",
            Stored::U64 => "uint64",
            Stored::F32 => "float32",
            Stored::F64 => "float64",
        }
    }
}

/// True when the file starts with the gzip magic.
pub(crate) fn is_gzip(path: &Path) -> Result<bool> {
    Ok(super::util::read_head(path, 2)? == [0x1f, 0x8b])
}

/// A reader over the file's bytes, inflated when the file is gzip.
pub(crate) fn open_stream(path: &Path) -> Result<Box<dyn Read>> {
    let f = crate::files::open(path)?.0;
    let f = std::io::BufReader::new(f);
    Ok(if is_gzip(path)? {
        Box::new(flate2::read::MultiGzDecoder::new(f))
    } else {
        Box::new(f)
    })
}

/// Where the voxels are and what they are.
pub(crate) struct Layout<'a> {
    /// The file holding the voxels (maybe gzip).
    pub data_path: &'a Path,
    /// Byte offset of the first voxel in the (inflated) file.
    pub offset: u64,
    pub dims: [u64; 3],
    pub stored: Stored,
    pub big_endian: bool,
    /// The header field(s) that give the dims, for errors (`dim`).
    pub dims_field: &'a str,
    /// The header field that gives the offset, for errors (`vox_offset`).
    pub offset_field: &'a str,
}

/// Reads and decodes the voxels `layout` describes. `header` is the file
/// whose fields are wrong when the dims cannot be (errors name it).
pub(crate) fn read_voxels(header: &Path, layout: &Layout) -> Result<VoxelData> {
    let Layout {
        data_path,
        offset,
        dims,
        stored,
        big_endian,
        dims_field,
        offset_field,
    } = *layout;
    // Guard before any allocation: the voxels the header claims must fit in
    // the file (or, gzipped, in what deflate can make of it).
    let (n, _) = check_dims(header, dims_field, dims, ScalarType::U8)?;
    let n_bytes = (n as u64).checked_mul(stored.size()).ok_or_else(|| {
        Error::format(header, dims_field, "voxel count × datatype size overflows")
    })?;
    let need = offset.saturating_add(n_bytes);
    let len = file_len(data_path)?;
    let gz = is_gzip(data_path)?;
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
            data_path,
            dims_field,
            format!(
                "{}, but the file holds only {len} bytes (truncated file or wrong {dims_field}/datatype)",
                describe()
            ),
        ));
    }
    if gz && len.saturating_mul(MAX_DEFLATE_RATIO) < need {
        return Err(Error::format(
            data_path,
            dims_field,
            format!(
                "{}, but {len} gzip-compressed bytes cannot hold that many",
                describe()
            ),
        ));
    }

    let mut stream = open_stream(data_path)?;
    let skipped =
        std::io::copy(&mut (&mut stream).take(offset), &mut std::io::sink()).map_err(|e| {
            Error::format(
                data_path,
                offset_field,
                format!("cannot read up to the voxels: {e}"),
            )
        })?;
    if skipped < offset {
        return Err(Error::format(
            data_path,
            offset_field,
            format!(
                "the voxels should start at byte {offset} but the data ends after {skipped} bytes"
            ),
        ));
    }
    let bytes = read_exact_or_short(stream, n_bytes, data_path, dims_field)?;
    Ok(decode(stored, &bytes, big_endian))
}

/// Decodes the voxel bytes into the narrowest voxcast type that holds them.
pub(crate) fn decode(stored: Stored, b: &[u8], big_endian: bool) -> VoxelData {
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
