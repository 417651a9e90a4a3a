//! Writing outputs without losing anything: a file appears at its target
//! only once it is complete (written beside it, then renamed into place),
//! and never over one of the command's inputs.
//!
//! Every failure is an [`OutputError`] naming the file; the I/O error under
//! a failed write or rename is its [`source`](std::error::Error::source), so
//! an error chain (anyhow's `{:#}`) reads `writing out.csv: No space left on
//! device`.

use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// An output that could not be written, or must not be.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The output is one of the inputs (the same file, or a link to it).
    #[error(
        "the output {} is the input {} itself: writing it would destroy the input",
        output.display(),
        input.display()
    )]
    IsInput {
        /// The output asked for.
        output: PathBuf,
        /// The input it is.
        input: PathBuf,
    },
    /// The target is a directory.
    #[error("{} is a directory", target.display())]
    IsDirectory {
        /// The output asked for.
        target: PathBuf,
    },
    /// The target's folder does not exist.
    #[error("cannot create {}: the folder {} does not exist", target.display(), dir.display())]
    NoFolder {
        /// The output asked for.
        target: PathBuf,
        /// Its folder.
        dir: PathBuf,
    },
    /// The file beside the target could not be created.
    #[error("cannot create {} in {}: {}", target.display(), dir.display(), kind)]
    Create {
        /// The output asked for.
        target: PathBuf,
        /// Its folder.
        dir: PathBuf,
        /// What failed (the kind only: the temporary file's name would mean
        /// nothing to the user).
        kind: std::io::Error,
    },
    /// Writing the data, or making them durable, failed.
    #[error("writing {}", target.display())]
    Write {
        /// The output.
        target: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
    /// Renaming the finished file onto the target failed.
    #[error("moving the finished output to {}", target.display())]
    Move {
        /// The output.
        target: PathBuf,
        /// The I/O error.
        #[source]
        source: std::io::Error,
    },
}

/// Whether `a` and `b` name the same existing file (symbolic and hard links
/// included).
pub fn same_file(a: &Path, b: &Path) -> bool {
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        #[cfg(unix)]
        (Ok(x), Ok(y)) => {
            use std::os::unix::fs::MetadataExt;
            x.dev() == y.dev() && x.ino() == y.ino()
        }
        #[cfg(not(unix))]
        (Ok(_), Ok(_)) => matches!((a.canonicalize(), b.canonicalize()), (Ok(x), Ok(y)) if x == y),
        _ => false,
    }
}

/// Refuses an output that is one of the inputs ([`OutputError::IsInput`]).
pub fn refuse_overwriting(output: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    for input in inputs {
        if same_file(input, output) {
            return Err(OutputError::IsInput {
                output: output.to_path_buf(),
                input: input.to_path_buf(),
            });
        }
    }
    Ok(())
}

/// A file being written beside its target; [`AtomicFile::commit`] renames it
/// into place, dropping it uncommitted removes it and leaves the target as
/// it was.
pub struct AtomicFile {
    tmp: tempfile::NamedTempFile,
    target: PathBuf,
}

impl AtomicFile {
    /// Starts a file that will become `target`.
    pub fn create(target: &Path) -> Result<AtomicFile, OutputError> {
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if target.is_dir() {
            return Err(OutputError::IsDirectory {
                target: target.to_path_buf(),
            });
        }
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let prefix = format!(".{name}.");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".partial");
        // An output gets the mode of the file it replaces, else 0666 less the
        // umask, as `File::create` would (tempfile's default is 0600).
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(target).map_or(0o666, |m| m.permissions().mode() & 0o7777);
            builder.permissions(std::fs::Permissions::from_mode(mode));
        }
        if !dir.is_dir() {
            return Err(OutputError::NoFolder {
                target: target.to_path_buf(),
                dir: dir.to_path_buf(),
            });
        }
        let tmp = builder.tempfile_in(dir).map_err(|e| OutputError::Create {
            target: target.to_path_buf(),
            dir: dir.to_path_buf(),
            kind: std::io::Error::from(e.kind()),
        })?;
        Ok(AtomicFile {
            tmp,
            target: target.to_path_buf(),
        })
    }

    /// Where the file is being written (for writers that open a path
    /// themselves, as the HDF5 library does).
    pub fn path(&self) -> &Path {
        self.tmp.path()
    }

    /// Makes the file durable and renames it onto the target.
    pub fn commit(self) -> Result<(), OutputError> {
        let target = self.target;
        if let Err(source) = self.tmp.as_file().sync_all() {
            return Err(OutputError::Write { target, source });
        }
        if let Err(e) = self.tmp.persist(&target) {
            return Err(OutputError::Move {
                target,
                source: e.error,
            });
        }
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.tmp.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.tmp.flush()
    }
}

impl Seek for AtomicFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.tmp.seek(pos)
    }
}

/// Writes `bytes` to `target` atomically.
pub fn write_atomic(target: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut f = AtomicFile::create(target)?;
    if let Err(source) = f.write_all(bytes) {
        return Err(OutputError::Write {
            target: target.to_path_buf(),
            source,
        });
    }
    f.commit()
}
#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_uncommitted_file_leaves_the_target_as_it_was() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.rois");
        std::fs::write(&target, b"before").unwrap();
        {
            let mut f = AtomicFile::create(&target).unwrap();
            f.write_all(b"half").unwrap();
        }
        assert_eq!(std::fs::read(&target).unwrap(), b"before");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let mut f = AtomicFile::create(&target).unwrap();
        f.write_all(b"after").unwrap();
        f.commit().unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"after");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[cfg(unix)]
    #[test]
    fn an_output_is_readable_as_create_would_make_it() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        let fresh = dir.path().join("fresh");
        write_atomic(&fresh, b"x").unwrap();
        let plain = dir.path().join("plain");
        std::fs::write(&plain, b"x").unwrap();
        assert_eq!(mode(&fresh), mode(&plain), "umask applied as File::create");
        std::fs::set_permissions(&plain, std::fs::Permissions::from_mode(0o640)).unwrap();
        write_atomic(&plain, b"y").unwrap();
        assert_eq!(mode(&plain), 0o640, "a replaced file keeps its mode");
    }

    #[test]
    fn links_to_an_input_are_the_input() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in.spad");
        std::fs::write(&input, b"x").unwrap();
        let hard = dir.path().join("hard");
        std::fs::hard_link(&input, &hard).unwrap();
        #[cfg(unix)]
        {
            let soft = dir.path().join("soft");
            std::os::unix::fs::symlink(&input, &soft).unwrap();
            assert!(refuse_overwriting(&soft, &[&input]).is_err());
        }
        let e = AtomicFile::create(&dir.path().join("no/such/out"))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("the folder") && e.contains("does not exist"),
            "{e}"
        );
        let e = refuse_overwriting(&hard, &[&input])
            .unwrap_err()
            .to_string();
        assert!(e.contains("destroy the input"), "{e}");
        assert!(refuse_overwriting(&dir.path().join("new"), &[&input]).is_ok());
    }
}
