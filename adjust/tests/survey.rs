//! esgt-2005's calibration applied to the survey fixture (docs/formats.md 8.5): the accelerations
//! at the survey's still attitudes lie within their sigmas of the truth, the stretch whose
//! temperature is beyond the calibration's is flagged (and only it), the attitude beyond the
//! calibrated counts is flagged, the knock is null and flagged saturated, an accelerometer
//! the model cannot calibrate is null and says why, the bytes are the same twice, the checks
//! refuse a foreign instrument and an ambiguous model, and DuckDB reads the table to the
//! same per-minute means.

use adjust::survey::apply::select::Choice;
use adjust::survey::apply::stream::{Options, run};
use arrow_array::types::{Float64Type, Int64Type, UInt8Type};
use arrow_array::{Array, cast::AsArray};
use ingest::contract::apply_ledger::ApplyReport;
use ingest::contract::tables::{self, applied};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

mod common;

#[path = "../../align/tests/peers/mod.rs"]
mod peers;

/// esgt-2005 calibrated into a temporary OUT; returns it and calibration.json's path.
fn calibrate() -> (tempfile::TempDir, PathBuf) {
    let dataset = fixtures::dataset_dir("esgt-2005");
    let out = tempfile::tempdir().expect("tempdir");
    ingest::run(&dataset, out.path()).expect("ingest");
    align::run(&dataset, out.path()).expect("align");
    adjust::run(&dataset, out.path()).expect("adjust");
    let cal = out.path().join("adjust/calibration.json");
    (out, cal)
}

/// One accelerometer's columns of the applied table.
#[derive(Default)]
struct Columns {
    acceleration: Vec<Option<f64>>,
    sigma: Vec<Option<f64>>,
    temperature: Vec<Option<f64>>,
    flags: Vec<u8>,
}

/// The applied table: times, and per accelerometer id its columns.
fn read_applied(path: &Path) -> (Vec<i64>, BTreeMap<String, Columns>) {
    let f = std::fs::File::open(path).expect("open");
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .expect("parquet")
        .build()
        .expect("reader");
    let mut times = Vec::new();
    let mut cols: BTreeMap<String, Columns> = BTreeMap::new();
    for b in reader {
        let b = b.expect("batch");
        let t = b.column_by_name(tables::TIME_GPS_NS).expect("time");
        times.extend_from_slice(t.as_primitive::<Int64Type>().values());
        for id in ["acc1", "acc2", "acc3"] {
            let [a, s, tc, fl] = applied::columns(id);
            let c = cols.entry(id.to_owned()).or_default();
            let get = |name: &str| {
                let x = b.column_by_name(name).expect("column");
                let x = x.as_primitive::<Float64Type>();
                (0..x.len())
                    .map(|i| x.is_valid(i).then(|| x.value(i)))
                    .collect::<Vec<_>>()
            };
            c.acceleration.extend(get(&a));
            c.sigma.extend(get(&s));
            c.temperature.extend(get(&tc));
            let f = b.column_by_name(&fl).expect("flags");
            c.flags
                .extend_from_slice(f.as_primitive::<UInt8Type>().values());
        }
    }
    (times, cols)
}

fn apply(survey: &Path, out: &Path, cal: &Path, model: &str, session: Option<&str>) -> ApplyReport {
    run(
        survey,
        out,
        &Options {
            calibration: cal,
            choice: Choice {
                model: Some(model),
                session,
            },
        },
    )
    .expect("apply")
}

