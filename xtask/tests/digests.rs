//! The refactoring net (issue 51): the six stages on every fixture summarised and held to
//! the committed summary, `fixtures/digests.txt` (`cargo xtask digest`, the README):
//! each table's column sums and each ledger's values to 1e-9 of their scale, every other
//! output to its SHA-256. A change meant is written again with `cargo xtask digest --write
//! fixtures/digests.txt` and shows in the commit's diff, key by key.

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn digest_check(summary: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_xtask"))
        .current_dir(root())
        .args(["digest", "--check"])
        .arg(summary)
        .output()
        .expect("xtask runs")
}

/// Every fixture's outputs as committed; and the same run against a summary with one
/// column's sum moved by 1e-6 of it fails, naming that column.
#[test]
fn every_fixture_s_outputs_are_the_committed_ones() {
    let committed = root().join("fixtures/digests.txt");
    let o = digest_check(&committed);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success(),
        "{}",
        &err[err.len().saturating_sub(4000)..]
    );
    let text = std::fs::read_to_string(&committed).expect("digests.txt");
    let key = "survey-lines/gravity/gravity.parquet down_filtered_mgal.sum ";
    let line = text
        .lines()
        .find(|l| l.starts_with(key))
        .expect("gravity's down");
    let (value, scale) = line[key.len()..]
        .split_once(' ')
        .expect("a sum and its scale");
    let value: f64 = value
        .strip_prefix('f')
        .and_then(|v| v.parse().ok())
        .expect("a float");
    let scale: f64 = scale
        .strip_prefix('f')
        .and_then(|v| v.parse().ok())
        .expect("a float");
    // Beyond the tolerance (1e-9 of the scale) by a thousand times.
    let moved = text.replacen(
        line,
        &format!("{key}f{:.15e} f{scale:.15e}", value + 1e-6 * scale),
        1,
    );
    let dir = tempfile::tempdir().expect("tempdir");
    let altered = dir.path().join("digests.txt");
    std::fs::write(&altered, moved).expect("write");
    let o = digest_check(&altered);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a moved sum passed");
    assert!(err.contains("down_filtered_mgal.sum"), "{err}");
}
