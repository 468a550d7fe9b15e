//! MetaImage (ITK's MetaIO): `.mhd` text headers naming a data file, and
//! `.mha` files whose data follow the header (`ElementDataFile = LOCAL`).
//!
//! Supported (keys matched without regard to case):
//! * `NDims` 2 (one slice, z = 1), 3, or 4 with a last size of 1; `DimSize`;
//! * `ElementType` MET_UCHAR, MET_USHORT, MET_SHORT, MET_FLOAT kept as
//!   stored; MET_CHAR becomes i16 (exact); MET_INT, MET_UINT, MET_LONG,
//!   MET_ULONG (32-bit in MetaIO), MET_LONG_LONG, MET_ULONG_LONG and
//!   MET_DOUBLE become f32, exact only up to 2²⁴ in magnitude;
//! * `ElementSpacing` (else `ElementSize`), `Offset`/`Origin`/`Position`;
//! * `BinaryDataByteOrderMSB`/`ElementByteOrderMSB`; `BinaryData = False`
//!   (values as text);
//! * `CompressedData = True`: a zlib stream (a gzip one is recognised by its
//!   magic), `CompressedDataSize` when given, else up to the end of the file;
//!   the inflated size is bounded by the compressed size × deflate's best ratio;
//! * `HeaderSize`: bytes skipped from the start of the data file (from the
//!   start of the file for LOCAL, as MetaIO does), −1 = the data are the
//!   last bytes of the file;
//! * `ElementDataFile` = a file relative to the header's folder, `LOCAL`,
//!   `LIST [filedim]` with the names on the following lines, or a pattern
//!   `fmt [min [max [step]]]` with one `%d`-style conversion (one file per slice).
//!
//! Not supported (an error naming the field): `ElementNumberOfChannels` > 1,
//! array, string and matrix element types, other `NDims`, `ObjectType`s other
//! than `Image`. `TransformMatrix`/`Orientation` and `AnatomicalOrientation`
//! are ignored: the volume is placed axis-aligned at the offset. Bytes after
//! the data are ignored, as MetaIO does.

