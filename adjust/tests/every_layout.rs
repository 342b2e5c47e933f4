//! Every session kind from every acquisition layout (docs/formats.md 9.2): a tilt-table
//! session logged as a lab stream calibrates to the numbers the same samples give in counts;
//! a survey logged as a lab stream is applied by an axis model to the accelerations the same
//! samples give in counts; a counts log with a reading unit other than counts is refused.

use adjust::survey::apply::select::Choice;
use adjust::survey::apply::stream::{Options, run};
use arrow_array::types::Float64Type;
use arrow_array::{Array, cast::AsArray};
use ingest::contract::calibration::Calibration;
use ingest::contract::tables::applied;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::path::{Path, PathBuf};

/// GPS time 1980-01-06 in Unix seconds, and GPS - UTC in February 2005 (13 s).
const GPS_EPOCH_UNIX_S: i64 = 315_964_800;
const LEAP_2005_S: i64 = 13;

/// `gps_week,tow_s,a,b,c` lines rewritten as a lab stream `unix_s,a,b,c` (times to the
/// millisecond, as written), comments and the header kept as comments.
fn to_lab_stream(csv: &str) -> String {
    let mut out = String::from("# the same samples, written as a lab logger would\n");
    for line in csv.lines() {
        let f: Vec<&str> = line.split(',').collect();
        let (Ok(week), Some((s, ms))) = (
            f[0].parse::<i64>(),
            f.get(1).and_then(|t| t.split_once('.')),
        ) else {
            out.push_str(&format!("# {line}\n"));
            continue;
        };
        let tow_ms: i64 = s.parse::<i64>().expect("tow") * 1000 + ms.parse::<i64>().expect("ms");
        let unix_ms = (GPS_EPOCH_UNIX_S + week * 604_800 - LEAP_2005_S) * 1000 + tow_ms;
        out.push_str(&format!(
            "{}.{:03},{}\n",
            unix_ms / 1000,
            unix_ms % 1000,
            f[2..].join(",")
        ));
    }
    out
}

/// A copy of esgt-2005-csv whose session `day1` is logged as a lab stream (and, with
/// `survey`, both sessions are surveys without theodolite logs).
fn esgt_csv(lab_day1: bool, survey: bool) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("esgt");
    fixtures::copy_dataset("esgt-2005-csv", &ds, |m| {
        let mut m = m;
        if lab_day1 {
            m = m.replace(
                "adc_csv = \"raw/day1_adc.csv\"\ntemperature_csv = \"raw/day1_temp.csv\"",
                "adc_csv = \"raw/day1_lab.txt\"\ntemperature_csv = \"raw/day1_lab_temp.txt\"\n\
                 adc_format = \"seconds\"\ntime_unit = \"unix_s\"",
            );
            assert!(
                m.contains("day1_lab.txt"),
                "the manifest's day1 was rewritten"
            );
        }
        if survey {
            m = m
                .lines()
                .filter(|l| !l.starts_with("theodolite"))
                .collect::<Vec<_>>()
                .join("\n")
                .replace("[[session]]", "[[session]]\nkind = \"survey\"");
        }
        m
    })
    .expect("copy");
    for (from, to) in [
        ("day1_adc.csv", "day1_lab.txt"),
        ("day1_temp.csv", "day1_lab_temp.txt"),
    ] {
        let text = std::fs::read_to_string(ds.join("raw").join(from)).expect("read");
        std::fs::write(ds.join("raw").join(to), to_lab_stream(&text)).expect("write");
    }
    (dir, ds)
}

fn calibrate(ds: &Path, out: &Path) -> Calibration {
    ingest::run(ds, out).expect("ingest");
    align::run(ds, out).expect("align");
    adjust::run(ds, out).expect("adjust")
}

#[test]
fn a_tilt_table_session_logged_as_a_lab_stream_calibrates_as_in_counts() {
    let (_a, counts) = esgt_csv(false, false);
    let (_b, lab) = esgt_csv(true, false);
    let (oa, ob) = (
        tempfile::tempdir().expect("t"),
        tempfile::tempdir().expect("t"),
    );
    let x = calibrate(&counts, oa.path());
    let y = calibrate(&lab, ob.path());
    let day1 = |c: &Calibration| {
        c.results
            .iter()
            .filter(|r| r.session == "day1")
            .cloned()
            .collect::<Vec<_>>()
    };
    let (x1, y1) = (day1(&x), day1(&y));
    assert!(!x1.is_empty(), "counts give day1 fits");
    assert_eq!(x1.len(), y1.len(), "the same fits from the lab stream");
    for (p, q) in x1.iter().zip(&y1) {
        assert_eq!((&p.accelerometer, &p.model), (&q.accelerometer, &q.model));
        assert_eq!(
            p.n_observations, q.n_observations,
            "{} {}",
            p.model, p.accelerometer
        );
        for (a, b) in p.parameters.iter().zip(&q.parameters) {
            let tol = 1e-9 * a.value.abs().max(a.sigma);
            assert!(
                (a.value - b.value).abs() <= tol && (a.sigma - b.sigma).abs() <= 1e-9 * a.sigma,
                "{} {} {}: counts {} ± {}, lab stream {} ± {}",
                p.model,
                p.accelerometer,
                a.name,
                a.value,
                a.sigma,
                b.value,
                b.sigma
            );
        }
    }
    assert_eq!(y.reading_unit, "count");
}

