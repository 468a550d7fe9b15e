//! The pressure projection's linear solve: conjugate gradients
//! preconditioned by one multigrid V-cycle (MGPCG, McAdams, Sifakis & Teran
//! 2010), to a stated relative tolerance.
//!
//! The system is the 7-point Poisson matrix of the MAC grid (Fedkiw, Stam &
//! Jensen 2001 §3, eq. 4: `∇²p = ∇·u*`): for a fluid cell `i`,
//! `(A p)_i = Σ_n (p_i − p_n)` over its non-solid neighbours `n`; a solid
//! neighbour adds nothing (no flow through it: Neumann), an open cell is a
//! neighbour with `p = 0` (Dirichlet: smoke may leave there).
//!
//! The multigrid levels aggregate 2×2×2 cells; each coarse operator is the
//! Galerkin product `Pᵀ A P` with piecewise-constant `P`, which is again a
//! 7-point operator whose face coefficients count the fine fluid–fluid faces
//! between two aggregates. So obstacles and openings carry to every level
//! exactly, with no rule to invent. Red–black Gauss–Seidel smooths (red
//! then black before the coarse correction, black then red after), and the
//! coarsest level is solved by symmetric sweeps: the V-cycle is then a
//! symmetric positive operator, as CG requires of its preconditioner.

use rayon::prelude::*;

/// Cell kinds of the simulation grid.
pub const FLUID: u8 = 0;
/// No flow through its faces.
pub const SOLID: u8 = 1;
/// Air at ambient pressure (`p = 0`): a door, an open end.
pub const OPEN: u8 = 2;

/// Cells per parallel chunk of the dot products: fixed, so the sums are
/// added in the same order on every run (same seed → same frames).
const DOT_CHUNK: usize = 8192;

/// One multigrid level: a 7-point operator with per-face coefficients.
#[derive(Debug)]
struct Level {
    dims: [usize; 3],
    /// Coupling of cell `c` to its +x, +y, +z neighbour (0: none).
    cx: Vec<f32>,
    cy: Vec<f32>,
    cz: Vec<f32>,
    /// Diagonal (0 for cells without unknown).
    diag: Vec<f32>,
    x: Vec<f32>,
    b: Vec<f32>,
    r: Vec<f32>,
}

impl Level {
    fn new(dims: [usize; 3]) -> Level {
        let n = dims[0] * dims[1] * dims[2];
        Level {
            dims,
            cx: vec![0.0; n],
            cy: vec![0.0; n],
            cz: vec![0.0; n],
            diag: vec![0.0; n],
            x: vec![0.0; n],
            b: vec![0.0; n],
            r: vec![0.0; n],
        }
    }

    /// `out = b − A x` (or `A x` when `b` is `None`).
    fn residual(&self, x: &[f32], b: Option<&[f32]>, out: &mut [f32]) {
        let [nx, ny, _] = self.dims;
        let slab = nx * ny;
        out.par_chunks_mut(slab).enumerate().for_each(|(k, o)| {
            for j in 0..ny {
                for i in 0..nx {
                    let c = i + nx * (j + ny * k);
                    let d = self.diag[c];
                    if d == 0.0 {
                        o[c - k * slab] = 0.0;
                        continue;
                    }
                    let ax = d * x[c] - self.neighbour_sum(x, c, i, j, k);
                    o[c - k * slab] = match b {
                        Some(b) => b[c] - ax,
                        None => ax,
                    };
                }
            }
        });
    }

    /// `Σ_n c_n x_n` over the six neighbours of cell `c` = (i, j, k).
    #[inline(always)]
    fn neighbour_sum(&self, x: &[f32], c: usize, i: usize, j: usize, k: usize) -> f32 {
        let [nx, ny, nz] = self.dims;
        let sx = 1;
        let sy = nx;
        let sz = nx * ny;
        let mut s = 0.0;
        if i + 1 < nx {
            s += self.cx[c] * x[c + sx];
        }
        if i > 0 {
            s += self.cx[c - sx] * x[c - sx];
        }
        if j + 1 < ny {
            s += self.cy[c] * x[c + sy];
        }
        if j > 0 {
            s += self.cy[c - sy] * x[c - sy];
        }
        if k + 1 < nz {
            s += self.cz[c] * x[c + sz];
        }
        if k > 0 {
            s += self.cz[c - sz] * x[c - sz];
        }
        s
    }

