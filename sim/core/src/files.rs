//! Writing outputs so that a crash or Ctrl-C never leaves a half-written file or folder that
//! looks complete.
//!
//! A file is written to a temporary file in its destination folder, flushed to disk (fsync)
//! and renamed over the destination ([`write_atomic`]). A folder of files is written into a
//! hidden temporary folder beside the destination and renamed into place when every file is
//! complete ([`write_dir_atomic`]).

use std::io::Write;
use std::path::{Path, PathBuf};

/// A file system operation that failed, with the path it failed on. Its message holds the
/// I/O error, which is therefore not also its `source` (an error chain printed with `{:#}`
/// would say `No space left on device` twice).
#[derive(Debug, thiserror::Error)]
#[error("{}: {error}", path.display())]
pub struct FileError {
    /// The path involved.
    pub path: PathBuf,
    /// What failed.
    pub error: std::io::Error,
}

impl FileError {
    /// A closure that wraps an I/O error with `path`.
    pub fn at(path: &Path) -> impl FnOnce(std::io::Error) -> FileError + '_ {
        move |error| FileError {
            path: path.to_path_buf(),
            error,
        }
    }
}

/// Bytes an unprivileged writer may still write on the file system that holds `path` (or,
/// where `path` does not exist yet, its nearest existing folder); `None` where the file
/// system does not say.
pub fn free_bytes(path: &Path) -> Option<u64> {
    let mut at = path;
    while !at.exists() {
        at = match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
    }
    let fs = rustix::fs::statvfs(at).ok()?;
    Some(fs.f_bavail.saturating_mul(fs.f_frsize))
}

/// `bytes` for people: `1.4 GB`, `300 kB` (decimal units, as `df -H` prints them).
pub fn human_bytes(bytes: u64) -> String {
    let b = bytes as f64;
    match b {
        b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
        b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
        b if b >= 1e3 => format!("{:.0} kB", b / 1e3),
        b => format!("{b:.0} B"),
    }
}

/// The folder a path lives in (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    path.parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
}

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, fsync, rename.
/// Creates the folder if needed. Readers see the old file or the new one, never a part.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let dir = folder_of(path);
    std::fs::create_dir_all(dir).map_err(FileError::at(dir))?;
    let mut builder = tempfile::Builder::new();
    builder.prefix(".partial-");
    // A temporary file is private (0600); the file it becomes is an ordinary output, readable
    // as one written with File::create would be (0644, less the umask).
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(FileError::at(dir))?;
    tmp.write_all(bytes).map_err(FileError::at(path))?;
    tmp.as_file().sync_all().map_err(FileError::at(path))?;
    tmp.persist(path).map_err(|e| FileError {
        path: path.to_path_buf(),
        error: e.error,
    })?;
    Ok(())
}

/// Writes `files` (relative path, bytes) as the folder `dir`, atomically: into a hidden
/// `.<leaf>.partial-<pid>` folder beside it, each file fsynced, then renamed into place.
/// `extra(tmp)` may move more into the temporary folder before the rename (a staged folder of
/// frames). An existing `dir` is replaced (the caller decides whether it may be). On failure
/// the temporary folder is removed.
pub fn write_dir_atomic(
    dir: &Path,
    files: &[(String, Vec<u8>)],
    extra: impl FnOnce(&Path) -> Result<(), FileError>,
) -> Result<(), FileError> {
    let parent = folder_of(dir);
    std::fs::create_dir_all(parent).map_err(FileError::at(parent))?;
    let leaf = dir
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_else(|| "run".into());
    let tmp = parent.join(format!(".{leaf}.partial-{}", std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(FileError::at(&tmp))?;
    }
    let written = (|| {
        for (name, bytes) in files {
            let path = tmp.join(name);
            let folder = folder_of(&path);
            std::fs::create_dir_all(folder).map_err(FileError::at(folder))?;
            let mut f = std::fs::File::create(&path).map_err(FileError::at(&path))?;
            f.write_all(bytes).map_err(FileError::at(&path))?;
            f.sync_all().map_err(FileError::at(&path))?;
        }
        extra(&tmp)?;
        if dir.exists() {
            // An earlier output with the same destination: move it aside, then replace it.
            let old = parent.join(format!(".{leaf}.old-{}", std::process::id()));
            std::fs::rename(dir, &old).map_err(FileError::at(dir))?;
            std::fs::rename(&tmp, dir).map_err(FileError::at(dir))?;
            std::fs::remove_dir_all(&old).map_err(FileError::at(&old))?;
        } else {
            std::fs::rename(&tmp, dir).map_err(FileError::at(dir))?;
        }
        Ok(())
    })();
    if written.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    written
}

#[cfg(test)]
mod tests {
    #[cfg(unix)]
    #[test]
    fn an_atomically_written_file_has_the_mode_of_an_ordinary_one() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let (atomic, plain) = (dir.path().join("a.json"), dir.path().join("b.json"));
        write_atomic(&atomic, b"{}").unwrap();
        std::fs::write(&plain, b"{}").unwrap();
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(
            mode(&atomic),
            mode(&plain),
            "not the temporary file's private 0600"
        );
    }

    use super::*;

    #[test]
    fn a_file_is_replaced_whole_and_nothing_is_left_beside_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub/a.txt");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = std::fs::read_dir(dir.path().join("sub"))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("a.txt")]);
    }

    #[test]
    fn a_failed_folder_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("run");
        let files = vec![("a/b.txt".to_string(), b"x".to_vec())];
        let err = write_dir_atomic(&out, &files, |_| {
            Err(FileError {
                path: "staged".into(),
                error: std::io::Error::other("interrupted"),
            })
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        write_dir_atomic(&out, &files, |_| Ok(())).unwrap();
        assert_eq!(std::fs::read(out.join("a/b.txt")).unwrap(), b"x");
    }
}
