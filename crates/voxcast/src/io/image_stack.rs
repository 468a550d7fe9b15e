//! Image sequences: one 2D image per slice, slice index = z.
//!
//! The input is a folder (every `.png`, `.tif`, `.tiff` file in it, any
//! case, not recursive; hidden files such as macOS `._x.png` are skipped),
//! a glob pattern (`slices/img_*.png`; matches with those extensions), or a
//! single image file (one slice, or one slice per page of a multi-page
//! TIFF). Files are ordered by natural sort
//! (`s2.png` before `s10.png`); the format is told by the magic bytes, not
//! the extension. Spacing is 1, 1, 1 (the CLI's `--spacing` overrides it),
//! origin 0.
//!
//! Supported pixels:
//! * PNG: grayscale 1 to 16 bits (1/2/4-bit expanded to u8), 16-bit kept as
//!   u16; grayscale+alpha (alpha ignored); palette and RGB(A) images are
//!   turned into their luminance with the Rec. 709 weights
//!   (0.2126 R + 0.7152 G + 0.0722 B, rounded), which is what users expect
//!   from a colour image of a grayscale scan. APNG: first frame only.
//! * TIFF (any compression the `tiff` crate decodes: none, LZW, deflate,
//!   PackBits, JPEG): grayscale 8-bit (u8), 16-bit (u16, or i16 when
//!   signed), signed 8-bit (i16), 32-bit float (f32), 16/64-bit float and
//!   32/64-bit integers (converted to f32); RGB(A) 8/16-bit as luminance as
//!   for PNG. Every page of a multi-page TIFF is a slice, except
//!   reduced-resolution pages (thumbnails, NewSubfileType bit 0).
//!
//! All slices must have the same width, height and type. Not supported:
//! bilevel (1-bit) TIFF, palette/CMYK/YCbCr TIFF, other image formats.

use super::util::{check_dims, file_len, natural_cmp, no_panic, read_head, MAX_DEFLATE_RATIO};
use crate::error::{Error, Result};
use crate::volume::{ScalarType, Volume, VoxelData};
use glam::Vec3;
use rayon::prelude::*;
use std::io::BufReader;
use std::path::{Path, PathBuf};

const EXTENSIONS: [&str; 3] = ["png", "tif", "tiff"];
const EXTENSIONS_TEXT: &str = ".png, .tif, .tiff";

/// LZW can reach a few thousand to one on constant data (deflate about
/// 1032:1); a TIFF page claiming more pixels than this many times its file
/// size is lying.
const TIFF_MAX_RATIO: u64 = 4096;

/// Reads a folder of slices, a glob pattern, or a single PNG/TIFF file.
pub fn read(path: &Path) -> Result<Volume> {
    let files = list_inputs(path)?;

    // Pass 1: headers only, so sizes are checked before the volume is
    // allocated and the first mismatching file is named.
    let probed: Vec<Result<Source>> = files.par_iter().map(|p| probe(p)).collect();
    let sources: Vec<Source> = probed.into_iter().collect::<Result<_>>()?;

    let first = sources
        .iter()
        .find_map(|s| s.pages.first().map(|pg| (s, pg)))
        .ok_or_else(|| Error::format(path, "image files", "no image pages found"))?;
    let (w, h, ty) = (first.1.width, first.1.height, first.1.ty);
    let first_name = page_name(first.0, first.1);
    for s in &sources {
        if s.pages.is_empty() {
            return Err(Error::format(
                &s.path,
                "pages",
                "the TIFF holds no full-resolution page",
            ));
        }
        for pg in &s.pages {
            if (pg.width, pg.height) != (w, h) {
                return Err(Error::format(
                    &s.path,
                    "image size",
                    format!(
                        "{}{}×{}, but {first_name} is {w}×{h}: all slices must have the same size",
                        page_label(s, pg),
                        pg.width,
                        pg.height
                    ),
                ));
            }
            if pg.ty != ty {
                return Err(Error::format(
                    &s.path,
                    "pixel type",
                    format!(
                        "{}{} ({}), but {first_name} is {}: all slices must have the same type",
                        page_label(s, pg),
                        pg.ty,
                        pg.describe,
                        ty
                    ),
                ));
            }
        }
    }

    let nz: u64 = sources.iter().map(|s| s.pages.len() as u64).sum();
    let (n, _) = check_dims(&sources[0].path, "image size", [w as u64, h as u64, nz], ty)?;
    let plane = w as usize * h as usize;

    // Pass 2: decode every file into its own run of slices, in parallel.
    let data = match ty {
        ScalarType::U8 => VoxelData::U8(decode_all(&sources, n, plane)?.into()),
        ScalarType::U16 => VoxelData::U16(decode_all(&sources, n, plane)?.into()),
        ScalarType::I16 => VoxelData::I16(decode_all(&sources, n, plane)?.into()),
        ScalarType::F32 => VoxelData::F32(decode_all(&sources, n, plane)?.into()),
    };
    Volume::new(
        [w as usize, h as usize, nz as usize],
        Vec3::ONE,
        Vec3::ZERO,
        data,
    )
    .map_err(|e| Error::format(path, "image size", e.to_string()))
}

