//! The time gate every sample reader passes its records through: records leave in strictly
//! increasing time, and a record whose time jumps away from its neighbours and back is the
//! one rejected, never the good records after it.
//!
//! The rule, per stream (acceleration and temperature each have their own gate):
//!
//! 1. A time outside the session's range (`ResolvedSession::gps_range_ns`) is rejected
//!    alone as `outside_session`; it never becomes the time later records are compared with.
//! 2. A time equal to the last accepted one is a `duplicate`; an earlier one goes
//!    `time_backwards`. Both are rejected alone.
//! 3. A time after the last accepted one by at most `max_step_ns` (one and a half nominal
//!    sample intervals) is an ordinary step and accepted at once: the fast path.
//! 4. Anything else (a jump ahead, or the first record of a file) is held until
//!    [`NEIGHBOURS`] records have followed it (or the file ends), and decided by them: it is
//!    accepted when at least as many of them come after it as fall between the last accepted
//!    time and it; otherwise it jumped ahead of its neighbours and is rejected as
//!    `time_outlier`. A real gap in the logging is followed by records after it, so it is
//!    kept; a frame stamped an hour ahead is followed by records that continue from before it.
//!
//! Limits, by construction: a burst of more than half of [`NEIGHBOURS`] consecutive records
//! that agree with one another is taken as the truth, and what follows them then goes
//! `time_backwards` (the ledger shows it); a record stamped ahead by less than one and a half
//! intervals is indistinguishable from the next sample, so it is kept and the sample it
//! displaces is rejected as a duplicate or as going backwards (one record either way); a
//! jump in the last records of a file is judged by the few records after it, and kept when
//! none follow. A logger whose clock really steps backwards loses the overlap: times must
//! increase in the tables.

use crate::contract::ingest_ledger::reason;
use std::collections::VecDeque;

/// Records after a jump that decide it.
pub const NEIGHBOURS: usize = 8;
/// One in this many accepted steps is sampled for the measured sample interval.
const INTERVAL_SAMPLING: u64 = 16;

/// Where a record sits in its file, for the ledger.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Position {
    /// Byte offset of a frame.
    Byte(u64),
    /// 1-based line number.
    Line(u64),
}

impl std::fmt::Display for Position {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Position::Byte(b) => write!(f, "byte {b}"),
            Position::Line(l) => write!(f, "line {l}"),
        }
    }
}

/// What the gate does with records: the reader's side.
pub trait Sink<T> {
    /// The reader's error.
    type Error;
    /// `item`, at `time_ns`, is accepted.
    fn accept(&mut self, time_ns: i64, item: T) -> Result<(), Self::Error>;
    /// `item` is rejected for `why` (a [`reason`]), with a detail for the ledger.
    fn reject(&mut self, at: Position, why: &'static str, detail: String, item: T);
}

struct Held<T> {
    time_ns: i64,
    at: Position,
    item: T,
}

/// The gate of one stream; see the module documentation for the rule.
pub struct TimeGate<T> {
    last: Option<i64>,
    max_step_ns: i64,
    range_ns: (i64, i64),
    held: VecDeque<Held<T>>,
    accepted: u64,
    intervals: Vec<i64>,
}

/// A GPS time as `week W tow S s`, for messages.
pub fn describe_gps(time_ns: i64) -> String {
    let week = time_ns.div_euclid(crate::base::time::NS_PER_WEEK);
    let tow = time_ns.rem_euclid(crate::base::time::NS_PER_WEEK);
    format!("GPS week {week} tow {:.3} s", tow as f64 * 1e-9)
}

impl<T> TimeGate<T> {
    /// A gate for a stream of nominal interval `interval_ns` within `[start, end)` of GPS time.
    pub fn new(interval_ns: i64, range_ns: (i64, i64)) -> Self {
        TimeGate {
            last: None,
            max_step_ns: (interval_ns.max(1) * 3 + 1) / 2,
            range_ns,
            held: VecDeque::new(),
            accepted: 0,
            intervals: Vec::new(),
        }
    }

    /// Offers a record; the sink hears what becomes of it (now, or once its neighbours are in).
    #[inline]
    pub fn offer<S: Sink<T>>(
        &mut self,
        time_ns: i64,
        at: Position,
        item: T,
        sink: &mut S,
    ) -> Result<(), S::Error> {
        if self.held.is_empty()
            && let Some(last) = self.last
            && time_ns > last
            && time_ns - last <= self.max_step_ns
            && time_ns < self.range_ns.1
        {
            self.accept(time_ns);
            return sink.accept(time_ns, item);
        }
        self.offer_held(Held { time_ns, at, item }, sink)
    }

    /// A record off the fast path: outside the session, or held until it can be decided.
    #[cold]
    fn offer_held<S: Sink<T>>(&mut self, h: Held<T>, sink: &mut S) -> Result<(), S::Error> {
        if h.time_ns < self.range_ns.0 || h.time_ns >= self.range_ns.1 {
            sink.reject(
                h.at,
                reason::OUTSIDE_SESSION,
                format!("{} is outside the session", describe_gps(h.time_ns)),
                h.item,
            );
            return Ok(());
        }
        self.held.push_back(h);
        self.decide(sink, false)
    }

