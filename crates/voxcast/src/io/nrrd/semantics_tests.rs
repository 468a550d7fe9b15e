//! NRRD semantics of issues 22 and 20: which axis is dropped, data longer
//! than the header says, spacings, magic, the byte-skip message.

use super::read;
use super::tests::{attached, gzip};
use crate::io::test_support::{err_naming, write};
use glam::Vec3;

#[test]
fn the_none_axis_is_dropped_wherever_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let data: Vec<u8> = (0..30).collect();
    // 1×5×6×1 with the LAST axis `none`: x has size 1, not the first dropped.
    let h = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 5 6 1\nencoding: raw\n\
             space directions: (2,0,0) (0,3,0) (0,0,4) none\n";
    let p = write(dir.path(), "last.nrrd", &attached(h, &data));
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [1, 5, 6]);
    assert_eq!(v.spacing(), Vec3::new(2.0, 3.0, 4.0));
    assert_eq!(v.value(0, 4, 5), 29.0);
    // The same told by `kinds:` (a non-space kind), spacings from `spacings:`.
    let h = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 5 6 1\nencoding: raw\n\
             kinds: domain domain domain vector\nspacings: 2 3 4 nan\n";
    let p = write(dir.path(), "kinds.nrrd", &attached(h, &data));
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [1, 5, 6]);
    assert_eq!(v.spacing(), Vec3::new(2.0, 3.0, 4.0));
    // A non-space axis of more than one component is refused by name.
    let h = "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 5 2 1\nencoding: raw\n\
             kinds: RGB-color domain domain domain\n";
    let p = write(dir.path(), "rgb.nrrd", &attached(h, &data));
    let s = read(&p).unwrap_err().to_string();
    assert!(s.contains("rgb.nrrd") && s.contains("axis 0"), "{s}");
}

#[test]
fn gzip_data_longer_than_the_sizes_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n";
    let p = write(dir.path(), "long.nrrd", &attached(h, &gzip(&[7u8; 18])));
    let s = err_naming(read(&p), "long.nrrd", "sizes");
    assert!(s.contains("10 byte(s) more"), "{s}");
    // Exactly the right length still reads.
    let p = write(dir.path(), "ok.nrrd", &attached(h, &gzip(&[7u8; 8])));
    assert_eq!(read(&p).unwrap().value(1, 1, 1), 7.0);
    // A detached header pointing at a .nii.gz: its 352 header bytes are
    // not voxels.
    let mut nii = vec![0u8; 352];
    nii[0..4].copy_from_slice(&348i32.to_le_bytes());
    nii.extend([1u8; 8]);
    write(dir.path(), "img.nii.gz", &gzip(&nii));
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\ndata file: img.nii.gz\n";
    let p = write(dir.path(), "d.nhdr", h.as_bytes());
    let s = read(&p).unwrap_err().to_string();
    assert!(
        s.contains("img.nii.gz") && s.contains("352 byte(s) more"),
        "{s}"
    );
}

#[test]
fn bad_spacings_and_magic_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let data = [0u8; 8];
    for (extra, field) in [
        ("spacings: 1 -1 1", "spacings"),
        ("spacings: 1 inf 1", "spacings"),
    ] {
        let h =
            format!("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n{extra}\n");
        let p = write(dir.path(), "s.nrrd", &attached(&h, &data));
        err_naming(read(&p), "s.nrrd", field);
    }
    // nan on a space axis: read with spacing 1 (and a warning).
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nspacings: 1 nan 2\n";
    let p = write(dir.path(), "n.nrrd", &attached(h, &data));
    assert_eq!(read(&p).unwrap().spacing(), Vec3::new(1.0, 1.0, 2.0));
    for magic in ["NRRD9999", "NRRD0006", "NRRDX"] {
        let h = format!("{magic}\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n");
        let p = write(dir.path(), "m.nrrd", &attached(&h, &data));
        let s = err_naming(read(&p), "m.nrrd", "magic");
        assert!(s.contains(magic), "{s}");
    }
    for magic in ["NRRD0001", "NRRD0005"] {
        let h = format!("{magic}\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n");
        let p = write(dir.path(), "m.nrrd", &attached(&h, &data));
        assert!(read(&p).is_ok(), "{magic}");
    }
}

#[test]
fn byte_skip_message_does_not_contradict_itself() {
    let dir = tempfile::tempdir().unwrap();
    // 54000 bytes of data asked for, the file holds fewer after its header.
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 30 30 60\nencoding: raw\nbyte skip: -1\n";
    let p = write(dir.path(), "b.nrrd", &attached(h, &vec![0u8; 53990]));
    let s = err_naming(read(&p), "b.nrrd", "byte skip");
    assert!(!s.contains("has no room"), "{s}");
    assert!(
        s.contains("54000 bytes of data") && s.contains("would start before byte"),
        "{s}"
    );
}

/// `bytes(range(8))` compressed by Python's `bz2.compress` (libbzip2).
const BZ2_0_TO_7: &[u8] = &[
    66, 90, 104, 57, 49, 65, 89, 38, 83, 89, 181, 53, 35, 237, 0, 0, 0, 64, 0, 127, 128, 32, 0, 49,
    12, 8, 25, 26, 105, 147, 53, 115, 249, 69, 220, 145, 78, 20, 36, 45, 77, 72, 251, 64,
];

#[test]
fn bzip2_encoding_reads_and_checks_its_length() {
    let dir = tempfile::tempdir().unwrap();
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n";
    let p = write(dir.path(), "b.nrrd", &attached(h, BZ2_0_TO_7));
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [2, 2, 2]);
    assert_eq!(v.value(1, 0, 0), 1.0);
    assert_eq!(v.value(1, 1, 1), 7.0);
    // Fewer voxels than the stream holds: an error, as for gzip.
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 1\nencoding: bz2\n";
    let p = write(dir.path(), "short.nrrd", &attached(h, BZ2_0_TO_7));
    let s = err_naming(read(&p), "short.nrrd", "sizes");
    assert!(s.contains("4 byte(s) more"), "{s}");
    // A truncated stream is an error, not a panic.
    let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bzip2\n";
    let p = write(dir.path(), "cut.nrrd", &attached(h, &BZ2_0_TO_7[..20]));
    err_naming(read(&p), "cut.nrrd", "sizes");
}
