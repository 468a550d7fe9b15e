//! Legacy VTK files (`.vtk`) holding `DATASET STRUCTURED_POINTS`.
//!
//! Supported:
//! * `# vtk DataFile Version x.y`, a title line, `ASCII` or `BINARY` (blank
//!   lines around them tolerated); keywords in any case;
//! * `DIMENSIONS`, `SPACING` (or the old `ASPECT_RATIO`), `ORIGIN`;
//!   `POINT_DATA n`, which must equal the product of the dimensions;
//! * the first one-component `SCALARS name type [1]` array of the point data
//!   (with or without its `LOOKUP_TABLE` line) becomes the volume. Binary
//!   data are big-endian and start after the newline ending the
//!   `LOOKUP_TABLE` line. Types: `unsigned_char`, `unsigned_short`, `short`,
//!   `float` kept as stored; `char`/`signed_char` become i16 (exact); `int`,
//!   `unsigned_int`, `vtktypeint64`, `vtktypeuint64` and `double` become f32,
//!   exact only up to 2²⁴ in magnitude;
//! * the other arrays are not loaded, only listed: every point-data array
//!   (`SCALARS`, `VECTORS`, `NORMALS`, `TENSORS`, `TEXTURE_COORDINATES`,
//!   `COLOR_SCALARS`, the arrays of a `FIELD`) goes into
//!   [`Volume::variables`] when there is more than one, and the volume's
//!   array name into [`Volume::name`]. They are skipped by computing their
//!   size (binary) or counting their values (ASCII), never read into memory;
//!   a damaged or unknown array after the volume ends the listing without
//!   an error, since the volume itself is complete. Cell data, dataset
//!   `FIELD`s and `METADATA` blocks are skipped.
//!
//! Not supported (an error naming the keyword): other `DATASET` types,
//! multi-component `SCALARS` for the volume, the `bit`, `long` and `string`
//! types for the volume. Negative spacings are taken as their magnitude (the
//! axis flip is not applied).

use super::decode::{
    byte_count, check_origin, check_spacing, make_volume, parse_ascii, parse_floats, parse_sizes,
    read_binary, read_text, shorten, LineReader, StoredType, Tokens,
};
use super::util::{check_dims, file_len};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume, VoxelData};
use glam::Vec3;
use std::path::Path;

/// Reads the legacy VTK file at `path`.
pub fn read(path: &Path) -> Result<Volume> {
    let mut lines = LineReader::open(path)?;
    let first = lines.next_line("version line")?.unwrap_or_default();
    if !first
        .trim_start()
        .to_ascii_lowercase()
        .starts_with("# vtk datafile version")
    {
        return Err(Error::format(
            path,
            "version line",
            format!(
                "expected `# vtk DataFile Version x.y`, found `{}`",
                shorten(&first)
            ),
        ));
    }
    if lines.next_line("title")?.is_none() {
        return Err(Error::format(
            path,
            "title",
            "the file ends after the version line",
        ));
    }
    let kind = loop {
        match lines.next_line("ASCII/BINARY")? {
            Some(l) if l.trim().is_empty() => continue,
            Some(l) => break l.trim().to_ascii_uppercase(),
            None => {
                return Err(Error::format(
                    path,
                    "ASCII/BINARY",
                    "the file ends after the title",
                ))
            }
        }
    };
    let cursor = match kind.as_str() {
        "BINARY" => Cursor::Binary {
            len: file_len(path)?,
            lines,
        },
        "ASCII" => {
            let base = lines.pos();
            Cursor::Text {
                text: read_text(path, base, "ASCII")?,
                pos: 0,
            }
        }
        _ => {
            return Err(Error::format(
                path,
                "ASCII/BINARY",
                format!("line 3 is `{}`: expected ASCII or BINARY", shorten(&kind)),
            ))
        }
    };
    let mut p = Parser {
        path,
        cur: cursor,
        dataset: false,
        dims: None,
        spacing: None,
        origin: None,
        section: Section::Geometry,
        volume: None,
        names: Vec::new(),
    };
    loop {
        let line = match p.cur.next_nonblank() {
            Ok(Some(line)) => line,
            Ok(None) => break,
            Err(_) if p.volume.is_some() => break,
            Err(e) => return Err(e),
        };
        match p.step(&line) {
            Ok(true) => {}
            Ok(false) => break,
            // The volume is complete: a damaged or unknown array after it only ends the listing.
            Err(_) if p.volume.is_some() => break,
            Err(e) => return Err(e),
        }
    }
    p.finish()
}

