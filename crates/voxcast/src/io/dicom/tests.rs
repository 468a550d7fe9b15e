//! Tests of the DICOM reader.
use super::*;
use crate::testdata::data_path;
use crate::volume::ScalarType;
use dicom_dictionary_std::tags;

/// The reader with default options.
fn read(p: &Path) -> Result<Volume> {
    super::read(p, &Default::default())
}

fn approx(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol
}

/// Copies slices `names` of the CT series into a new temporary folder.
fn copy_ct(names: &[&str]) -> Option<tempfile::TempDir> {
    let src = data_path("dicom_ct_lung")?;
    let dir = tempfile::tempdir().unwrap();
    for n in names {
        std::fs::copy(src.join(n), dir.path().join(n)).unwrap();
    }
    Some(dir)
}

// Ground truth from pydicom 3.0 + numpy (slices sorted by position).
#[test]
fn ct_lung_dims_spacing_origin_and_hu() {
    let Some(p) = data_path("dicom_ct_lung") else {
        return;
    };
    assert!(folder_has_dicom(&p).unwrap());
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [512, 512, 30]);
    assert_eq!(v.scalar_type(), ScalarType::I16);
    let s = v.spacing();
    assert!(
        approx(s.x, 0.646_484_4, 1e-6) && approx(s.y, 0.646_484_4, 1e-6) && approx(s.z, 8.0, 1e-5),
        "{s}"
    );
    let o = v.origin();
    assert!(
        approx(o.x, -173.17676, 1e-3) && approx(o.y, -294.17676, 1e-3) && approx(o.z, 80.0, 1e-4),
        "{o}"
    );
    assert_eq!((v.stats().min, v.stats().max), (-1024.0, 1548.0));
    assert_eq!(v.units.as_deref(), Some("HU"));
    assert_eq!(v.name.as_deref(), Some("ThoraxRoutine  8.0.0  B40f"));
    assert_eq!(v.value(0, 0, 0), -1001.0);
    assert_eq!(v.value(256, 200, 10), 1.0);
    assert_eq!(v.value(100, 150, 29), -1005.0);
    assert_eq!(v.value(300, 100, 5), 30.0);
    assert_eq!(v.value(150, 160, 12), -544.0);
    // The maximum sits at (445, 317, 22) in pydicom's ordering.
    assert_eq!(v.value(445, 317, 22), 1548.0);
}

#[test]
fn mri_brain_x_is_columns_and_step_is_along_the_normal() {
    let Some(p) = data_path("dicom_mri_brain") else {
        return;
    };
    let v = read(&p).unwrap();
    // Rows 320, Columns 260: x runs along the columns.
    assert_eq!(v.dims(), [260, 320, 24]);
    assert_eq!(v.scalar_type(), ScalarType::U16);
    let s = v.spacing();
    // Oblique slices: 6.5 mm along the normal (= SpacingBetweenSlices),
    // although the z coordinate of the positions moves by 6.4 mm.
    assert!(
        approx(s.x, 0.6875, 1e-6) && approx(s.y, 0.6875, 1e-6) && approx(s.z, 6.5, 1e-4),
        "{s}"
    );
    let o = v.origin();
    assert!(
        approx(o.x, -83.30032, 1e-3)
            && approx(o.y, -115.806_4, 1e-3)
            && approx(o.z, -61.45288, 1e-3),
        "{o}"
    );
    assert_eq!((v.stats().min, v.stats().max), (0.0, 2505.0));
    assert_eq!(v.units, None);
    assert_eq!(v.name.as_deref(), Some("T1post"));
    assert_eq!(v.value(256, 200, 10), 441.0);
    assert_eq!(v.value(200, 250, 23), 23.0);
    assert_eq!(v.value(150, 160, 12), 459.0);
    assert_eq!(v.value(130, 130, 1), 2505.0);
}

#[test]
fn a_single_file_reads_its_whole_series() {
    let Some(p) = data_path("dicom_ct_lung/1-05.dcm") else {
        return;
    };
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [512, 512, 30]);
    assert_eq!(v.value(150, 160, 12), -544.0);
}

#[test]
fn order_comes_from_positions_not_file_names() {
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    // 1-01 … 1-06 are at z = 312 … 272 (decreasing); name them so that
    // both name order and reversed name order disagree with position
    // order.
    let names = ["c", "a", "f", "b", "e", "d"];
    for (i, n) in names.iter().enumerate() {
        std::fs::copy(
            src.join(format!("1-0{}.dcm", i + 1)),
            dir.path().join(format!("{n}.dcm")),
        )
        .unwrap();
    }
    let sub = read(dir.path()).unwrap();
    let full = read(&src).unwrap();
    assert_eq!(sub.dims(), [512, 512, 6]);
    assert!(approx(sub.origin().z, 272.0, 1e-4));
    assert!(approx(sub.spacing().z, 8.0, 1e-5));
    // Slice k of the copy is slice 24 + k of the whole series.
    for k in 0..6 {
        for (i, j) in [(256, 256), (100, 300), (400, 120)] {
            assert_eq!(
                sub.value(i, j, k),
                full.value(i, j, 24 + k),
                "({i},{j},{k})"
            );
        }
    }
}

