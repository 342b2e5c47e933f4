//! `cargo xtask init <dataset>`: a commented draft `dataset.toml` from the logs in
//! `<dataset>/raw/` (docs/formats.md 9.3). Each file's head and tail (64 KiB each) is read:
//! its layout (binary log, counts CSV, temperature CSV, lab stream, theodolite log), how it
//! writes its times, its sample rate, channels and first and last time. Files are grouped
//! into sessions by name (`day1.gcb` with `day1_theodolite.txt`; `day1_adc.csv` with
//! `day1_temp.csv`): the stem before `_adc`, `_temp` or `_theodolite`. Every value the logs
//! cannot tell (the benchmark's gravity, a session's kind when no theodolite log says it
//! is a tilt table, a unit a number cannot show) is written as `"FILL IN"`, which the
//! manifest's validation refuses by key until a person replaces it. It never overwrites a
//! manifest.

use anyhow::{Context, Result, bail};
use ingest::base::time::{TimeForm, TimeReader, parse_iso};
use ingest::contract::manifest::{AdcFormat, TimeScale};
use ingest::contract::survey::TrajectoryFormat;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What the draft writes where it cannot know the value: refused by validation.
pub const FILL: &str = "\"FILL IN\"";

/// Bytes read at each end of a log.
const PEEK: usize = 64 * 1024;

/// A log's layout, as recognised.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    Binary,
    /// ADC counts, one integer column per channel.
    CountsCsv,
    /// Temperatures, degC.
    TemperatureCsv,
    /// Decimal readings (docs/formats.md 8.3).
    LabStream,
    Theodolite,
    /// A survey's GNSS positions (docs/formats.md 10.1).
    Trajectory(TrajectoryFormat),
    /// A survey's attitude (docs/formats.md 10.2).
    Attitude,
    /// A platform meter's serial output behind a logger's stamps (docs/formats.md 11.2):
    /// `AdcFormat::Bgm3` or `AdcFormat::DgsRaw`.
    MeterSerial(AdcFormat),
}

impl Layout {
    fn name(self) -> &'static str {
        match self {
            Layout::Binary => "binary log",
            Layout::CountsCsv => "counts CSV",
            Layout::TemperatureCsv => "temperature CSV",
            Layout::LabStream => "lab stream",
            Layout::Theodolite => "theodolite log",
            Layout::Trajectory(TrajectoryFormat::Rtklib) => "RTKLIB trajectory",
            Layout::Trajectory(TrajectoryFormat::Csv) => "CSV trajectory",
            Layout::Trajectory(TrajectoryFormat::DgsLaptop) => "DGS laptop file",
            Layout::Trajectory(TrajectoryFormat::Nmea) => "NMEA navigation",
            Layout::Attitude => "attitude CSV",
            Layout::MeterSerial(AdcFormat::Bgm3) => "BGM-3 serial file",
            Layout::MeterSerial(_) => "DGS raw serial file",
        }
    }
}

/// One file of raw/, recognised.
struct Found {
    rel: String,
    layout: Layout,
    time: Option<TimeForm>,
    /// First and last time, GPS ns (absolute times only).
    span_ns: Option<(i64, i64)>,
    /// Sample rate from the median interval, Hz.
    rate_hz: Option<f64>,
    /// Value columns.
    channels: usize,
    /// Comment lines, lower case: where a logger says its units and time scale.
    comments: String,
    /// Decimal readings' largest magnitude (lab streams), for the unit's hint.
    magnitude: f64,
}

/// Writes `<dataset>/dataset.toml` from `<dataset>/raw/`; returns its path.
pub fn run(dataset: &Path) -> Result<PathBuf> {
    let manifest = dataset.join("dataset.toml");
    // Anything there, a link whose target is missing included, is refused: the draft is
    // created new (never written through a link to a file elsewhere).
    if manifest.symlink_metadata().is_ok() {
        bail!(
            "{} exists: init never overwrites a manifest nor writes through a link (move it \
             away to draft a new one)",
            manifest.display()
        );
    }
    let raw = dataset.join("raw");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&raw)
        .with_context(|| format!("listing {} (init reads the logs in raw/)", raw.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    let mut found = Vec::new();
    for f in &files {
        match recognise(f) {
            Ok(x) => found.push(x),
            Err(e) => eprintln!("init: {}: left out: {e}", f.display()),
        }
    }
    if found.is_empty() {
        bail!("{}: no log init recognises", raw.display());
    }
    let name = dataset
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "dataset".to_owned());
    let mut text = draft(&name, &found);
    let logs: Vec<(PathBuf, bool)> = found
        .iter()
        .map(|f| (dataset.join(&f.rel), f.layout == Layout::Binary))
        .collect();
    let findings = crate::user::preflight::findings(dataset, &logs, &text)?;
    if !findings.is_empty() {
        let mut said = String::from(
            "# What `cargo xtask check` says of these logs as drafted (every \"FILL IN\"\n\
             # stood in for):\n",
        );
        for line in &findings {
            eprintln!("init: check: {line}");
            said.push_str(&format!("#   {line}\n"));
        }
        text = said + &text;
    }
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&manifest)
        .with_context(|| format!("creating {} (new)", manifest.display()))?;
    std::io::Write::write_all(&mut file, text.as_bytes())
        .with_context(|| format!("writing {}", manifest.display()))?;
    Ok(manifest)
}

