//! Ingest at its boundary: datasets in, Parquet tables and ledger out, checked against the
//! simulator's truth.

use arrow_array::types::{Float64Type, Int32Type, Int64Type};
use arrow_array::{RecordBatch, cast::AsArray};
use ingest::Options;
use ingest::contract::ingest_ledger::IngestReport;
use ingest::contract::ingest_ledger::reason;
use sha2::Digest;
use std::path::PathBuf;

mod common;
use common::read_table;

fn ingest(name: &str) -> (tempfile::TempDir, IngestReport) {
    let out = tempfile::tempdir().expect("tempdir");
    let report = ingest::run(&fixtures::dataset_dir(name), out.path()).expect("ingest succeeds");
    (out, report)
}

fn i64_col(batches: &[RecordBatch], name: &str) -> Vec<i64> {
    batches
        .iter()
        .flat_map(|b| {
            b.column_by_name(name)
                .expect("column")
                .as_primitive::<Int64Type>()
                .values()
                .to_vec()
        })
        .collect()
}

fn opt_i32_col(batches: &[RecordBatch], name: &str) -> Vec<Option<i32>> {
    batches
        .iter()
        .flat_map(|b| {
            b.column_by_name(name)
                .expect("column")
                .as_primitive::<Int32Type>()
                .iter()
                .collect::<Vec<_>>()
        })
        .collect()
}

fn opt_f64_col(batches: &[RecordBatch], name: &str) -> Vec<Option<f64>> {
    batches
        .iter()
        .flat_map(|b| {
            b.column_by_name(name)
                .expect("column")
                .as_primitive::<Float64Type>()
                .iter()
                .collect::<Vec<_>>()
        })
        .collect()
}

/// Every file of every fixture: accepted plus rejected is what was read, the bytes of a binary
/// log add up to its size, the hash is the file's, and the counts are the simulator's.
#[test]
fn every_fixture_is_accounted_for() {
    for name in fixtures::catalog::COMMITTED {
        let dir = fixtures::dataset_dir(name);
        let truth = fixtures::read_truth(&dir).expect("truth");
        let (_out, report) = ingest(name);
        for f in &report.files {
            let bytes = std::fs::read(dir.join(&f.path)).expect("input");
            assert_eq!(f.bytes, bytes.len() as u64, "{name}/{}", f.path);
            let sha = sha2::Sha256::digest(&bytes)
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect::<String>();
            assert_eq!(f.sha256, sha, "{name}/{}", f.path);
            assert_eq!(f.read, f.accepted + f.rejected_total(), "{name}/{}", f.path);
            let t = truth
                .session
                .iter()
                .find(|s| s.id == f.session)
                .and_then(|s| s.file.iter().find(|x| x.path == f.path))
                .expect("file in truth");
            if let Some(b) = &f.byte_ledger {
                assert_eq!(b.total(), f.bytes, "{name}/{}: {b:?}", f.path);
                let count = |r: &str| f.rejected.get(r).copied().unwrap_or(0);
                assert_eq!(
                    f.accepted_by_kind.get("acceleration").copied().unwrap_or(0),
                    t.acceleration_records
                );
                assert_eq!(
                    f.accepted_by_kind.get("temperature").copied().unwrap_or(0),
                    t.temperature_records
                );
                assert_eq!(count(reason::BAD_CRC), t.bad_crc, "{name}");
                assert_eq!(count(reason::UNKNOWN_TYPE), t.unknown_type, "{name}");
                assert_eq!(count(reason::WRONG_LENGTH), t.wrong_length, "{name}");
                assert_eq!(count(reason::DUPLICATE), t.duplicate, "{name}");
                assert_eq!(count(reason::TIME_BACKWARDS), t.backwards, "{name}");
                assert_eq!(
                    count(reason::TRUNCATED_TAIL),
                    u64::from(t.truncated_tail_bytes > 0)
                );
                assert_eq!(b.truncated_tail, t.truncated_tail_bytes);
                assert_eq!(b.in_rejected_frames, 25 * (t.duplicate + t.backwards));
                assert_eq!(
                    b.skipped_resynchronising,
                    t.junk_bytes + 25 * (t.bad_crc + t.unknown_type) + 26 * t.wrong_length,
                    "{name}"
                );
            } else if f.role == "theodolite" {
                assert_eq!(f.accepted, t.readings, "{name}/{}", f.path);
            } else {
                let kind = if f.role == "adc_csv" {
                    t.acceleration_records
                } else {
                    t.temperature_records
                };
                assert_eq!(f.accepted, kind, "{name}/{}", f.path);
                assert!(f.rejected.is_empty());
            }
        }
        for (s, st) in report.sessions.iter().zip(&truth.session) {
            assert_eq!(s.readings, st.readings, "{name}/{}", s.id);
            let never: Vec<String> = s
                .channels_never_connected
                .iter()
                .map(|ch| {
                    truth
                        .accelerometer
                        .iter()
                        .find(|a| a.channel == *ch)
                        .expect("acc")
                        .id
                        .clone()
                })
                .collect();
            assert_eq!(never, st.disconnected, "{name}/{}", s.id);
        }
    }
}

