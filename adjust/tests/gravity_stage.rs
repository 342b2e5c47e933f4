//! The gravity stage end to end (docs/formats.md 10, docs/model.md 7): triad-multipos
//! calibrates the triad, survey-lines is reduced with that calibration, and the filtered
//! disturbance down is compared with the simulator's truth through the same filter. Each
//! convention FORMATS.md 10 fixes is checked by breaking it (the result must then fail);
//! the manifest's new keys are refused where they cannot work; a gap cuts the track and
//! every epoch is accounted for; a thermal triad is applied at its logged temperatures; an
//! axis model calibrated on a tilt table reduces a vertical axis.

use adjust::survey::gravity::filter;
use adjust::survey::gravity::stage::{GravityArgs, print_summary};
use ingest::contract::gravity_ledger::GravityReport;
use ingest::contract::survey::FilterKind;
use ingest::contract::tables::gravity;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// triad-multipos's calibration.json, computed once for all the tests here.
fn calibration() -> &'static Path {
    static CAL: OnceLock<PathBuf> = OnceLock::new();
    CAL.get_or_init(|| {
        let out = tempfile::tempdir().expect("tempdir").keep();
        let dataset = fixtures::dataset_dir(fixtures::triad::MULTIPOS);
        ingest::run(&dataset, &out).expect("ingest");
        align::run(&dataset, &out).expect("align");
        adjust::run(&dataset, &out).expect("adjust");
        out.join("adjust").join("calibration.json")
    })
}

fn args(dataset: &Path) -> GravityArgs {
    GravityArgs {
        apply: adjust::survey::apply::stream::ApplyArgs {
            dataset: dataset.to_path_buf(),
            calibration: calibration().to_path_buf(),
            model: None,
            session: Some("lab".to_owned()),
            out: None,
        },
        accelerometer: None,
        skip_bad_lines: false,
        block_epochs: None,
    }
}

/// One epoch of gravity.parquet.
struct Row {
    time_s: f64,
    filtered: f64,
    sigma: f64,
    flags: u8,
}

fn rows(out: &Path) -> Vec<Row> {
    let path = out.join("gravity").join(gravity::FILE);
    let names = ["down_filtered_mgal", "sigma_down_mgal"];
    let mut rows = Vec::new();
    ingest::contract::tables::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            rows.push(Row {
                time_s: b.time_ns[i] as f64 * 1e-9,
                filtered: b.values[0].value(i),
                sigma: b.values[1].value(i),
                flags: b.flags[i],
            });
        }
        Ok(())
    })
    .expect("gravity.parquet");
    rows
}

/// The truth's `columns` of truth.csv (4 down, 5 north, 6 east, mGal) at `t` (GPS s),
/// linearly interpolated between its 1 Hz rows.
fn truth_table<const N: usize>(dataset: &Path, columns: [usize; N]) -> impl Fn(f64) -> [f64; N] {
    let text = std::fs::read_to_string(dataset.join("truth.csv")).expect("truth.csv");
    let table: Vec<(f64, [f64; N])> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().expect("number")).collect();
            (f[0], columns.map(|c| f[c]))
        })
        .collect();
    move |t| {
        let k = table
            .partition_point(|(s, _)| *s <= t)
            .clamp(1, table.len() - 1);
        let ((t0, v0), (t1, v1)) = (table[k - 1], table[k]);
        std::array::from_fn(|c| v0[c] + (v1[c] - v0[c]) * (t - t0) / (t1 - t0))
    }
}

/// rms of (estimate - filtered truth) in mGal and of its ratio to the sigma, over the epochs
/// not flagged as edges; the filtered truth is the truth at the epochs through the stage's
/// filter (checked against scipy in gravity_peers.rs).
fn scores(dataset: &Path, out: &Path, filter_s: f64) -> (f64, f64) {
    scores_with(dataset, out, (FilterKind::Butterworth, filter_s))
}

/// [`scores`] of a stage run with the filter `kind`.
fn scores_with(dataset: &Path, out: &Path, filter: (FilterKind, f64)) -> (f64, f64) {
    scores_of(dataset, out, filter, 0.0)
}

/// [`scores`] over the epochs at least a filter period from any epoch flagged turning:
/// an antenna array's down, whose track force lags a turn's onset and end
/// (docs/model.md 7, "An antenna array").
fn scores_away_from_turns(dataset: &Path, out: &Path, filter_s: f64) -> (f64, f64) {
    scores_of(dataset, out, (FilterKind::Butterworth, filter_s), filter_s)
}

/// [`scores`] over the epochs more than `away_s` from a turning epoch (0: all).
fn scores_of(dataset: &Path, out: &Path, filter: (FilterKind, f64), away_s: f64) -> (f64, f64) {
    let (rows, want) = filtered_truth(dataset, out, filter);
    let turns: Vec<f64> = rows
        .iter()
        .filter(|r| r.flags & gravity::TURN != 0)
        .map(|r| r.time_s)
        .collect();
    let near_turn = |t: f64| away_s > 0.0 && turns.iter().any(|u| (u - t).abs() <= away_s);
    let inner: Vec<usize> = (0..rows.len())
        .filter(|&k| rows[k].flags & gravity::EDGE == 0 && !near_turn(rows[k].time_s))
        .collect();
    assert!(
        inner.len() > rows.len() / 2,
        "{} of {}",
        inner.len(),
        rows.len()
    );
    let n = inner.len() as f64;
    let err = |k: usize| rows[k].filtered - want[k];
    let rms = (inner.iter().map(|&k| err(k).powi(2)).sum::<f64>() / n).sqrt();
    let z = (inner
        .iter()
        .map(|&k| (err(k) / rows[k].sigma).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    (rms, z)
}

/// The rows of gravity.parquet and the truth at each through the stage's filter (`kind` over
/// `filter_s`), stretch by stretch.
fn filtered_truth(
    dataset: &Path,
    out: &Path,
    (kind, filter_s): (FilterKind, f64),
) -> (Vec<Row>, Vec<f64>) {
    let rows = rows(out);
    let truth = truth_table(dataset, [4]);
    let dt = (rows[1].time_s - rows[0].time_s).abs();
    let lowpass = filter::Lowpass::design(kind, 1.0 / filter_s, 1.0 / dt).expect("filter");
    let pad = (3.0 * filter_s / dt).ceil() as usize;
    let pivot = (filter_s / dt).round() as usize;
    // The truth filtered stretch by stretch, as the stage filters.
    let mut want = Vec::with_capacity(rows.len());
    let mut start = 0;
    for k in 1..=rows.len() {
        if k == rows.len() || rows[k].time_s - rows[k - 1].time_s > 1.5 * dt {
            let raw: Vec<f64> = rows[start..k].iter().map(|r| truth(r.time_s)[0]).collect();
            want.extend(match &lowpass {
                filter::Lowpass::Butterworth(sections) => {
                    filter::filtfilt(sections, &raw).expect("filtered truth")
                }
                kernel => kernel.apply(&raw, pad, pivot.min(raw.len())),
            });
            start = k;
        }
    }
    (rows, want)
}

/// The one crossover of a survey-lines track, checked for where it is, and its error against
/// the filtered truth's difference over its sigma.
fn crossover_z(
    plan: &fixtures::survey_lines::LinesPlan,
    dataset: &Path,
    out: &Path,
    r: &GravityReport,
) -> f64 {
    assert_eq!(r.crossovers.len(), 1, "{:?}", r.crossovers);
    let c = &r.crossovers[0];
    let east_m = (c.longitude_deg - plan.origin[1]).to_radians()
        * 6_378_137.0
        * plan.origin[0].to_radians().cos();
    let want_east = plan.crossing_east_m().expect("the lines cross");
    assert!(
        (east_m - want_east).abs() < 0.01 * plan.line_m,
        "{c:?} at {east_m} m"
    );
    assert!((c.angle_deg - plan.return_deg).abs() < 1.0, "{c:?}");
    let (rows, want) = filtered_truth(dataset, out, (FilterKind::Butterworth, r.filter.filter_s));
    let truth = |ns: i64| {
        let t = ns as f64 * 1e-9;
        let k = rows
            .partition_point(|x| x.time_s <= t)
            .clamp(1, rows.len() - 1);
        let f = (t - rows[k - 1].time_s) / (rows[k].time_s - rows[k - 1].time_s);
        want[k - 1] + f * (want[k] - want[k - 1])
    };
    let true_difference = truth(c.second.time_gps_ns) - truth(c.first.time_gps_ns);
    let z = (c.difference_mgal - true_difference) / c.sigma_mgal;
    eprintln!(
        "crossover: {:+.3} +/- {:.3} mGal, the truth's {true_difference:+.3}: z {z:+.2}",
        c.difference_mgal, c.sigma_mgal
    );
    z
}

fn reduce(dataset: &Path, out: &Path) -> GravityReport {
    let report = args(dataset).run(out).expect("gravity");
    print_summary(&report, &mut std::io::stderr());
    report
}

#[test]
fn the_survey_lines_are_recovered_within_their_sigmas() {
    let dataset = fixtures::dataset_dir(fixtures::survey_lines::SURVEY_LINES);
    let out = tempfile::tempdir().expect("tempdir");
    let r = reduce(&dataset, out.path());
    let (rms, z) = scores(&dataset, out.path(), r.filter.filter_s);
    eprintln!(
        "survey-lines: rms error {rms:.3} mGal at {:.0} m resolution; rms of error / sigma {z:.3}",
        r.filter.resolution_m
    );
    assert!((0.8..1.2).contains(&z), "rms z {z}");
    assert!(rms < 0.3, "rms {rms} mGal");
    // Every epoch accounted for, both ties used on the one stretch.
    let s = &r.sessions[0];
    assert_eq!(
        s.epochs_used + s.dropped.values().sum::<u64>(),
        s.epochs_read
    );
    assert_eq!(s.stretches.len(), 1);
    assert!(r.ties.iter().all(|t| t.used_in.is_some()) && r.ties.len() == 2);
    // The turn (pi + 8.5 deg at 150 m and 5 m/s, 99 s) is flagged as a turn, little else.
    let turning = s.flagged.get("turn").copied().unwrap_or(0);
    assert!((800..1200).contains(&turning), "{turning} turning epochs");
    let z = crossover_z(&fixtures::survey_lines::plan(), &dataset, out.path(), &r);
    assert!(z.abs() < 3.5, "crossover z {z}");
}

#[test]
fn an_aircraft_survey_is_recovered_within_its_sigmas() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("aircraft");
    let plan = fixtures::survey_lines::aircraft_plan();
    fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("aircraft survey");
    let out = dir.path().join("out");
    let r = reduce(&dataset, &out);
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    eprintln!(
        "aircraft at {} m/s, {} m up: rms error {rms:.3} mGal at {:.0} m resolution; rms of \
         error / sigma {z:.3}",
        plan.speed_m_s, plan.climb_m, r.filter.resolution_m
    );
    assert!((0.8..1.2).contains(&z), "rms z {z}");
    let z = crossover_z(&plan, &dataset, &out, &r);
    assert!(z.abs() < 3.5, "crossover z {z}");
}

/// survey-lines with its manifest edited, reduced.
fn edited(edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("survey-lines");
    fixtures::copy_dataset(fixtures::survey_lines::SURVEY_LINES, &dataset, edit).expect("copy");
    std::fs::copy(
        fixtures::dataset_dir(fixtures::survey_lines::SURVEY_LINES).join("truth.csv"),
        dataset.join("truth.csv"),
    )
    .expect("truth.csv");
    let out = dir.path().join("out");
    (dir, dataset, out)
}

#[test]
fn a_convention_broken_fails_the_truth() {
    // The lever arm reversed still gives values on the Earth: they fail the truth.
    let (_dir, dataset, out) = edited(|m| {
        let from = "lever_arm_m = [0.4, -0.2, 1.6]";
        assert!(m.contains(from), "{from}");
        m.replace(from, "lever_arm_m = [-0.4, 0.2, -1.6]")
    });
    let r = reduce(&dataset, &out);
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    eprintln!("the lever arm reversed: rms error {rms:.3} mGal, rms z {z:.2}");
    assert!(z > 2.0, "rms z {z} (rms {rms} mGal) should fail");
    // A mounting left out (a diagonal triad taken as mounted straight: a level of -414 388
    // mGal and disturbances of thousands of mGal were written with sigmas of 0.15), or its
    // rotations taken in the other order: no such result is written.
    let mounting = "mounting_deg = [45.0, -35.264389682754654, 20.0]\n";
    for (what, to) in [
        ("the mounting left out", ""),
        (
            "the mounting's rotations taken in the other order (Rx Ry Rz)",
            // The angles whose Rz Ry Rx has the third row of Rx(45) Ry(-35.26) Rz(20)
            // (numpy: roll atan2(r1, r2), pitch -asin(r0) of that row).
            "mounting_deg = [42.27205917036782, -38.71688848984887, 20.0]\n",
        ),
    ] {
        let (_dir, dataset, out) = edited(|m| {
            assert!(m.contains(mounting), "{mounting}");
            m.replace(mounting, to)
        });
        let e = args(&dataset).run(&out).expect_err("refused").to_string();
        eprintln!("{what}: {e}");
        assert!(
            e.contains("stretch 0") && e.contains("beyond") && e.contains("mounting_deg"),
            "{what}: {e}"
        );
    }
}

/// `[survey] meter_status_flag_bits` on a survey whose samples are no meter's file (the
/// accelerometers' stream of survey-lines) is refused by key.
#[test]
fn meter_status_bits_on_a_stream_without_a_status_are_refused() {
    let (_dir, dataset, out) = edited(|m| {
        assert!(m.contains("[survey]\n"));
        m.replace("[survey]\n", "[survey]\nmeter_status_flag_bits = [0]\n")
    });
    let e = args(&dataset).run(&out).expect_err("refused").to_string();
    eprintln!("{e}");
    assert!(
        e.contains("survey.meter_status_flag_bits") && e.contains("no meter status"),
        "{e}"
    );
}

/// A calibration.json gravcal did not write as it is read: a field it does not know (one
/// added at the top, one in a parameter) is refused naming the field and the file, not
/// passed over.
#[test]
fn a_calibration_with_a_field_not_known_is_refused() {
    let dir = tempfile::tempdir().expect("tempdir");
    let text = std::fs::read_to_string(calibration()).expect("calibration");
    for (what, edited, field) in [
        (
            "top",
            text.replacen('{', "{\"made_by\": \"another tool\",", 1),
            "made_by",
        ),
        (
            "parameter",
            text.replacen("\"sigma\":", "\"sigma_2\": 1.0, \"sigma\":", 1),
            "sigma_2",
        ),
    ] {
        assert_ne!(edited, text, "{what}");
        let path = dir.path().join(format!("{what}.json"));
        std::fs::write(&path, edited).expect("write");
        let mut a = args(&fixtures::dataset_dir(fixtures::survey_lines::SURVEY_LINES));
        a.apply.calibration = path.clone();
        let e = a
            .run(&dir.path().join(format!("out-{what}")))
            .expect_err(what)
            .to_string();
        eprintln!("{what}: {e}");
        assert!(
            e.contains(&format!("unknown field `{field}`")) && e.contains(&*path.to_string_lossy()),
            "{what}: {e}"
        );
    }
}

/// `[survey] array_down = "magnitude"` on a survey none of whose sessions lists three
/// antennas (survey-lines, one trajectory) is refused by key.
#[test]
fn the_magnitude_without_an_array_is_refused() {
    let (_dir, dataset, out) = edited(|m| {
        assert!(m.contains("[survey]\n"));
        m.replace("[survey]\n", "[survey]\narray_down = \"magnitude\"\n")
    });
    let e = args(&dataset).run(&out).expect_err("refused").to_string();
    eprintln!("{e}");
    assert!(
        e.contains("survey.array_down") && e.contains("three or more antennas"),
        "{e}"
    );
}

/// North and east against the truth through the stage's filter, over the epochs not at an
/// edge: per component the rms error (mGal), the rms of error / sigma, and the median sigma
/// and its attitude part.
fn horizontal_scores(dataset: &Path, out: &Path, filter_s: f64) -> [[f64; 4]; 2] {
    let path = out.join("gravity").join(gravity::FILE);
    let names = [
        "north_filtered_mgal",
        "sigma_north_mgal",
        "sigma_north_attitude_mgal",
        "east_filtered_mgal",
        "sigma_east_mgal",
        "sigma_east_attitude_mgal",
    ];
    let (mut time, mut values, mut flags) = (Vec::new(), vec![Vec::new(); 6], Vec::new());
    ingest::contract::tables::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
        use arrow_array::Array;
        for i in 0..b.time_ns.len() {
            time.push(b.time_ns[i] as f64 * 1e-9);
            for (c, v) in values.iter_mut().enumerate() {
                assert!(b.values[c].is_valid(i), "{} null with attitude", names[c]);
                v.push(b.values[c].value(i));
            }
            flags.push(b.flags[i]);
        }
        Ok(())
    })
    .expect("gravity.parquet");
    let truth = truth_table(dataset, [5, 6]);
    let dt = time[1] - time[0];
    let sections = filter::butterworth(filter::ORDER, 1.0 / filter_s, 1.0 / dt).expect("filter");
    let inner: Vec<usize> = (0..time.len())
        .filter(|&k| flags[k] & gravity::EDGE == 0)
        .collect();
    let n = inner.len() as f64;
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    std::array::from_fn(|c| {
        let raw: Vec<f64> = time.iter().map(|&t| truth(t)[c]).collect();
        let want = filter::filtfilt(&sections, &raw).expect("filtered truth");
        let (est, sigma, att) = (&values[3 * c], &values[3 * c + 1], &values[3 * c + 2]);
        let err = |k: usize| est[k] - want[k];
        let rms = (inner.iter().map(|&k| err(k).powi(2)).sum::<f64>() / n).sqrt();
        let z = (inner
            .iter()
            .map(|&k| (err(k) / sigma[k]).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let sig = median(inner.iter().map(|&k| sigma[k]).collect());
        let a = median(inner.iter().map(|&k| att[k]).collect());
        [rms, z, sig, a]
    })
}

/// A boat that rolls 3 deg and pitches 1 deg, with an attitude file 0.1 mrad wrong in roll
/// and pitch (1 mrad in heading), errors wandering over 10 minutes: down as without
/// attitude, north and east within their sigmas, which say how large the attitude makes
/// them (g times 0.1 mrad, about 100 mGal).
#[test]
fn with_attitude_north_and_east_are_within_their_sigmas() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("attitude");
    let plan = fixtures::survey_lines::attitude_plan();
    fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
    let out = dir.path().join("out");
    let r = reduce(&dataset, &out);
    assert!(
        r.specific_force.contains("attitude"),
        "{}",
        r.specific_force
    );
    assert!(
        r.inputs.iter().any(|i| i.role == "attitude of lines"),
        "{:?}",
        r.inputs
    );
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    eprintln!("with attitude, down: rms error {rms:.3} mGal, rms z {z:.3}");
    assert!((0.8..1.2).contains(&z), "down rms z {z}");
    for (name, [rms, z, sigma, att]) in
        ["north", "east"]
            .into_iter()
            .zip(horizontal_scores(&dataset, &out, r.filter.filter_s))
    {
        eprintln!(
            "with attitude, {name}: rms error {rms:.2} mGal, rms z {z:.3}; median sigma \
             {sigma:.1} mGal, of it the attitude's {att:.1}"
        );
        assert!(z < 1.3, "{name} rms z {z}");
        assert!(
            (60.0..150.0).contains(&att),
            "{name}: attitude's part {att} mGal"
        );
    }
}

