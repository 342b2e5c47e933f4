//! Reader of the text acquisition logs (docs/formats.md section 4): the ADC CSV and the
//! temperature CSV, GPS time with the full week.
//!
//! A malformed line is an error naming the file, line and field, unless the user asked to
//! skip bad lines: then it is counted and listed. The CSV has no status column: an empty
//! field is a channel not connected, and a count at either end of the 24-bit range is taken
//! as over range (saturated).

use crate::base::time::NS_PER_WEEK;
use crate::base::time::{TimeForm, TimeReader};
use crate::base::timegate::{Position, Sink, TimeGate};
use crate::contract::ingest_ledger::{FileLedger, reason};
use crate::contract::manifest::{MAX_VALUE_COLUMNS, ValueColumns};
use crate::contract::status::{not_connected_bit, over_range_bit};
use crate::error::{Error, Result};
use crate::parquet_io::streams::StreamWriter;
use crate::readers::lines::{digits, read_lines, strip_comment, text};
use std::path::Path;

const COUNT_MIN: i64 = -8_388_608;
const COUNT_MAX: i64 = 8_388_607;
/// The last full GPS week a line may give (the year 2171): any later one is not a GPS week
/// of a real log, and its time in ns would not fit an i64 far beyond it. A week inside
/// this range but outside the session is rejected by the time gate instead.
const MAX_WEEK: i64 = 9_999;
/// Plausible temperatures, degC: every reader's ([`crate::readers::labstream::TEMPERATURE_LIMITS`]).
const CELSIUS_RANGE: std::ops::RangeInclusive<f64> = crate::readers::labstream::TEMPERATURE_LIMITS
    .lo
    ..=crate::readers::labstream::TEMPERATURE_LIMITS.hi;

/// Which of the two CSV logs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CsvKind {
    /// `gps_week,tow_s,c1,c2,c3`.
    Adc,
    /// `gps_week,tow_s,t1,t2,t3`.
    Temperature,
}

impl CsvKind {
    /// The name of a value column holding channel `ch` (0-based).
    fn value_name(self, ch: usize) -> &'static str {
        match self {
            CsvKind::Adc => ["c1", "c2", "c3"][ch],
            CsvKind::Temperature => ["t1", "t2", "t3"][ch],
        }
    }

    /// The name of value column `k` of `columns`: its first channel's, or `skipped`.
    fn column_name(self, columns: &ValueColumns, k: usize) -> &'static str {
        if columns.feeds(k) == 0 {
            "skipped"
        } else {
            self.value_name(columns.channel_of(k))
        }
    }

    /// The names of the value columns of `columns`.
    fn value_names(self, columns: &ValueColumns) -> Vec<&'static str> {
        (0..columns.width)
            .map(|k| self.column_name(columns, k))
            .collect()
    }

    /// The GPS week + tow header of a log laid out as `columns`.
    fn header(self, columns: &ValueColumns) -> Vec<&'static str> {
        let mut names = vec!["gps_week", "tow_s"];
        names.extend(self.value_names(columns));
        names
    }
}

struct Bad {
    field: &'static str,
    message: String,
}

fn bad(field: &'static str, message: impl Into<String>) -> Bad {
    Bad {
        field,
        message: message.into(),
    }
}

/// Parses a decimal `seconds[.fraction]` (up to 9 decimals) into exact nanoseconds.
fn parse_tow_ns(b: &[u8]) -> Option<i64> {
    let (int, frac) = match b.iter().position(|&c| c == b'.') {
        Some(i) => (&b[..i], &b[i + 1..]),
        None => (b, &b[..0]),
    };
    if int.is_empty()
        || int.len() > 6
        || frac.len() > 9
        || !int.iter().chain(frac).all(u8::is_ascii_digit)
    {
        return None;
    }
    if b.last() == Some(&b'.') {
        return None;
    }
    let mut s: i64 = 0;
    for &d in int {
        s = s * 10 + i64::from(d - b'0');
    }
    let mut ns: i64 = 0;
    for i in 0..9 {
        ns = ns * 10 + frac.get(i).map_or(0, |&d| i64::from(d - b'0'));
    }
    Some(s * 1_000_000_000 + ns)
}

