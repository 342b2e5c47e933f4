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
//!    sample intervals, or learned ones for a log whose interval nobody declares,
//!    [`TimeGate::learning`]) is an ordinary step and accepted at once: the fast path.
//! 4. Anything else (a jump ahead, or the first record of a file) is held until
//!    [`NEIGHBOURS`] records have followed it (or the file ends), and decided by what each
//!    choice costs: accepting it rejects every one of them timed from after the last accepted
//!    time up to its own (`time_backwards` or `duplicate`); rejecting it costs itself. It is
//!    accepted when at most one of them falls there, otherwise rejected as `time_outlier`. A
//!    real gap in the logging is followed by records after it, so it is kept; a frame stamped
//!    an hour ahead, or two samples ahead, is followed by records that continue from before
//!    it, and it alone is lost.
//!
//! Limits, by construction: a burst of [`NEIGHBOURS`] or more consecutive records that agree
//! with one another is taken as the truth, and what follows them then goes `time_backwards`
//! (the ledger shows it); a record stamped ahead by less than one and a half intervals is
//! indistinguishable from the next sample, so it is kept and the sample it displaces is
//! rejected as a duplicate or as going backwards (one record either way), and a jump with a
//! single record after it falling back is kept at the cost of that record; a jump in the last
//! records of a file is judged by the few records after it, and kept when none follow. A
//! logger whose clock really steps backwards loses the overlap: times must increase in the
//! tables.

use crate::contract::ingest_ledger::reason;
use std::collections::VecDeque;

/// Records after a jump that decide it.
pub const NEIGHBOURS: usize = 8;
/// Accepted steps a learning gate takes the median of for its interval.
const LEARNED_STEPS: usize = 8;
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
    learning: Option<Learning>,
}

/// A learning gate's last accepted steps, ns, and how many it has seen.
struct Learning {
    steps: [i64; LEARNED_STEPS],
    seen: usize,
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
            learning: None,
        }
    }

    /// A gate for a stream whose interval nobody declares (a temperature log written by a
    /// lab's own logger, at whatever rate it was set to): every record is judged by its
    /// neighbours until [`LEARNED_STEPS`] steps are accepted, then the ordinary step is one
    /// and a half times the median of the last [`LEARNED_STEPS`], learned again after each
    /// [`LEARNED_STEPS`] more. A nominal interval longer than the log's would let a record a
    /// few samples ahead through as an ordinary step, and cost the samples it displaced.
    pub fn learning(range_ns: (i64, i64)) -> Self {
        TimeGate {
            max_step_ns: 0,
            learning: Some(Learning {
                steps: [0; LEARNED_STEPS],
                seen: 0,
            }),
            ..Self::new(1, range_ns)
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
    /// keeping it costs at most one of the records after it, those timed after the last
    /// accepted one and no later than it (rejecting it costs one: itself).
    fn judge_jump(&self) -> Result<(), (&'static str, String)> {
        let t = self.held[0].time_ns;
        let back = self
            .held
            .iter()
            .skip(1)
            .take(NEIGHBOURS)
            .filter(|h| h.time_ns <= t && self.last.is_none_or(|last| h.time_ns > last))
            .count();
        if back <= 1 {
            Ok(())
        } else {
            Err((
                reason::TIME_OUTLIER,
                format!(
                    "{} jumps ahead of its neighbours: {back} of the {} records after it come no later",
                    describe_gps(t),
                    (self.held.len() - 1).min(NEIGHBOURS)
                ),
            ))
        }
    }

    #[inline]
    fn accept(&mut self, time_ns: i64) {
        if let Some(last) = self.last {
            if self.accepted.is_multiple_of(INTERVAL_SAMPLING) {
                self.intervals.push(time_ns - last);
            }
            if let Some(l) = self.learning.as_mut() {
                l.steps[l.seen % LEARNED_STEPS] = time_ns - last;
                l.seen += 1;
                if l.seen.is_multiple_of(LEARNED_STEPS) {
                    let mut s = l.steps;
                    s.sort_unstable();
                    self.max_step_ns = (s[LEARNED_STEPS / 2] * 3 + 1) / 2;
                }
            }
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

    /// Two to five samples ahead, on a sample's time or between two: the stray alone is lost,
    /// not the samples it would have displaced (the CI's proptest case: 112 s between 110 s
    /// and 111 s of a 1 s log).
    #[test]
    fn a_record_a_few_samples_ahead_is_rejected_alone() {
        for ahead in [20, 25, 30, 50] {
            let mut times: Vec<i64> = (1..100).map(|i| i * 10).collect();
            let at = 40;
            let stray = times[at - 1] + ahead;
            times.insert(at, stray);
            let c = run(&times);
            assert_eq!(
                c.rejected,
                vec![(stray, reason::TIME_OUTLIER)],
                "{ahead} ahead"
            );
            assert_eq!(c.accepted.len(), 99, "{ahead} ahead");
        }
    }

    /// A log every 10 ns read by a gate that learns its interval (a temperature log, whose
    /// nominal 4.096 s is a guess): a record two samples ahead is the one lost, anywhere,
    /// the first records included; a gate told 40 would take it as an ordinary step.
    #[test]
    fn a_learning_gate_rejects_a_record_two_samples_ahead() {
        for at in [0, 3, 9, 40] {
            let mut times: Vec<i64> = (1..100).map(|i| i * 10).collect();
            let stray = times[at] + 20;
            times.insert(at, stray);
            let mut gate = TimeGate::learning((0, 1_000_000));
            let mut c = Collect::default();
            for (i, &t) in times.iter().enumerate() {
                gate.offer(t, Position::Line(i as u64), t, &mut c)
                    .expect("collects");
            }
            gate.finish(&mut c).expect("collects");
            assert_eq!(c.rejected, vec![(stray, reason::TIME_OUTLIER)], "at {at}");
            assert_eq!(c.accepted.len(), 99, "at {at}");
            assert_eq!(gate.median_interval_ns(), Some(10), "at {at}");
        }
    }

    /// A burst shorter than the neighbours is rejected whole; one as long is taken as the
    /// truth, and the records that return from before it go backwards.
    #[test]
    fn a_burst_is_judged_by_its_length() {
        for (len, outliers) in [
            (3usize, 3usize),
            (NEIGHBOURS - 1, NEIGHBOURS - 1),
            (NEIGHBOURS, 0),
        ] {
            let mut times: Vec<i64> = (1..100).map(|i| i * 10).collect();
            for k in 0..len {
                times.insert(40 + k, 500_000 + 10 * k as i64);
            }
            let c = run(&times);
            let n = |why| c.rejected.iter().filter(|r| r.1 == why).count();
            assert_eq!(n(reason::TIME_OUTLIER), outliers, "burst of {len}");
            if outliers == 0 {
                assert_eq!(n(reason::TIME_BACKWARDS), 99 - 40, "burst of {len}");
            } else {
                assert_eq!(c.accepted.len(), 99, "burst of {len}");
            }
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
