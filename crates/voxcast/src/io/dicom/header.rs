//! Pass 1: one file's header (everything before the pixel data), with the
//! geometry of each of its frames.

use super::lengths::{check_lengths, PixelExtent};
use super::DICOMDIR_CLASS;
use crate::error::{Error, Result};
use crate::io::util::MAX_DEFLATE_RATIO;
use dicom_dictionary_std::tags;
use dicom_object::{InMemDicomObject, OpenFileOptions, Tag};
use std::path::{Path, PathBuf};

pub(crate) type Obj = dicom_object::DefaultDicomObject;

/// The geometry and rescale of one frame (one slice of the volume).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Frame {
    /// Index of the frame in its file.
    pub index: u32,
    pub position: Option<[f64; 3]>,
    pub orientation: Option<[f64; 6]>,
    pub instance_number: Option<i64>,
    pub slope: f64,
    pub intercept: f64,
}

/// What pass 1 learns from one image file.
#[derive(Clone, Debug)]
pub(crate) struct FileHeader {
    pub path: PathBuf,
    pub transfer_syntax: String,
    pub series_uid: String,
    pub series_description: Option<String>,
    pub modality: Option<String>,
    pub rows: u32,
    pub columns: u32,
    pub bits_allocated: u16,
    pub bits_stored: u16,
    pub high_bit: u16,
    pub pixel_representation: u16,
    pub samples_per_pixel: u16,
    pub photometric: Option<String>,
    pub pixel_spacing: Option<[f64; 2]>,
    pub slice_thickness: Option<f64>,
    pub spacing_between_slices: Option<f64>,
    /// Units of the rescaled values where the file says (RT Dose: `GY`).
    pub units: Option<String>,
    /// One entry per frame (NumberOfFrames, 1 for a classic slice).
    pub frames: Vec<Frame>,
    pub pixel: PixelExtent,
}

impl FileHeader {
    /// Bytes of native pixel data that Rows × Columns × frames need.
    pub fn native_bytes(&self) -> u64 {
        let samples = self.rows as u64
            * self.columns as u64
            * self.samples_per_pixel as u64
            * self.frames.len() as u64;
        if self.bits_allocated == 1 {
            samples.div_ceil(8)
        } else {
            samples * (self.bits_allocated as u64).div_ceil(8)
        }
    }
}

/// True for a gzip-compressed file (`.gz`, e.g. `slice.dcm.gz`).
pub(crate) fn is_gz(p: &Path) -> bool {
    p.extension()
        .map(|e| e.eq_ignore_ascii_case("gz"))
        .unwrap_or(false)
}

/// The bytes of a `.dcm.gz` file, inflated (bounded by deflate's ratio).
pub(crate) fn gunzip(path: &Path) -> Result<Vec<u8>> {
    use std::io::Read;
    let f = crate::files::open(path)?.0;
    let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
    let mut out = Vec::new();
    flate2::read::MultiGzDecoder::new(f)
        .take(len.saturating_mul(MAX_DEFLATE_RATIO).min(4 << 30))
        .read_to_end(&mut out)
        .map_err(|e| Error::format(path, "gzip", format!("cannot inflate: {e}")))?;
    Ok(out)
}

/// Checks the lengths of `path`, then parses it up to the pixel data
/// (`until_pixels`) or through it. The inner `Err` is a file that does not
/// parse as DICOM.
pub(crate) fn open_checked(
    path: &Path,
    until_pixels: bool,
) -> Result<std::result::Result<(Obj, PixelExtent), String>> {
    let opts = || {
        if until_pixels {
            OpenFileOptions::new().read_until(tags::PIXEL_DATA)
        } else {
            OpenFileOptions::new().read_to(tags::PIXEL_DATA)
        }
    };
    let res = if is_gz(path) {
        let bytes = gunzip(path)?;
        let n = bytes.len() as u64;
        let pixel = check_lengths(path, std::io::Cursor::new(&bytes), n)?;
        let skip = if bytes.len() >= 132 && &bytes[128..132] == b"DICM" {
            128
        } else {
            0
        };
        opts()
            .read_preamble(dicom_object::file::ReadPreamble::Never)
            .from_reader(&bytes[skip..])
            .map(|o| (o, pixel))
    } else {
        let f = crate::files::open(path)?.0;
        let len = f.metadata().map_err(|e| Error::io(path, e))?.len();
        let pixel = check_lengths(path, std::io::BufReader::new(f), len)?;
        opts().open_file(path).map(|o| (o, pixel))
    };
    Ok(res.map_err(|e| error_chain(&e)))
}