#[test]
fn the_survey_is_calibrated_within_its_sigmas_and_flagged_where_it_leaves_the_calibration() {
    let (_cal_out, cal) = calibrate();
    let survey = fixtures::dataset_dir("survey");
    let out = tempfile::tempdir().expect("tempdir");
    let report = apply(&survey, out.path(), &cal, "thermal", None);
    let table = out.path().join("apply").join(applied::FILE);
    let (times, cols) = read_applied(&table);
    assert_eq!(report.rows_written, times.len() as u64);
    assert_eq!(report.rows_read, report.rows_written);

    let truth = fixtures::read_truth(&survey).expect("truth");
    let scenario = fixtures::catalog::survey();
    let sim = fixtures::sim::SessionSim::plan(&scenario, &scenario.sessions[0]);
    let ranges: BTreeMap<&str, ([f64; 2], [f64; 2])> = report
        .accelerometers
        .iter()
        .filter_map(|a| Some((a.id.as_str(), (a.counts_range?, a.temperature_range_c?))))
        .collect();
    assert_eq!(ranges.len(), 2, "thermal calibrates acc1 and acc3");

    let calibration: ingest::contract::calibration::Calibration =
        ingest::read_json(&cal).expect("calibration.json");
    for id in ranges.keys() {
        let c = &cols[*id];
        let d = calibration_error_length(&calibration, &truth, id);
        let mut worst_z: f64 = 0.0;
        let acc = truth
            .accelerometer
            .iter()
            .find(|a| a.id == *id)
            .expect("accelerometer");
        for still in &truth.still {
            // The samples of the span, 2 s in from each end.
            let idx: Vec<usize> = (0..times.len())
                .filter(|&i| {
                    times[i] >= still.start_gps_ns + 2_000_000_000
                        && times[i] < still.end_gps_ns - 2_000_000_000
                })
                .filter(|&i| c.acceleration[i].is_some())
                .collect();
            assert!(
                idx.len() > 1000,
                "station {}: {} samples",
                still.station,
                idx.len()
            );
            let diffs: Vec<f64> = idx
                .iter()
                .map(|&i| {
                    let g = truth.gravity_mgal + sim.tide_mgal(times[i]);
                    c.acceleration[i].expect("value") - acc.sensed_mgal(g, still.dz_rad, 0.0)
                })
                .collect();
            let n = diffs.len() as f64;
            let mean = diffs.iter().sum::<f64>() / n;
            let var = diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / (n - 1.0);
            let sigma = idx.iter().map(|&i| c.sigma[i].expect("sigma")).sum::<f64>() / n;
            assert!(sigma > 0.0 && sigma < 3.0, "{id}: sigma {sigma} mGal");
            // Cauchy-Schwarz: the function's error J (p^ - p) is at most the Mahalanobis
            // length d of p^ - p times its sigma sqrt(J C J^T); the samples' own noise adds
            // a few standard errors of their mean.
            assert!(
                mean.abs() <= d * sigma + 4.0 * (var / n).sqrt() + 1e-6,
                "{id} station {}: error {mean} mGal, sigma {sigma}, d {d}",
                still.station
            );
            worst_z = worst_z.max(mean.abs() / sigma);
            // The attitude beyond the calibrated counts is flagged, the others are not.
            let flagged = idx
                .iter()
                .filter(|&&i| c.flags[i] & applied::COUNTS_OUT_OF_RANGE != 0)
                .count();
            let beyond = (still.dz_rad.to_degrees() - 150.0).abs() < 1.0;
            assert_eq!(
                flagged,
                if beyond { idx.len() } else { 0 },
                "{id} station {}: {flagged} of {} flagged counts out of range",
                still.station,
                idx.len()
            );
        }
        eprintln!(
            "{id}: largest |error| / sigma over the still attitudes {worst_z:.2}; the \
             calibration error's Mahalanobis length {d:.2}; the samples' noise adds up to 4 se"
        );
    }

    // Temperature: flagged exactly where the true temperature is beyond the calibration's
    // (away from the bounds by more than the sensor's noise), on a stretch of the survey.
    for (id, (_, [lo, hi])) in &ranges {
        let c = &cols[*id];
        let ch = usize::from(
            truth
                .accelerometer
                .iter()
                .find(|a| a.id == *id)
                .expect("acc")
                .channel,
        ) - 1;
        let (mut beyond, mut wrong) = (0usize, 0usize);
        for (i, &t) in times.iter().enumerate() {
            let true_t = sim.true_temperature_c(ch, t);
            // The range flags are for samples with a value.
            let near_bound = (true_t - lo).abs() < 0.01 || (true_t - hi).abs() < 0.01;
            if near_bound || c.flags[i] & applied::NO_VALUE != 0 {
                continue;
            }
            let out_of_range = true_t < *lo || true_t > *hi;
            beyond += usize::from(out_of_range);
            wrong +=
                usize::from(out_of_range != (c.flags[i] & applied::TEMPERATURE_OUT_OF_RANGE != 0));
        }
        let share = beyond as f64 / times.len() as f64;
        eprintln!(
            "{id}: {:.1} % of the survey beyond the calibrated temperatures",
            share * 100.0
        );
        assert!((0.1..0.9).contains(&share), "{id}: {share}");
        assert_eq!(
            wrong, 0,
            "{id}: samples flagged otherwise than their true temperature"
        );
    }

    // The knock: acc1 null and flagged saturated over exactly the truth's samples.
    let knock = &truth.session[0].saturation[0];
    let acc1 = &cols["acc1"];
    let saturated: Vec<usize> = (0..times.len())
        .filter(|&i| acc1.flags[i] & applied::SATURATED != 0)
        .collect();
    assert_eq!(saturated.len() as u64, knock.samples);
    assert!(saturated.iter().all(|&i| {
        acc1.acceleration[i].is_none()
            && times[i] >= knock.start_gps_ns
            && times[i] <= knock.end_gps_ns
    }));
    // acc2 has no thermal fit (disconnected on esgt-2005's second day): null, and why.
    let acc2 = &cols["acc2"];
    assert!(acc2.acceleration.iter().all(Option::is_none));
    assert!(acc2.flags.iter().all(|f| f & applied::NOT_CALIBRATED != 0));
    let why = report.accelerometers[1]
        .not_calibrated
        .as_deref()
        .expect("reason");
    assert!(why.contains("not estimable"), "{why}");
    // Never a zero for a missing value; a temperature wherever the log has one.
    assert!(
        cols.values()
            .all(|c| c.acceleration.iter().all(|a| *a != Some(0.0)))
    );
    assert!(
        cols.values()
            .all(|c| c.temperature.iter().all(Option::is_some))
    );

    // The same bytes twice.
    let first = std::fs::read(&table).expect("read");
    let again = apply(&survey, out.path(), &cal, "thermal", None);
    assert_eq!(std::fs::read(&table).expect("read"), first);
    assert_eq!(
        serde_json::to_string(&again).expect("json"),
        serde_json::to_string(&report).expect("json")
    );

    duckdb_agrees(&table, &times, &cols["acc1"]);
}

