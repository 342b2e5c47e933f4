//! The apply stage (docs/formats.md 8.5): a dataset's ingested acceleration stream (its survey
//! sessions, or any session) calibrated sample by sample into
//! `OUT/apply/acceleration.parquet`, with `OUT/apply/apply.json`.
//!
//! Streaming: ingest's table is read a row group (2^17 rows) at a time, each accelerometer's
//! columns are computed on its own rayon task, and the row group is handed to ingest's
//! column writer (columns encoded in parallel, appended in schema order, so the bytes do not
//! depend on the threads). Memory is a row group's columns and the temperature series
//! (4.096 s samples, 1/128 of the 31.25 Hz stream's rows), so flat in the log's length up
//! to the temperatures. Every sample is written: where there is no value the acceleration
//! is null and the flags say why (never a zero).

use super::CalibrationFunction;
use super::select::{Choice, Selection, Target, select};
use crate::Error;
use align::window::Interpolator;
use arrow_array::Array;
use ingest::contract::apply_ledger::{
    AppliedAccelerometer, ApplyReport, CalibrationUsed, LEDGER_FILE, LEDGER_FORMAT, STAGE_DIR,
};
use ingest::contract::calibration::{CALIBRATION_FORMAT, Calibration};
use ingest::contract::custody::{Custody, FileHash, Folders, Root, sha256_file};
use ingest::contract::ingest_ledger::{self, IngestReport};
use ingest::contract::manifest::Dataset;
use ingest::contract::status;
use ingest::contract::tables::temperature::Temperatures;
use ingest::contract::tables::{self, applied};
use ingest::parquet_io::table::STREAM_ROWS_PER_GROUP;
use rayon::prelude::*;
use std::path::Path;

/// What the sign and meaning of the applied acceleration are, for apply.json.
pub const QUANTITY: &str = "c(Ng, T): the specific force along each accelerometer's sensitive \
    axis in mGal, in the calibration's convention (at rest, -g cos of the axis's zenith \
    distance); sigma from the parameters' covariance only, not the sample's own noise";

/// The apply stage's options.
#[derive(Clone, Debug)]
pub struct Options<'a> {
    /// The calibration.json to apply.
    pub calibration: &'a Path,
    /// Which of its models and sessions.
    pub choice: Choice<'a>,
}

/// Applies a calibration to `dataset`'s acceleration stream (ingesting it into `out` first
/// unless `out` already holds its verified ingest); writes OUT/apply/. Every check of the
/// calibration against the dataset comes before any work.
pub fn run(dataset: &Path, out: &Path, opts: &Options<'_>) -> Result<ApplyReport, Error> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::base::lock::OutputLock::acquire(out)?;
    ingest::contract::custody::check_out_folder(out, &ds.manifest.name)?;
    let refused = |message| Error::Apply {
        path: opts.calibration.to_path_buf(),
        message,
    };
    let vendor = opts.calibration == Path::new(VENDOR);
    let cal = if vendor {
        None
    } else {
        Some(load_calibration(opts.calibration)?)
    };
    let (selection, triad) = match &cal {
        None => (vendor_selection(&ds, &opts.choice).map_err(refused)?, None),
        Some((cal, _)) => {
            let selection = select(cal, &ds, &opts.choice).map_err(|e| refused(e.to_string()))?;
            let triad = match super::select::triad_of(cal, &ds, &selection)
                .map_err(|e| refused(e.to_string()))?
            {
                Some((result, channels)) => {
                    let f = super::triad_stream::TriadFunction::new(result).map_err(&refused)?;
                    Some((result, channels, f))
                }
                None => None,
            };
            (selection, triad)
        }
    };
    // Ingest first where OUT holds no ingest of these logs as they are, saying why (another
    // dataset's OUT is refused by ingest itself, naming it).
    let ingest_report = match IngestReport::load_verified(&ds, out) {
        Ok(r) => r,
        Err(why) => {
            eprintln!("apply: ingesting {} first: {why}", dataset.display());
            ingest::run(dataset, out)?
        }
    };
    nothing_to_apply(&ds, &ingest_report).map_err(refused)?;
    let dir = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| ingest::Error::io(dir.clone(), e))?;
    let ledger_path = dir.join(LEDGER_FILE);
    ingest::remove_stale(&ledger_path)?;
    let used = match &cal {
        Some((cal, sha256)) => CalibrationUsed {
            path: opts.calibration.display().to_string(),
            sha256: sha256.clone(),
            dataset: cal.dataset.clone(),
            model: selection.model.clone(),
            session: selection.session.clone(),
        },
        None => CalibrationUsed {
            path: format!("{VENDOR}: the makers' stated calibrations in dataset.toml"),
            sha256: sha256_file(&ds.dir.join("dataset.toml"))?,
            dataset: ds.manifest.name.clone(),
            model: selection.model.clone(),
            session: selection.session.clone(),
        },
    };
    let report = match triad {
        Some((result, channels, f)) => {
            apply_triad(&ds, out, &ingest_report, used, result, channels, &f)?
        }
        None => apply_axes(&ds, out, &ingest_report, used, &selection)?,
    };
    ingest::write_json_atomically(&ledger_path, &report)?;
    Ok(report)
}

