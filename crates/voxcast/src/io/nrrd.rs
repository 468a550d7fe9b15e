//! NRRD ("nearly raw raster data", teem's format): `.nrrd` files with the
//! data attached after the blank line that ends the header, and `.nhdr`
//! detached headers that name their data file(s).
//!
//! Supported:
//! * magic `NRRD0001`…`NRRD0005`, `# comments`, `key:=value` pairs (ignored);
//! * `type:` every NRRD spelling of the eight integer and two float types.
//!   u8, u16, i16 and f32 are kept as stored; signed 8-bit becomes i16
//!   (exact); int32, uint32, int64, uint64 and double become f32, which is
//!   exact only up to 2²⁴ in magnitude (doubles beyond f32's range become ±inf);
//! * `dimension:` 3; 2 (one slice, z = 1); an axis of size 1 whose
//!   `space directions:` entry is `none` or whose `kinds:` entry is not a
//!   space kind is dropped wherever it is; without such marks a 4-D array
//!   drops its first or last axis of size 1;
//! * `sizes:`; spacing from `space directions:` (the length of each axis
//!   vector; `none` for a non-spatial axis), else from `spacings:` (`nan`
//!   on a space axis means 1, with a warning; negative or infinite is an
//!   error); `space origin:` → origin (z = 0 in a 2-D space);
//!   `sample units:` → [`Volume::units`];
//! * `encoding:` `raw`, `gzip`/`gz`, `bzip2`/`bz2`, `ascii`/`text`/`txt`; `endian:`
//!   `little`/`big` (little when absent);
//! * `line skip:` and `byte skip:` as teem applies them: lines are skipped in
//!   the file, bytes after decompression for gzip; with raw, a negative byte
//!   skip −(N+1) puts the data N bytes before the end of the file (−1: at the end);
//! * `data file:`/`datafile:` naming one file (relative to the header's
//!   folder), `LIST [subdim]` with the names on the header lines that follow,
//!   or a pattern `fmt min max step [subdim]` with one `%d`-style conversion.
//!
//! Not supported (an error naming the field): `type: block`; the `hex` and
//! encoding; other dimensions and multi-component axes; a negative
//! byte skip with gzip or ascii. Orientation is reduced to one spacing per
//! axis: rotations and axis flips in `space directions:` are not applied, the
//! volume is placed axis-aligned at `space origin:`. Raw bytes after the
//! data are ignored with a warning; gzip data longer than the header says is
//! an error (a wrong header or another format's file, e.g. a `.nii.gz`).
//!
//! Element types, bounded reading and number parsing live in
//! [`super::decode`], shared with the MetaImage and VTK readers.

use super::decode::*;
use super::util::{check_dims, file_len, read_bzip2_and_count_rest, read_gzip_and_count_rest};
use crate::error::{Error, Result};
use crate::volume::{Volume, VoxelData};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// Reads the NRRD file (attached or detached header) at `path`.
pub fn read(path: &Path) -> Result<Volume> {
    let header = read_header(path)?;
    let required = |key: &'static str| required_field(path, &header, key);

    let dim_s = required("dimension")?;
    let dimension: usize = dim_s.parse().map_err(|_| {
        Error::format(
            path,
            "dimension",
            format!("`{dim_s}` is not a whole number"),
        )
    })?;
    let ty = parse_type(path, required("type")?)?;
    let sizes = parse_sizes(path, "sizes", required("sizes")?)?;
    if sizes.len() != dimension {
        return Err(Error::format(
            path,
            "sizes",
            format!("{} sizes given for dimension {dimension}", sizes.len()),
        ));
    }
    let spatial = spatial_axes(
        path,
        dimension,
        &sizes,
        header.get("space directions"),
        header.get("kinds"),
    )?;
    let axis_size = |axis: Option<&usize>| axis.and_then(|&a| sizes.get(a)).copied().unwrap_or(1);
    let dims = [
        axis_size(spatial.first()),
        axis_size(spatial.get(1)),
        axis_size(spatial.get(2)),
    ];
    let (count, _) = check_dims(path, "sizes", dims, ty.target())?;

    let encoding = parse_encoding(path, required("encoding")?)?;
    let big_endian = match header.get("endian").map(str::to_ascii_lowercase).as_deref() {
        None | Some("little") => false,
        Some("big") => true,
        Some(other) => {
            return Err(Error::format(
                path,
                "endian",
                format!("`{other}`: expected `little` or `big`"),
            ))
        }
    };
    let line_skip: u64 = match header.get("line skip") {
        None => 0,
        Some(s) => s.parse().map_err(|_| {
            Error::format(
                path,
                "line skip",
                format!("`{s}` is not a whole number of lines"),
            )
        })?,
    };
    let byte_skip: i64 = match header.get("byte skip") {
        None => 0,
        Some(s) => s.parse().map_err(|_| {
            Error::format(path, "byte skip", format!("`{s}` is not a whole number"))
        })?,
    };
    if byte_skip < 0 && encoding != Encoding::Raw {
        return Err(Error::unsupported(
            path,
            format!("byte skip {byte_skip} with a non-raw encoding (the data's end cannot be found without decoding everything)"),
        ));
    }

    let spacing = nrrd_spacing(
        path,
        header.get("space directions"),
        header.get("spacings"),
        dimension,
        &spatial,
    )?;
    let origin = match header.get("space origin") {
        None => Vec3::ZERO,
        Some(s) => nrrd_origin(path, s)?,
    };

    let files = data_files(path, &header)?;
    let n_files = files.len();
    let per_file = per_file_count(path, "data file", &sizes, count, n_files, files.subdim())?;
    let layout = Layout {
        ty,
        big_endian,
        encoding,
        line_skip,
        byte_skip,
    };
    let mut parts = Vec::new();
    for i in 0..n_files {
        let part = match &files {
            DataFiles::Attached => read_chunk(path, header.data_start, per_file, &layout),
            _ => {
                let file = files.path(path, i)?;
                read_chunk(&file, 0, per_file, &layout)
                    .map_err(|e| in_data_file(path, "data file", e))
            }
        }?;
        parts.push(part);
    }
    let data = concat(parts).ok_or_else(|| {
        Error::format(
            path,
            "data file",
            "the data files decoded to different types",
        )
    })?;
    let mut vol = make_volume(path, dims, spacing, origin, data)?;
    vol.units = header
        .get("sample units")
        .map(|s| s.trim_matches('"').trim().to_string())
        .filter(|s| !s.is_empty());
    Ok(vol)
}

