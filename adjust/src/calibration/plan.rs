//! Pre-analysis (docs/model.md 6.6): what an experiment will determine before it is run. The
//! a-priori covariance (A^T Q_ww^-1 A)^-1 depends on the design alone, so the planner builds
//! the plan's noise-free observations and runs the very adjustment a calibration runs
//! ([`crate::calibration::calibrate::calibrate_with`], same conditions, same design check, no snooping,
//! no variance components): the predicted sigmas are the a-priori sigmas of that
//! adjustment. Also each parameter's correlations, the minimal detectable bias of a
//! theodolite reading and of a window mean (alpha 0.001, power 0.80: as the pipeline's
//! w-test on the station's other readings finds it, and Baarda's), and for a
//! parameter the plan cannot determine, what would fix it. The plan's format is in
//! docs/planning.md. No I/O.

use crate::calibration::calibrate::{self, CalError, FitOptions, Obs, Snooping};
use crate::calibration::model::{Misalignment, Terms};
use ingest::contract::calibration::ALL_SESSIONS;
use serde::{Deserialize, Serialize};

/// Baarda's non-centrality for alpha 0.001 (two-sided) and power 0.80: 3.29 + 0.84.
pub const DELTA_0: f64 = 4.13;

/// A planned experiment.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// What it is.
    #[serde(default)]
    pub description: String,
    /// The benchmark.
    pub site: PlanSite,
    /// The instrument's nominal calibration (to turn accelerations into counts).
    pub instrument: PlanInstrument,
    /// Noise levels.
    pub noise: PlanNoise,
    /// Sessions.
    pub session: Vec<PlanSession>,
    /// Models to fit.
    pub model: Vec<PlanModel>,
}

/// Gravity at the proof masses.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanSite {
    /// Gravity at the proof masses, mGal.
    pub g_mgal: f64,
}

/// The nominal calibration and sampling.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanInstrument {
    /// Nominal bias, mGal.
    pub b_mgal: f64,
    /// Nominal scale factor, mGal/count.
    pub k_mgal_per_bit: f64,
    /// ADC sampling rate, Hz.
    pub sample_rate_hz: f64,
}

/// Noise of one reading.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanNoise {
    /// Sd of one theodolite reading of Dz, arcsec.
    pub theodolite_arcsec: f64,
    /// Sd of one ADC sample, counts (white).
    pub adc_sample_bits: f64,
    /// Window averaged per reading, s.
    pub window_s: f64,
}

/// A planned session.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanSession {
    /// Identifier.
    pub id: String,
    /// Temperature, degC.
    pub temperature_c: f64,
    /// Roll of the block, deg.
    #[serde(default)]
    pub roll_deg: f64,
    /// Readings per station.
    pub readings_per_station: usize,
    /// Tilts (zenith distances), deg; or `tilt_range_deg` with `stations`.
    #[serde(default)]
    pub tilts_deg: Vec<f64>,
    /// First and last tilt, deg, spread evenly over `stations`.
    #[serde(default)]
    pub tilt_range_deg: Option<[f64; 2]>,
    /// Stations over `tilt_range_deg`.
    #[serde(default)]
    pub stations: Option<usize>,
}

/// A model to fit to the plan: the manifest's `[[adjust.model]]` (the same keys, defaults
/// and checks), of kind "axis".
pub type PlanModel = ingest::contract::manifest::ModelDecl;

/// The most readings, stations or tilts a planned session may have, and the most
/// observations a plan may build: far beyond any tilt-table experiment, and within what the
/// adjustment holds in memory.
pub const MAX_PER_SESSION: usize = 100_000;
/// See [`MAX_PER_SESSION`].
pub const MAX_OBSERVATIONS: usize = 2_000_000;

/// A parameter's predicted sd.
#[derive(Clone, Debug, Serialize)]
pub struct Predicted {
    /// Name.
    pub name: String,
    /// Unit.
    pub unit: String,
    /// Predicted a-priori sd.
    pub sigma: f64,
}

