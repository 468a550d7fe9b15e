//! Entry points for the fuzz targets in `fuzz/` and for the regression
//! tests of the inputs they found (`tests/fuzz_regressions.rs`).
//!
//! The readers take paths, so each entry writes the fuzz input to files in a
//! fresh scratch folder (under `/dev/shm` when it exists) with the names the
//! reader expects, and calls the real reader on them. Bad input must come
//! back as `Err`; a panic, an abort, a huge allocation or a hang is a bug.
//!
//! # Input layout
//!
//! One input can hold several files, for the formats whose header names
//! other files (NRRD/MetaImage detached data, NIfTI `.hdr` + `.img`, an FDS
//! `.smv` with its data files, a folder of DICOM or PNG/TIFF slices, a scene
//! with its transfer function, geometry and meshes):
//!
//! ```text
//! <main file bytes>
//! [FILE_MARKER <name> \n <bytes>]...
//! ```
//!
//! The main file gets the name the target gives it (e.g. `v.nhdr`); each
//! further part is written under `<name>`, made safe for a file name
//! (characters other than `A-Z a-z 0-9 . _ -` become `_`; an empty, `.` or
//! `..` name, or one taken already, becomes `part<k>`). The Zarr target's
//! names are paths inside the store (`0/c/0/0/0`; see [`Target::Zarr`]).
//! The raw target starts with a 34-byte layout instead (see
//! [`Target::Raw`]).

use crate::camera::CameraParams;
use crate::error::Result;
use crate::geometry::file::GeometryDef;
use crate::geometry::Geometry;
use crate::io::{self, OpenOptions, RawLayout};
use crate::render::RenderParams;
use crate::scene::Scene;
use crate::transfer::{Lut, TransferFunction};
use crate::volume::{ScalarType, Volume, VoxelData};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Separates the files of one input (see the module documentation).
pub const FILE_MARKER: &[u8] = b"\n%%voxcast-fuzz-file ";

/// Size of the layout that starts a [`Target::Raw`] input.
pub const RAW_LAYOUT_BYTES: usize = 34;

/// What an input is fed to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Target {
    /// `io::open` on `v.nrrd` (one part) or `v.nhdr` (with data files).
    Nrrd,
    /// `io::open` on `m.mha` (one part) or `m.mhd` (with data files).
    MetaImage,
    /// `io::open` on `v.vtk`.
    Vtk,
    /// `io::open` on `v.nii` / `v.nii.gz` (by the gzip magic), or `v.hdr`
    /// when the input has more parts (the `.img`).
    Nifti,
    /// `io::open` on a folder holding the main part as `0.dcm` and the
    /// other parts, and on `0.dcm` itself.
    Dicom,
    /// `io::open` on `s0000.png` (or `.tif` by the TIFF magic) and, with
    /// more parts, on the folder of slices.
    ImageStack,
    /// `io::open` on `v.vdb`.
    Vdb,
    /// An FDS case: `case.smv` and its data files; `parse_smv`, the summary
    /// (scans every data file), `fds::times` and `io::open` for the
    /// default quantity and for up to four named ones, at the last and the
    /// first time.
    Fds,
    /// One SMOKE3D `.s3d` file: `s3d_times` and `read_s3d_frame` (last
    /// frame and t = 0).
    FdsS3d,
    /// One PLOT3D `.q` file read as a mesh of the node dims in its own
    /// header (or 51×31×26 when those are not a valid mesh), every
    /// variable; the same for `read_xyz_iblank`.
    FdsQ,
    /// One 3D slice `.sf` file: `read_sf_frame` (last frame and t = 0).
    FdsSf,
    /// `io::open` on `v.vol` (Mitsuba).
    MitsubaVol,
    /// Raw voxels: the first [`RAW_LAYOUT_BYTES`] bytes are the layout
    /// (dims x, y, z as u64 LE; type u8/u16/i16/f32 by byte 24 mod 4; big
    /// endian when byte 25 is odd; header bytes as u64 LE), the rest is
    /// the file `v.raw`.
    Raw,
    /// `Scene::load` on `scene.toml`; when it loads, the scene is prepared
    /// with a small built-in volume (transfer function and geometry files
    /// resolved) and rendered at no more than 8×8 pixels.
    Scene,
    /// `TransferFunction::from_toml_file` on `tf.toml`; when it loads, it
    /// is baked into a LUT and evaluated.
    Tf,
    /// `Geometry::load` on `geometry.toml` (meshes from the other parts);
    /// when it loads, rays are cast at it.
    Geometry,
    /// An OBJ mesh `mesh.obj` as a geometry file's mesh; when it loads,
    /// rays are cast at it.
    Obj,
    /// An OME-Zarr / Zarr store, the folder `s.zarr`: the main part is its
    /// root `zarr.json` (`.zgroup` where it says `"zarr_format": 2`), the
    /// other parts its files under their paths in the store (`0/zarr.json`,
    /// `0/c/0/0/0`, `0/.zarray`, `0/0.0.0`…; each component made safe, as
    /// a part's name). `ZarrStore::open` and its summary; per level the
    /// first chunks' value ranges and voxels (chunks of up to
    /// [`ZARR_READ_LIMIT`] bytes decoded: the reader takes chunks of up to
    /// 4 GiB); `io::open` where level 0 is within that limit too; and a
    /// tiny out-of-core render of the coarsest level of at most
    /// [`ZARR_RENDER_CHUNKS`] such chunks, under a budget of three.
    Zarr,
}

