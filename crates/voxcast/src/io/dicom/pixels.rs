//! Pass 2: decoding the pixel data of a series into one volume.
//!
//! Native pixel data (and deflated data sets, inflated by the parser) is
//! read as stored; encapsulated pixel data (JPEG, JPEG-LS, JPEG 2000, RLE)
//! is decoded frame by frame by dicom-pixeldata, JPEG-LS by the decoder
//! `voxcast-native-io` installs (`io::external`).

use super::header::{open_checked, FileHeader};
use super::series::{is_native, Group};
use super::{EXPLICIT_BE, PIXEL_DATA_FIELD};
use crate::error::{Error, Result};
use crate::io::util::check_dims;
use crate::volume::{ScalarType, Volume, VoxelData};
use dicom_dictionary_std::tags;
use glam::Vec3;
use rayon::prelude::*;

/// The scalar type a series is stored in (before rescaling).
fn scalar_type(h: &FileHeader) -> ScalarType {
    match (h.bits_allocated, h.pixel_representation == 1) {
        (1, _) | (8, false) => ScalarType::U8,
        (16, false) => ScalarType::U16,
        (32, _) => ScalarType::F32,
        _ => ScalarType::I16,
    }
}

/// Builds the volume of an ordered group (see `series::prepare`).
pub(crate) fn assemble(g: &Group, z_spacing: f64) -> Result<Volume> {
    let first = g.first();
    let (nx, ny, nz) = (
        first.columns as u64,
        first.rows as u64,
        g.slices.len() as u64,
    );
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
    let origin = g.slices[0]
        .frame
        .position
        .map(|p| Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32))
        .unwrap_or(Vec3::ZERO);
    let ty = scalar_type(first);
    let (n, _) = check_dims(&first.path, "Rows/Columns", [nx, ny, nz], ty)?;
    let per_slice = (nx * ny) as usize;

    let data = match ty {
        ScalarType::U8 => VoxelData::U8(decode_all(g, n, per_slice, |v| v as u8)?.into()),
        ScalarType::U16 => VoxelData::U16(decode_all(g, n, per_slice, |v| v as u16)?.into()),
        ScalarType::I16 => VoxelData::I16(decode_all(g, n, per_slice, |v| v as i16)?.into()),
        ScalarType::F32 => VoxelData::F32(decode_all(g, n, per_slice, |v| v as f32)?.into()),
    };

    let f0 = &g.slices[0].frame;
    let same_rescale = g
        .slices
        .iter()
        .all(|s| s.frame.slope == f0.slope && s.frame.intercept == f0.intercept);
    let data = if same_rescale {
        data.rescaled(f0.slope, f0.intercept)
    } else {
        // Per-slice scaling (PET, some MR, enhanced objects): f32.
        let mut out = Vec::with_capacity(n);
        for (k, s) in g.slices.iter().enumerate() {
            for i in k * per_slice..(k + 1) * per_slice {
                out.push((data.get(i) as f64 * s.frame.slope + s.frame.intercept) as f32);
            }
        }
        VoxelData::F32(out.into())
    };

    let mut vol = Volume::new(
        [nx as usize, ny as usize, nz as usize],
        spacing,
        origin,
        data,
    )
    .map_err(|e| Error::format(&first.path, "geometry", e.to_string()))?;
    vol.units = first.units.clone();
    vol.name = first.series_description.clone();
    Ok(vol)
}

/// Decodes every file of `g` (in parallel) into its slices of a new
/// buffer of `n` voxels; the error of the first file wins so the message
/// does not depend on thread timing.
fn decode_all<T: Send + Default + Clone>(
    g: &Group,
    n: usize,
    per_slice: usize,
    conv: impl Fn(i64) -> T + Sync,
) -> Result<Vec<T>> {
    let mut out = vec![T::default(); n];
    {
        let mut chunks: Vec<Option<&mut [T]>> = out.chunks_mut(per_slice).map(Some).collect();
        let mut per_file: Vec<Vec<(u32, &mut [T])>> =
            (0..g.files.len()).map(|_| Vec::new()).collect();
        for (z, s) in g.slices.iter().enumerate() {
            let chunk = chunks[z].take().expect("one slice per chunk");
            per_file[s.file].push((s.frame.index, chunk));
        }
        let results: Vec<Result<()>> = per_file
            .into_par_iter()
            .enumerate()
            .map(|(fi, targets)| decode_file(&g.files[fi], targets, &conv))
            .collect();
        results.into_iter().collect::<Result<()>>()?;
    }
    Ok(out)
}

