//! The NIfTI-2, Analyze 7.5 and MGH/MGZ readers against small reference
//! files written by the tools that write these formats
//! (`tests/data/formats/make.py`: nibabel, minc-tools; MINC-2's files are
//! read in voxcast-native-io/tests/readers.rs, with its reader). The
//! numbers asserted here are the ones nibabel reads back from the same files
//! (`tests/data/formats/expected.txt`), translated to voxcast's conventions
//! where they differ (said at each place).
//!
//! Every reference volume is 7×5×3 with distinct values, spacing
//! 1.5 × 2 × 2.5 and a non-zero origin.

use glam::Vec3;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use voxcast::io::{open, OpenOptions};
use voxcast::volume::ScalarType;
use voxcast::{Error, Volume};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/formats")
        .join(name)
}

fn read(path: &Path) -> voxcast::Result<Volume> {
    open(path, &OpenOptions::default())
}

/// The index of voxel (i, j, k) in make.py's formulas.
fn idx(i: usize, j: usize, k: usize) -> f64 {
    (i + 7 * j + 35 * k) as f64
}

/// `BASE` of make.py: −50 … 262.
fn base(i: usize, j: usize, k: usize) -> f64 {
    idx(i, j, k) * 3.0 - 50.0
}

/// `UCHAR` of make.py: 0 … 208.
fn uchar(i: usize, j: usize, k: usize) -> f64 {
    idx(i, j, k) * 2.0
}

struct Expect {
    ty: ScalarType,
    origin: Vec3,
    value: fn(usize, usize, usize) -> f64,
    /// min, max, mean as nibabel reports them.
    stats: (f32, f32, f64),
}

fn check(name: &str, v: &Volume, e: &Expect) {
    assert_eq!(v.dims(), [7, 5, 3], "{name}");
    assert_eq!(v.scalar_type(), e.ty, "{name}");
    assert_eq!(v.spacing(), Vec3::new(1.5, 2.0, 2.5), "{name}");
    assert_eq!(v.origin(), e.origin, "{name}");
    for k in 0..3 {
        for j in 0..5 {
            for i in 0..7 {
                assert_eq!(
                    v.value(i, j, k) as f64,
                    (e.value)(i, j, k),
                    "{name} ({i}, {j}, {k})"
                );
            }
        }
    }
    let s = v.stats();
    assert_eq!((s.min, s.max), (e.stats.0, e.stats.1), "{name}");
    assert!((s.mean - e.stats.2).abs() < 1e-9, "{name}: mean {}", s.mean);
}

#[test]
fn nifti2_little_endian_int16_scaled_with_qform() {
    // int16 × scl_slope 0.5 + scl_inter 10 (a fractional slope gives f32);
    // origin = qoffset.
    let v = read(&data("nifti2_le.nii")).unwrap();
    check(
        "nifti2_le.nii",
        &v,
        &Expect {
            ty: ScalarType::F32,
            origin: Vec3::new(-10.0, 20.0, 5.0),
            value: |i, j, k| base(i, j, k) * 0.5 + 10.0,
            stats: (-15.0, 141.0, 63.0),
        },
    );
    assert_eq!(v.value(3, 2, 1), 63.0);
}

#[test]
fn nifti2_big_endian_float32_gzip_with_sform() {
    let v = read(&data("nifti2_be.nii.gz")).unwrap();
    check(
        "nifti2_be.nii.gz",
        &v,
        &Expect {
            ty: ScalarType::F32,
            origin: Vec3::new(3.25, -7.5, 12.0),
            value: |i, j, k| base(i, j, k) / 4.0,
            stats: (-12.5, 65.5, 26.5),
        },
    );
}

#[test]
fn analyze_little_endian_uint8_without_origin() {
    // No originator: voxcast puts voxel 0 at 0 (nibabel centres the volume,
    // translation (4.5, −4, −2.5)). Opening the .img finds its header.
    let e = Expect {
        ty: ScalarType::U8,
        origin: Vec3::ZERO,
        value: uchar,
        stats: (0.0, 208.0, 104.0),
    };
    for name in ["analyze_le.hdr", "analyze_le.img"] {
        check(name, &read(&data(name)).unwrap(), &e);
    }
}

