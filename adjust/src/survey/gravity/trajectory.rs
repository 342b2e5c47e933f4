//! GNSS trajectories (docs/formats.md 10.1): RTKLIB's solution file (`.pos`, geodetic
//! latitude, longitude and ellipsoidal height with their sds; times in GPST or UTC as its
//! header says, as a calendar or as GPS week and seconds) or a CSV (`time,lat_deg,lon_deg,
//! h_m[,sd_n_m,sd_e_m,sd_u_m]`, the time in any form of docs/formats.md 9.1). A line that
//! breaks the format is an error naming file, line and field; an XYZ-ECEF or
//! degrees-minutes-seconds solution is refused as a whole, with what would work. No
//! resampling here: epochs as written, in time order.

use super::{BadLine, GravityError, set_aside};
use ingest::base::time::{TimeForm, TimeReader};
use ingest::contract::manifest::TimeScale;
use std::collections::BTreeMap;
use std::io::BufRead;
use std::path::Path;

/// A trajectory's epochs, as columns.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    /// GPS time, ns.
    pub time_gps_ns: Vec<i64>,
    /// Geodetic latitude, deg.
    pub latitude_deg: Vec<f64>,
    /// Longitude, deg.
    pub longitude_deg: Vec<f64>,
    /// Ellipsoidal height, m.
    pub height_m: Vec<f64>,
    /// Sds north, east, up (m), where the file gives them.
    pub sd_neu_m: Vec<Option<[f64; 3]>>,
    /// The file's line of each epoch.
    pub line: Vec<u64>,
    /// Lines set aside (`--skip-bad-lines`).
    pub bad_lines: Vec<BadLine>,
}

impl Trajectory {
    fn push(&mut self, t: i64, llh: [f64; 3], sd: Option<[f64; 3]>, line: u64) {
        self.time_gps_ns.push(t);
        self.latitude_deg.push(llh[0]);
        self.longitude_deg.push(llh[1]);
        self.height_m.push(llh[2]);
        self.sd_neu_m.push(sd);
        self.line.push(line);
    }
}

pub(super) fn bad(path: &Path, line: u64, field: &str, message: String) -> GravityError {
    GravityError::Line {
        path: path.to_path_buf(),
        line,
        field: field.to_owned(),
        message,
    }
}

/// A geodetic position's three numbers, checked: latitude in [-90, 90], longitude in
/// [-180, 360], height within 100 km of the ellipsoid.
fn position(path: &Path, line: u64, f: &[&str]) -> Result<[f64; 3], GravityError> {
    let names = ["latitude", "longitude", "height"];
    let limits = [(-90.0, 90.0), (-180.0, 360.0), (-1.0e4, 1.0e5)];
    three_within(path, line, f, (names, limits, ""))
}

/// A line's first three fields, each a finite number within its closed range: `names`,
/// `limits` and the unit the message gives after the range ("" or " deg").
pub(super) fn three_within(
    path: &Path,
    line: u64,
    f: &[&str],
    (names, limits, unit): ([&str; 3], [(f64, f64); 3], &str),
) -> Result<[f64; 3], GravityError> {
    let mut out = [0.0; 3];
    for k in 0..3 {
        let v: f64 = f[k]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| bad(path, line, names[k], format!("`{}` is not a number", f[k])))?;
        let (lo, hi) = limits[k];
        if !(lo..=hi).contains(&v) {
            let message = format!("{v} is outside [{lo}, {hi}]{unit}");
            return Err(bad(path, line, names[k], message));
        }
        out[k] = v;
    }
    Ok(out)
}

/// Three sds (m), each finite and not negative.
fn sds(path: &Path, line: u64, f: &[&str]) -> Result<[f64; 3], GravityError> {
    let mut out = [0.0; 3];
    for (k, name) in ["sd_n", "sd_e", "sd_u"].iter().enumerate() {
        out[k] = f[k]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && *v >= 0.0)
            .ok_or_else(|| bad(path, line, name, format!("`{}` is not an sd in m", f[k])))?;
    }
    Ok(out)
}

