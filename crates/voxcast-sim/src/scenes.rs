//! Smoke scenes: the grid, the solids, the fire, the openings and the
//! physical constants of one simulation, as plain TOML data. The presets
//! (`room`, `office`, `corridor`) mirror the scenes of Liu, Lu & Chang 2021
//! (SPEC §S0): a closed space with a few objects; an office with desks,
//! chairs, a cabinet and a door; a long corridor open at one end. They are
//! written in the same TOML a user gives (`--save-scene` prints them).
//!
//! Coordinates are metres, z up, the grid's corner at the origin: cell
//! `(i, j, k)` spans `[i, i+1]·h × [j, j+1]·h × [k, k+1]·h` for cell size `h`.

use serde::{Deserialize, Serialize};
use std::path::Path;
use voxcast::error::{Error, Result};

/// A box in metres (an obstacle or an opening).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    pub min: [f32; 3],
    pub max: [f32; 3],
    /// sRGB 0…1, for the renderer's geometry (optional).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<[f32; 3]>,
    /// What it is (`desk`, `door`, …).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
}

/// The fire: a sphere that adds smoke and heat every step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceSpec {
    /// Centre in metres.
    pub center: [f32; 3],
    /// Radius in metres.
    pub radius: f32,
    /// Smoke density added per second inside the sphere (density units/s).
    #[serde(default = "default_rate")]
    pub density_rate: f32,
    /// Temperature above ambient the source holds its cells at (K).
    #[serde(default = "default_source_temp")]
    pub temperature: f32,
    /// Relative random flicker of the injection (0: steady), drawn from the seed.
    #[serde(default = "default_flicker")]
    pub flicker: f32,
}

fn default_rate() -> f32 {
    4.0
}
fn default_source_temp() -> f32 {
    30.0
}
fn default_flicker() -> f32 {
    0.5
}

/// A whole smoke simulation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SmokeScene {
    /// What it shows (the series title).
    #[serde(default)]
    pub title: String,
    /// Cells along x, y, z (z up).
    pub grid: [usize; 3],
    /// Edge of a cell in metres.
    pub cell_size: f32,
    /// Time step in seconds.
    pub dt: f32,
    /// Solver steps per written frame.
    #[serde(default = "one")]
    pub steps_per_frame: usize,
    /// Boussinesq buoyancy, Fedkiw 2001 eq. 8: `f = −α ρ ẑ + β (T − T_amb) ẑ`;
    /// `alpha` pulls smoke down by its density (m/s² per density unit)…
    #[serde(default = "default_alpha")]
    pub alpha: f32,
    /// …and `beta` lifts hot air (m/s² per kelvin).
    #[serde(default = "default_beta")]
    pub beta: f32,
    /// Vorticity confinement ε, Fedkiw 2001 eq. 11 (0: off).
    #[serde(default = "default_vorticity")]
    pub vorticity: f32,
    /// Rate (1/s) at which hot air cools towards ambient (heat lost to the
    /// walls and by radiation; without it a closed room only heats up).
    #[serde(default = "default_cooling")]
    pub cooling: f32,
    /// Seed of the source's flicker.
    #[serde(default)]
    pub seed: u64,
    /// The fire.
    pub source: SourceSpec,
    /// Solids (furniture, inner walls). The grid's own faces are walls.
    #[serde(default, rename = "obstacle")]
    pub obstacles: Vec<BoxSpec>,
    /// Openings: grid cells inside these boxes on the grid's boundary are
    /// open air (pressure 0): smoke leaves there.
    #[serde(default, rename = "opening")]
    pub openings: Vec<BoxSpec>,
    /// Relative tolerance of the pressure solve (‖r‖∞/‖b‖∞).
    #[serde(default = "default_tolerance")]
    pub tolerance: f64,
}

fn one() -> usize {
    1
}
fn default_alpha() -> f32 {
    0.02
}
fn default_beta() -> f32 {
    0.08
}
fn default_vorticity() -> f32 {
    2.0
}
fn default_cooling() -> f32 {
    0.05
}
fn default_tolerance() -> f64 {
    1e-4
}

/// The preset names.
pub const PRESETS: [&str; 3] = ["room", "office", "corridor"];

// The presets are scene files like any other, kept as data in
// `presets/*.toml` (templates to copy for `voxcast simulate smoke --scene
// FILE`) and built into the binary.

const ROOM: &str = include_str!("../presets/room.toml");

const OFFICE: &str = include_str!("../presets/office.toml");

const CORRIDOR: &str = include_str!("../presets/corridor.toml");

impl SmokeScene {
    /// A preset by name (`room`, `office`, `corridor`).
    pub fn preset(name: &str) -> Option<SmokeScene> {
        let text = match name {
            "room" => ROOM,
            "office" => OFFICE,
            "corridor" => CORRIDOR,
            _ => return None,
        };
        Some(toml::from_str(text).expect("presets parse"))
    }

    /// A preset by name, or a scene TOML file.
    pub fn load(name_or_path: &str) -> Result<SmokeScene> {
        if let Some(s) = SmokeScene::preset(name_or_path) {
            return Ok(s);
        }
        let path = Path::new(name_or_path);
        if !path.exists() {
            return Err(Error::invalid(format!(
                "scene `{name_or_path}`: neither a preset ({}) nor an existing file",
                PRESETS.join(", ")
            )));
        }
        let scene: SmokeScene = voxcast::files::read_toml(path)?;
        scene
            .validate()
            .map_err(|e| Error::format(path, e.field, e.message))?;
        Ok(scene)
    }