/// Refuses an application that would write no sample, naming the sessions.
fn nothing_to_apply(ds: &Dataset, ingest: &IngestReport) -> Result<(), String> {
    let rows = |file: &str| ingest.tables.get(file).copied().unwrap_or(0);
    if rows(tables::acceleration::FILE) + rows(tables::lab::FILE) > 0 {
        return Ok(());
    }
    let sessions: Vec<&str> = ds.sessions.iter().map(|s| s.session.id.as_str()).collect();
    Err(format!(
        "the dataset has no sample to apply the calibration to: sessions {} gave none",
        sessions.join(", ")
    ))
}

/// Axis models applied: each accelerometer's columns and the ledger.
fn apply_axes(
    ds: &Dataset,
    out: &Path,
    ingest_report: &IngestReport,
    used: CalibrationUsed,
    selection: &Selection,
) -> Result<ApplyReport, Error> {
    let ingest_dir = out.join(ingest_ledger::STAGE_DIR);
    let temperatures = tables::temperature::read(&ingest_dir)?;
    let max_gap_ns = (ds.manifest.align.max_temperature_gap_s * 1e9).round() as i64;
    let written = write_table(
        ds,
        &ingest_dir,
        &out.join(STAGE_DIR),
        selection,
        &temperatures,
        max_gap_ns,
    )?;
    Ok(ApplyReport {
        format: LEDGER_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        calibration: used,
        quantity: QUANTITY.to_owned(),
        rows_read: written.rows,
        rows_written: written.rows,
        accelerometers: selection
            .targets
            .iter()
            .zip(&written.lanes)
            .map(|(t, lane)| lane.ledger(t))
            .collect(),
        max_temperature_gap_s: ds.manifest.align.max_temperature_gap_s,
        custody: custody(ds, out, ingest_report, written.sha256)?,
    })
}

/// Samples flagged, by flag name, from the samples counted by their flags byte (a sample
/// may carry several flags); flags no sample carries are left out.
fn flag_counts(by_flags: &[u64; 256]) -> std::collections::BTreeMap<String, u64> {
    applied::FLAG_NAMES
        .iter()
        .map(|(bit, name)| {
            let n: u64 = (0..256)
                .filter(|f| f & usize::from(*bit) != 0)
                .map(|f| by_flags[f])
                .sum();
            ((*name).to_owned(), n)
        })
        .filter(|(_, n)| *n > 0)
        .collect()
}

/// What a triad's vector is, for apply.json.
pub const TRIAD_QUANTITY: &str = "a = T u(X, T): the calibrated specific-force vector in the \
    triad's body frame (imu_tk's; u = K (X - B) at order 1 without temperature terms), mGal, \
    with its 3 x 3 covariance from the parameters' covariance; flags per sample shared by the \
    three axes";