/// The file's lines, numbered from 1, without the line end (`\n` or `\r\n`) and, on the
/// first, a UTF-8 byte-order mark; a line that is not UTF-8 is a line error (field `line`,
/// the byte offset in it), which `--skip-bad-lines` sets aside as any other.
pub(super) fn numbered_lines(
    path: &Path,
) -> Result<impl Iterator<Item = (u64, Result<String, GravityError>)>, GravityError> {
    let file = std::fs::File::open(path).map_err(|e| GravityError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let path = path.to_path_buf();
    Ok(std::io::BufReader::new(file)
        .split(b'\n')
        .enumerate()
        .map(move |(i, l)| {
            let line_no = i as u64 + 1;
            let l = l
                .map_err(|e| GravityError::File {
                    path: path.clone(),
                    message: format!("line {line_no}: {e}"),
                })
                .and_then(|b| line_text(&path, line_no, &b).map(str::to_owned));
            (line_no, l)
        }))
}

/// Reads RTKLIB's `.pos` solution file; with `skip`, a line that breaks the format is set
/// aside instead of failing the file.
pub fn read_rtklib(path: &Path, skip: bool) -> Result<Trajectory, GravityError> {
    let mut out = Trajectory::default();
    out.bad_lines = for_each_rtklib(path, skip, |line, t, llh, sd| {
        out.push(t, llh, sd, line);
        Ok(())
    })?;
    Ok(out)
}

/// Calls `f` with each epoch of RTKLIB's `.pos` solution file at `path` in file order (its
/// line, time, position and sds); with `skip`, a line that breaks the format is set aside
/// (returned) instead of failing the file.
pub fn for_each_rtklib(
    path: &Path,
    skip: bool,
    mut f: impl FnMut(u64, i64, [f64; 3], Option<[f64; 3]>) -> Result<(), GravityError>,
) -> Result<Vec<BadLine>, GravityError> {
    let mut bad_lines = Vec::new();
    let mut scale: Option<Scale> = None;
    for (line_no, l) in numbered_lines(path)? {
        let l = match l {
            Ok(l) => l,
            Err(e) => {
                set_aside(e, skip, &mut bad_lines)?;
                continue;
            }
        };
        let t = l.trim();
        if let Some(h) = t.strip_prefix('%') {
            if h.contains("x-ecef") {
                return Err(GravityError::File {
                    path: path.to_path_buf(),
                    message: "an XYZ-ECEF solution: gravcal reads latitude, longitude and \
                              ellipsoidal height (RTKLIB's `out-solformat = llh`)"
                        .to_owned(),
                });
            }
            if h.contains("latitude") {
                scale = Some(header_scale(path, line_no, h)?);
            }
            continue;
        }
        if t.is_empty() {
            continue;
        }
        match rtklib_line(path, line_no, t, scale) {
            Ok((time, llh, sd)) => f(line_no, time, llh, Some(sd))?,
            Err(e) => set_aside(e, skip, &mut bad_lines)?,
        }
    }
    Ok(bad_lines)
}

/// The time system an RTKLIB file writes its times in (`out-timesys`), from its column
/// header's first word: GPST, UTC, JST (UTC + 9 h, RTKLIB's `jst`) or TAI.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scale {
    scale: TimeScale,
    /// The ISO offset of its calendar times from UTC (`+09:00` for JST), where not UTC.
    zone: Option<&'static str>,
    name: &'static str,
}

/// The time system of RTKLIB's column header `h` (its `%` stripped), or an error naming the
/// file, the line and the word it does not know.
fn header_scale(path: &Path, line_no: u64, h: &str) -> Result<Scale, GravityError> {
    let word = h.split_whitespace().next().unwrap_or("");
    let (scale, zone, name) = match word {
        "GPST" => (TimeScale::Gpst, None, "GPST"),
        "UTC" => (TimeScale::Utc, None, "UTC"),
        "JST" => (TimeScale::Utc, Some("+09:00"), "JST"),
        "TAI" => (TimeScale::Tai, None, "TAI"),
        other => {
            return Err(bad(
                path,
                line_no,
                "header",
                format!(
                    "the column header names the time system `{other}`: gravcal reads GPST, \
                     UTC, JST and TAI"
                ),
            ));
        }
    };
    Ok(Scale { scale, zone, name })
}

