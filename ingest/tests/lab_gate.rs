//! The time gate holds for lab streams and their temperature logs as for the binary log
//! (`frames_never_panic.rs`): one line with any time, inserted anywhere into a valid file,
//! costs at most one line (itself, or the line it displaces when it lands where it cannot
//! be told from the next sample), and the ledger adds up. Before the gate, a line stamped
//! 400 s ahead made the next 12 499 lines go `time_backwards`.

use ingest::contract::ingest_ledger::FileLedger;
use proptest::prelude::*;
use std::fmt::Write as _;

const STREAM_LINES: usize = 400;
const LOG_LINES: usize = 120;

fn manifest() -> &'static str {
    r#"name = "lab-gate"
[site]
g_abs_mgal = 980855.8
[instrument]
sample_rate_hz = 31.25
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
temperature_csv = "raw/temp.txt"
start = "2023-01-05T09:00:00"
"#
}

/// The stream's lines (`t,x,y,z` at 31.25 Hz) and the log's (`t,T1,T2,T3` every second).
fn files() -> (Vec<String>, Vec<String>) {
    let stream = (0..STREAM_LINES)
        .map(|i| {
            format!(
                "{:.3},{},{},{}",
                i as f64 * 0.032,
                1000 + i,
                -2000,
                4_100_000
            )
        })
        .collect();
    let log = (0..LOG_LINES)
        .map(|i| {
            let c = 24.0 + 0.01 * i as f64;
            format!("{i}.000,{c:.3},{:.3},{:.3}", c + 0.5, c + 1.0)
        })
        .collect();
    (stream, log)
}

/// Ingests the two files; returns the stream's and the log's ledgers.
fn ingest(stream: &[String], log: &[String]) -> (FileLedger, FileLedger) {
    let dir = tempfile::tempdir().expect("tempdir");
    let raw = dir.path().join("raw");
    std::fs::create_dir_all(&raw).expect("raw");
    let mut text = String::from("t,x,y,z\n");
    for l in stream {
        writeln!(text, "{l}").expect("write");
    }
    std::fs::write(raw.join("acc.txt"), text).expect("write");
    let mut text = String::from("t,T1,T2,T3\n");
    for l in log {
        writeln!(text, "{l}").expect("write");
    }
    std::fs::write(raw.join("temp.txt"), text).expect("write");
    std::fs::write(dir.path().join("dataset.toml"), manifest()).expect("manifest");
    let r = ingest::run(dir.path(), &dir.path().join("out")).expect("ingest");
    let find = |role: &str| {
        r.files
            .iter()
            .find(|f| f.role == role)
            .expect("ledger")
            .clone()
    };
    (find("adc_csv"), find("temperature_csv"))
}

fn check(f: &FileLedger, originals: usize) -> Result<(), TestCaseError> {
    prop_assert_eq!(f.read, f.accepted + f.rejected_total(), "{:?}", f);
    prop_assert_eq!(f.read, originals as u64 + 1);
    prop_assert!(f.rejected_total() <= 1, "{:?}", f.rejections);
    Ok(())
}

#[test]
fn intact_files_are_read_whole() {
    let (stream, log) = files();
    let (s, t) = ingest(&stream, &log);
    assert_eq!(s.accepted, STREAM_LINES as u64);
    assert_eq!(t.accepted, LOG_LINES as u64);
    assert_eq!(s.rejected_total() + t.rejected_total(), 0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// One line with any time of the session's day (a few milliseconds to hours away from
    /// its neighbours), inserted anywhere into the stream or the log.
    #[test]
    fn one_out_of_place_line_costs_at_most_one(
        at in any::<usize>(),
        ms in -32_400_000i64..54_000_000,
        in_log in any::<bool>(),
    ) {
        let (mut stream, mut log) = files();
        let stray = format!("{}.{:03},7,7,7", ms.div_euclid(1000), ms.rem_euclid(1000));
        let (s, t) = if in_log {
            log.insert(at % (LOG_LINES + 1), stray);
            let (s, t) = ingest(&stream, &log);
            check(&t, LOG_LINES)?;
            (s, t)
        } else {
            stream.insert(at % (STREAM_LINES + 1), stray);
            let (s, t) = ingest(&stream, &log);
            check(&s, STREAM_LINES)?;
            (s, t)
        };
        // The other file is untouched.
        if in_log {
            prop_assert_eq!(s.accepted, STREAM_LINES as u64);
        } else {
            prop_assert_eq!(t.accepted, LOG_LINES as u64);
        }
    }
}
