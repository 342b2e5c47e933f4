//! The fits to make: the models (the manifest's or the defaults), one job per model,
//! accelerometer and session (or all sessions), each fitted on its own rayon task, and the
//! reason a fit could not be made.

use super::calibrate::{self, CalError, LeftOut, Obs};
use super::model::{Misalignment, Terms};
use super::results::{result_of, vector_note};
use crate::lsq::components;
use crate::lsq::correlated::ColouredAdc;
use ingest::contract::align_ledger::AlignReport;
use ingest::contract::calibration::FitScope;
use ingest::contract::calibration::{CalibrationResult, Skipped, VarianceComponent};
use ingest::contract::manifest::{Dataset, ModelDecl, ModelKind, Per};
use ingest::contract::tables;

/// The models to fit: the manifest's, or the defaults (docs/formats.md section 2): `linear`, plus
/// `thermal` when the sessions' mean temperatures differ by more than 1 degree C.
pub fn models(declared: &[ModelDecl], session_mean_temperatures: &[f64]) -> Vec<ModelDecl> {
    if !declared.is_empty() {
        return declared.to_vec();
    }
    let mut v = vec![ModelDecl {
        name: "linear".into(),
        kind: ModelKind::Axis,
        order: 1,
        per: Per::Session,
        temperature: false,
        misalignment: Misalignment::None,
        position_floor: Default::default(),
    }];
    let (lo, hi) = session_mean_temperatures
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    if hi - lo > 1.0 {
        v.push(ModelDecl {
            name: "thermal".into(),
            kind: ModelKind::Axis,
            order: 1,
            per: Per::All,
            temperature: true,
            misalignment: Misalignment::None,
            position_floor: Default::default(),
        });
    }
    v
}

pub(crate) struct Job<'a> {
    pub(crate) model: &'a ModelDecl,
    pub(crate) accelerometer: String,
    pub(crate) scope: FitScope,
    pub(crate) obs: Vec<&'a tables::observations::Observation>,
    /// The accelerometer's coloured ADC noise from align's Allan deviation (None: white).
    pub(crate) coloured: Option<ColouredAdc>,
    /// Roll of the block at each observation, rad.
    pub(crate) rolls: Vec<f64>,
}

/// Why a fit was skipped, naming an observation by its theodolite log and line, never by an
/// internal index.
pub(crate) fn skip_reason(ds: &Dataset, job: &Job<'_>, e: &CalError) -> String {
    match e {
        CalError::ZeroVariance { index } => {
            let o = job.obs[*index];
            let log = ds
                .sessions
                .iter()
                .find(|s| s.session.id == o.session)
                .and_then(|s| s.theodolite.as_deref())
                .map(|t| t.strip_prefix(&ds.dir).unwrap_or(t).display().to_string())
                .unwrap_or_default();
            format!(
                "the reading at {log} line {} (session {}, station {}) has zero variance: its sd of Dz and of the counts are both 0",
                o.line, o.session, o.station
            )
        }
        other => other.to_string(),
    }
}

/// Each session's mean temperature over the observations used (sessions without any left out).
pub(crate) fn session_mean_temperatures(
    ds: &Dataset,
    used: &[&tables::observations::Observation],
) -> Vec<f64> {
    ds.sessions
        .iter()
        .filter_map(|s| {
            let t: Vec<f64> = used
                .iter()
                .filter(|o| o.session == s.session.id)
                .filter_map(|o| o.temperature_c)
                .collect();
            (!t.is_empty()).then(|| t.iter().sum::<f64>() / t.len() as f64)
        })
        .collect()
}