/// The rolling boat written under `dir`: the dataset and its attitude file's text.
fn rolling_boat(dir: &Path) -> (PathBuf, PathBuf, String) {
    let dataset = dir.join("rolling");
    let plan = fixtures::survey_lines::attitude_plan();
    fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
    let att = dataset.join("raw/lines_att.csv");
    let text = std::fs::read_to_string(&att).expect("attitude");
    (dataset, att, text)
}

/// An attitude file without sds: north and east are given, but their sigmas (and attitude
/// parts) are null, since the attitude's error, their largest part, is not known; each
/// epoch is flagged `attitude_sd_unknown`.
#[test]
fn without_attitude_sds_north_and_east_have_no_sigma() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (dataset, att, text) = rolling_boat(dir.path());
    let stripped: String = text
        .lines()
        .map(|l| l.splitn(5, ',').take(4).collect::<Vec<_>>().join(",") + "\n")
        .collect();
    std::fs::write(&att, stripped).expect("write");
    let out = dir.path().join("out");
    let r = reduce(&dataset, &out);
    let s = &r.sessions[0];
    assert_eq!(
        s.flagged.get("attitude_sd_unknown"),
        Some(&s.epochs_used),
        "{:?}",
        s.flagged
    );
    let path = out.join("gravity").join(gravity::FILE);
    let names = [
        "north_filtered_mgal",
        "sigma_north_mgal",
        "sigma_north_positions_mgal",
        "sigma_east_attitude_mgal",
    ];
    let mut counts = [0usize; 4];
    ingest::contract::tables::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
        use arrow_array::Array;
        for (c, v) in b.values.iter().enumerate() {
            counts[c] += v.len() - v.null_count();
        }
        Ok(())
    })
    .expect("gravity.parquet");
    let n = s.epochs_used as usize;
    assert_eq!(counts, [n, 0, n, 0], "non-null values of {names:?}");
}

/// Two minutes of attitude lost under way: the epochs without one dropped by name, the
/// track cut there; an attitude file of another day: nothing reduced, said so.
#[test]
fn epochs_without_attitude_are_dropped_by_name() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (dataset, att, text) = rolling_boat(dir.path());
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(k, _)| !(8001..9201).contains(k))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(&att, kept.join("\n") + "\n").expect("write");
    let r = reduce(&dataset, &dir.path().join("out"));
    let s = &r.sessions[0];
    let lost = s.dropped.get("no_attitude").copied().unwrap_or(0);
    assert!((1195..=1201).contains(&lost), "{:?}", s.dropped);
    assert_eq!(s.stretches.len(), 2, "{s:?}");
    assert_eq!(
        s.epochs_used + s.dropped.values().sum::<u64>(),
        s.epochs_read
    );
    // A day later: no epoch has an attitude.
    let shifted: String = text
        .lines()
        .map(|l| match l.split_once(',') {
            Some((t, rest)) if t.parse::<f64>().is_ok() => {
                format!("{:.3},{rest}\n", t.parse::<f64>().unwrap_or(0.0) + 86_400.0)
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&att, shifted).expect("write");
    let e = args(&dataset)
        .run(&dir.path().join("out2"))
        .expect_err("no attitude")
        .to_string();
    assert!(
        e.contains("none of its") && e.contains("no_attitude"),
        "{e}"
    );
}

/// One damaged line in the trajectory: an error naming file, line and field; with
/// --skip-bad-lines, set aside, counted and listed, and the epochs around it reduced.
#[test]
fn a_damaged_trajectory_line_fails_or_is_set_aside() {
    let (_dir, dataset, out) = edited(|m| m);
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    // Line 5001 (1-based), an epoch under way: its latitude damaged.
    let f: Vec<String> = lines[5000].split_whitespace().map(str::to_owned).collect();
    lines[5000] = lines[5000].replacen(&f[2], "43.2x", 1);
    std::fs::write(&pos, lines.join("\n") + "\n").expect("write");
    let e = args(&dataset).run(&out).expect_err("damaged").to_string();
    assert!(e.contains("lines.pos:5001: latitude:"), "{e}");
    let mut a = args(&dataset);
    a.skip_bad_lines = true;
    let r = a.run(&out).expect("set aside");
    let s = &r.sessions[0];
    assert_eq!(s.dropped.get("bad_line"), Some(&1), "{:?}", s.dropped);
    assert_eq!(s.bad_lines.len(), 1, "{:?}", s.bad_lines);
    assert!(
        s.bad_lines[0].starts_with("raw/lines.pos:5001: latitude:"),
        "{:?}",
        s.bad_lines
    );
    assert_eq!(
        s.epochs_used + s.dropped.values().sum::<u64>(),
        s.epochs_read
    );
    // The missing epoch is a gap: the track is cut there, both sides reduced.
    assert_eq!(s.stretches.len(), 2, "{s:?}");
}

/// A trajectory that gives no sds (a CSV of time and position only, seconds since the
/// session's start): the positions' sd is their own white noise from their third
/// differences, found at its true 1 and 2 cm, and the sigmas hold as with RTKLIB's sds.
#[test]
fn a_trajectory_without_sds_is_weighed_by_its_own_noise() {
    let (_dir, dataset, out) = edited(|m| {
        m.replacen(
            "trajectory = \"raw/lines.pos\"\ntrajectory_format = \"rtklib\"",
            "trajectory = \"raw/lines.csv\"\ntrajectory_format = \"csv\"\ntrajectory_time = \"s\"",
            1,
        )
    });
    let pos = std::fs::read_to_string(dataset.join("raw/lines.pos")).expect("pos");
    let mut csv = String::from("time,lat_deg,lon_deg,h_m\n");
    for l in pos.lines().filter(|l| !l.starts_with('%')) {
        let f: Vec<&str> = l.split_whitespace().collect();
        // GPST 07:00:18 is the session's start (07:00:00 UTC, GPS - UTC = 18 s).
        let hms: Vec<f64> = f[1].split(':').map(|x| x.parse().expect("time")).collect();
        let s = (hms[0] - 7.0) * 3600.0 + hms[1] * 60.0 + hms[2] - 18.0;
        csv.push_str(&format!("{s:.3},{},{},{}\n", f[2], f[3], f[4]));
    }
    std::fs::write(dataset.join("raw/lines.csv"), csv).expect("csv");
    let r = args(&dataset).run(&out).expect("gravity");
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    let s = &r.sessions[0];
    eprintln!(
        "no sds: positions' noise {:?} m; rms error {rms:.3} mGal, rms z {z:.3}",
        s.position_noise_m
    );
    assert_eq!(s.position_sd_given_m, None);
    let [n, e, u] = s.position_noise_m;
    assert!(
        (n / 0.01 - 1.0).abs() < 0.05 && (e / 0.01 - 1.0).abs() < 0.05,
        "{n} {e}"
    );
    assert!((u / 0.02 - 1.0).abs() < 0.05, "{u}");
    assert!((0.8..1.2).contains(&z), "rms z {z}");
}

/// Three single-point solutions among the fixed ones (RTKLIB's Q 5: heights 1.5 m off,
/// and sdu 1.5 m saying so): each epoch's error spreads over the filter's reach, and so
/// does its sd, so the sigmas hold around them. With the epoch's own sd times the gain,
/// the neighbours' sigmas would stay at a tenth of a mGal beside errors of tens.
#[test]
fn a_single_solution_among_fixed_ones_widens_the_sigma_around_it() {
    let (_dir, dataset, out) = edited(|m| m);
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    for k in [6000, 12000, 18000] {
        let mut f: Vec<String> = lines[k].split_whitespace().map(str::to_owned).collect();
        let h: f64 = f[4].parse().expect("height");
        f[4] = format!("{:.4}", h + 1.5);
        f[5] = "5".to_owned();
        f[9] = "1.5000".to_owned();
        lines[k] = f.join("   ");
    }
    std::fs::write(&pos, lines.join("\n") + "\n").expect("write");
    let r = args(&dataset).run(&out).expect("gravity");
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    // Within 100 s of a single solution (pos line k is epoch k - 2: two header lines).
    let (rows, want) = filtered_truth(&dataset, &out, (FilterKind::Butterworth, r.filter.filter_s));
    let spikes: Vec<f64> = [6000, 12000, 18000].map(|k| rows[k - 2].time_s).to_vec();
    let near: Vec<usize> = (0..rows.len())
        .filter(|&k| spikes.iter().any(|t| (rows[k].time_s - t).abs() < 100.0))
        .collect();
    let z_near = (near
        .iter()
        .map(|&k| ((rows[k].filtered - want[k]) / rows[k].sigma).powi(2))
        .sum::<f64>()
        / near.len() as f64)
        .sqrt();
    let sigma_near = near.iter().map(|&k| rows[k].sigma).sum::<f64>() / near.len() as f64;
    eprintln!(
        "three single solutions: rms error {rms:.3} mGal, rms z {z:.3}; within 100 s of \
         them rms z {z_near:.3}, mean sigma {sigma_near:.3} mGal"
    );
    assert!((0.8..1.2).contains(&z), "rms z {z}");
    assert!((0.6..1.4).contains(&z_near), "rms z near them {z_near}");
    assert!(sigma_near > 1.5 * rows[1000].sigma, "{sigma_near}");
}

/// A second survey session without a trajectory (the next day's drive, its trajectory
/// forgotten): apply calibrates it, the stage cannot reduce it and says so, by name.
#[test]
fn a_survey_session_without_a_trajectory_is_named_as_not_reduced() {
    let (_dir, dataset, out) = edited(|m| {
        let (i, j) = (
            m.find("[[session]]").expect("session"),
            m.find("[survey]").expect("survey"),
        );
        let next_day: String = m[i..j]
            .replace("id = \"lines\"", "id = \"lines-b\"")
            .replace("2026-06-10", "2026-06-11")
            .lines()
            .filter(|l| !l.starts_with("trajectory"))
            .map(|l| format!("{l}\n"))
            .collect();
        format!("{}{next_day}\n{}", &m[..j], &m[j..])
    });
    let r = args(&dataset).run(&out).expect("gravity");
    assert_eq!(r.sessions.len(), 1);
    assert_eq!(r.not_reduced.len(), 1, "{:?}", r.not_reduced);
    assert_eq!(r.not_reduced[0].session, "lines-b");
    assert!(
        r.not_reduced[0].why.contains("no `trajectory`"),
        "{:?}",
        r.not_reduced
    );
}

/// A trajectory's epochs pass ingest's time gate, as every log does: an epoch stamped an
/// hour ahead (a receiver's glitch) is dropped alone as `time_outlier`, not every epoch
/// after it; one stamped an hour back alone as `time_not_increasing`. Each leaves a gap.
#[test]
fn a_trajectory_time_out_of_place_costs_that_epoch_alone() {
    let (_dir, dataset, out) = edited(|m| m);
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    // Two epochs under way (lines 5001 and 15001, 1-based): an hour ahead, an hour back.
    lines[5000] = lines[5000].replacen("2026/06/10 07:", "2026/06/10 08:", 1);
    lines[15000] = lines[15000].replacen("2026/06/10 07:", "2026/06/10 06:", 1);
    std::fs::write(&pos, lines.join("\n") + "\n").expect("write");
    let r = args(&dataset).run(&out).expect("gravity");
    let s = &r.sessions[0];
    assert_eq!(s.dropped.get("time_outlier"), Some(&1), "{:?}", s.dropped);
    assert_eq!(
        s.dropped.get("time_not_increasing"),
        Some(&1),
        "{:?}",
        s.dropped
    );
    assert_eq!(s.epochs_used + 2, s.epochs_read, "{:?}", s.dropped);
    assert_eq!(s.stretches.len(), 3, "{s:?}");
}

/// Each named filter (docs/model.md 7, "The filters") reduces survey-lines with its sigmas
/// honest: the rms of error / sigma against the truth through the same filter within 0.8 to
/// 1.25, as the Butterworth's; gravity.json names the filter.
#[test]
fn every_named_filter_keeps_the_sigmas_honest() {
    for kind in [
        FilterKind::Gaussian,
        FilterKind::Blackman,
        FilterKind::Hamming,
    ] {
        let (_dir, dataset, out) = edited(|m| {
            m.replace(
                "[survey]\n",
                &format!("[survey]\nfilter = \"{}\"\n", kind.name()),
            )
        });
        let r = reduce(&dataset, &out);
        assert_eq!(r.filter.name, kind);
        let (rms, z) = scores_with(&dataset, &out, (kind, r.filter.filter_s));
        eprintln!(
            "survey-lines through a {} filter ({}): rms error {rms:.3} mGal, rms z {z:.3}",
            kind.name(),
            r.filter.kind
        );
        assert!((0.8..1.25).contains(&z), "{kind:?}: rms z {z}");
    }
}

#[test]
fn a_gap_cuts_the_track_and_every_epoch_is_accounted_for() {
    // One tie on each side of the gap: by default (tie_level = "session") both fix one
    // offset and drift for both stretches; with "stretch" each stretch its own offset.
    for (mode, ties) in [("session", 2), ("stretch", 1)] {
        let (_dir, dataset, out) =
            edited(|m| m.replace("[survey]\n", &format!("[survey]\ntie_level = \"{mode}\"\n")));
        // Two minutes of positions lost in the middle of the first line.
        let pos = dataset.join("raw/lines.pos");
        let text = std::fs::read_to_string(&pos).expect("pos");
        let kept: Vec<&str> = text
            .lines()
            .enumerate()
            .filter(|(k, _)| !(8000..9200).contains(k))
            .map(|(_, l)| l)
            .collect();
        std::fs::write(&pos, kept.join("\n") + "\n").expect("write");
        let r = reduce(&dataset, &out);
        let s = &r.sessions[0];
        assert_eq!(s.gaps, 1);
        assert_eq!(s.stretches.len(), 2);
        assert_eq!(
            s.epochs_used + s.dropped.values().sum::<u64>(),
            s.epochs_read
        );
        assert!(
            s.stretches
                .iter()
                .all(|st| st.drift.as_ref().is_some_and(|d| d.ties == ties)),
            "{mode}: {:?}",
            s.stretches
        );
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        eprintln!("with a gap, tie_level {mode}: rms error {rms:.3} mGal, rms z {z:.2}");
        assert!(z < 1.5, "{mode}: rms z {z}");
    }
}

#[test]
fn a_stage_that_would_reduce_nothing_or_the_wrong_thing_is_refused() {
    // A trajectory from another day: no epoch has specific force.
    let (_dir, dataset, out) = edited(|m| m);
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    std::fs::write(&pos, text.replace("2026/06/10", "2026/06/11")).expect("write");
    let e = args(&dataset)
        .run(&out)
        .expect_err("nothing reduced")
        .to_string();
    assert!(
        e.contains("session lines: none of its") && e.contains("no_specific_force"),
        "{e}"
    );
    // A trajectory a year off: outside the session's days, each epoch counted so.
    let (_dir, dataset, out) = edited(|m| m);
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    std::fs::write(&pos, text.replace("2026/06/10", "2027/06/10")).expect("write");
    let e = args(&dataset).run(&out).expect_err("outside").to_string();
    assert!(e.contains("outside_session"), "{e}");
    // --accelerometer with a triad model.
    let (_dir, dataset, out) = edited(|m| m);
    let mut a = args(&dataset);
    a.accelerometer = Some("acc1".to_owned());
    let e = a
        .run(&out)
        .expect_err("a triad has no axis to choose")
        .to_string();
    assert!(e.contains("--accelerometer") && e.contains("triad"), "{e}");
    // Ties no place along the track can have: one whose time falls under way (mistyped),
    // one whose gravity is 3000 mGal off normal gravity there (a digit mistyped). Either
    // would move the whole stretch to the gravity of another place.
    for (from, to, says) in [
        (
            "2026-06-10T07:03:20.000Z",
            "2026-06-10T07:20:00.000Z",
            "the tie at 2026-06-10T07:20:00.000Z: the vehicle moves at 5.0 m/s",
        ),
        (
            "g_mgal = 980444.809",
            "g_mgal = 983444.809",
            "the tie at 2026-06-10T07:03:20.000Z: its 983444.809 mGal is 3003 mGal",
        ),
    ] {
        let (_dir, dataset, out) = edited(|m| m.replacen(from, to, 1));
        let e = args(&dataset).run(&out).expect_err(says).to_string();
        assert!(e.contains(says), "{e}");
    }
    // A filter period the epochs cannot show: the trajectory at 1 Hz (every tenth epoch),
    // a 1.5 s filter. The filter's own check had said only "filter: a cut-off of
    // 0.6666666666666666 Hz at 1 Hz: it must lie in (0, 0.5) Hz".
    let (_dir, dataset, out) = edited(|m| m.replacen("filter_s = 100.0", "filter_s = 1.5", 1));
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with('%'))
        .chain(text.lines().filter(|l| !l.starts_with('%')).step_by(10))
        .collect();
    std::fs::write(&pos, kept.join("\n") + "\n").expect("write");
    let e = args(&dataset)
        .run(&out)
        .expect_err("1.5 s at 1 Hz")
        .to_string();
    assert!(
        e.contains("survey.filter_s = 1.5 s is not longer than two of session lines's epoch")
            && e.contains("lines.pos: an epoch every 1 s")
            && e.contains("choose more than 2 s"),
        "{e}"
    );
}

