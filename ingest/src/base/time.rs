//! Time scales: every time leaves ingest as GPS time, i64 nanoseconds since 1980-01-06.
//! Leap seconds come from hifitime's maintained table, not from a list written here.

use crate::contract::manifest::TimeScale;
use crate::readers::lines::text;
use hifitime::Epoch;

/// Nanoseconds in a GPS week.
pub const NS_PER_WEEK: i64 = 604_800 * 1_000_000_000;
/// Nanoseconds in a millisecond.
pub const NS_PER_MS: i64 = 1_000_000;

/// A calendar instant as written in a log, not yet tied to a time scale.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Calendar {
    /// Year.
    pub year: i32,
    /// Month 1..=12.
    pub month: u8,
    /// Day 1..=31.
    pub day: u8,
    /// Hour 0..=23.
    pub hour: u8,
    /// Minute 0..=59.
    pub minute: u8,
    /// Second 0..=60 (60 only in UTC, during a leap second).
    pub second: u8,
    /// Nanoseconds within the second.
    pub nanos: u32,
}

impl Calendar {
    /// 00:00:00 of `date` (year, month, day).
    pub fn midnight(date: (i32, u8, u8)) -> Self {
        Calendar {
            year: date.0,
            month: date.1,
            day: date.2,
            hour: 0,
            minute: 0,
            second: 0,
            nanos: 0,
        }
    }
}

/// How a text log writes its times (docs/formats.md 9.1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
pub enum TimeForm {
    /// Two fields: full GPS week, time of week in seconds.
    #[serde(rename = "gps_week_tow")]
    GpsWeekTow,
    /// One field: ISO 8601 calendar time, with `Z`, an offset, or no zone (then in the
    /// session's time scale).
    #[serde(rename = "iso")]
    Iso,
    /// One field: seconds since 1970-01-01T00:00:00 UTC.
    #[serde(rename = "unix_s")]
    UnixS,
    /// One field: seconds since the session's `start`.
    #[serde(rename = "s")]
    S,
}

impl TimeForm {
    /// The form as the manifest writes it.
    pub fn name(self) -> &'static str {
        match self {
            TimeForm::GpsWeekTow => "gps_week_tow",
            TimeForm::Iso => "iso",
            TimeForm::UnixS => "unix_s",
            TimeForm::S => "s",
        }
    }

    /// The fields a time takes.
    pub fn fields(self) -> usize {
        if self == TimeForm::GpsWeekTow { 2 } else { 1 }
    }
}

/// Reads times written in one [`TimeForm`] into GPS ns.
#[derive(Clone, Copy, Debug)]
pub struct TimeReader {
    /// The form.
    pub form: TimeForm,
    /// The scale of calendar times without a zone.
    pub scale: TimeScale,
    /// GPS time of the session's `start` (the zero of "s" times).
    pub start_gps_ns: Option<i64>,
    /// GPS minus Unix time over the UTC day last seen: (day since 1970, offset ns).
    utc_day: Option<(i64, i64)>,
    /// The ISO date last seen, whether it was in `Z`, and its midnight in GPS ns.
    iso_day: Option<([u8; 10], bool, i64)>,
}

/// Nanoseconds in a day.
const NS_PER_DAY: i64 = 86_400_000_000_000;

impl TimeReader {
    /// A reader of `form`, zone-less calendar times in `scale`, "s" times from `start_gps_ns`.
    pub fn new(form: TimeForm, scale: TimeScale, start_gps_ns: Option<i64>) -> Self {
        TimeReader {
            form,
            scale,
            start_gps_ns,
            utc_day: None,
            iso_day: None,
        }
    }

    /// An ISO time in the common case, `YYYY-MM-DDTHH:MM:SS[.fraction]` then `Z` or nothing,
    /// a second below 60: its date's midnight (in GPS ns, worked out once a day) plus the
    /// time of day. A leap second is inserted at the end of a UTC day, so it never lies
    /// between a UTC midnight and a time of day below 23:59:60. Anything else (an offset,
    /// a leap second, a malformed time) is `None`, left to the general parser.
    #[inline(always)]
    fn iso_fast(&mut self, field: &[u8]) -> Option<i64> {
        self.iso_fast_prefix(field)
            .and_then(|(t, end)| (end == field.len()).then_some(t))
    }

