//! Time scales: every time leaves ingest as GPS time, i64 nanoseconds since 1980-01-06.
//! Leap seconds come from hifitime's maintained table, not from a list written here.

use crate::contract::manifest::TimeScale;
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
        let frac = &s[20..];
        if b[19] != b'.'
            || frac.is_empty()
            || frac.len() > 9
            || !frac.bytes().all(|c| c.is_ascii_digit())
        {
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
mod tests {
    use super::*;

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
        ] {
            assert!(parse_calendar(bad).is_err(), "{bad}");
        }
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
}
