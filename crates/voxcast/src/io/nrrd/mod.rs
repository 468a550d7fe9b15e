//! NRRD ("nearly raw raster data", teem's format): `.nrrd` files with the
//! data attached after the blank line that ends the header, and `.nhdr`
//! detached headers that name their data file(s).
//!
//! Supported:
//! * magic `NRRD0001`…`NRRD0005`, `# comments`, `key:=value` pairs (ignored);
//! * `type:` every NRRD spelling of the eight integer and two float types.
//!   u8, u16, i16 and f32 are kept as stored; signed 8-bit becomes i16
//!   (exact); int32, uint32, int64, uint64 and double become f32, which is
//!   exact only up to 2²⁴ in magnitude (doubles beyond f32's range become ±inf);
//! * `dimension:` 3; 2 (one slice, z = 1); an axis of size 1 whose
//!   `space directions:` entry is `none` or whose `kinds:` entry is not a
//!   space kind is dropped wherever it is; without such marks a 4-D array
//!   drops its first or last axis of size 1;
//! * `sizes:`; spacing from `space directions:` (the length of each axis
//!   vector; `none` for a non-spatial axis), else from `spacings:` (`nan`
//!   on a space axis means 1, with a warning; negative or infinite is an
//!   error); `space origin:` → origin (z = 0 in a 2-D space);
//!   `sample units:` → [`Volume::units`];
//! * `encoding:` `raw`, `gzip`/`gz`, `bzip2`/`bz2`, `ascii`/`text`/`txt`; `endian:`
//!   `little`/`big` (little when absent);
//! * `line skip:` and `byte skip:` as teem applies them: lines are skipped in
//!   the file, bytes after decompression for gzip; with raw, a negative byte
//!   skip −(N+1) puts the data N bytes before the end of the file (−1: at the end);
//! * `data file:`/`datafile:` naming one file (relative to the header's
//!   folder), `LIST [subdim]` with the names on the header lines that follow,
//!   or a pattern `fmt min max step [subdim]` with one `%d`-style conversion.
//!
//! Not supported (an error naming the field): `type: block`; the `hex` and
//! encoding; other dimensions and multi-component axes; a negative
//! byte skip with gzip or ascii. Orientation is reduced to one spacing per
//! axis: rotations and axis flips in `space directions:` are not applied, the
//! volume is placed axis-aligned at `space origin:`. Raw bytes after the
//! data are ignored with a warning; gzip data longer than the header says is
//! an error (a wrong header or another format's file, e.g. a `.nii.gz`).
//!
//! Element types, bounded reading and number parsing live in
//! `io/decode.rs`, shared with the MetaImage and VTK readers.
//!
//! The parts: `header.rs` reads the header's fields (type, encoding),
//! `space.rs` turns the space fields into axes, spacing and origin,
//! `data.rs` finds the data file(s) and decodes their bytes; [`read`] puts
//! them together.

mod data;
mod header;
mod space;

use super::decode::*;
use super::util::check_dims;
use crate::error::{Error, Result};
use crate::volume::Volume;
use data::{data_files, read_chunk, DataFiles, Layout};
use glam::Vec3;
use header::{parse_encoding, parse_type, read_header, required_field, Encoding};
use space::{nrrd_origin, nrrd_spacing, spatial_axes};
use std::path::Path;