/// One solution line of an RTKLIB file: time, position, sds.
fn rtklib_line(
    path: &Path,
    line_no: u64,
    t: &str,
    scale: Option<Scale>,
) -> Result<(i64, [f64; 3], [f64; 3]), GravityError> {
    let Some(Scale { scale, zone, name }) = scale else {
        return Err(bad(
            path,
            line_no,
            "header",
            "a solution line before RTKLIB's column header (`%  GPST  latitude(deg) ...`)"
                .to_owned(),
        ));
    };
    let f: Vec<&str> = t.split_whitespace().collect();
    if f.len() < 10 {
        return Err(bad(
            path,
            line_no,
            "line",
            format!(
                "{} fields: expected time (2), latitude, longitude, height, Q, ns, sdn, \
                 sde, sdu (degrees-minutes-seconds solutions are not read: \
                 `out-solformat = llh` with decimal degrees)",
                f.len()
            ),
        ));
    }
    let time = if f[0].contains('/') {
        let iso = format!("{}T{}{}", f[0].replace('/', "-"), f[1], zone.unwrap_or(""));
        TimeReader::new(TimeForm::Iso, scale, None).read(&[iso.as_bytes()])
    } else if zone.is_some() {
        return Err(bad(
            path,
            line_no,
            "time",
            format!("GPS week and seconds in {name}: a week counts GPS time, never {name}"),
        ));
    } else {
        TimeReader::new(TimeForm::GpsWeekTow, scale, None).read(&[f[0].as_bytes(), f[1].as_bytes()])
    }
    .map_err(|(field, m)| bad(path, line_no, field, m))?;
    let llh = position(path, line_no, &f[2..5])?;
    let sd = sds(path, line_no, &f[7..10])?;
    Ok((time, llh, sd))
}

/// Reads a CSV trajectory whose times `time` reads; with `skip`, a line that breaks the
/// format is set aside instead of failing the file.
pub fn read_csv(path: &Path, time: TimeReader, skip: bool) -> Result<Trajectory, GravityError> {
    let mut out = Trajectory::default();
    out.bad_lines = for_each_csv(path, time, skip, |line, t, llh, sd| {
        out.push(t, llh, sd, line);
        Ok(())
    })?;
    Ok(out)
}

/// Reads a DGS laptop file's navigation (docs/formats.md 11.1): each line's latitude and
/// longitude through the parser ingest reads its gravity with ([`ingest::readers::dgs`]), at height
/// 0 (the file has none: the sea surface), without sds.
pub fn read_dgs_laptop(path: &Path, skip: bool) -> Result<Trajectory, GravityError> {
    let mut out = Trajectory::default();
    out.bad_lines = for_each_dgs_laptop(path, skip, |line, r| {
        out.push(r.gps_ns, [r.latitude_deg, r.longitude_deg, 0.0], None, line);
        Ok(())
    })?;
    Ok(out)
}

/// Calls `f` with each line of a DGS laptop file read (its number and the line: time,
/// position, the meter's gravity, monitors and status), in file order, the lines parsed on
/// the cores ([`for_each_line_parsed`]); with `skip`, a line that breaks the format is set
/// aside.
pub fn for_each_dgs_laptop(
    path: &Path,
    skip: bool,
    mut f: impl FnMut(u64, &ingest::readers::dgs::LaptopLine) -> Result<(), GravityError>,
) -> Result<Vec<BadLine>, GravityError> {
    let mut bad_lines = Vec::new();
    let parse = |line_no: u64, l: Result<&str, GravityError>| {
        l.and_then(|l| {
            if l.trim().is_empty() {
                return Ok(None);
            }
            ingest::readers::dgs::split(l.as_bytes())
                .and_then(|fields| ingest::readers::dgs::parse_laptop(&fields))
                .map(Some)
                .map_err(|(field, m)| bad(path, line_no, field, m))
        })
    };
    for_each_line_parsed(path, parse, |line_no, parsed| match parsed {
        Ok(Some(r)) => f(line_no, &r),
        Ok(None) => Ok(()),
        Err(e) => set_aside(e, skip, &mut bad_lines),
    })?;
    Ok(bad_lines)
}

/// The bytes [`for_each_line_parsed`] reads at a time: a chunk's lines and what they parse
/// to are held at once.
const CHUNK_BYTES: usize = 1 << 20;

