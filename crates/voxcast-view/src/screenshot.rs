//! Screenshots: the window's pixels (as the compositor got them from egui)
//! cropped to the volume view, written as an 8-bit sRGB PNG, atomically.

use std::path::Path;

/// An sRGB 8-bit RGB picture.
#[derive(Clone, Debug, PartialEq)]
pub struct Rgb8 {
    pub width: u32,
    pub height: u32,
    /// `width·height·3` bytes, row 0 at the top.
    pub data: Vec<u8>,
}

/// Crops RGBA rows `rgba` (`width` wide) to the pixel rectangle
/// `[x0, x1) × [y0, y1)`, clamped to the picture; alpha is dropped.
pub fn crop_rgba(
    rgba: &[u8],
    width: u32,
    height: u32,
    (x0, y0, x1, y1): (u32, u32, u32, u32),
) -> Rgb8 {
    let (x1, y1) = (x1.min(width), y1.min(height));
    let (x0, y0) = (x0.min(x1), y0.min(y1));
    let (w, h) = (x1 - x0, y1 - y0);
    let mut data = Vec::with_capacity((w * h * 3) as usize);
    for y in y0..y1 {
        let row = &rgba[(y * width * 4) as usize..((y + 1) * width * 4) as usize];
        for x in x0..x1 {
            let p = &row[(x * 4) as usize..(x * 4 + 3) as usize];
            data.extend_from_slice(p);
        }
    }
    Rgb8 {
        width: w,
        height: h,
        data,
    }
}

impl Rgb8 {
    /// Writes an RGB PNG to `path` through a temporary file and a rename.
    pub fn write_png(&self, path: &Path) -> voxcast::Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(voxcast::Error::invalid(format!(
                "{}: the screenshot is empty ({}×{})",
                path.display(),
                self.width,
                self.height
            )));
        }
        voxcast::files::write_file(path, |f| {
            let mut enc = png::Encoder::new(f, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
            let mut w = enc.write_header().map_err(std::io::Error::other)?;
            w.write_image_data(&self.data)
                .map_err(std::io::Error::other)?;
            w.finish().map_err(std::io::Error::other)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crop_takes_the_rectangle_and_round_trips_through_png() {
        // 4×3 picture, pixel (x, y) = (x, y, 7, 255).
        let mut rgba = Vec::new();
        for y in 0..3u8 {
            for x in 0..4u8 {
                rgba.extend_from_slice(&[x * 60, y * 100, 7, 255]);
            }
        }
        let c = crop_rgba(&rgba, 4, 3, (1, 1, 3, 9));
        assert_eq!((c.width, c.height), (2, 2));
        assert_eq!(&c.data[..6], &[60, 100, 7, 120, 100, 7]);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.png");
        c.write_png(&p).unwrap();
        let img = voxcast::Image::read(&p).unwrap();
        assert_eq!((img.width, img.height), (2, 2));
        let back = img.to_srgb8();
        assert_eq!(back, c.data);
        let empty = crop_rgba(&rgba, 4, 3, (5, 5, 9, 9));
        assert!(empty.write_png(&dir.path().join("e.png")).is_err());
        assert!(!dir.path().join("e.png").exists());
    }
}
