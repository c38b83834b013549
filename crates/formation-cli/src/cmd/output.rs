//! Outputs that never destroy an input or an earlier result (issue #32,
//! `docs/reliability.md`, "Outputs").
//!
//! - Every file a command writes is *staged*: written under a temporary name beside it
//!   (`.NAME.tmp-PID`), and renamed onto its real name only when the whole command has
//!   succeeded ([`Staged::commit`]). A run that fails, is interrupted, or produces nothing
//!   leaves every earlier file as it was and removes its temporary files when it ends.
//!   A folder of outputs (`demo`, `reproduce`, `markers`) is committed as a whole: every
//!   file is complete before the first is renamed, and the renames take microseconds.
//! - Outputs that are not regular files (`--out /dev/stdout`, a named pipe) are written
//!   directly: they cannot be renamed onto and hold no earlier result.
//! - An output that is one of the command's inputs (the same file by device and inode,
//!   `./x` and `x`, a hard link, or a file inside an input folder) is refused before any
//!   work, as a usage error (exit code 2): [`refuse_inputs_as_outputs`].

use std::path::{Path, PathBuf};

use super::{CliError, Usage};

/// The files a command is writing, each under its temporary name until [`Self::commit`].
/// Dropped without a commit, it removes them.
#[derive(Debug, Default)]
pub struct Staged {
    /// `(temporary, final)` names, in the order they were staged.
    files: Vec<(PathBuf, PathBuf)>,
    committed: bool,
}

impl Staged {
    /// No file staged yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The name to write `path`'s content under until the commit: `.NAME.tmp-PID` in the
    /// same folder, or `path` itself when it exists and is not a regular file (a device or a
    /// pipe). Staging the same path twice gives the same temporary name.
    pub fn path(&mut self, path: &Path) -> PathBuf {
        if let Some((tmp, _)) = self.files.iter().find(|(_, p)| p == path) {
            return tmp.clone();
        }
        if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
            return path.to_owned();
        }
        let name = path
            .file_name()
            .map_or_else(|| "output".into(), |n| n.to_string_lossy().into_owned());
        let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
        self.files.push((tmp.clone(), path.to_owned()));
        tmp
    }

    /// Writes `bytes` as the content of `path` (under its temporary name).
    ///
    /// # Errors
    /// The write's error, naming `path`.
    pub fn write(&mut self, path: &Path, bytes: impl AsRef<[u8]>) -> Result<(), CliError> {
        let tmp = self.path(path);
        std::fs::write(&tmp, bytes)
            .map_err(|e| format!("cannot write {}: {e}", path.display()).into())
    }

    /// Creates the temporary file of `path` for writing (buffered).
    ///
    /// # Errors
    /// The creation's error, naming `path`.
    pub fn create(&mut self, path: &Path) -> Result<std::io::BufWriter<std::fs::File>, CliError> {
        let tmp = self.path(path);
        let file = std::fs::File::create(&tmp)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        Ok(std::io::BufWriter::new(file))
    }

    /// Whether `path` (its real name) was staged.
    pub fn contains(&self, path: &Path) -> bool {
        self.files.iter().any(|(_, p)| p == path)
    }

    /// Moves every staged file onto its real name (after flushing it to disk), in the order
    /// they were staged.
    ///
    /// # Errors
    /// A file that cannot be synced or renamed, naming it; the files not yet renamed are
    /// removed.
    pub fn commit(mut self) -> Result<(), CliError> {
        for (tmp, path) in &self.files {
            if tmp == path {
                continue;
            }
            let fail = |e: std::io::Error| format!("cannot write {}: {e}", path.display());
            std::fs::File::open(tmp)
                .and_then(|f| f.sync_all())
                .map_err(fail)?;
        }
        for (tmp, path) in &self.files {
            if tmp != path {
                std::fs::rename(tmp, path)
                    .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            }
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        for (tmp, path) in &self.files {
            if tmp != path && !self.committed {
                let _ = std::fs::remove_file(tmp);
            }
        }
    }
}