    /// [`Self::iso_fast`] of the time at the start of `line`: the time and where it ends
    /// (its fraction's digits and a `Z`), so that a reader of the line needs no search for
    /// the field's end.
    #[inline(always)]
    fn iso_fast_prefix(&mut self, line: &[u8]) -> Option<(i64, usize)> {
        if line.len() < 19
            || !matches!(line[10], b'T' | b' ')
            || line[13] != b':'
            || line[16] != b':'
        {
            return None;
        }
        let two = |i: usize| -> Option<i64> {
            let (a, c) = (line[i].wrapping_sub(b'0'), line[i + 1].wrapping_sub(b'0'));
            (a < 10 && c < 10).then(|| i64::from(a) * 10 + i64::from(c))
        };
        let (h, m, sec) = (two(11)?, two(14)?, two(17)?);
        if h > 23 || m > 59 || sec > 59 {
            return None;
        }
        let mut p = 19;
        let mut nanos = 0i64;
        if line.get(p) == Some(&b'.') {
            // The fraction's digits eight at a time ([`crate::readers::lines::digits`]).
            p += 1;
            let frac = crate::readers::lines::digits(line, &mut p, 9)?;
            nanos = frac * crate::readers::lines::POWERS_OF_TEN[9 - (p - 20)];
        }
        let zulu = matches!(line.get(p), Some(b'Z' | b'z'));
        p += usize::from(zulu);
        let date: [u8; 10] = line[..10].try_into().ok()?;
        let midnight = match self.iso_day {
            Some((d, z, ns)) if d == date && z == zulu => ns,
            _ => {
                let ymd = crate::contract::manifest::parse_date(std::str::from_utf8(&date).ok()?)?;
                let scale = if zulu { TimeScale::Utc } else { self.scale };
                let ns = gps_ns(Calendar::midnight(ymd), scale)?;
                self.iso_day = Some((date, zulu, ns));
                ns
            }
        };
        Some((
            midnight + ((h * 60 + m) * 60 + sec) * 1_000_000_000 + nanos,
            p,
        ))
    }

    /// The time at the start of a line whose form is one field followed by a comma, on the
    /// common path and without an error to explain: the time and where its field ends (at
    /// the comma). None sends the caller to [`Self::read`], which says what is wrong. An
    /// ISO time is read without a search for the comma ([`Self::iso_fast_prefix`]).
    #[inline(always)]
    pub(crate) fn read_leading_fast(&mut self, line: &[u8]) -> Option<(i64, usize)> {
        if self.form == TimeForm::Iso
            && let Some((t, end)) = self.iso_fast_prefix(line)
            && line.get(end) == Some(&b',')
        {
            return Some((t, end));
        }
        let comma = memchr::memchr(b',', line)?;
        Some((self.read_one_fast(&line[..comma])?, comma))
    }

    /// [`Self::read`] of a form written as one field, on its common path and without an
    /// error to explain: None sends the caller to [`Self::read`], which says what is wrong.
    #[inline(always)]
    pub(crate) fn read_one_fast(&mut self, field: &[u8]) -> Option<i64> {
        match self.form {
            TimeForm::Iso => self.iso(field).ok(),
            TimeForm::UnixS => self.unix(field).ok(),
            TimeForm::S => self.since_start(field).ok(),
            TimeForm::GpsWeekTow => None,
        }
    }

    /// The GPS time (ns) of a time written as `fields` (as many as the form takes): Err with
    /// the field's name and what is wrong.
    pub fn read(&mut self, fields: &[&[u8]]) -> Result<i64, (&'static str, String)> {
        match self.form {
            TimeForm::GpsWeekTow => gps_week_tow(fields[0], fields[1]),
            TimeForm::Iso => self.iso(fields[0]),
            TimeForm::UnixS => self.unix(fields[0]),
            TimeForm::S => self.since_start(fields[0]),
        }
    }

