//! The render thread: the UI never waits for a render. The UI puts its
//! newest request in a one-place mailbox (a newer request replaces one not
//! yet started, so stale frames are skipped, never queued); the thread takes
//! it, loads the frame of a series if it changed (or takes the level of a
//! store that the level loader has read), renders, and sends the image back
//! with a wake-up for the UI.
//!
//! A full-quality frame in progress is cancelled when a newer request
//! arrives (the CPU renderer checks the flag per tile), so moving the camera
//! right after the refinement started gets a preview at once instead of
//! after the full frame. Previews are never cancelled: each is short, and
//! it is the newest image there is until the next one is done.

use crate::backend::{self, FrameRenderer};
use crate::levels::LevelSlots;
use crate::progressive::Quality;
use crate::stream::{StoreFrame, StoreFrames, Wants};
use crate::tf_model::LogHistogram;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Instant;
use voxcast::camera::CameraParams;
use voxcast::geometry::Geometry;
use voxcast::io::zarr::ZarrStore;
use voxcast::io::OpenOptions;
use voxcast::io::Series;
use voxcast::render::outofcore::OutOfCoreParams;
use voxcast::render::RenderParams;
use voxcast::transfer::TransferFunction;
use voxcast::{Image, RenderStats, Volume};
use voxcast_gpu::Device;

/// Bins of the histogram sent with each volume.
pub const HISTOGRAM_BINS: usize = 256;

/// One frame to render.
#[derive(Clone, Debug)]
pub struct Request {
    /// Increases with every request; replies carry it.
    pub generation: u64,
    /// Frame of the series, or level of the store shown coarse first (0
    /// for a single volume).
    pub frame: usize,
    /// Data values mapped to 0…1.
    pub window: [f32; 2],
    pub tf: TransferFunction,
    pub camera: CameraParams,
    /// Already sized for `quality`.
    pub params: RenderParams,
    pub quality: Quality,
}

/// What the render thread sends back.
#[derive(Debug)]
pub enum Reply {
    /// A new volume or window is in use: its histogram over the window.
    Volume {
        frame: usize,
        window: [f32; 2],
        histogram: LogHistogram,
        /// Seconds spent loading and preparing.
        seconds: f64,
    },
    /// A rendered frame.
    Frame {
        generation: u64,
        frame: usize,
        quality: Quality,
        image: Image,
        /// `image` as 8-bit sRGB RGBA (converted here, off the UI thread).
        srgba: Vec<u8>,
        stats: RenderStats,
        /// A store drawn out of core: the levels shown, the chunks wanted.
        store: Option<StoreFrame>,
    },
    /// A store drawn out of core: chunks a finer picture needs have been
    /// read since the last such reply; the same view drawn again shows
    /// more.
    Arrived { chunks: usize },
    /// A full-quality frame was abandoned for a newer request.
    Cancelled {
        generation: u64,
        /// Seconds from its start to giving up.
        seconds: f64,
    },
    /// A request failed.
    Error { generation: u64, message: String },
}

/// Where frames come from.
pub enum Source {
    /// One volume.
    Single,
    /// A series, loaded frame by frame with these options.
    Series(Box<Series>, OpenOptions),
    /// The levels of a store, coarsest first: a request's `frame` is the
    /// level, taken from here once the level loader has read it
    /// ([`crate::levels`]).
    Levels(Arc<LevelSlots>),
    /// A store too large for memory, drawn out of core with these
    /// parameters (resident only), refined as a loader reads chunks
    /// ([`crate::stream`]).
    Store(Arc<ZarrStore>, OutOfCoreParams),
}

/// The one-place mailbox.
#[derive(Default)]
pub struct Mailbox {
    state: Mutex<MailState>,
    wake: Condvar,
    /// Raised to stop the full-quality frame in progress.
    cancel: AtomicBool,
}

#[derive(Default)]
struct MailState {
    pending: Option<Request>,
    shutdown: bool,
    busy: bool,
    /// The request being rendered is a full-quality frame.
    full_running: bool,
}

