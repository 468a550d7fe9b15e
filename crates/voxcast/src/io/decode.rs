//! Decoding shared by the text-header readers (NRRD, MetaImage, VTK):
//! stored element types and their conversion to voxcast's scalar types,
//! bounded line, text and number reading, data-file naming.

use super::util::{file_len, read_exact_or_short, read_payload};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume, VoxelData};
use glam::Vec3;
use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

/// Longest text header accepted: far beyond real ones (a `LIST` of many
/// thousand slice names), small enough that a binary file mistaken for a
/// header cannot make us read much.
pub(crate) const MAX_HEADER_BYTES: u64 = 16 << 20;

/// Longest header line accepted.
pub(crate) const MAX_LINE_BYTES: u64 = 1 << 20;

/// An element type as stored in a file. Types a [`Volume`] cannot hold are
/// converted on reading: see [`StoredType::target`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum StoredType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
    F32,
    F64,
}

impl StoredType {
    /// Bytes per value in the file.
    pub(crate) fn size(self) -> u64 {
        match self {
            StoredType::I8 | StoredType::U8 => 1,
            StoredType::I16 | StoredType::U16 => 2,
            StoredType::I32 | StoredType::U32 | StoredType::F32 => 4,
            StoredType::I64 | StoredType::U64 | StoredType::F64 => 8,
        }
    }

    /// The volume type the values are kept in: i8 widens to i16 (exact); the
    /// 32- and 64-bit types become f32, exact up to 2²⁴ in magnitude.
    pub(crate) fn target(self) -> ScalarType {
        match self {
            StoredType::U8 => ScalarType::U8,
            StoredType::I8 | StoredType::I16 => ScalarType::I16,
            StoredType::U16 => ScalarType::U16,
            _ => ScalarType::F32,
        }
    }

    /// A C-style name for messages.
    pub(crate) fn name(self) -> &'static str {
        match self {
            StoredType::I8 => "int8",
            StoredType::U8 => "uint8",
            StoredType::I16 => "int16",
            StoredType::U16 => "uint16",
            StoredType::I32 => "int32",
            StoredType::U32 => "uint32",
            StoredType::I64 => "int64",
            StoredType::U64 => "uint64",
            StoredType::F32 => "float",
            StoredType::F64 => "double",
        }
    }

    fn is_native(self) -> bool {
        matches!(
            self,
            StoredType::U8 | StoredType::U16 | StoredType::I16 | StoredType::F32
        )
    }

    /// Range of an integer type (as f64), `None` for floats.
    fn int_range(self) -> Option<(f64, f64)> {
        match self {
            StoredType::I8 => Some((i8::MIN as f64, i8::MAX as f64)),
            StoredType::U8 => Some((0.0, u8::MAX as f64)),
            StoredType::I16 => Some((i16::MIN as f64, i16::MAX as f64)),
            StoredType::U16 => Some((0.0, u16::MAX as f64)),
            StoredType::I32 => Some((i32::MIN as f64, i32::MAX as f64)),
            StoredType::U32 => Some((0.0, u32::MAX as f64)),
            StoredType::I64 => Some((i64::MIN as f64, i64::MAX as f64)),
            StoredType::U64 => Some((0.0, u64::MAX as f64)),
            StoredType::F32 | StoredType::F64 => None,
        }
    }
}

/// `count × size` bytes, or an error naming `field`.
pub(crate) fn byte_count(path: &Path, field: &str, count: usize, ty: StoredType) -> Result<u64> {
    (count as u64).checked_mul(ty.size()).ok_or_else(|| {
        Error::format(
            path,
            field,
            format!("{count} values of {} overflow a byte count", ty.name()),
        )
    })
}

/// Decodes whole values of `ty` from `bytes` into the volume type.
pub(crate) fn decode(ty: StoredType, bytes: Vec<u8>, big_endian: bool) -> VoxelData {
    macro_rules! conv {
        ($t:ty, $n:expr) => {
            bytes
                .chunks_exact($n)
                .map(|c| {
                    let mut a = [0u8; $n];
                    a.copy_from_slice(c);
                    let v = if big_endian {
                        <$t>::from_be_bytes(a)
                    } else {
                        <$t>::from_le_bytes(a)
                    };
                    v as f32
                })
                .collect()
        };
    }
    match ty {
        StoredType::U8 => VoxelData::U8(bytes.into()),
        StoredType::I8 => VoxelData::I16(bytes.iter().map(|&b| i16::from(b as i8)).collect()),
        StoredType::I16 | StoredType::U16 | StoredType::F32 => {
            VoxelData::from_bytes(ty.target(), &bytes, big_endian)
        }
        StoredType::I32 => VoxelData::F32(conv!(i32, 4)),
        StoredType::U32 => VoxelData::F32(conv!(u32, 4)),
        StoredType::I64 => VoxelData::F32(conv!(i64, 8)),
        StoredType::U64 => VoxelData::F32(conv!(u64, 8)),
        StoredType::F64 => VoxelData::F32(conv!(f64, 8)),
    }
}

