//! The reference render the methods are compared against: its parameters
//! (uniform at [`REFERENCE_STEP`], no acceleration), its cache key (a stable
//! FNV-1a hash of the reference scene and of every voxel) and its cache
//! files (a linear float EXR and a JSON sidecar).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use voxcast::error::{Error, Result};
use voxcast::files::write_file;
use voxcast::image::Image;
use voxcast::render::{Method, RenderParams, RenderStats};
use voxcast::scene::{Prepared, Scene};
use voxcast::volume::{Volume, VoxelData};

/// Step of the reference render, in voxels.
pub const REFERENCE_STEP: f32 = 1.0 / 16.0;

/// Bumped whenever the reference's definition or its cache format changes,
/// so that old cache entries are not reused.
pub(super) const REFERENCE_FORMAT: &str = "voxcast-bench-reference 1";

/// The render parameters of the reference: `base` (the scene's) with the
/// uniform marcher at [`REFERENCE_STEP`], early ray termination off, no
/// empty-space skipping, no jitter, no grouping. Everything else (size,
/// optical model, order, shading, background, seed) is the scene's.
pub fn reference_params(base: &RenderParams) -> RenderParams {
    let mut p = base.clone();
    p.method = Method::Uniform;
    p.grouped = false;
    p.step = REFERENCE_STEP;
    p.ert = 1.0;
    p.skip_empty = false;
    p.jitter = false;
    // Parameters of the other marchers do not shape the reference.
    p.adaptive = Default::default();
    p.threshold = Default::default();
    p.block_size = None;
    p
}

/// FNV-1a, 64 bit: small and stable across Rust releases and platforms
/// (unlike `DefaultHasher`), which a cache key on disk needs.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a(u64);

impl Fnv1a {
    const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
    const PRIME: u64 = 0x0000_0100_0000_01b3;

    pub fn new() -> Fnv1a {
        Fnv1a(Self::OFFSET)
    }

    pub fn write(&mut self, bytes: &[u8]) {
        let mut h = self.0;
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(Self::PRIME);
        }
        self.0 = h;
    }

    /// Writes a length-prefixed field, so that `("ab", "c")` and `("a", "bc")`
    /// hash differently.
    pub fn field(&mut self, bytes: &[u8]) {
        self.write(&(bytes.len() as u64).to_le_bytes());
        self.write(bytes);
    }

    pub fn finish(&self) -> u64 {
        self.0
    }
}

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a::new()
    }
}

/// FNV-1a 64 of `bytes`.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h = Fnv1a::new();
    h.write(bytes);
    h.finish()
}

/// Voxels per chunk of the content hash (fixed: the hash must not depend on
/// the number of threads).
const HASH_CHUNK: usize = 1 << 20;

/// A stable hash of a volume's voxels (little-endian bytes), computed per
/// chunk in parallel and combined in order.
fn voxel_hash(data: &VoxelData) -> u64 {
    fn chunks<T: Copy + Sync, const N: usize>(v: &[T], bytes: impl Fn(T) -> [u8; N] + Sync) -> u64 {
        let parts: Vec<u64> = v
            .par_chunks(HASH_CHUNK)
            .map(|c| {
                let mut h = Fnv1a::new();
                for &x in c {
                    h.write(&bytes(x));
                }
                h.finish()
            })
            .collect();
        let mut h = Fnv1a::new();
        h.write(&(v.len() as u64).to_le_bytes());
        for p in parts {
            h.write(&p.to_le_bytes());
        }
        h.finish()
    }
    match data {
        VoxelData::U8(v) => {
            // One byte per voxel: hash the bytes directly.
            chunks(v, |x| [x])
        }
        VoxelData::U16(v) => chunks(v, u16::to_le_bytes),
        VoxelData::I16(v) => chunks(v, i16::to_le_bytes),
        VoxelData::F32(v) => chunks(v, |x: f32| x.to_bits().to_le_bytes()),
    }
}

/// The cache key of the reference render of `scene`: an FNV-1a 64 hash of
/// the reference scene resolved against `prepared` (transfer function inline,
/// window fixed) as TOML — without the input's path, which does not change
/// the picture — and of the volume itself (type, dims, spacing, origin and
/// every voxel), so that an edited file, a detached data file, a slice added
/// to a folder or a changed raw layout all give a new key, while the same
/// data under another path or a touched file do not. The scene's own method,
/// step and termination do not enter: the reference replaces them.
pub fn reference_key(scene: &Scene, prepared: &Prepared) -> u64 {
    let mut s = scene.resolved(prepared);
    s.render = reference_params(&s.render);
    s.input.path.clear();
    let toml = toml::to_string(&s).unwrap_or_else(|e| format!("unserialisable scene: {e}"));
    let mut h = Fnv1a::new();
    h.field(REFERENCE_FORMAT.as_bytes());
    h.field(env!("CARGO_PKG_VERSION").as_bytes());
    h.field(toml.as_bytes());
    let v: &Volume = &prepared.volume;
    h.field(v.scalar_type().name().as_bytes());
    for d in v.dims() {
        h.write(&(d as u64).to_le_bytes());
    }
    for x in v
        .spacing()
        .to_array()
        .into_iter()
        .chain(v.origin().to_array())
    {
        h.write(&x.to_bits().to_le_bytes());
    }
    h.write(&voxel_hash(v.data()).to_le_bytes());
    // Geometry found through the input's path is not in the scene's TOML.
    if let Some(g) = &prepared.geometry {
        h.write(&g.fingerprint().to_le_bytes());
    }
    h.finish()
}

