//! Hostile inputs, round two (issue 24): the paths added after the first round (lab streams
//! and their temperature logs, apply, plan, every name a user gives), each class as a
//! table of damage applied by the test to a committed fixture or to a file it writes, with
//! the right result or the clear error, and the ledgers still adding up.

use ingest::contract::ingest_ledger::{FileLedger, IngestReport, reason};
use std::path::{Path, PathBuf};

/// A copy of fixture `name` in a fresh folder, its manifest passed through `edit`.
fn copy(name: &str, edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join(name);
    fixtures::copy_dataset(name, &ds, edit).expect("copy");
    (dir, ds)
}

/// The text readers, and how each writes its time and its values.
#[derive(Clone, Copy, Debug)]
enum Layout {
    /// `gps_week,tow_s,c1,c2,c3` (counts).
    CsvAdc,
    /// `gps_week,tow_s,t1,t2,t3` (degC).
    CsvTemperature,
    /// `t,x,y,z` (a lab stream, counts).
    LabStream,
    /// `t,T1,T2,T3` (a lab temperature log, degC).
    LabTemperature,
}

impl Layout {
    /// Index of the time field (seconds) and of the first value.
    fn fields(self) -> (usize, usize) {
        match self {
            Layout::CsvAdc | Layout::CsvTemperature => (1, 2),
            Layout::LabStream | Layout::LabTemperature => (0, 1),
        }
    }

    /// The value no instrument of the fixture can give, and the reason it is rejected for.
    fn implausible(self) -> (&'static str, &'static str) {
        match self {
            // A text count outside 24 bits cannot be a count: a malformed line (an error
            // naming file, line and field, or with skip-bad-lines a counted rejection).
            Layout::CsvAdc => ("1000000000000", reason::MALFORMED),
            Layout::LabStream => ("1e12", reason::READING_OUT_OF_RANGE),
            Layout::CsvTemperature | Layout::LabTemperature => {
                ("5000.0", reason::TEMPERATURE_OUT_OF_RANGE)
            }
        }
    }
}

/// The readers: (fixture, file, layout). The lab temperature log is written by
/// [`with_lab_temperature_log`] into the triad fixture's copy.
const READERS: [(&str, &str, Layout); 4] = [
    ("esgt-2005-csv", "raw/day1_adc.csv", Layout::CsvAdc),
    ("esgt-2005-csv", "raw/day1_temp.csv", Layout::CsvTemperature),
    ("triad-multipos", "raw/lab.txt", Layout::LabStream),
    ("triad-multipos", "raw/lab_temp.txt", Layout::LabTemperature),
];

/// Adds a temperature log (`t,T1,T2,T3` every 2 s over the stream's 15 minutes) to a copy of
/// triad-multipos.
fn with_lab_temperature_log(ds: &Path) {
    let mut text = String::from("t,T1,T2,T3\n");
    for i in 0..500 {
        let t = f64::from(i) * 2.0;
        let c = 24.0 + 0.001 * f64::from(i);
        text.push_str(&format!("{t:.3},{c:.4},{:.4},{:.4}\n", c + 0.5, c + 1.0));
    }
    std::fs::write(ds.join("raw/lab_temp.txt"), text).expect("write log");
    let manifest = ds.join("dataset.toml");
    let m = std::fs::read_to_string(&manifest).expect("manifest");
    let m = m.replace(
        "adc_csv = \"raw/lab.txt\"",
        "adc_csv = \"raw/lab.txt\"\ntemperature_csv = \"raw/lab_temp.txt\"",
    );
    std::fs::write(manifest, m).expect("manifest");
}

/// A fresh copy of the reader's fixture (with the lab temperature log when it is read).
fn reader_copy(fixture: &str, layout: Layout) -> (tempfile::TempDir, PathBuf) {
    let (dir, ds) = copy(fixture, |m| m);
    if matches!(layout, Layout::LabStream | Layout::LabTemperature) {
        with_lab_temperature_log(&ds);
    }
    (dir, ds)
}

