//! The body tide against two references run side by side: ETERNA (through PyGTide) and an
//! independent Longman implementation (tidegravity), both in Python from the peers'
//! virtual environment that `.ci/peers-venv.sh` makes (`GRAVCAL_PEERS_PYTHON` names another
//! interpreter; `GRAVCAL_SKIP_PEERS=1` leaves this test out and says so).

use align::tide::{Site, body_tide_mgal, utc_seconds_of_gps};
use ingest::base::time::{gps_ns, parse_calendar};
use ingest::contract::manifest::TimeScale;
mod peers;

use peers::peers_python;
use std::path::PathBuf;
use std::process::Command;

/// (utc seconds since the GPS epoch, ETERNA, Longman in Python), mGal.
fn reference(py: &PathBuf, site: Site, start: &str, hours: u32) -> Vec<(f64, f64, f64)> {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/tide_reference.py");
    let dir = tempfile::tempdir().expect("tempdir");
    let o = Command::new(py)
        .arg(&script)
        .args([
            site.latitude_deg.to_string(),
            site.longitude_deg.to_string(),
            site.height_m.to_string(),
            start.to_owned(),
            hours.to_string(),
            "600".to_owned(),
        ])
        .current_dir(dir.path())
        .output()
        .expect("python runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout)
        .expect("utf-8")
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let cal = parse_calendar(f[0]).expect("time");
            let utc = utc_seconds_of_gps(gps_ns(cal, TimeScale::Utc).expect("after epoch"));
            (
                utc,
                f[1].parse().expect("eterna"),
                f[2].parse().expect("longman"),
            )
        })
        .collect()
}

#[test]
fn body_tide_agrees_with_eterna_and_longman() {
    let Some(py) = peers_python() else { return };
    for (site, start) in [
        (
            Site {
                latitude_deg: 48.0166,
                longitude_deg: 0.1576,
                height_m: 60.0,
            },
            "2005-02-15",
        ),
        (
            Site {
                latitude_deg: -33.9,
                longitude_deg: 18.4,
                height_m: 10.0,
            },
            "2021-06-10",
        ),
    ] {
        let rows = reference(&py, site, start, 72);
        assert!(rows.len() > 400);
        let (mut worst_eterna, mut worst_longman, mut sum_sq) = (0f64, 0f64, 0.0);
        for &(utc, eterna, longman) in &rows {
            let ours = body_tide_mgal(site, utc);
            worst_eterna = worst_eterna.max((ours - eterna).abs());
            worst_longman = worst_longman.max((ours - longman).abs());
            sum_sq += (ours - eterna).powi(2);
        }
        let rms_eterna = (sum_sq / rows.len() as f64).sqrt();
        eprintln!(
            "{start} at {:?}: vs ETERNA max {:.2} uGal, rms {:.2} uGal; vs tidegravity max {:.2e} uGal",
            site,
            worst_eterna * 1e3,
            rms_eterna * 1e3,
            worst_longman * 1e3
        );
        // The same formulas written twice agree to rounding.
        assert!(worst_longman < 1e-6, "vs tidegravity {worst_longman} mGal");
        // Within 5 microGal of ETERNA's harmonic development, with the same gravimetric
        // factor for every wave (measured: 1.4 and 1.7 microGal at worst).
        assert!(worst_eterna < 0.005, "vs ETERNA max {worst_eterna} mGal");
        assert!(rms_eterna < 0.002, "vs ETERNA rms {rms_eterna} mGal");
    }
}