/// Decodes the frames of one file that the volume uses into `targets`.
fn decode_file<T>(
    h: &FileHeader,
    mut targets: Vec<(u32, &mut [T])>,
    conv: &impl Fn(i64) -> T,
) -> Result<()> {
    let field = PIXEL_DATA_FIELD;
    let (obj, _) = open_checked(&h.path, false)?
        .map_err(|e| Error::format(&h.path, field, format!("cannot read the pixel data: {e}")))?;
    let elem = obj.get(tags::PIXEL_DATA).ok_or_else(|| {
        Error::format(
            &h.path,
            field,
            "missing: the file has image attributes but no pixel data",
        )
    })?;
    let per_frame = h.rows as usize * h.columns as usize;
    let signed = h.pixel_representation == 1;
    let bits = h.bits_stored as u32;
    let value = |raw: u32, shift: u32| -> i64 {
        let mask = if bits >= 32 {
            u32::MAX
        } else {
            (1u32 << bits) - 1
        };
        let v = (raw >> shift) & mask;
        if signed && bits < 64 {
            let sh = 32 - bits;
            (((v << sh) as i32) >> sh) as i64
        } else {
            v as i64
        }
    };
    if is_native(&h.transfer_syntax) {
        let bytes = elem.to_bytes().map_err(|e| {
            Error::format(
                &h.path,
                field,
                format!("encapsulated pixel data in an uncompressed transfer syntax ({e})"),
            )
        })?;
        let need = h.native_bytes() as usize;
        if bytes.len() < need {
            return Err(Error::format(
                &h.path,
                field,
                format!(
                    "{} bytes, but Rows {} × Columns {} × {} frame(s) × BitsAllocated {} need {need}",
                    bytes.len(),
                    h.rows,
                    h.columns,
                    h.frames.len(),
                    h.bits_allocated
                ),
            ));
        }
        // Bytes beyond `need` are padding: ignored.
        let big = h.transfer_syntax == EXPLICIT_BE;
        // dicom-parser stores OW values as decoded 16-bit words (native
        // byte order in memory) and OB/UN values as the bytes of the file;
        // the multiplicity tells which one we got.
        let words = elem.value().multiplicity() as usize * 2 == bytes.len();
        let shift = (h.high_bit + 1 - h.bits_stored) as u32;
        for (frame, out) in targets.iter_mut() {
            let start = *frame as usize * per_frame;
            match h.bits_allocated {
                1 => {
                    for (i, o) in out.iter_mut().enumerate() {
                        let bit = start + i;
                        *o = conv(((bytes[bit / 8] >> (bit % 8)) & 1) as i64);
                    }
                }
                8 => {
                    let src: Vec<u8> = if words {
                        // Undo the word decoding to get the file's bytes.
                        bytes
                            .chunks_exact(2)
                            .flat_map(|c| {
                                let w = u16::from_ne_bytes([c[0], c[1]]);
                                if big {
                                    w.to_be_bytes()
                                } else {
                                    w.to_le_bytes()
                                }
                            })
                            .skip(start)
                            .take(per_frame)
                            .collect()
                    } else {
                        bytes[start..start + per_frame].to_vec()
                    };
                    for (o, &b) in out.iter_mut().zip(&src) {
                        *o = conv(value(b as u32, shift));
                    }
                }
                16 => {
                    let src = &bytes[start * 2..(start + per_frame) * 2];
                    for (o, c) in out.iter_mut().zip(src.chunks_exact(2)) {
                        let w = if words {
                            u16::from_ne_bytes([c[0], c[1]])
                        } else if big {
                            u16::from_be_bytes([c[0], c[1]])
                        } else {
                            u16::from_le_bytes([c[0], c[1]])
                        };
                        *o = conv(value(w as u32, shift));
                    }
                }
                _ => {
                    let src = &bytes[start * 4..(start + per_frame) * 4];
                    for (o, c) in out.iter_mut().zip(src.chunks_exact(4)) {
                        let c = [c[0], c[1], c[2], c[3]];
                        let w = if words {
                            // Two native words, in the file's order.
                            let (a, b) = (
                                u16::from_ne_bytes([c[0], c[1]]),
                                u16::from_ne_bytes([c[2], c[3]]),
                            );
                            if big {
                                (a as u32) << 16 | b as u32
                            } else {
                                (b as u32) << 16 | a as u32
                            }
                        } else if big {
                            u32::from_be_bytes(c)
                        } else {
                            u32::from_le_bytes(c)
                        };
                        *o = conv(value(w, shift));
                    }
                }
            }
        }
        return Ok(());
    }
    decode_encapsulated(h, &obj, targets, conv, &value)
}