/// `s` as a TOML basic string, quoted and escaped by the toml crate's serializer (a log
/// named `my "lab".txt` made a draft that was not TOML).
fn q(s: &str) -> String {
    toml::Value::String(s.to_owned()).to_string()
}

/// A file's layout, time form, span, rate and channels from its head and tail.
fn recognise(path: &Path) -> Result<Found> {
    let (head, tail) = ends(path).with_context(|| format!("reading {}", path.display()))?;
    let rel = format!(
        "raw/{}",
        path.file_name().unwrap_or_default().to_string_lossy()
    );
    if head.starts_with(&ingest::readers::gcb::SYNC) {
        return Ok(binary(rel, &head, &tail));
    }
    let head = String::from_utf8_lossy(&head).into_owned();
    let tail = String::from_utf8_lossy(&tail).into_owned();
    if let Some(found) = meter_serial(&rel, &head, &tail) {
        return Ok(found);
    }
    if let Some(found) = trajectory(&rel, &head, &tail) {
        return Ok(found);
    }
    text(rel, &head, &tail)
}

/// A platform meter's serial output behind a logger's stamps (docs/formats.md 11.2): its
/// first lines (past `#` comments) read by the parser ingest reads it with, as a BGM-3's
/// or a DGS's raw records; one channel, in counts. The stamps without a zone are taken as
/// UTC here (only the span and rate are drafted).
fn meter_serial(rel: &str, head: &str, tail: &str) -> Option<Found> {
    use ingest::readers::meter_serial::{parse_bgm3, parse_dgs_raw};
    let lines = |text: &str| -> Vec<String> {
        text.lines()
            .map(str::trim)
            .filter(|l| !l.is_empty() && !l.starts_with('#'))
            .map(str::to_owned)
            .collect()
    };
    let (first, last) = (lines(head), lines(tail));
    for format in [AdcFormat::DgsRaw, AdcFormat::Bgm3] {
        let time = |l: &String| {
            let parsed = match format {
                AdcFormat::Bgm3 => parse_bgm3(l.as_bytes(), TimeScale::Utc),
                _ => parse_dgs_raw(l.as_bytes(), TimeScale::Utc),
            };
            parsed.ok().map(|r| r.gps_ns)
        };
        let times: Vec<i64> = first.iter().take(20).map_while(time).collect();
        if times.len() >= 2 {
            // The tail's first line may be cut.
            let end = last.iter().skip(1).filter_map(time).next_back();
            let mut found = trajectory_found(rel, Layout::MeterSerial(format), None, times, end);
            found.channels = 1;
            return Some(found);
        }
    }
    None
}

/// A survey's trajectory (docs/formats.md 10.1): an RTKLIB solution file (a `%` column
/// header naming the latitude, and its time scale) or a CSV whose header begins
/// `time,lat_deg`; or its attitude (10.2), a CSV whose header begins `time,heading_deg`;
/// span and rate from their ends.
fn trajectory(rel: &str, head: &str, tail: &str) -> Option<Found> {
    dgs_laptop(rel, head, tail)
        .or_else(|| nmea(rel, head, tail))
        .or_else(|| rtklib_trajectory(rel, head, tail))
        .or_else(|| {
            csv_epochs(
                rel,
                (head, tail),
                "lat_deg",
                Layout::Trajectory(TrajectoryFormat::Csv),
            )
        })
        .or_else(|| csv_epochs(rel, (head, tail), "heading_deg", Layout::Attitude))
}

/// A trajectory's entry: its layout, time form, and span and rate from its ends' times.
fn trajectory_found(
    rel: &str,
    layout: Layout,
    time: Option<TimeForm>,
    times: Vec<i64>,
    last: Option<i64>,
) -> Found {
    Found {
        rel: rel.to_owned(),
        layout,
        time,
        span_ns: times.first().map(|&a| (a, last.unwrap_or(a))),
        rate_hz: rate(&times, 1e-9),
        channels: 3,
        comments: String::new(),
        magnitude: 0.0,
    }
}

/// A DGS meter's laptop file (docs/formats.md 11.1): its first and last lines read by the
/// parser ingest reads it with; the meter's gravity and its navigation, one channel.
fn dgs_laptop(rel: &str, head: &str, tail: &str) -> Option<Found> {
    let time = |l: &str| {
        ingest::readers::dgs::split(l.trim_end().as_bytes())
            .and_then(|f| ingest::readers::dgs::parse_laptop(&f))
            .ok()
            .map(|r| r.gps_ns)
    };
    let times: Vec<i64> = head.lines().take(20).map_while(time).collect();
    if times.len() < 2 {
        return None;
    }
    let last = tail.lines().skip(1).filter_map(time).last();
    let mut found = trajectory_found(
        rel,
        Layout::Trajectory(TrajectoryFormat::DgsLaptop),
        None,
        times,
        last,
    );
    found.channels = 1;
    Some(found)
}