/// Minimal detectable biases over the observations of a fit: as the pipeline's w-test
/// detects them (its reading's sigma_Dz from the station's other readings, a t on n - 2
/// dof; the moderation toward the session's variance adds dof and lowers them toward
/// Baarda's), and with sigma_Dz known (Baarda's 4.13).
#[derive(Clone, Debug, Serialize)]
pub struct Mdb {
    /// Of one theodolite reading, arcsec: median and largest over the readings.
    pub dz_arcsec: [f64; 2],
    /// Of one window mean, counts: median and largest.
    pub ng_counts: [f64; 2],
    /// The same with sigma_Dz known.
    pub dz_arcsec_known: [f64; 2],
    /// The same with sigma_Dz known.
    pub ng_counts_known: [f64; 2],
}

/// What the plan gives one fit.
#[derive(Clone, Debug, Serialize)]
pub struct FitPrediction {
    /// Model name.
    pub model: String,
    /// Session id or `all`.
    pub session: String,
    /// Observations.
    pub observations: usize,
    /// Parameters with their predicted sds (empty when not estimable).
    pub parameters: Vec<Predicted>,
    /// Correlation matrix, in the order of `parameters`.
    pub correlation: Vec<Vec<f64>>,
    /// Minimal detectable biases.
    pub mdb: Option<Mdb>,
    /// What the plan cannot determine, and what would fix it.
    pub not_estimable: Vec<String>,
}

/// Why a plan cannot be predicted.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// A key with a bad value.
    #[error("{key}: {message}")]
    Bad {
        /// The key.
        key: String,
        /// What is wrong.
        message: String,
    },
}

fn bad(key: String, message: impl Into<String>) -> PlanError {
    PlanError::Bad {
        key,
        message: message.into(),
    }
}

impl Plan {
    /// Checks the plan as a manifest is checked (names, orders, ranges, counts), before
    /// anything is built; the error names the key.
    pub fn check(&self) -> Result<(), PlanError> {
        self.check_site_and_noise()?;
        self.check_sessions()?;
        self.check_models()
    }

    fn check_site_and_noise(&self) -> Result<(), PlanError> {
        finite("site.g_mgal".into(), self.site.g_mgal)?;
        if !(900_000.0..=1_000_000.0).contains(&self.site.g_mgal) {
            return Err(bad(
                "site.g_mgal".into(),
                format!("{} is out of range [900000, 1000000]", self.site.g_mgal),
            ));
        }
        finite("instrument.b_mgal".into(), self.instrument.b_mgal)?;
        finite(
            "instrument.k_mgal_per_bit".into(),
            self.instrument.k_mgal_per_bit,
        )?;
        if self.instrument.k_mgal_per_bit == 0.0 {
            return Err(bad(
                "instrument.k_mgal_per_bit".into(),
                "0 is no scale factor: the counts would not move with the acceleration",
            ));
        }
        if !(0.01..=10_000.0).contains(&self.instrument.sample_rate_hz) {
            return Err(bad(
                "instrument.sample_rate_hz".into(),
                format!(
                    "{} is out of range [0.01, 10000]",
                    self.instrument.sample_rate_hz
                ),
            ));
        }
        for (key, v) in [
            ("noise.theodolite_arcsec", self.noise.theodolite_arcsec),
            ("noise.adc_sample_bits", self.noise.adc_sample_bits),
            ("noise.window_s", self.noise.window_s),
        ] {
            if !(v.is_finite() && v > 0.0 && v <= 1e6) {
                return Err(bad(key.into(), format!("{v} is not in (0, 1e6]")));
            }
        }
        Ok(())
    }