    /// An ISO 8601 time: the common case on [`Self::iso_fast`], the rest (an offset, a leap
    /// second, an error to explain) through the calendar.
    fn iso(&mut self, field: &[u8]) -> Result<i64, (&'static str, String)> {
        match self.iso_fast(field) {
            Some(t) => Ok(t),
            None => self.iso_calendar(field),
        }
    }

    /// Any ISO 8601 time, through the calendar.
    fn iso_calendar(&self, field: &[u8]) -> Result<i64, (&'static str, String)> {
        let s = std::str::from_utf8(field).map_err(|_| ("time", "not UTF-8".to_owned()))?;
        iso_gps_ns(s, self.scale).map_err(|m| ("time", m))
    }

    /// Unix seconds: GPS minus Unix time worked out once a UTC day.
    fn unix(&mut self, field: &[u8]) -> Result<i64, (&'static str, String)> {
        let unix = parse_seconds_ns(field).ok_or_else(|| {
            (
                "time",
                format!("`{}` is not a time in seconds since 1970", text(field)),
            )
        })?;
        let day = unix.div_euclid(NS_PER_DAY);
        let offset = match self.utc_day {
            Some((d, o)) if d == day => o,
            _ => {
                let date = civil_from_days(day);
                let o = gps_ns(Calendar::midnight(date), TimeScale::Utc).ok_or_else(|| {
                    ("time", format!("`{}` is before the GPS epoch", text(field)))
                })? - day * NS_PER_DAY;
                self.utc_day = Some((day, o));
                o
            }
        };
        Ok(unix + offset)
    }

    /// Seconds since the session's `start`.
    fn since_start(&self, field: &[u8]) -> Result<i64, (&'static str, String)> {
        let s = parse_seconds_ns(field).ok_or_else(|| {
            (
                "time",
                format!("`{}` is not a time in seconds", text(field)),
            )
        })?;
        let start = self.start_gps_ns.ok_or_else(|| {
            (
                "time",
                "times in seconds since the start need the session's `start`".to_owned(),
            )
        })?;
        start
            .checked_add(s)
            .ok_or_else(|| ("time", format!("`{}` is beyond any GPS time", text(field))))
    }
}

/// GPS week and seconds of week as GPS time, ns.
fn gps_week_tow(week: &[u8], tow: &[u8]) -> Result<i64, (&'static str, String)> {
    let week = std::str::from_utf8(week)
        .ok()
        .and_then(|w| w.parse::<i64>().ok())
        .filter(|w| (0..=9_999).contains(w))
        .ok_or_else(|| {
            (
                "gps_week",
                format!("`{}` is not a GPS week [0, 9999]", text(week)),
            )
        })?;
    let tow = parse_seconds_ns(tow)
        .filter(|t| (0..NS_PER_WEEK).contains(t))
        .ok_or_else(|| {
            (
                "tow_s",
                format!(
                    "`{}` is not a time of week in seconds [0, 604800)",
                    text(tow)
                ),
            )
        })?;
    Ok(week * NS_PER_WEEK + tow)
}

/// Days from 1970-01-01 to `date` (proleptic Gregorian; Hinnant's days_from_civil).
pub fn days_from_civil((y, m, d): (i32, u8, u8)) -> i64 {
    let y = i64::from(y) - i64::from(m <= 2);
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let m = i64::from(m);
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + i64::from(d) - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// (year, month, day) of a count of days since 1970-01-01 (Hinnant's civil_from_days).
pub fn civil_from_days(z: i64) -> (i32, u8, u8) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let y = yoe + era * 400;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u8;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u8;
    ((y + i64::from(m <= 2)) as i32, m, d)
}

