//! Tests of issue 22/20: lengths before allocation (under a memory limit),
//! compressed transfer syntaxes, folders with strays, multi-frame files.

use super::*;
use crate::testdata::data_path;
use dicom_dictionary_std::tags;
use dicom_object::mem::InMemElement;
use dicom_object::InMemDicomObject;
use std::process::{Command, Stdio};

fn read(p: &Path) -> Result<Volume> {
    super::read(p, &Default::default())
}

fn read_var(p: &Path, var: &str) -> Result<Volume> {
    let opts = crate::io::OpenOptions {
        variable: Some(var.to_string()),
        ..Default::default()
    };
    super::read(p, &opts)
}

/// A file of the transfer-syntax set in `tests/data/dicom_ts` (made by its
/// `gen.py` and gdcmconv, see `make.sh` there).
pub(super) fn ts_file(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/dicom_ts")
        .join(name)
}

/// Reads one file of the set alone (each is its own folder: the files
/// share one series and one position).
fn read_alone(name: &str) -> Volume {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    std::fs::copy(ts_file(name), &p).unwrap();
    read(&p).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Runs the test `name` again in a child process whose address space is
/// limited to `kib` KiB (`ulimit -v`), and checks that it passed there.
/// Returns true inside the child (where the test does its work).
fn in_memory_limited_child(name: &str, kib: u64) -> bool {
    if std::env::var_os("VOXCAST_MEMLIMIT_CHILD").is_some() {
        return true;
    }
    let exe = std::env::current_exe().unwrap();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(exe)
        .args(["--exact", name, "--test-threads=1", "--nocapture"])
        .env("VOXCAST_MEMLIMIT_CHILD", "1")
        .env("RAYON_NUM_THREADS", "1")
        .env("MALLOC_ARENA_MAX", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // A failed allocation can leave the child hanging: give it 120 s.
    let start = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if start.elapsed().as_secs() > 120 {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    let out = child.wait_with_output().unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        status.is_some_and(|s| s.success()) && text.contains("1 passed"),
        "the test failed (or ran out of memory) under ulimit -v {kib}: {status:?}\n{text}"
    );
    false
}

fn el_explicit(g: u16, e: u16, vr: &[u8; 2], val: &[u8]) -> Vec<u8> {
    let mut v = val.to_vec();
    if v.len() % 2 == 1 {
        v.push(if vr == b"UI" { 0 } else { b' ' });
    }
    let mut b = Vec::new();
    b.extend(g.to_le_bytes());
    b.extend(e.to_le_bytes());
    b.extend(vr);
    if matches!(vr, b"OB" | b"OW" | b"SQ" | b"UN" | b"UT") {
        b.extend([0, 0]);
        b.extend((v.len() as u32).to_le_bytes());
    } else {
        b.extend((v.len() as u16).to_le_bytes());
    }
    b.extend(v);
    b
}

fn preamble_and_meta(ts: &str) -> Vec<u8> {
    let mut body = el_explicit(2, 1, b"OB", &[0, 1]);
    body.extend(el_explicit(2, 2, b"UI", b"1.2.840.10008.5.1.4.1.1.2"));
    body.extend(el_explicit(2, 3, b"UI", b"1.2.3.4"));
    body.extend(el_explicit(2, 0x10, b"UI", ts.as_bytes()));
    let mut b = vec![0u8; 128];
    b.extend(b"DICM");
    b.extend(el_explicit(2, 0, b"UL", &(body.len() as u32).to_le_bytes()));
    b.extend(body);
    b
}

/// Files whose element lengths lie: each claims 3,758,161,918 bytes (an
/// item tag read as a length) somewhere the parser would allocate it.
fn lying_files() -> Vec<(&'static str, Vec<u8>)> {
    const HUGE: [u8; 4] = [0xFE, 0xFF, 0x00, 0xE0];
    let mut out = Vec::new();
    // An UN element of undefined length (read as implicit VR inside)
    // holding an element that claims HUGE bytes, padded to 674 bytes.
    let mut b = preamble_and_meta(EXPLICIT_LE);
    b.extend(el_explicit(8, 0x60, b"CS", b"CT"));
    b.extend([0x09, 0x00, 0x10, 0x10]);
    b.extend(b"UN\0\0");
    b.extend([0xFF; 4]);
    b.extend([0xFE, 0xFF, 0x00, 0xE0, 0xFF, 0xFF, 0xFF, 0xFF]);
    b.extend([0x09, 0x00, 0x11, 0x10]);
    b.extend(HUGE);
    b.resize(674, 0);
    out.push(("un_sequence.dcm", b));
    // A sequence of defined length HUGE.
    let mut b = preamble_and_meta(EXPLICIT_LE);
    b.extend([0x08, 0x00, 0x15, 0x11]);
    b.extend(b"SQ\0\0");
    b.extend(HUGE);
    b.resize(400, 0);
    out.push(("sequence.dcm", b));
    // The same in a deflated data set.
    let mut inner = [0x08u8, 0x00, 0x15, 0x11].to_vec();
    inner.extend(b"SQ\0\0");
    inner.extend(HUGE);
    inner.resize(200, 0);
    let mut enc = flate2::write::DeflateEncoder::new(Vec::new(), flate2::Compression::best());
    std::io::Write::write_all(&mut enc, &inner).unwrap();
    let mut b = preamble_and_meta(DEFLATED);
    b.extend(enc.finish().unwrap());
    out.push(("deflated.dcm", b));
    // No preamble: the magic at byte 0.
    let mut b = preamble_and_meta(EXPLICIT_LE)[128..].to_vec();
    b.extend([0x08, 0x00, 0x15, 0x11]);
    b.extend(b"SQ\0\0");
    b.extend(HUGE);
    b.resize(300, 0);
    out.push(("no_preamble.dcm", b));
    out
}

#[test]
fn lying_lengths_fail_under_100_mb() {
    if !in_memory_limited_child(
        "io::dicom::tests_more::lying_lengths_fail_under_100_mb",
        100_000,
    ) {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in lying_files() {
        let sub = dir.path().join(name.trim_end_matches(".dcm"));
        std::fs::create_dir(&sub).unwrap();
        let p = sub.join(name);
        std::fs::write(&p, &bytes).unwrap();
        if name == "un_sequence.dcm" {
            assert_eq!(bytes.len(), 674);
        }
        let s = read(&p).unwrap_err().to_string();
        assert!(s.contains(name), "{name}: {s}");
        assert!(
            s.contains("3758161918") || s.contains("not readable") || s.contains("header"),
            "{name}: {s}"
        );
    }
}

/// Rows and Columns (US) of an Explicit VR Little Endian file, patched in
/// place to `v`.
fn patch_rows_columns(b: &mut [u8], v: u16) {
    for tag in [[0x28u8, 0x00, 0x10, 0x00], [0x28, 0x00, 0x11, 0x00]] {
        let mut pat = tag.to_vec();
        pat.extend(b"US\x02\x00");
        let at = b.windows(8).position(|w| w == pat.as_slice()).unwrap();
        b[at + 8..at + 10].copy_from_slice(&v.to_le_bytes());
    }
}

#[test]
fn huge_rows_columns_with_small_pixel_data_fail_under_100_mb() {
    if !in_memory_limited_child(
        "io::dicom::tests_more::huge_rows_columns_with_small_pixel_data_fail_under_100_mb",
        100_000,
    ) {
        return;
    }
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut b = std::fs::read(src.join("1-01.dcm")).unwrap();
    patch_rows_columns(&mut b, 65535);
    let p = dir.path().join("huge.dcm");
    std::fs::write(&p, &b).unwrap();
    let s = read(&p).unwrap_err().to_string();
    assert!(
        s.contains("huge.dcm") && s.contains("PixelData") && s.contains("65535"),
        "{s}"
    );
    // Beside good slices it is skipped.
    for n in ["1-02.dcm", "1-03.dcm"] {
        std::fs::copy(src.join(n), dir.path().join(n)).unwrap();
    }
    assert_eq!(read(dir.path()).unwrap().dims(), [512, 512, 2]);
    assert_eq!(scan(dir.path()).unwrap().skipped.len(), 1);
}

#[test]
fn lossless_transfer_syntaxes_decode_to_the_uncompressed_voxels() {
    let mr = read_alone("mr_raw.dcm");
    let ct = read_alone("ct_raw.dcm");
    assert_eq!(mr.dims(), [48, 48, 1]);
    assert_eq!(ct.scalar_type(), crate::volume::ScalarType::I16);
    assert!(ct.stats().min < 0.0, "the CT crop is signed");
    let cases = vec![
        ("mr_jpeg70.dcm", &mr),
        ("mr_j2k90.dcm", &mr),
        ("mr_rle.dcm", &mr),
        ("mr_deflate.dcm", &mr),
        ("ct_jpeg70.dcm", &ct),
        ("ct_j2k90.dcm", &ct),
        ("ct_rle.dcm", &ct),
    ];
    // JPEG-LS (feature jpeg-ls): voxcast-native-io/tests/readers.rs.
    for (name, reference) in cases {
        let v = read_alone(name);
        assert_eq!(v.dims(), reference.dims(), "{name}");
        assert_eq!(v.spacing(), reference.spacing(), "{name}");
        assert_eq!(v.origin(), reference.origin(), "{name}");
        assert_eq!(v.data(), reference.data(), "{name}");
    }
}

/// Largest absolute difference and RMS difference of two volumes.
fn diff(a: &Volume, b: &Volume) -> (f64, f64) {
    let n = a.len();
    let (mut max, mut sq) = (0f64, 0f64);
    for i in 0..n {
        let d = (a.data().get(i) as f64 - b.data().get(i) as f64).abs();
        max = max.max(d);
        sq += d * d;
    }
    (max, (sq / n as f64).sqrt())
}

#[test]
fn twelve_bit_lossy_jpeg_is_unsupported_naming_the_remedy() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("mr12_jpeg51.dcm");
    std::fs::copy(ts_file("mr12_jpeg51.dcm"), &p).unwrap();
    let e = read(&p).unwrap_err();
    let s = e.to_string();
    assert!(matches!(e, Error::Unsupported { .. }), "{s}");
    assert!(
        s.contains("mr12_jpeg51.dcm") && s.contains("12-bit") && s.contains("dcmdjpeg"),
        "{s}"
    );
}

#[test]
fn lossy_transfer_syntaxes_decode_within_the_codec_error() {
    let mr = read_alone("mr_raw.dcm");
    let mr8 = read_alone("mr8_raw.dcm");
    // (file, reference, max error, rms error) — the MR crop spans 147…588.
    let mut cases = vec![
        ("mr8_jpeg50.dcm", &mr8, 12.0, 3.0),
        ("mr_j2k91.dcm", &mr, 12.0, 3.7),
    ];
    // dcmcjpeg's extended-process file is far from the original (max 20,
    // rms 14 on values 14…58), so it is checked against dcmtk's own
    // decoding of it: the same up to IDCT rounding.
    let dcmtk = read_alone("mr8_jpeg51_dcmdjpeg.dcm");
    cases.push(("mr8_jpeg51.dcm", &dcmtk, 1.0, 0.5));
    // JPEG-LS near-lossless (feature jpeg-ls): voxcast-native-io/tests/readers.rs.
    for (name, reference, max_tol, rms_tol) in cases {
        let v = read_alone(name);
        assert_eq!(v.dims(), reference.dims(), "{name}");
        let (max, rms) = diff(&v, reference);
        assert!(
            max <= max_tol && rms <= rms_tol && (rms > 0.0 || name.contains("51")),
            "{name}: max error {max}, rms {rms}"
        );
    }
}

/// Copies CT slices `names` into `dir`, with SeriesInstanceUID `uid` and
/// SeriesDescription `desc` when given, and the orientation `orient`.
fn put_ct(dir: &Path, names: &[&str], prefix: &str, uid: Option<&str>, orient: Option<&str>) {
    let src = data_path("dicom_ct_lung").unwrap();
    for n in names {
        let mut obj = dicom_object::open_file(src.join(n)).unwrap();
        if let Some(u) = uid {
            let vr = obj.element(tags::SERIES_INSTANCE_UID).unwrap().vr();
            obj.put_str(tags::SERIES_INSTANCE_UID, vr, u);
            let vr = obj.element(tags::SERIES_DESCRIPTION).unwrap().vr();
            obj.put_str(tags::SERIES_DESCRIPTION, vr, format!("series {u}"));
        }
        if let Some(o) = orient {
            let vr = obj.element(tags::IMAGE_ORIENTATION_PATIENT).unwrap().vr();
            obj.put_str(tags::IMAGE_ORIENTATION_PATIENT, vr, o);
        }
        obj.write_to_file(dir.join(format!("{prefix}{n}"))).unwrap();
    }
}

#[test]
fn a_folder_with_strays_opens_the_series_and_lists_what_it_skipped() {
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    put_ct(
        d,
        &["1-01.dcm", "1-02.dcm", "1-03.dcm", "1-04.dcm"],
        "",
        None,
        None,
    );
    // A truncated slice, a report (no image), junk, a slice of another series.
    let b = std::fs::read(src.join("1-05.dcm")).unwrap();
    std::fs::write(d.join("1-05.dcm"), &b[..b.len() / 2]).unwrap();
    let mut report = dicom_object::open_file(src.join("1-06.dcm")).unwrap();
    for t in [tags::ROWS, tags::COLUMNS, tags::PIXEL_DATA] {
        report.remove_element(t);
    }
    report.write_to_file(d.join("report.dcm")).unwrap();
    std::fs::write(d.join("notes.dcm"), b"meeting notes").unwrap();
    put_ct(d, &["1-07.dcm"], "other", Some("1.2.3.99"), None);

    let v = read(d).unwrap();
    assert_eq!(v.dims(), [512, 512, 4]);
    let s = scan(d).unwrap();
    let names: Vec<String> = s.skipped.iter().map(|k| file_name(&k.path)).collect();
    assert_eq!(names, ["1-05.dcm", "notes.dcm", "report.dcm"]);
    assert!(
        s.skipped[2].reason.contains("not an image"),
        "{:?}",
        s.skipped
    );
    assert_eq!(s.series.len(), 2);
    assert_eq!(s.series[1].uid, "1.2.3.99");
    // --var picks the other series by UID or by index.
    for var in ["1.2.3.99", "1"] {
        let v = read_var(d, var).unwrap();
        assert_eq!(v.dims(), [512, 512, 1], "{var}");
        assert_eq!(v.name.as_deref(), Some("series 1.2.3.99"));
    }
    let e = read_var(d, "1.2.3.nope").unwrap_err().to_string();
    assert!(e.contains("--var") && e.contains("1.2.3.99"), "{e}");
    // `voxcast info` lines: series, frames, transfer syntax, skipped files.
    let lines = summary(d, None).unwrap().join("\n");
    assert!(
        lines.contains("4 frame(s) in 4 file(s)")
            && lines.contains("Explicit VR Little Endian")
            && lines.contains("(read)")
            && lines.contains("skipped report.dcm"),
        "{lines}"
    );
}

#[test]
fn a_three_plane_localizer_does_not_hide_the_real_series() {
    if data_path("dicom_ct_lung").is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The localizer has more files than the real series (6 against 4).
    let loc = Some("1.2.3.7");
    put_ct(d, &["1-01.dcm", "1-02.dcm"], "ax", loc, None);
    put_ct(
        d,
        &["1-03.dcm", "1-04.dcm"],
        "sag",
        loc,
        Some("0\\1\\0\\0\\0\\-1"),
    );
    put_ct(
        d,
        &["1-05.dcm", "1-06.dcm"],
        "cor",
        loc,
        Some("1\\0\\0\\0\\0\\-1"),
    );
    put_ct(d, &["1-10.dcm", "1-11.dcm", "1-12.dcm"], "", None, None);
    let v = read(d).unwrap();
    assert_eq!(v.dims(), [512, 512, 3]);
    assert_eq!(v.name.as_deref(), Some("ThoraxRoutine  8.0.0  B40f"));
    // When the largest group is not one volume (two slices at one
    // position), the next consistent one is read.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    put_ct(d, &["1-01.dcm", "1-02.dcm"], "", None, None);
    put_ct(
        d,
        &["1-20.dcm", "1-21.dcm", "1-22.dcm"],
        "",
        Some("1.2.3.8"),
        None,
    );
    put_ct(d, &["1-20.dcm"], "dup", Some("1.2.3.8"), None);
    let s = scan(d).unwrap();
    assert_eq!(s.series[0].frames, 4, "{:?}", s.list());
    assert!(
        s.series[0]
            .problem
            .as_deref()
            .is_some_and(|p| p.contains("same slice position")),
        "{:?}",
        s.series
    );
    assert_eq!(read(d).unwrap().dims(), [512, 512, 2]);
}

/// A multi-frame (enhanced-style) file built from CT slices `names`, with
/// per-frame positions and rescale in functional groups.
fn multi_frame_ct(names: &[&str], out: &Path, bits32: bool) -> Vec<Volume> {
    let src = data_path("dicom_ct_lung").unwrap();
    let mut frames = Vec::new();
    let mut pixels: Vec<u8> = Vec::new();
    let mut singles = Vec::new();
    for n in names {
        let o = dicom_object::open_file(src.join(n)).unwrap();
        let pos = o
            .element(tags::IMAGE_POSITION_PATIENT)
            .unwrap()
            .to_str()
            .unwrap()
            .to_string();
        let px = o
            .element(tags::PIXEL_DATA)
            .unwrap()
            .to_bytes()
            .unwrap()
            .to_vec();
        if bits32 {
            for c in px.chunks_exact(2) {
                let v = u16::from_le_bytes([c[0], c[1]]) as u32 * 1000;
                pixels.extend(v.to_le_bytes());
            }
        } else {
            pixels.extend(px);
        }
        let pos_item = InMemDicomObject::from_element_iter([InMemElement::new(
            tags::IMAGE_POSITION_PATIENT,
            dicom_core::VR::DS,
            dicom_core::PrimitiveValue::from(pos.as_str()),
        )]);
        let frame = InMemDicomObject::from_element_iter([InMemElement::new(
            tags::PLANE_POSITION_SEQUENCE,
            dicom_core::VR::SQ,
            dicom_core::value::DataSetSequence::from(vec![pos_item]),
        )]);
        frames.push(frame);
        let dir = tempfile::tempdir().unwrap();
        std::fs::copy(src.join(n), dir.path().join(n)).unwrap();
        singles.push(read(&dir.path().join(n)).unwrap());
    }
    let mut obj = dicom_object::open_file(src.join(names[0])).unwrap();
    let ori = obj
        .element(tags::IMAGE_ORIENTATION_PATIENT)
        .unwrap()
        .to_str()
        .unwrap()
        .to_string();
    let ps = obj
        .element(tags::PIXEL_SPACING)
        .unwrap()
        .to_str()
        .unwrap()
        .to_string();
    for t in [
        tags::IMAGE_POSITION_PATIENT,
        tags::IMAGE_ORIENTATION_PATIENT,
        tags::PIXEL_SPACING,
    ] {
        obj.remove_element(t);
    }
    let shared = InMemDicomObject::from_element_iter([
        InMemElement::new(
            tags::PLANE_ORIENTATION_SEQUENCE,
            dicom_core::VR::SQ,
            dicom_core::value::DataSetSequence::from(vec![InMemDicomObject::from_element_iter([
                InMemElement::new(
                    tags::IMAGE_ORIENTATION_PATIENT,
                    dicom_core::VR::DS,
                    dicom_core::PrimitiveValue::from(ori.as_str()),
                ),
            ])]),
        ),
        InMemElement::new(
            tags::PIXEL_MEASURES_SEQUENCE,
            dicom_core::VR::SQ,
            dicom_core::value::DataSetSequence::from(vec![InMemDicomObject::from_element_iter([
                InMemElement::new(
                    tags::PIXEL_SPACING,
                    dicom_core::VR::DS,
                    dicom_core::PrimitiveValue::from(ps.as_str()),
                ),
            ])]),
        ),
    ]);
    obj.put(InMemElement::new(
        tags::SHARED_FUNCTIONAL_GROUPS_SEQUENCE,
        dicom_core::VR::SQ,
        dicom_core::value::DataSetSequence::from(vec![shared]),
    ));
    obj.put(InMemElement::new(
        tags::PER_FRAME_FUNCTIONAL_GROUPS_SEQUENCE,
        dicom_core::VR::SQ,
        dicom_core::value::DataSetSequence::from(frames),
    ));
    obj.put_str(
        tags::NUMBER_OF_FRAMES,
        dicom_core::VR::IS,
        names.len().to_string(),
    );
    if bits32 {
        obj.put(InMemElement::new(
            tags::BITS_ALLOCATED,
            dicom_core::VR::US,
            dicom_core::PrimitiveValue::from(32u16),
        ));
        obj.put(InMemElement::new(
            tags::BITS_STORED,
            dicom_core::VR::US,
            dicom_core::PrimitiveValue::from(32u16),
        ));
        obj.put(InMemElement::new(
            tags::HIGH_BIT,
            dicom_core::VR::US,
            dicom_core::PrimitiveValue::from(31u16),
        ));
        obj.put_str(tags::RESCALE_SLOPE, dicom_core::VR::DS, "0.001");
    }
    obj.put(InMemElement::new(
        tags::PIXEL_DATA,
        dicom_core::VR::OB,
        dicom_core::PrimitiveValue::from(pixels),
    ));
    obj.write_to_file(out).unwrap();
    singles
}

#[test]
fn multi_frame_file_with_per_frame_positions_reads_as_the_slices() {
    if data_path("dicom_ct_lung").is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("enhanced.dcm");
    // Frames out of order: the volume follows the positions.
    let names = ["1-03.dcm", "1-01.dcm", "1-02.dcm"];
    let singles = multi_frame_ct(&names, &p, false);
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [512, 512, 3]);
    assert!((v.spacing().z - 8.0).abs() < 1e-4, "{}", v.spacing());
    assert!((v.spacing().x - 0.646_484_4).abs() < 1e-6);
    // 1-01 is at z 312, 1-03 at 296: ordered by position, 1-03 first.
    assert!((v.origin().z - 296.0).abs() < 1e-3, "{}", v.origin());
    for (k, single) in [(0, &singles[0]), (1, &singles[2]), (2, &singles[1])] {
        for (i, j) in [(256, 256), (100, 300), (400, 120)] {
            assert_eq!(v.value(i, j, k), single.value(i, j, 0), "({i},{j},{k})");
        }
    }
    let lines = summary(&p, None).unwrap().join("\n");
    assert!(lines.contains("3 frame(s) in 1 file(s)"), "{lines}");
}

#[test]
fn thirty_two_bit_pixels_with_a_slope_read_as_f32() {
    if data_path("dicom_ct_lung").is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("dose.dcm");
    let singles = multi_frame_ct(&["1-01.dcm", "1-02.dcm"], &p, true);
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [512, 512, 2]);
    // Stored value × 1000 × slope 0.001 − 1024 equals the HU of the slice.
    for (i, j) in [(256, 256), (100, 300)] {
        let a = v.value(i, j, 1);
        let b = singles[0].value(i, j, 0);
        assert!((a - b).abs() < 1e-2, "{a} vs {b}");
    }
}