    /// Sessions: at least one, ids checked and unique, finite conditions, readings per
    /// station and the observations in all within their bounds.
    fn check_sessions(&self) -> Result<(), PlanError> {
        use ingest::contract::manifest::{RESERVED_SESSION_IDS, check_name};
        if self.session.is_empty() {
            return Err(bad(
                "session".into(),
                "at least one [[session]] is required",
            ));
        }
        let mut ids = ingest::contract::manifest::Names::default();
        let mut total = 0usize;
        for (i, s) in self.session.iter().enumerate() {
            check_name(&s.id, RESERVED_SESSION_IDS)
                .map_err(|e| bad(format!("session[{i}].id"), e))?;
            ids.insert(&s.id, "id")
                .map_err(|e| bad(format!("session[{i}].id"), e))?;
            let t = ingest::readers::labstream::TEMPERATURE_LIMITS;
            if !(t.lo..=t.hi).contains(&s.temperature_c) {
                return Err(bad(
                    format!("session[{i}].temperature_c"),
                    format!(
                        "{} is not a temperature a session is read at (every log's readings \
                         lie in [{}, {}] degC)",
                        s.temperature_c, t.lo, t.hi
                    ),
                ));
            }
            finite(format!("session[{i}].roll_deg"), s.roll_deg)?;
            let stations = s.tilts(i)?.len();
            if !(1..=MAX_PER_SESSION).contains(&s.readings_per_station) {
                return Err(bad(
                    format!("session[{i}].readings_per_station"),
                    format!(
                        "{} is out of range [1, {MAX_PER_SESSION}]",
                        s.readings_per_station
                    ),
                ));
            }
            total = total.saturating_add(stations.saturating_mul(s.readings_per_station));
        }
        if total > MAX_OBSERVATIONS {
            return Err(bad(
                "session".into(),
                format!("{total} observations planned; at most {MAX_OBSERVATIONS} are allowed"),
            ));
        }
        Ok(())
    }

    /// Models: at least one, each checked as the manifest's, axis models only, names unique.
    fn check_models(&self) -> Result<(), PlanError> {
        use ingest::contract::manifest::ModelKind;
        if self.model.is_empty() {
            return Err(bad("model".into(), "at least one [[model]] is required"));
        }
        let mut names = ingest::contract::manifest::Names::default();
        for (i, m) in self.model.iter().enumerate() {
            m.check()
                .map_err(|(k, e)| bad(format!("model[{i}].{k}"), e))?;
            if m.kind != ModelKind::Axis {
                return Err(bad(
                    format!("model[{i}].kind"),
                    "the planner predicts axis models (tilt-table sessions) only",
                ));
            }
            names
                .insert(&m.name, "name")
                .map_err(|e| bad(format!("model[{i}].name"), e))?;
        }
        Ok(())
    }
}

/// `v` finite, or an error naming `key`.
fn finite(key: String, v: f64) -> Result<(), PlanError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(bad(key, format!("{v} is not a finite number")))
    }
}

impl PlanSession {
    /// The tilts, deg.
    fn tilts(&self, i: usize) -> Result<Vec<f64>, PlanError> {
        if self.tilts_deg.len() > MAX_PER_SESSION
            || self.stations.is_some_and(|n| n > MAX_PER_SESSION)
        {
            return Err(bad(
                format!("session[{i}]"),
                format!("more than {MAX_PER_SESSION} stations"),
            ));
        }
        if let Some(t) = self
            .tilts_deg
            .iter()
            .chain(self.tilt_range_deg.iter().flatten())
            .find(|t| !(t.is_finite() && (0.0..=360.0).contains(*t)))
        {
            return Err(bad(
                format!("session[{i}]"),
                format!("tilt {t} deg is not in [0, 360]"),
            ));
        }
        match (&self.tilts_deg[..], self.tilt_range_deg, self.stations) {
            (t, None, None) if !t.is_empty() => Ok(t.to_vec()),
            ([], Some([a, b]), Some(n)) if n >= 2 => Ok((0..n)
                .map(|j| a + (b - a) * j as f64 / (n - 1) as f64)
                .collect()),
            _ => Err(bad(
                format!("session[{i}]"),
                "give tilts_deg, or tilt_range_deg with stations >= 2",
            )),
        }
    }
}

/// The largest count any ADC a manifest declares gives (32 bits, the manifest's widest).
const ADC_COUNTS_MAX: f64 = 2_147_483_648.0;

