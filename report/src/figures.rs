//! The plots: residual small multiples, calibration curves, the sigma of one reading, the
//! tide and the Allan deviation.

use super::{
    CalibrationResult, Error, Section, Stages, Table, align_ledger, param, plots, section,
};

/// Points of a plot.
pub(crate) type Points = Vec<(f64, f64)>;

/// A residual plot's x axis: file key, label, and the value of an observation.
pub(crate) type Axis<'a> = (
    &'a str,
    &'a str,
    Box<dyn Fn(&ingest::contract::tables::residuals::Residual) -> f64 + 'a>,
);

/// Residual plots, calibration curves, the sigma of one reading and the tide.
pub(crate) fn plots_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("Residuals, observation sigmas and calibration curves");
    s.text.push("Condition residuals B·v in mGal of every per-session fit; crosses mark observations removed by data snooping, drawn at their misclosure under the final parameters.".to_owned());
    // One residual axis per model, so that its fits' small multiples compare at a glance.
    let y_range = |model: &str| {
        let used = st
            .residuals
            .iter()
            .filter(|x| x.model == model && !x.removed)
            .filter_map(|x| x.residual_mgal);
        let (lo, hi) = plots::range(used);
        Some((lo.min(0.0), hi.max(0.0)))
    };
    for r in st.cal.results.iter().filter(|r| !r.over_all_sessions()) {
        s.plots.extend(fit_plots(st, r, y_range(&r.model))?);
    }
    for session in st.ds.sessions.iter().filter(|x| x.is_tilt_table()) {
        s.plots.extend(sigma_plot(st, &session.session.id)?);
        s.plots.extend(tide_plot(st, &session.session.id)?);
    }
    Ok(s)
}

/// A plot: its file name and SVG.
pub(crate) type Plot = (String, String);

/// One per-session fit's residuals against Dz, time and temperature, and its calibration
/// curve.
pub(crate) fn fit_plots(
    st: &Stages<'_>,
    r: &CalibrationResult,
    y_range: Option<(f64, f64)>,
) -> Result<Vec<Plot>, Error> {
    let g = st.cal.gravity_mgal;
    let residuals = &st.residuals;
    let mut plots = Vec::new();
    let mine: Vec<&ingest::contract::tables::residuals::Residual> = residuals
        .iter()
        .filter(|x| {
            x.model == r.model && x.accelerometer == r.accelerometer && x.fit_session == r.session
        })
        .collect();
    if mine.is_empty() {
        return Ok(Vec::new());
    }
    let misclosure = |x: &ingest::contract::tables::residuals::Residual| -> f64 {
        x.residual_mgal
            .unwrap_or_else(|| -predict_misclosure(r, g, x))
    };
    let t0 = mine.iter().map(|x| x.time_gps_ns).min().unwrap_or(0);
    let split =
        |f: &dyn Fn(&ingest::contract::tables::residuals::Residual) -> f64| -> (Points, Points) {
            let used = mine
                .iter()
                .filter(|x| !x.removed)
                .map(|x| (f(x), misclosure(x)))
                .collect();
            let removed = mine
                .iter()
                .filter(|x| x.removed)
                .map(|x| (f(x), misclosure(x)))
                .collect();
            (used, removed)
        };
    let name = format!("{}-{}-{}", r.model, r.accelerometer, r.session);
    let axes: [Axis<'_>; 3] = [
        ("dz", "Dz (deg)", Box::new(|x| x.dz_rad.to_degrees())),
        (
            "time",
            "time since first reading (min)",
            Box::new(move |x| (x.time_gps_ns - t0) as f64 / 60e9),
        ),
        (
            "temperature",
            "temperature (degC)",
            Box::new(|x| x.temperature_c),
        ),
    ];
    for (key, xl, f) in axes {
        let (used, removed) = split(&*f);
        let title = format!(
            "{} {} ({}): residual vs {key}",
            r.accelerometer, r.session, r.model
        );
        let svg = plots::scatter(&plots::Scatter {
            title: &title,
            x_label: xl,
            y_label: "residual (mGal)",
            used: &used,
            removed: &removed,
            line: &[],
            zero_line: true,
            labels: plots::ADJUSTMENT_LABELS,
            y_range,
        })
        .map_err(|message| Error::Plot {
            name: name.clone(),
            message,
        })?;
        plots.push((format!("{name}-residual-{key}.svg"), svg));
    }
    if let Some(curve) = calibration_curve(r, g, &mine, &name)? {
        plots.push(curve);
    }
    Ok(plots)
}