/// An NMEA logger's navigation (docs/formats.md 10.1): GGA or RMC sentences among its
/// first lines, whatever the logger writes before them; the span from the first and last
/// GGA or RMC's time of day on the date of the first ZDA or RMC (none: the span is left to
/// the session's date).
fn nmea(rel: &str, head: &str, tail: &str) -> Option<Found> {
    use ingest::readers::nmea::{Sentence, find, parse};
    let sentences = |text: &str| -> Vec<Sentence> {
        text.lines()
            .filter_map(|l| find(l.as_bytes()).and_then(|s| parse(s).ok()))
            .collect()
    };
    let (first, last) = (sentences(head), sentences(tail));
    let fix_time = |s: &Sentence| match s {
        Sentence::Gga(g) => Some(g.time_of_day_ns),
        Sentence::Rmc { time_of_day_ns, .. } => Some(*time_of_day_ns),
        _ => None,
    };
    if !first.iter().any(|s| fix_time(s).is_some()) {
        return None;
    }
    let date = first.iter().find_map(|s| match s {
        Sentence::Zda { date, .. } | Sentence::Rmc { date, .. } => Some(*date),
        _ => None,
    });
    let midnight = date.and_then(|d| {
        ingest::base::time::gps_ns(ingest::base::time::Calendar::midnight(d), TimeScale::Utc)
    });
    let times: Vec<i64> = match midnight {
        Some(m) => first.iter().filter_map(fix_time).map(|t| m + t).collect(),
        None => Vec::new(),
    };
    let last = midnight.and_then(|m| last.iter().filter_map(fix_time).next_back().map(|t| m + t));
    Some(trajectory_found(
        rel,
        Layout::Trajectory(TrajectoryFormat::Nmea),
        None,
        times,
        last,
    ))
}

/// An RTKLIB solution file: a `%` column header naming the latitude and the time scale.
fn rtklib_trajectory(rel: &str, head: &str, tail: &str) -> Option<Found> {
    let h = head
        .lines()
        .find(|l| l.starts_with('%') && l.contains("latitude"))?;
    let scale = if h.contains("UTC") {
        TimeScale::Utc
    } else {
        TimeScale::Gpst
    };
    let time = |l: &str| -> Option<i64> {
        let f: Vec<&str> = l.split_whitespace().collect();
        if l.starts_with('%') || f.len() < 10 {
            return None;
        }
        if f[0].contains('/') {
            let iso = format!("{}T{}", f[0].replace('/', "-"), f[1]);
            TimeReader::new(TimeForm::Iso, scale, None)
                .read(&[iso.as_bytes()])
                .ok()
        } else {
            TimeReader::new(TimeForm::GpsWeekTow, scale, None)
                .read(&[f[0].as_bytes(), f[1].as_bytes()])
                .ok()
        }
    };
    let times: Vec<i64> = head.lines().filter_map(time).collect();
    let last = tail.lines().skip(1).filter_map(time).last();
    Some(trajectory_found(
        rel,
        Layout::Trajectory(TrajectoryFormat::Rtklib),
        None,
        times,
        last,
    ))
}

/// A CSV of epochs (a trajectory, an attitude): a header beginning `time,<second>`; its
/// time form from the first line.
fn csv_epochs(
    rel: &str,
    (head, tail): (&str, &str),
    second: &str,
    layout: Layout,
) -> Option<Found> {
    let (lines, _) = data_lines(head);
    let header = lines.first()?;
    if !(header.len() >= 4 && header[0] == "time" && header[1] == second) {
        return None;
    }
    // Not a `gps_week` header: a calendar time, Unix seconds or seconds since a start.
    let form = time_form(lines.get(1).filter(|f| !f.is_empty())?, "");
    let time = |f: &Vec<&str>| match form {
        TimeForm::Iso => iso_ns(f.first()?),
        TimeForm::UnixS => {
            unix_to_gps_ns(ingest::base::time::parse_seconds_ns(f.first()?.as_bytes())?)
        }
        _ => None,
    };
    let times: Vec<i64> = lines.iter().skip(1).filter_map(time).collect();
    let (tail_lines, _) = data_lines(tail);
    let last = tail_lines.iter().skip(1).filter_map(time).next_back();
    Some(trajectory_found(rel, layout, Some(form), times, last))
}

/// The first and last [`PEEK`] bytes of a file (the whole file twice when it is shorter),
/// without reading its middle.
fn ends(path: &Path) -> std::io::Result<(Vec<u8>, Vec<u8>)> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = std::fs::File::open(path)?;
    let len = f.metadata()?.len();
    let mut head = Vec::new();
    (&mut f).take(PEEK as u64).read_to_end(&mut head)?;
    f.seek(SeekFrom::Start(len.saturating_sub(PEEK as u64)))?;
    let mut tail = Vec::new();
    f.read_to_end(&mut tail)?;
    Ok((head, tail))
}

/// The acceleration frames' times (10-bit week, tow) at each end of a binary log.
fn binary(rel: String, head: &[u8], tail: &[u8]) -> Found {
    let frames = |b: &[u8]| -> Vec<(u16, u32)> {
        let n = ingest::readers::gcb::FRAME_LEN;
        let mut out = Vec::new();
        let mut i = 0;
        while i + n <= b.len() {
            let f = &b[i..i + n];
            let crc = u16::from_le_bytes([f[n - 2], f[n - 1]]);
            if f[..2] == ingest::readers::gcb::SYNC
                && f[2] == 1
                && ingest::readers::gcb::crc16_ccitt_false(&f[2..n - 2]) == crc
            {
                out.push((
                    u16::from_le_bytes([f[4], f[5]]),
                    u32::from_le_bytes([f[6], f[7], f[8], f[9]]),
                ));
                i += n;
            } else {
                i += 1;
            }
        }
        out
    };
    let head = frames(head);
    let tail = frames(tail);
    let ms: Vec<i64> = head.iter().map(|&(_, t)| i64::from(t)).collect();
    // Times stay relative to the 10-bit week until the session's date resolves it.
    let week_ns = |(w, t): (u16, u32)| {
        i64::from(w) * ingest::base::time::NS_PER_WEEK + i64::from(t) * 1_000_000
    };
    Found {
        rel,
        layout: Layout::Binary,
        time: None,
        span_ns: head
            .first()
            .zip(tail.last())
            .map(|(&a, &b)| (week_ns(a), week_ns(b))),
        rate_hz: rate(&ms, 1e-3),
        channels: 3,
        comments: String::new(),
        magnitude: 0.0,
    }
}

