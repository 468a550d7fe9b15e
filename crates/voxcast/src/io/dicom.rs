//! DICOM series: one single-frame image per file, all files of a series in
//! one folder (not searched recursively).
//!
//! Supported: files with a `.dcm` extension or the `DICM` magic at byte 128,
//! native (uncompressed) pixel data in Implicit VR Little Endian, Explicit VR
//! Little Endian and Explicit VR Big Endian; one sample per pixel
//! (MONOCHROME1/2, values read as stored), BitsAllocated 8 or 16, unsigned or
//! signed (i8 is widened to i16), BitsStored < BitsAllocated (masked or sign
//! extended). RescaleSlope/RescaleIntercept are applied (CT gives i16 HU and
//! `units = "HU"`); SeriesDescription becomes the volume's name.
//!
//! Geometry: x runs along the columns, y along the rows (so dims are
//! Columns × Rows × slices and the x spacing is the *second* PixelSpacing
//! value). Slices are ordered by the projection of ImagePositionPatient on
//! the slice normal (row cosine × column cosine), the z spacing is the
//! median gap between those projections and the origin is the position of
//! the first slice. The volume has no direction matrix: oblique series are
//! shown in their own (row, column, normal) frame.
//!
//! Not supported: compressed transfer syntaxes (JPEG, JPEG-LS, JPEG 2000,
//! RLE, deflate, …: an `Unsupported` error names the UID), multi-frame
//! files (enhanced CT/MR), colour images, 32-bit or float pixel data,
//! files without the file meta group, DICOMDIR navigation.
//!
//! A folder may hold several series: the one with the most slices is read
//! and the others are listed on stderr. Given a single file, the series it
//! belongs to is read from its folder.

use super::util::{check_dims, natural_cmp, read_head};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume, VoxelData};
use dicom_dictionary_std::tags;
use dicom_object::{OpenFileOptions, Tag};
use glam::Vec3;
use rayon::prelude::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

const IMPLICIT_LE: &str = "1.2.840.10008.1.2";
const EXPLICIT_LE: &str = "1.2.840.10008.1.2.1";
const EXPLICIT_BE: &str = "1.2.840.10008.1.2.2";
const DICOMDIR_CLASS: &str = "1.2.840.10008.1.3.10";
const PIXEL_DATA_FIELD: &str = "PixelData (7FE0,0010)";

/// Two slices closer than this along the normal (mm) are the same position.
const SAME_POSITION_MM: f64 = 1e-4;

/// True when the folder holds at least one file ending in `.dcm` or with
/// the `DICM` magic at byte 128 (only the first 132 bytes are read).
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

fn has_dcm_extension(p: &Path) -> bool {
    p.extension()
        .map(|e| e.eq_ignore_ascii_case("dcm"))
        .unwrap_or(false)
}

fn is_dicom_candidate(p: &Path) -> bool {
    if has_dcm_extension(p) {
        return true;
    }
    // An unreadable file is simply not a candidate: the folder scan must not
    // fail because of one stray file.
    matches!(read_head(p, 132), Ok(h) if h.len() == 132 && &h[128..132] == b"DICM")
}

/// Reads the DICOM series in folder `path`, or the series that the file
/// `path` belongs to (read from the file's folder).
pub fn read(path: &Path) -> Result<Volume> {
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
    type Parsed = Result<std::result::Result<Option<SliceHeader>, String>>;
    let parsed: Vec<(PathBuf, Parsed)> = candidates
        .into_par_iter()
        .map(|p| {
            let r = check_lengths(&p).and_then(|()| read_header(&p));
            (p, r)
        })
        .collect();

    let mut slices = Vec::new();
    let mut n_dicom = 0usize;
    let mut n_dicomdir = 0usize;
    let mut first_failure: Option<String> = None;
    for (p, r) in parsed {
        let is_wanted = wanted.as_deref().is_some_and(|w| same_file(w, &p));
        match r? {
            Ok(Some(h)) => {
                n_dicom += 1;
                slices.push(h);
            }
            Ok(None) => {
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
            }
            Err(msg) => {
                if is_wanted {
                    return Err(Error::format(&p, "DICOM header", msg));
                }
                eprintln!(
                    "warning: {}: skipped, not readable as DICOM: {msg}",
                    p.display()
                );
                first_failure.get_or_insert(format!("{}: {msg}", p.display()));
            }
        }
    }
    if slices.is_empty() {
        let mut msg = if n_dicom == 0 {
            "no DICOM image slices in this folder (no file ends in .dcm or has the DICM magic at byte 128".to_string()
        } else {
            format!("no DICOM image slices in this folder ({n_dicom} DICOM file(s), none of them an image")
        };
        if n_dicomdir > 0 {
            msg.push_str("; one is a DICOMDIR: open the series folders it lists");
        }
        msg.push(')');
        if let Some(f) = first_failure {
            msg.push_str(&format!("; unreadable: {f}"));
        }
        return Err(Error::format(&folder, "DICOM files", msg));
    }

    let series = select_series(&folder, slices, wanted.as_deref())?;
    assemble(&folder, series)
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

/// What pass 1 learns from one image file.
#[derive(Clone, Debug)]
struct SliceHeader {
    path: PathBuf,
    transfer_syntax: String,
    series_uid: String,
    series_description: Option<String>,
    modality: Option<String>,
    rows: u32,
    columns: u32,
    bits_allocated: u16,
    bits_stored: u16,
    high_bit: u16,
    pixel_representation: u16,
    samples_per_pixel: u16,
    frames: u32,
    photometric: Option<String>,
    position: Option<[f64; 3]>,
    orientation: Option<[f64; 6]>,
    instance_number: Option<i64>,
    pixel_spacing: Option<[f64; 2]>,
    slice_thickness: Option<f64>,
    spacing_between_slices: Option<f64>,
    slope: f64,
    intercept: f64,
}

type Obj = dicom_object::DefaultDicomObject;

fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        let m = c.to_string();
        if !s.contains(&m) {
            s.push_str(": ");
            s.push_str(&m);
        }
        cur = c.source();
    }
    s
}

