//! Reader of the binary acquisition log (`.gcb`, docs/formats.md section 3).
//!
//! Streaming: bytes arrive in chunks of any size ([`FrameScanner::push`]); a frame split
//! across chunks is completed from the next one. Damage is resynchronised over, counted and
//! listed: a candidate frame that fails (wrong length, bad CRC, unknown type) is rejected and
//! the search for the next sync word restarts one byte after its start, so the bytes of a
//! damaged frame and any junk count as skipped. Well-formed frames that cannot be used
//! (duplicate, time going backwards, reserved status bits, time of week out of range, count
//! out of the 24-bit range) are rejected whole. It never panics on any byte sequence.

use crate::base::time::{NS_PER_MS, NS_PER_WEEK, resolve_week};
use crate::base::timegate::{Position, Sink, TimeGate};
use crate::contract::ingest_ledger::{ByteLedger, FileLedger, MAX_LISTED, Rejection, reason};
use crate::contract::status::{RESERVED_BITS, not_connected};

/// Frame sync word.
pub const SYNC: [u8; 2] = [0xA5, 0x5A];
/// Payload length in version 1.
pub const PAYLOAD_LEN: usize = 19;
/// Bytes of a whole frame.
pub const FRAME_LEN: usize = 4 + PAYLOAD_LEN + 2;
const TYPE_ACCELERATION: u8 = 0x01;
const TYPE_TEMPERATURE: u8 = 0x02;
const COUNT_MIN: i32 = -8_388_608;
const COUNT_MAX: i32 = 8_388_607;

const fn crc_table() -> [u16; 256] {
    let mut table = [0u16; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u16) << 8;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 0x8000 != 0 {
                (crc << 1) ^ 0x1021
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
}

/// `T[k][b]` is the CRC (zero initial value) of byte `b` followed by `k` zero bytes: the
/// slicing tables for `N = 8`, and per-position tables for a whole frame.
const fn crc_tables<const N: usize>() -> [[u16; 256]; N] {
    let base = crc_table();
    let mut t = [[0u16; 256]; N];
    t[0] = base;
    let mut k = 1;
    while k < N {
        let mut i = 0;
        while i < 256 {
            let prev = t[k - 1][i];
            t[k][i] = (prev << 8) ^ base[(prev >> 8) as usize];
            i += 1;
        }
        k += 1;
    }
    t
}

static CRC_TABLES: [[u16; 256]; 8] = crc_tables::<8>();

/// Bytes a frame's CRC covers: type, length and payload.
const CRC_SPAN: usize = FRAME_LEN - 4;
/// Per-position tables for the CRC of a frame: `FRAME_CRC_TABLES[CRC_SPAN - 1 - i][b]` is
/// the share of byte `b` at position `i`.
static FRAME_CRC_TABLES: [[u16; 256]; CRC_SPAN] = crc_tables::<CRC_SPAN>();
/// The share of the initial value 0xFFFF: the CRC of `CRC_SPAN` zero bytes.
const FRAME_CRC_INIT: u16 = {
    let base = crc_table();
    let mut crc = 0xFFFF_u16;
    let mut i = 0;
    while i < CRC_SPAN {
        crc = (crc << 8) ^ base[(crc >> 8) as usize];
        i += 1;
    }
    crc
};

/// CRC-16/CCITT-FALSE of a frame's type, length and payload (bytes 2..23). The CRC is
/// linear, so it is the XOR of each byte's share, looked up independently: no chain of
/// dependent lookups, which is what bounds the bytewise and sliced forms.
#[inline]
fn frame_crc(frame: &[u8; FRAME_LEN]) -> u16 {
    let mut crc = FRAME_CRC_INIT;
    for i in 0..CRC_SPAN {
        crc ^= FRAME_CRC_TABLES[CRC_SPAN - 1 - i][usize::from(frame[2 + i])];
    }
    crc
}

/// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor), eight bytes
/// at a time.
pub fn crc16_ccitt_false(bytes: &[u8]) -> u16 {
    let t = &CRC_TABLES;
    let mut crc = 0xFFFF_u16;
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        let hi = (crc >> 8) as u8 ^ c[0];
        let lo = crc as u8 ^ c[1];
        crc = t[7][usize::from(hi)]
            ^ t[6][usize::from(lo)]
            ^ t[5][usize::from(c[2])]
            ^ t[4][usize::from(c[3])]
            ^ t[3][usize::from(c[4])]
            ^ t[2][usize::from(c[5])]
            ^ t[1][usize::from(c[6])]
            ^ t[0][usize::from(c[7])];
    }
    for &b in chunks.remainder() {
        crc = (crc << 8) ^ t[0][usize::from((crc >> 8) as u8 ^ b)];
    }
    crc
}