/// Every accelerometer's applied acceleration, in table order.
fn accelerations(out: &Path) -> Vec<Vec<Option<f64>>> {
    let f = std::fs::File::open(out.join("apply").join(applied::FILE)).expect("open");
    let mut cols = vec![Vec::new(); 3];
    for b in ParquetRecordBatchReaderBuilder::try_new(f)
        .expect("parquet")
        .build()
        .expect("reader")
    {
        let b = b.expect("batch");
        for (i, id) in ["acc1", "acc2", "acc3"].iter().enumerate() {
            let [a, ..] = applied::columns(id);
            let x = b.column_by_name(&a).expect("column");
            let x = x.as_primitive::<Float64Type>();
            cols[i].extend((0..x.len()).map(|r| x.is_valid(r).then(|| x.value(r))));
        }
    }
    cols
}

#[test]
fn a_survey_logged_as_a_lab_stream_is_applied_by_an_axis_model() {
    let (_c, calibration) = esgt_csv(false, false);
    let oc = tempfile::tempdir().expect("t");
    calibrate(&calibration, oc.path());
    let cal = oc.path().join("adjust/calibration.json");
    let apply = |ds: &Path, out: &Path| {
        run(
            ds,
            out,
            &Options {
                calibration: &cal,
                choice: Choice {
                    model: Some("linear"),
                    session: Some("day1"),
                },
            },
        )
        .expect("apply")
    };
    let (_a, counts) = esgt_csv(false, true);
    let (_b, lab) = esgt_csv(true, true);
    let (oa, ob) = (
        tempfile::tempdir().expect("t"),
        tempfile::tempdir().expect("t"),
    );
    let ra = apply(&counts, oa.path());
    let rb = apply(&lab, ob.path());
    assert_eq!(ra.rows_written, rb.rows_written);
    assert!(ra.rows_written > 100_000, "{} rows", ra.rows_written);
    // The counts table comes first (day2), then the lab table (day1): compare as sets of
    // rows by session, here simply sorted.
    let (mut x, mut y) = (accelerations(oa.path()), accelerations(ob.path()));
    let mut with_value = 0;
    for (cx, cy) in x.iter_mut().zip(y.iter_mut()) {
        let key = |v: &Option<f64>| v.map_or(f64::NEG_INFINITY, |a| a);
        cx.sort_by(|a, b| key(a).total_cmp(&key(b)));
        cy.sort_by(|a, b| key(a).total_cmp(&key(b)));
        assert_eq!(
            cx, cy,
            "the same accelerations from counts and from the lab stream"
        );
        with_value += cx.iter().flatten().count();
    }
    assert!(with_value > 100_000, "{with_value} samples with a value");
}

#[test]
fn a_counts_log_with_another_reading_unit_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("esgt");
    fixtures::copy_dataset("esgt-2005-csv", &ds, |m| {
        m.replace(
            "full_scale_g = 2.0",
            "full_scale_g = 2.0\nreading_unit = \"V\"",
        )
    })
    .expect("copy");
    let e = match ingest::contract::manifest::Dataset::load(&ds) {
        Ok(_) => panic!("counts read as volts: refused"),
        Err(e) => e.to_string(),
    };
    assert!(
        e.contains("session[0].adc_format") && e.contains("day1") && e.contains("reading_unit"),
        "{e}"
    );
}

