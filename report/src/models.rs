//! What the richer models hold: the fits compared against temperature, the misalignment
//! vector and the triad.

use super::{
    CalibrationResult, Error, Plot, Section, Stages, Table, calibration, ingest_ledger, param,
    plots, section,
};
use arrow_array::Array;
use ingest::contract::align_ledger::MultiPosition;

/// Radius of the 95 % error ellipse of a 2-D normal, in sds: sqrt of chi-square(2)'s 95 %.
pub(crate) const ELLIPSE_95: f64 = 2.447_746_830_680_816;

/// For each vector misalignment: theta and psi with their sigmas, and a polar plot of
/// (theta_x, theta_y) with its 95 % error ellipse. Empty when no model has one.
pub(crate) fn misalignment_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("Misalignment vector");
    let mut t = Table::headed(
        "model | accelerometer | theta (mrad) | sigma theta (mrad) | psi (deg) | sigma psi (deg)",
    );
    for r in &st.cal.results {
        let Some(v) = &r.misalignment_vector else {
            continue;
        };
        t.rows.push(vec![
            r.model.clone(),
            r.accelerometer.clone(),
            format!("{:.4}", v.theta_rad * 1e3),
            format!("{:.4}", v.sigma_theta_rad * 1e3),
            v.psi_deg.map_or_else(
                || v.psi_not_determined.clone().unwrap_or_default(),
                |p| format!("{p:.2}"),
            ),
            v.sigma_psi_deg
                .map_or("-".to_owned(), |x| format!("{x:.2}")),
        ]);
        let at = |name: &str| r.parameters.iter().position(|p| p.name == name);
        let (Some(ix), Some(iy)) = (at("theta_x"), at("theta_y")) else {
            continue;
        };
        s.plots.push(misalignment_plot(r, (ix, iy), v.theta_rad)?);
    }
    if t.rows.is_empty() {
        s.text.push(
            "No model estimated the misalignment as a vector (misalignment = \"vector\", sessions at two rolls)."
                .to_owned(),
        );
    } else {
        s.text.push(
            "The sensitive axis's misalignment in the block's frame (x: the tilt axis at roll 0, y: at roll 90 deg): \
             theta = sqrt(theta_x^2 + theta_y^2) and its direction psi = atan2(theta_y, theta_x), with propagated sigmas; \
             psi is given only when theta is more than 3 sigma from 0. The plots show (theta_x, theta_y) with the 95 % \
             error ellipse of the two."
                .to_owned(),
        );
        s.tables.push(("Misalignment vector".to_owned(), t));
    }
    Ok(s)
}

/// Result `r`'s plot of (theta_x, theta_y) (parameters `ix`, `iy`) with its 95 % error
/// ellipse, magnified by a power of ten (and saying so) when too small to see beside
/// theta: the file name and the SVG.
fn misalignment_plot(
    r: &CalibrationResult,
    (ix, iy): (usize, usize),
    theta_rad: f64,
) -> Result<(String, String), Error> {
    let (px, py) = (&r.parameters[ix], &r.parameters[iy]);
    let rho = r.correlation[ix][iy];
    // An ellipse too small to see beside theta is magnified by a power of ten, and says so.
    let theta_mrad = theta_rad * 1e3;
    let extent = ELLIPSE_95 * (px.sigma.max(py.sigma)) * 1e3;
    let magnify = if extent > 0.0 && extent < 0.05 * theta_mrad {
        10f64.powf((0.1 * theta_mrad / extent).log10().round())
    } else {
        1.0
    };
    let (sx, sy) = (px.sigma * 1e3 * magnify, py.sigma * 1e3 * magnify);
    // The ellipse: x = sx c cos u, y = sy c (rho cos u + sqrt(1 - rho^2) sin u).
    let ellipse: Vec<(f64, f64)> = (0..=72)
        .map(|i| {
            let u = f64::from(i) * std::f64::consts::TAU / 72.0;
            (
                px.value * 1e3 + ELLIPSE_95 * sx * u.cos(),
                py.value * 1e3
                    + ELLIPSE_95
                        * sy
                        * (rho * u.cos() + (1.0 - rho * rho).max(0.0).sqrt() * u.sin()),
            )
        })
        .collect();
    let title = format!("{} {}: misalignment", r.model, r.accelerometer);
    let name = format!("misalignment-{}-{}", r.model, r.accelerometer);
    let label = if magnify > 1.0 {
        format!("95 % error ellipse, magnified {magnify:.0} x")
    } else {
        "95 % error ellipse".to_owned()
    };
    let svg = plots::polar(&plots::Polar {
        title: &title,
        point: (px.value * 1e3, py.value * 1e3),
        ellipse: &ellipse,
        ellipse_label: &label,
    })
    .map_err(|message| Error::Plot {
        name: name.clone(),
        message,
    })?;
    Ok((format!("{name}.svg"), svg))
}

