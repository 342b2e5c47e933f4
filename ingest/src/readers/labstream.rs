//! Reader of lab loggers' streams in the "seconds" layout (docs/formats.md 8.3), imu_tk's ASCII
//! layout among them: one sample a line, a time in seconds (since the session's `start`, or
//! Unix), then one decimal reading a channel, separated by commas or any white space, with
//! an optional header line and `#` comments.
//!
//! What real lab files do, and what is done about it:
//! - Times printed coarser than the sample interval (10 ms stamps at 200 Hz: consecutive
//!   samples share a stamp). Every sample is kept: a run of samples sharing a stamp is
//!   spread evenly up to the next stamp (the last run at the declared interval), and the
//!   ledger counts them and gives the stamps' step.
//! - Scientific notation (`9.80665e+00`): read, and counted.
//! - No header, or one: a first line whose time field is not a number is the header.
//! - A time going back is rejected alone (`time_backwards`), as is a time outside the
//!   session; a malformed line is an error naming file, line and field (or, with
//!   skip-bad-lines, counted). `nan` for a reading is stored as null (counted by channel).
//!
//! Times are read exactly from their decimal digits (a Unix time with microseconds has 16
//! significant digits, more than an f64 holds); only scientific notation goes through f64.

use crate::base::time::parse_seconds_ns;
use crate::base::timegate::{Position, Sink, TimeGate};
use crate::contract::ingest_ledger::{FileLedger, LabStreamReport, reason};
use crate::contract::manifest::{AdcFormat, MAX_VALUE_COLUMNS, ValueColumns};
use crate::contract::tables;
use crate::contract::tables::GroupWriter;
use crate::error::{Error, Result};
use crate::parquet_io::rowgroup::{N, Spare, column, nullable, session_values, whole};
use crate::parquet_io::table::{ColumnValues, Written};
use crate::readers::lines::{POWERS_OF_TEN, digits, read_lines, strip_comment, text};
use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::sync::mpsc::{Receiver, Sender, SyncSender, channel, sync_channel};
use std::thread::JoinHandle;

/// `lab.parquet`, written a row group at a time on a thread of its own (the readings'
/// encoding and compression), while the caller parses the next lines. The row group's
/// columns are arrays filled in place, as the acceleration table's are (`streams`), their
/// buffers coming back from the writer for the next row groups.
pub struct LabWriter {
    to_writer: Option<SyncSender<ToWriter>>,
    writer: Option<JoinHandle<Result<Written>>>,
    spent: Receiver<Vec<ColumnValues>>,
    spare: Spare,
    rows: LabColumns,
}

/// Rows of the lab table not yet handed to the writer, all of one session: each reading's
/// value (0 where null) and, per row, which readings are null (bit `k` for channel `k + 1`),
/// worked into definition levels per row group only where a row group has a null.
struct LabColumns {
    len: usize,
    session: u16,
    time: Box<[i64; N]>,
    values: [Box<[f64; N]>; 3],
    nulls: Box<[u8; N]>,
    line: Box<[i64; N]>,
}

/// What the lab table's writer thread is told.
enum ToWriter {
    /// A row group (boxed: the message is a few pointers either way).
    RowGroup(Box<tables::lab::RowGroup>),
    /// Close the table and rename it into place.
    Finish,
}

/// The writer thread: writes row groups until told to finish, and hands their buffers back.
/// If the sender goes away without `Finish` (a run that failed), the table is dropped and
/// its partial file removed.
fn write_lab(
    mut table: GroupWriter<tables::lab::RowGroup>,
    rx: Receiver<ToWriter>,
    spent: Sender<Vec<ColumnValues>>,
) -> Result<Written> {
    for message in rx {
        match message {
            ToWriter::RowGroup(group) => {
                let buffers = table.write(*group)?;
                // The reader may have gone; then the buffers are simply freed.
                let _ = spent.send(buffers);
            }
            ToWriter::Finish => return table.finish_hashed(),
        }
    }
    Err(Error::io(
        Path::new(tables::lab::FILE),
        std::io::Error::other("ingest stopped before the lab table was complete"),
    ))
}

impl LabWriter {
    /// Starts the table in `dir` for the dataset's `sessions`.
    pub fn create(dir: &Path, sessions: &[String]) -> Result<Self> {
        let table = tables::lab::writer(dir, sessions)?;
        // Two row groups queued keep both threads busy.
        let (to_writer, rx) = sync_channel(2);
        let (spent_tx, spent) = channel();
        // The table is renamed into place only when told to finish: a run that fails, or
        // drops the writer, leaves no lab.parquet behind (the partial file is removed).
        let writer = std::thread::Builder::new()
            .name("lab-writer".to_owned())
            .spawn(move || write_lab(table, rx, spent_tx))
            .map_err(|e| Error::io(dir, e))?;
        Ok(LabWriter {
            to_writer: Some(to_writer),
            writer: Some(writer),
            spent,
            spare: Spare::default(),
            rows: LabColumns {
                len: 0,
                session: 0,
                time: whole(Vec::new()),
                values: std::array::from_fn(|_| whole(Vec::new())),
                nulls: whole(Vec::new()),
                line: whole(Vec::new()),
            },
        })
    }

    /// Rows that follow belong to the session at `index` in the manifest.
    fn start_session(&mut self, index: u16) -> Result<()> {
        self.flush()?;
        self.rows.session = index;
        Ok(())
    }

    /// One row: a sample at `time_ns`.
    #[inline(always)]
    fn push(&mut self, time_ns: i64, sample: &Sample) -> Result<()> {
        let r = &mut self.rows;
        // Below N: the row group is handed on as soon as it is full.
        let i = r.len;
        r.time[i] = time_ns;
        for (column, &value) in r.values.iter_mut().zip(&sample.readings.values) {
            column[i] = value;
        }
        r.nulls[i] = sample.readings.nulls;
        // A line number is far below 2^63.
        r.line[i] = sample.line as i64;
        r.len = i + 1;
        if r.len >= N {
            self.flush()?;
        }
        Ok(())
    }