use super::decode::{
    byte_count, check_header_size, check_origin, check_spacing, concat, decode, in_data_file,
    make_volume, parse_ascii, parse_floats, parse_sizes, per_file_count, read_binary, read_text,
    resolve_data_path, shorten, LineReader, Pattern, StoredType,
};
use super::util::{check_dims, file_len, read_exact_or_short, MAX_DEFLATE_RATIO};
use crate::error::{Error, Result};
use crate::volume::{Volume, VoxelData};
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Reads the MetaImage (`.mhd` or `.mha`) at `path`.
pub fn read(path: &Path) -> Result<Volume> {
    let mut lines = LineReader::open(path)?;
    let mut fields: Vec<(String, String)> = Vec::new();
    let mut complete = false;
    while let Some(line) = lines.next_line("header")? {
        check_header_size(path, &lines)?;
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(Error::format(
                path,
                "header",
                format!("line `{}` is not `Key = Value`", shorten(line)),
            ));
        };
        let key = key.trim().to_string();
        if fields.iter().any(|(k, _)| k.eq_ignore_ascii_case(&key)) {
            return Err(Error::format(path, key, "given twice"));
        }
        // ElementDataFile ends the header: what follows is data (LOCAL) or file names (LIST).
        let last = key.eq_ignore_ascii_case("ElementDataFile");
        fields.push((key, value.trim().to_string()));
        if last {
            complete = true;
            break;
        }
    }
    if !complete {
        return Err(Error::format(
            path,
            "ElementDataFile",
            "missing: the header must end with `ElementDataFile = <file or LOCAL>`",
        ));
    }
    let data_start = lines.pos();
    let get = |key: &str| {
        fields
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| v.as_str())
    };
    let required = |key: &'static str| {
        get(key)
            .ok_or_else(|| Error::format(path, key, "missing: a MetaImage header needs this field"))
    };

    if let Some(ot) = get("ObjectType") {
        if !ot.eq_ignore_ascii_case("Image") {
            return Err(Error::unsupported(
                path,
                format!("ObjectType `{ot}` (only Image)"),
            ));
        }
    }
    let nd_s = required("NDims")?;
    let ndims: usize = nd_s
        .parse()
        .map_err(|_| Error::format(path, "NDims", format!("`{nd_s}` is not a whole number")))?;
    let sizes = parse_sizes(path, "DimSize", required("DimSize")?)?;
    if sizes.len() != ndims {
        return Err(Error::format(
            path,
            "DimSize",
            format!("{} sizes given for NDims {ndims}", sizes.len()),
        ));
    }
    let n_spatial = match ndims {
        2 | 3 => ndims,
        4 if sizes.get(3) == Some(&1) => 3,
        _ => {
            return Err(Error::unsupported(
                path,
                format!(
                    "NDims {ndims} with DimSize {} (only 2, 3, or 4 with a last size of 1)",
                    sizes_str(&sizes)
                ),
            ))
        }
    };
    let dims = [0, 1, 2].map(|a| {
        if a < n_spatial {
            sizes.get(a).copied().unwrap_or(1)
        } else {
            1
        }
    });
    if let Some(c) = get("ElementNumberOfChannels") {
        if c.trim() != "1" {
            return Err(Error::unsupported(
                path,
                format!("ElementNumberOfChannels = {c} (only 1)"),
            ));
        }
    }
    let ty = parse_element_type(path, required("ElementType")?)?;
    let (count, _) = check_dims(path, "DimSize", dims, ty.target())?;

    let spacing = match ["ElementSpacing", "ElementSize"]
        .into_iter()
        .find_map(|k| get(k).map(|v| (k, v)))
    {
        None => check_spacing(path, "ElementSpacing", [1.0; 3])?,
        Some((key, v)) => check_spacing(path, key, per_axis(path, key, v, n_spatial, 1.0)?)?,
    };
    let origin = match ["Offset", "Origin", "Position"]
        .into_iter()
        .find_map(|k| get(k).map(|v| (k, v)))
    {
        None => check_origin(path, "Offset", [0.0; 3])?,
        Some((key, v)) => check_origin(path, key, per_axis(path, key, v, n_spatial, 0.0)?)?,
    };
    let big_endian = match ["BinaryDataByteOrderMSB", "ElementByteOrderMSB"]
        .into_iter()
        .find_map(|k| get(k).map(|v| (k, v)))
    {
        None => false,
        Some((key, v)) => parse_bool(path, key, v)?,
    };
    let binary = get("BinaryData")
        .map(|v| parse_bool(path, "BinaryData", v))
        .transpose()?
        .unwrap_or(true);
    let compressed = get("CompressedData")
        .map(|v| parse_bool(path, "CompressedData", v))
        .transpose()?
        .unwrap_or(false);
    let compressed_size: Option<u64> = get("CompressedDataSize")
        .map(|v| {
            v.parse().map_err(|_| {
                Error::format(
                    path,
                    "CompressedDataSize",
                    format!("`{v}` is not a whole number of bytes"),
                )
            })
        })
        .transpose()?;
    let header_size: i64 = match get("HeaderSize") {
        None => 0,
        Some(v) => v.parse().ok().filter(|&h| h >= -1).ok_or_else(|| {
            Error::format(
                path,
                "HeaderSize",
                format!("`{v}`: expected a byte count or -1"),
            )
        })?,
    };
    let encoding = match (binary, compressed) {
        (false, _) => Encoding::Ascii,
        (true, false) => Encoding::Raw,
        (true, true) => Encoding::Compressed(compressed_size),
    };
    let layout = Layout {
        ty,
        big_endian,
        encoding,
        header_size,
    };

    let field = "ElementDataFile";
    let edf = required(field)?;
    let first_word = edf.split_whitespace().next().unwrap_or_default();
    let data = if edf.eq_ignore_ascii_case("LOCAL") {
        read_chunk(path, data_start, count, &layout)?
    } else if first_word == "LIST" {
        let mut names = Vec::new();
        while let Some(line) = lines.next_line("ElementDataFile")? {
            check_header_size(path, &lines)?;
            let name = line.trim();
            if !name.is_empty() {
                names.push(name.to_string());
            }
        }
        let filedim = match edf.split_whitespace().nth(1) {
            None => None,
            Some(d) => Some(d.parse::<usize>().map_err(|_| {
                Error::format(
                    path,
                    field,
                    format!("`{d}` is not a whole number of dimensions"),
                )
            })?),
        }
        // MetaIO reads one slice per file when the count is missing or too large.
        .filter(|d| (1..=ndims).contains(d))
        .unwrap_or(ndims.saturating_sub(1).max(1));
        let n_files = names.len() as u64;
        let per = per_file_count(path, field, &sizes, count, n_files, Some(filedim))?;
        let files = names.iter().map(|n| Ok(resolve_data_path(path, n)));
        read_files(path, files, per, &layout)?
    } else if edf.contains('%') {
        let pattern = parse_pattern(path, edf, &sizes)?;
        let per = per_file_count(path, field, &sizes, count, pattern.count, pattern.subdim)?;
        let files =
            (0..pattern.count).map(|i| Ok(resolve_data_path(path, &pattern.name(path, field, i)?)));
        read_files(path, files, per, &layout)?
    } else {
        let file = resolve_data_path(path, edf);
        read_chunk(&file, 0, count, &layout).map_err(|e| in_data_file(path, field, e))?
    };
    make_volume(path, dims, spacing, origin, data)
}

