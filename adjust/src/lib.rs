//! gravcal's `adjust` stage: the calibration functions by a rigorous errors-in-both-variables
//! (Gauss-Helmert) adjustment (docs/model.md).
//!
//! Reads OUT/align (observations.parquet, align.json) and OUT/ingest/ingest.json, fits every
//! model the manifest declares (or the defaults of docs/formats.md section 2) per accelerometer
//! and session or over all sessions, in parallel (rayon), and writes
//! OUT/adjust/calibration.json (docs/formats.md section 6) and OUT/adjust/residuals.parquet.
//!
//! The mathematics does no I/O: [`gh`] is the general engine, [`model`] the condition
//! equations, [`calibrate`] one calibration fit with data snooping, [`fit`] the general
//! polynomial fitting command (docs/formats.md section 7).

pub mod apply;
pub mod calibrate;
pub mod components;
pub mod correlated;
pub mod fit;
pub mod gh;
pub mod gravity;
pub mod io;
pub mod model;
pub mod plan;
pub mod triad;
pub mod triad_fits;

use calibrate::{CalError, Obs};
use correlated::ColouredAdc;
use ingest::contract::align_ledger::{self, AlignReport};
use ingest::contract::calibration::{
    CALIBRATION_FILE, CALIBRATION_FORMAT, Calibration, CalibrationResult, GlobalTest, Input,
    KalibrNoise, MisalignmentVector, Parameter, Removed, STAGE_DIR, Skipped, VarianceComponent,
};
use ingest::contract::custody::{Custody, Folders, Root};
use ingest::contract::ledger::{self as ingest_ledger, IngestReport};
use ingest::contract::manifest::{Dataset, ModelDecl, ModelKind, Per};
use model::{Misalignment, Terms};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// What can go wrong in adjust.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading the manifest or an upstream ledger, or writing a table.
    #[error(transparent)]
    Ingest(#[from] ingest::Error),
    /// Reading align's outputs.
    #[error(transparent)]
    Align(#[from] align::Error),
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// An input table is not what align writes.
    #[error("{}: {message}", path.display())]
    Table {
        /// The table.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A calibration cannot be applied as asked (the instrument, the model or the session
    /// does not match): `path` is the calibration file.
    #[error("{}: {message}", path.display())]
    Apply {
        /// The calibration file.
        path: PathBuf,
        /// What does not match, and what to change.
        message: String,
    },
    /// The fit command's input is unusable.
    #[error("{0}")]
    Fit(String),
}

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
        });
    }
    v
}

struct Job<'a> {
    model: &'a ModelDecl,
    accelerometer: String,
    session: String,
    obs: Vec<&'a io::ObservationRow>,
    /// The accelerometer's coloured ADC noise from align's Allan deviation (None: white).
    coloured: Option<ColouredAdc>,
    /// Roll of the block at each observation, rad.
    rolls: Vec<f64>,
}

/// A parameter (beyond b and k) whose multiple correlation with the others is above this is
/// noted as barely estimable.
const NOTE_CORRELATION: f64 = 0.999;

