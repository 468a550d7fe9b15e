//! The NRRD header: the magic line, `field: value` lines (old spellings
//! mapped, `key:=value` pairs skipped, a `data file: LIST` followed by its
//! names), and the `type:` and `encoding:` values.

use crate::error::{Error, Result};
use crate::io::decode::{check_header_size, shorten, LineReader, StoredType};
use std::path::Path;

/// The fields of a NRRD header and where its attached data would start.
pub(super) struct Header {
    pub(super) fields: Vec<(String, String)>,
    /// File names listed after `data file: LIST`.
    pub(super) list: Option<Vec<String>>,
    /// Byte just after the blank line that ends the header.
    pub(super) data_start: u64,
}

impl Header {
    pub(super) fn get(&self, key: &str) -> Option<&str> {
        self.fields
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }
}

pub(super) fn required_field<'h>(
    path: &Path,
    header: &'h Header,
    key: &'static str,
) -> Result<&'h str> {
    header
        .get(key)
        .ok_or_else(|| Error::format(path, key, "missing: a NRRD header needs this field"))
}

pub(super) fn read_header(path: &Path) -> Result<Header> {
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

pub(super) fn parse_type(path: &Path, s: &str) -> Result<StoredType> {
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
pub(super) enum Encoding {
    Raw,
    Gzip,
    Bzip2,
    Ascii,
}

pub(super) fn parse_encoding(path: &Path, s: &str) -> Result<Encoding> {
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