/// Rewrites data line `k` (0-based among the data lines) of `path` with `edit` on its
/// comma-separated fields; returns its 1-based line number.
fn edit_data_line(path: &Path, k: usize, edit: impl FnOnce(&mut Vec<String>)) -> u64 {
    let text = std::fs::read_to_string(path).expect("read");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let data: Vec<usize> = (0..lines.len())
        .filter(|&i| {
            let l = &lines[i];
            !l.starts_with('#')
                && l.split(',')
                    .nth(1)
                    .is_some_and(|f| f.parse::<f64>().is_ok())
        })
        .collect();
    let i = data[k];
    let mut fields: Vec<String> = lines[i].split(',').map(str::to_owned).collect();
    edit(&mut fields);
    lines[i] = fields.join(",");
    std::fs::write(path, lines.join("\n") + "\n").expect("write");
    i as u64 + 1
}

fn ledger<'a>(r: &'a IngestReport, file: &str) -> &'a FileLedger {
    r.files
        .iter()
        .find(|f| f.path == file)
        .unwrap_or_else(|| panic!("no ledger for {file}"))
}

fn adds_up(f: &FileLedger) {
    assert_eq!(
        f.read,
        f.accepted + f.rejected_total(),
        "{}: read = accepted + rejected",
        f.path
    );
}

/// An edit of a line's fields.
type FieldEdit = Box<dyn Fn(&mut Vec<String>)>;

/// Every reader, through the same table of damage: a line stamped 400 s ahead of its
/// neighbours, one stamped 400 s behind, and a value the instrument cannot give, each costs
/// that line alone (before, in a lab stream, the line ahead made the next 12 499 lines go
/// `time_backwards`; 5000 degC and a count of 1e12 were stored).
#[test]
fn every_reader_loses_only_the_damaged_line() {
    for (fixture, file, layout) in READERS {
        let (clean_dir, clean) = reader_copy(fixture, layout);
        let clean_report = ingest::run(&clean, &clean_dir.path().join("out")).expect("clean");
        let clean_ledger = ledger(&clean_report, file).clone();
        assert_eq!(clean_ledger.rejected_total(), 0, "{file} clean");
        let (time, value) = layout.fields();
        let (implausible, implausible_reason) = layout.implausible();
        let cases: [(&str, FieldEdit, &[&str]); 3] = [
            (
                "400 s ahead",
                Box::new(move |f| {
                    let t: f64 = f[time].parse().expect("time");
                    f[time] = format!("{:.3}", t + 400.0);
                }),
                &[reason::TIME_OUTLIER],
            ),
            (
                "400 s behind",
                Box::new(move |f| {
                    let t: f64 = f[time].parse().expect("time");
                    f[time] = format!("{:.3}", t - 400.0);
                }),
                &[reason::TIME_BACKWARDS, reason::OUTSIDE_SESSION],
            ),
            (
                "implausible value",
                Box::new(move |f| f[value] = implausible.to_owned()),
                &[implausible_reason],
            ),
        ];
        for (what, edit, reasons) in cases {
            let (dir, ds) = reader_copy(fixture, layout);
            let path = ds.join(file);
            let n_data = std::fs::read_to_string(&path)
                .expect("read")
                .lines()
                .filter(|l| !l.starts_with('#'))
                .count();
            // Far from the start, where the gate judges by neighbours on both sides.
            let line = edit_data_line(&path, n_data * 2 / 3, edit);
            let skip = ingest::Options {
                skip_bad_lines: true,
                progress: false,
            };
            let r = ingest::run_with(&ds, &dir.path().join("out"), &skip)
                .unwrap_or_else(|e| panic!("{file}, {what}: {e}"));
            let f = ledger(&r, file);
            adds_up(f);
            assert_eq!(f.rejected_total(), 1, "{file}, {what}: {:?}", f.rejected);
            assert!(
                reasons.iter().any(|why| f.rejected.get(*why) == Some(&1)),
                "{file}, {what}: {:?}, expected one of {reasons:?}",
                f.rejected
            );
            assert_eq!(
                f.rejections[0].at,
                format!("line {line}"),
                "{file}, {what}: the damaged line is the one rejected"
            );
            assert_eq!(f.accepted + 1, clean_ledger.accepted, "{file}, {what}");
            // The session's other files are untouched.
            for g in r
                .files
                .iter()
                .filter(|g| g.path != file && g.session == f.session)
            {
                assert_eq!(
                    g.accepted,
                    ledger(&clean_report, &g.path).accepted,
                    "{}",
                    g.path
                );
            }
        }
    }
}