fn parse_int(b: &[u8]) -> Option<i64> {
    let (neg, digits) = match b.first() {
        Some(b'-') => (true, &b[1..]),
        Some(b'+') => (false, &b[1..]),
        _ => (false, b),
    };
    if digits.is_empty() || digits.len() > 12 || !digits.iter().all(u8::is_ascii_digit) {
        return None;
    }
    let v = digits
        .iter()
        .fold(0i64, |acc, &d| acc * 10 + i64::from(d - b'0'));
    Some(if neg { -v } else { v })
}

enum Row {
    Adc {
        time_ns: i64,
        counts: [i32; 3],
        status: u8,
    },
    Temperature {
        time_ns: i64,
        celsius: [Option<f64>; 3],
        status: u8,
    },
}

/// One pass over a plain ADC line (`week,sec.frac,int,int,int` with no spaces, empty fields
/// allowed for counts). `None` sends the line to [`parse_row_general`], which also explains
/// what is wrong.
fn parse_adc_fast(line: &[u8], columns: &ValueColumns) -> Option<Row> {
    let mut p = 0usize;
    let uint = |p: &mut usize, max_digits: usize| digits(line, p, max_digits);
    let week = uint(&mut p, 4)?;
    (line.get(p) == Some(&b',')).then_some(())?;
    p += 1;
    let sec = uint(&mut p, 6)?;
    let mut ns = 0i64;
    if line.get(p) == Some(&b'.') {
        p += 1;
        let start = p;
        let frac = uint(&mut p, 9)?;
        ns = frac * 10i64.pow(9 - (p - start) as u32);
    }
    let tow = sec * 1_000_000_000 + ns;
    if tow >= NS_PER_WEEK {
        return None;
    }
    let (counts, status) = counts_fast(line, p, columns)?;
    Some(Row::Adc {
        time_ns: week * NS_PER_WEEK + tow,
        counts,
        status,
    })
}

/// The ADC line's counts from `line[p..]` (each after a comma, an empty field for a
/// channel not connected), one per value column of `columns`, placed on their channels with
/// their status, in one pass; None unless the line ends there.
#[inline]
fn counts_fast(line: &[u8], mut p: usize, columns: &ValueColumns) -> Option<([i32; 3], u8)> {
    let n = line.len();
    let mut values = [None; 3];
    for k in 0..columns.width {
        (line.get(p) == Some(&b',')).then_some(())?;
        p += 1;
        let feeds = columns.feeds(k);
        if feeds == 0 {
            // A column no channel reads: skipped to the next comma.
            p += line[p..].iter().position(|&c| c == b',').unwrap_or(n - p);
            continue;
        }
        if p == n || line[p] == b',' {
            continue;
        }
        let neg = line[p] == b'-';
        if neg {
            p += 1;
        }
        let v = digits(line, &mut p, 8)?;
        let v = if neg { -v } else { v };
        if !(COUNT_MIN..=COUNT_MAX).contains(&v) {
            return None;
        }
        ValueColumns::place(feeds, &mut values, Some(v as i32));
    }
    (p == n).then(|| counts_on_channels(values))
}

/// The counts on their channels, and their status: a channel without a value (no column,
/// or an empty field) not connected, a count at either end of the 24-bit range over range.
#[inline]
fn counts_on_channels(values: [Option<i32>; 3]) -> ([i32; 3], u8) {
    let mut counts = [0i32; 3];
    let mut status = 0u8;
    for ch in 0..3 {
        match values[ch] {
            None => status |= not_connected_bit(ch),
            Some(v) => {
                if i64::from(v) == COUNT_MIN || i64::from(v) == COUNT_MAX {
                    status |= over_range_bit(ch);
                }
                counts[ch] = v;
            }
        }
    }
    (counts, status)
}

/// One pass over a plain ADC line whose time is one field in another form (`time,int,int,int`,
/// no spaces around the counts): the time through `time`, the counts as [`parse_adc_fast`]
/// reads them. `None` sends the line to [`parse_row_timed`], which also explains what is
/// wrong.
fn parse_adc_timed_fast(line: &[u8], time: &mut TimeReader, columns: &ValueColumns) -> Option<Row> {
    let (time_ns, comma) = time.read_leading_fast(line)?;
    let (counts, status) = counts_fast(line, comma, columns)?;
    Some(Row::Adc {
        time_ns,
        counts,
        status,
    })
}

