use super::*;
use crate::io::util::file_len;
use crate::volume::{ScalarType, VoxelData};
use std::io::Write;

/// The fields a test sets in a hand-written 348-byte NIfTI-1 header.
struct Hdr {
    dim: [i16; 8],
    datatype: i16,
    bitpix: i16,
    pixdim: [f32; 8],
    vox_offset: f32,
    slope: f32,
    inter: f32,
    qform_code: i16,
    qoffset: [f32; 3],
    sform_code: i16,
    srow_t: [f32; 3],
    intent_name: &'static [u8],
    magic: &'static [u8; 4],
    big_endian: bool,
}

impl Default for Hdr {
    fn default() -> Self {
        Hdr {
            dim: [3, 4, 3, 2, 1, 1, 1, 1],
            datatype: 2,
            bitpix: 8,
            pixdim: [1.0, 0.5, 0.75, 2.0, 1.0, 0.0, 0.0, 0.0],
            vox_offset: 352.0,
            slope: 0.0,
            inter: 0.0,
            qform_code: 0,
            qoffset: [0.0; 3],
            sform_code: 0,
            srow_t: [0.0; 3],
            intent_name: b"",
            magic: b"n+1\0",
            big_endian: false,
        }
    }
}

impl Hdr {
    /// The header bytes (348) plus the 4-byte extension flag (zeros).
    fn bytes(&self) -> Vec<u8> {
        let mut b = vec![0u8; 352];
        let be = self.big_endian;
        let mut put = |at: usize, v: &[u8]| b[at..at + v.len()].copy_from_slice(v);
        macro_rules! num {
            ($v:expr) => {
                if be {
                    $v.to_be_bytes()
                } else {
                    $v.to_le_bytes()
                }
            };
        }
        put(0, &num!(348i32));
        put(38, b"r");
        for (i, d) in self.dim.iter().enumerate() {
            put(40 + 2 * i, &num!(*d));
        }
        put(70, &num!(self.datatype));
        put(72, &num!(self.bitpix));
        for (i, p) in self.pixdim.iter().enumerate() {
            put(76 + 4 * i, &num!(*p));
        }
        put(108, &num!(self.vox_offset));
        put(112, &num!(self.slope));
        put(116, &num!(self.inter));
        put(123, &[2]); // xyzt_units: mm
        put(148, b"voxcast test");
        put(252, &num!(self.qform_code));
        put(254, &num!(self.sform_code));
        for (i, q) in self.qoffset.iter().enumerate() {
            put(268 + 4 * i, &num!(*q));
        }
        // srow_x/y/z = identity with translation srow_t.
        for r in 0..3 {
            let mut row = [0f32; 4];
            row[r] = 1.0;
            row[3] = self.srow_t[r];
            for (c, v) in row.iter().enumerate() {
                put(280 + 16 * r + 4 * c, &num!(*v));
            }
        }
        put(328, self.intent_name);
        put(344, self.magic);
        b
    }
}

fn write(dir: &Path, name: &str, h: &Hdr, data: &[u8], gzip: bool) -> PathBuf {
    let p = dir.join(name);
    let mut bytes = h.bytes();
    bytes.extend_from_slice(data);
    if gzip {
        let mut enc = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        enc.write_all(&bytes).unwrap();
        bytes = enc.finish().unwrap();
    }
    std::fs::write(&p, bytes).unwrap();
    p
}

fn le<T: Copy>(v: &[T], f: impl Fn(T) -> Vec<u8>) -> Vec<u8> {
    v.iter().flat_map(|x| f(*x)).collect()
}

#[test]
fn uint8_dims_spacing_origin_values() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        qform_code: 1,
        qoffset: [10.0, -20.0, 30.5],
        intent_name: b"density",
        ..Default::default()
    };
    let data: Vec<u8> = (0..24).map(|i| i * 10).collect();
    let p = write(dir.path(), "v.nii", &h, &data, false);
    let v = read(&p).unwrap();
    assert_eq!(v.dims(), [4, 3, 2]);
    assert_eq!(v.scalar_type(), ScalarType::U8);
    assert_eq!(v.spacing(), Vec3::new(0.5, 0.75, 2.0));
    assert_eq!(v.origin(), Vec3::new(10.0, -20.0, 30.5));
    assert_eq!(v.name.as_deref(), Some("density"));
    // x fastest: index = i + 4 (j + 3 k).
    assert_eq!(v.value(0, 0, 0), 0.0);
    assert_eq!(v.value(3, 0, 0), 30.0);
    assert_eq!(v.value(1, 2, 1), 10.0 * (1 + 4 * (2 + 3)) as f32);
    assert_eq!(v.value(3, 2, 1), 230.0);
}

