//! Writing output files without ever losing a user's data.
//!
//! [`Outputs`] holds every file one command writes. Each is checked when it
//! is planned — before any work is done — and again just before it is
//! written: it may not be an input of the command (the volume file, a file
//! of its folder or glob, or any file this process has read, such as a
//! detached NRRD's data file), a folder, in a missing folder, or another
//! output of the same command. Files are written under temporary names
//! beside their targets and renamed into place by [`Outputs::commit`] only
//! when all of them have been written, so a failure leaves none of them
//! (and no temporary file) behind.

use super::input::was_read;
use crate::error::{quote_path, Error, Result};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The files one command writes: see the module docs.
#[derive(Debug, Default)]
pub struct Outputs {
    /// Inputs named on the command line or in the scene: files, folders,
    /// globs (`builtin:` names are left out).
    inputs: Vec<String>,
    /// (what it is — a flag or a name — and the path) per planned output.
    planned: Vec<(String, PathBuf)>,
    /// (temporary, final) per file written and not yet committed.
    staged: Vec<(PathBuf, PathBuf)>,
}

impl Outputs {
    /// No outputs yet; `inputs` are the paths (files, folders, globs) the
    /// command reads.
    pub fn new<S: AsRef<str>>(inputs: impl IntoIterator<Item = S>) -> Outputs {
        Outputs {
            inputs: inputs
                .into_iter()
                .map(|s| s.as_ref().to_string())
                .filter(|s| !s.starts_with(crate::builtin::PREFIX) && !s.is_empty())
                .collect(),
            planned: Vec::new(),
            staged: Vec::new(),
        }
    }

    /// [`Outputs::plan`] for an output that may not be asked for (an
    /// optional flag): nothing when `path` is `None`.
    pub fn plan_optional(&mut self, what: &str, path: Option<&Path>, exts: &[&str]) -> Result<()> {
        match path {
            Some(p) => self.plan(what, p, exts),
            None => Ok(()),
        }
    }

    /// Plans an output: `what` names it in errors (e.g. `--stats-json`);
    /// `exts` are the allowed extensions (any when empty). Refuses it now if
    /// it could not be written safely (see [`check_path`]) or if another
    /// output of this command already names the same file.
    pub fn plan(&mut self, what: &str, path: &Path, exts: &[&str]) -> Result<()> {
        check_extension(what, path, exts)?;
        if let Some((other, _)) = self.planned.iter().find(|(_, p)| same_target(p, path)) {
            return Err(Error::invalid(format!(
                "{what} {}: {other} writes that file already; give each output its own name",
                quote_path(path)
            )));
        }
        check_path(what, path, &self.inputs)?;
        self.planned.push((what.to_string(), path.to_path_buf()));
        Ok(())
    }

    /// Checks every planned output again: call it after the inputs were
    /// read, before a long computation, so that an output that turned out to
    /// be a file the reader opened (a detached header's data file) is
    /// refused before any work is done.
    pub fn check(&self) -> Result<()> {
        for (what, p) in &self.planned {
            check_path(what, p, &self.inputs)?;
        }
        Ok(())
    }

    /// Writes `path` through `write` under a temporary name; it appears
    /// under its own name at [`Outputs::commit`].
    pub fn write(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
    ) -> Result<()> {
        self.write_with(path, |tmp| {
            let f = File::create(tmp).map_err(|e| Error::io(path, e))?;
            let mut w = BufWriter::new(f);
            write(&mut w)
                .and_then(|_| w.flush())
                .and_then(|_| w.get_ref().sync_all())
                .map_err(|e| Error::io(path, e))
        })
    }

    /// Like [`Outputs::write`] for writers that create the file themselves:
    /// `write` gets the temporary path to create.
    pub fn write_with(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> Result<()>,
    ) -> Result<()> {
        let what = self
            .planned
            .iter()
            .find(|(_, p)| same_target(p, path))
            .map(|(w, _)| w.clone())
            .unwrap_or_else(|| "output".into());
        check_path(&what, path, &self.inputs)?;
        if self.staged.iter().any(|(_, p)| same_target(p, path)) {
            return Err(Error::invalid(format!(
                "{what} {}: written twice by one command",
                quote_path(path)
            )));
        }
        let tmp = temp_path(path);
        // Registered first, so that a failed write removes what it left.
        self.staged.push((tmp.clone(), path.to_path_buf()));
        write(&tmp)
    }

    /// The temporary path `path` is written under until the commit (for a
    /// writer that streams into it, e.g. an encoder process); it is
    /// registered as written.
    pub fn stage(&mut self, path: &Path) -> Result<PathBuf> {
        let mut tmp = PathBuf::new();
        self.write_with(path, |t| {
            tmp = t.to_path_buf();
            Ok(())
        })?;
        Ok(tmp)
    }

    /// Renames every written file into place. Either all outputs appear or,
    /// if a rename fails, the ones not yet renamed are removed and the
    /// error says which were written.
    pub fn commit(mut self) -> Result<()> {
        let staged = std::mem::take(&mut self.staged);
        let mut done: Vec<&Path> = Vec::new();
        for (i, (tmp, path)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, path) {
                for (t, _) in &staged[i..] {
                    let _ = std::fs::remove_file(t);
                }
                let written = if done.is_empty() {
                    String::new()
                } else {
                    format!(
                        " (already written: {})",
                        done.iter()
                            .map(|p| quote_path(p))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                };
                return Err(Error::invalid(format!(
                    "{}: cannot move the finished file into place: {e}{written}",
                    quote_path(path)
                )));
            }
            done.push(path);
        }
        Ok(())
    }
}

