//! NMEA 0183 navigation sentences (docs/formats.md 10.1), as ships' loggers write them: one
//! sentence a line, after whatever the logger puts before it (a clock, a device name, a
//! comma-separated date), from its `$` to its checksum. Read here:
//!
//! | sentence | fields read |
//! |---|---|
//! | GGA | UTC time of day, latitude, longitude, fix quality (0: no fix), altitude above mean sea level (m), the geoid's separation (m; may be empty) |
//! | RMC | UTC time of day, status (A valid, V not), latitude, longitude, date (ddmmyy) |
//! | ZDA | UTC time of day, day, month, year |
//!
//! Any talker (GP, GN, IN, ...). A checksum (`*hh`, the XOR of the bytes between `$` and
//! `*`) that does not match refuses the sentence; one that is absent is allowed, as the
//! standard allows. Other sentences (VTG, GLL, HDT, proprietary `$P...`) are not read, nor
//! their checksums checked (R/V Sally Ride's logger writes `$PSXN` sentences whose
//! checksums do not match). No I/O.

/// A field that does not parse: (field name, message).
pub type Bad = (&'static str, String);

/// A sentence read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Sentence {
    /// A GGA fix.
    Gga(Gga),
    /// An RMC: its time and date, validity and position.
    Rmc {
        /// UTC time of day, ns.
        time_of_day_ns: i64,
        /// UTC date (year, month, day).
        date: (i32, u8, u8),
        /// Status A.
        valid: bool,
        /// Latitude and longitude, deg.
        position: [f64; 2],
    },
    /// A ZDA: the UTC date (and time of day).
    Zda {
        /// UTC time of day, ns.
        time_of_day_ns: i64,
        /// UTC date (year, month, day).
        date: (i32, u8, u8),
    },
    /// A sentence not read here.
    Other,
}

/// A GGA fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gga {
    /// UTC time of day, ns.
    pub time_of_day_ns: i64,
    /// Latitude and longitude, deg.
    pub position: [f64; 2],
    /// Fix quality (0: none; 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, ...).
    pub quality: u32,
    /// Altitude above mean sea level (the geoid), m; None where empty.
    pub altitude_m: Option<f64>,
    /// The geoid's height above the ellipsoid, m; None where empty.
    pub separation_m: Option<f64>,
}

/// The sentence in `line` (from its `$` on), or None when the line holds none.
pub fn find(line: &[u8]) -> Option<&[u8]> {
    let at = line.iter().position(|&b| b == b'$')?;
    Some(line[at..].trim_ascii_end())
}

/// `sentence` (from its `$`) read; a checksum that does not match, or a field that does not
/// parse in a sentence read here, names the field.
pub fn parse(sentence: &[u8]) -> Result<Sentence, Bad> {
    let body = &sentence[1..];
    let kind = body.split(|&b| b == b',').next().unwrap_or_default();
    if kind.len() < 5
        || kind.starts_with(b"P")
        || !matches!(&kind[kind.len() - 3..], b"GGA" | b"RMC" | b"ZDA")
    {
        // Not read here: passed over, its checksum unchecked.
        return Ok(Sentence::Other);
    }
    let fields: Vec<&[u8]> = verified(body)?.split(|&b| b == b',').collect();
    let need = |n: usize, name: &'static str| {
        if fields.len() < n {
            Err((
                name,
                format!(
                    "{} fields, a {name} sentence has at least {n}",
                    fields.len()
                ),
            ))
        } else {
            Ok(())
        }
    };
    Ok(match &kind[kind.len() - 3..] {
        b"GGA" => {
            need(12, "GGA")?;
            Sentence::Gga(Gga {
                time_of_day_ns: time_of_day(fields[1])?,
                position: position(&fields[2..6])?,
                quality: integer(fields[6], "quality")?,
                altitude_m: optional(fields[9], "altitude")?,
                separation_m: optional(fields[11], "separation")?,
            })
        }
        b"RMC" => {
            need(10, "RMC")?;
            Sentence::Rmc {
                time_of_day_ns: time_of_day(fields[1])?,
                valid: fields[2] == b"A",
                position: if fields[2] == b"A" {
                    position(&fields[3..7])?
                } else {
                    [f64::NAN; 2]
                },
                date: ddmmyy(fields[9])?,
            }
        }
        b"ZDA" => {
            need(5, "ZDA")?;
            let day = integer(fields[2], "day")?;
            let month = integer(fields[3], "month")?;
            let year = integer(fields[4], "year")?;
            Sentence::Zda {
                time_of_day_ns: time_of_day(fields[1])?,
                date: date(year, month, day)?,
            }
        }
        _ => Sentence::Other,
    })
}