fn has_image_extension(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| EXTENSIONS.iter().any(|x| e.eq_ignore_ascii_case(x)))
}

/// The files to read, in slice order.
fn list_inputs(path: &Path) -> Result<Vec<PathBuf>> {
    if path.is_dir() {
        let mut files = Vec::new();
        for entry in std::fs::read_dir(path).map_err(|e| Error::io(path, e))? {
            let p = entry.map_err(|e| Error::io(path, e))?.path();
            // Hidden files include macOS `._name.png` resource forks, which are
            // not images.
            if p.is_file() && has_image_extension(&p) && !name_of(&p).starts_with('.') {
                files.push(p);
            }
        }
        if files.is_empty() {
            return Err(Error::format(
                path,
                "image files",
                format!("no slice images in this folder (looked for {EXTENSIONS_TEXT})"),
            ));
        }
        files.sort_by(|a, b| natural_cmp(&name_of(a), &name_of(b)));
        return Ok(files);
    }
    if path.exists() {
        return Ok(vec![path.to_path_buf()]);
    }
    let pattern = path.to_string_lossy();
    if !pattern.contains(['*', '?', '[']) {
        return Err(Error::io(
            path,
            std::io::Error::from(std::io::ErrorKind::NotFound),
        ));
    }
    let matches = glob::glob(&pattern)
        .map_err(|e| Error::format(path, "glob pattern", format!("invalid pattern: {e}")))?;
    let mut files = Vec::new();
    for m in matches {
        let p = m.map_err(|e| Error::io(e.path(), std::io::Error::other(e.to_string())))?;
        if p.is_file() && has_image_extension(&p) {
            files.push(p);
        }
    }
    if files.is_empty() {
        return Err(Error::format(
            path,
            "glob pattern",
            format!("no {EXTENSIONS_TEXT} file matches this pattern"),
        ));
    }
    files.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
    Ok(files)
}

fn name_of(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Png,
    Tiff,
}

/// One slice as the header describes it.
#[derive(Clone, Debug)]
struct Page {
    /// Index of the TIFF directory (0 for PNG).
    ifd: usize,
    width: u32,
    height: u32,
    ty: ScalarType,
    describe: String,
}

#[derive(Clone, Debug)]
struct Source {
    path: PathBuf,
    format: Format,
    pages: Vec<Page>,
}

fn page_name(s: &Source, pg: &Page) -> String {
    if s.format == Format::Tiff && s.pages.len() > 1 {
        format!("{} (page {})", s.path.display(), pg.ifd)
    } else {
        s.path.display().to_string()
    }
}

fn page_label(s: &Source, pg: &Page) -> String {
    if s.format == Format::Tiff && s.pages.len() > 1 {
        format!("page {}: ", pg.ifd)
    } else {
        String::new()
    }
}