/// The plan's noise-free observations of one accelerometer, with their session ids: per station,
/// `readings_per_station` readings with counts from the nominal calibration.
pub fn observations(plan: &Plan) -> Result<Vec<(String, Obs)>, PlanError> {
    let n_window = (plan.noise.window_s * plan.instrument.sample_rate_hz).max(1.0);
    let sigma_ng = plan.noise.adc_sample_bits / n_window.sqrt();
    let sigma_dz = (plan.noise.theodolite_arcsec / 3600.0).to_radians();
    if !(sigma_ng > 0.0 && sigma_dz > 0.0) {
        return Err(bad("noise".to_owned(), "the noise levels must be positive"));
    }
    let mut out = Vec::new();
    let mut station = 0;
    for (si, s) in plan.session.iter().enumerate() {
        for (ti, tilt) in s.tilts(si)?.into_iter().enumerate() {
            let dz = tilt.to_radians();
            let a = -plan.site.g_mgal * dz.cos();
            let ng = (a - plan.instrument.b_mgal) / plan.instrument.k_mgal_per_bit;
            // NaN too: an overflow is no count.
            if ng.is_nan() || ng.abs() > ADC_COUNTS_MAX {
                return Err(bad(
                    "instrument".to_owned(),
                    format!(
                        "b_mgal {:e} and k_mgal_per_bit {:e} give {ng:e} counts at tilt {tilt} \
                         deg of session[{si}], beyond any ADC's range (+/- 2^31): they are not \
                         an instrument's calibration",
                        plan.instrument.b_mgal, plan.instrument.k_mgal_per_bit
                    ),
                ));
            }
            for r in 0..s.readings_per_station {
                out.push((
                    s.id.clone(),
                    Obs {
                        dz_rad: dz,
                        sigma_dz_rad: sigma_dz,
                        sigma_dz_dof: None,
                        sigma_dz_left_out: None,
                        station,
                        session: si,
                        time_s: (ti * s.readings_per_station + r) as f64 * 8.0,
                        roll_rad: s.roll_deg.to_radians(),
                        ng,
                        sigma_ng,
                        sigma_ng_dof: None,
                        temperature_c: s.temperature_c,
                        sigma_temperature_c: 0.0,
                        tide_mgal: 0.0,
                    },
                ));
            }
            station += 1;
        }
    }
    Ok(out)
}

/// Predicts every model of `plan`, per session or over all sessions as each asks.
pub fn predict(plan: &Plan) -> Result<Vec<FitPrediction>, PlanError> {
    use ingest::contract::manifest::Per;
    plan.check()?;
    let all = observations(plan)?;
    let mut out = Vec::new();
    for m in &plan.model {
        let groups: Vec<Option<&str>> = match m.per {
            Per::Session => plan.session.iter().map(|s| Some(s.id.as_str())).collect(),
            Per::All => vec![None],
        };
        for g in groups {
            let obs: Vec<Obs> = all
                .iter()
                .filter(|(s, _)| g.is_none_or(|g| s == g))
                .map(|(_, o)| o.clone())
                .collect();
            out.push(predict_fit(plan, m, g.unwrap_or(ALL_SESSIONS), &obs));
        }
    }
    Ok(out)
}

/// One fit's prediction.
fn predict_fit(plan: &Plan, m: &PlanModel, session: &str, obs: &[Obs]) -> FitPrediction {
    let mut terms = Terms {
        order: usize::from(m.order),
        temperature: m.temperature,
        misalignment: m.misalignment,
    };
    let mut not_estimable = Vec::new();
    let rolls: Vec<f64> = obs.iter().map(|o| o.roll_rad).collect();
    if let Some(note) = crate::vector_note(&terms, &rolls) {
        terms.misalignment = Misalignment::Plane;
        not_estimable.push(note);
    }
    let options = FitOptions {
        snooping: Snooping::Off,
        coloured: None,
        components: false,
    };
    let mut prediction = FitPrediction {
        model: m.name.clone(),
        session: session.to_owned(),
        observations: obs.len(),
        parameters: Vec::new(),
        correlation: Vec::new(),
        mdb: None,
        not_estimable,
    };
    match calibrate::calibrate_with(obs, terms, plan.site.g_mgal, &options) {
        Ok(f) => {
            let correlation = f.correlation();
            for (j, n) in terms.names().iter().enumerate() {
                prediction.parameters.push(Predicted {
                    name: n.name.to_owned(),
                    unit: n.unit.to_owned(),
                    sigma: f.sigma_apriori(j),
                });
            }
            for note in crate::barely_estimable(&terms, &correlation) {
                let fix = fix_for(note.split(' ').next().unwrap_or_default());
                prediction.not_estimable.push(format!("{note}; {fix}"));
            }
            prediction.correlation = correlation;
            prediction.mdb = Some(mdb(plan, obs, &f));
        }
        Err(CalError::NotEstimable { parameter, why }) => prediction
            .not_estimable
            .push(format!("{parameter} is not estimable: {why}")),
        Err(e) => prediction.not_estimable.push(e.to_string()),
    }
    prediction
}

