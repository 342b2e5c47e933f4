//! The adjustment against problems with published answers (`tests/reference/`, their public data and provenance): NIST StRD
//! linear regression and York's errors-in-both-variables line on Pearson's data.

use std::path::PathBuf;

fn reference() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/reference")
}

fn read_csv(path: &std::path::Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).expect("reference csv");
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let header: Vec<String> = lines
        .next()
        .expect("header")
        .split(',')
        .map(|s| s.trim().to_owned())
        .collect();
    let rows = lines
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse::<f64>().expect("number"))
                .collect()
        })
        .collect();
    (header, rows)
}

/// Log relative error: the number of correct significant digits.
fn lre(computed: f64, certified: f64) -> f64 {
    if certified == 0.0 {
        return if computed == 0.0 {
            15.0
        } else {
            -computed.abs().log10()
        };
    }
    let rel = ((computed - certified) / certified).abs();
    if rel == 0.0 { 15.0 } else { -rel.log10() }
}

fn num(v: &serde_json::Value) -> f64 {
    match v {
        serde_json::Value::String(s) => s.parse().expect("decimal string"),
        serde_json::Value::Number(n) => n.as_f64().expect("f64"),
        other => panic!("not a number: {other}"),
    }
}

#[test]
fn nist_strd_linear_regression() {
    let certified: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(reference().join("nist/certified.json")).expect("certified.json"),
    )
    .expect("json");
    let obj = certified.as_object().expect("object");
    let mut report = Vec::new();
    for (name, c) in obj {
        let Some(degree) = c.get("degree").and_then(serde_json::Value::as_u64) else {
            continue;
        };
        let (_, rows) = read_csv(&reference().join(format!("nist/{name}.csv")));
        let x: Vec<f64> = rows.iter().map(|r| r[0]).collect();
        let y: Vec<f64> = rows.iter().map(|r| r[1]).collect();
        let out = adjust::fit::fit(&x, &y, None, None, degree as usize)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let need = if name == "Filip" { 7.0 } else { 9.0 };
        let params = c
            .get("parameters")
            .and_then(serde_json::Value::as_array)
            .expect("parameters");
        let est: Vec<f64> = params.iter().map(|p| num(&p["value"])).collect();
        let sds: Vec<f64> = params.iter().map(|p| num(&p["sigma"])).collect();
        assert_eq!(est.len(), out.parameters.len(), "{name}");
        let mut worst: f64 = 15.0;
        let mut worst_est: f64 = 15.0;
        for (j, p) in out.parameters.iter().enumerate() {
            worst = worst.min(lre(p.value, est[j]));
            worst_est = worst_est.min(lre(p.value, est[j]));
            if sds[j] == 0.0 {
                // Exact fits (Wampler1, 2): the sd must be tiny relative to the estimate.
                assert!(
                    p.sigma <= 1e-9 * p.value.abs().max(1.0),
                    "{name} p{j}: sd {} for an exact fit",
                    p.sigma
                );
            } else {
                worst = worst.min(lre(p.sigma, sds[j]));
            }
        }
        let rsd = num(&c["residual_sd"]);
        if rsd != 0.0 {
            worst = worst.min(lre(out.residual_sd, rsd));
        }
        report.push(format!(
            "{name}: LRE {worst:.1} (estimates {worst_est:.1}; need {need})"
        ));
        assert!(worst >= need, "{}", report.join("\n"));
    }
    assert!(report.len() >= 8, "{report:?}");
    eprintln!("{}", report.join("\n"));
}

#[test]
fn york_line_on_pearson_data() {
    let (header, rows) = read_csv(&reference().join("york-pearson.csv"));
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("column {name} in {header:?}"))
    };
    let (xi, yi, sxi, syi) = (col("x"), col("y"), col("sigma_x"), col("sigma_y"));
    let x: Vec<f64> = rows.iter().map(|r| r[xi]).collect();
    let y: Vec<f64> = rows.iter().map(|r| r[yi]).collect();
    let sx: Vec<f64> = rows.iter().map(|r| r[sxi]).collect();
    let sy: Vec<f64> = rows.iter().map(|r| r[syi]).collect();
    let out = adjust::fit::fit(&x, &y, Some(&sx), Some(&sy), 1).expect("fit");
    let (a, b) = (&out.parameters[0], &out.parameters[1]);
    let checks = [
        (a.value, 5.479910224),
        (b.value, -0.480533407),
        (a.sigma_apriori, 0.2949707355),
        (b.sigma_apriori, 0.0579850090),
        (a.sigma, 0.3592465226),
        (b.sigma, 0.0706202695),
        (out.sigma0.powi(2) * out.dof as f64, 11.8663531941),
    ];
    for (i, (got, want)) in checks.iter().enumerate() {
        assert!(
            lre(*got, *want) >= 9.0,
            "check {i}: {got} vs {want} (LRE {:.1})",
            lre(*got, *want)
        );
    }
}