/// A decoded, accepted frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frame {
    /// Acceleration counts.
    Acceleration {
        /// GPS time, ns.
        time_ns: i64,
        /// Counts of channels 1..3 as logged (meaningless where the status says not connected).
        counts: [i32; 3],
        /// Status bits.
        status: u8,
    },
    /// Temperatures.
    Temperature {
        /// GPS time, ns.
        time_ns: i64,
        /// Milli-degrees C of channels 1..3 as logged.
        millidegrees: [i32; 3],
        /// Status bits.
        status: u8,
    },
}

/// Scans a binary log chunk by chunk, handing accepted frames to a callback and counting
/// everything else in a [`FileLedger`]. Frames pass a [`TimeGate`] per frame type.
pub struct FrameScanner {
    reference_week: i64,
    buf: Vec<u8>,
    /// File offset of `buf[0]`.
    offset: u64,
    /// Acceleration and temperature.
    gates: [TimeGate<Frame>; 2],
    bytes: ByteLedger,
    /// Start of the stretch currently being skipped, for listing it once.
    skip_start: Option<u64>,
}

/// The nominal interval of temperature frames (docs/formats.md section 3), ns.
pub const TEMPERATURE_INTERVAL_NS: i64 = 4_096_000_000;

/// What the scanner needs to know of the session.
#[derive(Clone, Copy, Debug)]
pub struct ScanConfig {
    /// GPS week nearest the session's date, for resolving 10-bit weeks.
    pub reference_week: i64,
    /// Nominal acceleration sample interval, ns.
    pub acceleration_interval_ns: i64,
    /// The session's range of GPS time, ns.
    pub range_ns: (i64, i64),
}

/// Where the time gate's verdicts go: the byte ledger, the file ledger and the caller.
struct FrameSink<'a, F> {
    bytes: &'a mut ByteLedger,
    ledger: &'a mut FileLedger,
    emit: &'a mut F,
}

impl<F: FnMut(Frame) -> Result<(), E>, E> Sink<Frame> for FrameSink<'_, F> {
    type Error = E;
    #[inline]
    fn accept(&mut self, _: i64, frame: Frame) -> Result<(), E> {
        self.bytes.in_accepted_frames += FRAME_LEN as u64;
        (self.emit)(frame)
    }
    fn reject(&mut self, at: Position, why: &'static str, detail: String, frame: Frame) {
        let kind = match frame {
            Frame::Acceleration { .. } => "acceleration",
            Frame::Temperature { .. } => "temperature",
        };
        self.ledger
            .reject(at.to_string(), why, format!("{kind} frame: {detail}"));
        self.bytes.in_rejected_frames += FRAME_LEN as u64;
    }
}

/// Whether every connected channel's count is a 24-bit value, without a branch per channel.
#[inline]
fn counts_in_range(values: [i32; 3], status: u8) -> bool {
    let mut out = 0u32;
    for (ch, v) in values.into_iter().enumerate() {
        // Shifted into 0..2^24 if in range; the top byte is then 0.
        let shifted = v.wrapping_sub(COUNT_MIN) as u32;
        let connected = u32::from(!not_connected(status, ch));
        out |= (shifted >> 24) * connected;
    }
    out == 0
}

/// Plausible temperatures, milli-degrees C: the range the CSV reader accepts too.
const MILLIDEGREE_MIN: i32 = -100_000;
const MILLIDEGREE_MAX: i32 = 200_000;

