//! DICOM: a folder of slices, one multi-frame file, or the series a given
//! file belongs to (read from its folder, not searched recursively).
//!
//! Files: a `.dcm` or `.dcm.gz` extension or the `DICM` magic at byte 128.
//! Transfer syntaxes: Implicit/Explicit VR Little Endian, Explicit VR Big
//! Endian, Deflated Explicit VR, JPEG Baseline/Extended/Lossless (SV1 and
//! non-SV1), JPEG 2000 (lossless and lossy), RLE Lossless (dicom-pixeldata,
//! pure Rust), JPEG-LS with voxcast-native-io's `jpeg-ls` (CharLS, through
//! `io::external`). One sample per pixel (MONOCHROME1/2, values read as
//! stored), BitsAllocated 1, 8, 16 or 32, unsigned or signed, BitsStored <
//! BitsAllocated (masked or sign extended); pixel data longer than the
//! image (padding) is read and the rest ignored. RescaleSlope/RescaleIntercept (or RT Dose's
//! DoseGridScaling) are applied (CT gives HU, RT Dose Gy);
//! SeriesDescription becomes the volume's name.
//!
//! Multi-frame files: enhanced CT/MR (per-frame and shared functional
//! groups give each frame's position, orientation, spacing and rescale), RT
//! Dose grids (GridFrameOffsetVector along the slice normal), other
//! multi-frame images (frames in order, z spacing from the header).
//!
//! Geometry: x runs along the columns, y along the rows (so dims are
//! Columns × Rows × slices and the x spacing is the *second* PixelSpacing
//! value). Slices are ordered by the projection of ImagePositionPatient on
//! the slice normal (row cosine × column cosine), the z spacing is the
//! median gap between those projections and the origin is the position of
//! the first slice. The volume has no direction matrix: oblique series are
//! shown in their own (row, column, normal) frame.
//!
//! A folder: every file's header is read (pass 1); files that fail, are no
//! image (reports, RT plans, DICOMDIR) or cannot be decoded are skipped
//! with one warning listing them. The images are grouped by
//! SeriesInstanceUID, then by size, pixel layout and orientation (a 3-plane
//! localizer is three groups; a multi-frame file is a group of its own).
//! The largest group that forms a consistent volume is read, others are
//! noted; `--var UID` (or the index [`scan`] lists) picks another.
//!
//! Every length in a file is checked against the bytes present before the
//! parser or the decoder allocates (see `lengths`).
//!
//! Not supported: colour images, DICOMDIR navigation, files without the
//! file meta group.

mod header;
mod lengths;
mod pixels;
mod series;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_more;

use super::util::{natural_cmp, read_head};
use crate::error::{Error, Result};
use crate::volume::Volume;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

const IMPLICIT_LE: &str = "1.2.840.10008.1.2";
const EXPLICIT_LE: &str = "1.2.840.10008.1.2.1";
const EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";
const DEFLATED: &str = "1.2.840.10008.1.2.1.99";
const DICOMDIR_CLASS: &str = "1.2.840.10008.1.3.10";
const PIXEL_DATA_FIELD: &str = "PixelData (7FE0,0010)";

/// True when the folder holds at least one DICOM candidate (see
/// [`is_dicom_candidate`]; only the first 132 bytes are read).
pub fn folder_has_dicom(path: &Path) -> Result<bool> {
    for entry in std::fs::read_dir(path).map_err(|e| Error::io(path, e))? {
        let entry = entry.map_err(|e| Error::io(path, e))?;
        let p = entry.path();
        if p.is_file() && is_dicom_candidate(&p) {
            return Ok(true);
        }
    }
    Ok(false)
}

/// True for a `.dcm` or `.dcm.gz` name.
pub fn has_dcm_name(p: &Path) -> bool {
    let n = p
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    n.ends_with(".dcm") || n.ends_with(".dcm.gz")
}

/// A `.dcm`/`.dcm.gz` name or the `DICM` magic at byte 128.
pub fn is_dicom_candidate(p: &Path) -> bool {
    if has_dcm_name(p) {
        return true;
    }
    // An unreadable file is simply not a candidate: the folder scan must not
    // fail because of one stray file.
    matches!(read_head(p, 132), Ok(h) if h.len() == 132 && &h[128..132] == b"DICM")
}

