//! A bounding-volume hierarchy over the bounded shapes, so that a ray costs
//! O(log n) box tests instead of one test per triangle. Built once per
//! geometry by median splits along the widest axis of the centroids;
//! traversed front to back with a fixed-size stack (no allocation per ray).

use super::packet::{meets_any, RaySoa, PACKET};
use super::shapes::Aabb;
use glam::Vec3;

/// Primitives per leaf at most.
const LEAF: usize = 4;
/// Traversal stack depth; median splits give depth ≤ log2(n / LEAF) + 1, so
/// 64 covers any count that fits in memory.
const STACK: usize = 64;

#[derive(Clone, Copy, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `order`; inner: index of the left child (the
    /// right child follows the left subtree, at `right`).
    first: u32,
    /// Leaf: primitive count (> 0); inner: 0.
    count: u32,
    right: u32,
}

/// The hierarchy: nodes and the primitive order the leaves index into.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
}

impl Bvh {
    /// Builds over primitives with the given bounds.
    pub fn build(bounds: &[Aabb]) -> Bvh {
        let mut bvh = Bvh {
            nodes: Vec::with_capacity(2 * bounds.len() / LEAF + 1),
            order: (0..bounds.len() as u32).collect(),
        };
        if !bounds.is_empty() {
            bvh.split(bounds, 0, bounds.len());
        }
        bvh
    }

    /// Builds the subtree over `order[lo..hi]`; returns its node index.
    fn split(&mut self, bounds: &[Aabb], lo: usize, hi: usize) -> u32 {
        let b = self.order[lo..hi]
            .iter()
            .fold(Aabb::EMPTY, |a, &i| a.union(bounds[i as usize]));
        let me = self.nodes.len() as u32;
        self.nodes.push(Node {
            bounds: b,
            first: lo as u32,
            count: (hi - lo) as u32,
            right: 0,
        });
        if hi - lo <= LEAF {
            return me;
        }
        let c = self.order[lo..hi].iter().fold(Aabb::EMPTY, |a, &i| {
            let p = bounds[i as usize].centre();
            a.union(Aabb { min: p, max: p })
        });
        let axis = (c.max - c.min).max_position();
        let mid = (lo + hi) / 2;
        let key = |i: &u32| bounds[*i as usize].centre()[axis];
        self.order[lo..hi].select_nth_unstable_by(mid - lo, |a, b| key(a).total_cmp(&key(b)));
        let left = self.split(bounds, lo, mid);
        let right = self.split(bounds, mid, hi);
        let n = &mut self.nodes[me as usize];
        n.first = left;
        n.count = 0;
        n.right = right;
        me
    }

    /// Bounds of everything, if anything.
    pub fn bounds(&self) -> Option<Aabb> {
        self.nodes.first().map(|n| n.bounds)
    }

    /// The nearest hit: `test(primitive, t_max)` returns the primitive's hit
    /// `t` (< `t_max`) or `None`; the result is the nearest `(t, primitive,
    /// payload)`. With `any`, stops at the first hit (shadow rays).
    #[inline]
    pub fn traverse<H: Copy>(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        mut t_max: f32,
        any: bool,
        mut test: impl FnMut(usize, f32) -> Option<(f32, H)>,
    ) -> Option<(f32, H)> {
        if self.nodes.is_empty() {
            return None;
        }
        let inv_d = Vec3::ONE / d;
        let mut stack = [0u32; STACK];
        let mut sp = 1usize;
        let mut best = None;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if node.bounds.clip(o, inv_d, t_min, t_max).is_none() {
                continue;
            }
            if node.count > 0 {
                let first = node.first as usize;
                for &p in &self.order[first..first + node.count as usize] {
                    if let Some((t, h)) = test(p as usize, t_max) {
                        t_max = t;
                        best = Some((t, h));
                        if any {
                            return best;
                        }
                    }
                }
                continue;
            }
            // Visit the nearer child first so `t_max` shrinks early.
            let (l, r) = (node.first, node.right);
            let near = |i: u32| {
                self.nodes[i as usize]
                    .bounds
                    .clip(o, inv_d, t_min, t_max)
                    .map_or(f32::INFINITY, |c| c.0)
            };
            let (a, b) = if near(l) <= near(r) { (l, r) } else { (r, l) };
            if sp + 2 <= STACK {
                stack[sp] = b;
                stack[sp + 1] = a;
                sp += 2;
            }
        }
        best
    }

    /// [`Bvh::traverse`] for a packet of rays: a node is entered where any
    /// lane's ray meets it before the lane's `t_max`, and `leaf(primitives,
    /// t_max)` tests a leaf's primitives against every lane, lowering
    /// `t_max` where one is nearer. Children are taken left first (the
    /// lanes' nearest hits do not depend on the order, only the work does).
    #[inline]
    pub(super) fn traverse_packet(
        &self,
        r: &RaySoa,
        t_max: &mut [f32; PACKET],
        mut leaf: impl FnMut(&[u32], &mut [f32; PACKET]),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; STACK];
        let mut sp = 1usize;
        while sp > 0 {
            sp -= 1;
            let node = &self.nodes[stack[sp] as usize];
            if !meets_any(&node.bounds, r, t_max) {
                continue;
            }
            if node.count > 0 {
                let first = node.first as usize;
                leaf(&self.order[first..first + node.count as usize], t_max);
            } else if sp + 2 <= STACK {
                stack[sp] = node.right;
                stack[sp + 1] = node.first;
                sp += 2;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_nearest_of_many_and_matches_brute_force() {
        // A 20×20 grid of unit cubes at z = 0 with heights varying, looked at
        // from above and from the side.
        let mut boxes = Vec::new();
        for j in 0..20 {
            for i in 0..20 {
                let h = 1.0 + ((i * 7 + j * 3) % 5) as f32;
                boxes.push(Aabb {
                    min: Vec3::new(i as f32, j as f32, 0.0),
                    max: Vec3::new(i as f32 + 0.8, j as f32 + 0.8, h),
                });
            }
        }
        let bvh = Bvh::build(&boxes);
        let rays = [
            (Vec3::new(3.4, 5.4, 20.0), -Vec3::Z),
            (Vec3::new(-5.0, 7.3, 0.5), Vec3::X),
            (
                Vec3::new(-5.0, -5.0, 3.0),
                Vec3::new(1.0, 1.0, -0.1).normalize(),
            ),
            (Vec3::new(10.9, 10.9, 20.0), -Vec3::Z), // in a gap: misses
        ];
        for (o, d) in rays {
            let brute = boxes
                .iter()
                .enumerate()
                .filter_map(|(i, b)| b.hit(o, d, 0.0, f32::INFINITY).map(|h| (h.0, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let got = bvh.traverse(o, d, 0.0, f32::INFINITY, false, |i, tm| {
                boxes[i].hit(o, d, 0.0, tm).map(|h| (h.0, i))
            });
            assert_eq!(got, brute, "{o} {d}");
        }
        assert!(bvh
            .traverse(rays[3].0, rays[3].1, 0.0, 1e9, true, |i, tm| boxes[i]
                .hit(rays[3].0, rays[3].1, 0.0, tm)
                .map(|h| (h.0, i)))
            .is_none());
        assert_eq!(Bvh::build(&[]).bounds(), None);
    }
}