/// The sentence's body (between `$` and `*`) with its checksum, where written, checked.
fn verified(body: &[u8]) -> Result<&[u8], Bad> {
    let Some(star) = body.iter().position(|&b| b == b'*') else {
        return Ok(body);
    };
    let (body, sum) = (&body[..star], body[star + 1..].trim_ascii());
    let want = std::str::from_utf8(sum)
        .ok()
        .and_then(|s| u8::from_str_radix(s, 16).ok())
        .ok_or_else(|| ("checksum", format!("`{}` is not two hex digits", text(sum))))?;
    let got = body.iter().fold(0u8, |a, b| a ^ b);
    if got != want {
        return Err((
            "checksum",
            format!("{got:02X} computed, {want:02X} written: the sentence is damaged"),
        ));
    }
    Ok(body)
}

fn text(f: &[u8]) -> String {
    String::from_utf8_lossy(f).into_owned()
}

fn number(f: &[u8], name: &'static str) -> Result<f64, Bad> {
    std::str::from_utf8(f.trim_ascii())
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .filter(|v| v.is_finite())
        .ok_or_else(|| (name, format!("`{}` is not a number", text(f))))
}

fn optional(f: &[u8], name: &'static str) -> Result<Option<f64>, Bad> {
    if f.trim_ascii().is_empty() {
        Ok(None)
    } else {
        number(f, name).map(Some)
    }
}

fn integer(f: &[u8], name: &'static str) -> Result<u32, Bad> {
    std::str::from_utf8(f.trim_ascii())
        .ok()
        .and_then(|s| s.parse::<u32>().ok())
        .ok_or_else(|| (name, format!("`{}` is not an integer", text(f))))
}

/// `hhmmss[.sss]` as ns since midnight.
fn time_of_day(f: &[u8]) -> Result<i64, Bad> {
    let bad = || {
        (
            "time",
            format!("`{}` is not a time of day hhmmss.ss", text(f)),
        )
    };
    if f.len() < 6 || !f[..6].iter().all(u8::is_ascii_digit) {
        return Err(bad());
    }
    let two = |k: usize| i64::from(f[k] - b'0') * 10 + i64::from(f[k + 1] - b'0');
    let (h, m) = (two(0), two(2));
    let s = number(&f[4..], "time").map_err(|_| bad())?;
    if h > 23 || m > 59 || !(0.0..61.0).contains(&s) {
        return Err(bad());
    }
    Ok((h * 3600 + m * 60) * 1_000_000_000 + (s * 1e9).round() as i64)
}

/// `[ddmm.mmmm, N|S, dddmm.mmmm, E|W]` as latitude and longitude, deg.
fn position(f: &[&[u8]]) -> Result<[f64; 2], Bad> {
    let angle =
        |v: &[u8], hemisphere: &[u8], name: &'static str, (pos, neg, max): (&[u8], &[u8], f64)| {
            let x = number(v, name)?;
            let degrees = (x / 100.0).trunc();
            let minutes = x - degrees * 100.0;
            if !(0.0..60.0).contains(&minutes) {
                return Err((name, format!("`{}`: {minutes} minutes", text(v))));
            }
            let value = degrees + minutes / 60.0;
            let value = match hemisphere {
                h if h == pos => value,
                h if h == neg => -value,
                h => return Err((name, format!("hemisphere `{}`", text(h)))),
            };
            if value.abs() > max {
                return Err((name, format!("{value} is beyond +/-{max}")));
            }
            Ok(value)
        };
    Ok([
        angle(f[0], f[1], "lat", (b"N", b"S", 90.0))?,
        angle(f[2], f[3], "lon", (b"E", b"W", 180.0))?,
    ])
}