/// The triad calibrations (docs/formats.md 8.4): parameters, departures from orthogonality, the
/// fit's statistics, |a| - g per position and the positions' directions in the body frame.
pub(crate) fn triad_section(st: &Stages<'_>) -> Result<Section, Error> {
    let mut s = section("Triad");
    s.text.push(
        "The three accelerometers calibrated together from the block's static positions: a = T K (X - B) in imu_tk's body \
         frame (T upper-triangular with unit diagonal: the non-orthogonality angles a_yz, a_zy, a_zx; K the scales; B the \
         biases), under |a| = g at every position, by a Gauss-Helmert adjustment with data snooping on the positions. \
         Sigmas are a-priori (the means' sigmas from each interval's scatter); sigma0 and the global test say whether \
         those fit."
            .to_owned(),
    );
    for mp in &st.align_report.multi_position {
        s.plots.extend(stillness_plot(st, mp)?);
    }
    for r in &st.cal.triad {
        let mut t = Table::headed("parameter | value | sigma | unit");
        for p in r.parameters.iter().chain(&r.non_orthogonality_mrad) {
            let (value, sigma) = ingest::contract::precision::rounded_to_sigma(p.value, p.sigma);
            t.rows
                .push(vec![p.name.clone(), value, sigma, p.unit.clone()]);
        }
        s.text.push(triad_summary(r));
        if let Some(advice) = r.advice() {
            s.text.push(advice);
        }
        s.text.extend(r.unit_warnings());
        s.tables
            .push((format!("Triad {} ({})", r.model, r.session), t));
        s.plots.extend(triad_plots(r)?);
    }
    Ok(s)
}

/// Time bins of a stillness plot.
const STILLNESS_BINS: usize = 800;

/// Bins (index, least, greatest) at twice the width: each pair of neighbours one.
fn merged_pairs(bins: &[(u64, f64, f64)]) -> Vec<(u64, f64, f64)> {
    let mut out: Vec<(u64, f64, f64)> = Vec::with_capacity(bins.len() / 2 + 1);
    for &(bin, lo, hi) in bins {
        match out.last_mut() {
            Some(e) if e.0 == bin / 2 => {
                e.1 = e.1.min(lo);
                e.2 = e.2.max(hi);
            }
            _ => out.push((bin / 2, lo, hi)),
        }
    }
    out
}