    /// Hands the buffered rows to the writer as a row group.
    #[inline(never)]
    fn flush(&mut self) -> Result<()> {
        let n = self.rows.len;
        if n == 0 {
            return Ok(());
        }
        for columns in self.spent.try_iter() {
            self.spare.keep(columns);
        }
        let (spare, rows) = (&mut self.spare, &mut self.rows);
        let time = column(std::mem::replace(&mut rows.time, whole(spare.int64())), n);
        let line = column(std::mem::replace(&mut rows.line, whole(spare.int64())), n);
        let nulls = &rows.nulls[..n];
        // Nearly always no reading of a row group is null: nothing to look at per row.
        let any_null = nulls.iter().fold(0u8, |a, &s| a | s);
        let values = std::array::from_fn(|ch| {
            let values = column(
                std::mem::replace(&mut rows.values[ch], whole(spare.double())),
                n,
            );
            let bit = 1u8 << ch;
            if any_null & bit == 0 {
                (values, None)
            } else {
                let valid: Vec<bool> = nulls.iter().map(|&s| s & bit == 0).collect();
                nullable(values, &valid)
            }
        });
        let group = tables::lab::RowGroup {
            session_index: session_values(rows.session, n, spare.int32()),
            time_gps_ns: time,
            channels: values,
            last: line,
        };
        rows.len = 0;
        let sent = self
            .to_writer
            .as_ref()
            .map(|w| w.send(ToWriter::RowGroup(Box::new(group))));
        if !matches!(sent, Some(Ok(()))) {
            // The writer stopped: its error says why.
            return self.join().map(|_| ());
        }
        Ok(())
    }

    /// Closes the channel and waits for the writer: the rows it wrote, or its error.
    fn join(&mut self) -> Result<Written> {
        self.to_writer = None;
        match self.writer.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err(Error::io(
                Path::new(tables::lab::FILE),
                std::io::Error::other("the lab table's writer thread panicked"),
            )),
            None => Err(Error::io(
                Path::new(tables::lab::FILE),
                std::io::Error::other("the lab table's writer had already stopped"),
            )),
        }
    }

    /// Writes what is buffered and closes the table; returns its rows and SHA-256.
    pub fn finish(mut self) -> Result<Written> {
        self.flush()?;
        if let Some(w) = &self.to_writer {
            // A failed send means the writer stopped; join says why.
            let _ = w.send(ToWriter::Finish);
        }
        self.join()
    }
}

impl Drop for LabWriter {
    fn drop(&mut self) {
        // Dropped without `finish` (a run that failed): closing the channel makes the writer
        // discard its partial table, and waiting for it means the file is gone when the
        // caller returns, not some time later.
        self.to_writer = None;
        if let Some(h) = self.writer.take() {
            let _ = h.join();
        }
    }
}

/// How to read one stream.
#[derive(Clone, Copy, Debug)]
pub struct LabConfig {
    /// The session's index in the manifest.
    pub session: u16,
    /// GPS time of the stream's time 0, ns.
    pub zero_gps_ns: i64,
    /// Declared sample interval, ns.
    pub interval_ns: i64,
    /// The session's range of GPS time, ns.
    pub range_ns: (i64, i64),
    /// Count and list malformed lines instead of failing.
    pub skip_bad_lines: bool,
    /// What the instrument, in its declared reading unit, can produce.
    pub reading_limits: Limits,
    /// Which channels the file's value columns hold (docs/formats.md 9.4).
    pub columns: ValueColumns,
    /// The stream's layout: "seconds" or a platform meter's file.
    pub layout: AdcFormat,
    /// The scale of a logger's stamps without a zone (a meter's serial output).
    pub time_scale: crate::contract::manifest::TimeScale,
}

