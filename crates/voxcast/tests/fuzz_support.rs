//! The fuzz targets' entry point (`voxcast::fuzz_support::run`) reaches
//! each reader, loader and the out-of-core render (a test that renders is
//! an integration test, not a unit test of the library: see
//! `render/outofcore/mod.rs`). The fuzzers' regressions are
//! `fuzz_regressions.rs`.

use std::path::PathBuf;
use voxcast::fuzz_support::{join_parts, run, Outcome, Target};

fn oks(v: &[Outcome]) -> usize {
    v.iter().filter(|o| o.is_ok()).count()
}

#[test]
fn a_zarr_store_reaches_the_reader_and_lying_chunks_are_refused() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz-regressions/zarr");
    let input = |name: &str| std::fs::read(dir.join(name)).unwrap();
    for (name, read) in [
        ("seed-v3_gzip_two_levels", "[4, 4, 4] U8"),
        ("seed-v2_u16", "[5, 4, 3] U16"),
        // Written by `voxcast convert builtin:fractal --dims 12,10,8
        // --type u16 --chunk 4 --levels 2 --compression zstd|blosc`.
        ("seed-v3_zstd_converted", "[12, 10, 8] U16"),
        ("seed-v3_blosc_converted", "[12, 10, 8] U16"),
    ] {
        let out = run(Target::Zarr, &input(name));
        assert!(out.iter().all(|o| o.is_ok()), "{name}: {out:?}");
        // Summary, then ranges and voxels of chunks, then the volume,
        // then the out-of-core render of the coarsest level.
        assert!(out.len() >= 5, "{name}: {out:?}");
        let volume = out[out.len() - 2].as_ref().unwrap();
        assert_eq!(volume, read, "{name}");
        let render = out.last().unwrap().as_ref().unwrap();
        assert!(render.contains(": 8×6 image"), "{name}: {render}");
        assert!(!render.contains(" 0 bytes read"), "{name}: {render}");
    }
    let bad = run(Target::Zarr, &input("hostile-chunk-product-overflows"));
    assert_eq!(bad.len(), 1, "{bad:?}");
    let e = bad[0].as_ref().unwrap_err().to_string();
    assert!(e.contains("over 2⁶⁴") && e.contains("4 GiB"), "{e}");
    for name in [
        "hostile-shape-of-exabytes",
        "hostile-ranges-sidecar-count-overflows",
    ] {
        let bad = run(Target::Zarr, &input(name));
        let e = bad[0].as_ref().unwrap_err().to_string();
        assert!(e.contains("up to 2³² chunks"), "{name}: {e}");
    }
    // 2³⁰ chunks of 256³, none stored: it opens, its chunks read as
    // the fill value, and the volume is not read whole.
    let fill = run(Target::Zarr, &input("hostile-sixteen-petabytes-of-fill"));
    assert!(fill.iter().all(|o| o.is_ok()), "{fill:?}");
    let chunks = fill
        .iter()
        .flatten()
        .filter(|o| o.contains("16777216 voxels"));
    assert_eq!(chunks.count(), 3, "{fill:?}");
    let render = fill.last().unwrap().as_ref().unwrap();
    assert_eq!(render, "no level small enough to render");
    // A garbled zstd chunk and a truncated blosc one, in the coarsest
    // level: reading that chunk and the render each fail naming the
    // chunk file and the codec's complaint; the other chunks read.
    for (name, why) in [
        ("hostile-zstd-chunk-bytes-garbled", "Data corruption"),
        ("hostile-blosc-chunk-truncated", "blosc"),
    ] {
        let out = run(Target::Zarr, &input(name));
        let errs: Vec<String> = out
            .iter()
            .filter_map(|o| o.as_ref().err().map(|e| e.to_string()))
            .collect();
        assert_eq!(errs.len(), 2, "{name}: {out:?}");
        for e in &errs {
            assert!(
                e.contains("chunk file 1/c/0/0/0") && e.contains(why),
                "{name}: {e}"
            );
        }
        assert!(out.last().unwrap().is_err(), "{name}: the render fails");
        assert!(oks(&out) >= 10, "{name}: {out:?}");
    }
}

#[test]
fn detached_nrrd_reaches_the_reader() {
    let h = b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 1\nencoding: raw\ndata file: d.raw\n";
    let ok = run(Target::Nrrd, &join_parts(h, &[("d.raw", &[1, 2, 3, 4])]));
    assert_eq!(oks(&ok), 1, "{ok:?}");
    let missing = run(Target::Nrrd, h);
    assert!(missing[0]
        .as_ref()
        .unwrap_err()
        .to_string()
        .contains("d.raw"));
}

#[test]
fn raw_layout_from_the_first_bytes() {
    let mut b = Vec::new();
    for d in [2u64, 1, 1] {
        b.extend_from_slice(&d.to_le_bytes());
    }
    b.extend_from_slice(&[1, 0]); // u16, little endian
    b.extend_from_slice(&0u64.to_le_bytes());
    b.extend_from_slice(&[7, 0, 9, 0]);
    let r = run(Target::Raw, &b);
    assert_eq!(r[0].as_ref().unwrap(), "[2, 1, 1] U16");
    assert!(run(
        Target::Raw,
        &b[..voxcast::fuzz_support::RAW_LAYOUT_BYTES - 1]
    )
    .is_empty());
}

#[test]
fn obj_and_tf_reach_their_loaders() {
    let r = run(Target::Obj, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_eq!(oks(&r), 1, "{r:?}");
    let r = run(
        Target::Tf,
        b"color = [[0.0, 0, 0, 0]]\nopacity = [[0.0, 0.5]]\n",
    );
    assert_eq!(oks(&r), 1, "{r:?}");
    let r = run(Target::Scene, b"[render]\nwidth = 640\nheight = 480\n");
    assert_eq!(r[0].as_ref().unwrap(), "8×8 image");
}