fn probe(path: &Path) -> Result<Source> {
    let head = read_head(path, 8)?;
    let format = if head.starts_with(b"\x89PNG\r\n\x1a\n") {
        Format::Png
    } else if head.starts_with(b"II*\0")
        || head.starts_with(b"MM\0*")
        || head.starts_with(b"II+\0")
        || head.starts_with(b"MM\0+")
    {
        Format::Tiff
    } else {
        return Err(Error::format(path, "magic", "not a PNG or TIFF file"));
    };
    let pages = match format {
        Format::Png => vec![probe_png(path)?],
        Format::Tiff => no_panic(path, "TIFF", || probe_tiff(path))?,
    };
    Ok(Source {
        path: path.to_path_buf(),
        format,
        pages,
    })
}

type PngReader = png::Reader<BufReader<std::fs::File>>;

fn open_png(path: &Path) -> Result<PngReader> {
    let f = crate::files::open(path)?.0;
    let mut dec = png::Decoder::new(BufReader::new(f));
    // EXPAND: palette → RGB, 1/2/4-bit gray → 8-bit; 16-bit stays 16-bit.
    dec.set_transformations(png::Transformations::EXPAND);
    dec.read_info()
        .map_err(|e| Error::format(path, "PNG header", format!("cannot decode: {e}")))
}

fn probe_png(path: &Path) -> Result<Page> {
    let r = open_png(path)?;
    let info = r.info();
    let (w, h) = (info.width, info.height);
    let raw = (info.raw_row_length() as u64).saturating_mul(h as u64);
    let len = file_len(path)?;
    if raw > len.saturating_mul(MAX_DEFLATE_RATIO) {
        return Err(Error::format(
            path,
            "IHDR",
            format!("{w}×{h} pixels cannot be stored in {len} bytes (corrupt header)"),
        ));
    }
    let (_, depth) = r.output_color_type();
    let ty = if depth == png::BitDepth::Sixteen {
        ScalarType::U16
    } else {
        ScalarType::U8
    };
    Ok(Page {
        ifd: 0,
        width: w,
        height: h,
        ty,
        describe: format!("{}-bit {:?} PNG", info.bit_depth as u8, info.color_type),
    })
}

fn open_tiff(path: &Path) -> Result<tiff::decoder::Decoder<BufReader<std::fs::File>>> {
    let f = crate::files::open(path)?.0;
    tiff::decoder::Decoder::new(BufReader::new(f))
        .map_err(|e| Error::format(path, "TIFF header", e.to_string()))
}

/// The voxcast type a TIFF page becomes, or why it cannot be read.
fn tiff_type(
    color: tiff::ColorType,
    sample_format: u16,
) -> std::result::Result<(ScalarType, String), String> {
    use tiff::ColorType as C;
    let (bits, what) = match color {
        C::Gray(b) => (b, "gray"),
        C::GrayA(b) => (b, "gray+alpha"),
        C::RGB(b) => (b, "RGB"),
        C::RGBA(b) => (b, "RGBA"),
        other => {
            return Err(format!(
                "{other:?} TIFF: only grayscale and RGB(A) are read"
            ))
        }
    };
    let kind = match sample_format {
        1 => "unsigned",
        2 => "signed",
        3 => "float",
        _ => {
            return Err(format!(
                "SampleFormat {sample_format}: only unsigned, signed and float samples are read"
            ))
        }
    };
    let ty = match (bits, sample_format) {
        (8, 1) => ScalarType::U8,
        (8, 2) => ScalarType::I16,
        (16, 1) => ScalarType::U16,
        (16, 2) => ScalarType::I16,
        (16, 3) | (32, _) | (64, _) => ScalarType::F32,
        _ => {
            return Err(format!(
                "{bits}-bit {kind} {what} TIFF: 8, 16, 32 and 64-bit samples are read"
            ))
        }
    };
    Ok((ty, format!("{bits}-bit {kind} {what} TIFF")))
}