/// A field that does not parse: (field name, message).
type Bad = (&'static str, String);

/// Powers of ten a double holds exactly.
const EXACT_POWERS: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// A plain decimal (sign, digits, a point, digits, an exponent) whose significant digits
/// fit in 2^53 and whose power of ten is within 10^22, read as its exact integer times or
/// over an exact power of ten: one correctly rounded operation, the double `str::parse`
/// gives (Clinger's fast path), and whether it had an exponent. None for anything else
/// (more digits, `nan`, malformed), which `str::parse` then reads or rejects.
pub(crate) fn fast_decimal(field: &[u8]) -> Option<(f64, bool)> {
    plain_decimal(field).or_else(|| general_decimal(field))
}

/// [`fast_decimal`] of the common field, `[-+]digits[.digits]` (no exponent), in a loop
/// without [`general_decimal`]'s states: the same mantissa (refused at 16 significant
/// digits, as there) over the same power of ten, so the same double. None for any other
/// field, which [`general_decimal`] then reads.
#[inline]
fn plain_decimal(field: &[u8]) -> Option<(f64, bool)> {
    const LIMIT: u64 = 1_000_000_000_000_000; // 16 significant digits
    let (negative, rest) = match field.first()? {
        b'-' => (true, &field[1..]),
        b'+' => (false, &field[1..]),
        _ => (false, field),
    };
    let (whole, fraction) = match rest.iter().position(|&c| c == b'.') {
        Some(p) => (&rest[..p], &rest[p + 1..]),
        None => (rest, &[][..]),
    };
    if whole.len() + fraction.len() == 0 {
        return None;
    }
    // Fifteen digits or fewer cannot reach the limit: no check per digit.
    let short = whole.len() + fraction.len() <= 15;
    let mut mantissa = 0u64;
    for &c in whole.iter().chain(fraction) {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        mantissa = mantissa * 10 + u64::from(d);
        if !short && mantissa >= LIMIT {
            return None;
        }
    }
    let m = mantissa as f64;
    let v = m / *EXACT_POWERS.get(fraction.len())?;
    Some((if negative { -v } else { v }, false))
}

/// [`fast_decimal`] of any field it reads (an exponent included).
fn general_decimal(field: &[u8]) -> Option<(f64, bool)> {
    let (negative, mut rest) = match field.first()? {
        b'-' => (true, &field[1..]),
        b'+' => (false, &field[1..]),
        _ => (false, field),
    };
    let (mut mantissa, mut digits, mut exponent) = (0u64, 0u32, 0i32);
    let mut seen_digit = false;
    let mut scientific = false;
    let mut in_fraction = false;
    while let Some((&c, tail)) = rest.split_first() {
        match c {
            b'0'..=b'9' => {
                seen_digit = true;
                if mantissa != 0 || c != b'0' {
                    digits += 1;
                    if digits > 15 {
                        return None;
                    }
                }
                mantissa = mantissa * 10 + u64::from(c - b'0');
                exponent -= i32::from(in_fraction);
            }
            b'.' if !in_fraction => in_fraction = true,
            b'e' | b'E' if seen_digit => {
                let e: i32 = std::str::from_utf8(tail).ok()?.parse().ok()?;
                exponent = exponent.checked_add(e)?;
                scientific = true;
                rest = &[];
                break;
            }
            _ => return None,
        }
        rest = tail;
    }
    if !seen_digit || !rest.is_empty() {
        return None;
    }
    let m = mantissa as f64;
    let power = *EXACT_POWERS.get(exponent.unsigned_abs() as usize)?;
    let v = if exponent >= 0 { m * power } else { m / power };
    Some((if negative { -v } else { v }, scientific))
}

/// The common data line in one pass: a time `seconds[.fraction]` (at most 10 and 9 digits),
/// then `width` (1 to 3) plain decimals (a `-`, digits, a `.` and digits, 15 digits at most), each
/// after one comma, space or tab, and nothing else. Returns the time since zero (ns), the
/// readings and where the time field ends. What it reads is what [`parse_line`] reads from
/// the same line, bit for bit (the readings are Clinger's exact case of `str::parse`);
/// None sends the line there, which also says what is wrong with it.
#[inline]
fn fast_line(line: &[u8], columns: &ValueColumns) -> Option<(i64, [f64; 3], usize)> {
    let mut p = 0;
    let mut ns = digits(line, &mut p, 10)?.checked_mul(1_000_000_000)?;
    if line.get(p) == Some(&b'.') {
        p += 1;
        let start = p;
        let frac = digits(line, &mut p, 9)?;
        ns = ns.checked_add(frac * POWERS_OF_TEN[9 - (p - start)])?;
    }
    let time_end = p;
    let mut values = [0.0; 3];
    for k in 0..columns.width {
        if !matches!(line.get(p), Some(b',' | b' ' | b'\t')) {
            return None;
        }
        p += 1;
        let feeds = columns.feeds(k);
        if feeds == 0 {
            // A column no channel reads: skipped to the next separator.
            p += line[p..]
                .iter()
                .position(|c| matches!(c, b',' | b' ' | b'\t'))
                .unwrap_or(line.len() - p);
            continue;
        }
        let negative = line.get(p) == Some(&b'-');
        p += usize::from(negative);
        let start = p;
        let mut mantissa = digits(line, &mut p, 15)?;
        let mut decimals = 0;
        if line.get(p) == Some(&b'.') {
            p += 1;
            let frac_start = p;
            let frac = digits(line, &mut p, 15 - (frac_start - 1 - start))?;
            decimals = p - frac_start;
            mantissa = mantissa * POWERS_OF_TEN[decimals] + frac;
        }
        // A whole number (counts) needs no division, the slowest step of the line.
        let v = if decimals == 0 {
            mantissa as f64
        } else {
            mantissa as f64 / EXACT_POWERS[decimals]
        };
        ValueColumns::place(feeds, &mut values, if negative { -v } else { v });
    }
    (p == line.len()).then_some((ns, values, time_end))
}

/// One data line of a time and `width` (1 to 3) values, `names` the time's and the value
/// columns': (time since zero ns, readings by column, values in scientific notation).
fn parse_line(
    fields: &[&[u8]],
    names: [&'static str; 4],
    columns: &ValueColumns,
) -> std::result::Result<(i64, [Option<f64>; 3], u64), Bad> {
    let expected = 1 + columns.width;
    let name = |k: usize| {
        if columns.feeds(k) == 0 {
            "skipped"
        } else {
            names[1 + columns.channel_of(k)]
        }
    };
    if fields.len() != expected {
        let n = if fields.len() > expected {
            format!("more than {expected}")
        } else {
            fields.len().to_string()
        };
        let all: Vec<&str> = std::iter::once(names[0])
            .chain((0..columns.width).map(name))
            .collect();
        return Err((
            "line",
            format!("{n} fields, expected {expected} ({})", all.join(" ")),
        ));
    }
    let time = parse_seconds_ns(fields[0]).ok_or_else(|| {
        (
            names[0],
            format!("`{}` is not a time in seconds", text(fields[0])),
        )
    })?;
    let mut values = [None; 3];
    let mut scientific = 0;
    for k in (0..columns.width).filter(|&k| columns.feeds(k) != 0) {
        let raw = fields[k + 1];
        let bad = |what: &str| (name(k), format!("`{}` is {what}", text(raw)));
        let (v, exponent) = match fast_decimal(raw) {
            Some(v) => v,
            None => (
                std::str::from_utf8(raw)
                    .ok()
                    .and_then(|f| f.parse::<f64>().ok())
                    .ok_or_else(|| bad("not a number"))?,
                raw.iter().any(|&b| b == b'e' || b == b'E'),
            ),
        };
        if v.is_nan() {
            continue;
        }
        if !v.is_finite() {
            return Err(bad("not finite"));
        }
        scientific += u64::from(exponent);
        ValueColumns::place(columns.feeds(k), &mut values, Some(v));
    }
    Ok((time, values, scientific))
}

/// A line's three readings: their values (0 where null) and which are null (bit `k` for
/// channel `k + 1`, a `nan` in the line).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Readings {
    values: [f64; 3],
    nulls: u8,
}

impl Readings {
    /// Readings none of which is null.
    fn all(values: [f64; 3]) -> Self {
        Readings { values, nulls: 0 }
    }

    fn from_options(readings: [Option<f64>; 3]) -> Self {
        let mut nulls = 0;
        for (k, r) in readings.iter().enumerate() {
            nulls |= u8::from(r.is_none()) << k;
        }
        Readings {
            values: readings.map(|r| r.unwrap_or(0.0)),
            nulls,
        }
    }

    fn options(self) -> [Option<f64>; 3] {
        std::array::from_fn(|k| (self.nulls >> k & 1 == 0).then_some(self.values[k]))
    }
}

/// A line's sample: its line number and readings.
#[derive(Clone, Copy, Debug)]
struct Sample {
    line: u64,
    readings: Readings,
}

/// A run of lines sharing one time stamp, as the time gate judges it (one record: the
/// stamps are what a lab logger writes; samples sharing one are spread once it is kept).
/// Its samples wait in [`RunSink::staged`].
#[derive(Clone, Copy, Debug)]
struct RunRef {
    /// The line of its first sample.
    first_line: u64,
    /// Its samples.
    len: usize,
}

/// The stream's side of the time gate: kept runs are spread and written, rejected ones
/// counted line by line.
struct RunSink<'a> {
    config: &'a LabConfig,
    out: &'a mut LabWriter,
    ledger: &'a mut FileLedger,
    /// The samples of the runs offered to the gate and not yet written, in line order:
    /// first the `pending` ones of the run kept last (waiting for the next kept stamp to
    /// spread them to), then those of the runs the gate holds. Flat memory: the gate holds
    /// a few runs at most.
    staged: VecDeque<Sample>,
    pending: usize,
    /// The stamp of the run kept last.
    pending_stamp: i64,
    accepted: u64,
    /// Samples whose stamp a sample before them had.
    shared: u64,
    /// Readings given as `nan`, by channel.
    nulls: [u64; 3],
    /// Intervals between consecutive written times, by length, of runs spread up to the
    /// next stamp (the last run, spread at the declared interval, measures nothing).
    intervals: Histogram,
    /// Steps between distinct kept stamps, by length.
    steps: Histogram,
    last_written: Option<i64>,
}

