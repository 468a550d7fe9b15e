//! The image cut into square tiles rendered in parallel by rayon — the
//! frame every integrator (the ray caster, the path tracer) fills with its
//! own per-pixel function. Statistics are counted per tile and summed, so
//! no pixel takes a lock.

use super::stats::RenderStats;
use crate::image::Image;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

/// Side of a square tile in pixels.
pub(super) const TILE: u32 = 16;

/// Renders a `w`×`h` image tile by tile: each tile makes its scratch state
/// with `state`, calls `pixel(state, stats, x, y)` for its pixels (linear
/// RGBA), then `finish(state, stats)`; `progress(done, total)` is called
/// after each tile. Generic, so the per-pixel call is inlined.
///
/// `cancel` is read once per tile (never per pixel or sample): once it is
/// raised, the tiles not yet started are skipped and `None` is returned.
pub(super) fn render_tiles<S>(
    w: u32,
    h: u32,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
    state: impl Fn() -> S + Sync,
    pixel: impl Fn(&mut S, &mut RenderStats, u32, u32) -> [f32; 4] + Sync,
    finish: impl Fn(S, &mut RenderStats) + Sync,
) -> Option<(Image, RenderStats)> {
    render_whole_tiles(
        w,
        h,
        progress,
        cancel,
        state,
        |s, stats, (tx, ty, tw), out| {
            for (i, px) in out.iter_mut().enumerate() {
                let i = i as u32;
                *px = pixel(s, stats, tx + i % tw, ty + i / tw);
            }
        },
        finish,
    )
}

/// [`render_tiles`] a whole tile at a time: `tile(state, stats, (x0, y0,
/// width), out)` fills the tile of `out.len() / width` rows from `(x0,
/// y0)`, row by row, for integrators that trace neighbouring rays
/// together (the SIMD packets).
pub(super) fn render_whole_tiles<S>(
    w: u32,
    h: u32,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
    state: impl Fn() -> S + Sync,
    tile: impl Fn(&mut S, &mut RenderStats, (u32, u32, u32), &mut [[f32; 4]]) + Sync,
    finish: impl Fn(S, &mut RenderStats) + Sync,
) -> Option<(Image, RenderStats)> {
    let job = |stats: &mut RenderStats, t: (u32, u32, u32), out: &mut [[f32; 4]]| {
        let mut s = state();
        tile(&mut s, stats, t, out);
        finish(s, stats);
    };
    run_tiles(w, h, progress, cancel, &job)
}

/// A tile's work: `job(stats, (x0, y0, width), out)`.
type TileJob<'a> = dyn Fn(&mut RenderStats, (u32, u32, u32), &mut [[f32; 4]]) + Sync + 'a;

/// The parallel loop of [`render_whole_tiles`], compiled once: the tile's
/// work comes as a `dyn` call (one per tile, never per pixel), so rayon's
/// machinery is not instantiated again for every integrator, voxel type
/// and method — it was a fifth of the crate's LLVM IR.
fn run_tiles(
    w: u32,
    h: u32,
    progress: &(dyn Fn(usize, usize) + Sync),
    cancel: &AtomicBool,
    job: &TileJob<'_>,
) -> Option<(Image, RenderStats)> {
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let total = (tiles_x * tiles_y) as usize;
    let done = AtomicUsize::new(0);
    let skipped = AtomicBool::new(false);
    let tiles: Vec<(u32, u32, Vec<[f32; 4]>, RenderStats)> = (0..tiles_x * tiles_y)
        .into_par_iter()
        .map(|ti| {
            let (tx, ty) = (ti % tiles_x * TILE, ti / tiles_x * TILE);
            let mut stats = RenderStats::default();
            if cancel.load(Ordering::Relaxed) {
                skipped.store(true, Ordering::Relaxed);
                return (tx, ty, Vec::new(), stats);
            }
            let tw = (tx + TILE).min(w) - tx;
            let th = (ty + TILE).min(h) - ty;
            let mut px = vec![[0.0; 4]; (tw * th) as usize];
            job(&mut stats, (tx, ty, tw), &mut px);
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(n, total);
            (tx, ty, px, stats)
        })
        .collect();
    if skipped.load(Ordering::Relaxed) {
        return None;
    }
    let mut image = Image::new(w, h);
    let mut stats = RenderStats::default();
    for (tx, ty, px, s) in tiles {
        stats.add(&s);
        let tw = (tx + TILE).min(w) - tx;
        for (i, p) in px.into_iter().enumerate() {
            image.set(tx + i as u32 % tw, ty + i as u32 / tw, p);
        }
    }
    Some((image, stats))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_raised_flag_skips_the_tiles_left() {
        let never = AtomicBool::new(false);
        let (img, _) = render_tiles(
            40,
            20,
            &|_, _| {},
            &never,
            || (),
            |_, _, x, _| [x as f32, 0.0, 0.0, 1.0],
            |_, _| {},
        )
        .expect("not cancelled");
        assert_eq!((img.width, img.height), (40, 20));
        // Raised before the start: nothing is drawn.
        let raised = AtomicBool::new(true);
        let drawn = AtomicUsize::new(0);
        let r = render_tiles(
            64,
            64,
            &|_, _| {},
            &raised,
            || (),
            |_, _, _, _| {
                drawn.fetch_add(1, Ordering::Relaxed);
                [0.0; 4]
            },
            |_, _| {},
        );
        assert!(r.is_none());
        assert_eq!(drawn.load(Ordering::Relaxed), 0);
        // Raised by the first tile: the frame is abandoned part-way.
        let flag = AtomicBool::new(false);
        let r = render_tiles(
            256,
            256,
            &|_, _| flag.store(true, Ordering::Relaxed),
            &flag,
            || (),
            |_, _, _, _| [0.0; 4],
            |_, _| {},
        );
        assert!(r.is_none());
    }
}