/// One series (one consistent group of images) found in a folder.
#[derive(Clone, Debug, PartialEq)]
pub struct SeriesInfo {
    /// SeriesInstanceUID (empty when the files have none).
    pub uid: String,
    pub description: Option<String>,
    pub modality: Option<String>,
    pub files: usize,
    /// Slices in the volume (frames of all its files).
    pub frames: usize,
    pub rows: u32,
    pub columns: u32,
    /// The transfer syntaxes of its files, by name.
    pub transfer_syntaxes: Vec<String>,
    /// Why this group cannot be read as one volume, if it cannot.
    pub problem: Option<String>,
}

/// A file of the folder that is not read, and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Skipped {
    pub path: PathBuf,
    pub reason: String,
}

/// A group checked and ordered: its z spacing and the warnings to print
/// when it is read, or why it is not one volume.
type Prepared = Result<(f64, Vec<String>)>;

/// Pass 1's answer for one file (see `header::read_header`).
type Parsed = Result<std::result::Result<Option<header::FileHeader>, String>>;

/// What a folder holds: its series (largest first) and the files skipped.
#[derive(Debug)]
pub struct Scan {
    pub folder: PathBuf,
    pub series: Vec<SeriesInfo>,
    pub skipped: Vec<Skipped>,
    groups: Vec<(series::Group, Prepared)>,
    /// The file given (when a file, not a folder, was opened).
    wanted: Option<PathBuf>,
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// An error's message without the path it starts with.
fn reason_of(p: &Path, e: &Error) -> String {
    let s = e.to_string();
    let prefix = format!("{}: ", p.display());
    s.strip_prefix(&prefix).map(str::to_string).unwrap_or(s)
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// Reads the header of every DICOM file of the folder `path` (or of the
/// folder of the file `path`), groups the images into series and checks
/// which of them can be read.
pub fn scan(path: &Path) -> Result<Scan> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    let (folder, wanted) = if meta.is_dir() {
        (path.to_path_buf(), None)
    } else {
        let folder = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        (folder, Some(path.to_path_buf()))
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(&folder).map_err(|e| Error::io(&folder, e))? {
        let p = entry.map_err(|e| Error::io(&folder, e))?.path();
        if p.is_file() {
            files.push(p);
        }
    }
    files.sort_by(|a, b| natural_cmp(&file_name(a), &file_name(b)));
    let candidates: Vec<PathBuf> = files
        .into_par_iter()
        .filter(|p| is_dicom_candidate(p))
        .collect();

    // Pass 1: headers only (stops before PixelData), in parallel.
    let parsed: Vec<(PathBuf, Parsed)> = candidates
        .into_par_iter()
        .map(|p| {
            let r = header::read_header(&p);
            (p, r)
        })
        .collect();

    let mut images = Vec::new();
    let mut skipped = Vec::new();
    let mut n_dicom = 0usize;
    let mut n_dicomdir = 0usize;
    for (p, r) in parsed {
        let is_wanted = wanted.as_deref().is_some_and(|w| same_file(w, &p));
        let reason = match r {
            Ok(Ok(Some(h))) => match series::check_file(&h) {
                Ok(()) => {
                    n_dicom += 1;
                    images.push(h);
                    continue;
                }
                Err(e) => {
                    n_dicom += 1;
                    if is_wanted {
                        return Err(e);
                    }
                    reason_of(&p, &e)
                }
            },
            Ok(Ok(None)) => {
                n_dicom += 1;
                if is_wanted {
                    return Err(Error::format(
                        &p,
                        "Rows/Columns",
                        "this DICOM object is not an image (no Rows/Columns): give a slice of an image series or its folder",
                    ));
                }
                if file_name(&p) == "DICOMDIR" {
                    n_dicomdir += 1;
                }
                "not an image (no Rows/Columns: a report, plan, DICOMDIR or other non-image object)"
                    .to_string()
            }
            Ok(Err(msg)) => {
                if is_wanted {
                    return Err(Error::format(&p, "DICOM header", msg));
                }
                format!("not readable as DICOM: {msg}")
            }
            Err(e) => {
                if is_wanted {
                    return Err(e);
                }
                reason_of(&p, &e)
            }
        };
        skipped.push(Skipped { path: p, reason });
    }
    if images.is_empty() {
        let mut msg = if n_dicom == 0 && skipped.is_empty() {
            "no DICOM image slices in this folder (no file ends in .dcm or has the DICM magic at byte 128".to_string()
        } else if n_dicom == 0 {
            "no DICOM image slices in this folder (no readable DICOM file".to_string()
        } else {
            format!("no DICOM image slices in this folder ({n_dicom} DICOM file(s), none of them a readable image")
        };
        if n_dicomdir > 0 {
            msg.push_str("; one is a DICOMDIR: open the series folders it lists");
        }
        msg.push(')');
        if let Some(s) = skipped.first() {
            msg.push_str(&format!("; skipped: {}: {}", s.path.display(), s.reason));
            if skipped.len() > 1 {
                msg.push_str(&format!(" (and {} more)", skipped.len() - 1));
            }
        }
        return Err(Error::format(&folder, "DICOM files", msg));
    }

    let mut groups: Vec<(series::Group, Prepared)> = series::group(images)
        .into_iter()
        .map(|mut g| {
            let r = series::prepare(&folder, &mut g);
            (g, r)
        })
        .collect();
    // Largest first; ties keep the order of first appearance.
    groups.sort_by_key(|(g, _)| std::cmp::Reverse(g.slices.len()));
    let series = groups
        .iter()
        .map(|(g, r)| {
            let mut ts: Vec<String> = Vec::new();
            for f in &g.files {
                let name = format!(
                    "{} ({})",
                    transfer_syntax_name(&f.transfer_syntax),
                    f.transfer_syntax
                );
                if !ts.contains(&name) {
                    ts.push(name);
                }
            }
            let first = g.first();
            SeriesInfo {
                uid: first.series_uid.clone(),
                description: first.series_description.clone(),
                modality: first.modality.clone(),
                files: g.files.len(),
                frames: g.slices.len(),
                rows: first.rows,
                columns: first.columns,
                transfer_syntaxes: ts,
                problem: r.as_ref().err().map(|e| e.to_string()),
            }
        })
        .collect();
    Ok(Scan {
        folder,
        series,
        skipped,
        groups,
        wanted,
    })
}

impl Scan {
    /// Index of the series to read: the one `choice` names (its index in
    /// [`Scan::series`], or its SeriesInstanceUID), else the one holding
    /// the file given, else the largest one that is consistent.
    pub fn choose(&self, choice: Option<&str>) -> Result<usize> {
        if let Some(c) = choice {
            let c = c.trim();
            if let Ok(i) = c.parse::<usize>() {
                if i < self.series.len() {
                    return Ok(i);
                }
            }
            // A UID may name several groups (orientations): the largest
            // consistent one, else the largest.
            let by_uid: Vec<usize> = (0..self.series.len())
                .filter(|&i| self.series[i].uid == c)
                .collect();
            if let Some(&i) = by_uid
                .iter()
                .find(|&&i| self.series[i].problem.is_none())
                .or(by_uid.first())
            {
                return Ok(i);
            }
            return Err(Error::format(
                &self.folder,
                "--var",
                format!(
                    "\"{c}\" is not a series here; give an index or a SeriesInstanceUID: {}",
                    self.list().join("; ")
                ),
            ));
        }
        if let Some(w) = &self.wanted {
            if let Some(i) = self
                .groups
                .iter()
                .position(|(g, _)| g.files.iter().any(|f| same_file(&f.path, w)))
            {
                return Ok(i);
            }
        }
        Ok(self
            .series
            .iter()
            .position(|s| s.problem.is_none())
            .unwrap_or(0))
    }

    /// One line per series: index, UID, description, size, frames.
    pub fn list(&self) -> Vec<String> {
        self.series
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let uid = if s.uid.is_empty() {
                    "(no SeriesInstanceUID)"
                } else {
                    s.uid.as_str()
                };
                let mut l = format!(
                    "[{i}] {uid} \"{}\" {} {}×{}, {} frame(s) in {} file(s), {}",
                    s.description.as_deref().unwrap_or(""),
                    s.modality.as_deref().unwrap_or("?"),
                    s.columns,
                    s.rows,
                    s.frames,
                    s.files,
                    s.transfer_syntaxes.join(", ")
                );
                if let Some(p) = &s.problem {
                    l.push_str(&format!(" — not readable as one volume: {p}"));
                }
                l
            })
            .collect()
    }

