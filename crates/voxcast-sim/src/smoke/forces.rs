//! The body forces of a step: Boussinesq buoyancy (Fedkiw 2001 eq. 8) and
//! vorticity confinement (eq. 9–11).

use super::projection::for_free_faces;
use super::Smoke;
use crate::pressure::SOLID;
use rayon::prelude::*;

impl Smoke {
    /// Boussinesq buoyancy, Fedkiw 2001 eq. 8: `f = −α ρ ẑ + β (T − T_amb) ẑ`
    /// on the z faces, from the average of the two cells.
    pub(super) fn add_buoyancy(&mut self, dt: f32) {
        let [nx, ny, _] = self.dims;
        let (a, b) = (self.scene.alpha, self.scene.beta);
        let (rho, t, free) = (&self.density, &self.temperature, &self.free_w);
        self.w
            .par_chunks_mut(nx * ny)
            .enumerate()
            .skip(1)
            .for_each(|(k, ws)| {
                for (c, wv) in ws.iter_mut().enumerate() {
                    let f = c + k * nx * ny;
                    if !free[f] || k * nx * ny + c >= rho.len() {
                        continue;
                    }
                    let lo = f - nx * ny;
                    let r = 0.5 * (rho[lo] + rho[f]);
                    let tt = 0.5 * (t[lo] + t[f]);
                    *wv += dt * (b * tt - a * r);
                }
            });
    }

    /// Vorticity confinement, Fedkiw 2001 eq. 9–11: `ω = ∇×u`,
    /// `N = ∇|ω| / |∇|ω||`, `f = ε h (N × ω)`, which puts back the small
    /// swirls the grid's numerical dissipation damps.
    pub(super) fn add_vorticity_confinement(&mut self, dt: f32) {
        let [nx, ny, nz] = self.dims;
        let slab = nx * ny;
        let eps_h = self.scene.vorticity * self.h;
        let inv2h = 0.5 / self.h;
        let [cu, cv, cw, ox, oy, oz, om] = &mut self.work;
        // Cell-centred velocity.
        {
            let (u, v, w) = (&self.u, &self.v, &self.w);
            cu.par_chunks_mut(slab)
                .zip(cv.par_chunks_mut(slab))
                .zip(cw.par_chunks_mut(slab))
                .enumerate()
                .for_each(|(k, ((a, b), c))| {
                    for j in 0..ny {
                        for i in 0..nx {
                            let o = i + nx * j;
                            let iu = i + (nx + 1) * (j + ny * k);
                            let iv = i + nx * (j + (ny + 1) * k);
                            let iw = o + slab * k;
                            a[o] = 0.5 * (u[iu] + u[iu + 1]);
                            b[o] = 0.5 * (v[iv] + v[iv + nx]);
                            c[o] = 0.5 * (w[iw] + w[iw + slab]);
                        }
                    }
                });
        }
        // ω by central differences; 0 on the grid's outer layer and in solids.
        {
            let (cu, cv, cw) = (&*cu, &*cv, &*cw);
            let flags = &self.flags;
            ox.par_chunks_mut(slab)
                .zip(oy.par_chunks_mut(slab))
                .zip(oz.par_chunks_mut(slab).zip(om.par_chunks_mut(slab)))
                .enumerate()
                .for_each(|(k, ((a, b), (c, m)))| {
                    for j in 0..ny {
                        for i in 0..nx {
                            let o = i + nx * j;
                            let g = o + slab * k;
                            if i == 0
                                || j == 0
                                || k == 0
                                || i == nx - 1
                                || j == ny - 1
                                || k == nz - 1
                                || flags[g] == SOLID
                            {
                                a[o] = 0.0;
                                b[o] = 0.0;
                                c[o] = 0.0;
                                m[o] = 0.0;
                                continue;
                            }
                            let d = |f: &[f32], s: usize| (f[g + s] - f[g - s]) * inv2h;
                            let wx = d(cw, nx) - d(cv, slab);
                            let wy = d(cu, slab) - d(cw, 1);
                            let wz = d(cv, 1) - d(cu, nx);
                            a[o] = wx;
                            b[o] = wy;
                            c[o] = wz;
                            m[o] = (wx * wx + wy * wy + wz * wz).sqrt();
                        }
                    }
                });
        }
        // f = ε h (N × ω), into cu/cv/cw (no longer needed).
        {
            let (ox, oy, oz, om) = (&*ox, &*oy, &*oz, &*om);
            cu.par_chunks_mut(slab)
                .zip(cv.par_chunks_mut(slab))
                .zip(cw.par_chunks_mut(slab))
                .enumerate()
                .for_each(|(k, ((a, b), c))| {
                    for j in 0..ny {
                        for i in 0..nx {
                            let o = i + nx * j;
                            let g = o + slab * k;
                            a[o] = 0.0;
                            b[o] = 0.0;
                            c[o] = 0.0;
                            if i == 0
                                || j == 0
                                || k == 0
                                || i == nx - 1
                                || j == ny - 1
                                || k == nz - 1
                            {
                                continue;
                            }
                            let gx = (om[g + 1] - om[g - 1]) * inv2h;
                            let gy = (om[g + nx] - om[g - nx]) * inv2h;
                            let gz = (om[g + slab] - om[g - slab]) * inv2h;
                            let len = (gx * gx + gy * gy + gz * gz).sqrt();
                            if len < 1e-9 {
                                continue;
                            }
                            let (nxv, nyv, nzv) = (gx / len, gy / len, gz / len);
                            a[o] = eps_h * (nyv * oz[g] - nzv * oy[g]);
                            b[o] = eps_h * (nzv * ox[g] - nxv * oz[g]);
                            c[o] = eps_h * (nxv * oy[g] - nyv * ox[g]);
                        }
                    }
                });
        }
        // Onto the faces: the average of the two cells' forces.
        let (fu, fv, fw) = (&*cu, &*cv, &*cw);
        let dims = self.dims;
        let add = |vel: &mut Vec<f32>, free: &Vec<bool>, f: &[f32], axis: usize| {
            for_free_faces(dims, vel, free, axis, |v, r, l| {
                *v += dt * 0.5 * (f[r] + f[l]);
            });
        };
        add(&mut self.u, &self.free_u, fu, 0);
        add(&mut self.v, &self.free_v, fv, 1);
        add(&mut self.w, &self.free_w, fw, 2);
    }
}
