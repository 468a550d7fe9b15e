//! Progressive refinement: while the view changes (the camera moves, the
//! transfer function is being dragged) frames are rendered at a reduced
//! resolution and a coarser step, sized from the measured cost per ray so
//! that one frame fits a time budget; once the view has been still for a
//! moment, one full-quality frame replaces them.

use std::time::Duration;
use voxcast::render::RenderParams;

/// How good a frame is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quality {
    /// `1/divisor` of the view's width and height, coarser step, 1 spp.
    Preview { divisor: u32 },
    /// The view's size and the scene's own parameters.
    Full,
}

/// Largest preview divisor (1/8 of each side).
pub const MAX_DIVISOR: u32 = 8;

/// Picks the preview resolution from the measured cost of earlier previews.
#[derive(Clone, Debug)]
pub struct Scheduler {
    /// Time one preview frame may take.
    pub budget: Duration,
    /// How long the view must be still before the full frame is rendered.
    pub settle: Duration,
    /// Seconds per ray of recent previews (exponential average).
    secs_per_ray: Option<f64>,
}

impl Default for Scheduler {
    fn default() -> Self {
        Scheduler {
            // 15 fps goal with some room for the UI's own frame.
            budget: Duration::from_millis(50),
            settle: Duration::from_millis(150),
            secs_per_ray: None,
        }
    }
}

impl Scheduler {
    /// The smallest divisor (largest preview) whose predicted time fits the
    /// budget; 4 before anything was measured.
    pub fn preview_divisor(&self, width: u32, height: u32) -> u32 {
        let Some(s) = self.secs_per_ray else {
            return 4;
        };
        let budget = self.budget.as_secs_f64();
        (1..=MAX_DIVISOR)
            .find(|&d| {
                let (w, h) = scaled(width, height, d);
                s * (w as f64 * h as f64) <= budget
            })
            .unwrap_or(MAX_DIVISOR)
    }

    /// Records a preview's rays and wall time.
    pub fn record(&mut self, rays: u64, seconds: f64) {
        if rays == 0 || !(seconds.is_finite() && seconds > 0.0) {
            return;
        }
        let s = seconds / rays as f64;
        self.secs_per_ray = Some(match self.secs_per_ray {
            None => s,
            Some(old) => 0.6 * old + 0.4 * s,
        });
    }

    /// The measured seconds per ray, if any.
    pub fn secs_per_ray(&self) -> Option<f64> {
        self.secs_per_ray
    }
}

/// `width`×`height` divided by `d`, at least 1×1 (rounded up).
pub fn scaled(width: u32, height: u32, d: u32) -> (u32, u32) {
    let d = d.max(1);
    (width.div_ceil(d).max(1), height.div_ceil(d).max(1))
}

/// The parameters of a frame of `quality` for a full frame of `full`.
pub fn frame_params(full: &RenderParams, quality: Quality) -> RenderParams {
    match quality {
        Quality::Full => full.clone(),
        Quality::Preview { divisor } => {
            let (w, h) = scaled(full.width, full.height, divisor);
            let mut p = full.clone();
            p.width = w;
            p.height = h;
            // A pixel now covers `divisor` pixels' worth of the volume:
            // twice the step costs half and, opacity-corrected, looks the
            // same at that size.
            if divisor > 1 {
                p.step = (full.step * 2.0).min(4.0).max(full.step);
            }
            p.spp = 1;
            p
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn divisor_follows_the_measured_cost() {
        let mut s = Scheduler::default();
        assert_eq!(s.preview_divisor(800, 600), 4, "unmeasured");
        // 1 µs per ray: 800×600 takes 0.48 s, /4 30 ms.
        s.record(1_000_000, 1.0);
        assert_eq!(s.preview_divisor(800, 600), 4);
        // 0.1 µs per ray: 800×600 takes 48 ms, fits at full size.
        let mut fast = Scheduler::default();
        fast.record(10_000_000, 1.0);
        assert_eq!(fast.preview_divisor(800, 600), 1);
        // Very slow: capped.
        let mut slow = Scheduler::default();
        slow.record(1, 10.0);
        assert_eq!(slow.preview_divisor(800, 600), MAX_DIVISOR);
        // Bad measurements are ignored.
        slow.record(0, 1.0);
        slow.record(10, f64::NAN);
        assert_eq!(slow.secs_per_ray(), Some(10.0));
    }

    #[test]
    fn preview_params_are_smaller_and_coarser() {
        let full = RenderParams {
            width: 801,
            height: 600,
            step: 0.5,
            spp: 16,
            ..Default::default()
        };
        let p = frame_params(&full, Quality::Preview { divisor: 4 });
        assert_eq!((p.width, p.height), (201, 150));
        assert_eq!(p.step, 1.0);
        assert_eq!(p.spp, 1);
        assert!(p.validate().is_ok());
        assert_eq!(frame_params(&full, Quality::Full), full);
        let p1 = frame_params(&full, Quality::Preview { divisor: 1 });
        assert_eq!((p1.width, p1.step), (801, 0.5));
    }
}
