//! Threshold-range marching (Zeng et al. 2018, S0's baseline): from each
//! sample the step to the next depends on the range its value falls into.
//! Positions follow from the samples before them, so here skipping an empty
//! block restarts the march on the base grid `t₀ + n·step` at the next
//! non-empty block (there is none past the end of the walk).
//!
//! `lod` marches the same way, its step picked before the sample from the
//! sample's position and the opacity in front ([`Pick`]).

use super::{BlockWalker, ThresholdParams};
use crate::render::ray::{Composite, Counters, Frame, Marcher, Sampler, Segment};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;
use glam::Vec3;

/// The threshold marcher: its ranges, and per range the step (world units)
/// and the step opacities.
pub(in crate::render) struct Threshold<'a> {
    pub params: ThresholdParams,
    pub steps: [f32; 3],
    pub alphas: &'a [Box<[f32; LUT_SIZE]>],
}

/// How a ranged march picks each sample's class (0, 1 or 2), whose step
/// and step opacities it then takes.
pub(in crate::render) trait Pick: Sync {
    /// Per class, the step (world units).
    fn steps(&self) -> &[f32; 3];
    /// Per class, the step opacities.
    fn alphas(&self, class: usize) -> &[f32; LUT_SIZE];
    /// The class as far as it is known before the sample: from its
    /// position `p` (at `t` on `seg`) and the opacity `a` in front.
    #[inline(always)]
    fn before(&self, _p: Vec3, _t: f32, _seg: &Segment, _a: f32) -> usize {
        0
    }
    /// The class once the sample's value is known (`pre` from `before`).
    #[inline(always)]
    fn after(&self, pre: usize, _value: f32) -> usize {
        pre
    }
}

impl Pick for Threshold<'_> {
    #[inline(always)]
    fn steps(&self) -> &[f32; 3] {
        &self.steps
    }
    #[inline(always)]
    fn alphas(&self, class: usize) -> &[f32; LUT_SIZE] {
        &self.alphas[class]
    }
    /// The range of the sample's value.
    #[inline(always)]
    fn after(&self, _pre: usize, value: f32) -> usize {
        self.params.range(value)
    }
}

/// Every [`Pick`] marches one ray the same way, each sample's step that
/// of its class; true where the ray terminated early.
impl<T: Voxel, P: Pick> Marcher<T> for P {
    #[inline(always)]
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        s: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        let walker = BlockWalker::of_segment(f, seg, seg.t_out);
        let t_stop = seg.walk.1;
        let mut t = seg.t0;
        // Samples since the last skip (grouped reuse counts from there).
        let mut count = 0u32;
        for (ta, tb, b) in walker {
            if ta >= t_stop {
                break;
            }
            if f.skip_empty && f.empty[b] {
                continue;
            }
            if t < ta {
                t = seg.t0 + ((ta - seg.t0) / f.step).ceil() * f.step;
                count = 0;
                s.restart();
            }
            while t < tb {
                n.samples += 1;
                let p = seg.o + seg.d * t;
                let pre = self.before(p, t, seg, c.opacity());
                let sample = s.at(f, p, t, count, seg.view, n);
                count += 1;
                let r = self.after(pre, sample.value);
                let st = self.steps()[r];
                if let Some((i, rgb)) = sample.hit {
                    // The last sample's stretch ends at `t_end` (the exit
                    // plus the jitter offset, see `Segment::t_end`).
                    let alpha = if t + st < seg.t_out {
                        self.alphas(r)[i]
                    } else {
                        1.0 - (-f.lut.sigma(i) * (seg.t_end() - t) / f.unit).exp()
                    };
                    if alpha > 0.0 && c.add(rgb, alpha) {
                        return true;
                    }
                }
                t += st;
            }
        }
        false
    }
}