/// The binary log and its CSV twin give the same samples, but for the frames damaged in the
/// binary log; the acceleration stream is in time order at 32 ms.
#[test]
fn binary_and_csv_give_the_same_streams() {
    let (bin_out, bin) = ingest("esgt-2005");
    let (csv_out, _) = ingest("esgt-2005-csv");
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let b = read_table(bin_out.path(), ingest::contract::tables::acceleration::FILE);
    let c = read_table(csv_out.path(), ingest::contract::tables::acceleration::FILE);
    let bt = i64_col(&b, ingest::contract::tables::TIME_GPS_NS);
    let ct = i64_col(&c, ingest::contract::tables::TIME_GPS_NS);
    let damaged: u64 = truth
        .session
        .iter()
        .map(|s| {
            s.damage
                .iter()
                .filter(|d| d.damage == fixtures::scenario::Damage::BadCrc)
                .count() as u64
        })
        .sum();
    assert_eq!(
        ct.len() as u64,
        truth
            .session
            .iter()
            .map(|s| s.acceleration_samples)
            .sum::<u64>()
    );
    assert_eq!(bt.len() as u64 + damaged, ct.len() as u64);
    assert_eq!(
        bin.tables[ingest::contract::tables::acceleration::FILE],
        bt.len() as u64
    );
    for name in ingest::contract::tables::acceleration::COUNTS {
        let bv = opt_i32_col(&b, name);
        let cv = opt_i32_col(&c, name);
        let mut j = 0;
        for (i, t) in bt.iter().enumerate() {
            while ct[j] != *t {
                j += 1;
            }
            assert_eq!(bv[i], cv[j], "{name} at {t}");
        }
    }
    // Day 2: channel 2 is null throughout.
    let ch2 = opt_i32_col(&b, "counts_ch2");
    let day2_start = truth.session[1].start_gps_ns;
    let day2: Vec<&Option<i32>> = bt
        .iter()
        .zip(&ch2)
        .filter(|(t, _)| **t >= day2_start)
        .map(|(_, v)| v)
        .collect();
    let day1: Vec<&Option<i32>> = bt
        .iter()
        .zip(&ch2)
        .filter(|(t, _)| **t < day2_start)
        .map(|(_, v)| v)
        .collect();
    assert!(!day1.is_empty() && !day2.is_empty());
    assert!(day2.iter().all(|v| v.is_none()));
    assert!(day1.iter().all(|v| v.is_some()));
    for w in bt.windows(2) {
        assert!(w[1] > w[0]);
    }
    let tb = read_table(bin_out.path(), ingest::contract::tables::temperature::FILE);
    let tc = read_table(csv_out.path(), ingest::contract::tables::temperature::FILE);
    for name in ingest::contract::tables::temperature::TEMPERATURE_C {
        assert_eq!(opt_f64_col(&tb, name), opt_f64_col(&tc, name), "{name}");
    }
}