/// Where the file's lines and values come from.
enum Cursor {
    /// A binary file, read line by line and skipped over by seeking.
    Binary { lines: LineReader, len: u64 },
    /// An ASCII file, in memory from the line after `ASCII` on.
    Text { text: String, pos: usize },
}

impl Cursor {
    fn next_line(&mut self) -> Result<Option<String>> {
        match self {
            Cursor::Binary { lines, .. } => lines.next_line("header"),
            Cursor::Text { text, pos } => {
                let rest = text.get(*pos..).unwrap_or("");
                if rest.is_empty() {
                    return Ok(None);
                }
                let (line, used) = match rest.split_once('\n') {
                    Some((line, _)) => (line, line.len() + 1),
                    None => (rest, rest.len()),
                };
                *pos += used;
                Ok(Some(line.trim_end_matches('\r').to_string()))
            }
        }
    }

    fn next_nonblank(&mut self) -> Result<Option<String>> {
        loop {
            match self.next_line()? {
                Some(l) if l.trim().is_empty() => continue,
                other => return Ok(other),
            }
        }
    }

    fn mark(&self) -> u64 {
        match self {
            Cursor::Binary { lines, .. } => lines.pos(),
            Cursor::Text { pos, .. } => *pos as u64,
        }
    }

    fn reset(&mut self, mark: u64) -> Result<()> {
        match self {
            Cursor::Binary { lines, .. } => lines.seek(mark),
            Cursor::Text { pos, .. } => {
                *pos = usize::try_from(mark).unwrap_or(usize::MAX);
                Ok(())
            }
        }
    }

    /// Skips `count` values of VTK type `ty`; false when that runs past the
    /// end of the file or the type's binary size is unknown.
    fn skip(&mut self, count: u64, ty: &str) -> Result<bool> {
        match self {
            Cursor::Binary { lines, len } => {
                let Some(bytes) = binary_size(ty, count) else {
                    return Ok(false);
                };
                match lines.pos().checked_add(bytes) {
                    Some(end) if end <= *len => {
                        lines.seek(end)?;
                        Ok(true)
                    }
                    _ => Ok(false),
                }
            }
            Cursor::Text { text, pos } => {
                let mut toks = Tokens::at(text, *pos);
                let mut left = count;
                while left > 0 {
                    if toks.next().is_none() {
                        return Ok(false);
                    }
                    left -= 1;
                }
                *pos = toks.pos;
                Ok(true)
            }
        }
    }

    /// Reads `count` values of `ty` (the volume).
    fn read_values(
        &mut self,
        path: &Path,
        field: &str,
        count: usize,
        ty: StoredType,
    ) -> Result<VoxelData> {
        match self {
            Cursor::Binary { lines, .. } => {
                let offset = lines.pos();
                let data = read_binary(path, offset, count, ty, true, false, field)?;
                let end = offset.saturating_add(byte_count(path, field, count, ty)?);
                lines.seek(end)?;
                Ok(data)
            }
            Cursor::Text { text, pos } => {
                let rest = text.get(*pos..).unwrap_or("");
                let (data, used) = parse_ascii(path, field, rest, count, ty)?;
                *pos += used;
                Ok(data)
            }
        }
    }
}

/// Bytes of `count` binary values of VTK type `ty`, `None` when unknown.
fn binary_size(ty: &str, count: u64) -> Option<u64> {
    let size = match ty.to_ascii_lowercase().as_str() {
        "bit" => return Some(count.div_ceil(8)),
        "unsigned_char" | "char" | "signed_char" => 1,
        "unsigned_short" | "short" => 2,
        // The legacy writer stores vtkIdType as 32-bit int.
        "unsigned_int" | "int" | "float" | "vtkidtype" => 4,
        "double" | "vtktypeint64" | "vtktypeuint64" => 8,
        // `long` is 4 or 8 bytes depending on the writer's platform.
        _ => return None,
    };
    count.checked_mul(size)
}

