use super::write::{level_dims, write_volume, Compression, WriteOptions, ZarrFormat};
use super::*;
use crate::volume::chunked::downsample2;

/// A u16 volume of odd dims with structure and an empty corner (x < 8,
/// y < 8: zero), so some chunks hold only the fill value.
fn sample(dims: [usize; 3]) -> Volume {
    let mut v = Volume::from_fn(dims, Vec3::new(0.5, 0.75, 1.25), |i, j, k| {
        if i < 8 && j < 8 {
            0.0
        } else {
            ((i * 37 + j * 11 + k * 5) % 1000) as f32 + 1.0
        }
    })
    .unwrap();
    v = Volume::new(
        v.dims(),
        v.spacing(),
        Vec3::new(10.0, -2.0, 3.0),
        VoxelData::U16(
            (0..v.data().len())
                .map(|i| v.data().get(i) as u16)
                .collect::<Vec<_>>()
                .into(),
        ),
    )
    .unwrap();
    v
}

fn opts(format: ZarrFormat, compression: Compression) -> WriteOptions {
    WriteOptions {
        chunk: [8, 8, 4],
        levels: None,
        format,
        compression,
    }
}

#[test]
fn v2_and_v3_round_trip_every_level_exactly() {
    let vol = sample([37, 29, 23]);
    for format in [ZarrFormat::V2, ZarrFormat::V3] {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.zarr");
        let st = write_volume(&vol, &p, &opts(format, Compression::Zstd(3)), &|_, _| {}).unwrap();
        assert!(st.chunks_empty > 0, "{st:?}");
        let s = ZarrStore::open(&p).unwrap();
        assert_eq!(
            s.info().zarr_format,
            if format == ZarrFormat::V2 { 2 } else { 3 }
        );
        assert_eq!(
            s.info().ome_version.as_deref(),
            Some(if format == ZarrFormat::V2 {
                "0.4"
            } else {
                "0.5"
            })
        );
        // Levels until one fits a chunk: 37×29×23 → 19×15×12 → 10×8×6 → 5×4×3.
        let dims: Vec<[u64; 3]> = s.levels().iter().map(|l| l.dims).collect();
        assert_eq!(
            dims,
            vec![[37, 29, 23], [19, 15, 12], [10, 8, 6], [5, 4, 3]]
        );
        assert_eq!(
            dims,
            level_dims([37, 29, 23], &opts(format, Compression::None))
        );
        let back = s.read_level(0).unwrap();
        assert_eq!(back.data(), vol.data(), "{format:?}");
        assert_eq!(back.spacing(), vol.spacing());
        assert_eq!(back.origin(), vol.origin());
        // Every level is the 2×2×2 mean of the one before, in the same
        // world box (origin at the first block's centre).
        let mut expect = vol.clone();
        for l in 1..dims.len() {
            expect = downsample2(&expect).unwrap();
            let got = s.read_level(l).unwrap();
            assert_eq!(got.data(), expect.data(), "{format:?} level {l}");
            assert!((got.spacing() - expect.spacing()).length() < 1e-6);
            assert!(
                (got.origin() - expect.origin()).length() < 1e-5,
                "level {l}"
            );
        }
        // Chunk reads give the chunk's box; the empty corner is known
        // without reading it, the rest by its range.
        assert_eq!(s.chunk_range(0, [0, 0, 0]), ChunkRange::Fill(0.0));
        let c = s.read_chunk(0, [0, 0, 0]).unwrap();
        assert!((0..c.len()).all(|i| c.get(i) == 0.0));
        match s.chunk_range(0, [2, 1, 3]) {
            ChunkRange::Range(lo, hi) => assert!(lo >= 1.0 && hi <= 1000.0 && lo < hi),
            r => panic!("{r:?}"),
        }
        let c = s.read_chunk(0, [4, 3, 5]).unwrap(); // the corner chunk: 5×5×3
        assert_eq!(c.len(), 5 * 5 * 3);
        assert_eq!(c.get(0), vol.value(32, 24, 20));
        assert_eq!(s.value_range(), Some([vol.stats().min, vol.stats().max]));
        assert!(s.bytes_read() > 0);
    }
}

#[test]
fn every_codec_and_type_round_trips() {
    let base = sample([20, 17, 9]);
    let types = [
        VoxelData::U8(
            (0..base.data().len())
                .map(|i| (base.data().get(i) as u32 % 256) as u8)
                .collect::<Vec<_>>()
                .into(),
        ),
        VoxelData::I16(
            (0..base.data().len())
                .map(|i| base.data().get(i) as i16 - 500)
                .collect::<Vec<_>>()
                .into(),
        ),
        VoxelData::F32(
            (0..base.data().len())
                .map(|i| base.data().get(i) * 0.25 - 3.0)
                .collect::<Vec<_>>()
                .into(),
        ),
    ];
    for data in types {
        let vol = Volume::new(base.dims(), base.spacing(), base.origin(), data).unwrap();
        for c in [
            Compression::Zstd(1),
            Compression::Blosc(5),
            Compression::Gzip(1),
            Compression::None,
        ] {
            for format in [ZarrFormat::V2, ZarrFormat::V3] {
                let dir = tempfile::tempdir().unwrap();
                let p = dir.path().join("t.zarr");
                write_volume(&vol, &p, &opts(format, c), &|_, _| {}).unwrap();
                let back = read(&p, &OpenOptions::default()).unwrap();
                assert_eq!(
                    back.data(),
                    vol.data(),
                    "{:?} {c:?} {format:?}",
                    vol.scalar_type()
                );
            }
        }
    }
}

