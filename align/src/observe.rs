//! Observations formed from the windows (one per reading and accelerometer, with the
//! exclusion reasons), align.json written with its chain of custody, and the console's
//! summary.

use super::{
    AdcNoise, AlignConfig, AlignReport, BTreeMap, Counts, Custody, DRIFT_T_LIMIT, Dataset,
    Disconnected, Folders, LEDGER_FILE, LEDGER_FORMAT, Location, MultiPosition, Observation, Path,
    Pending, ReadingUnit, Result, Root, STAGE_DIR, StationSigma, Thermometers, WindowStats,
    WindowSums, coloured_variance, ingest_ledger, interpolate, print_positions, reason,
    station_sigmas, tables, thermometer, tide, window,
};

/// What forming observations needs, from the manifest.
pub(crate) struct Setup {
    pub(crate) cfg: AlignConfig,
    pub(crate) g: f64,
    pub(crate) expected: f64,
    pub(crate) half_ns: i64,
    pub(crate) max_gap_ns: i64,
    pub(crate) fallback_sigma_rad: f64,
    pub(crate) location: Option<Location>,
    /// A sample's variance floor: the rounding to counts, or 0 for another reading unit.
    pub(crate) floor_variance: f64,
}

impl Setup {
    pub(crate) fn new(ds: &Dataset) -> Self {
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
    pub(crate) fn tide(&self, gps_ns: i64) -> Option<f64> {
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
    pub(crate) fn exclusion(
        &self,
        w: &WindowSums,
        stats: Option<WindowStats>,
        thermometer: Thermometer,
        temperature: Option<f64>,
    ) -> Option<&'static str> {
        if w.not_connected > 0 {
            Some(reason::NOT_CONNECTED)
        } else if w.saturated > 0 {
            Some(reason::SATURATED)
        } else if f64::from(w.rows) < self.cfg.min_window_fill * self.expected || stats.is_none() {
            Some(reason::WINDOW_UNDERFILLED)
        } else if thermometer == Thermometer::Silent {
            Some(reason::NO_TEMPERATURE)
        } else if thermometer == Thermometer::Logged && temperature.is_none() {
            Some(reason::TEMPERATURE_GAP)
        } else if stats.is_some_and(|s| s.drift_t.abs() > DRIFT_T_LIMIT) {
            Some(reason::WINDOW_DRIFT)
        } else {
            None
        }
    }
}

/// What a session's temperature log gives an accelerometer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Thermometer {
    /// The session declares none (`thermometers = "none"`): its observations carry no
    /// temperature, and none is missing.
    Declared,
    /// One is expected, and its log has no sample for the channel.
    Silent,
    /// Its log has samples for the channel.
    Logged,
}

/// What the sessions gave: observations and their counts.
#[derive(Default)]
pub(crate) struct Formed {
    pub(crate) observations: Vec<Observation>,
    pub(crate) counts: Vec<Counts>,
    pub(crate) disconnected: Vec<Disconnected>,
    pub(crate) noise: Vec<AdcNoise>,
    pub(crate) multi_position: Vec<MultiPosition>,
}

/// An accelerometer whose channel no sample of session `id` connected.
fn never_connected(id: &str, accelerometer: &str, channel: u8) -> Disconnected {
    Disconnected {
        session: id.to_owned(),
        accelerometer: accelerometer.to_owned(),
        channel,
        reason: "channel not connected in any sample of the session".to_owned(),
    }
}

/// The temperature at a reading's `time` from the series `temps` (value and distance to the
/// nearest sample), and its sd from the thermometer's noise `sd` through the
/// interpolation's weights.
fn reading_temperature(
    temps: Option<&(Vec<i64>, Vec<f64>)>,
    time: i64,
    max_gap_ns: i64,
    sd: Option<f64>,
) -> (Option<(f64, i64)>, Option<f64>) {
    let Some((t, v)) = temps else {
        return (None, None);
    };
    let squares = thermometer::interval_mean(t, v, &[time], max_gap_ns).map(|(_, q)| q);
    (
        interpolate(t, v, time, max_gap_ns),
        squares.zip(sd).map(|(q, sd)| sd * q.sqrt()),
    )
}

/// The observations of one session, one per (reading, accelerometer); `never` lists the
/// channels not connected in any sample, `temps` gives a channel's temperature series.
/// Session `id`'s accelerometer `acc`'s counts before its `readings` are looked at.
fn counts(id: &str, acc: &str, readings: usize, thermometer_sd_c: Option<f64>) -> Counts {
    Counts {
        session: id.to_owned(),
        accelerometer: acc.to_owned(),
        readings: readings as u64,
        used: 0,
        excluded: BTreeMap::new(),
        thermometer_sd_c,
    }
}

