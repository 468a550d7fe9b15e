//! Conservative flux-form transport of the smoke density, with local
//! sub-stepping per grid row (the sub-step [`Ladder`]) and the rows without
//! smoke skipped.

use super::Smoke;
use crate::advect::face_flux;
use crate::pressure::{FLUID, OPEN};
use rayon::prelude::*;

/// The longest grid row (cells along x) the density update's row buffers
/// hold; scene validation allows up to this.
const MAX_ROW: usize = 1024;

impl Smoke {
    /// Conservative transport of the density: each cell changes by the
    /// fluxes through its six faces, so what one cell loses its neighbour
    /// gains. Smoke that reaches an open cell is counted out and removed.
    ///
    /// Local sub-stepping (Osher & Sanders 1983): each grid row (the cells
    /// along x at one `j, k`) takes as many sub-steps as its own fastest
    /// cell needs, one of the counts of a [`Ladder`] (each divides the next),
    /// instead of the count the fastest cell of the whole grid needs. A face
    /// between two rows is computed at the finer row's rate. Each row adds
    /// the fluxes through its faces into an accumulator and applies them at
    /// the end of its own sub-step, so a slow row holds its value while a
    /// fast neighbour takes several sub-steps against it. Every face flux
    /// goes, with opposite signs, to the two cells beside it (both compute
    /// it from the same values), so the mass stays injected − outflow; and a
    /// cell's outgoing Courant numbers over its own sub-step still sum to at
    /// most 0.6, so it never gives more than it holds.
    ///
    /// A row with no smoke within the stencil's reach (two rows along y and
    /// z) is skipped: every flux through its faces is zero.
    ///
    /// Returns the sub-steps of the fastest rows and the row sub-steps
    /// computed, per row of the grid.
    pub(super) fn advect_density(&mut self, dt: f32) -> (usize, f64) {
        let [nx, ny, nz] = self.dims;
        assert!(
            nx <= MAX_ROW,
            "grid rows are at most {MAX_ROW} cells (scene validation)"
        );
        let slab = nx * ny;
        let base = dt / self.h;
        // Each row's sub-step need, from the largest total outflow velocity
        // of its cells: the limited face value is at most 1.5× the cell's,
        // so a cell's outgoing Courant numbers must sum to ≤ 2/3 for it not
        // to give more than it has. And whether the row holds smoke.
        {
            let (u, v, w, q) = (&self.u, &self.v, &self.w, &self.density);
            self.row_level
                .par_chunks_mut(ny)
                .zip(self.row_live.par_chunks_mut(ny))
                .enumerate()
                .for_each(|(k, (need, live))| {
                    for j in 0..ny {
                        let mut m = 0.0f32;
                        for i in 0..nx {
                            let iu = i + (nx + 1) * (j + ny * k);
                            let iv = i + nx * (j + (ny + 1) * k);
                            let iw = i + nx * (j + ny * k);
                            let s = (-u[iu]).max(0.0)
                                + u[iu + 1].max(0.0)
                                + (-v[iv]).max(0.0)
                                + v[iv + nx].max(0.0)
                                + (-w[iw]).max(0.0)
                                + w[iw + nx * ny].max(0.0);
                            m = m.max(s);
                        }
                        need[j] = substeps_for(m * base) as u8;
                        let b = nx * (j + ny * k);
                        live[j] = q[b..b + nx].iter().any(|&d| d != 0.0);
                    }
                });
        }
        let need = self.row_level.iter().copied().max().unwrap_or(1);
        let ladder = Ladder::new(need as usize);
        if self.local_substeps {
            for l in self.row_level.iter_mut() {
                *l = ladder.level_for(*l as usize) as u8;
            }
        } else {
            self.row_level.fill(ladder.top_level() as u8);
        }
        // The finest face of each row: its own level or a neighbour's.
        {
            let lv = &self.row_level;
            self.row_touch
                .par_chunks_mut(ny)
                .enumerate()
                .for_each(|(k, t)| {
                    for (j, tj) in t.iter_mut().enumerate() {
                        let r = j + ny * k;
                        let mut m = lv[r];
                        if j > 0 {
                            m = m.max(lv[r - 1]);
                        }
                        if j + 1 < ny {
                            m = m.max(lv[r + 1]);
                        }
                        if k > 0 {
                            m = m.max(lv[r - ny]);
                        }
                        if k + 1 < nz {
                            m = m.max(lv[r + ny]);
                        }
                        *tj = m;
                    }
                });
        }
        let scales = ladder
            .count
            .map(|c| if c > 0 { base / c as f32 } else { 0.0 });
        let fine = ladder.fine();
        let mut outflow = 0.0f64;
        let mut row_steps = 0u64;
        for s in 0..fine {
            // Faces of level ≥ `first` start a sub-step now; rows of level
            // ≥ `ending` finish theirs after this one.
            let first = ladder.first_active(s);
            let ending = ladder.first_active(s + 1);
            {
                let q = &self.density;
                let (u, v, w) = (&self.u, &self.v, &self.w);
                let (lv, touch, live) = (&self.row_level, &self.row_touch, &self.row_live);
                let zero = &self.zero_row;
                let skip = self.skip_empty;
                // Row j of slab k of the density, zeros outside the grid.
                let row = |j: isize, k: isize| -> &[f32] {
                    if j < 0 || k < 0 || j >= ny as isize || k >= nz as isize {
                        zero
                    } else {
                        let b = nx * (j as usize + ny * k as usize);
                        &q[b..b + nx]
                    }
                };
                let live_at = |j: isize, k: isize| -> bool {
                    j >= 0
                        && k >= 0
                        && j < ny as isize
                        && k < nz as isize
                        && live[j as usize + ny * k as usize]
                };
                self.flux_acc
                    .par_chunks_mut(slab)
                    .zip(self.row_dirty.par_chunks_mut(ny))
                    .enumerate()
                    .for_each(|(k, (acc, dirty))| {
                        let mut pad = [0f32; MAX_ROW + 4];
                        let mut fx = [0f32; MAX_ROW + 1];
                        let mut fy_lo = [0f32; MAX_ROW];
                        let mut fy_hi = [0f32; MAX_ROW];
                        let mut fz_lo = [0f32; MAX_ROW];
                        let mut fz_hi = [0f32; MAX_ROW];
                        let kk = k as isize;
                        // Whether fy_hi holds the active upper y face of
                        // the previous row (the lower one of this row).
                        let mut hi_valid = false;
                        for j in 0..ny {
                            let r = j + ny * k;
                            let jj = j as isize;
                            let prev_valid = std::mem::replace(&mut hi_valid, false);
                            if (touch[r] as usize) < first {
                                continue;
                            }
                            if skip
                                && !(live_at(jj, kk)
                                    || live_at(jj - 1, kk)
                                    || live_at(jj + 1, kk)
                                    || live_at(jj - 2, kk)
                                    || live_at(jj + 2, kk)
                                    || live_at(jj, kk - 1)
                                    || live_at(jj, kk + 1)
                                    || live_at(jj, kk - 2)
                                    || live_at(jj, kk + 2))
                            {
                                continue;
                            }
                            let lr = lv[r] as usize;
                            let qc = row(jj, kk);
                            // x faces 0..=nx, from the row padded with two
                            // empty cells at each end.
                            if lr >= first {
                                let sc = scales[lr];
                                pad[2..nx + 2].copy_from_slice(qc);
                                let ur = &u[(nx + 1) * (j + ny * k)..][..nx + 1];
                                for f in 0..=nx {
                                    fx[f] = face_flux(
                                        ur[f] * sc,
                                        pad[f],
                                        pad[f + 1],
                                        pad[f + 2],
                                        pad[f + 3],
                                    );
                                }
                            } else {
                                fx[..=nx].fill(0.0);
                            }
                            // y faces j and j + 1; the grid's own faces
                            // carry nothing.
                            let vr = |f: usize| &v[nx * (f + (ny + 1) * k)..][..nx];
                            let lf = if j > 0 { lr.max(lv[r - 1] as usize) } else { 0 };
                            if j > 0 && lf >= first {
                                if prev_valid {
                                    std::mem::swap(&mut fy_lo, &mut fy_hi);
                                } else {
                                    let sc = scales[lf];
                                    let (a, b, d) =
                                        (row(jj - 2, kk), row(jj - 1, kk), row(jj + 1, kk));
                                    let vl = vr(j);
                                    for i in 0..nx {
                                        fy_lo[i] = face_flux(vl[i] * sc, a[i], b[i], qc[i], d[i]);
                                    }
                                }
                            } else {
                                fy_lo[..nx].fill(0.0);
                            }
                            let lf = if j + 1 < ny {
                                lr.max(lv[r + 1] as usize)
                            } else {
                                0
                            };
                            if j + 1 < ny && lf >= first {
                                let sc = scales[lf];
                                let (a, c, d) = (row(jj - 1, kk), row(jj + 1, kk), row(jj + 2, kk));
                                let vh = vr(j + 1);
                                for i in 0..nx {
                                    fy_hi[i] = face_flux(vh[i] * sc, a[i], qc[i], c[i], d[i]);
                                }
                                hi_valid = true;
                            } else {
                                fy_hi[..nx].fill(0.0);
                            }
                            // z faces k and k + 1.
                            let lf = if k > 0 {
                                lr.max(lv[r - ny] as usize)
                            } else {
                                0
                            };
                            if k > 0 && lf >= first {
                                let sc = scales[lf];
                                let (a, b, d) = (row(jj, kk - 2), row(jj, kk - 1), row(jj, kk + 1));
                                let wl = &w[nx * (j + ny * k)..][..nx];
                                for i in 0..nx {
                                    fz_lo[i] = face_flux(wl[i] * sc, a[i], b[i], qc[i], d[i]);
                                }
                            } else {
                                fz_lo[..nx].fill(0.0);
                            }
                            let lf = if k + 1 < nz {
                                lr.max(lv[r + ny] as usize)
                            } else {
                                0
                            };
                            if k + 1 < nz && lf >= first {
                                let sc = scales[lf];
                                let (a, c, d) = (row(jj, kk - 1), row(jj, kk + 1), row(jj, kk + 2));
                                let wh = &w[nx * (j + ny * (k + 1))..][..nx];
                                for i in 0..nx {
                                    fz_hi[i] = face_flux(wh[i] * sc, a[i], qc[i], c[i], d[i]);
                                }
                            } else {
                                fz_hi[..nx].fill(0.0);
                            }
                            let ar = &mut acc[nx * j..][..nx];
                            for i in 0..nx {
                                ar[i] += (fx[i] - fx[i + 1])
                                    + (fy_lo[i] - fy_hi[i])
                                    + (fz_lo[i] - fz_hi[i]);
                            }
                            dirty[j] = true;
                        }
                    });
            }
            // Rows at the end of their sub-step take their fluxes; whatever
            // reached an open cell has left the room.
            {
                let (lv, flags) = (&self.row_level, &self.flags);
                self.density
                    .par_chunks_mut(slab)
                    .zip(self.flux_acc.par_chunks_mut(slab))
                    .zip(
                        self.row_dirty
                            .par_chunks_mut(ny)
                            .zip(self.row_live.par_chunks_mut(ny)),
                    )
                    .zip(self.slab_out.par_iter_mut())
                    .enumerate()
                    .for_each(|(k, (((q, acc), (dirty, live)), out))| {
                        *out = (0.0, 0);
                        for j in 0..ny {
                            if !dirty[j] || (lv[j + ny * k] as usize) < ending {
                                continue;
                            }
                            dirty[j] = false;
                            out.1 += 1;
                            let qr = &mut q[nx * j..][..nx];
                            let ar = &mut acc[nx * j..][..nx];
                            let fl = &flags[nx * (j + ny * k)..][..nx];
                            let mut any = false;
                            for i in 0..nx {
                                let mut d = qr[i] + ar[i];
                                ar[i] = 0.0;
                                if fl[i] != FLUID {
                                    if fl[i] == OPEN {
                                        out.0 += d as f64;
                                    }
                                    d = 0.0;
                                }
                                qr[i] = d;
                                any |= d != 0.0;
                            }
                            live[j] = any;
                        }
                    });
            }
            for &(o, n) in &self.slab_out {
                outflow += o;
                row_steps += n as u64;
            }
        }
        self.outflow += outflow * (self.h as f64).powi(3);
        (fine, row_steps as f64 / (ny * nz) as f64)
    }
}

