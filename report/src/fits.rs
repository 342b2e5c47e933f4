//! The axis fits: Table 1 as the paper prints it, the variance components with their
//! advice, every fit's parameters with correlations on demand, the extra terms' significance
//! and data snooping.

use super::{Section, Stages, Table, gps, param, section, t_critical};
use ingest::contract::precision::{rounded_to_sigma, two_digits};

/// Results in the form of the paper's Table 1.
pub(crate) fn table1_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    // Table 1.
    let mut s = section("Results in the form of the paper's Table 1");
    s.text.push(
        "Per session and accelerometer, order 1 without temperature terms. Sigmas from the estimated variance components \
         (next section) and a priori (every component 1). sigma0 is sqrt(v^T P v / r) at the a-priori weights; the global \
         test is of the station means' scatter about the fitted function (the between-station part of v^T P v) against its \
         scaled chi-square, since the weights were estimated from the readings within the stations."
            .to_owned(),
    );
    let mut t1 = Table::headed(
        "session | accelerometer | values | T (degC) | b (mGal) | k (mGal/kbit) | sigma b (mGal) | sigma k (mGal/kbit) | a priori sigma b (mGal) | a priori sigma k (mGal/kbit) | corr(b,k) | sigma0 | removed | global test",
    );
    for r in cal
        .results
        .iter()
        .filter(|r| !r.over_all_sessions() && r.order == 1 && !r.temperature && !r.misalignment)
    {
        let (Some(b), Some(k)) = (param(r, "b"), param(r, "k")) else {
            continue;
        };
        // One unit per quantity: k, its sigma and its a-priori sigma in mGal/kbit.
        let (b_value, b_sigma) = rounded_to_sigma(b.value, b.sigma);
        let (k_value, k_sigma) = rounded_to_sigma(k.value * 1e3, k.sigma * 1e3);
        t1.rows.push(vec![
            r.session.clone(),
            format!("{} ({})", r.accelerometer, r.model),
            r.n_observations.to_string(),
            r.mean_temperature_c
                .map_or("no thermometer".to_owned(), |t| format!("{t:.2}")),
            b_value,
            k_value,
            b_sigma,
            k_sigma,
            two_digits(b.sigma_apriori),
            two_digits(k.sigma_apriori * 1e3),
            format!("{:.2}", r.correlation[0][1]),
            format!("{:.3}", r.sigma0),
            r.n_excluded.to_string(),
            format!(
                "{} ({:.1} in [{:.1}, {:.1}])",
                r.global_test.verdict_in_a_table(),
                r.global_test.statistic,
                r.global_test.lower,
                r.global_test.upper
            ),
        ]);
    }
    s.text.extend(correlation_sentence(&t1));
    s.tables.push(("Table 1".to_owned(), t1));
    s
}

/// What Table 1's corr(b, k) column says, from its values: strongly (anti-)correlated only
/// when every row is beyond 0.9, else their range.
fn correlation_sentence(t1: &Table) -> Option<String> {
    let column = t1.header.iter().position(|h| h == "corr(b,k)")?;
    let corr: Vec<f64> = t1
        .rows
        .iter()
        .filter_map(|r| r[column].parse().ok())
        .collect();
    let lo = corr.iter().copied().reduce(f64::min)?;
    let hi = corr.iter().copied().reduce(f64::max)?;
    let range = if corr.len() == 1 {
        format!("{lo:.2}")
    } else {
        format!("{lo:.2} to {hi:.2}")
    };
    Some(if hi < -0.9 || lo > 0.9 {
        format!(
            "b and k are strongly {}correlated (corr(b, k) {range}) because the counts are far from zero: use them together, with their correlation.",
            if hi < 0.0 { "anti-" } else { "" }
        )
    } else {
        format!("corr(b, k) is {range}: use b and k with their correlation where it is far from 0.")
    })
}

