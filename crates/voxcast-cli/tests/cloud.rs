//! `voxcast cloud` end to end: a frame folder of the cloud's life cycle that
//! `voxcast render --time` reads, the `lod` method from the command line,
//! and clear errors.

mod common;
use common::{stderr, voxcast};

#[test]
fn cloud_life_cycle_renders_with_lod() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(
        &[
            "cloud", "--type", "stratus", "--grid", "64,64,16", "--frames", "6", "-o", "c", "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let manifest = std::fs::read_to_string(dir.path().join("c/series.toml")).unwrap();
    assert_eq!(manifest.matches("[[frame]]").count(), 6);
    // The middle of the life cycle has cloud; the end has less.
    let info = |t: &str| {
        let o = voxcast(&["info", "c", "--time", t, "--json"], dir.path());
        assert!(o.status.success(), "{}", stderr(&o));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        j["mean"].as_f64().unwrap()
    };
    let (mid, end) = (info("3"), info("5"));
    assert!(mid > 0.0 && end < mid, "mean density {mid} then {end}");
    let o = voxcast(
        &[
            "render", "c", "--time", "3", "--tf", "cloud", "--method", "lod", "--size", "64x48",
            "-o", "c3.png", "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("c3.png").is_file());
}

#[test]
fn bad_cloud_arguments_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let o = voxcast(&["cloud", "--type", "nimbus", "-o", "c"], dir.path());
    assert!(!o.status.success());
    assert!(stderr(&o).contains("cumulus"), "{}", stderr(&o));
    let o = voxcast(&["cloud", "--grid", "4,4", "-o", "c"], dir.path());
    assert!(!o.status.success() && stderr(&o).contains("--grid"));
}

#[cfg(not(feature = "wrf"))]
#[test]
fn wrf_without_the_feature_says_how_to_build() {
    let Some(k) = voxcast::testdata::data_path("wrf_katrina/mercator_sample.nc") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let k = k.to_string_lossy().into_owned();
    let o = voxcast(&["info", &k], dir.path());
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--features wrf"), "{}", stderr(&o));
}

/// The paper's path end to end with the feature on: `voxcast info` reads the
/// WRF file, `voxcast cloud --from-wrf` seeds a cloud from its QCLOUD at one
/// time index, and the frame renders.
#[cfg(feature = "wrf")]
#[test]
fn a_cloud_seeded_from_wrf_renders() {
    let Some(k) = voxcast::testdata::data_path("wrf_katrina/mercator_sample.nc") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let k = k.to_string_lossy().into_owned();
    let o = voxcast(&["info", &k, "--var", "QCLOUD", "--json"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let o = voxcast(
        &[
            "cloud",
            "--from-wrf",
            &k,
            "--time",
            "2",
            "--grid",
            "48,48,16",
            "-o",
            "w",
            "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = voxcast(&["info", "w", "--json"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(j["max"].as_f64().unwrap() > 0.0, "an empty cloud: {j}");
    let o = voxcast(
        &[
            "render", "w", "--tf", "cloud", "--method", "lod", "--size", "64x48", "-o", "w.png",
            "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("w.png").is_file());
    // A variable the file does not have is named in the error.
    let o = voxcast(
        &["cloud", "--from-wrf", &k, "--var", "NOPE", "-o", "x", "-q"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("NOPE"), "{}", stderr(&o));
}