pub(crate) fn error_chain(e: &dyn std::error::Error) -> String {
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

fn get_str(obj: &InMemDicomObject, tag: Tag) -> Option<String> {
    let s = obj.get(tag)?.to_str().ok()?;
    let s = s.trim_matches(|c: char| c.is_whitespace() || c == '\0');
    (!s.is_empty()).then(|| s.to_string())
}

fn is_empty(obj: &InMemDicomObject, tag: Tag) -> bool {
    obj.get(tag)
        .map(|e| e.to_bytes().map(|b| b.is_empty()).unwrap_or(false))
        .unwrap_or(true)
}

/// An optional integer attribute; present but unreadable is an error.
fn get_int(obj: &InMemDicomObject, path: &Path, tag: Tag, name: &str) -> Result<Option<i64>> {
    match obj.get(tag) {
        None => Ok(None),
        Some(_) if is_empty(obj, tag) => Ok(None),
        Some(e) => e
            .to_int::<i64>()
            .map(Some)
            .map_err(|err| Error::format(path, name, format!("not an integer ({err})"))),
    }
}

/// An optional list of at least `N` finite numbers; present but unreadable
/// (not numbers, too few, not finite) is an error naming the attribute.
fn get_floats<const N: usize>(
    obj: &InMemDicomObject,
    path: &Path,
    tag: Tag,
    name: &str,
) -> Result<Option<[f64; N]>> {
    if is_empty(obj, tag) {
        return Ok(None);
    }
    let Some(e) = obj.get(tag) else {
        return Ok(None);
    };
    let text = || e.to_str().map(|s| s.trim().to_string()).unwrap_or_default();
    let v = e.to_multi_float64().map_err(|_| {
        Error::format(
            path,
            name,
            format!("\"{}\" is not a list of numbers", text()),
        )
    })?;
    let a: [f64; N] = v.get(..N).and_then(|s| s.try_into().ok()).ok_or_else(|| {
        Error::format(
            path,
            name,
            format!("\"{}\": {N} number(s) expected", text()),
        )
    })?;
    if !a.iter().all(|x| x.is_finite()) {
        return Err(Error::format(
            path,
            name,
            format!("{a:?}: every value must be finite"),
        ));
    }
    Ok(Some(a))
}

fn get_float(obj: &InMemDicomObject, path: &Path, tag: Tag, name: &str) -> Result<Option<f64>> {
    Ok(get_floats::<1>(obj, path, tag, name)?.map(|a| a[0]))
}

/// The first item of sequence `tag` in `obj`.
fn first_item(obj: &InMemDicomObject, tag: Tag) -> Option<&InMemDicomObject> {
    obj.get(tag)?.items()?.first()
}

/// The attribute `tag` of a functional group: in the group's `seq` item of
/// `frame`'s per-frame item, else of the shared item, else at the top level.
fn in_groups<'a>(
    per_frame: Option<&'a InMemDicomObject>,
    shared: Option<&'a InMemDicomObject>,
    top: &'a InMemDicomObject,
    seq: Tag,
    tag: Tag,
) -> &'a InMemDicomObject {
    for g in [per_frame, shared].into_iter().flatten() {
        if let Some(item) = first_item(g, seq) {
            if item.get(tag).is_some() {
                return item;
            }
        }
    }
    top
}