    /// One Gauss–Seidel half-sweep over the cells of `colour`
    /// ((i + j + k) % 2), in parallel: a cell of one colour only reads cells
    /// of the other, so the updates are independent.
    fn gs_colour(&mut self, colour: usize) {
        let [nx, ny, _] = self.dims;
        let mut x = std::mem::take(&mut self.x);
        let len = x.len();
        let ptr = SyncPtr(x.as_mut_ptr());
        let this = &*self;
        (0..this.dims[2]).into_par_iter().for_each(|k| {
            let p = ptr;
            for j in 0..ny {
                let start = (colour + j + k) % 2;
                for i in (start..nx).step_by(2) {
                    let c = i + nx * (j + ny * k);
                    let d = this.diag[c];
                    if d == 0.0 {
                        continue;
                    }
                    // SAFETY: this task writes only cells of `colour` in
                    // slab k; it reads cells of the other colour, which no
                    // task writes during this half-sweep. Indices are in
                    // bounds (c < len, neighbours checked in neighbour_sum).
                    unsafe {
                        let xs = std::slice::from_raw_parts(p.0 as *const f32, len);
                        let v = (this.b[c] + this.neighbour_sum(xs, c, i, j, k)) / d;
                        *p.0.add(c) = v;
                    }
                }
            }
        });
        self.x = x;
    }
}

#[derive(Clone, Copy)]
struct SyncPtr(*mut f32);
// SAFETY: used only for the disjoint red/black writes described in gs_colour.
unsafe impl Send for SyncPtr {}
unsafe impl Sync for SyncPtr {}

/// What one solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// CG iterations.
    pub iterations: usize,
    /// Final `‖b − A p‖∞ / ‖b‖∞`.
    pub relative_residual: f64,
}

/// MGPCG solver for one fixed set of cell flags; all buffers are allocated
/// once, so a solve allocates nothing.
#[derive(Debug)]
pub struct PressureSolver {
    levels: Vec<Level>,
    /// CG vectors on the fine level.
    r: Vec<f32>,
    z: Vec<f32>,
    d: Vec<f32>,
    q: Vec<f32>,
    partial: Vec<f64>,
    /// True when no cell is open: the matrix is singular (constant null
    /// space) and the right-hand side is made compatible.
    closed: bool,
    /// Relative tolerance on `‖r‖∞ / ‖b‖∞`.
    pub tolerance: f64,
    /// Iteration cap (a solve that hits it reports its residual).
    pub max_iterations: usize,
    /// Gauss–Seidel sweeps before and after the coarse correction.
    pub smoothing: usize,
}

