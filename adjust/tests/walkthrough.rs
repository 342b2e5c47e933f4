//! docs/calibrate-your-own.md, followed as printed: its manifest (the TOML block after the
//! `walkthrough-manifest` marker) over the replica's CSV logs calibrates the three
//! accelerometers within their sigmas of the truth the logs were simulated from.

use std::path::Path;

/// The walkthrough's manifest, as the page prints it.
fn manifest_of_the_walkthrough() -> String {
    let page = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/calibrate-your-own.md");
    let text = std::fs::read_to_string(&page).expect("docs/calibrate-your-own.md");
    let after = text
        .split_once("<!-- walkthrough-manifest -->")
        .expect("the marker")
        .1;
    let block = after.split_once("```toml\n").expect("a toml block").1;
    block.split_once("```").expect("its end").0.to_owned()
}

#[test]
fn the_walkthrough_manifest_calibrates_within_its_sigmas() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = dir.path().join("my-calibration");
    fixtures::copy_dataset("esgt-2005-csv", &ds, |m| m).expect("copy");
    std::fs::write(ds.join("dataset.toml"), manifest_of_the_walkthrough()).expect("manifest");
    let out = dir.path().join("out");
    ingest::run(&ds, &out).expect("ingest");
    align::run(&ds, &out).expect("align");
    let c = adjust::run(&ds, &out).expect("adjust");
    let truth = fixtures::read_truth(&fixtures::dataset_dir("esgt-2005-csv")).expect("truth");
    let mut checked = 0;
    for r in c.results.iter().filter(|r| r.model == "thermal") {
        let a = truth
            .accelerometer
            .iter()
            .find(|a| a.id == r.accelerometer)
            .expect("acc");
        let dt = r.t_ref_c.expect("t_ref") - truth.t_ref_c;
        for (name, t) in [
            ("b", a.b_mgal + a.b_t_mgal_per_c * dt),
            ("k", a.k_mgal_per_bit + a.k_t_mgal_per_bit_per_c * dt),
            ("b_t", a.b_t_mgal_per_c),
            ("k_t", a.k_t_mgal_per_bit_per_c),
        ] {
            let p = r
                .parameters
                .iter()
                .find(|p| p.name == name)
                .expect("parameter");
            let z = (p.value - t) / p.sigma;
            // 3.45: Bonferroni's 1 % family-wise bound over the checked parameters.
            assert!(z.abs() < 3.45, "{} {name}: z {z}", r.accelerometer);
            checked += 1;
        }
    }
    // acc2 was disconnected on day 2: its thermal fit has one temperature, and is skipped.
    assert_eq!(checked, 8, "acc1 and acc3's thermal fits");
    assert!(
        c.results
            .iter()
            .any(|r| r.model == "linear" && r.session == "day1")
    );
}