/// Multi-position session `mp`'s stream as its norm over time (least and greatest per
/// time bin, read from ingest's lab table) with the positions align used shaded; None for
/// a session without samples in the table.
fn stillness_plot(st: &Stages<'_>, mp: &MultiPosition) -> Result<Option<Plot>, Error> {
    let Some(w) = st
        .ds
        .sessions
        .iter()
        .position(|s| s.session.id == mp.session)
    else {
        return Ok(None);
    };
    let w = u16::try_from(w).unwrap_or(u16::MAX);
    // (bin, least, greatest) in time order, binned as the samples stream by: when the bins
    // pass twice STILLNESS_BINS, pairs merge and the width doubles (flat memory, whatever
    // the session's length).
    let mut bins: Vec<(u64, f64, f64)> = Vec::new();
    let (mut t0, mut width_ns) = (None::<i64>, 10_000_000i64);
    ingest::contract::tables::lab::batches(&st.out.join(ingest_ledger::STAGE_DIR), 1 << 16, |b| {
        for i in (0..b.session.len()).filter(|&i| b.session[i] == w) {
            let v = b.values.map(|c| c.is_valid(i).then(|| c.value(i)));
            let [Some(x), Some(y), Some(z)] = v else {
                continue;
            };
            let n = (x * x + y * y + z * z).sqrt();
            let start = *t0.get_or_insert(b.time_ns[i]);
            let bin = u64::try_from((b.time_ns[i] - start) / width_ns).unwrap_or(0);
            match bins.last_mut() {
                Some(e) if e.0 == bin => {
                    e.1 = e.1.min(n);
                    e.2 = e.2.max(n);
                }
                _ => bins.push((bin, n, n)),
            }
            if bins.len() > 2 * STILLNESS_BINS {
                bins = merged_pairs(&bins);
                width_ns *= 2;
            }
        }
        Ok::<(), ingest::Error>(())
    })?;
    let Some(t0) = t0 else {
        return Ok(None);
    };
    let seconds = |t: i64| (t - t0) as f64 * 1e-9;
    let width = width_ns as f64 * 1e-9;
    let envelope: Vec<(f64, f64, f64)> = bins
        .iter()
        .map(|&(bin, lo, hi)| ((bin as f64 + 0.5) * width, lo, hi))
        .collect();
    let used: Vec<(f64, f64)> = mp
        .positions
        .iter()
        .map(|p| (seconds(p.start_gps_ns), seconds(p.end_gps_ns)))
        .collect();
    let plot = format!("positions-{}-norm", mp.session);
    let title = format!(
        "{}: the norm of the readings, {} positions used of {} found",
        mp.session, mp.used, mp.found
    );
    let y_label = format!(
        "|reading| ({})",
        st.ds.manifest.instrument.reading_unit.name()
    );
    let svg = plots::stillness(&plots::Stillness {
        title: &title,
        y_label: &y_label,
        envelope: &envelope,
        used: &used,
    })
    .map_err(|message| Error::Plot {
        name: plot.clone(),
        message,
    })?;
    Ok(Some((format!("{plot}.svg"), svg)))
}

/// A triad fit in a sentence: positions used and removed, sigma0, the global test, the
/// model's order and temperature terms, and its imu_tk file.
fn triad_summary(r: &calibration::TriadResult) -> String {
    let removed = r.positions.iter().filter(|p| p.removed).count();
    format!(
        "Model {} ({}): {} positions used, {removed} removed{}; sigma0 {:.3} on {} dof, global test {} ([{:.1}, {:.1}] for {:.1}){}; \
         {}. The last three rows are 90 deg minus the angle between each pair of sensitive axes.",
        r.model,
        r.session,
        r.positions_used,
        match r.positions_without_temperature {
            0 => String::new(),
            n => format!(", {n} left out for want of a temperature"),
        },
        r.sigma0,
        r.dof,
        r.global_test.verdict(),
        r.global_test.lower,
        r.global_test.upper,
        r.global_test.statistic,
        r.floor_clause(),
        match (r.order, r.t_ref_c) {
            (1, None) => String::new(),
            (o, t) => format!(
                "order {o}{}; ",
                t.map_or(String::new(), |t| format!(
                    ", temperature terms about t_ref = {t:.2} degC, the temperatures {}",
                    r.temperature_sd_c.map_or_else(
                        || "taken as exact".to_owned(),
                        |sd| format!(
                            "observed with sds about {:.2}, {:.2}, {:.2} mK",
                            1e3 * sd[0],
                            1e3 * sd[1],
                            1e3 * sd[2]
                        )
                    )
                ))
            ),
        } + &r.calib_file.as_ref().map_or_else(
            || "no imu_tk file: its layout has no place for higher orders or temperature terms"
                .to_owned(),
            |f| format!("imu_tk file adjust/{f}")
        )
    )
}

