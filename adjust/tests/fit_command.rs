//! The `fit` command as a user calls it: the binary reads a CSV table and prints JSON.

use std::process::Command;

fn fit(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_gravcal-adjust"))
        .arg("fit")
        .args(args)
        .output()
        .expect("binary runs")
}

#[test]
fn fit_prints_the_certified_norris_line() {
    let csv = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/reference/nist/Norris.csv"
    );
    let o = fit(&["--input", csv, "--x", "x", "--y", "y", "--degree", "1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON on stdout");
    let p1 = v["parameters"][1]["value"].as_f64().expect("p1");
    assert!((p1 - 1.002_116_818_020_45).abs() < 1e-12, "{p1}");
    assert_eq!(v["parameters"][0]["name"], "p0");
    assert_eq!(v["dof"], 34);
    for key in ["sigma0", "residual_sd", "iterations"] {
        assert!(v[key].is_number(), "{key}");
    }
}

#[test]
fn fit_names_a_missing_column_and_a_bad_value() {
    let csv = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/reference/york-pearson.csv"
    );
    let o = fit(&["--input", csv, "--x", "x", "--y", "yy"]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("york-pearson.csv") && e.contains("no column `yy`"),
        "{e}"
    );

    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("bad.csv");
    // `x` against `y` of bad.csv, as it stands.
    let fit_bad = || {
        fit(&[
            "--input",
            bad.to_str().expect("utf-8"),
            "--x",
            "x",
            "--y",
            "y",
        ])
    };
    std::fs::write(&bad, "x,y\n1,2\n2,oops\n3,4\n").expect("write");
    let o = fit_bad();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("bad.csv:3: y: `oops` is not a number"),
        "{e}"
    );

    // A short line names the field missing, a column named twice is refused, a
    // spreadsheet's quotes are read through, an overflow's figures are printed short.
    for (text, said) in [
        (
            "x,y\n1,2\n2\n3,4\n",
            "bad.csv:3: y: missing (the line has 1 field(s), the header 2)",
        ),
        (
            "x,y,y\n1,2,3\n2,3,4\n3,4,5\n",
            "two columns are named `y` (columns 2 and 3)",
        ),
        (
            "x,y\n1e300,2\n2e300,4.1\n3e300,5.9\n",
            "p1 came out as 1.95e-300 with an a-priori sd of 0e0: the arithmetic",
        ),
    ] {
        std::fs::write(&bad, text).expect("write");
        let o = fit_bad();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && e.contains(said), "{said}: {e}");
    }
    std::fs::write(&bad, "\"x\",\"y\"\n\"1\",\"2\"\n2,4.1\n3,5.9\n4,8.2\n").expect("write");
    let o = fit_bad();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