/// The calibration curve: F = -g cos(Dz) against Ng, with the fitted function.
pub(crate) fn calibration_curve(
    r: &CalibrationResult,
    g: f64,
    mine: &[&ingest::contract::tables::residuals::Residual],
    name: &str,
) -> Result<Option<Plot>, Error> {
    let (Some(b), Some(k)) = (param(r, "b"), param(r, "k")) else {
        return Ok(None);
    };
    let pts: Vec<(f64, f64)> = mine
        .iter()
        .filter(|x| !x.removed)
        .map(|x| (x.ng / 1e6, -g * x.dz_rad.cos()))
        .collect();
    let rem: Vec<(f64, f64)> = mine
        .iter()
        .filter(|x| x.removed)
        .map(|x| (x.ng / 1e6, -g * x.dz_rad.cos()))
        .collect();
    let (lo, hi) = pts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), p| {
            (a.min(p.0), c.max(p.0))
        });
    let line: Vec<(f64, f64)> = (0..=20)
        .map(|i| lo + (hi - lo) * f64::from(i) / 20.0)
        .map(|u| (u, b.value + k.value * u * 1e6))
        .collect();
    let title = format!(
        "{} {} ({}): calibration a = b + k Ng",
        r.accelerometer, r.session, r.model
    );
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "Ng (million counts)",
        y_label: "acceleration (mGal)",
        used: &pts,
        removed: &rem,
        line: &line,
        zero_line: false,
        labels: plots::ADJUSTMENT_LABELS,
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: name.to_owned(),
        message,
    })?;
    Ok(Some((format!("{name}-calibration.svg"), svg)))
}

/// One accelerometer's Allan deviation (log-log) with the curve of its fitted terms.
fn allan_plot(n: &align_ledger::AdcNoise) -> Result<Plot, Error> {
    let pts: Vec<(f64, f64)> = n
        .allan
        .iter()
        .map(|r| (r.tau_s.log10(), r.adev.log10()))
        .collect();
    let terms = align::allan::NoiseTerms {
        white_density: n.white_density_counts_per_sqrt_hz,
        bias_instability: n.bias_instability_counts,
        random_walk: n.random_walk_counts_sqrt_hz,
    };
    let line: Vec<(f64, f64)> = n
        .allan
        .iter()
        .map(|r| {
            (
                r.tau_s.log10(),
                terms.fitted_allan_variance(r.tau_s).sqrt().log10(),
            )
        })
        .collect();
    let title = format!("{}: Allan deviation of the counts (log10)", n.accelerometer);
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "log10 tau (s)",
        y_label: "log10 Allan deviation (counts)",
        used: &pts,
        removed: &[],
        line: &line,
        zero_line: false,
        labels: ("Allan deviation", "fitted N, B, K"),
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: format!("allan-{}", n.accelerometer),
        message,
    })?;
    Ok((format!("allan-{}.svg", n.accelerometer), svg))
}

/// The ADC noise: the Allan deviation of each accelerometer's counts over the still
/// intervals, log-log, with the fitted terms; and those terms in SI units (Kalibr's names).
pub(crate) fn noise_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("ADC noise: Allan deviation");
    s.text.push(
        "Overlapping Allan deviation of each accelerometer's counts, pooled over the still intervals (the platform at rest at a \
         station), with the white-noise density N, bias instability B and random walk K fitted to sigma^2(tau) = N^2/tau + \
         (2 ln 2/pi) B^2 + K^2 tau/3. For white noise the curve falls as tau^-1/2; it flattens with flicker and rises with a \
         random walk; the flicker is gravcal's model of it, flat from about 2 s and bending down below. In SI units by the \
         accelerometer's scale factor k, under Kalibr's imu.yaml names. A B below 2 standard errors of its fit, or a K below 3 \
         (a random walk is carried over the whole session, so it must show beside the flicker), is not determined by these \
         curves and shows as such; a B found is given with the degrees of freedom of B^2, which the ADC component's test \
         carries. When B or K is found, the sd of each \
         window mean includes their Allan variance at the window's length, and the adjustment propagates the noise's \
         correlation between stations and over the session into the parameters' sigmas (flicker modelled up to 5000 s)."
            .to_owned(),
    );
    let with_dof = |x: f64, dof: Option<f64>| match (x > 0.0, dof) {
        (true, Some(d)) => format!("{x:.4} (its square on {d:.0} dof)"),
        (true, None) => format!("{x:.4}"),
        (false, _) => "not determined".to_owned(),
    };
    let mut t = Table::headed(
        "accelerometer | still intervals | samples | N (counts/sqrt(Hz)) | B (counts) | K (counts sqrt(Hz)) | accelerometer_noise_density (m/s^2/sqrt(Hz)) | accelerometer_random_walk (m/s^3/sqrt(Hz)) | scale from",
    );
    for n in &st.align_report.noise {
        let si = st
            .cal
            .adc_noise
            .iter()
            .find(|k| k.accelerometer == n.accelerometer);
        t.rows.push(vec![
            n.accelerometer.clone(),
            n.still_intervals.to_string(),
            n.samples.to_string(),
            format!("{:.4}", n.white_density_counts_per_sqrt_hz),
            with_dof(n.bias_instability_counts, n.bias_instability_dof),
            with_dof(n.random_walk_counts_sqrt_hz, n.random_walk_dof),
            si.map_or("-".into(), |k| {
                format!("{:.3e}", k.accelerometer_noise_density)
            }),
            si.map_or("-".into(), |k| {
                k.accelerometer_random_walk
                    .map_or("not determined".into(), |x| format!("{x:.3e}"))
            }),
            si.map_or("-".into(), |k| k.scale_from.clone()),
        ]);
        s.plots.push(allan_plot(n)?);
    }
    s.tables.push(("Noise terms".to_owned(), t));
    Ok(s)
}

