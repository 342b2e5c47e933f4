//! One session ingested: its acquisition logs (binary, CSV pair or lab stream) and its
//! theodolite log read into the tables, each file's ledger, and what makes the session
//! unusable as a whole.

use crate::base::time;
use crate::contract::ingest_ledger::{FileLedger, SessionSummary};
use crate::contract::manifest::{self, Acquisition, Dataset};
use crate::parquet_io::streams::StreamWriter;
use crate::readers::{csvlog, gcb, labstream, lines, theodolite};
use crate::{Error, Options, Result, contract};
use std::io::IsTerminal;
use std::path::Path;

pub(crate) fn relative(ds: &Dataset, p: &Path) -> String {
    p.strip_prefix(&ds.dir)
        .unwrap_or(p)
        .to_string_lossy()
        .replace('\\', "/")
}

pub(crate) fn progress_bar(opts: &Options, path: &Path) -> indicatif::ProgressBar {
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

pub(crate) fn new_ledger(
    ds: &Dataset,
    path: &Path,
    session: &str,
    role: &str,
    unit: &str,
) -> FileLedger {
    FileLedger {
        path: relative(ds, path),
        session: session.to_owned(),
        role: role.to_owned(),
        unit: unit.to_owned(),
        ..FileLedger::default()
    }
}

pub(crate) fn read_binary(
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
pub(crate) fn session_errors(
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

/// What a log's times say of its declared unit (issue 49) when every line of a lab stream
/// or of a counts CSV in seconds fell outside the session: its first time read in the other
/// unit ("s" since `start`, or "unix_s"), where that puts it inside the session, named with
/// the key; None otherwise.
fn time_unit_hint(s: &manifest::ResolvedSession, f: &FileLedger) -> Option<String> {
    let declared = s.times.adc;
    if f.accepted > 0 || !matches!(declared, time::TimeForm::S | time::TimeForm::UnixS) {
        return None;
    }
    let first = f
        .rejections
        .iter()
        .find(|r| r.reason == contract::ingest_ledger::reason::OUTSIDE_SESSION)?;
    let unix_zero = s.start_gps_ns - time::days_from_civil(s.date) * 86_400_000_000_000;
    let (declared_zero, other, other_zero) = match declared {
        time::TimeForm::S => (s.times.start_gps_ns?, "unix_s", Some(unix_zero)),
        _ => (unix_zero, "s", s.times.start_gps_ns),
    };
    // The first time as written, ns from the declared zero: a lab stream's rejection
    // gives it as written, the time gate's as GPS week and tow.
    let value = match first.detail.strip_prefix("time ") {
        Some(rest) => time::parse_seconds_ns(rest.split(' ').next()?.as_bytes())?,
        None => {
            let rest = first.detail.strip_prefix("GPS week ")?;
            let (week, rest) = rest.split_once(" tow ")?;
            let tow = time::parse_seconds_ns(rest.split(' ').next()?.as_bytes())?;
            week.parse::<i64>().ok()? * time::NS_PER_WEEK + tow - declared_zero
        }
    };
    let (lo, hi) = s.gps_range_ns();
    let inside = other_zero
        .and_then(|z| z.checked_add(value))
        .is_some_and(|t| (lo..hi).contains(&t));
    let looks = match (inside, other) {
        (true, _) => format!("read as \"{other}\" they fall inside it"),
        // Unix times of this century are above 1e9 s; seconds from a start are not.
        (false, "s") if (0..1_000_000_000 * 1_000_000_000).contains(&value) => {
            "they look like seconds since a start (\"s\", with the session's `start`)".to_owned()
        }
        _ => return None,
    };
    Some(format!(
        "session {}: {}: every line's time is outside the session as \"{}\" (the first, \
         {:.3} s, at {}); {looks}: check session.adc_time (or time_unit)",
        s.session.id,
        f.path,
        declared.name(),
        value as f64 * 1e-9,
        first.at
    ))
}

/// The tables a run writes, and the session being read.
pub(crate) struct Writers {
    pub(crate) streams: StreamWriter,
    pub(crate) theo: contract::tables::theodolite::Writer,
    pub(crate) lab: labstream::LabWriter,
    /// Index of the session being read.
    pub(crate) session: u16,
}

/// Reads a session's acquisition logs (the binary log, or the CSV pair) into `streams`,
/// their ledgers into `files`; returns the median interval between acceleration samples.
pub(crate) fn read_acquisition(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    opts: &Options,
    out: &mut Writers,
    files: &mut Vec<FileLedger>,
) -> Result<Option<i64>> {
    let acceleration_interval_ns = (1e9 / ds.manifest.instrument.sample_rate_hz).round() as i64;
    let mut file = Reading {
        ds,
        id: s.session.id.as_str(),
        opts,
        files,
    };
    match &s.acquisition {
        Acquisition::Binary(path) => file.read(path, "acquisition", "frames", |ledger, pb| {
            let config = gcb::ScanConfig {
                reference_week: time::week_of_date(s.date),
                acceleration_interval_ns,
                range_ns: s.gps_range_ns(),
            };
            read_binary(path, config, &mut out.streams, ledger, pb)
        }),
        Acquisition::Lab {
            stream,
            temperature,
            zero_gps_ns,
            temperature_zero_gps_ns,
        } => {
            let lab = LabFiles {
                stream,
                temperature: temperature.as_deref(),
                zero_gps_ns: *zero_gps_ns,
                temperature_zero_gps_ns: *temperature_zero_gps_ns,
            };
            file.lab(s, lab, acceleration_interval_ns, out)
        }
        Acquisition::Csv { adc, temperature } => {
            let interval = file.read(adc, "adc_csv", "lines", |ledger, pb| {
                let config = csv_config(s, opts, csvlog::CsvKind::Adc, acceleration_interval_ns);
                csvlog::read_csv(adc, config, &mut out.streams, ledger, pb)
            })?;
            if let Some(temperature) = temperature {
                file.temperature_csv(temperature, s, acceleration_interval_ns, &mut out.streams)?;
            }
            Ok(interval)
        }
    }
}

/// How session `s`'s CSV log of `kind` is read: its time form, nominal interval (the
/// accelerometers' `acceleration_interval_ns`, or the thermometers') and value columns (a
/// lab stream's temperature log in a calendar form is one too).
fn csv_config(
    s: &manifest::ResolvedSession,
    opts: &Options,
    kind: csvlog::CsvKind,
    acceleration_interval_ns: i64,
) -> csvlog::CsvConfig {
    let (form, interval_ns, columns) = match kind {
        csvlog::CsvKind::Adc => (s.times.adc, Some(acceleration_interval_ns), s.columns.adc),
        // A temperature log's rate is its logger's, declared nowhere: the gate learns it.
        csvlog::CsvKind::Temperature => (s.times.temperature, None, s.columns.temperature),
    };
    csvlog::CsvConfig {
        kind,
        skip_bad_lines: opts.skip_bad_lines,
        interval_ns,
        range_ns: s.gps_range_ns(),
        time: s.times.reader(form),
        columns,
    }
}

/// Reads a session's files one at a time, each with its ledger and progress bar.
/// A lab session's files and their times' zeros ([`Acquisition::Lab`]).
struct LabFiles<'a> {
    stream: &'a Path,
    temperature: Option<&'a Path>,
    zero_gps_ns: i64,
    temperature_zero_gps_ns: i64,
}

struct Reading<'a> {
    ds: &'a Dataset,
    id: &'a str,
    opts: &'a Options,
    files: &'a mut Vec<FileLedger>,
}

impl Reading<'_> {
    /// A lab session's stream and its temperature log, if any (in seconds: the stream's
    /// layout; in calendar times or GPS week + tow: a temperature CSV, 9.1); the stream's
    /// interval.
    fn lab(
        &mut self,
        s: &manifest::ResolvedSession,
        lab: LabFiles<'_>,
        acceleration_interval_ns: i64,
        out: &mut Writers,
    ) -> Result<Option<i64>> {
        let LabFiles {
            stream,
            temperature,
            zero_gps_ns,
            temperature_zero_gps_ns,
        } = lab;
        let config = labstream::LabConfig {
            session: out.session,
            zero_gps_ns,
            interval_ns: acceleration_interval_ns,
            range_ns: s.gps_range_ns(),
            skip_bad_lines: self.opts.skip_bad_lines,
            reading_limits: labstream::reading_limits(&self.ds.manifest.instrument),
            columns: s.columns.adc,
            layout: s.session.adc_format,
            time_scale: s.times.scale,
        };
        let interval = self.read(stream, "adc_csv", "lines", |ledger, pb| {
            labstream::read_lab(stream, config, &mut out.lab, ledger, pb)
        })?;
        let seconds = matches!(
            s.times.temperature,
            time::TimeForm::S | time::TimeForm::UnixS
        );
        match temperature {
            Some(path) if seconds => {
                let config = labstream::LabConfig {
                    zero_gps_ns: temperature_zero_gps_ns,
                    columns: s.columns.temperature,
                    layout: manifest::AdcFormat::Seconds,
                    ..config
                };
                self.read(path, "temperature_csv", "lines", |ledger, pb| {
                    labstream::read_lab_temperature(path, config, &mut out.streams, ledger, pb)
                })?;
            }
            Some(path) => {
                self.temperature_csv(path, s, acceleration_interval_ns, &mut out.streams)?;
            }
            None => {}
        }
        Ok(interval)
    }

    /// Reads `path` (its `role` in the session, counted in `unit`) with `f`, and keeps its
    /// ledger.
    fn read<T>(
        &mut self,
        path: &Path,
        role: &str,
        unit: &str,
        f: impl FnOnce(&mut FileLedger, &indicatif::ProgressBar) -> Result<T>,
    ) -> Result<T> {
        let mut ledger = new_ledger(self.ds, path, self.id, role, unit);
        let pb = progress_bar(self.opts, path);
        let out = f(&mut ledger, &pb)?;
        pb.finish_and_clear();
        self.files.push(ledger);
        Ok(out)
    }

    /// Reads session `s`'s temperature CSV at `path` (docs/formats.md 9.1: the counts CSV
    /// pair's, or a lab stream's in calendar times or GPS week + tow) into `streams`.
    fn temperature_csv(
        &mut self,
        path: &Path,
        s: &manifest::ResolvedSession,
        acceleration_interval_ns: i64,
        streams: &mut StreamWriter,
    ) -> Result<()> {
        let opts = self.opts;
        self.read(path, "temperature_csv", "lines", |ledger, pb| {
            let kind = csvlog::CsvKind::Temperature;
            let config = csv_config(s, opts, kind, acceleration_interval_ns);
            csvlog::read_csv(path, config, streams, ledger, pb)
        })?;
        Ok(())
    }
}

