//! `voxcast bench-frames --chart`: frame rate against frame, one line per
//! method (S0 Fig. 14), as a PNG.

use super::{axes, canvas, drawing, encode, font, FAMILY, PALETTE};
use crate::bench_frames::FramesReport;
use plotters::prelude::*;
use voxcast::error::Result;

const SIZE: (u32, u32) = (1000, 560);

/// The chart of `report` as PNG bytes.
pub fn png(report: &FramesReport) -> Result<Vec<u8>> {
    encode(SIZE, |buf| draw(report, buf))
}

fn draw(r: &FramesReport, buf: &mut [u8]) -> Result<()> {
    font()?;
    let x0 = r.frames.first().map(|f| f.frame).unwrap_or(0) as f64;
    let x1 = (r.frames.last().map(|f| f.frame).unwrap_or(1) as f64).max(x0 + 1.0);
    let y1 = r
        .frames
        .iter()
        .flat_map(|f| f.results.iter().map(|x| x.fps))
        .fold(0.0, f64::max)
        .max(1.0)
        * 1.15;
    let root = canvas(buf, SIZE)?;
    let title = format!(
        "voxcast bench-frames — {}, {}×{}, {} threads",
        crate::input_label(&r.input),
        r.width,
        r.height,
        r.threads
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FAMILY, 22))
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, 0.0..y1)
        .map_err(drawing)?;
    axes(&mut chart, "frame", "frames per second (best of repeats)")
        .draw()
        .map_err(drawing)?;
    for (m, s) in r.summary.iter().enumerate() {
        let color = PALETTE[m % PALETTE.len()];
        let pts: Vec<(f64, f64)> = r
            .frames
            .iter()
            .map(|f| (f.frame as f64, f.results[m].fps))
            .collect();
        chart
            .draw_series(std::iter::once(PathElement::new(
                pts.clone(),
                color.stroke_width(2),
            )))
            .map_err(drawing)?
            .label(format!(
                "{} (mean {:.1} fps, {:.2}× uniform)",
                s.name, s.mean_fps, s.mean_speedup
            ))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(3))
            });
        chart
            .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
            .map_err(drawing)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FAMILY, 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(drawing)?;
    root.present().map_err(drawing)?;
    Ok(())
}