impl Mailbox {
    /// Leaves `req` for the thread, replacing a request not yet taken, and
    /// cancels the full-quality frame in progress, if any.
    pub fn put(&self, req: Request) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.pending = Some(req);
        if s.full_running {
            self.cancel.store(true, Ordering::Relaxed);
        }
        self.wake.notify_one();
    }

    /// Waits for a request; `None` once shut down.
    pub fn take(&self) -> Option<Request> {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        loop {
            if s.shutdown {
                return None;
            }
            if let Some(r) = s.pending.take() {
                s.busy = true;
                s.full_running = r.quality == Quality::Full;
                self.cancel.store(false, Ordering::Relaxed);
                return Some(r);
            }
            s.busy = false;
            s.full_running = false;
            s = self.wake.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }

    /// Takes a request without waiting.
    pub fn try_take(&self) -> Option<Request> {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.pending.take()
    }

    /// Puts `req` back unless a newer one arrived meanwhile.
    fn put_back(&self, req: Request) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if s.pending.is_none() {
            s.pending = Some(req);
        }
    }

    /// True while a request is pending or being rendered.
    pub fn busy(&self) -> bool {
        let s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.busy || s.pending.is_some()
    }

    fn shut_down(&self) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.shutdown = true;
        self.wake.notify_all();
    }
}

/// The render thread's handle; dropping it stops the thread (after the
/// frame in progress).
pub struct Worker {
    mailbox: Arc<Mailbox>,
    replies: Receiver<Reply>,
}

impl Worker {
    /// Starts the thread with frame `frame` (`volume`) of `source` loaded.
    /// `notify` is called after every reply (to wake the UI).
    pub fn spawn(
        device: Device,
        source: Source,
        frame: usize,
        volume: Arc<Volume>,
        geometry: Option<Arc<Geometry>>,
        notify: impl Fn() + Send + Sync + 'static,
    ) -> Worker {
        let mailbox = Arc::new(Mailbox::default());
        let (tx, replies) = std::sync::mpsc::channel();
        let mb = mailbox.clone();
        std::thread::Builder::new()
            .name("voxcast-view render".into())
            .spawn(move || {
                // Leave one core to the UI thread (and a software rasteriser
                // such as lavapipe), or dragging stutters while frames render.
                // `VOXCAST_VIEW_RENDER_THREADS` overrides.
                let threads = std::env::var("VOXCAST_VIEW_RENDER_THREADS")
                    .ok()
                    .and_then(|v| v.parse::<usize>().ok())
                    .filter(|&n| n > 0)
                    .unwrap_or_else(|| {
                        std::thread::available_parallelism()
                            .map_or(1, |n| n.get().saturating_sub(1).max(1))
                    });
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|i| format!("voxcast-view render {i}"))
                    .build();
                let mut t = Thread {
                    device,
                    source,
                    frame,
                    volume,
                    window: None,
                    geometry,
                    tx,
                    notify: Arc::new(notify),
                };
                match pool {
                    Ok(pool) => pool.install(|| t.run(&mb)),
                    Err(_) => t.run(&mb),
                }
            })
            .expect("spawning the render thread");
        Worker { mailbox, replies }
    }

    /// Asks for a frame (replacing one not yet started).
    pub fn submit(&self, req: Request) {
        self.mailbox.put(req);
    }

    /// The next reply, if any.
    pub fn try_recv(&self) -> Option<Reply> {
        self.replies.try_recv().ok()
    }

    /// True while a request is pending or being rendered.
    pub fn busy(&self) -> bool {
        self.mailbox.busy()
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.mailbox.shut_down();
    }
}

struct Thread {
    device: Device,
    source: Source,
    frame: usize,
    volume: Arc<Volume>,
    /// The window the current renderer was made for (`None`: none yet).
    window: Option<[f32; 2]>,
    geometry: Option<Arc<Geometry>>,
    tx: Sender<Reply>,
    notify: Arc<dyn Fn() + Send + Sync>,
}

/// Makes the frame renderer for a volume and data window.
trait Backends {
    fn create<'v>(
        &'v self,
        volume: &'v Volume,
        window: [f32; 2],
    ) -> voxcast::Result<Box<dyn FrameRenderer + 'v>>;
}

/// The device's renderer of the volume in memory.
struct OnDevice {
    device: Device,
    geometry: Option<Arc<Geometry>>,
}

impl Backends for OnDevice {
    fn create<'v>(
        &'v self,
        volume: &'v Volume,
        window: [f32; 2],
    ) -> voxcast::Result<Box<dyn FrameRenderer + 'v>> {
        backend::create(self.device.clone(), volume, window, self.geometry.clone())
    }
}