/// The element type of the volume array.
fn volume_type(path: &Path, field: &str, ty: &str) -> Result<StoredType> {
    Ok(match ty.to_ascii_lowercase().as_str() {
        "unsigned_char" => StoredType::U8,
        "char" | "signed_char" => StoredType::I8,
        "unsigned_short" => StoredType::U16,
        "short" => StoredType::I16,
        "int" => StoredType::I32,
        "unsigned_int" => StoredType::U32,
        "vtktypeint64" => StoredType::I64,
        "vtktypeuint64" => StoredType::U64,
        "float" => StoredType::F32,
        "double" => StoredType::F64,
        "bit" | "long" | "unsigned_long" | "vtkidtype" | "string" => {
            return Err(Error::unsupported(path, format!("{field} of type `{ty}`")));
        }
        _ => {
            return Err(Error::format(
                path,
                field,
                format!("unknown type `{ty}` (expected e.g. unsigned_char, short, unsigned_short, float, double)"),
            ))
        }
    })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Section {
    /// Before any `POINT_DATA`/`CELL_DATA`.
    Geometry,
    Point(u64),
    Cell(u64),
}

struct Parser<'a> {
    path: &'a Path,
    cur: Cursor,
    dataset: bool,
    dims: Option<[u64; 3]>,
    spacing: Option<Vec3>,
    origin: Option<Vec3>,
    section: Section,
    /// The volume's values and array name once read.
    volume: Option<(VoxelData, String)>,
    /// Names of the point-data arrays seen.
    names: Vec<String>,
}