/// The largest chunk or level (decoded bytes) the [`Target::Zarr`] input
/// has read: a store may rightly claim gigabytes of fill value in a few
/// bytes of metadata, which is not a bug to find.
pub const ZARR_READ_LIMIT: u64 = 64 << 20;

/// The most chunks of a Zarr level the fuzz target renders through the
/// out-of-core renderer (a store may claim 2³² chunks of fill value, which
/// the renderer would visit one by one).
pub const ZARR_RENDER_CHUNKS: u64 = 4096;

impl Target {
    /// Every target, in the order `fuzz/run.sh` runs them.
    pub const ALL: [Target; 18] = [
        Target::Nrrd,
        Target::MetaImage,
        Target::Vtk,
        Target::Nifti,
        Target::ImageStack,
        Target::FdsS3d,
        Target::FdsQ,
        Target::FdsSf,
        Target::Fds,
        Target::MitsubaVol,
        Target::Raw,
        Target::Scene,
        Target::Tf,
        Target::Geometry,
        Target::Obj,
        Target::Vdb,
        Target::Zarr,
        // Last: its reader is being rewritten.
        Target::Dicom,
    ];

    /// The fuzz target's name (`fuzz/fuzz_targets/<name>.rs`).
    pub fn name(self) -> &'static str {
        match self {
            Target::Nrrd => "nrrd",
            Target::MetaImage => "metaimage",
            Target::Vtk => "vtk",
            Target::Nifti => "nifti",
            Target::Dicom => "dicom",
            Target::ImageStack => "image_stack",
            Target::Vdb => "vdb",
            Target::Fds => "fds",
            Target::FdsS3d => "fds_s3d",
            Target::FdsQ => "fds_q",
            Target::FdsSf => "fds_sf",
            Target::MitsubaVol => "mitsuba_vol",
            Target::Raw => "raw",
            Target::Scene => "scene",
            Target::Tf => "tf",
            Target::Geometry => "geometry",
            Target::Obj => "obj",
            Target::Zarr => "zarr",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// What one call of a reader gave: a short description of what was read,
/// or the error.
pub type Outcome = Result<String>;

/// Runs `bytes` through `target`; one outcome per reader call.
pub fn run(target: Target, bytes: &[u8]) -> Vec<Outcome> {
    let dir = Scratch::new();
    let mut out = Vec::new();
    match target {
        Target::Raw => {
            let Some((layout, data)) = raw_layout(bytes) else {
                return out;
            };
            let p = dir.write("v.raw", data);
            let opts = OpenOptions {
                raw: Some(layout),
                ..Default::default()
            };
            out.push(io::open(&p, &opts).map(describe));
        }
        Target::FdsS3d => {
            let p = dir.write("v.s3d", bytes);
            out.push(io::fds::s3d_times(&p).map(|t| format!("{} frames", t.len())));
            for time in [None, Some(0.0)] {
                out.push(
                    io::fds::read_s3d_frame(&p, time)
                        .map(|f| format!("frame {} {:?}", f.index, f.dims)),
                );
            }
        }
        Target::FdsQ => {
            let p = dir.write("v.q", bytes);
            let dims = plot3d_dims(bytes);
            for n in 0..5 {
                out.push(
                    io::fds::read_q_variable(&p, dims, n).map(|v| format!("{} values", v.len())),
                );
            }
            out.push(io::fds::read_xyz_iblank(&p, dims).map(|v| format!("{} iblank", v.len())));
        }
        Target::FdsSf => {
            let p = dir.write("v.sf", bytes);
            for time in [None, Some(0.0)] {
                out.push(
                    io::fds::read_sf_frame(&p, time)
                        .map(|f| format!("{} values at {}", f.values.len(), f.time)),
                );
            }
        }
        Target::Fds => {
            let p = dir.write_parts(bytes, |_| "case.smv".into());
            fds_case(&p, &mut out);
        }
        Target::Scene => {
            let p = dir.write_parts(bytes, |_| "scene.toml".into());
            out.push(scene(&p));
        }
        Target::Tf => {
            let p = dir.write("tf.toml", bytes);
            out.push(TransferFunction::from_toml_file(&p).map(|tf| exercise_tf(&tf)));
        }
        Target::Geometry => {
            let p = dir.write_parts(bytes, |_| "geometry.toml".into());
            out.push(Geometry::load(&p).map(|g| exercise_geometry(&g)));
        }
        Target::Obj => {
            let p = dir.write("mesh.obj", bytes);
            let def: GeometryDef = toml::from_str("[[mesh]]\npath = \"mesh.obj\"\n")
                .expect("a fixed, valid geometry table");
            out.push(Geometry::from_def(&def, dir.path(), &p).map(|g| exercise_geometry(&g)));
        }
        Target::Dicom => {
            let p = dir.write_parts(bytes, |_| "0.dcm".into());
            out.push(io::open(dir.path(), &OpenOptions::default()).map(describe));
            out.push(io::open(&p, &OpenOptions::default()).map(describe));
        }
        Target::ImageStack => {
            let (_, parts) = split_parts(bytes);
            let p = dir.write_parts(bytes, |m| {
                if m.starts_with(b"II*\0") || m.starts_with(b"MM\0*") {
                    "s0000.tif".into()
                } else {
                    "s0000.png".into()
                }
            });
            out.push(io::open(&p, &OpenOptions::default()).map(describe));
            if !parts.is_empty() {
                out.push(io::open(dir.path(), &OpenOptions::default()).map(describe));
            }
        }
        Target::Zarr => {
            let root = dir.write_tree(bytes, "s.zarr", |m| {
                let v2 = find(m, b"\"zarr_format\": 2").is_some()
                    || find(m, b"\"zarr_format\":2").is_some();
                if v2 { ".zgroup" } else { "zarr.json" }.into()
            });
            zarr_store(&root, &mut out);
        }
        Target::Nrrd
        | Target::MetaImage
        | Target::Vtk
        | Target::Nifti
        | Target::Vdb
        | Target::MitsubaVol => {
            let p = dir.write_parts(bytes, |m| main_name(target, m, bytes.len() > m.len()));
            out.push(io::open(&p, &OpenOptions::default()).map(describe));
        }
    }
    out
}

/// The main file's name for the single-volume targets; `more`: the input
/// has other parts.
fn main_name(target: Target, main: &[u8], more: bool) -> String {
    match target {
        Target::Nrrd if more => "v.nhdr",
        Target::Nrrd => "v.nrrd",
        Target::MetaImage if more => "m.mhd",
        Target::MetaImage => "m.mha",
        Target::Vtk => "v.vtk",
        Target::Nifti if more => "v.hdr",
        Target::Nifti if main.starts_with(&[0x1f, 0x8b]) => "v.nii.gz",
        Target::Nifti => "v.nii",
        Target::Vdb => "v.vdb",
        _ => "v.vol",
    }
    .into()
}

fn describe(v: Volume) -> String {
    format!("{:?} {:?}", v.dims(), v.scalar_type())
}

/// A part of an input: its name and its bytes.
pub type Part<'a> = (&'a [u8], &'a [u8]);

/// Splits an input into its main file and its named parts.
pub fn split_parts(bytes: &[u8]) -> (&[u8], Vec<Part<'_>>) {
    let mut cuts = Vec::new();
    let mut i = 0;
    while let Some(k) = find(&bytes[i..], FILE_MARKER) {
        cuts.push(i + k);
        i += k + FILE_MARKER.len();
    }
    let main = &bytes[..cuts.first().copied().unwrap_or(bytes.len())];
    let mut parts = Vec::new();
    for (j, &c) in cuts.iter().enumerate() {
        let end = cuts.get(j + 1).copied().unwrap_or(bytes.len());
        let body = &bytes[c + FILE_MARKER.len()..end];
        let nl = body.iter().position(|&b| b == b'\n').unwrap_or(body.len());
        let data = body.get(nl + 1..).unwrap_or(&[]);
        parts.push((&body[..nl], data));
    }
    (main, parts)
}

/// Joins a main file and named parts into one input (the inverse of
/// [`split_parts`]), e.g. to build a seed.
pub fn join_parts(main: &[u8], parts: &[(&str, &[u8])]) -> Vec<u8> {
    let mut v = main.to_vec();
    for (name, data) in parts {
        v.extend_from_slice(FILE_MARKER);
        v.extend_from_slice(name.as_bytes());
        v.push(b'\n');
        v.extend_from_slice(data);
    }
    v
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// A file name from fuzz bytes: at most 64 safe characters.
fn safe_name(raw: &[u8]) -> String {
    raw.iter()
        .take(64)
        .map(|&b| {
            if b.is_ascii_alphanumeric() || b == b'.' || b == b'_' || b == b'-' {
                b as char
            } else {
                '_'
            }
        })
        .collect()
}

fn raw_layout(bytes: &[u8]) -> Option<(RawLayout, &[u8])> {
    if bytes.len() < RAW_LAYOUT_BYTES {
        return None;
    }
    let u64_at = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().expect("8 bytes"));
    let scalar_type = match bytes[24] % 4 {
        0 => ScalarType::U8,
        1 => ScalarType::U16,
        2 => ScalarType::I16,
        _ => ScalarType::F32,
    };
    Some((
        RawLayout {
            dims: [u64_at(0), u64_at(8), u64_at(16)],
            scalar_type,
            big_endian: bytes[25] % 2 == 1,
            header_bytes: u64_at(26),
        },
        &bytes[RAW_LAYOUT_BYTES..],
    ))
}

/// The node dims a PLOT3D header gives, when they make a mesh the `.smv`
/// parser accepts; else those of the test case.
fn plot3d_dims(bytes: &[u8]) -> [usize; 3] {
    let i32_at = |o: usize| {
        bytes
            .get(o..o + 4)
            .map(|b| i32::from_le_bytes(b.try_into().expect("4 bytes")))
    };
    let d = [i32_at(4), i32_at(8), i32_at(12)];
    if let [Some(x), Some(y), Some(z)] = d {
        let ok = [x, y, z].iter().all(|&n| (2..=(1 << 20) + 1).contains(&n));
        if ok && crate::volume::checked_voxel_count([x as u64, y as u64, z as u64]).is_ok() {
            return [x as usize, y as usize, z as usize];
        }
    }
    [51, 31, 26]
}

fn fds_case(p: &Path, out: &mut Vec<Outcome>) {
    let smv = match io::fds::parse_smv(p) {
        Ok(s) => s,
        Err(e) => {
            out.push(Err(e));
            return;
        }
    };
    out.push(Ok(smv.summary().join("\n")));
    out.push(Ok(exercise_geometry(&Geometry::from_fds(&smv, p))));
    let mut vars = vec![None];
    vars.extend(io::fds::quantities(&smv).into_iter().take(4).map(Some));
    for var in vars {
        let mut opts = OpenOptions {
            variable: var,
            ..Default::default()
        };
        out.push(io::fds::times(p, &opts).map(|t| format!("{} times", t.len())));
        out.push(io::open(p, &opts).map(describe));
        opts.time = Some(0.0);
        out.push(io::open(p, &opts).map(describe));
    }
}

/// Opens the store at `p`, its summary; per level the first chunks' ranges
/// and voxels; the whole volume where level 0 is small.
fn zarr_store(p: &Path, out: &mut Vec<Outcome>) {
    use crate::volume::chunked::ChunkedSource;
    let store = match io::zarr::ZarrStore::open(p) {
        Ok(s) => s,
        Err(e) => {
            out.push(Err(e));
            return;
        }
    };
    out.push(Ok(store.summary().join("\n")));
    let ty = store.scalar_type();
    for (i, l) in store.levels().iter().enumerate() {
        for k in 0..l.chunk_total().unwrap_or(u64::MAX).min(3) {
            let c = l.chunk_at(k);
            out.push(Ok(format!("{:?}", store.chunk_range(i, c))));
            if l.chunk_bytes(ty) <= ZARR_READ_LIMIT {
                out.push(
                    store
                        .read_chunk(i, c)
                        .map(|d| format!("level {i} chunk {c:?}: {} voxels", d.len())),
                );
            }
        }
    }
    if store.levels()[0].bytes(ty) <= ZARR_READ_LIMIT {
        out.push(io::open(p, &OpenOptions::default()).map(describe));
    }
    out.push(zarr_render(&store));
}

/// Renders the coarsest level of `store` that has at most
/// [`ZARR_RENDER_CHUNKS`] chunks of at most [`ZARR_READ_LIMIT`] bytes
/// through the out-of-core renderer: a tiny image, shaded (bricks with a
/// border), under a budget of a few chunks, so chunks are read, evicted and
/// read again.
fn zarr_render(store: &io::zarr::ZarrStore) -> Outcome {
    use crate::render::outofcore::{render_chunked, OutOfCoreParams};
    use crate::volume::chunked::ChunkedSource;
    let ty = store.scalar_type();
    let levels = store.levels();
    let Some(level) = (0..levels.len()).rev().find(|&i| {
        let l = &levels[i];
        l.chunk_total().is_some_and(|n| n <= ZARR_RENDER_CHUNKS)
            && l.chunk_bytes(ty) <= ZARR_READ_LIMIT
    }) else {
        return Ok("no level small enough to render".into());
    };
    let chunk = levels[level].chunk_bytes(ty);
    let ooc = OutOfCoreParams {
        budget: chunk.saturating_mul(3).max(1 << 16),
        level: Some(level),
        lod_scale: 1.0,
        prefetch: false,
        resident_only: false,
    };
    let params = RenderParams {
        width: 8,
        height: 6,
        shading: true,
        ..Default::default()
    };
    let tf = TransferFunction::preset("grayscale").expect("the grayscale preset");
    let window = store.value_range().unwrap_or([0.0, 255.0]);
    let (img, _, st) = render_chunked(
        store,
        &tf,
        window,
        &CameraParams::default(),
        &params,
        &ooc,
        &|_, _| {},
        &std::sync::atomic::AtomicBool::new(false),
    )?;
    let sum: f32 = img.pixels.iter().map(|p| p[0] + p[3]).sum();
    Ok(format!(
        "level {level}: {}×{} image, sum {sum}, {} bytes read",
        img.width, img.height, st.bytes_read
    ))
}

/// Bakes and evaluates a transfer function the way a render does.
fn exercise_tf(tf: &TransferFunction) -> String {
    let vol = tiny_volume();
    let window = tf.window_for(&vol, None);
    let lut = Lut::new(tf, 0.5);
    let mut acc = 0.0f32;
    for i in 0..=16 {
        let v = i as f32 / 16.0;
        acc += tf.color_at(v)[0] + tf.opacity_at(v) + tf.max_opacity_in(0.0, v);
        acc += tf.min_opacity_in(v, 1.0);
        if let Some(k) = Lut::index(v) {
            acc += lut.entry(k)[3] + lut.sigma(k);
        }
    }
    format!("window {window:?}, sum {acc}")
}

/// Casts a fan of rays at `g` through its bounds.
fn exercise_geometry(g: &Geometry) -> String {
    let (lo, hi) = g.bounds().unwrap_or((Vec3::splat(-1.0), Vec3::ONE));
    let c = (lo + hi) * 0.5;
    let r = (hi - lo).length().max(1.0);
    let mut hits = 0;
    for k in 0..16 {
        let a = k as f32 * 0.7;
        let d = Vec3::new(a.cos(), (a * 1.3).sin(), (a * 0.4).cos()).normalize();
        let o = c - d * 2.0 * r;
        if g.hit(o, d, 0.0, 4.0 * r).is_some() {
            hits += 1;
        }
        if g.occluded(o, d, 0.0, 4.0 * r) {
            hits += 1;
        }
    }
    format!("{} ({hits} hits)", g.describe())
}

/// A small volume with a ramp of values, standing in for the scene's input.
fn tiny_volume() -> Volume {
    let data: Vec<u8> = (0..64u32).map(|i| (i * 4) as u8).collect();
    Volume::new([4, 4, 4], Vec3::ONE, Vec3::ZERO, VoxelData::U8(data.into()))
        .expect("a 4×4×4 volume with 64 voxels")
}

fn scene(p: &Path) -> Outcome {
    let mut s = Scene::load(p)?;
    s.render.width = s.render.width.min(8);
    s.render.height = s.render.height.min(8);
    s.render.spp = s.render.spp.min(4);
    let prepared = s.prepare_with(tiny_volume())?;
    let (img, _) = s.render(&prepared, &|_, _| {})?;
    Ok(format!("{}×{} image", img.width, img.height))
}

/// A fresh scratch folder, removed when dropped.
struct Scratch {
    dir: PathBuf,
}

static SCRATCH_COUNT: AtomicU64 = AtomicU64::new(0);

impl Scratch {
    fn new() -> Scratch {
        let shm = Path::new("/dev/shm");
        let base = if shm.is_dir() {
            shm.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let k = SCRATCH_COUNT.fetch_add(1, Ordering::Relaxed);
        let dir = base.join(format!("voxcast-fuzz-{}-{k}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir)
            .unwrap_or_else(|e| panic!("cannot make the scratch folder {}: {e}", dir.display()));
        Scratch { dir }
    }

    fn path(&self) -> &Path {
        &self.dir
    }

    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let p = self.dir.join(name);
        std::fs::write(&p, bytes)
            .unwrap_or_else(|e| panic!("cannot write the scratch file {}: {e}", p.display()));
        p
    }

    /// Writes the main part under the name `main_name` gives it and the
    /// other parts under their own; returns the main file's path.
    fn write_parts(&self, bytes: &[u8], main_name: impl Fn(&[u8]) -> String) -> PathBuf {
        let (main, parts) = split_parts(bytes);
        let main_name = main_name(main);
        let mut taken = vec![main_name.clone()];
        for (k, (name, data)) in parts.into_iter().enumerate() {
            let mut n = safe_name(name);
            if n.is_empty() || n == "." || n == ".." || taken.contains(&n) {
                n = format!("part{k}");
            }
            self.write(&n, data);
            taken.push(n);
        }
        self.write(&main_name, main)
    }

    /// Writes the input as the folder `root` (a store): the main part as
    /// `root/<main_name>`, the other parts under their relative paths
    /// (`/`-separated, at most 8 deep, each component made safe; a part
    /// whose path is unusable, or collides with another's, is left out).
    /// Returns the folder's path.
    fn write_tree(&self, bytes: &[u8], root: &str, main_name: impl Fn(&[u8]) -> String) -> PathBuf {
        let (main, parts) = split_parts(bytes);
        let root = self.dir.join(root);
        std::fs::create_dir_all(&root)
            .unwrap_or_else(|e| panic!("cannot make the scratch folder {}: {e}", root.display()));
        let _ = std::fs::write(root.join(main_name(main)), main);
        for (name, data) in parts {
            let comps: Vec<String> = name.split(|&b| b == b'/').map(safe_name).collect();
            if comps.len() > 8 || comps.iter().any(|c| c.is_empty() || c == "." || c == "..") {
                continue;
            }
            let p = comps.iter().fold(root.clone(), |p, c| p.join(c));
            if let Some(parent) = p.parent() {
                let _ = std::fs::create_dir_all(parent);
            }
            if !p.exists() {
                let _ = std::fs::write(&p, data);
            }
        }
        root
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_split_as_joined() {
        let b = join_parts(b"main", &[("a.raw", b"12\n3"), ("../b", b"")]);
        let (main, parts) = split_parts(&b);
        assert_eq!(main, b"main");
        assert_eq!(
            parts,
            vec![(&b"a.raw"[..], &b"12\n3"[..]), (&b"../b"[..], &b""[..])]
        );
        assert_eq!(safe_name(b"../b/c\0"), ".._b_c_");
    }

    #[test]
    fn names_round_trip_and_scratch_is_removed() {
        for t in Target::ALL {
            assert_eq!(Target::from_name(t.name()), Some(t));
        }
        let d = Scratch::new();
        let p = d.path().to_path_buf();
        assert!(p.is_dir());
        drop(d);
        assert!(!p.exists());
    }
}