/// Calls `f` in file order with each line of `path` as `parse` reads it: its number, from
/// one, and its text, or its error, as [`numbered_lines`] gives them. The lines are read a
/// chunk of about [`CHUNK_BYTES`] at a time, and each chunk's are parsed on the cores:
/// this is for a format whose line parses alone, without what the lines before it said.
pub(super) fn for_each_line_parsed<T: Send>(
    path: &Path,
    parse: impl Fn(u64, Result<&str, GravityError>) -> T + Sync,
    mut f: impl FnMut(u64, T) -> Result<(), GravityError>,
) -> Result<(), GravityError> {
    use rayon::prelude::*;
    use std::io::Read;
    let io = |line: u64, e: std::io::Error| GravityError::File {
        path: path.to_path_buf(),
        message: format!("line {line}: {e}"),
    };
    let mut file = std::fs::File::open(path).map_err(|e| GravityError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let (mut buf, mut next_line, mut eof) = (Vec::new(), 1u64, false);
    while !eof {
        let held = buf.len();
        buf.resize(held + CHUNK_BYTES, 0);
        let mut got = 0;
        while held + got < buf.len() {
            match file.read(&mut buf[held + got..]) {
                Ok(0) => break,
                Ok(n) => got += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(io(next_line, e)),
            }
        }
        buf.truncate(held + got);
        eof = got == 0;
        let end = match memchr::memrchr(b'\n', &buf) {
            _ if eof => buf.len(),
            Some(k) => k + 1,
            None => continue, // a line longer than the chunk: read on
        };
        let lines = lines_of(&buf[..end], next_line);
        let parsed: Vec<T> = lines
            .par_iter()
            .with_min_len(1024)
            .map(|&(no, l)| parse(no, line_text(path, no, l)))
            .collect();
        for (&(no, _), p) in lines.iter().zip(parsed) {
            f(no, p)?;
        }
        next_line += lines.len() as u64;
        buf.drain(..end);
    }
    Ok(())
}

/// The lines of `bytes` (each ended by `\n`, the last perhaps not), numbered from `first`.
fn lines_of(bytes: &[u8], first: u64) -> Vec<(u64, &[u8])> {
    let mut lines = Vec::new();
    let mut start = 0;
    for end in memchr::memchr_iter(b'\n', bytes) {
        lines.push((first + lines.len() as u64, &bytes[start..end]));
        start = end + 1;
    }
    if start < bytes.len() {
        lines.push((first + lines.len() as u64, &bytes[start..]));
    }
    lines
}

/// Line `line_no`'s text (the bytes before its `\n`): without a `\r` at its end and, on
/// the first, a UTF-8 byte-order mark; not UTF-8, a line error naming the byte.
fn line_text<'a>(path: &Path, line_no: u64, mut l: &'a [u8]) -> Result<&'a str, GravityError> {
    if let Some(rest) = l.strip_suffix(b"\r") {
        l = rest;
    }
    if line_no == 1 {
        l = l.strip_prefix(ingest::BOM).unwrap_or(l);
    }
    std::str::from_utf8(l).map_err(|e| {
        bad(
            path,
            line_no,
            "line",
            format!("not UTF-8 at byte {} of the line", e.valid_up_to()),
        )
    })
}

/// What an NMEA file's first pass finds: whether its fixes come from GGA sentences (else
/// RMC's), and whether every GGA gives the geoid's separation (then the heights are
/// ellipsoidal, altitude plus separation; else above sea level, the altitude alone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NmeaScan {
    /// GGA sentences carry the fixes.
    pub gga: bool,
    /// The heights' datum.
    pub heights: ingest::contract::survey::Heights,
}

/// An NMEA file's first pass ([`NmeaScan`]); lines that do not parse are left to
/// [`for_each_nmea`].
pub fn nmea_scan(path: &Path) -> Result<NmeaScan, GravityError> {
    use ingest::readers::nmea::{Sentence, find, parse};
    let (mut gga, mut separated) = (false, true);
    for (_, l) in numbered_lines(path)? {
        let Ok(l) = l else { continue };
        if let Some(Ok(Sentence::Gga(g))) = find(l.as_bytes()).map(parse) {
            gga = true;
            separated &= g.separation_m.is_some() && g.altitude_m.is_some();
        }
    }
    Ok(NmeaScan {
        gga,
        heights: if gga && separated {
            ingest::contract::survey::Heights::Ellipsoidal
        } else {
            ingest::contract::survey::Heights::SeaLevel
        },
    })
}

/// Reads an NMEA file's fixes ([`for_each_nmea`]).
pub fn read_nmea(
    path: &Path,
    session_date: (i32, u8, u8),
    skip: bool,
) -> Result<Trajectory, GravityError> {
    let mut out = Trajectory::default();
    let scan = nmea_scan(path)?;
    out.bad_lines = for_each_nmea(path, scan, session_date, skip, |line, t, llh, sd| {
        out.push(t, llh, sd, line);
        Ok(())
    })?;
    Ok(out)
}

