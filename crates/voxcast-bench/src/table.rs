//! The report as a table: Markdown (for the README) or aligned plain text,
//! with the scene, the machine and the reference stated above it.

use crate::report::{BenchReport, CacheStatus, Measured};

/// `1234567` → `1,234,567`.
fn grouped_int(n: u64) -> String {
    let s = n.to_string();
    // The leading group has 1 to 3 digits, every later one 3.
    let (head, rest) = s.split_at((s.len() - 1) % 3 + 1);
    let mut out = head.to_string();
    for group in rest.as_bytes().chunks(3) {
        out.push(',');
        out.push_str(std::str::from_utf8(group).expect("ASCII digits"));
    }
    out
}

fn fmt_ms(ms: f64) -> String {
    if ms >= 100.0 {
        format!("{ms:.0}")
    } else if ms >= 10.0 {
        format!("{ms:.1}")
    } else {
        format!("{ms:.2}")
    }
}

fn fmt_psnr(m: &Measured) -> String {
    if m.psnr_db.is_finite() {
        format!("{:.2}", m.psnr_db)
    } else {
        "∞".into()
    }
}

const HEADER: [&str; 7] = [
    "method",
    "samples",
    "interpolations",
    "ms (median [min–max])",
    "speed-up",
    "PSNR dB",
    "SSIM",
];

/// The table's cells, one row per method.
fn rows(report: &BenchReport) -> Vec<[String; 7]> {
    report
        .methods
        .iter()
        .map(|m| match &m.measured {
            Some(x) => [
                match &m.quality {
                    Some(q) => format!("{} ({})", m.name, q.setting()),
                    None => m.name.clone(),
                },
                grouped_int(x.samples),
                grouped_int(x.interpolations),
                format!(
                    "{} [{}–{}]{}",
                    fmt_ms(x.ms_median),
                    fmt_ms(x.ms_min),
                    fmt_ms(x.ms_max),
                    match x.device_ms_median {
                        Some(d) => format!(" (GPU {})", fmt_ms(d)),
                        None => String::new(),
                    }
                ),
                format!("{:.2}×", x.speedup_vs_uniform),
                fmt_psnr(x),
                format!("{:.4}", x.ssim),
            ],
            None => [
                m.name.clone(),
                format!("failed: {}", m.error.as_deref().unwrap_or("no measurement")),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
                String::new(),
            ],
        })
        .collect()
}

/// The lines that say what was measured where.
fn preamble(r: &BenchReport) -> Vec<String> {
    let s = &r.scene;
    let onoff = |b: bool| if b { "on" } else { "off" };
    let ert = if s.ert >= 1.0 {
        "off".to_string()
    } else {
        format!("{}", s.ert)
    };
    let mut machine = format!("{} rayon threads", r.machine.threads);
    if let Some(cpu) = &r.machine.cpu {
        machine.push_str(&format!(", {cpu}"));
    }
    machine.push_str(&format!(", SIMD {}", r.machine.simd));
    let reference = &r.reference;
    let mut lines = vec![
        format!(
            "Scene: {} ({}×{}×{} {}), {}×{} image, tf {} (window {} … {}), step {} voxel, ERT {}, shading {}, empty-space skipping {}.",
            s.input,
            s.dims[0],
            s.dims[1],
            s.dims[2],
            s.scalar_type,
            s.width,
            s.height,
            s.tf,
            s.window[0],
            s.window[1],
            s.step,
            ert,
            onoff(s.shading),
            onoff(s.skip_empty)
        ),
        format!(
            "Machine: {machine}; median of {} timed renders after {} warm-up, voxcast {}.",
            r.run.repeat, r.run.warmup, r.run.voxcast_version
        ),
        format!(
            "Reference: uniform, step 1/{} voxel, ERT off, no empty-space skipping ({} samples, {} ms, cache {}).",
            (1.0 / reference.step).round(),
            grouped_int(reference.samples),
            fmt_ms(reference.ms),
            match reference.cache {
                CacheStatus::Hit => "hit",
                CacheStatus::Miss => "miss",
                CacheStatus::Refreshed => "refreshed",
                CacheStatus::Off => "off",
            }
        ),
    ];
    let on_device: Vec<String> = r
        .methods
        .iter()
        .filter_map(|m| {
            let x = m.measured.as_ref()?;
            let d = x.device_ms_median?;
            let per_s = x.samples as f64 / d * 1e3;
            Some(if per_s >= 1e9 {
                format!("{} {:.1} G samples/s", m.name, per_s * 1e-9)
            } else {
                format!("{} {:.1} M samples/s", m.name, per_s * 1e-6)
            })
        })
        .collect();
    // On a CPU with packets, the methods that ran the scalar loop.
    let packets_here = r.run.device == "cpu" && r.machine.simd != "none";
    let scalar: Vec<&str> = r
        .methods
        .iter()
        .filter(|m| packets_here && m.measured.as_ref().is_some_and(|x| x.simd.is_none()))
        .map(|m| m.name.as_str())
        .collect();
    if !scalar.is_empty() && r.run.simd == voxcast::render::Simd::Scalar {
        lines.push("Scalar loop for every method, as asked (--simd scalar).".to_string());
    } else if !scalar.is_empty() {
        lines.push(format!(
            "Scalar loop (these methods do not run in the SIMD packets yet): {}.",
            scalar.join(", ")
        ));
    }
    // The methods that left skipping out (hardly a block is empty).
    let unskipped: Vec<(&str, f32)> = r
        .methods
        .iter()
        .filter_map(|m| Some((m.name.as_str(), m.measured.as_ref()?.skipping_left_out?)))
        .collect();
    if let Some(&(_, share)) = unskipped.first() {
        let names: Vec<&str> = unskipped.iter().map(|u| u.0).collect();
        lines.push(format!(
            "Empty-space skipping left out by {}: the transfer function hides {:.1} % of the blocks, under the {:.1} % where skipping pays for its tests (the pictures are the same; the samples include the empty ones).",
            names.join(", "),
            share * 100.0,
            voxcast::render::SKIP_PAYS * 100.0
        ));
    }
    // The blocks each method skipped with, where they differ.
    let mut sizes: Vec<(u32, Vec<&str>)> = Vec::new();
    for m in &r.methods {
        let Some(b) = m.measured.as_ref().map(|x| x.block_size).filter(|&b| b > 0) else {
            continue;
        };
        match sizes.iter_mut().find(|s| s.0 == b) {
            Some(s) => s.1.push(m.name.as_str()),
            None => sizes.push((b, vec![m.name.as_str()])),
        }
    }
    if sizes.len() > 1 {
        let parts: Vec<String> = sizes
            .iter()
            .map(|(b, names)| format!("{b}³ for {}", names.join(", ")))
            .collect();
        lines.push(format!(
            "Blocks: {} (unset, uniform, jitter, stratified, mc and adaptive+grouped take 4³ on sparse data; --block-size sets one for all).",
            parts.join("; ")
        ));
    }
    if !on_device.is_empty() {
        lines.push(format!(
            "(GPU ms): the compute passes alone, by timestamp queries; the wall time adds writing the parameters, reading the image back and averaging it on the CPU. On the device: {}.",
            on_device.join(", ")
        ));
    }
    lines
}