/// The median interval of increasing times (in `unit` s) as a rate, Hz.
fn rate(times: &[i64], unit: f64) -> Option<f64> {
    let mut d: Vec<i64> = times
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|&d| d > 0)
        .collect();
    d.sort_unstable();
    let m = *d.get(d.len() / 2)?;
    Some(1.0 / (m as f64 * unit))
}

/// The data lines of a text (no comment, no blank), split; and the comments.
fn data_lines(text: &str) -> (Vec<Vec<&str>>, String) {
    let mut comments = String::new();
    let mut out = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(c) = line.strip_prefix('#') {
            comments.push_str(&c.to_lowercase());
            comments.push('\n');
        } else if !line.is_empty() {
            let fields: Vec<&str> = if line.contains(',') {
                line.split(',').map(str::trim).collect()
            } else {
                line.split_whitespace().collect()
            };
            out.push(fields);
        }
    }
    (out, comments)
}

/// A text log: theodolite log, CSV or lab stream.
fn text(rel: String, head: &str, tail: &str) -> Result<Found> {
    let (mut lines, comments) = data_lines(head);
    // A header line: its first field is neither a number nor a calendar time, and it is not
    // a theodolite reading (a station's name, then a calendar time).
    let header = lines.first().is_some_and(|f| {
        let reading = f.len() >= 3 && parse_iso(f[1]).is_ok();
        f[0].parse::<f64>().is_err() && parse_iso(f[0]).is_err() && !reading
    });
    let names = if header {
        lines.remove(0).join(",").to_lowercase()
    } else {
        String::new()
    };
    let (tail_lines, _) = data_lines(tail);
    // A tail that starts mid-line: drop its first line.
    let tail_lines: Vec<_> = tail_lines.into_iter().skip(1).collect();
    let first = lines.first().context("no data line in its first 64 KiB")?;
    if first.len() >= 3 && parse_iso(first[1]).is_ok() && first[0].parse::<f64>().is_err() {
        return Ok(theodolite(rel, &lines, &tail_lines, comments));
    }
    let form = time_form(first, &names);
    let time_of = |f: &Vec<&str>| -> Option<i64> {
        match form {
            TimeForm::GpsWeekTow => {
                let w: i64 = f.first()?.parse().ok()?;
                let tow = ingest::base::time::parse_seconds_ns(f.get(1)?.as_bytes())?;
                Some(w * ingest::base::time::NS_PER_WEEK + tow)
            }
            TimeForm::Iso => iso_ns(f.first()?),
            _ => ingest::base::time::parse_seconds_ns(f.first()?.as_bytes()),
        }
    };
    let skip = form.fields();
    well_formed(first, skip, time_of(first).is_some())?;
    let times: Vec<i64> = lines.iter().filter_map(time_of).collect();
    let last = tail_lines.iter().filter_map(time_of).next_back();
    let values: Vec<&str> = lines
        .iter()
        .flat_map(|f| f.iter().skip(skip).copied())
        .collect();
    let integers = values.iter().all(|v| v.parse::<i64>().is_ok());
    let magnitude = values
        .iter()
        .filter_map(|v| v.parse::<f64>().ok())
        .fold(0.0, |m: f64, v| m.max(v.abs()));
    let temperature = rel.to_lowercase().contains("temp")
        || names.contains("t1")
        || comments.contains("temperature");
    let layout = if temperature {
        Layout::TemperatureCsv
    } else if integers || matches!(form, TimeForm::GpsWeekTow | TimeForm::Iso) {
        Layout::CountsCsv
    } else {
        Layout::LabStream
    };
    let absolute = |t: i64| match form {
        TimeForm::UnixS => unix_to_gps_ns(t),
        TimeForm::S => None,
        _ => Some(t),
    };
    Ok(Found {
        rel,
        layout,
        time: Some(form),
        span_ns: times
            .first()
            .and_then(|&a| Some((absolute(a)?, absolute(last.unwrap_or(a))?))),
        rate_hz: rate(&times, 1e-9),
        channels: first.len().saturating_sub(skip),
        comments,
        magnitude,
    })
}

/// Whether a text's first data line (`fields`) is one a log writes: a time that reads in
/// its form (`time_read`), then at least one reading, each a number, `nan` or empty (a
/// channel not connected). Anything else (random bytes, one long field, a table of words)
/// is no log, and is left out with the reason rather than drafted as one of no channel.
fn well_formed(fields: &[&str], skip: usize, time_read: bool) -> Result<()> {
    let shown = || {
        // Control characters (random bytes) shown as the replacement character.
        let line: String = fields
            .join(",")
            .chars()
            .map(|c| if c.is_control() { '\u{fffd}' } else { c })
            .collect();
        let cut: String = line.chars().take(60).collect();
        if cut.len() < line.len() {
            format!("{cut}...")
        } else {
            cut
        }
    };
    if !time_read {
        bail!("no time in its first data line (`{}`)", shown());
    }
    if fields.len() <= skip {
        bail!(
            "no reading after the time in its first data line (`{}`)",
            shown()
        );
    }
    if let Some((k, v)) = fields
        .iter()
        .enumerate()
        .skip(skip)
        .find(|(_, v)| !v.is_empty() && v.parse::<f64>().is_err())
    {
        bail!(
            "field {} of its first data line, `{}`, is not a number (`{}`)",
            k + 1,
            v.chars().take(20).collect::<String>(),
            shown()
        );
    }
    Ok(())
}