/// A triad model applied: the vector table and its ledger.
fn apply_triad(
    ds: &Dataset,
    out: &Path,
    ingest_report: &IngestReport,
    used: CalibrationUsed,
    result: &ingest::contract::calibration::TriadResult,
    channels: [usize; 3],
    f: &super::triad_stream::TriadFunction,
) -> Result<ApplyReport, Error> {
    let sessions: Vec<String> = ds.sessions.iter().map(|s| s.session.id.clone()).collect();
    let ingest_dir = out.join(ingest_ledger::STAGE_DIR);
    let max_gap_ns = (ds.manifest.align.max_temperature_gap_s * 1e9).round() as i64;
    let w = super::triad_stream::write(
        &sessions,
        &ingest_dir,
        &out.join(STAGE_DIR),
        f,
        channels,
        max_gap_ns,
    )?;
    let flagged = flag_counts(&w.by_flags);
    let accelerometers = channels
        .iter()
        .enumerate()
        .map(|(axis, &ch)| {
            let acc = ds.accelerometer_on(u8::try_from(ch + 1).unwrap_or(0));
            AppliedAccelerometer {
                id: acc.map(|a| a.id.clone()).unwrap_or_default(),
                channel: u8::try_from(ch + 1).unwrap_or(0),
                serial: acc.and_then(|a| a.serial.clone()),
                not_calibrated: None,
                counts_range: result.readings_range.map(|r| r[axis]),
                temperature_range_c: result.temperature_range_c,
                with_value: w.with_value,
                flagged: flagged.clone(),
            }
        })
        .collect();
    Ok(ApplyReport {
        format: LEDGER_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        calibration: used,
        quantity: TRIAD_QUANTITY.to_owned(),
        rows_read: w.rows,
        rows_written: w.rows,
        accelerometers,
        max_temperature_gap_s: ds.manifest.align.max_temperature_gap_s,
        custody: custody(ds, out, ingest_report, w.sha256)?,
    })
}

/// `--calibration vendor`: each accelerometer's `vendor_calibration` from the survey's own
/// manifest (docs/formats.md 11.1), not a fit.
pub const VENDOR: &str = "vendor";

/// The survey's accelerometers with the calibrations their makers state; refused when one
/// states none, or a model or session is asked for (a stated calibration has neither).
fn vendor_selection(ds: &Dataset, choice: &Choice<'_>) -> Result<Selection, String> {
    if let Some(m) = choice.model {
        return Err(format!(
            "--model {m}: the makers' stated calibrations (--calibration {VENDOR}) are one each"
        ));
    }
    if let Some(s) = choice.session {
        return Err(format!(
            "--session {s}: the makers' stated calibrations (--calibration {VENDOR}) hold for \
             every session"
        ));
    }
    let targets = ds
        .manifest
        .instrument
        .accelerometer
        .iter()
        .map(|acc| {
            let v = acc.vendor_calibration.as_ref().ok_or_else(|| {
                format!(
                    "accelerometer `{}` states no vendor_calibration in dataset.toml: give its \
                     maker's scale and offset_mgal, or apply a fitted calibration.json",
                    acc.id
                )
            })?;
            Ok(Target {
                accelerometer: acc.clone(),
                function: Ok(CalibrationFunction::vendor(v)),
                counts_range: None,
                temperature_range_c: None,
            })
        })
        .collect::<Result<_, String>>()?;
    Ok(Selection {
        model: VENDOR.to_owned(),
        session: ingest::contract::calibration::ALL_SESSIONS.to_owned(),
        targets,
    })
}

/// Reads and checks calibration.json; returns it and its SHA-256.
fn load_calibration(path: &Path) -> Result<(Calibration, String), Error> {
    let cal: Calibration = ingest::read_json(path)?;
    if cal.format != CALIBRATION_FORMAT {
        return Err(Error::Apply {
            path: path.to_path_buf(),
            message: format!(
                "format `{}`, expected `{CALIBRATION_FORMAT}`: not a gravcal calibration",
                cal.format
            ),
        });
    }
    Ok((cal, sha256_file(path)?))
}

/// The files read (the manifest; ingest's ledger and the two tables, with the hashes its
/// ledger recorded and `load_verified` has just checked) and the table written, with the
/// hash its writer took as it wrote.
fn custody(
    ds: &Dataset,
    out: &Path,
    ingest_report: &IngestReport,
    table_sha256: String,
) -> Result<Custody, Error> {
    let folders = Folders {
        dataset: &ds.dir,
        out,
    };
    let mut inputs = vec![
        folders.record(Root::Dataset, ingest_ledger::MANIFEST_FILE)?,
        folders.record(
            Root::Out,
            &format!(
                "{}/{}",
                ingest_ledger::STAGE_DIR,
                ingest_ledger::LEDGER_FILE
            ),
        )?,
    ];
    let tables = [
        tables::acceleration::FILE,
        tables::temperature::FILE,
        tables::lab::FILE,
    ]
    .map(|t| format!("{}/{t}", ingest_ledger::STAGE_DIR));
    inputs.extend(
        ingest_report
            .custody
            .outputs
            .iter()
            .filter(|f| tables.contains(&f.path))
            .cloned(),
    );
    let outputs = vec![FileHash {
        root: Root::Out,
        path: format!("{STAGE_DIR}/{}", applied::FILE),
        sha256: table_sha256,
    }];
    Ok(Custody { inputs, outputs })
}