/// Multiple correlation of each parameter with all the others, from the correlation matrix
/// `C`: `sqrt(1 - 1 / (C^-1)_jj)`. 1 where `C` is numerically singular.
fn multiple_correlation(c: &[Vec<f64>]) -> Vec<f64> {
    let n = c.len();
    // Cholesky C = L L^T; (C^-1)_jj = sum_k (L^-1)_kj^2.
    let mut l = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = c[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s <= 1e-15 {
                    return vec![1.0; n];
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut inv = vec![vec![0.0; n]; n];
    for col in 0..n {
        for i in col..n {
            let s: f64 = (col..i).map(|k| l[i][k] * inv[k][col]).sum();
            inv[i][col] = (if i == col { 1.0 } else { 0.0 } - s) / l[i][i];
        }
    }
    (0..n)
        .map(|j| {
            let d: f64 = (0..n).map(|k| inv[k][j] * inv[k][j]).sum();
            (1.0 - 1.0 / d).max(0.0).sqrt()
        })
        .collect()
}

fn result_of(
    job: &Job<'_>,
    f: &calibrate::CalibrationSolution,
    terms: Terms,
    note: Option<String>,
) -> CalibrationResult {
    let names = terms.names();
    let correlation = f.correlation();
    let mut warnings: Vec<String> = note.into_iter().collect();
    warnings.extend(barely_estimable(&terms, &correlation));
    CalibrationResult {
        accelerometer: job.accelerometer.clone(),
        session: job.session.clone(),
        model: job.model.name.clone(),
        order: job.model.order,
        temperature: job.model.temperature,
        misalignment: terms.misalignment.any(),
        t_ref_c: job.model.temperature.then_some(f.t_ref_c),
        mean_temperature_c: f.mean_temperature_c,
        counts_range: range_of(f.residuals.iter().map(|r| job.obs[r.index].ng)),
        temperature_range_c: range_of(f.residuals.iter().map(|r| job.obs[r.index].temperature_c)),
        n_observations: f.residuals.len(),
        n_excluded: f.removed.len(),
        dof: f.dof,
        iterations: f.iterations,
        sigma0: f.sigma0,
        global_test: GlobalTest {
            statistic: f.global_test.statistic,
            expectation: f.global_test.mean,
            dof: f.global_test.dof,
            lower: f.global_test.lower,
            upper: f.global_test.upper,
            passed: f.global_test_passed(),
        },
        variance_components: f.components.iter().map(component_of).collect(),
        parameters: names
            .iter()
            .enumerate()
            .map(|(j, n)| Parameter {
                name: n.name.to_owned(),
                unit: n.unit.to_owned(),
                value: f.values[j],
                sigma: f.sigma(j),
                sigma_apriori: f.sigma_apriori(j),
            })
            .collect(),
        correlation,
        removed: f
            .removed
            .iter()
            .map(|r| {
                let o = job.obs[r.index];
                Removed {
                    session: o.session.clone(),
                    station: o.station.clone(),
                    line: o.line,
                    time_gps_ns: o.time_gps_ns,
                    w: r.w,
                }
            })
            .collect(),
        warnings,
        misalignment_vector: (terms.misalignment == Misalignment::Vector)
            .then(|| misalignment_vector(f, terms)),
    }
}

/// Each accelerometer's Allan noise terms (counts) in SI units, by the |k| of its first fit.
fn kalibr_noise(align_report: &AlignReport, results: &[CalibrationResult]) -> Vec<KalibrNoise> {
    const M_S2_PER_MGAL: f64 = 1e-5;
    align_report
        .noise
        .iter()
        .filter_map(|n| {
            let r = results
                .iter()
                .find(|r| r.accelerometer == n.accelerometer)?;
            let k = r.parameters.iter().find(|p| p.name == "k")?.value.abs();
            let si = k * M_S2_PER_MGAL;
            Some(KalibrNoise {
                accelerometer: n.accelerometer.clone(),
                scale_from: format!("{} {}", r.model, r.session),
                accelerometer_noise_density: n.white_density_counts_per_sqrt_hz * si,
                accelerometer_random_walk: (n.random_walk_counts_sqrt_hz > 0.0)
                    .then_some(n.random_walk_counts_sqrt_hz * si),
                bias_instability: (n.bias_instability_counts > 0.0)
                    .then_some(n.bias_instability_counts * si),
            })
        })
        .collect()
}

/// What calibration.json says of the body tide: applied, with its range over the
/// observations used, or not, with its size (docs/formats.md 8.1).
fn earth_tide_note(used: &[&io::ObservationRow]) -> String {
    let tides: Vec<f64> = used.iter().filter_map(|o| o.tide_mgal).collect();
    if tides.is_empty() {
        return "no body tide applied: the site has no latitude_deg and longitude_deg (or earth_tide = false); \
                the tide changes g by up to about 0.25 mGal peak to peak"
            .to_owned();
    }
    let (lo, hi) = tides
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| {
            (a.min(t), b.max(t))
        });
    format!(
        "body tide applied to g per observation (Longman 1959, gravimetric factor {:.4}): \
         {lo:.4} to {hi:.4} mGal over the observations used",
        align::tide::GRAVIMETRIC_FACTOR
    )
}

/// Why a fit was skipped, naming an observation by its theodolite log and line, never by an
/// internal index.
fn skip_reason(ds: &Dataset, job: &Job<'_>, e: &CalError) -> String {
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
fn session_mean_temperatures(ds: &Dataset, used: &[&io::ObservationRow]) -> Vec<f64> {
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
fn plan_jobs<'a>(
    ds: &Dataset,
    models: &'a [ModelDecl],
    used: &[&'a io::ObservationRow],
    align_report: &AlignReport,
) -> (Vec<Job<'a>>, Vec<Skipped>) {
    let mut jobs = Vec::new();
    let mut skipped = Vec::new();
    for model in models.iter().filter(|m| m.kind == ModelKind::Axis) {
        for acc in &ds.manifest.instrument.accelerometer {
            let groups: Vec<String> = match model.per {
                // Only tilt-table sessions have observations for an axis calibration.
                Per::Session => ds
                    .sessions
                    .iter()
                    .filter(|s| s.is_tilt_table())
                    .map(|s| s.session.id.clone())
                    .collect(),
                Per::All => vec!["all".to_owned()],
            };
            for session in groups {
                let disconnected = align_report
                    .disconnected
                    .iter()
                    .any(|d| d.accelerometer == acc.id && d.session == session);
                if disconnected {
                    skipped.push(Skipped {
                        accelerometer: acc.id.clone(),
                        session,
                        model: model.name.clone(),
                        reason: "channel not connected".to_owned(),
                    });
                    continue;
                }
                let obs: Vec<&io::ObservationRow> = used
                    .iter()
                    .copied()
                    .filter(|o| {
                        o.accelerometer == acc.id && (session == "all" || o.session == session)
                    })
                    .collect();
                jobs.push(Job {
                    model,
                    accelerometer: acc.id.clone(),
                    session,
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
fn component_of(c: &components::Component) -> VarianceComponent {
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
fn range_of(values: impl Iterator<Item = Option<f64>>) -> Option<[f64; 2]> {
    values.flatten().fold(None, |acc, v| match acc {
        None => Some([v, v]),
        Some([lo, hi]) => Some([lo.min(v), hi.max(v)]),
    })
}

/// Notes on the parameters beyond b and k whose multiple correlation with all the others
/// exceeds [`NOTE_CORRELATION`], with their correlation to each (b and k are always strongly
/// correlated, the counts being far from zero: the report says so).
pub fn barely_estimable(terms: &Terms, correlation: &[Vec<f64>]) -> Vec<String> {
    let names = terms.names();
    let multiple = multiple_correlation(correlation);
    (2..names.len())
        .filter(|&i| multiple[i] > NOTE_CORRELATION)
        .map(|i| {
            let pairs: Vec<String> = (0..names.len())
                .filter(|&j| j != i)
                .map(|j| format!("{} {:.6}", names[j].name, correlation[i][j]))
                .collect();
            format!(
                "{} is barely estimable: multiple correlation {:.6} with the other parameters; correlation with {}",
                names[i].name,
                multiple[i],
                pairs.join(", ")
            )
        })
        .collect()
}

/// When `terms` ask for the misalignment vector but the `rolls` (rad, per observation) lie
/// in one direction (mod 180 deg), the note naming the component they cannot see and the
/// roll that would: the fit then takes the plane (beta at that roll).
pub fn vector_note(terms: &Terms, rolls: &[f64]) -> Option<String> {
    let directions = roll_directions(rolls);
    if terms.misalignment != Misalignment::Vector || directions.len() >= 2 {
        return None;
    }
    let at = directions.first().copied().unwrap_or(0.0);
    // The unseen component lies along the block's direction at + 90 deg.
    let unseen = match at {
        a if a.abs() < 1e-9 => "theta_y".to_owned(),
        a if (a - 90.0).abs() < 1e-9 => "theta_x".to_owned(),
        a => format!("the component at psi = {:.1} deg", a + 90.0),
    };
    Some(format!(
        "the misalignment's component along the tilt axis at roll {at:.1} deg ({unseen}) is not estimable: \
         every session is at roll {at:.1} deg (mod 180); a session at roll {:.1} deg would determine it. \
         beta is the component in the tilt plane at roll {at:.1} deg",
        at + 90.0
    ))
}

/// theta and psi from theta_x, theta_y and their covariance: propagated; psi only when theta
/// is more than 3 sigma from 0 (closer, its distribution spreads toward uniform and a
/// linearised sd would be a fiction).
pub fn misalignment_vector(f: &calibrate::CalibrationSolution, terms: Terms) -> MisalignmentVector {
    let m = terms.len();
    let (ix, iy) = (m - 2, m - 1);
    let (tx, ty) = (f.values[ix], f.values[iy]);
    let c = |i: usize, j: usize| f.covariance[i * m + j];
    let theta = tx.hypot(ty);
    // Larger principal variance of (theta_x, theta_y).
    let (a, b, d) = (c(ix, ix), c(ix, iy), c(iy, iy));
    let lambda_max = 0.5 * (a + d) + (0.25 * (a - d).powi(2) + b * b).sqrt();
    let sigma_theta = if theta > 0.0 {
        let (jx, jy) = (tx / theta, ty / theta);
        (jx * jx * a + 2.0 * jx * jy * b + jy * jy * d)
            .max(0.0)
            .sqrt()
    } else {
        lambda_max.sqrt()
    };
    let determined = theta > PSI_SIGMAS * lambda_max.sqrt();
    let sigma_psi = {
        let (jx, jy) = (-ty / (theta * theta), tx / (theta * theta));
        (jx * jx * a + 2.0 * jx * jy * b + jy * jy * d)
            .max(0.0)
            .sqrt()
            .to_degrees()
    };
    MisalignmentVector {
        theta_rad: theta,
        sigma_theta_rad: if determined {
            sigma_theta
        } else {
            lambda_max.sqrt()
        },
        psi_deg: determined.then(|| ty.atan2(tx).to_degrees()),
        sigma_psi_deg: determined.then_some(sigma_psi),
        psi_not_determined: (!determined).then(|| {
            format!(
                "theta = {theta:.3e} rad is within {PSI_SIGMAS} sigma ({:.3e} rad) of 0: its direction is not determined",
                lambda_max.sqrt()
            )
        }),
    }
}

/// theta must exceed this many sds for its direction psi to be given.
const PSI_SIGMAS: f64 = 3.0;

/// The distinct directions (mod 180 deg) of the rolls, in deg.
fn roll_directions(rolls: &[f64]) -> Vec<f64> {
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
fn coloured_of(
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
        })
        .filter(|c| c.bias_instability > 0.0 || c.random_walk > 0.0)
}

/// Calibrates one job.
fn fit_job(
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
            station: stations
                .binary_search(&(o.session.as_str(), o.station.as_str()))
                .unwrap_or(0),
            session: sessions.binary_search(&o.session.as_str()).unwrap_or(0),
            time_s: (o.time_gps_ns - t0) as f64 * 1e-9,
            ng: o.ng.unwrap_or_default(),
            sigma_ng: o.sigma_ng.unwrap_or_default(),
            temperature_c: o.temperature_c.unwrap_or_default(),
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
fn residual_rows_of<'a>(
    job: &'a Job<'a>,
    f: &calibrate::CalibrationSolution,
) -> Vec<io::ResidualRow<'a>> {
    let row = |index: usize, w: f64| io::ResidualRow {
        model: &job.model.name,
        accelerometer: &job.accelerometer,
        fit_session: &job.session,
        obs: job.obs[index],
        v_dz_rad: None,
        v_ng: None,
        residual_mgal: None,
        redundancy: None,
        w,
        removed: true,
    };
    let used = f.residuals.iter().map(|res| io::ResidualRow {
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

/// Writes residuals.parquet and calibration.json, with the chain of custody: every file
/// adjust read and the table it wrote.
fn write_outputs(
    ds: &Dataset,
    out: &Path,
    mut calibration: Calibration,
    residual_rows: &[io::ResidualRow<'_>],
) -> Result<Calibration, Error> {
    let dir = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| Error::Io {
        path: dir.clone(),
        source: e,
    })?;
    let cal_path = dir.join(CALIBRATION_FILE);
    ingest::remove_stale(&cal_path)?;
    io::write_residuals(&dir, residual_rows)?;
    let folders = Folders {
        dataset: &ds.dir,
        out,
    };
    let mut inputs = vec![folders.record(Root::Dataset, ingest_ledger::MANIFEST_FILE)?];
    for file in [
        format!(
            "{}/{}",
            ingest_ledger::STAGE_DIR,
            ingest_ledger::LEDGER_FILE
        ),
        format!("{}/{}", align_ledger::STAGE_DIR, align_ledger::LEDGER_FILE),
        format!(
            "{}/{}",
            align_ledger::STAGE_DIR,
            ingest::contract::tables::observations::FILE
        ),
    ] {
        inputs.push(folders.record(Root::Out, &file)?);
    }
    let mut outputs = vec![folders.record(
        Root::Out,
        &format!("{STAGE_DIR}/{}", ingest::contract::tables::residuals::FILE),
    )?];
    for t in &calibration.triad {
        let Some(file) = &t.calib_file else {
            continue;
        };
        let path = dir.join(file);
        let tmp = dir.join(format!(".{file}.partial"));
        std::fs::write(&tmp, triad_fits::calib_text(t))
            .and_then(|()| std::fs::rename(&tmp, &path))
            .map_err(|e| Error::Io {
                path: path.clone(),
                source: e,
            })?;
        outputs.push(folders.record(Root::Out, &format!("{STAGE_DIR}/{file}"))?);
    }
    calibration.custody = Custody { inputs, outputs };
    ingest::write_json_atomically(&cal_path, &calibration)?;
    Ok(calibration)
}

/// Runs the stage: reads OUT/ingest and OUT/align, writes OUT/adjust.
pub fn run(dataset: &Path, out: &Path) -> Result<Calibration, Error> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::lock::OutputLock::acquire(out)?;
    let ingest_report = IngestReport::load_verified(&ds, out)?;
    let align_report = AlignReport::load_verified(&ds, out)?;
    let rows = io::read_observations(&out.join(align_ledger::STAGE_DIR))?;
    let g = ds.manifest.site.gravity_mgal();
    let used: Vec<&io::ObservationRow> = rows
        .iter()
        .filter(|o| {
            o.excluded.is_none()
                && o.ng.is_some()
                && o.sigma_ng.is_some()
                && o.temperature_c.is_some()
        })
        .collect();
    let models = models(
        &ds.manifest.adjust.model,
        &session_mean_temperatures(&ds, &used),
    );
    let (jobs, mut skipped) = plan_jobs(&ds, &models, &used, &align_report);
    let outcomes: Vec<_> = jobs.par_iter().map(|job| fit_job(job, g)).collect();
    let mut results = Vec::new();
    let mut residual_rows = Vec::new();
    for (job, outcome) in jobs.iter().zip(&outcomes) {
        match outcome {
            Ok((r, f)) => {
                results.push(r.clone());
                residual_rows.extend(residual_rows_of(job, f));
            }
            Err(e) => skipped.push(Skipped {
                accelerometer: job.accelerometer.clone(),
                session: job.session.clone(),
                model: job.model.name.clone(),
                reason: if job.obs.is_empty() {
                    "no usable observations".to_owned()
                } else {
                    skip_reason(&ds, job, e)
                },
            }),
        }
    }
    let adc_noise = kalibr_noise(&align_report, &results);
    let (triad, triad_skipped) = triad_fits::fit_all(&ds, &models, &align_report);
    skipped.extend(triad_skipped);
    let calibration = Calibration {
        format: CALIBRATION_FORMAT.to_owned(),
        dataset: ds.manifest.name.clone(),
        software: format!("gravcal {}", env!("CARGO_PKG_VERSION")),
        inputs: ingest_report
            .files
            .iter()
            .map(|f| Input {
                path: f.path.clone(),
                sha256: f.sha256.clone(),
            })
            .collect(),
        gravity_mgal: g,
        reading_unit: ds.manifest.instrument.reading_unit.name().to_owned(),
        accelerometers: ds.manifest.instrument.accelerometer.clone(),
        results,
        skipped,
        triad,
        custody: Custody::default(),
        adc_noise,
        earth_tide: earth_tide_note(&used),
    };
    write_outputs(&ds, out, calibration, &residual_rows)
}

/// A few lines per fit: b, k and sigma0; and every skipped fit with its reason.
pub fn print_summary(c: &Calibration, w: &mut impl std::io::Write) {
    if c.results.is_empty() && c.skipped.is_empty() && c.triad.is_empty() {
        let _ = writeln!(
            w,
            "adjust: no observation to calibrate with (a dataset of survey sessions only: \
             `cargo xtask apply` calibrates them)"
        );
    }
    for t in &c.triad {
        let removed = t.positions.iter().filter(|p| p.removed).count();
        let p: Vec<String> = t
            .parameters
            .iter()
            .map(|p| format!("{} = {:.6e} +/- {:.1e}", p.name, p.value, p.sigma))
            .collect();
        let _ = writeln!(
            w,
            "adjust: triad {} {}: {}; sigma0 {:.3}, {} positions, {removed} removed{}, global test {}; {}",
            t.model,
            t.session,
            p.join(", "),
            t.sigma0,
            t.positions_used,
            match t.positions_without_temperature {
                0 => String::new(),
                n => format!(", {n} without temperature left out"),
            },
            if t.global_test.passed {
                "passed"
            } else {
                "failed"
            },
            t.calib_file.as_ref().map_or_else(
                || "no imu_tk file (its layout has no higher orders or temperature terms)"
                    .to_owned(),
                |f| format!("wrote {f}")
            )
        );
        if let Some(advice) = t
            .global_test
            .advice(&format!("triad {} {}", t.model, t.session), true)
        {
            let _ = writeln!(w, "adjust: {advice}");
        }
    }
    for r in &c.results {
        let p: Vec<String> = r
            .parameters
            .iter()
            .map(|p| format!("{} = {:.6e} +/- {:.2e}", p.name, p.value, p.sigma))
            .collect();
        let _ = writeln!(
            w,
            "adjust: {} {} {}: {}; sigma0 {:.3}, {} obs, {} removed, global test {}",
            r.model,
            r.accelerometer,
            r.session,
            p.join(", "),
            r.sigma0,
            r.n_observations,
            r.n_excluded,
            if r.global_test.passed {
                "passed"
            } else {
                "FAILED"
            }
        );
        if let Some(advice) = r.global_test.advice(
            &format!("{} {} {}", r.model, r.accelerometer, r.session),
            false,
        ) {
            let _ = writeln!(w, "adjust: {advice}");
        }
    }
    for s in &c.skipped {
        let _ = writeln!(
            w,
            "adjust: {} {} {}: skipped: {}",
            s.model, s.accelerometer, s.session, s.reason
        );
    }
}

/// Arguments of the `fit` command (docs/formats.md section 7), shared by the stage binary and
/// `cargo xtask fit`.
#[derive(Clone, Debug, clap::Args)]
pub struct FitArgs {
    /// CSV table with a header line.
    #[arg(long)]
    pub input: PathBuf,
    /// Column of x.
    #[arg(long)]
    pub x: String,
    /// Column of y.
    #[arg(long)]
    pub y: String,
    /// Column of the sd of x (errors in both variables).
    #[arg(long)]
    pub sigma_x: Option<String>,
    /// Column of the sd of y (default: unit weights).
    #[arg(long)]
    pub sigma_y: Option<String>,
    /// Polynomial degree, 0..=10.
    #[arg(long, default_value_t = 1)]
    pub degree: usize,
}

/// Fits a polynomial to the columns of a CSV table (docs/formats.md section 7).
pub fn fit_csv(args: &FitArgs) -> Result<fit::FitOutput, Error> {
    let (path, x, y, degree) = (
        args.input.as_path(),
        args.x.as_str(),
        args.y.as_str(),
        args.degree,
    );
    let (sigma_x, sigma_y) = (args.sigma_x.as_deref(), args.sigma_y.as_deref());
    if path.is_dir() {
        return Err(Error::Fit(format!(
            "{}: is a folder, not a CSV file",
            path.display()
        )));
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    // A byte-order mark (spreadsheets write one) is not part of the first column's name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let (_, header) = lines
        .next()
        .ok_or_else(|| Error::Fit(format!("{}: no header line", path.display())))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let index = |name: &str| {
        names.iter().position(|n| *n == name).ok_or_else(|| {
            Error::Fit(format!(
                "{}: no column `{name}` (columns: {})",
                path.display(),
                names.join(", ")
            ))
        })
    };
    let cols: Vec<Option<usize>> = vec![
        Some(index(x)?),
        Some(index(y)?),
        sigma_x.map(index).transpose()?,
        sigma_y.map(index).transpose()?,
    ];
    let mut data: [Vec<f64>; 4] = Default::default();
    // The file's line of each data row, for messages about a row.
    let mut line_of_row = Vec::new();
    for (n, line) in lines {
        line_of_row.push(n + 1);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        for (k, c) in cols.iter().enumerate() {
            if let Some(c) = c {
                let v = fields
                    .get(*c)
                    .and_then(|f| f.parse::<f64>().ok())
                    .ok_or_else(|| {
                        Error::Fit(format!(
                            "{}:{}: {}: not a number",
                            path.display(),
                            n + 1,
                            names[*c]
                        ))
                    })?;
                data[k].push(v);
            }
        }
    }
    let [xs, ys, sx, sy] = data;
    fit::fit(
        &xs,
        &ys,
        sigma_x.map(|_| sx.as_slice()),
        sigma_y.map(|_| sy.as_slice()),
        degree,
    )
    .map_err(|e| match e {
        fit::FitError::BadValue { row, message } => Error::Fit(format!(
            "{}:{}: {message}",
            path.display(),
            line_of_row.get(row - 1).copied().unwrap_or(row)
        )),
        e => Error::Fit(format!("{}: {e}", path.display())),
    })
}
