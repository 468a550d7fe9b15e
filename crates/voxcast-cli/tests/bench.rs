//! End-to-end tests of `voxcast bench`: the JSON report's fields, the
//! reference compared with itself, the reference cache, the chart, the
//! Markdown table, and bad input. Small images (64×64) keep them fast; every
//! run gets its own cache folder through `VOXCAST_CACHE`.

use std::path::Path;
use std::process::Output;

mod common;
use common::{read_json, stderr, voxcast_with};

fn bench(args: &[&str], cwd: &Path, cache: &Path) -> Output {
    let all: Vec<&str> = std::iter::once("bench")
        .chain(args.iter().copied())
        .collect();
    voxcast_with(&all, cwd, &[("VOXCAST_CACHE", &cache.to_string_lossy())])
}

const FIELDS: [&str; 9] = [
    "name",
    "samples",
    "interpolations",
    "ms_median",
    "ms_min",
    "ms_max",
    "speedup_vs_uniform",
    "psnr_db",
    "ssim",
];

#[test]
fn bench_json_has_every_field_for_every_method() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    // The default method list.
    let o = bench(
        &[
            "builtin:sphere",
            "--size",
            "64x64",
            "--repeat",
            "2",
            "--json",
            "b.json",
        ],
        dir.path(),
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j = read_json(&dir.path().join("b.json"));
    let methods = j["methods"].as_array().unwrap();
    let names: Vec<&str> = methods
        .iter()
        .map(|m| m["name"].as_str().unwrap())
        .collect();
    let default: Vec<&str> = voxcast_bench::DEFAULT_METHODS.split(',').collect();
    assert_eq!(names, default);
    for m in methods {
        for f in FIELDS {
            assert!(m.get(f).is_some(), "{} lacks `{f}`: {m}", m["name"]);
        }
        let num = |f: &str| {
            m[f].as_f64()
                .unwrap_or_else(|| panic!("{}: `{f}` is not a number: {m}", m["name"]))
        };
        assert!(m["samples"].as_u64().unwrap() > 0, "{m}");
        assert!(m["interpolations"].as_u64().unwrap() > 0, "{m}");
        assert_eq!(m["rays"], 64 * 64, "{m}");
        let (lo, med, hi) = (num("ms_min"), num("ms_median"), num("ms_max"));
        assert!(lo > 0.0 && lo <= med && med <= hi, "{m}");
        assert_eq!(m["ms_per_repeat"].as_array().unwrap().len(), 2, "{m}");
        assert!(num("speedup_vs_uniform") > 0.0, "{m}");
        let ssim = num("ssim");
        assert!(ssim > 0.5 && ssim <= 1.0 + 1e-12, "{m}");
        // PSNR: a number of dB, or null when the image equals the reference.
        match m["psnr_db"].as_f64() {
            Some(p) => assert!(p > 20.0 && m["identical"] == false, "{m}"),
            None => assert!(m["psnr_db"].is_null() && m["identical"] == true, "{m}"),
        }
        assert!(m.get("error").is_none(), "{m}");
    }
    let u = &methods[0];
    assert_eq!(u["name"], "uniform");
    assert_eq!(u["speedup_vs_uniform"].as_f64(), Some(1.0));
    assert_eq!(u["samples_vs_uniform"].as_f64(), Some(1.0));
    let r = &j["reference"];
    assert_eq!(r["method"], "uniform");
    assert_eq!(r["step"].as_f64(), Some(1.0 / 16.0));
    assert_eq!(r["ert"].as_f64(), Some(1.0));
    assert_eq!(r["skip_empty"], false);
    assert_eq!(r["cache"], "miss");
    // The reference takes 8× finer steps than the scene's 0.5 voxel and
    // never terminates early.
    assert!(r["samples"].as_u64().unwrap() > 4 * u["samples"].as_u64().unwrap());
    assert!(Path::new(r["cache_file"].as_str().unwrap()).starts_with(&cache));
    assert_eq!(j["scene"]["width"], 64);
    assert_eq!(j["run"]["repeat"], 2);
    assert!(j["machine"]["threads"].as_u64().unwrap() >= 1);
    // The plain table went to stdout, one row per method.
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("speed-up") && out.contains("PSNR dB"), "{out}");
    for n in default {
        assert!(
            out.lines().any(|l| l.starts_with(&format!("{n} "))),
            "{out}"
        );
    }
}

