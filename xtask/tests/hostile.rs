//! Hostile inputs, each reproduced from a committed fixture damaged by the test itself (never
//! a hand-edited copy): every case gives the right result or a clear error, and the ledgers
//! still add up. Issue #12 listed them; each test names the case it holds.

use ingest::contract::ingest_ledger::reason;
use std::path::{Path, PathBuf};

/// A copy of fixture `name` in a fresh folder, its manifest passed through `edit`.
fn copy(name: &str, edit: impl FnOnce(String) -> String) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join(name);
    fixtures::copy_dataset(name, &ds, edit).expect("copy");
    (dir, ds)
}

fn out_of(dir: &tempfile::TempDir) -> PathBuf {
    dir.path().join("out")
}

/// Rewrites the frame at `index` of a log of intact frames with `edit` on its bytes, and
/// fixes its CRC.
fn edit_frame(path: &Path, index: usize, edit: impl FnOnce(&mut [u8])) {
    let mut bytes = std::fs::read(path).expect("read log");
    let f = &mut bytes[index * 25..(index + 1) * 25];
    assert_eq!(&f[..2], &[0xA5, 0x5A], "an intact frame at index {index}");
    edit(f);
    let crc = ingest::readers::gcb::crc16_ccitt_false(&f[2..23]);
    f[23..25].copy_from_slice(&crc.to_le_bytes());
    std::fs::write(path, bytes).expect("write log");
}

/// The index of the first frame of type `kind` at or after `from`.
fn frame_of_type(path: &Path, kind: u8, from: usize) -> usize {
    let bytes = std::fs::read(path).expect("read log");
    (from..bytes.len() / 25)
        .find(|i| bytes[i * 25 + 2] == kind)
        .expect("such a frame")
}

fn pipeline(ds: &Path, out: &Path) {
    ingest::run(ds, out).expect("ingest");
    align::run(ds, out).expect("align");
    adjust::run(ds, out).expect("adjust");
    report::run(ds, out).expect("report");
}

fn used_observations(out: &Path) -> u64 {
    let a =
        ingest::contract::align_ledger::AlignReport::load(&out.join("align")).expect("align.json");
    a.counts.iter().map(|c| c.used).sum()
}

/// Case 1: one valid-CRC frame stamped an hour ahead was accepted, and the next 55 829 good
/// frames went `time_backwards`.
#[test]
fn a_frame_stamped_an_hour_ahead_is_rejected_alone() {
    let (clean_dir, clean) = copy("gon-gpst", |m| m);
    pipeline(&clean, &out_of(&clean_dir));
    let (dir, ds) = copy("gon-gpst", |m| m);
    let log = ds.join("raw/s1.gcb");
    let i = frame_of_type(&log, 1, 5000);
    edit_frame(&log, i, |f| {
        let tow = u32::from_le_bytes([f[6], f[7], f[8], f[9]]) + 3_600_000;
        f[6..10].copy_from_slice(&tow.to_le_bytes());
    });
    let out = out_of(&dir);
    let r = ingest::run(&ds, &out).expect("ingest");
    let f = &r.files[0];
    assert_eq!(f.rejected.get(reason::TIME_OUTLIER), Some(&1), "{f:?}");
    assert_eq!(f.rejected_total(), 1);
    assert_eq!(f.accepted + 1, f.read);
    align::run(&ds, &out).expect("align");
    assert_eq!(
        used_observations(&out),
        used_observations(&out_of(&clean_dir))
    );
}

/// Case 1, text: one CSV line with a GPS week outside the session is rejected alone; a
/// week no real log can have (65535, 99999: their times overflowed into a message about
/// 4346874978839345152 ns) is a malformed line naming file, line and field.
#[test]
fn a_csv_line_with_a_wild_week_costs_only_itself() {
    let (dir, ds) = copy("esgt-2005-csv", |m| m);
    let adc = ds.join("raw/day1_adc.csv");
    let text = std::fs::read_to_string(&adc).expect("read");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let k = 20_000;
    let original = lines[k].clone();
    lines[k] = original.replacen("1310,", "1400,", 1);
    std::fs::write(&adc, lines.join("\n") + "\n").expect("write");
    let r = ingest::run(&ds, &out_of(&dir)).expect("ingest");
    let f = r
        .files
        .iter()
        .find(|f| f.path.ends_with("day1_adc.csv"))
        .expect("ledger");
    assert_eq!(f.rejected.get(reason::OUTSIDE_SESSION), Some(&1), "{f:?}");
    assert_eq!(f.rejected_total(), 1);

    for week in ["65535", "99999"] {
        lines[k] = original.replacen("1310", week, 1);
        std::fs::write(&adc, lines.join("\n") + "\n").expect("write");
        let e = ingest::run(&ds, &out_of(&dir)).expect_err("a malformed line");
        let msg = e.to_string();
        assert!(
            msg.contains(&format!("day1_adc.csv:{}: gps_week", k + 1)),
            "{msg}"
        );
        let opts = ingest::Options {
            skip_bad_lines: true,
            progress: false,
        };
        let r = ingest::run_with(&ds, &out_of(&dir), &opts).expect("skipping bad lines");
        let f = r
            .files
            .iter()
            .find(|f| f.path.ends_with("day1_adc.csv"))
            .expect("ledger");
        assert_eq!(f.rejected.get(reason::MALFORMED), Some(&1));
        assert_eq!(f.rejected_total(), 1);
    }
}