#[test]
fn implicit_little_and_explicit_big_endian_read_the_same_values() {
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let reference = {
        let Some(d) = copy_ct(&["1-10.dcm", "1-11.dcm", "1-12.dcm"]) else {
            return;
        };
        read(d.path()).unwrap()
    };
    for ts in [IMPLICIT_LE, EXPLICIT_BE] {
        let dir = tempfile::tempdir().unwrap();
        for n in ["1-10.dcm", "1-11.dcm", "1-12.dcm"] {
            let mut obj = dicom_object::open_file(src.join(n)).unwrap();
            obj.update_meta(|m| m.transfer_syntax = ts.to_string());
            obj.write_to_file(dir.path().join(n)).unwrap();
        }
        let v = read(dir.path()).unwrap();
        assert_eq!(v.dims(), reference.dims(), "{ts}");
        assert_eq!(v.data(), reference.data(), "{ts}");
        assert_eq!(v.spacing(), reference.spacing(), "{ts}");
    }
}

#[test]
fn jpeg_ls_without_the_feature_is_unsupported_naming_uid_and_remedy() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mr_jls80.dcm");
    std::fs::copy(super::tests_more::ts_file("mr_jls80.dcm"), &p).unwrap();
    let e = read(&p).unwrap_err();
    let s = e.to_string();
    assert!(matches!(e, Error::Unsupported { .. }), "{s}");
    assert!(
        s.contains("mr_jls80.dcm")
            && s.contains("1.2.840.10008.1.2.4.80")
            && s.contains("JPEG-LS Lossless")
            && s.contains("--features jpeg-ls")
            && s.contains("gdcmconv --raw"),
        "{s}"
    );
}

#[test]
fn truncated_file_is_skipped_in_a_folder_and_an_error_alone() {
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm"]) else {
        return;
    };
    let p = dir.path().join("1-02.dcm");
    let b = std::fs::read(&p).unwrap();
    std::fs::write(&p, &b[..b.len() - 1000]).unwrap();
    let s = read(&p).unwrap_err().to_string();
    assert!(s.contains("1-02.dcm") && s.contains("PixelData"), "{s}");
    // In its folder the truncated slice is skipped, and said so.
    let scan = scan(dir.path()).unwrap();
    assert_eq!(scan.skipped.len(), 1);
    let line = scan.skipped_line().unwrap();
    assert!(
        line.contains("1-02.dcm") && line.contains("PixelData"),
        "{line}"
    );
    assert_eq!(read(dir.path()).unwrap().dims(), [512, 512, 1]);
}

#[test]
fn short_pixel_data_is_an_error_naming_file_and_field() {
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm"]) else {
        return;
    };
    let p = dir.path().join("1-01.dcm");
    let mut obj = dicom_object::open_file(&p).unwrap();
    // Replace the 512×512 words by the 1-word value of Rows.
    let small = obj.element(tags::ROWS).unwrap().value().clone();
    assert!(obj.update_value(tags::PIXEL_DATA, |v| *v = small.clone()));
    obj.write_to_file(&p).unwrap();
    let s = read(&p).unwrap_err().to_string();
    assert!(
        s.contains("1-01.dcm") && s.contains("PixelData") && s.contains("524288"),
        "{s}"
    );
    let scan = scan(dir.path()).unwrap();
    assert_eq!(scan.skipped.len(), 1);
    assert!(
        scan.skipped[0].reason.contains("524288"),
        "{:?}",
        scan.skipped
    );
    assert_eq!(read(dir.path()).unwrap().dims(), [512, 512, 1]);
}

#[test]
fn a_slice_of_another_size_is_another_series() {
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-03.dcm"]) else {
        return;
    };
    let p = dir.path().join("1-03.dcm");
    let mut b = std::fs::read(&p).unwrap();
    // Rows (0028,0010) US 512 → 256, patched in place.
    let at = b
        .windows(10)
        .position(|w| w == b"\x28\x00\x10\x00US\x02\x00\x00\x02")
        .unwrap();
    b[at + 8] = 0;
    b[at + 9] = 1;
    std::fs::write(&p, b).unwrap();
    let scan = scan(dir.path()).unwrap();
    assert_eq!(scan.series.len(), 2);
    assert_eq!((scan.series[0].frames, scan.series[0].rows), (2, 512));
    assert_eq!((scan.series[1].frames, scan.series[1].rows), (1, 256));
    let v = read(dir.path()).unwrap();
    assert_eq!(v.dims(), [512, 512, 2]);
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [512, 256, 1]);
}