/// Seconds with up to 9 decimals as ns, exactly (read from the bytes, rounded half up at
/// the tenth decimal); scientific notation through f64; None for anything else.
pub fn parse_seconds_ns(field: &[u8]) -> Option<i64> {
    let (negative, digits) = match field.first()? {
        b'-' => (true, &field[1..]),
        b'+' => (false, &field[1..]),
        _ => (false, field),
    };
    let (mut whole, mut ns) = (0i64, 0i64);
    let (mut int_digits, mut frac_digits) = (0usize, 0usize);
    let mut in_fraction = false;
    for (k, &c) in digits.iter().enumerate() {
        match c {
            b'0'..=b'9' if in_fraction => {
                frac_digits += 1;
                let d = i64::from(c - b'0');
                if frac_digits <= 9 {
                    ns += d * 10i64.pow(9 - frac_digits as u32);
                } else if frac_digits == 10 && d >= 5 {
                    ns += 1;
                }
            }
            b'0'..=b'9' => {
                int_digits += 1;
                if int_digits > 10 {
                    return None;
                }
                whole = whole * 10 + i64::from(c - b'0');
            }
            b'.' if !in_fraction => in_fraction = true,
            b'e' | b'E' if int_digits + frac_digits > 0 && k + 1 < digits.len() => {
                let v: f64 = std::str::from_utf8(field).ok()?.parse().ok()?;
                return (v.is_finite() && v.abs() < 9.2e9).then(|| (v * 1e9).round() as i64);
            }
            _ => return None,
        }
    }
    if int_digits + frac_digits == 0 {
        return None;
    }
    let total = whole.checked_mul(1_000_000_000)?.checked_add(ns)?;
    Some(if negative { -total } else { total })
}

/// Parses ISO 8601 `YYYY-MM-DDTHH:MM:SS[.fraction]` (a space allowed for `T`), then `Z`
/// (offset 0), `+HH:MM` / `-HH:MM`, or nothing (None: the time is in the session's scale).
/// Returns the calendar as written and the offset from UTC in minutes.
pub fn parse_iso(s: &str) -> Result<(Calendar, Option<i32>), String> {
    let zone_at = s
        .char_indices()
        .skip(19)
        .find(|(_, c)| matches!(c, 'Z' | 'z' | '+' | '-'))
        .map(|(i, _)| i);
    let (body, offset) = match zone_at {
        None => (s, None),
        Some(i) => {
            let zone = &s[i..];
            let offset = match zone.as_bytes() {
                [b'Z' | b'z'] => 0,
                [sign @ (b'+' | b'-'), h1, h2, b':', m1, m2]
                    if [h1, h2, m1, m2].iter().all(|c| c.is_ascii_digit()) =>
                {
                    let h = i32::from(h1 - b'0') * 10 + i32::from(h2 - b'0');
                    let m = i32::from(m1 - b'0') * 10 + i32::from(m2 - b'0');
                    if h > 23 || m > 59 {
                        return Err(format!("`{s}`: the offset {zone} is not a time zone"));
                    }
                    if *sign == b'-' {
                        -(h * 60 + m)
                    } else {
                        h * 60 + m
                    }
                }
                _ => {
                    return Err(format!(
                        "`{s}`: a zone is `Z` or `+HH:MM` / `-HH:MM`, not `{zone}`"
                    ));
                }
            };
            (&s[..i], Some(offset))
        }
    };
    let normalised;
    let body = if body.len() > 10 && body.as_bytes()[10] == b' ' {
        normalised = format!("{}T{}", &body[..10], &body[11..]);
        normalised.as_str()
    } else {
        body
    };
    let c = parse_calendar(body).map_err(|e| {
        format!("{e} (ISO 8601: YYYY-MM-DDTHH:MM:SS[.fraction], then Z, +HH:MM or nothing)")
    })?;
    Ok((c, offset))
}