/// The fields of a NRRD header and where its attached data would start.
struct Header {
    fields: Vec<(String, String)>,
    /// File names listed after `data file: LIST`.
    list: Option<Vec<String>>,
    /// Byte just after the blank line that ends the header.
    data_start: u64,
}

impl Header {
    fn get(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

fn required_field<'h>(path: &Path, header: &'h Header, key: &'static str) -> Result<&'h str> {
    header
        .get(key)
        .ok_or_else(|| Error::format(path, key, "missing: a NRRD header needs this field"))
}

fn read_header(path: &Path) -> Result<Header> {
    let mut lines = LineReader::open(path)?;
    let magic = lines.next_line("magic")?.unwrap_or_default();
    let version_ok = magic
        .strip_prefix("NRRD000")
        .is_some_and(|v| matches!(v.trim_end(), "1" | "2" | "3" | "4" | "5"));
    if !version_ok {
        return Err(Error::format(
            path,
            "magic",
            format!(
                "expected `NRRD0001` … `NRRD0005` on the first line, found `{}`",
                shorten(&magic)
            ),
        ));
    }
    let mut fields: Vec<(String, String)> = Vec::new();
    let mut list: Option<Vec<String>> = None;
    while let Some(line) = lines.next_line("header")? {
        check_header_size(path, &lines)?;
        if line.trim().is_empty() {
            break;
        }
        if let Some(names) = list.as_mut() {
            names.push(line.trim().to_string());
            continue;
        }
        if line.starts_with('#') {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(Error::format(
                path,
                "header",
                format!(
                    "line `{}` is neither `field: value` nor a comment",
                    shorten(&line)
                ),
            ));
        };
        if value.starts_with('=') {
            // `key:=value` pairs carry free-form metadata.
            continue;
        }
        // teem accepts the old spellings without a space.
        let key = match key.trim() {
            "datafile" => "data file",
            "lineskip" => "line skip",
            "byteskip" => "byte skip",
            "sampleunits" => "sample units",
            k => k,
        }
        .to_string();
        let value = value.trim().to_string();
        if fields.iter().any(|(k, _)| *k == key) {
            return Err(Error::format(path, key, "given twice"));
        }
        if key == "data file" && (value == "LIST" || value.starts_with("LIST ")) {
            list = Some(Vec::new());
        }
        fields.push((key, value));
    }
    Ok(Header {
        fields,
        list,
        data_start: lines.pos(),
    })
}

fn parse_type(path: &Path, s: &str) -> Result<StoredType> {
    // teem reads these names without regard to case or repeated spaces.
    let norm = s
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .to_ascii_lowercase();
    Ok(match norm.as_str() {
        "signed char" | "int8" | "int8_t" => StoredType::I8,
        "uchar" | "unsigned char" | "uint8" | "uint8_t" => StoredType::U8,
        "short" | "short int" | "signed short" | "signed short int" | "int16" | "int16_t" => {
            StoredType::I16
        }
        "ushort" | "unsigned short" | "unsigned short int" | "uint16" | "uint16_t" => {
            StoredType::U16
        }
        "int" | "signed int" | "int32" | "int32_t" => StoredType::I32,
        "uint" | "unsigned int" | "uint32" | "uint32_t" => StoredType::U32,
        "longlong"
        | "long long"
        | "long long int"
        | "signed long long"
        | "signed long long int"
        | "int64"
        | "int64_t" => StoredType::I64,
        "ulonglong" | "unsigned long long" | "unsigned long long int" | "uint64" | "uint64_t" => {
            StoredType::U64
        }
        "float" => StoredType::F32,
        "double" => StoredType::F64,
        "block" => {
            return Err(Error::unsupported(
                path,
                "type `block` (opaque blocks are not voxels)",
            ));
        }
        _ => {
            return Err(Error::format(
                path,
                "type",
                format!(
                    "unknown type `{s}` (expected e.g. uchar, short, ushort, int, float, double)"
                ),
            ))
        }
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Raw,
    Gzip,
    Bzip2,
    Ascii,
}

fn parse_encoding(path: &Path, s: &str) -> Result<Encoding> {
    match s.to_ascii_lowercase().as_str() {
        "raw" => Ok(Encoding::Raw),
        "gzip" | "gz" => Ok(Encoding::Gzip),
        "bzip2" | "bz2" => Ok(Encoding::Bzip2),
        "ascii" | "text" | "txt" => Ok(Encoding::Ascii),
        _ => Err(Error::unsupported(
            path,
            format!("encoding `{s}` (supported: raw, gzip, bzip2, ascii)"),
        )),
    }
}

/// The axes (indices into `sizes:`) that become x, y and z.
/// The axes read as x, y, z. An axis whose `space directions:` entry is
/// `none`, or whose `kinds:` entry is not a space kind, is not spatial (and
/// must have size 1), wherever it is; without such marks a first or last
/// axis of size 1 is dropped from a 4-D array.
fn spatial_axes(
    path: &Path,
    dimension: usize,
    sizes: &[u64],
    directions: Option<&str>,
    kinds: Option<&str>,
) -> Result<Vec<usize>> {
    let mut non_spatial = vec![false; dimension];
    if let Some(d) = directions {
        let v = parse_vectors(path, "space directions", d)?;
        if v.len() == dimension {
            for (n, e) in non_spatial.iter_mut().zip(&v) {
                *n |= e.is_none();
            }
        }
    }
    if let Some(k) = kinds {
        let k: Vec<String> = k
            .split_whitespace()
            .map(|w| w.to_ascii_lowercase())
            .collect();
        if k.len() == dimension {
            for (n, w) in non_spatial.iter_mut().zip(&k) {
                // teem's spatial kinds; `???`/`none` say nothing.
                let spatial = matches!(w.as_str(), "domain" | "space" | "???" | "none");
                *n |= !spatial;
            }
        }
    }
    if non_spatial.iter().any(|&n| n) {
        for (a, &n) in non_spatial.iter().enumerate() {
            if n && sizes.get(a) != Some(&1) {
                return Err(Error::unsupported(
                    path,
                    format!(
                        "axis {a} (size {}) is not a space axis (`none` direction or a non-space kind): only one-component non-space axes can be dropped",
                        sizes.get(a).copied().unwrap_or(0)
                    ),
                ));
            }
        }
        let axes: Vec<usize> = (0..dimension).filter(|&a| !non_spatial[a]).collect();
        if (2..=3).contains(&axes.len()) {
            return Ok(axes);
        }
    }
    match dimension {
        2 => Ok(vec![0, 1]),
        3 => Ok(vec![0, 1, 2]),
        4 if sizes.first() == Some(&1) => Ok(vec![1, 2, 3]),
        4 if sizes.get(3) == Some(&1) => Ok(vec![0, 1, 2]),
        4 => Err(Error::unsupported(
            path,
            format!(
                "dimension 4 with sizes {}: only a first or last axis of size 1 can be dropped",
                join(sizes)
            ),
        )),
        _ => Err(Error::unsupported(
            path,
            format!("dimension {dimension} (only 2, 3, or 4 with a first or last axis of size 1)"),
        )),
    }
}

/// Spacing of the spatial axes, from `space directions:` or `spacings:`.
fn nrrd_spacing(
    path: &Path,
    directions: Option<&str>,
    spacings: Option<&str>,
    dimension: usize,
    spatial: &[usize],
) -> Result<Vec3> {
    let mut sp = [1.0f64; 3];
    if let Some(s) = directions {
        let field = "space directions";
        let vecs = parse_vectors(path, field, s)?;
        if vecs.len() != dimension {
            return Err(Error::format(
                path,
                field,
                format!("{} entries for dimension {dimension}", vecs.len()),
            ));
        }
        for (out, axis) in sp.iter_mut().zip(spatial) {
            if let Some(Some(v)) = vecs.get(*axis) {
                *out = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            }
        }
        check_spacing(path, field, sp)
    } else if let Some(s) = spacings {
        let field = "spacings";
        let vals = parse_floats(path, field, s)?;
        if vals.len() != dimension {
            return Err(Error::format(
                path,
                field,
                format!("{} spacings for dimension {dimension}", vals.len()),
            ));
        }
        for (out, axis) in sp.iter_mut().zip(spatial) {
            match vals.get(*axis) {
                Some(v) if v.is_nan() => eprintln!(
                    "warning: {}: field `spacings`: nan for axis {axis}: spacing 1 used",
                    path.display()
                ),
                Some(v) if !(*v > 0.0 && v.is_finite()) => {
                    return Err(Error::format(
                        path,
                        field,
                        format!("{v} for axis {axis}: a spacing must be a positive finite number"),
                    ))
                }
                Some(v) => *out = *v,
                None => {}
            }
        }
        check_spacing(path, field, sp)
    } else {
        Ok(Vec3::ONE)
    }
}

fn nrrd_origin(path: &Path, s: &str) -> Result<Vec3> {
    let field = "space origin";
    match parse_vectors(path, field, s)?.as_slice() {
        [Some(v)] if v.len() == 2 || v.len() == 3 => {
            check_origin(path, field, [v[0], v[1], v.get(2).copied().unwrap_or(0.0)])
        }
        _ => Err(Error::format(
            path,
            field,
            format!("`{s}`: expected one vector `(x,y,z)`"),
        )),
    }
}

/// Parses `(x,y,z) none (x,y,z)…` (spaces inside the brackets allowed).
fn parse_vectors(path: &Path, field: &str, s: &str) -> Result<Vec<Option<Vec<f64>>>> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix('(') {
            let Some((inner, after)) = r.split_once(')') else {
                return Err(Error::format(path, field, format!("`{s}`: unclosed `(`")));
            };
            out.push(Some(parse_floats(path, field, inner)?));
            rest = after.trim_start();
        } else if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
        } else {
            return Err(Error::format(
                path,
                field,
                format!("`{}`: expected `(x,y,z)` or `none`", shorten(rest)),
            ));
        }
    }
    Ok(out)
}

/// Where the data lives.
enum DataFiles {
    /// In the header's own file, after the blank line.
    Attached,
    Single(String),
    List {
        names: Vec<String>,
        subdim: Option<usize>,
    },
    Pattern(Pattern),
}

impl DataFiles {
    fn len(&self) -> u64 {
        match self {
            DataFiles::Attached | DataFiles::Single(_) => 1,
            DataFiles::List { names, .. } => names.len() as u64,
            DataFiles::Pattern(p) => p.count,
        }
    }

