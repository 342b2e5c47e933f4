//! The windows around each theodolite reading and the still intervals of each station:
//! opened in time order, filled in one pass over the samples, sigma_Dz per station, and the
//! ADC noise from the still intervals.

use super::{
    AdcNoise, BTreeMap, Dataset, Path, Result, SigmaDzMethod, WindowSums, allan, allan_row,
    sample_sd, sigma_source, status, tables, weights,
};

/// A reading with its windows being filled.
pub(crate) struct Pending {
    pub(crate) reading: tables::theodolite::Reading,
    pub(crate) start_ns: i64,
    pub(crate) end_ns: i64,
    pub(crate) sums: [WindowSums; 3],
}

/// Most samples kept per still interval and channel for the Allan deviation (2^16, about 35
/// min at 31.25 Hz): memory stays bounded on long logs.
pub(crate) const MAX_STILL_SAMPLES: usize = 1 << 16;

/// The platform at rest at one station: from the window of its first reading to that of its
/// last, the counts of each channel, for the Allan deviation.
pub(crate) struct StillInterval {
    pub(crate) start_ns: i64,
    pub(crate) end_ns: i64,
    pub(crate) counts: [Vec<f64>; 3],
    /// A sample flagged, missing, or a gap in time: the series is not usable.
    pub(crate) broken: [bool; 3],
    pub(crate) last_ns: Option<i64>,
}

/// The still intervals of a session's readings (in time order): one per run of readings at
/// the same station.
pub(crate) fn still_intervals(windows: &[Pending]) -> Vec<StillInterval> {
    let mut out: Vec<StillInterval> = Vec::new();
    let mut station: Option<&str> = None;
    for w in windows {
        if station == Some(w.reading.station.as_str())
            && let Some(last) = out.last_mut()
        {
            last.end_ns = last.end_ns.max(w.end_ns);
            continue;
        }
        station = Some(w.reading.station.as_str());
        out.push(StillInterval {
            start_ns: w.start_ns,
            end_ns: w.end_ns,
            counts: Default::default(),
            broken: [false; 3],
            last_ns: None,
        });
    }
    out
}

/// A station's sigma_Dz, where it came from, and its degrees of freedom (None: known).
#[derive(Clone, Copy, Debug)]
pub(crate) struct StationSigma {
    pub(crate) sigma_rad: f64,
    pub(crate) source: &'static str,
    pub(crate) dof: Option<f64>,
}

/// A session's sigma_Dz: per station, and per reading the same estimate formed without
/// that reading (what its w-test is referred to, so that a blunder does not hide behind
/// the variance it inflates).
pub(crate) struct SessionSigmas {
    /// Per station id.
    pub(crate) station: BTreeMap<String, StationSigma>,
    /// Per reading, in the order given: its station's sigma without it.
    pub(crate) left_out: Vec<StationSigma>,
}

/// A station's own variance of Dz (never below the floor's square) and its dof; (0, 0)
/// with fewer than two readings.
fn own_variance(dz: &[f64], floor_rad: f64) -> (f64, f64) {
    sample_sd(dz).map_or((0.0, 0.0), |sd| {
        (sd.max(floor_rad).powi(2), (dz.len() - 1) as f64)
    })
}

/// How a session forms one station's sigma_Dz from its readings.
struct SigmaRule {
    floor_rad: f64,
    fallback_rad: f64,
    pooled_dof: f64,
    moderated: Option<weights::Moderated>,
}

impl SigmaRule {
    /// The sigma of a station whose readings are `dz` (see [`station_sigmas`]).
    fn sigma(&self, dz: &[f64]) -> StationSigma {
        let at = |sigma_rad, source, dof| StationSigma {
            sigma_rad,
            source,
            dof,
        };
        let sd = sample_sd(dz);
        let own_dof = dz.len().saturating_sub(1) as f64;
        let Some(m) = &self.moderated else {
            return match sd {
                None => at(self.fallback_rad, sigma_source::MANIFEST, None),
                Some(sd) if sd >= self.floor_rad => at(sd, sigma_source::STATION_SD, Some(own_dof)),
                Some(_) => at(self.floor_rad, sigma_source::RESOLUTION, None),
            };
        };
        let (v, d) = own_variance(dz, self.floor_rad);
        let (variance, dof) = if m.prior_dof.is_finite() && d > 0.0 {
            (
                (m.prior_dof * m.prior_variance + d * v) / (m.prior_dof + d),
                m.prior_dof + d,
            )
        } else if m.prior_dof.is_finite() {
            (m.prior_variance, m.prior_dof)
        } else {
            (m.prior_variance, self.pooled_dof)
        };
        if variance.sqrt() >= self.floor_rad {
            at(variance.sqrt(), sigma_source::MODERATED, Some(dof))
        } else {
            at(self.floor_rad, sigma_source::RESOLUTION, None)
        }
    }
}