#[test]
fn gzip_reads_the_same_and_goes_through_open() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        datatype: 4,
        bitpix: 16,
        ..Default::default()
    };
    let vals: Vec<i16> = (0..24).map(|i| i * 100 - 1200).collect();
    let p = write(
        dir.path(),
        "v.nii.gz",
        &h,
        &le(&vals, |x| x.to_le_bytes().to_vec()),
        true,
    );
    let v = crate::io::open(&p, &Default::default()).unwrap();
    assert_eq!(v.dims(), [4, 3, 2]);
    assert_eq!(v.scalar_type(), ScalarType::I16);
    assert_eq!(v.data(), &VoxelData::I16(vals.into()));
}

#[test]
fn scaling_is_applied() {
    let dir = tempfile::tempdir().unwrap();
    // Integral scaling of int16 stays i16 (as CT HU would).
    let h = Hdr {
        datatype: 4,
        bitpix: 16,
        slope: 2.0,
        inter: -100.0,
        ..Default::default()
    };
    let vals: Vec<i16> = (0..24).collect();
    let p = write(
        dir.path(),
        "a.nii",
        &h,
        &le(&vals, |x| x.to_le_bytes().to_vec()),
        false,
    );
    let v = read(&p).unwrap();
    assert_eq!(v.scalar_type(), ScalarType::I16);
    assert_eq!(v.value(3, 2, 1), 23.0 * 2.0 - 100.0);
    // A fractional slope gives f32.
    let h = Hdr {
        datatype: 512,
        bitpix: 16,
        slope: 0.5,
        inter: 1.0,
        ..Default::default()
    };
    let vals: Vec<u16> = (0..24).map(|i| i * 1000).collect();
    let p = write(
        dir.path(),
        "b.nii",
        &h,
        &le(&vals, |x| x.to_le_bytes().to_vec()),
        false,
    );
    let v = read(&p).unwrap();
    assert_eq!(v.scalar_type(), ScalarType::F32);
    assert_eq!(v.value(1, 0, 0), 501.0);
    assert_eq!(v.value(3, 2, 1), 23000.0 * 0.5 + 1.0);
    // (1, 0) and slope 0 leave the data alone.
    for (slope, inter) in [(1.0, 0.0), (0.0, 5.0)] {
        let h = Hdr {
            datatype: 512,
            bitpix: 16,
            slope,
            inter,
            ..Default::default()
        };
        let p = write(
            dir.path(),
            "c.nii",
            &h,
            &le(&vals, |x| x.to_le_bytes().to_vec()),
            false,
        );
        let v = read(&p).unwrap();
        assert_eq!(
            v.data(),
            &VoxelData::U16(vals.clone().into()),
            "{slope} {inter}"
        );
    }
}

#[test]
fn big_endian_file() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        datatype: 16,
        bitpix: 32,
        big_endian: true,
        ..Default::default()
    };
    let vals: Vec<f32> = (0..24).map(|i| i as f32 * 0.25 - 1.0).collect();
    let p = write(
        dir.path(),
        "be.nii",
        &h,
        &le(&vals, |x| x.to_be_bytes().to_vec()),
        false,
    );
    let v = read(&p).unwrap();
    assert_eq!(v.spacing(), Vec3::new(0.5, 0.75, 2.0));
    assert_eq!(v.data(), &VoxelData::F32(vals.into()));
}