/// Parses `YYYY-MM-DDTHH:MM:SS[.fraction]` (no zone suffix; up to 9 decimals).
pub fn parse_calendar(s: &str) -> Result<Calendar, String> {
    let b = s.as_bytes();
    let bad = || format!("`{s}` is not YYYY-MM-DDTHH:MM:SS[.fraction]");
    if b.len() < 19
        || b[4] != b'-'
        || b[7] != b'-'
        || b[10] != b'T'
        || b[13] != b':'
        || b[16] != b':'
    {
        return Err(bad());
    }
    let digits = |a: usize, z: usize| -> Result<u32, String> {
        if b[a..z].iter().all(u8::is_ascii_digit) {
            s[a..z].parse().map_err(|_| bad())
        } else {
            Err(bad())
        }
    };
    let date = crate::contract::manifest::parse_date(&s[..10])
        .ok_or_else(|| format!("`{}` is not a valid date", &s[..10]))?;
    let hour = digits(11, 13)?;
    let minute = digits(14, 16)?;
    let second = digits(17, 19)?;
    if hour > 23 || minute > 59 || second > 60 {
        return Err(format!("`{}` is not a valid time of day", &s[11..19]));
    }
    let mut nanos = 0u32;
    if b.len() > 19 {
        // The point first: a byte 19 that starts a character of several bytes is no
        // boundary to cut at.
        if b[19] != b'.' {
            return Err(bad());
        }
        let frac = &s[20..];
        if frac.is_empty() || frac.len() > 9 || !frac.bytes().all(|c| c.is_ascii_digit()) {
            return Err(bad());
        }
        nanos = frac.parse::<u32>().map_err(|_| bad())? * 10u32.pow(9 - frac.len() as u32);
    }
    Ok(Calendar {
        year: date.0,
        month: date.1,
        day: date.2,
        hour: hour as u8,
        minute: minute as u8,
        second: second as u8,
        nanos,
    })
}

fn hifi(scale: TimeScale) -> hifitime::TimeScale {
    match scale {
        TimeScale::Utc => hifitime::TimeScale::UTC,
        TimeScale::Gpst => hifitime::TimeScale::GPST,
        TimeScale::Tai => hifitime::TimeScale::TAI,
    }
}

/// GPS time of a calendar instant read in time scale `scale`, ns; `None` before the GPS epoch
/// (or past 2262, beyond i64 nanoseconds). hifitime's `to_gpst_nanoseconds` refuses instants
/// a century or more past 1980 (it called 2080 "before the epoch"); the duration does not.
pub fn gps_ns(c: Calendar, scale: TimeScale) -> Option<i64> {
    let e = Epoch::maybe_from_gregorian(
        c.year,
        c.month,
        c.day,
        c.hour,
        c.minute,
        c.second,
        c.nanos,
        hifi(scale),
    )
    .ok()?;
    let ns = e.to_gpst_duration().total_nanoseconds();
    if ns < 0 {
        return None;
    }
    i64::try_from(ns).ok()
}

/// GPS time `gps_ns` as a UTC calendar time `YYYY-MM-DDTHH:MM:SS.mmmZ` (leap seconds from
/// hifitime's table; milliseconds truncated), for what a person reads.
pub fn utc_iso(gps_ns: i64) -> String {
    let e = Epoch::from_gpst_nanoseconds(u64::try_from(gps_ns).unwrap_or(0));
    let (y, mo, d, h, mi, s, ns) = e.to_gregorian_utc();
    format!(
        "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{:03}Z",
        ns / 1_000_000
    )
}

/// GPS time `gps_ns` as a log in `form` writes it, for a person to find it there: a
/// calendar time in `scale` (UTC with `Z`, GPST or TAI named), Unix seconds, seconds since
/// `start_gps_ns` (GPS ns), or GPS week and tow; milliseconds.
pub fn as_written(
    gps_ns: i64,
    form: TimeForm,
    scale: TimeScale,
    start_gps_ns: Option<i64>,
) -> String {
    use TimeScale as Scale;
    let e = Epoch::from_gpst_nanoseconds(u64::try_from(gps_ns).unwrap_or(0));
    let calendar = |scale: hifitime::TimeScale, name: &str| {
        let (y, mo, d, h, mi, s, ns) = e.to_gregorian(scale);
        format!(
            "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}.{:03} {name}",
            ns / 1_000_000
        )
    };
    match (form, scale, start_gps_ns) {
        (TimeForm::Iso, Scale::Utc, _) => utc_iso(gps_ns),
        (TimeForm::Iso, Scale::Gpst, _) => calendar(hifitime::TimeScale::GPST, "GPST"),
        (TimeForm::Iso, Scale::Tai, _) => calendar(hifitime::TimeScale::TAI, "TAI"),
        (TimeForm::UnixS, _, _) => format!("{:.3} (Unix s)", e.to_unix_seconds()),
        (TimeForm::S, _, Some(start)) => {
            format!("{:.3} s after start", (gps_ns - start) as f64 * 1e-9)
        }
        (TimeForm::S, _, None) => utc_iso(gps_ns),
        (TimeForm::GpsWeekTow, _, _) => format!(
            "{},{:.3}",
            gps_ns.div_euclid(NS_PER_WEEK),
            gps_ns.rem_euclid(NS_PER_WEEK) as f64 * 1e-9
        ),
    }
}