/// One job per (model, accelerometer, session or `all`), with its observations; an
/// accelerometer disconnected for the session is skipped.
pub(crate) fn plan_jobs<'a>(
    ds: &Dataset,
    models: &'a [ModelDecl],
    used: &[&'a tables::observations::Observation],
    align_report: &AlignReport,
) -> (Vec<Job<'a>>, Vec<Skipped>) {
    let mut jobs = Vec::new();
    let mut skipped = Vec::new();
    for model in models.iter().filter(|m| m.kind == ModelKind::Axis) {
        for acc in &ds.manifest.instrument.accelerometer {
            let scopes: Vec<FitScope> = match model.per {
                // Only tilt-table sessions have observations for an axis calibration.
                Per::Session => ds
                    .sessions
                    .iter()
                    .filter(|s| s.is_tilt_table())
                    .map(|s| FitScope::Session(s.session.id.clone()))
                    .collect(),
                Per::All => vec![FitScope::All],
            };
            for scope in scopes {
                let disconnected = align_report
                    .disconnected
                    .iter()
                    .any(|d| d.accelerometer == acc.id && d.session == scope.id());
                if disconnected {
                    skipped.push(Skipped {
                        accelerometer: acc.id.clone(),
                        session: scope.id().to_owned(),
                        model: model.name.clone(),
                        reason: "channel not connected".to_owned(),
                    });
                    continue;
                }
                let obs: Vec<&tables::observations::Observation> = used
                    .iter()
                    .copied()
                    .filter(|o| o.accelerometer == acc.id && scope.covers(&o.session))
                    .collect();
                let untempered = obs.iter().find(|o| o.temperature_c.is_none());
                if let Some(o) = untempered.filter(|_| model.temperature) {
                    skipped.push(Skipped {
                        accelerometer: acc.id.clone(),
                        session: scope.id().to_owned(),
                        model: model.name.clone(),
                        reason: format!(
                            "not estimable: its temperature terms need a temperature at every \
                             reading, and session {} declares no thermometer \
                             (thermometers = \"none\")",
                            o.session
                        ),
                    });
                    continue;
                }
                jobs.push(Job {
                    model,
                    accelerometer: acc.id.clone(),
                    scope,
                    coloured: coloured_of(align_report, &acc.id, ds.manifest.align.window_s),
                    rolls: obs
                        .iter()
                        .map(|o| {
                            ds.manifest
                                .session
                                .iter()
                                .find(|s| s.id == o.session)
                                .map_or(0.0, |s| s.roll_deg.to_radians())
                        })
                        .collect(),
                    obs,
                });
            }
        }
    }
    (jobs, skipped)
}

/// calibration.json's form of a variance component.
pub(crate) fn component_of(c: &components::Component) -> VarianceComponent {
    VarianceComponent {
        group: c.group.to_owned(),
        estimate: c.estimate,
        sigma: c.not_estimable.is_none().then_some(c.sigma),
        dof: c.test.dof,
        statistic: c.test.statistic,
        expectation: c.test.mean,
        lower: c.test.lower,
        upper: c.test.upper,
        passed: c.test.passed(),
        not_estimable: c.not_estimable.clone(),
    }
}

/// Least and greatest of the values present.
pub(crate) fn range_of(values: impl Iterator<Item = Option<f64>>) -> Option<[f64; 2]> {
    values.flatten().fold(None, |acc, v| match acc {
        None => Some([v, v]),
        Some([lo, hi]) => Some([lo.min(v), hi.max(v)]),
    })
}

/// The distinct directions (mod 180 deg) of the rolls, in deg.
pub(crate) fn roll_directions(rolls: &[f64]) -> Vec<f64> {
    let mut dirs: Vec<f64> = Vec::new();
    for r in rolls {
        let d = r.to_degrees().rem_euclid(180.0);
        if !dirs.iter().any(|x| {
            let diff = (x - d).rem_euclid(180.0);
            diff.min(180.0 - diff) < 1.0
        }) {
            dirs.push(d);
        }
    }
    dirs
}