#[test]
fn the_new_keys_are_refused_where_they_cannot_work() {
    let cases: [(&str, &str, &str); 10] = [
        // Only a meter's own file carries cross-coupling monitors.
        (
            "filter_s = 100.0",
            "filter_s = 100.0\ncross_coupling = \"fit\"",
            "survey.cross_coupling",
        ),
        (
            "filter_s = 100.0",
            "filter_s = 100.0\ncross_coupling = \"fitted\"",
            "`fitted`: expected \"none\", \"fit\" or",
        ),
        (
            "trajectory_format = \"rtklib\"\n",
            "trajectory_format = \"rtklib\"\ntrajectory_time = \"iso\"\n",
            "session[0].trajectory_time",
        ),
        (
            "trajectory_format = \"rtklib\"\n",
            "trajectory_format = \"rtklib\"\nattitude = \"raw/lines.pos\"\n",
            "session[0].attitude_time",
        ),
        (
            "trajectory_format = \"rtklib\"\n",
            "trajectory_format = \"rtklib\"\nattitude_time = \"iso\"\n",
            "session[0].attitude_time",
        ),
        (
            "trajectory_format = \"rtklib\"\n",
            "trajectory_format = \"rtklib\"\nattitude = \"raw/none.csv\"\nattitude_time = \"iso\"\n",
            "session[0].attitude",
        ),
        (
            "trajectory = \"raw/lines.pos\"\ntrajectory_format = \"rtklib\"\n",
            "",
            "survey",
        ),
        ("filter_s = 100.0", "filter_s = 0.0", "survey.filter_s"),
        (
            "duration_s = 300",
            "duration_s = -3",
            "survey.tie[0].duration_s",
        ),
        // The first tie given twice: its epochs would tie twice.
        (
            "[[survey.tie]]\n",
            "[[survey.tie]]\ntime = \"2026-06-10T07:04:00Z\"\nduration_s = 60\ng_mgal = \
             980444.809\n\n[[survey.tie]]\n",
            "survey.tie[1]",
        ),
    ];
    for (from, to, key) in cases {
        let (_dir, dataset, _out) = edited(|m| {
            assert!(m.contains(from), "{from}");
            m.replacen(from, to, 1)
        });
        let e = ingest::contract::manifest::Dataset::load(&dataset)
            .expect_err(key)
            .to_string();
        assert!(
            e.contains(&format!("{key}: ")) || e.contains(&format!("{key} ")),
            "{key}: {e}"
        );
    }
}

/// North and east over replicas: the rolling boat with attitude, 8 seeds (the attitude's
/// errors, the positions', the triad's), pooled over both components: the attitude's errors
/// wander over 10 minutes, so one survey of 40 minutes holds few independent values of them
/// and only a pool can say whether the sigma is their size.
#[test]
fn monte_carlo_of_north_and_east_with_attitude() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut down_z2, mut horizontal_z2, mut n) = (0.0, 0.0, 0.0);
    for seed in 1..=8u64 {
        let (_, dataset, out) = replica(dir.path(), fixtures::survey_lines::attitude_plan(), seed);
        let r = args(&dataset).run(&out).expect("gravity");
        let (_, z) = scores(&dataset, &out, r.filter.filter_s);
        let [north, east] = horizontal_scores(&dataset, &out, r.filter.filter_s);
        eprintln!(
            "seed {seed}: down rms z {z:.3}; north {:.1} mGal, z {:.3}; east {:.1} mGal, z {:.3}",
            north[0], north[1], east[0], east[1]
        );
        down_z2 += z * z;
        horizontal_z2 += 0.5 * (north[1].powi(2) + east[1].powi(2));
        n += 1.0;
    }
    let (down, horizontal) = ((down_z2 / n).sqrt(), (horizontal_z2 / n).sqrt());
    eprintln!(
        "8 rolling boats with attitude: pooled rms of error / sigma down {down:.3}, north and \
         east {horizontal:.3}"
    );
    assert!((0.8..1.2).contains(&down), "down pooled rms z {down}");
    assert!(
        (0.7..1.3).contains(&horizontal),
        "north and east pooled rms z {horizontal}"
    );
}

/// Replica `seed` of `plan` (its noise drawn again) written under `dir`: the plan, the
/// dataset and its output folder.
fn replica(
    dir: &Path,
    plan: fixtures::survey_lines::LinesPlan,
    seed: u64,
) -> (fixtures::survey_lines::LinesPlan, PathBuf, PathBuf) {
    let plan = fixtures::survey_lines::LinesPlan { seed, ..plan };
    let dataset = dir.join(format!("replica-{seed}"));
    fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("replica");
    (plan, dataset, dir.join(format!("out-{seed}")))
}

/// The sigma over replicas: the boat survey with other noise (8 seeds: the positions' and the
/// triad's), reduced; the pooled rms of error / sigma over the epochs not at an edge.
#[test]
fn monte_carlo_of_the_boat_sigmas() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (mut sum_z2, mut sum_e2, mut n, mut crossing_z2) = (0.0, 0.0, 0.0, 0.0);
    for seed in 1..=8u64 {
        let (plan, dataset, out) = replica(dir.path(), fixtures::survey_lines::plan(), seed);
        let r = args(&dataset).run(&out).expect("gravity");
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        eprintln!("seed {seed}: rms error {rms:.3} mGal, rms z {z:.3}");
        sum_z2 += z * z;
        sum_e2 += rms * rms;
        n += 1.0;
        crossing_z2 += crossover_z(&plan, &dataset, &out, &r).powi(2);
    }
    let (z, rms) = ((sum_z2 / n).sqrt(), (sum_e2 / n).sqrt());
    let crossing_z = (crossing_z2 / n).sqrt();
    eprintln!(
        "8 boat replicas: rms error {rms:.3} mGal, pooled rms of error / sigma {z:.3}; \
         crossovers' rms of error / sigma {crossing_z:.3}"
    );
    assert!((0.85..1.15).contains(&z), "pooled rms z {z}");
    // The sum of eight z^2 is chi-square with 8 degrees of freedom when the sigmas are
    // honest: 0.6 % below the lower bound, 0.5 % above the upper.
    assert!(
        (0.42..1.65).contains(&crossing_z),
        "crossovers' rms z {crossing_z}"
    );
}

/// A thermal-chamber calibration of [`fixtures::triad::thermal_chamber`]'s triad (order 2
/// with temperature terms, 42 positions), computed once.
fn thermal_calibration() -> &'static Path {
    static CAL: OnceLock<PathBuf> = OnceLock::new();
    CAL.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tempdir").keep();
        let dataset = dir.join("triad-thermal");
        let plan = fixtures::triad::thermal_chamber(42, 2);
        fixtures::triad::write_multipos(&plan, &dataset).expect("thermal chamber");
        let out = dir.join("out");
        ingest::run(&dataset, &out).expect("ingest");
        align::run(&dataset, &out).expect("align");
        adjust::run(&dataset, &out).expect("adjust");
        out.join("adjust").join("calibration.json")
    })
}

/// The survey's triad warms and cools by 3 degC over an hour, which the ties' linear drift
/// cannot take up: with the thermal chamber's calibration, applied at the logged
/// temperatures, the disturbance is within its sigmas; with triad-multipos's, which has no
/// temperature terms, the wander shows tens of sigmas over.
#[test]
fn a_thermal_triad_is_applied_at_its_temperatures() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("thermal");
    let plan = fixtures::survey_lines::thermal_plan();
    fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("thermal survey");
    let out = dir.path().join("out");
    let mut thermal = args(&dataset);
    thermal.apply.calibration = thermal_calibration().to_path_buf();
    let r = thermal.run(&out).expect("gravity");
    print_summary(&r, &mut std::io::stderr());
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    eprintln!(
        "thermal triad, its calibration: rms error {rms:.3} mGal; rms of error / sigma {z:.3}"
    );
    assert!((0.8..1.2).contains(&z), "rms z {z}");
    let s = &r.sessions[0];
    assert_eq!(
        s.epochs_used + s.dropped.values().sum::<u64>(),
        s.epochs_read
    );
    let cold = dir.path().join("out-cold");
    let r = args(&dataset).run(&cold).expect("gravity");
    let (rms_cold, z_cold) = scores(&dataset, &cold, r.filter.filter_s);
    eprintln!(
        "thermal triad, triad-multipos's calibration: rms error {rms_cold:.3} mGal; rms of \
         error / sigma {z_cold:.3}"
    );
    assert!(
        z_cold > 5.0 && rms_cold > 5.0 * rms,
        "{rms_cold} mGal, z {z_cold}"
    );
}

/// The paper's own use of one accelerometer: acc3 calibrated alone on a tilt table near the
/// vertical (the axis model a = b + k Ng, F from -g to -0.77 g), then carried on the boat
/// levelled with its axis vertical and reduced as the vertical axis pointing up (f_D = F):
/// eight boat replicas with other noise, pooled. The swell takes F past -g, where no tilt
/// table reaches: those epochs are flagged as outside the calibration and kept. Naming the
/// wrong axis (acc1, horizontal) is refused.
#[test]
fn a_vertical_axis_calibrated_on_a_tilt_table_is_recovered_within_its_sigmas() {
    let dir = tempfile::tempdir().expect("tempdir");
    let table = dir.path().join("vertical-axis");
    fixtures::write::write_dataset(&fixtures::catalog::vertical_axis(), &table)
        .expect("tilt table");
    let cal = dir.path().join("cal");
    ingest::run(&table, &cal).expect("ingest");
    align::run(&table, &cal).expect("align");
    adjust::run(&table, &cal).expect("adjust");
    let axis = |dataset: &Path, id: &str| GravityArgs {
        apply: adjust::survey::apply::stream::ApplyArgs {
            dataset: dataset.to_path_buf(),
            calibration: cal.join("adjust").join("calibration.json"),
            model: Some("linear".to_owned()),
            session: Some("s1".to_owned()),
            out: None,
        },
        accelerometer: Some(id.to_owned()),
        block_epochs: None,
        skip_bad_lines: false,
    };
    let (mut sum_z2, mut sum_e2, mut n) = (0.0, 0.0, 0.0);
    for seed in 1..=8u64 {
        let (_, dataset, out) = replica(dir.path(), fixtures::survey_lines::vertical_plan(), seed);
        let r = axis(&dataset, "acc3").run(&out).expect("gravity");
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        let s = &r.sessions[0];
        let outside = s.flagged.get("outside_calibration").copied().unwrap_or(0);
        eprintln!(
            "vertical axis, seed {seed}: rms error {rms:.3} mGal, rms z {z:.3}; {outside} of {} \
             epochs outside the calibration",
            s.epochs_used
        );
        assert!(outside > 0, "{:?}", s.flagged);
        sum_z2 += z * z;
        sum_e2 += rms * rms;
        n += 1.0;
        if seed == 1 {
            // The horizontal axis taken as the vertical reads no gravity: its level is
            // refused (it was written, a million mGal off).
            let wrong = dir.path().join("out-wrong");
            let e = axis(&dataset, "acc1")
                .run(&wrong)
                .expect_err("refused")
                .to_string();
            assert!(e.contains("the ties' level") && e.contains("beyond"), "{e}");
        }
    }
    let (z, rms) = ((sum_z2 / n).sqrt(), (sum_e2 / n).sqrt());
    eprintln!(
        "8 replicas of a vertical axis on the boat: rms error {rms:.3} mGal, pooled rms of \
         error / sigma {z:.3}"
    );
    assert!((0.85..1.15).contains(&z), "pooled rms z {z}");
}