/// Variance components per fit: which observation group was mis-weighted, and by how much.
pub(crate) fn components_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    let mut s = section("Variance components");
    s.text.push(
        "The factor the data put on each observation group's a-priori variances, with its sd, its degrees of freedom and a \
         two-sided 5 % test of whether it is 1. The theodolite's comes from the scatter of the station means about the \
         fitted function (the scatter within a station set its sigma_Dz), the ADC's from the scatter of a station's window \
         means about their mean against the sd each window's samples gave. A group whose test fails was mis-weighted by \
         the factor shown; the parameters' sigmas above use the estimated factors. One the data give fewer than 3 dof \
         is not estimated."
            .to_owned(),
    );
    let mut t = Table::headed(
        "model | accelerometer | session | group | factor | sigma | dof | test: statistic in [2.5 %, 97.5 %] | verdict",
    );
    for r in &cal.results {
        for c in &r.variance_components {
            let verdict = match (&c.not_estimable, c.passed) {
                (Some(why), _) => format!("not estimable: {why}"),
                (None, true) => "consistent with 1".to_owned(),
                (None, false) => format!("mis-weighted: variances x {:.2}", c.estimate),
            };
            t.rows.push(vec![
                r.model.clone(),
                r.accelerometer.clone(),
                r.session.clone(),
                c.group.clone(),
                format!("{:.3}", c.estimate),
                c.sigma.map_or("-".to_owned(), |x| format!("{x:.3}")),
                format!("{:.1}", c.dof),
                format!("{:.1} in [{:.1}, {:.1}]", c.statistic, c.lower, c.upper),
                verdict,
            ]);
        }
    }
    s.tables.push(("Variance components".to_owned(), t));
    s.text.extend(cal.component_advice());
    s
}

/// Every axis fit's parameters in a table of its own (what the model holds, the values,
/// sigmas at the estimated components and a priori), its correlations on demand, and its
/// notes.
pub(crate) fn parameters_section(st: &Stages<'_>) -> Section {
    let mut s = section("Parameters of every fit");
    s.text.push(
        "sigma is at the estimated variance components (the one to quote): the sd of the \
         parameter's t on the dof beside it, so that +/- 2 sigma is a 95 % interval at any \
         dof (a dash: no estimated component weighs it). sigma a priori is at the weights \
         align gave; the correlations open under each table."
            .to_owned(),
    );
    for r in &st.cal.results {
        let mut t = Table::headed("parameter | value | sigma | dof | sigma a priori | unit");
        for p in &r.parameters {
            let (value, sigma) = rounded_to_sigma(p.value, p.sigma);
            t.rows.push(vec![
                p.name.clone(),
                value,
                sigma,
                p.dof.map_or_else(|| "-".to_owned(), |d| format!("{d:.1}")),
                two_digits(p.sigma_apriori),
                p.unit.clone(),
            ]);
        }
        let what = format!(
            "{} {} {}: order {}{}{}{}",
            r.model,
            r.accelerometer,
            r.session,
            r.order,
            if r.temperature {
                ", temperature terms"
            } else {
                ""
            },
            if r.misalignment_vector.is_some() {
                ", misalignment vector"
            } else if r.misalignment {
                ", misalignment (beta)"
            } else {
                ""
            },
            r.t_ref_c
                .map_or(String::new(), |t| format!(", at t_ref {t:.2} degC")),
        );
        let names: Vec<&str> = r.parameters.iter().map(|p| p.name.as_str()).collect();
        let mut header = vec![""];
        header.extend(&names);
        let mut c = Table::new(&header);
        for (name, row) in names.iter().zip(&r.correlation) {
            let mut cells = vec![(*name).to_owned()];
            cells.extend(row.iter().map(|x| format!("{x:+.4}")));
            c.rows.push(cells);
        }
        s.details
            .push((s.tables.len(), format!("{what}: correlations"), c));
        s.tables.push((what, t));
    }
    // Every fit's notes (estimability, what the model does not carry), whatever else the
    // run fitted: this section is in every report with an axis fit.
    for r in st.cal.results.iter() {
        for w in &r.warnings {
            s.text.push(format!(
                "{} {} {}: {w}",
                r.model, r.accelerometer, r.session
            ));
        }
    }
    s
}