/// A lab stream whose time column never changes: every sample shares one stamp, and the
/// rate it "measured" was the declared one. Now the session fails, naming the file.
#[test]
fn a_lab_stream_whose_times_never_move_fails_its_session() {
    let (dir, ds) = copy("triad-multipos", |m| m);
    let path = ds.join("raw/lab.txt");
    let text = std::fs::read_to_string(&path).expect("read");
    let frozen: Vec<String> = text
        .lines()
        .map(|l| match l.split_once(',') {
            Some((t, rest)) if t.parse::<f64>().is_ok() => format!("12.000,{rest}"),
            _ => l.to_owned(),
        })
        .collect();
    std::fs::write(&path, frozen.join("\n") + "\n").expect("write");
    let e = ingest::run(&ds, &dir.path().join("out")).expect_err("no measured rate");
    let msg = e.to_string();
    assert!(
        msg.contains("raw/lab.txt") && msg.contains("never move"),
        "{msg}"
    );
}

/// Names a user gives: each bad id or model name is refused by the manifest with the key
/// it sits under, before any output is written; a model named to escape the output folder
/// writes nothing outside it.
#[test]
fn names_are_checked_as_names() {
    let long = "a".repeat(300);
    let cases: [(&str, &str, &str, &str); 9] = [
        ("id = \"day1\"", "id = \"all\"", "session[0].id", "reserved"),
        // Outputs are named by ids: macOS and Windows would write one over the other.
        (
            "id = \"day2\"",
            "id = \"DAY1\"",
            "session[1].id",
            "`DAY1` and `day1` differ only in case",
        ),
        (
            "id = \"acc2\"",
            "id = \"Acc1\"",
            "instrument.accelerometer[1].id",
            "`Acc1` and `acc1` differ only in case",
        ),
        (
            "id = \"day1\"",
            "id = \"day2\"",
            "session[1].id",
            "duplicate id",
        ),
        ("id = \"day1\"", "id = \"day/1\"", "session[0].id", "'/'"),
        (
            "id = \"acc1\"",
            "id = \"triad\"",
            "instrument.accelerometer[0].id",
            "reserved",
        ),
        (
            "id = \"acc1\"",
            &format!("id = \"{long}\""),
            "instrument.accelerometer[0].id",
            "at most 64",
        ),
        (
            "name = \"linear\"",
            "name = \"../../../escaped\"",
            "adjust.model[0].name",
            "'/'",
        ),
        (
            "name = \"linear\"",
            "name = \"..\"",
            "adjust.model[0].name",
            "begin with a letter",
        ),
    ];
    for (from, to, key, says) in cases {
        let (dir, ds) = copy("esgt-2005", |m| {
            let m = if m.contains("[[adjust.model]]") {
                m
            } else {
                m + "\n[[adjust.model]]\nname = \"linear\"\n"
            };
            m.replacen(from, to, 1)
        });
        let out = dir.path().join("out");
        let e = ingest::run(&ds, &out).expect_err(to);
        let msg = e.to_string();
        assert!(msg.contains(key) && msg.contains(says), "{to}: {msg}");
        assert!(!out.join("ingest").exists(), "{to}: nothing written");
        assert!(!dir.path().join("escaped").exists());
    }
}

/// A stage pointed at another dataset's output folder refuses before writing (apply used to
/// re-ingest over it, breaking that dataset's report).
#[test]
fn another_datasets_output_folder_is_refused() {
    let (dir, gon) = copy("gon-gpst", |m| m);
    let out = dir.path().join("out");
    ingest::run(&gon, &out).expect("ingest");
    let before = std::fs::read(out.join("ingest/ingest.json")).expect("ledger");
    let (_d2, other) = copy("week-rollover", |m| m);
    let e = ingest::run(&other, &out).expect_err("a foreign folder");
    assert!(e.to_string().contains("belongs to another dataset"), "{e}");
    let survey = fixtures::dataset_dir("survey");
    let cal = dir.path().join("calibration.json");
    std::fs::write(&cal, "{}").expect("write");
    let e = adjust::survey::apply::stream::run(
        &survey,
        &out,
        &adjust::survey::apply::stream::Options {
            calibration: &cal,
            choice: Default::default(),
        },
    )
    .expect_err("a foreign folder");
    assert!(e.to_string().contains("belongs to another dataset"), "{e}");
    assert_eq!(
        std::fs::read(out.join("ingest/ingest.json")).expect("ledger"),
        before,
        "untouched"
    );
}