#[test]
fn reference_against_itself_gives_infinite_psnr() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    // `uniform` at the reference's own settings (jitter off, the default
    // being on) renders the reference.
    let o = bench(
        &[
            "builtin:sphere",
            "--size",
            "64x64",
            "--methods",
            "uniform",
            "--step",
            "0.0625",
            "--ert",
            "1",
            "--skip-empty",
            "off",
            "--jitter",
            "off",
            "--repeat",
            "1",
            "--warmup",
            "0",
            "--json",
            "self.json",
        ],
        dir.path(),
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j = read_json(&dir.path().join("self.json"));
    let m = &j["methods"][0];
    // Documented: infinite PSNR is written as null, with identical = true.
    assert!(m["psnr_db"].is_null(), "{m}");
    assert_eq!(m["identical"], true);
    assert_eq!(m["ssim"].as_f64(), Some(1.0));
    assert_eq!(m["samples"], j["reference"]["samples"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains('∞'), "{out}");
}

/// `--quality DB`: bench times each method at the setting its pilot chose
/// and names it; render says what it chose and `--save-scene` keeps it.
#[test]
fn quality_picks_a_setting_per_method_and_render_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let o = bench(
        &[
            "builtin:demo",
            "--size",
            "96x96",
            "--methods",
            "uniform,adaptive+grouped",
            "--quality",
            "42",
            "--repeat",
            "1",
            "--warmup",
            "0",
            "--json",
            "q.json",
        ],
        dir.path(),
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j = read_json(&dir.path().join("q.json"));
    for m in j["methods"].as_array().unwrap() {
        let q = &m["quality"];
        assert_eq!(q["target_db"], 42.0, "{m}");
        assert!(q["step"].as_f64().unwrap() > 0.0, "{m}");
        assert!(!q["trials"].as_array().unwrap().is_empty(), "{m}");
        // The full image lands near the target the pilot aimed at.
        let psnr = m["psnr_db"].as_f64().unwrap();
        assert!((psnr - 42.0).abs() < 2.0, "{m}");
    }
    assert!(j["methods"][1]["quality"]["tolerance"].is_number());
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("adaptive+grouped (step "), "{table}");

    let o = common::voxcast(
        &[
            "render",
            "builtin:demo",
            "--size",
            "96x96",
            "--quality",
            "42",
            "-o",
            "q.png",
            "--save-scene",
            "q.toml",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let said = stderr(&o);
    assert!(said.contains("--quality 42 dB: step "), "{said}");
    let saved = std::fs::read_to_string(dir.path().join("q.toml")).unwrap();
    let step: f64 = saved
        .lines()
        .find_map(|l| l.strip_prefix("step = "))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no step in {saved}"));
    assert!(
        step != 0.5,
        "the saved scene keeps the chosen step: {saved}"
    );
    // Nothing to measure against for the path tracer.
    let o = common::voxcast(
        &[
            "render",
            "builtin:demo",
            "--method",
            "path",
            "--quality",
            "40",
        ],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--spp"), "{}", stderr(&o));
}

#[test]
fn second_run_hits_the_reference_cache() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let run = |extra: &[&str], json: &str| {
        let mut args = vec![
            "builtin:demo",
            "--size",
            "48x40",
            "--methods",
            "uniform",
            "--repeat",
            "1",
            "--warmup",
            "0",
            "--json",
            json,
        ];
        args.extend_from_slice(extra);
        let o = bench(&args, dir.path(), &cache);
        assert!(o.status.success(), "{}", stderr(&o));
        read_json(&dir.path().join(json))
    };
    let a = run(&[], "a.json");
    assert_eq!(a["reference"]["cache"], "miss");
    let b = run(&[], "b.json");
    assert_eq!(b["reference"]["cache"], "hit");
    assert_eq!(a["reference"]["key"], b["reference"]["key"]);
    assert_eq!(a["reference"]["cache_file"], b["reference"]["cache_file"]);
    // The cached reference is exact: the same PSNR to the last bit.
    assert_eq!(a["methods"][0]["psnr_db"], b["methods"][0]["psnr_db"]);
    assert_eq!(a["methods"][0]["ssim"], b["methods"][0]["ssim"]);
    // The scene's own step does not change the reference …
    let c = run(&["--step", "0.8"], "c.json");
    assert_eq!(c["reference"]["cache"], "hit");
    // … the camera does.
    let d = run(&["--azimuth", "15"], "d.json");
    assert_eq!(d["reference"]["cache"], "miss");
    assert_ne!(d["reference"]["key"], a["reference"]["key"]);
    let e = run(&["--refresh-reference"], "e.json");
    assert_eq!(e["reference"]["cache"], "refreshed");
    let mut files: Vec<String> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    assert_eq!(files.len(), 4, "{files:?}"); // two references, EXR + JSON each
    assert!(
        files.iter().all(|f| f.starts_with("reference-")),
        "{files:?}"
    );
}

#[test]
fn chart_writes_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let o = bench(
        &[
            "builtin:sphere",
            "--size",
            "64x64",
            "--methods",
            "uniform,threshold",
            "--repeat",
            "1",
            "--chart",
            "chart.png",
            "-q",
        ],
        dir.path(),
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).is_empty(), "-q: {}", stderr(&o));
    let img = voxcast::Image::read(&dir.path().join("chart.png")).unwrap();
    assert!(img.width >= 600 && img.height >= 400);
    // White paper with dark text and coloured points on it.
    let white = img
        .pixels
        .iter()
        .filter(|p| p[0] > 0.99 && p[1] > 0.99 && p[2] > 0.99);
    assert!(white.count() > img.pixels.len() / 2);
    let dark = img
        .pixels
        .iter()
        .filter(|p| p[0] + p[1] + p[2] < 0.1)
        .count();
    assert!(dark > 500, "no text? {dark} dark pixels");
    let coloured = img
        .pixels
        .iter()
        .filter(|p| {
            let (lo, hi) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
            hi - lo > 0.3
        })
        .count();
    assert!(coloured > 100, "no points? {coloured} coloured pixels");
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}"); // chart.png and cache/, no temporaries
}