/// sigma_Dz per station of one session, never below the quantisation of the log: the step
/// of the finest last decimal the session's readings were logged with, over sqrt(12). By
/// default each station's variance is moderated toward the session's ([`weights`]; a
/// station of one reading takes the session's prior), on the prior's dof plus its own (the
/// pooled dof when the stations are alike); with `sigma_dz = "station"` it is the station's
/// own sd (eq. 4) on n - 1 dof, and a station of one reading takes the manifest's
/// `theodolite_sigma_arcsec`, taken as known like the resolution floor.
///
/// Each reading's left-out sigma is formed the same way from its station's other readings
/// (n - 2 dof) under the same prior (the prior, estimated from every station, is not formed
/// again: one reading among a session's hundreds moves it little), leaving out as well any
/// other reading gross enough to mask a blunder ([`weights::gross_readings`]); a sigma
/// taken as known, or a station too small to leave a reading out of, keeps the station's
/// own.
pub(crate) fn station_sigmas(
    readings: &[Pending],
    fallback_rad: f64,
    method: SigmaDzMethod,
) -> SessionSigmas {
    let floor_rad = readings
        .iter()
        .map(|p| p.reading.step_rad)
        .fold(f64::INFINITY, f64::min)
        / 12f64.sqrt();
    let mut by_station: BTreeMap<&str, Vec<usize>> = BTreeMap::new();
    for (k, p) in readings.iter().enumerate() {
        by_station
            .entry(p.reading.station.as_str())
            .or_default()
            .push(k);
    }
    let dz_of =
        |ks: &[usize]| -> Vec<f64> { ks.iter().map(|&k| readings[k].reading.dz_rad).collect() };
    let own: Vec<(f64, f64)> = by_station
        .values()
        .map(|ks| own_variance(&dz_of(ks), floor_rad))
        .collect();
    let pooled_dof: f64 = own.iter().map(|&(_, d)| d).sum();
    let moderated = match method {
        SigmaDzMethod::Moderated => weights::moderate(&own),
        SigmaDzMethod::Station => None,
    };
    let rule = SigmaRule {
        floor_rad,
        fallback_rad,
        pooled_dof,
        moderated,
    };
    let mut left_out: Vec<Option<StationSigma>> = vec![None; readings.len()];
    let mut station = BTreeMap::new();
    let scale_floor = rule
        .moderated
        .as_ref()
        .map_or(floor_rad, |m| m.prior_variance.sqrt().max(floor_rad));
    for (id, ks) in by_station {
        let dz = dz_of(&ks);
        let whole = rule.sigma(&dz);
        let gross = weights::gross_readings(&dz, scale_floor);
        for (j, &k) in ks.iter().enumerate() {
            let others: Vec<f64> = dz
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != j && !gross[i])
                .map(|(_, &x)| x)
                .collect();
            let without = rule.sigma(&others);
            left_out[k] = Some(if whole.dof.is_none() || without.dof.is_none() {
                whole
            } else {
                without
            });
        }
        station.insert(id.to_owned(), whole);
    }
    SessionSigmas {
        station,
        left_out: left_out
            .into_iter()
            .map(|s| s.expect("every reading has a station"))
            .collect(),
    }
}

/// The windows of every session's readings, in time order.
pub(crate) fn open_windows(
    ds: &Dataset,
    theodolite: &BTreeMap<String, Vec<tables::theodolite::Reading>>,
    half_ns: i64,
) -> Vec<Vec<Pending>> {
    ds.sessions
        .iter()
        .map(|s| {
            let mut rows: Vec<tables::theodolite::Reading> =
                theodolite.get(&s.session.id).cloned().unwrap_or_default();
            rows.sort_by_key(|r| (r.time_gps_ns, r.line));
            rows.into_iter()
                .map(|r| Pending {
                    start_ns: r.time_gps_ns - half_ns,
                    end_ns: r.time_gps_ns + half_ns,
                    reading: r,
                    sums: Default::default(),
                })
                .collect()
        })
        .collect()
}

