//! PLOT3D `.q` solution and `.xyz` grid files, and the solid-node mask
//! (iblank from the `.xyz` file or from the OBST cell boxes) applied to
//! PLOT3D and slice values.

use super::data::{le_i32, open_data, read_at};
use super::model::Smv;
use crate::error::{Error, Result};
use std::path::Path;

/// Reads variable `n` (0..5) of a PLOT3D `.q` file with node dims `dims`.
pub fn read_q_variable(path: &Path, dims: [usize; 3], n: usize) -> Result<Vec<f32>> {
    let (mut r, len) = open_data(path, "PL3D", path)?;
    let h = read_at(&mut r, path, len, 0, 48, "header")?;
    if le_i32(&h, 0) != 12 || le_i32(&h, 16) != 12 || le_i32(&h, 20) != 16 || le_i32(&h, 40) != 16 {
        return Err(Error::format(
            path,
            "header",
            "bad record markers (not a PLOT3D .q file?)",
        ));
    }
    check_plot3d_dims(path, &h, dims)?;
    let np = dims[0] * dims[1] * dims[2];
    let nq = (le_i32(&h, 44).max(0) as u64) / (4 * np as u64);
    if nq == 0 || le_i32(&h, 44) as u64 != nq * 4 * np as u64 {
        return Err(Error::format(
            path,
            "data",
            format!(
                "record of {} bytes is not a whole number of variables",
                le_i32(&h, 44)
            ),
        ));
    }
    if n as u64 >= nq {
        return Err(Error::format(
            path,
            "variable",
            format!("index {n} of {nq}"),
        ));
    }
    let b = read_at(&mut r, path, len, 48 + (4 * np * n) as u64, 4 * np, "data")?;
    Ok(b.chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Checks the node dims in a PLOT3D header (`.q` or `.xyz`) against the mesh.
fn check_plot3d_dims(path: &Path, h: &[u8], dims: [usize; 3]) -> Result<()> {
    let d = [le_i32(h, 4), le_i32(h, 8), le_i32(h, 12)];
    if d.map(|x| x as i64) != dims.map(|x| x as i64) {
        return Err(Error::format(
            path,
            "dims",
            format!("{d:?} but the mesh has {dims:?} nodes"),
        ));
    }
    Ok(())
}

/// The iblank array of a PLOT3D `.xyz` file (0 = all 8 cells round the node are solid).
pub fn read_xyz_iblank(path: &Path, dims: [usize; 3]) -> Result<Vec<i32>> {
    let (mut r, len) = open_data(path, "XYZ", path)?;
    let h = read_at(&mut r, path, len, 0, 24, "header")?;
    check_plot3d_dims(path, &h, dims)?;
    let np = dims[0] * dims[1] * dims[2];
    let b = read_at(&mut r, path, len, 24 + 12 * np as u64, 4 * np, "iblank")?;
    Ok(b.chunks_exact(4)
        .map(|c| i32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Node iblank computed from the OBST cell boxes (ghost cells outside the
/// mesh copy the nearest interior cell): 0 where all 8 surrounding cells are solid.
fn iblank_from_obst(smv: &Smv, mesh: usize) -> Vec<i32> {
    let m = &smv.meshes[mesh];
    let [ci, cj, ck] = m.cells;
    let mut solid = vec![false; ci * cj * ck];
    for o in smv.obstructions.iter().filter(|o| o.mesh == mesh) {
        if let Some(c) = o.cells {
            let cl = |a: i64, n: usize| a.clamp(0, n as i64) as usize;
            for k in cl(c[4], ck)..cl(c[5], ck) {
                for j in cl(c[2], cj)..cl(c[3], cj) {
                    for i in cl(c[0], ci)..cl(c[1], ci) {
                        solid[i + ci * (j + cj * k)] = true;
                    }
                }
            }
        }
    }
    let [ni, nj, nk] = m.node_dims();
    let mut ib = vec![1; ni * nj * nk];
    for k in 0..nk {
        for j in 0..nj {
            for i in 0..ni {
                let mut all = true;
                'o: for dk in 0..2 {
                    for dj in 0..2 {
                        for di in 0..2 {
                            // Ghost cells outside the mesh copy the
                            // nearest interior cell.
                            let x = (i + di).clamp(1, ci);
                            let y = (j + dj).clamp(1, cj);
                            let z = (k + dk).clamp(1, ck);
                            if !solid[(x - 1) + ci * ((y - 1) + cj * (z - 1))] {
                                all = false;
                                break 'o;
                            }
                        }
                    }
                }
                if all {
                    ib[i + ni * (j + nj * k)] = 0;
                }
            }
        }
    }
    ib
}

/// The PLOT3D/slice solid-node quirk: nodes whose 8 surrounding cells are all
/// solid hold the quantity's ambient value (air density, 1.195 kg/m³, for
/// soot DENSITY). Gives them the minimum over gas nodes instead. `bounds` are
/// the node bounds of `data` within the mesh (checked by the caller).
pub(super) fn mask_solid_nodes(smv: &Smv, mesh: usize, bounds: [usize; 6], data: &mut [f32]) {
    let nd = smv.meshes[mesh].node_dims();
    let iblank = smv
        .xyz
        .iter()
        .find(|x| x.0 == mesh)
        .and_then(|x| read_xyz_iblank(&x.1, nd).ok())
        .unwrap_or_else(|| iblank_from_obst(smv, mesh));
    let dims = [0, 1, 2].map(|a| bounds[2 * a + 1] - bounds[2 * a] + 1);
    if data.len() != dims[0] * dims[1] * dims[2] {
        return;
    }
    let solid = |n: usize| {
        let (i, j, k) = (
            n % dims[0],
            (n / dims[0]) % dims[1],
            n / (dims[0] * dims[1]),
        );
        let (i, j, k) = (i + bounds[0], j + bounds[2], k + bounds[4]);
        iblank[i + nd[0] * (j + nd[1] * k)] == 0
    };
    let gas_min = data
        .iter()
        .enumerate()
        .filter(|(n, _)| !solid(*n))
        .map(|(_, &v)| v)
        .fold(f32::INFINITY, f32::min);
    if gas_min.is_finite() {
        for (n, v) in data.iter_mut().enumerate() {
            if solid(n) {
                *v = gas_min;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::fds::parse_smv;
    use crate::io::fds::test_support::smv_path;

    #[test]
    fn iblank_from_obst_matches_xyz() {
        let Some(p) = smv_path() else { return };
        let smv = parse_smv(&p).unwrap();
        let xyz = read_xyz_iblank(&smv.xyz[0].1, [51, 31, 26]).unwrap();
        assert_eq!(xyz.iter().filter(|&&b| b == 0).count(), 820);
        let ob = iblank_from_obst(&smv, 0);
        let diff = xyz.iter().zip(&ob).filter(|(a, b)| a != b).count();
        assert_eq!(diff, 0);
    }
}
