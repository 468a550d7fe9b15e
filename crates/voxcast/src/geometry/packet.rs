//! The first hits of a packet of camera rays at once (Wald et al. 2001,
//! *Interactive rendering with coherent ray tracing*): the BVH is walked
//! once for up to [`PACKET`] neighbouring rays, a node entered where any of
//! them meets it, and the boxes — the rooms' walls and furniture, an FDS
//! case's obstructions — and then the infinite planes (floors) tested for
//! every lane by loops the compiler turns into vector instructions.
//! Rectangles and triangles are tested lane by lane. The vector tests only
//! decide which shape is nearest: lane by lane, that shape's hit is then
//! computed again by its own scalar test, so a lane's hit is
//! [`Geometry::hit`]'s, bit for bit.

use super::shapes::{Aabb, Plane};
use super::{Geometry, Hit, Shape};
use glam::Vec3;

/// Rays per packet.
pub const PACKET: usize = 16;

/// A packet's rays, lane by lane: origins, directions and the
/// reciprocals of the directions. Lanes past the packet's rays repeat its
/// first ray.
pub(super) struct RaySoa {
    o: [[f32; PACKET]; 3],
    d: [[f32; PACKET]; 3],
    inv_d: [[f32; PACKET]; 3],
}

impl RaySoa {
    fn new(rays: &[(Vec3, Vec3)]) -> RaySoa {
        let mut r = RaySoa {
            o: [[0.0; PACKET]; 3],
            d: [[0.0; PACKET]; 3],
            inv_d: [[0.0; PACKET]; 3],
        };
        for l in 0..PACKET {
            let (o, d) = rays[if l < rays.len() { l } else { 0 }];
            for a in 0..3 {
                r.o[a][l] = o[a];
                r.d[a][l] = d[a];
            }
        }
        // `Vec3::ONE / d`, lanes at a time.
        for a in 0..3 {
            for l in 0..PACKET {
                r.inv_d[a][l] = 1.0 / r.d[a][l];
            }
        }
        r
    }
}

#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// Lane `l`'s slab test against `b` (Kay & Kajiya 1986): where it enters
/// and where it leaves the box's three slabs.
#[inline(always)]
fn slabs(b: &Aabb, r: &RaySoa, l: usize) -> (f32, f32) {
    let (mut near, mut far) = (f32::NEG_INFINITY, f32::INFINITY);
    for a in 0..3 {
        let t0 = (b.min[a] - r.o[a][l]) * r.inv_d[a][l];
        let t1 = (b.max[a] - r.o[a][l]) * r.inv_d[a][l];
        near = max(min(t0, t1), near);
        far = min(max(t0, t1), far);
    }
    (near, far)
}

/// Whether any lane's ray meets `b` between 0 and its `t_max`.
#[inline(always)]
pub(super) fn meets_any(b: &Aabb, r: &RaySoa, t_max: &[f32; PACKET]) -> bool {
    let mut any = 0u32;
    for (l, &tm) in t_max.iter().enumerate() {
        let (near, far) = slabs(b, r, l);
        any |= (max(near, 0.0) <= min(far, tm)) as u32;
    }
    any != 0
}

/// Box `b` (shape `me`) against every lane: where a lane's ray meets it
/// nearer than the lane's `t_max` (entering it, or leaving it from inside
/// as [`Aabb::hit`] does), `t_max` becomes that `t` and `id` becomes `me`.
#[inline(always)]
fn box_lanes(b: &Aabb, r: &RaySoa, t_max: &mut [f32; PACKET], id: &mut [u32; PACKET], me: u32) {
    for l in 0..PACKET {
        let (near, far) = slabs(b, r, l);
        let t = if near > 0.0 { near } else { far };
        let ok = near <= far && t > 0.0 && t < t_max[l];
        t_max[l] = if ok { t } else { t_max[l] };
        id[l] = if ok { me } else { id[l] };
    }
}

