//! Writing outputs without losing anything: a file appears at its target
//! only once it is complete (written beside it, then renamed into place),
//! and never over one of the command's inputs.

use anyhow::{bail, Context};
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

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

/// Refuses an output that is one of the inputs.
pub fn refuse_overwriting(output: &Path, inputs: &[&Path]) -> anyhow::Result<()> {
    for input in inputs {
        if same_file(input, output) {
            bail!(
                "the output {} is the input {} itself: writing it would destroy the input",
                output.display(),
                input.display()
            );
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
    pub fn create(target: &Path) -> anyhow::Result<AtomicFile> {
        let dir = match target.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if target.is_dir() {
            bail!("{} is a directory", target.display());
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
            bail!(
                "cannot create {}: the folder {} does not exist",
                target.display(),
                dir.display()
            );
        }
        let tmp = builder.tempfile_in(dir).map_err(|e| {
            anyhow::anyhow!(
                "cannot create {} in {}: {}",
                target.display(),
                dir.display(),
                std::io::Error::from(e.kind())
            )
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
    pub fn commit(self) -> anyhow::Result<()> {
        let target = self.target;
        self.tmp
            .as_file()
            .sync_all()
            .with_context(|| format!("writing {}", target.display()))?;
        self.tmp
            .persist(&target)
            .map_err(|e| e.error)
            .with_context(|| format!("moving the finished output to {}", target.display()))?;
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
pub fn write_atomic(target: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    let mut f = AtomicFile::create(target)?;
    f.write_all(bytes)
        .with_context(|| format!("writing {}", target.display()))?;
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