/// Theodolite times arrive as GPS time whatever the log's scale (UTC with 13 or 18 leap
/// seconds, GPST), and angles as radians whatever the unit.
#[test]
fn theodolite_times_and_angles_are_the_truth() {
    for name in ["esgt-2005", "week-rollover", "gon-gpst", "two-sided"] {
        let truth = fixtures::read_truth(&fixtures::dataset_dir(name)).expect("truth");
        let (out, _) = ingest(name);
        let t = read_table(out.path(), ingest::contract::tables::theodolite::FILE);
        let times = i64_col(&t, ingest::contract::tables::TIME_GPS_NS);
        let dz = opt_f64_col(&t, ingest::contract::tables::theodolite::DZ_RAD);
        assert_eq!(times.len(), truth.reading.len(), "{name}");
        for ((time, dz), r) in times.iter().zip(&dz).zip(&truth.reading) {
            assert_eq!(*time, r.time_gps_ns, "{name} {}", r.station);
            assert!(
                (dz.expect("dz") - r.dz_read_rad).abs() < 1e-8,
                "{name} {}",
                r.station
            );
        }
    }
}

/// Across the GPS week 2047/2048 boundary the 10-bit week resolves to a continuous time line.
#[test]
fn week_rollover_is_continuous() {
    let truth = fixtures::read_truth(&fixtures::dataset_dir("week-rollover")).expect("truth");
    let (out, _) = ingest("week-rollover");
    let t = i64_col(
        &read_table(out.path(), ingest::contract::tables::acceleration::FILE),
        ingest::contract::tables::TIME_GPS_NS,
    );
    assert_eq!(t[0], truth.session[0].start_gps_ns);
    assert_eq!(*t.last().expect("rows"), truth.session[0].end_gps_ns);
    assert!(t.windows(2).all(|w| w[1] - w[0] == 32_000_000));
}

/// Same inputs, same bytes; and no partial file under any name.
#[test]
fn outputs_are_deterministic() {
    let (a, _) = ingest("damaged-log");
    let (b, _) = ingest("damaged-log");
    let mut names: Vec<PathBuf> = std::fs::read_dir(a.path().join("ingest"))
        .expect("dir")
        .map(|e| e.expect("entry").path())
        .collect();
    names.sort();
    assert_eq!(names.len(), 5, "{names:?}");
    for p in names {
        let n = p.file_name().expect("name");
        assert_eq!(
            std::fs::read(&p).expect("a"),
            std::fs::read(b.path().join("ingest").join(n)).expect("b"),
            "{n:?}"
        );
    }
}

/// The custody's outputs are the four tables, each with the hash of its bytes on disk (the
/// writers hash what they write; nothing is read back): a stream, a lab stream and a
/// multi-session dataset.
#[test]
fn custody_holds_the_tables_hashes_as_on_disk() {
    for name in ["damaged-log", "lab-logger", "roll-sessions"] {
        let (out, report) = ingest(name);
        let outputs = &report.custody.outputs;
        let mut paths: Vec<&str> = outputs.iter().map(|f| f.path.as_str()).collect();
        paths.sort_unstable();
        assert_eq!(
            paths,
            [
                "ingest/acceleration.parquet",
                "ingest/lab.parquet",
                "ingest/temperature.parquet",
                "ingest/theodolite.parquet"
            ],
            "{name}"
        );
        for f in outputs {
            let on_disk =
                ingest::contract::custody::sha256_file(&out.path().join(&f.path)).expect("table");
            assert_eq!(f.sha256, on_disk, "{name}: {}", f.path);
        }
    }
}

