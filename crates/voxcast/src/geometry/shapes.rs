//! Ray intersection with the opaque shapes: axis-aligned boxes, planes
//! (infinite or bounded by a rectangle) and triangles. Rays are
//! `o + d·t` in world coordinates; every test returns the nearest `t` in
//! `(t_min, t_max)` and the geometric normal there (not yet faced towards
//! the viewer: lighting is two-sided, see [`super::light`]).

use glam::Vec3;

/// An axis-aligned box `[min, max]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (the identity of [`Aabb::union`]).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn union(self, b: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(b.min),
            max: self.max.max(b.max),
        }
    }

    pub fn centre(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Entry and exit `t` of the slab test (Kay & Kajiya 1986) clipped to
    /// `[t_min, t_max]`, or `None` when the ray misses. `inv_d` is `1/d`.
    #[inline(always)]
    pub fn clip(&self, o: Vec3, inv_d: Vec3, t_min: f32, t_max: f32) -> Option<(f32, f32)> {
        let t0 = (self.min - o) * inv_d;
        let t1 = (self.max - o) * inv_d;
        // `min`/`max` drop the NaN of 0·∞ (a ray in a slab's plane), so that
        // axis does not decide.
        let near = t0.min(t1).max_element().max(t_min);
        let far = t0.max(t1).min_element().min(t_max);
        (near <= far).then_some((near, far))
    }

    /// The nearest surface hit in `(t_min, t_max)`: the entry face from
    /// outside, the exit face from inside.
    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(f32, Vec3)> {
        let inv_d = Vec3::ONE / d;
        let t0 = (self.min - o) * inv_d;
        let t1 = (self.max - o) * inv_d;
        let lo = t0.min(t1);
        let hi = t0.max(t1);
        let near = lo.max_element();
        let far = hi.min_element();
        if near > far {
            return None;
        }
        let (t, v) = if near > t_min {
            (near, lo)
        } else if far > t_min {
            (far, hi)
        } else {
            return None;
        };
        if t >= t_max {
            return None;
        }
        // The face is the axis whose slab gave `t`.
        let axis = if v.x == t {
            0
        } else if v.y == t {
            1
        } else {
            2
        };
        let mut n = Vec3::ZERO;
        n[axis] = if d[axis] > 0.0 { -1.0 } else { 1.0 };
        Some((t, n))
    }
}

/// A plane through `point` with unit `normal`, seen only from the side its
/// normal points to (from behind it is transparent: walls of a room with
/// inward normals hide nothing from a camera outside — the cut-away view of
/// indoor scenes); bounded to the rectangle
/// `|u·(p − point)| ≤ half_extent[0]`, `|v·(p − point)| ≤ half_extent[1]`
/// when `half_extent` is set, with the in-plane axes of [`plane_axes`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub point: Vec3,
    pub normal: Vec3,
    pub u: Vec3,
    pub v: Vec3,
    pub half_extent: Option<[f32; 2]>,
}

/// The in-plane axes `(u, v)` of a plane with unit normal `n`: `u` is +x
/// projected into the plane (+y when `n` is within about 25° of ±x), `v =
/// n × u`. So a floor (`n = +z`) has `u = +x, v = +y`; a wall facing +x has
/// `u = +y, v = +z`; a wall facing +y has `u = +x, v = −z`.
pub fn plane_axes(n: Vec3) -> (Vec3, Vec3) {
    let e = if n.x.abs() < 0.9 { Vec3::X } else { Vec3::Y };
    let u = (e - n * e.dot(n)).normalize();
    (u, n.cross(u))
}

impl Plane {
    /// A plane from a point and a (not necessarily unit) normal.
    pub fn new(point: Vec3, normal: Vec3, half_extent: Option<[f32; 2]>) -> Plane {
        let normal = normal.normalize();
        let (u, v) = plane_axes(normal);
        Plane {
            point,
            normal,
            u,
            v,
            half_extent,
        }
    }

