//! What a parsed `.smv` holds: meshes, obstructions, the SMOKE3D, PLOT3D
//! and slice files with their quantities (its description, which scans the
//! data files, is `summary.rs`).

use glam::Vec3;
use std::path::PathBuf;

/// A quantity's labels as FDS writes them.
#[derive(Clone, Debug, PartialEq)]
pub struct Quantity {
    /// e.g. `SOOT DENSITY`.
    pub long: String,
    /// e.g. `rho_C`.
    pub short: String,
    /// e.g. `kg/m3`.
    pub units: String,
}

impl Quantity {
    pub(super) fn matches(&self, name: &str) -> bool {
        let n = name.trim();
        self.long.eq_ignore_ascii_case(n) || self.short.eq_ignore_ascii_case(n)
    }
}

/// One FDS mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// The GRID name, e.g. `MESH_0000001`.
    pub name: String,
    /// Cells along x, y, z (IBAR, JBAR, KBAR).
    pub cells: [usize; 3],
    /// PDIM: xmin xmax ymin ymax zmin zmax, metres.
    pub bounds: [f32; 6],
    /// Node coordinates (TRNX, TRNY, TRNZ): `cells[a] + 1` values each; empty
    /// when the `.smv` has no TRN block for this mesh.
    pub nodes: [Vec<f32>; 3],
}

impl Mesh {
    /// Node counts (IBAR+1, JBAR+1, KBAR+1).
    pub fn node_dims(&self) -> [usize; 3] {
        self.cells.map(|c| c + 1)
    }

    /// Cell size along each axis, from PDIM (uniform grids).
    pub fn cell_size(&self) -> Vec3 {
        let b = self.bounds;
        Vec3::new(
            (b[1] - b[0]) / self.cells[0] as f32,
            (b[3] - b[2]) / self.cells[1] as f32,
            (b[5] - b[4]) / self.cells[2] as f32,
        )
    }

    /// Minimum corner (PDIM).
    pub fn origin(&self) -> Vec3 {
        Vec3::new(self.bounds[0], self.bounds[2], self.bounds[4])
    }

    /// Whether the node coordinates are evenly spaced (true when unknown).
    pub(super) fn is_uniform(&self) -> bool {
        let h = self.cell_size().to_array();
        let o = self.origin().to_array();
        (0..3).all(|a| {
            self.nodes[a]
                .iter()
                .enumerate()
                .all(|(i, &x)| (x - (o[a] + i as f32 * h[a])).abs() <= 1e-3 * h[a].abs().max(1e-6))
        })
    }
}

/// An obstruction box, world coordinates in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Obstruction {
    /// Index into [`Smv::meshes`].
    pub mesh: usize,
    pub min: Vec3,
    pub max: Vec3,
    /// The FDS ID (text after `!`), e.g. `Table top`.
    pub label: String,
    /// RGBA in 0..1 when the `.smv` gives it (colour index −3).
    pub color: Option<[f32; 4]>,
    /// Cell index bounds i1 i2 j1 j2 k1 k2 (solid cells i1+1..=i2, 1-based).
    pub cells: Option<[i64; 6]>,
}

/// A SMOKE3D file (`SMOKF3D`/`SMOKE3D`).
#[derive(Clone, Debug, PartialEq)]
pub struct Smoke3d {
    pub file: PathBuf,
    /// Index into [`Smv::meshes`].
    pub mesh: usize,
    /// Mass extinction coefficient K_m (m²/kg); 0 = not soot.
    pub k_m: f32,
    pub quantity: Quantity,
}

/// A PLOT3D solution file (`PL3D`).
#[derive(Clone, Debug, PartialEq)]
pub struct Plot3d {
    pub file: PathBuf,
    pub mesh: usize,
    /// Time in s, from the file name `_<int>p<2 digits>.q` when it has one
    /// (the `.smv` value loses a digit: 20.01 s is written `20.1`).
    pub time: f64,
    /// The time written in the `.smv` line.
    pub time_smv: f64,
    /// Usually 5 quantities, in file order.
    pub quantities: Vec<Quantity>,
}

/// A slice file (`SLCF`, `SLCC`).
#[derive(Clone, Debug, PartialEq)]
pub struct Slice {
    pub file: PathBuf,
    pub mesh: usize,
    /// Node index bounds i1 i2 j1 j2 k1 k2, when the `.smv` line gives them.
    pub bounds: Option<[usize; 6]>,
    pub quantity: Quantity,
    /// True when no axis of `bounds` is degenerate.
    pub is_3d: bool,
}

/// A parsed `.smv` file. File paths are resolved against its folder.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Smv {
    pub path: PathBuf,
    pub chid: Option<String>,
    pub meshes: Vec<Mesh>,
    pub obstructions: Vec<Obstruction>,
    /// Zero-volume OBST entries that were skipped (e.g. door HOLE remnants).
    pub skipped_obstructions: usize,
    pub smoke3d: Vec<Smoke3d>,
    pub pl3d: Vec<Plot3d>,
    pub slices: Vec<Slice>,
    /// PLOT3D grid files (`XYZ`), per mesh index.
    pub xyz: Vec<(usize, PathBuf)>,
}
