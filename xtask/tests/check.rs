//! `cargo xtask check`: every committed fixture checks, printing each log with what was read
//! of it; a bad line in a log's tail is the error a full ingest gives, naming the dataset's
//! own file, the line's number in it and the field.

use std::path::Path;
use std::process::{Command, Output};

fn check(dataset: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .arg("check")
        .arg(dataset)
        .output()
        .expect("xtask runs")
}

#[test]
fn every_fixture_checks_and_every_log_is_listed() {
    for name in fixtures::catalog::ALL {
        let dir = fixtures::dataset_dir(name);
        let o = check(&dir);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{name}: {text}");
        for entry in std::fs::read_dir(dir.join("raw")).expect("raw") {
            let file = entry.expect("entry").file_name();
            let file = file.to_string_lossy();
            assert!(
                text.contains(&format!("raw/{file} (session")),
                "{name}: {file} in\n{text}"
            );
        }
        assert!(text.contains("accepted, first "), "{name}: {text}");
    }
}

#[test]
fn a_bad_line_in_the_tail_is_named_as_ingest_names_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("esgt");
    fixtures::copy_dataset("esgt-2005-csv", &ds, |m| m).expect("copy");
    let adc = ds.join("raw/day1_adc.csv");
    let text = std::fs::read_to_string(&adc).expect("read");
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let n = lines.len();
    // The fifth line from the end: its third field is not a count.
    let bad = n - 5;
    let mut fields: Vec<String> = lines[bad].split(',').map(str::to_owned).collect();
    fields[2] = "12x4".to_owned();
    lines[bad] = fields.join(",");
    std::fs::write(&adc, lines.join("\n") + "\n").expect("write");

    let o = check(&ds);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!o.status.success(), "{out}");
    let line_no = bad + 1;
    assert!(
        out.contains(&format!("{}:{line_no}: c1: `12x4`", adc.display())),
        "names {}, line {line_no} and the field:\n{out}",
        adc.display()
    );
    assert!(
        !out.contains("gravcal-check-"),
        "the scratch copy is not named: {out}"
    );

    // A full ingest gives the same message.
    let full = ingest::run(&ds, &dir.path().join("out"))
        .expect_err("ingest fails too")
        .to_string();
    assert!(
        out.contains(&full),
        "check said\n{out}\ningest said\n{full}"
    );
}

/// An empty lab stream: check fails, says none was read and no rate measured, and names no
/// scratch folder (the error named check's own ingest.json, deleted when it returned); it
/// claims no separator or header for a file without a line.
#[test]
fn an_empty_lab_stream_is_refused_without_naming_the_scratch_copy() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("triad");
    fixtures::copy_dataset("triad-multipos", &ds, |m| m).expect("copy");
    std::fs::write(ds.join("raw/lab.txt"), "").expect("empty");
    let o = check(&ds);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(!o.status.success(), "{out}");
    assert!(out.contains("0 lines read, 0 accepted"), "{out}");
    assert!(out.contains("rate: none measured"), "{out}");
    assert!(!out.contains("separated"), "{out}");
    assert!(
        out.contains("OUT/ingest/ingest.json: session lab: raw/lab.txt gave no usable"),
        "{out}"
    );
    assert!(!out.contains("gravcal-check-"), "{out}");
}

/// A trajectory in a subfolder of the dataset checks as `gravity` reads it (check failed
/// copying it into its scratch copy); one outside the dataset is refused by key, the file
/// untouched.
#[test]
fn a_trajectory_in_a_subfolder_or_outside_checks() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("lines");
    fixtures::copy_dataset(fixtures::survey_lines::SURVEY_LINES, &ds, |m| {
        m.replace(
            "trajectory = \"raw/lines.pos\"",
            "trajectory = \"gnss/lines.pos\"",
        )
    })
    .expect("copy");
    std::fs::create_dir_all(ds.join("gnss")).expect("gnss/");
    std::fs::rename(ds.join("raw/lines.pos"), ds.join("gnss/lines.pos")).expect("move");
    let o = check(&ds);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(text.contains("gnss/lines.pos"), "{text}");
    let outside = dir.path().join("elsewhere.pos");
    std::fs::rename(ds.join("gnss/lines.pos"), &outside).expect("move");
    let before = std::fs::metadata(&outside).expect("outside").len();
    let manifest = std::fs::read_to_string(ds.join("dataset.toml")).expect("manifest");
    let toml_path = toml::Value::String(outside.display().to_string()).to_string();
    std::fs::write(
        ds.join("dataset.toml"),
        manifest.replace("\"gnss/lines.pos\"", &toml_path),
    )
    .expect("manifest");
    let o = check(&ds);
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        !o.status.success(),
        "a trajectory outside the dataset checked"
    );
    assert!(
        said.contains("session[0].trajectory") && said.contains("outside the dataset"),
        "{said}"
    );
    assert_eq!(std::fs::metadata(&outside).expect("outside").len(), before);
}
