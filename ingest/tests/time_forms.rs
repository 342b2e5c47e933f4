//! Times as loggers write them (docs/formats.md 9.1): the replica's day-1 logs rewritten
//! with ISO 8601 UTC times and `Z` in the ADC CSV (a header of any names), Unix seconds in
//! the temperature CSV (no header), and the theodolite log's calendar times with a `+01:00`
//! offset, read through the 1.2 keys, give the very tables the GPS-week logs give: the same
//! acceleration and temperature tables byte for byte, the same readings at the same times.
//! Before, `2026-03-14T09:12:03Z` was rejected with no hint.

use ingest::base::time::NS_PER_WEEK;
use ingest::contract::ingest_ledger::IngestReport;
use std::path::Path;

/// GPS minus UTC in February 2005 (leap seconds; hifitime's table says the same, and the
/// simulator's test checks it by calendar arithmetic of its own).
const LEAP_2005_NS: i64 = 13_000_000_000;
/// Unix time of the GPS epoch 1980-01-06T00:00:00 UTC, s.
const GPS_EPOCH_UNIX_S: i64 = 315_964_800;

/// A GPS-week time as UTC: (Unix ns, ISO calendar text with `offset_min` applied).
fn utc_of(week: i64, tow_s: &str, offset_min: i64) -> (i64, String) {
    let tow_ns = ingest::base::time::parse_seconds_ns(tow_s.as_bytes()).expect("tow");
    let gps = week * NS_PER_WEEK + tow_ns;
    let unix_ns = gps + GPS_EPOCH_UNIX_S * 1_000_000_000 - LEAP_2005_NS;
    (unix_ns, calendar(unix_ns + offset_min * 60_000_000_000))
}

/// `YYYY-MM-DDTHH:MM:SS.mmm` of Unix ns.
fn calendar(unix_ns: i64) -> String {
    let day = unix_ns.div_euclid(86_400_000_000_000);
    let (y, m, d) = ingest::base::time::civil_from_days(day);
    let ns = unix_ns.rem_euclid(86_400_000_000_000);
    let (s, frac) = (ns / 1_000_000_000, (ns % 1_000_000_000) / 1_000_000);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{frac:03}",
        s / 3600,
        s / 60 % 60,
        s % 60
    )
}

/// Rewrites a GPS-week CSV's data lines with `time(week, tow)` in place of its two time
/// fields, and its header with `header` (None: no header).
fn rewrite_csv(path: &Path, header: Option<&str>, time: impl Fn(i64, &str) -> String) {
    let text = std::fs::read_to_string(path).expect("read");
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with('#') {
            out.push_str(line);
        } else if line.starts_with("gps_week") {
            match header {
                Some(h) => out.push_str(h),
                None => continue,
            }
        } else {
            let mut f = line.splitn(3, ',');
            let week: i64 = f.next().expect("week").parse().expect("week");
            let tow = f.next().expect("tow");
            out.push_str(&format!(
                "{},{}",
                time(week, tow),
                f.next().expect("values")
            ));
        }
        out.push('\n');
    }
    std::fs::write(path, out).expect("write");
}

#[test]
fn every_time_form_gives_the_same_tables() {
    let dir = tempfile::tempdir().expect("tempdir");
    let original = dir.path().join("original");
    let rewritten = dir.path().join("rewritten");
    fixtures::copy_dataset("esgt-2005-csv", &original, |m| m).expect("copy");
    fixtures::copy_dataset("esgt-2005-csv", &rewritten, |m| {
        m.replacen(
            "adc_csv = \"raw/day1_adc.csv\"",
            "adc_csv = \"raw/day1_adc.csv\"\nadc_time = \"iso\"\ntemperature_time = \"unix_s\"\n\
             theodolite_time = \"iso\"",
            1,
        )
    })
    .expect("copy");
    let raw = rewritten.join("raw");
    rewrite_csv(
        &raw.join("day1_adc.csv"),
        Some("utc,acc_x,acc_y,acc_z"),
        |w, t| format!("{}Z", utc_of(w, t, 0).1),
    );
    rewrite_csv(&raw.join("day1_temp.csv"), None, |w, t| {
        let unix_ns = utc_of(w, t, 0).0;
        format!(
            "{}.{:03}",
            unix_ns / 1_000_000_000,
            unix_ns % 1_000_000_000 / 1_000_000
        )
    });
    // The theodolite log's UTC calendar times, written one hour ahead with +01:00.
    let theodolite = raw.join("day1_theodolite.txt");
    let text = std::fs::read_to_string(&theodolite).expect("read");
    let shifted: Vec<String> = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            if l.starts_with('#') || f.len() != 3 {
                return l.to_owned();
            }
            let (c, _) = ingest::base::time::parse_iso(f[1]).expect("calendar");
            let unix_s =
                (ingest::base::time::gps_ns(c, ingest::contract::manifest::TimeScale::Gpst)
                    .expect("ns"))
                    + GPS_EPOCH_UNIX_S * 1_000_000_000;
            format!(
                "{} {}+01:00 {}",
                f[0],
                calendar(unix_s + 3_600_000_000_000),
                f[2]
            )
        })
        .collect();
    std::fs::write(&theodolite, shifted.join("\n") + "\n").expect("write");

    let (out_a, out_b) = (dir.path().join("out-a"), dir.path().join("out-b"));
    let a = ingest::run(&original, &out_a).expect("GPS-week logs");
    let b = ingest::run(&rewritten, &out_b).expect("ISO, Unix and offset logs");
    for (fa, fb) in a.files.iter().zip(&b.files) {
        assert_eq!(
            (fa.accepted, fa.rejected_total()),
            (fb.accepted, fb.rejected_total()),
            "{}: {:?}",
            fb.path,
            fb.rejections
        );
    }
    for table in ["acceleration.parquet", "temperature.parquet"] {
        let read = |out: &Path| std::fs::read(out.join("ingest").join(table)).expect(table);
        assert!(read(&out_a) == read(&out_b), "{table} differs");
    }
    let times = |r: &IngestReport| {
        r.sessions
            .iter()
            .map(|s| (s.first_gps_ns, s.last_gps_ns, s.readings))
            .collect::<Vec<_>>()
    };
    assert_eq!(times(&a), times(&b));
}