impl PressureSolver {
    /// Builds the levels for cell `flags` on a grid of `dims`.
    pub fn new(dims: [usize; 3], flags: &[u8]) -> PressureSolver {
        let mut fine = Level::new(dims);
        let [nx, ny, nz] = dims;
        let idx = |i: usize, j: usize, k: usize| i + nx * (j + ny * k);
        let mut closed = true;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let c = idx(i, j, k);
                    if flags[c] == OPEN {
                        closed = false;
                    }
                    if flags[c] != FLUID {
                        continue;
                    }
                    let mut d = 0.0;
                    let mut nb = |ii: usize, jj: usize, kk: usize| -> f32 {
                        match flags[idx(ii, jj, kk)] {
                            FLUID => {
                                d += 1.0;
                                1.0
                            }
                            OPEN => {
                                d += 1.0;
                                0.0
                            }
                            _ => 0.0,
                        }
                    };
                    if i + 1 < nx {
                        fine.cx[c] = nb(i + 1, j, k);
                    }
                    if j + 1 < ny {
                        fine.cy[c] = nb(i, j + 1, k);
                    }
                    if k + 1 < nz {
                        fine.cz[c] = nb(i, j, k + 1);
                    }
                    if i > 0 {
                        nb(i - 1, j, k);
                    }
                    if j > 0 {
                        nb(i, j - 1, k);
                    }
                    if k > 0 {
                        nb(i, j, k - 1);
                    }
                    // A fluid cell walled in on all sides keeps a unit
                    // diagonal so that it is not mistaken for a non-cell.
                    fine.diag[c] = if d == 0.0 { 1.0 } else { d };
                }
            }
        }
        let mut levels = vec![fine];
        while levels.last().is_some_and(|l| l.dims.iter().all(|&d| d > 4)) {
            let coarse = coarsen(levels.last().expect("non-empty"));
            levels.push(coarse);
        }
        let n = nx * ny * nz;
        PressureSolver {
            levels,
            r: vec![0.0; n],
            z: vec![0.0; n],
            d: vec![0.0; n],
            q: vec![0.0; n],
            partial: vec![0.0; n.div_ceil(DOT_CHUNK)],
            closed,
            tolerance: 1e-5,
            max_iterations: 200,
            smoothing: 1,
        }
    }

    /// Number of multigrid levels.
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// Solves `A p = b` for the fluid cells, starting from `p` (a warm
    /// start: the previous step's pressure). Non-fluid entries of `p` are
    /// left 0.
    pub fn solve(&mut self, b: &mut [f32], p: &mut [f32]) -> SolveStats {
        let fine_diag = std::mem::take(&mut self.levels[0].diag);
        if self.closed {
            // A closed room: Σ b must be 0 for a solution to exist (the
            // discrete divergence theorem gives it up to rounding).
            remove_mean(b, &fine_diag);
        }
        for (pi, &d) in p.iter_mut().zip(&fine_diag) {
            if d == 0.0 {
                *pi = 0.0;
            }
        }
        self.levels[0].diag = fine_diag;
        let bnorm = max_abs(b);
        if bnorm == 0.0 {
            p.iter_mut().for_each(|x| *x = 0.0);
            return SolveStats::default();
        }
        let mut r = std::mem::take(&mut self.r);
        let mut z = std::mem::take(&mut self.z);
        let mut d = std::mem::take(&mut self.d);
        let mut q = std::mem::take(&mut self.q);
        self.levels[0].residual(p, Some(b), &mut r);
        let mut stats = SolveStats {
            iterations: 0,
            relative_residual: max_abs(&r) / bnorm,
        };
        if stats.relative_residual > self.tolerance {
            self.precondition(&r, &mut z);
            d.copy_from_slice(&z);
            let mut rz = self.dot(&r, &z);
            while stats.iterations < self.max_iterations {
                stats.iterations += 1;
                self.levels[0].residual(&d, None, &mut q);
                let dq = self.dot(&d, &q);
                if dq <= 0.0 {
                    break;
                }
                let alpha = (rz / dq) as f32;
                p.par_iter_mut()
                    .zip(r.par_iter_mut())
                    .zip(d.par_iter().zip(q.par_iter()))
                    .for_each(|((p, r), (d, q))| {
                        *p += alpha * d;
                        *r -= alpha * q;
                    });
                stats.relative_residual = max_abs(&r) / bnorm;
                if stats.relative_residual <= self.tolerance {
                    break;
                }
                self.precondition(&r, &mut z);
                let rz_new = self.dot(&r, &z);
                let beta = (rz_new / rz) as f32;
                rz = rz_new;
                d.par_iter_mut()
                    .zip(z.par_iter())
                    .for_each(|(d, z)| *d = z + beta * *d);
            }
        }
        self.r = r;
        self.z = z;
        self.d = d;
        self.q = q;
        stats
    }

    /// `z = M⁻¹ r`: one V-cycle from zero.
    fn precondition(&mut self, r: &[f32], z: &mut [f32]) {
        self.levels[0].b.copy_from_slice(r);
        let nu = self.smoothing;
        vcycle(&mut self.levels, 0, nu);
        z.copy_from_slice(&self.levels[0].x);
        if self.closed {
            remove_mean(z, &self.levels[0].diag);
        }
    }

    /// A dot product summed in fixed chunks (deterministic order).
    fn dot(&mut self, a: &[f32], b: &[f32]) -> f64 {
        a.par_chunks(DOT_CHUNK)
            .zip(b.par_chunks(DOT_CHUNK))
            .zip(self.partial.par_iter_mut())
            .for_each(|((a, b), s)| {
                *s = a.iter().zip(b).map(|(x, y)| *x as f64 * *y as f64).sum();
            });
        self.partial.iter().sum()
    }
}

