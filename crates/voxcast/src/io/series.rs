//! Time series of volumes (DESIGN.md: "a `Series` is a sequence of volumes
//! with times"): smoke-simulation and cloud frames, FDS output, weather
//! times.
//!
//! A simulator writes a **frame folder**: one attached NRRD file per frame
//! (`frame_00000.nrrd`, …) and a manifest `series.toml` listing each frame's
//! file and time, rewritten atomically after every frame so that a run that
//! stops half-way still leaves a readable series:
//!
//! ```toml
//! title = "smoke: office"
//! time_units = "s"
//! [[frame]]
//! file = "frame_00000.nrrd"
//! time = 0.0
//! ```
//!
//! Frames are loaded one at a time ([`Series::load`]), so a long series
//! never has to fit in memory.

use crate::error::{Error, Result};
use crate::files::write_file;
use crate::io::nrrd_write::{self, Encoding};
use crate::io::OpenOptions;
use crate::volume::Volume;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The manifest's file name inside a frame folder.
pub const MANIFEST: &str = "series.toml";

/// The manifest of a frame folder.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// What the series shows (e.g. `smoke: office`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub title: Option<String>,
    /// Unit of the frame times (e.g. `s`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_units: Option<String>,
    /// The frames, in time order.
    #[serde(default, rename = "frame")]
    pub frames: Vec<FrameEntry>,
}

/// One frame of a manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrameEntry {
    /// The frame's volume file, relative to the folder.
    pub file: String,
    /// Its time.
    pub time: f64,
}

/// A sequence of volumes with times, loaded frame by frame.
#[derive(Clone, Debug)]
pub struct Series {
    /// The folder (or file) the series was opened from.
    pub source: PathBuf,
    pub title: Option<String>,
    pub time_units: Option<String>,
    /// A name for each frame's time where the file has one (WRF's `Times`
    /// strings); empty otherwise.
    pub labels: Vec<String>,
    frames: Vec<Frame>,
}

/// Where one frame's volume comes from.
#[derive(Clone, Debug)]
enum Frame {
    /// A volume file of its own.
    File { path: PathBuf, time: f64 },
    /// One time of a multi-time file (FDS `.smv`): opened with `--time`.
    TimeOf { path: PathBuf, time: f64 },
}

impl Frame {
    fn time(&self) -> f64 {
        match self {
            Frame::File { time, .. } | Frame::TimeOf { time, .. } => *time,
        }
    }
}

impl Series {
    /// True when `path` is a frame folder (a folder holding a manifest).
    pub fn is_frame_folder(path: &Path) -> bool {
        path.is_dir() && path.join(MANIFEST).is_file()
    }

    /// Opens the frame folder `dir` by its manifest. Every frame file is
    /// checked to exist, times must be finite and increasing.
    pub fn open_folder(dir: &Path) -> Result<Series> {
        let mpath = dir.join(MANIFEST);
        let m: Manifest = crate::files::read_toml(&mpath)?;
        if m.frames.is_empty() {
            return Err(Error::format(&mpath, "frame", "the series lists no frames"));
        }
        let mut frames = Vec::with_capacity(m.frames.len());
        let mut last = f64::NEG_INFINITY;
        for (i, f) in m.frames.iter().enumerate() {
            if !f.time.is_finite() || f.time <= last {
                return Err(Error::format(
                    &mpath,
                    format!("frame[{i}].time"),
                    format!(
                        "time {} must be finite and greater than the frame before ({last})",
                        f.time
                    ),
                ));
            }
            last = f.time;
            let rel = Path::new(&f.file);
            if rel.is_absolute()
                || rel
                    .components()
                    .any(|c| c == std::path::Component::ParentDir)
            {
                return Err(Error::format(
                    &mpath,
                    format!("frame[{i}].file"),
                    format!("`{}` must be a file name inside the folder", f.file),
                ));
            }
            let path = dir.join(rel);
            if !path.is_file() {
                return Err(Error::format(
                    &mpath,
                    format!("frame[{i}].file"),
                    format!("`{}` does not exist", path.display()),
                ));
            }
            frames.push(Frame::File { path, time: f.time });
        }
        Ok(Series {
            source: dir.to_path_buf(),
            title: m.title,
            time_units: m.time_units,
            labels: Vec::new(),
            frames,
        })
    }