/// The body tide applied at each reading of session `id` against time, when one was.
pub(crate) fn tide_plot(st: &Stages<'_>, id: &str) -> Result<Option<Plot>, Error> {
    let Some(first) = st.ds.manifest.instrument.accelerometer.first() else {
        return Ok(None);
    };
    let mine: Vec<&ingest::contract::tables::observations::Observation> = st
        .observations
        .iter()
        .filter(|o| o.session == id && o.accelerometer == first.id)
        .collect();
    let Some(t0) = mine.iter().map(|o| o.time_gps_ns).min() else {
        return Ok(None);
    };
    let pts: Vec<(f64, f64)> = mine
        .iter()
        .filter_map(|o| {
            o.tide_mgal
                .map(|t| ((o.time_gps_ns - t0) as f64 / 3.6e12, t * 1e3))
        })
        .collect();
    if pts.is_empty() {
        return Ok(None);
    }
    let title = format!("{id}: body tide added to g at each reading");
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "time since first reading (h)",
        y_label: "tide (microGal)",
        used: &pts,
        removed: &[],
        line: &[],
        zero_line: true,
        labels: ("readings", ""),
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: format!("tide-{id}"),
        message,
    })?;
    Ok(Some((format!("tide-{id}.svg"), svg)))
}

/// The sigma of one reading against Dz, for session `id`.
pub(crate) fn sigma_plot(st: &Stages<'_>, id: &str) -> Result<Option<Plot>, Error> {
    let (cal, residuals) = (&st.cal, &st.residuals);
    let g = cal.gravity_mgal;
    let Some(first) = cal.results.iter().find(|r| r.session == id) else {
        return Ok(None);
    };
    let pts: Vec<(f64, f64)> = residuals
        .iter()
        .filter(|x| {
            x.model == first.model && x.accelerometer == first.accelerometer && x.fit_session == id
        })
        .map(|x| {
            (
                x.dz_rad.to_degrees(),
                g * x.dz_rad.sin().abs() * x.sigma_dz_rad,
            )
        })
        .collect();
    let title = format!("{id}: sigma of one reading, g |sin Dz| sigma_Dz");
    let svg = plots::scatter(&plots::Scatter {
        title: &title,
        x_label: "Dz (deg)",
        y_label: "sigma (mGal)",
        used: &pts,
        removed: &[],
        line: &[],
        zero_line: false,
        labels: ("observations", ""),
        y_range: None,
    })
    .map_err(|message| Error::Plot {
        name: id.to_owned(),
        message,
    })?;
    Ok(Some((format!("sigma-{id}.svg"), svg)))
}

/// The condition value g cos(Dz + beta) + c(Ng, T) of an observation under the fit's final
/// parameters (the misclosure before residuals), for observations removed by snooping.
pub(crate) fn predict_misclosure(
    r: &CalibrationResult,
    g: f64,
    x: &ingest::contract::tables::residuals::Residual,
) -> f64 {
    let v = |name: &str| param(r, name).map_or(0.0, |p| p.value);
    let tau = r.t_ref_c.map_or(0.0, |t| x.temperature_c - t);
    let ng = x.ng;
    let c = v("b")
        + v("b_t") * tau
        + (v("k") + v("k_t") * tau) * ng
        + v("k2") * ng * ng
        + v("k3") * ng * ng * ng;
    g * (x.dz_rad + v("beta")).cos() + c
}
