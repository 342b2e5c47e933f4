//! `cargo xtask init` on each committed fixture's raw/ (docs/formats.md 9.3): the draft is
//! refused until its "FILL IN" lines are filled; filled from the committed manifest (each
//! marked line, and each commented optional line whose key the committed manifest sets,
//! with the committed value; the committed `[[adjust.model]]` and `[align]` tables, which
//! are the experimenter's choices and not in any log), it calibrates to the committed
//! manifest's numbers. It never overwrites a manifest.

use std::path::Path;
use std::process::Command;
use toml::Value;

fn xtask(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .output()
        .expect("xtask runs")
}

/// The committed value of `key` in the table the draft's line belongs to.
fn committed_value<'a>(
    committed: &'a Value,
    table: &str,
    index: usize,
    session: Option<&str>,
    key: &str,
) -> Option<&'a Value> {
    match table {
        "site" | "instrument" | "align" => committed.get(table)?.get(key),
        "instrument.accelerometer" => committed
            .get("instrument")?
            .get("accelerometer")?
            .as_array()?
            .get(index)?
            .get(key),
        "session" => committed
            .get("session")?
            .as_array()?
            .iter()
            .find(|s| s.get("id").and_then(Value::as_str) == session)?
            .get(key),
        _ => None,
    }
}

/// The draft filled as the module says.
fn fill(draft: &str, committed: &Value) -> String {
    let draft = draft.split("\n[[adjust.model]]").next().unwrap_or(draft);
    let (mut table, mut index, mut session) = (String::new(), 0usize, None::<String>);
    let mut counts = std::collections::BTreeMap::<String, usize>::new();
    let mut out = String::new();
    for line in draft.lines() {
        let t = line.trim();
        if t.starts_with('[') && !t.starts_with("# ") {
            table = t.trim_matches(|c| c == '[' || c == ']').to_owned();
            let n = counts.entry(table.clone()).or_default();
            index = *n;
            *n += 1;
            session = None;
        }
        if table == "session" && t.starts_with("id = ") {
            session = Some(t.trim_start_matches("id = ").trim_matches('"').to_owned());
        }
        let body = t.strip_prefix("# ").unwrap_or(t);
        let key = body.split(" = ").next().unwrap_or("");
        let marked = !t.starts_with('#') && t.contains("= \"FILL IN\"");
        let optional = t.starts_with("# ")
            && body.contains(" = ")
            && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if marked || optional {
            match committed_value(committed, &table, index, session.as_deref(), key) {
                Some(v) => {
                    out.push_str(&format!("{key} = {v}\n"));
                    continue;
                }
                None if marked => panic!("[{table}] {key} is marked but not in the manifest"),
                None => {}
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    let mut rest = toml::map::Map::new();
    for k in ["adjust", "align"] {
        if let Some(v) = committed.get(k) {
            rest.insert(k.to_owned(), v.clone());
        }
    }
    out + "\n" + &toml::to_string(&Value::Table(rest)).expect("toml")
}

fn calibrate(ds: &Path, out: &Path) -> ingest::contract::calibration::Calibration {
    ingest::run(ds, out).expect("ingest");
    align::run(ds, out).expect("align");
    adjust::run(ds, out).expect("adjust")
}

#[test]
fn a_draft_filled_in_calibrates_as_the_committed_manifest() {
    for name in fixtures::catalog::ALL {
        let committed_dir = fixtures::dataset_dir(name);
        let dir = tempfile::tempdir().expect("tempdir");
        let ds = dir.path().join(name);
        fixtures::copy_dataset(name, &ds, |m| m).expect("copy");
        std::fs::remove_file(ds.join("dataset.toml")).expect("remove");
        let o = xtask(&["init", ds.to_str().expect("utf-8")]);
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let draft = std::fs::read_to_string(ds.join("dataset.toml")).expect("draft");
        assert!(
            draft.contains("g_abs_mgal = \"FILL IN\""),
            "{name}: {draft}"
        );
        // Refused as it is.
        assert!(
            ingest::contract::manifest::Dataset::load(&ds).is_err(),
            "{name}: the draft validates unfilled"
        );
        // Never over a manifest.
        let again = xtask(&["init", ds.to_str().expect("utf-8")]);
        assert!(!again.status.success(), "{name}: init overwrote its draft");

        let text = std::fs::read_to_string(committed_dir.join("dataset.toml")).expect("m");
        let committed: Value = toml::from_str(&text).expect("committed toml");
        let filled = fill(&draft, &committed);
        std::fs::write(ds.join("dataset.toml"), &filled).expect("write");
        if name == "survey" {
            ingest::run(&ds, &dir.path().join("out")).expect("the survey's draft ingests");
            continue;
        }
        let x = calibrate(&committed_dir, &dir.path().join("committed"));
        let y = calibrate(&ds, &dir.path().join("draft"));
        let mut compared = 0;
        for a in &x.results {
            let b = y
                .results
                .iter()
                .find(|b| {
                    (&b.model, &b.session, &b.accelerometer)
                        == (&a.model, &a.session, &a.accelerometer)
                })
                .unwrap_or_else(|| {
                    panic!(
                        "{name}: {} {} {} not fitted from the draft\n{filled}",
                        a.model, a.session, a.accelerometer
                    )
                });
            for (p, q) in a.parameters.iter().zip(&b.parameters) {
                assert!(
                    (p.value - q.value).abs() <= 1e-9 * p.value.abs().max(p.sigma)
                        && (p.sigma - q.sigma).abs() <= 1e-9 * p.sigma,
                    "{name}: {} {} {}: {} ± {} vs {} ± {}",
                    a.model,
                    a.accelerometer,
                    p.name,
                    p.value,
                    p.sigma,
                    q.value,
                    q.sigma
                );
            }
            compared += 1;
        }
        for a in &x.triad {
            let b = y
                .triad
                .iter()
                .find(|b| b.model == a.model)
                .expect("triad from the draft");
            for (p, q) in a.parameters.iter().zip(&b.parameters) {
                assert!(
                    (p.value - q.value).abs() <= 1e-9 * p.value.abs().max(p.sigma),
                    "{name}: triad {}",
                    p.name
                );
            }
            compared += 1;
        }
        assert!(compared > 0, "{name}: nothing compared");
    }
}
