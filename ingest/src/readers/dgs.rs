//! DGS AT1M/AT1A marine gravimeters' "laptop" files (docs/formats.md 11.1): one line a
//! second, 26 comma-separated fields, its own UTC calendar time at the end. The layout is
//! the one shipgrav reads for R/V Atlantis, Revelle, Palmer, Ride and DGS's own test file
//! (`shipgrav.io._dgs_laptop_general`); the fields, from 0:
//!
//! | field | what | read here |
//! |---|---|---|
//! | 1 | raw gravity `rgrav`, mGal, before the meter's offset | the meter's reading, channel 1 |
//! | 2, 3 | long and cross accelerations | checked as numbers |
//! | 6 | status | checked as an integer |
//! | 10 to 13 | the cross-coupling monitors VE, VCC, AL, AX | checked as numbers |
//! | 14, 15 | latitude, longitude, deg | the trajectory's (the gravity stage) |
//! | 19 to 24 | year, month, day, hour, minute, second (UTC) | the time |
//!
//! The others (0, 4, 5, 7 to 9, 16 to 18, 25) are not read, as shipgrav does not read them.
//! One parser serves ingest (the reading) and the gravity stage (the positions), so the two
//! see the same lines the same way. No I/O.

use crate::base::time::{Calendar, gps_ns};
use crate::contract::manifest::TimeScale;

/// Fields a laptop line has.
pub const FIELDS: usize = 26;

/// One line of a laptop file, as read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LaptopLine {
    /// GPS time, ns (the line's UTC calendar time).
    pub gps_ns: i64,
    /// Raw gravity, mGal, before the meter's offset.
    pub raw_gravity_mgal: f64,
    /// The cross-coupling monitors VE, VCC, AL, AX.
    pub monitors: [f64; 4],
    /// The meter's status word (field 7), its bits as the meter sets them.
    pub status: u32,
    /// Latitude and longitude, deg.
    pub latitude_deg: f64,
    /// Longitude, deg.
    pub longitude_deg: f64,
}