/// Whether every connected channel's temperature is plausible, without a branch per channel.
#[inline]
fn temperatures_in_range(values: [i32; 3], status: u8) -> bool {
    let mut ok = true;
    for (ch, v) in values.into_iter().enumerate() {
        let connected = !not_connected(status, ch);
        ok &= !connected | (MILLIDEGREE_MIN..=MILLIDEGREE_MAX).contains(&v);
    }
    ok
}

/// `N` bytes of a frame from `at`: one load, where assembling the bytes one by one made the
/// compiler store them singly and load them whole, stalling on every frame.
#[inline]
fn field<const N: usize>(f: &[u8; FRAME_LEN], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    out.copy_from_slice(&f[at..at + N]);
    out
}

impl FrameScanner {
    /// A scanner for one session's log.
    pub fn new(config: ScanConfig) -> Self {
        FrameScanner {
            reference_week: config.reference_week,
            buf: Vec::with_capacity(1 << 20),
            offset: 0,
            gates: [
                TimeGate::new(config.acceleration_interval_ns, config.range_ns),
                TimeGate::new(TEMPERATURE_INTERVAL_NS, config.range_ns),
            ],
            bytes: ByteLedger::default(),
            skip_start: None,
        }
    }

    /// Median interval between accepted acceleration frames, ns (sampled).
    pub fn acceleration_interval_ns(&self) -> Option<i64> {
        self.gates[0].median_interval_ns()
    }

    fn skip(&mut self, at: u64, n: usize) {
        self.bytes.skipped_resynchronising += n as u64;
        if self.skip_start.is_none() {
            self.skip_start = Some(at);
        }
    }

    #[inline]
    fn end_skip(&mut self, ledger: &mut FileLedger, at: u64) {
        if self.skip_start.is_some() {
            self.list_skip(ledger, at);
        }
    }

    #[cold]
    fn list_skip(&mut self, ledger: &mut FileLedger, at: u64) {
        if let Some(start) = self.skip_start.take()
            && ledger.rejections.len() < MAX_LISTED
        {
            ledger.rejections.push(Rejection {
                at: format!("byte {start}"),
                reason: "skipped".to_owned(),
                detail: format!("{} bytes skipped while resynchronising", at - start),
            });
        }
    }

    /// Feeds the next chunk of the file; calls `emit` for every accepted frame.
    pub fn push<E>(
        &mut self,
        chunk: &[u8],
        ledger: &mut FileLedger,
        emit: &mut impl FnMut(Frame) -> Result<(), E>,
    ) -> Result<(), E> {
        let mut rest = chunk;
        if !self.buf.is_empty() {
            // The unfinished tail of the last chunk (shorter than a frame): complete it with
            // at most a frame's worth of this chunk, rather than copying the whole chunk.
            let mut buf = std::mem::take(&mut self.buf);
            let tail = buf.len();
            let take = if chunk.len() >= FRAME_LEN {
                FRAME_LEN
            } else {
                chunk.len()
            };
            buf.extend_from_slice(&chunk[..take]);
            let used = self.scan(&buf, false, ledger, emit)?;
            self.offset += used as u64;
            if used < tail {
                // Only when this chunk is shorter than a frame: wait for more bytes.
                buf.drain(..used);
                buf.extend_from_slice(&chunk[take..]);
                self.buf = buf;
                return Ok(());
            }
            // Everything from `tail` on is this chunk's, scanned in place from here.
            rest = &chunk[used - tail..];
            buf.clear();
            self.buf = buf;
        }
        // Scan in place; keep only the unfinished tail.
        let used = self.scan(rest, false, ledger, emit)?;
        self.offset += used as u64;
        self.buf.extend_from_slice(&rest[used..]);
        Ok(())
    }

