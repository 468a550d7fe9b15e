//! The pressure projection (Fedkiw 2001 eq. 4) that makes the velocity
//! divergence-free, and the walk over a velocity component's free faces it
//! shares with the forces.

use super::Smoke;
use crate::pressure::{SolveStats, FLUID};
use rayon::prelude::*;

impl Smoke {
    /// Makes the velocity divergence-free (Fedkiw 2001 eq. 4): solve
    /// `A p = −∇·u` and subtract the pressure gradient on every face next
    /// to a fluid cell. Returns `max |∇·u|` before, and the solve's stats.
    pub(super) fn project(&mut self) -> (f64, SolveStats) {
        let [nx, ny, _] = self.dims;
        let slab = nx * ny;
        {
            let mut rhs = std::mem::take(&mut self.rhs);
            let this = &*self;
            let flags = &this.flags;
            rhs.par_chunks_mut(slab).enumerate().for_each(|(k, r)| {
                for j in 0..ny {
                    for i in 0..nx {
                        let o = i + nx * j;
                        r[o] = if flags[o + k * slab] == FLUID {
                            -this.divergence(i, j, k)
                        } else {
                            0.0
                        };
                    }
                }
            });
            self.rhs = rhs;
        }
        let before = self
            .rhs
            .par_iter()
            .map(|x| x.abs())
            .reduce(|| 0.0, f32::max) as f64;
        let stats = self.solver.solve(&mut self.rhs, &mut self.pressure);
        let p = &self.pressure;
        let flags = &self.flags;
        let dims = self.dims;
        let sub = |vel: &mut Vec<f32>, free: &Vec<bool>, axis: usize| {
            for_free_faces(dims, vel, free, axis, |v, r, l| {
                // Non-fluid cells hold p = 0 (open air).
                if flags[r] == FLUID || flags[l] == FLUID {
                    *v -= p[r] - p[l];
                }
            });
        };
        sub(&mut self.u, &self.free_u, 0);
        sub(&mut self.v, &self.free_v, 1);
        sub(&mut self.w, &self.free_w, 2);
        (before, stats)
    }
}

/// Calls `f(value, r, l)` for every free face of velocity component `axis`
/// (a staggered grid one longer along `axis`), in parallel by z-slab; `r`
/// and `l` are the cells on the + and − side of the face.
pub(super) fn for_free_faces(
    dims: [usize; 3],
    vel: &mut [f32],
    free: &[bool],
    axis: usize,
    f: impl Fn(&mut f32, usize, usize) + Sync,
) {
    let [nx, ny, nz] = dims;
    let mut fd = [nx, ny, nz];
    fd[axis] += 1;
    let stride = [1, nx, nx * ny][axis];
    vel.par_chunks_mut(fd[0] * fd[1])
        .enumerate()
        .for_each(|(k, vs)| {
            for j in 0..fd[1] {
                for i in 0..fd[0] {
                    let o = i + fd[0] * j;
                    if !free[o + k * fd[0] * fd[1]] {
                        continue;
                    }
                    let r = i + nx * (j + ny * k);
                    f(&mut vs[o], r, r - stride);
                }
            }
        });
}
