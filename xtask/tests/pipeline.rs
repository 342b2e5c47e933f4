//! `cargo xtask pipeline` and the stages run one by one give the same outputs.

use std::path::Path;
use std::process::Command;

fn xtask(args: &[&str], out: &Path) {
    let o = Command::new(env!("CARGO_BIN_EXE_xtask"))
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .expect("xtask runs");
    assert!(
        o.status.success(),
        "xtask {args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn pipeline_and_stages_one_by_one_agree() {
    let dataset = fixtures::dataset_dir("esgt-2005");
    let ds = dataset.to_str().expect("utf-8 path");
    let a = tempfile::tempdir().expect("tempdir");
    let b = tempfile::tempdir().expect("tempdir");
    xtask(&["pipeline", ds], a.path());
    for stage in ["ingest", "align", "adjust", "report"] {
        xtask(&[stage, ds], b.path());
    }
    for file in [
        "adjust/calibration.json",
        "adjust/residuals.parquet",
        "align/observations.parquet",
        "report/report.md",
        "report/index.html",
    ] {
        let x = std::fs::read(a.path().join(file)).expect("pipeline output");
        let y = std::fs::read(b.path().join(file)).expect("stage output");
        assert!(x == y, "{file} differs between pipeline and stages");
    }
}