/// The manifest's time keys are checked: a form a log cannot have, `start` missing for
/// "s", a zone that is not `Z` or `+HH:MM`, each named with its key or field.
#[test]
fn time_keys_are_checked() {
    let cases = [
        (
            "adc_time = \"iso\"\nacquisition = \"raw/x.gcb\"",
            "session[0].adc_time",
        ),
        ("adc_time = \"s\"", "session[0].start"),
        ("theodolite_time = \"hours\"", "line"),
        ("start = \"2005-02-15T09:00:00\"", "session[0].start"),
    ];
    for (extra, key) in cases {
        let dir = tempfile::tempdir().expect("tempdir");
        let ds = dir.path().join("ds");
        fixtures::copy_dataset("esgt-2005-csv", &ds, |m| {
            let m = if extra.contains("acquisition") {
                m.replacen(
                    "adc_csv = \"raw/day1_adc.csv\"\ntemperature_csv = \"raw/day1_temp.csv\"",
                    "",
                    1,
                )
            } else {
                m
            };
            m.replacen("id = \"day1\"", &format!("id = \"day1\"\n{extra}"), 1)
        })
        .expect("copy");
        if extra.contains("x.gcb") {
            std::fs::write(ds.join("raw/x.gcb"), b"").expect("write");
        }
        let e = ingest::run(&ds, &dir.path().join("out")).expect_err(extra);
        assert!(e.to_string().contains(key), "{extra}: {e}");
    }
}

mod iso_fast_path {
    use ingest::base::time::{TimeForm, TimeReader, gps_ns, parse_iso};
    use ingest::contract::manifest::TimeScale;
    use proptest::prelude::*;

    /// The general parser's answer: calendar and zone, then hifitime.
    fn general(s: &str, scale: TimeScale) -> Option<i64> {
        let (c, offset) = parse_iso(s).ok()?;
        let scale = if offset.is_some() {
            TimeScale::Utc
        } else {
            scale
        };
        Some(gps_ns(c, scale)? - i64::from(offset.unwrap_or(0)) * 60_000_000_000)
    }

    proptest! {
        /// The reader's fast path (a date's midnight once, then the time of day) gives what
        /// the general parser gives, for `Z` and zone-less times in every scale, whatever
        /// the order of the days read (the cache is per date and zone).
        #[test]
        fn agrees_with_the_general_parser(
            times in prop::collection::vec(
                (1981i32..2035, 1u8..13, 1u8..29, 0u8..24, 0u8..60, 0u8..60, 0u32..1_000_000_000, 0usize..4, any::<bool>()),
                1..40,
            ),
            scale in prop::sample::select(vec![TimeScale::Utc, TimeScale::Gpst, TimeScale::Tai]),
        ) {
            let mut reader = TimeReader::new(TimeForm::Iso, scale, None);
            for (y, mo, d, h, mi, s, ns, digits, zulu) in times {
                let frac = match digits {
                    0 => String::new(),
                    k => format!(".{:0width$}", ns / 10u32.pow(9 - 3 * k as u32), width = 3 * k),
                };
                let text = format!(
                    "{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}{frac}{}",
                    if zulu { "Z" } else { "" }
                );
                let got = reader.read(&[text.as_bytes()]).ok();
                prop_assert_eq!(got, general(&text, scale), "{}", text);
            }
        }
    }

    /// Around the leap second at the end of 2016: the day's last second and the next day's
    /// first are one second apart in GPS time (23:59:60 goes to the general parser).
    #[test]
    fn a_leap_second_day_is_read_right() {
        let mut r = TimeReader::new(TimeForm::Iso, TimeScale::Utc, None);
        let mut at = |s: &str| r.read(&[s.as_bytes()]).expect("reads");
        let before = at("2016-12-31T23:59:59.000Z");
        let leap = at("2016-12-31T23:59:60.000Z");
        let after = at("2017-01-01T00:00:00.000Z");
        assert_eq!(leap - before, 1_000_000_000);
        assert_eq!(after - before, 2_000_000_000, "the inserted second counts");
        // No leap second ended 2018: its 23:59:60 does not exist, and is said so.
        let e = r
            .read(&[b"2018-12-31T23:59:60.000Z".as_slice()])
            .expect_err("not a leap second");
        assert!(e.0 == "time" && e.1.contains("leap second"), "{e:?}");
    }
}
