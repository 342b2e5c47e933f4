//! gravcal's `align` stage: from the raw streams to observations (docs/model.md section 1).
//!
//! One observation per (theodolite reading, accelerometer): the mean ADC count in a window of
//! `window_s` centred on the reading's GPS time (half-open, `[t - w/2, t + w/2)`, so a
//! 2.56 s window at 31.25 Hz holds exactly 80 samples), the sd of that mean, the
//! accelerometer's temperature interpolated at the reading's time, and sigma_Dz, the sample
//! sd of the station's readings (eq. 4 of the paper). An observation that cannot be used is
//! kept with the reason (the first that applies, in this order): a sample flagged not
//! connected, a saturated sample, too few samples, no temperature near enough, or a trend in
//! the window (the platform was not still). A channel not connected for a whole session
//! yields no observations, and one line saying so.
//!
//! Reads OUT/ingest/ (the tables of [`ingest::contract::tables`] and `ingest.json`), writes
//! OUT/align/observations.parquet and OUT/align/align.json. The acceleration table is
//! streamed once, in order: time is linear in the number of samples and memory does not
//! grow with it.

pub mod allan;
pub mod colour;
pub mod read;
pub mod statics;
pub mod tide;
pub mod weights;
pub mod window;

use ingest::contract::align_ledger::{
    AdcNoise, AlignReport, AllanRow, Counts, DRIFT_T_LIMIT, Disconnected, LEDGER_FILE,
    LEDGER_FORMAT, MultiPosition, STAGE_DIR, StaticNoise, StaticPosition, reason, sigma_source,
};
use ingest::contract::custody::{Custody, Folders, Root};
use ingest::contract::ledger as ingest_ledger;
use ingest::contract::manifest::{
    self, AlignConfig, Dataset, Location, ReadingUnit, SessionKind, SigmaDzMethod,
};
use ingest::contract::{status, tables};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use window::{WindowStats, WindowSums, interpolate, sample_sd};

