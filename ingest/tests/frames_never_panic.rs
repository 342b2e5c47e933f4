//! The frame reader on arbitrary and mutated bytes: it never panics, accepted plus rejected
//! is what it read, its bytes add up to the input, and chunking changes nothing. A valid
//! log with one out-of-place frame inserted anywhere loses at most one frame.

use fixtures::gcb::{Frame, TYPE_ACCELERATION, TYPE_TEMPERATURE};
use ingest::contract::ingest_ledger::FileLedger;
use ingest::readers::gcb::{FrameScanner, ScanConfig};
use proptest::prelude::*;

fn scan(bytes: &[u8], chunk: usize) -> (Vec<ingest::readers::gcb::Frame>, FileLedger) {
    let mut s = FrameScanner::new(ScanConfig {
        reference_week: 1310,
        acceleration_interval_ns: 32_000_000,
        range_ns: (0, i64::MAX),
    });
    let mut ledger = FileLedger::default();
    let mut out = Vec::new();
    let mut emit = |f| -> Result<(), ()> {
        out.push(f);
        Ok(())
    };
    for c in bytes.chunks(chunk.max(1)) {
        s.push(c, &mut ledger, &mut emit).expect("no sink error");
    }
    s.finish(&mut ledger, &mut emit).expect("no sink error");
    (out, ledger)
}

fn check(bytes: &[u8], chunk: usize) {
    let (frames, l) = scan(bytes, chunk);
    assert_eq!(l.read, l.accepted + l.rejected_total());
    assert_eq!(frames.len() as u64, l.accepted);
    let b = l.byte_ledger.clone().expect("binary ledger");
    assert_eq!(b.total(), bytes.len() as u64, "{b:?}");
    let (frames1, l1) = scan(bytes, bytes.len().max(1));
    assert_eq!(frames, frames1);
    assert_eq!(l.rejected, l1.rejected);
    assert_eq!(l.byte_ledger, l1.byte_ledger);
}

fn valid_log(n: usize, seed: u64) -> Vec<u8> {
    let mut out = Vec::new();
    for i in 0..n as u32 {
        let kind = if i % 5 == 4 {
            TYPE_TEMPERATURE
        } else {
            TYPE_ACCELERATION
        };
        let v = (seed as i32).wrapping_mul(i as i32 + 1) & 0x7F_FFFF;
        // Temperatures in milli-degrees, within [-50, 50] degC.
        let v = if kind == TYPE_TEMPERATURE {
            v % 50_000
        } else {
            v
        };
        let f = Frame {
            kind,
            week10: 286,
            tow_ms: 1000 + 32 * i,
            values: [v, -v, 3],
            status: (seed as u8) & 0b0111_0111,
        };
        out.extend_from_slice(&f.encode());
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..3000), chunk in 1usize..200) {
        check(&bytes, chunk);
    }

    #[test]
    fn sync_heavy_bytes(bytes in proptest::collection::vec(prop_oneof![Just(0xA5u8), Just(0x5Au8), Just(19u8), Just(1u8), any::<u8>()], 0..3000), chunk in 1usize..64) {
        check(&bytes, chunk);
    }

    #[test]
    fn mutated_logs(
        n in 1usize..120,
        seed in any::<u64>(),
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), 0u8..3), 0..12),
        chunk in 1usize..300,
    ) {
        let mut bytes = valid_log(n, seed);
        for (at, value, op) in edits {
            if bytes.is_empty() { break; }
            let at = at % bytes.len();
            match op {
                0 => bytes[at] ^= value | 1,
                1 => bytes.insert(at, value),
                _ => { bytes.remove(at); }
            }
        }
        check(&bytes, chunk);
    }

    #[test]
    fn intact_logs_are_read_whole(n in 1usize..200, seed in any::<u64>(), chunk in 1usize..300) {
        let bytes = valid_log(n, seed);
        let (frames, l) = scan(&bytes, chunk);
        prop_assert_eq!(frames.len(), n);
        prop_assert!(l.rejected.is_empty());
    }

    /// One valid frame with any time, inserted anywhere into a valid log, costs at most one
    /// frame: itself, or (when it lands within one and a half intervals after the frame
    /// before it, where it cannot be told from the next sample) the sample it displaces.
    /// Before the time gate, a frame stamped ahead made every good frame after it go
    /// `time_backwards`.
    #[test]
    fn one_out_of_place_frame_costs_at_most_one(
        n in 2usize..300,
        seed in any::<u64>(),
        at in any::<usize>(),
        tow_ms in 0u32..604_800_000,
        temperature in any::<bool>(),
        chunk in 1usize..300,
    ) {
        let log = valid_log(n, seed);
        let (originals, _) = scan(&log, log.len());
        let at = at % (n + 1) * 25;
        let stray = Frame {
            kind: if temperature { TYPE_TEMPERATURE } else { TYPE_ACCELERATION },
            week10: 286,
            tow_ms,
            values: [7, 7, 7],
            status: 0,
        };
        let mut bytes = log[..at].to_vec();
        bytes.extend_from_slice(&stray.encode());
        bytes.extend_from_slice(&log[at..]);
        let (frames, l) = scan(&bytes, chunk);
        prop_assert!(l.rejected_total() <= 1, "{:?}", l.rejections);
        let kept = originals.iter().filter(|f| frames.contains(f)).count();
        prop_assert!(kept + 1 >= originals.len(), "{} of {} kept", kept, originals.len());
        if frames.len() < originals.len() + 1 && kept == originals.len() {
            // The stray is the one rejected.
            prop_assert_eq!(l.rejected_total(), 1);
        }
    }
}
