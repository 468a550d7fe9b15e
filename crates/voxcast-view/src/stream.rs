//! A store too large for memory, drawn out of core: each frame is an
//! out-of-core render that reads nothing
//! ([`OutOfCoreParams::resident_only`](voxcast::render::outofcore::OutOfCoreParams::resident_only)) — every region is drawn at the finest
//! level whose chunks are in memory — and lists the chunks a finer picture
//! needs. A loader thread (neither the UI nor the render thread) reads
//! them, newest frame's list first, and says when some have arrived; the
//! UI then asks for the same view again. So the view opens at once at the
//! coarsest level, refines region by region as chunks arrive (nearest the
//! eye and coarsest levels first), and the camera never waits for a read.

use crate::backend::FrameRenderer;
use crate::worker::Reply;
use std::collections::{HashSet, VecDeque};
use std::sync::atomic::AtomicBool;
use std::sync::mpsc::Sender;
use std::sync::{Condvar, Mutex};
use std::time::{Duration, Instant};
use voxcast::camera::CameraParams;
use voxcast::render::outofcore::{ChunkKey, OutOfCore, OutOfCoreParams};
use voxcast::render::RenderParams;
use voxcast::transfer::TransferFunction;
use voxcast::{Image, RenderStats};

/// What a frame drawn from a store showed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StoreFrame {
    /// The finest and coarsest levels drawn.
    pub finest: usize,
    pub coarsest: usize,
    /// Chunks it asked the loader for.
    pub wanted: usize,
    /// A finer picture needs more chunks than the memory budget holds.
    pub over_budget: bool,
}

/// The chunks the newest frame wants read, for the loader.
#[derive(Default)]
pub struct Wants {
    state: Mutex<WantState>,
    wake: Condvar,
}

#[derive(Default)]
struct WantState {
    list: VecDeque<ChunkKey>,
    stop: bool,
}

/// What the loader is to do next.
enum Next {
    Read(ChunkKey),
    /// Nothing to read (for now).
    Idle,
    Stop,
}

impl Wants {
    /// Replaces the list (the newest view's needs come first, the rest
    /// are no longer needed).
    pub fn set(&self, list: &[ChunkKey]) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.list = list.iter().copied().collect();
        self.wake.notify_one();
    }

    /// Stops the loader.
    pub fn stop(&self) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        s.stop = true;
        self.wake.notify_one();
    }

    fn next(&self, wait: Duration) -> Next {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if !s.stop && s.list.is_empty() {
            s = self
                .wake
                .wait_timeout(s, wait)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        if s.stop {
            return Next::Stop;
        }
        s.list.pop_front().map_or(Next::Idle, Next::Read)
    }
}

/// Reads the chunks `wants` lists into `ooc`'s cache until stopped, and
/// sends [`Reply::Arrived`] (calling `notify`) when the list is done, and
/// every quarter second while it is not. A chunk that cannot be read is
/// reported once and not tried again.
pub fn load(ooc: &OutOfCore<'_>, wants: &Wants, tx: &Sender<Reply>, notify: &(dyn Fn() + Sync)) {
    let mut failed = HashSet::new();
    let mut fresh = 0usize;
    let mut since = Instant::now();
    loop {
        let idle = match wants.next(Duration::from_millis(100)) {
            Next::Stop => return,
            Next::Idle => true,
            Next::Read(k) if failed.contains(&k) => false,
            Next::Read(k) => {
                match ooc.fetch(k) {
                    Ok(read) => fresh += read as usize,
                    Err(e) => {
                        failed.insert(k);
                        let _ = tx.send(Reply::Error {
                            generation: 0,
                            message: format!("reading chunk {:?} of level {}: {e}", k.1, k.0),
                        });
                        notify();
                    }
                }
                false
            }
        };
        if fresh > 0 && (idle || since.elapsed() > Duration::from_millis(250)) {
            let _ = tx.send(Reply::Arrived { chunks: fresh });
            notify();
            fresh = 0;
            since = Instant::now();
        }
    }
}

/// The frame renderer of a store: resident-only out-of-core frames, each
/// handing its wanted chunks to the loader.
pub struct StoreFrames<'a> {
    pub ooc: &'a OutOfCore<'a>,
    pub window: [f32; 2],
    pub wants: &'a Wants,
    pub last: Option<StoreFrame>,
}

impl FrameRenderer for StoreFrames<'_> {
    fn render(
        &mut self,
        tf: &TransferFunction,
        camera: &CameraParams,
        params: &RenderParams,
        cancel: &AtomicBool,
    ) -> voxcast::Result<(Image, RenderStats)> {
        let (image, stats, ooc) =
            self.ooc
                .render(tf, self.window, camera, params, &|_, _| {}, cancel)?;
        self.wants.set(&ooc.wanted);
        self.last = Some(StoreFrame {
            finest: ooc.level,
            coarsest: ooc.coarsest,
            wanted: ooc.wanted.len(),
            over_budget: ooc.over_budget,
        });
        Ok((image, stats))
    }

    fn store_frame(&self) -> Option<StoreFrame> {
        self.last
    }
}

/// The out-of-core parameters of a viewer's frames: within `budget`
/// bytes, levels chosen with `lod_scale`, reading nothing.
pub fn params(budget: u64, lod_scale: f32) -> OutOfCoreParams {
    OutOfCoreParams {
        budget,
        lod_scale,
        resident_only: true,
        prefetch: false,
        ..Default::default()
    }
}