impl RunSink<'_> {
    /// Writes the pending run, its samples spread evenly from its stamp to `next` (or at
    /// the declared interval).
    #[inline(always)]
    fn write_pending(&mut self, next: Option<i64>) -> Result<()> {
        let n = self.pending;
        let stamp = self.pending_stamp;
        let step = match next {
            // One sample, the common case: no division.
            _ if n <= 1 => 0,
            Some(t) => (t - stamp) / n as i64,
            None => self.config.interval_ns,
        };
        for j in 0..n {
            let Some(sample) = self.staged.pop_front() else {
                break;
            };
            let t = stamp + j as i64 * step;
            if let Some(prev) = self.last_written
                && (next.is_some() || j == 0)
            {
                self.intervals.add(t - prev);
            }
            self.last_written = Some(t);
            let nulls = sample.readings.nulls;
            if nulls != 0 {
                for (k, count) in self.nulls.iter_mut().enumerate() {
                    *count += u64::from(nulls >> k & 1);
                }
            }
            self.out.push(t, &sample)?;
        }
        self.accepted += n as u64;
        self.pending = 0;
        Ok(())
    }

    /// Where `run`'s samples start in `staged`: right after the pending ones, since the
    /// gate decides runs in the order they were offered, except one outside the session,
    /// rejected at once (never offered here: [`Lines`] rejects those lines first), which
    /// is looked up by line.
    fn find(&self, run: RunRef) -> usize {
        let undecided = self.staged.range(self.pending..);
        self.pending + undecided.take_while(|s| s.line != run.first_line).count()
    }

    /// The null readings by channel, for the ledger.
    fn null_counts(&self) -> BTreeMap<String, u64> {
        (0..3)
            .filter(|&k| self.nulls[k] > 0 && self.config.columns.column_of[k].is_some())
            .map(|k| (format!("ch{} nan", k + 1), self.nulls[k]))
            .collect()
    }
}

impl Sink<RunRef> for RunSink<'_> {
    type Error = Error;

    #[inline(always)]
    fn accept(&mut self, time_ns: i64, run: RunRef) -> Result<()> {
        if self.pending > 0 {
            self.steps.add(time_ns - self.pending_stamp);
        }
        self.write_pending(Some(time_ns))?;
        debug_assert_eq!(self.find(run), 0, "runs are kept in the order offered");
        self.pending = run.len;
        self.pending_stamp = time_ns;
        Ok(())
    }

    fn reject(&mut self, _: Position, why: &'static str, detail: String, run: RunRef) {
        let at = self.find(run);
        // The stamp of the run kept last (a duplicate's time is the last kept one): more
        // samples sharing it, split from it by a line out of place between them.
        if why == reason::DUPLICATE && self.pending > 0 {
            debug_assert_eq!(
                at, self.pending,
                "the lines between were decided and removed"
            );
            self.shared += run.len as u64;
            self.pending += run.len;
            return;
        }
        // Every line of the run is rejected, each under its own line number.
        let end = (at + run.len).min(self.staged.len());
        for sample in self.staged.drain(at..end) {
            self.ledger
                .reject(format!("line {}", sample.line), why, detail.clone());
        }
    }
}

/// Counts by key: the intervals and steps of a stream. A run of equal keys (nearly every
/// sample of a logger's stream) is counted in place and added to the map once.
#[derive(Default)]
struct Histogram {
    map: BTreeMap<i64, u64>,
    run: Option<(i64, u64)>,
}

impl Histogram {
    fn add(&mut self, key: i64) {
        match &mut self.run {
            Some((k, n)) if *k == key => *n += 1,
            _ => {
                self.flush();
                self.run = Some((key, 1));
            }
        }
    }

    fn flush(&mut self) {
        if let Some((k, n)) = self.run.take() {
            *self.map.entry(k).or_default() += n;
        }
    }

    /// Every count, in the map.
    fn counts(mut self) -> BTreeMap<i64, u64> {
        self.flush();
        self.map
    }
}

/// The most common key of a histogram.
fn mode(h: &BTreeMap<i64, u64>) -> Option<i64> {
    h.iter().max_by_key(|(_, n)| **n).map(|(k, _)| *k)
}

/// The median key of a histogram.
fn median(h: &BTreeMap<i64, u64>) -> Option<i64> {
    let total: u64 = h.values().sum();
    let mut seen = 0;
    for (k, n) in h {
        seen += n;
        if 2 * seen >= total {
            return Some(*k);
        }
    }
    None
}

/// A data line: its GPS time (ns), its three values, and its time field as written.
type DataLine<'l> = (i64, Readings, &'l [u8]);

