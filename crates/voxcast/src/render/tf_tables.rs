//! What a render derives from its transfer function and step, kept for the
//! renders after it with the same ones.

use super::blocks::BlockGrid;
use super::lod::{LodParams, LodRay};
use super::octree::Octree;
use super::Derived;
use crate::transfer::{Lut, TransferFunction};
use glam::Vec3;
use std::sync::{Arc, Mutex, OnceLock};

/// How many transfer functions and steps a renderer keeps the tables of,
/// and how many sets of level tables (and of `adaptive`'s changes) each
/// keeps: a bench alternating methods with different levels rebuilds none
/// of them.
const KEPT: usize = 8;

/// What a render derives from its transfer function and step: the baked
/// table, the blocks' emptiness, the box of the blocks that are not empty,
/// the levels' premultiplied tables, `adaptive`'s change of the
/// classified signal per block and `lod`'s leaves and classes. Built by the first render with that
/// transfer function and step and kept for the renders after it — a
/// turning camera in the viewer, the bench's repeats — which rebuilt all
/// of it every frame before: 1.3 ms a frame on the teapot CT with
/// `uniform`, 1.8 ms with `adaptive+grouped` (docs/engine.md), most of it
/// the emptiness (the transfer function's largest opacity over each
/// block's range) and the table (4096 evaluations of the transfer
/// function).
pub(super) struct TfTables {
    tf: TransferFunction,
    step: f32,
    /// The transfer function baked for steps of `step` unit lengths.
    pub lut: Lut,
    /// Per block, whether the transfer function hides all of it.
    pub empty: Vec<bool>,
    /// The share of blocks `empty` (0 … 1).
    pub empty_share: f32,
    /// [`BlockGrid::occupied_box`] of `empty` in the volume's sample box
    /// (the same for every render of one volume).
    occupied: OnceLock<(Vec3, Vec3)>,
    /// The premultiplied tables of steps of the given lengths, end to end.
    levels: Mutex<Vec<Levels>>,
    /// [`BlockGrid::classified_change`] by shade weight.
    change: Mutex<Vec<(f32, Arc<Vec<f32>>)>>,
    /// `lod`'s leaves and classes by its parameters and the voxel's world
    /// length.
    lod: Mutex<Vec<(LodParams, u32, Arc<LodRay>)>>,
}

/// Step lengths (unit lengths), and their premultiplied tables end to end.
type Levels = (Vec<f32>, Arc<Vec<[f32; 4]>>);

impl TfTables {
    /// Whether the transfer function hides enough of the blocks for
    /// skipping them to pay for its tests ([`SKIP_PAYS`](super::SKIP_PAYS)).
    pub fn skipping_pays(&self) -> bool {
        self.empty_share >= super::SKIP_PAYS
    }

    /// The box of the blocks that are not empty within `lo..hi`, the
    /// volume's sample box ([`BlockGrid::occupied_box`]).
    pub fn occupied(&self, blocks: &BlockGrid, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
        *self
            .occupied
            .get_or_init(|| blocks.occupied_box(&self.empty, lo, hi))
    }

    /// The premultiplied tables ([`Lut::premultiplied`]) for steps of
    /// `ratios` unit lengths, one after the other.
    pub fn levels(&self, ratios: &[f32]) -> Arc<Vec<[f32; 4]>> {
        let same = |r: &[f32]| {
            r.iter()
                .map(|x| x.to_bits())
                .eq(ratios.iter().map(|x| x.to_bits()))
        };
        kept(
            &self.levels,
            |(r, _)| same(r),
            || {
                let t: Vec<[f32; 4]> = ratios
                    .iter()
                    .flat_map(|&r| *self.lut.premultiplied(r))
                    .collect();
                (ratios.to_vec(), Arc::new(t))
            },
        )
        .1
    }

    /// `adaptive`'s `k` per block ([`BlockGrid::classified_change`]) with
    /// the largest derivatives `max_gradient` and shade weight `shade`.
    pub fn change(&self, blocks: &BlockGrid, max_gradient: &[f32], shade: f32) -> Arc<Vec<f32>> {
        kept(
            &self.change,
            |(s, _)| s.to_bits() == shade.to_bits(),
            || {
                let k = blocks.classified_change(&self.lut, max_gradient, &self.empty, shade);
                (shade, Arc::new(k))
            },
        )
        .1
    }

    /// `lod`'s leaves (their amounts of cloud in `tree`) and its classes'
    /// steps and step opacities with parameters `params`, `unit` the world
    /// length of a voxel.
    pub fn lod(&self, tree: &Octree, params: &LodParams, unit: f32) -> Arc<LodRay> {
        kept(
            &self.lod,
            |(p, u, _)| p == params && *u == unit.to_bits(),
            || {
                let m = LodRay::new(tree, &self.lut, &self.empty, params, self.step, unit);
                (*params, unit.to_bits(), Arc::new(m))
            },
        )
        .2
    }
}

/// The entry of `list` that `is` picks, or a new one from `make` (the
/// oldest dropped past [`KEPT`]).
fn kept<E: Clone>(list: &Mutex<Vec<E>>, is: impl Fn(&E) -> bool, make: impl FnOnce() -> E) -> E {
    // A poisoned lock only means another render panicked while building;
    // the list itself is always consistent.
    let mut list = list.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(e) = list.iter().find(|e| is(e)) {
        return e.clone();
    }
    let e = make();
    if list.len() == KEPT {
        list.remove(0);
    }
    list.push(e.clone());
    e
}

impl Derived {
    /// The tables of transfer function `tf` for steps of `step` unit
    /// lengths: those of an earlier render with the same (the last
    /// [`KEPT`] are kept: the viewer's previews take twice the step of its
    /// full frames), else new ones.
    pub(super) fn tf_tables(&self, tf: &TransferFunction, step: f32) -> Arc<TfTables> {
        kept(
            &self.tf_tables,
            |t| t.tf == *tf && t.step.to_bits() == step.to_bits(),
            || {
                let empty = self.blocks.empty_flags(tf);
                let hidden = empty.iter().filter(|&&e| e).count();
                Arc::new(TfTables {
                    tf: tf.clone(),
                    step,
                    lut: Lut::new(tf, step),
                    empty_share: hidden as f32 / empty.len().max(1) as f32,
                    empty,
                    occupied: OnceLock::new(),
                    levels: Mutex::new(Vec::new()),
                    change: Mutex::new(Vec::new()),
                    lod: Mutex::new(Vec::new()),
                })
            },
        )
    }
}