    fn subdim(&self) -> Option<usize> {
        match self {
            DataFiles::List { subdim, .. } => *subdim,
            DataFiles::Pattern(p) => p.subdim,
            _ => None,
        }
    }

    /// The path of data file `i`, relative names taken from the header's folder.
    fn path(&self, header: &Path, i: u64) -> Result<PathBuf> {
        let name = match self {
            DataFiles::Attached => return Ok(header.to_path_buf()),
            DataFiles::Single(name) => name.clone(),
            DataFiles::List { names, .. } => usize::try_from(i)
                .ok()
                .and_then(|i| names.get(i))
                .cloned()
                .ok_or_else(|| {
                    Error::format(header, "data file", format!("no file {i} in the list"))
                })?,
            DataFiles::Pattern(p) => p.name(header, "data file", i)?,
        };
        Ok(resolve_data_path(header, &name))
    }
}

fn data_files(path: &Path, header: &Header) -> Result<DataFiles> {
    let field = "data file";
    let Some(value) = header.get(field) else {
        return Ok(DataFiles::Attached);
    };
    let words: Vec<&str> = value.split_whitespace().collect();
    let parse_subdim = |w: Option<&&str>| -> Result<Option<usize>> {
        w.map(|s| {
            s.parse::<usize>().map_err(|_| {
                Error::format(path, field, format!("subdim `{s}` is not a whole number"))
            })
        })
        .transpose()
    };
    if let Some(names) = &header.list {
        if names.is_empty() {
            return Err(Error::format(
                path,
                field,
                "LIST is followed by no file names",
            ));
        }
        return Ok(DataFiles::List {
            names: names.clone(),
            subdim: parse_subdim(words.get(1))?,
        });
    }
    let ints: Vec<Option<i64>> = words
        .iter()
        .skip(1)
        .take(3)
        .map(|w| w.parse().ok())
        .collect();
    let fmt = words.first().filter(|w| w.contains('%'));
    if let (Some(fmt), [Some(min), Some(max), Some(step)]) = (fmt, ints.as_slice()) {
        let (min, max, step) = (*min, *max, *step);
        let count = pattern_count(min, max, step).ok_or_else(|| {
            Error::format(
                path,
                field,
                format!("`{value}`: min {min}, max {max} and step {step} give no files"),
            )
        })?;
        let fmt = fmt.to_string();
        return Ok(DataFiles::Pattern(Pattern {
            fmt,
            min,
            step,
            count,
            subdim: parse_subdim(words.get(4))?,
        }));
    }
    Ok(DataFiles::Single(value.to_string()))
}

/// Number of indices in `min, min+step, … max`, or `None` when they go nowhere.
fn pattern_count(min: i64, max: i64, step: i64) -> Option<u64> {
    if step == 0 {
        return None;
    }
    let span = max.checked_sub(min)?;
    if span != 0 && (span < 0) != (step < 0) {
        return None;
    }
    u64::try_from(span.checked_div(step)?).ok()?.checked_add(1)
}

/// How the bytes of every data file are laid out.
struct Layout {
    ty: StoredType,
    big_endian: bool,
    encoding: Encoding,
    line_skip: u64,
    byte_skip: i64,
}

/// Reads `count` voxels from `file`, whose data (before skips) start at `start`.
fn read_chunk(file: &Path, start: u64, count: usize, l: &Layout) -> Result<VoxelData> {
    let field = "sizes";
    let n_bytes = byte_count(file, field, count, l.ty)?;
    let mut offset = start;
    if l.line_skip > 0 {
        offset = skip_lines(file, offset, l.line_skip, "line skip")?;
    }
    let skip = u64::try_from(l.byte_skip).ok();
    match (l.encoding, skip) {
        (Encoding::Raw, Some(skip)) => {
            let offset = offset
                .checked_add(skip)
                .ok_or_else(|| Error::format(file, "byte skip", "offset overflows"))?;
            let len = file_len(file)?;
            let extra = len.saturating_sub(offset.saturating_add(n_bytes));
            if extra > 0 && len >= offset.saturating_add(n_bytes) {
                eprintln!(
                    "warning: {}: field `sizes`: the file holds {extra} byte(s) after the {n_bytes} bytes the sizes and type describe; they are ignored (check the header, or say `byte skip: -1` if the data is at the end)",
                    file.display()
                );
            }
            read_binary(file, offset, count, l.ty, l.big_endian, false, field)
        }
        (Encoding::Raw, None) => {
            // teem: byte skip −(N+1) = the data end N bytes before the end of the file.
            let back = l.byte_skip.unsigned_abs() - 1;
            let len = file_len(file)?;
            let offset = len
                .checked_sub(back)
                .and_then(|end| end.checked_sub(n_bytes))
                .filter(|&o| o >= offset)
                .ok_or_else(|| {
                    Error::format(
                        file,
                        "byte skip",
                        format!(
                            "byte skip {}: {n_bytes} bytes of data ending {back} byte(s) before the end of the file ({len} bytes) would start before byte {offset}, where the data may begin (wrong sizes/type, or not the right data file)",
                            l.byte_skip
                        ),
                    )
                })?;
            read_binary(file, offset, count, l.ty, l.big_endian, false, field)
        }
        (Encoding::Gzip | Encoding::Bzip2, Some(skip)) => {
            // The byte skip of a compressed encoding counts decompressed bytes.
            let total = n_bytes
                .checked_add(skip)
                .ok_or_else(|| Error::format(file, "byte skip", "size overflows"))?;
            let (mut bytes, rest) = if l.encoding == Encoding::Gzip {
                read_gzip_and_count_rest(file, offset, total, field)?
            } else {
                read_bzip2_and_count_rest(file, offset, total, field)?
            };
            if rest > 0 {
                let more = if rest >= 1 << 20 { "at least " } else { "" };
                return Err(Error::format(
                    file,
                    field,
                    format!(
                        "the compressed data holds {more}{rest} byte(s) more than the {total} that byte skip, sizes and type describe (a wrong header, or a data file of another format, e.g. a .nii.gz)"
                    ),
                ));
            }
            let skip = usize::try_from(skip).ok().filter(|&s| s <= bytes.len());
            let Some(skip) = skip else {
                return Err(Error::format(file, "byte skip", "larger than the data"));
            };
            bytes.drain(..skip);
            Ok(decode(l.ty, bytes, l.big_endian))
        }
        (Encoding::Ascii, Some(skip)) => {
            let offset = offset
                .checked_add(skip)
                .ok_or_else(|| Error::format(file, "byte skip", "offset overflows"))?;
            let text = read_text(file, offset, field)?;
            Ok(parse_ascii(file, field, &text, count, l.ty)?.0)
        }
        (_, None) => Err(Error::unsupported(
            file,
            "negative byte skip with a non-raw encoding",
        )),
    }
}

#[cfg(test)]
#[path = "nrrd_semantics_tests.rs"]
mod semantics_tests;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_support::{err_naming, never_panics, write};
    use crate::testdata::data_path;
    use crate::volume::ScalarType;
    use flate2::write::GzEncoder;
    use flate2::Compression;
    use std::io::Write;