/// What a "seconds" file's lines showed before any row is kept: the line classifier both
/// the acceleration stream and a temperature log are read through.
struct Lines<'c> {
    path: &'c Path,
    /// Field names in error messages: the time, then the three channels.
    names: [&'static str; 4],
    /// Which channels the value columns hold.
    columns: ValueColumns,
    zero_gps_ns: i64,
    range_ns: (i64, i64),
    skip_bad_lines: bool,
    data_seen: bool,
    /// Comment, blank and header lines.
    other: u64,
    comma_separated: bool,
    header: bool,
    scientific: u64,
    /// The plausible range of a value, and the reason a line outside it is rejected for.
    limits: Limits,
    /// "seconds", or a platform meter's file (its time in the line).
    layout: AdcFormat,
    /// The scale of a logger's stamps without a zone.
    time_scale: crate::contract::manifest::TimeScale,
}

/// What values a file's lines may hold: outside, the line is rejected for `reason`.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Least plausible value.
    pub lo: f64,
    /// Greatest plausible value.
    pub hi: f64,
    /// The rejection reason.
    pub reason: &'static str,
    /// The values' unit, for the ledger.
    pub unit: &'static str,
}

/// Plausible temperatures, degC (every reader's).
pub const TEMPERATURE_LIMITS: Limits = Limits {
    lo: -100.0,
    hi: 200.0,
    reason: reason::TEMPERATURE_OUT_OF_RANGE,
    unit: "degC",
};

/// What the instrument can produce in its declared reading unit: counts within the ADC's
/// range, two's complement or offset binary (-2^(adc_bits - 1) to 2^adc_bits: an unsigned
/// 16-bit IMU's raw counts run from 0 to 65535); an acceleration (m/s^2, mGal, g) within
/// twice the declared full scale (the instrument saturates at its full scale: a reading
/// beyond twice it cannot be one of its own); volts within +/- 100 V (no accelerometer's
/// output is wider).
pub fn reading_limits(instrument: &crate::contract::manifest::Instrument) -> Limits {
    use crate::contract::manifest::ReadingUnit;
    let full_scale_g = 2.0 * instrument.full_scale_g;
    let bits = i32::try_from(instrument.adc_bits).unwrap_or(32);
    let (hi, unit) = match instrument.reading_unit {
        ReadingUnit::Count => {
            return Limits {
                lo: -(2f64.powi(bits - 1)),
                hi: 2f64.powi(bits),
                reason: reason::READING_OUT_OF_RANGE,
                unit: "counts",
            };
        }
        ReadingUnit::MetrePerSecond2 => (full_scale_g * 9.806_65, "m/s^2"),
        ReadingUnit::MilliGal => (full_scale_g * 980_665.0, "mGal"),
        ReadingUnit::StandardGravity => (full_scale_g, "g"),
        ReadingUnit::Volt => (100.0, "V"),
    };
    Limits {
        lo: -hi,
        hi,
        reason: reason::READING_OUT_OF_RANGE,
        unit,
    }
}

/// A DGS laptop line's GPS time, raw gravity (mGal) and the bytes of its calendar fields
/// (19 to 24), split by [`crate::readers::dgs::split`].
fn laptop_record(line: &[u8]) -> std::result::Result<(i64, f64, std::ops::Range<usize>), Bad> {
    let fields = crate::readers::dgs::split(line)?;
    let record = crate::readers::dgs::parse_laptop(&fields)?;
    // The fields are slices of `line`: their offsets in it.
    let at = |f: &[u8]| f.as_ptr() as usize - line.as_ptr() as usize;
    let calendar = at(fields[19])..at(fields[24]) + fields[24].len();
    Ok((record.gps_ns, record.raw_gravity_mgal, calendar))
}