    /// The bounding box of a bounded plane.
    pub fn bounds(&self) -> Option<Aabb> {
        let [a, b] = self.half_extent?;
        let r = (self.u * a).abs() + (self.v * b).abs();
        Some(Aabb {
            min: self.point - r,
            max: self.point + r,
        })
    }

    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(f32, Vec3)> {
        let den = self.normal.dot(d);
        // One-sided: only rays travelling against the normal hit.
        if den >= 0.0 {
            return None;
        }
        let t = self.normal.dot(self.point - o) / den;
        if !(t > t_min && t < t_max) {
            return None;
        }
        if let Some([a, b]) = self.half_extent {
            let q = o + d * t - self.point;
            if q.dot(self.u).abs() > a || q.dot(self.v).abs() > b {
                return None;
            }
        }
        Some((t, self.normal))
    }
}

/// A triangle `a, b, c`; its geometric normal is `(b − a) × (c − a)`
/// (counter-clockwise faces front).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    pub a: Vec3,
    pub b: Vec3,
    pub c: Vec3,
}

impl Triangle {
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.a.min(self.b).min(self.c),
            max: self.a.max(self.b).max(self.c),
        }
    }

    /// Möller & Trumbore (1997): `t` and the unit geometric normal.
    #[inline]
    pub fn hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<(f32, Vec3)> {
        let e1 = self.b - self.a;
        let e2 = self.c - self.a;
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return None;
        }
        let inv = 1.0 / det;
        let s = o - self.a;
        let u = s.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = s.cross(e1);
        let v = d.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(q) * inv;
        (t > t_min && t < t_max).then(|| (t, e1.cross(e2).normalize()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f32 = 1e-5;

    #[test]
    fn box_entry_face_and_normal() {
        let b = Aabb {
            min: Vec3::new(1.0, 2.0, 3.0),
            max: Vec3::new(2.0, 4.0, 6.0),
        };
        // Along +y through the middle: enters the y = 2 face.
        let (t, n) = b
            .hit(Vec3::new(1.5, 0.0, 4.0), Vec3::Y, 0.0, f32::INFINITY)
            .unwrap();
        assert!((t - 2.0).abs() < EPS);
        assert_eq!(n, -Vec3::Y);
        // Diagonal ray: hits x = 1 at t·(1/√2) … computed by hand.
        let d = Vec3::new(1.0, 0.0, 1.0).normalize();
        let (t, n) = b
            .hit(Vec3::new(0.0, 3.0, 2.5), d, 0.0, f32::INFINITY)
            .unwrap();
        // x reaches 1 at t = √2 (z = 3.5, inside [3, 6]).
        assert!((t - 2f32.sqrt()).abs() < EPS, "{t}");
        assert_eq!(n, -Vec3::X);
        // From inside: the exit face.
        let (t, n) = b
            .hit(Vec3::new(1.5, 3.0, 4.0), -Vec3::Z, 0.0, f32::INFINITY)
            .unwrap();
        assert!((t - 1.0).abs() < EPS);
        assert_eq!(n, Vec3::Z);
        // Misses, behind, beyond t_max.
        assert!(b.hit(Vec3::new(5.0, 0.0, 4.0), Vec3::Y, 0.0, 1e9).is_none());
        assert!(b.hit(Vec3::new(1.5, 9.0, 4.0), Vec3::Y, 0.0, 1e9).is_none());
        assert!(b.hit(Vec3::new(1.5, 0.0, 4.0), Vec3::Y, 0.0, 1.9).is_none());
        // An axis-parallel ray in a face plane's slab does not NaN its way in.
        assert!(b.hit(Vec3::new(0.0, 3.0, 4.0), Vec3::X, 0.0, 1e9).is_some());
        assert!(b.hit(Vec3::new(0.0, 5.0, 4.0), Vec3::X, 0.0, 1e9).is_none());
    }

    #[test]
    fn plane_infinite_and_bounded() {
        let p = Plane::new(Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.0, 0.0, 2.0), None);
        let d = Vec3::new(0.0, 0.6, -0.8);
        let (t, n) = p.hit(Vec3::new(0.0, 0.0, 5.0), d, 0.0, 1e9).unwrap();
        assert!((t - 5.0).abs() < EPS, "{t}"); // 4 down at 0.8 per unit
        assert_eq!(n, Vec3::Z);
        assert!(p.hit(Vec3::new(0.0, 0.0, 5.0), Vec3::X, 0.0, 1e9).is_none());
        assert!(p.hit(Vec3::new(0.0, 0.0, 5.0), -d, 0.0, 1e9).is_none());
        // One-sided: from below, the plane lets the ray through.
        assert!(p.hit(Vec3::new(0.0, 0.0, -5.0), -d, 0.0, 1e9).is_none());
        // Floor axes: u = +x, v = +y; half extents 2 × 1.
        let r = Plane::new(Vec3::ZERO, Vec3::Z, Some([2.0, 1.0]));
        assert_eq!((r.u, r.v), (Vec3::X, Vec3::Y));
        let down = -Vec3::Z;
        assert!(r.hit(Vec3::new(1.9, 0.9, 1.0), down, 0.0, 9.0).is_some());
        assert!(r.hit(Vec3::new(2.1, 0.0, 1.0), down, 0.0, 9.0).is_none());
        assert!(r.hit(Vec3::new(0.0, 1.1, 1.0), down, 0.0, 9.0).is_none());
        let b = r.bounds().unwrap();
        assert_eq!(
            (b.min, b.max),
            (Vec3::new(-2., -1., 0.), Vec3::new(2., 1., 0.))
        );
        // Wall axes.
        let (u, v) = plane_axes(Vec3::X);
        assert_eq!((u, v), (Vec3::Y, Vec3::Z));
        let (u, v) = plane_axes(Vec3::Y);
        assert!((u - Vec3::X).length() < EPS && (v + Vec3::Z).length() < EPS);
    }

    #[test]
    fn triangle_inside_edges_and_outside() {
        let tri = Triangle {
            a: Vec3::new(0.0, 0.0, 0.0),
            b: Vec3::new(1.0, 0.0, 0.0),
            c: Vec3::new(0.0, 1.0, 0.0),
        };
        let o = |x: f32, y: f32| Vec3::new(x, y, 3.0);
        let (t, n) = tri.hit(o(0.25, 0.25), -Vec3::Z, 0.0, 9.0).unwrap();
        assert!((t - 3.0).abs() < EPS);
        assert_eq!(n, Vec3::Z);
        // From below: same normal (geometric, not faced).
        let (t, n) = tri
            .hit(Vec3::new(0.25, 0.25, -2.0), Vec3::Z, 0.0, 9.0)
            .unwrap();
        assert!((t - 2.0).abs() < EPS && n == Vec3::Z);
        assert!(tri.hit(o(0.6, 0.6), -Vec3::Z, 0.0, 9.0).is_none()); // past the hypotenuse
        assert!(tri.hit(o(-0.01, 0.5), -Vec3::Z, 0.0, 9.0).is_none());
        assert!(tri.hit(o(0.25, 0.25), -Vec3::Z, 0.0, 2.5).is_none()); // beyond t_max
        assert!(tri.hit(o(0.25, 0.25), Vec3::X, 0.0, 9.0).is_none()); // parallel
                                                                      // A slanted ray hits where the plane equation says.
        let d = Vec3::new(0.1, 0.1, -1.0).normalize();
        let (t, _) = tri.hit(o(0.1, 0.1), d, 0.0, 9.0).unwrap();
        let p = o(0.1, 0.1) + d * t;
        assert!(p.z.abs() < EPS && (p.x - 0.4).abs() < EPS && (p.y - 0.4).abs() < EPS);
    }
}