/// Reads `count` values of `ty` at `offset` of `path` (gzip or not) through
/// [`read_payload`], so the sizes are checked before anything is allocated.
pub(crate) fn read_binary(
    path: &Path,
    offset: u64,
    count: usize,
    ty: StoredType,
    big_endian: bool,
    gzip: bool,
    field: &str,
) -> Result<VoxelData> {
    let n_bytes = byte_count(path, field, count, ty)?;
    if ty.is_native() {
        return read_payload(path, offset, n_bytes, ty.target(), big_endian, gzip, field);
    }
    let bytes = read_bytes(path, offset, n_bytes, gzip, field)?;
    Ok(decode(ty, bytes, big_endian))
}

/// `n_bytes` raw bytes through [`read_payload`] (same checks).
pub(crate) fn read_bytes(
    path: &Path,
    offset: u64,
    n_bytes: u64,
    gzip: bool,
    field: &str,
) -> Result<Vec<u8>> {
    match read_payload(path, offset, n_bytes, ScalarType::U8, false, gzip, field)? {
        VoxelData::U8(b) => Ok(b.into_vec()),
        other => Err(Error::format(
            path,
            field,
            format!("internal: bytes decoded as {}", other.scalar_type()),
        )),
    }
}

/// The file from `offset` to its end, as text (invalid UTF-8 replaced, which
/// then fails to parse as a number with a clear message).
pub(crate) fn read_text(path: &Path, offset: u64, field: &str) -> Result<String> {
    let len = file_len(path)?;
    let Some(n) = len.checked_sub(offset) else {
        return Err(Error::format(
            path,
            field,
            format!("data should start at byte {offset} but the file has only {len} bytes"),
        ));
    };
    let mut f = crate::files::open(path)?.0;
    f.seek(SeekFrom::Start(offset))
        .map_err(|e| Error::io(path, e))?;
    let bytes = read_exact_or_short(f, n, path, field)?;
    Ok(String::from_utf8(bytes)
        .unwrap_or_else(|e| String::from_utf8_lossy(e.as_bytes()).into_owned()))
}

/// Whitespace- or comma-separated tokens of a text, with the byte position
/// reached (so a caller can go on after the values).
pub(crate) struct Tokens<'a> {
    text: &'a str,
    pub(crate) pos: usize,
}

impl<'a> Tokens<'a> {
    pub(crate) fn at(text: &'a str, pos: usize) -> Self {
        Tokens { text, pos }
    }

    fn is_sep(c: u8) -> bool {
        c.is_ascii_whitespace() || c == b','
    }
}

impl<'a> Iterator for Tokens<'a> {
    type Item = &'a str;

    fn next(&mut self) -> Option<&'a str> {
        let b = self.text.as_bytes();
        while b.get(self.pos).is_some_and(|&c| Self::is_sep(c)) {
            self.pos += 1;
        }
        let start = self.pos;
        while b.get(self.pos).is_some_and(|&c| !Self::is_sep(c)) {
            self.pos += 1;
        }
        // Both ends sit next to ASCII separators or at the ends, so on char boundaries.
        self.text.get(start..self.pos).filter(|t| !t.is_empty())
    }
}

/// Parses `count` numbers of type `ty` from `text` into the volume type.
/// Returns the values and the byte position after the last one. Too few
/// values is an error naming `field`; a value that is not a number of `ty`
/// (a fraction for an integer type, out of range) names `data`.
pub(crate) fn parse_ascii(
    path: &Path,
    field: &str,
    text: &str,
    count: usize,
    ty: StoredType,
) -> Result<(VoxelData, usize)> {
    // Every value takes at least two bytes but the last: this bounds the
    // allocation by the text, whatever the header claims.
    let cap = count.min(text.len() / 2 + 1);
    let mut toks = Tokens::at(text, 0);
    let mut next = |i: usize| -> Result<f64> {
        let Some(tok) = toks.next() else {
            return Err(Error::format(
                path,
                field,
                format!("the data end after {i} values but the header describes {count}"),
            ));
        };
        ascii_value(tok, ty).ok_or_else(|| {
            Error::format(
                path,
                "data",
                format!("value {i}: `{}` is not a valid {}", shorten(tok), ty.name()),
            )
        })
    };
    macro_rules! collect {
        ($var:ident, $t:ty) => {{
            let mut v: Vec<$t> = Vec::with_capacity(cap);
            for i in 0..count {
                v.push(next(i)? as $t);
            }
            VoxelData::$var(v.into())
        }};
    }
    let data = match ty.target() {
        ScalarType::U8 => collect!(U8, u8),
        ScalarType::U16 => collect!(U16, u16),
        ScalarType::I16 => collect!(I16, i16),
        ScalarType::F32 => collect!(F32, f32),
    };
    Ok((data, toks.pos))
}