#[test]
fn analyze_spm_big_endian_int16_with_originator_and_scale() {
    // SPM's scale factor 2 (integral: stays i16); originator (4, 4, 3) puts
    // voxel 0 at (1 − originator)·spacing = (−4.5, −6, −5). nibabel's SPM
    // affine says (4.5, −6, −5): the same with SPM's left–right flip, which
    // voxcast does not apply.
    let v = read(&data("analyze_spm_be.hdr")).unwrap();
    check(
        "analyze_spm_be.hdr",
        &v,
        &Expect {
            ty: ScalarType::I16,
            origin: Vec3::new(-4.5, -6.0, -5.0),
            value: |i, j, k| base(i, j, k) * 2.0,
            stats: (-100.0, 524.0, 212.0),
        },
    );
}

#[test]
fn mgh_float32_in_lia_orientation() {
    // Mdc = LIA; origin = the vox2ras translation nibabel reports (the
    // position of voxel 0); the axes are kept as stored.
    let v = read(&data("brain.mgh")).unwrap();
    check(
        "brain.mgh",
        &v,
        &Expect {
            ty: ScalarType::F32,
            origin: Vec3::new(4.0, 30.0, -12.0),
            value: |i, j, k| base(i, j, k) / 8.0,
            stats: (-6.25, 32.75, 13.25),
        },
    );
}

#[test]
fn mgz_uint8() {
    let v = read(&data("brain.mgz")).unwrap();
    check(
        "brain.mgz",
        &v,
        &Expect {
            ty: ScalarType::U8,
            origin: Vec3::new(-20.0, 8.0, 1.25),
            value: uchar,
            stats: (0.0, 208.0, 104.0),
        },
    );
}

#[test]
fn header_facts_for_info() {
    let lines = |name: &str| {
        let (title, l) = voxcast::io::header_summary(&data(name), &OpenOptions::default())
            .unwrap()
            .unwrap();
        format!("{title}\n{}", l.join("\n"))
    };
    let s = lines("nifti2_be.nii.gz");
    for w in [
        "NIfTI-2 (single file)",
        "big-endian",
        "gzip",
        "16 (float32)",
    ] {
        assert!(s.contains(w), "{w}: {s}");
    }
    assert!(
        s.contains("sform_code 2 (aligned); origin from srow"),
        "{s}"
    );
    let s = lines("analyze_spm_be.hdr");
    for w in [
        "Analyze 7.5 (header + image file analyze_spm_be.img)",
        "originator  4 4 3",
        "scaling     2 · v + 0",
    ] {
        assert!(s.contains(w), "{w}: {s}");
    }
    let s = lines("brain.mgh");
    for w in [
        "FreeSurfer MGH",
        "3 (float32)",
        "LIA",
        "voxel 0 at 4 30 -12",
    ] {
        assert!(s.contains(w), "{w}: {s}");
    }
    assert!(lines("brain.mgz").contains("MGZ (gzip)"));
}

fn tmp_copy(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn gunzip(b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(b)
        .read_to_end(&mut out)
        .unwrap();
    out
}

fn gzip(b: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(b).unwrap();
    e.finish().unwrap()
}

/// The error of reading `p`, which must name the file and `field`.
fn error_of(p: &Path, field: &str) -> String {
    let e = read(p).unwrap_err();
    let s = e.to_string();
    let name = p.file_name().unwrap().to_string_lossy();
    assert!(
        matches!(e, Error::Format { .. }) && s.contains(&*name) && s.contains(field),
        "{field}: {s}"
    );
    s
}

#[test]
fn truncated_files_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n2 = std::fs::read(data("nifti2_le.nii")).unwrap();
    // In the voxels (544 + 210 bytes), in the header.
    let s = error_of(&tmp_copy(d, "cut.nii", &n2[..700]), "`dim`");
    assert!(s.contains("truncated"), "{s}");
    let s = error_of(&tmp_copy(d, "head.nii", &n2[..300]), "`header`");
    assert!(s.contains("540-byte header"), "{s}");
    // Gzip: the stream ends early.
    let be = gunzip(&std::fs::read(data("nifti2_be.nii.gz")).unwrap());
    let s = error_of(&tmp_copy(d, "cut.nii.gz", &gzip(&be[..600])), "`dim`");
    assert!(s.contains("ends after"), "{s}");
    // Analyze: the .img is short.
    std::fs::copy(data("analyze_le.hdr"), d.join("a.hdr")).unwrap();
    let img = std::fs::read(data("analyze_le.img")).unwrap();
    tmp_copy(d, "a.img", &img[..100]);
    let s = error_of(&d.join("a.img"), "`dim`");
    assert!(s.contains("truncated"), "{s}");
    // MGH in the voxels and in the header; MGZ in the voxels.
    let mgh = std::fs::read(data("brain.mgh")).unwrap();
    let s = error_of(&tmp_copy(d, "cut.mgh", &mgh[..500]), "`width/height/depth`");
    assert!(s.contains("truncated"), "{s}");
    let s = error_of(&tmp_copy(d, "head.mgh", &mgh[..100]), "`header`");
    assert!(s.contains("284-byte MGH header"), "{s}");
    let mgz = gunzip(&std::fs::read(data("brain.mgz")).unwrap());
    let s = error_of(
        &tmp_copy(d, "cut.mgz", &gzip(&mgz[..300])),
        "`width/height/depth`",
    );
    assert!(s.contains("ends after"), "{s}");
}