/// The Mahalanobis length of the thermal fit's error against the simulator's truth,
/// sqrt((p^ - p)^T C^-1 (p^ - p)) over b, k (at the fit's t_ref), b_t, k_t: what bounds
/// the function's error over its sigma anywhere. Its distribution over calibrations is
/// sqrt(chi2(4)) when C is honest, which `monte_carlo_default_is_honest_*` checks.
fn calibration_error_length(
    cal: &ingest::contract::calibration::Calibration,
    truth: &fixtures::write::Truth,
    id: &str,
) -> f64 {
    let r = cal
        .results
        .iter()
        .find(|r| r.model == "thermal" && r.accelerometer == id)
        .expect("thermal fit");
    let a = truth
        .accelerometer
        .iter()
        .find(|a| a.id == id)
        .expect("truth");
    let dt = r.t_ref_c.expect("t_ref") - truth.t_ref_c;
    let names = ["b", "k", "b_t", "k_t"];
    let truths = [
        a.b_mgal + a.b_t_mgal_per_c * dt,
        a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * dt,
        a.b_t_mgal_per_c,
        a.k_t_mgal_per_bit_per_c,
    ];
    let idx = names.map(|n| {
        r.parameters
            .iter()
            .position(|p| p.name == n)
            .expect("parameter")
    });
    let x: Vec<f64> = (0..4)
        .map(|j| r.parameters[idx[j]].value - truths[j])
        .collect();
    let c = |i: usize, j: usize| {
        r.parameters[idx[i]].sigma * r.parameters[idx[j]].sigma * r.correlation[idx[i]][idx[j]]
    };
    common::quadratic_form_of_inverse(&c, &x).sqrt()
}