/// Calls `f` with each fix of an NMEA file (docs/formats.md 10.1): its GGA sentences' (or,
/// in a file without GGA, its valid RMC's), at the UTC time of day the sentence gives on the
/// date the last ZDA or RMC before it gave (the session's date before any), a day on when the
/// time of day falls back by more than 12 h; the height as `scan` (the file's
/// [`nmea_scan`]) says (0 for RMC's); no sds. A sentence whose checksum or fields do not
/// hold, and a fix that is none (GGA quality 0, RMC status V), is a bad line, set aside with
/// `skip`.
pub fn for_each_nmea(
    path: &Path,
    scan: NmeaScan,
    session_date: (i32, u8, u8),
    skip: bool,
    mut f: impl FnMut(u64, i64, [f64; 3], Option<[f64; 3]>) -> Result<(), GravityError>,
) -> Result<Vec<BadLine>, GravityError> {
    let mut clock = NmeaClock::new(session_date);
    let mut bad_lines = Vec::new();
    for (line_no, l) in numbered_lines(path)? {
        let fix = l.and_then(|l| {
            let Some(sentence) = ingest::readers::nmea::find(l.as_bytes()) else {
                return Ok(None);
            };
            let sentence = ingest::readers::nmea::parse(sentence)
                .map_err(|(field, m)| bad(path, line_no, field, m))?;
            nmea_fix(sentence, scan, &mut clock).map_err(|(field, m)| bad(path, line_no, field, m))
        });
        match fix {
            Ok(Some((t, llh))) => f(line_no, t, llh, None)?,
            Ok(None) => {}
            Err(e) => set_aside(e, skip, &mut bad_lines)?,
        }
    }
    Ok(bad_lines)
}

/// The UTC date an NMEA file's fixes are on, as its sentences go by.
struct NmeaClock {
    /// GPS time of the date's midnight, ns.
    day_gps_ns: i64,
    /// The last fix's time of day on it, ns.
    last_of_day: Option<i64>,
}

impl NmeaClock {
    fn new(date: (i32, u8, u8)) -> Self {
        let mut c = NmeaClock {
            day_gps_ns: 0,
            last_of_day: None,
        };
        c.date(date);
        c
    }

    /// A date sentence's (ZDA, RMC) date.
    fn date(&mut self, d: (i32, u8, u8)) {
        self.day_gps_ns =
            ingest::base::time::gps_ns(ingest::base::time::Calendar::midnight(d), TimeScale::Utc)
                .unwrap_or(i64::MIN);
        self.last_of_day = None;
    }

    /// A fix's GPS time from its time of day: a day on when the time of day falls back by
    /// more than 12 h with no date sentence since.
    fn at(&mut self, time_of_day_ns: i64) -> i64 {
        if self
            .last_of_day
            .is_some_and(|t| time_of_day_ns + 43_200_000_000_000 < t)
        {
            self.day_gps_ns += 86_400_000_000_000;
        }
        self.last_of_day = Some(time_of_day_ns);
        self.day_gps_ns + time_of_day_ns
    }
}

/// The fix a sentence gives (GPS time, position), if any, as [`for_each_nmea`] takes them;
/// a fix that is none, or a height beyond [-10 km, 100 km], is refused naming the field.
fn nmea_fix(
    sentence: ingest::readers::nmea::Sentence,
    scan: NmeaScan,
    clock: &mut NmeaClock,
) -> Result<Option<(i64, [f64; 3])>, ingest::readers::nmea::Bad> {
    use ingest::readers::nmea::Sentence;
    let no_fix = |what: &str| ("quality", format!("{what}: no fix"));
    let (time_of_day_ns, llh) = match sentence {
        Sentence::Zda { date, .. } => {
            clock.date(date);
            return Ok(None);
        }
        Sentence::Rmc {
            date,
            valid,
            position,
            time_of_day_ns,
        } => {
            clock.date(date);
            match (scan.gga, valid) {
                (true, _) => return Ok(None),
                (false, true) => (time_of_day_ns, [position[0], position[1], 0.0]),
                (false, false) => return Err(no_fix("RMC status V")),
            }
        }
        Sentence::Gga(g) if g.quality == 0 => return Err(no_fix("GGA quality 0")),
        Sentence::Gga(g) => {
            let ellipsoidal = scan.heights == ingest::contract::survey::Heights::Ellipsoidal;
            let h = match (g.altitude_m, g.separation_m) {
                (Some(a), Some(n)) if ellipsoidal => a + n,
                (Some(a), _) => a,
                (None, _) => 0.0,
            };
            (g.time_of_day_ns, [g.position[0], g.position[1], h])
        }
        Sentence::Other => return Ok(None),
    };
    if !(-1.0e4..=1.0e5).contains(&llh[2]) {
        return Err((
            "altitude",
            format!("{} m is not a height within [-10000, 100000] m", llh[2]),
        ));
    }
    Ok(Some((clock.at(time_of_day_ns), llh)))
}