    /// Ends the file: reports a cut-off last frame or trailing junk, decides the frames the
    /// time gates still hold, and fills in the byte ledger. Returns the median interval
    /// between accepted acceleration frames (ns), if there were two.
    pub fn finish<E>(
        mut self,
        ledger: &mut FileLedger,
        emit: &mut impl FnMut(Frame) -> Result<(), E>,
    ) -> Result<Option<i64>, E> {
        let buf = std::mem::take(&mut self.buf);
        let used = self.scan(&buf, true, ledger, emit)?;
        debug_assert_eq!(used, buf.len());
        self.offset += used as u64;
        let end = self.offset;
        self.end_skip(ledger, end);
        for gate in &mut self.gates {
            let mut sink = FrameSink {
                bytes: &mut self.bytes,
                ledger,
                emit,
            };
            gate.finish(&mut sink)?;
        }
        ledger.accept("acceleration", self.gates[0].accepted());
        ledger.accept("temperature", self.gates[1].accepted());
        ledger.byte_ledger = Some(self.bytes);
        Ok(self.gates[0].median_interval_ns())
    }

    /// Scans `b` (starting at file offset `self.offset`); returns how many bytes were consumed.
    /// Unless `eof`, an incomplete frame at the end is left for the next chunk.
    fn scan<E>(
        &mut self,
        b: &[u8],
        eof: bool,
        ledger: &mut FileLedger,
        emit: &mut impl FnMut(Frame) -> Result<(), E>,
    ) -> Result<usize, E> {
        let mut p = 0usize;
        while p < b.len() {
            let at = self.offset + p as u64;
            let rest = &b[p..];
            if rest[0] != SYNC[0] || rest.get(1).is_some_and(|&x| x != SYNC[1]) {
                // Not a frame start: skip to the next possible sync byte.
                let k = rest[1..]
                    .iter()
                    .position(|&x| x == SYNC[0])
                    .map_or(rest.len(), |k| k + 1);
                self.skip(at, k);
                p += k;
                continue;
            }
            if rest.len() < 4 {
                if !eof {
                    break;
                }
                if rest.len() < 2 {
                    // A lone 0xA5 at the very end: not even a sync word.
                    self.skip(at, rest.len());
                } else {
                    self.truncated(ledger, at, rest.len());
                }
                p += rest.len();
                continue;
            }
            if usize::from(rest[3]) != PAYLOAD_LEN {
                self.reject_candidate(
                    ledger,
                    at,
                    reason::WRONG_LENGTH,
                    format!("length byte {}", rest[3]),
                );
                p += 1;
                continue;
            }
            let Some(frame) = rest.first_chunk::<FRAME_LEN>() else {
                if !eof {
                    break;
                }
                self.end_skip(ledger, at);
                self.truncated(ledger, at, rest.len());
                p += rest.len();
                continue;
            };
            let crc = u16::from_le_bytes(field(frame, 23));
            let kind = frame[2];
            if frame_crc(frame) != crc {
                self.reject_candidate(ledger, at, reason::BAD_CRC, format!("type 0x{kind:02x}"));
                p += 1;
                continue;
            }
            if kind != TYPE_ACCELERATION && kind != TYPE_TEMPERATURE {
                self.reject_candidate(
                    ledger,
                    at,
                    reason::UNKNOWN_TYPE,
                    format!("type 0x{kind:02x}"),
                );
                p += 1;
                continue;
            }
            self.end_skip(ledger, at);
            p += FRAME_LEN;
            self.frame(frame, at, ledger, emit)?;
        }
        Ok(p)
    }

    /// A candidate frame at `at` rejected for `reason`: the skipped run before it closes,
    /// and the search for the next sync word restarts one byte after it.
    fn reject_candidate(
        &mut self,
        ledger: &mut FileLedger,
        at: u64,
        reason: &'static str,
        detail: String,
    ) {
        self.end_skip(ledger, at);
        ledger.reject(format!("byte {at}"), reason, detail);
        self.skip(at, 1);
    }

    fn truncated(&mut self, ledger: &mut FileLedger, at: u64, n: usize) {
        ledger.reject(
            format!("byte {at}"),
            reason::TRUNCATED_TAIL,
            format!("{n} of {FRAME_LEN} bytes"),
        );
        self.bytes.truncated_tail += n as u64;
    }