/// DuckDB's mean acceleration per minute of acc1 equals ours.
fn duckdb_agrees(table: &Path, times: &[i64], acc1: &Columns) {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let [a, _, _, _] = applied::columns("acc1");
    let sql = format!(
        "SELECT time_gps_ns // 60000000000 AS minute, avg({a}) AS mean, count({a}) AS n \
         FROM read_parquet('{}') GROUP BY minute ORDER BY minute",
        table.display()
    );
    let script = format!("import duckdb, json\nprint(json.dumps(duckdb.sql({sql:?}).fetchall()))");
    let o = std::process::Command::new(&py)
        .args(["-c", &script])
        .output()
        .expect("python");
    assert!(
        o.status.success(),
        "duckdb: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let rows: Vec<(i64, Option<f64>, u64)> = serde_json::from_slice(&o.stdout).expect("json");
    let mut ours: BTreeMap<i64, (f64, u64)> = BTreeMap::new();
    for (t, v) in times.iter().zip(&acc1.acceleration) {
        let e = ours.entry(t.div_euclid(60_000_000_000)).or_default();
        if let Some(v) = v {
            e.0 += v;
            e.1 += 1;
        }
    }
    assert_eq!(rows.len(), ours.len());
    for (minute, mean, n) in rows {
        let (sum, count) = ours[&minute];
        assert_eq!(n, count, "minute {minute}");
        if let Some(mean) = mean {
            let want = sum / count as f64;
            assert!(
                (mean - want).abs() <= 1e-9 * want.abs(),
                "minute {minute}: {mean} vs {want}"
            );
        }
    }
    eprintln!("duckdb: {} minutes agree", ours.len());
}

#[test]
fn a_model_fitted_per_session_needs_its_session_and_warns_of_its_temperature() {
    let (_cal_out, cal) = calibrate();
    let survey = fixtures::dataset_dir("survey");
    let out = tempfile::tempdir().expect("tempdir");
    let err = run(
        &survey,
        out.path(),
        &Options {
            calibration: &cal,
            choice: Choice {
                model: Some("linear"),
                session: None,
            },
        },
    )
    .expect_err("a per-session model without --session");
    assert!(err.to_string().contains("--session"), "{err}");
    let err = run(
        &survey,
        out.path(),
        &Options {
            calibration: &cal,
            choice: Choice::default(),
        },
    )
    .expect_err("two models, none named");
    assert!(err.to_string().contains("--model"), "{err}");
    // Day 1's linear fit (24.8 degC) applied to the survey (29-32 degC): every sample of
    // every accelerometer is beyond its temperature.
    let report = apply(&survey, out.path(), &cal, "linear", Some("day1"));
    for a in &report.accelerometers {
        assert!(a.with_value > 0, "{}", a.id);
        assert_eq!(
            a.flagged.get("temperature_out_of_range"),
            Some(&a.with_value),
            "{}",
            a.id
        );
    }
}

#[test]
fn a_foreign_instrument_is_refused_by_name() {
    let (_cal_out, cal) = calibrate();
    let dir = tempfile::tempdir().expect("tempdir");
    let survey = dir.path().join("survey");
    fixtures::copy_dataset("survey", &survey, |m| {
        m.replace("QA3000-20 SN 2062", "QA3000-20 SN 9999")
    })
    .expect("copy");
    let err = run(
        &survey,
        &dir.path().join("out"),
        &Options {
            calibration: &cal,
            choice: Choice {
                model: Some("thermal"),
                session: None,
            },
        },
    )
    .expect_err("another acc3");
    let msg = err.to_string();
    assert!(
        msg.contains("acc3") && msg.contains("SN 9999") && msg.contains("SN 2062"),
        "{msg}"
    );
    assert!(
        !dir.path().join("out/apply").exists(),
        "checked before any work"
    );
}
