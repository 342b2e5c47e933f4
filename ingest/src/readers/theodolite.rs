//! Reader of the theodolite log (docs/formats.md section 5): station, time in the session's time
//! scale, zenith distance in the session's unit. Times leave as GPS time; angles as radians.

use crate::base::time::TimeReader;
use crate::contract::ingest_ledger::{FileLedger, reason};
use crate::contract::manifest::{AngleUnit, ResolvedSession};
use crate::contract::tables::theodolite::Logged;
use crate::error::{Error, Result};
use crate::readers::lines::{read_lines, strip_comment};
use std::path::Path;

/// One reading from a data line (`station time... dz`, white space between): Err with the
/// field and what is wrong.
fn parse_reading(
    line_no: u64,
    line: &[u8],
    time: &mut TimeReader,
    unit: AngleUnit,
) -> std::result::Result<Logged, (&'static str, String)> {
    let time_fields = time.form.fields();
    let text = std::str::from_utf8(line).map_err(|_| ("line", "not UTF-8".to_owned()))?;
    let f: Vec<&str> = text.split_whitespace().collect();
    if f.len() != 2 + time_fields {
        return Err((
            "line",
            format!(
                "{} fields, expected {} (station, the time as \"{}\", dz)",
                f.len(),
                2 + time_fields,
                time.form.name()
            ),
        ));
    }
    let time_text = f[1..1 + time_fields].join(" ");
    let time_bytes: Vec<&[u8]> = f[1..1 + time_fields].iter().map(|x| x.as_bytes()).collect();
    let time_gps_ns = time.read(&time_bytes)?;
    let dz_field = f[1 + time_fields];
    let dz_value: f64 = dz_field
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite())
        .ok_or_else(|| ("dz", format!("`{dz_field}` is not a number")))?;
    if !(0.0..unit.full_turn()).contains(&dz_value) {
        return Err((
            "dz",
            format!(
                "{dz_value} is outside [0, {}) {}",
                unit.full_turn(),
                unit.name()
            ),
        ));
    }
    let line = u32::try_from(line_no).map_err(|_| ("line", "more than 2^32 lines".to_owned()))?;
    Ok(Logged {
        station: f[0].to_owned(),
        time_gps_ns,
        dz_rad: unit.to_rad(dz_value),
        dz_value,
        time_as_read: time_text,
        line,
    })
}

/// Reads the theodolite log of `session`. A malformed line is an error (or, with
/// `skip_bad_lines`, counted); a reading timed outside the session's range
/// ([`ResolvedSession::gps_range_ns`]) is rejected as outside the session, counted and listed.
pub fn read_theodolite(
    session: &ResolvedSession,
    path: &Path,
    skip_bad_lines: bool,
    ledger: &mut FileLedger,
    progress: &indicatif::ProgressBar,
) -> Result<Vec<Logged>> {
    let mut time = session.times.reader(session.times.theodolite);
    let unit = session.session.theodolite_unit;
    let range = session.gps_range_ns();
    let mut out = Vec::new();
    let mut other = 0u64;
    let (sha, bytes) = read_lines(path, progress, |line_no, raw| {
        let line = strip_comment(raw);
        if line.is_empty() {
            other += 1;
            return Ok(());
        }
        match parse_reading(line_no, line, &mut time, unit) {
            Ok(r) if r.time_gps_ns < range.0 || r.time_gps_ns >= range.1 => {
                ledger.reject(
                    format!("line {line_no}"),
                    reason::OUTSIDE_SESSION,
                    format!(
                        "time {} is outside the session's {} day(s) from {}",
                        r.time_as_read, session.session.days, session.session.date
                    ),
                );
            }
            Ok(r) => out.push(r),
            Err((field, message)) if skip_bad_lines => {
                ledger.reject(
                    format!("line {line_no}"),
                    reason::MALFORMED,
                    format!("{field}: {message}"),
                );
            }
            Err((field, message)) => {
                return Err(Error::Line {
                    path: path.to_path_buf(),
                    line: line_no,
                    field: field.to_owned(),
                    message,
                });
            }
        }
        Ok(())
    })?;
    ledger.accept("reading", out.len() as u64);
    ledger.sha256 = sha;
    ledger.bytes = bytes;
    ledger.comment_blank_or_header_lines = Some(other);
    Ok(out)
}