    /// A well-formed frame (sync, length, CRC and type good) at file offset `at`.
    #[inline]
    fn frame<E>(
        &mut self,
        f: &[u8; FRAME_LEN],
        at: u64,
        ledger: &mut FileLedger,
        emit: &mut impl FnMut(Frame) -> Result<(), E>,
    ) -> Result<(), E> {
        let kind = f[2];
        let week10 = u16::from_le_bytes(field(f, 4));
        let tow_ms = u32::from_le_bytes(field(f, 6));
        let values = [
            i32::from_le_bytes(field(f, 10)),
            i32::from_le_bytes(field(f, 14)),
            i32::from_le_bytes(field(f, 18)),
        ];
        let status = f[22];
        let slot = usize::from(kind == TYPE_TEMPERATURE);
        // Wrapping: a time of week out of range is rejected below, before the time is used.
        let time_ns = resolve_week(week10, self.reference_week)
            .wrapping_mul(NS_PER_WEEK)
            .wrapping_add(i64::from(tow_ms) * NS_PER_MS);
        // All the checks of the frame alone at once, without a branch each; a frame that
        // fails one is looked at again, check by check, to say why. Its time is judged
        // against its neighbours by the gate.
        let usable = (status & RESERVED_BITS == 0)
            & (i64::from(tow_ms) * NS_PER_MS < NS_PER_WEEK)
            & if slot == 0 {
                counts_in_range(values, status)
            } else {
                temperatures_in_range(values, status)
            };
        if !usable {
            self.reject_frame(f, at, ledger);
            return Ok(());
        }
        let frame = if slot == 0 {
            Frame::Acceleration {
                time_ns,
                counts: values,
                status,
            }
        } else {
            Frame::Temperature {
                time_ns,
                millidegrees: values,
                status,
            }
        };
        let mut sink = FrameSink {
            bytes: &mut self.bytes,
            ledger,
            emit,
        };
        self.gates[slot].offer(time_ns, Position::Byte(at), frame, &mut sink)
    }