/// A triad fit's plots: |a| - g per position, and the gravity directions in the body frame.
fn triad_plots(r: &calibration::TriadResult) -> Result<Vec<Plot>, Error> {
    let mut out = Vec::new();
    let points = |removed: bool, f: &dyn Fn(usize, &calibration::TriadPosition) -> (f64, f64)| {
        r.positions
            .iter()
            .enumerate()
            .filter(|(_, p)| p.removed == removed)
            .map(|(i, p)| f(i, p))
            .collect::<Vec<_>>()
    };
    let residual = |i: usize, p: &calibration::TriadPosition| (i as f64, p.residual_mgal);
    let sky = |_: usize, p: &calibration::TriadPosition| {
        let [x, y, z] = p.direction;
        (
            y.atan2(x).to_degrees(),
            z.clamp(-1.0, 1.0).asin().to_degrees(),
        )
    };
    for (name, title, x_label, y_label, f, zero) in [
        (
            "residuals",
            "|a| - g per position",
            "position",
            "|a| - g (mGal)",
            &residual as &dyn Fn(usize, &calibration::TriadPosition) -> (f64, f64),
            true,
        ),
        (
            "sky",
            "gravity directions in the body frame",
            "azimuth atan2(y, x) (deg)",
            "elevation asin(z) (deg)",
            &sky,
            false,
        ),
    ] {
        let plot = format!("triad-{}-{}-{name}", r.model, r.session);
        let title = format!("{} ({}): {title}", r.model, r.session);
        let svg = plots::scatter(&plots::Scatter {
            title: &title,
            x_label,
            y_label,
            used: &points(false, f),
            removed: &points(true, f),
            line: &[],
            zero_line: zero,
            labels: ("positions", ""),
            y_range: None,
        })
        .map_err(|message| Error::Plot {
            name: plot.clone(),
            message,
        })?;
        out.push((format!("{plot}.svg"), svg));
    }
    Ok(out)
}

/// The fits compared: per accelerometer with per-session linear fits and a temperature
/// model over all sessions, b and k of each session against its mean temperature, with the
/// temperature model's b(T) and k(T) and their 1-sigma bands (from its covariance).
pub(crate) fn comparison_section(st: &Stages<'_>) -> Result<Option<Section>, Error> {
    let mut s = section("The fits compared: b and k against temperature");
    let results = &st.cal.results;
    for thermal in results
        .iter()
        .filter(|r| r.over_all_sessions() && r.temperature && r.order == 1 && !r.misalignment)
    {
        let sessions: Vec<&CalibrationResult> = results
            .iter()
            .filter(|r| {
                r.accelerometer == thermal.accelerometer
                    && !r.over_all_sessions()
                    && r.order == 1
                    && !r.temperature
                    && !r.misalignment
            })
            .collect();
        let Some(t_ref) = thermal.t_ref_c else {
            continue;
        };
        if sessions.is_empty() {
            continue;
        }
        for (name, slope, unit) in [("b", "b_t", "mGal"), ("k", "k_t", "mGal/bit")] {
            if let Some(plot) = trend_plot(thermal, &sessions, (name, slope, unit), t_ref)? {
                s.plots.push(plot);
            }
        }
    }
    if s.plots.is_empty() {
        return Ok(None);
    }
    s.text.push(
        "Each session's linear fit holds b and k at its mean temperature; drawn is its \
         difference from the temperature model's b + b_t (T - t_ref) (and k + k_t (T - t_ref)) \
         at that temperature, against the model's 1-sigma band (from its parameters' \
         covariance) about 0. Points off the band by more than their bars say the \
         temperature model does not carry what changed between the sessions."
            .to_owned(),
    );
    Ok(Some(s))
}