/// A reading unit the scale factors do not fit is named (issue 49): esgt-2005-csv's two
/// days written as lab streams in m/s^2 (each count through one affine map, as a logger
/// converting with a nominal scale would), declared "m/s^2", calibrate with no word on the
/// unit; declared "mGal", every fit's warnings say k is 1e5 times too large and that the
/// readings look like m/s^2, naming the key.
#[test]
fn a_reading_unit_the_scale_factors_do_not_fit_is_named() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("esgt");
    let declare = |unit: &str| {
        let text =
            std::fs::read_to_string(fixtures::dataset_dir("esgt-2005-csv").join("dataset.toml"))
                .expect("manifest");
        let mut m = text.replace(
            "full_scale_g = 2.0",
            &format!("full_scale_g = 2.0\nreading_unit = \"{unit}\""),
        );
        for day in ["day1", "day2"] {
            m = m.replace(
                &format!("adc_csv = \"raw/{day}_adc.csv\"\ntemperature_csv = \"raw/{day}_temp.csv\""),
                &format!(
                    "adc_csv = \"raw/{day}_lab.txt\"\ntemperature_csv = \"raw/{day}_lab_temp.txt\"\n\
                     adc_format = \"seconds\"\ntime_unit = \"unix_s\""
                ),
            );
        }
        assert_eq!(
            m.matches("adc_format = \"seconds\"").count(),
            2,
            "both days rewritten"
        );
        m
    };
    fixtures::copy_dataset("esgt-2005-csv", &ds, |_| declare("m/s^2")).expect("copy");
    // A lab stream's values through `f`, an empty field (not connected) as nan.
    let mapped = |text: &str, f: &dyn Fn(f64) -> String| -> String {
        to_lab_stream(text)
            .lines()
            .map(|l| match l.split_once(',') {
                Some((t, v)) if !l.starts_with('#') => {
                    let values: Vec<String> = v
                        .split(',')
                        .map(|c| c.parse::<f64>().map_or("nan".to_owned(), f))
                        .collect();
                    format!("{t},{}\n", values.join(","))
                }
                _ => format!("{l}\n"),
            })
            .collect()
    };
    for day in ["day1", "day2"] {
        let raw = ds.join("raw");
        let read = |name: String| std::fs::read_to_string(raw.join(name)).expect("read");
        let in_si = mapped(&read(format!("{day}_adc.csv")), &|c| {
            format!("{:.7}", (0.243 * c - 29_500.0) * 1e-5)
        });
        std::fs::write(raw.join(format!("{day}_lab.txt")), in_si).expect("write");
        let temps = mapped(&read(format!("{day}_temp.csv")), &|t| t.to_string());
        std::fs::write(raw.join(format!("{day}_lab_temp.txt")), temps).expect("write");
    }
    let warned = |c: &Calibration| {
        c.results
            .iter()
            .filter(|r| {
                r.warnings
                    .iter()
                    .any(|w| w.contains("instrument.reading_unit"))
            })
            .count()
    };
    let out = tempfile::tempdir().expect("t");
    let right = calibrate(&ds, out.path());
    assert!(!right.results.is_empty());
    assert_eq!(warned(&right), 0, "m/s^2 declared m/s^2");
    std::fs::write(ds.join("dataset.toml"), declare("mGal")).expect("write");
    let out = tempfile::tempdir().expect("t");
    let wrong = calibrate(&ds, out.path());
    assert_eq!(warned(&wrong), wrong.results.len(), "m/s^2 declared mGal");
    let note = wrong.results[0]
        .warnings
        .iter()
        .find(|w| w.contains("reading_unit"))
        .expect("note");
    assert!(note.contains("look like \"m/s^2\""), "{note}");
}

/// A lab stream of fewer channels and one thermometer (docs/formats.md 9.4): day 1 written
/// with channels 1 and 2 only and its temperature log with one column (channel 1's),
/// declared `adc_columns = [1, 2]` and `thermometers = "one"`, gives acc1's and acc2's
/// linear fits of the full stream to the last digit, and acc3 named as not connected.
#[test]
fn a_lab_stream_of_two_channels_and_one_thermometer_calibrates_them() {
    let (_a, full) = esgt_csv(true, false);
    let (_b, two) = esgt_csv(true, false);
    let keep = |text: &str, n: usize| -> String {
        text.lines()
            .map(|l| {
                if l.starts_with('#') {
                    format!("{l}\n")
                } else {
                    let f: Vec<&str> = l.split(',').collect();
                    format!("{}\n", f[..=n].join(","))
                }
            })
            .collect()
    };
    for (file, n) in [("day1_lab.txt", 2), ("day1_lab_temp.txt", 1)] {
        let path = two.join("raw").join(file);
        let text = std::fs::read_to_string(&path).expect("read");
        std::fs::write(&path, keep(&text, n)).expect("write");
    }
    let manifest = two.join("dataset.toml");
    let m = std::fs::read_to_string(&manifest).expect("manifest");
    let declared = m.replacen(
        "adc_format = \"seconds\"",
        "adc_format = \"seconds\"\nadc_columns = [1, 2]\nthermometers = \"one\"",
        1,
    );
    assert_ne!(declared, m);
    std::fs::write(&manifest, declared).expect("write");
    let (oa, ob) = (
        tempfile::tempdir().expect("t"),
        tempfile::tempdir().expect("t"),
    );
    let x = calibrate(&full, oa.path());
    let y = calibrate(&two, ob.path());
    let linear = |c: &Calibration, acc: &str| {
        c.results
            .iter()
            .find(|r| r.session == "day1" && r.model == "linear" && r.accelerometer == acc)
            .cloned()
    };
    for acc in ["acc1", "acc2"] {
        let (p, q) = (
            linear(&x, acc).expect("full"),
            linear(&y, acc).expect("two"),
        );
        for (a, b) in p.parameters.iter().zip(&q.parameters) {
            assert!(
                (a.value - b.value).abs() <= 1e-9 * a.value.abs(),
                "{acc} {}",
                a.name
            );
        }
    }
    assert!(linear(&y, "acc3").is_none());
    assert!(
        y.skipped.iter().any(|s| s.accelerometer == "acc3"
            && s.session == "day1"
            && s.reason.contains("not connected")),
        "{:?}",
        y.skipped
    );
}