/// Pass 1 on one file. The inner `Err` is a file that does not parse as
/// DICOM, `Ok(None)` a DICOM object that is not an image (no Rows/Columns:
/// structured reports, RT plans, presentation states, DICOMDIR); the outer
/// `Err` an image whose attributes are unusable.
pub(crate) fn read_header(path: &Path) -> Result<std::result::Result<Option<FileHeader>, String>> {
    let (obj, pixel) = match open_checked(path, true)? {
        Ok(o) => o,
        Err(e) => return Ok(Err(e)),
    };
    let ts = obj.meta().transfer_syntax().to_string();
    let sop_class = obj
        .meta()
        .media_storage_sop_class_uid()
        .trim_end_matches(['\0', ' '])
        .to_string();
    if sop_class == DICOMDIR_CLASS {
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
    let n_frames = to_u32(
        get_int(&obj, path, tags::NUMBER_OF_FRAMES, "NumberOfFrames")?.unwrap_or(1),
        "NumberOfFrames",
    )?;
    if n_frames == 0 {
        return Err(Error::format(
            path,
            "NumberOfFrames",
            "0: an image needs at least one frame",
        ));
    }
    let rows = to_u32(rows, "Rows")?;
    let columns = to_u32(columns, "Columns")?;

    let shared = first_item(&obj, tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE);
    let per_frame: Vec<&InMemDicomObject> = obj
        .get(tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE)
        .and_then(|e| e.items())
        .map(|items| items.iter().collect())
        .unwrap_or_default();
    if !per_frame.is_empty() && per_frame.len() != n_frames as usize {
        return Err(Error::format(
            path,
            "PerFrameFunctionalGroupsSequence",
            format!(
                "{} items for NumberOfFrames {n_frames}: one item per frame expected",
                per_frame.len()
            ),
        ));
    }
    // Spacing: Pixel Measures (enhanced objects) or the top level.
    let measures = in_groups(
        per_frame.first().copied(),
        shared,
        &obj,
        tags::PIXEL_MEASURES_SEQUENCE,
        tags::PIXEL_SPACING,
    );
    let pixel_spacing = match get_floats::<2>(measures, path, tags::PIXEL_SPACING, "PixelSpacing")?
    {
        Some(s) => Some(s),
        None => get_floats::<2>(&obj, path, tags::IMAGER_PIXEL_SPACING, "ImagerPixelSpacing")?,
    };
    let thick_src = in_groups(
        per_frame.first().copied(),
        shared,
        &obj,
        tags::PIXEL_MEASURES_SEQUENCE,
        tags::SLICE_THICKNESS,
    );
    let between_src = in_groups(
        per_frame.first().copied(),
        shared,
        &obj,
        tags::PIXEL_MEASURES_SEQUENCE,
        tags::SPACING_BETWEEN_SLICES,
    );
    // Only fallbacks for the z spacing: an unreadable one counts as missing.
    let slice_thickness = get_float(thick_src, path, tags::SLICE_THICKNESS, "SliceThickness")
        .ok()
        .flatten();
    let spacing_between_slices = get_float(
        between_src,
        path,
        tags::SPACING_BETWEEN_SLICES,
        "SpacingBetweenSlices",
    )
    .ok()
    .flatten();
    let instance_number = get_int(&obj, path, tags::INSTANCE_NUMBER, "InstanceNumber")
        .ok()
        .flatten();

    // RT Dose: the grid scaling is the slope, frames are offset along the
    // normal by GridFrameOffsetVector.
    let dose_scaling = get_float(&obj, path, tags::DOSE_GRID_SCALING, "DoseGridScaling")?;
    let offsets: Option<Vec<f64>> = if n_frames > 1 && per_frame.is_empty() {
        match obj.get(tags::GRID_FRAME_OFFSET_VECTOR) {
            Some(e) if !is_empty(&obj, tags::GRID_FRAME_OFFSET_VECTOR) => {
                let v = e.to_multi_float64().map_err(|_| {
                    Error::format(path, "GridFrameOffsetVector", "not a list of numbers")
                })?;
                if v.len() != n_frames as usize || !v.iter().all(|x| x.is_finite()) {
                    return Err(Error::format(
                        path,
                        "GridFrameOffsetVector",
                        format!(
                            "{} values for NumberOfFrames {n_frames}: one finite offset per frame expected",
                            v.len()
                        ),
                    ));
                }
                Some(v)
            }
            _ => None,
        }
    } else {
        None
    };

    let mut frames = Vec::with_capacity(n_frames.min(1 << 16) as usize);
    for k in 0..n_frames {
        let pf = per_frame.get(k as usize).copied();
        let pos_src = in_groups(
            pf,
            shared,
            &obj,
            tags::PLANE_POSITION_SEQUENCE,
            tags::IMAGE_POSITION_PATIENT,
        );
        let ori_src = in_groups(
            pf,
            shared,
            &obj,
            tags::PLANE_ORIENTATION_SEQUENCE,
            tags::IMAGE_ORIENTATION_PATIENT,
        );
        let res_src = in_groups(
            pf,
            shared,
            &obj,
            tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE,
            tags::RESCALE_SLOPE,
        );
        let mut position = get_floats::<3>(
            pos_src,
            path,
            tags::IMAGE_POSITION_PATIENT,
            "ImagePositionPatient",
        )?;
        let orientation = get_floats::<6>(
            ori_src,
            path,
            tags::IMAGE_ORIENTATION_PATIENT,
            "ImageOrientationPatient",
        )?;
        if let (Some(off), Some(p), Some(n)) = (
            offsets.as_ref(),
            position,
            orientation.and_then(slice_normal),
        ) {
            let d = off[k as usize] - off[0];
            position = Some([p[0] + d * n[0], p[1] + d * n[1], p[2] + d * n[2]]);
        }
        let slope = match dose_scaling {
            Some(s) => s,
            None => get_float(res_src, path, tags::RESCALE_SLOPE, "RescaleSlope")?.unwrap_or(1.0),
        };
        let int_src = in_groups(
            pf,
            shared,
            &obj,
            tags::PIXEL_VALUE_TRANSFORMATION_SEQUENCE,
            tags::RESCALE_INTERCEPT,
        );
        let intercept =
            get_float(int_src, path, tags::RESCALE_INTERCEPT, "RescaleIntercept")?.unwrap_or(0.0);
        if slope == 0.0 {
            return Err(Error::format(
                path,
                "RescaleSlope",
                "0: every pixel would have the same value",
            ));
        }
        frames.push(Frame {
            index: k,
            position,
            orientation,
            instance_number: if n_frames == 1 {
                instance_number
            } else {
                Some(k as i64)
            },
            slope,
            intercept,
        });
    }
    let units = if dose_scaling.is_some() {
        get_str(&obj, tags::DOSE_UNITS).map(|u| {
            if u.eq_ignore_ascii_case("GY") {
                "Gy".to_string()
            } else {
                u
            }
        })
    } else if get_str(&obj, tags::MODALITY).as_deref() == Some("CT") {
        Some("HU".to_string())
    } else {
        None
    };
    Ok(Ok(Some(FileHeader {
        path: path.to_path_buf(),
        transfer_syntax: ts,
        series_uid: get_str(&obj, tags::SERIES_INSTANCE_UID).unwrap_or_default(),
        series_description: get_str(&obj, tags::SERIES_DESCRIPTION),
        modality: get_str(&obj, tags::MODALITY),
        rows,
        columns,
        bits_allocated,
        bits_stored,
        high_bit,
        pixel_representation: u16_field(
            tags::PIXEL_REPRESENTATION,
            "PixelRepresentation",
            Some(0),
        )?,
        samples_per_pixel: u16_field(tags::SAMPLES_PER_PIXEL, "SamplesPerPixel", Some(1))?,
        photometric: get_str(&obj, tags::PHOTOMETRIC_INTERPRETATION),
        pixel_spacing,
        slice_thickness,
        spacing_between_slices,
        units,
        frames,
        pixel,
    })))
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The slice normal (row cosine × column cosine), normalised, or None for a
/// degenerate orientation.
pub(crate) fn slice_normal(o: [f64; 6]) -> Option<[f64; 3]> {
    let (r, c) = ([o[0], o[1], o[2]], [o[3], o[4], o[5]]);
    let n = [
        r[1] * c[2] - r[2] * c[1],
        r[2] * c[0] - r[0] * c[2],
        r[0] * c[1] - r[1] * c[0],
    ];
    let len = dot(n, n).sqrt();
    (len > 1e-6 && len.is_finite()).then(|| n.map(|v| v / len))
}