/// An ISO 8601 time as GPS ns: in UTC where it carries `Z` or an offset, in `scale`
/// otherwise, UTC's leap second 23:59:60 where one was inserted. The one path every time
/// gravcal reads in ISO goes through: the logs' and the manifest's (a session's `start`, a
/// tie's `time`).
pub fn iso_gps_ns(s: &str, scale: TimeScale) -> Result<i64, String> {
    let (c, offset_min) = parse_iso(s)?;
    let scale = if offset_min.is_some() {
        TimeScale::Utc
    } else {
        scale
    };
    let t = if c.second == 60 {
        leap_second(c, scale).map_err(|m| format!("`{s}`: {m}"))?
    } else {
        gps_ns(c, scale)
    }
    .ok_or_else(|| format!("`{s}` is before the GPS epoch (1980-01-06)"))?;
    Ok(t - i64::from(offset_min.unwrap_or(0)) * 60_000_000_000)
}

/// The GPS time of second 60 of a minute, as written (`c.second == 60`): only UTC's
/// 23:59:60 on a day that ends with an inserted leap second (by hifitime's table) exists;
/// anything else is an error, never a guess. `Ok(None)` before the GPS epoch.
fn leap_second(c: Calendar, scale: TimeScale) -> Result<Option<i64>, String> {
    let date = (c.year, c.month, c.day);
    let Some(midnight) = gps_ns(Calendar::midnight(date), TimeScale::Utc) else {
        return Ok(None);
    };
    let next = gps_ns(
        Calendar::midnight(civil_from_days(days_from_civil(date) + 1)),
        TimeScale::Utc,
    );
    let leap_day = next.is_some_and(|n| n - midnight == NS_PER_DAY + 1_000_000_000);
    if scale != TimeScale::Utc || c.hour != 23 || c.minute != 59 || !leap_day {
        return Err(format!(
            "second 60 exists only as UTC's 23:59:60 on a day ending with an inserted leap \
             second, and {:04}-{:02}-{:02} {:02}:{:02} in {scale:?} is not one",
            c.year, c.month, c.day, c.hour, c.minute
        ));
    }
    Ok(Some(midnight + NS_PER_DAY + i64::from(c.nanos)))
}

/// GPS week containing 00:00 UTC of `date`.
pub fn week_of_date(date: (i32, u8, u8)) -> i64 {
    gps_ns(Calendar::midnight(date), TimeScale::Utc).map_or(0, |ns| ns.div_euclid(NS_PER_WEEK))
}

/// The full GPS week nearest `reference_week` that is congruent to `week10` modulo 1024.
#[inline]
pub fn resolve_week(week10: u16, reference_week: i64) -> i64 {
    let w = i64::from(week10 % 1024);
    w + 1024 * (reference_week - w + 512).div_euclid(1024)
}

#[cfg(test)]
mod time_form_tests {
    use super::*;