/// Calls `f` with each epoch of a CSV trajectory whose times `time` reads, in file order
/// (its line, time, position and sds if given); with `skip`, a line that breaks the format
/// is set aside (returned) instead of failing the file.
pub fn for_each_csv(
    path: &Path,
    mut time: TimeReader,
    skip: bool,
    mut f: impl FnMut(u64, i64, [f64; 3], Option<[f64; 3]>) -> Result<(), GravityError>,
) -> Result<Vec<BadLine>, GravityError> {
    let mut bad_lines = Vec::new();
    for_each_csv_line(path, |line_no, fields| {
        match fields.and_then(|fl| epoch_line((path, line_no), fl, &mut time, &POSITION_COLUMNS)) {
            Ok((tns, llh, sd)) => f(line_no, tns, llh, sd)?,
            Err(e) => set_aside(e, skip, &mut bad_lines)?,
        }
        Ok(())
    })?;
    Ok(bad_lines)
}

/// Calls `f` with each data line of a CSV (a trajectory's, an attitude's): its number
/// (from 1) and its comma-separated fields, trimmed, or the line's error (not UTF-8); `#` starts a comment, blank lines are
/// passed over, and a first line whose first field begins `time` is the header.
pub(super) fn for_each_csv_line(
    path: &Path,
    mut f: impl FnMut(u64, Result<&[&str], GravityError>) -> Result<(), GravityError>,
) -> Result<(), GravityError> {
    let mut header_seen = false;
    for (line_no, l) in numbered_lines(path)? {
        let l = match l {
            Ok(l) => l,
            Err(e) => {
                f(line_no, Err(e))?;
                continue;
            }
        };
        let t = l.split('#').next().unwrap_or("").trim();
        if t.is_empty() {
            continue;
        }
        let fields: Vec<&str> = t.split(',').map(str::trim).collect();
        if !header_seen {
            header_seen = true;
            if fields.first().is_some_and(|x| x.starts_with("time")) {
                continue;
            }
        }
        f(line_no, Ok(&fields))?;
    }
    Ok(())
}

/// An epoch's three values (a position; or heading, pitch and roll) and their sds if given.
pub(super) type Values = ([f64; 3], Option<[f64; 3]>);

/// An epoch as a reader gives it: its GPS time (ns), its three values and their sds if given.
pub(super) type Epoch = (i64, [f64; 3], Option<[f64; 3]>);

/// Counts one more epoch the time gate dropped for `why`.
pub(super) fn count_dropped(dropped: &mut BTreeMap<String, u64>, why: &str) {
    *dropped.entry(why.to_owned()).or_insert(0) += 1;
}

/// A value's or an sd's check: the line's three fields (its file and line for the error)
/// read into numbers.
type Check = fn(&Path, u64, &[&str]) -> Result<[f64; 3], GravityError>;

/// What a CSV of epochs holds after its time: the fields named for an error, the check of
/// the three values and of their sds.
pub(super) struct Columns {
    /// The line's fields, as an error names them.
    pub expected: &'static str,
    /// The values' check.
    pub values: Check,
    /// The sds' check.
    pub sds: Check,
}

/// A CSV trajectory's: time, position, sds if given.
const POSITION_COLUMNS: Columns = Columns {
    expected: "time, lat_deg, lon_deg, h_m and optionally sd_n_m, sd_e_m, sd_u_m",
    values: position,
    sds,
};

/// One line of a CSV of epochs whose fields after the time `columns` says: the epoch.
pub(super) fn epoch_line(
    (path, line_no): (&Path, u64),
    f: &[&str],
    time: &mut TimeReader,
    columns: &Columns,
) -> Result<Epoch, GravityError> {
    let (tns, values, sd) = timed_fields(path, line_no, f, time, columns.expected)?;
    let values = (columns.values)(path, line_no, values)?;
    let sd = sd.map(|x| (columns.sds)(path, line_no, x)).transpose()?;
    Ok((tns, values, sd))
}

/// A CSV line's time (GPS ns), its three values, and their three sds where given.
pub(super) type TimedFields<'a, 'b> = (i64, &'a [&'b str], Option<&'a [&'b str]>);