/// Reads the NRRD file (attached or detached header) at `path`.
pub fn read(path: &Path) -> Result<Volume> {
    let header = read_header(path)?;
    let required = |key: &'static str| required_field(path, &header, key);

    let dim_s = required("dimension")?;
    let dimension: usize = dim_s.parse().map_err(|_| {
        Error::format(
            path,
            "dimension",
            format!("`{dim_s}` is not a whole number"),
        )
    })?;
    let ty = parse_type(path, required("type")?)?;
    let sizes = parse_sizes(path, "sizes", required("sizes")?)?;
    if sizes.len() != dimension {
        return Err(Error::format(
            path,
            "sizes",
            format!("{} sizes given for dimension {dimension}", sizes.len()),
        ));
    }
    let spatial = spatial_axes(
        path,
        dimension,
        &sizes,
        header.get("space directions"),
        header.get("kinds"),
    )?;
    let axis_size = |axis: Option<&usize>| axis.and_then(|&a| sizes.get(a)).copied().unwrap_or(1);
    let dims = [
        axis_size(spatial.first()),
        axis_size(spatial.get(1)),
        axis_size(spatial.get(2)),
    ];
    let (count, _) = check_dims(path, "sizes", dims, ty.target())?;

    let encoding = parse_encoding(path, required("encoding")?)?;
    let big_endian = match header.get("endian").map(str::to_ascii_lowercase).as_deref() {
        None | Some("little") => false,
        Some("big") => true,
        Some(other) => {
            return Err(Error::format(
                path,
                "endian",
                format!("`{other}`: expected `little` or `big`"),
            ))
        }
    };
    let line_skip: u64 = match header.get("line skip") {
        None => 0,
        Some(s) => s.parse().map_err(|_| {
            Error::format(
                path,
                "line skip",
                format!("`{s}` is not a whole number of lines"),
            )
        })?,
    };
    let byte_skip: i64 = match header.get("byte skip") {
        None => 0,
        Some(s) => s.parse().map_err(|_| {
            Error::format(path, "byte skip", format!("`{s}` is not a whole number"))
        })?,
    };
    if byte_skip < 0 && encoding != Encoding::Raw {
        return Err(Error::unsupported(
            path,
            format!("byte skip {byte_skip} with a non-raw encoding (the data's end cannot be found without decoding everything)"),
        ));
    }

    let spacing = nrrd_spacing(
        path,
        header.get("space directions"),
        header.get("spacings"),
        dimension,
        &spatial,
    )?;
    let origin = match header.get("space origin") {
        None => Vec3::ZERO,
        Some(s) => nrrd_origin(path, s)?,
    };

    let files = data_files(path, &header)?;
    let n_files = files.len();
    let per_file = per_file_count(path, "data file", &sizes, count, n_files, files.subdim())?;
    let layout = Layout {
        ty,
        big_endian,
        encoding,
        line_skip,
        byte_skip,
    };
    let mut parts = Vec::new();
    for i in 0..n_files {
        let part = match &files {
            DataFiles::Attached => read_chunk(path, header.data_start, per_file, &layout),
            _ => {
                let file = files.path(path, i)?;
                read_chunk(&file, 0, per_file, &layout)
                    .map_err(|e| in_data_file(path, "data file", e))
            }
        }?;
        parts.push(part);
    }
    let data = concat(parts).ok_or_else(|| {
        Error::format(
            path,
            "data file",
            "the data files decoded to different types",
        )
    })?;
    let mut vol = make_volume(path, dims, spacing, origin, data)?;
    vol.units = header
        .get("sample units")
        .map(|s| s.trim_matches('"').trim().to_string())
        .filter(|s| !s.is_empty());
    Ok(vol)
}

