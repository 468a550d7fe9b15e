//! A multi-resolution store (OME-Zarr) opened coarse first: the viewer
//! shows the coarsest level at once, while a loader thread (neither the UI
//! nor the render thread) reads finer and finer levels, down to the finest
//! that fits in memory, and hands each over. The render thread swaps a
//! level in as it swaps a series' frame (a request's `frame` is the level;
//! see [`crate::worker::Source::Levels`]), without any I/O of its own: the
//! loader has read it already. So the camera and the transfer function
//! never wait for a read.

use glam::Vec3;
use std::path::Path;
use std::sync::mpsc::Receiver;
use std::sync::{Arc, Mutex};
use voxcast::io::zarr::ZarrStore;
use voxcast::io::{Format, OpenOptions};
use voxcast::volume::ChunkedSource;
use voxcast::Volume;

/// A store of several levels, to be shown coarsest first.
pub struct Pyramid {
    store: ZarrStore,
    /// `--spacing`: level 0's spacing (the coarser levels' is scaled).
    spacing: Option<[f32; 3]>,
    /// The coarsest level: opened first.
    pub coarsest: usize,
    /// The finest level read: the finest whose decoded voxels fit in the
    /// budget twice over (the in-core renderer holds about two copies); 0
    /// unless memory is short.
    pub finest: usize,
    /// The memory budget it was opened with (bytes).
    pub budget: u64,
    /// `--lod-scale` (checked: positive), for out-of-core frames.
    pub lod_scale: f32,
    /// Draw it out of core instead ([`crate::stream`]): set where level 0
    /// does not fit and the CPU draws the frames.
    pub out_of_core: bool,
}

impl std::fmt::Debug for Pyramid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pyramid")
            .field("store", &self.store.path())
            .field("coarsest", &self.coarsest)
            .field("finest", &self.finest)
            .finish()
    }
}

/// A level the loader read (or why it could not).
pub type Loaded = Result<(usize, Arc<Volume>), String>;

impl Pyramid {
    /// `path` as a pyramid to show coarse first, reading at most `budget`
    /// bytes twice over. `None` where it is no Zarr store, `--level` picks
    /// one level, the store has a single level, or not even the coarsest
    /// level fits: such inputs open as one volume, as any other file.
    pub fn open(path: &Path, opts: &OpenOptions, budget: u64) -> voxcast::Result<Option<Pyramid>> {
        if opts.level.is_some() || !matches!(voxcast::io::detect(path, opts), Ok(Format::Zarr)) {
            return Ok(None);
        }
        let lod_scale = opts.lod_scale()?;
        let store = ZarrStore::open_with(path, opts)?;
        let coarsest = store.levels().len().saturating_sub(1);
        let Some(finest) = store.finest_within(budget / 2) else {
            return Ok(None);
        };
        if coarsest == 0 {
            return Ok(None);
        }
        Ok(Some(Pyramid {
            store,
            spacing: opts.spacing,
            coarsest,
            finest,
            budget,
            lod_scale,
            out_of_core: false,
        }))
    }

    /// The store, to be drawn out of core.
    pub fn into_store(self) -> ZarrStore {
        self.store
    }

    /// Decoded bytes of `level`.
    pub fn bytes(&self, level: usize) -> u64 {
        self.store.levels()[level].bytes(self.store.scalar_type())
    }

    /// Level `level` read whole (`--spacing` scaled to it).
    pub fn read(&self, level: usize) -> voxcast::Result<Volume> {
        let mut v = self.store.read_level(level)?;
        if let Some(s) = self.spacing {
            let l = self.store.levels();
            v.set_spacing(Vec3::from(s) * l[level].spacing / l[0].spacing)?;
        }
        Ok(v)
    }

    /// Starts the loader thread: it reads the levels finer than the
    /// coarsest, one after the other down to `finest`, puts each in `slots`
    /// and then announces it on the channel returned (calling `notify`). It
    /// stops after an error (announced too) or once the receiver is gone.
    pub fn load_finer(
        self,
        slots: Arc<LevelSlots>,
        notify: impl Fn() + Send + 'static,
    ) -> Receiver<Loaded> {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::Builder::new()
            .name("voxcast-view levels".into())
            .spawn(move || {
                for level in (self.finest..self.coarsest).rev() {
                    let msg = match self.read(level) {
                        Ok(v) => {
                            let v = Arc::new(v);
                            slots.put(level, v.clone());
                            Ok((level, v))
                        }
                        Err(e) => Err(format!("level {level}: {e}")),
                    };
                    let failed = msg.is_err();
                    if tx.send(msg).is_err() {
                        return;
                    }
                    notify();
                    if failed {
                        return;
                    }
                }
            })
            .expect("spawning the level loader");
        rx
    }
}

