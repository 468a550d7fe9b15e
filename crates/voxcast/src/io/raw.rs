//! Headerless raw voxels: the layout comes from the command line
//! (`--raw-dims X,Y,Z --raw-type T [--raw-endian E] [--spacing x,y,z]`).

use super::util::{check_dims, read_payload};
use super::RawLayout;
use crate::error::Result;
use crate::volume::Volume;
use glam::Vec3;
use std::path::Path;

/// Reads `path` as raw voxels with `layout` (spacing 1, origin 0).
pub fn read(path: &Path, layout: &RawLayout) -> Result<Volume> {
    let (_, bytes) = check_dims(path, "--raw-dims", layout.dims, layout.scalar_type)?;
    let data = read_payload(
        path,
        layout.header_bytes,
        bytes,
        layout.scalar_type,
        layout.big_endian,
        false,
        "--raw-dims/--raw-type",
    )?;
    let dims = layout.dims.map(|d| d as usize);
    Volume::new(dims, Vec3::ONE, Vec3::ZERO, data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::ScalarType;

    fn layout(dims: [u64; 3], ty: ScalarType, big: bool) -> RawLayout {
        RawLayout {
            dims,
            scalar_type: ty,
            big_endian: big,
            header_bytes: 0,
        }
    }

    #[test]
    fn reads_big_endian_u16() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.raw");
        let vals: Vec<u16> = (0..24).map(|i| i * 1000).collect();
        let bytes: Vec<u8> = vals.iter().flat_map(|v| v.to_be_bytes()).collect();
        std::fs::write(&p, bytes).unwrap();
        let v = read(&p, &layout([2, 3, 4], ScalarType::U16, true)).unwrap();
        assert_eq!(v.dims(), [2, 3, 4]);
        assert_eq!(v.value(1, 2, 3), 23000.0);
        assert_eq!(v.stats().max, 23000.0);
    }

    #[test]
    fn too_small_file_is_an_error_naming_the_flag() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.raw");
        std::fs::write(&p, [0u8; 1024]).unwrap();
        let e = read(&p, &layout([1000, 1000, 1000], ScalarType::U8, false)).unwrap_err();
        let s = e.to_string();
        assert!(
            s.contains("v.raw") && s.contains("--raw-dims") && s.contains("1000000000"),
            "{s}"
        );
        let e = read(&p, &layout([0, 4, 4], ScalarType::U8, false)).unwrap_err();
        assert!(e.to_string().contains("at least 1"), "{e}");
        let e = read(&p, &layout([u64::MAX, 2, 2], ScalarType::F32, false)).unwrap_err();
        assert!(e.to_string().contains("more than"), "{e}");
    }
}
