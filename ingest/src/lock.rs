//! One writer per output folder: every stage holds an advisory lock on `OUT/.gravcal.lock`
//! while it runs, so a second run into the same folder fails at once with a clear message
//! and leaves the first run's outputs intact.
//!
//! The lock is `flock(2)` through the standard library's `File::try_lock` (stable since Rust
//! 1.89, so no crate is needed): the kernel drops it when the process ends, however it ends,
//! so a killed run leaves no stale lock. Within one process the lock is re-entrant:
//! `cargo xtask pipeline` holds it across the stages, and each stage takes it again.

use crate::error::{Error, Result};
use std::collections::BTreeMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// File name of the lock in the output folder.
pub const LOCK_FILE: &str = ".gravcal.lock";

/// Locks this process holds: folder to (file, holders).
static HELD: Mutex<BTreeMap<PathBuf, (File, usize)>> = Mutex::new(BTreeMap::new());

/// The lock of an output folder, held until dropped.
#[derive(Debug)]
pub struct OutputLock {
    key: PathBuf,
}

impl OutputLock {
    /// Takes the lock of `out` (created if missing), or fails at once if another process
    /// holds it.
    pub fn acquire(out: &Path) -> Result<OutputLock> {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        let key = out.canonicalize().map_err(|e| Error::io(out, e))?;
        let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, n)) = held.get_mut(&key) {
            *n += 1;
            return Ok(OutputLock { key });
        }
        let path = key.join(LOCK_FILE);
        let file = File::options()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                return Err(Error::io(
                    &path,
                    std::io::Error::new(
                        std::io::ErrorKind::WouldBlock,
                        format!(
                            "another gravcal run is writing to {}; wait for it to finish or choose another --out",
                            out.display()
                        ),
                    ),
                ));
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(&path, e)),
        }
        held.insert(key.clone(), (file, 1));
        Ok(OutputLock { key })
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
        if let Some((_, n)) = held.get_mut(&self.key) {
            *n -= 1;
            if *n == 0 {
                // Closing the file releases the lock.
                held.remove(&self.key);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Re-entrant within a process, released when the last holder drops it; another open
    /// file description (as another process would have) is refused while it is held.
    #[test]
    fn one_writer_per_folder() {
        let dir = tempfile::tempdir().expect("tempdir");
        let a = OutputLock::acquire(dir.path()).expect("first");
        let b = OutputLock::acquire(dir.path()).expect("re-entrant");
        let other = File::options()
            .write(true)
            .open(dir.path().join(LOCK_FILE))
            .expect("open");
        assert!(matches!(
            other.try_lock(),
            Err(std::fs::TryLockError::WouldBlock)
        ));
        drop(a);
        assert!(matches!(
            other.try_lock(),
            Err(std::fs::TryLockError::WouldBlock)
        ));
        drop(b);
        other.try_lock().expect("free once every holder dropped it");
    }
}