/// Case 2: a theodolite log edited after align ran; ingest re-run alone. Adjust used the old
/// align output and recorded the new file's hash. Now every downstream stage refuses.
#[test]
fn stale_and_foreign_upstream_folders_are_refused() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let out = out_of(&dir);
    pipeline(&ds, &out);
    let theodolite = ds.join("raw/s1_theodolite.txt");
    let text = std::fs::read_to_string(&theodolite).expect("read");
    let kept: Vec<&str> = text.lines().filter(|l| !l.contains("T01 ")).collect();
    std::fs::write(&theodolite, kept.join("\n") + "\n").expect("write");

    // Nothing re-run: the raw log no longer matches what ingest read.
    let e = adjust::run(&ds, &out).expect_err("stale raw log");
    let msg = e.to_string();
    assert!(
        msg.contains("s1_theodolite.txt") && msg.contains("re-run from ingest"),
        "{msg}"
    );

    // Ingest re-run alone: align's record of ingest's tables no longer holds.
    ingest::run(&ds, &out).expect("ingest");
    let e = adjust::run(&ds, &out).expect_err("stale align folder");
    let msg = e.to_string();
    assert!(msg.contains("ingest/"), "names ingest's table: {msg}");
    assert!(msg.contains("re-run from align"), "{msg}");
    let e = report::run(&ds, &out).expect_err("stale chain");
    assert!(e.to_string().contains("re-run from align"), "{e}");

    // Re-run onward: accepted again, and calibration.json names the new log's hash.
    align::run(&ds, &out).expect("align");
    let c = adjust::run(&ds, &out).expect("adjust");
    let sha = ingest::contract::custody::sha256_file(&theodolite).expect("hash");
    assert!(c.inputs.iter().any(|i| i.sha256 == sha));
    report::run(&ds, &out).expect("report");

    // Another dataset's folder.
    let (_d2, other) = copy("week-rollover", |m| m);
    let e = align::run(&other, &out).expect_err("foreign folder");
    let msg = e.to_string();
    assert!(msg.contains("not `week-rollover`"), "{msg}");
}

/// Case 3: Dz logged to 0.001 deg makes the readings of a station all equal; their sd was 0,
/// an infinite weight. Now the floor is the quantisation of the log, with eq. 4 (where such
/// a station takes it exactly) as with the default moderated variances.
#[test]
fn coarsely_logged_readings_get_the_quantisation_floor() {
    for method in ["station", "moderated"] {
        coarsely_logged(method);
    }
}

fn coarsely_logged(method: &str) {
    let (dir, ds) = copy("esgt-2005", |m| {
        format!("{m}\n[align]\nsigma_dz = \"{method}\"\n")
    });
    for day in ["day1", "day2"] {
        let p = ds.join(format!("raw/{day}_theodolite.txt"));
        let text = std::fs::read_to_string(&p).expect("read");
        let rounded: Vec<String> = text
            .lines()
            .map(|l| {
                let f: Vec<&str> = l.split_whitespace().collect();
                if l.starts_with('#') || f.len() != 3 {
                    return l.to_owned();
                }
                let dz: f64 = f[2].parse().expect("dz");
                format!("{} {} {:.3}", f[0], f[1], dz)
            })
            .collect();
        std::fs::write(&p, rounded.join("\n") + "\n").expect("write");
    }
    let out = out_of(&dir);
    pipeline(&ds, &out);
    let a =
        ingest::contract::align_ledger::AlignReport::load(&out.join("align")).expect("align.json");
    assert!(a.errors.is_empty());
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005")).expect("truth");
    let c =
        ingest::contract::calibration::Calibration::load(&out.join("adjust")).expect("calibration");
    let floor = (0.001f64).to_radians() / 12f64.sqrt();
    let rows =
        ingest::contract::tables::observations::read(&out.join("align")).expect("observations");
    assert!(rows.len() > 600, "{} observations", rows.len());
    assert!(rows.iter().all(|o| o.sigma_dz_rad >= floor * (1.0 - 1e-9)));
    if method == "station" {
        assert!(
            rows.iter()
                .any(|o| (o.sigma_dz_rad / floor - 1.0).abs() < 1e-9),
            "some station's readings are all equal and take the floor"
        );
    }
    for r in c.results.iter().filter(|r| r.model == "linear") {
        let t = truth
            .session
            .iter()
            .find(|s| s.id == r.session)
            .and_then(|s| {
                s.calibration
                    .iter()
                    .find(|t| t.accelerometer == r.accelerometer)
            })
            .expect("truth");
        let b = &r.parameters[0];
        assert!(
            (b.value - t.b_mgal).abs() < 3.0 * b.sigma,
            "{} {}: b {} +/- {} vs {}",
            r.accelerometer,
            r.session,
            b.value,
            b.sigma,
            t.b_mgal
        );
    }
}

