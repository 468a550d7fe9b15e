//! Transport on the MAC grid: trilinear sampling of staggered fields,
//! semi-Lagrangian back-tracing (Stam 1999; Fedkiw, Stam & Jensen 2001 §3,
//! eq. 5) for velocity and temperature, and a conservative flux-form
//! update for the smoke density, so that the smoke's mass changes only by
//! what the fire injects and what leaves through the openings.

/// A scalar field on a regular lattice whose point `(i, j, k)` sits at
/// `(i, j, k) + offset` in cell units.
#[derive(Clone, Copy)]
pub struct Field<'a> {
    pub data: &'a [f32],
    pub dims: [usize; 3],
    pub offset: [f32; 3],
}

impl Field<'_> {
    /// The stored value at lattice point `(i, j, k)`.
    #[inline(always)]
    pub fn get(&self, i: usize, j: usize, k: usize) -> f32 {
        self.data[i + self.dims[0] * (j + self.dims[1] * k)]
    }

    /// Trilinear interpolation at `p` (cell units), clamped to the lattice.
    #[inline(always)]
    pub fn sample(&self, p: [f32; 3]) -> f32 {
        let [nx, ny, nz] = self.dims;
        self.sample_at(
            lattice(p[0] - self.offset[0], nx),
            lattice(p[1] - self.offset[1], ny),
            lattice(p[2] - self.offset[2], nz),
        )
    }

    /// Trilinear interpolation from the lower lattice index and fraction
    /// along each axis ([`lattice`]).
    #[inline(always)]
    fn sample_at(
        &self,
        (i, fx): (usize, f32),
        (j, fy): (usize, f32),
        (k, fz): (usize, f32),
    ) -> f32 {
        let [nx, ny, nz] = self.dims;
        let (di, dj, dk) = (
            usize::from(nx > 1),
            if ny > 1 { nx } else { 0 },
            if nz > 1 { nx * ny } else { 0 },
        );
        let c = i + nx * (j + ny * k);
        let d = self.data;
        // One bounds check for the far corner; the other seven are below it.
        assert!(
            c + dk + dj + di < d.len(),
            "field data shorter than its dims"
        );
        // SAFETY: every index is c + a subset of {di, dj, dk}, each ≥ 0,
        // so at most the one just checked.
        let at = |o: usize| unsafe { *d.get_unchecked(c + o) };
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(at(0), at(di), fx);
        let x10 = lerp(at(dj), at(dj + di), fx);
        let x01 = lerp(at(dk), at(dk + di), fx);
        let x11 = lerp(at(dk + dj), at(dk + dj + di), fx);
        lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz)
    }
}

/// The lower lattice index and the fraction towards the next one of the
/// coordinate `x` on an axis of `n` points, clamped to `[0, n − 1]`.
#[inline(always)]
fn lattice(x: f32, n: usize) -> (usize, f32) {
    let x = x.clamp(0.0, (n - 1) as f32);
    // x ≥ 0 and small: the 32-bit conversion is exact and cheap.
    let i = (x as i32 as usize).min(n.saturating_sub(2));
    (i, x - i as f32)
}

/// The three staggered velocity components (MAC grid): `u` on x faces
/// (`(nx+1)·ny·nz`), `v` on y faces, `w` on z faces, in m/s.
#[derive(Clone, Copy)]
pub struct Mac<'a> {
    pub u: Field<'a>,
    pub v: Field<'a>,
    pub w: Field<'a>,
}