#[test]
fn a_missing_chunk_reads_as_fill_and_a_corrupt_one_is_named() {
    let vol = sample([24, 24, 8]);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.zarr");
    write_volume(
        &vol,
        &p,
        &opts(ZarrFormat::V3, Compression::Zstd(3)),
        &|_, _| {},
    )
    .unwrap();
    // v3 keys: c/z/y/x.
    let chunk = p.join("0/c/1/2/2");
    assert!(chunk.is_file());
    std::fs::remove_file(&chunk).unwrap();
    let s = ZarrStore::open(&p).unwrap();
    assert_eq!(s.chunk_range(0, [2, 2, 1]), ChunkRange::Fill(0.0));
    let c = s.read_chunk(0, [2, 2, 1]).unwrap();
    assert!((0..c.len()).all(|i| c.get(i) == 0.0));
    std::fs::write(p.join("0/c/0/2/2"), b"not zstd at all").unwrap();
    let e = s.read_chunk(0, [2, 2, 0]).unwrap_err().to_string();
    assert!(e.contains("m.zarr") && e.contains("c/0/2/2"), "{e}");
    let e = s.read_level(0).unwrap_err().to_string();
    assert!(e.contains("level 0"), "{e}");
}

#[test]
fn bad_metadata_is_a_clear_error() {
    let vol = sample([16, 16, 8]);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("b.zarr");
    write_volume(
        &vol,
        &p,
        &opts(ZarrFormat::V2, Compression::None),
        &|_, _| {},
    )
    .unwrap();
    let attrs = p.join(".zattrs");
    let good = std::fs::read_to_string(&attrs).unwrap();
    let cases = [
        (
            good.replace("\"path\": \"1\"", "\"path\": \"../1\""),
            "inside the store",
        ),
        (good.replace("\"path\": \"1\"", "\"path\": \"9\""), "9"),
        (
            good.replace("\"multiscales\"", "\"other\""),
            "no OME-Zarr multiscales",
        ),
        (good.replace("\"name\": \"x\"", "\"name\": \"q\""), "axes"),
        (
            good.replacen("\"scale\": [", "\"scale\": [-1, ", 1)
                .replacen("-1, 1.25", "-1", 1),
            "scale",
        ),
        ("{".to_string(), "JSON"),
    ];
    for (text, want) in cases {
        std::fs::write(&attrs, &text).unwrap();
        let e = ZarrStore::open(&p).unwrap_err().to_string();
        assert!(e.contains("b.zarr") && e.contains(want), "{want}: {e}");
    }
    // Levels out of order: the coarser one first.
    std::fs::write(
        &attrs,
        good.replace("\"path\": \"0\"", "\"path\": \"TMP\"")
            .replace("\"path\": \"1\"", "\"path\": \"0\"")
            .replace("\"path\": \"TMP\"", "\"path\": \"1\""),
    )
    .unwrap();
    let e = ZarrStore::open(&p).unwrap_err().to_string();
    assert!(e.contains("finest to coarsest"), "{e}");
    std::fs::write(&attrs, &good).unwrap();
    assert!(ZarrStore::open(&p).is_ok());
    // A stale sidecar is ignored, not trusted.
    std::fs::write(p.join("0").join(RANGES_FILE), b"VXCRNG01short").unwrap();
    let s = ZarrStore::open(&p).unwrap();
    assert!(!s.info().levels[0].has_ranges && s.info().levels[1].has_ranges);
    assert_eq!(s.chunk_range(0, [1, 1, 1]), ChunkRange::Unknown);
}

#[test]
fn a_level_is_read_by_number_and_a_missing_one_is_named() {
    let vol = sample([16, 16, 8]);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("l.zarr");
    write_volume(
        &vol,
        &p,
        &opts(ZarrFormat::V3, Compression::None),
        &|_, _| {},
    )
    .unwrap();
    let o = OpenOptions {
        level: Some(1),
        ..Default::default()
    };
    assert_eq!(read(&p, &o).unwrap().dims(), [8, 8, 4]);
    let o = OpenOptions {
        level: Some(7),
        ..Default::default()
    };
    let e = read(&p, &o).unwrap_err().to_string();
    assert!(e.contains("levels 0…1"), "{e}");
}

// The out-of-core render of a store against the in-core picture:
// tests/outofcore.rs (a unit test that renders makes the library's test
// build compile every SIMD ray loop again; see render/outofcore/mod.rs).