    /// One instant written in every form reads as one GPS time: 2026-03-14T09:12:03.456 UTC
    /// is GPS week 2409, 18 leap seconds ahead.
    #[test]
    fn one_instant_in_every_form() {
        let gps = gps_ns(
            parse_calendar("2026-03-14T09:12:21.456").expect("calendar"),
            TimeScale::Gpst,
        )
        .expect("gps");
        let read = |form, fields: &[&str], start| {
            let f: Vec<&[u8]> = fields.iter().map(|f| f.as_bytes()).collect();
            TimeReader::new(form, TimeScale::Utc, start).read(&f)
        };
        assert_eq!(
            read(TimeForm::Iso, &["2026-03-14T09:12:03.456Z"], None),
            Ok(gps)
        );
        assert_eq!(
            read(TimeForm::Iso, &["2026-03-14T10:12:03.456+01:00"], None),
            Ok(gps)
        );
        assert_eq!(
            read(TimeForm::Iso, &["2026-03-14T04:12:03.456-05:00"], None),
            Ok(gps)
        );
        assert_eq!(
            read(TimeForm::Iso, &["2026-03-14T09:12:03.456"], None),
            Ok(gps)
        );
        assert_eq!(
            read(TimeForm::Iso, &["2026-03-14 09:12:03.456Z"], None),
            Ok(gps)
        );
        assert_eq!(read(TimeForm::UnixS, &["1773479523.456"], None), Ok(gps));
        let week = gps.div_euclid(NS_PER_WEEK);
        let tow = format!("{:.3}", gps.rem_euclid(NS_PER_WEEK) as f64 * 1e-9);
        assert_eq!(
            read(TimeForm::GpsWeekTow, &[&week.to_string(), &tow], None),
            Ok(gps)
        );
        assert_eq!(
            read(TimeForm::S, &["3.456"], Some(gps - 3_456_000_000)),
            Ok(gps)
        );
        for bad in [
            "2026-03-14T09:12:03+0100",
            "2026-03-14T09:12:03 Z",
            "2026-03-14T09:12:03+25:00",
        ] {
            let e = read(TimeForm::Iso, &[bad], None).expect_err(bad);
            assert_eq!(e.0, "time");
        }
        assert!(read(TimeForm::S, &["1.0"], None).is_err(), "no start");
    }