fn get_str(obj: &Obj, tag: Tag) -> Option<String> {
    let s = obj.get(tag)?.to_str().ok()?;
    let s = s.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    (!s.is_empty()).then(|| s.to_string())
}

/// An optional integer attribute; present but unreadable is an error.
fn get_int(obj: &Obj, path: &Path, tag: Tag, name: &str) -> Result<Option<i64>> {
    match obj.get(tag) {
        None => Ok(None),
        Some(e) => {
            if e.to_bytes().map(|b| b.is_empty()).unwrap_or(false) {
                return Ok(None);
            }
            e.to_int::<i64>()
                .map(Some)
                .map_err(|err| Error::format(path, name, format!("not an integer ({err})")))
        }
    }
}

fn get_floats<const N: usize>(obj: &Obj, tag: Tag) -> Option<[f64; N]> {
    let v = obj.get(tag)?.to_multi_float64().ok()?;
    let a: [f64; N] = v.get(..N)?.try_into().ok()?;
    a.iter().all(|x| x.is_finite()).then_some(a)
}

fn get_float(obj: &Obj, tag: Tag) -> Option<f64> {
    get_floats::<1>(obj, tag).map(|a| a[0])
}

/// Checks every element length the parser would trust against the bytes
/// left in the file, before dicom-parser sees the file: it allocates (and
/// zero-fills) whatever an element header claims, up to 4 GiB, before it
/// finds that the file is shorter. Walks the file meta group and the data
/// set flatly (nested items are walked in place); where the encoding gets
/// unusual (deflate, UN of undefined length, unknown VRs) it stops checking
/// and leaves the file to the parser.
fn check_lengths(path: &Path) -> Result<()> {
    use std::io::{BufReader, Read};
    const UNDEFINED: u32 = u32::MAX;
    let file = crate::files::open(path)?.0;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut r = BufReader::new(file);
    let mut pos = 0u64;
    let mut head = [0u8; 132];
    if r.read_exact(&mut head).is_err() {
        return Ok(());
    }
    if &head[128..132] == b"DICM" {
        pos = 132;
    } else if head[..2] == [2, 0] {
        r.seek_relative(-132).map_err(|e| Error::io(path, e))?;
    } else {
        return Ok(());
    }

    let mut ts = String::new();
    let mut explicit = true;
    let mut big = false;
    let mut in_meta = true;
    let mut in_fragments = false;
    loop {
        let mut b = [0u8; 4];
        if len - pos < 8 || r.read_exact(&mut b).is_err() {
            return Ok(());
        }
        pos += 4;
        let u16_at = |b: [u8; 2], big: bool| {
            if big {
                u16::from_be_bytes(b)
            } else {
                u16::from_le_bytes(b)
            }
        };
        let (mut g, mut e) = (u16_at([b[0], b[1]], false), u16_at([b[2], b[3]], false));
        if in_meta && g != 2 {
            // The data set starts: its encoding comes from the meta group.
            in_meta = false;
            match ts.as_str() {
                IMPLICIT_LE => explicit = false,
                EXPLICIT_BE => big = true,
                "1.2.840.10008.1.2.1.99" => return Ok(()),
                _ => {}
            }
        }
        if big {
            (g, e) = (
                u16::from_be_bytes([b[0], b[1]]),
                u16::from_be_bytes([b[2], b[3]]),
            );
        }
        let read_u32 = |r: &mut BufReader<std::fs::File>, pos: &mut u64| -> Option<u32> {
            let mut x = [0u8; 4];
            r.read_exact(&mut x).ok()?;
            *pos += 4;
            Some(if big {
                u32::from_be_bytes(x)
            } else {
                u32::from_le_bytes(x)
            })
        };
        let field = || {
            if (g, e) == (0x7FE0, 0x0010) {
                PIXEL_DATA_FIELD.to_string()
            } else {
                format!("({g:04X},{e:04X})")
            }
        };
        let too_long = |n: u32, left: u64| {
            Error::format(
                path,
                field(),
                format!("the element claims {n} bytes but only {left} remain in the file (truncated or corrupt file)"),
            )
        };
        if g == 0xFFFE {
            let Some(n) = read_u32(&mut r, &mut pos) else {
                return Ok(());
            };
            match e {
                // A fragment of encapsulated pixel data holds bytes, an item
                // of a sequence holds elements (walked in place).
                0xE000 if in_fragments => {
                    if n as u64 > len - pos {
                        return Err(too_long(n, len - pos));
                    }
                    r.seek_relative(n as i64).map_err(|e| Error::io(path, e))?;
                    pos += n as u64;
                }
                0xE000 => {
                    if n != UNDEFINED && n as u64 > len - pos {
                        return Err(too_long(n, len - pos));
                    }
                }
                0xE0DD => in_fragments = false,
                0xE00D => {}
                // Any other (FFFE,xxxx) is read as a value of that length.
                _ if n == UNDEFINED => return Ok(()),
                _ => {
                    if n as u64 > len - pos {
                        return Err(too_long(n, len - pos));
                    }
                    r.seek_relative(n as i64).map_err(|e| Error::io(path, e))?;
                    pos += n as u64;
                }
            }
            continue;
        }
        let (vr, n) = if explicit || in_meta {
            let mut v = [0u8; 2];
            if r.read_exact(&mut v).is_err() {
                return Ok(());
            }
            pos += 2;
            // Same rule as dicom-encoding: these VRs have a 2-byte length,
            // every other one (unknown VRs too, read as UN) a 4-byte length.
            let long = !matches!(
                &v,
                b"AE"
                    | b"AS"
                    | b"AT"
                    | b"CS"
                    | b"DA"
                    | b"DS"
                    | b"DT"
                    | b"FL"
                    | b"FD"
                    | b"IS"
                    | b"LO"
                    | b"LT"
                    | b"PN"
                    | b"SH"
                    | b"SL"
                    | b"SS"
                    | b"ST"
                    | b"TM"
                    | b"UI"
                    | b"UL"
                    | b"US"
            );
            let n = if long {
                let mut skip = [0u8; 2];
                if r.read_exact(&mut skip).is_err() {
                    return Ok(());
                }
                pos += 2;
                let Some(n) = read_u32(&mut r, &mut pos) else {
                    return Ok(());
                };
                n
            } else {
                let mut x = [0u8; 2];
                if r.read_exact(&mut x).is_err() {
                    return Ok(());
                }
                pos += 2;
                u16_at(x, big && !in_meta) as u32
            };
            (Some(v), n)
        } else {
            let Some(n) = read_u32(&mut r, &mut pos) else {
                return Ok(());
            };
            (None, n)
        };
        if n == UNDEFINED {
            match vr.as_ref() {
                Some(b"SQ") | None if (g, e) != (0x7FE0, 0x0010) => {}
                Some(b"UN") => return Ok(()),
                _ => in_fragments = true,
            }
            continue;
        }
        if n as u64 > len - pos {
            return Err(too_long(n, len - pos));
        }
        if vr.as_ref() == Some(b"SQ") {
            continue;
        }
        if vr.is_none() && n >= 8 {
            // Implicit VR does not say which elements are sequences; a value
            // that starts with an item tag is one, and is walked in place.
            let mut peek = [0u8; 4];
            if r.read_exact(&mut peek).is_err() {
                return Ok(());
            }
            r.seek_relative(-4).map_err(|e| Error::io(path, e))?;
            if peek == [0xFE, 0xFF, 0x00, 0xE0] {
                continue;
            }
        }
        if in_meta && (g, e) == (0x0002, 0x0010) && n <= 64 {
            let mut v = vec![0u8; n as usize];
            if r.read_exact(&mut v).is_err() {
                return Ok(());
            }
            ts = String::from_utf8_lossy(&v)
                .trim_end_matches(['\0', ' '])
                .to_string();
        } else {
            r.seek_relative(n as i64).map_err(|e| Error::io(path, e))?;
        }
        pos += n as u64;
    }
}

