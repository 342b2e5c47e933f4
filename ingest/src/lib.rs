//! gravcal's `ingest` stage: raw logs to Parquet tables, with every byte accounted for.
//!
//! Reads a dataset folder (FORMATS.md sections 2-5): the manifest, validated strictly; per
//! session the binary acquisition log or the CSV pair, and the theodolite log. Writes, under
//! `OUT/ingest/`, the raw streams as zstd Parquet tables in one time scale (GPS time, i64 ns
//! since 1980-01-06; see [`schema`]) and `ingest.json`, the ledger: per input file its
//! SHA-256, size, and what was read, accepted and rejected by reason ([`ledger`]).
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

mod csvlog;
pub mod encoding;
mod error;
pub mod gcb;
pub mod ledger;
mod lines;
pub mod manifest;
pub mod schema;
mod streams;
pub mod table;
pub mod theodolite;
pub mod time;

pub use error::{Error, Result};

use ledger::FileLedger;
use manifest::{Acquisition, Dataset};
use serde::{Deserialize, Serialize};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use streams::StreamWriter;

/// File name of the ledger.
pub const LEDGER_FILE: &str = "ingest.json";
/// Format tag of the ledger.
pub const LEDGER_FORMAT: &str = "gravcal-ingest/1";

/// How to ingest.
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Count and list malformed text lines instead of failing on the first one.
    pub skip_bad_lines: bool,
    /// Show a progress bar (only when stderr is a terminal).
    pub progress: bool,
}

/// What a session gave.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SessionSummary {
    /// Session id.
    pub id: String,
    /// Acceleration samples accepted.
    pub acceleration_samples: u64,
    /// Temperature samples accepted.
    pub temperature_samples: u64,
    /// Theodolite readings accepted.
    pub readings: u64,
    /// GPS time of the first accepted acceleration sample, ns.
    pub first_gps_ns: Option<i64>,
    /// GPS time of the last accepted acceleration sample, ns.
    pub last_gps_ns: Option<i64>,
    /// Channels (1..3) flagged not connected in every accepted acceleration sample.
    pub channels_never_connected: Vec<u8>,
}

/// `ingest.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct IngestReport {
    /// [`LEDGER_FORMAT`].
    pub format: String,
    /// Dataset name.
    pub dataset: String,
    /// Software and version.
    pub software: String,
    /// Per input file, in manifest order.
    pub files: Vec<FileLedger>,
    /// Per session.
    pub sessions: Vec<SessionSummary>,
    /// Rows written per table file.
    pub tables: std::collections::BTreeMap<String, u64>,
}