/// A theodolite log (a station's name, then a calendar time, then the reading): its span
/// from both ends and its largest reading.
fn theodolite(
    rel: String,
    lines: &[Vec<&str>],
    tail_lines: &[Vec<&str>],
    comments: String,
) -> Found {
    let times: Vec<i64> = lines
        .iter()
        .chain(tail_lines.iter())
        .filter_map(|f| f.get(1).and_then(|t| iso_ns(t)))
        .collect();
    Found {
        rel,
        layout: Layout::Theodolite,
        time: Some(TimeForm::Iso),
        span_ns: times.first().zip(times.last()).map(|(&a, &b)| (a, b)),
        rate_hz: None,
        channels: 1,
        comments,
        magnitude: lines
            .iter()
            .filter_map(|f| f.get(2)?.parse::<f64>().ok())
            .fold(0.0, f64::max),
    }
}

/// A CSV's time form from its first data line (and its header's names): GPS week and
/// seconds under a `gps_week` header, a calendar time, Unix seconds (past 1973), or seconds
/// since a start.
fn time_form(first: &[&str], names: &str) -> TimeForm {
    if first.len() >= 2
        && first[0].parse::<u32>().is_ok_and(|w| w < 10_000)
        && !first[0].contains('.')
        && first[1].parse::<f64>().is_ok()
        && names.starts_with("gps_week")
    {
        TimeForm::GpsWeekTow
    } else if parse_iso(first[0]).is_ok() {
        TimeForm::Iso
    } else if first[0].parse::<f64>().is_ok_and(|t| t > 1e8) {
        TimeForm::UnixS
    } else {
        TimeForm::S
    }
}

/// An ISO 8601 time as GPS ns (zone-less times taken as UTC: only the date is used).
fn iso_ns(s: &str) -> Option<i64> {
    let (c, offset_min) = parse_iso(s).ok()?;
    let ns = ingest::base::time::gps_ns(c, TimeScale::Utc)?;
    Some(ns - i64::from(offset_min.unwrap_or(0)) * 60_000_000_000)
}

/// Unix time (ns) as GPS ns, with the leap seconds of hifitime's table.
fn unix_to_gps_ns(unix_ns: i64) -> Option<i64> {
    let days = unix_ns.div_euclid(86_400_000_000_000);
    let date = ingest::base::time::civil_from_days(days);
    let midnight =
        ingest::base::time::gps_ns(ingest::base::time::Calendar::midnight(date), TimeScale::Utc)?;
    Some(midnight + unix_ns.rem_euclid(86_400_000_000_000))
}

/// The session a file belongs to: its name without extension, with any of `_adc`, `_temp`,
/// `_theodolite` (and the like) taken off its end.
fn stem(rel: &str) -> String {
    let name = rel.trim_start_matches("raw/");
    let mut base = name.split('.').next().unwrap_or(name).to_owned();
    let suffixes = [
        "_theodolite",
        "_theo",
        "_temperature",
        "_temp",
        "_adc",
        "_acc",
        "_lab",
        "_attitude",
        "_att",
        "_pos",
        // A ship's meter and navigation logs (shipgrav's samples: `TN400_dgs_raw.Raw`,
        // `TN400_nav.Raw`, `AT01_bgm.BGM`, `AT01_nav.gps`).
        "_raw",
        "_dgs",
        "_bgm",
        "_nav",
        "_gps",
    ];
    while let Some(s) = suffixes
        .iter()
        .find(|s| base.to_lowercase().ends_with(*s) && base.len() > s.len())
    {
        base.truncate(base.len() - s.len());
    }
    base
}

/// The draft manifest's text.
fn draft(name: &str, found: &[Found]) -> String {
    let mut groups: BTreeMap<String, Vec<&Found>> = BTreeMap::new();
    for f in found {
        groups.entry(stem(&f.rel)).or_default().push(f);
    }
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# Draft written by `cargo xtask init` from the logs in raw/ (docs/formats.md 9.3).\n\
         # Every {FILL} must be replaced before the manifest validates; `cargo xtask check`\n\
         # then reads every log's head and tail.\n\
         name = {}\n\
         description = {}\n",
        q(name),
        q(&format!("{name}: drafted by cargo xtask init"))
    );
    site(&mut t);
    instrument(&mut t, found);
    let mut triad = false;
    for (id, files) in &groups {
        triad |= session(&mut t, id, files);
    }
    let _ = writeln!(
        t,
        "# [[adjust.model]] tables choose the models fitted (docs/formats.md 2); without one\n\
         # the default models are fitted to the tilt-table sessions.\n"
    );
    if triad {
        // Declaring one model drops the defaults: the tilt-table sessions' is declared too.
        if found.iter().any(|f| f.layout == Layout::Theodolite) {
            let _ = writeln!(
                t,
                "[[adjust.model]]                 # b and k per accelerometer and tilt-table session\n\
                 name = \"linear\"\n"
            );
        }
        let _ = writeln!(
            t,
            "[[adjust.model]]                 # a triad calibration of the multi-position sessions\n\
             name = \"triad\"\nkind = \"triad\"\n"
        );
    }
    t
}

