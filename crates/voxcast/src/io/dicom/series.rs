//! Grouping the image files of a folder into series, checking that a series
//! can be decoded, and ordering its slices.

use super::header::{dot, slice_normal, FileHeader, Frame};
use super::lengths::PixelExtent;
use super::{transfer_syntax_name, DEFLATED, EXPLICIT_BE, EXPLICIT_LE, IMPLICIT_LE};
use crate::error::{Error, Result};
use std::path::Path;

/// Two slices closer than this along the normal (mm) are the same position.
const SAME_POSITION_MM: f64 = 1e-4;

/// Encapsulated pixel data is refused when it would decode to more than
/// this many times its size (no codec compresses real images that well).
pub(crate) const MAX_CODEC_RATIO: u64 = 20_000;

/// The transfer syntaxes whose pixel data is decoded.
pub(crate) fn can_decode(ts: &str) -> bool {
    matches!(
        ts,
        IMPLICIT_LE
            | EXPLICIT_LE
            | EXPLICIT_BE
            | DEFLATED
            | "1.2.840.10008.1.2.4.50"
            | "1.2.840.10008.1.2.4.51"
            | "1.2.840.10008.1.2.4.57"
            | "1.2.840.10008.1.2.4.70"
            | "1.2.840.10008.1.2.4.90"
            | "1.2.840.10008.1.2.4.91"
            | "1.2.840.10008.1.2.5"
    ) || (is_jpeg_ls(ts) && crate::io::external::installed().jpeg_ls.is_some())
}

/// JPEG-LS, lossless or near-lossless: decoded by the reader that
/// `voxcast-native-io` installs (feature `jpeg-ls`, CharLS).
pub(crate) fn is_jpeg_ls(ts: &str) -> bool {
    matches!(ts, "1.2.840.10008.1.2.4.80" | "1.2.840.10008.1.2.4.81")
}

/// True for pixel data stored as is (after the parser's inflating).
pub(crate) fn is_native(ts: &str) -> bool {
    matches!(ts, IMPLICIT_LE | EXPLICIT_LE | EXPLICIT_BE | DEFLATED)
}

/// One slice of a series: a frame of one of its files.
#[derive(Clone, Debug)]
pub(crate) struct Slice {
    /// Index into the series' files.
    pub file: usize,
    pub frame: Frame,
}

/// A group of image files that may form one volume.
#[derive(Clone, Debug)]
pub(crate) struct Group {
    pub files: Vec<FileHeader>,
    pub slices: Vec<Slice>,
}

impl Group {
    pub fn first(&self) -> &FileHeader {
        &self.files[0]
    }
}

/// Groups image files by SeriesInstanceUID, then by size, pixel layout and
/// orientation (a 3-plane localizer becomes three groups); a multi-frame
/// file is a group of its own. Groups keep the order of first appearance.
pub(crate) fn group(files: Vec<FileHeader>) -> Vec<Group> {
    type Key = (String, u32, u32, u16, u16, Option<[i64; 6]>, Option<String>);
    let key = |h: &FileHeader| -> Key {
        let o = h.frames[0]
            .orientation
            .map(|o| o.map(|v| (v * 1000.0).round() as i64));
        let own = (h.frames.len() > 1).then(|| h.path.display().to_string());
        (
            h.series_uid.clone(),
            h.rows,
            h.columns,
            h.bits_allocated,
            h.pixel_representation,
            o,
            own,
        )
    };
    let mut keys: Vec<Key> = Vec::new();
    let mut groups: Vec<Group> = Vec::new();
    for h in files {
        let k = key(&h);
        let i = match keys.iter().position(|x| *x == k) {
            Some(i) => i,
            None => {
                keys.push(k);
                groups.push(Group {
                    files: Vec::new(),
                    slices: Vec::new(),
                });
                groups.len() - 1
            }
        };
        let g = &mut groups[i];
        let fi = g.files.len();
        g.slices.extend(h.frames.iter().map(|f| Slice {
            file: fi,
            frame: f.clone(),
        }));
        g.files.push(h);
    }
    groups
}