/// What the cache stores beside the EXR.
#[derive(Serialize, Deserialize)]
pub(super) struct CacheMeta {
    pub(super) key: String,
    pub(super) format: String,
    pub(super) ms: f64,
    pub(super) stats: RenderStats,
    /// The reference scene, for a person reading the cache.
    pub(super) scene: String,
}

pub(super) fn cache_paths(dir: &Path, key: u64) -> (PathBuf, PathBuf) {
    (
        dir.join(format!("reference-{key:016x}.exr")),
        dir.join(format!("reference-{key:016x}.json")),
    )
}

/// Reads a cached reference; `None` when absent or unusable.
pub(super) fn load_cached(
    dir: &Path,
    key: u64,
    width: u32,
    height: u32,
) -> Option<(Image, CacheMeta)> {
    let (exr, json) = cache_paths(dir, key);
    let meta: CacheMeta = serde_json::from_str(&std::fs::read_to_string(json).ok()?).ok()?;
    if meta.key != format!("{key:016x}") || meta.format != REFERENCE_FORMAT {
        return None;
    }
    let img = Image::read(&exr).ok()?;
    ((img.width, img.height) == (width, height)).then_some((img, meta))
}

pub(super) fn store_cached(dir: &Path, key: u64, img: &Image, meta: &CacheMeta) -> Result<PathBuf> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let (exr, json) = cache_paths(dir, key);
    img.write_exr(&exr)?;
    let text = serde_json::to_string_pretty(meta)
        .map_err(|e| Error::invalid(format!("cache metadata: {e}")))?;
    write_file(&json, |w| {
        use std::io::Write;
        writeln!(w, "{text}")
    })?;
    Ok(exr)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_matches_the_published_test_vectors() {
        // From the FNV reference (Fowler, Noll, Vo): these values must never
        // change, or every cached reference would silently be orphaned.
        assert_eq!(fnv1a64(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a64(b"a"), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv1a64(b"foobar"), 0x8594_4171_f739_67e8);
        // Streaming equals one shot.
        let mut h = Fnv1a::new();
        h.write(b"foo");
        h.write(b"bar");
        assert_eq!(h.finish(), fnv1a64(b"foobar"));
        // Length-prefixed fields keep boundaries apart.
        let field2 = |a: &[u8], b: &[u8]| {
            let mut h = Fnv1a::new();
            h.field(a);
            h.field(b);
            h.finish()
        };
        assert_ne!(field2(b"ab", b"c"), field2(b"a", b"bc"));
    }

    #[test]
    fn voxel_hash_is_chunking_independent_of_threads_and_sees_every_voxel() {
        let n = HASH_CHUNK * 2 + 17;
        let a = VoxelData::U16((0..n).map(|i| (i * 7 % 65_521) as u16).collect());
        let h1 = voxel_hash(&a);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        assert_eq!(pool.install(|| voxel_hash(&a)), h1);
        let VoxelData::U16(mut v) = a else {
            unreachable!()
        };
        v.make_mut()[n - 1] ^= 1;
        assert_ne!(voxel_hash(&VoxelData::U16(v)), h1);
        // The same bytes as another type differ (the type is in the key, but
        // the data alone differs too in length).
        let b = VoxelData::U8(vec![1, 2, 3].into());
        assert_ne!(
            voxel_hash(&b),
            voxel_hash(&VoxelData::U8(vec![1, 2, 4].into()))
        );
    }

    #[test]
    fn reference_key_depends_on_what_shapes_the_reference_only() {
        let mut scene = Scene::default();
        scene.input.path = "builtin:sphere".into();
        scene.render.width = 32;
        scene.render.height = 24;
        let prepared = scene.prepare().unwrap();
        let k = reference_key(&scene, &prepared);
        // Stable: the same inputs give the same key, every time.
        assert_eq!(k, reference_key(&scene.clone(), &scene.prepare().unwrap()));
        // What the reference replaces does not count.
        let mut s = scene.clone();
        s.render.step = 0.9;
        s.render.ert = 0.5;
        s.render.method = Method::Threshold;
        s.render.grouped = true;
        s.render.jitter = true;
        s.render.skip_empty = false;
        assert_eq!(reference_key(&s, &prepared), k);
        // Nor the input's path when the data are the same.
        let mut s = scene.clone();
        s.input.path = "elsewhere/sphere.nrrd".into();
        assert_eq!(reference_key(&s, &prepared), k);
        // What shapes the picture does.
        let mut s = scene.clone();
        s.camera.azimuth = 10.0;
        assert_ne!(reference_key(&s, &prepared), k);
        let mut s = scene.clone();
        s.render.width = 33;
        assert_ne!(reference_key(&s, &prepared), k);
        let mut s = scene.clone();
        s.transfer.window = Some([0.1, 0.9]);
        let p = s.prepare().unwrap();
        assert_ne!(reference_key(&s, &p), k);
        // And so does one voxel.
        let v = &prepared.volume;
        let mut data: Vec<f32> = (0..v.len()).map(|i| v.data().get(i)).collect();
        data[v.len() / 2] += 0.25;
        let edited = Volume::new(
            v.dims(),
            v.spacing(),
            v.origin(),
            VoxelData::F32(data.into()),
        )
        .unwrap();
        let p = Prepared {
            volume: edited,
            tf: prepared.tf.clone(),
            window: prepared.window,
            geometry: None,
        };
        assert_ne!(reference_key(&scene, &p), k);
    }
}
