//! Guards that keep a run from destroying its user's files: an output may never be one of
//! the run's inputs (or lie inside an input folder, or hold an input that it would
//! replace), and an output folder that a failed run created is removed again, so a
//! failure leaves nothing behind.

use std::path::{Path, PathBuf};

/// Why an output path was refused.
#[derive(Debug, thiserror::Error)]
pub enum GuardError {
    /// The output would replace or sit inside one of the inputs.
    #[error(
        "{out_flag} {out} would overwrite the input {in_flag} {input}; choose another {out_flag}"
    )]
    Clobbers {
        /// The flag naming the output (e.g. `--out`).
        out_flag: String,
        /// The output path as given.
        out: PathBuf,
        /// The flag naming the input (e.g. `--data`).
        in_flag: String,
        /// The input path as given.
        input: PathBuf,
    },
    /// The output folder could not be created or is not writable.
    #[error("cannot use output directory {path}: {source}; choose a writable --out")]
    Io {
        /// The folder.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
}

/// The absolute, symlink-resolved form of `p`, also for a path that does not exist yet
/// (its nearest existing ancestor is resolved and the rest appended).
pub fn resolve(p: &Path) -> PathBuf {
    let abs = if p.is_absolute() {
        p.to_path_buf()
    } else {
        std::env::current_dir()
            .map(|d| d.join(p))
            .unwrap_or_else(|_| p.to_path_buf())
    };
    let mut tail = Vec::new();
    let mut cur = abs.as_path();
    loop {
        if let Ok(c) = cur.canonicalize() {
            let mut out = c;
            for t in tail.iter().rev() {
                out.push(t);
            }
            return normalise(&out);
        }
        match (cur.parent(), cur.file_name()) {
            (Some(parent), Some(name)) => {
                tail.push(name.to_os_string());
                cur = parent;
            }
            _ => return normalise(&abs),
        }
    }
}

/// Drop `.` and resolve `..` lexically (after the existing prefix was canonicalised).
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            std::path::Component::CurDir => {}
            std::path::Component::ParentDir => {
                out.pop();
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Refuse an output **file** `out` (named by `out_flag`) that is, or lies inside, one of
/// `inputs` (`(flag, path)` pairs). Call it before any computation.
pub fn check_output_file(
    out_flag: &str,
    out: &Path,
    inputs: &[(&str, &Path)],
) -> Result<(), GuardError> {
    let o = resolve(out);
    for (flag, input) in inputs {
        let i = resolve(input);
        if o == i || o.starts_with(&i) {
            return Err(clobbers(out_flag, out, flag, input));
        }
    }
    Ok(())
}

/// Refuse an output **folder** `out` that is, or lies inside, an input, or that holds an
/// input under one of the names the run writes (`writes`, relative to `out`).
pub fn check_output_dir(
    out_flag: &str,
    out: &Path,
    writes: &[&str],
    inputs: &[(&str, &Path)],
) -> Result<(), GuardError> {
    let o = resolve(out);
    for (flag, input) in inputs {
        let i = resolve(input);
        let collides = writes.iter().any(|w| resolve(&out.join(w)) == i);
        if o == i || o.starts_with(&i) || collides {
            return Err(clobbers(out_flag, out, flag, input));
        }
    }
    Ok(())
}

fn clobbers(out_flag: &str, out: &Path, in_flag: &str, input: &Path) -> GuardError {
    GuardError::Clobbers {
        out_flag: out_flag.to_string(),
        out: out.to_path_buf(),
        in_flag: in_flag.to_string(),
        input: input.to_path_buf(),
    }
}

/// An output folder for one run: created (with any missing parents) and probed for
/// writability up front; if the run fails (the value is dropped without [`OutDir::keep`]),
/// every folder this value created is removed again when it is still empty, so a failed
/// run leaves no empty folders behind. Files already written are never removed.
#[derive(Debug)]
pub struct OutDir {
    path: PathBuf,
    /// Folders created here, outermost first.
    created: Vec<PathBuf>,
    kept: bool,
}

impl OutDir {
    /// Create `path` if needed and check that a file can be written in it.
    pub fn prepare(path: &Path) -> Result<Self, GuardError> {
        let io = |source| GuardError::Io {
            path: path.to_path_buf(),
            source,
        };
        let mut missing = Vec::new();
        let mut cur = Some(path);
        while let Some(c) = cur {
            if c.as_os_str().is_empty() || c.exists() {
                break;
            }
            missing.push(c.to_path_buf());
            cur = c.parent();
        }
        missing.reverse();
        let mut dir = OutDir {
            path: path.to_path_buf(),
            created: Vec::new(),
            kept: false,
        };
        for m in &missing {
            std::fs::create_dir(m).map_err(io)?;
            dir.created.push(m.clone());
        }
        if !path.is_dir() {
            return Err(io(std::io::Error::other("exists and is not a directory")));
        }
        let probe = path.join(format!(".samara-probe-{}", std::process::id()));
        std::fs::write(&probe, b"").map_err(io)?;
        let _ = std::fs::remove_file(&probe);
        Ok(dir)
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The run succeeded: keep the folder.
    pub fn keep(mut self) {
        self.kept = true;
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if self.kept {
            return;
        }
        // Innermost first; remove_dir only removes empty folders.
        for d in self.created.iter().rev() {
            if std::fs::remove_dir(d).is_err() {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("samara-guard-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn output_equal_to_input_is_refused_under_any_spelling() {
        let d = tmp("eq");
        let data = d.join("data.csv");
        std::fs::write(&data, "1,2\n").unwrap();
        let other = d.join("sub").join("..").join("data.csv");
        let e = check_output_file("--out", &other, &[("--data", &data)]).unwrap_err();
        assert!(e.to_string().contains("--data"), "{e}");
        assert!(check_output_file("--out", &d.join("net.onnx"), &[("--data", &data)]).is_ok());
        // a folder output that would write data.csv over the input
        assert!(check_output_dir("--out", &d, &["data.csv"], &[("--data", &data)]).is_err());
        assert!(check_output_dir("--out", &d, &["other.csv"], &[("--data", &data)]).is_ok());
        // an output inside an input folder
        assert!(check_output_dir("--out", &d.join("x"), &[], &[("--ref", &d)]).is_err());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn failed_run_leaves_no_empty_folders_but_kept_one_stays() {
        let d = tmp("outdir");
        let deep = d.join("a").join("b");
        {
            let o = OutDir::prepare(&deep).unwrap();
            assert!(o.path().is_dir());
        }
        assert!(!d.join("a").exists());
        let o = OutDir::prepare(&deep).unwrap();
        o.keep();
        assert!(deep.is_dir());
        // a folder that existed before is never removed
        {
            let _o = OutDir::prepare(&deep).unwrap();
        }
        assert!(deep.is_dir());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
