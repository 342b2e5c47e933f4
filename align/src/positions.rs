//! The static positions of multi-position sessions: listed in the manifest or found by the
//! detector, their means and sigmas, and the console's summary of them.

use super::{
    AllanRow, Dataset, Error, MultiPosition, Path, Result, SessionKind, Setup, StaticNoise,
    StaticPosition, allan, manifest, statics, tables, thermometer,
};

/// The static positions of every multi-position session: listed in the manifest, or found
/// by [`statics::detect`]; an interval of fewer than [`statics::MIN_POSITION_SAMPLES`] or with an
/// axis of fewer than three values is counted, not used. Each position's temperature per
/// channel is the mean over its samples' times of the temperature interpolated as for a
/// window (the average the mean reading sees; none when a channel has no sample within
/// the gap allowed: a model without temperature terms still uses the position), with its
/// sd from the thermometer's noise ([`thermometer`]).
pub(crate) fn multi_positions(
    ds: &Dataset,
    setup: &Setup,
    ingest_dir: &Path,
    temperatures: &tables::temperature::Temperatures,
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
    let mut series = crate::samples::series(ingest_dir, &wanted)?;
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
pub(crate) fn find_intervals(
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
pub(crate) fn session_positions(
    ds: &Dataset,
    setup: &Setup,
    ingest_dir: &Path,
    (w, data): (u16, &statics::Series),
    temperatures: &tables::temperature::Temperatures,
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
        thermometer_sd_c: [1u8, 2, 3].map(|ch| {
            let given = ds.manifest.instrument.thermometer_sd_c;
            temperatures
                .get(&(w, ch))
                .and_then(|(_, v)| given.or_else(|| thermometer::white_noise_sd(v)))
        }),
        positions: Vec::new(),
    };
    let intervals = find_intervals(s, data, rate, ingest_dir, &mut mp)?;
    mp.found = intervals.len() as u64;
    let kept = interval_means(data, intervals, &mut mp);
    let spans: Vec<(usize, usize)> = kept.iter().map(|(span, _)| *span).collect();
    let noise = statics::noise(data, &spans, 1.0 / rate);
    mp.noise = static_noise(ds, &noise);
    for ((i, j), (mean, white, samples)) in kept {
        let (t0, t1) = (data.time_ns[i], data.time_ns[j - 1]);
        let duration_s = (j - i) as f64 / rate;
        // The samples' scatter over sqrt(n) is the mean's sd only for independent samples;
        // held ones (a positive lag-one correlation) widen it.
        let white: [f64; 3] = std::array::from_fn(|k| {
            let rho = noise[k].as_ref().and_then(|n| n.lag_one);
            white[k] * statics::held_variance_factor(rho).sqrt()
        });
        let sigma = std::array::from_fn(|k| {
            let coloured = noise[k]
                .as_ref()
                .map_or(0.0, |n| n.coloured_variance(duration_s));
            (white[k] * white[k] + coloured).sqrt()
        });
        let (temperature_c, temperature_sd_c) = position_temperatures(
            temperatures,
            w,
            (&data.time_ns[i..j], setup.max_gap_ns),
            mp.thermometer_sd_c,
        );
        mp.positions.push(StaticPosition {
            start_gps_ns: t0,
            end_gps_ns: t1,
            samples,
            mean,
            sigma,
            sigma_white: Some(white),
            gravity_mgal: setup.g + setup.tide(t0 / 2 + t1 / 2).unwrap_or(0.0),
            temperature_c,
            temperature_sd_c,
        });
    }
    mp.used = mp.positions.len() as u64;
    Ok(mp)
}

/// An interval's means, their white sds and its samples ([`statics::means`]).
type IntervalMeans = ([f64; 3], [f64; 3], u64);

/// Each interval's means (their span, and [`statics::means`]'s), the intervals rejected
/// counted in `mp` by why: a detected interval is clear of the motion by half a window
/// each side already, and needs the samples its sigma needs.
fn interval_means(
    data: &statics::Series,
    intervals: Vec<(usize, usize)>,
    mp: &mut MultiPosition,
) -> Vec<((usize, usize), IntervalMeans)> {
    let mut kept = Vec::new();
    for (i, j) in intervals {
        let short = mp.method == "detected" && j - i < statics::MIN_POSITION_SAMPLES;
        match (!short).then(|| statics::means(data, (i, j))).flatten() {
            Some(stats) => kept.push(((i, j), stats)),
            None => {
                let why = if short { "too_short" } else { "no_samples" };
                *mp.rejected.entry(why.to_owned()).or_default() += 1;
            }
        }
    }
    kept
}

/// A position's temperature per channel over the sample `times` of session `w`, and their
/// sds from the thermometer's noise `thermometer_sd_c`: none unless every channel has one.
fn position_temperatures(
    temperatures: &tables::temperature::Temperatures,
    w: u16,
    (times, max_gap_ns): (&[i64], i64),
    thermometer_sd_c: [Option<f64>; 3],
) -> (Option<[f64; 3]>, Option<[f64; 3]>) {
    let all = |v: [Option<f64>; 3]| match v {
        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
        _ => None,
    };
    let means = [1u8, 2, 3].map(|ch| {
        let (t, v) = temperatures.get(&(w, ch))?;
        thermometer::interval_mean(t, v, times, max_gap_ns)
    });
    let sd = std::array::from_fn(|k| Some(thermometer_sd_c[k]? * means[k]?.1.sqrt()));
    match all(means.map(|m| m.map(|m| m.0))) {
        Some(t) => (Some(t), all(sd)),
        None => (None, None),
    }
}

/// One point of an Allan curve for align.json.
pub(crate) fn allan_row(p: &allan::AllanPoint) -> AllanRow {
    AllanRow {
        tau_s: p.tau_s,
        adev: p.adev,
        lower: p.interval.0,
        upper: p.interval.1,
        edf: p.edf,
    }
}

/// A multi-position session's noise per axis for align.json, in the reading unit.
pub(crate) fn static_noise(
    ds: &Dataset,
    noise: &[Option<statics::AxisNoise>; 3],
) -> Vec<StaticNoise> {
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
                lag_one_correlation: n.lag_one,
            })
        })
        .collect()
}

/// A multi-position session's line: how its intervals were had, found, used, rejected by
/// reason, the detector's figures, and its warnings.
pub(crate) fn print_positions(mp: &MultiPosition, w: &mut impl std::io::Write) {
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
