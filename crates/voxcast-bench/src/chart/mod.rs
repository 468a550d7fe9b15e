//! The reports as PNG charts: [`bench_png`] (`voxcast bench --chart`:
//! median time against PSNR, one labelled point per method) and
//! [`frames_png`] (`voxcast bench-frames --chart`: frame rate against frame,
//! one line per method, S0 Fig. 14).
//!
//! Text is drawn with DejaVu Sans embedded in the binary (see
//! `assets/DejaVuSans-LICENSE.txt`), so a chart looks the same on a machine
//! without system fonts; plotters draws into an RGB buffer that the `png`
//! crate encodes (no image crate, no font-kit).
//!
//! This file holds what both charts share: the font, the palette, the
//! canvas, the axes' style and the PNG encoding.

mod bench;
mod frames;

pub use bench::png as bench_png;
pub use frames::png as frames_png;

use plotters::chart::{ChartContext, MeshStyle};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::sync::Once;
use voxcast::error::{Error, Result};

const FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");
const FAMILY: &str = "sans-serif";

/// Colour-blind-safe palette (Okabe & Ito 2008).
const PALETTE: [RGBColor; 8] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(120, 120, 120),
    RGBColor(0, 0, 0),
];

/// Registers the embedded font under [`FAMILY`] (once).
fn font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut ok = true;
    ONCE.call_once(|| ok = register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if ok {
        Ok(())
    } else {
        Err(Error::invalid("the embedded chart font could not be read"))
    }
}

/// A plotters error as the library's.
fn drawing<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> Error {
    Error::invalid(format!("drawing the chart: {e}"))
}

/// A chart of `size` pixels drawn by `draw` into a white RGB buffer, as
/// PNG bytes (sRGB).
fn encode(size: (u32, u32), draw: impl FnOnce(&mut [u8]) -> Result<()>) -> Result<Vec<u8>> {
    let (w, h) = size;
    let mut buf = vec![255u8; (w * h * 3) as usize];
    draw(&mut buf)?;
    let png_error = |e: png::EncodingError| Error::invalid(e.to_string());
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    let mut wr = enc.write_header().map_err(png_error)?;
    wr.write_image_data(&buf).map_err(png_error)?;
    wr.finish().map_err(png_error)?;
    Ok(out)
}

/// The drawing area of `buf`: white, inside the charts' margins.
fn canvas(buf: &mut [u8], size: (u32, u32)) -> Result<DrawingArea<BitMapBackend<'_>, Shift>> {
    let root = BitMapBackend::with_buffer(buf, size).into_drawing_area();
    root.fill(&WHITE).map_err(drawing)?;
    Ok(root.margin(14, 14, 18, 24))
}

/// The axes of `chart` named `x` and `y`, labelled in the charts' font;
/// the caller adds its own style and draws them.
fn axes<'a, 'b, DB: DrawingBackend>(
    chart: &'a mut ChartContext<'b, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    x: &str,
    y: &str,
) -> MeshStyle<'b, 'a, RangedCoordf64, RangedCoordf64, DB> {
    let mut mesh = chart.configure_mesh();
    mesh.x_desc(x).y_desc(y).label_style((FAMILY, 15));
    mesh
}