fn site(t: &mut String) {
    let _ = writeln!(
        t,
        "[site]\n\
         g_abs_mgal = {FILL}          # absolute gravity at the benchmark, mGal (e.g. 980855.8)\n\
         # gradient_mgal_per_m = -0.3086  # vertical gradient, mGal/m (default -0.3086)\n\
         # sensor_height_m = 0.0          # the proof masses above the benchmark, m\n\
         # latitude_deg = 0.0             # with longitude and height: the Earth tide\n\
         # longitude_deg = 0.0\n\
         # height_m = 0.0\n"
    );
}

/// The instrument: the rate measured, a channel per value column.
fn instrument(t: &mut String, found: &[Found]) {
    let acc = found.iter().filter(|f| {
        matches!(
            f.layout,
            Layout::Binary
                | Layout::CountsCsv
                | Layout::LabStream
                | Layout::Trajectory(TrajectoryFormat::DgsLaptop)
                | Layout::MeterSerial(_)
        )
    });
    let serial = found
        .iter()
        .find(|f| matches!(f.layout, Layout::MeterSerial(_)));
    let meter = found
        .iter()
        .any(|f| f.layout == Layout::Trajectory(TrajectoryFormat::DgsLaptop));
    let rates: Vec<f64> = acc.clone().filter_map(|f| f.rate_hz).collect();
    let rate = rates.first().map_or(FILL.to_owned(), |&r| nice_rate(r));
    let channels = acc
        .clone()
        .map(|f| f.channels)
        .max()
        .unwrap_or(3)
        .clamp(1, 3);
    let lab: Vec<&Found> = acc.filter(|f| f.layout == Layout::LabStream).collect();
    let _ = writeln!(
        t,
        "[instrument]\n\
         sample_rate_hz = {rate}        # measured from the logs' time stamps{}",
        if rates.len() > 1 && rates.iter().any(|r| (r / rates[0] - 1.0).abs() > 0.01) {
            format!(" (they differ: {rates:?})")
        } else {
            String::new()
        }
    );
    if let Some(l) = lab.first() {
        let (unit, why) = reading_unit(l);
        let _ = writeln!(t, "reading_unit = {unit}          # {why}");
    } else if meter {
        let _ = writeln!(
            t,
            "reading_unit = \"mGal\"         # a DGS meter's raw gravity (docs/formats.md 11.1)\n\n\
             [[instrument.accelerometer]]\nid = \"meter\"\nchannel = 1\n\n\
             # The meter's scale and offset as its maker states them (--calibration vendor):\n\
             [instrument.accelerometer.vendor_calibration]\nscale = 1.0\n\
             offset_mgal = {FILL}         # mGal: gravity = offset_mgal + scale * reading\n"
        );
        return;
    } else if let Some(f) = serial {
        let _ = writeln!(
            t,
            "reading_unit = \"count\"        # {}: a {}'s reading is in counts (docs/formats.md 11.2)\n\n\
             [[instrument.accelerometer]]\nid = \"meter\"\nchannel = 1\n\n\
             # The meter's scale and offset as its maker states them (--calibration vendor):\n\
             [instrument.accelerometer.vendor_calibration]\n\
             scale = {FILL}               # mGal a count (a BGM-3's is about 5)\n\
             offset_mgal = {FILL}         # mGal: gravity = offset_mgal + scale * reading\n",
            f.rel,
            f.layout.name()
        );
        return;
    }
    let _ = writeln!(t);
    for ch in 1..=channels {
        let _ = writeln!(
            t,
            "[[instrument.accelerometer]]\nid = \"acc{ch}\"\nchannel = {ch}\n\
             # serial = \"\"                  # checked by apply against the calibration's\n"
        );
    }
}

/// A rate near a usual one is taken as it; else to 4 significant digits.
fn nice_rate(r: f64) -> String {
    let usual = [
        1.0, 2.0, 5.0, 10.0, 20.0, 25.0, 31.25, 50.0, 62.5, 100.0, 125.0, 200.0, 250.0, 400.0,
        500.0, 1000.0,
    ];
    match usual.iter().find(|&&u| (r / u - 1.0).abs() < 0.02) {
        Some(u) => format!("{u}"),
        None => format!("{:.4}", r),
    }
}

/// A lab stream's unit: what its comments say, or a question with the magnitude's hint.
fn reading_unit(f: &Found) -> (String, String) {
    let c = &f.comments;
    for (word, unit) in [
        ("count", "count"),
        ("m/s^2", "m/s^2"),
        ("m/s2", "m/s^2"),
        ("mgal", "mGal"),
        ("volt", "V"),
    ] {
        if c.contains(word) {
            return (
                format!("\"{unit}\""),
                format!("as {}'s comments say", f.rel),
            );
        }
    }
    let hint = match f.magnitude {
        m if m > 1e5 => "counts?",
        m if m > 1e3 => "mGal?",
        m if m > 3.0 => "m/s^2?",
        _ => "g or V?",
    };
    (
        FILL.to_owned(),
        format!(
            "\"count\" | \"m/s^2\" | \"mGal\" | \"g\" | \"V\": readings up to {:.4} ({hint})",
            f.magnitude
        ),
    )
}

