//! `voxcast info`.

use crate::args::InfoArgs;
use anyhow::Result;
use std::path::Path;
use voxcast::scene::Scene;
use voxcast::volume::ChunkedSource;

pub fn run(a: InfoArgs) -> Result<()> {
    let mut scene = Scene::default();
    scene.input.path = a.input.clone();
    scene.input.options = a.open.options()?;
    // A chunked store: its levels; the statistics of the finest level of
    // at most 512 MiB unless --level says which.
    let zarr = if voxcast::io::detect(Path::new(&a.input), &scene.input.options).ok()
        == Some(voxcast::io::Format::Zarr)
    {
        let store =
            voxcast::io::zarr::ZarrStore::open_with(Path::new(&a.input), &scene.input.options)?;
        let n = store.levels().len();
        let level = scene
            .input
            .options
            .level
            .unwrap_or_else(|| store.finest_within(512 << 20).unwrap_or(n - 1));
        scene.input.options.level = Some(level);
        let mut lines = store.summary();
        lines.push(format!("statistics below: level {level}"));
        // The same for scripts: one object per level.
        let i = store.info();
        let ty = store.scalar_type();
        let levels: Vec<serde_json::Value> = store
            .levels()
            .iter()
            .zip(&i.levels)
            .map(|(l, li)| {
                serde_json::json!({
                    "path": li.path,
                    "dims": l.dims,
                    "spacing": l.spacing.to_array(),
                    "origin": l.origin.to_array(),
                    "chunk": l.chunk,
                    "codecs": li.codecs,
                    "bytes": l.bytes(ty),
                    "chunk_ranges": li.has_ranges,
                })
            })
            .collect();
        let json = serde_json::json!({
            "zarr_format": i.zarr_format,
            "ome_version": i.ome_version,
            "data_type": i.stored.name(),
            "fill_value": i.fill,
            "axes": i.axes.iter().map(|(n, k, u)| serde_json::json!({"name": n, "type": k, "unit": u})).collect::<Vec<_>>(),
            "levels": levels,
            "statistics_level": level,
        });
        Some((lines, json))
    } else {
        None
    };
    let vol = scene.load_volume()?;
    // An FDS case: its meshes, quantities, times and obstructions.
    let fds = if a.input.to_ascii_lowercase().ends_with(".smv") {
        Some(voxcast::io::fds::parse_smv(Path::new(&a.input))?.summary())
    } else {
        None
    };
    // A WRF file: its 3D fields and times.
    let wrf = if voxcast::io::detect(Path::new(&a.input), &scene.input.options).ok()
        == Some(voxcast::io::Format::Wrf)
    {
        Some(voxcast::io::wrf::summary(Path::new(&a.input))?)
    } else {
        None
    };
    // A DICOM folder or file: the series found, their frames and transfer
    // syntaxes, and the files skipped.
    let dicom = if voxcast::io::detect(Path::new(&a.input), &scene.input.options).ok()
        == Some(voxcast::io::Format::Dicom)
    {
        Some(voxcast::io::dicom::summary(
            Path::new(&a.input),
            scene.input.options.variable.as_deref(),
        )?)
    } else {
        None
    };
    // NIfTI-1/2, Analyze, MGH, MINC: what the header says.
    let header = voxcast::io::header_summary(Path::new(&a.input), &scene.input.options)?;
    let s = *vol.stats();
    let hist = vol.histogram(256);
    let pct = [0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 0.99].map(|q| (q, hist.quantile(q)));
    let d = vol.dims();
    let (lo, hi) = vol.world_bounds();
    if a.json {
        let coarse = vol.histogram(64);
        let j = serde_json::json!({
            "path": a.input,
            "name": vol.name,
            "dims": d,
            "scalar_type": vol.scalar_type().name(),
            "spacing": vol.spacing().to_array(),
            "origin": vol.origin().to_array(),
            "extent": [lo.to_array(), hi.to_array()],
            "units": vol.units,
            "min": s.min,
            "max": s.max,
            "mean": s.mean,
            "nan": s.nan,
            "inf": s.inf,
            "percentiles": pct.iter().map(|(q, v)| serde_json::json!({"q": q, "value": v})).collect::<Vec<_>>(),
            "histogram": {"lo": coarse.lo, "hi": coarse.hi, "counts": coarse.counts},
            "variables": vol.variables,
            "active_voxels": vol.active_voxels,
            "fds": fds,
            "wrf": wrf,
            "dicom": dicom,
            "zarr": zarr.as_ref().map(|z| &z.1),
            "header": header.as_ref().map(|(_, lines)| lines),
            "time": vol.time,
        });
        println!("{}", serde_json::to_string_pretty(&j)?);
        return Ok(());
    }
    println!("{}", a.input);
    if let Some(n) = &vol.name {
        println!("  name        {n}");
    }
    println!(
        "  dims        {} × {} × {}  ({} voxels, {:.1} MB)",
        d[0],
        d[1],
        d[2],
        vol.len(),
        (vol.len() * vol.scalar_type().size()) as f64 / 1e6
    );
    println!("  type        {}", vol.scalar_type());
    let sp = vol.spacing();
    let o = vol.origin();
    println!("  spacing     {} {} {}", sp.x, sp.y, sp.z);
    println!("  origin      {} {} {}", o.x, o.y, o.z);
    println!(
        "  extent      {:.4} … {:.4}, {:.4} … {:.4}, {:.4} … {:.4}",
        lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
    );
    let units = vol
        .units
        .as_deref()
        .map(|u| format!(" {u}"))
        .unwrap_or_default();
    println!(
        "  range       {} … {}{units}  (mean {:.4})",
        s.min, s.max, s.mean
    );
    println!("  NaN / Inf   {} / {}", s.nan, s.inf);
    let p: Vec<String> = pct
        .iter()
        .map(|(q, v)| format!("p{}={}", (q * 100.0) as u32, v))
        .collect();
    println!("  percentiles {}", p.join("  "));
    println!(
        "  histogram   {}  (64 bins, log counts)",
        sparkline(&vol.histogram(64).counts)
    );
    if let Some(n) = vol.active_voxels {
        println!("  active      {n} voxels");
    }
    if let Some(lines) = &fds {
        println!("  FDS case");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some(lines) = &wrf {
        println!("  WRF output");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some((title, lines)) = &header {
        println!("  {title}");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some((lines, _)) = &zarr {
        println!("  Zarr store");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some(lines) = &dicom {
        println!("  DICOM series");
        for l in lines {
            println!("    {l}");
        }
    }
    if let Some(t) = vol.time {
        println!("  time        {t}");
    }
    if !vol.variables.is_empty() {
        println!("  variables   {}", vol.variables.join(", "));
    }
    Ok(())
}

/// A one-line histogram of log counts.
fn sparkline(counts: &[u64]) -> String {
    const BARS: [char; 8] = ['▁', '▂', '▃', '▄', '▅', '▆', '▇', '█'];
    let max = counts.iter().copied().max().unwrap_or(0) as f64;
    counts
        .iter()
        .map(|&c| {
            if c == 0 {
                ' '
            } else {
                let f = (c as f64).ln_1p() / max.ln_1p().max(1e-9);
                BARS[((f * 7.0).round() as usize).min(7)]
            }
        })
        .collect()
}