/// The planner reads its models as the manifest's, with its limits: orders 0 and 4 panicked
/// (index out of bounds), a station count of 2^63 aborted on allocation, two sessions with
/// one id were pooled.
#[test]
fn the_planner_is_validated_like_a_manifest() {
    let plan = std::fs::read_to_string(xtask_root().join("fixtures/plans/paper.toml"))
        .expect("paper.toml");
    let parse = |text: &str| -> Result<adjust::calibration::plan::Plan, String> {
        toml::from_str(text).map_err(|e| e.to_string())
    };
    let ok = parse(&plan).expect("the paper's plan parses");
    adjust::calibration::plan::predict(&ok).expect("the paper's plan predicts");
    let first_model = plan.find("[[model]]").expect("a model");
    let with_model = |extra: &str| {
        let mut p = plan.clone();
        p.insert_str(
            first_model,
            &format!("[[model]]\nname = \"x\"\n{extra}\n\n"),
        );
        p
    };
    let cases: Vec<(String, &str)> = vec![
        (with_model("order = 0"), "model[0].order"),
        (with_model("order = 4"), "model[0].order"),
        (with_model("order = 1\nper = \"bogus\""), "per"),
        (
            plan.replacen(
                "readings_per_station = 15",
                "readings_per_station = 100000000",
                1,
            ),
            "readings_per_station",
        ),
        (
            plan.replacen("stations = 15", "stations = 9223372036854775807", 1),
            "stations",
        ),
        (
            plan.replacen("id = \"day2\"", "id = \"day1\"", 1),
            "duplicate id",
        ),
        (
            plan.replacen("id = \"day1\"", "id = \"all\"", 1),
            "reserved",
        ),
        (
            plan.replacen("temperature_c = 31.0", "temperature_c = 3100.0", 1),
            "session[1].temperature_c: 3100 is not a temperature",
        ),
        // A scale of 0 was said to be a noise level; a scale of 1e-300 mGal/bit planned
        // counts of 1e305 and printed k's sigma as 0.
        (
            plan.replacen("k_mgal_per_bit = 0.24305", "k_mgal_per_bit = 0.0", 1),
            "instrument.k_mgal_per_bit: 0 is no scale factor",
        ),
        (
            plan.replacen("k_mgal_per_bit = 0.24305", "k_mgal_per_bit = 1e-300", 1),
            "beyond any ADC's range",
        ),
        (
            plan.replacen("b_mgal = -29497.0", "b_mgal = 1e300", 1),
            "beyond any ADC's range",
        ),
    ];
    for (text, says) in cases {
        assert_ne!(text, plan, "the case changed the plan ({says})");
        let e = match parse(&text) {
            Err(e) => e,
            Ok(p) => adjust::calibration::plan::predict(&p)
                .map(|_| ())
                .expect_err(says)
                .to_string(),
        };
        assert!(e.contains(says), "{says}: {e}");
    }
}

fn xtask_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("workspace")
        .to_path_buf()
}

/// `fit` on numbers the arithmetic cannot hold says so (it printed every parameter null with
/// sigmas of 0, exit 0); a CSV with a byte-order mark reads its first column; a folder given
/// as the file is named as a folder; a bad value names the file's line, not the data row.
#[test]
fn fit_says_what_it_cannot_do() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv = dir.path().join("t.csv");
    let args = |x: &str| adjust::FitArgs {
        input: csv.clone(),
        x: x.to_owned(),
        y: "y".to_owned(),
        sigma_x: None,
        sigma_y: None,
        degree: 1,
    };
    let mut text = String::from("x,y\n");
    for i in 0..10 {
        text.push_str(&format!("{}e200,{}\n", 1.0 + f64::from(i) * 1e-3, i));
    }
    std::fs::write(&csv, &text).expect("write");
    let e = adjust::fit_csv(&args("x")).expect_err("overflow");
    assert!(e.to_string().contains("rescale"), "{e}");

    std::fs::write(&csv, "\u{feff}x,y\n1,2\n2,4.1\n3,5.9\n4,8.2\n").expect("write");
    let f = adjust::fit_csv(&args("x")).expect("a BOM is not part of `x`");
    assert!((f.parameters[1].value - 2.0).abs() < 0.2);

    std::fs::write(&csv, "# comment\nx,y\n\n1,2\n2,4\n3,inf\n").expect("write");
    let e = adjust::fit_csv(&args("x")).expect_err("inf");
    assert!(e.to_string().contains("t.csv:6"), "the file's line 6: {e}");

    let e = adjust::fit_csv(&adjust::FitArgs {
        input: dir.path().to_path_buf(),
        ..args("x")
    })
    .expect_err("a folder");
    assert!(e.to_string().contains("folder"), "{e}");
}