#[test]
fn markdown_prints_a_table_with_a_header_row() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let o = bench(
        &[
            "builtin:sphere",
            "--size",
            "64x64",
            "--methods",
            "threshold",
            "--repeat",
            "1",
            "--markdown",
        ],
        dir.path(),
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<&str> = out.lines().collect();
    let h = lines
        .iter()
        .position(|l| l.starts_with("| method | samples | interpolations |"))
        .unwrap_or_else(|| panic!("no header row: {out}"));
    assert!(
        lines[h].contains("speed-up") && lines[h].contains("PSNR dB") && lines[h].contains("SSIM")
    );
    assert!(lines[h + 1].starts_with("|---|"), "{out}");
    // uniform was added as the baseline, first, and the note says so.
    assert!(lines[h + 2].starts_with("| uniform | "), "{out}");
    assert!(lines[h + 3].starts_with("| threshold | "), "{out}");
    assert!(lines[h + 2].contains("1.00×"), "{out}");
    assert_eq!(lines[h + 2].matches('|').count(), 8, "{out}");
    assert!(
        out.contains("Scene: builtin:sphere") && out.contains("rayon threads"),
        "{out}"
    );
    assert!(out.contains("uniform` was added"), "{out}");
}

#[test]
fn bad_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let cache = d.join("cache");
    let out = ["--json", "o.json", "--chart", "o.png"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["builtin:sphere", "--methods", "uniform,warp"],
            "known: uniform, adaptive, adaptive-s0, adaptive-max, threshold",
        ),
        (vec!["builtin:sphere", "--methods", "uniform,warp"], "warp"),
        (
            vec!["builtin:sphere", "--methods", "adaptive+fast"],
            "+fast",
        ),
        (vec!["builtin:sphere", "--methods", ","], "no method"),
        (vec!["builtin:sphere", "--repeat", "0"], "--repeat"),
        (vec!["builtin:sphere", "--size", "64"], "--size"),
        (vec!["builtin:sphere", "--step", "0"], "step"),
        (
            vec!["builtin:sphere", "--skip-empty", "maybe"],
            "--skip-empty",
        ),
        (vec!["missing.nrrd"], "missing.nrrd"),
        (vec!["builtin:nope"], "nope"),
        (vec!["builtin:sphere", "--tf", "no-such-tf"], "no-such-tf"),
    ];
    for (args, needle) in cases {
        let mut a = args.clone();
        a.extend_from_slice(&out);
        let o = bench(&a, d, &cache);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{a:?}: {err}");
        assert!(err.contains(needle), "{a:?}: `{needle}` not in: {err}");
        assert!(!err.contains("panicked"), "{a:?} panicked: {err}");
    }
    // Output names that cannot work are refused before anything renders.
    let o = bench(&["builtin:sphere", "--chart", "c.jpg"], d, &cache);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("c.jpg"), "{}", stderr(&o));
    let o = bench(&["builtin:sphere", "--json", "nofolder/o.json"], d, &cache);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
    // Nothing was written: no outputs, no temporaries, no cache.
    let names: Vec<_> = std::fs::read_dir(d).unwrap().collect();
    assert!(names.is_empty(), "{names:?}");
}

