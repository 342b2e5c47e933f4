//! A platform meter's own record beside its readings (docs/formats.md 11.1, 11.2): each
//! line's cross-coupling monitors (a DGS's) and its status word (a DGS's status field, a
//! BGM-3's `SS`), read from the meter's file, and brought onto the trajectory's epochs:
//! an epoch takes the lines within half an epoch interval of it, `[t - dt/2, t + dt/2)`,
//! the monitors' mean and the status words or-ed (a bit set in any line of the epoch is
//! set in the epoch's).
//!
//! The status bits are numbered from the least significant, 0. gravcal names none of
//! them: the makers' maps are not published with the records (shipgrav's own map is marked
//! "from DGS documentation?", and DGS's processing software for the AT1A reads the bits in
//! the other order). The words are counted per bit in gravity.json and written per epoch;
//! the bits `[survey] meter_status_flag_bits` declares flag an epoch `meter_status`.
//!
//! No I/O but [`read`].

use super::GravityError;
use ingest::contract::manifest::{AdcFormat, TimeScale};
use std::path::Path;

/// A meter's record, a line at a time, its times increasing.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MeterLines {
    /// GPS time, ns, increasing.
    pub time_gps_ns: Vec<i64>,
    /// VE, VCC, AL, AX (None for a meter whose record has none: a BGM-3's).
    pub monitors: Option<Vec<[f64; 4]>>,
    /// The status word.
    pub status: Vec<u32>,
}

impl MeterLines {
    /// An empty record of a meter whose file is in `format`: with monitors but a BGM-3's.
    pub fn empty(format: AdcFormat) -> Self {
        MeterLines {
            monitors: (format != AdcFormat::Bgm3).then(Vec::new),
            ..MeterLines::default()
        }
    }

    /// A line's time, monitors and status added; passed over unless its time is after the
    /// last line's (the time gate ingest puts the meter's gravity through counts it).
    pub fn push(&mut self, t: i64, monitors: Option<[f64; 4]>, status: u32) {
        if self.time_gps_ns.last().is_some_and(|&last| last >= t) {
            return;
        }
        self.time_gps_ns.push(t);
        self.status.push(status);
        if let (Some(all), Some(m)) = (&mut self.monitors, monitors) {
            all.push(m);
        }
    }

    /// A DGS laptop line added ([`MeterLines::push`]).
    pub fn push_laptop(&mut self, r: &ingest::readers::dgs::LaptopLine) {
        self.push(r.gps_ns, Some(r.monitors), r.status);
    }

    /// The lines within half of `interval_ns` of `t`: `[t - dt/2, t + dt/2)`.
    fn window(&self, t: i64, interval_ns: i64) -> std::ops::Range<usize> {
        let half = interval_ns / 2;
        let from = self.time_gps_ns.partition_point(|&x| x < t - half);
        let to = self
            .time_gps_ns
            .partition_point(|&x| x < t - half + interval_ns);
        from..to
    }

    /// The monitors at each of `times` (epochs `interval_ns` apart): the mean of the
    /// lines within half an interval, NaN where there is none, or where the meter's record
    /// carries no monitors.
    pub fn monitors_at(&self, times: &[i64], interval_ns: i64) -> Vec<[f64; 4]> {
        let Some(values) = &self.monitors else {
            return vec![[f64::NAN; 4]; times.len()];
        };
        times
            .iter()
            .map(|&t| {
                let w = self.window(t, interval_ns);
                if w.is_empty() {
                    return [f64::NAN; 4];
                }
                let n = w.len() as f64;
                let mut sum = [0.0; 4];
                for m in &values[w] {
                    for i in 0..4 {
                        sum[i] += m[i];
                    }
                }
                sum.map(|s| s / n)
            })
            .collect()
    }

    /// The status at each of `times`: the words of the lines within half an interval
    /// or-ed, None where there is no line.
    pub fn status_at(&self, times: &[i64], interval_ns: i64) -> Vec<Option<u32>> {
        times
            .iter()
            .map(|&t| {
                let w = self.window(t, interval_ns);
                (!w.is_empty()).then(|| self.status[w].iter().fold(0, |a, s| a | s))
            })
            .collect()
    }
}

/// Whether `format` is a meter's own file, which carries a status word a line.
pub fn is_meter_file(format: AdcFormat) -> bool {
    matches!(
        format,
        AdcFormat::DgsLaptop | AdcFormat::DgsRaw | AdcFormat::Bgm3
    )
}

