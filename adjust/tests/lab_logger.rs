//! The lab-logger fixture (a laboratory's own layouts, docs/formats.md 9) through the
//! pipeline: the tilt-table day (ISO UTC times, Unix-time temperatures, a hand-typed
//! theodolite log) calibrates within its sigmas of the truth, the multi-position session's
//! triad too, and the tilt-table day's linear model applied to the drive (a lab stream)
//! gives the true specific force at every still attitude within its sigma.

use arrow_array::types::{Float64Type, Int64Type};
use arrow_array::{Array, cast::AsArray};
use fixtures::lab::LabTruth;
use ingest::contract::tables::{self, applied};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;

fn truth() -> LabTruth {
    let path = fixtures::dataset_dir(fixtures::lab::LAB).join("truth.toml");
    toml::from_str(&std::fs::read_to_string(path).expect("truth.toml")).expect("parses")
}

#[test]
fn the_lab_logger_calibrates_and_applies_within_its_sigmas() {
    let dataset = fixtures::dataset_dir(fixtures::lab::LAB);
    let out = tempfile::tempdir().expect("tempdir");
    ingest::run(&dataset, out.path()).expect("ingest");
    align::run(&dataset, out.path()).expect("align");
    let cal = adjust::run(&dataset, out.path()).expect("adjust");
    let truth = truth();

    // The tilt-table day, per accelerometer: b and k at the day's mean temperature.
    let table = truth
        .calibration
        .session
        .iter()
        .find(|s| s.id == "table")
        .expect("table");
    for c in &table.calibration {
        let r = cal
            .results
            .iter()
            .find(|r| r.accelerometer == c.accelerometer && r.session == "table")
            .expect("a fit of the table day");
        for (name, t) in [("b", c.b_mgal), ("k", c.k_mgal_per_bit)] {
            let p = r.parameters.iter().find(|p| p.name == name).expect("param");
            let z = (p.value - t) / p.sigma;
            assert!(
                z.abs() < 4.0,
                "{} {name}: {} vs {t}, z {z:.2}",
                c.accelerometer,
                p.value
            );
        }
    }

    // The positions' triad.
    let triad = cal.triad.first().expect("a triad fit");
    for (p, t) in triad
        .parameters
        .iter()
        .zip(&truth.multi_position.parameters)
    {
        let z = (p.value - t) / p.sigma;
        assert!(
            z.abs() < 4.0,
            "triad {}: {} vs {t}, z {z:.2}",
            p.name,
            p.value
        );
    }

    // The day's linear model applied to the drive, a lab stream.
    let cal_path = out.path().join("adjust/calibration.json");
    let applied_out = tempfile::tempdir().expect("tempdir");
    adjust::survey::apply::stream::run(
        &dataset,
        applied_out.path(),
        &adjust::survey::apply::stream::Options {
            calibration: &cal_path,
            choice: adjust::survey::apply::select::Choice {
                model: Some("linear"),
                session: Some("table"),
            },
        },
    )
    .expect("apply");
    let f = std::fs::File::open(applied_out.path().join("apply").join(applied::FILE))
        .expect("applied table");
    let scenario = fixtures::catalog::lab_logger();
    let drive = fixtures::sim::SessionSim::plan(&scenario, &scenario.sessions[1]);
    let mut checked = 0;
    for acc in &truth.calibration.accelerometer {
        let [a_col, s_col, ..] = applied::columns(&acc.id);
        let (mut t, mut a, mut s) = (Vec::new(), Vec::new(), Vec::new());
        let reader = ParquetRecordBatchReaderBuilder::try_new(f.try_clone().expect("fd"))
            .expect("parquet")
            .build()
            .expect("reader");
        for b in reader {
            let b = b.expect("batch");
            let time = b.column_by_name(tables::TIME_GPS_NS).expect("time");
            let x = b.column_by_name(&a_col).expect("a");
            let x = x.as_primitive::<Float64Type>();
            let y = b.column_by_name(&s_col).expect("s");
            let y = y.as_primitive::<Float64Type>();
            for (i, &ti) in time.as_primitive::<Int64Type>().values().iter().enumerate() {
                if x.is_valid(i) {
                    t.push(ti);
                    a.push(x.value(i));
                    s.push(y.value(i));
                }
            }
        }
        let ch = usize::from(acc.channel) - 1;
        let mean_t = table
            .calibration
            .iter()
            .find(|c| c.accelerometer == acc.id)
            .expect("acc")
            .mean_temperature_c;
        for still in &truth.calibration.still {
            let idx: Vec<usize> = (0..t.len())
                .filter(|&i| {
                    t[i] >= still.start_gps_ns + 2_000_000_000
                        && t[i] < still.end_gps_ns - 2_000_000_000
                })
                .collect();
            assert!(
                idx.len() > 100,
                "station {}: {} samples",
                still.station,
                idx.len()
            );
            let n = idx.len() as f64;
            let mut err = Vec::new();
            for &i in &idx {
                let truth_a = acc.sensed_mgal(truth.calibration.gravity_mgal, still.dz_rad, 0.0);
                // The counts the instrument gave at its true temperature, read by the true
                // function at the table day's mean temperature: what a perfect linear
                // model of that day would say.
                let temp = drive.true_temperature_c(ch, t[i]);
                let dt = temp - truth.calibration.t_ref_c;
                let counts = (truth_a - acc.b_mgal - acc.b_t_mgal_per_c * dt)
                    / (acc.k_mgal_per_bit + acc.k_t_mgal_per_bit_per_c * dt);
                let ideal = acc.acceleration_mgal(counts, mean_t, truth.calibration.t_ref_c);
                err.push(a[i] - ideal);
            }
            let mean = err.iter().sum::<f64>() / n;
            let var = err.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0);
            let sigma = idx.iter().map(|&i| s[i]).sum::<f64>() / n;
            let bound = 4.0 * (sigma * sigma + var / n).sqrt();
            assert!(
                mean.abs() < bound,
                "{} station {}: error {mean:.3} mGal, sigma {sigma:.3}, bound {bound:.3}",
                acc.id,
                still.station
            );
            checked += 1;
        }
    }
    assert!(
        checked >= 30,
        "{checked} (accelerometer, attitude) pairs checked"
    );
}