/// `--target-psnr`: time to quality, and the equal-time table — by default
/// within uniform's time, or within `--time-budget`.
#[test]
fn time_to_quality_compares_at_equal_quality_and_equal_time() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "builtin:sphere",
            "--size",
            "32x32",
            "--methods",
            "uniform,jitter",
            "--target-psnr",
            "30",
            "--repeat",
            "1",
            "-q",
            "--json",
            "t.json",
        ];
        a.extend_from_slice(extra);
        a
    };
    // Default budget: uniform's time to quality.
    let o = bench(&args(&[]), dir.path(), &cache);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("| method | setting | PSNR (dB) |"), "{out}");
    assert!(out.contains("Equal time:"), "{out}");
    let j = read_json(&dir.path().join("t.json"));
    let results = j["results"].as_array().unwrap();
    assert_eq!(results.len(), 2, "{j}");
    let uniform = &results[0];
    assert_eq!(uniform["method"], "uniform");
    let best_s = uniform["best"]["seconds"].as_f64().unwrap();
    assert!(uniform["best"]["psnr_db"].as_f64().unwrap() >= 30.0, "{j}");
    assert_eq!(j["time_budget_s"].as_f64().unwrap(), best_s);
    // Uniform within its own time: its timed setting.
    assert_eq!(uniform["equal_time"]["step"], uniform["best"]["step"]);
    for r in results {
        if let Some(e) = r["equal_time"].as_object() {
            assert!(e["seconds"].as_f64().unwrap() <= best_s, "{j}");
        }
    }
    // A generous budget: every method's best PSNR among what it tried.
    let o = bench(&args(&["--time-budget", "1000"]), dir.path(), &cache);
    assert!(o.status.success(), "{}", stderr(&o));
    let j = read_json(&dir.path().join("t.json"));
    assert_eq!(j["time_budget_s"].as_f64().unwrap(), 1000.0);
    for r in j["results"].as_array().unwrap() {
        let top = r["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["psnr_db"].as_f64().unwrap())
            .fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(r["equal_time"]["psnr_db"].as_f64().unwrap(), top, "{j}");
    }
    // Bad budgets are refused, naming the option.
    let o = bench(&args(&["--time-budget", "0"]), dir.path(), &cache);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("time budget"), "{}", stderr(&o));
    let o = bench(
        &["builtin:sphere", "--time-budget", "1", "-q"],
        dir.path(),
        &cache,
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--target-psnr"), "{}", stderr(&o));
}

/// `--target-psnr 25,30`: one ladder per method for both targets, one
/// table each, and the JSON an array of reports in the order given.
#[test]
fn time_to_quality_takes_several_targets() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let o = bench(
        &[
            "builtin:sphere",
            "--size",
            "32x32",
            "--methods",
            "uniform,stratified",
            "--target-psnr",
            "25,30",
            "--repeat",
            "1",
            "-q",
            "--json",
            "t.json",
        ],
        dir.path(),
        &cache,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("Time to reach 25.0 dB"), "{out}");
    assert!(out.contains("Time to reach 30.0 dB"), "{out}");
    let j = read_json(&dir.path().join("t.json"));
    let reports = j.as_array().expect("an array of reports");
    assert_eq!(reports.len(), 2, "{j}");
    for (r, target) in reports.iter().zip([25.0, 30.0]) {
        assert_eq!(r["target_psnr_db"].as_f64().unwrap(), target);
        for m in r["results"].as_array().unwrap() {
            if let Some(b) = m["best"].as_object() {
                assert!(b["psnr_db"].as_f64().unwrap() >= target, "{j}");
            }
        }
    }
    // Both reports see the same ladder.
    assert_eq!(
        reports[0]["results"][1]["points"],
        reports[1]["results"][1]["points"]
    );
}