/// The plot of the per-session fits' `name` (b or k) against temperature, less the thermal
/// model's `name` + `slope` (T - t_ref), with the model's band about 0: the file name and the
/// SVG; None when the model lacks the parameters.
fn trend_plot(
    thermal: &CalibrationResult,
    sessions: &[&CalibrationResult],
    (name, slope, unit): (&str, &str, &str),
    t_ref: f64,
) -> Result<Option<(String, String)>, Error> {
    let at: Vec<(f64, f64, f64)> = sessions
        .iter()
        .filter_map(|r| {
            let p = param(r, name)?;
            Some((r.mean_temperature_c?, p.value, p.sigma))
        })
        .collect();
    let line = temperature_line(thermal, name, slope, t_ref, &at);
    let Some(model_at) = temperature_model(thermal, name, slope, t_ref) else {
        return Ok(None);
    };
    // Differences from the model's line, which the plot draws at 0 with its band:
    // b changes by tens of mGal between sessions, their sigmas are below one.
    let points: Vec<(f64, f64, f64)> = at
        .iter()
        .map(|&(t, v, e)| (t, v - model_at(t), e))
        .collect();
    let line: Vec<(f64, f64, f64)> = line.iter().map(|&(t, _, e)| (t, 0.0, e)).collect();
    let title = format!(
        "{} {name}: per-session {} fits minus the {} model's {name}(T)",
        thermal.accelerometer, sessions[0].model, thermal.model
    );
    let y_label = format!("{name} - {name}(T) ({unit})");
    let labels = (
        format!("{} per session", sessions[0].model),
        format!("{} model {name}(T) (0)", thermal.model),
    );
    let svg = plots::trend(&plots::Trend {
        title: &title,
        y_label: &y_label,
        points: &points,
        line: &line,
        labels: (&labels.0, &labels.1),
    })
    .map_err(|message| Error::Plot {
        name: title.clone(),
        message,
    })?;
    Ok(Some((
        format!(
            "trend-{}-{}-{name}.svg",
            thermal.model, thermal.accelerometer
        ),
        svg,
    )))
}

/// The model's `name` + `slope` (T - t_ref) as a function of T.
pub(crate) fn temperature_model(
    r: &CalibrationResult,
    name: &str,
    slope: &str,
    t_ref: f64,
) -> Option<impl Fn(f64) -> f64> {
    let (a, b) = (param(r, name)?.value, param(r, slope)?.value);
    Some(move |t: f64| a + b * (t - t_ref))
}

/// (T, value, sigma) of `name` + `slope` (T - t_ref) over the points' temperatures (and a
/// degree beyond), from the fit's parameters and correlations.
pub(crate) fn temperature_line(
    r: &CalibrationResult,
    name: &str,
    slope: &str,
    t_ref: f64,
    points: &[(f64, f64, f64)],
) -> Vec<(f64, f64, f64)> {
    let index = |n: &str| r.parameters.iter().position(|p| p.name == n);
    let (Some(i), Some(j)) = (index(name), index(slope)) else {
        return Vec::new();
    };
    let (a, b) = (&r.parameters[i], &r.parameters[j]);
    let rho = r
        .correlation
        .get(i)
        .and_then(|row| row.get(j))
        .copied()
        .unwrap_or(0.0);
    let (lo, hi) = points
        .iter()
        .fold((t_ref, t_ref), |(l, h), p| (l.min(p.0), h.max(p.0)));
    (0..=40)
        .map(|k| {
            let t = lo - 1.0 + (hi - lo + 2.0) * f64::from(k) / 40.0;
            let d = t - t_ref;
            let var = a.sigma.powi(2) + (d * b.sigma).powi(2) + 2.0 * d * rho * a.sigma * b.sigma;
            (t, a.value + b.value * d, var.max(0.0).sqrt())
        })
        .collect()
}