impl Parser<'_> {
    /// Handles one keyword line; false to stop.
    fn step(&mut self, line: &str) -> Result<bool> {
        let path = self.path;
        let line = line.trim();
        let (kw, rest) = line.split_once(char::is_whitespace).unwrap_or((line, ""));
        let kw = kw.to_ascii_uppercase();
        let rest = rest.trim();
        match kw.as_str() {
            "DATASET" => {
                if !rest.eq_ignore_ascii_case("STRUCTURED_POINTS") {
                    return Err(Error::unsupported(
                        path,
                        format!("DATASET {rest} (only STRUCTURED_POINTS is a volume)"),
                    ));
                }
                self.dataset = true;
            }
            "DIMENSIONS" => {
                let d = parse_sizes(path, "DIMENSIONS", rest)?;
                let [x, y, z] = d[..] else {
                    return Err(Error::format(
                        path,
                        "DIMENSIONS",
                        format!("`{rest}`: expected 3 numbers"),
                    ));
                };
                self.dims = Some([x, y, z]);
            }
            "SPACING" | "ASPECT_RATIO" => {
                self.spacing = Some(check_spacing(path, &kw, three(path, &kw, rest)?)?)
            }
            "ORIGIN" => {
                self.origin = Some(check_origin(path, "ORIGIN", three(path, "ORIGIN", rest)?)?)
            }
            "POINT_DATA" => {
                if !self.dataset {
                    return Err(Error::format(path, "DATASET", "missing before POINT_DATA"));
                }
                let Some(dims) = self.dims else {
                    return Err(Error::format(
                        path,
                        "DIMENSIONS",
                        "missing before POINT_DATA",
                    ));
                };
                let (count, _) = check_dims(path, "DIMENSIONS", dims, ScalarType::U8)?;
                let n = count_of(path, "POINT_DATA", rest)?;
                if n != count as u64 {
                    return Err(Error::format(
                        path,
                        "POINT_DATA",
                        format!(
                            "{n} points, but DIMENSIONS {} {} {} make {count}",
                            dims[0], dims[1], dims[2]
                        ),
                    ));
                }
                self.section = Section::Point(n);
            }
            "CELL_DATA" => self.section = Section::Cell(count_of(path, "CELL_DATA", rest)?),
            "FIELD" => return self.field(rest),
            "METADATA" => {
                // A METADATA block ends at the first empty line.
                while let Some(l) = self.cur.next_line()? {
                    if l.trim().is_empty() {
                        break;
                    }
                }
            }
            "SCALARS"
            | "VECTORS"
            | "NORMALS"
            | "TENSORS"
            | "TENSORS6"
            | "TEXTURE_COORDINATES"
            | "COLOR_SCALARS"
            | "LOOKUP_TABLE" => return self.array(&kw, rest),
            _ => {
                return Err(Error::format(
                    path,
                    "header",
                    format!("unexpected line `{}`", shorten(line)),
                ))
            }
        }
        Ok(true)
    }

    /// One attribute array: the volume, or one to skip (and list).
    fn array(&mut self, kw: &str, rest: &str) -> Result<bool> {
        let path = self.path;
        let (is_point, n) = match self.section {
            Section::Point(n) => (true, n),
            Section::Cell(n) => (false, n),
            Section::Geometry => {
                return Err(Error::format(
                    path,
                    kw,
                    "an array before POINT_DATA or CELL_DATA",
                ));
            }
        };
        let words: Vec<&str> = rest.split_whitespace().collect();
        let word = |i: usize, what: &str| {
            words
                .get(i)
                .copied()
                .ok_or_else(|| Error::format(path, kw, format!("`{kw} {rest}`: no {what}")))
        };
        let name = unescape(word(0, "name")?);
        let (values, ty): (u64, &str) = match kw {
            "SCALARS" => {
                let ty = word(1, "type")?;
                let comps = match words.get(2) {
                    None => 1,
                    Some(c) => count_of(path, "SCALARS", c)?,
                };
                // Some writers omit LOOKUP_TABLE: then the values follow the SCALARS line.
                let mark = self.cur.mark();
                match self.cur.next_line() {
                    Ok(Some(l))
                        if l.trim_start()
                            .to_ascii_uppercase()
                            .starts_with("LOOKUP_TABLE") => {}
                    _ => self.cur.reset(mark)?,
                }
                if is_point && self.volume.is_none() {
                    let field = "DIMENSIONS/SCALARS";
                    let st = volume_type(path, "SCALARS", ty)?;
                    if comps != 1 {
                        return Err(Error::unsupported(
                            path,
                            format!("SCALARS {name} with {comps} components (the volume needs 1)"),
                        ));
                    }
                    let count = usize::try_from(n)
                        .map_err(|_| Error::format(path, "POINT_DATA", "too many points"))?;
                    let data = self.cur.read_values(path, field, count, st)?;
                    self.names.push(name.clone());
                    self.volume = Some((data, name));
                    return Ok(true);
                }
                (comps, ty)
            }
            "VECTORS" | "NORMALS" => (3, word(1, "type")?),
            "TENSORS" => (9, word(1, "type")?),
            "TENSORS6" => (6, word(1, "type")?),
            "TEXTURE_COORDINATES" => (count_of(path, kw, word(1, "dimension")?)?, word(2, "type")?),
            // Colours are bytes in binary files, floats in ASCII ones; lookup tables hold RGBA entries.
            "COLOR_SCALARS" => (
                count_of(path, kw, word(1, "component count")?)?,
                "unsigned_char",
            ),
            _ => {
                let size = count_of(path, kw, word(1, "size")?)?;
                let bytes = size
                    .checked_mul(4)
                    .ok_or_else(|| Error::format(path, kw, "size overflows"))?;
                return self.skip_or_fail(kw, &name, bytes, "unsigned_char");
            }
        };
        let total = values
            .checked_mul(n)
            .ok_or_else(|| Error::format(path, kw, "size overflows"))?;
        if !self.skip_or_fail(kw, &name, total, ty)? {
            return Ok(false);
        }
        if is_point {
            self.names.push(name);
        }
        Ok(true)
    }

    /// Skips `count` values; before the volume, data that cannot be skipped is an error.
    fn skip_or_fail(&mut self, kw: &str, name: &str, count: u64, ty: &str) -> Result<bool> {
        if self.cur.skip(count, ty)? {
            return Ok(true);
        }
        if self.volume.is_none() {
            return Err(Error::format(
                self.path,
                kw,
                format!("array `{name}` ({count} values of `{ty}`) runs past the end of the file or has an unknown type"),
            ));
        }
        Ok(false)
    }

    /// `FIELD name n` followed by n arrays `name components tuples type`.
    fn field(&mut self, rest: &str) -> Result<bool> {
        let path = self.path;
        let n_arrays = match rest.split_whitespace().nth(1) {
            Some(c) => count_of(path, "FIELD", c)?,
            None => {
                return Err(Error::format(
                    path,
                    "FIELD",
                    format!("`FIELD {rest}`: no array count"),
                ))
            }
        };
        let is_point = matches!(self.section, Section::Point(_));
        let mut left = n_arrays;
        while left > 0 {
            let Some(line) = self.cur.next_nonblank()? else {
                return Ok(false);
            };
            let words: Vec<&str> = line.split_whitespace().collect();
            if words
                .first()
                .is_some_and(|w| w.eq_ignore_ascii_case("METADATA"))
            {
                self.step(&line)?;
                continue;
            }
            let [name, comps, tuples, ty] = words[..] else {
                return Err(Error::format(
                    path,
                    "FIELD",
                    format!(
                        "array line `{}`: expected `name components tuples type`",
                        shorten(&line)
                    ),
                ));
            };
            let total = count_of(path, "FIELD", comps)?
                .checked_mul(count_of(path, "FIELD", tuples)?)
                .ok_or_else(|| Error::format(path, "FIELD", "size overflows"))?;
            let name = unescape(name);
            if !self.skip_or_fail("FIELD", &name, total, ty)? {
                return Ok(false);
            }
            if is_point {
                self.names.push(name);
            }
            left -= 1;
        }
        Ok(true)
    }

    fn finish(self) -> Result<Volume> {
        let path = self.path;
        let Some(dims) = self.dims else {
            return Err(Error::format(path, "DIMENSIONS", "missing"));
        };
        let Some((data, name)) = self.volume else {
            return Err(match self.section {
                Section::Point(_) => Error::unsupported(
                    path,
                    format!(
                        "no one-component SCALARS array in POINT_DATA (arrays: {})",
                        if self.names.is_empty() {
                            "none".to_string()
                        } else {
                            self.names.join(", ")
                        }
                    ),
                ),
                _ => Error::format(path, "POINT_DATA", "missing: the file has no point data"),
            });
        };
        let mut vol = make_volume(
            path,
            dims,
            self.spacing.unwrap_or(Vec3::ONE),
            self.origin.unwrap_or(Vec3::ZERO),
            data,
        )?;
        vol.name = Some(name);
        if self.names.len() > 1 {
            vol.variables = self.names;
        }
        Ok(vol)
    }
}