#[test]
fn folder_without_image_slices_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not an image").unwrap();
    let e = read(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains(&dir.path().display().to_string()) && e.contains("no DICOM image slices"),
        "{e}"
    );
    assert!(!folder_has_dicom(dir.path()).unwrap());

    // A DICOM object without image attributes does not count either.
    let Some(src) = data_path("dicom_ct_lung/1-01.dcm") else {
        return;
    };
    let mut obj = dicom_object::open_file(&src).unwrap();
    for t in [tags::ROWS, tags::COLUMNS, tags::PIXEL_DATA] {
        obj.remove_element(t);
    }
    obj.write_to_file(dir.path().join("report.dcm")).unwrap();
    assert!(folder_has_dicom(dir.path()).unwrap());
    let e = read(dir.path()).unwrap_err().to_string();
    assert!(
        e.contains("no DICOM image slices") && e.contains("1 DICOM file(s), none"),
        "{e}"
    );
}

#[test]
fn two_series_reads_the_larger_one_or_the_one_asked_for() {
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-03.dcm"]) else {
        return;
    };
    for n in ["1-04.dcm", "1-05.dcm"] {
        let mut obj = dicom_object::open_file(src.join(n)).unwrap();
        let vr = obj.element(tags::SERIES_INSTANCE_UID).unwrap().vr();
        obj.put_str(
            tags::SERIES_INSTANCE_UID,
            vr,
            "1.2.826.0.1.3680043.2.1125.42",
        );
        let vr = obj.element(tags::SERIES_DESCRIPTION).unwrap().vr();
        obj.put_str(tags::SERIES_DESCRIPTION, vr, "second series");
        obj.write_to_file(dir.path().join(format!("x{n}"))).unwrap();
    }
    let v = read(dir.path()).unwrap();
    assert_eq!(v.dims()[2], 3);
    assert!(approx(v.origin().z, 296.0, 1e-4));
    let v = read(&dir.path().join("x1-05.dcm")).unwrap();
    assert_eq!(v.dims()[2], 2);
    assert_eq!(v.name.as_deref(), Some("second series"));
    assert!(approx(v.origin().z, 280.0, 1e-4));
}

#[test]
fn unusable_image_attribute_and_junk_are_skipped() {
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-03.dcm"]) else {
        return;
    };
    // A .dcm file that is not DICOM at all is skipped (with a warning).
    std::fs::write(dir.path().join("junk.dcm"), b"not DICOM").unwrap();
    assert_eq!(read(dir.path()).unwrap().dims(), [512, 512, 3]);
    // An image without BitsAllocated cannot be decoded: skipped in its
    // folder, an error when it is the file given.
    let p = dir.path().join("1-02.dcm");
    let mut obj = dicom_object::open_file(&p).unwrap();
    obj.remove_element(tags::BITS_ALLOCATED);
    obj.write_to_file(&p).unwrap();
    let s = read(&p).unwrap_err().to_string();
    assert!(
        s.contains("1-02.dcm") && s.contains("`BitsAllocated`"),
        "{s}"
    );
    let scan = scan(dir.path()).unwrap();
    let line = scan.skipped_line().unwrap();
    assert!(
        line.contains("skipped 2 file(s)")
            && line.contains("1-02.dcm (field `BitsAllocated`")
            && line.contains("junk.dcm (not readable as DICOM"),
        "{line}"
    );
    assert_eq!(read(dir.path()).unwrap().dims(), [512, 512, 2]);
}

#[test]
fn two_slices_at_one_position_is_an_error() {
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm"]) else {
        return;
    };
    std::fs::copy(dir.path().join("1-02.dcm"), dir.path().join("copy.dcm")).unwrap();
    let s = read(dir.path()).unwrap_err().to_string();
    assert!(
        s.contains("ImagePositionPatient") && s.contains("same slice position"),
        "{s}"
    );
}

#[test]
fn a_missing_slice_still_loads_with_the_median_step() {
    let Some(dir) = copy_ct(&["1-01.dcm", "1-02.dcm", "1-04.dcm", "1-05.dcm"]) else {
        return;
    };
    let v = read(dir.path()).unwrap();
    assert_eq!(v.dims()[2], 4);
    assert!(approx(v.spacing().z, 8.0, 1e-5));
}

#[test]
fn non_dicom_folder_is_not_dicom() {
    let Some(p) = data_path("teapot_ct/slices") else {
        return;
    };
    assert!(!folder_has_dicom(&p).unwrap());
}
