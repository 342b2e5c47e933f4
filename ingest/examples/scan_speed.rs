//! Times the `.gcb` frame scanner alone: the file is read into memory first and the frames
//! are only counted, so neither the disk, the hashing nor the Parquet writer is in the way.
//!
//! ```text
//! cargo run --release -p ingest --example scan_speed -- target/bench-data/bench-250hz-24h/raw/long.gcb
//! ```

use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args()
        .nth(1)
        .ok_or("usage: scan_speed FILE.gcb")?;
    let bytes = std::fs::read(&path)?;
    let mut best = f64::INFINITY;
    let mut frames = 0u64;
    for _ in 0..3 {
        let t0 = Instant::now();
        let mut scanner = ingest::gcb::FrameScanner::new(1310);
        let mut ledger = ingest::ledger::FileLedger::default();
        let mut n = 0u64;
        let mut count = |f: ingest::gcb::Frame| -> Result<(), ()> {
            n += u64::from(matches!(f, ingest::gcb::Frame::Acceleration { .. }));
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