/// Out-of-core frames of a store (the volume in memory, its coarsest
/// level, serves the histogram only).
struct OfStore<'a> {
    ooc: &'a voxcast::render::outofcore::OutOfCore<'a>,
    wants: &'a Wants,
}

impl Backends for OfStore<'_> {
    fn create<'v>(
        &'v self,
        _volume: &'v Volume,
        window: [f32; 2],
    ) -> voxcast::Result<Box<dyn FrameRenderer + 'v>> {
        Ok(Box::new(StoreFrames {
            ooc: self.ooc,
            window,
            wants: self.wants,
            last: None,
        }))
    }
}

impl Thread {
    fn send(&self, r: Reply) {
        let _ = self.tx.send(r);
        (self.notify)();
    }

    fn run(&mut self, mailbox: &Mailbox) {
        let Source::Store(store, params) = &self.source else {
            let on = OnDevice {
                device: self.device.clone(),
                geometry: self.geometry.clone(),
            };
            return self.serve(mailbox, &on);
        };
        let store = store.clone();
        let ooc = voxcast::render::outofcore::OutOfCore::new(&*store, params.clone());
        let wants = Wants::default();
        let (tx, notify) = (self.tx.clone(), self.notify.clone());
        std::thread::scope(|s| {
            let loader = std::thread::Builder::new()
                .name("voxcast-view chunks".into())
                .spawn_scoped(s, || crate::stream::load(&ooc, &wants, &tx, &*notify));
            if let Err(e) = loader {
                self.send(Reply::Error {
                    generation: 0,
                    message: format!("cannot start the chunk loader: {e}"),
                });
            }
            self.serve(
                mailbox,
                &OfStore {
                    ooc: &ooc,
                    wants: &wants,
                },
            );
            wants.stop();
        });
    }

    fn serve(&mut self, mailbox: &Mailbox, backends: &dyn Backends) {
        // One pass of the outer loop per (volume, window): the renderer
        // borrows the volume, and its derived structures are built once.
        'volume: loop {
            let Some(req) = mailbox.take() else { return };
            if let Err(message) = self.switch(&req) {
                self.send(Reply::Error {
                    generation: req.generation,
                    message,
                });
                continue;
            }
            let volume = self.volume.clone();
            let window = req.window;
            let mut renderer: Box<dyn FrameRenderer + '_> = match backends.create(&volume, window) {
                Ok(r) => r,
                Err(e) => {
                    self.window = None;
                    self.send(Reply::Error {
                        generation: req.generation,
                        message: e.to_string(),
                    });
                    continue;
                }
            };
            let mut next = Some(req);
            loop {
                let req = match next.take() {
                    Some(r) => r,
                    None => match mailbox.take() {
                        Some(r) => r,
                        None => return,
                    },
                };
                if req.frame != self.frame || Some(req.window) != self.window {
                    mailbox.put_back(req);
                    continue 'volume;
                }
                let start = Instant::now();
                let result = renderer.render(&req.tf, &req.camera, &req.params, &mailbox.cancel);
                // A newer request that arrived during the render makes this
                // frame stale only if it needs another volume; the image is
                // still the best there is until the newer one is done.
                match result {
                    Ok((image, stats)) => self.send(Reply::Frame {
                        generation: req.generation,
                        frame: req.frame,
                        quality: req.quality,
                        srgba: srgba8(&image),
                        image,
                        stats,
                        store: renderer.store_frame(),
                    }),
                    Err(voxcast::Error::Cancelled) => self.send(Reply::Cancelled {
                        generation: req.generation,
                        seconds: start.elapsed().as_secs_f64(),
                    }),
                    Err(e) => self.send(Reply::Error {
                        generation: req.generation,
                        message: e.to_string(),
                    }),
                }
            }
        }
    }

    /// Loads `req.frame` (a level: takes it) and computes the histogram for
    /// `req.window` when either changed.
    fn switch(&mut self, req: &Request) -> Result<(), String> {
        if req.frame == self.frame && Some(req.window) == self.window {
            return Ok(());
        }
        let start = Instant::now();
        if req.frame != self.frame {
            self.volume = match &self.source {
                Source::Series(series, options) => {
                    Arc::new(series.load(req.frame, options).map_err(|e| e.to_string())?)
                }
                Source::Levels(levels) => levels.take(req.frame)?,
                Source::Single | Source::Store(..) => {
                    return Err(format!("frame {}: the input is a single volume", req.frame))
                }
            };
            self.frame = req.frame;
        }
        self.window = Some(req.window);
        let histogram = LogHistogram::new(&self.volume, req.window, HISTOGRAM_BINS);
        self.send(Reply::Volume {
            frame: self.frame,
            window: req.window,
            histogram,
            seconds: start.elapsed().as_secs_f64(),
        });
        Ok(())
    }
}