/// The most density sub-steps a step takes (beyond, the Courant limit is
/// broken rather than the step made endless).
const MAX_SUBSTEPS: usize = 64;

/// The density sub-steps a cell needs whose outgoing Courant numbers sum
/// to `courant` over the whole step: ≤ 0.6 each.
fn substeps_for(courant: f32) -> usize {
    ((courant / 0.6).ceil() as usize).clamp(1, MAX_SUBSTEPS)
}

/// The sub-step counts the rows of one step may take: 1 and then `top`
/// halved while it stays whole (`top` = 2ᵃ or 3·2ᵃ, the smallest such ≥
/// the fastest row's need), so that each count divides the next and a
/// slower row's sub-step is a whole number of a faster one's.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Ladder {
    /// Sub-steps per step at each level, increasing; 0 past the last.
    count: [u32; 8],
    levels: usize,
}

impl Ladder {
    fn new(need: usize) -> Ladder {
        let need = need.clamp(1, MAX_SUBSTEPS);
        let top = need
            .next_power_of_two()
            .min(need.div_ceil(3).next_power_of_two() * 3);
        let mut count = [0u32; 8];
        count[0] = 1;
        let mut levels = 1;
        let mut c = if top.is_multiple_of(3) { 3 } else { 2 };
        while c <= top {
            count[levels] = c as u32;
            levels += 1;
            c *= 2;
        }
        Ladder { count, levels }
    }