/// One session of files sharing a stem; returns whether it is a multi-position session.
fn session(t: &mut String, id: &str, files: &[&Found]) -> bool {
    let get = |l: Layout| files.iter().copied().find(|f| f.layout == l);
    let theodolite = get(Layout::Theodolite);
    let temperature = get(Layout::TemperatureCsv);
    let _ = writeln!(t, "[[session]]\nid = {}", q(id));
    list_files(t, files);
    let _ = writeln!(t, "date = {}", date(files));
    let lab = get(Layout::LabStream);
    let track = files
        .iter()
        .copied()
        .find(|f| matches!(f.layout, Layout::Trajectory(_)));
    let _ = writeln!(t, "kind = {}", kind(theodolite.is_some(), track.is_some()));
    let binary = get(Layout::Binary);
    let serial = files
        .iter()
        .copied()
        .find(|f| matches!(f.layout, Layout::MeterSerial(_)));
    if let Some(m) = serial {
        let format = match m.layout {
            Layout::MeterSerial(f) => f.name(),
            _ => "",
        };
        let _ = writeln!(
            t,
            "adc_csv = {}\nadc_format = \"{format}\"\nthermometers = \"none\"",
            q(&m.rel)
        );
    } else {
        acquisition_keys(t, binary, lab, get(Layout::CountsCsv));
    }
    if let Some(x) = temperature {
        let _ = writeln!(
            t,
            "temperature_csv = {}\ntemperature_time = \"{}\"",
            q(&x.rel),
            x.time.unwrap_or(TimeForm::GpsWeekTow).name()
        );
    }
    if let (None, None, Some(counts)) = (binary, lab, get(Layout::CountsCsv)) {
        column_keys(t, counts, temperature);
    }
    match (track, get(Layout::Attitude)) {
        (Some(tr), attitude) => trajectory_keys(t, tr, attitude),
        (None, Some(a)) => {
            let _ = writeln!(
                t,
                "# {}: an attitude without a trajectory in this session is not used: the \
                 gravity stage reads both (docs/formats.md 10)",
                a.rel
            );
        }
        (None, None) => {}
    }
    if let Some(th) = theodolite {
        theodolite_keys(t, th);
        let _ = writeln!(
            t,
            "# roll_deg = 0.0                # the block's turn about its mirror axis, deg (docs/formats.md 8.2)"
        );
    } else {
        let _ = writeln!(
            t,
            "# quiet_start_s = 40.0          # multi-position: the still stretch at the start, s (8.4)\n\
             # static_s = [[40.0, 52.5]]     # multi-position: the still intervals, s since the start"
        );
    }
    let _ = writeln!(
        t,
        "# days = 2                      # UTC days the session spans from its date\n"
    );
    theodolite.is_none() && lab.is_some() && track.is_none()
}

/// The channels of a counts CSV's value columns and the session's thermometers
/// (docs/formats.md 9.4): 1 to 3 count columns are channels 1, 2, ... in order; a
/// temperature log of as many columns has a thermometer each, of one column one for all,
/// and none is a session without a thermometer.
fn column_keys(t: &mut String, counts: &Found, temperature: Option<&Found>) {
    let n = counts.channels;
    match n {
        3 => {}
        1..=3 => {
            let list: Vec<String> = (1..=n).map(|c| c.to_string()).collect();
            let _ = writeln!(
                t,
                "adc_columns = [{}]            # {}'s {n} count column(s) are these channels",
                list.join(", "),
                counts.rel
            );
        }
        _ => {
            let _ = writeln!(
                t,
                "adc_columns = {FILL}          # {}'s {n} count columns: list the channel (1 to \
                 3) each holds, 0 for a column to skip, e.g. [1, 2, 3, 0]",
                counts.rel
            );
        }
    }
    match temperature.map(|x| x.channels) {
        None => {
            let _ = writeln!(
                t,
                "thermometers = \"none\"          # no temperature log: models without temperature \
                 terms only"
            );
        }
        Some(m) if m == n => {}
        Some(1) => {
            let _ = writeln!(
                t,
                "thermometers = \"one\"           # one temperature column for {n} count columns: \
                 every accelerometer's temperature"
            );
        }
        Some(m) => {
            let _ = writeln!(
                t,
                "thermometers = {FILL}          # \"each\" | \"one\" | \"none\": the temperature \
                 log has {m} columns, the counts log {n}"
            );
        }
    }
}

/// A comment line per file: its layout, time form, channels, rate and span.
fn list_files(t: &mut String, files: &[&Found]) {
    for f in files {
        let span = f.span_ns.map_or(String::new(), |(a, b)| match f.layout {
            Layout::Binary => " (times by the 10-bit week)".to_owned(),
            _ => format!(
                ", {} to {}",
                ingest::base::time::utc_iso(a),
                ingest::base::time::utc_iso(b)
            ),
        });
        let _ = writeln!(
            t,
            "# {}: {}{}, {} channel(s){}{span}",
            f.rel,
            f.layout.name(),
            f.time
                .map_or(String::new(), |x| format!(", times {}", x.name())),
            f.channels,
            f.rate_hz.map_or(String::new(), |r| format!(", {r:.4} Hz"))
        );
    }
}