fn max_abs(v: &[f32]) -> f64 {
    v.par_iter().map(|x| x.abs()).reduce(|| 0.0, f32::max) as f64
}

/// Subtracts the mean over the cells with an unknown (`diag > 0`).
fn remove_mean(v: &mut [f32], diag: &[f32]) {
    let (mut s, mut n) = (0.0f64, 0usize);
    for (x, d) in v.iter().zip(diag) {
        if *d > 0.0 {
            s += *x as f64;
            n += 1;
        }
    }
    if n == 0 {
        return;
    }
    let m = (s / n as f64) as f32;
    for (x, d) in v.iter_mut().zip(diag) {
        if *d > 0.0 {
            *x -= m;
        }
    }
}

/// The Galerkin coarse level `Pᵀ A P` of `fine` (2×2×2 aggregates).
fn coarsen(fine: &Level) -> Level {
    let [fx, fy, fz] = fine.dims;
    let dims = [fx.div_ceil(2), fy.div_ceil(2), fz.div_ceil(2)];
    let mut c = Level::new(dims);
    let [cx, cy, _] = dims;
    for k in 0..fz {
        for j in 0..fy {
            for i in 0..fx {
                let f = i + fx * (j + fy * k);
                let (ci, cj, ck) = (i / 2, j / 2, k / 2);
                // A fine face at an even index lies inside its aggregate.
                let cc = ci + cx * (cj + cy * ck);
                c.diag[cc] += fine.diag[f];
                // A fine face inside an aggregate cancels twice in the
                // Galerkin sum; one between aggregates becomes a coarse face.
                if i + 1 < fx {
                    if i % 2 == 0 {
                        c.diag[cc] -= 2.0 * fine.cx[f];
                    } else {
                        c.cx[cc] += fine.cx[f];
                    }
                }
                if j + 1 < fy {
                    if j % 2 == 0 {
                        c.diag[cc] -= 2.0 * fine.cy[f];
                    } else {
                        c.cy[cc] += fine.cy[f];
                    }
                }
                if k + 1 < fz {
                    if k % 2 == 0 {
                        c.diag[cc] -= 2.0 * fine.cz[f];
                    } else {
                        c.cz[cc] += fine.cz[f];
                    }
                }
            }
        }
    }
    // An aggregate of fluid cells sealed from every opening has a zero
    // Galerkin diagonal only if it has no cells; rounding never applies
    // (all coefficients are small integers).
    for d in &mut c.diag {
        if *d < 0.5 {
            *d = 0.0;
        }
    }
    c
}

/// One V-cycle on `levels[l..]` for `levels[l].b`, result in `levels[l].x`.
fn vcycle(levels: &mut [Level], l: usize, nu: usize) {
    let last = levels.len() - 1;
    levels[l].x.iter_mut().for_each(|x| *x = 0.0);
    if l == last {
        // The coarsest level: symmetric Gauss–Seidel to (near) convergence;
        // it holds at most a few hundred cells.
        for _ in 0..20 {
            levels[l].gs_colour(0);
            levels[l].gs_colour(1);
            levels[l].gs_colour(1);
            levels[l].gs_colour(0);
        }
        return;
    }
    for _ in 0..nu {
        levels[l].gs_colour(0);
        levels[l].gs_colour(1);
    }
    {
        let lv = &mut levels[l];
        let mut r = std::mem::take(&mut lv.r);
        lv.residual(&lv.x, Some(&lv.b), &mut r);
        lv.r = r;
    }
    let (fine, rest) = levels.split_at_mut(l + 1);
    let fine = &mut fine[l];
    let coarse = &mut rest[0];
    restrict(fine, coarse);
    vcycle(levels, l + 1, nu);
    let (fine, rest) = levels.split_at_mut(l + 1);
    prolong_add(&rest[0], &mut fine[l]);
    for _ in 0..nu {
        levels[l].gs_colour(1);
        levels[l].gs_colour(0);
    }
}