/// A meter's record from its laptop file ([`ingest::readers::dgs`]) or its raw serial output
/// ([`ingest::readers::meter_serial`], the logger's stamps without a zone in `scale`); None for a
/// stream of another `format`. The lines that do not parse, or do not move time on, are
/// passed over: ingest rejects and counts them, naming them, when it reads the same file
/// for the meter's gravity.
pub fn read(
    path: &Path,
    format: AdcFormat,
    scale: TimeScale,
) -> Result<Option<MeterLines>, GravityError> {
    if !is_meter_file(format) {
        return Ok(None);
    }
    let mut out = MeterLines::empty(format);
    if format == AdcFormat::DgsLaptop {
        // The lines that do not parse are set aside, and passed over.
        super::trajectory::for_each_dgs_laptop(path, true, |_, r| {
            out.push_laptop(r);
            Ok(())
        })?;
        return Ok(Some(out));
    }
    for (_, l) in super::trajectory::numbered_lines(path)? {
        let Ok(l) = l else { continue };
        let line = l.as_bytes();
        let read = match format {
            AdcFormat::DgsRaw => ingest::readers::meter_serial::parse_dgs_raw(line, scale)
                .ok()
                .map(|r| (r.gps_ns, r.monitors, r.status)),
            _ => ingest::readers::meter_serial::parse_bgm3(line, scale)
                .ok()
                .map(|r| (r.gps_ns, None, r.status)),
        };
        if let Some((t, monitors, status)) = read {
            out.push(t, monitors, status);
        }
    }
    Ok(Some(out))
}

/// The status `words` of a block's epochs added to a session's `m`.
pub fn count(m: &mut ingest::contract::gravity_ledger::MeterStatus, words: &[Option<u32>]) {
    let (with, bits) = summary(words);
    m.epochs += with;
    for (bit, n) in bits {
        *m.bits_set.entry(bit).or_insert(0) += n;
    }
}

/// A session's status words as gravity.json gives them: the epochs with a word, and per
/// bit set in any, the epochs it is set at.
pub fn summary(status: &[Option<u32>]) -> (u64, Vec<(u8, u64)>) {
    let mut per_bit = [0u64; 32];
    let mut with = 0;
    for s in status.iter().flatten() {
        with += 1;
        for (bit, n) in per_bit.iter_mut().enumerate() {
            *n += u64::from(s >> bit & 1);
        }
    }
    let bits = (0u8..32).zip(per_bit).filter(|(_, n)| *n > 0).collect();
    (with, bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(times: &[i64], status: &[u32]) -> MeterLines {
        MeterLines {
            time_gps_ns: times.to_vec(),
            monitors: Some(times.iter().map(|&t| [t as f64; 4]).collect()),
            status: status.to_vec(),
        }
    }

    /// An epoch takes the lines of its half-open window: at a logger's fractional stamps
    /// around whole-second epochs, every line of the window (their monitors' mean, their
    /// words or-ed), or one, or none.
    #[test]
    fn an_epoch_takes_the_lines_of_its_window() {
        let m = lines(&[700, 1300, 1400, 3100], &[1, 2, 4, 8]);
        let times = [1000, 2000, 3000];
        assert_eq!(m.status_at(&times, 1000), vec![Some(7), None, Some(8)]);
        let at = m.monitors_at(&times, 1000);
        assert!(at[0].iter().all(|v| (v - 3400.0 / 3.0).abs() < 1e-9));
        assert!(at[1].iter().all(|v| v.is_nan()));
        assert!(at[2].iter().all(|v| (v - 3100.0).abs() < 1e-12));
        // A line at exactly t + dt/2 belongs to the next epoch, once.
        let edge = lines(&[1500], &[16]);
        assert_eq!(edge.status_at(&[1000, 2000], 1000), vec![None, Some(16)]);
        // No monitors in the record: NaN everywhere, the status still read.
        let bgm = MeterLines {
            monitors: None,
            ..lines(&[1000], &[5])
        };
        assert!(bgm.monitors_at(&[1000], 1000)[0][0].is_nan());
        assert_eq!(bgm.status_at(&[1000], 1000), vec![Some(5)]);
    }

    /// Each bit set is counted at the epochs it is set at; epochs without a word are not
    /// counted; the top bit is bit 31.
    #[test]
    fn the_summary_counts_each_bit() {
        let (with, bits) = summary(&[Some(0b101), None, Some(0b100), Some(1 << 31)]);
        assert_eq!(with, 3);
        assert_eq!(bits, vec![(0, 1), (2, 2), (31, 1)]);
    }
}