#[test]
fn other_datatypes_are_converted() {
    let dir = tempfile::tempdir().unwrap();
    let case = |datatype: i16, bitpix: i16, data: Vec<u8>| {
        let h = Hdr {
            datatype,
            bitpix,
            ..Default::default()
        };
        read(&write(dir.path(), "t.nii", &h, &data, false)).unwrap()
    };
    let i8s: Vec<i8> = (0..24).map(|i| i * 5 - 60).collect();
    let v = case(256, 8, le(&i8s, |x| x.to_le_bytes().to_vec()));
    assert_eq!(
        v.data(),
        &VoxelData::I16(i8s.iter().map(|&x| x as i16).collect())
    );
    let f64s: Vec<f64> = (0..24).map(|i| i as f64 / 3.0).collect();
    let v = case(64, 64, le(&f64s, |x| x.to_le_bytes().to_vec()));
    assert_eq!(
        v.data(),
        &VoxelData::F32(f64s.iter().map(|&x| x as f32).collect())
    );
    // A small int32 label map fits i16; large uint32 values need f32.
    let labels: Vec<i32> = (0..24).map(|i| i % 5 - 1).collect();
    let v = case(8, 32, le(&labels, |x| x.to_le_bytes().to_vec()));
    assert_eq!(
        v.data(),
        &VoxelData::I16(labels.iter().map(|&x| x as i16).collect())
    );
    let big: Vec<u32> = (0..24).map(|i| i * 1_000_000).collect();
    let v = case(768, 32, le(&big, |x| x.to_le_bytes().to_vec()));
    assert_eq!(v.scalar_type(), ScalarType::F32);
    assert_eq!(v.value(3, 2, 1), 23_000_000.0);
}

#[test]
fn single_slice_and_4d_with_one_volume() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        dim: [2, 4, 3, 0, 0, 0, 0, 0],
        pixdim: [1.0, 0.5, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0],
        ..Default::default()
    };
    let v = read(&write(dir.path(), "2d.nii", &h, &[7u8; 12], false)).unwrap();
    assert_eq!(v.dims(), [4, 3, 1]);
    assert_eq!(v.spacing(), Vec3::new(0.5, 0.5, 1.0));
    let h = Hdr {
        dim: [4, 4, 3, 2, 1, 1, 1, 1],
        ..Default::default()
    };
    let v = read(&write(dir.path(), "4d.nii", &h, &[1u8; 24], false)).unwrap();
    assert_eq!(v.dims(), [4, 3, 2]);
    let h = Hdr {
        dim: [4, 4, 3, 2, 5, 1, 1, 1],
        ..Default::default()
    };
    let e = read(&write(dir.path(), "4d5.nii", &h, &[1u8; 120], false)).unwrap_err();
    assert!(
        matches!(e, Error::Unsupported { .. }) && e.to_string().contains("dim[4] = 5"),
        "{e}"
    );
}

#[test]
fn sform_translation_when_no_qform() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        sform_code: 2,
        srow_t: [-90.0, 126.0, -72.0],
        ..Default::default()
    };
    let v = read(&write(dir.path(), "s.nii", &h, &[0u8; 24], false)).unwrap();
    assert_eq!(v.origin(), Vec3::new(-90.0, 126.0, -72.0));
}

#[test]
fn header_image_pair() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        magic: b"ni1\0",
        vox_offset: 0.0,
        ..Default::default()
    };
    let hdr = dir.path().join("pair.hdr");
    std::fs::write(&hdr, &h.bytes()[..348]).unwrap();
    std::fs::write(dir.path().join("pair.img"), (0..24u8).collect::<Vec<_>>()).unwrap();
    let v = crate::io::open(&hdr, &Default::default()).unwrap();
    assert_eq!(v.dims(), [4, 3, 2]);
    assert_eq!(v.value(3, 2, 1), 23.0);
}

#[test]
fn a_billion_voxels_in_a_small_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        dim: [3, 1000, 1000, 1000, 1, 1, 1, 1],
        ..Default::default()
    };
    for gz in [false, true] {
        let name = if gz { "big.nii.gz" } else { "big.nii" };
        let p = write(dir.path(), name, &h, &[0u8; 600], gz);
        assert!(file_len(&p).unwrap() < 1024);
        let s = read(&p).unwrap_err().to_string();
        assert!(
            s.contains(name) && s.contains("`dim`") && s.contains("1000000000"),
            "{s}"
        );
    }
}

#[test]
fn truncated_data_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        datatype: 4,
        bitpix: 16,
        ..Default::default()
    };
    let s = read(&write(dir.path(), "t.nii", &h, &[0u8; 40], false))
        .unwrap_err()
        .to_string();
    assert!(
        s.contains("t.nii") && s.contains("`dim`") && s.contains("truncated"),
        "{s}"
    );
    // Gzip: the size check passes, the stream ends early.
    let s = read(&write(dir.path(), "t.nii.gz", &h, &[0u8; 40], true))
        .unwrap_err()
        .to_string();
    assert!(
        s.contains("t.nii.gz") && s.contains("`dim`") && s.contains("ends after 40 bytes"),
        "{s}"
    );
}