impl<'c> Lines<'c> {
    fn new(path: &'c Path, names: [&'static str; 4], config: &LabConfig, limits: Limits) -> Self {
        let columns = config.columns;
        Lines {
            limits,
            path,
            names,
            columns,
            zero_gps_ns: config.zero_gps_ns,
            range_ns: config.range_ns,
            skip_bad_lines: config.skip_bad_lines,
            data_seen: false,
            other: 0,
            comma_separated: false,
            header: false,
            scientific: 0,
            layout: config.layout,
            time_scale: config.time_scale,
        }
    }

    /// A line that does not parse: with `--skip-bad-lines` a counted rejection, otherwise an
    /// error naming file, line and field.
    fn malformed<T>(
        &self,
        line_no: u64,
        (field, message): Bad,
        ledger: &mut FileLedger,
    ) -> Result<Option<T>> {
        if self.skip_bad_lines {
            ledger.reject(
                format!("line {line_no}"),
                reason::MALFORMED,
                format!("{field}: {message}"),
            );
            return Ok(None);
        }
        Err(Error::Line {
            path: self.path.to_path_buf(),
            line: line_no,
            field: field.to_owned(),
            message,
        })
    }

    /// A platform meter's line (a DGS laptop line, [`crate::readers::dgs`]; a BGM-3's or DGS's serial
    /// line as a logger writes it, [`crate::readers::meter_serial`]): its reading on channel 1,
    /// judged as any line; the time field in messages is the line's calendar fields or the
    /// logger's stamp.
    fn meter_data<'l>(
        &mut self,
        line_no: u64,
        raw: &'l [u8],
        ledger: &mut FileLedger,
    ) -> Result<Option<DataLine<'l>>> {
        let line = strip_comment(raw);
        if line.is_empty() {
            self.other += 1;
            return Ok(None);
        }
        self.data_seen = true;
        let scale = self.time_scale;
        let record = match self.layout {
            AdcFormat::DgsLaptop => {
                self.comma_separated = true;
                laptop_record(line)
            }
            AdcFormat::Bgm3 => crate::readers::meter_serial::parse_bgm3(line, scale)
                .map(|r| (r.gps_ns, r.reading, r.stamp)),
            _ => crate::readers::meter_serial::parse_dgs_raw(line, scale)
                .map(|r| (r.gps_ns, r.reading, r.stamp)),
        };
        let (gps_ns, reading, time_field) = match record {
            Ok(r) => r,
            Err(bad) => return self.malformed(line_no, bad, ledger),
        };
        let readings = Readings::from_options([Some(reading), None, None]);
        let rel = gps_ns - self.zero_gps_ns;
        Ok(self.judge(line_no, rel, readings, &line[time_field], ledger))
    }

    /// A data line's GPS time (ns), values and time field; None for a comment, blank or
    /// header line, or a line rejected into `ledger` (malformed when skipping, outside the
    /// session); an error for a malformed line otherwise.
    fn data<'l>(
        &mut self,
        line_no: u64,
        raw: &'l [u8],
        ledger: &mut FileLedger,
    ) -> Result<Option<DataLine<'l>>> {
        if self.layout.is_meter_file() {
            return self.meter_data(line_no, raw, ledger);
        }
        if self.data_seen
            && let Some((rel, values, time_end)) = fast_line(raw, &self.columns)
        {
            let readings = if self.columns == ValueColumns::EVERY_CHANNEL {
                Readings::all(values)
            } else {
                let column_of = self.columns.column_of;
                Readings::from_options(std::array::from_fn(|ch| column_of[ch].map(|_| values[ch])))
            };
            return Ok(self.judge(line_no, rel, readings, &raw[..time_end], ledger));
        }
        let line = strip_comment(raw);
        if line.is_empty() {
            self.other += 1;
            return Ok(None);
        }
        if !self.data_seen {
            self.comma_separated = line.contains(&b',');
        }
        // The fields without allocating (one more only to say there are too many).
        let mut buf: [&[u8]; 2 + MAX_VALUE_COLUMNS] = [&[]; 2 + MAX_VALUE_COLUMNS];
        let mut count = 0;
        for f in line
            .split(|&c| c == b',' || c.is_ascii_whitespace())
            .filter(|f| !f.is_empty())
        {
            if count < buf.len() {
                buf[count] = f;
            }
            count += 1;
        }
        let fields = &buf[..count.min(buf.len())];
        if !self.data_seen
            && fields
                .first()
                .is_some_and(|f| parse_seconds_ns(f).is_none())
        {
            self.header = true;
            self.other += 1;
            self.data_seen = true;
            return Ok(None);
        }
        self.data_seen = true;
        let (rel, values, scientific) = match parse_line(fields, self.names, &self.columns) {
            Ok(x) => x,
            Err(bad) => return self.malformed(line_no, bad, ledger),
        };
        self.scientific += scientific;
        let readings = Readings::from_options(values);
        Ok(self.judge(line_no, rel, readings, fields[0], ledger))
    }

    /// Rejects a line for its first reading outside the limits; whether there was one.
    #[cold]
    fn reject_reading(
        &self,
        line_no: u64,
        values: [Option<f64>; 3],
        ledger: &mut FileLedger,
    ) -> bool {
        let l = self.limits;
        let outside = (0..3).find_map(|k| {
            values[k]
                .filter(|v| !(l.lo..=l.hi).contains(v))
                .map(|v| (k, v))
        });
        if let Some((k, v)) = outside {
            ledger.reject(
                format!("line {line_no}"),
                l.reason,
                format!(
                    "{}: {v} {} is outside [{}, {}]",
                    self.names[k + 1],
                    l.unit,
                    l.lo,
                    l.hi
                ),
            );
        }
        outside.is_some()
    }

    /// A parsed line judged: its GPS time, readings and time field, or None when it is
    /// rejected into `ledger` (a reading outside the limits, a time outside the session).
    #[inline(always)]
    fn judge<'l>(
        &self,
        line_no: u64,
        rel: i64,
        readings: Readings,
        time_field: &'l [u8],
        ledger: &mut FileLedger,
    ) -> Option<DataLine<'l>> {
        let l = self.limits;
        // One test of all three on the common path; a null reading (stored as 0) is looked
        // at again, and passes, only off it.
        let within = |v: &f64| (l.lo..=l.hi).contains(v);
        if !readings.values.iter().fold(true, |all, v| all & within(v))
            && self.reject_reading(line_no, readings.options(), ledger)
        {
            return None;
        }
        let Some(t) = self.zero_gps_ns.checked_add(rel) else {
            ledger.reject(
                format!("line {line_no}"),
                reason::OUTSIDE_SESSION,
                "time beyond any GPS time".to_owned(),
            );
            return None;
        };
        if t < self.range_ns.0 || t >= self.range_ns.1 {
            ledger.reject(
                format!("line {line_no}"),
                reason::OUTSIDE_SESSION,
                format!(
                    "time {}{} is outside the session",
                    text(time_field),
                    match self.layout {
                        AdcFormat::DgsLaptop => " (UTC year, month, day, hour, minute, second)",
                        AdcFormat::DgsRaw | AdcFormat::Bgm3 => " (the logger's stamp)",
                        AdcFormat::Seconds | AdcFormat::Gps => " s",
                    }
                ),
            );
            return None;
        }
        Some((t, readings, time_field))
    }
}