    fn top_level(&self) -> usize {
        self.levels - 1
    }

    /// The sub-steps of the finest level: the step's sub-step clock.
    fn fine(&self) -> usize {
        self.count[self.top_level()] as usize
    }

    /// The lowest level whose count covers `need` sub-steps.
    fn level_for(&self, need: usize) -> usize {
        (0..self.levels)
            .find(|&l| self.count[l] as usize >= need)
            .unwrap_or(self.top_level())
    }

    /// The lowest level whose sub-steps start at fine sub-step `s`
    /// (0 ≤ s ≤ fine): every level from it up starts one there.
    fn first_active(&self, s: usize) -> usize {
        let fine = self.fine();
        (0..self.levels)
            .find(|&l| s.is_multiple_of(fine / self.count[l] as usize))
            .unwrap_or(self.top_level())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ladder_counts_nest_and_cover_the_need() {
        for need in 1..=MAX_SUBSTEPS {
            let l = Ladder::new(need);
            let fine = l.fine();
            // At most 1.5× the need (2ᵃ and 3·2ᵃ⁻¹ alternate), never less.
            assert!(fine >= need && 2 * fine <= 3 * need, "{need}: {l:?}");
            assert_eq!(l.count[0], 1);
            for a in 1..l.levels {
                assert_eq!(l.count[a] % l.count[a - 1], 0, "{l:?}");
            }
            for n in 1..=need {
                let lv = l.level_for(n);
                assert!(l.count[lv] as usize >= n);
                assert!(lv == 0 || (l.count[lv - 1] as usize) < n);
            }
            // A level's sub-steps start at every multiple of its stride, and
            // every finer level's start there too.
            for s in 0..=fine {
                let first = l.first_active(s);
                for a in 0..l.levels {
                    let stride = fine / l.count[a] as usize;
                    assert_eq!(s % stride == 0, a >= first, "{l:?} s {s} level {a}");
                }
            }
        }
    }
}