fn parse_element_type(path: &Path, s: &str) -> Result<StoredType> {
    let u = s.trim().to_ascii_uppercase();
    Ok(match u.as_str() {
        "MET_CHAR" => StoredType::I8,
        "MET_UCHAR" => StoredType::U8,
        "MET_SHORT" => StoredType::I16,
        "MET_USHORT" => StoredType::U16,
        "MET_INT" | "MET_LONG" => StoredType::I32,
        "MET_UINT" | "MET_ULONG" => StoredType::U32,
        "MET_LONG_LONG" => StoredType::I64,
        "MET_ULONG_LONG" => StoredType::U64,
        "MET_FLOAT" => StoredType::F32,
        "MET_DOUBLE" => StoredType::F64,
        _ if u.ends_with("_ARRAY") || matches!(u.as_str(), "MET_STRING" | "MET_ASCII_CHAR" | "MET_FLOAT_MATRIX") => {
            return Err(Error::unsupported(path, format!("ElementType `{s}` (only scalar types)")));
        }
        _ => {
            return Err(Error::format(
                path,
                "ElementType",
                format!("unknown element type `{s}` (expected e.g. MET_UCHAR, MET_SHORT, MET_USHORT, MET_FLOAT)"),
            ))
        }
    })
}

fn parse_bool(path: &Path, field: &str, v: &str) -> Result<bool> {
    match v.trim().to_ascii_lowercase().as_str() {
        "true" | "1" | "yes" => Ok(true),
        "false" | "0" | "no" => Ok(false),
        _ => Err(Error::format(
            path,
            field,
            format!("`{v}`: expected True or False"),
        )),
    }
}

/// The first `n` values of a per-axis field, padded with `fill` up to 3.
fn per_axis(path: &Path, field: &str, v: &str, n: usize, fill: f64) -> Result<[f64; 3]> {
    let vals = parse_floats(path, field, v)?;
    if vals.len() < n {
        return Err(Error::format(
            path,
            field,
            format!("{} values, expected one per axis ({n})", vals.len()),
        ));
    }
    Ok([0, 1, 2].map(|a| {
        if a < n {
            vals.get(a).copied().unwrap_or(fill)
        } else {
            fill
        }
    }))
}

/// `fmt [min [max [step]]]` as MetaIO reads it: one file per slice, indices
/// from 1 by default.
fn parse_pattern(path: &Path, edf: &str, sizes: &[u64]) -> Result<Pattern> {
    let field = "ElementDataFile";
    let words: Vec<&str> = edf.split_whitespace().collect();
    let nums: Vec<i64> = words
        .iter()
        .skip(1)
        .map(|w| {
            w.parse().map_err(|_| {
                Error::format(
                    path,
                    field,
                    format!("`{w}` in `{edf}` is not a whole number"),
                )
            })
        })
        .collect::<Result<_>>()?;
    let slices = sizes.last().copied().unwrap_or(1);
    let min = nums.first().copied().unwrap_or(1);
    let step = nums.get(2).copied().unwrap_or(1);
    let count = match nums.get(1) {
        None => slices,
        Some(&max) => crate::io::util::pattern_count(min, max, step).ok_or_else(|| {
            Error::format(
                path,
                field,
                format!("`{edf}`: min {min}, max {max} and step {step} give no files"),
            )
        })?,
    };
    // MetaIO reads no more files than there are slices.
    let count = count.min(slices);
    let fmt = words.first().copied().unwrap_or_default().to_string();
    Ok(Pattern {
        fmt,
        min,
        step,
        count,
        subdim: Some(sizes.len().saturating_sub(1).max(1)),
    })
}