/// Temperature, higher orders and misalignment: the significance of the extra terms.
pub(crate) fn extra_terms_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    // Temperature, higher orders, misalignment: significance of the extra terms.
    let mut s = section("Temperature, higher orders and misalignment");
    s.text.push(
        "Each term beyond b and k with its t = value/sigma against Student's t at 5 % (two-sided): a term is significant when |t| exceeds the critical value."
            .to_owned(),
    );
    let mut extra = Table::headed(
        "model | accelerometer | session | t_ref (degC) | parameter | value | sigma | unit | t | critical | significant",
    );
    for r in &cal.results {
        for p in r
            .parameters
            .iter()
            .filter(|p| p.name != "b" && p.name != "k")
        {
            let t = if p.sigma > 0.0 {
                p.value / p.sigma
            } else {
                0.0
            };
            let crit = t_critical(r.dof);
            extra.rows.push(vec![
                r.model.clone(),
                r.accelerometer.clone(),
                r.session.clone(),
                r.t_ref_c
                    .map(|t| format!("{t:.2}"))
                    .unwrap_or_else(|| "-".into()),
                p.name.clone(),
                rounded_to_sigma(p.value, p.sigma).0,
                rounded_to_sigma(p.value, p.sigma).1,
                p.unit.clone(),
                format!("{t:.2}"),
                format!("{crit:.3}"),
                if t.abs() > crit { "yes" } else { "no" }.to_owned(),
            ]);
        }
    }
    if extra.rows.is_empty() {
        s.text
            .push("No model with terms beyond b and k was fitted.".to_owned());
    } else {
        s.tables.push(("Extra terms".to_owned(), extra));
    }
    s
}

/// GPS time `gps_ns` of a reading of `session` as its theodolite log writes its times (its
/// form and scale: docs/formats.md 9.1).
fn written(st: &Stages<'_>, session: &str, gps_ns: i64) -> String {
    match st.ds.sessions.iter().find(|s| s.session.id == session) {
        Some(s) => ingest::base::time::as_written(
            gps_ns,
            s.times.theodolite,
            s.times.scale,
            s.times.start_gps_ns,
        ),
        None => ingest::base::time::utc_iso(gps_ns),
    }
}

/// The global test, data snooping and the fits skipped.
pub(crate) fn snooping_section(st: &Stages<'_>) -> Section {
    let Stages { cal, .. } = st;
    // Blunders and skipped fits.
    let mut s = section("Global test and data snooping");
    s.text.push(format!(
        "Data snooping removed, one at a time, the observation with the largest normalised residual |w| > {} (alpha = 0.001) and re-adjusted. Every removal:",
        adjust::calibration::calibrate::W_CRITICAL
    ));
    let mut removed = Table::headed(
        "model | accelerometer | fit | session | station | line | time, as its log writes it | GPS week / tow (s) | w",
    );
    for r in &cal.results {
        for x in &r.removed {
            removed.rows.push(vec![
                r.model.clone(),
                r.accelerometer.clone(),
                r.session.clone(),
                x.session.clone(),
                x.station.clone(),
                x.line.to_string(),
                written(st, &x.session, x.time_gps_ns),
                gps(x.time_gps_ns),
                format!("{:.2}", x.w),
            ]);
        }
    }
    s.tables.push(("Removed observations".to_owned(), removed));
    s
}

/// Whether b and k repeat between the sessions of each model fitted per session
/// (docs/model.md 6.9): the homogeneity test's table and its sentences.
pub(crate) fn repeatability_section(st: &Stages<'_>) -> Section {
    let mut s = section("Repeatability between sessions");
    s.text.push(format!(
        "For each model fitted one session at a time, the sessions' (b, k) are tested for one common value at their sigmas and correlation: chi-square on 2 (sessions - 1) dof, a change reported below p = {}. The test's false-alarm rate on two sessions of one truth is measured by `cargo xtask verdicts` (docs/model.md 6.9).",
        adjust::calibration::repeatability::LEVEL,
    ));
    let mut t = Table::headed("model | accelerometer | sessions | chi-square | dof | p | b and k");
    for r in &st.cal.repeatability {
        t.rows.push(vec![
            r.model.clone(),
            r.accelerometer.clone(),
            r.sessions.join(", "),
            format!("{:.2}", r.statistic),
            r.dof.to_string(),
            r.p_text(),
            if r.passed { "repeat" } else { "CHANGED" }.to_owned(),
        ]);
        s.text.push(r.sentence());
    }
    s.tables.push(("Repeatability".to_owned(), t));
    s
}