/// Refuses, as a usage error, any output in `outputs` that is one of `inputs` or lies inside
/// an input folder (a frame folder, a bag folder): the same file by device and inode when it
/// exists, else the same canonical path. `(option, path)` pairs name the offending options.
///
/// # Errors
/// A [`Usage`] error naming both options and paths.
pub fn refuse_inputs_as_outputs(
    outputs: &[(&str, &Path)],
    inputs: &[(&str, &Path)],
) -> Result<(), CliError> {
    use std::os::unix::fs::MetadataExt as _;
    for &(out_name, out) in outputs {
        let out_meta = std::fs::metadata(out).ok();
        // Devices and pipes (`--out /dev/stdout`) hold no data to lose.
        if out_meta
            .as_ref()
            .is_some_and(|m| !m.is_file() && !m.is_dir())
        {
            continue;
        }
        let out_canon = canonical(out);
        for &(in_name, input) in inputs {
            let in_meta = std::fs::metadata(input).ok();
            let same_file = match (&out_meta, &in_meta) {
                (Some(o), Some(i)) => o.dev() == i.dev() && o.ino() == i.ino(),
                _ => false,
            };
            let in_canon = canonical(input);
            let inside =
                in_meta.as_ref().is_some_and(|m| m.is_dir()) && out_canon.starts_with(&in_canon);
            if same_file || out_canon == in_canon || inside {
                return Err(Usage(format!(
                    "{out_name} {} would overwrite the input {in_name} {}{}: choose another output",
                    out.display(),
                    input.display(),
                    if inside && !same_file {
                        " (it is inside that folder)"
                    } else {
                        ""
                    }
                ))
                .into());
            }
        }
    }
    Ok(())
}

/// `path` made absolute with its links resolved, as far as it exists: the canonical form of
/// its longest existing ancestor, with the rest appended.
fn canonical(path: &Path) -> PathBuf {
    if let Ok(c) = std::fs::canonicalize(path) {
        return c;
    }
    match (path.parent(), path.file_name()) {
        (Some(parent), Some(name)) => {
            let parent = if parent.as_os_str().is_empty() {
                Path::new(".")
            } else {
                parent
            };
            canonical(parent).join(name)
        }
        _ => path.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("ft-output-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn staged_files_appear_only_at_the_commit_and_vanish_without_it() {
        let d = dir("staged");
        let target = d.join("a.txt");
        std::fs::write(&target, "old").unwrap();
        let mut staged = Staged::new();
        staged.write(&target, "new").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
        drop(staged);
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "old");
        assert_eq!(
            std::fs::read_dir(&d).unwrap().count(),
            1,
            "temporary left behind"
        );
        let mut staged = Staged::new();
        staged.write(&target, "new").unwrap();
        staged.write(&d.join("b.txt"), "b").unwrap();
        staged.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "new");
        assert_eq!(std::fs::read_to_string(d.join("b.txt")).unwrap(), "b");
        assert_eq!(std::fs::read_dir(&d).unwrap().count(), 2);
    }

    #[test]
    fn an_input_is_never_an_output() {
        let d = dir("inputs");
        let input = d.join("in.mcap");
        std::fs::write(&input, "bag").unwrap();
        std::fs::hard_link(&input, d.join("link.mcap")).unwrap();
        let frames = d.join("frames");
        std::fs::create_dir_all(&frames).unwrap();
        let dotted = d.join(".").join("in.mcap");
        for out in [
            input.clone(),
            d.join("link.mcap"),
            dotted,
            frames.join("x.mcap"),
        ] {
            let err = refuse_inputs_as_outputs(
                &[("--mcap", &out)],
                &[("INPUT", &input), ("INPUT", &frames)],
            )
            .unwrap_err();
            assert!(err.downcast_ref::<Usage>().is_some(), "{out:?}: {err}");
            assert!(
                err.to_string().contains("would overwrite the input"),
                "{err}"
            );
        }
        refuse_inputs_as_outputs(&[("--mcap", &d.join("out.mcap"))], &[("INPUT", &input)]).unwrap();
        refuse_inputs_as_outputs(&[("--out", Path::new("/dev/null"))], &[("INPUT", &input)])
            .unwrap();
    }
}