    /// Checks every field; the error names the field and what was expected.
    pub fn validate(&self) -> std::result::Result<(), voxcast::FieldError> {
        let bad = |f: &str, m: String| Err(voxcast::FieldError::new(f, m));
        if self.grid.iter().any(|&n| !(4..=1024).contains(&n)) {
            return bad(
                "grid",
                format!("{:?}: each count must be 4…1024", self.grid),
            );
        }
        if self.grid.iter().product::<usize>() > 64 << 20 {
            return bad("grid", format!("{:?}: more than 64 M cells", self.grid));
        }
        let pos = |x: f32| x.is_finite() && x > 0.0;
        if !pos(self.cell_size) {
            return bad(
                "cell_size",
                format!("{}: expected metres > 0", self.cell_size),
            );
        }
        if !pos(self.dt) {
            return bad("dt", format!("{}: expected seconds > 0", self.dt));
        }
        if self.steps_per_frame == 0 || self.steps_per_frame > 1000 {
            return bad(
                "steps_per_frame",
                format!("{}: expected 1…1000", self.steps_per_frame),
            );
        }
        for (f, v) in [
            ("alpha", self.alpha),
            ("beta", self.beta),
            ("vorticity", self.vorticity),
            ("cooling", self.cooling),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(f, format!("{v}: expected a number ≥ 0"));
            }
        }
        if !(self.tolerance > 0.0 && self.tolerance < 1.0) {
            return bad(
                "tolerance",
                format!("{}: expected 0 < tol < 1", self.tolerance),
            );
        }
        let s = &self.source;
        if !s.center.iter().all(|x| x.is_finite()) || !pos(s.radius) {
            return bad("source", "center must be finite and radius > 0".into());
        }
        let non_negative = |x: f32| x.is_finite() && x >= 0.0;
        if !non_negative(s.density_rate)
            || !non_negative(s.temperature)
            || !(0.0..=1.0).contains(&s.flicker)
        {
            return bad(
                "source",
                "density_rate and temperature must be ≥ 0, flicker in 0…1".into(),
            );
        }
        for (kind, list) in [("obstacle", &self.obstacles), ("opening", &self.openings)] {
            for (i, b) in list.iter().enumerate() {
                let ok = (0..3)
                    .all(|a| b.min[a].is_finite() && b.max[a].is_finite() && b.min[a] < b.max[a]);
                if !ok {
                    return bad(
                        &format!("{kind}[{i}]"),
                        format!(
                            "min {:?} must be below max {:?} on every axis",
                            b.min, b.max
                        ),
                    );
                }
            }
        }
        Ok(())
    }

    /// The scene as TOML (what `--save-scene` writes).
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a scene serialises")
    }

    /// The room's size in metres.
    pub fn extent(&self) -> [f32; 3] {
        self.grid.map(|n| n as f32 * self.cell_size)
    }

    /// The solids as the renderer's `geometry.toml` (the schema agreed with
    /// the geometry branch): the furniture as `[[box]]`es and the floor as a
    /// `[[plane]]`. The room's walls and ceiling are left out on purpose: as
    /// opaque boxes they would hide the smoke from any camera outside the
    /// room; the volume's bounding box shows where they are.
    pub fn geometry_toml(&self) -> String {
        let mut s = String::from(
            "# Solids of the smoke scene (metres, the volume's coordinates): furniture\n\
             # boxes and the floor. The walls are the volume's bounding box and are left\n\
             # out so that they do not hide the smoke.\n",
        );
        for b in &self.obstacles {
            s.push_str("\n[[box]]\n");
            s.push_str(&format!("min = {}\n", fmt3(b.min)));
            s.push_str(&format!("max = {}\n", fmt3(b.max)));
            s.push_str(&format!(
                "color = {}\n",
                fmt3(b.color.unwrap_or([0.6, 0.6, 0.6]))
            ));
            if let Some(n) = &b.name {
                s.push_str(&format!("name = {}\n", toml_string(n)));
            }
        }
        s.push_str(
            "\n[[plane]]\npoint = [0.0, 0.0, 0.0]\nnormal = [0.0, 0.0, 1.0]\ncolor = [0.5, 0.5, 0.5]\nname = \"floor\"\n",
        );
        s
    }
}

fn fmt3(v: [f32; 3]) -> String {
    format!("[{:?}, {:?}, {:?}]", v[0], v[1], v[2])
}

fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_validate_and_round_trip() {
        for name in PRESETS {
            let s = SmokeScene::preset(name).unwrap();
            s.validate().unwrap();
            let back: SmokeScene = toml::from_str(&s.to_toml()).unwrap();
            assert_eq!(back, s, "{name}");
            let g: toml::Table = toml::from_str(&s.geometry_toml()).unwrap();
            let boxes = g["box"].as_array().unwrap();
            assert_eq!(boxes.len(), s.obstacles.len());
        }
    }

    #[test]
    fn bad_scene_files_name_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.toml");
        let mut s = SmokeScene::preset("room").unwrap();
        s.dt = -1.0;
        std::fs::write(&p, s.to_toml()).unwrap();
        let e = SmokeScene::load(p.to_str().unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("dt") && e.contains("s.toml"), "{e}");
        std::fs::write(&p, "grid = [8, 8]\n").unwrap();
        let e = SmokeScene::load(p.to_str().unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("s.toml"), "{e}");
        let e = SmokeScene::load("nope").unwrap_err().to_string();
        assert!(e.contains("preset"), "{e}");
    }
}