/// survey-lines moved east by 174.775 deg, so that its lines cross the antimeridian
/// (179.97 to -179.98): every longitude difference is taken the short way round. Before,
/// the step across it was 360 deg: the stretch was tied 464 759 mGal off and its crossover
/// differed by 3.2e9 mGal, exit 0. Now it reduces as the survey at home does, and so does
/// the same move written in 0 to 360 deg; the positions' east noise no longer takes the
/// latitude's in proportion to the longitude (2.4 cm east at 180 deg from 1 cm north).
#[test]
fn a_survey_across_the_antimeridian_reduces_as_at_home() {
    let (_home_dir, home, home_out) = edited(|m| m);
    let at_home = args(&home).run(&home_out).expect("at home");
    let home_rows = rows(&home_out);
    for (label, wrap) in [("-180 to 180", true), ("0 to 360", false)] {
        let (_dir, dataset, out) = edited(|m| m);
        let pos = dataset.join("raw/lines.pos");
        let text = std::fs::read_to_string(&pos).expect("pos");
        let moved: String = text
            .lines()
            .map(|l| {
                if l.starts_with('%') || l.trim().is_empty() {
                    return format!("{l}\n");
                }
                let mut f: Vec<String> = l.split_whitespace().map(str::to_owned).collect();
                let mut lon = f[3].parse::<f64>().expect("longitude") + 174.775;
                if wrap && lon >= 180.0 {
                    lon -= 360.0;
                }
                f[3] = format!("{lon:.9}");
                format!("{}\n", f.join("  "))
            })
            .collect();
        let past = if wrap { "  -179.9" } else { "  180.0" };
        assert!(moved.contains(past), "{label}: the track crosses");
        std::fs::write(&pos, moved).expect("write");
        let across = args(&dataset).run(&out).expect(label);
        let r = rows(&out);
        assert_eq!(r.len(), home_rows.len(), "{label}");
        let worst = r
            .iter()
            .zip(&home_rows)
            .map(|(a, b)| {
                (a.filtered - b.filtered)
                    .abs()
                    .max((a.sigma - b.sigma).abs())
            })
            .fold(0.0, f64::max);
        assert!(worst < 0.005, "{label}: differs from home by {worst} mGal");
        let (s, h) = (&across.sessions[0], &at_home.sessions[0]);
        for k in 0..3 {
            assert!(
                (s.position_noise_m[k] - h.position_noise_m[k]).abs() < 2e-4,
                "{label}: {:?} {:?}",
                s.position_noise_m,
                h.position_noise_m
            );
        }
        assert_eq!(across.crossovers.len(), at_home.crossovers.len(), "{label}");
        for (c, d) in across.crossovers.iter().zip(&at_home.crossovers) {
            assert!(
                (c.difference_mgal - d.difference_mgal).abs() < 0.005,
                "{label}: {c:?} {d:?}"
            );
        }
    }
    // East is the noise alone at home too: 1 cm simulated.
    let east = at_home.sessions[0].position_noise_m[1];
    assert!((east - 0.01).abs() < 5e-4, "{east}");
}

/// A column as doubles: a number as its value, a name (dictionary) as its length, null as
/// NaN.
// One `as` for every integer type the macro meets, i64 among them (no `From`).
#[allow(clippy::cast_lossless)]
fn as_doubles(c: &dyn arrow_array::Array) -> Vec<f64> {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Float64Type, Int64Type, UInt8Type, UInt16Type, UInt32Type};
    use arrow_schema::DataType;
    macro_rules! numbers {
        ($t:ty) => {
            c.as_primitive::<$t>()
                .iter()
                .map(|v| v.map_or(f64::NAN, |v| v as f64))
                .collect()
        };
    }
    match c.data_type() {
        DataType::Float64 => numbers!(Float64Type),
        DataType::Int64 => numbers!(Int64Type),
        DataType::UInt32 => numbers!(UInt32Type),
        DataType::UInt16 => numbers!(UInt16Type),
        DataType::UInt8 => numbers!(UInt8Type),
        DataType::Dictionary(_, _) => {
            let d = c.as_any_dictionary();
            let names = d.values().as_string::<i32>();
            d.normalized_keys()
                .into_iter()
                .enumerate()
                .map(|(i, k)| {
                    if c.is_null(i) {
                        f64::NAN
                    } else {
                        names.value(k).len() as f64
                    }
                })
                .collect()
        }
        other => panic!("gravity.parquet holds a column of {other}"),
    }
}

/// Every column of gravity.parquet in `out`, as doubles (null as NaN), by name.
fn all_columns(out: &Path) -> Vec<(String, Vec<f64>)> {
    use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
    let f = std::fs::File::open(out.join("gravity").join(gravity::FILE)).expect("table");
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .expect("parquet")
        .build()
        .expect("reader");
    let mut columns: Vec<(String, Vec<f64>)> = Vec::new();
    for batch in reader {
        let batch = batch.expect("batch");
        for (i, field) in batch.schema().fields().iter().enumerate() {
            let values = as_doubles(batch.column(i).as_ref());
            match columns.iter_mut().find(|(n, _)| n == field.name()) {
                Some((_, v)) => v.extend(values),
                None => columns.push((field.name().clone(), values)),
            }
        }
    }
    columns
}

/// A stretch reduced a block at a time is the stretch reduced whole (docs/model.md 7): the
/// rolling boat with attitude (down, north and east, tied at both ends, its lines
/// crossing), in blocks of 1500 epochs (the filter reaches 6000 either side) against one
/// block: every column within 1e-6 of its unit (mGal, m, m/s; north and east 1e-4 mGal),
/// nulls and flags the same, the drift and the crossovers the same. Memory then holds a
/// block, not the survey.
#[test]
fn a_stretch_in_blocks_is_the_stretch_whole() {
    let dir = tempfile::tempdir().expect("dir");
    let (dataset, _, _) = rolling_boat(dir.path());
    let whole = args(&dataset)
        .run(&dir.path().join("whole"))
        .expect("whole");
    let mut blocked = args(&dataset);
    blocked.block_epochs = Some(1500);
    let parts = blocked.run(&dir.path().join("blocked")).expect("blocks");
    assert_eq!(whole.rows_written, parts.rows_written);
    let stretches = |r: &GravityReport| -> Vec<(u64, f64, f64)> {
        r.sessions
            .iter()
            .flat_map(|s| &s.stretches)
            .map(|s| {
                let d = s.drift.as_ref().expect("tied at both ends");
                (s.epochs, d.offset_mgal, d.rate_mgal_per_h)
            })
            .collect()
    };
    let (a, b) = (stretches(&whole), stretches(&parts));
    assert_eq!(a.len(), b.len());
    assert!(a.iter().any(|s| s.0 > 3 * 1500), "{a:?}: one block only");
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0, y.0);
        assert!(
            (x.1 - y.1).abs() < 1e-6 && (x.2 - y.2).abs() < 1e-6,
            "{x:?} {y:?}"
        );
    }
    assert!(!whole.crossovers.is_empty());
    assert_eq!(whole.crossovers.len(), parts.crossovers.len());
    for (x, y) in whole.crossovers.iter().zip(&parts.crossovers) {
        assert!(
            (x.difference_mgal - y.difference_mgal).abs() < 1e-6,
            "{x:?} {y:?}"
        );
        assert!((x.sigma_mgal - y.sigma_mgal).abs() < 1e-6, "{x:?} {y:?}");
    }
    let (a, b) = (
        all_columns(&dir.path().join("whole")),
        all_columns(&dir.path().join("blocked")),
    );
    assert_eq!(a.len(), b.len());
    let mut worst = (String::new(), 0.0_f64);
    for ((name, x), (other, y)) in a.iter().zip(&b) {
        assert_eq!(name, other);
        assert_eq!(x.len(), y.len(), "{name}");
        let mut column = (String::new(), 0.0_f64);
        for (k, (u, v)) in x.iter().zip(y).enumerate() {
            assert_eq!(u.is_nan(), v.is_nan(), "{name} row {k}: {u} {v}");
            let d = if u.is_nan() { 0.0 } else { (u - v).abs() };
            if d > column.1 {
                column = (format!("{name} row {k}: {u} {v}"), d);
            }
        }
        println!("{name}: {:.3e}", column.1);
        // North and east are second differences of northing and easting summed from the
        // block's first epoch, not the stretch's: their rounding differs (east before the
        // filter by 5e-6 mGal here).
        let horizontal = name.starts_with("north") || name.starts_with("east");
        let tolerance = if horizontal { 1e-4 } else { 1e-6 };
        assert!(column.1 < tolerance, "{}", column.0);
        if column.1 > worst.1 {
            worst = column;
        }
    }
    println!("largest difference: {} ({:.3e})", worst.0, worst.1);
}

/// The rms of error / sigma of down, north and east over the epochs not at an edge, of
/// replica `seed` of `plan` reduced under `dir`, and the median attitude part of north's
/// and east's sigmas, mGal.
fn component_scores(
    dir: &Path,
    plan: fixtures::survey_lines::LinesPlan,
    seed: u64,
) -> ([f64; 3], [f64; 2]) {
    let (_, dataset, out) = replica(dir, plan, seed);
    let r = args(&dataset).run(&out).expect("gravity");
    let (_, down) = scores(&dataset, &out, r.filter.filter_s);
    let [north, east] = horizontal_scores(&dataset, &out, r.filter.filter_s);
    std::fs::remove_dir_all(&dataset).expect("replica removed");
    std::fs::remove_dir_all(&out).expect("output removed");
    ([down, north[1], east[1]], [north[3], east[3]])
}

/// `plan` with its attitude file's errors of `errors` (white: 0.1 mrad of roll and pitch, 1
/// mrad of heading, per 10 Hz sample).
fn with_attitude_errors(
    plan: fixtures::survey_lines::LinesPlan,
    errors: fixtures::survey_lines::SimErrors,
) -> fixtures::survey_lines::LinesPlan {
    let mut p = plan;
    if let Some(a) = p.attitude.as_mut() {
        a.errors = errors;
    }
    p
}

/// White attitude errors (0.1 mrad per 10 Hz sample, declared white): the filter averages
/// them down, and the sigma of north and east says so (one survey holds about 24 filter
/// periods of independent errors, so one replica can be checked).
#[test]
fn white_attitude_errors_are_averaged_by_the_filter() {
    use fixtures::survey_lines::{SimErrors, attitude_plan};
    let dir = tempfile::tempdir().expect("tempdir");
    let ([down, north, east], [att_north, att_east]) = component_scores(
        dir.path(),
        with_attitude_errors(attitude_plan(), SimErrors::White),
        1,
    );
    eprintln!(
        "white attitude errors: rms z down {down:.3}, north {north:.3}, east {east:.3}; the \
         attitude's part of the sigma north {att_north:.2}, east {att_east:.2} mGal (median)"
    );
    // Held over the filter, 0.1 mrad is 98 mGal north; white, the filter averages it down.
    assert!(
        att_north < 10.0 && att_east < 10.0,
        "{att_north} {att_east}"
    );
    for (name, z) in [("down", down), ("north", north), ("east", east)] {
        assert!((0.7..1.3).contains(&z), "{name}: rms z {z}");
    }
}

