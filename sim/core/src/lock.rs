//! A folder claimed by one process at a time: `<folder>.lock` beside it, created exclusively,
//! holding the claiming process's id and host, removed when the claim is dropped. Two runs
//! given one results folder at once would otherwise both write it and both report success.
//!
//! A lock whose process is gone (on this host: no `/proc/<pid>`) is stale and taken over, so
//! a run killed with -9 does not block the next one. A lock held on another host (a shared
//! file system) is never taken over: its process cannot be checked from here.

use std::io::Write;
use std::path::{Path, PathBuf};

/// A held claim on a folder; dropping it releases the claim.
#[derive(Debug)]
pub struct FolderLock {
    path: PathBuf,
}

/// Why a folder could not be claimed.
#[derive(Debug, thiserror::Error)]
pub enum LockError {
    /// Another live process holds it.
    #[error("{}: being written by process {pid} on {host} (lock {}); wait for it to finish, choose another folder, or, if that process is gone, remove the lock", folder.display(), lock.display())]
    Held {
        /// The folder.
        folder: PathBuf,
        /// Its lock file.
        lock: PathBuf,
        /// The holder's process id.
        pid: u32,
        /// The holder's host.
        host: String,
    },
    /// The lock file could not be made or read.
    #[error(transparent)]
    File(#[from] crate::files::FileError),
}

/// This machine's host name (`unknown` where the kernel does not say).
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_string())
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "unknown".into())
}

impl FolderLock {
    /// Claims `folder` (which need not exist yet) for this process.
    pub fn take(folder: &Path) -> Result<Self, LockError> {
        use crate::files::FileError;
        let leaf = folder
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_else(|| "folder".into());
        let parent = folder
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(parent).map_err(FileError::at(parent))?;
        let path = parent.join(format!("{leaf}.lock"));
        // The claim is written whole into a file of this process's own, then linked into
        // place: the link exists with its content or not at all, so no other process reads
        // a lock half-written (and takes it for a stale one).
        let mine = parent.join(format!(".{leaf}.lock-{}", std::process::id()));
        std::fs::File::create(&mine)
            .and_then(|mut f| {
                writeln!(f, "{} {}", std::process::id(), host_name())?;
                f.sync_all()
            })
            .map_err(FileError::at(&mine))?;
        let claimed = Self::link(&mine, &path, folder);
        let _ = std::fs::remove_file(&mine);
        claimed
    }

    fn link(mine: &Path, path: &Path, folder: &Path) -> Result<Self, LockError> {
        use crate::files::FileError;
        let path = path.to_path_buf();
        // Twice at most: once more after removing a stale lock.
        for _ in 0..2 {
            match std::fs::hard_link(mine, &path) {
                Ok(()) => return Ok(Self { path }),
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                    let text = std::fs::read_to_string(&path).unwrap_or_default();
                    let mut words = text.split_whitespace();
                    let pid = words.next().and_then(|p| p.parse::<u32>().ok());
                    let host = words.next().unwrap_or("").to_string();
                    let gone = |pid: u32| !Path::new(&format!("/proc/{pid}")).exists();
                    match pid {
                        Some(pid) if host != host_name() || !gone(pid) => {
                            return Err(LockError::Held {
                                folder: folder.to_path_buf(),
                                lock: path,
                                pid,
                                host,
                            })
                        }
                        // Stale (its process is gone) or not a lock this code wrote.
                        _ => std::fs::remove_file(&path).map_err(FileError::at(&path))?,
                    }
                }
                Err(e) => return Err(FileError::at(&path)(e).into()),
            }
        }
        Err(FileError::at(&path)(std::io::Error::other("lock file keeps reappearing")).into())
    }
}

impl Drop for FolderLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_second_claim_is_refused_naming_the_holder_and_a_stale_one_is_taken_over() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("run");
        let lock = FolderLock::take(&folder).unwrap();
        match FolderLock::take(&folder) {
            Err(LockError::Held { pid, host, .. }) => {
                assert_eq!(pid, std::process::id());
                assert_eq!(host, host_name());
            }
            other => panic!("expected Held, got {other:?}"),
        }
        drop(lock);
        assert!(!dir.path().join("run.lock").exists(), "released on drop");
        // A lock left by a process that is gone (pid_max on Linux is at most 2^22).
        std::fs::write(
            dir.path().join("run.lock"),
            format!("4194304 {}\n", host_name()),
        )
        .unwrap();
        let _taken = FolderLock::take(&folder).unwrap();
        // Held on another host: never taken over.
        drop(_taken);
        std::fs::write(dir.path().join("run.lock"), "1 another-host\n").unwrap();
        assert!(matches!(
            FolderLock::take(&folder),
            Err(LockError::Held { pid: 1, .. })
        ));
    }
}