fn copy_dataset(name: &str) -> tempfile::TempDir {
    let dst = tempfile::tempdir().expect("tempdir");
    fixtures::copy_dataset(name, dst.path(), |m| m).expect("copy");
    dst
}

fn error_with_manifest(edit: impl Fn(String) -> String) -> String {
    let ds = copy_dataset("gon-gpst");
    let path = ds.path().join("dataset.toml");
    let text = std::fs::read_to_string(&path).expect("manifest");
    std::fs::write(&path, edit(text)).expect("write");
    let out = tempfile::tempdir().expect("tempdir");
    match ingest::run(ds.path(), out.path()) {
        Ok(_) => panic!("the edited manifest should be rejected"),
        Err(e) => e.to_string(),
    }
}

/// Each manifest error names the file and the key.
#[test]
fn manifest_errors_name_the_key_and_file() {
    // (text in the manifest, replaced by, what the error must name)
    let cases = [
        (
            "sensor_height_m = 0.25",
            "sensor_height_m = 0.25\nsensor_hieght_m = 1.0",
            "sensor_hieght_m",
        ),
        (
            "raw/s1_theodolite.txt",
            "raw/missing.txt",
            "session[0].theodolite",
        ),
        (
            "id = \"acc2\"",
            "id = \"acc1\"",
            "instrument.accelerometer[1].id",
        ),
        (
            "channel = 3",
            "channel = 2",
            "instrument.accelerometer[2].channel",
        ),
        (
            "g_abs_mgal = 980855.8",
            "g_abs_mgal = 9.81",
            "site.g_abs_mgal",
        ),
        // 980 856 mGal is a mid-latitude gravity: on the equator it is 2822 mGal from
        // normal gravity, where no place is farther than 1000.
        (
            "sensor_height_m = 0.25",
            "sensor_height_m = 0.25\nlatitude_deg = 0.0\nlongitude_deg = 10.0",
            "site.g_abs_mgal: 980855.8 mGal is 2823 mGal from normal gravity at latitude 0",
        ),
        (
            "date = \"2021-06-10\"",
            "date = \"2021-06-31\"",
            "session[0].date",
        ),
        (
            "theodolite_unit = \"gon\"",
            "theodolite_unit = \"mil\"",
            "mil",
        ),
        ("name = \"gon-gpst\"", "name = \"Gon GPST\"", "name"),
        ("sample_rate_hz = 31.25\n", "", "sample_rate_hz"),
        (
            "sample_rate_hz = 31.25\n",
            "sample_rate_hz = 31.25\nthermometer_sd_c = -0.002\n",
            "instrument.thermometer_sd_c",
        ),
        // The binary log's frames hold three channels and their temperatures.
        (
            "theodolite_unit = \"gon\"",
            "theodolite_unit = \"gon\"\nadc_columns = [1, 2]",
            "session[0].adc_columns",
        ),
        (
            "theodolite_unit = \"gon\"",
            "theodolite_unit = \"gon\"\nthermometers = \"one\"",
            "session[0].thermometers",
        ),
    ];
    for (from, to, key) in cases {
        let msg = error_with_manifest(|t| {
            assert!(t.contains(from), "{from}");
            t.replace(from, to)
        });
        assert!(msg.contains("dataset.toml"), "{msg}");
        assert!(msg.contains(key), "expected `{key}` in: {msg}");
    }
}