/// How the session's samples are logged: a binary log, else a lab stream, else a counts
/// CSV, with their time forms (a stream counting from a start asks for it).
fn acquisition_keys(
    t: &mut String,
    binary: Option<&Found>,
    lab: Option<&Found>,
    counts: Option<&Found>,
) {
    if let Some(b) = binary {
        let _ = writeln!(t, "acquisition = {}", q(&b.rel));
    } else if let Some(l) = lab {
        let form = l.time.unwrap_or(TimeForm::S);
        let _ = writeln!(
            t,
            "adc_csv = {}\nadc_format = \"seconds\"\nadc_time = \"{}\"",
            q(&l.rel),
            form.name()
        );
        if form == TimeForm::S {
            let _ = writeln!(
                t,
                "start = {FILL}                # the time (ISO 8601, e.g. 2026-03-14T09:00:00Z) of the stream's t = 0"
            );
        }
    } else if let Some(c) = counts {
        let _ = writeln!(
            t,
            "adc_csv = {}\nadc_time = \"{}\"",
            q(&c.rel),
            c.time.unwrap_or(TimeForm::GpsWeekTow).name()
        );
    }
}

/// A session's kind: a theodolite log makes it a tilt table, a trajectory a survey; else
/// the user says which.
fn kind(theodolite: bool, trajectory: bool) -> String {
    if theodolite {
        "\"tilt-table\"".to_owned()
    } else if trajectory {
        "\"survey\"                # a trajectory: a survey reduced to gravity".to_owned()
    } else {
        format!(
            "{FILL}                # no theodolite log: \"multi-position\" (a triad calibrated) or \"survey\" (a calibration applied)"
        )
    }
}

/// A survey session's trajectory keys, and the `[survey]` table's, commented: how the
/// accelerometers sit in the vehicle and the ties are the experimenter's, in no log.
fn trajectory_keys(t: &mut String, tr: &Found, attitude: Option<&Found>) {
    let format = match tr.layout {
        Layout::Trajectory(TrajectoryFormat::Csv) => "csv",
        Layout::Trajectory(TrajectoryFormat::DgsLaptop) => "dgs-laptop",
        Layout::Trajectory(TrajectoryFormat::Nmea) => "nmea",
        _ => "rtklib",
    };
    if tr.layout == Layout::Trajectory(TrajectoryFormat::DgsLaptop) {
        // The meter's own gravity, its one channel, from the same file.
        let _ = writeln!(
            t,
            "adc_csv = {}
adc_format = \"dgs-laptop\"
thermometers = \"none\"",
            q(&tr.rel)
        );
    }
    let _ = writeln!(
        t,
        "trajectory = {}\ntrajectory_format = \"{format}\"",
        q(&tr.rel)
    );
    if let Some(form) = tr.time {
        let _ = writeln!(t, "trajectory_time = \"{}\"", form.name());
    }
    if let Some(a) = attitude {
        let form = a.time.unwrap_or(TimeForm::Iso);
        let _ = writeln!(
            t,
            "attitude = {}\nattitude_time = \"{}\"",
            q(&a.rel),
            form.name()
        );
    }
    let _ = writeln!(
        t,
        "# Then, once for the dataset (docs/formats.md 10):\n\
         # [survey]\n\
         # lever_arm_m = [0.0, 0.0, 0.0]  # from the GNSS antenna to the accelerometers, m (x forward, y right, z down)\n\
         # mounting_deg = [0.0, 0.0, 0.0] # roll, pitch, yaw of the accelerometers' body frame in the vehicle\n\
         # filter_s = 100.0               # the low-pass filter's cut-off period, s\n\
         # [[survey.tie]]                 # a still window at known gravity (one or more)\n\
         # time = \"2026-03-14T08:55:00Z\" # its centre\n\
         # duration_s = 300.0\n\
         # g_mgal = 980000.0              # absolute gravity at the accelerometers"
    );
}

/// The session's UTC date from its files' first absolute time, or a line to fill.
fn date(files: &[&Found]) -> String {
    let first = files
        .iter()
        .filter(|f| f.layout != Layout::Binary)
        .filter_map(|f| f.span_ns.map(|s| s.0))
        .min();
    match first {
        Some(ns) => format!("\"{}\"", &ingest::base::time::utc_iso(ns)[..10]),
        None => format!(
            "{FILL}                # YYYY-MM-DD (UTC) of the first sample: no log of the session \
             writes a calendar time (a binary log's 10-bit week repeats every 1024 weeks)"
        ),
    }
}

/// The theodolite log's time scale and unit, from its comments or values.
fn theodolite_keys(t: &mut String, th: &Found) {
    let c = &th.comments;
    let scale = ["utc", "gpst", "tai"]
        .iter()
        .find(|s| c.contains(*s))
        .map(|s| format!("\"{}\"", s.to_uppercase()));
    let scale = scale.unwrap_or_else(|| {
        format!(
            "{FILL}                # \"UTC\" | \"GPST\" | \"TAI\": the scale of its zone-less times"
        )
    });
    let unit = if c.contains("gon") {
        "\"gon\"".to_owned()
    } else if c.contains("deg") {
        "\"deg\"".to_owned()
    } else if th.magnitude > 360.0 {
        "\"gon\"                  # readings above 360".to_owned()
    } else {
        format!(
            "{FILL}                # \"deg\" | \"gon\": readings up to {:.4} could be either",
            th.magnitude
        )
    };
    let _ = writeln!(
        t,
        "theodolite = {}\ntheodolite_time = \"iso\"\ntime_scale = {scale}\ntheodolite_unit = {unit}",
        q(&th.rel)
    );
}