impl Thermometer {
    /// A reading's thermometer: declared none by its session, logging (its channel's
    /// `temps` hold samples), or silent.
    fn of(declared_none: bool, temps: Option<&(Vec<i64>, Vec<f64>)>) -> Self {
        if declared_none {
            Thermometer::Declared
        } else if temps.is_some_and(|(t, _)| !t.is_empty()) {
            Thermometer::Logged
        } else {
            Thermometer::Silent
        }
    }
}

pub(crate) fn observe_session<'t>(
    ds: &Dataset,
    setup: &Setup,
    id: &str,
    pending: &[Pending],
    never: &[u8],
    temps: impl Fn(u8) -> Option<&'t (Vec<i64>, Vec<f64>)>,
    formed: &mut Formed,
) {
    let sigma = station_sigmas(pending, setup.fallback_sigma_rad, setup.cfg.sigma_dz);
    let declared_none = ds
        .sessions
        .iter()
        .any(|s| s.session.id == id && s.session.thermometers == Thermometers::None);
    for acc in &ds.manifest.instrument.accelerometer {
        let ch = usize::from(acc.channel) - 1;
        if never.contains(&acc.channel) {
            formed
                .disconnected
                .push(never_connected(id, &acc.id, acc.channel));
            continue;
        }
        let temps = temps(acc.channel);
        let given = ds.manifest.instrument.thermometer_sd_c;
        let thermometer_sd =
            temps.and_then(|(_, v)| given.or_else(|| thermometer::white_noise_sd(v)));
        let coloured = coloured_variance(&formed.noise, &acc.id, setup.cfg.window_s);
        let mut c = counts(id, &acc.id, pending.len(), thermometer_sd);
        for (k, p) in pending.iter().enumerate() {
            let w = &p.sums[ch];
            let stats = w.stats(setup.floor_variance);
            let StationSigma {
                sigma_rad: sigma_dz_rad,
                source,
                dof: sigma_dz_dof,
            } = sigma.station[p.reading.station.as_str()];
            let left_out = sigma.left_out[k];
            let time = p.reading.time_gps_ns;
            let (temperature, sigma_temperature_c) =
                reading_temperature(temps, time, setup.max_gap_ns, thermometer_sd);
            let thermometer = Thermometer::of(declared_none, temps);
            let excluded = setup.exclusion(w, stats, thermometer, temperature.map(|(v, _)| v));
            match excluded {
                Some(r) => *c.excluded.entry(r.to_owned()).or_default() += 1,
                None => c.used += 1,
            }
            let tide_mgal = setup.tide(time);
            formed.observations.push(Observation {
                session: id.to_owned(),
                accelerometer: acc.id.clone(),
                channel: acc.channel,
                station: p.reading.station.clone(),
                line: p.reading.line,
                time_gps_ns: time,
                dz_rad: p.reading.dz_rad,
                sigma_dz_rad,
                sigma_dz_source: source.to_owned(),
                sigma_dz_dof,
                sigma_dz_loo_rad: left_out.sigma_rad,
                sigma_dz_loo_dof: left_out.dof,
                sigma_am_mgal: setup.g * p.reading.dz_rad.sin().abs() * sigma_dz_rad,
                ng: stats.map(|s| s.mean),
                sigma_ng: stats.map(|s| (s.sigma_mean.powi(2) + coloured).sqrt()),
                sigma_ng_dof: stats.and_then(|s| s.sigma_mean_dof(w.n, coloured)),
                n_samples: w.n,
                expected_samples: setup.expected,
                temperature_c: temperature.map(|(v, _)| v),
                sigma_temperature_c,
                drift_t: stats.map(|s| s.drift_t),
                excluded: excluded.map(str::to_owned),
                tide_mgal,
                gravity_mgal: setup.g + tide_mgal.unwrap_or(0.0),
            });
        }
        formed.counts.push(c);
    }
}

/// Writes observations.parquet and align.json (with the chain of custody); fails, after
/// writing, when a session gave no usable observation.
pub(crate) fn write_outputs(
    ds: &Dataset,
    out: &Path,
    setup: Setup,
    formed: Formed,
) -> Result<AlignReport> {
    let dir = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| ingest::Error::Io {
        path: dir.clone(),
        source: e,
    })?;
    let ledger_path = dir.join(LEDGER_FILE);
    ingest::remove_stale(&ledger_path)?;
    let rows = tables::observations::write(&dir, &formed.observations)?;
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
    let errors = unused_sessions(ds, &formed);
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

/// A tilt-table session that gave no usable observation for any accelerometer (and was not
/// declared `expect_empty`), each as an error naming it.
fn unused_sessions(ds: &Dataset, formed: &Formed) -> Vec<String> {
    ds.sessions
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
        .collect()
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