/// Checks that one file can be decoded and that its pixel data is as long
/// as its header says (before anything is allocated for it).
pub(crate) fn check_file(s: &FileHeader) -> Result<()> {
    let ts = s.transfer_syntax.as_str();
    if !can_decode(ts) {
        let hint = match ts {
            "1.2.840.10008.1.2.4.80" | "1.2.840.10008.1.2.4.81" => {
                "this build has no JPEG-LS decoder (build with `--features jpeg-ls`, which needs libcharls), or convert with `gdcmconv --raw IN OUT` or `dcmdjpls IN OUT`"
            }
            _ => "convert it to uncompressed DICOM with `gdcmconv --raw IN OUT`",
        };
        return Err(Error::unsupported(
            &s.path,
            format!(
                "transfer syntax {ts} ({}) is not decoded: {hint}",
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
    if !matches!(s.bits_allocated, 1 | 8 | 16 | 32) {
        return Err(Error::unsupported(
            &s.path,
            format!(
                "BitsAllocated {}: only 1, 8, 16 and 32 are read",
                s.bits_allocated
            ),
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
    let need = s.native_bytes();
    let field = super::PIXEL_DATA_FIELD;
    match s.pixel {
        PixelExtent::Native(n) if is_native(ts) && n < need => Err(Error::format(
            &s.path,
            field,
            format!(
                "{n} bytes, but Rows {} × Columns {} × {} frame(s) × BitsAllocated {} need {need}",
                s.rows,
                s.columns,
                s.frames.len(),
                s.bits_allocated
            ),
        )),
        PixelExtent::Encapsulated(n) if n.saturating_mul(MAX_CODEC_RATIO) < need => {
            Err(Error::format(
                &s.path,
                field,
                format!(
                    "{n} bytes of compressed data cannot hold Rows {} × Columns {} × {} frame(s) ({need} bytes)",
                    s.rows,
                    s.columns,
                    s.frames.len()
                ),
            ))
        }
        PixelExtent::Encapsulated(_) if is_native(ts) => Err(Error::format(
            &s.path,
            field,
            format!(
                "encapsulated pixel data in an uncompressed transfer syntax ({})",
                transfer_syntax_name(ts)
            ),
        )),
        PixelExtent::Native(_) if !is_native(ts) => Err(Error::format(
            &s.path,
            field,
            format!(
                "native pixel data in a compressed transfer syntax ({}): encapsulated fragments expected",
                transfer_syntax_name(ts)
            ),
        )),
        _ => Ok(()),
    }
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

/// Orders the slices of `g` in place; returns the z spacing and the
/// warnings to print if this group is the one read.
pub(crate) fn order_slices(folder: &Path, g: &mut Group) -> Result<(f64, Vec<String>)> {
    let mut notes = Vec::new();
    let first = g.first().clone();
    let fallback_spacing = first
        .spacing_between_slices
        .filter(|v| *v > 0.0)
        .or(first.slice_thickness.filter(|v| *v > 0.0));
    let have_geometry = g
        .slices
        .iter()
        .all(|s| s.frame.position.is_some() && s.frame.orientation.is_some());
    if !have_geometry {
        if g.slices.len() > 1 {
            if g.slices.iter().all(|s| s.frame.instance_number.is_some()) {
                notes.push(format!(
                    "warning: {}: ImagePositionPatient/ImageOrientationPatient missing; slices ordered by InstanceNumber",
                    folder.display()
                ));
                g.slices.sort_by_key(|s| s.frame.instance_number);
            } else {
                notes.push(format!(
                    "warning: {}: slice positions and InstanceNumber missing; slices ordered by file name",
                    folder.display()
                ));
            }
        }
        let spacing = match fallback_spacing {
            Some(v) => v,
            None => {
                if g.slices.len() > 1 {
                    notes.push(format!(
                        "warning: {}: no slice positions, SpacingBetweenSlices or SliceThickness: z spacing set to 1",
                        folder.display()
                    ));
                }
                1.0
            }
        };
        return Ok((spacing, notes));
    }

    let orient = g.slices[0].frame.orientation.unwrap_or_default();
    let normal = slice_normal(orient).ok_or_else(|| {
        Error::format(
            &first.path,
            "ImageOrientationPatient",
            format!("{orient:?}: the row and column directions are parallel or zero"),
        )
    })?;
    for s in &g.slices {
        let o = s.frame.orientation.unwrap_or_default();
        if o.iter()
            .zip(orient.iter())
            .any(|(a, b)| (a - b).abs() > 1e-3)
        {
            return Err(Error::format(
                &g.files[s.file].path,
                "ImageOrientationPatient",
                format!(
                    "{o:?} (frame {}) differs from {orient:?} in {}: the slices of a series must share one orientation",
                    s.frame.index,
                    first.path.display()
                ),
            ));
        }
    }
    let mut keyed: Vec<(f64, Slice)> = g
        .slices
        .iter()
        .cloned()
        .map(|s| (dot(s.frame.position.unwrap_or_default(), normal), s))
        .collect();
    keyed.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gaps: Vec<f64> = keyed.windows(2).map(|w| w[1].0 - w[0].0).collect();
    for (i, gap) in gaps.iter().enumerate() {
        if *gap < SAME_POSITION_MM {
            let (a, b) = (&keyed[i].1, &keyed[i + 1].1);
            return Err(Error::format(
                &g.files[b.file].path,
                "ImagePositionPatient",
                format!(
                    "{:?} is the same slice position as {} ({:?}): duplicate slice or two acquisitions in one series",
                    b.frame.position.unwrap_or_default(),
                    g.files[a.file].path.display(),
                    a.frame.position.unwrap_or_default()
                ),
            ));
        }
    }
    let spacing = if gaps.is_empty() {
        fallback_spacing.unwrap_or(1.0)
    } else {
        let m = median(&gaps);
        let (lo, hi) = gaps
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), g| {
                (lo.min(*g), hi.max(*g))
            });
        if hi - m > 0.01 * m || m - lo > 0.01 * m {
            notes.push(format!(
                "warning: {}: slice gaps are not uniform ({lo:.4} to {hi:.4} mm, median {m:.4} mm used): missing slices or variable spacing; the volume is shown with uniform spacing",
                folder.display()
            ));
        }
        m
    };
    g.slices = keyed.into_iter().map(|(_, s)| s).collect();
    Ok((spacing, notes))
}

/// Checks every file of `g` and orders its slices: a group that passes can
/// be read as one volume.
pub(crate) fn prepare(folder: &Path, g: &mut Group) -> Result<(f64, Vec<String>)> {
    for f in &g.files {
        check_file(f)?;
    }
    order_slices(folder, g)
}