fn parse_row(kind: CsvKind, line: &[u8], columns: &ValueColumns) -> Result<Row, Bad> {
    if kind == CsvKind::Adc
        && let Some(row) = parse_adc_fast(line, columns)
    {
        return Ok(row);
    }
    parse_row_general(kind, line, columns)
}

fn parse_row_general(kind: CsvKind, line: &[u8], columns: &ValueColumns) -> Result<Row, Bad> {
    let expected = 2 + columns.width;
    let mut fields = [&line[..0]; 2 + MAX_VALUE_COLUMNS];
    let mut n = 0;
    for f in line.split(|&c| c == b',') {
        if n == expected {
            return Err(bad(
                "line",
                format!("more than {expected} fields in `{}`", text(line)),
            ));
        }
        fields[n] = f.trim_ascii();
        n += 1;
    }
    if n < expected {
        return Err(bad(
            "line",
            format!(
                "{n} fields, expected {expected} ({})",
                kind.header(columns).join(",")
            ),
        ));
    }
    let week = parse_int(fields[0])
        .filter(|w| (0..=MAX_WEEK).contains(w))
        .ok_or_else(|| {
            bad(
                "gps_week",
                format!(
                    "`{}` is not a GPS week number [0, {MAX_WEEK}]",
                    text(fields[0])
                ),
            )
        })?;
    let tow = parse_tow_ns(fields[1])
        .filter(|&t| t < NS_PER_WEEK)
        .ok_or_else(|| {
            bad(
                "tow_s",
                format!(
                    "`{}` is not a time of week in seconds [0, 604800)",
                    text(fields[1])
                ),
            )
        })?;
    row_of(kind, week * NS_PER_WEEK + tow, &fields[2..], columns)
}

/// A row at `time_ns` from its value fields, one per column of `columns` (named as the
/// GPS-week header's), placed on their channels.
fn row_of(
    kind: CsvKind,
    time_ns: i64,
    fields: &[&[u8]],
    columns: &ValueColumns,
) -> Result<Row, Bad> {
    // The fields a channel reads (a skipped column is not read), with the channels each
    // feeds.
    let read = fields[..columns.width]
        .iter()
        .enumerate()
        .map(|(k, f)| (k, columns.feeds(k), f))
        .filter(|(_, feeds, f)| *feeds != 0 && !f.is_empty());
    let name = |k: usize| kind.column_name(columns, k);
    match kind {
        CsvKind::Adc => {
            let mut values = [None; 3];
            for (k, feeds, f) in read {
                let v = parse_int(f).ok_or_else(|| {
                    bad(name(k), format!("`{}` is not an integer count", text(f)))
                })?;
                if !(COUNT_MIN..=COUNT_MAX).contains(&v) {
                    return Err(bad(name(k), format!("{v} is outside the 24-bit range")));
                }
                ValueColumns::place(feeds, &mut values, Some(v as i32));
            }
            let (counts, status) = counts_on_channels(values);
            Ok(Row::Adc {
                time_ns,
                counts,
                status,
            })
        }
        CsvKind::Temperature => {
            let mut celsius = [None; 3];
            for (k, feeds, f) in read {
                let v: f64 = std::str::from_utf8(f)
                    .ok()
                    .and_then(|s| s.parse().ok())
                    .filter(|v: &f64| v.is_finite())
                    .ok_or_else(|| {
                        bad(
                            name(k),
                            format!("`{}` is not a temperature in degC", text(f)),
                        )
                    })?;
                ValueColumns::place(feeds, &mut celsius, Some(v));
            }
            let mut status = 0u8;
            for (ch, v) in celsius.iter().enumerate() {
                if v.is_none() {
                    status |= not_connected_bit(ch);
                }
            }
            Ok(Row::Temperature {
                time_ns,
                celsius,
                status,
            })
        }
    }
}

/// A row of a log whose time is one field in another form than GPS week + tow
/// (docs/formats.md 9.1): `time,v1,v2,v3`.
fn parse_row_timed(
    kind: CsvKind,
    line: &[u8],
    time: &mut TimeReader,
    columns: &ValueColumns,
) -> Result<Row, Bad> {
    // The fields without allocating (one more only to say there are too many).
    let mut buf: [&[u8]; 2 + MAX_VALUE_COLUMNS] = [&[]; 2 + MAX_VALUE_COLUMNS];
    let mut count = 0;
    for f in line.split(|&c| c == b',') {
        if count < buf.len() {
            buf[count] = f.trim_ascii();
        }
        count += 1;
    }
    let fields = &buf[..count.min(buf.len())];
    if count != 1 + columns.width {
        return Err(bad(
            "line",
            format!(
                "{count} fields, expected {} (a time in the form \"{}\", then {})",
                1 + columns.width,
                time.form.name(),
                kind.value_names(columns).join(",")
            ),
        ));
    }
    let t = time
        .read(&fields[..1])
        .map_err(|(field, message)| bad(field, message))?;
    row_of(kind, t, &fields[1..], columns)
}