    /// Decides every held record that can be decided (all of them at the end of the file).
    fn decide<S: Sink<T>>(&mut self, sink: &mut S, end: bool) -> Result<(), S::Error> {
        while let Some(front) = self.held.front() {
            let t = front.time_ns;
            let verdict = match self.last {
                Some(last) if t == last => Some(Err((
                    reason::DUPLICATE,
                    "same time as the record accepted before it".to_owned(),
                ))),
                Some(last) if t < last => Some(Err((
                    reason::TIME_BACKWARDS,
                    format!(
                        "{} ms before the record accepted before it",
                        (last - t) / crate::base::time::NS_PER_MS
                    ),
                ))),
                Some(last) if t - last <= self.max_step_ns => Some(Ok(())),
                _ if self.held.len() > NEIGHBOURS || end => Some(self.judge_jump()),
                _ => None,
            };
            let Some(verdict) = verdict else { break };
            let Some(h) = self.held.pop_front() else {
                break;
            };
            match verdict {
                Ok(()) => {
                    self.accept(h.time_ns);
                    sink.accept(h.time_ns, h.item)?;
                }
                Err((why, detail)) => sink.reject(h.at, why, detail, h.item),
            }
        }
        Ok(())
    }

    /// The front record jumped ahead of the last accepted one (or is the first): kept when
    /// at least as many of the records after it come after it as fall back before it.
    fn judge_jump(&self) -> Result<(), (&'static str, String)> {
        let t = self.held[0].time_ns;
        let (mut after, mut back) = (0usize, 0usize);
        for h in self.held.iter().skip(1).take(NEIGHBOURS) {
            if h.time_ns > t {
                after += 1;
            } else if h.time_ns < t && self.last.is_none_or(|last| h.time_ns > last) {
                back += 1;
            }
        }
        if after >= back {
            Ok(())
        } else {
            Err((
                reason::TIME_OUTLIER,
                format!(
                    "{} jumps ahead of its neighbours: {back} of the {} records after it come before it",
                    describe_gps(t),
                    (self.held.len() - 1).min(NEIGHBOURS)
                ),
            ))
        }
    }

    #[inline]
    fn accept(&mut self, time_ns: i64) {
        if let Some(last) = self.last
            && self.accepted.is_multiple_of(INTERVAL_SAMPLING)
        {
            self.intervals.push(time_ns - last);
        }
        self.last = Some(time_ns);
        self.accepted += 1;
    }

    /// Ends the file: the held records are decided by what follows them, if anything.
    pub fn finish<S: Sink<T>>(&mut self, sink: &mut S) -> Result<(), S::Error> {
        self.decide(sink, true)
    }

    /// Median of the sampled intervals between accepted records, ns (None before two).
    pub fn median_interval_ns(&self) -> Option<i64> {
        let mut v = self.intervals.clone();
        if v.is_empty() {
            return None;
        }
        let mid = v.len() / 2;
        Some(*v.select_nth_unstable(mid).1)
    }

    /// Records accepted so far.
    pub fn accepted(&self) -> u64 {
        self.accepted
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Default)]
    struct Collect {
        accepted: Vec<i64>,
        rejected: Vec<(i64, &'static str)>,
    }

    impl Sink<i64> for Collect {
        type Error = ();
        fn accept(&mut self, t: i64, _: i64) -> Result<(), ()> {
            self.accepted.push(t);
            Ok(())
        }
        fn reject(&mut self, _: Position, why: &'static str, _: String, item: i64) {
            self.rejected.push((item, why));
        }
    }

    fn run(times: &[i64]) -> Collect {
        let mut gate = TimeGate::new(10, (0, 1_000_000));
        let mut c = Collect::default();
        for (i, &t) in times.iter().enumerate() {
            gate.offer(t, Position::Line(i as u64), t, &mut c)
                .expect("collects");
        }
        gate.finish(&mut c).expect("collects");
        c
    }

    /// In the middle of the stream and as its first record.
    #[test]
    fn a_frame_stamped_ahead_is_rejected_alone() {
        for at in [40, 0] {
            let mut times: Vec<i64> = (1..100).map(|i| i * 10).collect();
            times.insert(at, 500_000);
            let c = run(&times);
            assert_eq!(c.rejected, vec![(500_000, reason::TIME_OUTLIER)], "at {at}");
            assert_eq!(c.accepted.len(), 99, "at {at}");
        }
    }

    #[test]
    fn a_real_gap_is_kept_and_backwards_and_outside_are_alone() {
        let mut times: Vec<i64> = (1..50).map(|i| i * 10).collect();
        times.extend((0..50).map(|i| 10_000 + i * 10));
        times.insert(20, 100);
        times.insert(70, 2_000_000);
        let c = run(&times);
        assert_eq!(
            c.rejected,
            vec![
                (100, reason::TIME_BACKWARDS),
                (2_000_000, reason::OUTSIDE_SESSION)
            ]
        );
        assert_eq!(c.accepted.len(), 99);
        assert!(c.accepted.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn the_interval_is_measured() {
        let times: Vec<i64> = (1..1000).map(|i| i * 10).collect();
        let mut gate = TimeGate::new(10, (0, 1_000_000));
        let mut c = Collect::default();
        for &t in &times {
            gate.offer(t, Position::Byte(0), t, &mut c)
                .expect("collects");
        }
        gate.finish(&mut c).expect("collects");
        assert_eq!(gate.median_interval_ns(), Some(10));
        assert_eq!(gate.accepted(), 999);
    }
}