/// A field that does not parse: (field name, message).
pub type Bad = (&'static str, String);

fn text(f: &[u8]) -> String {
    String::from_utf8_lossy(f).into_owned()
}

/// A field's decimal: on the lab streams' exact fast path where its digits allow
/// (`crate::readers::labstream::fast_decimal`, the double `str::parse` gives), through `str::parse`
/// otherwise.
fn number(fields: &[&[u8]], k: usize, name: &'static str) -> Result<f64, Bad> {
    let f = fields[k].trim_ascii();
    crate::readers::labstream::fast_decimal(f)
        .map(|(v, _)| v)
        .or_else(|| std::str::from_utf8(f).ok()?.parse::<f64>().ok())
        .filter(|v| v.is_finite())
        .ok_or_else(|| (name, format!("`{}` is not a number", text(f))))
}

fn integer(fields: &[&[u8]], k: usize, name: &'static str) -> Result<u32, Bad> {
    let f = fields[k].trim_ascii();
    unsigned(f).ok_or_else(|| (name, format!("`{}` is not an integer", text(f))))
}

/// What `str::parse::<u32>` reads: an optional `+`, then decimal digits, within u32.
fn unsigned(f: &[u8]) -> Option<u32> {
    let digits = f.strip_prefix(b"+").unwrap_or(f);
    if digits.is_empty() {
        return None;
    }
    digits.iter().try_fold(0u32, |v, &c| {
        c.is_ascii_digit()
            .then(|| v.checked_mul(10)?.checked_add(u32::from(c - b'0')))
            .flatten()
    })
}

/// A laptop line split at its commas into [`FIELDS`] fields, without allocating; a line of
/// another count is refused as [`parse_laptop`] refuses it.
pub fn split(line: &[u8]) -> Result<[&[u8]; FIELDS], Bad> {
    let mut fields: [&[u8]; FIELDS] = [&[]; FIELDS];
    let (mut n, mut start) = (0, 0);
    for comma in memchr::memchr_iter(b',', line) {
        if let Some(slot) = fields.get_mut(n) {
            *slot = &line[start..comma];
        }
        (n, start) = (n + 1, comma + 1);
    }
    if let Some(slot) = fields.get_mut(n) {
        *slot = &line[start..];
    }
    n += 1;
    if n != FIELDS {
        return Err(field_count(n));
    }
    Ok(fields)
}

fn field_count(n: usize) -> Bad {
    (
        "line",
        format!(
            "{n} fields, expected {FIELDS} (a DGS laptop line: gravity, raw gravity, long, cross, \
             ..., year, month, day, hour, minute, second, ...)"
        ),
    )
}

/// A laptop line's fields (split at commas, white space around each allowed) read; the
/// error names the field and what is wrong with it.
pub fn parse_laptop(fields: &[&[u8]]) -> Result<LaptopLine, Bad> {
    if fields.len() != FIELDS {
        return Err(field_count(fields.len()));
    }
    let raw_gravity_mgal = number(fields, 1, "rgrav")?;
    number(fields, 2, "long_a")?;
    number(fields, 3, "crss_a")?;
    let status = integer(fields, 6, "status")?;
    let mut monitors = [0.0; 4];
    for (m, (k, name)) in monitors
        .iter_mut()
        .zip([(10, "ve"), (11, "vcc"), (12, "al"), (13, "ax")])
    {
        *m = number(fields, k, name)?;
    }
    let latitude_deg = number(fields, 14, "lat")?;
    let longitude_deg = number(fields, 15, "lon")?;
    if !(-90.0..=90.0).contains(&latitude_deg) {
        return Err(("lat", format!("{latitude_deg} is outside [-90, 90]")));
    }
    if !(-180.0..=360.0).contains(&longitude_deg) {
        return Err(("lon", format!("{longitude_deg} is outside [-180, 360]")));
    }
    let gps_ns = parse_time(fields)?;
    Ok(LaptopLine {
        gps_ns,
        raw_gravity_mgal,
        monitors,
        status,
        latitude_deg,
        longitude_deg,
    })
}

/// The line's UTC calendar time (fields 19 to 24; the second may have a fraction) as GPS ns.
fn parse_time(fields: &[&[u8]]) -> Result<i64, Bad> {
    let year = integer(fields, 19, "year")?;
    let month = integer(fields, 20, "month")?;
    let day = integer(fields, 21, "day")?;
    let hour = integer(fields, 22, "hour")?;
    let minute = integer(fields, 23, "minute")?;
    let second = number(fields, 24, "second")?;
    let bad = |name: &'static str, v: String| (name, format!("`{v}` is out of range"));
    if !(1..=12).contains(&month) {
        return Err(bad("month", month.to_string()));
    }
    let narrow = |v: u32| u8::try_from(v).unwrap_or(0);
    let date = i32::try_from(year)
        .ok()
        .and_then(|y| crate::contract::manifest::calendar_date(y, narrow(month), narrow(day)))
        .ok_or_else(|| {
            (
                "day",
                format!("{year:04}-{month:02}-{day:02} is not a date (from 1980 to 2200)"),
            )
        })?;
    if hour > 23 {
        return Err(bad("hour", hour.to_string()));
    }
    if minute > 59 {
        return Err(bad("minute", minute.to_string()));
    }
    if !(0.0..61.0).contains(&second) {
        return Err(bad("second", second.to_string()));
    }
    let minute_gps_ns = minute_start(Calendar {
        year: date.0,
        month: date.1,
        day: date.2,
        hour: hour as u8,
        minute: minute as u8,
        second: 0,
        nanos: 0,
    })
    .ok_or_else(|| ("year", format!("{year}: before the GPS epoch (1980-01-06)")))?;
    // Seconds counted on from the minute's start: a leap second (23:59:60) is the GPS second
    // after 23:59:59, as the calendar's own conversion has it.
    let whole = second.floor();
    let nanos = ((second - whole) * 1e9).round().min(999_999_999.0) as i64;
    Ok(minute_gps_ns + whole as i64 * 1_000_000_000 + nanos)
}

/// The GPS time of a UTC minute's start, the last one converted kept: a laptop file's lines
/// come a second apart, so one conversion serves sixty of them.
fn minute_start(c: Calendar) -> Option<i64> {
    /// A UTC minute: year, month, day, hour, minute.
    type Minute = (i32, u8, u8, u8, u8);
    thread_local! {
        static LAST: std::cell::Cell<Option<(Minute, i64)>> = const { std::cell::Cell::new(None) };
    }
    let key = (c.year, c.month, c.day, c.hour, c.minute);
    LAST.with(|last| match last.get() {
        Some((k, ns)) if k == key => Some(ns),
        _ => {
            let ns = gps_ns(c, TimeScale::Utc)?;
            last.set(Some((key, ns)));
            Some(ns)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integer fields read as `str::parse::<u32>` reads them.
    #[test]
    fn integers_are_str_parse_s() {
        for f in [
            "0",
            "7",
            "+7",
            "-7",
            "",
            "+",
            "++1",
            "00012",
            "4294967295",
            "4294967296",
            "99999999999",
            "1a",
            "a1",
            " 1",
            "1 ",
            "\u{661}",
        ] {
            assert_eq!(unsigned(f.as_bytes()), f.parse::<u32>().ok(), "`{f}`");
        }
    }

    const LINE: &str = "11773.330941280192,12295.691114150419, -0.574874946460, \
        -0.635361747189,  0.003210411454, 53.370688000000,           20814,         5403321, \
        31.117220000000, 50.141118000000,  0.810980000000, -0.001845585113,  0.107840000000,  \
        0.254290000000, 48.073118466700,-10.317187150000, 11.400000000000,270.080000000000,  \
        0.319623703139,2019,07,11,00,00,00.00,0";

    fn fields(line: &str) -> Vec<&[u8]> {
        line.as_bytes().split(|&b| b == b',').collect()
    }

    /// Lines a second apart across the 2016 leap second, each minute's start converted once:
    /// 23:59:59, 23:59:60 and 00:00:00 are three GPS seconds in a row, and a line of another
    /// minute read between them does not disturb them; `split` reads the line as the
    /// collected fields do and refuses another count.
    #[test]
    fn seconds_count_on_from_the_minute_across_a_leap_second() {
        let at = |time: &str| {
            let line = LINE.replace("2019,07,11,00,00,00.00", time);
            let f = split(line.as_bytes()).expect("26 fields");
            assert_eq!(f.to_vec(), fields(&line));
            parse_laptop(&f).expect("line").gps_ns
        };
        let t = [
            at("2016,12,31,23,59,59.00"),
            at("2016,12,31,23,59,60.00"),
            at("2019,07,11,00,00,00.50"),
            at("2017,01,01,00,00,00.00"),
        ];
        assert_eq!(t[1] - t[0], 1_000_000_000);
        assert_eq!(t[3] - t[1], 1_000_000_000);
        // 2019-07-11T00:00:00.5 UTC: 18 leap seconds.
        let gps = gps_ns(
            Calendar {
                year: 2019,
                month: 7,
                day: 11,
                hour: 0,
                minute: 0,
                second: 0,
                nanos: 500_000_000,
            },
            TimeScale::Utc,
        );
        assert_eq!(Some(t[2]), gps);
        assert!(split(b"1,2,3").is_err());
        for bad in ["2019,02,29,00,00,00.00", "2020,04,31,00,00,00.00"] {
            let line = LINE.replace("2019,07,11,00,00,00.00", bad);
            let e = parse_laptop(&fields(&line)).expect_err("not a date");
            assert_eq!(e.0, "day", "{bad}: {e:?}");
        }
        let line = LINE.replace("2019,07,11,00,00,00.00", "2020,02,29,00,00,00.00");
        assert!(parse_laptop(&fields(&line)).is_ok(), "a leap day");
    }

    /// shipgrav's test file's first line: its values, and 2019-07-11T00:00:00 UTC as GPS
    /// time (18 leap seconds then).
    #[test]
    fn the_first_line_of_dgs_test_file() {
        let l = parse_laptop(&fields(LINE)).expect("line");
        // The doubles the text gives, bit for bit.
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(
            bits(&[l.raw_gravity_mgal, l.latitude_deg, l.longitude_deg]),
            bits(&[12_295.691_114_150_419, 48.073_118_466_7, -10.317_187_15])
        );
        assert_eq!(
            bits(&l.monitors),
            bits(&[0.81098, -0.001_845_585_113, 0.10784, 0.25429])
        );
        let midnight = gps_ns(
            crate::base::time::parse_calendar("2019-07-11T00:00:00").expect("calendar"),
            TimeScale::Utc,
        )
        .expect("gps");
        assert_eq!(l.gps_ns, midnight);
        let gpst = gps_ns(
            crate::base::time::parse_calendar("2019-07-11T00:00:18").expect("calendar"),
            TimeScale::Gpst,
        );
        assert_eq!(Some(l.gps_ns), gpst);
    }

    /// Each damaged field is named.
    #[test]
    fn a_damaged_field_is_named() {
        for (k, to, name) in [
            (1, "12295.6x", "rgrav"),
            (6, "-3", "status"),
            (11, "", "vcc"),
            (14, "91.0", "lat"),
            (20, "13", "month"),
            (21, "32", "day"),
            (22, "24", "hour"),
            (24, "61.5", "second"),
        ] {
            let mut f = fields(LINE);
            f[k] = to.as_bytes();
            let (field, message) = parse_laptop(&f).expect_err(name);
            assert_eq!(field, name, "{message}");
        }
        let (field, _) = parse_laptop(&fields(&LINE[..LINE.len() - 2])).expect_err("25 fields");
        assert_eq!(field, "line");
    }
}