/// A counts CSV's value columns and thermometers (docs/formats.md 9.4) are checked by key:
/// channels out of range or twice, a temperature log beside `thermometers = "none"`, and
/// none without it where one is expected; and a log whose header is not the declared
/// columns' is refused naming its line and the header expected.
#[test]
fn value_columns_and_thermometers_are_checked_by_key() {
    let first = "adc_csv = \"raw/day1_adc.csv\"";
    for (to, key, says) in [
        (
            "adc_columns = [1, 4]",
            "session[0].adc_columns",
            "channel 4",
        ),
        ("adc_columns = [2, 2]", "session[0].adc_columns", "twice"),
        ("adc_columns = []", "session[0].adc_columns", "0 columns"),
        (
            "adc_columns = [0, 0]",
            "session[0].adc_columns",
            "0 of them a channel's",
        ),
        (
            "thermometers = \"none\"",
            "session[0].temperature_csv",
            "give one",
        ),
        (
            "thermometers = \"some\"",
            "line 37",
            "expected one of `each`, `one`, `none`",
        ),
    ] {
        let ds = copy_dataset("esgt-2005-csv");
        let path = ds.path().join("dataset.toml");
        let text = std::fs::read_to_string(&path).expect("manifest");
        std::fs::write(&path, text.replacen(first, &format!("{first}\n{to}"), 1)).expect("w");
        let out = tempfile::tempdir().expect("tempdir");
        let e = ingest::run(ds.path(), out.path())
            .expect_err(to)
            .to_string();
        assert!(e.contains(key) && e.contains(says), "{to}: {e}");
    }
    let ds = copy_dataset("esgt-2005-csv");
    let path = ds.path().join("dataset.toml");
    let text = std::fs::read_to_string(&path).expect("manifest");
    let text = text.replacen("temperature_csv = \"raw/day1_temp.csv\"", "", 1);
    std::fs::write(&path, &text).expect("w");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(ds.path(), out.path())
        .expect_err("no thermometer")
        .to_string();
    assert!(
        e.contains("session[0].temperature_csv") && e.contains("thermometers = \"none\""),
        "{e}"
    );
    std::fs::write(
        &path,
        text.replacen(
            first,
            &format!("{first}\nadc_columns = [1, 3]\nthermometers = \"none\""),
            1,
        ),
    )
    .expect("w");
    let e = ingest::run(ds.path(), out.path())
        .expect_err("three columns")
        .to_string();
    assert!(
        e.contains("day1_adc.csv:2: header") && e.contains("expected `gps_week,tow_s,c1,c3`"),
        "{e}"
    );
}

/// The temperature table ingest writes of the dataset `ds`.
fn temperature_table(ds: &std::path::Path) -> Vec<u8> {
    let out = tempfile::tempdir().expect("tempdir");
    ingest::run(ds, out.path()).expect("ingest");
    std::fs::read(out.path().join("ingest/temperature.parquet")).expect("table")
}

/// The manifest `m` of the dataset `ds` written with `lines` after the first `at`.
fn declare_after(ds: &std::path::Path, m: &str, at: &str, lines: &str) {
    let declared = m.replacen(at, &format!("{at}\n{lines}"), 1);
    assert_ne!(declared, m, "{at} is in the manifest");
    std::fs::write(ds.join("dataset.toml"), declared).expect("write");
}

/// A temperature log of more columns than thermometers at the accelerometers (docs/formats.md
/// 9.4): esgt-2005-csv's day 1 log with a box thermometer's column first, declared
/// `temperature_columns = [0, 1, 2, 3]`, gives the same temperature table as the log
/// without it; a channel given twice is refused by key.
#[test]
fn a_temperature_log_maps_its_columns() {
    let plain = copy_dataset("esgt-2005-csv");
    let boxed = copy_dataset("esgt-2005-csv");
    let log = boxed.path().join("raw/day1_temp.csv");
    let text = std::fs::read_to_string(&log).expect("log");
    let with_box: Vec<String> = text
        .lines()
        .map(|l| {
            match l
                .split_once(',')
                .and_then(|(w, rest)| Some((w, rest.split_once(',')?)))
            {
                _ if l.starts_with('#') => l.to_owned(),
                Some((w, (tow, rest))) => {
                    let first = if w == "gps_week" { "box" } else { "21.5" };
                    format!("{w},{tow},{first},{rest}")
                }
                None => l.to_owned(),
            }
        })
        .collect();
    std::fs::write(&log, with_box.join("\n") + "\n").expect("write");
    let m = std::fs::read_to_string(boxed.path().join("dataset.toml")).expect("manifest");
    let at = "temperature_csv = \"raw/day1_temp.csv\"";
    declare_after(boxed.path(), &m, at, "temperature_columns = [0, 1, 2, 3]");
    assert!(
        temperature_table(plain.path()) == temperature_table(boxed.path()),
        "the same temperatures"
    );
    declare_after(boxed.path(), &m, at, "temperature_columns = [0, 1, 1, 3]");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(boxed.path(), out.path())
        .expect_err("twice")
        .to_string();
    assert!(
        e.contains("session[0].temperature_columns") && e.contains("twice"),
        "{e}"
    );
}