#[derive(Clone, Copy, Debug)]
enum Encoding {
    Raw,
    /// zlib (or gzip) with the compressed size when the header gives it.
    Compressed(Option<u64>),
    Ascii,
}

struct Layout {
    ty: StoredType,
    big_endian: bool,
    encoding: Encoding,
    header_size: i64,
}

/// Reads the files in order, `per` voxels each, and joins them.
fn read_files(
    header: &Path,
    files: impl Iterator<Item = Result<PathBuf>>,
    per: usize,
    layout: &Layout,
) -> Result<VoxelData> {
    let mut parts = Vec::new();
    for file in files {
        let file = file?;
        parts.push(
            read_chunk(&file, 0, per, layout)
                .map_err(|e| in_data_file(header, "ElementDataFile", e))?,
        );
    }
    concat(parts).ok_or_else(|| Error::format(header, "ElementDataFile", "no data files"))
}

/// Reads `count` voxels from `file`, whose data start at `start` unless
/// `HeaderSize` says otherwise.
fn read_chunk(file: &Path, start: u64, count: usize, l: &Layout) -> Result<VoxelData> {
    let field = "DimSize";
    let start = match u64::try_from(l.header_size) {
        Ok(h) if h > 0 => h,
        _ => start,
    };
    let at_end = l.header_size == -1;
    match l.encoding {
        Encoding::Raw => {
            let offset = if at_end {
                let n_bytes = byte_count(file, field, count, l.ty)?;
                let len = file_len(file)?;
                len.checked_sub(n_bytes).filter(|&o| o >= start).ok_or_else(|| {
                    Error::format(
                        file,
                        "HeaderSize",
                        format!("-1: the file ({len} bytes) is smaller than the {n_bytes} bytes of data"),
                    )
                })?
            } else {
                start
            };
            read_binary(file, offset, count, l.ty, l.big_endian, false, field)
        }
        Encoding::Compressed(size) => {
            let n_bytes = byte_count(file, field, count, l.ty)?;
            let len = file_len(file)?;
            let (offset, csize) = match (at_end, size) {
                (false, Some(c)) => (start, c),
                (false, None) => (start, len.saturating_sub(start)),
                (true, Some(c)) => (len.saturating_sub(c), c),
                (true, None) => {
                    return Err(Error::unsupported(
                        file,
                        "HeaderSize = -1 with compressed data needs CompressedDataSize",
                    ))
                }
            };
            let bytes = read_compressed(file, offset, csize, n_bytes, field)?;
            Ok(decode(l.ty, bytes, l.big_endian))
        }
        Encoding::Ascii => {
            if at_end {
                return Err(Error::unsupported(
                    file,
                    "HeaderSize = -1 with BinaryData = False",
                ));
            }
            let text = read_text(file, start, field)?;
            Ok(parse_ascii(file, field, &text, count, l.ty)?.0)
        }
    }
}

/// Inflates `n_bytes` from the `csize` compressed bytes at `offset`. Like
/// `util::read_payload`, the sizes are checked against the file before
/// anything is allocated.
fn read_compressed(
    path: &Path,
    offset: u64,
    csize: u64,
    n_bytes: u64,
    field: &str,
) -> Result<Vec<u8>> {
    let len = file_len(path)?;
    if offset.checked_add(csize).is_none_or(|end| end > len) {
        return Err(Error::format(
            path,
            "CompressedDataSize",
            format!("{csize} compressed bytes from byte {offset} run past the end of the file ({len} bytes)"),
        ));
    }
    if csize.saturating_mul(MAX_DEFLATE_RATIO) < n_bytes {
        return Err(Error::format(
            path,
            field,
            format!("the header describes {n_bytes} bytes of voxels but {csize} compressed bytes cannot hold that many"),
        ));
    }
    let mut f = crate::files::open(path)?.0;
    f.seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    let mut r = BufReader::new(f.take(csize));
    let gzip = r
        .fill_buf()
        .map_err(|e| Error::io(path, e))?
        .starts_with(&[0x1f, 0x8b]);
    if gzip {
        read_exact_or_short(
            flate2::bufread::MultiGzDecoder::new(r),
            n_bytes,
            path,
            field,
        )
    } else {
        read_exact_or_short(flate2::bufread::ZlibDecoder::new(r), n_bytes, path, field)
    }
}