impl IngestReport {
    /// Reads `dir/ingest.json` (`dir` being OUT/ingest).
    pub fn load(dir: &Path) -> Result<Self> {
        let path = dir.join(LEDGER_FILE);
        let invalid = |m: String| {
            Error::io(
                &path,
                std::io::Error::new(std::io::ErrorKind::InvalidData, m),
            )
        };
        let report: IngestReport = read_json(&path)?;
        if report.format != LEDGER_FORMAT {
            return Err(invalid(format!(
                "format `{}`, expected `{LEDGER_FORMAT}`",
                report.format
            )));
        }
        Ok(report)
    }
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

/// Writes `value` as pretty JSON to `path`, under a temporary name first.
pub fn write_json_atomically<T: Serialize>(path: &Path, value: &T) -> Result<()> {
    let json = serde_json::to_string_pretty(value).map_err(|e| Error::io(path, e.into()))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.partial"));
    std::fs::write(&tmp, json + "\n").map_err(|e| Error::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
}

fn relative(ds: &Dataset, p: &Path) -> String {
    p.strip_prefix(&ds.dir)
        .unwrap_or(p)
        .to_string_lossy()
        .replace('\\', "/")
}

fn progress_bar(opts: &Options, path: &Path) -> indicatif::ProgressBar {
    if !opts.progress || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let len = std::fs::metadata(path).map_or(0, |m| m.len());
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg} {wide_bar} {bytes}/{total_bytes} {bytes_per_sec}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb.set_message(
        path.file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
    );
    pb
}

fn new_ledger(ds: &Dataset, path: &Path, session: &str, role: &str, unit: &str) -> FileLedger {
    FileLedger {
        path: relative(ds, path),
        session: session.to_owned(),
        role: role.to_owned(),
        unit: unit.to_owned(),
        ..FileLedger::default()
    }
}

fn read_binary(
    path: &Path,
    reference_week: i64,
    streams: &mut StreamWriter,
    ledger: &mut FileLedger,
    progress: &indicatif::ProgressBar,
) -> Result<()> {
    let mut scanner = gcb::FrameScanner::new(reference_week);
    let mut emit = |f: gcb::Frame| -> Result<()> {
        match f {
            gcb::Frame::Acceleration {
                time_ns,
                counts,
                status,
            } => streams.acceleration(time_ns, counts, status),
            gcb::Frame::Temperature {
                time_ns,
                millidegrees,
                status,
            } => streams.temperature(
                time_ns,
                millidegrees.map(|m| Some(f64::from(m) / 1000.0)),
                status,
            ),
        }
    };
    let (sha, bytes) = lines::read_chunks(path, |chunk| {
        progress.inc(chunk.len() as u64);
        scanner.push(chunk, ledger, &mut emit)
    })?;
    scanner.finish(ledger, &mut emit)?;
    ledger.null_values = streams.take_null_counts()?;
    ledger.sha256 = sha;
    ledger.bytes = bytes;
    Ok(())
}

/// Ingests `dataset` into `out/ingest/` with default options.
pub fn run(dataset: &Path, out: &Path) -> Result<IngestReport> {
    run_with(dataset, out, &Options::default())
}

/// Ingests `dataset` into `out/ingest/`.
pub fn run_with(dataset: &Path, out: &Path, opts: &Options) -> Result<IngestReport> {
    let ds = Dataset::load(dataset)?;
    let dir: PathBuf = out.join("ingest");
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let ledger_path = dir.join(LEDGER_FILE);
    remove_stale(&ledger_path)?;
    let ids: Vec<String> = ds.sessions.iter().map(|s| s.session.id.clone()).collect();
    let mut streams = StreamWriter::create(&dir, &ids)?;
    let mut theo = theodolite::TheodoliteWriter::create(&dir)?;
    let mut files = Vec::new();
    let mut sessions = Vec::new();
    for (index, s) in ds.sessions.iter().enumerate() {
        let id = s.session.id.as_str();
        let index = u16::try_from(index).map_err(|_| Error::Manifest {
            path: ds.manifest_path.clone(),
            key: "session".to_owned(),
            message: "more than 65535 sessions".to_owned(),
        })?;
        streams.start_session(index)?;
        // The theodolite log is read on its own thread while the acquisition log is: it is
        // independent of it, and the Parquet writer is idle while the first row group fills.
        let mut ledger = new_ledger(&ds, &s.theodolite, id, "theodolite", "lines");
        let skip_bad_lines = opts.skip_bad_lines;
        let (readings, theodolite_ledger) = std::thread::scope(|scope| {
            let theodolite = scope.spawn(move || {
                theodolite::read_theodolite(
                    s,
                    skip_bad_lines,
                    &mut ledger,
                    &indicatif::ProgressBar::hidden(),
                )
                .map(|readings| (readings, ledger))
            });
            let acquisition = (|| -> Result<()> {
                match &s.acquisition {
                    Acquisition::Binary(path) => {
                        let mut ledger = new_ledger(&ds, path, id, "acquisition", "frames");
                        let pb = progress_bar(opts, path);
                        read_binary(
                            path,
                            time::week_of_date(s.date),
                            &mut streams,
                            &mut ledger,
                            &pb,
                        )?;
                        pb.finish_and_clear();
                        files.push(ledger);
                    }
                    Acquisition::Csv { adc, temperature } => {
                        for (path, kind, role) in [
                            (adc, csvlog::CsvKind::Adc, "adc_csv"),
                            (temperature, csvlog::CsvKind::Temperature, "temperature_csv"),
                        ] {
                            let mut ledger = new_ledger(&ds, path, id, role, "lines");
                            let pb = progress_bar(opts, path);
                            csvlog::read_csv(
                                path,
                                kind,
                                opts.skip_bad_lines,
                                &mut streams,
                                &mut ledger,
                                &pb,
                            )?;
                            pb.finish_and_clear();
                            files.push(ledger);
                        }
                    }
                }
                Ok(())
            })();
            let readings = theodolite.join().map_err(|_| {
                Error::io(
                    &s.theodolite,
                    std::io::Error::other("the theodolite reading thread panicked"),
                )
            })?;
            acquisition?;
            readings
        })?;
        theo.write(
            id,
            s.session.theodolite_unit,
            s.session.theodolite_time_scale,
            &readings,
        )?;
        files.push(theodolite_ledger);
        let st = streams.stats()?;
        sessions.push(SessionSummary {
            id: id.to_owned(),
            acceleration_samples: st.acceleration,
            temperature_samples: st.temperature,
            readings: readings.len() as u64,
            first_gps_ns: st.first_gps_ns,
            last_gps_ns: st.last_gps_ns,
            channels_never_connected: (0..3u8)
                .filter(|&ch| st.acceleration > 0 && !st.connected_seen[usize::from(ch)])
                .map(|ch| ch + 1)
                .collect(),
        });
    }
    // The theodolite table is finished while the writer thread finishes the stream tables.
    let closing = streams.close()?;
    let theo_rows = theo.finish();
    let (acc_rows, temp_rows) = closing.wait()?;
    let theo_rows = theo_rows?;
    let report = IngestReport {
        format: LEDGER_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        files,
        sessions,
        tables: [
            (schema::acceleration::FILE.to_owned(), acc_rows),
            (schema::temperature::FILE.to_owned(), temp_rows),
            (schema::theodolite::FILE.to_owned(), theo_rows),
        ]
        .into_iter()
        .collect(),
    };
    write_json_atomically(&ledger_path, &report)?;
    Ok(report)
}

/// Writes a few lines per file: what was read, accepted and rejected, and why.
pub fn print_summary(report: &IngestReport, w: &mut impl std::io::Write) {
    for f in &report.files {
        let rejected: Vec<String> = f.rejected.iter().map(|(r, n)| format!("{n} {r}")).collect();
        let _ = writeln!(
            w,
            "ingest: {}: {} {} read, {} accepted{}",
            f.path,
            f.read,
            f.unit,
            f.accepted,
            if rejected.is_empty() {
                String::new()
            } else {
                format!(", rejected: {}", rejected.join(", "))
            }
        );
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

/// CPU time of this process so far, user plus system, all threads, in seconds, from
/// /proc/self/stat (Linux only; in clock ticks of 1/100 s, USER_HZ on Linux), for
/// benchmarks: on a machine of few cores CPU time, not wall time, says what a change saved.
pub fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) in parentheses; utime and
    // stime are fields 14 and 15 of the line, the 12th and 13th after the name.
    let mut f = stat.rsplit_once(')')?.1.split_whitespace().skip(11);
    let utime: u64 = f.next()?.parse().ok()?;
    let stime: u64 = f.next()?.parse().ok()?;
    Some((utime + stime) as f64 / 100.0)
}

/// Peak resident set size of this process in kB, from /proc (Linux only), for benchmarks.
pub fn peak_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