/// Where the time gate's verdicts on CSV rows go.
struct RowSink<'a> {
    streams: &'a mut StreamWriter,
    ledger: &'a mut FileLedger,
}

impl Sink<Row> for RowSink<'_> {
    type Error = Error;
    fn accept(&mut self, _: i64, row: Row) -> Result<()> {
        match row {
            Row::Adc {
                time_ns,
                counts,
                status,
            } => self.streams.acceleration(time_ns, counts, status),
            Row::Temperature {
                time_ns,
                celsius,
                status,
            } => self.streams.temperature(time_ns, celsius, status),
        }
    }
    fn reject(&mut self, at: Position, why: &'static str, detail: String, _: Row) {
        self.ledger.reject(at.to_string(), why, detail);
    }
}

/// What the CSV reader needs to know of its session.
#[derive(Clone, Copy, Debug)]
pub struct CsvConfig {
    /// Which log.
    pub kind: CsvKind,
    /// Count and list malformed lines instead of failing.
    pub skip_bad_lines: bool,
    /// Nominal interval between rows, ns; `None` for a log whose interval nobody declares,
    /// which the time gate learns ([`TimeGate::learning`]).
    pub interval_ns: Option<i64>,
    /// The session's range of GPS time, ns.
    pub range_ns: (i64, i64),
    /// How the log writes its times.
    pub time: TimeReader,
    /// Which channels its value columns hold.
    pub columns: ValueColumns,
}

/// A CSV log's lines as they are read: the header (required in GPS week + tow, optional and
/// taken by position in any other time form), then rows.
struct CsvLines<'p> {
    path: &'p Path,
    kind: CsvKind,
    skip_bad_lines: bool,
    time: TimeReader,
    columns: ValueColumns,
    gps_week_tow: bool,
    header_seen: bool,
    /// Comment, blank and header lines.
    other: u64,
}

impl CsvLines<'_> {
    /// The row of line `line_no`; None for a comment, blank or header line, or a line
    /// rejected into `ledger` (malformed when skipping, a temperature out of range); an
    /// error for a malformed line or header otherwise.
    #[inline]
    fn row(&mut self, line_no: u64, raw: &[u8], ledger: &mut FileLedger) -> Result<Option<Row>> {
        // A line a fast ADC parser takes whole has no comment and no white space at either
        // end to strip (its counts are digits, signs and commas, its time a form's own
        // characters), which saves a search per line.
        let fast = match (
            self.header_seen && self.kind == CsvKind::Adc,
            self.gps_week_tow,
        ) {
            (false, _) => None,
            (true, true) => parse_adc_fast(raw, &self.columns),
            (true, false) => parse_adc_timed_fast(raw, &mut self.time, &self.columns),
        };
        let line = if fast.is_some() {
            raw
        } else {
            strip_comment(raw)
        };
        if line.is_empty() || (!self.header_seen && self.header(line_no, line)?) {
            self.other += 1;
            return Ok(None);
        }
        let parsed = match fast {
            Some(row) => Ok(row),
            None if self.gps_week_tow => parse_row(self.kind, line, &self.columns),
            None => parse_row_timed(self.kind, line, &mut self.time, &self.columns),
        };
        let row = match parsed {
            Ok(r) => r,
            Err(b) if self.skip_bad_lines => {
                ledger.reject(
                    format!("line {line_no}"),
                    reason::MALFORMED,
                    format!("{}: {}", b.field, b.message),
                );
                return Ok(None);
            }
            Err(b) => return Err(self.error(line_no, b.field, b.message)),
        };
        if let Row::Temperature { celsius, .. } = &row
            && let Some((ch, v)) = celsius
                .iter()
                .enumerate()
                .find_map(|(ch, v)| v.filter(|v| !CELSIUS_RANGE.contains(v)).map(|v| (ch, v)))
        {
            ledger.reject(
                format!("line {line_no}"),
                reason::TEMPERATURE_OUT_OF_RANGE,
                format!("{}: {v} degC", self.kind.value_name(ch)),
            );
            return Ok(None);
        }
        Ok(Some(row))
    }

    /// The first line that is not a comment: whether it is the header (an error when it must
    /// be and is not the expected one). In another time form than GPS week + tow a header
    /// is optional, any names, taken by position: a first field that is not a time.
    fn header(&mut self, line_no: u64, line: &[u8]) -> Result<bool> {
        self.header_seen = true;
        let fields = || line.split(|&c| c == b',').map(<[u8]>::trim_ascii);
        if !self.gps_week_tow {
            let first = fields().next().unwrap_or_default();
            if self.time.read(&[first]).is_ok() {
                return Ok(false);
            }
            let n = fields().count();
            let expected = 1 + self.columns.width;
            if n != expected {
                let message = format!(
                    "`{}`: {n} names, expected {expected} (the time, then one per value column: \
                     {}; the session's adc_columns and thermometers say which)",
                    text(line),
                    self.kind.value_names(&self.columns).join(",")
                );
                return Err(self.error(line_no, "header", message));
            }
            return Ok(true);
        }
        let names = self.kind.header(&self.columns);
        let got: Vec<&[u8]> = fields().collect();
        // A skipped column's name is the logger's own.
        let differs = got
            .iter()
            .zip(&names)
            .any(|(g, n)| *n != "skipped" && *g != n.as_bytes());
        if got.len() != names.len() || differs {
            let message = format!("`{}`, expected `{}`", text(line), names.join(","));
            return Err(self.error(line_no, "header", message));
        }
        Ok(true)
    }

    fn error(&self, line: u64, field: &str, message: String) -> Error {
        Error::Line {
            path: self.path.to_path_buf(),
            line,
            field: field.to_owned(),
            message,
        }
    }
}