/// One text value, checked against `ty` (integers must be whole and in range).
fn ascii_value(tok: &str, ty: StoredType) -> Option<f64> {
    match ty.int_range() {
        None if ty == StoredType::F32 => tok.parse::<f32>().ok().map(f64::from),
        None => tok.parse::<f64>().ok(),
        Some((lo, hi)) => {
            let x = match tok.parse::<i64>() {
                Ok(i) => i as f64,
                Err(_) => tok.parse::<f64>().ok().filter(|f| f.fract() == 0.0)?,
            };
            (lo..=hi).contains(&x).then_some(x)
        }
    }
}

/// Joins the parts of a volume read from several files.
pub(crate) fn concat(parts: Vec<VoxelData>) -> Option<VoxelData> {
    let mut it = parts.into_iter();
    let mut all = it.next()?;
    for part in it {
        match (&mut all, part) {
            (VoxelData::U8(a), VoxelData::U8(b)) => a.make_mut().extend(b.iter()),
            (VoxelData::U16(a), VoxelData::U16(b)) => a.make_mut().extend(b.iter()),
            (VoxelData::I16(a), VoxelData::I16(b)) => a.make_mut().extend(b.iter()),
            (VoxelData::F32(a), VoxelData::F32(b)) => a.make_mut().extend(b.iter()),
            _ => return None,
        }
    }
    Some(all)
}

/// Reads a text header line by line, keeping the byte position so the data
/// after it can be found.
pub(crate) struct LineReader {
    path: PathBuf,
    reader: BufReader<File>,
    pos: u64,
}

impl LineReader {
    pub(crate) fn open(path: &Path) -> Result<Self> {
        let f = crate::files::open(path)?.0;
        Ok(LineReader {
            path: path.to_path_buf(),
            reader: BufReader::new(f),
            pos: 0,
        })
    }

    /// Byte position of the next line.
    pub(crate) fn pos(&self) -> u64 {
        self.pos
    }

    pub(crate) fn seek(&mut self, pos: u64) -> Result<()> {
        self.reader
            .seek(SeekFrom::Start(pos))
            .map_err(|e| Error::io(&self.path, e))?;
        self.pos = pos;
        Ok(())
    }

    /// The next line without its `\n` or `\r\n`, `None` at the end of the
    /// file. A line longer than [`MAX_LINE_BYTES`] is an error naming `field`
    /// (binary data where a header was expected).
    pub(crate) fn next_line(&mut self, field: &str) -> Result<Option<String>> {
        let mut buf = Vec::new();
        let n = (&mut self.reader)
            .take(MAX_LINE_BYTES + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| Error::io(&self.path, e))?;
        if n == 0 {
            return Ok(None);
        }
        if buf.len() as u64 > MAX_LINE_BYTES {
            return Err(Error::format(
                &self.path,
                field,
                format!(
                    "a header line at byte {} is longer than {MAX_LINE_BYTES} bytes",
                    self.pos
                ),
            ));
        }
        self.pos += n as u64;
        if buf.last() == Some(&b'\n') {
            buf.pop();
        }
        if buf.last() == Some(&b'\r') {
            buf.pop();
        }
        Ok(Some(String::from_utf8_lossy(&buf).into_owned()))
    }
}

/// Errors once a header has grown beyond [`MAX_HEADER_BYTES`].
pub(crate) fn check_header_size(path: &Path, lines: &LineReader) -> Result<()> {
    if lines.pos() > MAX_HEADER_BYTES {
        return Err(Error::format(
            path,
            "header",
            format!("no end of the header in the first {MAX_HEADER_BYTES} bytes"),
        ));
    }
    Ok(())
}