/// What can go wrong in align.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading the manifest or ingest's outputs, or writing a table.
    #[error(transparent)]
    Ingest(#[from] ingest::Error),
    /// An input table is not what ingest writes (a missing column, a wrong type).
    #[error("{}: {message}", path.display())]
    Table {
        /// The table.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// Reading a Parquet table failed.
    #[error("{}: {source}", path.display())]
    Parquet {
        /// The table.
        path: PathBuf,
        /// The underlying error.
        source: parquet::errors::ParquetError,
    },
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// One observation.
#[derive(Clone, Debug, PartialEq)]
pub struct Observation {
    /// Session id.
    pub session: String,
    /// Accelerometer id.
    pub accelerometer: String,
    /// Channel 1..3.
    pub channel: u8,
    /// Station id.
    pub station: String,
    /// Line in the theodolite log.
    pub line: u32,
    /// GPS time of the reading, ns.
    pub time_gps_ns: i64,
    /// Zenith distance, rad.
    pub dz_rad: f64,
    /// Sd of one reading at the station, rad.
    pub sigma_dz_rad: f64,
    /// `moderated`, `station_sd`, `manifest` or `resolution`.
    pub sigma_dz_source: &'static str,
    /// Degrees of freedom of sigma_dz when estimated from readings: the moderated
    /// variance's prior dof plus the station's own, or the station's own (eq. 4); None when
    /// taken as known (manifest, resolution floor).
    pub sigma_dz_dof: Option<f64>,
    /// g |sin Dz| sigma_Dz, mGal.
    pub sigma_am_mgal: f64,
    /// Mean count.
    pub ng: Option<f64>,
    /// Sd of the mean count.
    pub sigma_ng: Option<f64>,
    /// Valid samples in the window.
    pub n_samples: u32,
    /// Samples a full window holds.
    pub expected_samples: f64,
    /// Temperature at the reading, degC.
    pub temperature_c: Option<f64>,
    /// Trend t statistic.
    pub drift_t: Option<f64>,
    /// Why it is not used.
    pub excluded: Option<&'static str>,
    /// Body tide at the reading's time, mGal (None when no tide is applied).
    pub tide_mgal: Option<f64>,
    /// Gravity at the proof masses at the reading: g, plus the tide when applied, mGal.
    pub gravity_mgal: f64,
}

/// A reading with its windows being filled.
struct Pending {
    reading: read::TheodoliteRow,
    start_ns: i64,
    end_ns: i64,
    sums: [WindowSums; 3],
}

/// Most samples kept per still interval and channel for the Allan deviation (2^16, about 35
/// min at 31.25 Hz): memory stays bounded on long logs.
const MAX_STILL_SAMPLES: usize = 1 << 16;

/// The platform at rest at one station: from the window of its first reading to that of its
/// last, the counts of each channel, for the Allan deviation.
struct StillInterval {
    start_ns: i64,
    end_ns: i64,
    counts: [Vec<f64>; 3],
    /// A sample flagged, missing, or a gap in time: the series is not usable.
    broken: [bool; 3],
    last_ns: Option<i64>,
}

/// The still intervals of a session's readings (in time order): one per run of readings at
/// the same station.
fn still_intervals(windows: &[Pending]) -> Vec<StillInterval> {
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
struct StationSigma {
    sigma_rad: f64,
    source: &'static str,
    dof: Option<f64>,
}

/// sigma_Dz per station of one session, never below the quantisation of the log: the step
/// of the finest last decimal the session's readings were logged with, over sqrt(12). By
/// default each station's variance is moderated toward the session's ([`weights`]; a
/// station of one reading takes the session's prior), on the prior's dof plus its own (the
/// pooled dof when the stations are alike); with `sigma_dz = "station"` it is the station's
/// own sd (eq. 4) on n - 1 dof, and a station of one reading takes the manifest's
/// `theodolite_sigma_arcsec`, taken as known like the resolution floor.
fn station_sigmas(
    readings: &[Pending],
    fallback_rad: f64,
    method: SigmaDzMethod,
) -> BTreeMap<String, StationSigma> {
    let floor_rad = readings
        .iter()
        .map(|p| p.reading.step_rad)
        .fold(f64::INFINITY, f64::min)
        / 12f64.sqrt();
    let mut by_station: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for p in readings {
        by_station
            .entry(p.reading.station.as_str())
            .or_default()
            .push(p.reading.dz_rad);
    }
    let own: Vec<(f64, f64)> = by_station
        .values()
        .map(|dz| match sample_sd(dz) {
            Some(sd) => (sd.max(floor_rad).powi(2), (dz.len() - 1) as f64),
            None => (0.0, 0.0),
        })
        .collect();
    let pooled_dof: f64 = own.iter().map(|&(_, d)| d).sum();
    let moderated = match method {
        SigmaDzMethod::Moderated => weights::moderate(&own),
        SigmaDzMethod::Station => None,
    };
    let at = |sigma_rad, source, dof| StationSigma {
        sigma_rad,
        source,
        dof,
    };
    by_station
        .into_iter()
        .enumerate()
        .map(|(i, (station, dz))| {
            let sigma = match (&moderated, sample_sd(&dz)) {
                (Some(m), _) if m.variances[i].sqrt() >= floor_rad => {
                    let dof = if m.prior_dof.is_finite() {
                        m.prior_dof + own[i].1
                    } else {
                        pooled_dof
                    };
                    at(m.variances[i].sqrt(), sigma_source::MODERATED, Some(dof))
                }
                (Some(_), _) => at(floor_rad, sigma_source::RESOLUTION, None),
                (None, None) => at(fallback_rad, sigma_source::MANIFEST, None),
                (None, Some(sd)) if sd >= floor_rad => {
                    at(sd, sigma_source::STATION_SD, Some(own[i].1))
                }
                (None, Some(_)) => at(floor_rad, sigma_source::RESOLUTION, None),
            };
            (station.to_owned(), sigma)
        })
        .collect()
}

/// What forming observations needs, from the manifest.
struct Setup {
    cfg: AlignConfig,
    g: f64,
    expected: f64,
    half_ns: i64,
    max_gap_ns: i64,
    fallback_sigma_rad: f64,
    location: Option<Location>,
    /// A sample's variance floor: the rounding to counts, or 0 for another reading unit.
    floor_variance: f64,
}

impl Setup {
    fn new(ds: &Dataset) -> Self {
        let cfg = ds.manifest.align.clone();
        Setup {
            g: ds.manifest.site.gravity_mgal(),
            expected: cfg.window_s * ds.manifest.instrument.sample_rate_hz,
            half_ns: (cfg.window_s * 0.5e9).round() as i64,
            max_gap_ns: (cfg.max_temperature_gap_s * 1e9).round() as i64,
            fallback_sigma_rad: (cfg.theodolite_sigma_arcsec / 3600.0).to_radians(),
            location: ds.manifest.site.tide_location(),
            floor_variance: if ds.manifest.instrument.reading_unit == ReadingUnit::Count {
                window::QUANTISATION_VARIANCE
            } else {
                0.0
            },
            cfg,
        }
    }

    /// The body tide at `gps_ns`, when the site's location asks for it.
    fn tide(&self, gps_ns: i64) -> Option<f64> {
        self.location.map(|l| {
            let site = tide::Site {
                latitude_deg: l.latitude_deg,
                longitude_deg: l.longitude_deg,
                height_m: l.height_m,
            };
            tide::body_tide_mgal(site, tide::utc_seconds_of_gps(gps_ns))
        })
    }

    /// Why a window cannot be used, the first reason that applies; None when it can.
    fn exclusion(
        &self,
        w: &WindowSums,
        stats: Option<WindowStats>,
        has_temperatures: bool,
        temperature: Option<f64>,
    ) -> Option<&'static str> {
        if w.not_connected > 0 {
            Some(reason::NOT_CONNECTED)
        } else if w.saturated > 0 {
            Some(reason::SATURATED)
        } else if f64::from(w.rows) < self.cfg.min_window_fill * self.expected || stats.is_none() {
            Some(reason::WINDOW_UNDERFILLED)
        } else if !has_temperatures {
            Some(reason::NO_TEMPERATURE)
        } else if temperature.is_none() {
            Some(reason::TEMPERATURE_GAP)
        } else if stats.is_some_and(|s| s.drift_t.abs() > DRIFT_T_LIMIT) {
            Some(reason::WINDOW_DRIFT)
        } else {
            None
        }
    }
}

/// Aligns the dataset: reads OUT/ingest, writes OUT/align. Returns the ledger.
pub fn run(dataset: &Path, out: &Path) -> Result<AlignReport> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::lock::OutputLock::acquire(out)?;
    let ingest_dir = out.join(ingest_ledger::STAGE_DIR);
    let ingest_report = ingest_ledger::IngestReport::load_verified(&ds, out)?;
    let setup = Setup::new(&ds);
    let temperatures = read::temperatures(&ingest_dir)?;
    let mut pending = open_windows(&ds, &read::theodolite(&ingest_dir)?, setup.half_ns);
    let mut still: Vec<Vec<StillInterval>> = pending.iter().map(|p| still_intervals(p)).collect();
    let tau0_s = 1.0 / ds.manifest.instrument.sample_rate_hz;
    fill_windows(
        &ingest_dir,
        &mut pending,
        &mut still,
        (tau0_s * 1e9).round() as i64,
    )?;
    let mut formed = Formed {
        noise: adc_noise(&ds, &still, tau0_s),
        ..Formed::default()
    };
    for (si, s) in ds.sessions.iter().enumerate() {
        if !s.is_tilt_table() {
            continue;
        }
        let never = ingest_report
            .sessions
            .iter()
            .find(|x| x.id == s.session.id)
            .map(|x| x.channels_never_connected.clone())
            .unwrap_or_default();
        let temps = |channel: u8| {
            u16::try_from(si)
                .ok()
                .and_then(|i| temperatures.get(&(i, channel)))
        };
        observe_session(
            &ds,
            &setup,
            &s.session.id,
            &pending[si],
            &never,
            temps,
            &mut formed,
        );
    }
    formed.multi_position = multi_positions(&ds, &setup, &ingest_dir, &temperatures)?;
    write_outputs(&ds, out, setup, formed)
}

/// The static positions of every multi-position session: listed in the manifest, or found
/// by [`statics::detect`]; an interval of fewer than [`statics::MIN_POSITION_SAMPLES`] or with an
/// axis of fewer than three values is counted, not used. Each position's temperature per
/// channel is the mean over its samples' times of the temperature interpolated as for a
/// window (the average the mean reading sees; none when a channel has no sample within
/// the gap allowed: a model without temperature terms still uses the position).
fn multi_positions(
    ds: &Dataset,
    setup: &Setup,
    ingest_dir: &Path,
    temperatures: &read::Temperatures,
) -> Result<Vec<MultiPosition>> {
    let wanted: Vec<u16> = ds
        .sessions
        .iter()
        .enumerate()
        .filter(|(_, s)| s.session.kind == SessionKind::MultiPosition)
        .filter_map(|(i, _)| u16::try_from(i).ok())
        .collect();
    if wanted.is_empty() {
        return Ok(Vec::new());
    }
    let mut series = read::series(ingest_dir, &wanted)?;
    wanted
        .into_iter()
        .map(|w| {
            let data = series.remove(&w).unwrap_or_default();
            session_positions(ds, setup, ingest_dir, (w, &data), temperatures)
        })
        .collect()
}

/// One multi-position session's static intervals: listed or detected, the method and the
/// detector's figures recorded in `mp`.
fn find_intervals(
    s: &manifest::ResolvedSession,
    data: &statics::Series,
    rate: f64,
    ingest_dir: &Path,
    mp: &mut MultiPosition,
) -> Result<Vec<(usize, usize)>> {
    if let Some(listed) = &s.session.static_s {
        mp.method = "listed".to_owned();
        return Ok(statics::listed(data, listed));
    }
    mp.method = "detected".to_owned();
    let quiet_s = s.session.quiet_start_s.unwrap_or(statics::QUIET_S);
    let d = statics::detect(data, rate, quiet_s).map_err(|e| Error::Table {
        path: ingest_dir.join(tables::lab::FILE),
        message: format!("session {}: {e}", s.session.id),
    })?;
    mp.window_s = d.window as f64 / rate;
    mp.quiet_start_s = Some(quiet_s);
    mp.quiet_sd = Some(d.quiet_sd);
    mp.still_sd = d.still_sd;
    mp.warnings.extend(d.warning);
    mp.threshold = Some(d.threshold);
    Ok(d.intervals)
}

/// One multi-position session (index `w`, readings `data`): its intervals, those usable
/// (the others counted by reason), its noise, and a position per usable interval.
fn session_positions(
    ds: &Dataset,
    setup: &Setup,
    ingest_dir: &Path,
    (w, data): (u16, &statics::Series),
    temperatures: &read::Temperatures,
) -> Result<MultiPosition> {
    let s = &ds.sessions[usize::from(w)];
    let rate = ds.manifest.instrument.sample_rate_hz;
    let mut mp = MultiPosition {
        session: s.session.id.clone(),
        method: String::new(),
        quiet_start_s: None,
        quiet_sd: None,
        still_sd: None,
        warnings: Vec::new(),
        window_s: statics::WINDOW_S,
        threshold: None,
        found: 0,
        used: 0,
        rejected: Default::default(),
        noise: Vec::new(),
        positions: Vec::new(),
    };
    let intervals = find_intervals(s, data, rate, ingest_dir, &mut mp)?;
    mp.found = intervals.len() as u64;
    // A detected interval is clear of the motion by half a window each side already; it
    // needs the samples its sigma needs.
    let min_samples = statics::MIN_POSITION_SAMPLES;
    let mut kept = Vec::new();
    for (i, j) in intervals {
        let short = mp.method == "detected" && j - i < min_samples;
        match (!short).then(|| statics::means(data, (i, j))).flatten() {
            Some(stats) => kept.push(((i, j), stats)),
            None => {
                let why = if short { "too_short" } else { "no_samples" };
                *mp.rejected.entry(why.to_owned()).or_default() += 1;
            }
        }
    }
    let spans: Vec<(usize, usize)> = kept.iter().map(|(span, _)| *span).collect();
    let noise = statics::noise(data, &spans, 1.0 / rate);
    mp.noise = static_noise(ds, &noise);
    for ((i, j), (mean, white, samples)) in kept {
        let (t0, t1) = (data.time_ns[i], data.time_ns[j - 1]);
        let duration_s = (j - i) as f64 / rate;
        let sigma = std::array::from_fn(|k| {
            let coloured = noise[k]
                .as_ref()
                .map_or(0.0, |n| n.coloured_variance(duration_s));
            (white[k] * white[k] + coloured).sqrt()
        });
        let temperature_c = [1u8, 2, 3].map(|ch| {
            let (t, v) = temperatures.get(&(w, ch))?;
            interval_mean(t, v, &data.time_ns[i..j], setup.max_gap_ns)
        });
        mp.positions.push(StaticPosition {
            start_gps_ns: t0,
            end_gps_ns: t1,
            samples,
            mean,
            sigma,
            sigma_white: Some(white),
            gravity_mgal: setup.g + setup.tide(t0 / 2 + t1 / 2).unwrap_or(0.0),
            temperature_c: match temperature_c {
                [Some(a), Some(b), Some(c)] => Some([a, b, c]),
                _ => None,
            },
        });
    }
    mp.used = mp.positions.len() as u64;
    Ok(mp)
}

/// One point of an Allan curve for align.json.
fn allan_row(p: &allan::AllanPoint) -> AllanRow {
    AllanRow {
        tau_s: p.tau_s,
        adev: p.adev,
        lower: p.interval.0,
        upper: p.interval.1,
        edf: p.edf,
    }
}

/// A multi-position session's noise per axis for align.json, in the reading unit.
fn static_noise(ds: &Dataset, noise: &[Option<statics::AxisNoise>; 3]) -> Vec<StaticNoise> {
    let unit = ds.manifest.instrument.reading_unit.name().to_owned();
    noise
        .iter()
        .enumerate()
        .filter_map(|(k, n)| {
            let n = n.as_ref()?;
            Some(StaticNoise {
                channel: u8::try_from(k + 1).unwrap_or(0),
                unit: unit.clone(),
                intervals: n.intervals,
                samples: n.samples,
                allan: n.points.iter().map(allan_row).collect(),
                white_density_per_sqrt_hz: n.terms.white_density,
                bias_instability: n.terms.bias_instability,
                random_walk_sqrt_hz: n.terms.random_walk,
            })
        })
        .collect()
}

/// The mean of a temperature series interpolated at `times` (sorted); none when any of
/// them is farther than `max_gap_ns` from a temperature sample.
fn interval_mean(t: &[i64], v: &[f64], times: &[i64], max_gap_ns: i64) -> Option<f64> {
    let mut it = window::Interpolator::new(t, v);
    let mut sum = 0.0;
    for &time in times {
        sum += it.at(time, max_gap_ns)?.0;
    }
    (!times.is_empty()).then(|| sum / times.len() as f64)
}

/// The windows of every session's readings, in time order.
fn open_windows(
    ds: &Dataset,
    theodolite: &BTreeMap<String, Vec<read::TheodoliteRow>>,
    half_ns: i64,
) -> Vec<Vec<Pending>> {
    ds.sessions
        .iter()
        .map(|s| {
            let mut rows: Vec<read::TheodoliteRow> =
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
fn fill_windows(
    ingest_dir: &Path,
    pending: &mut [Vec<Pending>],
    still: &mut [Vec<StillInterval>],
    interval_ns: i64,
) -> Result<()> {
    let mut cursor: Vec<(usize, usize)> = vec![(0, 0); pending.len()]; // (first active, next to open)
    let mut still_cursor = vec![0usize; still.len()];
    read::samples(ingest_dir, |session, time_ns, counts, status| {
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
fn add_to_still(
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
/// unbroken still intervals of all sessions (averaging factors in octaves up to a tenth of
/// the longest), and the three terms fitted to it.
fn adc_noise(ds: &Dataset, still: &[Vec<StillInterval>], tau0_s: f64) -> Vec<AdcNoise> {
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
            let points = allan::pooled(&series, tau0_s, &allan::octave_factors(longest));
            let fit = allan::fit_noise(&points);
            Some(AdcNoise {
                accelerometer: acc.id.clone(),
                still_intervals: series.len(),
                samples: series.iter().map(|s| s.len()).sum(),
                allan: points.iter().map(allan_row).collect(),
                white_density_counts_per_sqrt_hz: fit.white_density,
                bias_instability_counts: fit.bias_instability,
                random_walk_counts_sqrt_hz: fit.random_walk,
            })
        })
        .collect()
}

/// The variance that an accelerometer's flicker and random walk add to a window mean of
/// `window_s`, counts^2: their terms of the fitted Allan variance at the window's length
/// (docs/model.md 6.2), 0 when the Allan deviation shows white noise only. The sd of a window
/// mean is then sqrt(s^2/n + this): s^2/n alone is the sd of a mean only for white noise.
fn coloured_variance(noise: &[AdcNoise], accelerometer: &str, window_s: f64) -> f64 {
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

/// What the sessions gave: observations and their counts.
#[derive(Default)]
struct Formed {
    observations: Vec<Observation>,
    counts: Vec<Counts>,
    disconnected: Vec<Disconnected>,
    noise: Vec<AdcNoise>,
    multi_position: Vec<MultiPosition>,
}

/// The observations of one session, one per (reading, accelerometer); `never` lists the
/// channels not connected in any sample, `temps` gives a channel's temperature series.
fn observe_session<'t>(
    ds: &Dataset,
    setup: &Setup,
    id: &str,
    pending: &[Pending],
    never: &[u8],
    temps: impl Fn(u8) -> Option<&'t (Vec<i64>, Vec<f64>)>,
    formed: &mut Formed,
) {
    let sigma = station_sigmas(pending, setup.fallback_sigma_rad, setup.cfg.sigma_dz);
    for acc in &ds.manifest.instrument.accelerometer {
        let ch = usize::from(acc.channel) - 1;
        if never.contains(&acc.channel) {
            formed.disconnected.push(Disconnected {
                session: id.to_owned(),
                accelerometer: acc.id.clone(),
                channel: acc.channel,
                reason: "channel not connected in any sample of the session".to_owned(),
            });
            continue;
        }
        let temps = temps(acc.channel);
        let coloured = coloured_variance(&formed.noise, &acc.id, setup.cfg.window_s);
        let mut c = Counts {
            session: id.to_owned(),
            accelerometer: acc.id.clone(),
            readings: pending.len() as u64,
            used: 0,
            excluded: BTreeMap::new(),
        };
        for p in pending {
            let w = &p.sums[ch];
            let stats = w.stats(setup.floor_variance);
            let StationSigma {
                sigma_rad: sigma_dz_rad,
                source,
                dof: sigma_dz_dof,
            } = sigma[p.reading.station.as_str()];
            let temperature =
                temps.and_then(|(t, v)| interpolate(t, v, p.reading.time_gps_ns, setup.max_gap_ns));
            let has_temperatures = temps.is_some_and(|(t, _)| !t.is_empty());
            let excluded = setup.exclusion(w, stats, has_temperatures, temperature.map(|(v, _)| v));
            match excluded {
                Some(r) => *c.excluded.entry(r.to_owned()).or_default() += 1,
                None => c.used += 1,
            }
            let tide_mgal = setup.tide(p.reading.time_gps_ns);
            formed.observations.push(Observation {
                session: id.to_owned(),
                accelerometer: acc.id.clone(),
                channel: acc.channel,
                station: p.reading.station.clone(),
                line: p.reading.line,
                time_gps_ns: p.reading.time_gps_ns,
                dz_rad: p.reading.dz_rad,
                sigma_dz_rad,
                sigma_dz_source: source,
                sigma_dz_dof,
                sigma_am_mgal: setup.g * p.reading.dz_rad.sin().abs() * sigma_dz_rad,
                ng: stats.map(|s| s.mean),
                sigma_ng: stats.map(|s| (s.sigma_mean.powi(2) + coloured).sqrt()),
                n_samples: w.n,
                expected_samples: setup.expected,
                temperature_c: temperature.map(|(v, _)| v),
                drift_t: stats.map(|s| s.drift_t),
                excluded,
                tide_mgal,
                gravity_mgal: setup.g + tide_mgal.unwrap_or(0.0),
            });
        }
        formed.counts.push(c);
    }
}

/// Writes observations.parquet and align.json (with the chain of custody); fails, after
/// writing, when a session gave no usable observation.
fn write_outputs(ds: &Dataset, out: &Path, setup: Setup, formed: Formed) -> Result<AlignReport> {
    let dir = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| ingest::Error::Io {
        path: dir.clone(),
        source: e,
    })?;
    let ledger_path = dir.join(LEDGER_FILE);
    ingest::remove_stale(&ledger_path)?;
    let rows = read::write_observations(&dir, &formed.observations)?;
    let folders = Folders {
        dataset: &ds.dir,
        out,
    };
    let mut inputs = vec![folders.record(Root::Dataset, ingest_ledger::MANIFEST_FILE)?];
    for file in [
        ingest_ledger::LEDGER_FILE,
        tables::acceleration::FILE,
        tables::temperature::FILE,
        tables::theodolite::FILE,
        tables::lab::FILE,
    ] {
        inputs.push(folders.record(Root::Out, &format!("{}/{file}", ingest_ledger::STAGE_DIR))?);
    }
    let outputs = vec![folders.record(
        Root::Out,
        &format!("{STAGE_DIR}/{}", tables::observations::FILE),
    )?];
    let errors = ds
        .sessions
        .iter()
        .filter(|s| !s.session.expect_empty && s.is_tilt_table())
        .filter(|s| {
            formed
                .counts
                .iter()
                .filter(|c| c.session == s.session.id)
                .all(|c| c.used == 0)
        })
        .map(|s| {
            format!(
                "session {}: no usable observation for any accelerometer (align.json counts why; \
                 if this is expected, set `expect_empty = true` in its [[session]])",
                s.session.id
            )
        })
        .collect();
    let report = AlignReport {
        format: LEDGER_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        gravity_mgal: setup.g,
        earth_tide_applied: setup.location.is_some(),
        noise: formed.noise,
        config: setup.cfg,
        counts: formed.counts,
        disconnected: formed.disconnected,
        observations: rows,
        custody: Custody { inputs, outputs },
        multi_position: formed.multi_position,
        surveys: ds
            .sessions
            .iter()
            .filter(|s| s.is_survey())
            .map(|s| s.session.id.clone())
            .collect(),
        errors,
    };
    ingest::write_json_atomically(&ledger_path, &report)?;
    if !report.errors.is_empty() {
        return Err(ingest::Error::Unusable {
            path: ledger_path,
            errors: report.errors,
        }
        .into());
    }
    Ok(report)
}

/// Writes a few lines: per session and accelerometer, used and excluded by reason.
pub fn print_summary(report: &AlignReport, w: &mut impl std::io::Write) {
    for c in &report.counts {
        let ex: Vec<String> = c.excluded.iter().map(|(r, n)| format!("{n} {r}")).collect();
        let _ = writeln!(
            w,
            "align: {} {}: {} readings, {} used{}",
            c.session,
            c.accelerometer,
            c.readings,
            c.used,
            if ex.is_empty() {
                String::new()
            } else {
                format!(", excluded: {}", ex.join(", "))
            }
        );
    }
    for d in &report.disconnected {
        let _ = writeln!(
            w,
            "align: {} {}: no observations: channel {} not connected for the whole session",
            d.session, d.accelerometer, d.channel
        );
    }
    for mp in &report.multi_position {
        print_positions(mp, w);
    }
}

/// A multi-position session's line: how its intervals were had, found, used, rejected by
/// reason, the detector's figures, and its warnings.
fn print_positions(mp: &MultiPosition, w: &mut impl std::io::Write) {
    let rejected: Vec<String> = mp
        .rejected
        .iter()
        .map(|(r, n)| format!("{n} {r}"))
        .collect();
    let sd = |v: &[f64; 3]| {
        v.iter()
            .map(|x| format!("{x:.3e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let detector = match (mp.quiet_start_s, &mp.quiet_sd, mp.threshold) {
        (Some(q), Some(quiet), Some(th)) => format!(
            "; detector: quiet start {q} s (sd {}), noise inside the still stretches (sd {}), \
             window {} s, threshold {th:.3}",
            sd(quiet),
            mp.still_sd.as_ref().map_or_else(|| "-".to_owned(), sd),
            mp.window_s
        ),
        _ => String::new(),
    };
    let _ = writeln!(
        w,
        "align: {} ({} intervals): {} found, {} used as positions{}{detector}",
        mp.session,
        mp.method,
        mp.found,
        mp.used,
        if rejected.is_empty() {
            String::new()
        } else {
            format!(", rejected: {}", rejected.join(", "))
        }
    );
    for warning in &mp.warnings {
        let _ = writeln!(w, "align: {}: WARNING: {warning}", mp.session);
    }
}
