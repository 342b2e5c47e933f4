//! gravcal's `ingest` stage: raw logs to Parquet tables, with every byte accounted for.
//!
//! Reads a dataset folder (docs/formats.md sections 2-5): the manifest, validated strictly; per
//! session the binary acquisition log or the CSV pair, and the theodolite log. Writes, under
//! `OUT/ingest/`, the raw streams as zstd Parquet tables in one time scale (GPS time, i64 ns
//! since 1980-01-06; see [`contract::tables`]) and `ingest.json`, the ledger: per input file its
//! SHA-256, size, and what was read, accepted and rejected by reason ([`contract::ledger`]).
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

pub mod contract;
mod csvlog;
pub mod encoding;
mod error;
pub mod gcb;
pub mod labstream;
mod lines;
pub mod lock;
mod streams;
pub mod table;
pub mod theodolite;
pub mod time;
pub mod timegate;

pub use error::{Error, Result};

use contract::custody;
use contract::ledger::{
    FileLedger, IngestReport, LEDGER_FILE, LEDGER_FORMAT, MANIFEST_FILE, STAGE_DIR, SessionSummary,
};
use contract::manifest::{self, Acquisition, Dataset};
use contract::tables;
use serde::Serialize;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use streams::StreamWriter;

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
    config: gcb::ScanConfig,
    streams: &mut StreamWriter,
    ledger: &mut FileLedger,
    progress: &indicatif::ProgressBar,
) -> Result<Option<i64>> {
    let mut scanner = gcb::FrameScanner::new(config);
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
    let interval = scanner.finish(ledger, &mut emit)?;
    ledger.null_values = streams.take_null_counts()?;
    ledger.sha256 = sha;
    ledger.bytes = bytes;
    Ok(interval)
}

/// A measured rate further than this fraction from the declared one is an error.
pub const RATE_TOLERANCE: f64 = 0.01;

/// What makes a session unusable as a whole, if anything: no data (unless the manifest
/// expects none), or a sample rate that is not the declared one.
fn session_errors(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    summary: &SessionSummary,
    acquisition: &[String],
) -> Vec<String> {
    let id = &s.session.id;
    let files = acquisition.join(", ");
    let mut errors = Vec::new();
    let hint = "(if this is expected, set `expect_empty = true` in its [[session]])";
    if summary.acceleration_samples == 0 && !s.session.expect_empty {
        errors.push(format!(
            "session {id}: {files} gave no usable acceleration sample {hint}"
        ));
    }
    if let Some(theodolite) = &s.theodolite
        && summary.readings == 0
        && !s.session.expect_empty
    {
        errors.push(format!(
            "session {id}: {} gave no usable theodolite reading {hint}",
            relative(ds, theodolite)
        ));
    }
    let declared = ds.manifest.instrument.sample_rate_hz;
    if let Some(measured) = summary.measured_sample_rate_hz
        && (measured / declared - 1.0).abs() > RATE_TOLERANCE
    {
        errors.push(format!(
            "session {id}: {files}: the acceleration samples come at {measured:.4} Hz, but \
             instrument.sample_rate_hz declares {declared} Hz (more than {:.0} % off)",
            RATE_TOLERANCE * 100.0
        ));
    }
    errors
}

/// The tables a run writes, and the session being read.
struct Writers {
    streams: StreamWriter,
    theo: theodolite::TheodoliteWriter,
    lab: labstream::LabWriter,
    /// Index of the session being read.
    session: u16,
}

/// Ingests `dataset` into `out/ingest/` with default options.
pub fn run(dataset: &Path, out: &Path) -> Result<IngestReport> {
    run_with(dataset, out, &Options::default())
}

