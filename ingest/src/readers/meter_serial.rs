//! A platform meter's serial output as a ship's logger writes it (docs/formats.md 11.2): the
//! logger's time stamp, then the meter's own record. Two meters' records are read:
//!
//! - **BGM-3** (`adc_format = "bgm3"`): `PP:CCCCCC SS`, the counter's counts `CCCCCC` of the
//!   last second after a two-digit prefix `PP`, then a two-digit status `SS`. The counts are
//!   the meter's reading (its maker's scale, about 5 mGal a count, turns them into gravity).
//!   shipgrav (`shipgrav.io._bgmserial_*`) reads only the counts; the prefix and the status
//!   are checked here as integers, their meaning left to the meter's documentation.
//! - **DGS AT1M/AT1A raw serial** (`adc_format = "dgs-raw"`): `$AT1M_<version>_<counter>`, then
//!   18 comma-separated fields (`shipgrav.io._dgs_raw_general`): gravity, long, cross, beam,
//!   temperature, pressure, electronics temperature (AD units), the cross-coupling monitors
//!   VCC, VE, AL, AX, the status, a checksum, latitude, longitude, speed, course and the
//!   meter's own stamp. The checksum is the sum of the eleven fields from gravity to AX (it
//!   holds on every line of shipgrav's three ships' samples): a line whose sum differs is
//!   damaged and refused, a check shipgrav does not make. The monitors are scaled by 1e-5, as
//!   shipgrav's `scale_ccp` does; the position fields are the meter's serial input, zero when
//!   none is wired, and are not read (the navigation is its own file).
//!
//! The logger's stamp is whatever precedes the record; its tokens (separated by commas, tabs
//! or spaces) that are not a time are the logger's tags (`BGM`, `vc01`, `grav_dgs_33_raw`)
//! and are passed over. One time must be there, in one of the forms UNOLS ships' loggers
//! write ([`StampForm`]); a form without a zone is in the session's `time_scale`. No I/O.

use crate::contract::manifest::TimeScale;

/// A field that does not parse: (field name, message).
pub type Bad = (&'static str, String);

/// How a logger writes its time stamp.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StampForm {
    /// `2022-11-07T17:13:45.329611Z`: ISO 8601 (R/V Revelle, Ride, Sikuliaq).
    Iso,
    /// `2022/07/01 12:17:33.492`: year/month/day, then the time (R/V Atlantis).
    YearMonthDay,
    /// `03/13/2022,00:00:02.449`: month/day/year, then the time (R/V Thompson).
    MonthDayYear,
    /// `2020:244:00:00:00.3244`: year, day of year, time (R/V Langseth).
    YearDayOfYear,
}

impl StampForm {
    /// The form as docs/formats.md names it.
    pub fn name(self) -> &'static str {
        match self {
            StampForm::Iso => "ISO 8601",
            StampForm::YearMonthDay => "YYYY/MM/DD hh:mm:ss",
            StampForm::MonthDayYear => "MM/DD/YYYY hh:mm:ss",
            StampForm::YearDayOfYear => "YYYY:DDD:hh:mm:ss",
        }
    }
}

/// One line of a meter's serial output, as read.
#[derive(Clone, Debug, PartialEq)]
pub struct SerialLine {
    /// GPS time of the logger's stamp, ns.
    pub gps_ns: i64,
    /// How the stamp was written.
    pub form: StampForm,
    /// The meter's reading: BGM-3 counts, or the DGS's gravity in AD units.
    pub reading: f64,
    /// The cross-coupling monitors VE, VCC, AL, AX (a DGS's, scaled by 1e-5), in the order
    /// of the laptop file's ([`crate::readers::dgs::LaptopLine::monitors`]); None for a BGM-3.
    pub monitors: Option<[f64; 4]>,
    /// The meter's status word: a DGS's status field, a BGM-3's `SS`, as integers.
    pub status: u32,
    /// The bytes of the line that hold the logger's stamp.
    pub stamp: std::ops::Range<usize>,
}

fn text(f: &[u8]) -> String {
    String::from_utf8_lossy(f).into_owned()
}

/// The tokens of `bytes` (separated by commas, tabs or spaces), each with its offset.
fn tokens(bytes: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    let mut at = 0;
    bytes
        .split(|&c| c == b',' || c == b'\t' || c == b' ')
        .map(move |t| {
            let start = at;
            at += t.len() + 1;
            (start, t)
        })
        .filter(|(_, t)| !t.is_empty())
}

fn digits(t: &[u8]) -> bool {
    !t.is_empty() && t.iter().all(u8::is_ascii_digit)
}

/// `hh:mm:ss[.fraction]`.
fn is_clock(t: &[u8]) -> bool {
    t.len() >= 8 && t[2] == b':' && t[5] == b':' && digits(&t[..2]) && digits(&t[3..5])
}