/// Pass 1 on one file. The inner `Err` is a file that does not parse as
/// DICOM (skipped with a warning), `Ok(None)` a DICOM object that is not an
/// image (no Rows/Columns: structured reports, presentation states,
/// DICOMDIR); the outer `Err` an image whose attributes are unusable.
fn read_header(path: &Path) -> Result<std::result::Result<Option<SliceHeader>, String>> {
    let obj = match OpenFileOptions::new()
        .read_until(tags::PIXEL_DATA)
        .open_file(path)
    {
        Ok(o) => o,
        Err(e) => return Ok(Err(error_chain(&e))),
    };
    let ts = obj.meta().transfer_syntax().to_string();
    if obj.meta().media_storage_sop_class_uid() == DICOMDIR_CLASS {
        return Ok(Ok(None));
    }
    let rows = get_int(&obj, path, tags::ROWS, "Rows")?;
    let columns = get_int(&obj, path, tags::COLUMNS, "Columns")?;
    let (Some(rows), Some(columns)) = (rows, columns) else {
        return Ok(Ok(None));
    };
    let u16_field = |tag: Tag, name: &str, default: Option<u16>| -> Result<u16> {
        match get_int(&obj, path, tag, name)? {
            Some(v) => u16::try_from(v)
                .map_err(|_| Error::format(path, name, format!("{v} is out of range"))),
            None => {
                default.ok_or_else(|| Error::format(path, name, "missing (required for an image)"))
            }
        }
    };
    let to_u32 = |v: i64, name: &str| {
        u32::try_from(v).map_err(|_| Error::format(path, name, format!("{v} is out of range")))
    };
    let bits_allocated = u16_field(tags::BITS_ALLOCATED, "BitsAllocated", None)?;
    let bits_stored = u16_field(tags::BITS_STORED, "BitsStored", Some(bits_allocated))?;
    let high_bit = u16_field(
        tags::HIGH_BIT,
        "HighBit",
        Some(bits_stored.saturating_sub(1)),
    )?;
    let frames = get_int(&obj, path, tags::NUMBER_OF_FRAMES, "NumberOfFrames")?.unwrap_or(1);
    Ok(Ok(Some(SliceHeader {
        path: path.to_path_buf(),
        transfer_syntax: ts,
        series_uid: get_str(&obj, tags::SERIES_INSTANCE_UID).unwrap_or_default(),
        series_description: get_str(&obj, tags::SERIES_DESCRIPTION),
        modality: get_str(&obj, tags::MODALITY),
        rows: to_u32(rows, "Rows")?,
        columns: to_u32(columns, "Columns")?,
        bits_allocated,
        bits_stored,
        high_bit,
        pixel_representation: u16_field(
            tags::PIXEL_REPRESENTATION,
            "PixelRepresentation",
            Some(0),
        )?,
        samples_per_pixel: u16_field(tags::SAMPLES_PER_PIXEL, "SamplesPerPixel", Some(1))?,
        frames: to_u32(frames, "NumberOfFrames")?,
        photometric: get_str(&obj, tags::PHOTOMETRIC_INTERPRETATION),
        position: get_floats::<3>(&obj, tags::IMAGE_POSITION_PATIENT),
        orientation: get_floats::<6>(&obj, tags::IMAGE_ORIENTATION_PATIENT),
        // Only a fallback for ordering: an unreadable one counts as missing.
        instance_number: get_int(&obj, path, tags::INSTANCE_NUMBER, "InstanceNumber")
            .ok()
            .flatten(),
        pixel_spacing: get_floats::<2>(&obj, tags::PIXEL_SPACING)
            .or_else(|| get_floats::<2>(&obj, tags::IMAGER_PIXEL_SPACING)),
        slice_thickness: get_float(&obj, tags::SLICE_THICKNESS),
        spacing_between_slices: get_float(&obj, tags::SPACING_BETWEEN_SLICES),
        slope: get_float(&obj, tags::RESCALE_SLOPE).unwrap_or(1.0),
        intercept: get_float(&obj, tags::RESCALE_INTERCEPT).unwrap_or(0.0),
    })))
}

