//! The readers of this crate on real files, through voxcast's public API
//! after `install()`: WRF (feature `wrf`), MINC-2 (`minc`, minc-tools'
//! reference files of voxcast/tests/data/formats) and JPEG-LS DICOM
//! (`jpeg-ls`). CI runs them in its one build with the optional features
//! (`.ci/run`); without a feature its module is left out.

/// Without the readers, the core refuses these inputs naming the feature;
/// `install()` gives it exactly the readers this build has.
#[test]
fn install_gives_the_core_the_readers_of_this_build() {
    voxcast_native_io::install();
    let r = voxcast::io::external::installed();
    assert_eq!(r.wrf.is_some(), cfg!(feature = "wrf"));
    assert_eq!(r.minc.is_some(), cfg!(feature = "minc"));
    assert_eq!(r.jpeg_ls.is_some(), cfg!(feature = "jpeg-ls"));
    // A second call changes nothing.
    assert!(!voxcast::io::external::install(Default::default()));
    assert_eq!(
        voxcast::io::external::installed().wrf.is_some(),
        cfg!(feature = "wrf")
    );
}

#[cfg(feature = "wrf")]
mod wrf {
    use voxcast::io::OpenOptions;
    use voxcast::testdata::data_path;
    use voxcast_native_io::wrf::{column_heights, read, read_native, summary, times};

    #[test]
    fn katrina_qcloud_maximum_and_heights() {
        let Some(p) = data_path("wrf_katrina/mercator_sample.nc") else {
            return;
        };
        let n = times(&p).unwrap().len();
        let mut max = 0f32;
        for t in 0..n {
            let (q, _) = read_native(&p, "QCLOUD", t).unwrap();
            max = q.iter().copied().fold(max, f32::max);
            // Heights increase upward in every column.
            let (z, [nx, ny, nz]) = column_heights(&p, t).unwrap();
            for i in 0..nx * ny {
                for k in 1..nz {
                    assert!(z[k * nx * ny + i] > z[(k - 1) * nx * ny + i]);
                }
            }
        }
        assert!((max - 1.8e-3).abs() <= 1.8e-5, "QCLOUD max {max}");
        // The resampled volume keeps the values in range and spans metres.
        let opts = OpenOptions::default();
        let v = read(&p, &opts).unwrap();
        assert!(v.stats().max <= max * 1.0001 && v.stats().max > 0.5 * max);
        assert!(v.spacing().z > 10.0 && v.origin().z >= 0.0);
        assert_eq!(v.name.as_deref(), Some("QCLOUD"));
    }

    #[test]
    fn missing_variable_lists_the_ones_that_exist() {
        let Some(p) = data_path("wrf_katrina/mercator_sample.nc") else {
            return;
        };
        let opts = OpenOptions {
            variable: Some("QCLOUD+QICE".into()),
            ..Default::default()
        };
        let e = read(&p, &opts).unwrap_err().to_string();
        assert!(
            e.contains("QICE") && e.contains("QCLOUD") && e.contains("QRAIN"),
            "{e}"
        );
        let bad_time = OpenOptions {
            time: Some(99.0),
            ..Default::default()
        };
        assert!(read(&p, &bad_time)
            .unwrap_err()
            .to_string()
            .contains("time index"));
    }

    #[test]
    fn salem_sums_cloud_water_and_ice() {
        let Some(p) = data_path("wrf_salem/wrf_d01_allvars_cropped.nc") else {
            return;
        };
        let (a, _) = read_native(&p, "QCLOUD", 1).unwrap();
        let (b, _) = read_native(&p, "QICE", 1).unwrap();
        let (s, _) = read_native(&p, "QCLOUD+QICE", 1).unwrap();
        for ((x, y), z) in a.iter().zip(&b).zip(&s) {
            assert_eq!(x + y, *z);
        }
        let lines = summary(&p).unwrap();
        assert!(lines.iter().any(|l| l.contains("QGRAUP")));
        assert_eq!(lines.iter().filter(|l| l.starts_with("time ")).count(), 4);
    }