/// A lab stream's times declared in the wrong unit are named (issue 49): the lab-logger's
/// drive, in Unix seconds, declared as seconds since a start, loses every line outside the
/// session, and the run's error says that read as "unix_s" they fall inside it.
#[test]
fn a_lab_stream_in_the_wrong_time_unit_is_named() {
    let ds = copy_dataset("lab-logger");
    let manifest = ds.path().join("dataset.toml");
    let m = std::fs::read_to_string(&manifest).expect("manifest");
    let wrong = m.replacen(
        "adc_time = \"unix_s\"",
        "adc_time = \"s\"\nstart = \"2026-03-16T10:00:00Z\"",
        1,
    );
    assert_ne!(wrong, m);
    std::fs::write(&manifest, wrong).expect("write");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(ds.path(), out.path())
        .expect_err("no sample")
        .to_string();
    assert!(
        e.contains("raw/drive.txt") && e.contains("read as \"unix_s\" they fall inside it"),
        "{e}"
    );
}

/// The same for a counts CSV: the lab-logger's tilt-table counts rewritten in Unix seconds
/// and declared as seconds since a start are named, their first time given.
#[test]
fn a_counts_csv_in_the_wrong_time_unit_is_named() {
    let ds = copy_dataset("lab-logger");
    let log = ds.path().join("raw/table_acc.csv");
    let text = std::fs::read_to_string(&log).expect("log");
    let unix: Vec<String> = text
        .lines()
        .map(|l| match l.split_once(',') {
            Some((t, rest)) if t.starts_with("20") => {
                let gps =
                    ingest::base::time::iso_gps_ns(t, ingest::contract::manifest::TimeScale::Utc)
                        .expect("iso");
                let written = ingest::base::time::as_written(
                    gps,
                    ingest::base::time::TimeForm::UnixS,
                    ingest::contract::manifest::TimeScale::Utc,
                    None,
                );
                format!("{},{rest}", written.split(' ').next().expect("seconds"))
            }
            _ => l.to_owned(),
        })
        .collect();
    std::fs::write(&log, unix.join("\n") + "\n").expect("write");
    let manifest = ds.path().join("dataset.toml");
    let m = std::fs::read_to_string(&manifest).expect("manifest");
    let wrong = m.replacen(
        "adc_time = \"iso\"",
        "adc_time = \"s\"\nstart = \"2026-03-14T09:12:00Z\"",
        1,
    );
    assert_ne!(wrong, m);
    std::fs::write(&manifest, wrong).expect("write");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(ds.path(), out.path())
        .expect_err("no sample")
        .to_string();
    assert!(
        e.contains("raw/table_acc.csv")
            && e.contains("the first, 1773479520.000 s")
            && e.contains("read as \"unix_s\" they fall inside it"),
        "{e}"
    );
}