#[test]
fn padding_after_the_pixels_is_ignored_and_dcm_gz_reads() {
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut obj = dicom_object::open_file(src.join("1-01.dcm")).unwrap();
    let mut px = obj
        .element(tags::PIXEL_DATA)
        .unwrap()
        .to_bytes()
        .unwrap()
        .to_vec();
    px.extend([0xAB; 64]);
    obj.put(InMemElement::new(
        tags::PIXEL_DATA,
        dicom_core::VR::OB,
        dicom_core::PrimitiveValue::from(px),
    ));
    let p = dir.path().join("padded.dcm");
    obj.write_to_file(&p).unwrap();
    let v = read(&p).unwrap();
    let reference = {
        let d = tempfile::tempdir().unwrap();
        std::fs::copy(src.join("1-01.dcm"), d.path().join("1-01.dcm")).unwrap();
        read(&d.path().join("1-01.dcm")).unwrap()
    };
    assert_eq!(v.data(), reference.data());
    // The same slice gzip-compressed, alone in a folder.
    let gz_dir = tempfile::tempdir().unwrap();
    let gz = gz_dir.path().join("slice.dcm.gz");
    let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(&mut enc, &std::fs::read(src.join("1-01.dcm")).unwrap()).unwrap();
    std::fs::write(&gz, enc.finish().unwrap()).unwrap();
    assert_eq!(
        crate::io::detect(&gz, &Default::default()).unwrap(),
        crate::io::Format::Dicom
    );
    let v = read(&gz).unwrap();
    assert_eq!(v.data(), reference.data());
    assert!(folder_has_dicom(gz_dir.path()).unwrap());
}

#[test]
fn non_numeric_rescale_slope_is_refused_naming_the_field() {
    let Some(src) = data_path("dicom_ct_lung") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let mut obj = dicom_object::open_file(src.join("1-01.dcm")).unwrap();
    obj.put_str(tags::RESCALE_SLOPE, dicom_core::VR::DS, "abc");
    let p = dir.path().join("slope.dcm");
    obj.write_to_file(&p).unwrap();
    let s = read(&p).unwrap_err().to_string();
    assert!(
        s.contains("slope.dcm") && s.contains("RescaleSlope") && s.contains("abc"),
        "{s}"
    );
}
