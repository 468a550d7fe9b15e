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
//! The multigrid levels aggregate 2×2×2 cells; each coarse operator is half
//! the Galerkin product `Pᵀ A P` with piecewise-constant `P`, which is again
//! a 7-point operator whose face coefficients count the fine fluid–fluid
//! faces between two aggregates. So obstacles and openings carry to every
//! level exactly, with no rule to invent (the half: see `coarsen`). Two
//! red–black Gauss–Seidel sweeps smooth (red then black before the coarse
//! correction, black then red after), and the
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
    /// The same operator packed per cell when every coupling is 0 or 1 (the
    /// fine level): bits 0–5 couple to the +x, −x, +y, −y, +z, −z
    /// neighbour, bits 8–11 hold the diagonal: the smoothing sweeps and
    /// residuals read 2 bytes a cell instead of 16. Empty on the coarse
    /// levels.
    unit: Vec<u16>,
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
            unit: Vec::new(),
            x: vec![0.0; n],
            b: vec![0.0; n],
            r: vec![0.0; n],
        }
    }

    /// Packs the operator into [`Level::unit`] when all its couplings
    /// are 0 or 1 and its diagonal a whole number ≤ 6.
    fn pack_unit(&mut self) {
        let unit01 = |v: &[f32]| v.iter().all(|&c| c == 0.0 || c == 1.0);
        let small = self
            .diag
            .iter()
            .all(|&d| d == d.round() && (0.0..=6.0).contains(&d));
        if !(unit01(&self.cx) && unit01(&self.cy) && unit01(&self.cz) && small) {
            return;
        }
        let [nx, ny, _] = self.dims;
        let (sy, sz) = (nx, nx * ny);
        let n = self.diag.len();
        let bit = |v: &[f32], c: Option<usize>| c.map_or(0, |c| u16::from(v[c] == 1.0));
        self.unit = (0..n)
            .map(|c| {
                let i = c % nx;
                let j = (c / nx) % ny;
                bit(&self.cx, Some(c))
                    | bit(&self.cx, (i > 0).then(|| c - 1)) << 1
                    | bit(&self.cy, Some(c)) << 2
                    | bit(&self.cy, (j > 0).then(|| c - sy)) << 3
                    | bit(&self.cz, Some(c)) << 4
                    | bit(&self.cz, c.checked_sub(sz)) << 5
                    | (self.diag[c] as u16) << 8
            })
            .collect();
    }

    /// `out = b − A x` (or `A x` when `b` is `None`).
    fn residual(&self, x: &[f32], b: Option<&[f32]>, out: &mut [f32]) {
        if self.unit.is_empty() {
            self.residual_with::<false>(x, b, out)
        } else {
            self.residual_with::<true>(x, b, out)
        }
    }

    fn residual_with<const UNIT: bool>(&self, x: &[f32], b: Option<&[f32]>, out: &mut [f32]) {
        let [nx, ny, _] = self.dims;
        let slab = nx * ny;
        out.par_chunks_mut(slab).enumerate().for_each(|(k, o)| {
            for j in 0..ny {
                for i in 0..nx {
                    let c = i + nx * (j + ny * k);
                    let d = self.diag_at::<UNIT>(c);
                    if d == 0.0 {
                        o[c - k * slab] = 0.0;
                        continue;
                    }
                    let ax = d * x[c] - self.neighbour_sum::<UNIT>(x, c, i, j, k);
                    o[c - k * slab] = match b {
                        Some(b) => b[c] - ax,
                        None => ax,
                    };
                }
            }
        });
    }

    /// The diagonal of cell `c` (0: no unknown there).
    #[inline(always)]
    fn diag_at<const UNIT: bool>(&self, c: usize) -> f32 {
        if UNIT {
            f32::from(self.unit[c] >> 8)
        } else {
            self.diag[c]
        }
    }

    /// The couplings of cell `c` to its +x, −x, +y, −y, +z, −z neighbours.
    #[inline(always)]
    fn couplings<const UNIT: bool>(&self, c: usize, [sx, sy, sz]: [usize; 3]) -> [f32; 6] {
        if UNIT {
            let m = self.unit[c];
            std::array::from_fn(|b| f32::from((m >> b) & 1))
        } else {
            let g = |v: &[f32], o: Option<usize>| o.map_or(0.0, |o| v[o]);
            [
                self.cx[c],
                g(&self.cx, c.checked_sub(sx)),
                self.cy[c],
                g(&self.cy, c.checked_sub(sy)),
                self.cz[c],
                g(&self.cz, c.checked_sub(sz)),
            ]
        }
    }

    /// `Σ_n c_n x_n` over the six neighbours of cell `c` = (i, j, k).
    #[inline(always)]
    fn neighbour_sum<const UNIT: bool>(
        &self,
        x: &[f32],
        c: usize,
        i: usize,
        j: usize,
        k: usize,
    ) -> f32 {
        let [nx, ny, nz] = self.dims;
        let (sx, sy, sz) = (1, nx, nx * ny);
        let w = self.couplings::<UNIT>(c, [sx, sy, sz]);
        if i > 0 && j > 0 && k > 0 && i + 1 < nx && j + 1 < ny && k + 1 < nz {
            // An inner cell (most of them): all six neighbours exist. The
            // same sum in the same order as below, without the checks.
            assert!(c + sz < x.len());
            // SAFETY: c − sz ≥ 0 (k > 0) and c + sz < x.len() (checked);
            // every index below lies between the two.
            unsafe {
                let g = |o: usize| *x.get_unchecked(o);
                let mut s = 0.0;
                s += w[0] * g(c + sx);
                s += w[1] * g(c - sx);
                s += w[2] * g(c + sy);
                s += w[3] * g(c - sy);
                s += w[4] * g(c + sz);
                s += w[5] * g(c - sz);
                return s;
            }
        }
        let mut s = 0.0;
        if i + 1 < nx {
            s += w[0] * x[c + sx];
        }
        if i > 0 {
            s += w[1] * x[c - sx];
        }
        if j + 1 < ny {
            s += w[2] * x[c + sy];
        }
        if j > 0 {
            s += w[3] * x[c - sy];
        }
        if k + 1 < nz {
            s += w[4] * x[c + sz];
        }
        if k > 0 {
            s += w[5] * x[c - sz];
        }
        s
    }

    /// One Gauss–Seidel half-sweep over the cells of `colour`
    /// ((i + j + k) % 2), in parallel: a cell of one colour only reads cells
    /// of the other, so the updates are independent.
    fn gs_colour(&mut self, colour: usize) {
        if self.unit.is_empty() {
            self.gs_colour_with::<false>(colour)
        } else {
            self.gs_colour_with::<true>(colour)
        }
    }

    fn gs_colour_with<const UNIT: bool>(&mut self, colour: usize) {
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
                    let d = this.diag_at::<UNIT>(c);
                    if d == 0.0 {
                        continue;
                    }
                    // SAFETY: this task writes only cells of `colour` in
                    // slab k; it reads cells of the other colour, which no
                    // task writes during this half-sweep. Indices are in
                    // bounds (c < len, neighbours checked in neighbour_sum).
                    unsafe {
                        let xs = std::slice::from_raw_parts(p.0 as *const f32, len);
                        let v = (this.b[c] + this.neighbour_sum::<UNIT>(xs, c, i, j, k)) / d;
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
    /// Fine cells with an unknown.
    unknowns: usize,
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
        for l in &mut levels {
            l.pack_unit();
        }
        let n = nx * ny * nz;
        PressureSolver {
            unknowns: levels[0].diag.iter().filter(|&&d| d > 0.0).count(),
            levels,
            r: vec![0.0; n],
            z: vec![0.0; n],
            d: vec![0.0; n],
            q: vec![0.0; n],
            partial: vec![0.0; n.div_ceil(DOT_CHUNK)],
            closed,
            tolerance: 1e-5,
            max_iterations: 200,
            smoothing: 2,
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
            remove_mean(b, &fine_diag, self.unknowns, &mut self.partial);
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
            self.precondition(&mut r, &mut z);
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
                self.precondition(&mut r, &mut z);
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

    /// `z = M⁻¹ r`: one V-cycle from zero. `r` and `z` trade places with
    /// the fine level's right-hand side and solution instead of being
    /// copied.
    fn precondition(&mut self, r: &mut Vec<f32>, z: &mut Vec<f32>) {
        std::mem::swap(&mut self.levels[0].b, r);
        let nu = self.smoothing;
        vcycle(&mut self.levels, 0, nu);
        std::mem::swap(&mut self.levels[0].b, r);
        std::mem::swap(&mut self.levels[0].x, z);
        if self.closed {
            remove_mean(z, &self.levels[0].diag, self.unknowns, &mut self.partial);
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

/// Subtracts the mean over the `unknowns` cells with an unknown
/// (`diag > 0`), summed in fixed chunks into `partial` (deterministic
/// order).
fn remove_mean(v: &mut [f32], diag: &[f32], unknowns: usize, partial: &mut [f64]) {
    if unknowns == 0 {
        return;
    }
    v.par_chunks(DOT_CHUNK)
        .zip(diag.par_chunks(DOT_CHUNK))
        .zip(partial.par_iter_mut())
        .for_each(|((v, d), s)| {
            *s = v
                .iter()
                .zip(d)
                .filter(|(_, d)| **d > 0.0)
                .map(|(x, _)| *x as f64)
                .sum();
        });
    let m = (partial.iter().sum::<f64>() / unknowns as f64) as f32;
    v.par_iter_mut().zip(diag.par_iter()).for_each(|(x, d)| {
        if *d > 0.0 {
            *x -= m;
        }
    });
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
    // Piecewise-constant aggregation makes the Galerkin operator of a
    // smooth error twice as stiff as the Laplacian it stands for (a coarse
    // face sums 4 fine faces, but the coarse cell is only twice as wide),
    // so the plain coarse correction comes back at half its size and CG
    // needs about twice the iterations. Halving each coarse operator (the
    // usual over-correction of unsmoothed aggregation, Braess 1995) keeps
    // it symmetric positive definite, so the V-cycle stays a valid
    // preconditioner; only the size of the correction changes.
    for v in [&mut c.diag, &mut c.cx, &mut c.cy, &mut c.cz] {
        v.iter_mut().for_each(|x| *x *= 0.5);
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