fn decode_encapsulated<T>(
    h: &FileHeader,
    obj: &super::header::Obj,
    targets: Vec<(u32, &mut [T])>,
    conv: &impl Fn(i64) -> T,
    value: &impl Fn(u32, u32) -> i64,
) -> Result<()> {
    use dicom_pixeldata::PixelDecoder;
    let field = PIXEL_DATA_FIELD;
    let per_frame = h.rows as usize * h.columns as usize;
    let bytes_per = (h.bits_allocated as usize).div_ceil(8);
    // JPEG-LS through the installed decoder (`io::external`), every other
    // codec through dicom-pixeldata.
    let jpeg_ls = if super::series::is_jpeg_ls(&h.transfer_syntax) {
        crate::io::external::installed().jpeg_ls
    } else {
        None
    };
    for (frame, out) in targets {
        let (decoded, frame_of_codec);
        let data: &[u8] = if let Some(decode) = jpeg_ls {
            decoded = decode_with(h, obj, frame, decode)?;
            &decoded
        } else {
            frame_of_codec = obj.decode_pixel_data_frame(frame).map_err(|e| {
            let msg = super::header::error_chain(&e);
            if msg.contains("SamplePrecision(12)") {
                return Error::unsupported(
                    &h.path,
                    format!(
                        "{field}: 12-bit lossy JPEG ({}) is not decoded (the pure-Rust JPEG decoder reads 8-bit lossy and lossless JPEG only): convert with `dcmdjpeg IN OUT` or `gdcmconv --raw IN OUT`",
                        super::transfer_syntax_name(&h.transfer_syntax)
                    ),
                );
            }
            Error::format(
                &h.path,
                field,
                format!(
                    "cannot decode frame {frame} ({}): {}",
                    super::transfer_syntax_name(&h.transfer_syntax),
                    msg
                ),
            )
            })?;
            frame_of_codec.data()
        };
        if data.len() < per_frame * bytes_per {
            return Err(Error::format(
                &h.path,
                field,
                format!(
                    "frame {frame} decodes to {} bytes, but Rows {} × Columns {} × BitsAllocated {} need {}",
                    data.len(),
                    h.rows,
                    h.columns,
                    h.bits_allocated,
                    per_frame * bytes_per
                ),
            ));
        }
        // Decoders give samples right-aligned, little endian.
        match bytes_per {
            1 => {
                for (o, &b) in out.iter_mut().zip(data) {
                    *o = conv(value(b as u32, 0));
                }
            }
            2 => {
                for (o, c) in out.iter_mut().zip(data.chunks_exact(2)) {
                    *o = conv(value(u16::from_le_bytes([c[0], c[1]]) as u32, 0));
                }
            }
            _ => {
                for (o, c) in out.iter_mut().zip(data.chunks_exact(4)) {
                    *o = conv(value(u32::from_le_bytes([c[0], c[1], c[2], c[3]]), 0));
                }
            }
        }
    }
    Ok(())
}

/// One frame decoded by an installed decoder (`io::external::FrameDecoder`):
/// the frame's fragments joined (through the basic offset table when a
/// frame spans several), then the codec.
fn decode_with(
    h: &FileHeader,
    obj: &super::header::Obj,
    frame: u32,
    decode: crate::io::external::FrameDecoder,
) -> Result<Vec<u8>> {
    use dicom_encoding::adapters::PixelDataObject;
    let fail = |msg: String| {
        Error::format(
            &h.path,
            PIXEL_DATA_FIELD,
            format!(
                "cannot decode frame {frame} ({}): {msg}",
                super::transfer_syntax_name(&h.transfer_syntax)
            ),
        )
    };
    let bytes = obj
        .frame_pixel_data(frame)
        .ok_or_else(|| fail("its fragments are missing".into()))?;
    let shape = crate::io::external::FrameShape {
        rows: h.rows,
        columns: h.columns,
        bits_allocated: h.bits_allocated,
    };
    decode(&bytes, shape).map_err(fail)
}