/// `image` as 8-bit sRGB RGBA, opaque.
pub fn srgba8(image: &Image) -> Vec<u8> {
    use voxcast::transfer::linear_to_srgb;
    image
        .pixels
        .iter()
        .flat_map(|p| {
            let [r, g, b] = [p[0], p[1], p[2]].map(|c| (linear_to_srgb(c) * 255.0 + 0.5) as u8);
            [r, g, b, 255]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn request(generation: u64) -> Request {
        Request {
            generation,
            frame: 0,
            window: [0.0, 1.0],
            tf: TransferFunction::preset("grayscale").unwrap(),
            camera: CameraParams::default(),
            params: RenderParams {
                width: 24,
                height: 16,
                ..Default::default()
            },
            quality: Quality::Full,
        }
    }

    #[test]
    fn mailbox_keeps_only_the_newest_request() {
        let m = Mailbox::default();
        assert!(!m.busy());
        m.put(request(1));
        m.put(request(2));
        m.put(request(3));
        assert!(m.busy());
        assert_eq!(m.try_take().unwrap().generation, 3);
        assert!(m.try_take().is_none(), "the older ones were dropped");
        m.put(request(4));
        m.put_back(request(3));
        assert_eq!(
            m.try_take().unwrap().generation,
            4,
            "newer wins over put-back"
        );
    }

    #[test]
    fn a_newer_request_cancels_the_full_frame_in_progress() {
        let v = voxcast::builtin::open("sphere").unwrap();
        let w = Worker::spawn(Device::Cpu, Source::Single, 0, Arc::new(v), None, || {});
        // Minutes of work uncancelled: 2000² pixels × 256 samples per pixel.
        let mut big = request(1);
        big.params.width = 2000;
        big.params.height = 2000;
        big.params.jitter = true;
        big.params.spp = 256;
        w.submit(big);
        let first = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(matches!(first, Reply::Volume { .. }), "{first:?}");
        // Wait until the thread has taken the big frame.
        let start = Instant::now();
        while !w.mailbox.state.lock().unwrap().full_running {
            assert!(start.elapsed() < Duration::from_secs(60), "never started");
            std::thread::sleep(Duration::from_millis(5));
        }
        std::thread::sleep(Duration::from_millis(50));
        let mut small = request(2);
        small.quality = Quality::Preview { divisor: 4 };
        let asked = Instant::now();
        w.submit(small);
        let r = w.replies.recv_timeout(Duration::from_secs(30)).unwrap();
        assert!(matches!(r, Reply::Cancelled { generation: 1, .. }), "{r:?}");
        let r = w.replies.recv_timeout(Duration::from_secs(30)).unwrap();
        assert!(matches!(r, Reply::Frame { generation: 2, .. }), "{r:?}");
        assert!(
            asked.elapsed() < Duration::from_secs(20),
            "the preview took {:?}",
            asked.elapsed()
        );
        // Previews are not cancelled by newer requests.
        assert!(!w.mailbox.cancel.load(Ordering::Relaxed));
    }

    #[test]
    fn thread_renders_and_reports_the_histogram_first() {
        let v = voxcast::builtin::open("sphere").unwrap();
        let w = Worker::spawn(Device::Cpu, Source::Single, 0, Arc::new(v), None, || {});
        let mut req = request(7);
        req.window = [0.0, 1.0];
        w.submit(req);
        let mut got = Vec::new();
        let start = Instant::now();
        while got.len() < 2 && start.elapsed() < Duration::from_secs(60) {
            match w.replies.recv_timeout(Duration::from_secs(60)) {
                Ok(r) => got.push(r),
                Err(_) => break,
            }
        }
        assert!(
            matches!(&got[0], Reply::Volume { histogram, .. } if histogram.counts.iter().sum::<u64>() > 0),
            "{got:?}"
        );
        match &got[1] {
            Reply::Frame {
                generation,
                image,
                srgba,
                ..
            } => {
                assert_eq!(*generation, 7);
                assert_eq!((image.width, image.height), (24, 16));
                // The bytes are exactly `to_srgb8`'s, opaque.
                let rgb = image.to_srgb8();
                assert_eq!(srgba.len(), 24 * 16 * 4);
                for (a, b) in srgba.chunks(4).zip(rgb.chunks(3)) {
                    assert_eq!(&a[..3], b);
                    assert_eq!(a[3], 255);
                }
            }
            r => panic!("expected a frame, got {r:?}"),
        }
        // A frame of a single volume other than 0 is an error, not a panic.
        let mut bad = request(8);
        bad.frame = 3;
        w.submit(bad);
        let r = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(
            matches!(&r, Reply::Error { generation: 8, message } if message.contains("single")),
            "{r:?}"
        );
    }

    #[test]
    fn a_store_level_is_taken_from_the_slots_without_reading() {
        let coarse = voxcast::builtin::open("marschner-lobb").unwrap();
        let fine = Arc::new(voxcast::builtin::open("sphere").unwrap());
        let slots = Arc::new(LevelSlots::default());
        let source = Source::Levels(slots.clone());
        let w = Worker::spawn(Device::Cpu, source, 2, Arc::new(coarse), None, || {});
        let mut req = request(1);
        req.frame = 2;
        w.submit(req);
        let r = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(matches!(r, Reply::Volume { frame: 2, .. }), "{r:?}");
        let r = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(matches!(r, Reply::Frame { frame: 2, .. }), "{r:?}");
        // Level 0 is not read yet: an error, not a wait.
        let mut req = request(2);
        req.frame = 0;
        w.submit(req.clone());
        let r = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(
            matches!(&r, Reply::Error { generation: 2, message } if message.contains("level 0")),
            "{r:?}"
        );
        slots.put(0, fine);
        req.generation = 3;
        w.submit(req);
        let r = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(matches!(r, Reply::Volume { frame: 0, .. }), "{r:?}");
        let r = w.replies.recv_timeout(Duration::from_secs(60)).unwrap();
        assert!(
            matches!(
                r,
                Reply::Frame {
                    generation: 3,
                    frame: 0,
                    ..
                }
            ),
            "{r:?}"
        );
    }

    #[test]
    fn a_store_is_drawn_from_memory_and_drawn_finer_as_chunks_arrive() {
        // The render thread draws what is in memory (the coarsest level at
        // first) and hands the chunks it lacks to the loader, which says
        // when they have arrived; the same request then draws finer.
        let dir = tempfile::tempdir().unwrap();
        let v = voxcast::builtin::open("sphere").unwrap();
        let p = dir.path().join("sphere.zarr");
        let opts = voxcast::io::zarr::write::WriteOptions {
            chunk: [16; 3],
            ..Default::default()
        };
        voxcast::io::zarr::write::write_volume(&v, &p, &opts, &|_, _| {}).unwrap();
        let store = Arc::new(ZarrStore::open(&p).unwrap());
        let coarsest = Arc::new(store.read_level(2).unwrap());
        let source = Source::Store(store, crate::stream::params(64 << 20, 1.0));
        let w = Worker::spawn(Device::Cpu, source, 0, coarsest, None, || {});
        let mut finest = Vec::new();
        for generation in 1..20 {
            // Pixels finer than level 0's voxels.
            let mut req = request(generation);
            (req.params.width, req.params.height) = (160, 160);
            w.submit(req);
            let frame = loop {
                match w.replies.recv_timeout(Duration::from_secs(60)).unwrap() {
                    Reply::Frame { store, .. } => break store.expect("a store frame"),
                    Reply::Error { message, .. } => panic!("{message}"),
                    _ => {}
                }
            };
            finest.push(frame.finest);
            if frame.wanted == 0 {
                break;
            }
            // Wait for the loader.
            loop {
                match w.replies.recv_timeout(Duration::from_secs(60)).unwrap() {
                    Reply::Arrived { chunks } => {
                        assert!(chunks > 0);
                        break;
                    }
                    Reply::Error { message, .. } => panic!("{message}"),
                    _ => {}
                }
            }
        }
        assert_eq!(finest.first(), Some(&2), "{finest:?}");
        assert_eq!(finest.last(), Some(&0), "{finest:?}");
    }
}