#[cfg(test)]
mod semantics_tests;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::test_support::{err_naming, never_panics, write};
    use crate::testdata::data_path;
    use crate::volume::ScalarType;
    use flate2::write::GzEncoder;
    use flate2::Compression;
    use std::io::Write;

    /// A header and its data in one attached file.
    pub(super) fn attached(header: &str, data: &[u8]) -> Vec<u8> {
        let mut v = header.as_bytes().to_vec();
        v.push(b'\n');
        v.extend_from_slice(data);
        v
    }

    pub(super) fn gzip(data: &[u8]) -> Vec<u8> {
        let mut e = GzEncoder::new(Vec::new(), Compression::default());
        e.write_all(data).unwrap();
        e.finish().unwrap()
    }

    #[test]
    fn reads_neghip() {
        let Some(p) = data_path("neghip/neghip.nhdr") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [64, 64, 64]);
        assert_eq!(v.spacing(), Vec3::ONE);
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.scalar_type(), ScalarType::U8);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 255.0));
        // Values read from the raw file with Python, index i + 64·(j + 64·k).
        assert_eq!(v.value(10, 20, 30), 166.0);
        assert_eq!(v.value(40, 12, 50), 25.0);
        assert_eq!(v.value(30, 53, 6), 255.0);
    }

    #[test]
    fn reads_headsq() {
        let Some(p) = data_path("ct_head_headsq/headsq.nhdr") else {
            return;
        };
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [64, 64, 93]);
        assert_eq!(v.spacing(), Vec3::new(3.2, 3.2, 1.5));
        assert_eq!(v.origin(), Vec3::ZERO);
        assert_eq!(v.scalar_type(), ScalarType::U16);
        assert_eq!((v.stats().min, v.stats().max), (0.0, 3926.0));
        assert_eq!(v.value(10, 20, 30), 861.0);
        assert_eq!(v.value(40, 30, 60), 2187.0);
        assert_eq!(v.value(39, 24, 53), 3926.0);
    }

    #[test]
    fn reads_attached_with_directions_and_origin() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<u8> = (0..24).collect();
        let h = "NRRD0005\n# a comment\ntype: unsigned char\ndimension: 3\nsizes: 2 3 4\n\
                 space: left-posterior-superior\n\
                 space directions: (0.5,0,0) (0, -2, 0) (0,0,3)\n\
                 space origin: (1.5, -2, 10)\nencoding: raw\nsample units: HU\nfoo:=bar\n";
        let p = write(dir.path(), "a.nrrd", &attached(h, &data));
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [2, 3, 4]);
        assert_eq!(v.spacing(), Vec3::new(0.5, 2.0, 3.0));
        assert_eq!(v.origin(), Vec3::new(1.5, -2.0, 10.0));
        assert_eq!(v.value(1, 2, 3), 23.0);
        assert_eq!(v.units.as_deref(), Some("HU"));
    }

    #[test]
    fn reads_gzip_attached_and_detached() {
        let dir = tempfile::tempdir().unwrap();
        let vals: Vec<i16> = (0..60).map(|i| i * 100 - 3000).collect();
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let h = "NRRD0004\ntype: short\ndimension: 3\nsizes: 3 4 5\nendian: little\nencoding: gzip\nspacings: 1 2 nan\n";
        let p = write(dir.path(), "g.nrrd", &attached(h, &gzip(&raw)));
        let v = read(&p).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.spacing(), Vec3::new(1.0, 2.0, 1.0));
        assert_eq!(v.value(2, 3, 4), 2900.0);
        assert_eq!(v.stats().min, -3000.0);

        // Detached, gz spelling, with a byte skip counted in decompressed bytes.
        let mut skipped = vec![9u8; 7];
        skipped.extend_from_slice(&raw);
        write(dir.path(), "g.raw.gz", &gzip(&skipped));
        let h = "NRRD0004\ntype: int16\ndimension: 3\nsizes: 3 4 5\nendian: little\nencoding: gz\nbyte skip: 7\ndatafile: g.raw.gz\n";
        let p = write(dir.path(), "g.nhdr", h.as_bytes());
        let v = read(&p).unwrap();
        assert_eq!(v.value(2, 3, 4), 2900.0);
        assert_eq!(v.value(0, 0, 0), -3000.0);
    }

    #[test]
    fn reads_big_endian_and_converted_types() {
        let dir = tempfile::tempdir().unwrap();
        let vals: Vec<u16> = (0..8).map(|i| i * 1000 + 1).collect();
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 2 2 2\nendian: big\nencoding: raw\n";
        let v = read(&write(dir.path(), "be.nrrd", &attached(h, &raw))).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::U16);
        assert_eq!(v.value(1, 1, 1), 7001.0);

        let vals = [-5i32, 70000, 3, 4];
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        let h = "NRRD0004\ntype: int\ndimension: 2\nsizes: 2 2\nendian: big\nencoding: raw\n";
        let v = read(&write(dir.path(), "i32.nrrd", &attached(h, &raw))).unwrap();
        assert_eq!(v.dims(), [2, 2, 1]);
        assert_eq!(v.scalar_type(), ScalarType::F32);
        assert_eq!((v.stats().min, v.stats().max), (-5.0, 70000.0));

        let vals = [-1.5f64, 2.25];
        let raw: Vec<u8> = vals.iter().flat_map(|v| v.to_le_bytes()).collect();
        let h =
            "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: little\nencoding: raw\n";
        let v = read(&write(dir.path(), "f64.nrrd", &attached(h, &raw))).unwrap();
        assert_eq!(v.value(0, 0, 0), -1.5);
        assert_eq!(v.value(1, 0, 0), 2.25);

        let h = "NRRD0004\ntype: Signed  Char\ndimension: 3\nsizes: 2 1 1\nencoding: RAW\nendian: Big\n";
        let v = read(&write(dir.path(), "i8.nrrd", &attached(h, &[0xff, 0x7f]))).unwrap();
        assert_eq!(v.scalar_type(), ScalarType::I16);
        assert_eq!(v.value(0, 0, 0), -1.0);
        assert_eq!(v.value(1, 0, 0), 127.0);
    }

    #[test]
    fn reads_dimension_4_and_ascii() {
        let dir = tempfile::tempdir().unwrap();
        let h = "NRRD0004\ntype: float\ndimension: 4\nsizes: 1 2 2 1\nencoding: ascii\n\
                 space directions: none (2,0,0) (0,2,0) (0,0,2)\n";
        let p = write(dir.path(), "t.nrrd", &attached(h, b"1.5 2\n-3,4e2\n"));
        let v = read(&p).unwrap();
        assert_eq!(v.dims(), [2, 2, 1]);
        assert_eq!(v.spacing(), Vec3::splat(2.0));
        assert_eq!(v.value(1, 1, 0), 400.0);
        assert_eq!(v.value(0, 1, 0), -3.0);

        // An integer type in ascii must hold whole numbers in range.
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 1 1\nencoding: text\n";
        let p = write(dir.path(), "bad.nrrd", &attached(h, b"1 256\n"));
        err_naming(read(&p), "bad.nrrd", "256");
    }

    #[test]
    fn reads_skips_and_lists() {
        let dir = tempfile::tempdir().unwrap();
        // Line skip then byte skip, in a detached file.
        let mut f = b"junk line\nsecond\nXX".to_vec();
        f.extend(0u8..8);
        write(dir.path(), "skip.raw", &f);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nline skip: 2\nbyte skip: 2\ndata file: skip.raw\n";
        let v = read(&write(dir.path(), "skip.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 0), 0.0);
        assert_eq!(v.value(1, 1, 1), 7.0);

        // byte skip -1: the data are the last bytes of the file.
        let mut f = vec![0xAAu8; 100];
        f.extend(10u8..18);
        write(dir.path(), "end.raw", &f);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nbyte skip: -1\ndata file: end.raw\n";
        let v = read(&write(dir.path(), "end.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 0), 10.0);
        assert_eq!(v.value(1, 1, 1), 17.0);

        // LIST: one slice per file; and the same as a pattern.
        write(dir.path(), "s1.raw", &[1, 2, 3, 4]);
        write(dir.path(), "s2.raw", &[5, 6, 7, 8]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: LIST\ns1.raw\ns2.raw\n";
        let v = read(&write(dir.path(), "list.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(0, 0, 1), 5.0);
        assert_eq!(v.value(1, 1, 1), 8.0);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: s%d.raw 1 2 1 2\n";
        let v = read(&write(dir.path(), "pat.nhdr", h.as_bytes())).unwrap();
        assert_eq!(v.value(1, 1, 1), 8.0);
        assert_eq!(
            format_index("slice%03d.raw", 7).as_deref(),
            Some("slice007.raw")
        );
        assert_eq!(format_index("a%%%4i", -3).as_deref(), Some("a%  -3"));
        assert_eq!(format_index("%s", 1), None);
    }

    #[test]
    fn bad_sizes_are_errors_naming_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let data = [0u8; 64];
        let cases = [
            ("sizes: 4 4 0", "at least 1"),
            ("sizes: 4 -4 4", "negative"),
            ("sizes: 4 four 4", "not a whole number"),
            ("sizes: 4294967296 4294967296 4294967296", "more than"),
            ("sizes: 99999999999999999999999 1 1", "too large"),
            ("sizes: 4 4", "2 sizes"),
            ("sizes: 4 4 8", "truncated"),
        ];
        for (i, (sizes, why)) in cases.iter().enumerate() {
            let h = format!("NRRD0004\ntype: uchar\ndimension: 3\n{sizes}\nencoding: raw\n");
            let name = format!("bad{i}.nrrd");
            let p = write(dir.path(), &name, &attached(&h, &data));
            let s = err_naming(read(&p), &name, "sizes");
            assert!(s.contains(why), "{sizes}: {s}");
        }
    }

    #[test]
    fn truncated_and_lying_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        // Detached data file one byte short: the error names the header, the field and the data file.
        write(dir.path(), "short.raw", &[0u8; 63]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: short.raw\n";
        let p = write(dir.path(), "short.nhdr", h.as_bytes());
        let s = err_naming(read(&p), "short.nhdr", "sizes");
        assert!(s.contains("short.raw"), "{s}");

        // A 1 KB file claiming 10⁹ voxels, raw and gzip: refused before allocating.
        for enc in ["raw", "gzip"] {
            let h = format!(
                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1000 1000 1000\nencoding: {enc}\n"
            );
            let name = format!("huge_{enc}.nrrd");
            let p = write(dir.path(), &name, &attached(&h, &[0u8; 1024]));
            let s = err_naming(read(&p), &name, "sizes");
            assert!(s.contains("1000000000"), "{s}");
        }

        // Gzip stream cut short.
        let z = gzip(&[7u8; 4096]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 16 16 16\nencoding: gzip\n";
        let p = write(dir.path(), "cut.nrrd", &attached(h, &z[..z.len() / 2]));
        err_naming(read(&p), "cut.nrrd", "sizes");

        // Too few ascii values.
        let h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n";
        let p = write(dir.path(), "few.nrrd", &attached(h, b"1 2 3\n"));
        err_naming(read(&p), "few.nrrd", "sizes");
    }

    #[test]
    fn unknown_and_unsupported_fields_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            ("type: complex", "encoding: raw", "type"),
            ("type: block", "encoding: raw", "type"),
            ("type: uchar", "encoding: hex", "encoding"),
            ("type: uchar", "encoding: rot13", "encoding"),
            ("type: uchar", "encoding: raw\nendian: middle", "endian"),
            ("type: uchar", "encoding: raw\nspacings: 1 0 1", "spacings"),
            (
                "type: uchar",
                "encoding: raw\nspace directions: (1,0,0) (0,1,0)",
                "space directions",
            ),
            (
                "type: uchar",
                "encoding: raw\nspace origin: 1 2 3",
                "space origin",
            ),
            ("type: uchar", "encoding: raw\nbyte skip: many", "byte skip"),
            ("type: uchar", "encoding: raw\nencoding: raw", "encoding"),
            ("type: uchar", "encoding: gzip\nbyte skip: -1", "byte skip"),
        ];
        for (i, (ty, enc, field)) in cases.iter().enumerate() {
            let h = format!("NRRD0004\n{ty}\ndimension: 3\nsizes: 2 2 2\n{enc}\n");
            let name = format!("f{i}.nrrd");
            let p = write(dir.path(), &name, &attached(&h, &[0u8; 8]));
            err_naming(read(&p), &name, field);
        }
        let p = write(
            dir.path(),
            "nodim.nrrd",
            &attached("NRRD0004\ntype: uchar\nsizes: 2\nencoding: raw\n", &[0]),
        );
        err_naming(read(&p), "nodim.nrrd", "dimension");
        let p = write(
            dir.path(),
            "d5.nrrd",
            &attached(
                "NRRD0004\ntype: uchar\ndimension: 5\nsizes: 1 1 1 1 1\nencoding: raw\n",
                &[0],
            ),
        );
        err_naming(read(&p), "d5.nrrd", "dimension 5");
        let p = write(
            dir.path(),
            "rgb.nrrd",
            &attached(
                "NRRD0004\ntype: uchar\ndimension: 4\nsizes: 3 2 2 2\nencoding: raw\n",
                &[0; 24],
            ),
        );
        err_naming(read(&p), "rgb.nrrd", "dimension 4");
        let p = write(dir.path(), "nomagic.nrrd", b"P5\n2 2\n255\n\0\0\0\0");
        err_naming(read(&p), "nomagic.nrrd", "magic");
        let p = write(dir.path(), "binary.nrrd", &[0xffu8; 300]);
        err_naming(read(&p), "binary.nrrd", "magic");
    }

    #[test]
    fn missing_data_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: nowhere.raw\n";
        let p = write(dir.path(), "lost.nhdr", h.as_bytes());
        let s = err_naming(read(&p), "lost.nhdr", "data file");
        assert!(s.contains("nowhere.raw"), "{s}");
        // A LIST whose files do not split the volume evenly.
        write(dir.path(), "a.raw", &[0; 8]);
        let h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\ndata file: LIST\na.raw\na.raw\na.raw\n";
        let p = write(dir.path(), "list3.nhdr", h.as_bytes());
        err_naming(read(&p), "list3.nhdr", "data file");
    }

    #[test]
    fn mutated_files_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let raw: Vec<u8> = (0..16u16).flat_map(|v| v.to_be_bytes()).collect();
        let h = "NRRD0004\ntype: ushort\ndimension: 3\nsizes: 2 2 4\nendian: big\nencoding: gzip\n\
                 space directions: (1,0,0) (0,1,0) (0,0,2)\nspace origin: (1,2,3)\nbyte skip: 0\n";
        never_panics(
            read,
            dir.path(),
            "m.nrrd",
            &attached(h, &gzip(&raw)),
            h.len(),
        );
        let h = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 2\nencoding: ascii\nspacings: 1 nan 2\nline skip: 0\n";
        never_panics(
            read,
            dir.path(),
            "t.nrrd",
            &attached(h, b"1 2.5\n-3 4\n"),
            h.len(),
        );
        write(dir.path(), "p1.raw", &[1, 2]);
        write(dir.path(), "p2.raw", &[3, 4]);
        let h = b"NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\nencoding: raw\ndata file: p%d.raw 1 2 1\n";
        never_panics(read, dir.path(), "p.nhdr", h, h.len());
        let h = b"NRRD0004\ntype: uchar\ndimension: 4\nsizes: 1 2 1 2\nencoding: raw\nbyte skip: -1\ndata file: LIST 3\np1.raw\np2.raw\n";
        never_panics(read, dir.path(), "l.nhdr", h, h.len());
    }
}
