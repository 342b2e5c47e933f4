//! Chain of custody: every stage records the SHA-256 of every file it read and wrote, and
//! checks, before it reads an upstream folder, that the files on disk are still the ones
//! the upstream stages recorded. A stale or foreign folder is refused with a message naming
//! the file that changed and the command to re-run.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::{Path, PathBuf};

/// Which folder a recorded path is relative to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Root {
    /// The dataset folder (the manifest and the raw logs).
    Dataset,
    /// The output folder OUT (the stages' tables and ledgers).
    Out,
}

/// A file and its hash.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileHash {
    /// Folder `path` is relative to.
    pub root: Root,
    /// Path relative to `root`, with `/`.
    pub path: String,
    /// SHA-256 of its bytes, hex.
    pub sha256: String,
}

/// What a stage read and wrote.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Custody {
    /// Every file the stage read.
    pub inputs: Vec<FileHash>,
    /// Every table it wrote (its own ledger is not among them: it holds this record).
    pub outputs: Vec<FileHash>,
}

/// The two folders paths are relative to.
#[derive(Clone, Copy, Debug)]
pub struct Folders<'a> {
    /// The dataset folder.
    pub dataset: &'a Path,
    /// The output folder OUT.
    pub out: &'a Path,
}

impl Folders<'_> {
    fn resolve(&self, root: Root, path: &str) -> PathBuf {
        match root {
            Root::Dataset => self.dataset.join(path),
            Root::Out => self.out.join(path),
        }
    }

    /// Hashes `path` (relative to `root`) now.
    pub fn record(&self, root: Root, path: &str) -> Result<FileHash> {
        Ok(FileHash {
            root,
            path: path.to_owned(),
            sha256: sha256_file(&self.resolve(root, path))?,
        })
    }

    /// Checks that every file of `custody` still has its recorded hash. `stage` is the stage
    /// that recorded it, `rerun` the stage to re-run from when an input changed.
    pub fn verify(&self, custody: &Custody, stage: &str, rerun: &str) -> Result<()> {
        for (list, what, from) in [
            (&custody.inputs, "read", rerun),
            (&custody.outputs, "wrote", stage),
        ] {
            for f in list {
                let path = self.resolve(f.root, &f.path);
                let now = match sha256_file(&path) {
                    Ok(h) => h,
                    Err(_) => String::from("(missing)"),
                };
                if now != f.sha256 {
                    return Err(Error::Stale {
                        path,
                        message: format!(
                            "is not the file {stage} {what} (sha256 {} recorded, {} now); \
                             re-run from {from}: `cargo xtask pipeline {}` or `cargo xtask {from} {}`",
                            short(&f.sha256),
                            short(&now),
                            self.dataset.display(),
                            self.dataset.display()
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

fn short(h: &str) -> &str {
    &h[..h.len().min(12)]
}

/// SHA-256 of a file's bytes, hex. A file hashed before in this process and not changed
/// since (the same device, inode, length, and modification and change times to the
/// nanosecond) is not read again: the gravity stage hashes a DGS laptop file as apply
/// verifies ingest's inputs and again as its own input, 15 MB for a day at 1 Hz. As git
/// does with its index, a file changed less than [`RACY_S`] before it was read is hashed
/// every time: the clock that stamps a file's times moves in ticks of milliseconds, so a
/// change within one tick of the last would keep the stamps.
pub fn sha256_file(path: &Path) -> Result<String> {
    use std::collections::HashMap;
    use std::sync::{Mutex, OnceLock};
    type Seen = Mutex<HashMap<(PathBuf, FileStamp), String>>;
    static SEEN: OnceLock<Seen> = OnceLock::new();
    let stamp = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))
        .map(|m| FileStamp::of(&m))?;
    let key = (path.to_path_buf(), stamp);
    let seen = SEEN.get_or_init(Seen::default);
    if let Some(hex) = seen.lock().ok().and_then(|s| s.get(&key).cloned()) {
        return Ok(hex);
    }
    let started = std::time::SystemTime::now();
    let hex = sha256_read(path)?;
    // Kept only if the file did not change while it was read, nor just before.
    let after = std::fs::metadata(path).ok().map(|m| FileStamp::of(&m));
    let started_ns = started
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i128);
    let settled = key.1.changed_ns() + i128::from(RACY_S) * 1_000_000_000 < started_ns;
    if settled
        && after == Some(key.1)
        && let Ok(mut s) = seen.lock()
    {
        s.insert(key, hex.clone());
    }
    Ok(hex)
}

/// Seconds a file's last change must lie before its hash for the hash to be reused.
pub const RACY_S: u64 = 2;

/// What says a file is unchanged: its device and inode, length, and modification and
/// change times in nanoseconds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct FileStamp([i128; 5]);

impl FileStamp {
    fn of(m: &std::fs::Metadata) -> Self {
        use std::os::unix::fs::MetadataExt;
        let ns = |s: i64, n: i64| i128::from(s) * 1_000_000_000 + i128::from(n);
        FileStamp([
            i128::from(m.dev()),
            i128::from(m.ino()),
            i128::from(m.size()),
            ns(m.mtime(), m.mtime_nsec()),
            ns(m.ctime(), m.ctime_nsec()),
        ])
    }

    /// The later of the modification and change times, ns since 1970.
    fn changed_ns(&self) -> i128 {
        self.0[3].max(self.0[4])
    }
}

#[cfg(test)]
thread_local! {
    /// Files read by [`sha256_read`] on this thread.
    static READS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// SHA-256 of a file's bytes, read.
fn sha256_read(path: &Path) -> Result<String> {
    #[cfg(test)]
    READS.with(|r| r.set(r.get() + 1));
    let mut f = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
    }
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// Checks, before a stage writes anything into `out`, that no ledger already there belongs
/// to another dataset (a stage run with `--out` at another dataset's folder would write
/// over its outputs and break its chain). A ledger that cannot be read says nothing and is
/// left to the stage that reads it.
pub fn check_out_folder(out: &Path, expected: &str) -> Result<()> {
    use crate::contract::{align_ledger, apply_ledger, calibration, gravity_ledger, ingest_ledger};
    for (dir, file) in [
        (ingest_ledger::STAGE_DIR, ingest_ledger::LEDGER_FILE),
        (align_ledger::STAGE_DIR, align_ledger::LEDGER_FILE),
        (calibration::STAGE_DIR, calibration::CALIBRATION_FILE),
        (apply_ledger::STAGE_DIR, apply_ledger::LEDGER_FILE),
        (gravity_ledger::STAGE_DIR, gravity_ledger::LEDGER_FILE),
    ] {
        let path = out.join(dir).join(file);
        let Ok(bytes) = std::fs::read(&path) else {
            continue;
        };
        let recorded = serde_json::from_slice::<serde_json::Value>(&bytes)
            .ok()
            .and_then(|v| v.get("dataset").and_then(|d| d.as_str()).map(str::to_owned));
        if let Some(recorded) = recorded {
            check_dataset(&path, &recorded, expected)?;
        }
    }
    Ok(())
}

/// Checks that a ledger `ledger` was written for the dataset named `expected`.
pub fn check_dataset(ledger: &Path, recorded: &str, expected: &str) -> Result<()> {
    if recorded == expected {
        Ok(())
    } else {
        Err(Error::Stale {
            path: ledger.to_path_buf(),
            message: format!(
                "was written for dataset `{recorded}`, not `{expected}`: this output folder belongs to another dataset; choose another --out"
            ),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file changed within [`RACY_S`] is read at each hash; one settled is read once,
    /// until it changes, even to bytes of the same length.
    #[test]
    fn a_settled_file_is_hashed_once_until_it_changes() {
        let dir = tempfile::tempdir().expect("dir");
        let path = dir.path().join("raw.dat");
        std::fs::write(&path, b"abc").expect("written");
        let reads = || READS.with(std::cell::Cell::get);
        let before = reads();
        let fresh = sha256_file(&path).expect("hashed");
        assert_eq!(sha256_file(&path).expect("hashed"), fresh);
        assert_eq!(reads() - before, 2, "a fresh file is read each time");
        std::thread::sleep(std::time::Duration::from_millis(RACY_S * 1000 + 100));
        let before = reads();
        assert_eq!(sha256_file(&path).expect("hashed"), fresh);
        assert_eq!(sha256_file(&path).expect("hashed"), fresh);
        assert_eq!(reads() - before, 1, "a settled file is read once");
        std::fs::write(&path, b"abd").expect("written");
        let changed = sha256_file(&path).expect("hashed");
        assert_ne!(changed, fresh);
        assert_eq!(
            changed,
            "a52d159f262b2c6ddb724a61840befc36eb30c88877a4030b65cbe86298449c9"
        );
    }
}