/// One pass over the acceleration stream, adding every sample to the windows it falls in,
/// and to the still interval it falls in (`interval_ns`: the nominal sample interval).
pub(crate) fn fill_windows(
    ingest_dir: &Path,
    pending: &mut [Vec<Pending>],
    still: &mut [Vec<StillInterval>],
    interval_ns: i64,
) -> Result<()> {
    let mut cursor: Vec<(usize, usize)> = vec![(0, 0); pending.len()]; // (first active, next to open)
    let mut still_cursor = vec![0usize; still.len()];
    crate::samples::samples(ingest_dir, |session, time_ns, counts, status| {
        let si = usize::from(session);
        if si >= pending.len() {
            return;
        }
        add_to_still(
            &mut still[si],
            &mut still_cursor[si],
            time_ns,
            counts,
            status,
            interval_ns,
        );
        let windows = &mut pending[si];
        let (first, next) = &mut cursor[si];
        while *next < windows.len() && windows[*next].start_ns <= time_ns {
            *next += 1;
        }
        while *first < *next && windows[*first].end_ns <= time_ns {
            *first += 1;
        }
        for w in &mut windows[*first..*next] {
            if time_ns >= w.end_ns {
                continue;
            }
            let t_s = (time_ns - w.reading.time_gps_ns) as f64 * 1e-9;
            for ch in 0..3 {
                let s = &mut w.sums[ch];
                s.rows += 1;
                if status::not_connected(status, ch) {
                    s.not_connected += 1;
                } else if status::over_range(status, ch) {
                    s.saturated += 1;
                } else if let Some(x) = counts[ch] {
                    s.add(t_s, x);
                }
            }
        }
    })
}

/// Adds a sample to the still interval it falls in, if any (intervals in time order,
/// `cursor` the first that has not ended).
pub(crate) fn add_to_still(
    intervals: &mut [StillInterval],
    cursor: &mut usize,
    time_ns: i64,
    counts: [Option<f64>; 3],
    status: u8,
    interval_ns: i64,
) {
    while *cursor < intervals.len() && intervals[*cursor].end_ns <= time_ns {
        *cursor += 1;
    }
    let Some(iv) = intervals.get_mut(*cursor) else {
        return;
    };
    if time_ns < iv.start_ns {
        return;
    }
    // A gap of more than half an interval beyond the nominal one breaks the series.
    let gap = iv
        .last_ns
        .is_some_and(|l| time_ns - l > interval_ns + interval_ns / 2);
    iv.last_ns = Some(time_ns);
    for ch in 0..3 {
        match counts[ch] {
            Some(c)
                if !gap
                    && !status::not_connected(status, ch)
                    && !status::over_range(status, ch) =>
            {
                if iv.counts[ch].len() < MAX_STILL_SAMPLES {
                    iv.counts[ch].push(c);
                }
            }
            _ => iv.broken[ch] = true,
        }
    }
}

/// The ADC noise of every accelerometer: the Allan deviation of its counts pooled over the
/// unbroken still intervals of all sessions (averaging factors in octaves up to a quarter of
/// the longest), and the three terms fitted to it.
pub(crate) fn adc_noise(ds: &Dataset, still: &[Vec<StillInterval>], tau0_s: f64) -> Vec<AdcNoise> {
    ds.manifest
        .instrument
        .accelerometer
        .iter()
        .filter_map(|acc| {
            let ch = usize::from(acc.channel) - 1;
            let series: Vec<&[f64]> = still
                .iter()
                .flatten()
                .filter(|iv| !iv.broken[ch] && iv.counts[ch].len() >= 64)
                .map(|iv| iv.counts[ch].as_slice())
                .collect();
            let longest = series.iter().map(|s| s.len()).max()?;
            let points = allan::pooled(&series, tau0_s, &allan::still_interval_factors(longest));
            let lengths: Vec<usize> = series.iter().map(|s| s.len()).collect();
            let fitted = allan::fit_noise_levels(&points, &lengths);
            let fit = fitted.terms;
            Some(AdcNoise {
                accelerometer: acc.id.clone(),
                still_intervals: series.len(),
                samples: series.iter().map(|s| s.len()).sum(),
                allan: points.iter().map(allan_row).collect(),
                white_density_counts_per_sqrt_hz: fit.white_density,
                bias_instability_counts: fit.bias_instability,
                random_walk_counts_sqrt_hz: fit.random_walk,
                bias_instability_dof: fitted.bias_instability_dof,
                random_walk_dof: fitted.random_walk_dof,
            })
        })
        .collect()
}

/// The variance that an accelerometer's flicker and random walk add to a window mean of
/// `window_s`, counts^2: their terms of the fitted Allan variance at the window's length
/// (docs/model.md 6.2), 0 when the Allan deviation shows white noise only. The sd of a window
/// mean is then sqrt(s^2/n + this): s^2/n alone is the sd of a mean only for white noise.
pub(crate) fn coloured_variance(noise: &[AdcNoise], accelerometer: &str, window_s: f64) -> f64 {
    noise
        .iter()
        .find(|n| n.accelerometer == accelerometer)
        .map_or(0.0, |n| {
            allan::NoiseTerms {
                white_density: 0.0,
                bias_instability: n.bias_instability_counts,
                random_walk: n.random_walk_counts_sqrt_hz,
            }
            .allan_variance(window_s)
        })
}