/// Case 3: a reading of Dz = 0 exactly made fits fail with `condition 9 has zero variance`.
#[test]
fn a_reading_at_dz_zero_is_a_blunder_not_a_crash() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let p = ds.join("raw/s1_theodolite.txt");
    let text = std::fs::read_to_string(&p).expect("read");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let k = lines
        .iter()
        .position(|l| !l.starts_with('#'))
        .expect("a reading")
        + 9;
    let f: Vec<String> = lines[k].split_whitespace().map(str::to_owned).collect();
    lines[k] = format!("{} {} 0", f[0], f[1]);
    std::fs::write(&p, lines.join("\n") + "\n").expect("write");
    let out = out_of(&dir);
    pipeline(&ds, &out);
    let c =
        ingest::contract::calibration::Calibration::load(&out.join("adjust")).expect("calibration");
    assert!(c.skipped.is_empty(), "{:?}", c.skipped);
    for r in &c.results {
        assert!(
            r.removed.iter().any(|x| x.line as usize == k + 1),
            "{}: the Dz = 0 reading (line {}) is removed as a blunder: {:?}",
            r.accelerometer,
            k + 1,
            r.removed
        );
    }
}

/// Case 4: 50 000 degC in a valid binary frame reached the observations.
#[test]
fn an_implausible_binary_temperature_is_rejected() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let log = ds.join("raw/s1.gcb");
    let i = frame_of_type(&log, 2, 100);
    edit_frame(&log, i, |f| {
        f[10..14].copy_from_slice(&50_000_000i32.to_le_bytes())
    });
    let r = ingest::run(&ds, &out_of(&dir)).expect("ingest");
    let f = &r.files[0];
    assert_eq!(
        f.rejected.get(reason::TEMPERATURE_OUT_OF_RANGE),
        Some(&1),
        "{f:?}"
    );
    assert_eq!(f.read, f.accepted + f.rejected_total());
}

/// Case 5: two runs into one output folder left unreadable Parquet files under final names.
#[test]
fn a_second_run_into_the_same_folder_fails_at_once() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let out = out_of(&dir);
    ingest::run(&ds, &out).expect("ingest");
    let table = out.join("ingest/acceleration.parquet");
    let before = std::fs::read(&table).expect("table");
    // This process holds the lock, as a running pipeline would; another process is refused.
    let _held = ingest::base::lock::OutputLock::acquire(&out).expect("lock");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(["ingest", ds.to_str().expect("utf-8"), "--out"])
        .arg(&out)
        .output()
        .expect("xtask runs");
    assert!(!o.status.success());
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        stderr.contains("another gravcal run is writing"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(&table).expect("table"), before);
}

/// Also seen: an acquisition path `../../../../etc/passwd` (or absolute) was read.
#[test]
fn paths_must_stay_inside_the_dataset() {
    for path in ["../../../../etc/passwd", "/etc/passwd"] {
        let (_dir, ds) = copy("gon-gpst", |m| {
            m.replace(
                "acquisition = \"raw/s1.gcb\"",
                &format!("acquisition = \"{path}\""),
            )
        });
        let e = ingest::run(&ds, &ds.join("out")).expect_err("outside");
        let msg = e.to_string();
        assert!(
            msg.contains("session[0].acquisition") && msg.contains("outside the dataset folder"),
            "{msg}"
        );
    }
}