fn three(path: &Path, field: &str, s: &str) -> Result<[f64; 3]> {
    match parse_floats(path, field, s)?[..] {
        [x, y, z] => Ok([x, y, z]),
        _ => Err(Error::format(
            path,
            field,
            format!("`{s}`: expected 3 numbers"),
        )),
    }
}

/// A count from a keyword line.
fn count_of(path: &Path, field: &str, s: &str) -> Result<u64> {
    match parse_sizes(path, field, s)?[..] {
        [n] => Ok(n),
        _ => Err(Error::format(
            path,
            field,
            format!("`{s}`: expected one number"),
        )),
    }
}

/// Array names escape spaces and odd characters as `%XX`.
fn unescape(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while let Some(&c) = b.get(i) {
        let hex = b
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok());
        match hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
            Some(v) if c == b'%' => {
                out.push(v);
                i += 3;
            }
            _ => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_support::{err_naming, never_panics, write};
    use crate::testdata::data_path;

    fn binary(header: &str, data: &[u8], tail: &[u8]) -> Vec<u8> {
        let mut v = header.as_bytes().to_vec();
        v.extend_from_slice(data);
        v.extend_from_slice(tail);
        v
    }

    const HEAD: &str = "# vtk DataFile Version 3.0\ntest\nBINARY\nDATASET STRUCTURED_POINTS\n";

    #[test]
    fn reads_iron_protein() {
        let Some(p) = data_path("iron_protein/ironProt.vtk") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [68, 68, 68]);
        assert_eq!(v.spacing(), Vec3::ONE);
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.scalar_type(), ScalarType::U8);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 255.0));
        // Values read from the file with Python (data at byte 209), index i + 68·(j + 68·k).
        assert_eq!(v.value(34, 34, 34), 131.0);
        assert_eq!(v.value(40, 30, 20), 64.0);
        assert_eq!(v.value(32, 54, 9), 255.0);
        assert_eq!(v.name.as_deref(), Some("scalars"));
        assert!(v.variables.is_empty());
    }

    #[test]
    fn reads_carotid() {
        let Some(p) = data_path("carotid_mra/carotid.vtk") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [76, 49, 45]);
        assert_eq!(v.spacing(), Vec3::ONE);
        assert_eq!(v.origin(), Vec3::new(100.0, 80.0, 1.0));
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 580.0));
        // Big-endian floats from byte 182, read with Python.
        assert_eq!(v.value(0, 0, 0), 57.0);
        assert_eq!(v.value(38, 24, 22), 162.0);
        assert_eq!(v.value(50, 6, 22), 580.0);
        assert_eq!(v.name.as_deref(), Some("scalars"));
        assert_eq!(v.variables, ["scalars", "vectors"]);
    }

    #[test]
    fn reads_ascii_with_several_arrays() {
        let dir = tempfile::tempdir().unwrap();
        let text = "# vtk DataFile Version 2.0\nascii test\nASCII\n\nDATASET STRUCTURED_POINTS\n\
                    DIMENSIONS 2 2 2\nORIGIN -1 0 2.5\nSPACING 0.5 1 2\n\
                    CELL_DATA 1\nSCALARS cellid int 1\nLOOKUP_TABLE default\n7\n\
                    POINT_DATA 8\nVECTORS flow float\n0 0 0 1 1 1 2 2 2 3 3 3\n4 4 4 5 5 5 6 6 6 7 7 7\n\
                    SCALARS density%20a double 1\nLOOKUP_TABLE default\n0.5 1.5 -2 3\n4 5 6 1e3\n\
                    FIELD FieldData 2\ntemp 1 8 float\n1 2 3 4 5 6 7 8\nids 2 8 int\n\
                    0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 0\n\
                    SCALARS other short\n1 2 3 4 5 6 7 8\n";
        let v = read(&write(dir.path(), "a.vtk", text.as_bytes())).unwrap();
        assert_eq!(v.dims(), [2, 2, 2]);
        assert_eq!(v.spacing(), Vec3::new(0.5, 1.0, 2.0));
        assert_eq!(v.origin(), Vec3::new(-1.0, 0.0, 2.5));
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!(v.value(0, 1, 0), -2.0);
        assert_eq!(v.value(1, 1, 1), 1000.0);
        assert_eq!(v.name.as_deref(), Some("density a"));
        assert_eq!(v.variables, ["flow", "density a", "temp", "ids", "other"]);
    }

    #[test]
    fn reads_binary_types_and_lists_arrays() {
        let dir = tempfile::tempdir().unwrap();
        let vals: Vec<i16> = (0..8).map(|i| i * 1000 - 4000).collect();
        let data: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = format!("{HEAD}DIMENSIONS 2 2 2\nASPECT_RATIO 1 2 3\nORIGIN 0 0 0\nPOINT_DATA 8\nSCALARS s short 1\nLOOKUP_TABLE default\n");
        let tail = [
            b"\nNORMALS n float\n".as_slice(),
            &[0u8; 96],
            b"\nFIELD f 1\nmass 1 8 double\n",
            &[0u8; 64],
            b"\n",
        ]
        .concat();
        let v = read(&write(dir.path(), "b.vtk", &binary(&h, &data, &tail))).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.spacing(), Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(v.value(1, 1, 1), 3000.0);
        assert_eq!(v.value(0, 0, 0), -4000.0);
        assert_eq!(v.variables, ["s", "n", "mass"]);

        // A trailing array claiming far more than the file holds only ends the listing.
        let tail = b"\nVECTORS huge double\n\x01\x02";
        let h = format!(
            "{HEAD}DIMENSIONS 2 2 2\nPOINT_DATA 8\nSCALARS s unsigned_char\nLOOKUP_TABLE default\n"
        );
        let v = read(&write(dir.path(), "t.vtk", &binary(&h, &[9u8; 8], tail))).unwrap();
        assert_eq!(v.value(1, 1, 1), 9.0);
        assert!(v.variables.is_empty());

        // char → i16, unsigned_int → f32, no LOOKUP_TABLE line.
        let h = format!("{HEAD}DIMENSIONS 2 1 1\nPOINT_DATA 2\nSCALARS c char\n");
        let v = read(&write(dir.path(), "c.vtk", &binary(&h, &[0xfe, 3], b""))).unwrap();
        assert_eq!((v.value(0, 0, 0), v.value(1, 0, 0)), (-2.0, 3.0));
        let h = format!(
            "{HEAD}DIMENSIONS 2 1 1\nPOINT_DATA 2\nSCALARS u unsigned_int\nLOOKUP_TABLE default\n"
        );
        let data = [3_000_000_000u32.to_be_bytes(), 7u32.to_be_bytes()].concat();
        let v = read(&write(dir.path(), "u.vtk", &binary(&h, &data, b""))).unwrap();
        assert_eq!(v.value(0, 0, 0), 3e9);
    }

    #[test]
    fn bad_dimensions_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            ("DIMENSIONS 4 4 0\nPOINT_DATA 0", "DIMENSIONS", "at least 1"),
            ("DIMENSIONS 4 -4 4\nPOINT_DATA 64", "DIMENSIONS", "negative"),
            (
                "DIMENSIONS 4 four 4\nPOINT_DATA 64",
                "DIMENSIONS",
                "not a whole number",
            ),
            (
                "DIMENSIONS 4294967296 4294967296 4294967296\nPOINT_DATA 1",
                "DIMENSIONS",
                "more than",
            ),
            ("DIMENSIONS 4 4\nPOINT_DATA 16", "DIMENSIONS", "3 numbers"),
            ("DIMENSIONS 4 4 4\nPOINT_DATA 60", "POINT_DATA", "64"),
            (
                "DIMENSIONS 4 4 8\nPOINT_DATA 128",
                "DIMENSIONS",
                "truncated",
            ),
            (
                "DIMENSIONS 4 4 4\nSPACING 1 0 1\nPOINT_DATA 64",
                "SPACING",
                "non-zero",
            ),
        ];
        for (i, (dims, field, why)) in cases.iter().enumerate() {
            let h = format!("{HEAD}{dims}\nSCALARS s unsigned_char\nLOOKUP_TABLE default\n");
            let name = format!("bad{i}.vtk");
            let p = write(dir.path(), &name, &binary(&h, &[0u8; 64], b"\n"));
            let s = err_naming(read(&p), &name, field);
            assert!(s.contains(why), "{dims}: {s}");
        }
    }

    #[test]
    fn truncated_and_lying_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let h = format!(
            "{HEAD}DIMENSIONS 4 4 4\nPOINT_DATA 64\nSCALARS s float\nLOOKUP_TABLE default\n"
        );
        let p = write(dir.path(), "short.vtk", &binary(&h, &[0u8; 255], b""));
        err_naming(read(&p), "short.vtk", "DIMENSIONS/SCALARS");

        // A 1 KB file claiming 10⁹ voxels is refused before allocating.
        let h = format!("{HEAD}DIMENSIONS 1000 1000 1000\nPOINT_DATA 1000000000\nSCALARS s unsigned_char\nLOOKUP_TABLE default\n");
        let p = write(dir.path(), "huge.vtk", &binary(&h, &[0u8; 1024], b""));
        let s = err_naming(read(&p), "huge.vtk", "DIMENSIONS/SCALARS");
        assert!(s.contains("1000000000"), "{s}");
        // The same in ASCII.
        let h = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 1000 1000 1000\nPOINT_DATA 1000000000\nSCALARS s float\nLOOKUP_TABLE default\n1 2 3\n";
        let p = write(dir.path(), "hugetext.vtk", h.as_bytes());
        err_naming(read(&p), "hugetext.vtk", "DIMENSIONS/SCALARS");
        // An array before the volume that runs past the end.
        let h = format!("{HEAD}DIMENSIONS 2 2 2\nPOINT_DATA 8\nVECTORS v float\n");
        let p = write(dir.path(), "vec.vtk", &binary(&h, &[0u8; 20], b""));
        err_naming(read(&p), "vec.vtk", "VECTORS");
    }

    #[test]
    fn unknown_and_unsupported_input_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            ("# vtk DataFile Version 3.0\nt\nBINARY\nDATASET POLYDATA\nPOINTS 3 float\n", "POLYDATA"),
            ("# vtk DataFile Version 3.0\nt\nBINARY\nDATASET STRUCTURED_GRID\n", "STRUCTURED_GRID"),
            ("# vtk DataFile Version 3.0\nt\nUTF-8\nDATASET STRUCTURED_POINTS\n", "ASCII/BINARY"),
            ("hello\n", "version line"),
            ("# vtk DataFile Version 3.0\n", "title"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\nPOINT_DATA 2\nSCALARS s complex\nLOOKUP_TABLE default\n"), "complex"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\nPOINT_DATA 2\nSCALARS s bit\nLOOKUP_TABLE default\n"), "SCALARS"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\nPOINT_DATA 2\nSCALARS s float 3\nLOOKUP_TABLE default\n"), "SCALARS"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\nSCALARS s float\nLOOKUP_TABLE default\n"), "SCALARS"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\nBOGUS 1\n"), "BOGUS"),
            ("# vtk DataFile Version 3.0\nt\nBINARY\nDIMENSIONS 2 1 1\nPOINT_DATA 2\n", "DATASET"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\nPOINT_DATA 2\n"), "SCALARS"),
            (&format!("{HEAD}DIMENSIONS 2 1 1\n"), "POINT_DATA"),
        ];
        for (i, (text, field)) in cases.iter().enumerate() {
            let name = format!("u{i}.vtk");
            err_naming(
                read(&write(dir.path(), &name, text.as_bytes())),
                &name,
                field,
            );
        }
    }

    #[test]
    fn mutated_files_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let h = format!("{HEAD}DIMENSIONS 2 2 1\nSPACING 1 1 1\nORIGIN 0 0 0\nCELL_DATA 1\nCOLOR_SCALARS c 2\n\x01\x02\nPOINT_DATA 4\nSCALARS s%20x float 1\nLOOKUP_TABLE default\n");
        let tail = [
            b"\nVECTORS v short\n".as_slice(),
            &[0u8; 24],
            b"\nFIELD f 2\na 1 4 unsigned_char\n\x01\x02\x03\x04\nb 2 4 double\n",
            &[0u8; 64],
        ]
        .concat();
        let data: Vec<u8> = [1.0f32, -2.0, 3.5, 4.0]
            .iter()
            .flat_map(|v| v.to_be_bytes())
            .collect();
        let base = binary(&h, &data, &tail);
        never_panics(read, dir.path(), "m.vtk", &base, base.len());
        let t = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 1 2\nPOINT_DATA 4\n\
                 SCALARS s unsigned_short\nLOOKUP_TABLE default\n1 2 3 4\nTEXTURE_COORDINATES t 2 float\n1 2 3 4 5 6 7 8\n\
                 LOOKUP_TABLE l 1\n0 0 0 1\nTENSORS6 x double\n";
        never_panics(read, dir.path(), "t.vtk", t.as_bytes(), t.len());
    }
}