/// The logger's time in `prefix` (the bytes before the meter's record): its GPS time and
/// form, and the bytes that hold it.
pub fn logger_time(
    prefix: &[u8],
    scale: TimeScale,
) -> Result<(i64, StampForm, std::ops::Range<usize>), Bad> {
    let toks: Vec<(usize, &[u8])> = tokens(prefix).collect();
    let mut found = None;
    for (k, &(at, t)) in toks.iter().enumerate() {
        let next = toks.get(k + 1).filter(|(_, c)| is_clock(c));
        let stamp = if t.len() >= 19 && t[4] == b'-' && t[7] == b'-' && t[10] == b'T' {
            Some((StampForm::Iso, text(t), at..at + t.len()))
        } else if let (Some(&(c_at, clock)), Some(date)) = (next, slashed_date(t)) {
            let (form, (y, m, d)) = date;
            let iso = format!("{y:04}-{m:02}-{d:02}T{}", text(clock));
            Some((form, iso, at..c_at + clock.len()))
        } else {
            day_of_year(t).map(|iso| (StampForm::YearDayOfYear, iso, at..at + t.len()))
        };
        if let Some(s) = stamp {
            if found.is_some() {
                return Err(("time", "the logger's stamp holds two times".to_owned()));
            }
            found = Some(s);
        }
    }
    let (form, iso, range) = found.ok_or_else(|| {
        (
            "time",
            format!(
                "no logger time before the meter's record in `{}` (ISO 8601, YYYY/MM/DD hh:mm:ss, \
                 MM/DD/YYYY hh:mm:ss or YYYY:DDD:hh:mm:ss)",
                text(prefix)
            ),
        )
    })?;
    let t = crate::base::time::iso_gps_ns(&iso, scale).map_err(|m| ("time", m))?;
    Ok((t, form, range))
}

/// `YYYY/MM/DD` or `MM/DD/YYYY` as (form, year, month, day); the day is checked by the
/// calendar when the time is converted.
fn slashed_date(t: &[u8]) -> Option<(StampForm, (u16, u8, u8))> {
    let parts: Vec<&[u8]> = t.split(|&c| c == b'/').collect();
    if parts.len() != 3 || !parts.iter().all(|p| digits(p)) {
        return None;
    }
    let n = |p: &[u8]| std::str::from_utf8(p).ok()?.parse::<u16>().ok();
    match (parts[0].len(), parts[2].len()) {
        (4, 1..=2) => Some((
            StampForm::YearMonthDay,
            (
                n(parts[0])?,
                u8::try_from(n(parts[1])?).ok()?,
                u8::try_from(n(parts[2])?).ok()?,
            ),
        )),
        (1..=2, 4) => Some((
            StampForm::MonthDayYear,
            (
                n(parts[2])?,
                u8::try_from(n(parts[0])?).ok()?,
                u8::try_from(n(parts[1])?).ok()?,
            ),
        )),
        _ => None,
    }
}

/// `YYYY:DDD:hh:mm:ss[.fraction]` as an ISO 8601 calendar time; None when it is not one
/// (a day of the year beyond the year's is not a time).
fn day_of_year(t: &[u8]) -> Option<String> {
    if t.len() < 17 || t[4] != b':' || t[8] != b':' || !digits(&t[..4]) || !digits(&t[5..8]) {
        return None;
    }
    let clock = &t[9..];
    if !is_clock(clock) {
        return None;
    }
    let year: i32 = std::str::from_utf8(&t[..4]).ok()?.parse().ok()?;
    let doy: i64 = std::str::from_utf8(&t[5..8]).ok()?.parse().ok()?;
    let jan1 = crate::base::time::days_from_civil((year, 1, 1));
    let (y, m, d) = crate::base::time::civil_from_days(jan1 + doy - 1);
    (doy >= 1 && y == year).then(|| format!("{y:04}-{m:02}-{d:02}T{}", text(clock)))
}

fn integer(t: &[u8], name: &'static str) -> Result<i64, Bad> {
    std::str::from_utf8(t.trim_ascii())
        .ok()
        .and_then(|s| s.parse::<i64>().ok())
        .ok_or_else(|| (name, format!("`{}` is not an integer", text(t))))
}

/// A status word: an integer from 0 to 2^32 - 1 (its bits are the meter's flags).
fn status_word(t: &[u8]) -> Result<u32, Bad> {
    std::str::from_utf8(t.trim_ascii())
        .ok()
        .and_then(|s| s.parse::<u32>().ok())
        .ok_or_else(|| {
            (
                "status",
                format!(
                    "`{}` is not a status word (an integer from 0 to 2^32 - 1)",
                    text(t)
                ),
            )
        })
}

