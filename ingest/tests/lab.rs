//! Lab loggers' "seconds" streams (docs/formats.md 8.3) through ingest: imu_tk's ASCII layout
//! with the quirks of real lab files (10 ms stamps at 200 Hz, scientific notation, no
//! header), and a comma-separated file with a header and Unix times; every sample kept and
//! what was found reported; a line going back in time rejected alone; manifest errors
//! naming the key; a temperature log in the same layout.

use arrow_array::types::{Float64Type, Int64Type};
use arrow_array::{Array, cast::AsArray};
use ingest::contract::ingest_ledger::{IngestReport, reason};
use ingest::contract::tables;
use std::fmt::Write as _;
use std::path::Path;

mod common;
use common::read_table;

fn manifest(session: &str) -> String {
    format!(
        r#"name = "lab"
[site]
g_abs_mgal = 980855.8
[instrument]
sample_rate_hz = 200.0
reading_unit = "m/s^2"
[[instrument.accelerometer]]
id = "x"
channel = 1
[[instrument.accelerometer]]
id = "y"
channel = 2
[[instrument.accelerometer]]
id = "z"
channel = 3
[[session]]
id = "lab1"
date = "2023-01-05"
kind = "multi-position"
adc_format = "seconds"
adc_csv = "raw/acc.txt"
{session}
"#
    )
}

fn table(out: &Path) -> (Vec<i64>, Vec<Option<f64>>) {
    let mut times = Vec::new();
    for b in read_table(out, tables::lab::FILE) {
        times.extend_from_slice(
            b.column_by_name(tables::TIME_GPS_NS)
                .expect("time")
                .as_primitive::<Int64Type>()
                .values(),
        );
    }
    (times, readings(out, 0))
}

/// Channel `k + 1`'s readings in the lab table, None where null.
fn readings(out: &Path, k: usize) -> Vec<Option<f64>> {
    let mut values = Vec::new();
    for b in read_table(out, tables::lab::FILE) {
        let v = b
            .column_by_name(tables::lab::VALUES[k])
            .expect("readings")
            .as_primitive::<Float64Type>();
        values.extend((0..v.len()).map(|i| v.is_valid(i).then(|| v.value(i))));
    }
    values
}

/// imu_tk's layout: `t x y z`, white space, no header, m/s^2 in scientific notation, times
/// printed to 10 ms at 200 Hz (pairs share a stamp), one line going back in time.
#[test]
fn imu_tk_ascii_with_coarse_stamps_keeps_every_sample() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(dir.path().join("raw")).expect("raw");
    let mut text = String::new();
    let n = 2000;
    for i in 0..n {
        let t = (i / 2) as f64 * 0.01;
        writeln!(
            text,
            "{t:.2}   {:.6e} {:.6e} {:.6e}",
            9.80665 + 1e-4 * i as f64,
            0.01,
            -0.02
        )
        .expect("write");
        if i == 1000 {
            // A stale line, 3 s back.
            writeln!(text, "2.00 1.0 1.0 1.0").expect("write");
        }
    }
    std::fs::write(dir.path().join("raw/acc.txt"), text).expect("write");
    std::fs::write(
        dir.path().join("dataset.toml"),
        manifest("start = \"2023-01-05T02:52:39\""),
    )
    .expect("manifest");
    let out = dir.path().join("out");
    let report = ingest::run(dir.path(), &out).expect("ingest");
    let f = &report.files[0];
    assert_eq!(f.accepted, n as u64);
    assert_eq!(f.rejected.get(reason::TIME_BACKWARDS), Some(&1));
    let lab = f.lab_stream.as_ref().expect("lab report");
    assert!(!lab.header && !lab.comma_separated);
    assert_eq!(lab.samples_sharing_a_stamp, (n / 2) as u64);
    assert_eq!(lab.stamp_step_ns, Some(10_000_000));
    assert_eq!(lab.median_interval_ns, Some(5_000_000));
    assert_eq!(lab.scientific_notation_values, 3 * n as u64);
    let rate = report.sessions[0].measured_sample_rate_hz.expect("rate");
    assert!((rate - 200.0).abs() < 1e-9, "{rate}");
    assert_eq!(report.sessions[0].acceleration_samples, n as u64);
    let (times, x) = table(&out);
    assert_eq!(times.len(), n);
    assert!(
        times.windows(2).all(|w| w[1] - w[0] == 5_000_000),
        "spread at 5 ms"
    );
    assert!((x[1999].expect("x") - (9.80665 + 0.1999)).abs() < 1e-12);
    // The start 2023-01-05T02:52:39 UTC is 18 leap seconds behind GPS time.
    let start = ingest::base::time::gps_ns(
        ingest::base::time::parse_calendar("2023-01-05T02:52:57").expect("calendar"),
        ingest::contract::manifest::TimeScale::Gpst,
    )
    .expect("gps");
    assert_eq!(times[0], start);
    let reloaded = IngestReport::load(&out.join("ingest")).expect("ledger");
    assert_eq!(reloaded.files[0].lab_stream, f.lab_stream);
}

