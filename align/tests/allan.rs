//! The overlapping Allan deviation against allantools, run side by side on the same series
//! (white noise plus a random walk, like an accelerometer's counts at rest).

mod peers;

use align::allan::{octave_factors, overlapping};
use std::process::Command;

#[test]
fn allan_deviation_agrees_with_allantools() {
    let Some(py) = peers::peers_python() else {
        return;
    };
    let tau0 = 0.032;
    let mut s = 0x9E37_79B9_7F4A_7C15_u64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut walk = 0.0;
    let y: Vec<f64> = (0..50_000)
        .map(|_| {
            walk += 0.05 * next();
            1_534_211.0 + 3.0 * next() + walk
        })
        .collect();
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("series.txt");
    let text: String = y.iter().map(|v| format!("{v:.6}\n")).collect();
    std::fs::write(&file, text).expect("write");
    // The values as written, for both sides.
    let y: Vec<f64> = std::fs::read_to_string(&file)
        .expect("read")
        .lines()
        .map(|l| l.parse().expect("number"))
        .collect();
    let ms = octave_factors(y.len());
    let list: Vec<String> = ms.iter().map(ToString::to_string).collect();
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/allan_reference.py");
    let o = Command::new(&py)
        .arg(&script)
        .arg(&file)
        .arg((1.0 / tau0).to_string())
        .arg(list.join(","))
        .output()
        .expect("python runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let theirs: Vec<Vec<f64>> = String::from_utf8(o.stdout)
        .expect("utf-8")
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|f| f.parse().expect("number")).collect())
        .collect();
    let ours = overlapping(&y, tau0, &ms);
    assert_eq!(ours.len(), theirs.len());
    let mut worst = 0f64;
    for (p, t) in ours.iter().zip(&theirs) {
        assert_eq!(p.m, t[0] as usize);
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        worst = worst.max(rel(p.adev, t[2]));
        assert!(
            rel(p.adev, t[2]) < 1e-6,
            "m {}: {} vs {}",
            p.m,
            p.adev,
            t[2]
        );
        assert!(
            rel(p.edf, t[3]) < 1e-9,
            "m {}: edf {} vs {}",
            p.m,
            p.edf,
            t[3]
        );
        assert!(
            rel(p.interval.0, t[4]) < 1e-6 && rel(p.interval.1, t[5]) < 1e-6,
            "m {}: {:?} vs {:?}",
            p.m,
            p.interval,
            &t[4..]
        );
    }
    eprintln!(
        "{} taus, worst relative difference from allantools {worst:.1e}",
        ours.len()
    );
}