/// Streams ingest's acceleration table through the calibration into the applied table;
/// returns the rows and each accelerometer's counts.
fn write_table<'t>(
    ds: &Dataset,
    ingest_dir: &Path,
    dir: &Path,
    selection: &'t Selection,
    temperatures: &'t Temperatures,
    max_gap_ns: i64,
) -> Result<Written<'t>, Error> {
    let sessions: Vec<String> = ds.sessions.iter().map(|s| s.session.id.clone()).collect();
    let ids: Vec<String> = selection
        .targets
        .iter()
        .map(|t| t.accelerometer.id.clone())
        .collect();
    let mut writer = applied::writer(dir, &sessions, &ids)?;
    let mut lanes: Vec<Lane<'t>> = selection
        .targets
        .iter()
        .map(|t| Lane::new(t, temperatures, sessions.len()))
        .collect();
    let mut rows = 0u64;
    // The writer encodes and writes a row group on its own thread while the next one is
    // read and calibrated.
    let (tx, rx) = std::sync::mpsc::sync_channel::<applied::RowGroup>(1);
    let (reading, writing) = std::thread::scope(|scope| {
        let writing = scope.spawn(move || -> Result<(u64, String), ingest::Error> {
            for group in rx {
                writer.write(group)?;
            }
            writer.finish_hashed()
        });
        let table = dir.join(applied::FILE);
        let mut send = Sender {
            rows: &mut rows,
            lanes: &mut lanes,
            tx: &tx,
            max_gap_ns,
            table: &table,
        };
        // The counts table, then the lab table (a survey logged as a lab stream).
        let reading =
            tables::acceleration::batches(ingest_dir, STREAM_ROWS_PER_GROUP, |b| send.batch(&b))
                .and_then(|()| {
                    tables::lab::batches(ingest_dir, STREAM_ROWS_PER_GROUP, |b| send.batch(&b))
                });
        drop(tx);
        (reading, writing.join())
    });
    let (_, sha256) = match writing {
        Ok(written) => written?,
        Err(_) => {
            return Err(ingest::Error::io(
                dir.join(applied::FILE),
                std::io::Error::other("the writer thread panicked"),
            )
            .into());
        }
    };
    reading?;
    Ok(Written {
        rows,
        sha256,
        lanes,
    })
}

/// Calibrates batches and hands them to the writer thread.
struct Sender<'a, 't> {
    rows: &'a mut u64,
    lanes: &'a mut [Lane<'t>],
    tx: &'a std::sync::mpsc::SyncSender<applied::RowGroup>,
    max_gap_ns: i64,
    table: &'a Path,
}

impl Sender<'_, '_> {
    /// One batch: its columns calibrated, each accelerometer on its own rayon task.
    fn batch<B: SampleBatch>(&mut self, b: &B) -> Result<(), align::Error> {
        let n = b.session().len();
        *self.rows += n as u64;
        let max_gap_ns = self.max_gap_ns;
        let accelerometers = self
            .lanes
            .par_iter_mut()
            .map(|lane| lane.calibrate(b, max_gap_ns))
            .collect();
        let group = applied::RowGroup {
            session_index: b.session().iter().map(|&s| i32::from(s)).collect(),
            time_gps_ns: b.time_ns().to_vec(),
            accelerometers,
        };
        // A closed channel means the writer failed: reading stops, and the writer's error
        // is the one reported.
        self.tx.send(group).map_err(|_| align::Error::Table {
            path: self.table.to_path_buf(),
            message: "the writer stopped".to_owned(),
        })
    }
}

/// What the table's writing gave: rows, the table's SHA-256, each accelerometer's counts.
struct Written<'t> {
    rows: u64,
    sha256: String,
    lanes: Vec<Lane<'t>>,
}