fn probe_tiff(path: &Path) -> Result<Vec<Page>> {
    let mut dec = open_tiff(path)?;
    let mut pages = Vec::new();
    let len = file_len(path)?;
    let fail = |ifd: usize, e: &dyn std::fmt::Display| {
        Error::format(path, format!("TIFF page {ifd}"), e.to_string())
    };
    for ifd in 0.. {
        let reduced = dec
            .find_tag_unsigned::<u32>(tiff::tags::Tag::NewSubfileType)
            .map_err(|e| fail(ifd, &e))?
            .is_some_and(|t| t & 1 == 1);
        if !reduced {
            let (w, h) = dec.dimensions().map_err(|e| fail(ifd, &e))?;
            let color = dec.colortype().map_err(|e| fail(ifd, &e))?;
            let sample_format = match dec
                .find_tag(tiff::tags::Tag::SampleFormat)
                .map_err(|e| fail(ifd, &e))?
            {
                Some(v) => v
                    .into_u16_vec()
                    .ok()
                    .and_then(|v| v.first().copied())
                    .unwrap_or(1),
                None => 1,
            };
            let (ty, describe) = tiff_type(color, sample_format)
                .map_err(|m| Error::unsupported(path, format!("page {ifd}: {m}")))?;
            let bytes = (w as u64)
                .saturating_mul(h as u64)
                .saturating_mul(ty.size() as u64);
            if bytes > len.saturating_mul(TIFF_MAX_RATIO) {
                return Err(fail(
                    ifd,
                    &format!("{w}×{h} pixels cannot be stored in {len} bytes (corrupt header)"),
                ));
            }
            pages.push(Page {
                ifd,
                width: w,
                height: h,
                ty,
                describe,
            });
        }
        if !dec.more_images() {
            break;
        }
        dec.next_image().map_err(|e| fail(ifd + 1, &e))?;
    }
    Ok(pages)
}

/// Output voxel types, built from any decoded sample.
trait Voxel: Copy + Default + Send + Sync {
    fn from_f64(v: f64) -> Self;
}

impl Voxel for u8 {
    fn from_f64(v: f64) -> Self {
        v.round().clamp(0.0, u8::MAX as f64) as u8
    }
}
impl Voxel for u16 {
    fn from_f64(v: f64) -> Self {
        v.round().clamp(0.0, u16::MAX as f64) as u16
    }
}
impl Voxel for i16 {
    fn from_f64(v: f64) -> Self {
        v.round().clamp(i16::MIN as f64, i16::MAX as f64) as i16
    }
}
impl Voxel for f32 {
    fn from_f64(v: f64) -> Self {
        v as f32
    }
}

/// Writes one decoded plane (`spp` interleaved samples per pixel) into
/// `out`: the first sample for gray(+alpha), Rec. 709 luminance for RGB(A).
fn store<T: Voxel, S: Copy>(
    src: &[S],
    spp: usize,
    rgb: bool,
    out: &mut [T],
    f: impl Fn(S) -> f64,
) -> bool {
    if spp == 0 || src.len() < out.len() * spp {
        return false;
    }
    if rgb && spp >= 3 {
        for (o, px) in out.iter_mut().zip(src.chunks_exact(spp)) {
            *o = T::from_f64(0.2126 * f(px[0]) + 0.7152 * f(px[1]) + 0.0722 * f(px[2]));
        }
    } else {
        for (o, px) in out.iter_mut().zip(src.chunks_exact(spp)) {
            *o = T::from_f64(f(px[0]));
        }
    }
    true
}

fn decode_all<T: Voxel>(sources: &[Source], n: usize, plane: usize) -> Result<Vec<T>> {
    let mut out = vec![T::default(); n];
    let mut chunks = Vec::with_capacity(sources.len());
    let mut rest: &mut [T] = &mut out;
    for s in sources {
        let (head, tail) = rest.split_at_mut(s.pages.len() * plane);
        chunks.push((s, head));
        rest = tail;
    }
    let results: Vec<Result<()>> = chunks
        .into_par_iter()
        .map(|(s, chunk)| match s.format {
            Format::Png => decode_png(&s.path, chunk),
            Format::Tiff => no_panic(&s.path, "TIFF", || decode_tiff(s, chunk, plane)),
        })
        .collect();
    // Report the first failing file in slice order, whatever thread failed first.
    results.into_iter().collect::<Result<()>>()?;
    Ok(out)
}

