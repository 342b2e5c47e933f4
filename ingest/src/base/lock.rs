//! One writer per output folder: every stage holds an advisory lock on `OUT/.gravcal.lock`
//! while it runs, so a second run into the same folder fails within [`GRACE`] with a clear
//! message and leaves the first run's outputs intact.
//!
//! The grace: a child process this process starts (a peer, a browser) holds a copy of every
//! open file between its fork and its exec, the lock's too, and so keeps a lock this
//! process has just released for that moment. One stage finishing as another thread
//! started a child made the next stage of the same run fail (`xtask/tests/init.rs`, in CI
//! under load); the next stage now retries for a second before it says another run holds
//! the folder.
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

/// How long a stage retries a lock another process holds before it gives up.
pub const GRACE: std::time::Duration = std::time::Duration::from_secs(1);

/// Locks this process holds: folder to (file, holders).
static HELD: Mutex<BTreeMap<PathBuf, (File, usize)>> = Mutex::new(BTreeMap::new());

/// The lock of an output folder, held until dropped.
#[derive(Debug)]
pub struct OutputLock {
    key: PathBuf,
}

impl OutputLock {
    /// Takes the lock of `out` (created if missing), or fails if another process holds it
    /// for longer than [`GRACE`].
    pub fn acquire(out: &Path) -> Result<OutputLock> {
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        let key = out.canonicalize().map_err(|e| Error::io(out, e))?;
        let path = key.join(LOCK_FILE);
        let started = std::time::Instant::now();
        let mut file: Option<File> = None;
        loop {
            let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
            if let Some((_, n)) = held.get_mut(&key) {
                *n += 1;
                return Ok(OutputLock { key });
            }
            let f = match file.take() {
                Some(f) => f,
                None => File::options()
                    .create(true)
                    .truncate(false)
                    .write(true)
                    .open(&path)
                    .map_err(|e| Error::io(&path, e))?,
            };
            match f.try_lock() {
                Ok(()) => {
                    held.insert(key.clone(), (f, 1));
                    return Ok(OutputLock { key });
                }
                Err(std::fs::TryLockError::WouldBlock) if started.elapsed() < GRACE => {
                    file = Some(f);
                }
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
            // Not holding the map while waiting: this process's other locks stay free.
            drop(held);
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
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

    /// A lock another open file description (a child between fork and exec) releases
    /// within the grace is taken; one held past it is refused, after the grace.
    #[test]
    fn a_lock_released_within_the_grace_is_taken() {
        let dir = tempfile::tempdir().expect("tempdir");
        let other = File::options()
            .create(true)
            .truncate(false)
            .write(true)
            .open(dir.path().join(LOCK_FILE))
            .expect("open");
        other.try_lock().expect("free");
        let release = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(200));
            drop(other);
        });
        let lock = OutputLock::acquire(dir.path()).expect("taken once released");
        release.join().expect("thread");
        drop(lock);
        let other = File::options()
            .write(true)
            .open(dir.path().join(LOCK_FILE))
            .expect("open");
        other.try_lock().expect("free");
        let started = std::time::Instant::now();
        let e = OutputLock::acquire(dir.path()).expect_err("held past the grace");
        assert!(started.elapsed() >= GRACE, "{:?}", started.elapsed());
        assert!(e.to_string().contains("another gravcal run"), "{e}");
    }
}