/// apply reads a calibration file as untrusted, at the stage: a term it cannot evaluate in
/// an axis result, a negative sigma in a triad result, each refused before any work (no
/// OUT/apply), naming the calibration file and the defect.
#[test]
fn apply_refuses_a_damaged_calibration_before_any_work() {
    use adjust::survey::apply::select::Choice;
    use adjust::survey::apply::stream::{Options, run};
    let dir = tempfile::tempdir().expect("tempdir");
    let cases: [(&str, &str, &str, Option<&str>, &str); 2] = [
        ("esgt-2005", "survey", "thermal", None, "`k4`"),
        (
            "triad-multipos",
            "triad-multipos",
            "triad",
            Some("lab"),
            "sigma -",
        ),
    ];
    for (calibrated, applied, model, session, says) in cases {
        let out = dir.path().join(calibrated);
        let ds = fixtures::dataset_dir(calibrated);
        ingest::run(&ds, &out).expect("ingest");
        align::run(&ds, &out).expect("align");
        adjust::run(&ds, &out).expect("adjust");
        let text = std::fs::read_to_string(out.join("adjust/calibration.json")).expect("read");
        let mut cal: serde_json::Value = serde_json::from_str(&text).expect("json");
        let result = if model == "triad" {
            &mut cal["triad"][0]
        } else {
            let results = cal["results"].as_array_mut().expect("results");
            results
                .iter_mut()
                .find(|r| r["model"] == model && r["accelerometer"] == "acc1")
                .expect("the thermal fit of acc1")
        };
        if model == "triad" {
            let s = result["parameters"][3]["sigma"].as_f64().expect("sigma");
            result["parameters"][3]["sigma"] = serde_json::json!(-s);
        } else {
            let n = result["parameters"].as_array().expect("parameters").len();
            let mut k4 = result["parameters"][1].clone();
            k4["name"] = serde_json::json!("k4");
            result["parameters"].as_array_mut().expect("p").push(k4);
            for row in result["correlation"].as_array_mut().expect("rows") {
                row.as_array_mut()
                    .expect("row")
                    .push(serde_json::json!(0.0));
            }
            let mut last = vec![serde_json::json!(0.0); n + 1];
            last[n] = serde_json::json!(1.0);
            result["correlation"]
                .as_array_mut()
                .expect("rows")
                .push(serde_json::Value::Array(last));
        }
        let damaged = dir.path().join(format!("{calibrated}-damaged.json"));
        std::fs::write(&damaged, cal.to_string()).expect("write");
        let target_out = dir.path().join(format!("apply-{applied}"));
        let e = run(
            &fixtures::dataset_dir(applied),
            &target_out,
            &Options {
                calibration: &damaged,
                choice: Choice {
                    model: Some(model),
                    session,
                },
            },
        )
        .expect_err(says);
        let msg = e.to_string();
        assert!(
            msg.contains(says) && msg.contains("damaged.json"),
            "{calibrated}: {msg}"
        );
        assert!(!target_out.join("apply").exists(), "{calibrated}: no work");
    }
}

