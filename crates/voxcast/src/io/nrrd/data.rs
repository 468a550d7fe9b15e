//! Where the data lives (attached, one file, a `LIST`, a `%d` pattern) and
//! how one data file's bytes are read: line and byte skips, raw, gzip,
//! bzip2 or ascii.

use super::header::{Encoding, Header};
use crate::error::{Error, Result};
use crate::io::decode::*;
use crate::io::util::{file_len, read_bzip2_and_count_rest, read_gzip_and_count_rest};
use crate::volume::VoxelData;
use std::path::{Path, PathBuf};

/// Where the data lives.
pub(super) enum DataFiles {
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
    pub(super) fn len(&self) -> u64 {
        match self {
            DataFiles::Attached | DataFiles::Single(_) => 1,
            DataFiles::List { names, .. } => names.len() as u64,
            DataFiles::Pattern(p) => p.count,
        }
    }

    pub(super) fn subdim(&self) -> Option<usize> {
        match self {
            DataFiles::List { subdim, .. } => *subdim,
            DataFiles::Pattern(p) => p.subdim,
            _ => None,
        }
    }

    /// The path of data file `i`, relative names taken from the header's folder.
    pub(super) fn path(&self, header: &Path, i: u64) -> Result<PathBuf> {
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

pub(super) fn data_files(path: &Path, header: &Header) -> Result<DataFiles> {
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
        let count = crate::io::util::pattern_count(min, max, step).ok_or_else(|| {
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

/// How the bytes of every data file are laid out.
pub(super) struct Layout {
    pub(super) ty: StoredType,
    pub(super) big_endian: bool,
    pub(super) encoding: Encoding,
    pub(super) line_skip: u64,
    pub(super) byte_skip: i64,
}

/// Reads `count` voxels from `file`, whose data (before skips) start at `start`.
pub(super) fn read_chunk(file: &Path, start: u64, count: usize, l: &Layout) -> Result<VoxelData> {
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