#[test]
fn headers_lying_about_dims_are_refused_before_allocating() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // NIfTI-2: dim[1..=3] are i64 at byte 16 + 8·i; 2000³ int16 voxels
    // (16 GB) claimed by a 754-byte file.
    let mut n2 = std::fs::read(data("nifti2_le.nii")).unwrap();
    for i in 1..=3 {
        n2[16 + 8 * i..24 + 8 * i].copy_from_slice(&2000i64.to_le_bytes());
    }
    let s = error_of(&tmp_copy(d, "big.nii", &n2), "`dim`");
    assert!(s.contains("2000×2000×2000"), "{s}");
    // The same in a gzip stream of a few hundred bytes.
    let mut be = gunzip(&std::fs::read(data("nifti2_be.nii.gz")).unwrap());
    for i in 1..=3 {
        be[16 + 8 * i..24 + 8 * i].copy_from_slice(&2000i64.to_be_bytes());
    }
    let s = error_of(&tmp_copy(d, "big.nii.gz", &gzip(&be)), "`dim`");
    assert!(s.contains("cannot hold"), "{s}");
    // A negative NIfTI-2 dimension.
    n2[24..32].copy_from_slice(&(-7i64).to_le_bytes());
    let s = error_of(&tmp_copy(d, "neg.nii", &n2), "`dim`");
    assert!(s.contains("dim[1] = -7"), "{s}");
    // Analyze: dim[1..=3] are i16 at byte 40 + 2·i, big-endian here.
    let mut hdr = std::fs::read(data("analyze_spm_be.hdr")).unwrap();
    for i in 1..=3 {
        hdr[40 + 2 * i..42 + 2 * i].copy_from_slice(&30000i16.to_be_bytes());
    }
    std::fs::copy(data("analyze_spm_be.img"), d.join("big.img")).unwrap();
    let s = error_of(&tmp_copy(d, "big.hdr", &hdr), "`dim`");
    assert!(s.contains("30000×30000×30000"), "{s}");
    // MGH: width/height/depth are big-endian i32 at bytes 4, 8, 12.
    let mut mgh = std::fs::read(data("brain.mgh")).unwrap();
    for at in [4, 8, 12] {
        mgh[at..at + 4].copy_from_slice(&5000i32.to_be_bytes());
    }
    let s = error_of(&tmp_copy(d, "big.mgh", &mgh), "`width/height/depth`");
    assert!(s.contains("5000×5000×5000"), "{s}");
    let mut mgz = gunzip(&std::fs::read(data("brain.mgz")).unwrap());
    for at in [4, 8, 12] {
        mgz[at..at + 4].copy_from_slice(&1000i32.to_be_bytes());
    }
    let s = error_of(&tmp_copy(d, "big.mgz", &gzip(&mgz)), "`width/height/depth`");
    assert!(
        s.contains("1000×1000×1000") && s.contains("cannot hold"),
        "{s}"
    );
}

#[test]
fn mgh_with_several_frames_or_a_bad_type_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mgh = std::fs::read(data("brain.mgh")).unwrap();
    let mut m = mgh.clone();
    m[16..20].copy_from_slice(&4i32.to_be_bytes());
    let e = read(&tmp_copy(d, "frames.mgh", &m)).unwrap_err();
    let s = e.to_string();
    assert!(
        matches!(e, Error::Unsupported { .. })
            && s.contains("frames.mgh")
            && s.contains("nframes = 4")
            && s.contains("mri_convert --frame 0"),
        "{s}"
    );
    let mut m = mgh.clone();
    m[20..24].copy_from_slice(&7i32.to_be_bytes());
    let s = error_of(&tmp_copy(d, "type.mgh", &m), "`type`");
    assert!(s.contains("expected 0 (uchar)"), "{s}");
    let mut m = mgh;
    m[0..4].copy_from_slice(&2i32.to_be_bytes());
    error_of(&tmp_copy(d, "version.mgh", &m), "`version`");
}
