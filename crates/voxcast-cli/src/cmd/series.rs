//! A series and its selected frames, for animate and bench-frames.

use crate::args::SceneArgs;
use anyhow::{bail, Context, Result};
use std::path::PathBuf;
use voxcast::io::Series;
use voxcast::render::MethodSpec;
use voxcast::scene::Scene;

/// Parses `A..B`, `A..=B`, `A..`, `..B` into indices of a series of `n`.
pub fn select(spec: Option<&str>, every: usize, n: usize) -> Result<Vec<usize>> {
    if every == 0 {
        bail!("--every 0: expected 1 or more");
    }
    let (a, b) = match spec {
        None => (0, n),
        Some(s) => {
            let (l, r, incl) = if let Some((l, r)) = s.split_once("..=") {
                (l, r, true)
            } else if let Some((l, r)) = s.split_once("..") {
                (l, r, false)
            } else {
                bail!("--frames {s}: expected A..B (e.g. 0..100, 50.., ..=20)");
            };
            let num = |t: &str, d: usize| -> Result<usize> {
                if t.trim().is_empty() {
                    Ok(d)
                } else {
                    t.trim()
                        .parse()
                        .map_err(|_| anyhow::anyhow!("--frames {s}: `{t}` is not a frame index"))
                }
            };
            let a = num(l, 0)?;
            let b = num(r, n)? + usize::from(incl && !r.trim().is_empty());
            (a, b.min(n))
        }
    };
    let v: Vec<usize> = (a..b).step_by(every).collect();
    if v.is_empty() {
        bail!(
            "--frames {}: selects no frame of the {n} in the series",
            spec.unwrap_or("")
        );
    }
    Ok(v)
}

/// The scene and the series these flags imply; the transfer function and
/// window are fixed from the last selected frame.
pub fn scene_and_series(scene_args: &SceneArgs, method: Option<&str>) -> Result<(Scene, Series)> {
    let mut scene = scene_args.base_scene()?;
    if let Some(m) = method {
        MethodSpec::parse(m)
            .with_context(|| format!("--method {m}"))?
            .apply(&mut scene.render);
    }
    scene_args.apply(&mut scene)?;
    if scene.input.path.starts_with(voxcast::scene::BUILTIN_PREFIX) {
        bail!("give a series: a frame folder, an FDS .smv, or a folder/glob of volumes");
    }
    let path = PathBuf::from(&scene.input.path);
    let series = Series::open(&path, &scene.input.options)
        .with_context(|| format!("opening {} as a series", path.display()))?;
    Ok((scene, series))
}

/// Fixes the transfer function and window from frame `i`, so every frame
/// is drawn with the same mapping.
pub fn fix_transfer(scene: &Scene, series: &Series, i: usize) -> Result<Scene> {
    let v = series.load(i, &scene.input.options)?;
    let prepared = scene.prepare_with(v)?;
    Ok(scene.resolved(&prepared))
}

#[cfg(test)]
mod tests {
    use super::select;

    #[test]
    fn frame_selection() {
        assert_eq!(select(None, 1, 4).unwrap(), vec![0, 1, 2, 3]);
        assert_eq!(select(Some("1..3"), 1, 10).unwrap(), vec![1, 2]);
        assert_eq!(select(Some("1..=3"), 1, 10).unwrap(), vec![1, 2, 3]);
        assert_eq!(select(Some("5.."), 2, 10).unwrap(), vec![5, 7, 9]);
        assert_eq!(select(Some("..3"), 1, 10).unwrap(), vec![0, 1, 2]);
        assert_eq!(select(Some("0..100"), 50, 10).unwrap(), vec![0]);
        assert!(select(Some("20..30"), 1, 10).is_err());
        assert!(select(Some("x..3"), 1, 10).is_err());
        assert!(select(None, 0, 10).is_err());
    }
}
