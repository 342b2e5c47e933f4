//! Times the `.gcb` frame scanner alone: the file is read into memory first and the frames
//! are only counted, so neither the disk, the hashing nor the Parquet writer is in the way.
//!
//! ```text
//! cargo run --release -p ingest --example scan_speed -- target/bench-data/bench-250hz-24h/raw/long.gcb [RATE_HZ]
//! ```
//!
//! RATE_HZ is the nominal acceleration rate the time gate expects (default 250).

use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: scan_speed FILE.gcb")?;
    let rate_hz: f64 = match std::env::args().nth(2) {
        Some(r) => r.parse()?,
        None => 250.0,
    };
    let config = ingest::readers::gcb::ScanConfig {
        reference_week: 1310,
        acceleration_interval_ns: (1e9 / rate_hz).round() as i64,
        range_ns: (0, i64::MAX),
    };
    let bytes = std::fs::read(&path)?;
    let mut best = f64::INFINITY;
    let mut frames = 0u64;
    for _ in 0..3 {
        let t0 = Instant::now();
        let mut scanner = ingest::readers::gcb::FrameScanner::new(config);
        let mut ledger = ingest::contract::ingest_ledger::FileLedger::default();
        let mut n = 0u64;
        let mut count = |f: ingest::readers::gcb::Frame| -> Result<(), ()> {
            n += u64::from(matches!(
                f,
                ingest::readers::gcb::Frame::Acceleration { .. }
            ));
            Ok(())
        };
        for chunk in bytes.chunks(1 << 20) {
            let _ = scanner.push(chunk, &mut ledger, &mut count);
        }
        let _ = scanner.finish(&mut ledger, &mut count);
        best = best.min(t0.elapsed().as_secs_f64());
        frames = n;
    }
    println!(
        "{path}: {frames} acceleration frames in {best:.3} s: {:.0} MB/s, {:.1} ns per frame",
        bytes.len() as f64 / 1e6 / best,
        best * 1e9 / frames as f64
    );
    Ok(())
}