    /// The warning line listing the skipped files, if any.
    pub fn skipped_line(&self) -> Option<String> {
        if self.skipped.is_empty() {
            return None;
        }
        let list: Vec<String> = self
            .skipped
            .iter()
            .map(|s| format!("{} ({})", file_name(&s.path), s.reason))
            .collect();
        Some(format!(
            "warning: {}: skipped {} file(s): {}",
            self.folder.display(),
            self.skipped.len(),
            list.join("; ")
        ))
    }

    /// Reads series `i` as a volume.
    pub fn read(mut self, i: usize) -> Result<Volume> {
        let (g, r) = self.groups.swap_remove(i);
        let (z, notes) = r?;
        for n in notes {
            eprintln!("{n}");
        }
        pixels::assemble(&g, z)
    }
}

/// Reads a DICOM series: the folder `path`'s largest consistent series, or
/// the one `opts.variable` names (index or SeriesInstanceUID), or the series
/// the file `path` belongs to.
pub fn read(path: &Path, opts: &super::OpenOptions) -> Result<Volume> {
    let s = scan(path)?;
    if let Some(l) = s.skipped_line() {
        eprintln!("{l}");
    }
    let i = s.choose(opts.variable.as_deref())?;
    if s.series.len() > 1 {
        eprintln!(
            "note: {} holds {} DICOM series; reading [{i}] (pick another with --var INDEX or --var SERIES_UID):",
            s.folder.display(),
            s.series.len()
        );
        for l in s.list() {
            eprintln!("note:   {l}");
        }
    }
    let mut uids: Vec<String> = s
        .series
        .iter()
        .map(|x| x.uid.clone())
        .filter(|u| !u.is_empty())
        .collect();
    uids.dedup();
    let mut v = s.read(i)?;
    if uids.len() > 1 {
        v.variables = uids;
    }
    Ok(v)
}