/// Also seen: a session whose log is empty, random or has no usable frame yielded nothing
/// and the run exited 0.
#[test]
fn a_session_without_data_is_an_error_unless_expected() {
    for content in [
        Vec::new(),
        (0..5000u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
            .collect(),
    ] {
        let (dir, ds) = copy("esgt-2005", |m| m);
        std::fs::write(ds.join("raw/day2.gcb"), &content).expect("write");
        let e = ingest::run(&ds, &out_of(&dir)).expect_err("a lost day");
        let msg = e.to_string();
        assert!(
            msg.contains("session day2") && msg.contains("expect_empty"),
            "{msg}"
        );
        // The ledger is written, and downstream stages refuse it.
        let e = align::run(&ds, &out_of(&dir)).expect_err("refused");
        assert!(e.to_string().contains("session day2"), "{e}");
    }
    let (dir, ds) = copy("esgt-2005", |m| {
        m.replace(
            "acquisition = \"raw/day2.gcb\"",
            "acquisition = \"raw/day2.gcb\"\nexpect_empty = true",
        )
    });
    std::fs::write(ds.join("raw/day2.gcb"), b"").expect("write");
    ingest::run(&ds, &out_of(&dir)).expect("declared empty");
}

/// Also seen: a declared rate of 250 Hz on 31.25 Hz data only showed as every window
/// `window_underfilled`.
#[test]
fn a_sample_rate_off_the_declared_one_is_an_error() {
    let (dir, ds) = copy("gon-gpst", |m| {
        m.replace("sample_rate_hz = 31.25", "sample_rate_hz = 250.0")
    });
    let e = ingest::run(&ds, &out_of(&dir)).expect_err("wrong rate");
    let msg = e.to_string();
    assert!(msg.contains("31.25") && msg.contains("250"), "{msg}");
}

/// Also seen: a UTF-8 BOM before the first theodolite line became part of a station name;
/// a manifest that is not UTF-8 gave no position.
#[test]
fn byte_order_marks_and_bad_encodings() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let p = ds.join("raw/s1_theodolite.txt");
    let text = std::fs::read_to_string(&p).expect("read");
    let body: String = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .collect::<Vec<_>>()
        .join("\n");
    std::fs::write(&p, format!("\u{feff}{body}\n")).expect("write");
    let out = out_of(&dir);
    ingest::run(&ds, &out).expect("ingest");
    align::run(&ds, &out).expect("align");
    let rows =
        ingest::contract::tables::observations::read(&out.join("align")).expect("observations");
    assert!(!rows.is_empty(), "observations from the log with a BOM");
    assert!(
        rows.iter().all(|o| o.station.starts_with('T')),
        "{:?}",
        rows[0].station
    );

    let manifest = ds.join("dataset.toml");
    let mut bytes = std::fs::read(&manifest).expect("read");
    bytes.insert(40, 0xff);
    std::fs::write(&manifest, bytes).expect("write");
    let e = ingest::run(&ds, &out).expect_err("not UTF-8");
    assert!(e.to_string().contains("byte 40: not UTF-8"), "{e}");
}

/// Also seen: a design with constant Dz printed k = 1e-17 +/- 5e-18; one station gave "no
/// convergence after 50 iterations". Both now name k as not estimable.
#[test]
fn one_tilt_position_names_what_it_cannot_determine() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let p = ds.join("raw/s1_theodolite.txt");
    let text = std::fs::read_to_string(&p).expect("read");
    let mut first: Option<(String, String)> = None;
    let same: Vec<String> = text
        .lines()
        .map(|l| {
            let f: Vec<&str> = l.split_whitespace().collect();
            if l.starts_with('#') || f.len() != 3 {
                return l.to_owned();
            }
            let (station, dz) = first.get_or_insert((f[0].to_owned(), f[2].to_owned()));
            format!("{station} {} {dz}", f[1])
        })
        .collect();
    std::fs::write(&p, same.join("\n") + "\n").expect("write");
    let out = out_of(&dir);
    ingest::run(&ds, &out).expect("ingest");
    align::run(&ds, &out).expect("align");
    let c = adjust::run(&ds, &out).expect("adjust");
    assert!(c.results.is_empty());
    assert_eq!(c.skipped.len(), 3);
    for s in &c.skipped {
        assert!(
            s.reason.contains("parameter k is not estimable")
                && s.reason.contains("1 tilt position"),
            "{}",
            s.reason
        );
    }
    report::run(&ds, &out).expect("report");
}

/// Also seen: the report caption read "Align (window of  s, fill >= )".
#[test]
fn the_align_caption_has_its_numbers() {
    let (dir, ds) = copy("gon-gpst", |m| m);
    let out = out_of(&dir);
    pipeline(&ds, &out);
    let md = std::fs::read_to_string(out.join("report/report.md")).expect("report.md");
    assert!(
        md.contains("Align (window of 2.56 s, fill >= 0.8)"),
        "caption"
    );
}