/// Reads one "seconds" stream into `out`, filling in `ledger`; returns the median interval
/// between samples (ns) measured from stamps that move (None when no two do).
///
/// Each run of lines sharing a stamp passes the time gate ([`crate::base::timegate`]) as one
/// record, so a line stamped far ahead (or behind) of its neighbours is the one rejected,
/// never the lines after it.
pub fn read_lab(
    path: &Path,
    config: LabConfig,
    out: &mut LabWriter,
    ledger: &mut FileLedger,
    progress: &indicatif::ProgressBar,
) -> Result<Option<i64>> {
    out.start_session(config.session)?;
    let mut gate: TimeGate<RunRef> = TimeGate::new(config.interval_ns, config.range_ns);
    let mut lines = Lines::new(path, ["t", "x", "y", "z"], &config, config.reading_limits);
    let mut sink = RunSink {
        config: &config,
        out,
        ledger,
        staged: VecDeque::new(),
        pending: 0,
        pending_stamp: 0,
        accepted: 0,
        shared: 0,
        nulls: [0; 3],
        intervals: Histogram::default(),
        steps: Histogram::default(),
        last_written: None,
    };
    // The run being read: its stamp, and the run as the gate will be offered it.
    let mut open: Option<(i64, RunRef)> = None;
    let (sha, bytes) = read_lines(path, progress, |line_no, raw| {
        let Some((t, readings, _)) = lines.data(line_no, raw, sink.ledger)? else {
            return Ok(());
        };
        sink.staged.push_back(Sample {
            line: line_no,
            readings,
        });
        let next = RunRef {
            first_line: line_no,
            len: 1,
        };
        match &mut open {
            Some((stamp, run)) if *stamp == t => {
                run.len += 1;
                sink.shared += 1;
            }
            Some((stamp, run)) => {
                let (stamp, run) = (std::mem::replace(stamp, t), std::mem::replace(run, next));
                gate.offer(stamp, Position::Line(run.first_line), run, &mut sink)?;
            }
            None => open = Some((t, next)),
        }
        Ok(())
    })?;
    if let Some((stamp, run)) = open {
        gate.offer(stamp, Position::Line(run.first_line), run, &mut sink)?;
    }
    gate.finish(&mut sink)?;
    sink.write_pending(None)?;
    let null_values = sink.null_counts();
    let report = LabStreamReport {
        comma_separated: lines.comma_separated,
        header: lines.header,
        scientific_notation_values: lines.scientific,
        samples_sharing_a_stamp: sink.shared,
        stamp_step_ns: mode(&sink.steps.counts()),
        median_interval_ns: median(&sink.intervals.counts()),
    };
    let accepted = sink.accepted;
    ledger.sha256 = sha;
    ledger.bytes = bytes;
    ledger.accept("acceleration", accepted);
    ledger.comment_blank_or_header_lines = Some(lines.other);
    ledger.null_values = null_values;
    ledger.lab_stream = Some(report.clone());
    Ok(report.median_interval_ns)
}

/// The temperature log's side of the time gate: kept lines go to the temperature table.
struct TemperatureSink<'a> {
    streams: &'a mut crate::parquet_io::streams::StreamWriter,
    ledger: &'a mut FileLedger,
    intervals: Histogram,
    last: Option<i64>,
}

impl Sink<[Option<f64>; 3]> for TemperatureSink<'_> {
    type Error = Error;

    fn accept(&mut self, time_ns: i64, celsius: [Option<f64>; 3]) -> Result<()> {
        if let Some(prev) = self.last {
            self.intervals.add(time_ns - prev);
        }
        self.last = Some(time_ns);
        // A `nan` is a channel that gave no value: stored as null, counted by the writer.
        let status = (0..3)
            .filter(|&ch| celsius[ch].is_none())
            .fold(0u8, |s, ch| {
                s | crate::contract::status::not_connected_bit(ch)
            });
        self.streams.temperature(time_ns, celsius, status)
    }

    fn reject(&mut self, at: Position, why: &'static str, detail: String, _: [Option<f64>; 3]) {
        self.ledger.reject(at.to_string(), why, detail);
    }
}

