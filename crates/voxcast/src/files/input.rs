//! Opening input files: every file voxcast reads by path comes through
//! [`open`], which refuses what is not a regular file (a folder, a device
//! such as `/dev/zero`, a FIFO, a socket) before a byte is read, and — in a
//! process that runs one command, after [`record_inputs`] — remembers what
//! it opened so that no output can be written over it ([`was_read`]).

use crate::error::{Error, Result};
use serde::de::DeserializeOwned;
use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// Text files (scenes, transfer functions, geometry, manifests, headers)
/// larger than this are refused: no real one comes near it.
pub const MAX_TEXT_BYTES: u64 = 64 << 20;

/// One file this process has opened for reading.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Identity {
    path: PathBuf,
    /// (device, inode, modification time in ns): the same file under another
    /// name (a hard link). The time tells a new file that reuses the inode
    /// of a deleted one from the file that was read.
    #[cfg(unix)]
    inode: (u64, u64, i64),
}

static READ: Mutex<Vec<Identity>> = Mutex::new(Vec::new());
static RECORD: AtomicBool = AtomicBool::new(false);

/// From now on, remember every file opened as an input, so that
/// [`was_read`] knows it: for a process that runs one command (the CLI,
/// whose outputs must never land on what it read). A long-lived process (a
/// viewer session, a Python kernel) that reads and writes files over hours
/// should not call it.
pub fn record_inputs() {
    RECORD.store(true, Ordering::Relaxed);
}

fn identity(path: &Path, meta: &std::fs::Metadata) -> Identity {
    #[cfg(not(unix))]
    let _ = meta;
    Identity {
        path: path.canonicalize().unwrap_or_else(|_| path.to_path_buf()),
        #[cfg(unix)]
        inode: {
            use std::os::unix::fs::MetadataExt;
            (
                meta.dev(),
                meta.ino(),
                meta.mtime() * 1_000_000_000 + meta.mtime_nsec(),
            )
        },
    }
}

/// What kind of thing `meta` describes, for an error message.
fn kind_name(meta: &std::fs::Metadata) -> &'static str {
    let t = meta.file_type();
    if t.is_dir() {
        return "a folder";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_char_device() || t.is_block_device() {
            return "a device";
        }
        if t.is_fifo() {
            return "a pipe (FIFO)";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "not a regular file"
}

/// Metadata of `path` (following links), refusing anything but a regular
/// file with an error that says what it is.
pub fn regular_file(path: &Path) -> Result<std::fs::Metadata> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::invalid(format!(
            "{}: is {}; expected a regular file",
            crate::error::quote_path(path),
            kind_name(&meta)
        )));
    }
    Ok(meta)
}

/// Opens `path` for reading: a regular file only, remembered as an input.
/// Returns the file and its size.
pub fn open(path: &Path) -> Result<(File, u64)> {
    open_as(path, true)
}

/// [`open`], remembering the file as an input or not (a file voxcast keeps
/// for itself, such as the manifest of the series it is writing).
fn open_as(path: &Path, input: bool) -> Result<(File, u64)> {
    let meta = regular_file(path)?;
    let f = File::open(path).map_err(|e| Error::io(path, e))?;
    if input && RECORD.load(Ordering::Relaxed) {
        let id = identity(path, &meta);
        let mut read = READ.lock().unwrap_or_else(|p| p.into_inner());
        if !read.contains(&id) {
            read.push(id);
        }
    }
    Ok((f, meta.len()))
}

/// Reads a whole file of at most `max` bytes (the size is checked before
/// anything is read).
pub fn read_bytes(path: &Path, max: u64) -> Result<Vec<u8>> {
    read_bytes_as(path, max, true)
}

fn read_bytes_as(path: &Path, max: u64, input: bool) -> Result<Vec<u8>> {
    let (f, len) = open_as(path, input)?;
    if len > max {
        return Err(Error::format(
            path,
            "size",
            format!("the file holds {len} bytes; files of this kind are at most {max}"),
        ));
    }
    let mut buf = Vec::with_capacity(len as usize);
    f.take(max)
        .read_to_end(&mut buf)
        .map_err(|e| Error::io(path, e))?;
    Ok(buf)
}

/// Reads a UTF-8 text file of at most [`MAX_TEXT_BYTES`].
pub fn read_text(path: &Path) -> Result<String> {
    read_text_as(path, true)
}