/// A BGM-3 line: the logger's stamp, then `PP:CCCCCC SS` (the line's last two tokens).
pub fn parse_bgm3(line: &[u8], scale: TimeScale) -> Result<SerialLine, Bad> {
    let toks: Vec<(usize, &[u8])> = tokens(line.trim_ascii_end()).collect();
    let [.., (at, record), (_, status)] = toks[..] else {
        return Err((
            "line",
            "not a BGM-3 line: a logger's time, then `PP:CCCCCC SS`".to_owned(),
        ));
    };
    let Some(colon) = record.iter().position(|&c| c == b':') else {
        return Err((
            "counts",
            format!("`{}` is not `PP:CCCCCC` (prefix, counts)", text(record)),
        ));
    };
    integer(&record[..colon], "prefix")?;
    let counts = integer(&record[colon + 1..], "counts")?;
    let status = status_word(status)?;
    let (gps_ns, form, stamp) = logger_time(&line[..at], scale)?;
    Ok(SerialLine {
        gps_ns,
        form,
        reading: counts as f64,
        monitors: None,
        status,
        stamp,
    })
}

/// Fields of a DGS raw record, its `$AT1M_...` head included.
pub const DGS_RAW_FIELDS: usize = 19;

/// The monitors' scale, as shipgrav's `read_dgs_raw(scale_ccp=True)`.
const MONITOR_SCALE: f64 = 1e-5;

