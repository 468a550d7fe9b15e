//! Semi-Lagrangian advection (Stam 1999): the temperature (with Newtonian
//! cooling) and the velocity's self-advection, each traced back through the
//! MAC velocity.

use super::Smoke;
use crate::advect::{Field, Mac};
use crate::pressure::FLUID;
use rayon::prelude::*;

impl Smoke {
    /// Semi-Lagrangian temperature, then Newtonian cooling towards ambient.
    pub(super) fn advect_temperature(&mut self, dt: f32) {
        let [nx, ny, _] = self.dims;
        let mac = Mac::new(self.dims, &self.u, &self.v, &self.w);
        let t = Field {
            data: &self.temperature,
            dims: self.dims,
            offset: [0.5; 3],
        };
        let flags = &self.flags;
        let scale = dt / self.h;
        let decay = (-self.scene.cooling * dt).exp();
        self.scratch
            .par_chunks_mut(nx * ny)
            .enumerate()
            .for_each(|(k, out)| {
                for j in 0..ny {
                    for i in 0..nx {
                        let c = i + nx * (j + ny * k);
                        out[c - k * nx * ny] = if flags[c] == FLUID {
                            let p = [i as f32 + 0.5, j as f32 + 0.5, k as f32 + 0.5];
                            let v0 = mac.at_centre(i, j, k);
                            t.sample(mac.trace_back_from(p, v0, scale)) * decay
                        } else {
                            0.0
                        };
                    }
                }
            });
        std::mem::swap(&mut self.temperature, &mut self.scratch);
    }

    /// Semi-Lagrangian self-advection of the velocity (each component at
    /// its own faces); faces that cannot carry flow stay 0.
    pub(super) fn advect_velocity(&mut self, dt: f32) {
        let mac = Mac::new(self.dims, &self.u, &self.v, &self.w);
        let scale = dt / self.h;
        let jobs = [
            (&mut self.u_tmp, &self.free_u, mac.u),
            (&mut self.v_tmp, &self.free_v, mac.v),
            (&mut self.w_tmp, &self.free_w, mac.w),
        ];
        for (axis, (out, free, field)) in jobs.into_iter().enumerate() {
            let [fx, fy, _] = field.dims;
            let off = field.offset;
            out.par_chunks_mut(fx * fy).enumerate().for_each(|(k, o)| {
                for j in 0..fy {
                    for i in 0..fx {
                        let c = i + fx * j;
                        o[c] = if free[c + k * fx * fy] {
                            // A free face is an inner one: at_face applies.
                            let p = [i as f32 + off[0], j as f32 + off[1], k as f32 + off[2]];
                            let v0 = mac.at_face(axis, i, j, k);
                            field.sample(mac.trace_back_from(p, v0, scale))
                        } else {
                            0.0
                        };
                    }
                }
            });
        }
        std::mem::swap(&mut self.u, &mut self.u_tmp);
        std::mem::swap(&mut self.v, &mut self.v_tmp);
        std::mem::swap(&mut self.w, &mut self.w_tmp);
    }
}