/// A lab stream's temperature log may count its seconds otherwise than the stream (9.1):
/// the drive's log rewritten in seconds since a `start`, and again as a CSV of ISO 8601 UTC
/// times, gives the same temperature table as in Unix seconds.
#[test]
fn a_lab_temperature_log_counts_its_own_seconds() {
    let unix = copy_dataset("lab-logger");
    let relative = copy_dataset("lab-logger");
    let log = relative.path().join("raw/drive_temp.txt");
    let text = std::fs::read_to_string(&log).expect("log");
    // 2026-03-16T10:00:00Z, the drive's first temperature, in Unix seconds.
    let zero = 1_773_655_200.0;
    let rewritten: Vec<String> = text
        .lines()
        .map(|l| match l.split_once(' ') {
            Some((t, rest)) if t.parse::<f64>().is_ok() => {
                format!("{:.3} {rest}", t.parse::<f64>().expect("t") - zero)
            }
            _ => l.to_owned(),
        })
        .collect();
    std::fs::write(&log, rewritten.join("\n") + "\n").expect("write");
    let m = std::fs::read_to_string(relative.path().join("dataset.toml")).expect("manifest");
    let drive = "temperature_csv = \"raw/drive_temp.txt\"";
    let since_start = "temperature_time = \"s\"\nstart = \"2026-03-16T10:00:00Z\"";
    declare_after(relative.path(), &m, drive, since_start);
    let unix_table = temperature_table(unix.path());
    assert!(
        unix_table == temperature_table(relative.path()),
        "the same temperatures"
    );
    // In ISO 8601 UTC times the log is a temperature CSV (9.1): the same table again.
    let iso_lines: Vec<String> = text
        .lines()
        .map(|l| match l.split_once(' ') {
            Some((t, rest)) if t.parse::<f64>().is_ok() => {
                let ms = (t.parse::<f64>().expect("t") * 1e3).round() as i64;
                let (y, mo, d) = ingest::base::time::civil_from_days(ms.div_euclid(86_400_000));
                let ms = ms.rem_euclid(86_400_000);
                format!(
                    "{y:04}-{mo:02}-{d:02}T{:02}:{:02}:{:02}.{:03}Z,{}",
                    ms / 3_600_000,
                    ms / 60_000 % 60,
                    ms / 1000 % 60,
                    ms % 1000,
                    rest.split(' ').collect::<Vec<_>>().join(",")
                )
            }
            _ if l.starts_with('#') => l.to_owned(),
            // The header, comma-separated as a CSV's.
            _ => l.replace(' ', ","),
        })
        .collect();
    std::fs::write(&log, iso_lines.join("\n") + "\n").expect("write");
    declare_after(relative.path(), &m, drive, "temperature_time = \"iso\"");
    assert!(
        unix_table == temperature_table(relative.path()),
        "the same temperatures from ISO times"
    );
}

/// A malformed CSV line stops the run with file, line and field, or is counted when skipping;
/// either way no partial table and no ledger is left.
#[test]
fn malformed_csv_line_names_file_line_and_field() {
    let ds = copy_dataset("esgt-2005-csv");
    let adc = ds.path().join("raw/day2_adc.csv");
    let text = std::fs::read_to_string(&adc).expect("csv");
    let mut lines: Vec<&str> = text.lines().collect();
    lines[99] = "1310,290836.136,1449571,,14x1522";
    std::fs::write(&adc, lines.join("\n") + "\n").expect("write");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(ds.path(), out.path())
        .expect_err("malformed line")
        .to_string();
    assert!(e.contains("day2_adc.csv:100: c3:"), "{e}");
    let left: Vec<_> = std::fs::read_dir(out.path().join("ingest"))
        .expect("dir")
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");

    let opts = Options {
        skip_bad_lines: true,
        progress: false,
    };
    let report = ingest::run_with(ds.path(), out.path(), &opts).expect("skipping bad lines");
    let f = report
        .files
        .iter()
        .find(|f| f.path == "raw/day2_adc.csv")
        .expect("file");
    assert_eq!(f.rejected.get(reason::MALFORMED), Some(&1));
    assert_eq!(f.rejections[0].at, "line 100");
    assert_eq!(f.read, f.accepted + 1);
}