/// Reads a session's acquisition logs (the binary log, or the CSV pair) into `streams`,
/// their ledgers into `files`; returns the median interval between acceleration samples.
fn read_acquisition(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    opts: &Options,
    out: &mut Writers,
    files: &mut Vec<FileLedger>,
) -> Result<Option<i64>> {
    let streams = &mut out.streams;
    let id = s.session.id.as_str();
    let acceleration_interval_ns = (1e9 / ds.manifest.instrument.sample_rate_hz).round() as i64;
    match &s.acquisition {
        Acquisition::Binary(path) => {
            let mut ledger = new_ledger(ds, path, id, "acquisition", "frames");
            let pb = progress_bar(opts, path);
            let config = gcb::ScanConfig {
                reference_week: time::week_of_date(s.date),
                acceleration_interval_ns,
                range_ns: s.gps_range_ns(),
            };
            let interval = read_binary(path, config, streams, &mut ledger, &pb)?;
            pb.finish_and_clear();
            files.push(ledger);
            Ok(interval)
        }
        Acquisition::Lab {
            stream,
            temperature,
            zero_gps_ns,
        } => {
            let mut ledger = new_ledger(ds, stream, id, "adc_csv", "lines");
            let pb = progress_bar(opts, stream);
            let config = labstream::LabConfig {
                session: out.session,
                zero_gps_ns: *zero_gps_ns,
                interval_ns: acceleration_interval_ns,
                range_ns: s.gps_range_ns(),
                skip_bad_lines: opts.skip_bad_lines,
                reading_limits: labstream::reading_limits(&ds.manifest.instrument),
            };
            let interval = labstream::read_lab(stream, config, &mut out.lab, &mut ledger, &pb)?;
            pb.finish_and_clear();
            files.push(ledger);
            if let Some(path) = temperature {
                let mut ledger = new_ledger(ds, path, id, "temperature_csv", "lines");
                let pb = progress_bar(opts, path);
                labstream::read_lab_temperature(
                    path,
                    config,
                    gcb::TEMPERATURE_INTERVAL_NS,
                    streams,
                    &mut ledger,
                    &pb,
                )?;
                pb.finish_and_clear();
                files.push(ledger);
            }
            Ok(interval)
        }
        Acquisition::Csv { adc, temperature } => {
            let mut interval = None;
            for (path, kind, role, interval_ns) in [
                (
                    adc,
                    csvlog::CsvKind::Adc,
                    "adc_csv",
                    acceleration_interval_ns,
                ),
                (
                    temperature,
                    csvlog::CsvKind::Temperature,
                    "temperature_csv",
                    gcb::TEMPERATURE_INTERVAL_NS,
                ),
            ] {
                let mut ledger = new_ledger(ds, path, id, role, "lines");
                let pb = progress_bar(opts, path);
                let form = match kind {
                    csvlog::CsvKind::Adc => s.times.adc,
                    csvlog::CsvKind::Temperature => s.times.temperature,
                };
                let config = csvlog::CsvConfig {
                    kind,
                    skip_bad_lines: opts.skip_bad_lines,
                    interval_ns,
                    range_ns: s.gps_range_ns(),
                    time: s.times.reader(form),
                };
                let median = csvlog::read_csv(path, config, streams, &mut ledger, &pb)?;
                if kind == csvlog::CsvKind::Adc {
                    interval = median;
                }
                pb.finish_and_clear();
                files.push(ledger);
            }
            Ok(interval)
        }
    }
}

/// Reads a session's acquisition logs and, on a thread of its own meanwhile, its theodolite
/// log at `path`: the readings, the acquisition's median interval, and the theodolite's ledger.
fn read_with_theodolite(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    path: &Path,
    opts: &Options,
    out: &mut Writers,
    files: &mut Vec<FileLedger>,
) -> Result<(Vec<theodolite::Reading>, Option<i64>, FileLedger)> {
    // The theodolite log is independent of the acquisition log, and the Parquet writer is
    // idle while the first row group fills.
    let mut ledger = new_ledger(ds, path, &s.session.id, "theodolite", "lines");
    let skip_bad_lines = opts.skip_bad_lines;
    std::thread::scope(|scope| {
        let theodolite = scope.spawn(move || {
            theodolite::read_theodolite(
                s,
                path,
                skip_bad_lines,
                &mut ledger,
                &indicatif::ProgressBar::hidden(),
            )
            .map(|readings| (readings, ledger))
        });
        let acquisition = read_acquisition(ds, s, opts, out, files);
        let readings = theodolite.join().map_err(|_| {
            Error::io(
                path,
                std::io::Error::other("the theodolite reading thread panicked"),
            )
        })?;
        let interval_ns = acquisition?;
        readings.map(|(r, ledger)| (r, interval_ns, ledger))
    })
}