/// The boat and the aircraft with attitude, each error model of the attitude in turn,
/// declared as simulated (white, correlated over 10 minutes, a bias): the rms of error /
/// sigma of down, north and east pooled over 50 surveys each.
#[cfg(gravcal_monte_carlo)]
#[test]
fn monte_carlo_of_each_attitude_error_model() {
    use fixtures::survey_lines::{SimErrors, aircraft_attitude_plan, attitude_plan};
    let dir = tempfile::tempdir().expect("tempdir");
    let surveys = surveys();
    let mut failures = Vec::new();
    for (vehicle, plan) in [
        ("boat", attitude_plan()),
        ("aircraft", aircraft_attitude_plan()),
    ] {
        for errors in [
            SimErrors::White,
            SimErrors::Correlated,
            SimErrors::Systematic,
        ] {
            let plan = with_attitude_errors(plan.clone(), errors);
            let mut z2 = [0.0; 3];
            for seed in 1..=surveys {
                let z = component_scores(dir.path(), plan.clone(), seed).0;
                for c in 0..3 {
                    z2[c] += z[c] * z[c] / surveys as f64;
                }
            }
            let z = z2.map(f64::sqrt);
            eprintln!(
                "{vehicle}, {errors:?} attitude errors, {surveys} surveys: pooled rms z down \
                 {:.3}, north {:.3}, east {:.3}",
                z[0], z[1], z[2]
            );
            for (name, z) in ["down", "north", "east"].into_iter().zip(z) {
                if !(0.8..1.2).contains(&z) {
                    failures.push(format!("{vehicle} {errors:?} {name}: {z:.3}"));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// Surveys per Monte-Carlo: `GRAVCAL_SURVEYS`, or 50.
#[cfg(gravcal_monte_carlo)]
fn surveys() -> u64 {
    std::env::var("GRAVCAL_SURVEYS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(50)
}

/// The levelled boat with its positions' errors correlated (a Gauss-Markov of 1 cm
/// horizontal and 2 cm vertical over 30 s, declared so): the rms of error / sigma of down
/// pooled over 50 surveys; and the boat at 250 Hz with its heave, whose noise part is what
/// the noise itself gives (the triad's 9 counts, not the heave).
#[cfg(gravcal_monte_carlo)]
#[test]
fn monte_carlo_of_correlated_positions() {
    let dir = tempfile::tempdir().expect("tempdir");
    let surveys = surveys();
    let plan = fixtures::survey_lines::LinesPlan {
        position_correlation_s: Some(30.0),
        ..fixtures::survey_lines::plan()
    };
    let mut z2 = 0.0;
    for seed in 1..=surveys {
        let (_, dataset, out) = replica(dir.path(), plan.clone(), seed);
        let r = args(&dataset).run(&out).expect("gravity");
        let (_, z) = scores(&dataset, &out, r.filter.filter_s);
        z2 += z * z / surveys as f64;
        std::fs::remove_dir_all(&dataset).expect("replica removed");
        std::fs::remove_dir_all(&out).expect("output removed");
    }
    let z = z2.sqrt();
    eprintln!("boat, positions correlated over 30 s, {surveys} surveys: pooled rms z down {z:.3}");
    assert!((0.8..1.2).contains(&z), "pooled rms z {z}");
}

/// The median of column `name` of gravity.parquet over the epochs not at an edge.
fn median_column(out: &Path, name: &str) -> f64 {
    let path = out.join("gravity").join(gravity::FILE);
    let mut v = Vec::new();
    ingest::contract::tables::float_batches(&path, &[name], gravity::FLAGS, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            if b.flags[i] & gravity::EDGE == 0 {
                v.push(b.values[0].value(i));
            }
        }
        Ok(())
    })
    .expect("gravity.parquet");
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// A 1 Hz marine platform record under a 10 s swell of about 600 mGal sd: the noise part of
/// the sigma is what the same record without swell gives (the swell lies below the band the
/// noise is measured in), and the error is within its sigma.
#[test]
fn a_swell_at_1_hz_does_not_pass_for_noise() {
    use fixtures::survey_lines::platform_plan;
    let dir = tempfile::tempdir().expect("tempdir");
    let mut noise = Vec::new();
    for swell in [false, true] {
        let dataset = dir.path().join(format!("platform-{swell}"));
        fixtures::survey_lines::write_survey_lines(&platform_plan(swell), &dataset)
            .expect("survey");
        let out = dir.path().join(format!("out-{swell}"));
        let r = args(&dataset).run(&out).expect("gravity");
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        let n = median_column(&out, "sigma_noise_mgal");
        eprintln!(
            "1 Hz platform, swell {swell}: rms error {rms:.3} mGal, rms z {z:.3}, noise part \
             {n:.4} mGal, sigma {:.4}",
            median_column(&out, "sigma_down_mgal")
        );
        assert!((0.8..1.2).contains(&z), "swell {swell}: rms z {z}");
        noise.push(n);
    }
    assert!(
        noise[1] < 1.1 * noise[0],
        "the noise part with a swell {} against {} without",
        noise[1],
        noise[0]
    );
}

/// The 1 Hz platform record as a meter that filters its own output writes it (each axis
/// smoothed four times by [1/4, 1/2, 1/4], as shipgrav's real DGS record falls across the
/// upper band): the stage refuses to guess its noise and names the key; with the noise
/// declared, the sigmas carry it (twice the declared, twice the noise part) and
/// gravity.json says where it came from and why the record gave none.
#[test]
fn a_record_its_meter_filtered_needs_its_noise_declared() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("filtered");
    let plan = fixtures::survey_lines::platform_plan(true);
    fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
    let stream = dataset.join("raw/lines.txt");
    let text = std::fs::read_to_string(&stream).expect("stream");
    let (head, rest): (Vec<&str>, Vec<&str>) = text
        .lines()
        .partition(|l| l.starts_with('#') || l.starts_with('t'));
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); 4];
    for l in &rest {
        for (c, v) in l.split(',').enumerate() {
            cols[c].push(v.parse().expect("value"));
        }
    }
    for col in &mut cols[1..] {
        for _ in 0..4 {
            let x = col.clone();
            for i in 1..x.len() - 1 {
                col[i] = 0.25 * x[i - 1] + 0.5 * x[i] + 0.25 * x[i + 1];
            }
        }
    }
    let mut out_text = head.join("\n") + "\n";
    for i in 0..cols[0].len() {
        out_text += &format!(
            "{:.3},{:.1},{:.1},{:.1}\n",
            cols[0][i], cols[1][i], cols[2][i], cols[3][i]
        );
    }
    std::fs::write(&stream, out_text).expect("filtered stream");
    let e = args(&dataset)
        .run(&dir.path().join("refused"))
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("session lines")
            && e.contains("survey.sample_noise_mgal")
            && e.contains("no two bands"),
        "{e}"
    );
    let manifest = dataset.join("dataset.toml");
    let toml = std::fs::read_to_string(&manifest).expect("manifest");
    let mut noise = Vec::new();
    for declared in [1.0, 2.0] {
        let with = toml.replace(
            "[survey]\n",
            &format!("[survey]\nsample_noise_mgal = {declared}\n"),
        );
        assert_ne!(with, toml);
        std::fs::write(&manifest, with).expect("manifest");
        let out = dir.path().join(format!("declared-{declared}"));
        let r = args(&dataset).run(&out).expect("gravity");
        let s = &r.sessions[0];
        assert!(
            (s.sample_noise_mgal - declared).abs() < 1e-12,
            "{}",
            s.sample_noise_mgal
        );
        assert!(
            s.sample_noise_from.starts_with("declared") && s.sample_noise_from.contains("no floor"),
            "{}",
            s.sample_noise_from
        );
        noise.push(median_column(&out, "sigma_noise_mgal"));
    }
    assert!((noise[1] / noise[0] - 2.0).abs() < 1e-6, "{noise:?}");
}

/// A strapdown record at 250 Hz under the boat's heave (0.15 m at 8 s: about 6500 mGal sd
/// of vertical acceleration) against the same record without it: the noise part is the
/// triad's noise either way, and the error within its sigma.
#[test]
fn a_heave_at_250_hz_does_not_pass_for_noise() {
    let dir = tempfile::tempdir().expect("tempdir");
    let mut noise = Vec::new();
    for heave in [false, true] {
        let mut plan = fixtures::survey_lines::bench_plan(0.5);
        if !heave {
            plan.swell.clear();
        }
        let dataset = dir.path().join(format!("strapdown-{heave}"));
        fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
        let out = dir.path().join(format!("out-{heave}"));
        let r = args(&dataset).run(&out).expect("gravity");
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        let n = median_column(&out, "sigma_noise_mgal");
        eprintln!(
            "250 Hz strapdown, heave {heave}: rms error {rms:.3} mGal, rms z {z:.3}, noise \
             part {n:.4} mGal"
        );
        assert!((0.7..1.3).contains(&z), "heave {heave}: rms z {z}");
        noise.push(n);
    }
    assert!(
        (noise[1] / noise[0] - 1.0).abs() < 0.05,
        "the noise part with heave {} against {} without",
        noise[1],
        noise[0]
    );
}

/// `--block-epochs` shorter than one filter period of epochs is refused naming the option
/// (0 was taken as 1, and 1 reduced each epoch with 24 000 epochs of margin: 446 s).
#[test]
fn a_block_shorter_than_the_filter_is_refused() {
    let dataset = fixtures::dataset_dir(fixtures::survey_lines::SURVEY_LINES);
    let dir = tempfile::tempdir().expect("tempdir");
    for block in [0, 1, 999] {
        let mut a = args(&dataset);
        a.block_epochs = Some(block);
        let e = a.run(dir.path()).expect_err("refused").to_string();
        assert!(
            e.contains(&format!("--block-epochs {block}"))
                && e.contains("at least 1000")
                && !e.contains("  "),
            "{e}"
        );
    }
}

/// survey-lines with its trajectory's lines `lines` (0-based among the solution lines)
/// edited by `edit` (the fields of the line), reduced: the report and the output folder.
fn with_positions_edited(
    dir: &Path,
    lines: std::ops::Range<usize>,
    edit: impl Fn(&mut Vec<String>),
) -> (
    PathBuf,
    PathBuf,
    Result<GravityReport, adjust::survey::gravity::GravityError>,
) {
    let dataset = dir.join("lines");
    fixtures::copy_dataset(fixtures::survey_lines::SURVEY_LINES, &dataset, |m| m).expect("copy");
    std::fs::copy(
        fixtures::dataset_dir(fixtures::survey_lines::SURVEY_LINES).join("truth.csv"),
        dataset.join("truth.csv"),
    )
    .expect("truth.csv");
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    let mut solution = 0;
    let mut out = String::new();
    for l in text.lines() {
        if l.starts_with('%') {
            out += l;
        } else {
            if lines.contains(&solution) {
                let mut f: Vec<String> = l.split_whitespace().map(str::to_owned).collect();
                edit(&mut f);
                out += &f.join("   ");
            } else {
                out += l;
            }
            solution += 1;
        }
        out.push('\n');
    }
    std::fs::write(&pos, out).expect("pos");
    let out = dir.join("out");
    let r = args(&dataset).run(&out);
    (dataset, out, r)
}

/// A position outlier among the trajectory's epochs (issue 50): one epoch 0.45 deg (50 km)
/// north with an sd of 1 cm, or 50 m high, was used as it was (11 337 epochs wrong by more
/// than 5 sigma, a crossover of +126 mGal). Now it is replaced by its neighbours'
/// prediction and flagged `position_outlier`, and the survey is within its sigmas; three in
/// a row replace two and drop the third, which cuts the track.
#[test]
fn a_position_outlier_is_replaced_and_counted() {
    for (what, field, by) in [("50 km north", 2usize, 0.45), ("50 m high", 4, 50.0)] {
        let dir = tempfile::tempdir().expect("tempdir");
        let (dataset, out, r) = with_positions_edited(dir.path(), 12_000..12_001, |f| {
            let v: f64 = f[field].parse().expect("number");
            f[field] = format!("{:.9}", v + by);
        });
        let r = r.unwrap_or_else(|e| panic!("{what}: {e}"));
        let s = &r.sessions[0];
        assert_eq!(
            s.flagged.get("position_outlier"),
            Some(&1),
            "{what}: {:?}",
            s.flagged
        );
        assert_eq!(s.stretches.len(), 1, "{what}");
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        eprintln!("{what}: rms error {rms:.3} mGal, rms z {z:.3}");
        assert!(z < 1.3 && rms < 0.3, "{what}: rms {rms} mGal, z {z}");
    }
    let dir = tempfile::tempdir().expect("tempdir");
    let (_, _, r) = with_positions_edited(dir.path(), 12_000..12_003, |f| {
        let v: f64 = f[4].parse().expect("number");
        f[4] = format!("{:.4}", v + 50.0);
    });
    let r = r.expect("three in a row");
    let s = &r.sessions[0];
    assert_eq!(
        s.flagged.get("position_outlier"),
        Some(&2),
        "{:?}",
        s.flagged
    );
    assert_eq!(
        s.dropped.get("position_outlier"),
        Some(&1),
        "{:?}",
        s.dropped
    );
    assert_eq!(s.stretches.len(), 2, "the dropped epoch cuts the track");
}

/// The body tide in the moving reduction (issue 48): survey-lines' world has the tide in
/// its specific force; the stage removes it at each epoch with align's model, at the
/// epoch's place and UTC time (checked here against the model called epoch by epoch, to
/// 1e-5 mGal: the stage computes it a minute apart and interpolates, 6.8e-7 mGal off at
/// the track's turns; and not 0), and writes it as `tide_mgal`. Untied (the ties' level would take up the tide's
/// mean), with `earth_tide = false` the column is 0 and the filtered disturbance is larger
/// by the tide, to the filter's smoothing of it.
#[test]
fn the_body_tide_is_removed_and_written() {
    let untied = |m: String| m[..m.find("[[survey.tie]]").expect("ties")].to_owned();
    let (_dir, dataset, out) = edited(untied);
    reduce(&dataset, &out);
    let with = all_columns(&out);
    let (_dir2, dataset2, out2) =
        edited(|m| untied(m).replace("[survey]\n", "[survey]\nearth_tide = false\n"));
    reduce(&dataset2, &out2);
    let without = all_columns(&out2);
    let col = |c: &[(String, Vec<f64>)], name: &str| {
        c.iter().find(|(n, _)| n == name).expect(name).1.clone()
    };
    let (t, lat, lon, h) = (
        col(&with, "time_gps_ns"),
        col(&with, "latitude_deg"),
        col(&with, "longitude_deg"),
        col(&with, "height_m"),
    );
    let tide = col(&with, "tide_mgal");
    let worst = (0..t.len())
        .map(|k| {
            let site = align::tide::Site {
                latitude_deg: lat[k],
                longitude_deg: lon[k],
                height_m: h[k],
            };
            let utc = align::tide::utc_seconds_of_gps(t[k] as i64);
            (align::tide::body_tide_mgal(site, utc) - tide[k]).abs()
        })
        .fold(0.0, f64::max);
    let range = tide
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &x| (a.min(x), b.max(x)));
    eprintln!(
        "tide {:.4} to {:.4} mGal; worst against the model {worst:.2e}",
        range.0, range.1
    );
    assert!(worst < 1e-5 && range.1 - range.0 > 1e-3 && range.0.abs().max(range.1.abs()) > 0.01);
    assert!(col(&without, "tide_mgal").iter().all(|&x| x == 0.0));
    let (a, b) = (
        col(&with, "down_filtered_mgal"),
        col(&without, "down_filtered_mgal"),
    );
    let worst = (0..a.len())
        .filter(|&k| a[k].is_finite())
        .map(|k| (b[k] - a[k] - tide[k]).abs())
        .fold(0.0, f64::max);
    eprintln!("without the tide, filtered less the tide: worst {worst:.2e} mGal");
    assert!(worst < 2e-3, "{worst} mGal");
}

/// Dock ties at a cruise's two ends level every stretch between them across three gaps in
/// the navigation (issue 48; `tie_level = "session"`, the default): each of the four
/// stretches carries the one drift of both ties, and the survey is within its sigmas. A
/// third tie whose still window falls in a gap is used by no stretch, and named.
#[test]
fn dock_ties_level_every_stretch_across_the_gaps() {
    let (_dir, dataset, out) = edited(|m| {
        m + "\n[[survey.tie]]\ntime = \"2026-06-10T07:14:20Z\"\nduration_s = 60\ng_mgal = 980444.8\n"
    });
    let pos = dataset.join("raw/lines.pos");
    let text = std::fs::read_to_string(&pos).expect("pos");
    let gaps = [8000..9200, 14000..15000, 18000..19000];
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(k, _)| !gaps.iter().any(|g| g.contains(k)))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(&pos, kept.join("\n") + "\n").expect("write");
    let r = reduce(&dataset, &out);
    let s = &r.sessions[0];
    assert_eq!((s.gaps, s.stretches.len()), (3, 4), "{:?}", s.stretches);
    assert!(
        s.stretches
            .iter()
            .all(|st| st.drift.as_ref().is_some_and(|d| d.ties == 2)),
        "{:?}",
        s.stretches
    );
    let unused: Vec<&str> = r
        .ties
        .iter()
        .filter(|t| t.used_in.is_none())
        .map(|t| t.time.as_str())
        .collect();
    assert_eq!(unused, ["2026-06-10T07:14:20.000Z"]);
    let mut said = Vec::new();
    print_summary(&r, &mut said);
    let said = String::from_utf8(said).expect("utf-8");
    assert!(
        said.contains("the tie at 2026-06-10T07:14:20.000Z (980444.8 mGal) is not used"),
        "{said}"
    );
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    eprintln!("three gaps, dock ties: rms error {rms:.3} mGal, rms z {z:.2}");
    assert!(z < 1.5, "rms z {z}");
}

mod cross_coupling {
    //! Cross-coupling on simulated cruises with known coefficients (issue 48, docs/model.md 7
    //! "Cross-coupling"): `fixtures::meter` writes a DGS laptop file whose gravity holds the
    //! monitors' coupling; the gravity stage fits it (`cross_coupling = "fit"`) and corrects
    //! the anomaly. Over replicas, the coefficients' errors against their sigmas say which
    //! covariance is honest; the corrected, filtered anomaly is held to the truth within its
    //! sigma.

    use adjust::survey::gravity::stage::GravityArgs;
    use fixtures::meter::Cruise;
    use ingest::contract::gravity_ledger::GravityReport;
    use ingest::contract::tables::gravity;
    use std::path::Path;

