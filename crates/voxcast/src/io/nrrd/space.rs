//! The space fields: which axes are spatial (`space directions:` `none`,
//! `kinds:`, a dropped axis of size 1), the spacing from `space
//! directions:` or `spacings:`, and `space origin:`.

use crate::error::{Error, Result};
use crate::io::decode::{check_origin, check_spacing, join, parse_floats, shorten};
use glam::Vec3;
use std::path::Path;

/// The axes (indices into `sizes:`) that become x, y and z.
/// The axes read as x, y, z. An axis whose `space directions:` entry is
/// `none`, or whose `kinds:` entry is not a space kind, is not spatial (and
/// must have size 1), wherever it is; without such marks a first or last
/// axis of size 1 is dropped from a 4-D array.
pub(super) fn spatial_axes(
    path: &Path,
    dimension: usize,
    sizes: &[u64],
    directions: Option<&str>,
    kinds: Option<&str>,
) -> Result<Vec<usize>> {
    let mut non_spatial = vec![false; dimension];
    if let Some(d) = directions {
        let v = parse_vectors(path, "space directions", d)?;
        if v.len() == dimension {
            for (n, e) in non_spatial.iter_mut().zip(&v) {
                *n |= e.is_none();
            }
        }
    }
    if let Some(k) = kinds {
        let k: Vec<String> = k
            .split_whitespace()
            .map(|w| w.to_ascii_lowercase())
            .collect();
        if k.len() == dimension {
            for (n, w) in non_spatial.iter_mut().zip(&k) {
                // teem's spatial kinds; `???`/`none` say nothing.
                let spatial = matches!(w.as_str(), "domain" | "space" | "???" | "none");
                *n |= !spatial;
            }
        }
    }
    if non_spatial.iter().any(|&n| n) {
        for (a, &n) in non_spatial.iter().enumerate() {
            if n && sizes.get(a) != Some(&1) {
                return Err(Error::unsupported(
                    path,
                    format!(
                        "axis {a} (size {}) is not a space axis (`none` direction or a non-space kind): only one-component non-space axes can be dropped",
                        sizes.get(a).copied().unwrap_or(0)
                    ),
                ));
            }
        }
        let axes: Vec<usize> = (0..dimension).filter(|&a| !non_spatial[a]).collect();
        if (2..=3).contains(&axes.len()) {
            return Ok(axes);
        }
    }
    match dimension {
        2 => Ok(vec![0, 1]),
        3 => Ok(vec![0, 1, 2]),
        4 if sizes.first() == Some(&1) => Ok(vec![1, 2, 3]),
        4 if sizes.get(3) == Some(&1) => Ok(vec![0, 1, 2]),
        4 => Err(Error::unsupported(
            path,
            format!(
                "dimension 4 with sizes {}: only a first or last axis of size 1 can be dropped",
                join(sizes)
            ),
        )),
        _ => Err(Error::unsupported(
            path,
            format!("dimension {dimension} (only 2, 3, or 4 with a first or last axis of size 1)"),
        )),
    }
}

/// Spacing of the spatial axes, from `space directions:` or `spacings:`.
pub(super) fn nrrd_spacing(
    path: &Path,
    directions: Option<&str>,
    spacings: Option<&str>,
    dimension: usize,
    spatial: &[usize],
) -> Result<Vec3> {
    let mut sp = [1.0f64; 3];
    if let Some(s) = directions {
        let field = "space directions";
        let vecs = parse_vectors(path, field, s)?;
        if vecs.len() != dimension {
            return Err(Error::format(
                path,
                field,
                format!("{} entries for dimension {dimension}", vecs.len()),
            ));
        }
        for (out, axis) in sp.iter_mut().zip(spatial) {
            if let Some(Some(v)) = vecs.get(*axis) {
                *out = v.iter().map(|c| c * c).sum::<f64>().sqrt();
            }
        }
        check_spacing(path, field, sp)
    } else if let Some(s) = spacings {
        let field = "spacings";
        let vals = parse_floats(path, field, s)?;
        if vals.len() != dimension {
            return Err(Error::format(
                path,
                field,
                format!("{} spacings for dimension {dimension}", vals.len()),
            ));
        }
        for (out, axis) in sp.iter_mut().zip(spatial) {
            match vals.get(*axis) {
                Some(v) if v.is_nan() => eprintln!(
                    "warning: {}: field `spacings`: nan for axis {axis}: spacing 1 used",
                    path.display()
                ),
                Some(v) if !(*v > 0.0 && v.is_finite()) => {
                    return Err(Error::format(
                        path,
                        field,
                        format!("{v} for axis {axis}: a spacing must be a positive finite number"),
                    ))
                }
                Some(v) => *out = *v,
                None => {}
            }
        }
        check_spacing(path, field, sp)
    } else {
        Ok(Vec3::ONE)
    }
}

pub(super) fn nrrd_origin(path: &Path, s: &str) -> Result<Vec3> {
    let field = "space origin";
    match parse_vectors(path, field, s)?.as_slice() {
        [Some(v)] if v.len() == 2 || v.len() == 3 => {
            check_origin(path, field, [v[0], v[1], v.get(2).copied().unwrap_or(0.0)])
        }
        _ => Err(Error::format(
            path,
            field,
            format!("`{s}`: expected one vector `(x,y,z)`"),
        )),
    }
}

/// Parses `(x,y,z) none (x,y,z)…` (spaces inside the brackets allowed).
fn parse_vectors(path: &Path, field: &str, s: &str) -> Result<Vec<Option<Vec<f64>>>> {
    let mut out = Vec::new();
    let mut rest = s.trim();
    while !rest.is_empty() {
        if let Some(r) = rest.strip_prefix('(') {
            let Some((inner, after)) = r.split_once(')') else {
                return Err(Error::format(path, field, format!("`{s}`: unclosed `(`")));
            };
            out.push(Some(parse_floats(path, field, inner)?));
            rest = after.trim_start();
        } else if let Some(r) = rest.strip_prefix("none") {
            out.push(None);
            rest = r.trim_start();
        } else {
            return Err(Error::format(
                path,
                field,
                format!("`{}`: expected `(x,y,z)` or `none`", shorten(rest)),
            ));
        }
    }
    Ok(out)
}