fn decode_png<T: Voxel>(path: &Path, out: &mut [T]) -> Result<()> {
    let mut r = open_png(path)?;
    let size = r
        .output_buffer_size()
        .ok_or_else(|| Error::format(path, "IHDR", "image too large"))?;
    let mut buf = vec![0u8; size];
    let info = r
        .next_frame(&mut buf)
        .map_err(|e| Error::format(path, "PNG data", format!("cannot decode: {e}")))?;
    if info.line_size == 0 {
        return Err(Error::format(path, "IHDR", "empty image"));
    }
    let spp = info.color_type.samples();
    let rgb = matches!(info.color_type, png::ColorType::Rgb | png::ColorType::Rgba);
    let row_samples = info.width as usize * spp;
    let ok = if info.bit_depth == png::BitDepth::Sixteen {
        // PNG stores 16-bit samples big-endian.
        let mut samples = Vec::with_capacity(row_samples * info.height as usize);
        for row in buf.chunks(info.line_size).take(info.height as usize) {
            samples.extend(
                row.chunks_exact(2)
                    .take(row_samples)
                    .map(|c| u16::from_be_bytes([c[0], c[1]])),
            );
        }
        store(&samples, spp, rgb, out, f64::from)
    } else if info.line_size == row_samples {
        store(&buf, spp, rgb, out, f64::from)
    } else {
        let packed: Vec<u8> = buf
            .chunks(info.line_size)
            .take(info.height as usize)
            .flat_map(|row| row.iter().take(row_samples).copied())
            .collect();
        store(&packed, spp, rgb, out, f64::from)
    };
    if !ok {
        return Err(Error::format(
            path,
            "PNG data",
            "decoded image is smaller than its header says",
        ));
    }
    Ok(())
}