    /// A cruise reduced: the report, and per epoch the filtered value and its sigma against
    /// the truth's disturbance (the truth filtered as the stage filters, as the stage's own
    /// convention: the edges without a value are left out).
    fn cruise(
        dir: &Path,
        cruise: Cruise,
        cross_coupling: &str,
    ) -> (GravityReport, Vec<(f64, f64, f64)>) {
        let dataset = dir.join("cruise");
        let truth =
            fixtures::meter::write_cruise(&dataset, cruise, cross_coupling).expect("cruise");
        let out = dir.join("out");
        let report = GravityArgs::new(&dataset, Path::new(adjust::survey::apply::stream::VENDOR))
            .run(&out)
            .expect("reduced");
        let (sections, pad, pivot) = (
            adjust::survey::gravity::filter::butterworth(
                adjust::survey::gravity::filter::ORDER,
                1.0 / report.filter.filter_s,
                1.0,
            )
            .expect("filter"),
            720,
            240,
        );
        let truth_filtered = adjust::survey::gravity::filter::filtfilt_pivoted(
            &sections,
            &truth.disturbance_mgal,
            pad,
            pivot,
        );
        let mut rows = Vec::new();
        let names = ["down_filtered_mgal", "sigma_down_mgal"];
        let path = out.join("gravity").join(gravity::FILE);
        let mut k = 0;
        ingest::contract::tables::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
            for i in 0..b.time_ns.len() {
                let (v, s) = (b.values[0].value(i), b.values[1].value(i));
                if v.is_finite() {
                    rows.push((v, s, truth_filtered[k]));
                }
                k += 1;
            }
            Ok(())
        })
        .expect("gravity.parquet");
        (report, rows)
    }

    /// The rms of the corrected, filtered anomaly's error against the truth once the untied
    /// level (the meter's stated offset; the simulated meter has no other) is taken out, and
    /// the rms of that error over its sigma.
    fn scores(rows: &[(f64, f64, f64)]) -> (f64, f64) {
        let n = rows.len() as f64;
        let mean = rows.iter().map(|(v, _, t)| v - t).sum::<f64>() / n;
        let rms = (rows
            .iter()
            .map(|(v, _, t)| (v - t - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let z = (rows
            .iter()
            .map(|(v, s, t)| ((v - t - mean) / s).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        (rms, z)
    }

    /// One cruise of two hours: each coefficient within 3 of its sigma of the truth, and the
    /// corrected anomaly's error a fraction of the uncorrected one's (the coupling is about 4
    /// mGal rms).
    #[test]
    fn a_cruise_with_known_cross_coupling_is_corrected() {
        let dir = tempfile::tempdir().expect("tempdir");
        let (report, rows) = cruise(dir.path(), Cruise::new(7200, 1), "fit");
        let c = report.sessions[0].cross_coupling.as_ref().expect("fitted");
        for i in 0..4 {
            let z = (c.coefficients[i] - fixtures::meter::COUPLING[i]) / c.sigma[i];
            eprintln!(
                "{}: {:.4e} +/- {:.2e} (OLS {:.2e}), truth {:.4e}: z {z:.2}",
                adjust::survey::gravity::coupling::MONITORS[i],
                c.coefficients[i],
                c.sigma[i],
                c.ols_sigma.expect("a fit's")[i],
                fixtures::meter::COUPLING[i]
            );
            assert!(z.abs() < 3.0, "{i}: z {z}");
        }
        let (rms, z) = scores(&rows);
        let dir = tempfile::tempdir().expect("tempdir");
        let (_, rows) = cruise(dir.path(), Cruise::new(7200, 1), "none");
        let (uncorrected, _) = scores(&rows);
        eprintln!(
            "corrected: rms error {rms:.3} mGal (rms z {z:.2}); uncorrected {uncorrected:.3} mGal"
        );
        assert!(rms < uncorrected / 3.0, "{rms} against {uncorrected} mGal");
    }

    /// A laptop file's positions written as a logger writes a GPS: a clock before each
    /// sentence, a ZDA first, GGA fixes at 1e-6 arc-minutes with an altitude of 0 and no geoid
    /// separation (so above sea level).
    fn nmea_of_laptop(laptop: &str) -> String {
        let checked = |body: String| {
            let sum = body.bytes().fold(0u8, |a, b| a ^ b);
            format!("${body}*{sum:02X}")
        };
        let minutes = |v: f64, digits: usize| {
            let d = v.abs().trunc();
            format!("{:0digits$}{:09.6}", d as u32, (v.abs() - d) * 60.0)
        };
        let mut nmea = checked("GPZDA,000000.00,01,03,2021,00,00".to_owned()) + "\n";
        for line in laptop.lines() {
            let f: Vec<&str> = line.split(',').collect();
            let (lat, lon): (f64, f64) = (f[14].parse().expect("lat"), f[15].parse().expect("lon"));
            let time = format!(
                "{}{}{:05.2}",
                f[22],
                f[23],
                f[24].parse::<f64>().expect("s")
            );
            let gga = format!(
                "GPGGA,{time},{},{},{},{},2,12,0.9,0.0,M,,M,,",
                minutes(lat, 2),
                if lat < 0.0 { "S" } else { "N" },
                minutes(lon, 3),
                if lon < 0.0 { "W" } else { "E" }
            );
            nmea += &format!(
                "NAV 2021/03/01 {}:{}:{} GPS {}\n",
                f[22],
                f[23],
                f[24],
                checked(gga)
            );
        }
        nmea
    }

    /// The cruise's manifest navigated by `raw/nav.nmea` ([`nmea_of_laptop`]) instead of its
    /// meter's own columns.
    fn navigated_by_nmea(manifest: &str) -> String {
        manifest
            .replace(
                "trajectory = \"raw/cruise.dat\"",
                "trajectory = \"raw/nav.nmea\"",
            )
            .replace(
                "trajectory_format = \"dgs-laptop\"",
                "trajectory_format = \"nmea\"",
            )
    }

    /// The filtered free-air anomaly of a reduction into `out`.
    fn filtered(out: &Path) -> Vec<f64> {
        use arrow_array::Array as _;
        let path = out.join("gravity").join(gravity::FILE);
        let mut v = Vec::new();
        let names = ["free_air_anomaly_filtered_mgal"];
        ingest::contract::tables::float_batches(&path, &names, gravity::FLAGS, 1 << 16, |b| {
            v.extend((0..b.time_ns.len()).map(|i| {
                assert!(!b.values[0].is_null(i), "formed");
                b.values[0].value(i)
            }));
            Ok(())
        })
        .expect("gravity.parquet");
        v
    }

    /// The rms of the differences of two reductions' series where both are finite, and how
    /// many there are.
    fn rms_apart(a: &[f64], b: &[f64]) -> (f64, usize) {
        assert_eq!(a.len(), b.len());
        let d: Vec<f64> = a
            .iter()
            .zip(b)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(x, y)| x - y)
            .collect();
        let rms = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
        (rms, d.len())
    }

    /// The cruise navigated by NMEA sentences (docs/formats.md 10.1) instead of the meter's own
    /// columns ([`nmea_of_laptop`]): the same filtered free-air anomaly to 0.01 mGal rms.
    #[test]
    fn a_cruise_navigated_by_nmea_reduces_as_by_the_meters_own_columns() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("cruise");
        fixtures::meter::write_cruise(&dataset, Cruise::new(3600, 3), "none").expect("cruise");
        let laptop = std::fs::read_to_string(dataset.join("raw/cruise.dat")).expect("dat");
        std::fs::write(dataset.join("raw/nav.nmea"), nmea_of_laptop(&laptop)).expect("nmea");
        let vendor = Path::new(adjust::survey::apply::stream::VENDOR);
        let own = dir.path().join("own");
        GravityArgs::new(&dataset, vendor)
            .run(&own)
            .expect("reduced");
        let manifest = std::fs::read_to_string(dataset.join("dataset.toml")).expect("toml");
        std::fs::write(dataset.join("dataset.toml"), navigated_by_nmea(&manifest)).expect("toml");
        let by_nmea = dir.path().join("nmea");
        let r = GravityArgs::new(&dataset, vendor)
            .run(&by_nmea)
            .expect("reduced");
        assert_eq!(r.sessions[0].epochs_used, 3600);
        assert!(
            r.inputs.iter().any(|i| i.path.ends_with("nav.nmea")),
            "{:?}",
            r.inputs
        );
        assert_eq!(
            r.sessions[0].quantities.heights,
            ingest::contract::survey::Heights::SeaLevel
        );
        let (rms, n) = rms_apart(&filtered(&own), &filtered(&by_nmea));
        eprintln!(
            "the cruise by NMEA against its meter's own navigation: rms {rms:.2e} mGal over {n} epochs"
        );
        assert!(n > 2000 && rms < 0.01, "rms {rms} over {n}");
    }

    /// A laptop line as the meter's raw serial output behind a logger's stamp (docs/formats.md
    /// 11.1): a DGS `$AT1M` record (gravity in counts of 0.01 mGal, the monitors in 1e-5
    /// units, the checksum) behind R/V Thompson's `MM/DD/YYYY,hh:mm:ss.sss,`, or a BGM-3's
    /// `04:CCCCCCC 00` (counts of 0.01 mGal) behind R/V Atlantis's `BGM YYYY/MM/DD hh:mm:ss BGM3`.
    fn serial_of_laptop(line: &str, k: usize, meter: &str) -> String {
        let f: Vec<&str> = line.split(',').collect();
        let counts = (f[1].trim().parse::<f64>().expect("rgrav") * 100.0).round() as i64;
        let (date, clock) = (
            format!("{}/{}/{}", f[20], f[21], f[19]),
            format!("{}:{}:{}", f[22], f[23], f[24]),
        );
        if meter == "bgm3" {
            return format!(
                "BGM {}/{}/{} {clock} BGM3 04:{counts:07} 00\n",
                f[19], f[20], f[21]
            );
        }
        let monitor =
            |i: usize| (f[i].trim().parse::<f64>().expect("monitor") * 1e5).round() as i64;
        // The raw record's order: VCC, VE, AL, AX.
        let v = [
            counts,
            0,
            0,
            0,
            0,
            0,
            0,
            monitor(11),
            monitor(10),
            monitor(12),
            monitor(13),
        ];
        let fields: Vec<String> = v.iter().map(ToString::to_string).collect();
        format!(
            "{date},{clock},$AT1M_3.61_{k},{},330,{},0.0,0.0,0.0,0.0,{k}\n",
            fields.join(","),
            v.iter().sum::<i64>()
        )
    }

    /// The cruise's manifest with its meter's samples from `raw/meter.raw`, written as
    /// `meter` ("dgs-raw" or "bgm3") writes them, in counts.
    fn serial_manifest(manifest: &str, meter: &str) -> String {
        manifest
            .replace("reading_unit = \"mGal\"", "reading_unit = \"count\"")
            .replace(
                "adc_csv = \"raw/cruise.dat\"",
                "adc_csv = \"raw/meter.raw\"",
            )
            .replace(
                "adc_format = \"dgs-laptop\"",
                &format!("adc_format = \"{meter}\""),
            )
    }

    /// The cruise logged as its meter's raw serial output instead of its laptop file, as DGS
    /// raw records (`adc_format = "dgs-raw"`, the monitors from the same file, cross-coupling
    /// fitted) and as BGM-3 counts (`"bgm3"`, no monitors, none), each navigated by NMEA, the
    /// maker's scale 0.01 mGal a count: every line read, the same filtered free-air anomaly as
    /// the laptop file's (the counts' and monitors' rounding is all that differs) to 0.01 mGal
    /// rms without cross-coupling, and with it fitted on the rounded monitors to 0.05 mGal, the
    /// coefficients within 0.05 of their sigmas; a damaged line refused, naming file, line and
    /// field (`checksum`, `counts`).
    #[test]
    fn a_cruise_logged_as_raw_serial_reduces_as_its_laptop_file() {
        let vendor = Path::new(adjust::survey::apply::stream::VENDOR);
        for (meter, coupling) in [("dgs-raw", "fit"), ("bgm3", "none")] {
            let dir = tempfile::tempdir().expect("tempdir");
            let dataset = dir.path().join("cruise");
            fixtures::meter::write_cruise(&dataset, Cruise::new(3600, 3), coupling)
                .expect("cruise");
            let own = dir.path().join("own");
            GravityArgs::new(&dataset, vendor)
                .run(&own)
                .expect("laptop");
            let laptop = std::fs::read_to_string(dataset.join("raw/cruise.dat")).expect("dat");
            std::fs::write(dataset.join("raw/nav.nmea"), nmea_of_laptop(&laptop)).expect("nmea");
            let serial: String = laptop
                .lines()
                .enumerate()
                .map(|(k, l)| serial_of_laptop(l, k, meter))
                .collect();
            std::fs::write(dataset.join("raw/meter.raw"), &serial).expect("raw");
            let manifest = navigated_by_nmea(&serial_manifest(
                &std::fs::read_to_string(dataset.join("dataset.toml")).expect("toml"),
                meter,
            ))
            .replace("scale = 1.0,", "scale = 0.01,");
            std::fs::write(dataset.join("dataset.toml"), &manifest).expect("toml");
            let by_serial = dir.path().join("serial");
            let r = GravityArgs::new(&dataset, vendor)
                .run(&by_serial)
                .expect(meter);
            assert_eq!(r.sessions[0].epochs_used, 3600, "{meter}");
            // The status words: the DGS records' 330 (bits 1, 3, 6, 8), the BGM-3's 00.
            let status = r.sessions[0]
                .meter_status
                .clone()
                .expect("a meter's status");
            assert_eq!(status.epochs, 3600, "{meter}");
            let bits: Vec<u8> = status.bits_set.keys().copied().collect();
            let want: &[u8] = if meter == "bgm3" { &[] } else { &[1, 3, 6, 8] };
            assert_eq!(bits, want, "{meter}");
            assert!(status.bits_set.values().all(|&n| n == 3600), "{meter}");
            assert_eq!(
                r.sessions[0].cross_coupling.is_some(),
                coupling == "fit",
                "{meter}"
            );
            let (rms, n) = rms_apart(&filtered(&own), &filtered(&by_serial));
            eprintln!(
                "{meter}: against the laptop file's reduction, rms {rms:.2e} mGal over {n} epochs"
            );
            // The fit on rounded monitors: its coefficients within 0.05 of their sigmas of the
            // laptop file's fit, and the anomaly within 0.05 mGal; without, the counts'
            // rounding alone, 0.01 mGal.
            let mut bound = 0.01;
            if let Some(c) = &r.sessions[0].cross_coupling {
                bound = 0.05;
                let read = std::fs::read_to_string(own.join("gravity/gravity.json")).expect("json");
                let laptop: GravityReport = serde_json::from_str(&read).expect("report");
                let l = laptop.sessions[0].cross_coupling.clone().expect("fitted");
                for i in 0..4 {
                    let z = (c.coefficients[i] - l.coefficients[i]) / l.sigma[i];
                    eprintln!(
                        "{}: {:.4e} against the laptop file's {:.4e}: {z:.3} sigma",
                        adjust::survey::gravity::coupling::MONITORS[i],
                        c.coefficients[i],
                        l.coefficients[i]
                    );
                    assert!(z.abs() < 0.05, "{i}: {z}");
                }
            }
            assert!(n > 2000 && rms < bound, "{meter}: rms {rms} over {n}");
            // One damaged line: refused, naming file, line and field.
            let damaged = serial
                .replacen("$AT1M_3.61_10,", "$AT1M_3.61_10,1", 1)
                .replacen(" 04:", " 04:x", 1);
            std::fs::write(dataset.join("raw/meter.raw"), damaged).expect("raw");
            let e = GravityArgs::new(&dataset, vendor)
                .run(&dir.path().join("damaged"))
                .expect_err("a damaged line");
            let line = if meter == "bgm3" { 1 } else { 11 };
            let field = if meter == "bgm3" {
                "counts"
            } else {
                "checksum"
            };
            let text = format!("{e:#}");
            assert!(
                text.contains(&format!("meter.raw:{line}: {field}")),
                "{meter}: {text}"
            );
        }
    }

    /// A laptop line with its time moved by `seconds` (within the day) or its raw gravity
    /// set to `rgrav`.
    fn laptop_edited(line: &str, seconds: i64, rgrav: Option<f64>) -> String {
        let mut f: Vec<String> = line.split(',').map(str::to_owned).collect();
        let at = |k: usize| f[k].trim().parse::<f64>().expect("a number") as i64;
        let t = at(22) * 3600 + at(23) * 60 + at(24) + seconds;
        f[22] = format!("{:02}", t / 3600);
        f[23] = format!("{:02}", t / 60 % 60);
        f[24] = format!("{:05.2}", (t % 60) as f64);
        if let Some(g) = rgrav {
            f[1] = format!("{g:.2}");
        }
        f.join(",")
    }

    /// The raw serial readers through the same damage as every reader's
    /// (xtask/tests/hostile_round2.rs): a line stamped 400 s ahead of its neighbours, one
    /// 400 s behind, and a reading the ADC cannot give (1e8 counts, its checksum made to
    /// hold), each in a cruise's 2401st line, costs that line alone with
    /// `--skip-bad-lines`, for the reason the time gate or the reading limits give, and the
    /// ledger adds up.
    #[test]
    fn a_damaged_serial_line_costs_that_line_alone() {
        use ingest::contract::ingest_ledger::reason;
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("cruise");
        fixtures::meter::write_cruise(&dataset, Cruise::new(3600, 3), "none").expect("cruise");
        let laptop = std::fs::read_to_string(dataset.join("raw/cruise.dat")).expect("dat");
        let lines: Vec<&str> = laptop.lines().collect();
        let skip = ingest::Options {
            skip_bad_lines: true,
            progress: false,
        };
        let manifest = std::fs::read_to_string(dataset.join("dataset.toml")).expect("toml");
        for meter in ["dgs-raw", "bgm3"] {
            let m = serial_manifest(&manifest, meter);
            std::fs::write(dataset.join("dataset.toml"), m).expect("toml");
            let k = 2400;
            let cases: [(&str, Option<String>, &[&str]); 4] = [
                ("clean", None, &[]),
                (
                    "400 s ahead",
                    Some(laptop_edited(lines[k], 400, None)),
                    &[reason::TIME_OUTLIER],
                ),
                (
                    "400 s behind",
                    Some(laptop_edited(lines[k], -400, None)),
                    &[reason::TIME_BACKWARDS, reason::TIME_OUTLIER],
                ),
                (
                    "1e8 counts",
                    Some(laptop_edited(lines[k], 0, Some(1e6))),
                    &[reason::READING_OUT_OF_RANGE],
                ),
            ];
            for (what, edited, reasons) in cases {
                let serial: String = lines
                    .iter()
                    .enumerate()
                    .map(|(i, l)| match &edited {
                        Some(e) if i == k => serial_of_laptop(e, i, meter),
                        _ => serial_of_laptop(l, i, meter),
                    })
                    .collect();
                std::fs::write(dataset.join("raw/meter.raw"), serial).expect("raw");
                let out = dir
                    .path()
                    .join(format!("{meter}-{}", what.replace(' ', "-")));
                let r = ingest::run_with(&dataset, &out, &skip).expect(what);
                let f = r
                    .files
                    .iter()
                    .find(|f| f.path == "raw/meter.raw")
                    .expect("its ledger");
                assert_eq!(f.read, f.accepted + f.rejected_total(), "{meter}, {what}");
                if edited.is_none() {
                    assert_eq!((f.accepted, f.rejected_total()), (3600, 0), "{meter}");
                    continue;
                }
                assert_eq!(f.rejected_total(), 1, "{meter}, {what}: {:?}", f.rejected);
                assert!(
                    reasons.iter().any(|why| f.rejected.get(*why) == Some(&1)),
                    "{meter}, {what}: {:?}",
                    f.rejected
                );
                assert_eq!(
                    f.rejections[0].at,
                    format!("line {}", k + 1),
                    "{meter}, {what}"
                );
                assert_eq!(f.accepted, 3599, "{meter}, {what}");
            }
        }
    }

    /// Replicas of the cruise over `disturbance` times the simulated one: the rms over
    /// replicas and coefficients of (error / sigma) for the sigmas the stage carries (the
    /// frequency-domain jackknife's) and for the ordinary ones, and the corrected anomaly's rms
    /// z over replicas.
    fn replicas(replicas: u64, disturbance: f64) -> (f64, f64, f64) {
        let (mut carried, mut ols, mut anomaly) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 0..replicas {
            let dir = tempfile::tempdir().expect("tempdir");
            let spec = Cruise {
                disturbance,
                ..Cruise::new(7200, 1000 + seed)
            };
            let (report, rows) = cruise(dir.path(), spec, "fit");
            let c = report.sessions[0].cross_coupling.clone().expect("fitted");
            for i in 0..4 {
                let e = c.coefficients[i] - fixtures::meter::COUPLING[i];
                carried.push(e / c.sigma[i]);
                ols.push(e / c.ols_sigma.expect("a fit's")[i]);
            }
            anomaly.push(scores(&rows).1);
        }
        let rms = |z: &[f64]| (z.iter().map(|x| x * x).sum::<f64>() / z.len() as f64).sqrt();
        (rms(&carried), rms(&ols), rms(&anomaly))
    }

    /// Replicas of the cruise (`GRAVCAL_MONTE_CARLO=1`: 200, else 24), over the simulated
    /// disturbance and, varying that alone, over none (white noise alone left to the
    /// regression): the carried sigmas are honest in both, the coefficients' rms z and the
    /// corrected anomaly's within 0.25 of 1 (three standard errors at 24 replicas), where the
    /// ordinary sigmas, which take the filtered residuals for independent, are far too small.
    #[test]
    fn monte_carlo_of_the_cross_coupling_sigmas() {
        let n = if std::env::var_os("GRAVCAL_MONTE_CARLO").is_some() {
            200
        } else {
            24
        };
        for disturbance in [1.0, 0.0] {
            let (carried, ols, anomaly) = replicas(n, disturbance);
            eprintln!(
                "{n} cruises, disturbance x {disturbance}: coefficients' rms z {carried:.2} with \
                 the jackknife's sigmas, {ols:.2} with the ordinary ones; the corrected \
                 anomaly's rms z {anomaly:.2}"
            );
            for z in [carried, anomaly] {
                assert!((z - 1.0).abs() < 0.25, "{carried} {anomaly}");
            }
            assert!(ols > 2.0 * carried, "{ols} against {carried}");
        }
    }
}

/// The seed's instrument (issue 52): a survey whose session lists four GNSS antennas
/// instead of a trajectory and an attitude file.
mod antenna_array {
    use super::*;
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Float64Type, Int64Type};

    /// attitude.parquet's times (s after the start), angles and sds (deg).
    pub(super) fn attitude_table(out: &Path) -> (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>) {
        use ingest::contract::tables::attitude;
        let file = std::fs::File::open(out.join("gravity").join(attitude::FILE)).expect("file");
        let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
            .expect("reader")
            .build()
            .expect("reader");
        let (mut t, mut hpr, mut sd) = (Vec::new(), Vec::new(), Vec::new());
        let start = fixtures::survey_lines::START_GPS_S as f64;
        for batch in reader {
            let b = batch.expect("batch");
            let col = |name: &str| {
                b.column_by_name(name)
                    .expect(name)
                    .as_primitive::<Float64Type>()
                    .clone()
            };
            let time = b
                .column_by_name("time_gps_ns")
                .expect("time")
                .as_primitive::<Int64Type>()
                .clone();
            let f: Vec<_> = attitude::FLOATS.iter().map(|n| col(n)).collect();
            for i in 0..b.num_rows() {
                t.push(time.value(i) as f64 * 1e-9 - start);
                hpr.push([f[0].value(i), f[1].value(i), f[2].value(i)]);
                sd.push([f[3].value(i), f[4].value(i), f[5].value(i)]);
            }
        }
        (t, hpr, sd)
    }

    /// The rms z of attitude.parquet's heading, pitch and roll against `plan`'s truth.
    fn attitude_z(plan: &fixtures::survey_lines::LinesPlan, out: &Path) -> [f64; 3] {
        let (t, hpr, sd) = attitude_table(out);
        let want = plan.attitude_at(&t);
        let mut z2 = [0.0; 3];
        for k in 0..t.len() {
            for j in 0..3 {
                let mut d = hpr[k][j] - want[k][j].to_degrees();
                d = (d + 180.0).rem_euclid(360.0) - 180.0;
                z2[j] += (d / sd[k][j]).powi(2);
            }
        }
        z2.map(|v| (v / t.len() as f64).sqrt())
    }

    /// Antenna `a{k}`'s `position_m` in `dataset`'s manifest made `"estimate"`.
    fn estimate_antenna(dataset: &Path, k: usize) {
        let path = dataset.join("dataset.toml");
        let m = std::fs::read_to_string(&path).expect("manifest");
        let m = antenna_position_written(&m, k, "\"estimate\"");
        std::fs::write(&path, m).expect("manifest");
    }

    /// The rolling boat of the test below with its fourth antenna's position declared
    /// `"estimate"`: the other three fix the vehicle frame, the estimate is within its sds
    /// of the truth (each axis within 4 sds, sigma0 within 0.1 of 1), and the session is
    /// reduced as with the position declared (every epoch, the attitude's rms z 0.8 to 1.2).
    #[test]
    fn an_antennas_position_is_estimated_within_its_sds() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("antennas");
        let plan = fixtures::survey_lines::antenna_plan();
        let truth = fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
        estimate_antenna(&dataset, 3);
        let out = dir.path().join("out");
        let r = reduce(&dataset, &out);
        let a = r.sessions[0].antennas.clone().expect("the array's");
        let e = a.estimated.get("a3").copied().expect("a3 estimated");
        let want = fixtures::survey_lines::four_antennas().positions_m[3];
        let z: [f64; 3] = std::array::from_fn(|k| (e.position_m[k] - want[k]) / e.sd_m[k]);
        eprintln!("estimated a3: {e:?}; z {z:?}");
        assert!(z.iter().all(|z| z.abs() < 4.0), "{e:?} against {want:?}");
        assert!((e.sigma0 - 1.0).abs() < 0.1, "{e:?}");
        assert!(e.screened <= 2, "{e:?}");
        assert_eq!(a.estimated.len(), 1, "{:?}", a.estimated);
        assert_eq!(a.epochs_solved, truth.epochs, "every epoch");
        let z = attitude_z(&plan, &out);
        eprintln!("with a3 estimated: attitude rms z {z:?}");
        for (name, z) in ["heading", "pitch", "roll"].iter().zip(z) {
            assert!((0.8..1.2).contains(&z), "{name}: rms z {z}");
        }
    }

    /// An antenna to estimate whose file holds one epoch is refused, naming it and why.
    #[test]
    fn an_antenna_to_estimate_that_one_epoch_sees_is_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("antennas");
        let plan = fixtures::survey_lines::antenna_plan();
        fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
        estimate_antenna(&dataset, 3);
        let pos = dataset.join("raw/antenna3.pos");
        let text = std::fs::read_to_string(&pos).expect("pos");
        let header = text.lines().take_while(|l| l.starts_with('%'));
        let first = text
            .lines()
            .find(|l| !l.starts_with('%'))
            .expect("an epoch");
        let one: Vec<&str> = header.chain([first]).collect();
        std::fs::write(&pos, one.join("\n") + "\n").expect("pos");
        let e = args(&dataset)
            .run(&dir.path().join("out"))
            .expect_err("refused")
            .to_string();
        eprintln!("{e}");
        assert!(
            e.contains("antenna `a3`") && e.contains("two at least"),
            "{e}"
        );
    }

    /// `[survey] array_down = "magnitude"` written into `dataset`'s manifest.
    pub(super) fn down_from_magnitude(dataset: &Path) {
        let path = dataset.join("dataset.toml");
        let m = std::fs::read_to_string(&path).expect("manifest");
        assert!(m.contains("[survey]\n"), "{m}");
        let m = m.replace("[survey]\n", "[survey]\narray_down = \"magnitude\"\n");
        std::fs::write(&path, m).expect("manifest");
    }

    /// The boat of the test below with `[survey] array_down = "magnitude"`: down from the
    /// force's magnitude, which no tilt enters, within a fifth of a mGal rms of the truth
    /// (turned by the array's attitude, 1.15 mGal); a filter period from turns (where the
    /// track's low-passed force lags the turn's onset and end, and the sigma does not say
    /// so) within its sigma (rms z 0.8 to 1.2).
    #[test]
    fn four_antennas_give_down_from_the_force_magnitude() {
        let dir = tempfile::tempdir().expect("tempdir");
        let dataset = dir.path().join("antennas");
        let plan = fixtures::survey_lines::antenna_plan();
        fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
        down_from_magnitude(&dataset);
        let out = dir.path().join("out");
        let r = reduce(&dataset, &out);
        assert!(
            r.specific_force.contains("magnitude"),
            "{}",
            r.specific_force
        );
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        eprintln!("antennas, down from the magnitude: rms error {rms:.3} mGal, rms z {z:.3}");
        assert!(rms < 0.2, "down rms error {rms}");
        let (away, z) = scores_away_from_turns(&dataset, &out, r.filter.filter_s);
        eprintln!(
            "antennas, down from the magnitude a filter period from turns: rms error \
             {away:.3} mGal, rms z {z:.3}"
        );
        assert!((0.8..1.2).contains(&z), "down rms z away from turns {z}");
    }

    /// Four antennas on the rolling boat (3 deg of roll, 1 deg of pitch), 1.9 to 3 m
    /// apart, at RTK's 5 mm horizontal and 10 mm vertical noise, and no attitude file: every
    /// epoch solved, its heading, pitch and roll within their sds of the truth (rms z 0.8 to
    /// 1.2 each), down as accurate as with the truth's attitude (rms z 0.8 to 1.2), north and
    /// east within their sigmas, which carry the derived attitude's part.
    #[test]
    fn four_antennas_give_the_attitude_and_north_and_east_within_their_sigmas() {
        let dir = tempfile::tempdir().expect("tempdir");
        let root = dir.path();
        let dataset = root.join("antennas");
        let plan = fixtures::survey_lines::antenna_plan();
        let truth = fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
        let out = root.join("out");
        let r = reduce(&dataset, &out);
        let a = r.sessions[0].antennas.clone().expect("the array's");
        eprintln!("{a:?}");
        assert_eq!(a.epochs_solved, truth.epochs, "every epoch");
        // Six baselines an epoch tested at 5 sds: 0.09 false alarms expected over the
        // survey's 25 631 epochs; two at most.
        assert!(a.set_aside.values().sum::<u64>() <= 2, "{:?}", a.set_aside);
        assert!(
            r.inputs
                .iter()
                .filter(|i| i.role.starts_with("antenna a"))
                .count()
                == 4,
            "{:?}",
            r.inputs
        );
        assert!(r.attitude_table.is_some());
        let z = attitude_z(&plan, &out);
        eprintln!(
            "derived attitude: rms z heading, pitch, roll {z:?}; median sds {:?} deg",
            a.median_sd_hpr_deg
        );
        for (name, z) in ["heading", "pitch", "roll"].iter().zip(z) {
            assert!((0.8..1.2).contains(&z), "{name}: rms z {z}");
        }
        // The planner (`cargo xtask plan` on an `[array]`) for this array, level, heading
        // east as the lines run: the stage's median sds within 3 % of its prediction.
        let array = adjust::survey::gravity::array_plan::ArrayPlan {
            description: String::new(),
            array: adjust::survey::gravity::array_plan::PlanArray {
                positions_m: fixtures::survey_lines::four_antennas().positions_m,
                sd_m: plan.position_sd_m,
                rate_hz: plan.rates_hz[1],
                filter_s: r.filter.filter_s,
                g_mgal: 980_000.0,
            },
        };
        let east = &adjust::survey::gravity::array_plan::predict(&array).expect("plan")[2];
        let [north_sigma, east_sigma] =
            horizontal_scores(&dataset, &out, r.filter.filter_s).map(|s| s[2]);
        let pairs = [
            (
                "heading",
                a.median_sd_hpr_deg[0].expect("heading").to_radians() * 1e3,
                east.sd_hpr_mrad[0],
            ),
            (
                "pitch",
                a.median_sd_hpr_deg[1].expect("pitch").to_radians() * 1e3,
                east.sd_hpr_mrad[1],
            ),
            (
                "roll",
                a.median_sd_hpr_deg[2].expect("roll").to_radians() * 1e3,
                east.sd_hpr_mrad[2],
            ),
            ("north filtered", north_sigma, east.sd_filtered_mgal[0]),
            ("east filtered", east_sigma, east.sd_filtered_mgal[1]),
        ];
        for (what, stage, planned) in pairs {
            eprintln!("{what}: the stage's median sd {stage:.3}, the planner's {planned:.3}");
            assert!(
                (stage / planned - 1.0).abs() < 0.03,
                "{what}: {stage} against {planned}"
            );
        }
        let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
        eprintln!("antennas, down: rms error {rms:.3} mGal, rms z {z:.3}");
        assert!((0.6..1.2).contains(&z), "down rms z {z}");
        for (name, [rms, z, sigma, att]) in
            ["north", "east"]
                .into_iter()
                .zip(horizontal_scores(&dataset, &out, r.filter.filter_s))
        {
            eprintln!(
                "antennas, {name}: rms error {rms:.2} mGal, rms z {z:.3}; median sigma \
                 {sigma:.1} mGal, of it the attitude's {att:.1}"
            );
            assert!(z < 1.3 && z > 0.7, "{name} rms z {z}");
        }
    }
}