/// A CSV line of epochs (a trajectory's, an attitude's): its time, read by `time`, then its
/// three values and, where given, their three sds; another number of fields is an error
/// naming what was `expected`.
pub(super) fn timed_fields<'a, 'b>(
    path: &Path,
    line_no: u64,
    f: &'a [&'b str],
    time: &mut TimeReader,
    expected: &str,
) -> Result<TimedFields<'a, 'b>, GravityError> {
    let n = time.form.fields();
    if f.len() != n + 3 && f.len() != n + 6 {
        return Err(bad(
            path,
            line_no,
            "line",
            format!("{} fields: expected {expected}", f.len()),
        ));
    }
    let bytes: Vec<&[u8]> = f[..n].iter().map(|x| x.as_bytes()).collect();
    let tns = time
        .read(&bytes)
        .map_err(|(field, m)| bad(path, line_no, field, m))?;
    let sd = (f.len() == n + 6).then(|| &f[n + 3..]);
    Ok((tns, &f[n..n + 3], sd))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(text: &str) -> (tempfile::TempDir, std::path::PathBuf) {
        super::super::test_logs::written("t.pos", text)
    }

    /// The lines read a chunk at a time and parsed on the cores are the lines read one at a
    /// time, numbered alike, with the same errors: CR-LF ends, a byte-order mark, a line
    /// not UTF-8, no newline at the end, blank lines, a line longer than a chunk and a file
    /// of several chunks.
    #[test]
    fn lines_parsed_a_chunk_at_a_time_are_the_lines_one_at_a_time() {
        let long = "x".repeat(CHUNK_BYTES + 17);
        let many: String = (0..200_000).map(|k| format!("{k},{}\r\n", k * 7)).collect();
        let mut contents: Vec<Vec<u8>> = [
            "",
            "\n",
            "a",
            "a\n",
            "a\n\n\nb",
            "\u{feff}first\r\nsecond\r\n\u{feff}third",
            &format!("one\n{long}\nthree\n"),
            &many,
        ]
        .iter()
        .map(|s| s.as_bytes().to_vec())
        .collect();
        contents.push(b"ok\nnot \xff utf-8\nok again".to_vec());
        for bytes in contents {
            let d = tempfile::tempdir().expect("tempdir");
            let p = d.path().join("lines.txt");
            std::fs::write(&p, &bytes).expect("write");
            let one: Vec<(u64, String)> = numbered_lines(&p)
                .expect("opened")
                .map(|(no, l)| (no, l.unwrap_or_else(|e| format!("error {e}"))))
                .collect();
            let mut chunked = Vec::new();
            for_each_line_parsed(
                &p,
                |no, l| (no, l.map_or_else(|e| format!("error {e}"), str::to_owned)),
                |no, parsed| {
                    assert_eq!(no, parsed.0);
                    chunked.push(parsed);
                    Ok(())
                },
            )
            .expect("read");
            assert_eq!(chunked.len(), one.len());
            assert!(
                chunked == one,
                "{:?}",
                String::from_utf8_lossy(&bytes[..bytes.len().min(40)])
            );
        }
    }

    const HEADER: &str = "% program   : RTKPOST ver.2.4.3\n%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n";

    #[test]
    fn rtklib_calendar_and_week_times_agree() {
        let (_d, p) = write(&format!(
            "{HEADER}2026/03/14 09:12:03.500   48.016600000    0.157600000    60.1230   1   9   0.0040   0.0030   0.0090   0.0010  -0.0010   0.0020   0.00    0.0\n\
             2409 551523.600   48.016600100    0.157600100    60.1240   1   9   0.0040   0.0030   0.0090   0.0010  -0.0010   0.0020   0.00    0.0\n"
        ));
        let t = read_rtklib(&p, false).expect("reads");
        assert_eq!(t.time_gps_ns.len(), 2);
        // 2026-03-14 is a Saturday of GPS week 2409: 09:12:03.5 is 6 d 33123.5 s in.
        assert_eq!(t.time_gps_ns[1] - t.time_gps_ns[0], 100_000_000);
        assert_eq!(t.sd_neu_m[0], Some([0.004, 0.003, 0.009]));
        assert!((t.height_m[0] - 60.123).abs() < 1e-12);
    }

    /// The same instant written in each time system RTKLIB's `out-timesys` offers is read as
    /// one GPS time: JST nine hours ahead of UTC, UTC 18 s behind GPST in 2026, TAI 19 s
    /// ahead of GPST; a time system gravcal does not know is named.
    #[test]
    fn every_time_system_of_the_header_is_read_or_named() {
        let header = |word: &str| HEADER.replace("%  GPST ", &format!("%  {word} "));
        let rest = "   48.0166    0.1576   60.1230   1   9   0.004   0.003   0.009   0.001  \
                    -0.001   0.002   0.00    0.0";
        let mut times = Vec::new();
        for (word, time) in [
            ("GPST", "2026/03/14 09:12:21.500"),
            ("UTC", "2026/03/14 09:12:03.500"),
            ("JST", "2026/03/14 18:12:03.500"),
            ("TAI", "2026/03/14 09:12:40.500"),
        ] {
            let (_d, p) = write(&format!("{}{time}{rest}\n", header(word)));
            let t = read_rtklib(&p, false).unwrap_or_else(|e| panic!("{word}: {e}"));
            times.push(t.time_gps_ns[0]);
        }
        assert!(times.iter().all(|t| *t == times[0]), "{times:?}");
        let (_d, p) = write(&format!(
            "{}2026/03/14 09:12:03.500{rest}\n",
            header("LOCAL")
        ));
        let e = read_rtklib(&p, false).expect_err("unknown").to_string();
        assert!(
            e.contains("t.pos:2: header") && e.contains("`LOCAL`"),
            "{e}"
        );
    }

    /// A byte-order mark and CRLF line ends (a Windows editor's) are read as any file; a
    /// line that is not UTF-8 is an error naming it, set aside with `skip`.
    #[test]
    fn bom_crlf_and_bytes_that_are_not_text() {
        let line = "2026/03/14 09:12:03.500   48.0166    0.1576   60.1230   1   9   0.004   \
                    0.003   0.009   0.001  -0.001   0.002   0.00    0.0";
        let later = line.replace("03.500", "03.600");
        let text = format!("\u{feff}{HEADER}{line}\n{later}\n").replace('\n', "\r\n");
        let (_d, p) = write(&text);
        let t = read_rtklib(&p, false).expect("reads");
        assert_eq!(t.time_gps_ns.len(), 2);
        let mut bytes = format!("{HEADER}{line}\n").into_bytes();
        bytes.extend_from_slice(b"2026/03/14 09:12:03.550 \xff\xfe\n");
        bytes.extend_from_slice(format!("{later}\n").as_bytes());
        std::fs::write(&p, &bytes).expect("write");
        let e = read_rtklib(&p, false).expect_err("not UTF-8").to_string();
        assert!(e.contains("t.pos:4: line: not UTF-8 at byte 24"), "{e}");
        let t = read_rtklib(&p, true).expect("set aside");
        assert_eq!((t.time_gps_ns.len(), t.bad_lines.len()), (2, 1));
    }

    #[test]
    fn bad_lines_are_named() {
        let (_d, p) = write(&format!(
            "{HEADER}2026/03/14 09:12:03.500   98.0    0.1    60.1   1   9   0.004   0.003   0.009   0.001  -0.001   0.002   0.00    0.0\n"
        ));
        let e = read_rtklib(&p, false).expect_err("latitude 98").to_string();
        assert!(e.contains(":3: latitude: 98 is outside"), "{e}");
        let (_d, p) = write("%  GPST   x-ecef(m)  y-ecef(m)  z-ecef(m)\n");
        let e = read_rtklib(&p, false).expect_err("ecef").to_string();
        assert!(e.contains("XYZ-ECEF"), "{e}");
    }

    #[test]
    fn a_csv_in_unix_seconds() {
        let (_d, p) = super::super::test_logs::written(
            "t.csv",
            "time,lat_deg,lon_deg,h_m,sd_n_m,sd_e_m,sd_u_m\n1773479523.5,48.0,0.1,60.0,0.01,0.01,0.02\n1773479523.6,48.0,0.1,nan,0.01,0.01,0.02\n",
        );
        let r = super::super::test_logs::unix_utc();
        let e = read_csv(&p, r, false).expect_err("nan height").to_string();
        assert!(e.contains(":3: height:"), "{e}");
        // Set aside, the line before still read.
        let t = read_csv(&p, r, true).expect("skips");
        assert_eq!(t.time_gps_ns.len(), 1);
        assert_eq!(t.bad_lines.len(), 1);
        assert_eq!(
            (t.bad_lines[0].line, t.bad_lines[0].field.as_str()),
            (3, "height")
        );
    }
}
