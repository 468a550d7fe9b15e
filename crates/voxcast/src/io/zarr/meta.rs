//! OME-Zarr metadata: the group's attributes, the multiscales' axes and
//! coordinate transformations, and what an array's metadata names.

use super::keys::Keys;
use crate::error::{Error, Result};
use serde_json::Value;
use std::path::Path;
use zarrs::array::ArrayMetadata;

/// The group's attributes: `zarr.json`'s `attributes` (v3) or `.zattrs` (v2).
pub(super) fn group_attributes(
    keys: &Keys<'_>,
    zarr_format: u8,
) -> Result<serde_json::Map<String, Value>> {
    let v = if zarr_format == 3 {
        keys.json("zarr.json")?
            .get("attributes")
            .cloned()
            .unwrap_or(Value::Null)
    } else if keys.exists(".zattrs") {
        keys.json(".zattrs")?
    } else {
        Value::Null
    };
    Ok(match v {
        Value::Object(m) => m,
        _ => serde_json::Map::new(),
    })
}

pub(super) fn parse_axes(
    path: &Path,
    v: Option<&Value>,
) -> Result<Vec<(String, String, Option<String>)>> {
    let Some(list) = v.and_then(|a| a.as_array()) else {
        return Ok(Vec::new());
    };
    list.iter()
        .enumerate()
        .map(|(i, a)| {
            if let Some(s) = a.as_str() {
                // OME-Zarr 0.3: axis names only.
                let kind = match s {
                    "t" => "time",
                    "c" => "channel",
                    _ => "space",
                };
                return Ok((s.to_string(), kind.to_string(), None));
            }
            let name = a.get("name").and_then(|n| n.as_str()).ok_or_else(|| {
                Error::format(
                    path,
                    format!("multiscales[0].axes[{i}].name"),
                    "expected a string",
                )
            })?;
            let kind = a
                .get("type")
                .and_then(|n| n.as_str())
                .map(str::to_string)
                .unwrap_or_else(|| match name {
                    "x" | "y" | "z" => "space".into(),
                    "t" => "time".into(),
                    "c" => "channel".into(),
                    _ => String::new(),
                });
            let unit = a.get("unit").and_then(|n| n.as_str()).map(str::to_string);
            Ok((name.to_string(), kind, unit))
        })
        .collect()
}

/// Positions of z, y, x among the axes: the last three, in that order.
pub(super) fn spatial_axes(
    path: &Path,
    axes: &[(String, String, Option<String>)],
) -> Result<[usize; 3]> {
    let n = axes.len();
    let space: Vec<usize> = (0..n).filter(|&i| axes[i].1 == "space").collect();
    let names: Vec<&str> = axes.iter().map(|a| a.0.as_str()).collect();
    if space.len() != 3 || space != [n - 3, n - 2, n - 1] {
        return Err(Error::unsupported(
            path,
            format!(
                "axes [{}]: a volume needs three space axes, last (OME-Zarr's order)",
                names.join(", ")
            ),
        ));
    }
    if names[n - 3..] != ["z", "y", "x"] {
        return Err(Error::unsupported(
            path,
            format!(
                "space axes [{}]: voxcast reads them in the order z, y, x (x fastest in memory)",
                names[n - 3..].join(", ")
            ),
        ));
    }
    Ok([n - 3, n - 2, n - 1])
}

/// The scale and translation of a `coordinateTransformations` list (empty
/// where absent).
pub(super) fn transforms(path: &Path, field: &str, node: &Value) -> Result<(Vec<f64>, Vec<f64>)> {
    let mut scale = Vec::new();
    let mut trans = Vec::new();
    let Some(list) = node
        .get("coordinateTransformations")
        .and_then(|c| c.as_array())
    else {
        return Ok((scale, trans));
    };
    for (i, t) in list.iter().enumerate() {
        let nums = |key: &str| -> Result<Vec<f64>> {
            t.get(key)
                .and_then(|v| v.as_array())
                .and_then(|a| a.iter().map(|x| x.as_f64()).collect::<Option<Vec<f64>>>())
                .ok_or_else(|| {
                    Error::format(
                        path,
                        format!("{field}[{i}].{key}"),
                        "expected a list of numbers",
                    )
                })
        };
        match t.get("type").and_then(|v| v.as_str()) {
            Some("scale") => scale = nums("scale")?,
            Some("translation") => trans = nums("translation")?,
            Some("identity") => {}
            other => {
                return Err(Error::unsupported(
                    path,
                    format!("{field}[{i}]: transformation type {other:?} (voxcast reads scale and translation)"),
                ))
            }
        }
    }
    Ok((scale, trans))
}

pub(super) fn compose_scale(s: &[f64], g: &[f64]) -> Vec<f64> {
    let n = s.len().max(g.len());
    (0..n)
        .map(|i| s.get(i).copied().unwrap_or(1.0) * g.get(i).copied().unwrap_or(1.0))
        .collect()
}

pub(super) fn compose_translation(t: &[f64], gs: &[f64], gt: &[f64]) -> Vec<f64> {
    let n = t.len().max(gt.len());
    (0..n)
        .map(|i| {
            t.get(i).copied().unwrap_or(0.0) * gs.get(i).copied().unwrap_or(1.0)
                + gt.get(i).copied().unwrap_or(0.0)
        })
        .collect()
}

pub(super) fn data_type_name(m: &ArrayMetadata) -> String {
    match m {
        ArrayMetadata::V3(v) => v.data_type.name().to_string(),
        ArrayMetadata::V2(v) => serde_json::to_string(&v.dtype).unwrap_or_default(),
    }
}

pub(super) fn codec_names(m: &ArrayMetadata) -> Vec<String> {
    match m {
        ArrayMetadata::V3(v) => v.codecs.iter().map(|c| c.name().to_string()).collect(),
        ArrayMetadata::V2(v) => {
            let mut out: Vec<String> = v
                .filters
                .iter()
                .flatten()
                .map(|f| f.id().to_string())
                .collect();
            if let Some(c) = &v.compressor {
                out.push(c.id().to_string());
            }
            out
        }
    }
}