/// Readings in two units (issue 25's "no silent nothing"): a lab stream now serves every
/// session kind (docs/formats.md 9.2), but one fit cannot take counts and volts, and a
/// calibration fitted in counts cannot be applied to readings in m/s^2. The manifest names
/// the session and what would work; apply refuses before any work, naming both units.
#[test]
fn readings_in_two_units_are_refused() {
    let (dir, ds) = copy("esgt-2005-csv", |m| {
        m.replacen(
            "full_scale_g = 2.0",
            "full_scale_g = 2.0\nreading_unit = \"V\"",
            1,
        )
    });
    let e = ingest::run(&ds, &dir.path().join("out")).expect_err("counts read as volts");
    let msg = e.to_string();
    assert!(
        msg.contains("session[0].adc_format")
            && msg.contains("day1")
            && msg.contains("adc_format = \"seconds\""),
        "{msg}"
    );

    let (dir, survey) = copy("triad-multipos", |m| {
        m.replace("kind = \"multi-position\"", "kind = \"survey\"")
            .replace("reading_unit = \"count\"", "reading_unit = \"m/s^2\"")
    });
    let cal_out = dir.path().join("esgt");
    let esgt = fixtures::dataset_dir("esgt-2005");
    ingest::run(&esgt, &cal_out).expect("ingest");
    align::run(&esgt, &cal_out).expect("align");
    adjust::run(&esgt, &cal_out).expect("adjust");
    let out = dir.path().join("out");
    let e = adjust::survey::apply::stream::run(
        &survey,
        &out,
        &adjust::survey::apply::stream::Options {
            calibration: &cal_out.join("adjust/calibration.json"),
            choice: adjust::survey::apply::select::Choice {
                model: Some("thermal"),
                session: None,
            },
        },
    )
    .expect_err("a calibration in counts on readings in m/s^2");
    let msg = e.to_string();
    assert!(
        msg.contains("readings in count") && msg.contains("the survey's are in m/s^2"),
        "{msg}"
    );
    assert!(!out.join("apply").exists(), "refused before any work");
}

/// Output files are named by names joined with `-`, which names may hold: model `t` with
/// session `x-lab` and model `t-x` with session `lab` both wrote `t-x-lab.calib` (the
/// second over the first; the report then refused it as not the file adjust wrote). Adjust
/// now refuses before writing it, naming the file.
#[test]
fn two_calibration_files_named_alike_are_refused() {
    let (dir, ds) = copy("triad-multipos", |m| {
        let start = m.find("[[session]]").expect("session");
        let end = m.find("[[adjust.model]]").expect("model");
        let session = m[start..end].to_owned();
        let twice = session.clone() + &session.replacen("id = \"lab\"", "id = \"x-lab\"", 1);
        m.replacen(&session, &twice, 1).replacen(
            "[[adjust.model]]\nname = \"triad\"\nkind = \"triad\"",
            "[[adjust.model]]\nname = \"t\"\nkind = \"triad\"\n\n\
             [[adjust.model]]\nname = \"t-x\"\nkind = \"triad\"",
            1,
        )
    });
    let out = dir.path().join("out");
    ingest::run(&ds, &out).expect("ingest");
    align::run(&ds, &out).expect("align");
    let msg = adjust::run(&ds, &out)
        .expect_err("one file for two fits")
        .to_string();
    assert!(
        msg.contains("t-x-lab.calib: duplicate file `t-x-lab.calib`: two triad fits"),
        "{msg}"
    );
    assert!(!out.join("adjust/calibration.json").exists(), "{msg}");
}

/// The same for the report's plots: model `lin` with accelerometer `x-acc1` and model
/// `lin-x` with `acc1` drew `lin-x-acc1-day1-residual-dz.svg` twice, the report then
/// showing one fit's plot for both. The report now refuses, naming the plot.
#[test]
fn two_plots_named_alike_are_refused() {
    let (dir, ds) = copy("esgt-2005", |m| {
        m.replacen("id = \"acc2\"", "id = \"x-acc1\"", 1)
            + "\n[[adjust.model]]\nname = \"lin\"\n\n[[adjust.model]]\nname = \"lin-x\"\n"
    });
    let out = dir.path().join("out");
    ingest::run(&ds, &out).expect("ingest");
    align::run(&ds, &out).expect("align");
    adjust::run(&ds, &out).expect("adjust");
    let msg = report::run(&ds, &out)
        .expect_err("one plot for two fits")
        .to_string();
    assert!(
        msg.contains("duplicate plot `lin-x-acc1-day1-") && msg.contains("rename one"),
        "{msg}"
    );
}