/// Commas, a header line, Unix times with microseconds, `nan` for a missing reading.
#[test]
fn comma_separated_unix_times_with_a_header() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(dir.path().join("raw")).expect("raw");
    let mut text = String::from("# lab logger\ntime,ax,ay,az\n");
    for i in 0..400 {
        let t = 1_672_887_159.0 + f64::from(i) * 0.005;
        let z = if i == 7 {
            "nan".to_owned()
        } else {
            "-9.8".to_owned()
        };
        writeln!(text, "{t:.6},0.1,0.2,{z}").expect("write");
    }
    std::fs::write(dir.path().join("raw/acc.txt"), text).expect("write");
    std::fs::write(
        dir.path().join("dataset.toml"),
        manifest("time_unit = \"unix_s\""),
    )
    .expect("manifest");
    let out = dir.path().join("out");
    let report = ingest::run(dir.path(), &out).expect("ingest");
    let f = &report.files[0];
    let lab = f.lab_stream.as_ref().expect("lab report");
    assert!(lab.header && lab.comma_separated);
    assert_eq!(lab.samples_sharing_a_stamp, 0);
    assert_eq!(f.accepted, 400);
    assert_eq!(f.null_values.get("ch3 nan"), Some(&1));
    // Stored as null in its row, and only there.
    let z = readings(&out, 2);
    assert_eq!(z.len(), 400);
    assert!(z.iter().enumerate().all(|(i, v)| (i == 7) == v.is_none()));
    assert!(readings(&out, 1).iter().all(|v| *v == Some(0.2)));
    // 1672887159 s Unix is 2023-01-05T02:52:39 UTC.
    let (times, _) = table(&out);
    let want = ingest::base::time::gps_ns(
        ingest::base::time::parse_calendar("2023-01-05T02:52:39").expect("calendar"),
        ingest::contract::manifest::TimeScale::Utc,
    )
    .expect("gps");
    assert_eq!(times[0], want);
}

/// A "seconds" session's temperature log, in the same layout as its stream: read into the
/// temperature table at the stream's times; a `nan` stored as null and counted, a line not
/// written twice rejected alone (a duplicate), a malformed one named by file, line and field.
#[test]
fn a_lab_temperature_log_in_the_seconds_layout() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::create_dir_all(dir.path().join("raw")).expect("raw");
    let mut acc = String::new();
    for i in 0..2000 {
        writeln!(acc, "{:.3} 0.1 0.2 -9.8", f64::from(i) * 0.005).expect("write");
    }
    std::fs::write(dir.path().join("raw/acc.txt"), acc).expect("write");
    let mut temp = String::from("t,T1,T2,T3\n");
    for i in 0..10 {
        let t1 = if i == 4 {
            "nan".to_owned()
        } else {
            format!("{:.2}", 25.0 + 0.1 * f64::from(i))
        };
        writeln!(temp, "{},{t1},26.5,27.5", f64::from(i)).expect("write");
        if i == 6 {
            // Written twice by the logger: the repeat is rejected.
            writeln!(temp, "{},{t1},26.5,27.5", f64::from(i)).expect("write");
        }
    }
    std::fs::write(dir.path().join("raw/temp.txt"), &temp).expect("write");
    let session = "start = \"2023-01-05T02:52:39\"\ntemperature_csv = \"raw/temp.txt\"";
    std::fs::write(dir.path().join("dataset.toml"), manifest(session)).expect("manifest");
    let out = dir.path().join("out");
    let report = ingest::run(dir.path(), &out).expect("ingest");
    let f = report
        .files
        .iter()
        .find(|f| f.role == "temperature_csv")
        .expect("temperature ledger");
    assert_eq!(f.accepted, 10, "{f:?}");
    assert_eq!(f.rejected.get(reason::DUPLICATE), Some(&1), "{f:?}");
    assert_eq!(
        f.null_values.get("ch1 temperature not connected"),
        Some(&1),
        "{f:?}"
    );
    assert_eq!(report.sessions[0].temperature_samples, 10);
    assert_eq!(report.tables.get(tables::temperature::FILE), Some(&10));
    // The same times as the stream's: its second 3 is the stream's sample 600.
    let (acc_times, _) = table(&out);
    let batches = read_table(&out, tables::temperature::FILE);
    let b = batches.first().expect("a batch");
    let times = b
        .column_by_name(tables::TIME_GPS_NS)
        .expect("time")
        .as_primitive::<Int64Type>();
    assert_eq!(times.value(3), acc_times[600]);
    let t1 = b
        .column_by_name(tables::temperature::TEMPERATURE_C[0])
        .expect("T1")
        .as_primitive::<Float64Type>();
    assert!(t1.is_null(4) && (t1.value(3) - 25.3).abs() < 1e-12);

    // A malformed line names the file, the line and the field.
    std::fs::write(
        dir.path().join("raw/temp.txt"),
        temp.replace("26.5,27.5\n3,", "26.5,27.5\n3x,"),
    )
    .expect("write");
    let e = ingest::run(dir.path(), &out)
        .expect_err("malformed")
        .to_string();
    assert!(e.contains("temp.txt:5: t:"), "{e}");
}