/// A batch of samples as apply reads them: the counts table's or the lab table's.
trait SampleBatch: Sync {
    /// Session index per row.
    fn session(&self) -> &[u16];
    /// GPS time per row, ns.
    fn time_ns(&self) -> &[i64];
    /// Channel `ch`'s (0-based) reading at row `i`, or the flag saying why there is none.
    fn reading(&self, ch: usize, i: usize) -> Result<f64, u8>;
}

impl SampleBatch for tables::acceleration::Batch<'_> {
    fn session(&self) -> &[u16] {
        self.session
    }
    fn time_ns(&self) -> &[i64] {
        self.time_ns
    }
    fn reading(&self, ch: usize, i: usize) -> Result<f64, u8> {
        let (st, counts) = (self.status[i], self.counts[ch]);
        if status::not_connected(st, ch) {
            Err(applied::NOT_CONNECTED)
        } else if status::over_range(st, ch) {
            Err(applied::SATURATED)
        } else if !counts.is_valid(i) {
            Err(applied::NOT_CONNECTED)
        } else {
            Ok(f64::from(counts.value(i)))
        }
    }
}

impl SampleBatch for tables::lab::Batch<'_> {
    fn session(&self) -> &[u16] {
        self.session
    }
    fn time_ns(&self) -> &[i64] {
        self.time_ns
    }
    /// A lab stream's `nan` is a channel without a reading.
    fn reading(&self, ch: usize, i: usize) -> Result<f64, u8> {
        let v = self.values[ch];
        if v.is_valid(i) {
            Ok(v.value(i))
        } else {
            Err(applied::NOT_CONNECTED)
        }
    }
}

/// One accelerometer's way through the stream: its function, its temperature series per
/// session, and what it has counted.
struct Lane<'t> {
    /// Channel, 0-based.
    channel: usize,
    /// Its id, which names its four columns in the applied table ([`applied::columns`]).
    id: String,
    function: Option<&'t CalibrationFunction>,
    /// Per session index: the interpolator over its temperature series.
    temperatures: Vec<Option<Interpolator<'t>>>,
    with_value: u64,
    /// Samples by their flags byte.
    by_flags: [u64; 256],
}

impl<'t> Lane<'t> {
    fn new(target: &'t Target, temperatures: &'t Temperatures, sessions: usize) -> Self {
        let channel = target.accelerometer.channel;
        Lane {
            channel: usize::from(channel).saturating_sub(1),
            id: target.accelerometer.id.clone(),
            function: target.function.as_ref().ok(),
            temperatures: (0..sessions)
                .map(|s| {
                    let s = u16::try_from(s).ok()?;
                    let (t, v) = temperatures.get(&(s, channel))?;
                    Some(Interpolator::new(t, v))
                })
                .collect(),
            with_value: 0,
            by_flags: [0; 256],
        }
    }

    /// The calibration function at one sample: (acceleration, sigma, temperature), flags.
    fn sample<B: SampleBatch>(
        &mut self,
        b: &B,
        i: usize,
        max_gap_ns: i64,
    ) -> (Option<(f64, f64)>, Option<f64>, u8) {
        let temperature = self
            .temperatures
            .get_mut(usize::from(b.session()[i]))
            .and_then(Option::as_mut)
            .and_then(|it| it.at(b.time_ns()[i], max_gap_ns))
            .map(|(v, _)| v);
        let reading = match b.reading(self.channel, i) {
            Ok(x) => x,
            Err(flag) => return (None, temperature, flag),
        };
        let Some(f) = self.function else {
            return (None, temperature, applied::NOT_CALIBRATED);
        };
        let a = f.apply(reading, temperature);
        (a.acceleration_mgal.zip(a.sigma_mgal), temperature, a.flags)
    }

