//! Threshold-range marching (Zeng et al. 2018, S0's baseline): from each
//! sample the step to the next depends on the range its value falls into.
//! Positions follow from the samples before them, so here skipping an empty
//! block restarts the march on the base grid `t₀ + n·step` at the next
//! non-empty block (there is none past the end of the walk).

use super::{BlockWalker, ThresholdParams};
use crate::render::ray::{Composite, Counters, Frame, Marcher, Sampler, Segment};
use crate::transfer::LUT_SIZE;
use crate::volume::Voxel;

/// The threshold marcher: its ranges, and per range the step (world units)
/// and the step opacities.
pub(in crate::render) struct Threshold<'a> {
    pub params: ThresholdParams,
    pub steps: [f32; 3],
    pub alphas: &'a [Box<[f32; LUT_SIZE]>],
}

impl<T: Voxel> Marcher<T> for Threshold<'_> {
    #[inline(always)]
    fn march<S: Sampler<T>, C: Composite>(
        &self,
        f: &Frame<'_, T>,
        seg: &Segment,
        s: &mut S,
        c: &mut C,
        n: &mut Counters,
    ) -> bool {
        let walker = BlockWalker::new(
            seg.o,
            seg.d,
            seg.walk.0,
            seg.t_out,
            f.block_size,
            f.block_counts,
        )
        .staying();
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
                let sample = s.at(f, seg.o + seg.d * t, t, count, seg.view, n);
                count += 1;
                let r = self.params.range(sample.value);
                let st = self.steps[r];
                if let Some((i, rgb)) = sample.hit {
                    // The last sample's stretch ends at `t_end` (the exit
                    // plus the jitter offset, see `Segment::t_end`).
                    let alpha = if t + st < seg.t_out {
                        self.alphas[r][i]
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