/// The files under `dir` as a zip file of stored (uncompressed) entries,
/// as OME-Zarr's zipped stores are written: a minimal writer (no zip64).
fn zip_stored(dir: &Path, out: &Path) {
    fn crc32(b: &[u8]) -> u32 {
        let mut c = !0u32;
        for &x in b {
            c ^= x as u32;
            for _ in 0..8 {
                c = if c & 1 == 1 {
                    (c >> 1) ^ 0xEDB8_8320
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn files(d: &Path, root: &Path, out: &mut Vec<(String, Vec<u8>)>) {
        let mut entries: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                files(&p, root, out);
            } else {
                let name = p
                    .strip_prefix(root)
                    .unwrap()
                    .to_string_lossy()
                    .replace('\\', "/");
                out.push((name, std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut list = Vec::new();
    files(dir, dir, &mut list);
    let (mut body, mut central) = (Vec::new(), Vec::new());
    let u16le = |v: &mut Vec<u8>, x: u16| v.extend_from_slice(&x.to_le_bytes());
    let u32le = |v: &mut Vec<u8>, x: u32| v.extend_from_slice(&x.to_le_bytes());
    for (name, data) in &list {
        let (crc, n, offset) = (crc32(data), data.len() as u32, body.len() as u32);
        u32le(&mut body, 0x0403_4b50);
        for x in [20, 0, 0, 0, 0] {
            u16le(&mut body, x);
        }
        for x in [crc, n, n] {
            u32le(&mut body, x);
        }
        u16le(&mut body, name.len() as u16);
        u16le(&mut body, 0);
        body.extend_from_slice(name.as_bytes());
        body.extend_from_slice(data);
        u32le(&mut central, 0x0201_4b50);
        for x in [20, 20, 0, 0, 0, 0] {
            u16le(&mut central, x);
        }
        for x in [crc, n, n] {
            u32le(&mut central, x);
        }
        for x in [name.len() as u16, 0, 0, 0, 0] {
            u16le(&mut central, x);
        }
        u32le(&mut central, 0);
        u32le(&mut central, offset);
        central.extend_from_slice(name.as_bytes());
    }
    let (cd_offset, cd_len) = (body.len() as u32, central.len() as u32);
    body.extend_from_slice(&central);
    u32le(&mut body, 0x0605_4b50);
    for x in [0, 0, list.len() as u16, list.len() as u16] {
        u16le(&mut body, x);
    }
    u32le(&mut body, cd_len);
    u32le(&mut body, cd_offset);
    u16le(&mut body, 0);
    std::fs::write(out, body).unwrap();
}

#[test]
fn a_store_in_a_zip_file_reads_as_the_folder() {
    // OME-Zarr's zipped stores (`.ozx`, or any `.zip`): the same levels,
    // voxels, chunk ranges (the sidecar) and unwritten chunks as the
    // folder the zip was made from; a zip without a store, or not a zip,
    // is a clear error.
    let vol = sample([37, 29, 23]);
    for format in [ZarrFormat::V2, ZarrFormat::V3] {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.zarr");
        write_volume(&vol, &p, &opts(format, Compression::Zstd(3)), &|_, _| {}).unwrap();
        let z = dir.path().join("s.ozx");
        zip_stored(&p, &z);
        assert!(is_zarr(&z), "{format:?}");
        assert_eq!(
            crate::io::detect(&z, &OpenOptions::default()).unwrap(),
            crate::io::Format::Zarr
        );
        let (a, b) = (ZarrStore::open(&p).unwrap(), ZarrStore::open(&z).unwrap());
        assert_eq!(a.levels(), b.levels(), "{format:?}");
        assert_eq!(b.info().zarr_format, a.info().zarr_format);
        for l in 0..a.levels().len() {
            assert_eq!(
                a.read_level(l).unwrap().data(),
                b.read_level(l).unwrap().data()
            );
        }
        assert_eq!(b.chunk_range(0, [0, 0, 0]), ChunkRange::Fill(0.0));
        assert_eq!(b.chunk_range(0, [2, 1, 3]), a.chunk_range(0, [2, 1, 3]));
        assert!(matches!(b.chunk_range(0, [2, 1, 3]), ChunkRange::Range(..)));
        assert_eq!(b.value_range(), a.value_range());
        assert!(b.bytes_read() > 0);
    }
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    std::fs::write(empty.join("readme.txt"), b"no store here").unwrap();
    let z = dir.path().join("other.zip");
    zip_stored(&empty, &z);
    assert!(!is_zarr(&z));
    let e = ZarrStore::open(&z).err().unwrap().to_string();
    assert!(e.contains("not a Zarr store") && e.contains(".ozx"), "{e}");
    let junk = dir.path().join("junk.zip");
    std::fs::write(&junk, vec![7u8; 500]).unwrap();
    let e = ZarrStore::open(&junk).err().unwrap().to_string();
    assert!(e.contains("junk.zip") && e.contains("zip"), "{e}");
}