    /// Its four columns for one batch: acceleration, sigma, temperature, flags.
    fn calibrate<B: SampleBatch>(&mut self, b: &B, max_gap_ns: i64) -> applied::Accelerometer {
        let n = b.session().len();
        let (mut acc, mut sigma, mut temp) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        let (mut acc_def, mut temp_def) = (Vec::with_capacity(n), Vec::with_capacity(n));
        let mut flags = Vec::with_capacity(n);
        for i in 0..n {
            let (value, temperature, f) = self.sample(b, i, max_gap_ns);
            if let Some((a, s)) = value {
                acc.push(a);
                sigma.push(s);
                self.with_value += 1;
            }
            acc_def.push(i16::from(value.is_some()));
            if let Some(t) = temperature {
                temp.push(t);
            }
            temp_def.push(i16::from(temperature.is_some()));
            self.by_flags[usize::from(f)] += 1;
            flags.push(i32::from(f));
        }
        let levels = |values: &Vec<f64>, def: Vec<i16>| (values.len() < n).then_some(def);
        let acc_levels = levels(&acc, acc_def);
        let temp_levels = levels(&temp, temp_def);
        applied::Accelerometer {
            id: self.id.clone(),
            acceleration_mgal: (acc, acc_levels.clone()),
            sigma_mgal: (sigma, acc_levels),
            temperature_c: (temp, temp_levels),
            flags,
        }
    }

    /// What apply.json says of this accelerometer.
    fn ledger(&self, target: &Target) -> AppliedAccelerometer {
        AppliedAccelerometer {
            id: target.accelerometer.id.clone(),
            channel: target.accelerometer.channel,
            serial: target.accelerometer.serial.clone(),
            not_calibrated: target.function.as_ref().err().cloned(),
            counts_range: target.counts_range,
            temperature_range_c: target.temperature_range_c,
            with_value: self.with_value,
            flagged: flag_counts(&self.by_flags),
        }
    }
}

/// The command line of `cargo xtask apply` and of `gravcal-apply`.
#[derive(clap::Args, Clone, Debug)]
pub struct ApplyArgs {
    /// Dataset folder holding the survey (dataset.toml and its logs).
    pub dataset: std::path::PathBuf,
    /// The calibration.json to apply (OUT/adjust/calibration.json of the calibration run),
    /// or `vendor`: the makers' stated scale and offset in the survey's dataset.toml
    /// (`vendor_calibration`; a file named so is given as ./vendor).
    #[arg(long)]
    pub calibration: std::path::PathBuf,
    /// The model to apply (needed when the calibration holds several).
    #[arg(long)]
    pub model: Option<String>,
    /// The session whose fits to apply, for a model fitted per session.
    #[arg(long)]
    pub session: Option<String>,
    /// Output folder OUT (default: out/<dataset folder name>); apply writes OUT/apply/,
    /// gravity also OUT/gravity/.
    #[arg(long)]
    pub out: Option<std::path::PathBuf>,
}

impl ApplyArgs {
    /// OUT: `--out`, or out/<dataset folder name> under `root`.
    pub fn out_dir(&self, root: &Path) -> std::path::PathBuf {
        ingest::base::cli::out_dir(root, &self.dataset, self.out.as_deref())
    }

    /// Runs the stage with these arguments.
    pub fn run(&self, root: &Path) -> Result<ApplyReport, Error> {
        run(&self.dataset, &self.out_dir(root), &self.options())
    }

    /// The calibration and the choice among its fits.
    pub fn options(&self) -> Options<'_> {
        Options {
            calibration: &self.calibration,
            choice: Choice {
                model: self.model.as_deref(),
                session: self.session.as_deref(),
            },
        }
    }
}

/// A few lines: the calibration applied, rows, and per accelerometer values and flags.
pub fn print_summary(r: &ApplyReport, w: &mut impl std::io::Write) {
    let c = &r.calibration;
    let _ = writeln!(
        w,
        "apply: model {} ({}) of {} (sha256 {}), {} rows read, {} written",
        c.model,
        c.session,
        c.dataset,
        &c.sha256[..c.sha256.len().min(12)],
        r.rows_read,
        r.rows_written
    );
    for a in &r.accelerometers {
        let flags: Vec<String> = a.flagged.iter().map(|(k, n)| format!("{n} {k}")).collect();
        let _ = writeln!(
            w,
            "apply: {}: {} with a value{}{}",
            a.id,
            a.with_value,
            if flags.is_empty() {
                String::new()
            } else {
                format!("; flagged: {}", flags.join(", "))
            },
            a.not_calibrated
                .as_deref()
                .map(|why| format!(" (not calibrated: {why})"))
                .unwrap_or_default()
        );
    }
}
