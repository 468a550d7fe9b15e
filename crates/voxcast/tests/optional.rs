//! The readers behind cargo features — WRF (`wrf`, libnetcdf) and JPEG-LS
//! DICOM (`jpeg-ls`, CharLS) — on real files, through the public API. CI
//! runs them in its one build with the optional features (`.ci/run`); in
//! the default build this file is empty (MINC-2's tests are in
//! `formats.rs`).

#[cfg(feature = "wrf")]
mod wrf {
    use voxcast::io::wrf::{column_heights, read, read_native, summary, times};
    use voxcast::io::OpenOptions;
    use voxcast::testdata::data_path;

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
            .join("tests/data/dicom_ts")
            .join(name);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(name);
        std::fs::copy(src, &p).unwrap();
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
}