/// A DGS raw serial line: the logger's stamp, then the `$AT1` record; the checksum checked.
pub fn parse_dgs_raw(line: &[u8], scale: TimeScale) -> Result<SerialLine, Bad> {
    let Some(at) = memchr::memmem::find(line, b"$AT1") else {
        return Err((
            "line",
            "no `$AT1` record (a DGS AT1M/AT1A raw serial line)".to_owned(),
        ));
    };
    let record = line[at..].trim_ascii_end();
    let fields: Vec<&[u8]> = record.split(|&c| c == b',').collect();
    if fields.len() != DGS_RAW_FIELDS {
        return Err((
            "line",
            format!(
                "{} fields in the `$AT1` record, expected {DGS_RAW_FIELDS} ($AT1M_..., gravity, \
                 long, cross, beam, temperature, pressure, e-temperature, VCC, VE, AL, AX, status, \
                 checksum, latitude, longitude, speed, course, stamp)",
                fields.len()
            ),
        ));
    }
    const NAMES: [&str; 11] = [
        "gravity", "long", "cross", "beam", "temp", "pressure", "etemp", "vcc", "ve", "al", "ax",
    ];
    let mut v = [0i64; 11];
    for (k, name) in NAMES.iter().enumerate() {
        v[k] = integer(fields[k + 1], name)?;
    }
    let status = status_word(fields[12])?;
    let checksum = integer(fields[13], "checksum")?;
    let sum: i64 = v.iter().sum();
    if sum != checksum {
        return Err((
            "checksum",
            format!("the fields from gravity to AX sum to {sum}, the checksum is {checksum}"),
        ));
    }
    let (gps_ns, form, stamp) = logger_time(&line[..at], scale)?;
    let m = |k: usize| v[k] as f64 * MONITOR_SCALE;
    Ok(SerialLine {
        gps_ns,
        form,
        reading: v[0] as f64,
        monitors: Some([m(8), m(7), m(9), m(10)]),
        status,
        stamp,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn utc(iso: &str) -> i64 {
        crate::base::time::iso_gps_ns(iso, TimeScale::Utc).expect("time")
    }

    /// Each of the four loggers' stamps of shipgrav's BGM-3 samples: the time, the form, the
    /// counts, and the bytes of the stamp.
    #[test]
    fn each_loggers_stamp_is_read() {
        for (line, form, iso, counts, stamp) in [
            (
                "BGM 2022/07/01 12:17:33.492 BGM3 04:024963 00",
                StampForm::YearMonthDay,
                "2022-07-01T12:17:33.492Z",
                24963.0,
                "2022/07/01 12:17:33.492",
            ),
            (
                "2022-11-07T17:13:45.329611Z 04:024882 00",
                StampForm::Iso,
                "2022-11-07T17:13:45.329611Z",
                24882.0,
                "2022-11-07T17:13:45.329611Z",
            ),
            (
                "03/13/2022,00:00:02.449,04:025529 00",
                StampForm::MonthDayYear,
                "2022-03-13T00:00:02.449Z",
                25529.0,
                "03/13/2022,00:00:02.449",
            ),
            (
                "vc01\t2020:244:00:00:00.3244\t04:025229 00",
                StampForm::YearDayOfYear,
                "2020-08-31T00:00:00.3244Z",
                25229.0,
                "2020:244:00:00:00.3244",
            ),
        ] {
            let l = parse_bgm3(line.as_bytes(), TimeScale::Utc).expect(line);
            assert_eq!(
                (l.form, l.gps_ns, l.reading),
                (form, utc(iso), counts),
                "{line}"
            );
            assert_eq!(&line[l.stamp.clone()], stamp);
        }
        // The session's scale where the stamp has no zone.
        let l = parse_bgm3(b"03/13/2022,00:00:02.449,04:025529 00", TimeScale::Gpst).expect("gpst");
        assert_eq!(l.gps_ns + 18_000_000_000, utc("2022-03-13T00:00:02.449Z"));
    }

    /// Every cut and every one-byte change of each layout's line (to a separator, a digit, a
    /// letter, a NUL or a byte that is not UTF-8) is read or refused, never a panic.
    #[test]
    fn no_damaged_line_panics() {
        let lines = [
            "BGM 2022/07/01 12:17:33.492 BGM3 04:024963 00",
            "2022-11-07T17:13:45.329611Z 04:024882 00",
            "03/13/2022,00:00:02.449,04:025529 00",
            "vc01\t2020:244:00:00:00.3244\t04:025229 00",
            "grav_dgs_33_raw\t2024-10-18T22:12:35.6591Z\t$AT1M_3.64_438219,19964,1208,-578,\
             4008935,273,498,202,30569,425,277,-224,266,4061549,0.0,0.0,0.0,0.0,438219",
        ];
        let mut read = 0;
        for line in lines {
            let b = line.as_bytes();
            let mut variants: Vec<Vec<u8>> = (0..=b.len()).map(|k| b[..k].to_vec()).collect();
            for k in 0..b.len() {
                for to in [b',', b' ', b':', b'/', b'9', b'x', 0, 0xff] {
                    let mut v = b.to_vec();
                    v[k] = to;
                    variants.push(v);
                }
            }
            for v in &variants {
                read += usize::from(parse_bgm3(v, TimeScale::Utc).is_ok());
                read += usize::from(parse_dgs_raw(v, TimeScale::Utc).is_ok());
            }
        }
        assert!(read > 100, "{read}");
    }

    /// A damaged field is named, and a stamp that is not a time is refused.
    #[test]
    fn a_damaged_bgm3_or_dgs_raw_field_is_named() {
        for (line, field) in [
            ("BGM 2022/07/01 12:17:33.492 BGM3 04:0249x3 00", "counts"),
            ("BGM 2022/07/01 12:17:33.492 BGM3 04:024963 0x", "status"),
            ("BGM 2022/07/01 12:17:33.492 BGM3 04:024963 -1", "status"),
            (
                "BGM 2022/07/01 12:17:33.492 BGM3 04:024963 4294967296",
                "status",
            ),
            ("BGM 2022/07/01 12:17:33.492 BGM3 04024963 00", "counts"),
            ("BGM 2022/13/01 12:17:33.492 BGM3 04:024963 00", "time"),
            ("BGM BGM3 04:024963 00", "time"),
            ("vc01\t2021:366:00:00:00.3244\t04:025229 00", "time"),
            ("00", "line"),
        ] {
            let e = parse_bgm3(line.as_bytes(), TimeScale::Utc).expect_err(line);
            assert_eq!(e.0, field, "{line}: {e:?}");
        }
        let good = "03/12/2022,16:04:06.634,$AT1M_3.61_5370472,-82,533,826,4081100,209,511,200,\
                    3571,2,7,-1,330,4086876,0.0000000000,0.0000000000,0.0000,0.0000,00000131034752 ";
        let l = parse_dgs_raw(good.as_bytes(), TimeScale::Utc).expect("good");
        assert_eq!(l.reading.to_bits(), (-82.0f64).to_bits());
        assert_eq!(l.status, 330);
        let m = l.monitors.expect("a DGS's");
        for (got, want) in m.iter().zip([2e-5, 3571e-5, 7e-5, -1e-5]) {
            assert!((got - want).abs() < 1e-15, "{m:?}");
        }
        for (from, to, field) in [
            (",-82,", ",-83,", "checksum"),
            (",3571,", ",35x1,", "vcc"),
            (",4086876,", ",,", "checksum"),
            ("$AT1M", "$XT1M", "line"),
            ("03/12/2022", "03/12/20x2", "time"),
            (",330,", ",-330,", "status"),
        ] {
            let line = good.replacen(from, to, 1);
            let e = parse_dgs_raw(line.as_bytes(), TimeScale::Utc).expect_err(&line);
            assert_eq!(e.0, field, "{line}: {e:?}");
        }
    }
}