fn read_text_as(path: &Path, input: bool) -> Result<String> {
    let bytes = read_bytes_as(path, MAX_TEXT_BYTES, input)?;
    String::from_utf8(bytes).map_err(|e| {
        Error::format(
            path,
            "text",
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// Reads and parses a TOML file as `T`. Errors name the line; an unknown
/// key is refused with the nearest known one (a typo must not pass
/// unnoticed).
pub fn read_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text(path)?;
    parse_toml(path, &text)
}

/// [`read_toml`] for a file voxcast keeps for itself and may rewrite (the
/// manifest of a series it is writing): not remembered as an input.
pub fn read_own_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text = read_text_as(path, false)?;
    parse_toml(path, &text)
}

/// Parses TOML `text` read from `path` (see [`read_toml`]).
pub fn parse_toml<T: DeserializeOwned>(path: &Path, text: &str) -> Result<T> {
    toml::from_str(text).map_err(|e| {
        let field = e
            .span()
            .map(|s| {
                text.as_bytes()[..s.start.min(text.len())]
                    .iter()
                    .filter(|&&b| b == b'\n')
                    .count()
                    + 1
            })
            .map(|l| format!("line {l}"))
            .unwrap_or_else(|| "toml".into());
        Error::format(path, field, did_you_mean(e.message()))
    })
}

/// Adds "did you mean `x`?" to serde's "unknown field `y`, expected one of
/// `a`, `b`, …" (or "unknown variant …") when one known name is close.
pub fn did_you_mean(message: &str) -> String {
    let Some(rest) = message
        .strip_prefix("unknown field `")
        .or_else(|| message.strip_prefix("unknown variant `"))
    else {
        return message.to_string();
    };
    let Some((bad, expected)) = rest.split_once('`') else {
        return message.to_string();
    };
    let known: Vec<&str> = expected
        .split('`')
        .skip(1)
        .step_by(2)
        .filter(|s| !s.is_empty())
        .collect();
    let best = known
        .iter()
        .map(|k| (edit_distance(bad, k), *k))
        .min()
        .filter(|(d, k)| *d <= (k.len().max(bad.len()) / 3).max(1));
    match best {
        Some((_, k)) => format!("{message}; did you mean `{k}`?"),
        None => message.to_string(),
    }
}

/// Edit distance counting a swap of neighbours as one edit (optimal
/// string alignment), for typos such as `stpe`.
fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = v;
        }
    }
    d[a.len()][b.len()]
}

/// True when `path` (existing) is a file this process has read.
pub fn was_read(path: &Path) -> bool {
    let Ok(meta) = std::fs::metadata(path) else {
        return false;
    };
    let id = identity(path, &meta);
    let read = READ.lock().unwrap_or_else(|p| p.into_inner());
    read.iter().any(|r| {
        #[cfg(unix)]
        if r.inode == id.inode {
            return true;
        }
        r.path == id.path
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_fifos_and_folders_are_refused_before_reading() {
        let e = read_text(Path::new("/dev/zero")).unwrap_err().to_string();
        assert!(e.contains("/dev/zero") && e.contains("a device"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let e = open(dir.path()).unwrap_err().to_string();
        assert!(e.contains("a folder"), "{e}");
        #[cfg(unix)]
        {
            let fifo = dir.path().join("pipe");
            let ok = std::process::Command::new("mkfifo")
                .arg(&fifo)
                .status()
                .is_ok_and(|s| s.success());
            if ok {
                let e = open(&fifo).unwrap_err().to_string();
                assert!(e.contains("FIFO"), "{e}");
            }
        }
    }

    #[test]
    fn oversized_text_is_refused_by_its_size() {
        let e = read_bytes(Path::new("Cargo.toml"), 3)
            .unwrap_err()
            .to_string();
        assert!(e.contains("at most 3"), "{e}");
    }

    #[test]
    fn unknown_keys_get_the_nearest_known_one() {
        let m = did_you_mean(
            "unknown field `azimth`, expected one of `projection`, `azimuth`, `elevation`",
        );
        assert!(m.ends_with("did you mean `azimuth`?"), "{m}");
        let m = did_you_mean("unknown field `qqqqqq`, expected `zoom` or `fov`");
        assert!(!m.contains("did you mean"), "{m}");
        let m = did_you_mean("unknown field `fob`, expected `zoom` or `fov`");
        assert!(m.ends_with("did you mean `fov`?"), "{m}");
        let m = did_you_mean("unknown field `stpe`, expected `width` or `step`");
        assert!(m.ends_with("did you mean `step`?"), "{m}");
    }
}