/// Groups the slices by SeriesInstanceUID and keeps the wanted one: the
/// series of `wanted` when given, else the one with the most slices.
fn select_series(
    folder: &Path,
    slices: Vec<SliceHeader>,
    wanted: Option<&Path>,
) -> Result<Vec<SliceHeader>> {
    // Keep groups in order of first appearance so ties are broken the same
    // way on every run.
    let mut order: Vec<String> = Vec::new();
    let mut groups: HashMap<String, Vec<SliceHeader>> = HashMap::new();
    for s in slices {
        if !groups.contains_key(&s.series_uid) {
            order.push(s.series_uid.clone());
        }
        groups.entry(s.series_uid.clone()).or_default().push(s);
    }
    let chosen = match wanted {
        Some(w) => order
            .iter()
            .find(|uid| groups[*uid].iter().any(|s| same_file(&s.path, w)))
            .cloned()
            .ok_or_else(|| {
                Error::format(
                    w,
                    "DICOM header",
                    format!("not found among the image slices of {}", folder.display()),
                )
            })?,
        None => {
            let mut best = &order[0];
            for uid in &order {
                if groups[uid].len() > groups[best].len() {
                    best = uid;
                }
            }
            best.clone()
        }
    };
    if order.len() > 1 {
        let describe = |uid: &String| {
            let g = &groups[uid];
            let desc = g
                .iter()
                .find_map(|s| s.series_description.clone())
                .unwrap_or_default();
            let uid_text = if uid.is_empty() {
                "(no SeriesInstanceUID)"
            } else {
                uid.as_str()
            };
            format!("{uid_text} \"{desc}\" ({} slices)", g.len())
        };
        eprintln!(
            "note: {} holds {} DICOM series; reading {}",
            folder.display(),
            order.len(),
            describe(&chosen)
        );
        for uid in order.iter().filter(|u| **u != chosen) {
            eprintln!("note:   also there: {}", describe(uid));
        }
    }
    Ok(groups.remove(&chosen).unwrap_or_default())
}

fn transfer_syntax_name(uid: &str) -> &'static str {
    match uid {
        IMPLICIT_LE => "Implicit VR Little Endian",
        EXPLICIT_LE => "Explicit VR Little Endian",
        EXPLICIT_BE => "Explicit VR Big Endian",
        "1.2.840.10008.1.2.1.99" => "Deflated Explicit VR Little Endian",
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

/// Checks that every slice can be decoded and agrees with the first.
fn check_slices(series: &[SliceHeader]) -> Result<()> {
    let first = &series[0];
    for s in series {
        let ts = s.transfer_syntax.as_str();
        if ![IMPLICIT_LE, EXPLICIT_LE, EXPLICIT_BE].contains(&ts) {
            return Err(Error::unsupported(
                &s.path,
                format!(
                    "transfer syntax {ts} ({}): only uncompressed pixel data is read (Implicit/Explicit VR Little Endian, Explicit VR Big Endian); decompress the series first, e.g. `gdcmconv --raw` or `dcmdjpeg`",
                    transfer_syntax_name(ts)
                ),
            ));
        }
        if s.samples_per_pixel != 1 {
            return Err(Error::unsupported(
                &s.path,
                format!(
                    "SamplesPerPixel {} ({}): only one sample per pixel (grayscale) is read",
                    s.samples_per_pixel,
                    s.photometric.as_deref().unwrap_or("colour")
                ),
            ));
        }
        if s.frames != 1 {
            return Err(Error::unsupported(
                &s.path,
                format!("NumberOfFrames {}: multi-frame (enhanced) DICOM is not read, only one frame per file", s.frames),
            ));
        }
        if !matches!(s.bits_allocated, 8 | 16) {
            return Err(Error::unsupported(
                &s.path,
                format!("BitsAllocated {}: only 8 and 16 are read", s.bits_allocated),
            ));
        }
        if s.pixel_representation > 1 {
            return Err(Error::format(
                &s.path,
                "PixelRepresentation",
                format!(
                    "{}: must be 0 (unsigned) or 1 (signed)",
                    s.pixel_representation
                ),
            ));
        }
        if s.bits_stored == 0
            || s.bits_stored > s.bits_allocated
            || s.high_bit >= s.bits_allocated
            || s.high_bit + 1 < s.bits_stored
        {
            return Err(Error::format(
                &s.path,
                "BitsStored/HighBit",
                format!(
                    "BitsStored {} and HighBit {} do not fit in BitsAllocated {}",
                    s.bits_stored, s.high_bit, s.bits_allocated
                ),
            ));
        }
        if s.rows == 0 || s.columns == 0 {
            return Err(Error::format(
                &s.path,
                "Rows/Columns",
                format!(
                    "{}×{}: an image needs at least one pixel",
                    s.rows, s.columns
                ),
            ));
        }
        if (s.rows, s.columns) != (first.rows, first.columns) {
            return Err(Error::format(
                &s.path,
                "Rows/Columns",
                format!(
                    "{} rows × {} columns, but {} has {} × {}: all slices of a series must have the same size",
                    s.rows,
                    s.columns,
                    first.path.display(),
                    first.rows,
                    first.columns
                ),
            ));
        }
        let layout = (
            s.bits_allocated,
            s.bits_stored,
            s.high_bit,
            s.pixel_representation,
        );
        let first_layout = (
            first.bits_allocated,
            first.bits_stored,
            first.high_bit,
            first.pixel_representation,
        );
        if layout != first_layout {
            return Err(Error::format(
                &s.path,
                "BitsAllocated/BitsStored/HighBit/PixelRepresentation",
                format!(
                    "{:?}, but {} has {:?}: all slices of a series must store pixels the same way",
                    layout,
                    first.path.display(),
                    first_layout
                ),
            ));
        }
    }
    Ok(())
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The slice normal (row cosine × column cosine), normalised, or None for a
/// degenerate orientation.
fn slice_normal(o: [f64; 6]) -> Option<[f64; 3]> {
    let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
    let n = [
        r[1] * c[2] - r[2] * c[1],
        r[2] * c[0] - r[0] * c[2],
        r[0] * c[1] - r[1] * c[0],
    ];
    let len = dot(n, n).sqrt();
    (len > 1e-6 && len.is_finite()).then(|| n.map(|v| v / len))
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let m = s.len() / 2;
    if s.len() % 2 == 1 {
        s[m]
    } else {
        (s[m - 1] + s[m]) / 2.0
    }
}

/// Orders the slices in place; returns the z spacing.
fn order_slices(folder: &Path, series: &mut Vec<SliceHeader>) -> Result<f64> {
    let fallback_spacing = |s: &SliceHeader| {
        s.spacing_between_slices
            .filter(|v| *v > 0.0)
            .or(s.slice_thickness.filter(|v| *v > 0.0))
    };
    let have_geometry = series
        .iter()
        .all(|s| s.position.is_some() && s.orientation.is_some());
    if !have_geometry {
        if series.len() > 1 {
            if series.iter().all(|s| s.instance_number.is_some()) {
                eprintln!(
                    "warning: {}: ImagePositionPatient/ImageOrientationPatient missing; slices ordered by InstanceNumber",
                    folder.display()
                );
                series.sort_by_key(|s| s.instance_number);
            } else {
                eprintln!(
                    "warning: {}: slice positions and InstanceNumber missing; slices ordered by file name",
                    folder.display()
                );
            }
        }
        return Ok(match fallback_spacing(&series[0]) {
            Some(v) => v,
            None => {
                if series.len() > 1 {
                    eprintln!(
                        "warning: {}: no slice positions, SpacingBetweenSlices or SliceThickness: z spacing set to 1",
                        folder.display()
                    );
                }
                1.0
            }
        });
    }

    let first = &series[0];
    let orient = first.orientation.unwrap_or_default();
    let normal = slice_normal(orient).ok_or_else(|| {
        Error::format(
            &first.path,
            "ImageOrientationPatient",
            format!("{orient:?}: the row and column directions are parallel or zero"),
        )
    })?;
    for s in series.iter() {
        let o = s.orientation.unwrap_or_default();
        if o.iter()
            .zip(orient.iter())
            .any(|(a, b)| (a - b).abs() > 1e-3)
        {
            return Err(Error::format(
                &s.path,
                "ImageOrientationPatient",
                format!(
                    "{o:?} differs from {orient:?} in {}: the slices of a series must share one orientation",
                    first.path.display()
                ),
            ));
        }
    }
    let mut keyed: Vec<(f64, SliceHeader)> = series
        .drain(..)
        .map(|s| (dot(s.position.unwrap_or_default(), normal), s))
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gaps: Vec<f64> = keyed.windows(2).map(|w| w[1].0 - w[0].0).collect();
    for (i, g) in gaps.iter().enumerate() {
        if *g < SAME_POSITION_MM {
            return Err(Error::format(
                &keyed[i + 1].1.path,
                "ImagePositionPatient",
                format!(
                    "{:?} is the same slice position as {} ({:?}): duplicate slice or two acquisitions in one series",
                    keyed[i + 1].1.position.unwrap_or_default(),
                    keyed[i].1.path.display(),
                    keyed[i].1.position.unwrap_or_default()
                ),
            ));
        }
    }
    let spacing = if gaps.is_empty() {
        fallback_spacing(&keyed[0].1).unwrap_or(1.0)
    } else {
        let m = median(&gaps);
        let (lo, hi) = gaps
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), g| {
                (lo.min(*g), hi.max(*g))
            });
        if hi - m > 0.01 * m || m - lo > 0.01 * m {
            eprintln!(
                "warning: {}: slice gaps are not uniform ({lo:.4} to {hi:.4} mm, median {m:.4} mm used): missing slices or variable spacing; the volume is shown with uniform spacing",
                folder.display()
            );
        }
        m
    };
    series.extend(keyed.into_iter().map(|(_, s)| s));
    Ok(spacing)
}

