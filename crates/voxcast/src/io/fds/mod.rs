//! NIST Fire Dynamics Simulator (FDS) output, opened through its Smokeview
//! index file `.smv`.
//!
//! * [`parse_smv`] reads the `.smv` text: meshes (GRID, PDIM, TRNX/Y/Z),
//!   obstructions (OBST boxes in metres, zero-volume ones skipped), SMOKE3D
//!   files (`SMOKF3D`), PLOT3D files (`PL3D`, time taken from the file name)
//!   and slices (`SLCF`/`SLCC`).
//! * [`read`] picks a quantity (`--var`, default soot density from SMOKE3D)
//!   and a time (`--time`, nearest frame, default the last one) and returns
//!   it as an f32 volume at the mesh nodes. Soot bytes are converted to the
//!   extinction coefficient in 1/m; HRRPUV and temperature bytes to kW/m³ and
//!   °C; `.q` PLOT3D and 3D `.sf` slices are read as floats.
//!
//! Every length read from a binary file is checked against the file's size
//! before anything is allocated; a truncated frame is an error naming the
//! file, the frame and the byte counts.
//!
//! A quantity can be forced to a source with a prefix: `s3d:temp`,
//! `sf:temp`, `q:temp` (also `smoke3d:`, `slice:`, `plot3d:`). Without one,
//! SMOKE3D is tried first, then 3D slices, then PLOT3D.
//!
//! The reader is split by what it reads:
//!
//! * `model.rs` — what a parsed `.smv` holds ([`Smv`], [`Mesh`], …) and its
//!   summary;
//! * `smv.rs` — the `.smv` text parser ([`parse_smv`]);
//! * `data.rs` — helpers shared by the binary readers (little-endian fields,
//!   bounded reads, the frame nearest a time);
//! * `s3d.rs` — SMOKE3D `.s3d` files (RLE frames, byte → physical value);
//! * `plot3d.rs` — PLOT3D `.q` and `.xyz` files and the solid-node mask;
//! * `slice.rs` — `.sf` slice files;
//! * `read.rs` — quantity selection and [`read`] / [`times`].

mod data;
mod model;
mod plot3d;
mod read;
mod s3d;
mod slice;
mod smv;
mod summary;

pub use model::{Mesh, Obstruction, Plot3d, Quantity, Slice, Smoke3d, Smv};
pub use plot3d::{read_q_variable, read_xyz_iblank};
pub use read::{quantities, read, times};
pub use s3d::{decode_rle, read_s3d_frame, s3d_times, soot_extinction, S3dFrame};
pub use slice::{read_sf_frame, SfFrame};
pub use smv::{parse_smv, time_from_q_name};

/// Test helpers shared by the parts' tests.
#[cfg(test)]
mod test_support {
    use std::path::{Path, PathBuf};

    pub(super) fn smv_path() -> Option<PathBuf> {
        crate::testdata::data_path("fds_room/room_smoke.smv")
    }

    /// Copies the case into a temp dir.
    pub(super) fn copy_case(src: &Path) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for e in std::fs::read_dir(src.parent().unwrap()).unwrap() {
            let e = e.unwrap();
            let n = e.file_name().to_string_lossy().to_string();
            if n.ends_with(".smv") || n.ends_with("_1_1.s3d") || n.ends_with(".xyz") {
                std::fs::copy(e.path(), dir.path().join(&n)).unwrap();
            }
        }
        dir
    }
}
