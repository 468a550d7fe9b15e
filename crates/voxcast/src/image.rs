//! Images: linear RGBA f32 pixels, encoded to sRGB 8-bit only on output.
//! Files are written through [`Outputs`]: under a temporary name beside the
//! target, renamed into place only when complete.

use crate::error::{Error, Result};
use crate::files::Outputs;
use crate::transfer::{linear_to_srgb, srgb_to_linear};
use std::io::Write;
use std::path::Path;

/// A linear-light RGBA image, row 0 at the top. RGB is already composited
/// over the background; A is the volume's coverage.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[f32; 4]>,
}

impl Image {
    /// A black, transparent image.
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![[0.0; 4]; width as usize * height as usize],
        }
    }

    /// Pixel at (x, y).
    pub fn get(&self, x: u32, y: u32) -> [f32; 4] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Sets pixel (x, y).
    pub fn set(&mut self, x: u32, y: u32, p: [f32; 4]) {
        let w = self.width;
        self.pixels[(y * w + x) as usize] = p;
    }

    /// RGB bytes, sRGB-encoded.
    pub fn to_srgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| [p[0], p[1], p[2]].map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8))
            .collect()
    }

    /// The image as the bytes of an 8-bit sRGB PNG, as [`Image::write_png`]
    /// writes them (for notebooks and in-memory use).
    pub fn png_bytes(&self) -> Result<Vec<u8>> {
        let mut v = Vec::new();
        self.encode_png(&mut v)
            .map_err(|e| Error::invalid(format!("cannot encode the image as PNG: {e}")))?;
        Ok(v)
    }

    /// Encodes an 8-bit sRGB PNG (RGB) into `w`.
    fn encode_png(&self, w: &mut impl Write) -> std::io::Result<()> {
        let data = self.to_srgb8();
        let mut enc = png::Encoder::new(w, self.width, self.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut w = enc.write_header().map_err(std::io::Error::other)?;
        w.write_image_data(&data).map_err(std::io::Error::other)?;
        w.finish().map_err(std::io::Error::other)
    }

    /// Writes a linear float RGBA OpenEXR file at `tmp` (errors name `path`).
    fn encode_exr(&self, tmp: &Path, path: &Path) -> Result<()> {
        let w = self.width as usize;
        exr::prelude::write_rgba_file(tmp, w, self.height as usize, |x, y| {
            let p = self.pixels[y * w + x];
            (p[0], p[1], p[2], p[3])
        })
        .map_err(|e| Error::io(path, std::io::Error::other(e.to_string())))
    }

    /// Adds the image to a command's outputs: an 8-bit sRGB PNG or a linear
    /// float RGBA EXR by the extension of `path`.
    pub fn write_into(&self, outputs: &mut Outputs, path: &Path) -> Result<()> {
        match extension(path).as_str() {
            "png" => outputs.write(path, |w| self.encode_png(w)),
            "exr" => self.write_exr_into(outputs, path),
            e => Err(Error::invalid(format!(
                "{}: unknown image extension `{e}` (use .png or .exr)",
                path.display()
            ))),
        }
    }

    /// Adds the image to a command's outputs as a linear float RGBA EXR,
    /// whatever the extension of `path`.
    pub fn write_exr_into(&self, outputs: &mut Outputs, path: &Path) -> Result<()> {
        outputs.write_with(path, |tmp| self.encode_exr(tmp, path))
    }

    /// Writes PNG or EXR by the extension of `path`, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let mut o = Outputs::default();
        self.write_into(&mut o, path)?;
        o.commit()
    }

    /// Writes an 8-bit sRGB PNG (RGB), whatever the extension.
    pub fn write_png(&self, path: &Path) -> Result<()> {
        let mut o = Outputs::default();
        o.write(path, |w| self.encode_png(w))?;
        o.commit()
    }

    /// Writes a linear float RGBA OpenEXR file, whatever the extension.
    pub fn write_exr(&self, path: &Path) -> Result<()> {
        let mut o = Outputs::default();
        self.write_exr_into(&mut o, path)?;
        o.commit()
    }

    /// Reads a PNG (8 or 16 bit; grey, grey+alpha, RGB, RGBA or palette) or an
    /// RGBA EXR into linear light. PNG values are taken as sRGB-encoded.
    pub fn read(path: &Path) -> Result<Image> {
        match extension(path).as_str() {
            "exr" => read_exr(path),
            _ => read_png(path),
        }
    }
}

fn extension(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

fn read_png(path: &Path) -> Result<Image> {
    let (f, _) = crate::files::open(path)?;
    let mut dec = png::Decoder::new(std::io::BufReader::new(f));
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec
        .read_info()
        .map_err(|e| Error::format(path, "PNG", e.to_string()))?;
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| Error::format(path, "PNG", "image too large"))?;
    let mut buf = vec![0u8; size];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| Error::format(path, "PNG data", e.to_string()))?;
    let (w, h) = (info.width, info.height);
    let channels = info.color_type.samples();
    let sixteen = info.bit_depth == png::BitDepth::Sixteen;
    let bytes_per = if sixteen { 2 } else { 1 };
    let get = |i: usize| -> f32 {
        if sixteen {
            u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]]) as f32 / 65535.0
        } else {
            buf[i] as f32 / 255.0
        }
    };
    let mut img = Image::new(w, h);
    let stride = info.line_size / bytes_per;
    for y in 0..h as usize {
        for x in 0..w as usize {
            let base = y * stride + x * channels;
            let (r, g, b, a) = match channels {
                1 => (get(base), get(base), get(base), 1.0),
                2 => (get(base), get(base), get(base), get(base + 1)),
                3 => (get(base), get(base + 1), get(base + 2), 1.0),
                _ => (get(base), get(base + 1), get(base + 2), get(base + 3)),
            };
            img.set(
                x as u32,
                y as u32,
                [srgb_to_linear(r), srgb_to_linear(g), srgb_to_linear(b), a],
            );
        }
    }
    Ok(img)
}

fn read_exr(path: &Path) -> Result<Image> {
    // The EXR crate opens the path itself: refuse a device or a pipe first.
    crate::files::regular_file(path)?;
    let img = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |res, _| Image::new(res.width() as u32, res.height() as u32),
        |img: &mut Image, pos, (r, g, b, a): (f32, f32, f32, f32)| {
            img.set(pos.x() as u32, pos.y() as u32, [r, g, b, a])
        },
    )
    .map_err(|e| Error::format(path, "EXR", e.to_string()))?;
    Ok(img.layer_data.channel_data.pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn png_and_exr_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = Image::new(3, 2);
        img.set(2, 1, [1.0, 0.5, 0.0, 1.0]);
        img.set(0, 0, [0.2, 0.2, 0.2, 0.5]);
        let p = dir.path().join("a.png");
        img.write(&p).unwrap();
        let back = Image::read(&p).unwrap();
        assert_eq!((back.width, back.height), (3, 2));
        for (a, b) in img.pixels.iter().zip(&back.pixels) {
            for c in 0..3 {
                // 8-bit sRGB quantisation
                assert!((linear_to_srgb(a[c]) - linear_to_srgb(b[c])).abs() <= 0.5 / 255.0 + 1e-6);
            }
        }
        let e = dir.path().join("a.exr");
        img.write(&e).unwrap();
        let back = Image::read(&e).unwrap();
        assert_eq!(back, img);
        // No temporary files left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn failed_write_leaves_target_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("keep.png");
        std::fs::write(&p, b"precious").unwrap();
        let r = crate::files::write_file(&p, |_| Err(std::io::Error::other("boom")));
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"precious");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