/// An accelerometer's coloured ADC noise as align fitted it: None when its Allan deviation
/// shows white noise only.
pub(crate) fn coloured_of(
    align_report: &AlignReport,
    accelerometer: &str,
    window_s: f64,
) -> Option<ColouredAdc> {
    align_report
        .noise
        .iter()
        .find(|n| n.accelerometer == accelerometer)
        .map(|n| ColouredAdc {
            bias_instability: n.bias_instability_counts,
            random_walk: n.random_walk_counts_sqrt_hz,
            window_s,
            bias_instability_dof: n.bias_instability_dof,
            random_walk_dof: n.random_walk_dof,
        })
        .filter(|c| c.bias_instability > 0.0 || c.random_walk > 0.0)
}

/// Calibrates one job.
pub(crate) fn fit_job(
    job: &Job<'_>,
    g: f64,
) -> Result<(CalibrationResult, calibrate::CalibrationSolution), CalError> {
    let mut terms = Terms {
        order: usize::from(job.model.order),
        temperature: job.model.temperature,
        misalignment: job.model.misalignment,
    };
    // One roll direction sees one component of the vector: fit its plane (beta at that roll)
    // and name the other.
    let note = vector_note(&terms, &job.rolls);
    if note.is_some() {
        terms.misalignment = Misalignment::Plane;
    }
    let mut stations: Vec<(&str, &str)> = job
        .obs
        .iter()
        .map(|o| (o.session.as_str(), o.station.as_str()))
        .collect();
    stations.sort_unstable();
    stations.dedup();
    let mut sessions: Vec<&str> = job.obs.iter().map(|o| o.session.as_str()).collect();
    sessions.sort_unstable();
    sessions.dedup();
    let t0 = job.obs.iter().map(|o| o.time_gps_ns).min().unwrap_or(0);
    let obs: Vec<Obs> = job
        .obs
        .iter()
        .enumerate()
        .map(|(i, o)| Obs {
            dz_rad: o.dz_rad,
            sigma_dz_rad: o.sigma_dz_rad,
            sigma_dz_dof: o.sigma_dz_dof,
            sigma_dz_left_out: Some(LeftOut {
                sigma_rad: o.sigma_dz_loo_rad,
                dof: o.sigma_dz_loo_dof,
            }),
            station: stations
                .binary_search(&(o.session.as_str(), o.station.as_str()))
                .unwrap_or(0),
            session: sessions.binary_search(&o.session.as_str()).unwrap_or(0),
            time_s: (o.time_gps_ns - t0) as f64 * 1e-9,
            ng: o.ng.unwrap_or_default(),
            sigma_ng: o.sigma_ng.unwrap_or_default(),
            sigma_ng_dof: o.sigma_ng_dof,
            temperature_c: o.temperature_c.unwrap_or_default(),
            sigma_temperature_c: o.sigma_temperature_c.unwrap_or_default(),
            tide_mgal: o.tide_mgal.unwrap_or_default(),
            roll_rad: job.rolls[i],
        })
        .collect();
    let options = calibrate::FitOptions {
        coloured: job.coloured,
        ..calibrate::FitOptions::default()
    };
    calibrate::calibrate_with(&obs, terms, g, &options)
        .map(|f| (result_of(job, &f, terms, note), f))
}

/// residuals.parquet's rows of one calibration: the observations used, then those removed.
pub(crate) fn residual_rows_of<'a>(
    job: &'a Job<'a>,
    f: &calibrate::CalibrationSolution,
) -> Vec<tables::residuals::Fitted<'a>> {
    let row = |index: usize, w: f64| tables::residuals::Fitted {
        model: &job.model.name,
        accelerometer: &job.accelerometer,
        fit_session: job.scope.id(),
        obs: job.obs[index],
        v_dz_rad: None,
        v_ng: None,
        residual_mgal: None,
        redundancy: None,
        w,
        removed: true,
    };
    let used = f.residuals.iter().map(|res| tables::residuals::Fitted {
        v_dz_rad: Some(res.v_dz_rad),
        v_ng: Some(res.v_ng),
        residual_mgal: Some(res.misclosure_mgal),
        redundancy: Some(res.redundancy),
        removed: false,
        ..row(res.index, res.w)
    });
    let removed = f.removed.iter().map(|rem| row(rem.index, rem.w));
    used.chain(removed).collect()
}