/// Reads a "seconds" session's temperature log (`t T1 T2 T3`, degC, times as the session's
/// stream gives them) into the temperature table through `streams`, filling in `ledger`:
/// lines pass the time gate (a line out of place is the one rejected), temperatures
/// outside [-100, 200] degC are rejected, `nan` stored as null and counted. The log's
/// interval is its logger's, declared nowhere: the gate learns it ([`TimeGate::learning`]).
/// Returns the median interval between kept samples (ns).
pub fn read_lab_temperature(
    path: &Path,
    config: LabConfig,
    streams: &mut crate::parquet_io::streams::StreamWriter,
    ledger: &mut FileLedger,
    progress: &indicatif::ProgressBar,
) -> Result<Option<i64>> {
    let mut lines = Lines::new(path, ["t", "T1", "T2", "T3"], &config, TEMPERATURE_LIMITS);
    let mut gate = TimeGate::learning(config.range_ns);
    let mut sink = TemperatureSink {
        streams,
        ledger,
        intervals: Histogram::default(),
        last: None,
    };
    let (sha, bytes) = read_lines(path, progress, |line_no, raw| {
        let Some((t, readings, _)) = lines.data(line_no, raw, sink.ledger)? else {
            return Ok(());
        };
        let celsius = readings.options();
        gate.offer(t, Position::Line(line_no), celsius, &mut sink)
    })?;
    gate.finish(&mut sink)?;
    let null_values = sink.streams.take_null_counts()?;
    let intervals = sink.intervals;
    ledger.sha256 = sha;
    ledger.bytes = bytes;
    ledger.accept("temperature", gate.accepted());
    ledger.comment_blank_or_header_lines = Some(lines.other);
    ledger.null_values = null_values;
    Ok(median(&intervals.counts()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_are_read_exactly() {
        assert_eq!(parse_seconds_ns(b"0"), Some(0));
        assert_eq!(parse_seconds_ns(b"1.5"), Some(1_500_000_000));
        assert_eq!(parse_seconds_ns(b"-0.25"), Some(-250_000_000));
        assert_eq!(
            parse_seconds_ns(b"1672887159.123456"),
            Some(1_672_887_159_123_456_000)
        );
        assert_eq!(parse_seconds_ns(b".004"), Some(4_000_000));
        assert_eq!(parse_seconds_ns(b"1.5e-3"), Some(1_500_000));
        assert_eq!(parse_seconds_ns(b"12x"), None);
        assert_eq!(parse_seconds_ns(b"time"), None);
        assert_eq!(parse_seconds_ns(b"."), None);
    }

    const XYZ: [&str; 4] = ["t", "x", "y", "z"];

    /// A 64-bit linear congruential generator from `seed`, its top 53 bits a draw.
    fn lcg(seed: u64) -> impl FnMut() -> u64 {
        let mut state = seed;
        move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1442695040888963407);
            state >> 11
        }
    }

    /// The fast path gives str::parse's double, bit for bit, and leaves the rest to it.
    #[test]
    fn fast_decimals_are_str_parse_bit_for_bit() {
        let mut next = lcg(7);
        let mut cases: Vec<String> = [
            "0",
            "-0",
            "1449571.5",
            "-9.8",
            "9.806650000e+00",
            "+.5",
            "5.",
            "1e22",
            "1e-22",
            "123456789012345",
            "0.000000000000000000001",
            "-3.2E-5",
            "007.250",
        ]
        .iter()
        .map(|s| (*s).to_owned())
        .collect();
        for _ in 0..20_000 {
            let m = next() % 10u64.pow(1 + (next() % 15) as u32);
            let e = (next() % 31) as i32 - 15;
            let sign = if next().is_multiple_of(2) { "-" } else { "" };
            cases.push(format!("{sign}{m}e{e}"));
            let point = (next() % 16) as usize;
            let digits = m.to_string();
            let at = point.min(digits.len());
            cases.push(format!(
                "{sign}{}.{}",
                &digits[..digits.len() - at],
                &digits[digits.len() - at..]
            ));
        }
        for c in &cases {
            let want: f64 = c.parse().expect("parses");
            if let Some((got, exponent)) = fast_decimal(c.as_bytes()) {
                assert_eq!(got.to_bits(), want.to_bits(), "{c}");
                assert_eq!(exponent, c.contains(['e', 'E']), "{c}");
            }
        }
        let fast = cases
            .iter()
            .filter(|c| fast_decimal(c.as_bytes()).is_some())
            .count();
        assert!(fast > cases.len() * 9 / 10, "{fast} of {}", cases.len());
        for c in [
            "nan",
            "inf",
            "1.2.3",
            "e5",
            "-",
            "",
            "1e",
            "12x",
            "1234567890123456789",
        ] {
            assert_eq!(fast_decimal(c.as_bytes()), None, "{c}");
        }
    }

    /// The one-pass reader of a common line gives what the general parser gives from the
    /// same line, bit for bit, takes the lines a logger usually writes, and leaves every
    /// other line to the general parser.
    #[test]
    fn the_fast_line_agrees_with_the_general_parser() {
        let general = |line: &[u8]| {
            let fields: Vec<&[u8]> = line
                .split(|&c| c == b',' || c.is_ascii_whitespace())
                .filter(|f| !f.is_empty())
                .collect();
            parse_line(&fields, XYZ, &ValueColumns::EVERY_CHANNEL)
                .ok()
                .map(|(t, v, _)| (t, v))
        };
        let mut next = lcg(11);
        let mut lines: Vec<String> = Vec::new();
        for _ in 0..20_000 {
            let seconds = next() % 10u64.pow(1 + (next() % 10) as u32);
            let decimals = (next() % 10) as usize;
            let mut line = seconds.to_string();
            if decimals > 0 {
                line += &format!(".{:0w$}", next() % 10u64.pow(decimals as u32), w = decimals);
            }
            for _ in 0..3 {
                line.push([',', ' ', '\t'][(next() % 3) as usize]);
                let m = (next() % 10u64.pow(1 + (next() % 16) as u32)).to_string();
                let at = ((next() % 8) as usize).min(m.len() - 1);
                let sign = if next().is_multiple_of(2) { "-" } else { "" };
                if at == 0 {
                    line += &format!("{sign}{m}");
                } else {
                    line += &format!("{sign}{}.{}", &m[..m.len() - at], &m[m.len() - at..]);
                }
            }
            lines.push(line);
        }
        let mut taken = 0;
        for line in &lines {
            let Some(want) = general(line.as_bytes()) else {
                // A time beyond an i64 of ns.
                assert_eq!(
                    fast_line(line.as_bytes(), &ValueColumns::EVERY_CHANNEL),
                    None,
                    "{line}"
                );
                continue;
            };
            if let Some((t, values, end)) = fast_line(line.as_bytes(), &ValueColumns::EVERY_CHANNEL)
            {
                taken += 1;
                assert_eq!(t, want.0, "{line}");
                let bits = |v: [Option<f64>; 3]| v.map(|x| x.map(f64::to_bits));
                assert_eq!(bits(values.map(Some)), bits(want.1), "{line}");
                let time = line.split([',', ' ', '\t']).next().expect("time");
                assert_eq!(&line.as_bytes()[..end], time.as_bytes());
            }
        }
        // Readings of 16 digits and times past 2^63 ns go to the general parser.
        assert!(taken > lines.len() * 8 / 10, "{taken} of {}", lines.len());
        for line in [
            "0.004,1451608,1479836,1433175",
            "1672887159.123456 9.80665 -0.001 0.5",
            "12\t-0\t0.0\t-7.25",
        ] {
            assert!(
                fast_line(line.as_bytes(), &ValueColumns::EVERY_CHANNEL).is_some(),
                "{line}"
            );
        }
        for line in [
            "t,x,y,z",
            "0.004,1,2",
            "0.004,1,2,3,4",
            "0.004,1,2,3 ",
            " 0.004,1,2,3",
            "0.004,,1,2,3",
            "0.004, 1,2,3",
            "0.004,1,2,3 # note",
            "0.004,1,2,nan",
            "0.004,1,2,9.8e+00",
            "0.004,+1,2,3",
            "0.004,.5,2,3",
            "0.004,5.,2,3",
            ".004,1,2,3",
            "-0.004,1,2,3",
            "0.0041234567,1,2,3",
            "12345678901,1,2,3",
            "9300000000,1,2,3",
            "0.004,1234567890123456,2,3",
            "0.004,123456789.0123456,2,3",
        ] {
            assert_eq!(
                fast_line(line.as_bytes(), &ValueColumns::EVERY_CHANNEL),
                None,
                "{line}"
            );
        }
    }

    #[test]
    fn a_line_needs_a_time_and_three_readings() {
        let ok = parse_line(
            &[b"0.01", b"9.8e+00", b"-0.1", b"nan"],
            XYZ,
            &ValueColumns::EVERY_CHANNEL,
        )
        .expect("parses");
        assert_eq!(ok, (10_000_000, [Some(9.8), Some(-0.1), None], 1));
        assert_eq!(
            parse_line(&[b"0.01", b"1", b"2"], XYZ, &ValueColumns::EVERY_CHANNEL)
                .expect_err("3 fields")
                .0,
            "line"
        );
        assert_eq!(
            parse_line(
                &[b"0.01", b"1", b"x", b"2"],
                XYZ,
                &ValueColumns::EVERY_CHANNEL
            )
            .expect_err("x")
            .0,
            "y"
        );
    }
}