    /// A series of the times `times` of one multi-time file (e.g. an FDS
    /// `.smv`), each frame read with `OpenOptions::time` set.
    pub fn of_times(path: &Path, times: &[f64], time_units: Option<String>) -> Result<Series> {
        if times.is_empty() {
            return Err(Error::format(path, "time", "the file holds no times"));
        }
        Ok(Series {
            source: path.to_path_buf(),
            title: None,
            time_units,
            labels: Vec::new(),
            frames: times
                .iter()
                .map(|&time| Frame::TimeOf {
                    path: path.to_path_buf(),
                    time,
                })
                .collect(),
        })
    }

    /// Opens any input as a series: a frame folder (by its manifest), an
    /// FDS `.smv` (the times of the quantity `opts.variable` picks, soot by
    /// default), a folder or glob of volume files (sorted by name, one
    /// frame each, at times 0, 1, 2, …), or any single volume (one frame).
    pub fn open(path: &Path, opts: &OpenOptions) -> Result<Series> {
        use crate::io::Format;
        if Series::is_frame_folder(path) {
            return Series::open_folder(path);
        }
        let s = path.to_string_lossy();
        let is_glob = s.contains(['*', '?', '[']) && !path.exists();
        if !is_glob && !path.exists() {
            return Err(Error::io(
                path,
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or folder"),
            ));
        }
        let volume_file = |p: &Path| {
            let n = p
                .file_name()
                .map(|n| n.to_string_lossy().to_ascii_lowercase())
                .unwrap_or_default();
            [
                ".nrrd", ".nhdr", ".mhd", ".mha", ".vtk", ".nii", ".nii.gz", ".vdb",
            ]
            .iter()
            .any(|e| n.ends_with(e))
        };
        let mut files: Vec<PathBuf> = if is_glob {
            glob::glob(&s)
                .map_err(|e| Error::invalid(format!("{s}: bad pattern: {e}")))?
                .filter_map(|p| p.ok())
                .filter(|p| volume_file(p))
                .collect()
        } else if path.is_dir() {
            std::fs::read_dir(path)
                .map_err(|e| Error::io(path, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| volume_file(p))
                .collect()
        } else {
            Vec::new()
        };
        if !files.is_empty() {
            files.sort();
            return Series::of_files(path, files);
        }
        match crate::io::detect(path, opts)? {
            Format::Fds => {
                let times = crate::io::fds::times(path, opts)?;
                Series::of_times(path, &times, Some("s".into()))
            }
            // WRF: one frame per time index (a WRF file's `--time` is the
            // index), labelled with the file's `Times` strings.
            Format::Wrf => {
                let labels = crate::io::wrf::times(path)?;
                let times: Vec<f64> = (0..labels.len()).map(|i| i as f64).collect();
                let mut s = Series::of_times(path, &times, Some("index".into()))?;
                s.labels = labels;
                Ok(s)
            }
            _ => Series::of_files(path, vec![path.to_path_buf()]),
        }
    }

    /// A series of separate volume files in the order given, at times
    /// 0, 1, 2, … (frame numbers).
    pub fn of_files(source: &Path, files: Vec<PathBuf>) -> Result<Series> {
        if files.is_empty() {
            return Err(Error::format(source, "frames", "no volume files found"));
        }
        Ok(Series {
            source: source.to_path_buf(),
            title: None,
            time_units: None,
            labels: Vec::new(),
            frames: files
                .into_iter()
                .enumerate()
                .map(|(i, path)| Frame::File {
                    path,
                    time: i as f64,
                })
                .collect(),
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Always false: a series has at least one frame.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The frame times.
    pub fn times(&self) -> Vec<f64> {
        self.frames.iter().map(Frame::time).collect()
    }

    /// The index of the frame nearest to time `t` (the earlier on a tie).
    pub fn nearest(&self, t: f64) -> usize {
        let mut best = 0;
        for (i, f) in self.frames.iter().enumerate() {
            if (f.time() - t).abs() < (self.frames[best].time() - t).abs() {
                best = i;
            }
        }
        best
    }

    /// Loads frame `i` (its `time` set). `opts` carries the variable, raw
    /// layout and spacing override, as for a single volume.
    pub fn load(&self, i: usize, opts: &OpenOptions) -> Result<Volume> {
        let f = self.frames.get(i).ok_or_else(|| {
            Error::invalid(format!(
                "frame {i} of {}: the series has {} frames",
                self.source.display(),
                self.frames.len()
            ))
        })?;
        let mut v = match f {
            Frame::File { path, .. } => {
                let mut o = opts.clone();
                o.time = None;
                crate::io::open(path, &o)?
            }
            Frame::TimeOf { path, time } => {
                let mut o = opts.clone();
                o.time = Some(*time);
                crate::io::open(path, &o)?
            }
        };
        v.time = Some(f.time());
        Ok(v)
    }

    /// The name of frame `i`'s time, where the file has one.
    pub fn label(&self, i: usize) -> Option<&str> {
        self.labels.get(i).map(String::as_str)
    }

    /// The file frame `i` is read from.
    pub fn frame_path(&self, i: usize) -> Option<&Path> {
        self.frames.get(i).map(|f| match f {
            Frame::File { path, .. } | Frame::TimeOf { path, .. } => path.as_path(),
        })
    }
}

/// Writes a frame folder frame by frame (the simulators' output).
#[derive(Debug)]
pub struct SeriesWriter {
    dir: PathBuf,
    manifest: Manifest,
    encoding: Encoding,
}

impl SeriesWriter {
    /// Starts a frame folder at `dir`, creating it. An existing folder must
    /// be empty or hold a series (whose frames are then replaced): anything
    /// else is refused, so a simulation never writes over a user's files.
    pub fn create(dir: &Path, title: Option<String>, time_units: Option<String>) -> Result<Self> {
        if dir.exists() {
            if !dir.is_dir() {
                return Err(Error::invalid(format!(
                    "{}: exists and is not a folder",
                    dir.display()
                )));
            }
            let entries: Vec<_> = std::fs::read_dir(dir)
                .map_err(|e| Error::io(dir, e))?
                .filter_map(|e| e.ok())
                .collect();
            if !entries.is_empty() && !dir.join(MANIFEST).is_file() {
                return Err(Error::invalid(format!(
                    "{}: the folder is not empty and holds no {MANIFEST}; give an empty or new folder",
                    dir.display()
                )));
            }
            // Remove the old series' frames, so no stale frame is mixed in
            // (the manifest is our own, not an input: read it as such).
            if let Ok(old) = crate::files::read_own_toml::<Manifest>(&dir.join(MANIFEST)) {
                for f in &old.frames {
                    let rel = Path::new(&f.file);
                    if rel.components().count() == 1 && !rel.is_absolute() {
                        let _ = std::fs::remove_file(dir.join(rel));
                    }
                }
            }
        } else {
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        }
        let w = SeriesWriter {
            dir: dir.to_path_buf(),
            manifest: Manifest {
                title,
                time_units,
                frames: Vec::new(),
            },
            encoding: Encoding::Gzip,
        };
        w.write_manifest()?;
        Ok(w)
    }

    /// Writes frames raw instead of gzip-compressed (faster, larger).
    pub fn raw(mut self) -> Self {
        self.encoding = Encoding::Raw;
        self
    }

    /// The folder.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Appends `volume` as the frame at `time` (greater than the last).
    pub fn push(&mut self, volume: &Volume, time: f64) -> Result<PathBuf> {
        if let Some(last) = self.manifest.frames.last() {
            if time.is_nan() || time <= last.time {
                return Err(Error::invalid(format!(
                    "frame time {time} must be greater than the last ({})",
                    last.time
                )));
            }
        }
        let name = format!("frame_{:05}.nrrd", self.manifest.frames.len());
        let path = self.dir.join(&name);
        nrrd_write::write(&path, volume, self.encoding)?;
        self.manifest.frames.push(FrameEntry { file: name, time });
        self.write_manifest()?;
        Ok(path)
    }

    fn write_manifest(&self) -> Result<()> {
        let text = toml::to_string(&self.manifest)
            .map_err(|e| Error::invalid(format!("cannot write the manifest: {e}")))?;
        write_file(&self.dir.join(MANIFEST), |f| {
            use std::io::Write;
            f.write_all(b"# voxcast frame series: render with `voxcast render DIR --time T`, animate with `voxcast animate DIR`\n")?;
            f.write_all(text.as_bytes())
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn frame(v: f32) -> Volume {
        Volume::from_fn([4, 3, 2], Vec3::ONE, |i, j, k| v + (i + j + k) as f32).unwrap()
    }

    #[test]
    fn writes_and_reads_a_frame_folder() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join("run");
        let mut w = SeriesWriter::create(&d, Some("test".into()), Some("s".into())).unwrap();
        for (i, t) in [0.0, 0.5, 1.5].into_iter().enumerate() {
            w.push(&frame(i as f32 * 10.0), t).unwrap();
        }
        assert!(w.push(&frame(0.0), 1.5).is_err(), "times must increase");
        assert!(Series::is_frame_folder(&d));
        let s = Series::open_folder(&d).unwrap();
        assert_eq!(s.len(), 3);
        assert_eq!(s.times(), vec![0.0, 0.5, 1.5]);
        assert_eq!(s.title.as_deref(), Some("test"));
        assert_eq!(s.nearest(1.1), 2);
        assert_eq!(s.nearest(0.2), 0);
        let v = s.load(1, &OpenOptions::default()).unwrap();
        assert_eq!(v.time, Some(0.5));
        assert_eq!(v.value(1, 2, 1), 10.0 + 4.0);
        assert!(s.load(3, &OpenOptions::default()).is_err());
        // Opening the folder as a volume picks a frame by --time (nearest).
        let o = OpenOptions {
            time: Some(0.6),
            ..Default::default()
        };
        let v = crate::io::open(&d, &o).unwrap();
        assert_eq!(v.time, Some(0.5));
        // Default: the last frame.
        let v = crate::io::open(&d, &OpenOptions::default()).unwrap();
        assert_eq!(v.time, Some(1.5));
        // Rewriting the folder replaces the old frames.
        let mut w = SeriesWriter::create(&d, None, None).unwrap();
        w.push(&frame(1.0), 0.0).unwrap();
        assert_eq!(Series::open_folder(&d).unwrap().len(), 1);
        assert!(!d.join("frame_00002.nrrd").exists());
    }

    #[test]
    fn opens_folders_of_files_and_fds_cases_as_series() {
        let dir = tempfile::tempdir().unwrap();
        for i in 0..3 {
            nrrd_write::write(
                &dir.path().join(format!("v{i}.nrrd")),
                &frame(i as f32),
                Encoding::Raw,
            )
            .unwrap();
        }
        std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
        let s = Series::open(dir.path(), &OpenOptions::default()).unwrap();
        assert_eq!(s.len(), 3);
        assert_eq!(
            s.load(2, &OpenOptions::default()).unwrap().value(0, 0, 0),
            2.0
        );
        let g = dir.path().join("v*.nrrd");
        assert_eq!(Series::open(&g, &OpenOptions::default()).unwrap().len(), 3);
        let one = Series::open(&dir.path().join("v1.nrrd"), &OpenOptions::default()).unwrap();
        assert_eq!(one.len(), 1);
        assert!(Series::open(&dir.path().join("nope.nrrd"), &OpenOptions::default()).is_err());

        let Some(smv) = crate::testdata::data_path("fds_room/room_smoke.smv") else {
            return;
        };
        let s = Series::open(&smv, &OpenOptions::default()).unwrap();
        assert_eq!(s.len(), 121, "soot SMOKE3D frames");
        let t = s.times();
        assert!(t.windows(2).all(|w| w[1] > w[0]));
        let v = s.load(60, &OpenOptions::default()).unwrap();
        assert_eq!(v.time, Some(t[60]));
    }

    #[test]
    fn refuses_a_foreign_folder_and_bad_manifests() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
        let e = SeriesWriter::create(dir.path(), None, None).unwrap_err();
        assert!(e.to_string().contains("not empty"), "{e}");
        assert!(dir.path().join("notes.txt").exists());

        let d = tempfile::tempdir().unwrap();
        let m = d.path().join(MANIFEST);
        std::fs::write(&m, "[[frame]]\nfile = \"missing.nrrd\"\ntime = 0.0\n").unwrap();
        let e = Series::open_folder(d.path()).unwrap_err().to_string();
        assert!(
            e.contains("frame[0].file") && e.contains("does not exist"),
            "{e}"
        );
        std::fs::write(&m, "[[frame]]\nfile = \"../x.nrrd\"\ntime = 0.0\n").unwrap();
        let e = Series::open_folder(d.path()).unwrap_err().to_string();
        assert!(e.contains("inside the folder"), "{e}");
        std::fs::write(&m, "title = 3\n").unwrap();
        let e = Series::open_folder(d.path()).unwrap_err().to_string();
        assert!(e.contains(MANIFEST), "{e}");
        std::fs::write(&m, "").unwrap();
        let e = Series::open_folder(d.path()).unwrap_err().to_string();
        assert!(e.contains("no frames"), "{e}");
    }
}