    /// Rejects a well-formed frame that [`FrameScanner::frame`] found unusable, with the
    /// reason of the first check it fails.
    #[cold]
    #[inline(never)]
    fn reject_frame(&mut self, f: &[u8; FRAME_LEN], at: u64, ledger: &mut FileLedger) {
        let tow_ms = u32::from_le_bytes(field(f, 6));
        let status = f[22];
        let temperature = f[2] == TYPE_TEMPERATURE;
        let connected_out_of = |lo: i32, hi: i32| {
            (0..3)
                .map(|ch| (ch, i32::from_le_bytes(field(f, 10 + 4 * ch))))
                .find(|&(ch, v)| !not_connected(status, ch) && !(lo..=hi).contains(&v))
                .unwrap_or((0, 0))
        };
        let (why, detail) = if status & RESERVED_BITS != 0 {
            (
                reason::RESERVED_STATUS_BITS,
                format!("status 0b{status:08b}"),
            )
        } else if i64::from(tow_ms) * NS_PER_MS >= NS_PER_WEEK {
            (reason::BAD_TIME_OF_WEEK, format!("tow_ms {tow_ms}"))
        } else if temperature {
            let (ch, v) = connected_out_of(MILLIDEGREE_MIN, MILLIDEGREE_MAX);
            (
                reason::TEMPERATURE_OUT_OF_RANGE,
                format!(
                    "channel {} temperature {} degC",
                    ch + 1,
                    f64::from(v) / 1000.0
                ),
            )
        } else {
            let (ch, v) = connected_out_of(COUNT_MIN, COUNT_MAX);
            (
                reason::COUNT_OUT_OF_RANGE,
                format!("channel {} count {v}", ch + 1),
            )
        };
        ledger.reject(format!("byte {at}"), why, detail);
        self.bytes.in_rejected_frames += FRAME_LEN as u64;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crc_check_value() {
        assert_eq!(crc16_ccitt_false(b"123456789"), 0x29B1);
    }

    /// The sliced CRC against the bit-by-bit definition (the simulator's, which shares no
    /// code with it), for every length up to 40.
    #[test]
    fn sliced_crc_is_the_bitwise_crc() {
        use fixtures::gcb::crc16_ccitt_false as bitwise;
        let data: Vec<u8> = (0..40u32)
            .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        for n in 0..=data.len() {
            assert_eq!(
                crc16_ccitt_false(&data[..n]),
                bitwise(&data[..n]),
                "length {n}"
            );
        }
        for start in 0..data.len() - FRAME_LEN {
            let frame = data[start..]
                .first_chunk::<FRAME_LEN>()
                .expect("long enough");
            assert_eq!(frame_crc(frame), bitwise(&frame[2..23]), "start {start}");
        }
    }

    fn frame(kind: u8, week10: u16, tow_ms: u32, v: [i32; 3], status: u8) -> Vec<u8> {
        let mut f = vec![0xA5, 0x5A, kind, 19];
        f.extend_from_slice(&week10.to_le_bytes());
        f.extend_from_slice(&tow_ms.to_le_bytes());
        for x in v {
            f.extend_from_slice(&x.to_le_bytes());
        }
        f.push(status);
        let crc = crc16_ccitt_false(&f[2..]);
        f.extend_from_slice(&crc.to_le_bytes());
        f
    }

    fn scan_all(bytes: &[u8], chunk: usize) -> (Vec<Frame>, FileLedger) {
        let mut s = FrameScanner::new(ScanConfig {
            reference_week: 1310,
            acceleration_interval_ns: 32 * NS_PER_MS,
            range_ns: (0, i64::MAX),
        });
        let mut ledger = FileLedger::default();
        let mut out = Vec::new();
        let mut emit = |f: Frame| -> Result<(), ()> {
            out.push(f);
            Ok(())
        };
        for c in bytes.chunks(chunk.max(1)) {
            s.push(c, &mut ledger, &mut emit).expect("no sink error");
        }
        s.finish(&mut ledger, &mut emit).expect("no sink error");
        (out, ledger)
    }

    #[test]
    fn damage_is_counted_and_bytes_add_up() {
        let mut log = Vec::new();
        log.extend(frame(1, 286, 1000, [1, 2, 3], 0));
        log.extend([0x00, 0x13, 0xA5, 0x77]); // junk with a false sync byte
        let mut bad = frame(1, 286, 1032, [1, 2, 3], 0);
        bad[12] ^= 0x40;
        log.extend(bad);
        log.extend(frame(1, 286, 1064, [4, 5, 6], 0));
        log.extend(frame(1, 286, 1064, [4, 5, 6], 0)); // duplicate
        log.extend(frame(2, 286, 1064, [24_800, 0, 0], 0b0010_0000));
        log.extend(frame(1, 286, 1000, [4, 5, 6], 0)); // backwards
        log.extend(frame(9, 286, 1096, [4, 5, 6], 0)); // unknown type
        log.extend(frame(1, 286, 1128, [7, 8, 9], 0));
        log.extend(&frame(1, 286, 1160, [7, 8, 9], 0)[..10]);
        for chunk in [1, 3, 7, 25, 1 << 16] {
            let (frames, l) = scan_all(&log, chunk);
            assert_eq!(frames.len(), 4, "chunk {chunk}");
            assert_eq!(l.accepted, 4);
            assert_eq!(l.rejected.get(reason::BAD_CRC), Some(&1));
            assert_eq!(l.rejected.get(reason::DUPLICATE), Some(&1));
            assert_eq!(l.rejected.get(reason::TIME_BACKWARDS), Some(&1));
            assert_eq!(l.rejected.get(reason::UNKNOWN_TYPE), Some(&1));
            assert_eq!(l.rejected.get(reason::TRUNCATED_TAIL), Some(&1));
            assert_eq!(l.read, l.accepted + l.rejected_total());
            let b = l.byte_ledger.clone().expect("binary ledger");
            assert_eq!(b.total(), log.len() as u64, "chunk {chunk}: {b:?}");
            assert_eq!(b.skipped_resynchronising, 4 + 25 + 25);
            assert_eq!(b.truncated_tail, 10);
        }
    }

    #[test]
    fn week_resolution_and_time() {
        let log = frame(1, 286, 295_200_032, [1, 2, 3], 0);
        let (frames, _) = scan_all(&log, 100);
        assert_eq!(
            frames[0],
            Frame::Acceleration {
                time_ns: 1310 * NS_PER_WEEK + 295_200_032 * NS_PER_MS,
                counts: [1, 2, 3],
                status: 0
            }
        );
    }
}