/// `manifest` with antenna `a{k}`'s `position_m` written as `value`.
fn antenna_position_written(manifest: &str, k: usize, value: &str) -> String {
    let m = manifest;
    let at = m.find(&format!("id = \"a{k}\"")).expect("the antenna");
    let start = at + m[at..].find("position_m = ").expect("its position");
    let end = start + m[start..].find('\n').expect("its line");
    format!("{}position_m = {value}{}", &m[..start], &m[end..])
}

/// Two antennas fore and aft (a GNSS compass on a boat whose triad is level, issue 52):
/// heading and pitch per epoch within their sds of the truth (rms z 0.8 to 1.2), roll null
/// throughout attitude.parquet and named in gravity.json as not given, north and east not
/// given (null), down reduced as without an attitude and within its sigma of the truth.
#[test]
fn two_antennas_give_heading_and_pitch_and_name_the_roll_not_given() {
    use arrow_array::Array;
    use arrow_array::cast::AsArray;
    use arrow_array::types::Float64Type;
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("compass");
    let plan = fixtures::survey_lines::two_antenna_plan();
    let truth = fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
    let out = dir.path().join("out");
    let r = reduce(&dataset, &out);
    let a = r.sessions[0].antennas.clone().expect("the array's");
    eprintln!("{a:?}");
    assert!(
        a.epochs_solved + 2 >= truth.epochs,
        "{} of {}",
        a.epochs_solved,
        truth.epochs
    );
    assert!(
        a.not_given
            .get("roll")
            .is_some_and(|w| w.contains("two antennas"))
    );
    assert!(a.median_sd_hpr_deg[2].is_none() && a.median_sd_hpr_deg[1].is_some());
    let (t, hpr, sd) = antenna_array::attitude_table(&out);
    let want = plan.attitude_at(&t);
    let mut z2 = [0.0; 2];
    for k in 0..t.len() {
        for j in 0..2 {
            let d = (hpr[k][j] - want[k][j].to_degrees() + 180.0).rem_euclid(360.0) - 180.0;
            z2[j] += (d / sd[k][j]).powi(2);
        }
    }
    let z = z2.map(|v| (v / t.len() as f64).sqrt());
    eprintln!("two antennas: rms z heading, pitch {z:?}");
    for (name, z) in ["heading", "pitch"].iter().zip(z) {
        assert!((0.8..1.2).contains(&z), "{name}: rms z {z}");
    }
    let file = std::fs::File::open(out.join("gravity/attitude.parquet")).expect("file");
    for b in parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .expect("reader")
        .build()
        .expect("reader")
    {
        let b = b.expect("batch");
        for name in ["roll_deg", "sd_roll_deg", "corr_pitch_roll"] {
            let c = b
                .column_by_name(name)
                .expect(name)
                .as_primitive::<Float64Type>();
            assert_eq!(c.null_count(), c.len(), "{name}");
        }
    }
    let columns = all_columns(&out);
    for name in ["north_filtered_mgal", "east_filtered_mgal"] {
        let c = &columns.iter().find(|(n, _)| n == name).expect(name).1;
        assert!(c.iter().all(|v| v.is_nan()), "{name} given");
    }
    let (rms, z) = scores(&dataset, &out, r.filter.filter_s);
    eprintln!("two antennas, down: rms error {rms:.3} mGal, rms z {z:.3}");
    assert!((0.6..1.2).contains(&z), "down rms z {z}");
}