    #[test]
    fn series_lists_the_time_indices_with_their_names() {
        voxcast_native_io::install();
        let Some(p) = data_path("wrf_salem/wrf_d01_allvars_cropped.nc") else {
            return;
        };
        let opts = OpenOptions::default();
        let s = voxcast::io::Series::open(&p, &opts).unwrap();
        assert_eq!(s.len(), 4);
        assert_eq!(s.times(), vec![0.0, 1.0, 2.0, 3.0]);
        assert_eq!(s.labels, times(&p).unwrap());
        assert!(s.label(1).unwrap().contains(':'), "{:?}", s.labels);
        // Frame 1 is time index 1.
        let v = s.load(1, &opts).unwrap();
        let w = read(
            &p,
            &OpenOptions {
                time: Some(1.0),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!(v.stats().max, w.stats().max);
        assert_eq!(v.time, Some(1.0));
    }
}

#[cfg(feature = "minc")]
mod minc {
    use glam::Vec3;
    use std::path::{Path, PathBuf};
    use voxcast::io::{open, OpenOptions};
    use voxcast::volume::ScalarType;
    use voxcast::Volume;

    fn data(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../voxcast/tests/data/formats")
            .join(name)
    }

    /// Through the core's `open`, as every caller reads files.
    fn read(path: &Path) -> voxcast::Result<Volume> {
        voxcast_native_io::install();
        open(path, &OpenOptions::default())
    }

    /// The value make.py (voxcast/tests/data/formats) gives voxel (i, j, k).
    fn base(i: usize, j: usize, k: usize) -> f64 {
        (i + 7 * j + 35 * k) as f64 * 3.0 - 50.0
    }

    fn tmp_copy(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    /// MINC-2 by minc-tools (`rawtominc -scan_range`): int16 normalised per
    /// slice, so the values come back within a quantisation step of the
    /// originals (a slice's range / 65535: under 0.005 here); the extremes are
    /// exact.
    #[test]
    fn minc2_transverse_and_sagittal_orders() {
        // nibabel's means of the two files (their quantisation differs).
        for (name, mean) in [
            ("minc2.mnc", 105.999993),
            ("minc2_sagittal.mnc", 106.000107),
        ] {
            let v = read(&data(name)).unwrap();
            assert_eq!(v.dims(), [7, 5, 3], "{name}");
            assert_eq!(v.scalar_type(), ScalarType::F32, "{name}");
            assert_eq!(v.spacing(), Vec3::new(1.5, 2.0, 2.5), "{name}");
            assert_eq!(v.origin(), Vec3::new(-10.0, 20.0, 5.0), "{name}");
            for k in 0..3 {
                for j in 0..5 {
                    for i in 0..7 {
                        let d = (v.value(i, j, k) as f64 - base(i, j, k)).abs();
                        assert!(d < 0.005, "{name} ({i}, {j}, {k}): off by {d}");
                    }
                }
            }
            let s = v.stats();
            assert_eq!((s.min, s.max), (-50.0, 262.0), "{name}");
            assert!((s.mean - mean).abs() < 1e-4, "{name}: mean {}", s.mean);
        }
        let (title, lines) =
            voxcast::io::header_summary(&data("minc2_sagittal.mnc"), &OpenOptions::default())
                .unwrap()
                .unwrap();
        let s = format!("{title}\n{}", lines.join("\n"));
        for w in [
            "MINC-2 (HDF5), image type i16",
            "xspace 7, zspace 3, yspace 5",
            "xspace      start -10 step 1.5",
            "per xspace (7 values)",
        ] {
            assert!(s.contains(w), "{w}: {s}");
        }
    }

    #[test]
    fn minc2_errors_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let m = std::fs::read(data("minc2.mnc")).unwrap();
        // Truncated HDF5, and an HDF5 file that is not MINC-2 (a NetCDF-4 one
        // would be the same: no /minc-2.0 group).
        let e = read(&tmp_copy(d, "cut.mnc", &m[..4000])).unwrap_err();
        assert!(e.to_string().contains("cut.mnc"), "{e}");
        let e = read(&tmp_copy(d, "junk.mnc", &[0u8; 100])).unwrap_err();
        assert!(e.to_string().contains("junk.mnc"), "{e}");
    }
}

#[cfg(feature = "jpeg-ls")]
mod jpeg_ls {
    use std::path::PathBuf;
    use voxcast::io::{open, OpenOptions};
    use voxcast::Volume;

    /// Reads one file of the transfer-syntax set in `tests/data/dicom_ts`
    /// (its `make.sh`) alone: each goes into a folder of its own, as the
    /// files share one series and one position.
    fn read_alone(name: &str) -> Volume {
        let src = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../voxcast/tests/data/dicom_ts")
            .join(name);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::copy(src, &p).unwrap();
        voxcast_native_io::install();
        open(&p, &OpenOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    #[test]
    fn lossless_jpeg_ls_decodes_to_the_uncompressed_voxels() {
        for (name, raw) in [
            ("mr_jls80.dcm", "mr_raw.dcm"),
            ("ct_jls80.dcm", "ct_raw.dcm"),
        ] {
            let (v, reference) = (read_alone(name), read_alone(raw));
            assert_eq!(v.dims(), reference.dims(), "{name}");
            assert_eq!(v.spacing(), reference.spacing(), "{name}");
            assert_eq!(v.origin(), reference.origin(), "{name}");
            assert_eq!(v.data(), reference.data(), "{name}");
        }
    }

    #[test]
    fn near_lossless_jpeg_ls_stays_within_its_allowed_error() {
        // Encoded with an allowed error of 2 (the MR crop spans 147…588).
        let (v, reference) = (read_alone("mr_jls81.dcm"), read_alone("mr_raw.dcm"));
        assert_eq!(v.dims(), reference.dims());
        let n = v.len();
        let (mut max, mut sq) = (0f64, 0f64);
        for i in 0..n {
            let d = (v.data().get(i) as f64 - reference.data().get(i) as f64).abs();
            max = max.max(d);
            sq += d * d;
        }
        let rms = (sq / n as f64).sqrt();
        assert!(
            max <= 2.0 && rms > 0.0 && rms <= 2.0,
            "max error {max}, rms {rms}"
        );
    }

    /// A frame whose own JPEG-LS header disagrees with the DICOM header is
    /// refused before CharLS allocates, naming the file and both sizes.
    #[test]
    fn a_frame_that_disagrees_with_the_header_is_refused() {
        let src = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("../voxcast/tests/data/dicom_ts/mr_jls80.dcm");
        let mut b = std::fs::read(src).unwrap();
        // Rows (0028,0010), explicit VR little endian: one row fewer.
        let tag = [0x28, 0, 0x10, 0, b'U', b'S', 2, 0];
        let i = b.windows(8).position(|w| w == tag).unwrap() + 8;
        let rows = u16::from_le_bytes([b[i], b[i + 1]]);
        b[i..i + 2].copy_from_slice(&(rows - 1).to_le_bytes());
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("short.dcm");
        std::fs::write(&p, &b).unwrap();
        voxcast_native_io::install();
        let e = open(&p, &OpenOptions::default()).unwrap_err().to_string();
        assert!(
            e.contains("short.dcm")
                && e.contains("JPEG-LS frame is")
                && e.contains(&format!("× {rows},"))
                && e.contains(&format!("Rows {}", rows - 1)),
            "{e}"
        );
    }
}