impl Drop for Outputs {
    /// Outputs dropped without a commit (an error, a panic) leave nothing.
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Writes one file atomically: checked, written under a temporary name,
/// renamed into place (see [`Outputs`]).
pub fn write_file(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let mut o = Outputs::default();
    o.write(path, write)?;
    o.commit()
}

/// Checks that a folder voxcast fills (frames, a series) is not an input:
/// not a folder it reads, not inside one, not a file.
pub fn check_folder(what: &str, dir: &Path, inputs: &[&str]) -> Result<()> {
    if dir.is_file() {
        return Err(Error::invalid(format!(
            "{what} {}: is a file; expected a folder",
            quote_path(dir)
        )));
    }
    for input in inputs
        .iter()
        .filter(|s| !s.starts_with(crate::builtin::PREFIX) && !s.is_empty())
    {
        if writes_into_input(dir, Path::new(input)) || Path::new(input) == dir {
            return Err(Error::invalid(format!(
                "{what} {}: refusing to write over or into the input {}",
                quote_path(dir),
                quote_path(Path::new(input))
            )));
        }
    }
    Ok(())
}

fn check_extension(what: &str, path: &Path, exts: &[&str]) -> Result<()> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if !exts.is_empty() && !exts.contains(&ext.as_str()) {
        return Err(Error::invalid(format!(
            "{what} {}: the file name must end in {}",
            quote_path(path),
            exts.iter()
                .map(|e| format!(".{e}"))
                .collect::<Vec<_>>()
                .join(" or ")
        )));
    }
    Ok(())
}

/// Refuses an output path that is an input (named, or read by this
/// process), lies in an input folder or glob, is a folder, or lies in a
/// folder that does not exist.
pub fn check_path(what: &str, path: &Path, inputs: &[String]) -> Result<()> {
    let refuse = |why: String| {
        Err(Error::invalid(format!(
            "{what} {}: {why}",
            quote_path(path)
        )))
    };
    if path.as_os_str().is_empty() {
        return refuse("an empty file name".into());
    }
    for input in inputs {
        if writes_into_input(path, Path::new(input)) {
            return refuse(format!(
                "refusing to write over or into the input {}",
                quote_path(Path::new(input))
            ));
        }
    }
    if was_read(path) {
        return refuse("refusing to write over a file this command reads as input".into());
    }
    if path.is_dir() {
        return refuse("is a folder; give a file name".into());
    }
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        if !parent.is_dir() {
            return refuse(format!("the folder {} does not exist", quote_path(parent)));
        }
    }
    Ok(())
}

/// True when `out` is the input file, lies inside the input folder (a slice
/// stack would pick it up), or matches the input glob.
pub fn writes_into_input(out: &Path, input: &Path) -> bool {
    let Some(out_abs) = absolute_target(out) else {
        return false;
    };
    if let Ok(inp) = input.canonicalize() {
        return out_abs == inp || (inp.is_dir() && out_abs.starts_with(&inp));
    }
    // A glob of slices: refuse an output the pattern would match.
    let pattern = std::path::absolute(input).unwrap_or_else(|_| input.to_path_buf());
    glob::Pattern::new(&pattern.to_string_lossy())
        .map(|p| p.matches_path(&out_abs))
        .unwrap_or(false)
}

/// `path` with its folder made canonical (the file itself need not exist).
fn absolute_target(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?;
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    parent.canonicalize().ok().map(|p| p.join(name))
}

/// True when `a` and `b` name the same file.
fn same_target(a: &Path, b: &Path) -> bool {
    a == b
        || match (absolute_target(a), absolute_target(b)) {
            (Some(x), Some(y)) => x == y,
            _ => false,
        }
}

/// A temporary name beside `path` (same folder, so the rename is atomic).
fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn all_outputs_appear_together_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.toml"));
        let mut o = Outputs::new(["builtin:demo"]);
        o.plan("--a", &a, &["json"]).unwrap();
        o.plan("--b", &b, &["toml"]).unwrap();
        o.write(&a, |w| w.write_all(b"{}")).unwrap();
        assert!(!a.exists(), "nothing appears before the commit");
        let r = o.write(&b, |_| Err(std::io::Error::other("disk full")));
        assert!(r.is_err());
        drop(o);
        assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));

        let mut o = Outputs::new(Vec::<String>::new());
        o.write(&a, |w| w.write_all(b"{}")).unwrap();
        o.write(&b, |w| w.write_all(b"x")).unwrap();
        o.commit().unwrap();
        assert_eq!(names(dir.path()), ["a.json", "b.toml"]);
    }

    #[test]
    fn one_file_named_twice_missing_folders_and_folders_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let x = dir.path().join("x.exr");
        let mut o = Outputs::default();
        o.plan("-o", &x, &["png", "exr"]).unwrap();
        let e = o.plan("--float-out", &x, &["exr"]).unwrap_err().to_string();
        assert!(e.contains("-o writes that file already"), "{e}");
        let e = o
            .plan("--stats-json", &dir.path().join("no/s.json"), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not exist"), "{e}");
        let e = o.plan("--chart", dir.path(), &[]).unwrap_err().to_string();
        assert!(e.contains("is a folder"), "{e}");
        let e = o
            .plan("-o", &dir.path().join("a.jpg"), &["png"])
            .unwrap_err();
        assert!(e.to_string().contains(".png"), "{e}");
    }

    #[test]
    fn slice_folders_and_globs_are_inputs() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("s1.png"), "x").unwrap();
        assert!(writes_into_input(&dir.path().join("out.png"), dir.path()));
        let glob = dir.path().join("s*.png");
        assert!(writes_into_input(&dir.path().join("s9.png"), &glob));
        assert!(!writes_into_input(&dir.path().join("t9.png"), &glob));
    }
}