fn assemble(folder: &Path, mut series: Vec<SliceHeader>) -> Result<Volume> {
    if series.is_empty() {
        return Err(Error::format(
            folder,
            "DICOM files",
            "no image slices in the selected series",
        ));
    }
    check_slices(&series)?;
    let z_spacing = order_slices(folder, &mut series)?;
    let first = &series[0];
    let (nx, ny, nz) = (first.columns as u64, first.rows as u64, series.len() as u64);
    let [row_spacing, col_spacing] = match first.pixel_spacing {
        Some(ps) => ps,
        None => {
            eprintln!(
                "warning: {}: no PixelSpacing: x and y spacing set to 1",
                first.path.display()
            );
            [1.0, 1.0]
        }
    };
    let spacing = Vec3::new(col_spacing as f32, row_spacing as f32, z_spacing as f32);
    if !(spacing.is_finite() && spacing.min_element() > 0.0) {
        let field = if z_spacing > 0.0 && z_spacing.is_finite() {
            "PixelSpacing"
        } else {
            "ImagePositionPatient"
        };
        return Err(Error::format(
            &first.path,
            field,
            format!(
                "spacing {} {} {}: each must be a positive finite number",
                spacing.x, spacing.y, spacing.z
            ),
        ));
    }
    let origin = first
        .position
        .map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
        .unwrap_or(Vec3::ZERO);

    let signed = first.pixel_representation == 1;
    let ty = match (first.bits_allocated, signed) {
        (8, false) => ScalarType::U8,
        (16, false) => ScalarType::U16,
        _ => ScalarType::I16,
    };
    let (n, _) = check_dims(&first.path, "Rows/Columns", [nx, ny, nz], ty)?;
    let per_slice = (nx * ny) as usize;

    // Pass 2: pixel data, decoded in parallel straight into the volume.
    let data = match ty {
        ScalarType::U8 => {
            let mut v = vec![0u8; n];
            decode_all(&series, &mut v, per_slice, |s, px, out| {
                fill(s, px, out, |x| x as u8)
            })?;
            VoxelData::U8(v)
        }
        ScalarType::U16 => {
            let mut v = vec![0u16; n];
            decode_all(&series, &mut v, per_slice, |s, px, out| {
                fill(s, px, out, |x| x as u16)
            })?;
            VoxelData::U16(v)
        }
        _ => {
            let mut v = vec![0i16; n];
            decode_all(&series, &mut v, per_slice, |s, px, out| {
                fill(s, px, out, |x| x as i16)
            })?;
            VoxelData::I16(v)
        }
    };

    let same_rescale = series
        .iter()
        .all(|s| s.slope == first.slope && s.intercept == first.intercept);
    let data = if same_rescale {
        data.rescaled(first.slope, first.intercept)
    } else {
        // Per-slice scaling (PET, some MR): only f32 holds every slice exactly.
        let mut out = Vec::with_capacity(n);
        for (k, s) in series.iter().enumerate() {
            for i in k * per_slice..(k + 1) * per_slice {
                out.push((data.get(i) as f64 * s.slope + s.intercept) as f32);
            }
        }
        VoxelData::F32(out)
    };

    let mut vol = Volume::new(
        [nx as usize, ny as usize, nz as usize],
        spacing,
        origin,
        data,
    )
    .map_err(|e| Error::format(&first.path, "geometry", e.to_string()))?;
    if first.modality.as_deref() == Some("CT") {
        vol.units = Some("HU".to_string());
    }
    vol.name = first.series_description.clone();
    Ok(vol)
}