/// A theodolite line that does not parse names the file, the line and the field; one dated
/// outside its session is counted and listed.
#[test]
fn theodolite_errors_and_dates() {
    let ds = copy_dataset("gon-gpst");
    let theo = ds.path().join("raw/s1_theodolite.txt");
    let text = std::fs::read_to_string(&theo).expect("log");
    // Line 4 is the first reading (three comment lines before it).
    let edit = |f: &dyn Fn(&str) -> String| -> String {
        let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
        lines[3] = f(&lines[3]);
        lines.join("\n") + "\n"
    };
    std::fs::write(&theo, edit(&|l| l.replacen(":", "h", 1))).expect("write");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(ds.path(), out.path())
        .expect_err("bad time")
        .to_string();
    assert!(e.contains("s1_theodolite.txt:4: time:"), "{e}");

    std::fs::write(&theo, edit(&|l| l.replacen("2021-06-10", "2021-07-10", 1))).expect("write");
    let report = ingest::run(ds.path(), out.path()).expect("runs");
    let f = report
        .files
        .iter()
        .find(|f| f.role == "theodolite")
        .expect("file");
    assert_eq!(f.rejected.get(reason::OUTSIDE_SESSION), Some(&1));
    assert_eq!(f.rejections[0].at, "line 4");
}

/// A triad model with two accelerometers declared is refused naming the model's key (its
/// third axis was fitted from the undeclared channel 3, a calibration apply then refused).
#[test]
fn a_triad_model_needs_three_accelerometers_declared() {
    let dst = tempfile::tempdir().expect("tempdir");
    fixtures::copy_dataset("triad-multipos", dst.path(), |m| {
        let third = m
            .rfind("[[instrument.accelerometer]]")
            .expect("three declared");
        let end = m[third..].find("\n\n").map_or(m.len(), |e| third + e + 2);
        format!("{}{}", &m[..third], &m[end..])
    })
    .expect("copy");
    let out = tempfile::tempdir().expect("tempdir");
    let e = ingest::run(dst.path(), out.path())
        .expect_err("two accelerometers")
        .to_string();
    assert!(
        e.contains("adjust.model[0].kind") && e.contains("declares 2"),
        "{e}"
    );
}

/// No output is written through a link (issue 50): links planted in OUT at every name ingest
/// writes, final and temporary, pointing outside, leave their targets untouched, and the
/// outputs are files of their own.
#[cfg(unix)]
#[test]
fn outputs_are_never_written_through_a_link() {
    let ds = fixtures::dataset_dir("gon-gpst");
    let first = tempfile::tempdir().expect("tempdir");
    ingest::run(&ds, first.path()).expect("ingest");
    let names: Vec<String> = std::fs::read_dir(first.path().join("ingest"))
        .expect("ingest/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert!(names.iter().any(|n| n.ends_with(".parquet")), "{names:?}");
    let out = tempfile::tempdir().expect("tempdir");
    let victims = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(out.path().join("ingest")).expect("ingest/");
    let mut planted = Vec::new();
    for (k, name) in names.iter().enumerate() {
        for link in [name.clone(), format!(".{name}.partial")] {
            let victim = victims.path().join(format!("victim-{k}-{}", link.len()));
            std::fs::write(&victim, "untouched").expect("victim");
            std::os::unix::fs::symlink(&victim, out.path().join("ingest").join(&link))
                .expect("link");
            planted.push(victim);
        }
    }
    ingest::run(&ds, out.path()).expect("ingest over the links");
    for v in &planted {
        assert_eq!(
            std::fs::read_to_string(v).expect("victim"),
            "untouched",
            "{}",
            v.display()
        );
    }
    for name in &names {
        let meta = std::fs::symlink_metadata(out.path().join("ingest").join(name)).expect("out");
        assert!(meta.file_type().is_file(), "{name} is still a link");
    }
}