    #[test]
    fn civil_days_round_trip() {
        for (days, date) in [
            (0, (1970, 1, 1)),
            (11_017, (2000, 3, 1)),
            (19_362, (2023, 1, 5)),
        ] {
            assert_eq!(civil_from_days(days), date);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn days_from_the_unix_epoch() {
        assert_eq!(days_from_civil((1970, 1, 1)), 0);
        assert_eq!(days_from_civil((2000, 3, 1)), 11_017);
        assert_eq!(days_from_civil((2023, 1, 5)), 19_362);
        assert_eq!(civil_from_days(19_362), (2023, 1, 5));
    }

    fn cal(s: &str) -> Calendar {
        parse_calendar(s).expect("valid")
    }

    #[test]
    fn leap_seconds_from_the_table() {
        let utc = gps_ns(cal("2005-02-15T09:12:03.250"), TimeScale::Utc).expect("after epoch");
        let gpst = gps_ns(cal("2005-02-15T09:12:03.250"), TimeScale::Gpst).expect("after epoch");
        let tai = gps_ns(cal("2005-02-15T09:12:03.250"), TimeScale::Tai).expect("after epoch");
        assert_eq!(utc - gpst, 13_000_000_000);
        assert_eq!(gpst - tai, 19_000_000_000);
        let utc = gps_ns(cal("2019-04-06T23:59:42"), TimeScale::Utc).expect("after epoch");
        assert_eq!(utc, 2048 * NS_PER_WEEK);
    }

    /// Regression: hifitime's GPST nanoseconds refuse a century past 1980, and readings
    /// after 2080 were called "before the GPS epoch".
    #[test]
    fn dates_after_2080_are_after_the_epoch() {
        let a = gps_ns(cal("2081-03-01T00:00:00"), TimeScale::Gpst).expect("after epoch");
        let b = gps_ns(cal("2081-03-02T00:00:00"), TimeScale::Gpst).expect("after epoch");
        assert_eq!(b - a, 86_400 * 1_000_000_000);
        assert!(gps_ns(cal("1980-01-05T23:59:59"), TimeScale::Gpst).is_none());
    }

    #[test]
    fn fractions_and_bad_times() {
        assert_eq!(cal("2005-02-15T09:12:03.25").nanos, 250_000_000);
        assert_eq!(cal("2005-02-15T09:12:03.000000001").nanos, 1);
        for bad in [
            "2005-02-15 09:12:03",
            "2005-02-30T09:12:03",
            "2005-02-15T24:00:00",
            "2005-02-15T09:12:03.",
            "2005-02-15T09:12:03.1234567890",
            "2005-02-15T09:12:03Z",
            "2005-02-15T09:1a:03",
            // A character of several bytes where the point goes (it panicked, cut inside).
            "2005-02-15T09:12:03\u{fffd}25",
            "2005-02-15T09:12:03\u{e9}",
        ] {
            assert!(parse_calendar(bad).is_err(), "{bad}");
        }
    }

    /// The ISO fast path reads what the calendar reads: every length of fraction, `Z` or
    /// none, `T` or a space, across a midnight it keeps; and it leaves the rest (no
    /// fraction digit, ten of them, a stray byte, a leap second, an offset) to it.
    #[test]
    fn iso_fast_path_agrees_with_the_calendar() {
        let mut taken = 0;
        for scale in [TimeScale::Utc, TimeScale::Gpst] {
            let mut r = TimeReader::new(TimeForm::Iso, scale, None);
            let mut fields: Vec<String> = Vec::new();
            for day in ["2016-12-31", "2017-01-01", "2026-03-14"] {
                for (sep, zone) in [("T", "Z"), (" ", ""), ("T", "")] {
                    for frac in [
                        "",
                        ".1",
                        ".12",
                        ".123",
                        ".1234",
                        ".12345",
                        ".123456",
                        ".1234567",
                        ".12345678",
                        ".123456789",
                        ".1234567891",
                        ".",
                        ".12a",
                        "x",
                    ] {
                        fields.push(format!("{day}{sep}23:59:59{frac}{zone}"));
                        fields.push(format!("{day}{sep}00:00:07{frac}{zone}"));
                    }
                }
                fields.push(format!("{day}T23:59:60Z"));
                fields.push(format!("{day}T09:12:03+01:00"));
            }
            for f in &fields {
                let general = r.iso_calendar(f.as_bytes()).ok();
                match r.iso_fast(f.as_bytes()) {
                    Some(t) => {
                        taken += 1;
                        assert_eq!(Some(t), general, "{f} in {scale:?}");
                    }
                    None => {
                        let plain = f.len() >= 19 && !f.contains(['.', 'x', '+']);
                        assert!(!plain || f.contains(":60"), "{f} declined");
                    }
                }
                assert_eq!(r.read_one_fast(f.as_bytes()), general, "{f} in {scale:?}");
            }
        }
        assert!(taken > 200, "{taken} taken");
    }

    #[test]
    fn week_rollover() {
        assert_eq!(resolve_week(1023, 2047), 2047);
        assert_eq!(resolve_week(0, 2047), 2048);
        assert_eq!(resolve_week(286, 1310), 1310);
        assert_eq!(resolve_week(1020, 2050), 2044);
        assert_eq!(resolve_week(5, 2040), 2053);
        assert_eq!(resolve_week(300, 0), 300);
        assert_eq!(week_of_date((2005, 2, 15)), 1310);
        assert_eq!(week_of_date((2019, 4, 7)), 2048);
    }

    /// A time as each form writes it: 2017-01-01T00:00:00.250Z, just after the leap second
    /// of 2016, is GPST 18 s and TAI 37 s ahead, Unix 1483228800.250, and GPS week 1930
    /// (which starts that Sunday) at 18.250 s.
    #[test]
    fn a_time_as_each_form_writes_it() {
        let gps = iso_gps_ns("2017-01-01T00:00:00.250Z", TimeScale::Utc).expect("iso");
        assert_eq!(
            as_written(gps, TimeForm::Iso, TimeScale::Utc, None),
            "2017-01-01T00:00:00.250Z"
        );
        assert_eq!(
            as_written(gps, TimeForm::Iso, TimeScale::Gpst, None),
            "2017-01-01T00:00:18.250 GPST"
        );
        assert_eq!(
            as_written(gps, TimeForm::Iso, TimeScale::Tai, None),
            "2017-01-01T00:00:37.250 TAI"
        );
        assert_eq!(
            as_written(gps, TimeForm::UnixS, TimeScale::Utc, None),
            "1483228800.250 (Unix s)"
        );
        assert_eq!(
            as_written(gps, TimeForm::S, TimeScale::Utc, Some(gps - 1_500_000_000)),
            "1.500 s after start"
        );
        assert_eq!(
            as_written(gps, TimeForm::GpsWeekTow, TimeScale::Utc, None),
            "1930,18.250"
        );
    }
}