/// The levels read and not yet taken by the render thread.
#[derive(Default)]
pub struct LevelSlots {
    volumes: Mutex<Vec<(usize, Arc<Volume>)>>,
}

impl LevelSlots {
    /// Leaves `level` for the render thread.
    pub fn put(&self, level: usize, volume: Arc<Volume>) {
        let mut v = self.volumes.lock().unwrap_or_else(|e| e.into_inner());
        v.push((level, volume));
    }

    /// Takes `level`, dropping the coarser ones too: the viewer's level
    /// only ever gets finer, so no request names them again.
    pub fn take(&self, level: usize) -> Result<Arc<Volume>, String> {
        let mut v = self.volumes.lock().unwrap_or_else(|e| e.into_inner());
        let found = v.iter().find(|(l, _)| *l == level).map(|(_, v)| v.clone());
        if found.is_some() {
            v.retain(|(l, _)| *l < level);
        }
        found.ok_or_else(|| format!("level {level} has not been read"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;
    use voxcast::io::zarr::write::{write_volume, WriteOptions};

    /// The built-in sphere (64³) as a store of 64³, 32³ and 16³.
    fn store(dir: &Path) -> std::path::PathBuf {
        let v = voxcast::builtin::open("sphere").unwrap();
        let p = dir.join("sphere.zarr");
        let opts = WriteOptions {
            chunk: [16; 3],
            ..Default::default()
        };
        write_volume(&v, &p, &opts, &|_, _| {}).unwrap();
        p
    }

    #[test]
    fn the_finest_level_read_is_the_finest_that_fits_twice() {
        let dir = tempfile::tempdir().unwrap();
        let p = store(dir.path());
        let o = OpenOptions::default();
        let all = Pyramid::open(&p, &o, u64::MAX).unwrap().unwrap();
        assert_eq!((all.coarsest, all.finest), (2, 0));
        let l1 = all.bytes(1);
        let some = Pyramid::open(&p, &o, 2 * l1).unwrap().unwrap();
        assert_eq!((some.coarsest, some.finest), (2, 1));
        let none = Pyramid::open(&p, &o, 2 * l1 - 1).unwrap().unwrap();
        assert_eq!(none.finest, 2, "only the coarsest: nothing to refine");
        // Not even the coarsest fits, or --level: one volume, as before.
        assert!(Pyramid::open(&p, &o, 1).unwrap().is_none());
        let one = OpenOptions {
            level: Some(1),
            ..Default::default()
        };
        assert!(Pyramid::open(&p, &one, u64::MAX).unwrap().is_none());
        // Not a store.
        assert!(Pyramid::open(&dir.path().join("none.nrrd"), &o, u64::MAX)
            .unwrap()
            .is_none());
    }

    #[test]
    fn spacing_given_is_level_0s_and_scales_with_the_level() {
        let dir = tempfile::tempdir().unwrap();
        let p = store(dir.path());
        let o = OpenOptions {
            spacing: Some([0.5, 1.0, 2.0]),
            ..Default::default()
        };
        let pyr = Pyramid::open(&p, &o, u64::MAX).unwrap().unwrap();
        assert_eq!(pyr.read(0).unwrap().spacing(), Vec3::new(0.5, 1.0, 2.0));
        assert_eq!(pyr.read(2).unwrap().spacing(), Vec3::new(2.0, 4.0, 8.0));
    }

    #[test]
    fn the_loader_hands_over_finer_levels_in_order() {
        let dir = tempfile::tempdir().unwrap();
        let p = store(dir.path());
        let pyr = Pyramid::open(&p, &OpenOptions::default(), u64::MAX)
            .unwrap()
            .unwrap();
        let slots = Arc::new(LevelSlots::default());
        let rx = pyr.load_finer(slots.clone(), || {});
        let mut got = Vec::new();
        while let Ok(m) = rx.recv_timeout(Duration::from_secs(60)) {
            let (level, v) = m.unwrap();
            got.push((level, v.dims()));
        }
        assert_eq!(got, [(1, [32; 3]), (0, [64; 3])]);
        // The render thread takes level 0; level 1 goes with it.
        assert_eq!(slots.take(0).unwrap().dims(), [64; 3]);
        let e = slots.take(1).unwrap_err();
        assert!(e.contains("level 1"), "{e}");
    }
}
