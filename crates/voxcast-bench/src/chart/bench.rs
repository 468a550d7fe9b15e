//! `voxcast bench --chart`: median render time against PSNR, one labelled
//! point per method.

use super::{axes, canvas, drawing, encode, font, FAMILY, PALETTE};
use crate::BenchReport;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use voxcast::error::Result;

const SIZE: (u32, u32) = (1000, 660);

/// One point of the chart.
struct Point {
    label: String,
    ms: f64,
    ms_min: f64,
    ms_max: f64,
    /// `None`: identical to the reference (PSNR infinite).
    psnr: Option<f64>,
    color: RGBColor,
}

/// The chart of `report` as PNG bytes.
pub fn png(report: &BenchReport) -> Result<Vec<u8>> {
    encode(SIZE, |buf| draw(report, buf))
}

/// Axis range with some air around `lo…hi`.
fn padded(lo: f64, hi: f64, frac: f64, min_span: f64) -> (f64, f64) {
    let span = (hi - lo).max(min_span);
    let mid = 0.5 * (lo + hi);
    (mid - span * (0.5 + frac), mid + span * (0.5 + frac))
}

fn draw(report: &BenchReport, buf: &mut [u8]) -> Result<()> {
    font()?;
    let points: Vec<Point> = report
        .methods
        .iter()
        .filter_map(|m| m.measured.as_ref().map(|x| (m, x)))
        .enumerate()
        .map(|(i, (m, x))| Point {
            label: format!("{} ({:.2}×)", m.name, x.speedup_vs_uniform),
            ms: x.ms_median,
            ms_min: x.ms_min,
            ms_max: x.ms_max,
            psnr: x.psnr_db.is_finite().then_some(x.psnr_db),
            color: PALETTE[i % PALETTE.len()],
        })
        .collect();

    // x: time from 0, with room on the right for labels.
    let x_max = points
        .iter()
        .map(|p| p.ms_max)
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.25;
    // y: the finite PSNRs, with a row above them for "identical" (∞).
    let finite: Vec<f64> = points.iter().filter_map(|p| p.psnr).collect();
    let any_inf = points.iter().any(|p| p.psnr.is_none());
    let (y_lo, y_hi) = if finite.is_empty() {
        (0.0, 60.0)
    } else {
        let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        padded(lo, hi, 0.15, 4.0)
    };
    let y_inf = y_hi + 0.12 * (y_hi - y_lo);
    let y_top = if any_inf {
        y_inf + 0.06 * (y_hi - y_lo)
    } else {
        y_hi
    };

    let s = &report.scene;
    let title = format!("voxcast bench — {}, {}×{}", s.label, s.width, s.height);
    let subtitle = format!(
        "{} rayon threads; median of {} renders (bars: min–max); PSNR against uniform at 1/{} voxel, no ERT",
        report.machine.threads,
        report.run.repeat,
        (1.0 / report.reference.step).round()
    );

    let root = canvas(buf, SIZE)?;
    let (top, body) = root.split_vertically(62);
    top.draw(&Text::new(
        title,
        (0, 0),
        (FAMILY, 26).into_font().color(&BLACK),
    ))
    .map_err(drawing)?;
    top.draw(&Text::new(
        subtitle,
        (0, 34),
        (FAMILY, 15).into_font().color(&RGBColor(90, 90, 90)),
    ))
    .map_err(drawing)?;

    let mut chart = ChartBuilder::on(&body)
        .x_label_area_size(52)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..x_max, y_lo..y_top)
        .map_err(drawing)?;
    let y_fmt = |v: &f64| {
        if *v > y_hi + 1e-9 {
            String::new()
        } else {
            format!("{v:.0}")
        }
    };
    let x_fmt = |v: &f64| {
        if x_max < 5.0 {
            format!("{v:.2}")
        } else if x_max < 50.0 {
            format!("{v:.1}")
        } else {
            format!("{v:.0}")
        }
    };
    axes(
        &mut chart,
        "median render time (ms) — lower is faster",
        "PSNR against the reference (dB) — higher is better",
    )
    .axis_desc_style((FAMILY, 17))
    .x_label_formatter(&x_fmt)
    .y_label_formatter(&y_fmt)
    .light_line_style(WHITE)
    .bold_line_style(RGBColor(225, 225, 225))
    .draw()
    .map_err(drawing)?;

    // What a label must not cover, in pixels: (y centre, half height, x0, x1).
    let mut taken: Vec<(i32, i32, i32, i32)> = Vec::new();
    if any_inf {
        let grey = RGBColor(120, 120, 120);
        chart
            .draw_series(std::iter::once(DashedPathElement::new(
                [(0.0, y_inf), (x_max, y_inf)],
                6,
                4,
                grey.stroke_width(1),
            )))
            .map_err(drawing)?;
        let note = "identical to the reference";
        chart
            .draw_series(std::iter::once(
                EmptyElement::at((0.0, y_inf))
                    + Text::new(
                        note,
                        (8, -11),
                        (FAMILY, 14)
                            .into_font()
                            .color(&grey)
                            .pos(Pos::new(HPos::Left, VPos::Center)),
                    ),
            ))
            .map_err(drawing)?;
        let (px, py) = chart.backend_coord(&(0.0, y_inf));
        let (w, _) = body
            .estimate_text_size(note, &(FAMILY, 14).into_text_style(&body))
            .map_err(drawing)?;
        taken.push((py - 11, 9, px, px + 8 + w as i32));
        // "∞" on the y axis, where the row of identical images is.
        let base = body.get_base_pixel();
        body.draw(&Text::new(
            "∞",
            (px - base.0 - 8, py - base.1),
            (FAMILY, 18)
                .into_font()
                .color(&BLACK)
                .pos(Pos::new(HPos::Right, VPos::Center)),
        ))
        .map_err(drawing)?;
    }

    // Min–max bars and markers.
    for p in &points {
        let y = p.psnr.unwrap_or(y_inf);
        let style = p.color.stroke_width(2);
        chart
            .draw_series(std::iter::once(PathElement::new(
                [(p.ms_min, y), (p.ms_max, y)],
                style,
            )))
            .map_err(drawing)?;
        let cap = |x: f64| {
            EmptyElement::at((x, y)) + PathElement::new([(0, -5), (0, 5)], p.color.stroke_width(2))
        };
        chart
            .draw_series([cap(p.ms_min), cap(p.ms_max)])
            .map_err(drawing)?;
        let at = (p.ms, y);
        if p.psnr.is_some() {
            chart
                .draw_series(std::iter::once(Circle::new(at, 7, p.color.filled())))
                .map_err(drawing)?;
        } else {
            chart
                .draw_series(std::iter::once(TriangleMarker::new(
                    at,
                    9,
                    p.color.filled(),
                )))
                .map_err(drawing)?;
        }
        let (px, py) = chart.backend_coord(&at);
        let (bx0, _) = chart.backend_coord(&(p.ms_min, y));
        let (bx1, _) = chart.backend_coord(&(p.ms_max, y));
        taken.push((py, 9, px - 9, px + 9));
        taken.push((py, 5, bx0 - 1, bx1 + 1));
    }

    // Labels, top to bottom: beside the point, above or below its bar, on
    // the right where the text fits, else on the left; farther out when
    // those places are taken.
    let (plot_x, plot_y) = chart.plotting_area().get_pixel_range();
    let label_font = (FAMILY, 16).into_font().color(&BLACK);
    let mut order: Vec<usize> = (0..points.len()).collect();
    order.sort_by(|&a, &b| {
        let ya = points[a].psnr.unwrap_or(y_inf);
        let yb = points[b].psnr.unwrap_or(y_inf);
        yb.total_cmp(&ya)
            .then(points[a].ms.total_cmp(&points[b].ms))
    });
    for i in order {
        let p = &points[i];
        let at = (p.ms, p.psnr.unwrap_or(y_inf));
        let (px, py) = chart.backend_coord(&at);
        let (tw, _) = body
            .estimate_text_size(&p.label, &label_font)
            .map_err(drawing)?;
        let tw = tw as i32;
        let half = 9;
        let fits = |dx: i32, dy: i32| {
            let (x0, x1) = if dx > 0 {
                (px + dx, px + dx + tw)
            } else {
                (px + dx - tw, px + dx)
            };
            let yc = py + dy;
            x0 >= plot_x.start
                && x1 <= plot_x.end
                && yc - half >= plot_y.start
                && yc + half <= plot_y.end
                && !taken
                    .iter()
                    .any(|&(ty, th, a, b)| (ty - yc).abs() < th + half && a < x1 && x0 < b)
        };
        let mut candidates = Vec::new();
        for k in 1..=6 {
            for dx in [12, -12] {
                for dy in [-15 * k, 15 * k] {
                    candidates.push((dx, dy));
                }
            }
        }
        let (dx, dy) = candidates
            .into_iter()
            .find(|&(dx, dy)| fits(dx, dy))
            .unwrap_or((12, -15));
        let (x0, x1) = if dx > 0 {
            (px + dx, px + dx + tw)
        } else {
            (px + dx - tw, px + dx)
        };
        taken.push((py + dy, half, x0, x1));
        let anchor = if dx > 0 { HPos::Left } else { HPos::Right };
        chart
            .draw_series(std::iter::once(
                EmptyElement::at(at)
                    + Text::new(
                        p.label.clone(),
                        (dx, dy),
                        label_font.pos(Pos::new(anchor, VPos::Center)),
                    ),
            ))
            .map_err(drawing)?;
    }

    if points.is_empty() {
        body.draw(&Text::new(
            "no method rendered",
            (300, 250),
            (FAMILY, 22).into_font().color(&RED),
        ))
        .map_err(drawing)?;
    }
    root.present().map_err(drawing)?;
    Ok(())
}