#[test]
fn unknown_and_unsupported_datatypes() {
    let dir = tempfile::tempdir().unwrap();
    let h = Hdr {
        datatype: 999,
        ..Default::default()
    };
    let s = read(&write(dir.path(), "u.nii", &h, &[0u8; 24], false))
        .unwrap_err()
        .to_string();
    assert!(
        s.contains("u.nii") && s.contains("`datatype`") && s.contains("999"),
        "{s}"
    );
    let h = Hdr {
        datatype: 32,
        bitpix: 64,
        ..Default::default()
    };
    let e = read(&write(dir.path(), "c.nii", &h, &[0u8; 192], false)).unwrap_err();
    assert!(
        matches!(e, Error::Unsupported { .. }) && e.to_string().contains("complex"),
        "{e}"
    );
}

#[test]
fn bad_header_fields_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let mut pd = Hdr::default().pixdim;
    for bad in [0.0, f32::NAN, f32::INFINITY] {
        pd[2] = bad;
        let h = Hdr {
            pixdim: pd,
            ..Default::default()
        };
        let s = read(&write(dir.path(), "p.nii", &h, &[0u8; 24], false))
            .unwrap_err()
            .to_string();
        assert!(s.contains("p.nii") && s.contains("`pixdim`"), "{s}");
    }
    // Negative pixdim (a flipped axis) is read as its size.
    let h = Hdr {
        pixdim: [-1.0, -0.5, 0.75, 2.0, 0.0, 0.0, 0.0, 0.0],
        ..Default::default()
    };
    assert_eq!(
        read(&write(dir.path(), "n.nii", &h, &[0u8; 24], false))
            .unwrap()
            .spacing()
            .x,
        0.5
    );
    for (dim, what) in [
        ([3, 4, -3, 2, 1, 1, 1, 1], "dim[2] = -3"),
        ([0, 4, 3, 2, 1, 1, 1, 1], "dim[0] = 0"),
        ([3, 4, 0, 2, 1, 1, 1, 1], "dim[2] = 0"),
    ] {
        let h = Hdr {
            dim,
            ..Default::default()
        };
        let s = read(&write(dir.path(), "d.nii", &h, &[0u8; 24], false))
            .unwrap_err()
            .to_string();
        assert!(s.contains("`dim`") && s.contains(what), "{s}");
    }
    let h = Hdr {
        vox_offset: 100.0,
        ..Default::default()
    };
    let s = read(&write(dir.path(), "o.nii", &h, &[0u8; 24], false))
        .unwrap_err()
        .to_string();
    assert!(s.contains("`vox_offset`"), "{s}");
    // Not NIfTI at all, too short, NIfTI-2.
    std::fs::write(dir.path().join("x.nii"), vec![7u8; 400]).unwrap();
    let s = read(&dir.path().join("x.nii")).unwrap_err().to_string();
    assert!(s.contains("x.nii") && s.contains("`sizeof_hdr`"), "{s}");
    std::fs::write(dir.path().join("s.nii"), 348i32.to_le_bytes()).unwrap();
    let s = read(&dir.path().join("s.nii")).unwrap_err().to_string();
    assert!(s.contains("s.nii") && s.contains("348-byte header"), "{s}");
    let mut b = Hdr::default().bytes();
    b[..4].copy_from_slice(&540i32.to_le_bytes());
    std::fs::write(dir.path().join("n2.nii"), b).unwrap();
    // A 540 `sizeof_hdr` is NIfTI-2, whose header is longer than this file.
    let s = read(&dir.path().join("n2.nii")).unwrap_err().to_string();
    assert!(
        s.contains("n2.nii") && s.contains("`header`") && s.contains("540-byte header"),
        "{s}"
    );
    let mut b = Hdr::default().bytes();
    b[344..348].copy_from_slice(b"abc\0");
    b.extend_from_slice(&[0u8; 24]);
    std::fs::write(dir.path().join("m.nii"), b).unwrap();
    let s = read(&dir.path().join("m.nii")).unwrap_err().to_string();
    assert!(s.contains("m.nii") && s.contains("`magic`"), "{s}");
}