/// The array's checks on the rolling boat: antenna a2 moved 5 cm north at one epoch has
/// its baselines' lengths off, is set aside there and the epoch reduced from the other
/// three; a lever arm beside the antennas and two antennas across the boat are each
/// refused by name.
#[test]
fn an_antenna_off_by_5_cm_is_set_aside_and_the_epoch_kept() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("antennas");
    let plan = fixtures::survey_lines::antenna_plan();
    let truth = fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
    let file = dataset.join("raw/antenna2.pos");
    let out = dir.path().join("out");
    let text = std::fs::read_to_string(&file).expect("pos");
    let moved: String = text
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if k != 1002 {
                return format!("{l}\n");
            }
            let f: Vec<&str> = l.split_whitespace().collect();
            let lat: f64 = f[2].parse().expect("latitude");
            let north = (0.05 / 6_367_000.0f64).to_degrees();
            format!(
                "{} {} {:.9} {}\n",
                f[0],
                f[1],
                lat + north,
                f[3..].join(" ")
            )
        })
        .collect();
    std::fs::write(&file, moved).expect("pos");
    let r = reduce(&dataset, &out);
    let a = r.sessions[0].antennas.clone().expect("the array's");
    eprintln!("{a:?}");
    assert_eq!(a.epochs_solved, truth.epochs, "the epoch kept");
    // attitude.parquet's masks at that epoch (the 1000th): a2 set aside, the others used.
    let masks = {
        use arrow_array::cast::AsArray;
        use arrow_array::types::UInt32Type;
        let file = std::fs::File::open(out.join("gravity/attitude.parquet")).expect("file");
        let b = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
            .expect("reader")
            .build()
            .expect("reader")
            .next()
            .expect("a batch")
            .expect("batch");
        let m = |n: &str| {
            b.column_by_name(n)
                .expect(n)
                .as_primitive::<UInt32Type>()
                .value(1000)
        };
        [m("antennas_used"), m("antennas_set_aside")]
    };
    assert_eq!(masks, [0b1011, 0b0100], "{:?}", a.set_aside);
    let manifest = std::fs::read_to_string(dataset.join("dataset.toml")).expect("toml");
    // The manifest without the antennas `gone` (each block ends at a blank line).
    let without = |gone: &[usize]| {
        let mut m = manifest.clone();
        for k in gone {
            let at = m
                .find(&format!("[[session.antenna]]\nid = \"a{k}\""))
                .expect("antenna");
            let end = m[at + 1..].find("\n\n").map_or(m.len(), |e| at + 2 + e);
            m = format!("{}{}", &m[..at], &m[end..]);
        }
        m
    };
    let two_across = without(&[0, 1]);
    for (what, m, want) in [
        (
            "a lever arm",
            manifest.replace(
                "lever_arm_m = [0.0, 0.0, 0.0]",
                "lever_arm_m = [0.1, 0.0, 0.0]",
            ),
            "survey.lever_arm_m",
        ),
        (
            "two antennas across",
            two_across,
            "along the vehicle's x axis",
        ),
        (
            "a position misspelt",
            antenna_position_written(&manifest, 1, "\"estimated\""),
            "antenna[1].position_m: `estimated` is not a position [x, y, z] in metres or \"estimate\"",
        ),
        (
            "a position out of reach",
            antenna_position_written(&manifest, 1, "[1e6, 0.0, 0.0]"),
            "antenna[1].position_m",
        ),
        (
            "two to estimate beside two",
            antenna_position_written(
                &antenna_position_written(&manifest, 1, "\"estimate\""),
                2,
                "\"estimate\"",
            ),
            "2 to estimate (a1, a2) beside 2 declared",
        ),
    ] {
        assert_ne!(m, manifest, "{what}");
        std::fs::write(dataset.join("dataset.toml"), &m).expect("toml");
        let e = args(&dataset)
            .run(&dir.path().join(what))
            .expect_err(what)
            .to_string();
        eprintln!("{what}: {e}");
        assert!(e.contains(want), "{what}: {e}");
    }
}

/// Four-antenna surveys over replicas (`GRAVCAL_MONTE_CARLO=1`: 30 boats and 30
/// aircraft, else 2 boats), each with its noise drawn again: per survey the rms of error /
/// sigma of the derived heading, pitch and roll per epoch and of north, east and down
/// filtered, pooled over the surveys of each vehicle. North and east within 0.8 to 1.2, each
/// angle within 0.9 to 1.1; down's sigma not too small (at most 1.2: it is conservative,
/// docs/model.md 7, "An antenna array"). The boats again with `array_down = "magnitude"`:
/// down within 0.8 to 1.2 over all epochs and a filter period from turns; and (full only)
/// the aircraft, whose down is held to 0.8 to 1.5: the same aircraft with a perfect
/// attitude file and the array's position sds ([`perfect_attitude_aircraft`]) is not
/// within 1.2 either, a part not modelled that is not the array's (docs/model.md 7, "An
/// antenna array"). Each survey's rms error over all epochs and away from turns printed.
#[test]
fn monte_carlo_of_four_antenna_surveys() {
    let full = std::env::var_os("GRAVCAL_MONTE_CARLO").is_some();
    if full {
        perfect_attitude_aircraft(30);
    }
    let boats = if full { 30 } else { 2 };
    let vehicles = [
        ("boat", fixtures::survey_lines::antenna_plan(), boats, false),
        (
            "aircraft",
            fixtures::survey_lines::aircraft_antenna_plan(),
            if full { 30 } else { 0 },
            false,
        ),
        (
            "magnitude boat",
            fixtures::survey_lines::antenna_plan(),
            boats,
            true,
        ),
        (
            "magnitude aircraft",
            fixtures::survey_lines::aircraft_antenna_plan(),
            if full { 30 } else { 0 },
            true,
        ),
    ];
    for (vehicle, plan, n, magnitude) in vehicles {
        if n == 0 {
            continue;
        }
        let mut z2 = [0.0; 6];
        let mut z_away2 = 0.0;
        for seed in 1..=n {
            let dir = tempfile::tempdir().expect("tempdir");
            let (plan, dataset, out) = replica(dir.path(), plan.clone(), 100 + seed);
            if magnitude {
                antenna_array::down_from_magnitude(&dataset);
            }
            let r = args(&dataset).run(&out).expect("gravity");
            let (t, hpr, sd) = antenna_array::attitude_table(&out);
            let want = plan.attitude_at(&t);
            let mut a = [0.0; 3];
            for k in 0..t.len() {
                for j in 0..3 {
                    let d = (hpr[k][j] - want[k][j].to_degrees() + 180.0).rem_euclid(360.0) - 180.0;
                    a[j] += (d / sd[k][j]).powi(2) / t.len() as f64;
                }
            }
            let (all, z_all) = scores(&dataset, &out, r.filter.filter_s);
            let (away, z_away) = scores_away_from_turns(&dataset, &out, r.filter.filter_s);
            eprintln!("{vehicle} {seed}: down rms error {all:.3} mGal, {away:.3} away from turns");
            let down = z_all;
            if magnitude {
                z_away2 += z_away * z_away / f64::from(u32::try_from(n).expect("count"));
            }
            let [north, east] = horizontal_scores(&dataset, &out, r.filter.filter_s);
            let z = [
                a[0].sqrt(),
                a[1].sqrt(),
                a[2].sqrt(),
                north[1],
                east[1],
                down,
            ];
            eprintln!("{vehicle} {seed}: rms z heading, pitch, roll, north, east, down {z:.3?}");
            for (s, z) in z2.iter_mut().zip(z) {
                *s += z * z / f64::from(u32::try_from(n).expect("count"));
            }
        }
        let pooled = z2.map(f64::sqrt);
        eprintln!(
            "{n} {vehicle}s with four antennas: pooled rms z heading, pitch, roll {:.3?}, north \
             {:.3}, east {:.3}, down {:.3}",
            &pooled[..3],
            pooled[3],
            pooled[4],
            pooled[5]
        );
        for (name, z) in ["heading", "pitch", "roll"].iter().zip(&pooled[..3]) {
            assert!((0.9..1.1).contains(z), "{vehicle} {name}: {z}");
        }
        assert!(
            (0.8..1.2).contains(&pooled[3]),
            "{vehicle} north: {}",
            pooled[3]
        );
        assert!(
            (0.8..1.2).contains(&pooled[4]),
            "{vehicle} east: {}",
            pooled[4]
        );
        let (least, most) = match (magnitude, vehicle.ends_with("aircraft")) {
            (false, _) => (0.0, 1.2),
            (true, false) => (0.8, 1.2),
            (true, true) => (0.8, 1.5),
        };
        assert!(
            (least..most).contains(&pooled[5]),
            "{vehicle} down: {}",
            pooled[5]
        );
        if magnitude {
            let away = z_away2.sqrt();
            eprintln!("{n} {vehicle}s: down's pooled rms z a filter period from turns {away:.3}");
            assert!(
                (least..most).contains(&away),
                "{vehicle} down away from turns: {away}"
            );
        }
    }
}

/// The aircraft of the four-antenna surveys with an attitude file and no antennas, the
/// file's errors a millionth of a mrad and the positions' sds the array's (1.1 cm north and
/// east, 0.5 cm up): down's pooled rms z over `n` surveys, over all epochs and a filter
/// period from turns, printed, and held under 1.6; then the same without the climb (950 m
/// over the speed's ramps, a cosine in height whose vertical acceleration steps by 0.05
/// m/s^2 at the ramps' ends), held to 0.8 to 1.2.
fn perfect_attitude_aircraft(n: u64) {
    for climb in [true, false] {
        perfect_attitude_aircraft_climbing(n, climb);
    }
}

/// [`perfect_attitude_aircraft`], the aircraft climbing or not.
fn perfect_attitude_aircraft_climbing(n: u64, climb: bool) {
    let mut plan = fixtures::survey_lines::aircraft_attitude_plan();
    plan.position_sd_m = [0.011, 0.005];
    if !climb {
        plan.climb_m = 0.0;
    }
    if let Some(a) = plan.attitude.as_mut() {
        a.sd_mrad = [1e-6, 1e-6];
    }
    let (mut all2, mut away2, mut rms2) = (0.0, 0.0, 0.0);
    for seed in 1..=n {
        let dir = tempfile::tempdir().expect("tempdir");
        let (_, dataset, out) = replica(dir.path(), plan.clone(), 100 + seed);
        let r = args(&dataset).run(&out).expect("gravity");
        let (rms, all) = scores(&dataset, &out, r.filter.filter_s);
        let (away_rms, away) = scores_away_from_turns(&dataset, &out, r.filter.filter_s);
        eprintln!(
            "perfect-attitude aircraft {seed}: down rms error {rms:.3} mGal, {away_rms:.3} \
             away from turns; rms z {all:.3}, {away:.3}"
        );
        let w = 1.0 / n as f64;
        (all2, away2, rms2) = (
            all2 + w * all * all,
            away2 + w * away * away,
            rms2 + w * rms * rms,
        );
    }
    let [all, away, rms] = [all2, away2, rms2].map(f64::sqrt);
    let what = if climb { "climbing" } else { "level" };
    eprintln!(
        "{n} perfect-attitude aircraft, {what}: down's pooled rms z {all:.3}, {away:.3} a \
         filter period from turns; rms error {rms:.3} mGal"
    );
    let (least, most) = if climb { (0.0, 1.6) } else { (0.8, 1.2) };
    assert!(
        (least..most).contains(&all) && (least..most).contains(&away),
        "{what}: {all} {away}"
    );
}

/// An antenna's file through the damage every reader faces (docs/hostile-input.md): a
/// latitude that is not a number on one line of antenna a1 fails the run naming the file,
/// line and field; with `--skip-bad-lines` it costs a1 that epoch alone (the epoch fitted
/// from the other three), listed and counted; a line of a3 repeated is dropped by a3's
/// time gate and counted under a3.
#[test]
fn a_damaged_antenna_line_costs_that_antenna_that_epoch() {
    let dir = tempfile::tempdir().expect("tempdir");
    let dataset = dir.path().join("antennas");
    let plan = fixtures::survey_lines::antenna_plan();
    let truth = fixtures::survey_lines::write_survey_lines(&plan, &dataset).expect("survey");
    let edit = |name: &str, f: &dyn Fn(usize, &str) -> String| {
        let path = dataset.join("raw").join(name);
        let text = std::fs::read_to_string(&path).expect("pos");
        let out: String = text.lines().enumerate().map(|(k, l)| f(k, l)).collect();
        std::fs::write(&path, out).expect("pos");
    };
    edit("antenna1.pos", &|k, l| match k {
        500 => {
            let f: Vec<&str> = l.split_whitespace().collect();
            format!("{} {} 43.2x {}\n", f[0], f[1], f[3..].join(" "))
        }
        _ => format!("{l}\n"),
    });
    edit("antenna3.pos", &|k, l| match k {
        700 => format!("{l}\n{l}\n"),
        _ => format!("{l}\n"),
    });
    let e = args(&dataset)
        .run(&dir.path().join("strict"))
        .expect_err("a damaged line")
        .to_string();
    eprintln!("{e}");
    assert!(e.contains("antenna1.pos:501"), "{e}");
    let mut skipping = args(&dataset);
    skipping.skip_bad_lines = true;
    let r = skipping.run(&dir.path().join("out")).expect("skipping");
    let a = r.sessions[0].antennas.clone().expect("the array's");
    eprintln!("{a:?}; {:?}", r.sessions[0].bad_lines);
    assert_eq!(
        a.epochs_solved, truth.epochs,
        "every epoch, from the others where a1 has none"
    );
    assert_eq!(a.epochs_read[1], truth.epochs - 1);
    assert!(
        r.sessions[0]
            .bad_lines
            .iter()
            .any(|l| l.contains("antenna1.pos:501"))
    );
    // The epoch is not lost: the line is counted under its antenna.
    assert!(
        r.sessions[0].dropped.is_empty(),
        "{:?}",
        r.sessions[0].dropped
    );
    assert_eq!(r.sessions[0].epochs_used, truth.epochs);
    let count = |id: &str, why: &str| a.dropped.get(id).and_then(|d| d.get(why)).copied();
    assert_eq!(count("a1", "bad_line"), Some(1), "{:?}", a.dropped);
    let a3: u64 = a.dropped.get("a3").map_or(0, |d| d.values().sum());
    assert_eq!(a3, 1, "{:?}", a.dropped);
}
