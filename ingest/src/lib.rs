//! gravcal's `ingest` stage: raw logs to Parquet tables, with every byte accounted for.
//!
//! Reads a dataset folder (docs/formats.md sections 2-5): the manifest, validated strictly; per
//! session the binary acquisition log or the CSV pair, and the theodolite log. Writes, under
//! `OUT/ingest/`, the raw streams as zstd Parquet tables in one time scale (GPS time, i64 ns
//! since 1980-01-06; see [`contract::tables`]) and `ingest.json`, the ledger: per input file its
//! SHA-256, size, and what was read, accepted and rejected by reason ([`contract::ingest_ledger`]).
//!
//! ```no_run
//! let report = ingest::run_with(
//!     std::path::Path::new("fixtures/esgt-2005"),
//!     std::path::Path::new("out/esgt-2005"),
//!     &ingest::Options::default(),
//! )?;
//! for f in &report.files {
//!     println!("{}: {} {} read, {} accepted", f.path, f.read, f.unit, f.accepted);
//! }
//! # Ok::<(), ingest::Error>(())
//! ```

pub mod base;
pub mod contract;
mod error;
pub mod parquet_io;
pub mod readers;
mod session;

pub use base::probes::{cpu_seconds, peak_rss_kb, print_usage};
pub use readers::lines::BOM;
pub use session::RATE_TOLERANCE;
use session::{Writers, ingest_session};

pub use error::{Error, Result};

use base::lock;
use contract::custody;
use contract::ingest_ledger::{
    FileLedger, IngestReport, LEDGER_FILE, LEDGER_FORMAT, MANIFEST_FILE, STAGE_DIR,
};
use contract::manifest::Dataset;
use contract::tables;
use parquet_io::streams::StreamWriter;
use parquet_io::table;
use readers::labstream;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// How to ingest.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Count and list malformed text lines instead of failing on the first one.
    pub skip_bad_lines: bool,
    /// Show a progress bar (only when stderr is a terminal).
    pub progress: bool,
}

/// Reads a JSON file written by a stage; a file that does not parse is an error naming it.
pub fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| {
        Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidData, e),
        )
    })
}

/// Removes a stage's ledger before the stage writes its tables: a stale ledger must not vouch
/// for tables this run may fail to replace. A missing file is fine.
pub fn remove_stale(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(Error::io(path, e)),
        _ => Ok(()),
    }
}

/// Creates `path` new for writing, never through what is there: whatever the name holds
/// (a file a killed run left, or a link, to anywhere) is removed first, not followed, and the
/// file is created exclusively (O_EXCL: a link planted in between fails it). Every stage
/// writes its outputs under a temporary name this way, then renames it into place (a
/// rename replaces a link at the final name, never writes through it).
pub fn create_new(path: &Path) -> std::io::Result<std::fs::File> {
    if path.symlink_metadata().is_ok() {
        std::fs::remove_file(path)?;
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

/// Writes `bytes` to `path` under a temporary name created new ([`create_new`]), then
/// renames it into place.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.partial"));
    let mut f = create_new(&tmp)?;
    f.write_all(bytes)?;
    drop(f);
    std::fs::rename(&tmp, path)
}

/// Writes `value` as pretty JSON to `path`, under a temporary name first.
pub fn write_json_atomically<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let json = serde_json::to_string_pretty(value).map_err(|e| Error::io(path, e.into()))?;
    write_atomically(path, (json + "\n").as_bytes()).map_err(|e| Error::io(path, e))
}

/// Ingests `dataset` into `out/ingest/` with default options.
pub fn run(dataset: &Path, out: &Path) -> Result<IngestReport> {
    run_with(dataset, out, &Options::default())
}