/// Infinite plane `p` (number `me`) against every lane, as [`Plane::hit`]
/// tests it: seen from the side its normal points to, nearer than the
/// lane's `t_max`.
#[inline(always)]
fn plane_lanes(p: &Plane, r: &RaySoa, t_max: &mut [f32; PACKET], id: &mut [u32; PACKET], me: u32) {
    let (n, q) = (p.normal, p.point);
    for l in 0..PACKET {
        let den = n.x * r.d[0][l] + n.y * r.d[1][l] + n.z * r.d[2][l];
        let t = (n.x * (q.x - r.o[0][l]) + n.y * (q.y - r.o[1][l]) + n.z * (q.z - r.o[2][l])) / den;
        let ok = den < 0.0 && t > 0.0 && t < t_max[l];
        t_max[l] = if ok { t } else { t_max[l] };
        id[l] = if ok { me } else { id[l] };
    }
}

impl Geometry {
    /// [`Geometry::hit`] with `t_min = 0`, `t_max = ∞` for each of `rays`
    /// (world origin and direction; at most [`PACKET`]) into `hits` (as
    /// many): the same hits, the BVH walked once for all of them.
    pub fn hit_packet(&self, rays: &[(Vec3, Vec3)], hits: &mut [Option<Hit>]) {
        assert!(rays.len() <= PACKET && hits.len() == rays.len());
        hits.fill(None);
        if rays.is_empty() {
            return;
        }
        let r = RaySoa::new(rays);
        let mut t_max = [f32::INFINITY; PACKET];
        // The nearest shape (`shapes.len() + i`: infinite plane `i`).
        let mut id = [u32::MAX; PACKET];
        self.bvh.traverse_packet(&r, &mut t_max, |prims, t_max| {
            for &p in prims {
                match &self.shapes[p as usize] {
                    Shape::Box(b) => box_lanes(b, &r, t_max, &mut id, p),
                    s => {
                        for (l, &(o, d)) in rays.iter().enumerate() {
                            if let Some((t, _)) = s.hit(o, d, 0.0, t_max[l]) {
                                t_max[l] = t;
                                id[l] = p;
                            }
                        }
                    }
                }
            }
        });
        let bounded = self.shapes.len();
        for (i, (p, _)) in self.infinite.iter().enumerate() {
            plane_lanes(p, &r, &mut t_max, &mut id, (bounded + i) as u32);
        }
        // Each lane's hit by its shape's own test, written in place (passed
        // back through a temporary, the hit cost a quarter of this function
        // in a store the next load could not forward).
        for (l, (&(o, d), hit)) in rays.iter().zip(hits).enumerate() {
            let s = id[l] as usize;
            let found = if id[l] == u32::MAX {
                continue;
            } else if s < bounded {
                self.shapes[s].hit(o, d, 0.0, f32::INFINITY).map(|(t, n)| {
                    *hit = Some(Hit {
                        t,
                        normal: self.shading_normal(s, o + d * t, n),
                        albedo: self.albedo[s],
                    });
                })
            } else {
                let (p, albedo) = &self.infinite[s - bounded];
                p.hit(o, d, 0.0, f32::INFINITY).map(|(t, normal)| {
                    *hit = Some(Hit {
                        t,
                        normal,
                        albedo: *albedo,
                    });
                })
            };
            // A ray that the lanes' rounding let in and the shape's test
            // does not (on a face's plane): the scalar walk.
            if found.is_none() {
                *hit = self.hit(o, d, 0.0, f32::INFINITY);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Parts, Plane, Triangle};
    use super::*;

    /// A room of everything: boxes (some overlapping, some inside others),
    /// rectangles, triangles and infinite planes.
    fn clutter() -> Geometry {
        let mut rng = crate::render::rng::Rng::new(0x2545_f491_4f6c_dd1d, 0);
        let mut rnd = move || rng.uniform();
        let mut v = |s: f32| Vec3::new(rnd(), rnd(), rnd()) * s;
        let mut p = Parts::default();
        for i in 0..40 {
            let lo = v(10.0);
            let hi = lo + v(3.0) + 0.01;
            p.push(
                Shape::Box(Aabb { min: lo, max: hi }),
                [i as f32 / 40.0, 0.5, 0.5],
            );
        }
        // One box on another's face, one flat.
        p.push(
            Shape::Box(Aabb {
                min: Vec3::new(2.0, 2.0, 2.0),
                max: Vec3::new(3.0, 3.0, 3.0),
            }),
            [0.1, 0.2, 0.3],
        );
        p.push(
            Shape::Box(Aabb {
                min: Vec3::new(3.0, 2.0, 2.0),
                max: Vec3::new(4.0, 3.0, 2.0),
            }),
            [0.3, 0.2, 0.1],
        );
        for i in 0..6 {
            let (pt, n) = (v(10.0), v(2.0) - 1.0);
            p.push(
                Shape::Rect(Plane::new(pt, n, Some([1.0 + i as f32 * 0.3, 0.7]))),
                [0.9, 0.1, i as f32 / 6.0],
            );
        }
        for i in 0..20 {
            let a = v(10.0);
            let t = Triangle {
                a,
                b: a + v(2.0),
                c: a + v(2.0),
            };
            p.push(Shape::Tri(t), [0.2, i as f32 / 20.0, 0.9]);
        }
        p.infinite.push((
            Plane::new(Vec3::new(0.0, 0.0, -0.5), Vec3::Z, None),
            Vec3::splat(0.4),
        ));
        p.infinite.push((
            Plane::new(Vec3::new(11.0, 0.0, 0.0), -Vec3::X, None),
            Vec3::splat(0.6),
        ));
        p.build()
    }

    /// The packet's hits are [`Geometry::hit`]'s, bit for bit: rays from
    /// outside and from inside boxes, along the axes and not, in packets
    /// of every size from 1 to 16.
    #[test]
    fn packet_hits_are_the_scalar_hits() {
        let g = clutter();
        let mut rng = crate::render::rng::Rng::new(0x9e37_79b9_7f4a_7c15, 0);
        let mut rnd = move || rng.uniform();
        let mut rays = Vec::new();
        for i in 0..4000 {
            // Coherent bundles (a camera's) and scattered rays.
            let o = if i % 2 == 0 {
                Vec3::new(-8.0, 5.0, 14.0) + Vec3::new(rnd(), rnd(), rnd()) * 0.5
            } else {
                Vec3::new(rnd(), rnd(), rnd()) * 12.0 - 1.0
            };
            let mut d = Vec3::new(rnd(), rnd(), rnd()) * 2.0 - 1.0;
            if i % 2 == 0 {
                d = (Vec3::new(5.0, 5.0, 5.0) + d * 5.0 - o).normalize();
            }
            if i % 7 == 3 {
                let a = i % 3;
                d = Vec3::ZERO;
                d[a] = if i % 2 == 0 { 1.0 } else { -1.0 };
            }
            rays.push((o, d.normalize()));
        }
        let (mut hit, mut boxes) = (0, 0);
        let mut at = 0;
        for n in (1..=PACKET).cycle() {
            if at + n > rays.len() {
                break;
            }
            let r = &rays[at..at + n];
            let mut got = vec![None; n];
            g.hit_packet(r, &mut got);
            for (i, (&(o, d), got)) in r.iter().zip(&got).enumerate() {
                let want = g.hit(o, d, 0.0, f32::INFINITY);
                assert_eq!(*got, want, "ray {} ({o}, {d})", at + i);
                hit += want.is_some() as u32;
                boxes += want.is_some_and(|h| h.normal.abs().max_element() == 1.0) as u32;
            }
            at += n;
        }
        // Both outcomes, and most hits on boxes or the planes.
        assert!(hit > 1000 && hit < 3900, "{hit} hits");
        assert!(boxes > 500, "{boxes} hits on boxes and planes");
    }
}