    fn attached(header: &str, data: &[u8]) -> Vec<u8> {
        let mut v = header.as_bytes().to_vec();
        v.push(b'\n');
        v.extend_from_slice(data);
        v
    }

    fn gzip(data: &[u8]) -> Vec<u8> {
        let mut e = GzEncoder::new(Vec::new(), Compression::default());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn reads_neghip() {
        let Some(p) = data_path("neghip/neghip.nhdr") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [64, 64, 64]);
        assert_eq!(v.spacing(), Vec3::ONE);
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.scalar_type(), ScalarType::U8);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 255.0));
        // Values read from the raw file with Python, index i + 64·(j + 64·k).
        assert_eq!(v.value(10, 20, 30), 166.0);
        assert_eq!(v.value(40, 12, 50), 25.0);
        assert_eq!(v.value(30, 53, 6), 255.0);
    }

    #[test]
    fn reads_headsq() {
        let Some(p) = data_path("ct_head_headsq/headsq.nhdr") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [64, 64, 93]);
        assert_eq!(v.spacing(), Vec3::new(3.2, 3.2, 1.5));
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.scalar_type(), ScalarType::U16);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 3926.0));
        assert_eq!(v.value(10, 20, 30), 861.0);
        assert_eq!(v.value(40, 30, 60), 2187.0);
        assert_eq!(v.value(39, 24, 53), 3926.0);
    }

    #[test]
    fn reads_attached_with_directions_and_origin() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..24).collect();
        let h = "NRRD0005\n# a comment\ntype: unsigned char\ndimension: 3\nsizes: 2 3 4\n\
                 space: left-posterior-superior\n\
                 space directions: (0.5,0,0) (0, -2, 0) (0,0,3)\n\
                 space origin: (1.5, -2, 10)\nencoding: raw\nsample units: HU\nfoo:=bar\n";
        let p = write(dir.path(), "a.nrrd", &attached(h, &data));
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [2, 3, 4]);
        assert_eq!(v.spacing(), Vec3::new(0.5, 2.0, 3.0));
        assert_eq!(v.origin(), Vec3::new(1.5, -2.0, 10.0));
        assert_eq!(v.value(1, 2, 3), 23.0);
        assert_eq!(v.units.as_deref(), Some("HU"));
    }

    #[test]
    fn reads_gzip_attached_and_detached() {
        let dir = tempfile::tempdir().unwrap();
        let vals: Vec<i16> = (0..60).map(|i| i * 100 - 3000).collect();
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let h = "NRRD0004\ntype: short\ndimension: 3\nsizes: 3 4 5\nendian: little\nencoding: gzip\nspacings: 1 2 nan\n";
        let p = write(dir.path(), "g.nrrd", &attached(h, &gzip(&raw)));
        let v = read(&p).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.spacing(), Vec3::new(1.0, 2.0, 1.0));
        assert_eq!(v.value(2, 3, 4), 2900.0);
        assert_eq!(v.stats().min, -3000.0);

        // Detached, gz spelling, with a byte skip counted in decompressed bytes.
        let mut skipped = vec![9u8; 7];
        skipped.extend_from_slice(&raw);
        write(dir.path(), "g.raw.gz", &gzip(&skipped));
        let h = "NRRD0004\ntype: int16\ndimension: 3\nsizes: 3 4 5\nendian: little\nencoding: gz\nbyte skip: 7\ndatafile: g.raw.gz\n";
        let p = write(dir.path(), "g.nhdr", h.as_bytes());
        let v = read(&p).unwrap();
        assert_eq!(v.value(2, 3, 4), 2900.0);
        assert_eq!(v.value(0, 0, 0), -3000.0);
    }

    #[test]
    fn reads_big_endian_and_converted_types() {
        let dir = tempfile::tempdir().unwrap();
        let vals: Vec<u16> = (0..8).map(|i| i * 1000 + 1).collect();
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 2 2 2\nendian: big\nencoding: raw\n";
        let v = read(&write(dir.path(), "be.nrrd", &attached(h, &raw))).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::U16);
        assert_eq!(v.value(1, 1, 1), 7001.0);

        let vals = [-5i32, 70000, 3, 4];
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = "NRRD0004\ntype: int\ndimension: 2\nsizes: 2 2\nendian: big\nencoding: raw\n";
        let v = read(&write(dir.path(), "i32.nrrd", &attached(h, &raw))).unwrap();
        assert_eq!(v.dims(), [2, 2, 1]);
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!((v.stats().min, v.stats().max), (-5.0, 70000.0));

        let vals = [-1.5f64, 2.25];
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let h =
            "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: little\nencoding: raw\n";
        let v = read(&write(dir.path(), "f64.nrrd", &attached(h, &raw))).unwrap();
        assert_eq!(v.value(0, 0, 0), -1.5);
        assert_eq!(v.value(1, 0, 0), 2.25);

        let h = "NRRD0004\ntype: Signed  Char\ndimension: 3\nsizes: 2 1 1\nencoding: RAW\nendian: Big\n";
        let v = read(&write(dir.path(), "i8.nrrd", &attached(h, &[0xff, 0x7f]))).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.value(0, 0, 0), -1.0);
        assert_eq!(v.value(1, 0, 0), 127.0);
    }

    #[test]
    fn reads_dimension_4_and_ascii() {
        let dir = tempfile::tempdir().unwrap();
        let h = "NRRD0004\ntype: float\ndimension: 4\nsizes: 1 2 2 1\nencoding: ascii\n\
                 space directions: none (2,0,0) (0,2,0) (0,0,2)\n";
        let p = write(dir.path(), "t.nrrd", &attached(h, b"1.5 2\n-3,4e2\n"));
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [2, 2, 1]);
        assert_eq!(v.spacing(), Vec3::splat(2.0));
        assert_eq!(v.value(1, 1, 0), 400.0);
        assert_eq!(v.value(0, 1, 0), -3.0);

        // An integer type in ascii must hold whole numbers in range.
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 1 1\nencoding: text\n";
        let p = write(dir.path(), "bad.nrrd", &attached(h, b"1 256\n"));
        err_naming(read(&p), "bad.nrrd", "256");
    }

    #[test]
    fn reads_skips_and_lists() {
        let dir = tempfile::tempdir().unwrap();
        // Line skip then byte skip, in a detached file.
        let mut f = b"junk line\nsecond\nXX".to_vec();
        f.extend(0u8..8);
        write(dir.path(), "skip.raw", &f);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nline skip: 2\nbyte skip: 2\ndata file: skip.raw\n";
        let v = read(&write(dir.path(), "skip.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 0), 0.0);
        assert_eq!(v.value(1, 1, 1), 7.0);

        // byte skip -1: the data are the last bytes of the file.
        let mut f = vec![0xAAu8; 100];
        f.extend(10u8..18);
        write(dir.path(), "end.raw", &f);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nbyte skip: -1\ndata file: end.raw\n";
        let v = read(&write(dir.path(), "end.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 0), 10.0);
        assert_eq!(v.value(1, 1, 1), 17.0);

        // LIST: one slice per file; and the same as a pattern.
        write(dir.path(), "s1.raw", &[1, 2, 3, 4]);
        write(dir.path(), "s2.raw", &[5, 6, 7, 8]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: LIST\ns1.raw\ns2.raw\n";
        let v = read(&write(dir.path(), "list.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 1), 5.0);
        assert_eq!(v.value(1, 1, 1), 8.0);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: s%d.raw 1 2 1 2\n";
        let v = read(&write(dir.path(), "pat.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(1, 1, 1), 8.0);
        assert_eq!(
            format_index("slice%03d.raw", 7).as_deref(),
            Some("slice007.raw")
        );
        assert_eq!(format_index("a%%%4i", -3).as_deref(), Some("a%  -3"));
        assert_eq!(format_index("%s", 1), None);
    }

    #[test]
    fn bad_sizes_are_errors_naming_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let data = [0u8; 64];
        let cases = [
            ("sizes: 4 4 0", "at least 1"),
            ("sizes: 4 -4 4", "negative"),
            ("sizes: 4 four 4", "not a whole number"),
            ("sizes: 4294967296 4294967296 4294967296", "more than"),
            ("sizes: 99999999999999999999999 1 1", "too large"),
            ("sizes: 4 4", "2 sizes"),
            ("sizes: 4 4 8", "truncated"),
        ];
        for (i, (sizes, why)) in cases.iter().enumerate() {
            let h = format!("NRRD0004\ntype: uchar\ndimension: 3\n{sizes}\nencoding: raw\n");
            let name = format!("bad{i}.nrrd");
            let p = write(dir.path(), &name, &attached(&h, &data));
            let s = err_naming(read(&p), &name, "sizes");
            assert!(s.contains(why), "{sizes}: {s}");
        }
    }

    #[test]
    fn truncated_and_lying_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        // Detached data file one byte short: the error names the header, the field and the data file.
        write(dir.path(), "short.raw", &[0u8; 63]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: short.raw\n";
        let p = write(dir.path(), "short.nhdr", h.as_bytes());
        let s = err_naming(read(&p), "short.nhdr", "sizes");
        assert!(s.contains("short.raw"), "{s}");

        // A 1 KB file claiming 10⁹ voxels, raw and gzip: refused before allocating.
        for enc in ["raw", "gzip"] {
            let h = format!(
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1000 1000 1000\nencoding: {enc}\n"
            );
            let name = format!("huge_{enc}.nrrd");
            let p = write(dir.path(), &name, &attached(&h, &[0u8; 1024]));
            let s = err_naming(read(&p), &name, "sizes");
            assert!(s.contains("1000000000"), "{s}");
        }

        // Gzip stream cut short.
        let z = gzip(&[7u8; 4096]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 16 16 16\nencoding: gzip\n";
        let p = write(dir.path(), "cut.nrrd", &attached(h, &z[..z.len() / 2]));
        err_naming(read(&p), "cut.nrrd", "sizes");

        // Too few ascii values.
        let h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n";
        let p = write(dir.path(), "few.nrrd", &attached(h, b"1 2 3\n"));
        err_naming(read(&p), "few.nrrd", "sizes");
    }

    #[test]
    fn unknown_and_unsupported_fields_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            ("type: complex", "encoding: raw", "type"),
            ("type: block", "encoding: raw", "type"),
            ("type: uchar", "encoding: hex", "encoding"),
            ("type: uchar", "encoding: rot13", "encoding"),
            ("type: uchar", "encoding: raw\nendian: middle", "endian"),
            ("type: uchar", "encoding: raw\nspacings: 1 0 1", "spacings"),
            (
                "type: uchar",
                "encoding: raw\nspace directions: (1,0,0) (0,1,0)",
                "space directions",
            ),
            (
                "type: uchar",
                "encoding: raw\nspace origin: 1 2 3",
                "space origin",
            ),
            ("type: uchar", "encoding: raw\nbyte skip: many", "byte skip"),
            ("type: uchar", "encoding: raw\nencoding: raw", "encoding"),
            ("type: uchar", "encoding: gzip\nbyte skip: -1", "byte skip"),
        ];
        for (i, (ty, enc, field)) in cases.iter().enumerate() {
            let h = format!("NRRD0004\n{ty}\ndimension: 3\nsizes: 2 2 2\n{enc}\n");
            let name = format!("f{i}.nrrd");
            let p = write(dir.path(), &name, &attached(&h, &[0u8; 8]));
            err_naming(read(&p), &name, field);
        }
        let p = write(
            dir.path(),
            "nodim.nrrd",
            &attached("NRRD0004\ntype: uchar\nsizes: 2\nencoding: raw\n", &[0]),
        );
        err_naming(read(&p), "nodim.nrrd", "dimension");
        let p = write(
            dir.path(),
            "d5.nrrd",
            &attached(
                "NRRD0004\ntype: uchar\ndimension: 5\nsizes: 1 1 1 1 1\nencoding: raw\n",
                &[0],
            ),
        );
        err_naming(read(&p), "d5.nrrd", "dimension 5");
        let p = write(
            dir.path(),
            "rgb.nrrd",
            &attached(
                "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 2 2 2\nencoding: raw\n",
                &[0; 24],
            ),
        );
        err_naming(read(&p), "rgb.nrrd", "dimension 4");
        let p = write(dir.path(), "nomagic.nrrd", b"P5\n2 2\n255\n\0\0\0\0");
        err_naming(read(&p), "nomagic.nrrd", "magic");
        let p = write(dir.path(), "binary.nrrd", &[0xffu8; 300]);
        err_naming(read(&p), "binary.nrrd", "magic");
    }

    #[test]
    fn missing_data_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: nowhere.raw\n";
        let p = write(dir.path(), "lost.nhdr", h.as_bytes());
        let s = err_naming(read(&p), "lost.nhdr", "data file");
        assert!(s.contains("nowhere.raw"), "{s}");
        // A LIST whose files do not split the volume evenly.
        write(dir.path(), "a.raw", &[0; 8]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: LIST\na.raw\na.raw\na.raw\n";
        let p = write(dir.path(), "list3.nhdr", h.as_bytes());
        err_naming(read(&p), "list3.nhdr", "data file");
    }

    #[test]
    fn mutated_files_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let raw: Vec<u8> = (0..16u16).flat_map(|v| v.to_be_bytes()).collect();
        let h = "NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 2 4\nendian: big\nencoding: gzip\n\
                 space directions: (1,0,0) (0,1,0) (0,0,2)\nspace origin: (1,2,3)\nbyte skip: 0\n";
        never_panics(
            read,
            dir.path(),
            "m.nrrd",
            &attached(h, &gzip(&raw)),
            h.len(),
        );
        let h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 2\nencoding: ascii\nspacings: 1 nan 2\nline skip: 0\n";
        never_panics(
            read,
            dir.path(),
            "t.nrrd",
            &attached(h, b"1 2.5\n-3 4\n"),
            h.len(),
        );
        write(dir.path(), "p1.raw", &[1, 2]);
        write(dir.path(), "p2.raw", &[3, 4]);
        let h = b"NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\nencoding: raw\ndata file: p%d.raw 1 2 1\n";
        never_panics(read, dir.path(), "p.nhdr", h, h.len());
        let h = b"NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 1 2\nencoding: raw\nbyte skip: -1\ndata file: LIST 3\np1.raw\np2.raw\n";
        never_panics(read, dir.path(), "l.nhdr", h, h.len());
    }
}