fn ddmmyy(f: &[u8]) -> Result<(i32, u8, u8), Bad> {
    let n = integer(f, "date")?;
    if f.trim_ascii().len() != 6 {
        return Err(("date", format!("`{}` is not ddmmyy", text(f))));
    }
    // Two-digit years: 1980-2079 (GPS's own era).
    let yy = n % 100;
    let year = if yy >= 80 { 1900 + yy } else { 2000 + yy };
    date(year, (n / 100) % 100, n / 10_000)
}

fn date(year: u32, month: u32, day: u32) -> Result<(i32, u8, u8), Bad> {
    let narrow = |v: u32| u8::try_from(v).unwrap_or(0);
    i32::try_from(year)
        .ok()
        .and_then(|y| crate::contract::manifest::calendar_date(y, narrow(month), narrow(day)))
        .ok_or_else(|| {
            (
                "date",
                format!("{year:04}-{month:02}-{day:02} is not a date"),
            )
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// R/V Atlantis's logger (shipgrav's `AT01_nav.gps`): a clock and a device before the
    /// sentence.
    #[test]
    fn a_gga_after_a_loggers_prefix() {
        let line = b"NAV 2022/07/01 12:17:33.537 GPS $GPGGA,121733.00,4131.403226,N,07040.311159,W,2,12,0.9,25.169,M,-30.062,M,4.0,0402*46";
        let Sentence::Gga(g) = parse(find(line).expect("a sentence")).expect("read") else {
            panic!("a GGA");
        };
        assert_eq!(g.time_of_day_ns, (12 * 3600 + 17 * 60 + 33) * 1_000_000_000);
        assert!((g.position[0] - (41.0 + 31.403226 / 60.0)).abs() < 1e-12);
        assert!((g.position[1] + (70.0 + 40.311159 / 60.0)).abs() < 1e-12);
        assert_eq!(
            (g.quality, g.altitude_m, g.separation_m),
            (2, Some(25.169), Some(-30.062))
        );
    }

    /// A damaged sentence is refused by its checksum; RMC and ZDA give their dates; an empty
    /// separation is None; other sentences are passed over.
    #[test]
    fn checksums_dates_and_empty_fields() {
        let damaged = b"$GPGGA,121733.00,4131.403226,N,07040.311159,W,2,12,0.9,25.169,M,-30.062,M,4.0,0402*47";
        assert_eq!(parse(damaged).expect_err("damaged").0, "checksum");
        let rmc = b"$GPRMC,000000.81,A,7520.156405,S,17945.635852,W,5.2,5.71,130123,,,A*6C";
        match parse(rmc).expect("rmc") {
            Sentence::Rmc {
                date,
                valid,
                position,
                ..
            } => {
                assert_eq!(date, (2023, 1, 13));
                assert!(valid && position[0] < -75.0 && position[1] < -179.0);
            }
            s => panic!("{s:?}"),
        }
        let zda = b"$GPZDA,000000.00,05,11,2022,,*61";
        assert!(matches!(
            parse(zda).expect("zda"),
            Sentence::Zda {
                date: (2022, 11, 5),
                ..
            }
        ));
        let no_separation =
            b"$INGGA,000003.560,3217.33152,N,11839.14935,W,5,26,0.8,0.19,M,,,7,1015*06";
        let Sentence::Gga(g) = parse(no_separation).expect("gga") else {
            panic!("a GGA");
        };
        assert_eq!((g.altitude_m, g.separation_m), (Some(0.19), None));
        assert_eq!(
            parse(b"$PSXN,20,0,0,0,0*3B").expect("other"),
            Sentence::Other
        );
        assert_eq!(
            parse(b"$GPVTG,218.7,T,,M,0.01,N,0.02,K,D*07").expect("other"),
            Sentence::Other
        );
        let bad_lat =
            b"$GPGGA,121733.00,41x1.4,N,07040.311159,W,2,12,0.9,25.169,M,-30.062,M,4.0,0402";
        assert_eq!(parse(bad_lat).expect_err("lat").0, "lat");
        assert!(find(b"no sentence here").is_none());
    }
}