/// What separates a barely estimable parameter from the others.
fn fix_for(parameter: &str) -> &'static str {
    match parameter {
        "beta" | "theta_x" | "theta_y" => {
            "tilts on both sides of the vertical would separate it (and a second roll, for the vector)"
        }
        "b_t" | "k_t" => "a second temperature further from the first would separate it",
        _ => "more tilt positions over a wider range would separate it",
    }
}

/// The minimal detectable bias of each reading and window mean: the bias whose w-test
/// reaches the non-centrality `delta`, `delta sqrt(q_i / r_i) / |B_ij|`, with `delta` that
/// of a t on n - 2 dof for a station of n readings ([`calibrate::mdb_noncentrality`]), and
/// Baarda's [`DELTA_0`].
fn mdb(plan: &Plan, obs: &[Obs], f: &calibrate::CalibrationSolution) -> Mdb {
    let k = plan.instrument.k_mgal_per_bit.abs();
    let stations = obs.iter().map(|o| o.station).max().map_or(0, |m| m + 1);
    let mut readings = vec![0usize; stations];
    for o in obs {
        readings[o.station] += 1;
    }
    let (mut dz, mut ng, mut dz_known, mut ng_known) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for r in &f.residuals {
        let o = &obs[r.index];
        let b0 = plan.site.g_mgal * o.dz_rad.sin().abs();
        let q = (b0 * o.sigma_dz_rad).powi(2) + (k * o.sigma_ng).powi(2);
        if r.redundancy > 1e-9 {
            let dof = (readings[o.station] > 2).then(|| (readings[o.station] - 2) as f64);
            for (delta, dz, ng) in [
                (calibrate::mdb_noncentrality(dof), &mut dz, &mut ng),
                (DELTA_0, &mut dz_known, &mut ng_known),
            ] {
                let base = delta * (q / r.redundancy).sqrt();
                dz.push((base / b0).to_degrees() * 3600.0);
                ng.push(base / k);
            }
        }
    }
    let stats = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        if v.is_empty() {
            [f64::NAN; 2]
        } else {
            [v[v.len() / 2], v[v.len() - 1]]
        }
    };
    Mdb {
        dz_arcsec: stats(dz),
        ng_counts: stats(ng),
        dz_arcsec_known: stats(dz_known),
        ng_counts_known: stats(ng_known),
    }
}

/// The predictions as a text table.
pub fn render(predictions: &[FitPrediction]) -> String {
    let mut s = String::new();
    for p in predictions {
        s += &format!(
            "{} {} ({} observations)\n",
            p.model, p.session, p.observations
        );
        for (j, q) in p.parameters.iter().enumerate() {
            let corr: Vec<String> = p.correlation[j]
                .iter()
                .enumerate()
                .filter(|&(i, _)| i != j)
                .map(|(i, c)| format!("{} {c:+.3}", p.parameters[i].name))
                .collect();
            s += &format!(
                "  {:<8} sigma {:>11.4e} {:<14} corr: {}\n",
                q.name,
                q.sigma,
                q.unit,
                corr.join(", ")
            );
        }
        if let Some(m) = &p.mdb {
            s += &format!(
                "  MDB (alpha 0.001, power 0.80; each reading tested on its station's other readings, a t on n - 2 dof): theodolite reading {:.2} arcsec (worst {:.2}), window mean {:.2} counts (worst {:.2}); with sigma_Dz known (Baarda): {:.2} arcsec, {:.2} counts\n",
                m.dz_arcsec[0],
                m.dz_arcsec[1],
                m.ng_counts[0],
                m.ng_counts[1],
                m.dz_arcsec_known[0],
                m.ng_counts_known[0]
            );
        }
        for n in &p.not_estimable {
            s += &format!("  NOT DETERMINED: {n}\n");
        }
    }
    s
}