/// Decodes every slice into its part of `out` (in parallel); the error of the
/// lowest slice wins so the message does not depend on thread timing.
fn decode_all<T: Send>(
    series: &[SliceHeader],
    out: &mut [T],
    per_slice: usize,
    f: impl Fn(&SliceHeader, &[i32], &mut [T]) + Sync,
) -> Result<()> {
    let results: Vec<Result<()>> = out
        .par_chunks_mut(per_slice)
        .zip(series.par_iter())
        .map(|(chunk, s)| {
            let px = read_pixels(s)?;
            f(s, &px, chunk);
            Ok(())
        })
        .collect();
    results.into_iter().collect()
}

fn fill<T>(_s: &SliceHeader, px: &[i32], out: &mut [T], conv: impl Fn(i32) -> T) {
    for (o, &v) in out.iter_mut().zip(px) {
        *o = conv(v);
    }
}

/// Reads one slice's PixelData as integers (masked or sign-extended to
/// BitsStored), checking its length against Rows × Columns.
fn read_pixels(s: &SliceHeader) -> Result<Vec<i32>> {
    let field = PIXEL_DATA_FIELD;
    let obj = OpenFileOptions::new()
        .read_to(tags::PIXEL_DATA)
        .open_file(&s.path)
        .map_err(|e| {
            Error::format(
                &s.path,
                field,
                format!("cannot read the pixel data: {}", error_chain(&e)),
            )
        })?;
    let elem = obj.get(tags::PIXEL_DATA).ok_or_else(|| {
        Error::format(
            &s.path,
            field,
            "missing: the file has image attributes but no pixel data",
        )
    })?;
    let bytes = elem.to_bytes().map_err(|e| {
        Error::unsupported(
            &s.path,
            format!("{field}: encapsulated (compressed) pixel data is not read ({e})"),
        )
    })?;
    let n = s.rows as usize * s.columns as usize;
    let bytes_per = s.bits_allocated as usize / 8;
    let expected = n * bytes_per;
    // An odd-length value is padded to even length with one byte.
    let ok_len = bytes.len() == expected || (expected % 2 == 1 && bytes.len() == expected + 1);
    if !ok_len {
        return Err(Error::format(
            &s.path,
            field,
            format!(
                "{} bytes, but Rows {} × Columns {} × BitsAllocated {}/8 need {expected}",
                bytes.len(),
                s.rows,
                s.columns,
                s.bits_allocated
            ),
        ));
    }
    let big_endian = s.transfer_syntax == EXPLICIT_BE;
    // dicom-parser stores OW values as decoded 16-bit words (native byte
    // order in memory) and OB/UN values as the bytes of the file; the
    // multiplicity tells which one we got.
    let words = !bytes.is_empty() && elem.value().multiplicity() as usize * 2 == bytes.len();
    let raw: Vec<u32> = match (bytes_per, words) {
        (2, true) => bytes
            .chunks_exact(2)
            .take(n)
            .map(|c| u16::from_ne_bytes([c[0], c[1]]) as u32)
            .collect(),
        (2, false) => bytes
            .chunks_exact(2)
            .take(n)
            .map(|c| {
                if big_endian {
                    u16::from_be_bytes([c[0], c[1]]) as u32
                } else {
                    u16::from_le_bytes([c[0], c[1]]) as u32
                }
            })
            .collect(),
        (_, true) => bytes
            .chunks_exact(2)
            .flat_map(|c| {
                let w = u16::from_ne_bytes([c[0], c[1]]);
                if big_endian {
                    w.to_be_bytes()
                } else {
                    w.to_le_bytes()
                }
            })
            .take(n)
            .map(u32::from)
            .collect(),
        (_, false) => bytes.iter().take(n).map(|&b| b as u32).collect(),
    };
    let shift = (s.high_bit + 1 - s.bits_stored) as u32;
    let bits = s.bits_stored as u32;
    let mask = if bits >= 32 {
        u32::MAX
    } else {
        (1u32 << bits) - 1
    };
    let signed = s.pixel_representation == 1;
    let full = bits == s.bits_allocated as u32 && shift == 0;
    Ok(raw
        .into_iter()
        .map(|r| {
            let v = if full { r } else { (r >> shift) & mask };
            if signed {
                // Sign-extend from BitsStored bits.
                let sh = 32 - bits;
                ((v << sh) as i32) >> sh
            } else {
                v as i32
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::data_path;

    fn approx(a: f32, b: f32, tol: f32) -> bool {
        (a - b).abs() <= tol
    }

    /// Copies slices `names` of the CT series into a new temporary folder.
    fn copy_ct(names: &[&str]) -> Option<tempfile::TempDir> {
        let src = data_path("dicom_ct_lung")?;
        let dir = tempfile::tempdir().unwrap();
        for n in names {
            std::fs::copy(src.join(n), dir.path().join(n)).unwrap();
        }
        Some(dir)
    }

    // Ground truth from pydicom 3.0 + numpy (slices sorted by position).
    #[test]
    fn ct_lung_dims_spacing_origin_and_hu() {
        let Some(p) = data_path("dicom_ct_lung") else {
            return;
        };
        assert!(folder_has_dicom(&p).unwrap());
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [512, 512, 30]);
        assert_eq!(v.scalar_type(), ScalarType::I16);
        let s = v.spacing();
        assert!(
            approx(s.x, 0.646_484_4, 1e-6)
                && approx(s.y, 0.646_484_4, 1e-6)
                && approx(s.z, 8.0, 1e-5),
            "{s}"
        );
        let o = v.origin();
        assert!(
            approx(o.x, -173.17676, 1e-3)
                && approx(o.y, -294.17676, 1e-3)
                && approx(o.z, 80.0, 1e-4),
            "{o}"
        );
        assert_eq!((v.stats().min, v.stats().max), (-1024.0, 1548.0));
        assert_eq!(v.units.as_deref(), Some("HU"));
        assert_eq!(v.name.as_deref(), Some("ThoraxRoutine  8.0.0  B40f"));
        assert_eq!(v.value(0, 0, 0), -1001.0);
        assert_eq!(v.value(256, 200, 10), 1.0);
        assert_eq!(v.value(100, 150, 29), -1005.0);
        assert_eq!(v.value(300, 100, 5), 30.0);
        assert_eq!(v.value(150, 160, 12), -544.0);
        // The maximum sits at (445, 317, 22) in pydicom's ordering.
        assert_eq!(v.value(445, 317, 22), 1548.0);
    }

    #[test]
    fn mri_brain_x_is_columns_and_step_is_along_the_normal() {
        let Some(p) = data_path("dicom_mri_brain") else {
            return;
        };
        let v = read(&p).unwrap();
        // Rows 320, Columns 260: x runs along the columns.
        assert_eq!(v.dims(), [260, 320, 24]);
        assert_eq!(v.scalar_type(), ScalarType::U16);
        let s = v.spacing();
        // Oblique slices: 6.5 mm along the normal (= SpacingBetweenSlices),
        // although the z coordinate of the positions moves by 6.4 mm.
        assert!(
            approx(s.x, 0.6875, 1e-6) && approx(s.y, 0.6875, 1e-6) && approx(s.z, 6.5, 1e-4),
            "{s}"
        );
        let o = v.origin();
        assert!(
            approx(o.x, -83.30032, 1e-3)
                && approx(o.y, -115.806_4, 1e-3)
                && approx(o.z, -61.45288, 1e-3),
            "{o}"
        );
        assert_eq!((v.stats().min, v.stats().max), (0.0, 2505.0));
        assert_eq!(v.units, None);
        assert_eq!(v.name.as_deref(), Some("T1post"));
        assert_eq!(v.value(256, 200, 10), 441.0);
        assert_eq!(v.value(200, 250, 23), 23.0);
        assert_eq!(v.value(150, 160, 12), 459.0);
        assert_eq!(v.value(130, 130, 1), 2505.0);
    }

    #[test]
    fn a_single_file_reads_its_whole_series() {
        let Some(p) = data_path("dicom_ct_lung/1-05.dcm") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [512, 512, 30]);
        assert_eq!(v.value(150, 160, 12), -544.0);
    }

    #[test]
    fn order_comes_from_positions_not_file_names() {
        let Some(src) = data_path("dicom_ct_lung") else {
            return;
        };
        let dir = tempfile::tempdir().unwrap();
        // 1-01 … 1-06 are at z = 312 … 272 (decreasing); name them so that
        // both name order and reversed name order disagree with position
        // order.
        let names = ["c", "a", "f", "b", "e", "d"];
        for (i, n) in names.iter().enumerate() {
            std::fs::copy(
                src.join(format!("1-0{}.dcm", i + 1)),
                dir.path().join(format!("{n}.dcm")),
            )
            .unwrap();
        }
        let sub = read(dir.path()).unwrap();
        let full = read(&src).unwrap();
        assert_eq!(sub.dims(), [512, 512, 6]);
        assert!(approx(sub.origin().z, 272.0, 1e-4));
        assert!(approx(sub.spacing().z, 8.0, 1e-5));
        // Slice k of the copy is slice 24 + k of the whole series.
        for k in 0..6 {
            for (i, j) in [(256, 256), (100, 300), (400, 120)] {
                assert_eq!(
                    sub.value(i, j, k),
                    full.value(i, j, 24 + k),
                    "({i},{j},{k})"
                );
            }
        }
    }

    #[test]
    fn implicit_little_and_explicit_big_endian_read_the_same_values() {
        let Some(src) = data_path("dicom_ct_lung") else {
            return;
        };
        let reference = {
            let Some(d) = copy_ct(&["1-10.dcm", "1-11.dcm", "1-12.dcm"]) else {
                return;
            };
            read(d.path()).unwrap()
        };
        for ts in [IMPLICIT_LE, EXPLICIT_BE] {
            let dir = tempfile::tempdir().unwrap();
            for n in ["1-10.dcm", "1-11.dcm", "1-12.dcm"] {
                let mut obj = dicom_object::open_file(src.join(n)).unwrap();
                obj.update_meta(|m| m.transfer_syntax = ts.to_string());
                obj.write_to_file(dir.path().join(n)).unwrap();
            }
            let v = read(dir.path()).unwrap();
            assert_eq!(v.dims(), reference.dims(), "{ts}");
            assert_eq!(v.data(), reference.data(), "{ts}");
            assert_eq!(v.spacing(), reference.spacing(), "{ts}");
        }
    }

    #[test]
    fn compressed_transfer_syntax_is_unsupported_naming_the_uid() {
        let Some(dir) = copy_ct(&["1-01.dcm"]) else {
            return;
        };
        let p = dir.path().join("1-01.dcm");
        let mut b = std::fs::read(&p).unwrap();
        // Same length: "1.2.840.10008.1.2.1\0" → "1.2.840.10008.1.2.5\0".
        let at = b
            .windows(20)
            .position(|w| w == b"1.2.840.10008.1.2.1\0")
            .unwrap();
        b[at + 18] = b'5';
        std::fs::write(&p, b).unwrap();
        let e = read(dir.path()).unwrap_err();
        let s = e.to_string();
        assert!(matches!(e, Error::Unsupported { .. }), "{s}");
        assert!(
            s.contains("1-01.dcm")
                && s.contains("1.2.840.10008.1.2.5")
                && s.contains("RLE Lossless"),
            "{s}"
        );
    }

    #[test]
    fn truncated_file_is_an_error_naming_file_and_pixel_data() {
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm"]) else {
            return;
        };
        let p = dir.path().join("1-02.dcm");
        let b = std::fs::read(&p).unwrap();
        std::fs::write(&p, &b[..b.len() - 1000]).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(s.contains("1-02.dcm") && s.contains("PixelData"), "{s}");
    }

    #[test]
    fn short_pixel_data_is_an_error_naming_file_and_field() {
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm"]) else {
            return;
        };
        let p = dir.path().join("1-01.dcm");
        let mut obj = dicom_object::open_file(&p).unwrap();
        // Replace the 512×512 words by the 1-word value of Rows.
        let small = obj.element(tags::ROWS).unwrap().value().clone();
        assert!(obj.update_value(tags::PIXEL_DATA, |v| *v = small.clone()));
        obj.write_to_file(&p).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains("1-01.dcm") && s.contains("PixelData") && s.contains("524288"),
            "{s}"
        );
    }

    #[test]
    fn mismatched_rows_is_an_error_naming_the_file() {
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-03.dcm"]) else {
            return;
        };
        let p = dir.path().join("1-03.dcm");
        let mut b = std::fs::read(&p).unwrap();
        // Rows (0028,0010) US 512 → 256, patched in place.
        let at = b
            .windows(10)
            .position(|w| w == b"\x28\x00\x10\x00US\x02\x00\x00\x02")
            .unwrap();
        b[at + 8] = 0;
        b[at + 9] = 1;
        std::fs::write(&p, b).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains("1-03.dcm") && s.contains("Rows/Columns") && s.contains("256"),
            "{s}"
        );
    }

    #[test]
    fn folder_without_image_slices_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("notes.txt"), "not an image").unwrap();
        let e = read(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains(&dir.path().display().to_string()) && e.contains("no DICOM image slices"),
            "{e}"
        );
        assert!(!folder_has_dicom(dir.path()).unwrap());

        // A DICOM object without image attributes does not count either.
        let Some(src) = data_path("dicom_ct_lung/1-01.dcm") else {
            return;
        };
        let mut obj = dicom_object::open_file(&src).unwrap();
        for t in [tags::ROWS, tags::COLUMNS, tags::PIXEL_DATA] {
            obj.remove_element(t);
        }
        obj.write_to_file(dir.path().join("report.dcm")).unwrap();
        assert!(folder_has_dicom(dir.path()).unwrap());
        let e = read(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("no DICOM image slices") && e.contains("1 DICOM file(s), none"),
            "{e}"
        );
    }

    #[test]
    fn two_series_reads_the_larger_one_or_the_one_asked_for() {
        let Some(src) = data_path("dicom_ct_lung") else {
            return;
        };
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-03.dcm"]) else {
            return;
        };
        for n in ["1-04.dcm", "1-05.dcm"] {
            let mut obj = dicom_object::open_file(src.join(n)).unwrap();
            let vr = obj.element(tags::SERIES_INSTANCE_UID).unwrap().vr();
            obj.put_str(
                tags::SERIES_INSTANCE_UID,
                vr,
                "1.2.826.0.1.3680043.2.1125.42",
            );
            let vr = obj.element(tags::SERIES_DESCRIPTION).unwrap().vr();
            obj.put_str(tags::SERIES_DESCRIPTION, vr, "second series");
            obj.write_to_file(dir.path().join(format!("x{n}"))).unwrap();
        }
        let v = read(dir.path()).unwrap();
        assert_eq!(v.dims()[2], 3);
        assert!(approx(v.origin().z, 296.0, 1e-4));
        let v = read(&dir.path().join("x1-05.dcm")).unwrap();
        assert_eq!(v.dims()[2], 2);
        assert_eq!(v.name.as_deref(), Some("second series"));
        assert!(approx(v.origin().z, 280.0, 1e-4));
    }

    #[test]
    fn unusable_image_attribute_is_an_error_and_junk_is_skipped() {
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-03.dcm"]) else {
            return;
        };
        // A .dcm file that is not DICOM at all is skipped (with a warning).
        std::fs::write(dir.path().join("junk.dcm"), b"not DICOM").unwrap();
        assert_eq!(read(dir.path()).unwrap().dims(), [512, 512, 3]);
        // An image without BitsAllocated cannot be decoded: an error.
        let p = dir.path().join("1-02.dcm");
        let mut obj = dicom_object::open_file(&p).unwrap();
        obj.remove_element(tags::BITS_ALLOCATED);
        obj.write_to_file(&p).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains("1-02.dcm") && s.contains("`BitsAllocated`"),
            "{s}"
        );
    }

    #[test]
    fn two_slices_at_one_position_is_an_error() {
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm"]) else {
            return;
        };
        std::fs::copy(dir.path().join("1-02.dcm"), dir.path().join("copy.dcm")).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains("ImagePositionPatient") && s.contains("same slice position"),
            "{s}"
        );
    }

    #[test]
    fn a_missing_slice_still_loads_with_the_median_step() {
        let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-04.dcm", "1-05.dcm"]) else {
            return;
        };
        let v = read(dir.path()).unwrap();
        assert_eq!(v.dims()[2], 4);
        assert!(approx(v.spacing().z, 8.0, 1e-5));
    }

    #[test]
    fn non_dicom_folder_is_not_dicom() {
        let Some(p) = data_path("teapot_ct/slices") else {
            return;
        };
        assert!(!folder_has_dicom(&p).unwrap());
    }
}