fn decode_tiff<T: Voxel>(s: &Source, out: &mut [T], plane: usize) -> Result<()> {
    use tiff::decoder::DecodingResult as D;
    let path = &s.path;
    let mut dec = open_tiff(path)?;
    let mut at = 0usize;
    for (k, pg) in s.pages.iter().enumerate() {
        while at < pg.ifd {
            dec.next_image()
                .map_err(|e| Error::format(path, format!("TIFF page {}", at + 1), e.to_string()))?;
            at += 1;
        }
        let field = || format!("TIFF page {}", pg.ifd);
        let color = dec
            .colortype()
            .map_err(|e| Error::format(path, field(), e.to_string()))?;
        let (spp, rgb) = match color {
            tiff::ColorType::GrayA(_) => (2, false),
            tiff::ColorType::RGB(_) => (3, true),
            tiff::ColorType::RGBA(_) => (4, true),
            _ => (1, false),
        };
        let img = dec
            .read_image()
            .map_err(|e| Error::format(path, field(), format!("cannot decode: {e}")))?;
        let dst = &mut out[k * plane..(k + 1) * plane];
        let ok = match &img {
            D::U8(v) => store(v, spp, rgb, dst, f64::from),
            D::U16(v) => store(v, spp, rgb, dst, f64::from),
            D::U32(v) => store(v, spp, rgb, dst, f64::from),
            D::U64(v) => store(v, spp, rgb, dst, |x| x as f64),
            D::I8(v) => store(v, spp, rgb, dst, f64::from),
            D::I16(v) => store(v, spp, rgb, dst, f64::from),
            D::I32(v) => store(v, spp, rgb, dst, f64::from),
            D::I64(v) => store(v, spp, rgb, dst, |x| x as f64),
            D::F16(v) => store(v, spp, rgb, dst, |x| x.to_f64()),
            D::F32(v) => store(v, spp, rgb, dst, f64::from),
            D::F64(v) => store(v, spp, rgb, dst, |x| x),
        };
        if !ok {
            return Err(Error::format(
                path,
                field(),
                "decoded image is smaller than its header says",
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testdata::data_path;

    fn write_png(
        p: &Path,
        w: u32,
        h: u32,
        color: png::ColorType,
        depth: png::BitDepth,
        data: &[u8],
    ) {
        let f = std::fs::File::create(p).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(f), w, h);
        enc.set_color(color);
        enc.set_depth(depth);
        if color == png::ColorType::Indexed {
            // Palette: black, pure red, pure green, white.
            enc.set_palette(vec![0, 0, 0, 255, 0, 0, 0, 255, 0, 255, 255, 255]);
        }
        let mut wr = enc.write_header().unwrap();
        wr.write_image_data(data).unwrap();
    }

    fn gray8(p: &Path, w: u32, h: u32, v: u8) {
        write_png(
            p,
            w,
            h,
            png::ColorType::Grayscale,
            png::BitDepth::Eight,
            &vec![v; (w * h) as usize],
        );
    }

    // Ground truth from Pillow + numpy over the sorted files.
    #[test]
    fn teapot_stack() {
        let Some(p) = data_path("teapot_ct/slices") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [256, 256, 178]);
        assert_eq!(v.scalar_type(), ScalarType::U8);
        assert_eq!(v.spacing(), Vec3::ONE);
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 255.0));
        for ((i, j, k), want) in [
            ((128, 128, 89), 14.0),
            ((50, 200, 120), 30.0),
            ((144, 137, 96), 255.0),
            ((117, 84, 124), 103.0),
            ((22, 149, 89), 117.0),
            ((162, 125, 162), 112.0),
            ((157, 192, 85), 57.0),
        ] {
            assert_eq!(v.value(i, j, k), want, "({i},{j},{k})");
        }
        let VoxelData::U8(d) = v.data() else {
            unreachable!()
        };
        assert_eq!(d.iter().map(|&x| x as u64).sum::<u64>(), 74_626_577);
    }

    #[test]
    fn teapot_glob_and_single_file() {
        let Some(p) = data_path("teapot_ct/slices") else {
            return;
        };
        let v = read(&p.join("teapot_1[0-4]?.png")).unwrap();
        assert_eq!(v.dims(), [256, 256, 50]);
        assert_eq!(v.value(50, 200, 20), 30.0); // slice 120
        let v = read(&p.join("teapot_089.png")).unwrap();
        assert_eq!(v.dims(), [256, 256, 1]);
        assert_eq!(v.value(128, 128, 0), 14.0);
    }

    #[test]
    fn natural_sort_orders_slices() {
        let dir = tempfile::tempdir().unwrap();
        for n in [10u8, 2, 1] {
            gray8(&dir.path().join(format!("s{n}.png")), 3, 2, n);
        }
        // Not an image: ignored in a folder.
        std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
        std::fs::write(dir.path().join("._s5.png"), "resource fork").unwrap();
        for input in [dir.path().to_path_buf(), dir.path().join("s*.png")] {
            let v = read(&input).unwrap();
            assert_eq!(v.dims(), [3, 2, 3]);
            assert_eq!(
                [v.value(0, 0, 0), v.value(2, 1, 1), v.value(1, 1, 2)],
                [1.0, 2.0, 10.0],
                "{}",
                input.display()
            );
        }
    }

    #[test]
    fn png_16_bit_colour_and_palette() {
        let dir = tempfile::tempdir().unwrap();
        // 16-bit gray: big-endian in the file.
        let vals: [u16; 4] = [0, 0x1234, 40000, 65535];
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        write_png(
            &dir.path().join("g16.png"),
            2,
            2,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            &bytes,
        );
        let v = read(&dir.path().join("g16.png")).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::U16);
        assert_eq!(v.data(), &VoxelData::U16(vals.to_vec().into()));
        // RGB: Rec. 709 luminance.
        let rgb = [255, 0, 0, 0, 255, 0, 0, 0, 255, 100, 100, 100];
        write_png(
            &dir.path().join("rgb.png"),
            4,
            1,
            png::ColorType::Rgb,
            png::BitDepth::Eight,
            &rgb,
        );
        let v = read(&dir.path().join("rgb.png")).unwrap();
        assert_eq!(v.data(), &VoxelData::U8(vec![54, 182, 18, 100].into()));
        // Palette (2-bit indices 0..3 → black, red, green, white).
        write_png(
            &dir.path().join("pal.png"),
            4,
            1,
            png::ColorType::Indexed,
            png::BitDepth::Two,
            &[0b00_01_10_11],
        );
        let v = read(&dir.path().join("pal.png")).unwrap();
        assert_eq!(v.data(), &VoxelData::U8(vec![0, 54, 182, 255].into()));
        // Gray + alpha: alpha ignored.
        write_png(
            &dir.path().join("ga.png"),
            2,
            1,
            png::ColorType::GrayscaleAlpha,
            png::BitDepth::Eight,
            &[7, 0, 9, 255],
        );
        assert_eq!(
            read(&dir.path().join("ga.png")).unwrap().data(),
            &VoxelData::U8(vec![7, 9].into())
        );
    }

    fn write_tiff<C: tiff::encoder::colortype::ColorType>(
        p: &Path,
        w: u32,
        h: u32,
        pages: &[&[C::Inner]],
    ) where
        [C::Inner]: tiff::encoder::TiffValue,
    {
        let f = std::fs::File::create(p).unwrap();
        let mut enc = tiff::encoder::TiffEncoder::new(std::io::BufWriter::new(f)).unwrap();
        for data in pages {
            enc.write_image::<C>(w, h, data).unwrap();
        }
    }

    #[test]
    fn tiff_types_and_pages() {
        use tiff::encoder::colortype::{Gray16, Gray32Float, Gray8, GrayI16, RGB8};
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        write_tiff::<Gray8>(&d.join("a.tif"), 2, 2, &[&[1, 2, 3, 4]]);
        assert_eq!(
            read(&d.join("a.tif")).unwrap().data(),
            &VoxelData::U8(vec![1, 2, 3, 4].into())
        );
        write_tiff::<Gray16>(&d.join("b.tiff"), 2, 1, &[&[300, 65000]]);
        assert_eq!(
            read(&d.join("b.tiff")).unwrap().data(),
            &VoxelData::U16(vec![300, 65000].into())
        );
        write_tiff::<GrayI16>(&d.join("c.tif"), 2, 1, &[&[-300, 1200]]);
        assert_eq!(
            read(&d.join("c.tif")).unwrap().data(),
            &VoxelData::I16(vec![-300, 1200].into())
        );
        write_tiff::<Gray32Float>(&d.join("f.tif"), 2, 1, &[&[-1.5, f32::MAX]]);
        assert_eq!(
            read(&d.join("f.tif")).unwrap().data(),
            &VoxelData::F32(vec![-1.5, f32::MAX].into())
        );
        write_tiff::<RGB8>(&d.join("rgb.tif"), 2, 1, &[&[255, 0, 0, 100, 100, 100]]);
        assert_eq!(
            read(&d.join("rgb.tif")).unwrap().data(),
            &VoxelData::U8(vec![54, 100].into())
        );
        // Multi-page: every page is a slice.
        write_tiff::<Gray16>(&d.join("m.tif"), 2, 1, &[&[1, 2], &[3, 4], &[5, 6]]);
        let v = read(&d.join("m.tif")).unwrap();
        assert_eq!(v.dims(), [2, 1, 3]);
        assert_eq!(v.data(), &VoxelData::U16(vec![1, 2, 3, 4, 5, 6].into()));
        // A folder of multi-page files: pages of the first, then the second.
        let sub = d.join("pages");
        std::fs::create_dir(&sub).unwrap();
        write_tiff::<Gray8>(&sub.join("p1.tif"), 1, 1, &[&[1], &[2]]);
        write_tiff::<Gray8>(&sub.join("p2.tif"), 1, 1, &[&[3]]);
        write_tiff::<Gray8>(&sub.join("p10.tif"), 1, 1, &[&[4], &[5]]);
        assert_eq!(
            read(&sub).unwrap().data(),
            &VoxelData::U8(vec![1, 2, 3, 4, 5].into())
        );
    }

    #[test]
    fn different_sizes_name_the_file_and_both_sizes() {
        let dir = tempfile::tempdir().unwrap();
        gray8(&dir.path().join("a1.png"), 4, 4, 0);
        gray8(&dir.path().join("a2.png"), 4, 4, 0);
        gray8(&dir.path().join("a3.png"), 5, 4, 0);
        gray8(&dir.path().join("a4.png"), 3, 3, 0);
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains("a3.png") && s.contains("5×4") && s.contains("a1.png") && s.contains("4×4"),
            "{s}"
        );
        assert!(s.contains("`image size`"), "{s}");
    }

    #[test]
    fn different_types_are_an_error() {
        let dir = tempfile::tempdir().unwrap();
        gray8(&dir.path().join("a1.png"), 2, 2, 0);
        write_png(
            &dir.path().join("a2.png"),
            2,
            2,
            png::ColorType::Grayscale,
            png::BitDepth::Sixteen,
            &[0; 8],
        );
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains("a2.png") && s.contains("`pixel type`") && s.contains("u16"),
            "{s}"
        );
    }

    #[test]
    fn corrupt_png_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        gray8(&dir.path().join("a1.png"), 64, 64, 5);
        // Damage the compressed data (keeps the header readable).
        let p = dir.path().join("a2.png");
        gray8(&p, 64, 64, 5);
        let mut b = std::fs::read(&p).unwrap();
        let idat = b.windows(4).position(|w| w == b"IDAT").unwrap();
        for x in &mut b[idat + 4..idat + 20] {
            *x ^= 0x5a;
        }
        std::fs::write(&p, &b).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(s.contains("a2.png") && s.contains("PNG"), "{s}");
        // Truncated after the header.
        std::fs::write(&p, &b[..idat + 8]).unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(s.contains("a2.png") && s.contains("PNG"), "{s}");
        // Not a PNG at all.
        std::fs::write(&p, b"hello, world").unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(s.contains("a2.png") && s.contains("`magic`"), "{s}");
    }

    #[test]
    fn lying_png_header_is_refused_before_allocating() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("big.png");
        gray8(&p, 4, 4, 1);
        let mut b = std::fs::read(&p).unwrap();
        // IHDR data starts at byte 16: width, height; then the CRC at 29.
        b[16..20].copy_from_slice(&60000u32.to_be_bytes());
        b[20..24].copy_from_slice(&60000u32.to_be_bytes());
        let mut crc = flate2::Crc::new();
        crc.update(&b[12..29]);
        b[29..33].copy_from_slice(&crc.sum().to_be_bytes());
        std::fs::write(&p, &b).unwrap();
        let s = read(&p).unwrap_err().to_string();
        assert!(s.contains("big.png") && s.contains("60000×60000"), "{s}");
    }

    #[test]
    fn empty_folder_and_no_matches_name_what_was_looked_for() {
        let dir = tempfile::tempdir().unwrap();
        let s = read(dir.path()).unwrap_err().to_string();
        assert!(
            s.contains(&dir.path().display().to_string()) && s.contains(".png, .tif, .tiff"),
            "{s}"
        );
        let pat = dir.path().join("slice_*.png");
        let s = read(&pat).unwrap_err().to_string();
        assert!(
            s.contains("slice_*.png") && s.contains(".png, .tif, .tiff"),
            "{s}"
        );
        let s = read(&dir.path().join("missing.png"))
            .unwrap_err()
            .to_string();
        assert!(s.contains("missing.png"), "{s}");
    }
}