/// Lines for `voxcast info`: the series found (the one read, by `choice`
/// as for `--var`, marked), their frames and transfer syntaxes, and the
/// files skipped.
pub fn summary(path: &Path, choice: Option<&str>) -> Result<Vec<String>> {
    let s = scan(path)?;
    let chosen = s.choose(choice)?;
    let mut lines: Vec<String> = s
        .list()
        .into_iter()
        .enumerate()
        .map(|(i, l)| {
            if i == chosen {
                format!("{l}  (read)")
            } else {
                l
            }
        })
        .collect();
    for k in &s.skipped {
        lines.push(format!("skipped {}: {}", file_name(&k.path), k.reason));
    }
    Ok(lines)
}

fn transfer_syntax_name(uid: &str) -> &'static str {
    match uid {
        IMPLICIT_LE => "Implicit VR Little Endian",
        EXPLICIT_LE => "Explicit VR Little Endian",
        EXPLICIT_BE => "Explicit VR Big Endian",
        DEFLATED => "Deflated Explicit VR Little Endian",
        "1.2.840.10008.1.2.4.50" => "JPEG Baseline (Process 1)",
        "1.2.840.10008.1.2.4.51" => "JPEG Extended (Process 2 & 4)",
        "1.2.840.10008.1.2.4.57" => "JPEG Lossless, Non-Hierarchical (Process 14)",
        "1.2.840.10008.1.2.4.70" => "JPEG Lossless, First-Order Prediction (Process 14, SV1)",
        "1.2.840.10008.1.2.4.80" => "JPEG-LS Lossless",
        "1.2.840.10008.1.2.4.81" => "JPEG-LS Near-Lossless",
        "1.2.840.10008.1.2.4.90" => "JPEG 2000 (Lossless Only)",
        "1.2.840.10008.1.2.4.91" => "JPEG 2000",
        "1.2.840.10008.1.2.4.92" => "JPEG 2000 Part 2 Multi-component (Lossless Only)",
        "1.2.840.10008.1.2.4.93" => "JPEG 2000 Part 2 Multi-component",
        "1.2.840.10008.1.2.4.201" => "High-Throughput JPEG 2000 (Lossless Only)",
        "1.2.840.10008.1.2.4.202" => "High-Throughput JPEG 2000 with RPCL (Lossless Only)",
        "1.2.840.10008.1.2.4.203" => "High-Throughput JPEG 2000",
        "1.2.840.10008.1.2.5" => "RLE Lossless",
        u if u.starts_with("1.2.840.10008.1.2.4.10") => "MPEG video",
        _ => "unknown transfer syntax",
    }
}