fn sizes_str(s: &[u64]) -> String {
    s.iter().map(u64::to_string).collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_support::{err_naming, never_panics, write};
    use crate::testdata::data_path;
    use crate::volume::ScalarType;
    use flate2::write::ZlibEncoder;
    use flate2::Compression;
    use glam::Vec3;
    use std::io::Write;

    fn local(header: &str, data: &[u8]) -> Vec<u8> {
        let mut v = header.as_bytes().to_vec();
        v.extend_from_slice(data);
        v
    }

    fn zlib(data: &[u8]) -> Vec<u8> {
        let mut e = ZlibEncoder::new(Vec::new(), Compression::default());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn reads_mr_head() {
        let Some(p) = data_path("mr_head/HeadMRVolume.mhd") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [48, 62, 42]);
        assert_eq!(v.spacing(), Vec3::splat(4.0));
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.scalar_type(), ScalarType::U8);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 255.0));
        // Values read from the raw file with Python, index i + 48·(j + 62·k).
        assert_eq!(v.value(24, 31, 21), 79.0);
        assert_eq!(v.value(30, 40, 15), 106.0);
        assert_eq!(v.value(28, 39, 22), 255.0);
        assert_eq!(v.value(0, 0, 0), 1.0);
    }

    #[test]
    fn reads_local_mha_big_endian() {
        let dir = tempfile::tempdir().unwrap();
        let vals: Vec<i16> = (0..24).map(|i| i * 10 - 100).collect();
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = "ObjectType = Image\nNDims = 3\nDimSize = 2 3 4\nElementType = MET_SHORT\n\
                 ElementSpacing = 0.5 0.5 2\nOffset = -10 20 30.5\nBinaryDataByteOrderMSB = True\n\
                 ElementDataFile = LOCAL\n";
        let p = write(dir.path(), "v.mha", &local(h, &raw));
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [2, 3, 4]);
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.spacing(), Vec3::new(0.5, 0.5, 2.0));
        assert_eq!(v.origin(), Vec3::new(-10.0, 20.0, 30.5));
        assert_eq!(v.value(0, 0, 0), -100.0);
        assert_eq!(v.value(1, 2, 3), 130.0);
    }

    #[test]
    fn reads_compressed() {
        let dir = tempfile::tempdir().unwrap();
        let raw: Vec<u8> = (0..1000u32).map(|i| (i % 251) as u8).collect();
        let z = zlib(&raw);
        // With and without CompressedDataSize.
        for (i, size) in [format!("CompressedDataSize = {}\n", z.len()), String::new()]
            .iter()
            .enumerate()
        {
            let h = format!(
                "NDims = 3\nDimSize = 10 10 10\nElementType = MET_UCHAR\nCompressedData = True\n{size}ElementDataFile = LOCAL\n"
            );
            let name = format!("z{i}.mha");
            let v = read(&write(dir.path(), &name, &local(&h, &z))).unwrap();
            assert_eq!(v.value(9, 9, 9), (999 % 251) as f32);
            assert_eq!(v.stats().max, 250.0);
        }
        // Detached .zraw.
        write(dir.path(), "d.zraw", &z);
        let h = "NDims = 3\nDimSize = 10 10 10\nElementType = MET_UCHAR\nCompressedData = True\nElementDataFile = d.zraw\n";
        let v = read(&write(dir.path(), "d.mhd", h.as_bytes())).unwrap();
        assert_eq!(v.value(5, 0, 0), 5.0);
    }

    #[test]
    fn reads_converted_types_header_size_and_2d() {
        let dir = tempfile::tempdir().unwrap();
        let vals = [1.25f64, -7.5, 1e6, 0.0];
        let mut raw = vec![0xEEu8; 13];
        raw.extend(vals.iter().flat_map(|v| v.to_le_bytes()));
        write(dir.path(), "d.raw", &raw);
        let h = "NDims = 2\nDimSize = 2 2\nElementType = MET_DOUBLE\nElementSize = 3 4\nHeaderSize = 13\nElementDataFile = d.raw\n";
        let v = read(&write(dir.path(), "d.mhd", h.as_bytes())).unwrap();
        assert_eq!(v.dims(), [2, 2, 1]);
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!(v.spacing(), Vec3::new(3.0, 4.0, 1.0));
        assert_eq!(v.value(1, 0, 0), -7.5);
        assert_eq!(v.stats().max, 1e6);
        // HeaderSize = -1: the data are the last bytes.
        let h = "NDims = 2\nDimSize = 2 2\nElementType = MET_DOUBLE\nHeaderSize = -1\nElementDataFile = d.raw\n";
        let v = read(&write(dir.path(), "e.mhd", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 0), 1.25);

        let h = "NDims = 3\nDimSize = 3 1 1\nElementType = MET_CHAR\nElementDataFile = LOCAL\n";
        let v = read(&write(dir.path(), "c.mha", &local(h, &[0x80, 0xff, 5]))).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(
            (v.value(0, 0, 0), v.value(1, 0, 0), v.value(2, 0, 0)),
            (-128.0, -1.0, 5.0)
        );

        let vals = [4_000_000_000u32, 1];
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = "NDims = 3\nDimSize = 2 1 1\nElementType = MET_UINT\nElementByteOrderMSB = True\nElementDataFile = LOCAL\n";
        let v = read(&write(dir.path(), "u.mha", &local(h, &raw))).unwrap();
        assert_eq!(v.value(0, 0, 0), 4e9);
    }

    #[test]
    fn reads_ascii_and_slice_files() {
        let dir = tempfile::tempdir().unwrap();
        let h = "NDims = 3\nDimSize = 2 2 1\nElementType = MET_FLOAT\nBinaryData = False\nElementDataFile = LOCAL\n";
        let v = read(&write(dir.path(), "t.mha", &local(h, b"0.5 1\n-2 3e1\n"))).unwrap();
        assert_eq!(v.value(1, 1, 0), 30.0);
        assert_eq!(v.value(0, 1, 0), -2.0);

        write(dir.path(), "sl_1.raw", &[1, 2, 3, 4]);
        write(dir.path(), "sl_2.raw", &[5, 6, 7, 8]);
        let h = "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LIST 2\nsl_1.raw\nsl_2.raw\n";
        let v = read(&write(dir.path(), "list.mhd", h.as_bytes())).unwrap();
        assert_eq!(v.value(1, 1, 1), 8.0);
        let h = "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = sl_%d.raw 1 2 1\n";
        let v = read(&write(dir.path(), "pat.mhd", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 1), 5.0);
    }

    #[test]
    fn bad_dims_are_errors_naming_dimsize() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            ("DimSize = 4 4 0", "at least 1"),
            ("DimSize = 4 -4 4", "negative"),
            ("DimSize = 4 x 4", "not a whole number"),
            ("DimSize = 4294967296 4294967296 4294967296", "more than"),
            ("DimSize = 4 4", "2 sizes"),
            ("DimSize = 4 4 8", "truncated"),
        ];
        for (i, (dims, why)) in cases.iter().enumerate() {
            let h =
                format!("NDims = 3\n{dims}\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n");
            let name = format!("bad{i}.mha");
            let p = write(dir.path(), &name, &local(&h, &[0u8; 64]));
            let s = err_naming(read(&p), &name, "DimSize");
            assert!(s.contains(why), "{dims}: {s}");
        }
    }

    #[test]
    fn truncated_and_lying_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        write(dir.path(), "short.raw", &[0u8; 63]);
        let h =
            "NDims = 3\nDimSize = 4 4 4\nElementType = MET_UCHAR\nElementDataFile = short.raw\n";
        let s = err_naming(
            read(&write(dir.path(), "short.mhd", h.as_bytes())),
            "short.mhd",
            "DimSize",
        );
        assert!(s.contains("short.raw"), "{s}");

        // 1 KB claiming 10⁹ voxels, raw and compressed: refused before allocating.
        for (i, extra) in ["", "CompressedData = True\n"].iter().enumerate() {
            let h = format!("NDims = 3\nDimSize = 1000 1000 1000\nElementType = MET_UCHAR\n{extra}ElementDataFile = LOCAL\n");
            let name = format!("huge{i}.mha");
            let s = err_naming(
                read(&write(dir.path(), &name, &local(&h, &[0u8; 1024]))),
                &name,
                "DimSize",
            );
            assert!(s.contains("1000000000"), "{s}");
        }
        // A compressed stream cut short, and a CompressedDataSize beyond the file.
        let z = zlib(&[3u8; 4096]);
        let h = "NDims = 3\nDimSize = 16 16 16\nElementType = MET_UCHAR\nCompressedData = True\nElementDataFile = LOCAL\n";
        let p = write(dir.path(), "cut.mha", &local(h, &z[..z.len() / 2]));
        err_naming(read(&p), "cut.mha", "DimSize");
        let h = "NDims = 3\nDimSize = 16 16 16\nElementType = MET_UCHAR\nCompressedData = True\nCompressedDataSize = 99999\nElementDataFile = LOCAL\n";
        let p = write(dir.path(), "big.mha", &local(h, &z));
        err_naming(read(&p), "big.mha", "CompressedDataSize");
        // Too few text values.
        let h = "NDims = 3\nDimSize = 2 2 2\nElementType = MET_FLOAT\nBinaryData = False\nElementDataFile = LOCAL\n";
        let p = write(dir.path(), "few.mha", &local(h, b"1 2 3"));
        err_naming(read(&p), "few.mha", "DimSize");
    }

    #[test]
    fn unknown_and_unsupported_fields_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_COMPLEX",
                "ElementType",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_FLOAT_ARRAY",
                "ElementType",
            ),
            ("NDims = 3\nDimSize = 2 2 2", "ElementType"),
            ("DimSize = 2 2 2\nElementType = MET_UCHAR", "NDims"),
            (
                "NDims = 5\nDimSize = 2 2 2 2 2\nElementType = MET_UCHAR",
                "NDims 5",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementNumberOfChannels = 3",
                "ElementNumberOfChannels",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementSpacing = 1 0 1",
                "ElementSpacing",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementSpacing = 1 1",
                "ElementSpacing",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nOffset = a b c",
                "Offset",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nCompressedData = maybe",
                "CompressedData",
            ),
            (
                "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nHeaderSize = -5",
                "HeaderSize",
            ),
            (
                "ObjectType = Mesh\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR",
                "ObjectType",
            ),
        ];
        for (i, (h, field)) in cases.iter().enumerate() {
            let name = format!("f{i}.mha");
            let p = write(
                dir.path(),
                &name,
                &local(&format!("{h}\nElementDataFile = LOCAL\n"), &[0u8; 8]),
            );
            err_naming(read(&p), &name, field);
        }
        let p = write(
            dir.path(),
            "noedf.mhd",
            b"NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n",
        );
        err_naming(read(&p), "noedf.mhd", "ElementDataFile");
        let p = write(dir.path(), "junk.mha", &[0xffu8; 300]);
        err_naming(read(&p), "junk.mha", "header");
    }

    #[test]
    fn missing_data_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let h = "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = gone.raw\n";
        let s = err_naming(
            read(&write(dir.path(), "lost.mhd", h.as_bytes())),
            "lost.mhd",
            "ElementDataFile",
        );
        assert!(s.contains("gone.raw"), "{s}");
        let h = "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = gone_%02d.raw\n";
        let s = err_naming(
            read(&write(dir.path(), "lostpat.mhd", h.as_bytes())),
            "lostpat.mhd",
            "ElementDataFile",
        );
        assert!(s.contains("gone_01.raw"), "{s}");
    }

    #[test]
    fn mutated_files_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let h = "ObjectType = Image\nNDims = 3\nDimSize = 4 2 2\nElementType = MET_USHORT\nElementSpacing = 1 2 3\n\
                 Offset = 1 2 3\nElementByteOrderMSB = True\nCompressedData = True\nCompressedDataSize = 20\nElementDataFile = LOCAL\n";
        let raw: Vec<u8> = (0..16u16).flat_map(|v| v.to_be_bytes()).collect();
        never_panics(read, dir.path(), "m.mha", &local(h, &zlib(&raw)), h.len());
        let h = "NDims = 2\nDimSize = 2 2\nElementType = MET_DOUBLE\nBinaryData = False\nHeaderSize = 0\nElementDataFile = LOCAL\n";
        never_panics(
            read,
            dir.path(),
            "t.mha",
            &local(h, b"1 2\n3 4.5\n"),
            h.len(),
        );
        write(dir.path(), "s1.raw", &[1, 2]);
        write(dir.path(), "s2.raw", &[3, 4]);
        let h = b"NDims = 3\nDimSize = 2 1 2\nElementType = MET_UCHAR\nHeaderSize = -1\nElementDataFile = s%d.raw 1 2 1\n";
        never_panics(read, dir.path(), "p.mhd", h, h.len());
        let h = b"NDims = 3\nDimSize = 2 1 2\nElementType = MET_CHAR\nElementDataFile = LIST 2\ns1.raw\ns2.raw\n";
        never_panics(read, dir.path(), "l.mhd", h, h.len());
    }
}