/// Ingests one session: its acquisition logs and (tilt-table sessions) its theodolite log.
/// Returns what it gave, and what makes it unusable as a whole, if anything.
fn ingest_session(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    index: u16,
    opts: &Options,
    out: &mut Writers,
    files: &mut Vec<FileLedger>,
) -> Result<(SessionSummary, Vec<String>)> {
    let id = s.session.id.as_str();
    out.streams.start_session(index)?;
    out.session = index;
    let (readings, interval_ns) = match &s.theodolite {
        Some(path) => {
            let (readings, interval_ns, ledger) =
                read_with_theodolite(ds, s, path, opts, out, files)?;
            out.theo
                .write(id, s.session.theodolite_unit, s.times.scale, &readings)?;
            files.push(ledger);
            (readings.len() as u64, interval_ns)
        }
        // A survey or a multi-position session: acquisition logs only.
        None => (0, read_acquisition(ds, s, opts, out, files)?),
    };
    let st = out.streams.stats()?;
    // A lab stream's samples go to lab.parquet: its ledger counts them.
    let lab_samples: u64 = match s.acquisition {
        Acquisition::Lab { .. } => files
            .iter()
            .filter(|f| f.session == id && f.lab_stream.is_some())
            .map(|f| f.accepted)
            .sum(),
        _ => 0,
    };
    let summary = SessionSummary {
        id: id.to_owned(),
        acceleration_samples: st.acceleration + lab_samples,
        temperature_samples: st.temperature,
        kind: s.session.kind,
        readings,
        first_gps_ns: st.first_gps_ns,
        last_gps_ns: st.last_gps_ns,
        channels_never_connected: (0..3u8)
            .filter(|&ch| st.acceleration > 0 && !st.connected_seen[usize::from(ch)])
            .map(|ch| ch + 1)
            .collect(),
        measured_sample_rate_hz: interval_ns.filter(|&i| i > 0).map(|i| 1e9 / i as f64),
    };
    let acquisition_files: Vec<String> = files
        .iter()
        .filter(|f| f.session == id && f.role != "theodolite")
        .map(|f| f.path.clone())
        .collect();
    let mut errors = session_errors(ds, s, &summary, &acquisition_files);
    // A lab stream whose stamps never move has no measured rate: its samples' times would
    // be the declared rate's, not the logger's.
    errors.extend(
        files
            .iter()
            .filter(|f| f.session == id && f.accepted >= 2)
            .filter(|f| {
                f.lab_stream
                    .as_ref()
                    .is_some_and(|l| l.median_interval_ns.is_none())
            })
            .map(|f| {
                format!(
                    "session {id}: {}: the {} samples kept share one time stamp: the times \
                     never move, so the sample rate cannot be measured (is the time column \
                     the first?)",
                    f.path, f.accepted
                )
            }),
    );
    Ok((summary, errors))
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
        theo: theodolite::TheodoliteWriter::create(&dir)?,
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
    let theo_rows = theo.finish();
    let lab_rows = lab.finish();
    let (acc_rows, temp_rows) = closing.wait()?;
    let theo_rows = theo_rows?;
    let lab_rows = lab_rows?;
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
    let outputs = [
        tables::acceleration::FILE,
        tables::temperature::FILE,
        tables::theodolite::FILE,
        tables::lab::FILE,
    ]
    .iter()
    .map(|t| folders.record(custody::Root::Out, &format!("{STAGE_DIR}/{t}")))
    .collect::<Result<Vec<_>>>()?;
    let report = IngestReport {
        format: LEDGER_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        files,
        sessions,
        tables: [
            (tables::acceleration::FILE.to_owned(), acc_rows),
            (tables::temperature::FILE.to_owned(), temp_rows),
            (tables::theodolite::FILE.to_owned(), theo_rows),
            (tables::lab::FILE.to_owned(), lab_rows),
        ]
        .into_iter()
        .collect(),
        custody: custody::Custody { inputs, outputs },
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

/// Prints `peak_rss_kb N` and `cpu_s S` to stderr, for `cargo xtask bench`.
pub fn print_usage() {
    match peak_rss_kb() {
        Some(kb) => eprintln!("peak_rss_kb {kb}"),
        None => eprintln!("peak_rss_kb unavailable"),
    }
    if let Some(s) = cpu_seconds() {
        eprintln!("cpu_s {s}");
    }
}

/// Peak resident set size of this process in kB, from /proc (Linux only), for benchmarks.
pub fn peak_rss_kb() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