#[test]
fn lab_manifest_errors_name_the_key() {
    let cases = [
        ("", "session[0].start"),
        (
            "start = \"2023-01-05T02:52:39\"\ntime_unit = \"unix_s\"",
            "session[0].start",
        ),
        (
            "start = \"2023-01-05T02:52:39\"\ntemperature_csv = \"raw/missing.txt\"",
            "session[0].temperature_csv",
        ),
        (
            "start = \"2023-01-05T02:52:39\"\nstatic_s = [[10.0, 5.0]]",
            "session[0].static_s[0]",
        ),
    ];
    for (session, key) in cases {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::create_dir_all(dir.path().join("raw")).expect("raw");
        std::fs::write(dir.path().join("raw/acc.txt"), "0 1 2 3\n").expect("write");
        std::fs::write(dir.path().join("dataset.toml"), manifest(session)).expect("manifest");
        let e = ingest::run(dir.path(), &dir.path().join("out")).expect_err(key);
        assert!(e.to_string().contains(key), "{key}: {e}");
    }
}

#[path = "../../align/tests/peers/mod.rs"]
mod peers;

/// DuckDB (an independent Parquet reader) reads the lab table of the lab-logger fixture
/// (two lab streams, decimals in m/s^2) as parquet-rs does, bit for bit, from readings
/// compressed with LZ4_RAW.
#[test]
fn duckdb_reads_the_lab_table_as_written() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let out = tempfile::tempdir().expect("tempdir");
    ingest::run(&fixtures::dataset_dir("lab-logger"), out.path()).expect("ingest");
    let mut ours = Vec::new();
    for b in read_table(out.path(), tables::lab::FILE) {
        let column = |name: &str| b.column_by_name(name).expect("column").clone();
        let session = column(tables::SESSION_INDEX);
        let session = session.as_primitive::<arrow_array::types::UInt16Type>();
        let time = column(tables::TIME_GPS_NS);
        let time = time.as_primitive::<Int64Type>();
        let line = column(tables::lab::LINE);
        let line = line.as_primitive::<arrow_array::types::UInt64Type>();
        let values: Vec<_> = tables::lab::VALUES.iter().map(|v| column(v)).collect();
        for i in 0..b.num_rows() {
            let mut row = format!("{} {} {}", session.value(i), time.value(i), line.value(i));
            for v in &values {
                let v = v.as_primitive::<Float64Type>();
                match v.is_valid(i) {
                    true => write!(row, " {}", v.value(i).to_bits() as i64).expect("write"),
                    false => row.push_str(" null"),
                }
            }
            ours.push(row);
        }
    }
    ours.sort();
    let script = r#"
import duckdb, struct, sys
t = sys.argv[1]
codecs = {c for (c,) in duckdb.sql(
    f"select distinct compression from parquet_metadata('{t}') where path_in_schema like 'value_ch%'"
).fetchall()}
print("codecs", " ".join(sorted(codecs)))
bits = lambda v: "null" if v is None else str(struct.unpack("<q", struct.pack("<d", v))[0])
for s, tm, ln, *vs in duckdb.sql(
    f"select session_index, time_gps_ns, line, value_ch1, value_ch2, value_ch3 from read_parquet('{t}')"
).fetchall():
    print(s, tm, ln, *map(bits, vs))
"#;
    let table = out.path().join("ingest").join(tables::lab::FILE);
    let o = std::process::Command::new(&py)
        .arg("-c")
        .arg(script)
        .arg(&table)
        .output()
        .expect("python");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8(o.stdout).expect("utf-8");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("codecs LZ4_RAW"));
    let mut theirs: Vec<String> = lines.map(str::to_owned).collect();
    theirs.sort();
    assert!(ours.len() > 10_000, "{} rows", ours.len());
    assert_eq!(ours.len(), theirs.len());
    for (a, b) in ours.iter().zip(&theirs) {
        assert_eq!(a, b);
    }
}
