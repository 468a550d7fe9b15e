//! What a sample contributes (DESIGN.md axis 3): the optical model turns a
//! sample's colour and step opacity into emitted light and absorbed
//! fraction, and the compositor accumulates them — [`Front`] to back with
//! early ray termination, or [`Back`] to front.
//!
//! The three optical models of S4 differ only by which of the two terms
//! they keep, so they are two weights (`emission`, `absorption`, each 0 or
//! 1) multiplied in, not three copies of the loop.

use super::optics::{over_back, over_front, OpticalModel};
use super::ray::Composite;
use glam::{Vec3, Vec4};

/// Emission and absorption weights of an optical model.
#[derive(Clone, Copy, Debug)]
pub(super) struct Weights {
    pub emission: f32,
    pub absorption: f32,
}

impl Weights {
    pub fn of(model: OpticalModel) -> Weights {
        let (emission, absorption) = match model {
            OpticalModel::AbsorptionOnly => (0.0, 1.0),
            OpticalModel::EmissionOnly => (1.0, 0.0),
            OpticalModel::EmissionAbsorption => (1.0, 1.0),
        };
        Weights {
            emission,
            absorption,
        }
    }

    /// `(emitted colour, absorbed fraction)` of a step of premultiplied
    /// colour `e` and opacity `alpha`.
    #[inline(always)]
    pub(super) fn apply(self, e: Vec3, alpha: f32) -> (Vec3, f32) {
        (e * self.emission, alpha * self.absorption)
    }
}

/// The opacity at which early ray termination stops a ray: `ert`, or ∞
/// when it is off (`ert` = 1).
#[inline]
pub(super) fn ert_stop(ert: f32) -> f32 {
    if ert < 1.0 {
        ert
    } else {
        f32::INFINITY
    }
}

/// A compositing order: makes the compositor of each ray (which may
/// borrow the tile's scratch buffer).
pub(super) trait Order: Sync {
    type C<'s>: Composite;
    fn start(w: Weights, ert: f32, scratch: &mut Vec<(Vec3, f32)>) -> Self::C<'_>;
}

/// Front to back ([`Front`]).
pub(super) struct FrontToBack;
/// Back to front ([`Back`]).
pub(super) struct BackToFront;

impl Order for FrontToBack {
    type C<'s> = Front;
    #[inline(always)]
    fn start(w: Weights, ert: f32, _: &mut Vec<(Vec3, f32)>) -> Front {
        Front {
            c: Vec3::ZERO,
            a: 0.0,
            stop: ert_stop(ert),
            w,
        }
    }
}

impl Order for BackToFront {
    type C<'s> = Back<'s>;
    #[inline(always)]
    fn start(w: Weights, _: f32, scratch: &mut Vec<(Vec3, f32)>) -> Back<'_> {
        scratch.clear();
        Back { buf: scratch, w }
    }
}

/// Front to back (S4): `C += (1 − A)·e; A += (1 − A)·a`, stopping once `A`
/// reaches the early-termination threshold.
pub(super) struct Front {
    c: Vec3,
    a: f32,
    /// The threshold, or ∞ when termination is off (`ert` = 1).
    stop: f32,
    w: Weights,
}

impl Front {
    /// A ray's compositor that goes on from premultiplied colour and
    /// opacity `acc` (the SIMD packets' lanes, between their runs).
    #[inline(always)]
    #[cfg_attr(not(packets), allow(dead_code))]
    pub fn resume(acc: Vec4, w: Weights, stop: f32) -> Front {
        Front {
            c: acc.truncate(),
            a: acc.w,
            stop,
            w,
        }
    }

    /// The premultiplied colour and opacity so far.
    #[inline(always)]
    #[cfg_attr(not(packets), allow(dead_code))]
    pub fn acc(&self) -> Vec4 {
        self.c.extend(self.a)
    }
}

impl Composite for Front {
    #[inline(always)]
    fn add_premul(&mut self, e: Vec3, alpha: f32) -> bool {
        let (e, a) = self.w.apply(e, alpha);
        over_front(&mut self.c, &mut self.a, e, a);
        self.a >= self.stop
    }
    #[inline(always)]
    fn opacity(&self) -> f32 {
        self.a
    }
    #[inline(always)]
    fn finish(mut self, behind: Option<Vec3>) -> Vec4 {
        if let Some(s) = behind {
            over_front(&mut self.c, &mut self.a, s, 1.0);
        }
        self.c.extend(self.a)
    }
}

/// Back to front (S4): the samples are kept in order and composited from
/// the far end, `C = e + (1 − a)·C`, so no early termination is possible.
pub(super) struct Back<'s> {
    buf: &'s mut Vec<(Vec3, f32)>,
    w: Weights,
}

impl Composite for Back<'_> {
    #[inline(always)]
    fn add_premul(&mut self, e: Vec3, alpha: f32) -> bool {
        self.buf.push(self.w.apply(e, alpha));
        false
    }
    #[inline(always)]
    fn opacity(&self) -> f32 {
        0.0
    }
    #[inline(always)]
    fn finish(self, behind: Option<Vec3>) -> Vec4 {
        // Back to front starts from the opaque surface.
        let (mut c, mut a) = match behind {
            Some(s) => (s, 1.0),
            None => (Vec3::ZERO, 0.0),
        };
        for &(e, ab) in self.buf.iter().rev() {
            over_back(&mut c, &mut a, e, ab);
        }
        c.extend(a)
    }
}