/// A fitted result is held to the instrument where it is formed (issue 50): a lab stream
/// whose x channel reads 3 g beyond its zero (another instrument's output, a logger's
/// offset; the ADC declared wide enough to pass it) gives a triad whose bias s_x b_x is
/// beyond the declared full scale of 2 g. It is refused naming the parameter, the bound and
/// the likely causes, and no triad result is written.
#[test]
fn a_bias_beyond_the_full_scale_is_refused_not_written() {
    let (_dir, ds) = copy("triad-multipos", |m| {
        m.replace(
            "reading_unit = \"count\"",
            "reading_unit = \"count\"\nadc_bits = 28",
        )
    });
    let lab = ds.join("raw/lab.txt");
    let text = std::fs::read_to_string(&lab).expect("lab.txt");
    // 3 g at the fixture's 0.243 mGal per count.
    let offset = 3.0 * 980_665.0 / 0.243;
    let shifted: Vec<String> = text
        .lines()
        .map(|l| {
            let mut f: Vec<String> = l.split(',').map(str::to_owned).collect();
            match f.get(1).and_then(|x| x.parse::<f64>().ok()) {
                Some(x) if f.len() == 4 => f[1] = format!("{:.1}", x + offset),
                _ => {}
            }
            f.join(",")
        })
        .collect();
    std::fs::write(&lab, shifted.join("\n") + "\n").expect("lab.txt");
    let out = ds.join("out");
    ingest::run(&ds, &out).expect("ingest");
    align::run(&ds, &out).expect("align");
    let calibration = adjust::run(&ds, &out).expect("adjust writes what it refused");
    assert!(calibration.triad.is_empty(), "no triad result is written");
    let said = &calibration.skipped[0].reason;
    assert!(
        said.contains("implausible: the fitted bias s_x b_x = ")
            && said.contains("beyond the instrument's full scale (+/-2 g")
            && said.contains("adc_columns"),
        "{said}"
    );
}

/// The DGS laptop reader (issue 48) through the same damage as every reader: a line
/// stamped 7 minutes ahead of its neighbours, one 7 minutes behind, a raw gravity the
/// instrument cannot give, and a monitor that is not a number each cost that line alone,
/// counted by reason, the ledger adding up; without `--skip-bad-lines` the last is an error
/// naming the file, the line and the field.
#[test]
fn the_dgs_reader_loses_only_the_damaged_line() {
    let write = |dir: &Path| {
        let ds = dir.join("cruise");
        fixtures::meter::write_cruise(&ds, fixtures::meter::Cruise::new(1200, 7), "none")
            .expect("cruise");
        ds
    };
    let file = "raw/cruise.dat";
    let clean_dir = tempfile::tempdir().expect("tempdir");
    let clean = write(clean_dir.path());
    let clean_report = ingest::run(&clean, &clean_dir.path().join("out")).expect("clean");
    let accepted = ledger(&clean_report, file).accepted;
    assert_eq!(accepted, 1200);
    let minute = |by: i64| -> FieldEdit {
        Box::new(move |f| {
            let m: i64 = f[23].parse().expect("minute");
            f[23] = format!("{:02}", m + by);
        })
    };
    let cases: [(&str, FieldEdit, &str); 4] = [
        ("7 minutes ahead", minute(7), reason::TIME_OUTLIER),
        ("7 minutes behind", minute(-7), reason::TIME_BACKWARDS),
        (
            "implausible gravity",
            Box::new(|f| f[1] = "1e12".to_owned()),
            reason::READING_OUT_OF_RANGE,
        ),
        (
            "a monitor not a number",
            Box::new(|f| f[11] = "x".to_owned()),
            reason::MALFORMED,
        ),
    ];
    for (what, edit, why) in cases {
        let dir = tempfile::tempdir().expect("tempdir");
        let ds = write(dir.path());
        // Line 800 of 1200: minute 13, so 7 either way stays within the hour.
        let line = edit_data_line(&ds.join(file), 799, edit);
        let skip = ingest::Options {
            skip_bad_lines: true,
            progress: false,
        };
        let r = ingest::run_with(&ds, &dir.path().join("out"), &skip)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        let f = ledger(&r, file);
        adds_up(f);
        assert_eq!(
            (f.rejected_total(), f.rejected.get(why)),
            (1, Some(&1)),
            "{what}: {:?}",
            f.rejected
        );
        assert_eq!(f.rejections[0].at, format!("line {line}"), "{what}");
        assert_eq!(f.accepted + 1, accepted, "{what}");
        if why == reason::MALFORMED {
            let e = ingest::run(&ds, &dir.path().join("out2"))
                .expect_err("a bad line without --skip-bad-lines")
                .to_string();
            assert!(
                e.contains(&format!("cruise.dat:{line}: vcc: `x` is not a number")),
                "{e}"
            );
        }
    }
}
