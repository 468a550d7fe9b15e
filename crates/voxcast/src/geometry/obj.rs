//! Wavefront OBJ triangle meshes (read with the `tobj` crate). Polygons are
//! triangulated; points, lines, texture coordinates and materials are
//! ignored (the colour comes from the geometry file). Vertex normals (`vn`),
//! where every vertex of a mesh has one, shade the mesh smoothly; without
//! them faces are flat, which suits the furniture of indoor scenes.

use super::shapes::Triangle;
use crate::error::{Error, Result};
use glam::Vec3;
use std::path::Path;

/// A mesh's triangles and, when the file gives them, unit vertex normals
/// per triangle (same order).
#[derive(Clone, Debug, Default)]
pub struct ObjMesh {
    pub triangles: Vec<Triangle>,
    /// Empty, or one `[n_a, n_b, n_c]` per triangle.
    pub normals: Vec<[Vec3; 3]>,
}

/// Reads the triangles of `path`, each vertex placed at `p·scale + translate`.
pub fn load_obj(path: &Path, scale: f32, translate: Vec3) -> Result<ObjMesh> {
    if !(scale.is_finite() && scale > 0.0 && translate.is_finite()) {
        return Err(Error::invalid(format!(
            "mesh {}: scale must be positive and translate finite",
            path.display()
        )));
    }
    let file = crate::files::open(path)?.0;
    let mut reader = std::io::BufReader::new(file);
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // A parser bug must not take the program down with it: user files are
    // untrusted input.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        tobj::load_obj_buf(&mut reader, &opts, |_| {
            Err(tobj::LoadError::MaterialParseError)
        })
    }))
    .map_err(|_| Error::format(path, "obj", "the OBJ parser failed on this file"))?;
    let (models, _materials) = parsed.map_err(|e| {
        let (field, what) = match e {
            tobj::LoadError::FaceVertexOutOfBounds => (
                "f",
                "a face refers to a vertex that does not exist (OBJ indices count the `v` lines from 1; negative ones count back from the last)".to_string(),
            ),
            tobj::LoadError::FaceParseError | tobj::LoadError::InvalidPolygon => (
                "f",
                "a face line is not `f i j k …` with valid vertex indices".to_string(),
            ),
            tobj::LoadError::PositionParseError => {
                ("v", "a vertex line is not `v x y z` with numbers".to_string())
            }
            tobj::LoadError::ReadError => ("obj", "cannot read the file as text".to_string()),
            e => ("obj", e.to_string()),
        };
        Error::format(path, field, what)
    })?;
    let mut tris = Vec::new();
    let mut normals = Vec::new();
    // Smooth only when every vertex of every mesh has a usable normal.
    let smooth = models.iter().all(|m| {
        m.mesh.normals.len() == m.mesh.positions.len()
            && m.mesh.normals.chunks_exact(3).all(|n| {
                let n = Vec3::new(n[0], n[1], n[2]);
                n.is_finite() && n.length_squared() > 0.0
            })
    });
    for m in &models {
        let p = &m.mesh.positions;
        let normal = |i: u32| {
            let i = 3 * i as usize;
            Vec3::new(
                m.mesh.normals[i],
                m.mesh.normals[i + 1],
                m.mesh.normals[i + 2],
            )
            .normalize()
        };
        let vertex = |i: u32| -> Result<Vec3> {
            let i = i as usize;
            let v = p
                .get(3 * i..3 * i + 3)
                .map(|s| Vec3::new(s[0], s[1], s[2]))
                .ok_or_else(|| {
                    Error::format(path, "f", format!("vertex index {} out of range", i + 1))
                })?;
            if !v.is_finite() {
                return Err(Error::format(
                    path,
                    "v",
                    "a vertex coordinate is not finite",
                ));
            }
            Ok(v * scale + translate)
        };
        for f in m.mesh.indices.chunks_exact(3) {
            let t = Triangle {
                a: vertex(f[0])?,
                b: vertex(f[1])?,
                c: vertex(f[2])?,
            };
            // Degenerate triangles have no normal and cover nothing.
            if (t.b - t.a).cross(t.c - t.a).length_squared() > 0.0 {
                tris.push(t);
                if smooth {
                    normals.push([normal(f[0]), normal(f[1]), normal(f[2])]);
                }
            }
        }
    }
    if tris.is_empty() {
        return Err(Error::format(
            path,
            "f",
            "no triangles: an OBJ mesh needs `v` vertex lines and `f` face lines",
        ));
    }
    Ok(ObjMesh {
        triangles: tris,
        normals,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn quad_is_two_triangles_placed_by_scale_and_translate() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(
            dir.path(),
            "quad.obj",
            "# a unit square\nmtllib none.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n",
        );
        let m = load_obj(&p, 2.0, Vec3::new(0.0, 0.0, 5.0)).unwrap();
        let t = &m.triangles;
        assert_eq!(t.len(), 2);
        // Every vertex has `vn 0 0 1`: smooth normals, all +z.
        assert_eq!(m.normals.len(), 2);
        assert!(m.normals.iter().flatten().all(|n| *n == Vec3::Z));
        let area: f32 = t
            .iter()
            .map(|t| 0.5 * (t.b - t.a).cross(t.c - t.a).length())
            .sum();
        assert!((area - 4.0).abs() < 1e-6);
        assert!(t.iter().all(|t| t.a.z == 5.0 && t.b.z == 5.0));
        // Negative (relative) indices are valid OBJ.
        let p = write(
            dir.path(),
            "rel.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\n",
        );
        let m = load_obj(&p, 1.0, Vec3::ZERO).unwrap();
        assert_eq!(m.triangles.len(), 1);
        assert!(m.normals.is_empty()); // no `vn`: flat
    }

    #[test]
    fn errors_name_the_file_and_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("chair.obj");
        let e = load_obj(&missing, 1.0, Vec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("chair.obj"), "{e}");
        let bad = write(
            dir.path(),
            "bad.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        );
        let e = load_obj(&bad, 1.0, Vec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("bad.obj") && e.contains("`f`"), "{e}");
        let bad = write(dir.path(), "neg.obj", "v 0 0 0\nf 1 -5 1\n");
        let e = load_obj(&bad, 1.0, Vec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("neg.obj"), "{e}");
        let bad = write(
            dir.path(),
            "v.obj",
            "v 0 zero 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        );
        let e = load_obj(&bad, 1.0, Vec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("v.obj") && e.contains("`v`"), "{e}");
        let empty = write(dir.path(), "empty.obj", "# nothing\n");
        let e = load_obj(&empty, 1.0, Vec3::ZERO).unwrap_err().to_string();
        assert!(e.contains("empty.obj") && e.contains("no triangles"), "{e}");
        let p = write(dir.path(), "ok.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        assert!(load_obj(&p, 0.0, Vec3::ZERO).is_err());
        // Garbage bytes: an error, not a panic.
        let g = dir.path().join("garbage.obj");
        std::fs::write(&g, [0xffu8, 0xfe, b'f', b' ', b'1', 0, 0x80]).unwrap();
        assert!(load_obj(&g, 1.0, Vec3::ZERO).is_err());
    }
}