/// Ingests `dataset` into `out/ingest/`.
pub fn run_with(dataset: &Path, out: &Path, opts: &Options) -> Result<IngestReport> {
    let ds = Dataset::load(dataset)?;
    let _lock = lock::OutputLock::acquire(out)?;
    custody::check_out_folder(out, &ds.manifest.name)?;
    let dir: PathBuf = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let ledger_path = dir.join(LEDGER_FILE);
    remove_stale(&ledger_path)?;
    let ids: Vec<String> = ds.sessions.iter().map(|s| s.session.id.clone()).collect();
    let mut out_tables = Writers {
        streams: StreamWriter::create(&dir, &ids)?,
        theo: tables::theodolite::Writer::create(&dir)?,
        lab: labstream::LabWriter::create(&dir, &ids)?,
        session: 0,
    };
    let mut files = Vec::new();
    let mut sessions = Vec::new();
    let mut errors = Vec::new();
    for (index, s) in ds.sessions.iter().enumerate() {
        let index = u16::try_from(index).map_err(|_| Error::Manifest {
            path: ds.manifest_path.clone(),
            key: "session".to_owned(),
            message: "more than 65535 sessions".to_owned(),
        })?;
        let (summary, problems) = ingest_session(&ds, s, index, opts, &mut out_tables, &mut files)?;
        errors.extend(problems);
        sessions.push(summary);
    }
    // The small tables are finished while the writer thread finishes the stream tables.
    let Writers {
        streams, theo, lab, ..
    } = out_tables;
    let closing = streams.close()?;
    let theo = theo.finish();
    let lab = lab.finish();
    let (acc, temp) = closing.wait()?;
    let written = [
        (tables::acceleration::FILE, acc),
        (tables::temperature::FILE, temp),
        (tables::theodolite::FILE, theo?),
        (tables::lab::FILE, lab?),
    ];
    let custody = custody_of(&ds, out, &files, &written)?;
    let report = IngestReport {
        format: LEDGER_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        files,
        sessions,
        tables: written
            .iter()
            .map(|(file, (rows, _))| ((*file).to_owned(), *rows))
            .collect(),
        custody,
        errors,
    };
    write_json_atomically(&ledger_path, &report)?;
    if !report.errors.is_empty() {
        return Err(Error::Unusable {
            path: ledger_path,
            errors: report.errors,
        });
    }
    Ok(report)
}

/// The chain of custody of an ingest run: the manifest and every log read (hashed as they
/// were read), and the four tables `written` (hashed as they were written: reading them
/// back was a serial tail of every run, 5 ms on the 250 Hz two-hour log).
fn custody_of(
    ds: &Dataset,
    out: &Path,
    files: &[FileLedger],
    written: &[(&str, table::Written)],
) -> Result<custody::Custody> {
    let folders = custody::Folders {
        dataset: &ds.dir,
        out,
    };
    let mut inputs = vec![folders.record(custody::Root::Dataset, MANIFEST_FILE)?];
    inputs.extend(files.iter().map(|f| custody::FileHash {
        root: custody::Root::Dataset,
        path: f.path.clone(),
        sha256: f.sha256.clone(),
    }));
    let outputs = written
        .iter()
        .map(|(file, (_, sha256))| custody::FileHash {
            root: custody::Root::Out,
            path: format!("{STAGE_DIR}/{file}"),
            sha256: sha256.clone(),
        })
        .collect();
    Ok(custody::Custody { inputs, outputs })
}

/// Writes a few lines per file: what was read, accepted and rejected, and why.
pub fn print_summary(report: &IngestReport, w: &mut impl std::io::Write) {
    for f in &report.files {
        let _ = writeln!(w, "ingest: {}: {}", f.path, f.counts_line());
        if let Some(b) = &f.byte_ledger
            && b.skipped_resynchronising > 0
        {
            let _ = writeln!(
                w,
                "ingest: {}: {} bytes skipped while resynchronising",
                f.path, b.skipped_resynchronising
            );
        }
        for (what, n) in &f.null_values {
            let _ = writeln!(w, "ingest: {}: {n} values null ({what})", f.path);
        }
    }
    for s in &report.sessions {
        for ch in &s.channels_never_connected {
            let _ = writeln!(
                w,
                "ingest: session {}: channel {ch} is not connected in any sample",
                s.id
            );
        }
    }
}