/// The report as a Markdown table (for the README), with the scene, the
/// machine and the reference stated above it.
pub fn markdown(report: &BenchReport) -> String {
    let mut out = String::new();
    for l in preamble(report) {
        out.push_str(&l);
        out.push_str("\n\n");
    }
    out.push_str(&format!("| {} |\n", HEADER.join(" | ")));
    out.push_str("|---|---:|---:|---:|---:|---:|---:|\n");
    for row in rows(report) {
        let cells: Vec<String> = row.iter().map(|c| c.replace('|', "\\|")).collect();
        out.push_str(&format!("| {} |\n", cells.join(" | ")));
    }
    for n in &report.notes {
        out.push_str(&format!("\nNote: {n}\n"));
    }
    out
}

/// The report as an aligned plain-text table.
pub fn text_table(report: &BenchReport) -> String {
    let rows = rows(report);
    let width = |i: usize| {
        rows.iter()
            .filter(|r| r[2].chars().count() > 0 || i == 0)
            .map(|r| r[i].chars().count())
            .chain([HEADER[i].chars().count()])
            .max()
            .unwrap_or(0)
    };
    let widths: Vec<usize> = (0..7).map(width).collect();
    let line = |cells: &[String]| {
        let mut s = String::new();
        for (i, c) in cells.iter().enumerate() {
            let pad = widths[i].saturating_sub(c.chars().count());
            if i > 0 {
                s.push_str("  ");
            }
            if i == 0 {
                s.push_str(c);
                s.push_str(&" ".repeat(pad));
            } else {
                s.push_str(&" ".repeat(pad));
                s.push_str(c);
            }
        }
        s.trim_end().to_string()
    };
    let mut out = String::new();
    for l in preamble(report) {
        out.push_str(&l);
        out.push('\n');
    }
    out.push('\n');
    let header: Vec<String> = HEADER.iter().map(|h| h.to_string()).collect();
    out.push_str(&line(&header));
    out.push('\n');
    for row in &rows {
        if row[2].is_empty() {
            // A failed method: name, then the message.
            out.push_str(&format!("{:w$}  {}\n", row[0], row[1], w = widths[0]));
        } else {
            out.push_str(&line(row));
            out.push('\n');
        }
    }
    for n in &report.notes {
        out.push_str(&format!("note: {n}\n"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input_label;

    #[test]
    fn labels_and_numbers() {
        assert_eq!(input_label("builtin:demo"), "demo");
        assert_eq!(
            input_label("../shared/data/teapot_ct/slices"),
            "teapot_ct/slices"
        );
        assert_eq!(input_label("vol.nrrd"), "vol.nrrd");
        assert_eq!(grouped_int(0), "0");
        assert_eq!(grouped_int(999), "999");
        assert_eq!(grouped_int(1000), "1,000");
        assert_eq!(grouped_int(28_901_234), "28,901,234");
    }
}