impl<'a> Mac<'a> {
    pub fn new(dims: [usize; 3], u: &'a [f32], v: &'a [f32], w: &'a [f32]) -> Mac<'a> {
        let [nx, ny, nz] = dims;
        Mac {
            u: Field {
                data: u,
                dims: [nx + 1, ny, nz],
                offset: [0.0, 0.5, 0.5],
            },
            v: Field {
                data: v,
                dims: [nx, ny + 1, nz],
                offset: [0.5, 0.0, 0.5],
            },
            w: Field {
                data: w,
                dims: [nx, ny, nz + 1],
                offset: [0.5, 0.5, 0.0],
            },
        }
    }

    /// Velocity at `p` (cell units).
    #[inline(always)]
    pub fn at(&self, p: [f32; 3]) -> [f32; 3] {
        // Along each axis one component's lattice sits on the faces and the
        // other two on the centres: two lattice look-ups per axis, not three.
        let (u, v, w) = (&self.u, &self.v, &self.w);
        let x_face = lattice(p[0] - u.offset[0], u.dims[0]);
        let x_cell = lattice(p[0] - v.offset[0], v.dims[0]);
        let y_face = lattice(p[1] - v.offset[1], v.dims[1]);
        let y_cell = lattice(p[1] - u.offset[1], u.dims[1]);
        let z_face = lattice(p[2] - w.offset[2], w.dims[2]);
        let z_cell = lattice(p[2] - u.offset[2], u.dims[2]);
        [
            u.sample_at(x_face, y_cell, z_cell),
            v.sample_at(x_cell, y_face, z_cell),
            w.sample_at(x_cell, y_cell, z_face),
        ]
    }

    /// Where the particle now at `p` was `dt` ago: second-order
    /// Runge–Kutta (midpoint) back-trace; `scale = dt / h` turns m/s into
    /// cells.
    #[inline(always)]
    pub fn trace_back(&self, p: [f32; 3], scale: f32) -> [f32; 3] {
        self.trace_back_from(p, self.at(p), scale)
    }

    /// [`Mac::trace_back`] with the velocity at `p` already known.
    #[inline(always)]
    pub fn trace_back_from(&self, p: [f32; 3], v0: [f32; 3], scale: f32) -> [f32; 3] {
        let mid = [
            p[0] - 0.5 * scale * v0[0],
            p[1] - 0.5 * scale * v0[1],
            p[2] - 0.5 * scale * v0[2],
        ];
        let v1 = self.at(mid);
        [
            p[0] - scale * v1[0],
            p[1] - scale * v1[1],
            p[2] - scale * v1[2],
        ]
    }

    /// The velocity at the centre of cell `(i, j, k)`: each component the
    /// mean of the cell's two faces (what [`Mac::at`] interpolates there).
    #[inline(always)]
    pub fn at_centre(&self, i: usize, j: usize, k: usize) -> [f32; 3] {
        let (u, v, w) = (&self.u, &self.v, &self.w);
        [
            0.5 * (u.get(i, j, k) + u.get(i + 1, j, k)),
            0.5 * (v.get(i, j, k) + v.get(i, j + 1, k)),
            0.5 * (w.get(i, j, k) + w.get(i, j, k + 1)),
        ]
    }

    /// The velocity at the inner face `(i, j, k)` of component `axis`
    /// (`1 ≤ [i, j, k][axis] < n[axis]`): its own component as stored, the
    /// other two the mean of the four faces around it (what [`Mac::at`]
    /// interpolates there, without the search and weights).
    #[inline(always)]
    pub fn at_face(&self, axis: usize, i: usize, j: usize, k: usize) -> [f32; 3] {
        let (u, v, w) = (&self.u, &self.v, &self.w);
        let quad = |f: &Field, a: [usize; 3], b: [usize; 3], c: [usize; 3], d: [usize; 3]| {
            0.25 * (f.get(a[0], a[1], a[2])
                + f.get(b[0], b[1], b[2])
                + f.get(c[0], c[1], c[2])
                + f.get(d[0], d[1], d[2]))
        };
        match axis {
            // x face between cells i − 1 and i.
            0 => [
                u.get(i, j, k),
                quad(
                    v,
                    [i - 1, j, k],
                    [i, j, k],
                    [i - 1, j + 1, k],
                    [i, j + 1, k],
                ),
                quad(
                    w,
                    [i - 1, j, k],
                    [i, j, k],
                    [i - 1, j, k + 1],
                    [i, j, k + 1],
                ),
            ],
            1 => [
                quad(
                    u,
                    [i, j - 1, k],
                    [i + 1, j - 1, k],
                    [i, j, k],
                    [i + 1, j, k],
                ),
                v.get(i, j, k),
                quad(
                    w,
                    [i, j - 1, k],
                    [i, j, k],
                    [i, j - 1, k + 1],
                    [i, j, k + 1],
                ),
            ],
            _ => [
                quad(
                    u,
                    [i, j, k - 1],
                    [i + 1, j, k - 1],
                    [i, j, k],
                    [i + 1, j, k],
                ),
                quad(
                    v,
                    [i, j, k - 1],
                    [i, j + 1, k - 1],
                    [i, j, k],
                    [i, j + 1, k],
                ),
                w.get(i, j, k),
            ],
        }
    }
}

/// minmod slope limiter: the smaller one-sided difference, 0 at extrema,
/// which keeps the second-order flux free of new over- and undershoots.
#[inline(always)]
fn minmod(a: f32, b: f32) -> f32 {
    if a * b <= 0.0 {
        0.0
    } else if a.abs() < b.abs() {
        a
    } else {
        b
    }
}

/// The amount crossing one face per sub-step, in density × cells (a
/// limited second-order upwind flux): `c` is the face's Courant number
/// (velocity · dt / h, positive towards `r`), `ll, l, r, rr` the four cell
/// values along the axis.
#[inline(always)]
pub fn face_flux(c: f32, ll: f32, l: f32, r: f32, rr: f32) -> f32 {
    if c > 0.0 {
        c * (l + 0.5 * (1.0 - c) * minmod(l - ll, r - l))
    } else if c < 0.0 {
        c * (r - 0.5 * (1.0 + c) * minmod(r - l, rr - r))
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sampling_reproduces_linear_fields() {
        let dims = [5, 4, 3];
        let data: Vec<f32> = (0..60)
            .map(|c| {
                let (i, j, k) = (c % 5, (c / 5) % 4, c / 20);
                1.0 + 2.0 * i as f32 - 0.5 * j as f32 + 3.0 * k as f32
            })
            .collect();
        let f = Field {
            data: &data,
            dims,
            offset: [0.5, 0.0, 0.5],
        };
        let p = [2.3, 1.7, 1.1];
        let expect = 1.0 + 2.0 * (2.3 - 0.5) - 0.5 * 1.7 + 3.0 * (1.1 - 0.5);
        assert!((f.sample(p) - expect).abs() < 1e-5);
        // Clamped outside.
        assert_eq!(f.sample([-3.0, 0.0, 0.5]), 1.0);
    }

    /// The velocity at faces and cell centres read from the stored values
    /// is what trilinear interpolation gives there, on a random field.
    #[test]
    fn face_and_centre_velocities_match_interpolation() {
        let [nx, ny, nz] = [6usize, 5, 4];
        let mut seed = 99u64;
        let mut rnd = |n: usize| -> Vec<f32> {
            (0..n)
                .map(|_| {
                    seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                    ((seed >> 33) as f32 / (1u64 << 31) as f32) - 0.5
                })
                .collect()
        };
        let (u, v, w) = (
            rnd((nx + 1) * ny * nz),
            rnd(nx * (ny + 1) * nz),
            rnd(nx * ny * (nz + 1)),
        );
        let mac = Mac::new([nx, ny, nz], &u, &v, &w);
        let close = |a: [f32; 3], b: [f32; 3]| (0..3).all(|i| (a[i] - b[i]).abs() < 1e-6);
        let mut checked = 0;
        for axis in 0..3 {
            let mut fd = [nx, ny, nz];
            fd[axis] += 1;
            for k in 0..fd[2] {
                for j in 0..fd[1] {
                    for i in 0..fd[0] {
                        let q = [i, j, k];
                        if q[axis] == 0 || q[axis] == fd[axis] - 1 {
                            continue;
                        }
                        let mut p = [i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5];
                        p[axis] -= 0.5;
                        let (a, b) = (mac.at_face(axis, i, j, k), mac.at(p));
                        assert!(close(a, b), "axis {axis} face {q:?}: {a:?} vs {b:?}");
                        checked += 1;
                    }
                }
            }
        }
        assert!(checked > 200);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p = [i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5];
                    assert!(close(mac.at_centre(i, j, k), mac.at(p)));
                }
            }
        }
    }

    #[test]
    fn flux_is_upwind_and_bounded() {
        // A constant field moves at its Courant number.
        assert!((face_flux(0.3, 2.0, 2.0, 2.0, 2.0) - 0.6).abs() < 1e-6);
        assert!((face_flux(-0.3, 2.0, 2.0, 2.0, 2.0) + 0.6).abs() < 1e-6);
        // Nothing flows out of an empty upwind cell.
        assert_eq!(face_flux(0.4, 5.0, 0.0, 3.0, 1.0), 0.0);
    }
}