/// The byte position after `n` more newlines from `start`, read in blocks
/// (a data file may have no newline at all: nothing is kept in memory).
pub(crate) fn skip_lines(path: &Path, start: u64, n: u64, field: &str) -> Result<u64> {
    let mut f = crate::files::open(path)?.0;
    f.seek(SeekFrom::Start(start))
        .map_err(|e| Error::io(path, e))?;
    let mut r = BufReader::new(f);
    let mut pos = start;
    let mut left = n;
    while left > 0 {
        let buf = r.fill_buf().map_err(|e| Error::io(path, e))?;
        if buf.is_empty() {
            return Err(Error::format(
                path,
                field,
                format!(
                    "{n} lines to skip after byte {start}, the file has only {}",
                    n - left
                ),
            ));
        }
        let mut used = buf.len();
        for (i, &c) in buf.iter().enumerate() {
            if c == b'\n' {
                left -= 1;
                if left == 0 {
                    used = i + 1;
                    break;
                }
            }
        }
        pos += used as u64;
        r.consume(used);
    }
    Ok(pos)
}

/// Parses whitespace- or comma-separated sizes: positive whole numbers
/// (zero is left to [`check_dims`], which names the field too).
pub(crate) fn parse_sizes(path: &Path, field: &str, s: &str) -> Result<Vec<u64>> {
    let out: Vec<u64> = Tokens::at(s, 0)
        .map(|t| {
            t.parse::<u64>().map_err(|_| {
                let digits = |d: &str| !d.is_empty() && d.bytes().all(|c| c.is_ascii_digit());
                let why = if t.strip_prefix('-').is_some_and(digits) {
                    "is negative"
                } else if digits(t.trim_start_matches('+')) {
                    "is too large"
                } else {
                    "is not a whole number"
                };
                Error::format(
                    path,
                    field,
                    format!("`{}` {why} (in `{}`)", shorten(t), shorten(s)),
                )
            })
        })
        .collect::<Result<_>>()?;
    if out.is_empty() {
        return Err(Error::format(path, field, "no sizes given"));
    }
    Ok(out)
}

/// Parses whitespace- or comma-separated numbers (`nan` and `inf` included:
/// callers decide).
pub(crate) fn parse_floats(path: &Path, field: &str, s: &str) -> Result<Vec<f64>> {
    Tokens::at(s, 0)
        .map(|t| {
            t.parse::<f64>().map_err(|_| {
                Error::format(
                    path,
                    field,
                    format!("`{}` is not a number (in `{}`)", shorten(t), shorten(s)),
                )
            })
        })
        .collect()
}

/// Spacing from a header: magnitudes (a negative spacing flips an axis,
/// which is not applied), each positive and finite in f32.
pub(crate) fn check_spacing(path: &Path, field: &str, s: [f64; 3]) -> Result<Vec3> {
    let v = Vec3::new(s[0].abs() as f32, s[1].abs() as f32, s[2].abs() as f32);
    if !(v.is_finite() && v.min_element() > 0.0) {
        return Err(Error::format(
            path,
            field,
            format!(
                "spacing {} {} {}: each must be a non-zero finite number",
                s[0], s[1], s[2]
            ),
        ));
    }
    Ok(v)
}

/// Origin from a header, finite in f32.
pub(crate) fn check_origin(path: &Path, field: &str, o: [f64; 3]) -> Result<Vec3> {
    let v = Vec3::new(o[0] as f32, o[1] as f32, o[2] as f32);
    if !v.is_finite() {
        return Err(Error::format(
            path,
            field,
            format!("origin {} {} {} is not finite", o[0], o[1], o[2]),
        ));
    }
    Ok(v)
}

/// Builds the volume; dims, spacing and origin were checked before.
pub(crate) fn make_volume(
    path: &Path,
    dims: [u64; 3],
    spacing: Vec3,
    origin: Vec3,
    data: VoxelData,
) -> Result<Volume> {
    let mut d = [0usize; 3];
    for (o, &i) in d.iter_mut().zip(&dims) {
        *o = usize::try_from(i)
            .map_err(|_| Error::format(path, "dims", format!("{i} does not fit in memory")))?;
    }
    Volume::new(d, spacing, origin, data).map_err(|e| Error::format(path, "data", e.to_string()))
}