/// `coarse.b = Pᵀ fine.r` (sum over each aggregate).
fn restrict(fine: &Level, coarse: &mut Level) {
    let [fx, fy, fz] = fine.dims;
    let [cx, cy, _] = coarse.dims;
    let cslab = cx * cy;
    coarse
        .b
        .par_chunks_mut(cslab)
        .enumerate()
        .for_each(|(ck, out)| {
            out.iter_mut().for_each(|x| *x = 0.0);
            for k in (2 * ck)..(2 * ck + 2).min(fz) {
                for j in 0..fy {
                    for i in 0..fx {
                        out[i / 2 + cx * (j / 2)] += fine.r[i + fx * (j + fy * k)];
                    }
                }
            }
        });
}

/// `fine.x += P coarse.x` (each fine cell takes its aggregate's value).
fn prolong_add(coarse: &Level, fine: &mut Level) {
    let [fx, fy, _] = fine.dims;
    let [cx, cy, _] = coarse.dims;
    let slab = fx * fy;
    let diag = &fine.diag;
    fine.x.par_chunks_mut(slab).enumerate().for_each(|(k, xs)| {
        for j in 0..fy {
            for i in 0..fx {
                let f = i + fx * j;
                if diag[f + k * slab] > 0.0 {
                    xs[f] += coarse.x[i / 2 + cx * (j / 2 + cy * (k / 2))];
                }
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random right-hand side on a box with an obstacle and an opening:
    /// the solve meets its tolerance, and A p = b holds when checked
    /// independently of the solver's own residual.
    #[test]
    fn mgpcg_solves_poisson_with_obstacles_and_openings() {
        let dims = [19, 12, 15];
        let n = dims[0] * dims[1] * dims[2];
        let mut flags = vec![FLUID; n];
        let idx = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
        for k in 2..6 {
            for j in 3..8 {
                for i in 4..10 {
                    flags[idx(i, j, k)] = SOLID;
                }
            }
        }
        for j in 0..4 {
            flags[idx(dims[0] - 1, j, 1)] = OPEN;
        }
        let mut seed = 12345u64;
        let mut b: Vec<f32> = (0..n)
            .map(|c| {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                if flags[c] == FLUID {
                    ((seed >> 33) as f32 / (1u64 << 31) as f32) - 0.5
                } else {
                    0.0
                }
            })
            .collect();
        let mut s = PressureSolver::new(dims, &flags);
        assert!(s.levels() >= 2);
        let mut p = vec![0.0; n];
        let st = s.solve(&mut b, &mut p);
        assert!(st.relative_residual <= 1e-5, "{st:?}");
        assert!(st.iterations < 60, "{st:?}");
        // Independent check of A p = b from the flags.
        let mut worst = 0.0f64;
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let c = idx(i, j, k);
                    if flags[c] != FLUID {
                        continue;
                    }
                    let mut ap = 0.0f64;
                    let nbs = [
                        (i + 1 < dims[0]).then(|| idx(i + 1, j, k)),
                        (i > 0).then(|| idx(i - 1, j, k)),
                        (j + 1 < dims[1]).then(|| idx(i, j + 1, k)),
                        (j > 0).then(|| idx(i, j - 1, k)),
                        (k + 1 < dims[2]).then(|| idx(i, j, k + 1)),
                        (k > 0).then(|| idx(i, j, k - 1)),
                    ];
                    for nb in nbs.into_iter().flatten() {
                        match flags[nb] {
                            FLUID => ap += p[c] as f64 - p[nb] as f64,
                            OPEN => ap += p[c] as f64,
                            _ => {}
                        }
                    }
                    worst = worst.max((ap - b[c] as f64).abs());
                }
            }
        }
        assert!(worst < 1e-4, "max |Ap − b| = {worst}");
    }

    /// A closed box (all Neumann): the compatible part of b is solved.
    #[test]
    fn closed_box_is_solved_up_to_a_constant() {
        let dims = [16, 8, 12];
        let n = dims[0] * dims[1] * dims[2];
        let flags = vec![FLUID; n];
        let mut b: Vec<f32> = (0..n).map(|c| ((c * 7919) % 13) as f32 - 6.0).collect();
        let mut s = PressureSolver::new(dims, &flags);
        let mut p = vec![0.0; n];
        let st = s.solve(&mut b, &mut p);
        assert!(st.relative_residual <= 1e-5, "{st:?}");
        let sum: f64 = b.iter().map(|&x| x as f64).sum();
        assert!(sum.abs() < 1e-3, "b made compatible: Σb = {sum}");
    }
}