impl Row {
    fn time_ns(&self) -> i64 {
        match self {
            Row::Adc { time_ns, .. } | Row::Temperature { time_ns, .. } => *time_ns,
        }
    }
}

/// Reads one CSV log into `streams`, filling in `ledger`. Returns the median interval
/// between accepted rows (ns), if there were two.
pub fn read_csv(
    path: &Path,
    config: CsvConfig,
    streams: &mut StreamWriter,
    ledger: &mut FileLedger,
    progress: &indicatif::ProgressBar,
) -> Result<Option<i64>> {
    let kind = config.kind;
    let mut lines = CsvLines {
        path,
        kind,
        skip_bad_lines: config.skip_bad_lines,
        time: config.time,
        columns: config.columns,
        gps_week_tow: config.time.form == TimeForm::GpsWeekTow,
        header_seen: false,
        other: 0,
    };
    let mut gate = match config.interval_ns {
        Some(interval_ns) => TimeGate::new(interval_ns, config.range_ns),
        None => TimeGate::learning(config.range_ns),
    };
    let mut sink = RowSink { streams, ledger };
    let (sha, bytes) = read_lines(path, progress, |line_no, raw| {
        match lines.row(line_no, raw, sink.ledger)? {
            Some(row) => gate.offer(row.time_ns(), Position::Line(line_no), row, &mut sink),
            None => Ok(()),
        }
    })?;
    gate.finish(&mut sink)?;
    if !lines.header_seen {
        let message = format!("no header line `{}`", kind.header(&lines.columns).join(","));
        return Err(lines.error(1, "header", message));
    }
    let RowSink { streams, ledger } = sink;
    ledger.accept(
        if kind == CsvKind::Adc {
            "acceleration"
        } else {
            "temperature"
        },
        gate.accepted(),
    );
    ledger.null_values = streams.take_null_counts()?;
    ledger.sha256 = sha;
    ledger.bytes = bytes;
    ledger.comment_blank_or_header_lines = Some(lines.other);
    Ok(gate.median_interval_ns())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fast path and the general parser agree on every line the fast path takes, and the
    /// fast path declines what it cannot judge.
    #[test]
    fn fast_path_agrees_with_the_general_parser() {
        let lines: [&[u8]; 12] = [
            b"1308,295200.032,1534211,,-8388608",
            b"1308,295200,1,2,3",
            b"0,0.5,,,",
            b"1308,604799.999999999,8388607,-1,0",
            b"1308,604800,1,2,3",
            b"1308,1.0,1,2,8388608",
            b"1308,1.,1,2,3",
            b"1308, 1.0,1,2,3",
            b"1308,1.0,+1,2,3",
            b"1308,1.0,1,2",
            b"1308,1.0,1,2,3,4",
            b"1308,1.0,1,2,3x",
        ];
        for line in lines {
            let fast = parse_adc_fast(line, &ValueColumns::EVERY_CHANNEL);
            let general = parse_row_general(CsvKind::Adc, line, &ValueColumns::EVERY_CHANNEL);
            match (fast, general) {
                (
                    Some(Row::Adc {
                        time_ns: a,
                        counts: b,
                        status: c,
                    }),
                    Ok(Row::Adc {
                        time_ns: x,
                        counts: y,
                        status: z,
                    }),
                ) => {
                    assert_eq!((a, b, c), (x, y, z), "{}", text(line));
                }
                (Some(_), _) => panic!(
                    "fast path took a line the general parser rejects: {}",
                    text(line)
                ),
                (None, _) => {}
            }
        }
        assert!(
            parse_adc_fast(
                b"1308,295200.032,1534211,,-8388608",
                &ValueColumns::EVERY_CHANNEL
            )
            .is_some()
        );
    }

    /// The fast path of a log in another time form agrees with the general parser on every
    /// line it takes, takes the plain ones, and declines what it cannot judge.
    #[test]
    fn timed_fast_path_agrees_with_the_general_parser() {
        use crate::contract::manifest::TimeScale;
        let cases: [(TimeForm, &[u8], bool); 15] = [
            (
                TimeForm::Iso,
                b"2026-03-14T09:12:03Z,1534211,,-8388608",
                true,
            ),
            (TimeForm::Iso, b"2026-03-14T09:12:03.125Z,1,2,3", true),
            (TimeForm::Iso, b"2026-03-14T09:12:03.123456789Z,1,2,3", true),
            (TimeForm::Iso, b"2026-03-14T09:12:03.5,1,2,3", true),
            (TimeForm::Iso, b"2026-03-14T09:12:03Z1,2,3", false),
            (TimeForm::Iso, b"2026-03-14 09:12:03.125,1,2,3", true),
            (TimeForm::Iso, b"2026-03-14T09:12:03+01:00,1,2,3", true),
            (TimeForm::Iso, b"2026-03-14T09:12:03Z, 1,2,3", false),
            (TimeForm::Iso, b"2026-03-14T09:12:03Z,1,2,3 # note", false),
            (TimeForm::Iso, b"2026-03-14T09:12:60Z,1,2,3", false),
            (TimeForm::Iso, b"2026-03-14T09:12:03Z,1,2", false),
            (TimeForm::Iso, b"2026-03-14T09:12:03Z,1,2,8388608", false),
            (TimeForm::UnixS, b"1773479523.004,1,-2,3", true),
            (TimeForm::UnixS, b"1773479523.004,1,x,3", false),
            (TimeForm::S, b"12.5,1,2,3", true),
        ];
        for (form, line, taken) in cases {
            let mut fast = TimeReader::new(form, TimeScale::Utc, Some(1_000_000_000_000));
            let mut general = fast;
            let got = parse_adc_timed_fast(line, &mut fast, &ValueColumns::EVERY_CHANNEL);
            assert_eq!(got.is_some(), taken, "{}", text(line));
            if let Some(Row::Adc {
                time_ns,
                counts,
                status,
            }) = got
            {
                let Ok(Row::Adc {
                    time_ns: t,
                    counts: c,
                    status: s,
                }) = parse_row_timed(
                    CsvKind::Adc,
                    line,
                    &mut general,
                    &ValueColumns::EVERY_CHANNEL,
                )
                else {
                    panic!("the general parser rejects {}", text(line));
                };
                assert_eq!((time_ns, counts, status), (t, c, s), "{}", text(line));
            }
        }
    }

    #[test]
    fn tow_is_exact() {
        assert_eq!(parse_tow_ns(b"295200.032"), Some(295_200_032_000_000));
        assert_eq!(parse_tow_ns(b"7"), Some(7_000_000_000));
        assert_eq!(parse_tow_ns(b"0.000000001"), Some(1));
        for bad in [
            &b""[..],
            b"1.",
            b".5",
            b"1e3",
            b"-1",
            b"1.0000000001",
            b"12a",
        ] {
            assert_eq!(parse_tow_ns(bad), None, "{}", text(bad));
        }
    }

    #[test]
    fn rows_parse_and_fail_by_field() {
        match parse_row(
            CsvKind::Adc,
            b"1308,295200.032,1534211,,-8388608",
            &ValueColumns::EVERY_CHANNEL,
        ) {
            Ok(Row::Adc {
                time_ns,
                counts,
                status,
            }) => {
                assert_eq!(time_ns, 1308 * NS_PER_WEEK + 295_200_032_000_000);
                assert_eq!(counts[0], 1_534_211);
                assert_eq!(status, not_connected_bit(1) | over_range_bit(2));
            }
            _ => panic!("row should parse"),
        }
        for (line, field) in [
            (&b"1308,295200.032,1,2"[..], "line"),
            (b"1308,295200.032,1,2,3,4", "line"),
            (b"x,295200.032,1,2,3", "gps_week"),
            (b"1308,604800,1,2,3", "tow_s"),
            (b"1308,1.0,1,2.5,3", "c2"),
            (b"1308,1.0,1,2,8388608", "c3"),
        ] {
            match parse_row(CsvKind::Adc, line, &ValueColumns::EVERY_CHANNEL) {
                Err(b) => assert_eq!(b.field, field, "{}", text(line)),
                Ok(_) => panic!("{} should not parse", text(line)),
            }
        }
        assert!(matches!(
            parse_row(
                CsvKind::Temperature,
                b"1308,1.0,24.812,,nan",
                &ValueColumns::EVERY_CHANNEL
            ),
            Err(Bad { field: "t3", .. })
        ));
    }

    /// A log of fewer value columns than channels (docs/formats.md 9.4): each column lands
    /// on its channel, a channel without one is not connected, one thermometer's column is
    /// every listed channel's temperature, and a line of the wrong width names the width.
    #[test]
    fn value_columns_land_on_their_channels() {
        let two = ValueColumns {
            width: 2,
            column_of: [None, Some(1), Some(0)],
        };
        let line = b"1308,295200.032,-12,8388607";
        for row in [
            parse_adc_fast(line, &two),
            parse_row_general(CsvKind::Adc, line, &two).ok(),
        ] {
            match row {
                Some(Row::Adc { counts, status, .. }) => {
                    assert_eq!(counts, [0, 8_388_607, -12]);
                    assert_eq!(status, not_connected_bit(0) | over_range_bit(1));
                }
                _ => panic!("two columns read"),
            }
        }
        assert!(matches!(
            parse_row(CsvKind::Adc, b"1308,295200.032,1,2,3", &two),
            Err(Bad { field: "line", .. })
        ));
        let one = ValueColumns {
            width: 1,
            column_of: [Some(0), Some(0), None],
        };
        match parse_row(CsvKind::Temperature, b"1308,1.0,24.5", &one) {
            Ok(Row::Temperature {
                celsius, status, ..
            }) => {
                assert_eq!(celsius, [Some(24.5), Some(24.5), None]);
                assert_eq!(status, not_connected_bit(2));
            }
            _ => panic!("one thermometer read"),
        }
        match parse_row(CsvKind::Temperature, b"1308,1.0,24.5,24.6", &one) {
            Err(b) => assert!(b.message.contains("more than 3"), "{}", b.message),
            Ok(_) => panic!("a second column is not the one thermometer's"),
        }
        assert_eq!(
            CsvKind::Temperature.header(&one),
            ["gps_week", "tow_s", "t1"]
        );
        // A column no channel reads is skipped unread, whatever it holds.
        let skipping = ValueColumns {
            width: 4,
            column_of: [Some(2), None, Some(0)],
        };
        let line = b"1308,295200.032,5,0.25,7,x";
        for row in [
            parse_adc_fast(line, &skipping),
            parse_row_general(CsvKind::Adc, line, &skipping).ok(),
        ] {
            match row {
                Some(Row::Adc { counts, status, .. }) => {
                    assert_eq!(counts, [7, 0, 5]);
                    assert_eq!(status, not_connected_bit(1));
                }
                _ => panic!("skipped columns pass"),
            }
        }
        assert_eq!(
            CsvKind::Adc.header(&skipping),
            ["gps_week", "tow_s", "c3", "skipped", "c1", "skipped"]
        );
    }
}