/// Voxels per file when `count` voxels are split over `n_files` files, each
/// holding the first `subdim` axes of `sizes` when given, else an equal share.
pub(crate) fn per_file_count(
    path: &Path,
    field: &str,
    sizes: &[u64],
    count: usize,
    n_files: u64,
    subdim: Option<usize>,
) -> Result<usize> {
    let total = count as u64;
    if n_files == 0 || n_files > total {
        return Err(Error::format(
            path,
            field,
            format!("{n_files} data files for {total} voxels"),
        ));
    }
    let per = match subdim {
        Some(sd) if (1..=sizes.len()).contains(&sd) => {
            let per = sizes
                .iter()
                .take(sd)
                .try_fold(1u64, |a, &b| a.checked_mul(b))
                .unwrap_or(u64::MAX);
            if per.checked_mul(n_files) != Some(total) {
                return Err(Error::format(
                    path,
                    field,
                    format!("{n_files} files of {per} voxels (subdim {sd}) do not make the {total} voxels of the sizes"),
                ));
            }
            per
        }
        Some(sd) => {
            return Err(Error::format(
                path,
                field,
                format!("subdim {sd}: expected 1 to {}", sizes.len()),
            ))
        }
        None => {
            if !total.is_multiple_of(n_files) {
                return Err(Error::format(
                    path,
                    field,
                    format!("{total} voxels cannot be split evenly over {n_files} data files"),
                ));
            }
            total / n_files
        }
    };
    usize::try_from(per).map_err(|_| Error::format(path, field, "too many voxels per file"))
}

/// A data-file name pattern: `fmt` with one `%d`-style conversion, indices
/// `min, min + step, …` (`count` of them).
pub(crate) struct Pattern {
    pub(crate) fmt: String,
    pub(crate) min: i64,
    pub(crate) step: i64,
    pub(crate) count: u64,
    pub(crate) subdim: Option<usize>,
}

impl Pattern {
    /// The name of file `i` (not checked against `count`).
    pub(crate) fn name(&self, header: &Path, field: &str, i: u64) -> Result<String> {
        let index = i64::try_from(i)
            .ok()
            .and_then(|i| i.checked_mul(self.step))
            .and_then(|o| o.checked_add(self.min))
            .ok_or_else(|| Error::format(header, field, "file index overflows"))?;
        format_index(&self.fmt, index).ok_or_else(|| {
            Error::unsupported(
                header,
                format!(
                    "{field} pattern `{}`: only one %d, %i or %u conversion (with an optional 0 flag and width) is understood",
                    self.fmt
                ),
            )
        })
    }
}

/// printf of one `%[0][width]d|i|u` conversion (and `%%`), `None` for anything else.
pub(crate) fn format_index(fmt: &str, i: i64) -> Option<String> {
    let mut out = String::with_capacity(fmt.len() + 8);
    let mut chars = fmt.chars().peekable();
    let mut done = false;
    while let Some(c) = chars.next() {
        if c != '%' {
            out.push(c);
            continue;
        }
        if chars.peek() == Some(&'%') {
            chars.next();
            out.push('%');
            continue;
        }
        if done {
            return None;
        }
        let zero = chars.next_if_eq(&'0').is_some();
        let mut width = 0usize;
        while let Some(d) = chars.peek().and_then(|c| c.to_digit(10)) {
            width = width.checked_mul(10)?.checked_add(d as usize)?;
            chars.next();
        }
        if width > 64 || !matches!(chars.next(), Some('d' | 'i' | 'u')) {
            return None;
        }
        if zero {
            out.push_str(&format!("{i:0width$}"));
        } else {
            out.push_str(&format!("{i:width$}"));
        }
        done = true;
    }
    done.then_some(out)
}

/// A data-file name from a header, taken relative to the header's folder.
pub(crate) fn resolve_data_path(header: &Path, name: &str) -> PathBuf {
    let p = Path::new(name);
    if p.is_absolute() {
        p.to_path_buf()
    } else {
        header.parent().unwrap_or(Path::new("")).join(p)
    }
}

/// Rewrites an error about a detached data file so that it names the header
/// the user opened (and, in the message, the data file): `file_field` is the
/// header field that names data files.
pub(crate) fn in_data_file(header: &Path, file_field: &str, e: Error) -> Error {
    match e {
        Error::Format {
            path,
            field,
            message,
        } if path != header => Error::format(
            header,
            field,
            format!("in data file {}: {message}", path.display()),
        ),
        Error::Io { path, source } if path != header => Error::format(
            header,
            file_field,
            format!("cannot read data file {}: {source}", path.display()),
        ),
        Error::Unsupported { path, message } if path != header => Error::unsupported(
            header,
            format!("in data file {}: {message}", path.display()),
        ),
        other => other,
    }
}

/// At most 80 characters of `s`, for messages.
pub(crate) fn shorten(s: &str) -> String {
    if s.chars().count() <= 80 {
        s.to_string()
    } else {
        let mut t: String = s.chars().take(77).collect();
        t.push('…');
        t
    }
}

pub(crate) fn join(v: &[u64]) -> String {
    v.iter().map(u64::to_string).collect::<Vec<_>>().join(" ")
}