/// Reads a session's acquisition logs and, on a thread of its own meanwhile, its theodolite
/// log at `path`: the readings, the acquisition's median interval, and the theodolite's ledger.
pub(crate) fn read_with_theodolite(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    path: &Path,
    opts: &Options,
    out: &mut Writers,
    files: &mut Vec<FileLedger>,
) -> Result<(
    Vec<contract::tables::theodolite::Logged>,
    Option<i64>,
    FileLedger,
)> {
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
pub(crate) fn ingest_session(
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
        // A lab stream's channel without a column (adc_columns) is never connected, as a
        // counts log's whose status says so in every sample.
        channels_never_connected: (0..3u8)
            .filter(|&ch| {
                let ch = usize::from(ch);
                (st.acceleration > 0 && !st.connected_seen[ch])
                    || (lab_samples > 0 && s.columns.adc.column_of[ch].is_none())
            })
            .map(|ch| ch + 1)
            .collect(),
        measured_sample_rate_hz: interval_ns.filter(|&i| i > 0).map(|i| 1e9 / i as f64),
    };
    let errors = ingested_errors(ds, s, &summary, files);
    Ok((summary, errors))
}

/// What makes session `s`'s ingest fail once its `files` are read ([`session_errors`]),
/// with a hint at the time unit where no sample was kept, and a lab stream whose stamps
/// never move (it has no measured rate: its samples' times would be the declared rate's,
/// not the logger's).
fn ingested_errors(
    ds: &Dataset,
    s: &manifest::ResolvedSession,
    summary: &SessionSummary,
    files: &[FileLedger],
) -> Vec<String> {
    let id = s.session.id.as_str();
    let acquisition_files: Vec<String> = files
        .iter()
        .filter(|f| f.session == id && f.role != "theodolite")
        .map(|f| f.path.clone())
        .collect();
    let mut errors = session_errors(ds, s, summary, &acquisition_files);
    if summary.acceleration_samples == 0 {
        errors.extend(
            files
                .iter()
                .filter(|f| f.session == id && f.role == "adc_csv")
                .filter_map(|f| time_unit_hint(s, f)),
        );
    }
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
    errors
}
