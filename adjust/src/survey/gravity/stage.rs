//! The gravity stage's run, `cargo xtask gravity` (docs/formats.md 10.3): the calibration
//! applied to the survey (apply's stage, which ingests first if needed), each survey
//! session's trajectory read, the calibrated samples brought onto its epochs
//! ([`super::epochs`]), the track cut at gaps into stretches, each stretch reduced
//! ([`super::reduce`]) and tied, and `OUT/gravity/gravity.parquet` and `gravity.json`
//! written. Every epoch of every trajectory is accounted for: written, or dropped by reason.

use super::GravityError;
use super::attitude::{self, AttitudeAt, AttitudeCursor};
use super::coupling;
use super::crossover;
use super::epochs::{self, BinsAt, DownForce, SpilledBins, Target};
use super::errors::{self, AttitudeErrors};
use super::horizontal::{self, Horizontal, ReducedHorizontal};
use super::magnitude;
use super::normal::MAX_DISTURBANCE_MGAL;
use super::reduce::{self, CalibrationGradient, Reduced, Stretch, Tie};
use super::spectrum::{self, Floor};
use super::track::{Track, read_tracks};
use crate::survey::apply::triad_stream::TriadFunction;
use ingest::base::time::utc_iso;
use ingest::contract::apply_ledger::{self, ApplyReport};
use ingest::contract::gravity_ledger::{
    CouplingUsed, Crossover, DriftFitted, ErrorModelsUsed, FilterUsed, GravityReport, Input,
    LEDGER_FILE, LEDGER_FORMAT, MeterStatus, NotReduced, Quantities, STAGE_DIR, SessionGravity,
    StretchSummary, TieUsed, dropped,
};
use ingest::contract::manifest::Dataset;
use ingest::contract::survey::{
    ArrayDown, ErrorModel, FilterKind, ResolvedTie, SurveyConfig, TieLevel,
};
use ingest::contract::tables::{applied, gravity};
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

/// The gravity stage's options: apply's, and for an axis model the accelerometer to use.
#[derive(Clone, Debug)]
pub struct Options<'a> {
    /// What to apply.
    pub apply: crate::survey::apply::stream::Options<'a>,
    /// With an axis model: the accelerometer taken as the vertical axis.
    pub accelerometer: Option<&'a str>,
    /// Set aside a trajectory's or attitude's line that breaks the format (counted and
    /// listed) instead of failing on it.
    pub skip_bad_lines: bool,
    /// Epochs reduced at a time ([`blocks`]); None: [`BLOCK_EPOCHS`], or four margins
    /// where the filter reaches farther.
    pub block_epochs: Option<usize>,
}

/// Epochs a stretch is reduced in at a time by default, each with a margin of twelve filter
/// periods either side ([`margin`]): memory holds two blocks (reduced at once, one on each
/// core, [`reduce_stretch`]), not the survey.
pub const BLOCK_EPOCHS: usize = 1 << 16;

/// Runs the stage on `dataset` into `out`.
pub fn run(dataset: &Path, out: &Path, opts: &Options<'_>) -> Result<GravityReport, GravityError> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::base::lock::OutputLock::acquire(out)?;
    let survey = ds.manifest.survey.clone().unwrap_or_default();
    let table = out.join(apply_ledger::STAGE_DIR).join(applied::FILE);
    let dir = out.join(STAGE_DIR);
    std::fs::create_dir_all(&dir).map_err(|e| ingest::Error::io(dir.clone(), e))?;
    let (applied, tracks) = applied_and_tracks(&ds, dataset, out, &dir, &survey, opts)?;
    let force = down_force(&applied, &survey, opts.accelerometer)?;
    let triad = triad_function(&applied, opts.apply.calibration)?;
    refuse_attitude_with_an_axis(&force, &tracks)?;
    // The inputs' SHA-256 on the second core while the first reduces (a twentieth of a day
    // at 1 Hz's reduction when it came after).
    std::thread::scope(|scope| {
        let hashing = scope.spawn(|| inputs(&table, &tracks));
        let reduced = reduce_and_write(&Reading {
            ds: &ds,
            survey: &survey,
            tracks: &tracks,
            table: &table,
            force: &force,
            triad: triad.as_ref(),
            dir: &dir,
            opts,
        });
        let inputs = hashing
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        let r = reduced?;
        // Written once the reduction holds, beside the gravity.parquet it went into.
        let attitude_table = attitude_table(&ds, &tracks, &dir)?;
        let report = GravityReport {
            format: LEDGER_FORMAT.to_owned(),
            dataset: ds.manifest.name.clone(),
            calibration: applied.calibration.clone(),
            specific_force: describe(&force, &survey, &tracks),
            inputs: inputs?,
            lever_arm_m: survey.lever_arm_m,
            mounting_deg: survey.mounting_deg,
            error_models: ErrorModelsUsed {
                attitude: survey.attitude_error_model(),
                positions: survey.position_error_model(),
            },
            normal_gravity: survey.normal_gravity,
            geoid_height_m: survey.geoid_height_m,
            earth_tide: survey.earth_tide,
            not_reduced: not_reduced(&ds),
            filter: r.filter,
            sessions: r.sessions,
            ties: r.ties,
            crossovers: r.crossovers,
            rows_written: r.rows_written,
            sha256: r.sha256,
            attitude_table,
        };
        ingest::write_json_atomically(&dir.join(LEDGER_FILE), &report)?;
        Ok(report)
    })
}

/// Apply run on `dataset` into `out`, and the survey's tracks read (their kept epochs into
/// `dir`), with the meters' own records. Apply, then the meters' records, run on the second
/// core while the first reads the trajectories: none reads what another writes (the lock is
/// re-entrant, and held by [`run`] across them). Apply's error is the one told when several
/// fail, as when it came first.
fn applied_and_tracks<'a>(
    ds: &'a Dataset,
    dataset: &Path,
    out: &Path,
    dir: &Path,
    survey: &SurveyConfig,
    opts: &Options<'_>,
) -> Result<(ApplyReport, Vec<Track<'a>>), GravityError> {
    let (applied, tracks) = std::thread::scope(|scope| {
        let applying = scope.spawn(|| {
            let applied = crate::survey::apply::stream::run(dataset, out, &opts.apply)?;
            Ok::<_, GravityError>((applied, super::track::read_meters(ds)?))
        });
        let tracks = read_tracks(ds, survey, opts.skip_bad_lines, dir);
        let applied = applying
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (applied, tracks)
    });
    let (applied, meters) = applied?;
    let mut tracks = tracks?;
    // A meter's record read with its trajectory (track::meter_in_trajectory) is None here.
    for (track, meter) in tracks.iter_mut().zip(meters) {
        if meter.is_some() {
            track.meter = meter;
        }
    }
    Ok((applied, tracks))
}

/// attitude.parquet written in `dir` from the array sessions' fits (its rows and SHA-256),
/// or, without one, a stale one from an earlier run removed.
fn attitude_table(
    ds: &Dataset,
    tracks: &[Track<'_>],
    dir: &Path,
) -> Result<Option<(u64, String)>, GravityError> {
    let tables: Vec<(u16, &[ingest::contract::tables::attitude::Row])> = tracks
        .iter()
        .filter_map(|t| t.array.as_ref().map(|(_, rows)| (t.index, &rows[..])))
        .collect();
    if tables.is_empty() {
        ingest::remove_stale(&dir.join(ingest::contract::tables::attitude::FILE))?;
        return Ok(None);
    }
    let names: Vec<String> = ds.sessions.iter().map(|s| s.session.id.clone()).collect();
    Ok(Some(ingest::contract::tables::attitude::write(
        dir, &names, &tables,
    )?))
}

/// What the reduction reads and where it writes.
struct Reading<'a> {
    ds: &'a Dataset,
    survey: &'a SurveyConfig,
    tracks: &'a [Track<'a>],
    /// Apply's table of calibrated samples.
    table: &'a Path,
    /// How the down component is read from it.
    force: &'a DownForce,
    triad: Option<&'a TriadFunction>,
    /// The stage's folder.
    dir: &'a Path,
    opts: &'a Options<'a>,
}

/// The reduction of every track, its rows written.
fn reduce_and_write(r: &Reading<'_>) -> Result<Reduction, GravityError> {
    let Reading {
        ds,
        survey,
        tracks,
        table,
        force,
        triad,
        dir,
        opts,
    } = *r;
    let mut targets: Vec<Target<'_>> = tracks
        .iter()
        .map(|t| {
            let attitude = t.attitude.as_ref().map(AttitudeCursor::new);
            let times = (&t.times[..], t.interval_ns);
            Target::new(t.index, times, attitude.map(|a| (a, mounting(survey))))
        })
        .collect();
    let interval_ns = (1e9 / ds.manifest.instrument.sample_rate_hz).round() as i64;
    let filled = epochs::fill(table, force, &mut targets, interval_ns, dir)?;
    ingest::remove_stale(&dir.join(LEDGER_FILE))?;
    let names: Vec<String> = ds.sessions.iter().map(|s| s.session.id.clone()).collect();
    let with_horizontal = tracks.iter().any(|t| t.attitude.is_some());
    let noise = tracks
        .iter()
        .zip(&filled.floors)
        .map(|(t, f)| sample_noise(f, survey.sample_noise_mgal, &t.session.session.id))
        .collect::<Result<Vec<_>, _>>()?;
    let mut rows = Rows::create(dir, &names, with_horizontal)?;
    let ctx = |k: usize| Context {
        survey,
        ties: &ds.ties,
        samples_per_s: ds.manifest.instrument.sample_rate_hz,
        sample_noise: &noise[k],
        triad,
        mounting: mounting(survey),
        block_epochs: opts.block_epochs,
        coupling: None,
    };
    let (sessions, ties) = reduce_tracks(ds, tracks, &filled, ctx, &mut rows)?;
    let filter = filter_used(&rows.speeds, (survey.filter, survey.filter_s));
    let crossovers = rows.crossovers(&names, tracks, &sessions, survey.filter_s);
    let (rows_written, sha256) = rows.finish()?;
    Ok(Reduction {
        filter,
        sessions,
        ties,
        crossovers,
        rows_written,
        sha256,
    })
}

/// What the reduction of every track gives the report.
struct Reduction {
    filter: FilterUsed,
    sessions: Vec<SessionGravity>,
    ties: Vec<TieUsed>,
    crossovers: Vec<Crossover>,
    rows_written: u64,
    sha256: String,
}

/// An attitude turns a triad's vector; an axis model has none to turn.
fn refuse_attitude_with_an_axis(
    force: &DownForce,
    tracks: &[Track<'_>],
) -> Result<(), GravityError> {
    match (force, tracks.iter().find(|t| t.attitude.is_some())) {
        (DownForce::Axis { .. }, Some(t)) => Err(GravityError::Refused {
            message: format!(
                "session {} gives an attitude, which turns a triad's vector into north, east \
                 and down: an axis model gives one axis; apply a triad model, or remove the \
                 session's `attitude`",
                t.session.session.id
            ),
        }),
        _ => Ok(()),
    }
}

/// Every track reduced (`ctx(k)` the k-th's context), gravity.parquet's rows written into
/// `rows`: each session's summary, the ties marked with the stretch that used them. A
/// session none of whose epochs could be reduced is an error naming it and why.
fn reduce_tracks<'a>(
    ds: &Dataset,
    tracks: &[Track<'_>],
    filled: &epochs::Filled,
    ctx: impl Fn(usize) -> Context<'a>,
    rows: &mut Rows,
) -> Result<(Vec<SessionGravity>, Vec<TieUsed>), GravityError> {
    let mut sessions = Vec::new();
    let mut ties: Vec<TieUsed> = ds.ties.iter().map(tie_entry).collect();
    for (k, (track, bins)) in tracks.iter().zip(&filled.bins).enumerate() {
        let summary = reduce_track(track, bins, &ctx(k), rows, &mut ties)?;
        if summary.epochs_read == 0 {
            let path = track.session.trajectory.as_ref().map(|t| t.path.display());
            return Err(GravityError::Refused {
                message: format!(
                    "session {}: its trajectory {} holds no epoch (comments, a header or \
                     blank lines only)",
                    summary.id,
                    path.map_or_else(String::new, |p| p.to_string())
                ),
            });
        }
        if summary.epochs_used == 0 {
            let why: Vec<String> = summary
                .dropped
                .iter()
                .map(|(k, n)| format!("{n} {k}"))
                .collect();
            return Err(GravityError::Refused {
                message: format!(
                    "session {}: none of its {} trajectory epochs could be reduced ({})",
                    summary.id,
                    summary.epochs_read,
                    why.join(", ")
                ),
            });
        }
        sessions.push(summary);
    }
    Ok((sessions, ties))
}

/// The dataset's survey sessions without a trajectory: applied by apply, not reduced here.
fn not_reduced(ds: &Dataset) -> Vec<NotReduced> {
    ds.sessions
        .iter()
        .filter(|s| s.is_survey() && s.trajectory.is_none())
        .map(|s| NotReduced {
            session: s.session.id.clone(),
            why: "no `trajectory` in the manifest (docs/formats.md 10.1): its samples are \
                  calibrated by apply, but there is no track to reduce them along"
                .to_owned(),
        })
        .collect()
}

/// The files read, with their hashes: apply's table, each trajectory and attitude.
fn inputs(table: &Path, tracks: &[Track<'_>]) -> Result<Vec<Input>, GravityError> {
    let mut inputs = vec![Input {
        role: "calibrated samples".to_owned(),
        path: table.display().to_string(),
        sha256: ingest::contract::custody::sha256_file(table)?,
    }];
    for t in tracks {
        let Some(src) = &t.session.trajectory else {
            continue;
        };
        let attitude = src
            .attitude
            .as_ref()
            .map(|(p, _)| ("attitude".to_owned(), p));
        let files: Vec<(String, &std::path::PathBuf)> = match src.antennas.is_empty() {
            true => std::iter::once(("trajectory".to_owned(), &src.path))
                .chain(attitude)
                .collect(),
            false => (src.antennas.iter())
                .map(|a| (format!("antenna {}", a.id), &a.path))
                .collect(),
        };
        for (role, path) in files {
            inputs.push(Input {
                role: format!("{role} of {}", t.session.session.id),
                path: path.display().to_string(),
                sha256: ingest::contract::custody::sha256_file(path)?,
            });
        }
    }
    Ok(inputs)
}

/// How f_D is read from apply's table: a triad's vector through the mounting, or the one
/// axis asked for (or the only one) taken as vertical, which a tilted mounting forbids.
fn down_force(
    applied: &ApplyReport,
    survey: &SurveyConfig,
    accelerometer: Option<&str>,
) -> Result<DownForce, GravityError> {
    let refused = |message: String| GravityError::Refused { message };
    let ids: Vec<&str> = applied
        .accelerometers
        .iter()
        .filter(|a| a.not_calibrated.is_none())
        .map(|a| a.id.as_str())
        .collect();
    if applied.quantity == crate::survey::apply::stream::TRIAD_QUANTITY {
        if accelerometer.is_some() {
            return Err(refused(
                "--accelerometer chooses one axis of an axis model; a triad model gives the \
                 whole vector"
                    .to_owned(),
            ));
        }
        return Ok(DownForce::Triad {
            row: epochs::mounting_down_row(survey.mounting_deg),
        });
    }
    let [roll, pitch, _] = survey.mounting_deg;
    if roll.abs() > 1e-9 || pitch.abs() > 1e-9 {
        return Err(refused(format!(
            "an axis model gives one axis, taken as vertical: survey.mounting_deg rolls or \
             pitches it ({roll}, {pitch}); a tilted mounting needs a triad model"
        )));
    }
    let id = match (accelerometer, ids.as_slice()) {
        (Some(a), _) if ids.contains(&a) => a,
        (Some(a), _) => {
            return Err(refused(format!(
                "--accelerometer {a}: the calibration applied has {} calibrated",
                ids.join(", ")
            )));
        }
        (None, [one]) => one,
        (None, _) => {
            return Err(refused(format!(
                "the axis model calibrates {}: name the vertical one with --accelerometer",
                ids.join(", ")
            )));
        }
    };
    Ok(DownForce::Axis { id: id.to_owned() })
}

/// The triad function of the calibration applied, when it has no temperature terms (the
/// stage then carries the calibration's error left after a tie from the parameters).
fn triad_function(
    applied: &ApplyReport,
    calibration: &Path,
) -> Result<Option<TriadFunction>, GravityError> {
    if applied.quantity != crate::survey::apply::stream::TRIAD_QUANTITY {
        return Ok(None);
    }
    let cal: ingest::contract::calibration::Calibration = ingest::read_json(calibration)?;
    let used = &applied.calibration;
    let Some(r) = cal
        .triad
        .iter()
        .find(|t| t.model == used.model && t.session == used.session)
    else {
        return Ok(None);
    };
    let f = TriadFunction::new(r).map_err(|message| GravityError::Refused { message })?;
    Ok((!f.needs_temperature()).then_some(f))
}

/// The gradient by the calibration's parameters of its error at the drift's reference: the
/// first tie inside the stretch `of` with a window of two epochs or
/// more, its window's mean vector read back into readings, along the window's mean down row
/// (the mounting's, or C_b^n's with attitude). None without such a tie or where the vector
/// cannot be read back.
fn tie_gradient(
    f: &TriadFunction,
    of: &StretchOf<'_>,
    ctx: &Context<'_>,
) -> Result<Option<Vec<f64>>, GravityError> {
    let StretchOf {
        track, bins, span, ..
    } = of;
    let window = of.inside.iter().find_map(|(_, tie)| {
        let w = of.window(tie);
        (w.len() >= 2).then_some(span.start + w.start..span.start + w.end)
    });
    let Some(window) = window else {
        return Ok(None);
    };
    let at = block(track, bins, window.clone())?;
    let (mut reference, mut row_ref) = ([0.0; 3], [0.0; 3]);
    for k in window.clone() {
        let v = at.bins.at(k).mean_vector();
        let m = down_row(&at, k, ctx);
        for i in 0..3 {
            reference[i] += v[i] / window.len() as f64;
            row_ref[i] += m[i] / window.len() as f64;
        }
    }
    Ok(f.readings_for(reference).map(|x| f.gradient(x, row_ref)))
}

/// A block's epochs read back: their sums, positions and attitude.
struct Block<'a> {
    bins: BinsAt<'a>,
    positions: super::track::Positions,
    attitude: Option<Vec<AttitudeAt>>,
}

impl Block<'_> {
    /// The attitude at kept epoch `k` (None without attitude).
    fn attitude(&self, k: usize) -> Option<AttitudeAt> {
        Some(self.attitude.as_ref()?[k - self.bins.start])
    }
}

/// The epochs `range` of `track` read back.
fn block<'a>(
    track: &Track<'_>,
    bins: &'a SpilledBins,
    range: Range<usize>,
) -> Result<Block<'a>, GravityError> {
    Ok(Block {
        bins: bins.read(range.clone()).map_err(|e| spill_error(bins, e))?,
        positions: track.positions(range.clone())?,
        attitude: track.attitude_at(range)?,
    })
}

/// The epochs' sums, written aside, could not be read back.
fn spill_error(bins: &SpilledBins, e: std::io::Error) -> GravityError {
    GravityError::Refused {
        message: format!(
            "the epochs' sums written aside ({} epochs) could not be read back: {e}",
            bins.len()
        ),
    }
}

/// The down row at kept epoch `k`: C_b^n's with attitude, the mounting's without.
fn down_row(b: &Block<'_>, k: usize, ctx: &Context<'_>) -> [f64; 3] {
    body_to_nav(b, k, &ctx.mounting).map_or(ctx.mounting[2], |c| c[2])
}

/// The calibration's error at each epoch of `range` less its error at the drift's
/// reference (`at_tie`, [`tie_gradient`]), as gradients by the parameters: each epoch's mean
/// vector read back into readings, along its down row. None where a vector cannot be read
/// back.
fn calibration_gradient(
    f: &TriadFunction,
    b: &Block<'_>,
    range: Range<usize>,
    ctx: &Context<'_>,
    at_tie: &[f64],
) -> Option<CalibrationGradient> {
    let mut gradient = vec![Vec::with_capacity(range.len()); at_tie.len()];
    for k in range {
        let g = f.gradient(
            f.readings_for(b.bins.at(k).mean_vector())?,
            down_row(b, k, ctx),
        );
        for ((series, g), g0) in gradient.iter_mut().zip(g).zip(at_tie) {
            series.push(g - g0);
        }
    }
    Some(CalibrationGradient {
        gradient,
        covariance: f.covariance().to_vec(),
    })
}

/// A stretch's filtered values and sigmas are numbers: one that is not (inputs at the edge
/// of the arithmetic: a pole, a calibration extrapolated beyond its range) stops the run
/// naming the epoch, rather than a NaN written as a result.
fn numbers_only(s: &Stretch, r: &Reduced) -> Result<(), GravityError> {
    let bad = (0..s.time_gps_ns.len())
        .find(|&k| !(r.filtered_mgal[k].is_finite() && r.sigma_mgal[k].is_finite()));
    match bad {
        None => Ok(()),
        Some(k) => Err(GravityError::Refused {
            message: format!(
                "at {} (latitude {} deg, specific force down {} mGal) the reduction gives \
                 {} +/- {} mGal, not a number",
                utc_iso(s.time_gps_ns[k]),
                s.latitude_deg[k],
                s.f_down_mgal[k],
                r.filtered_mgal[k],
                r.sigma_mgal[k]
            ),
        }),
    }
}

/// A tie's level (the offset between the calibrated specific force and the ties) beyond
/// this is not a calibration's error but a setup's, mGal.
pub const OFFSET_BOUND_MGAL: f64 = 1000.0;
/// A drift between ties beyond this is not an accelerometer's, mGal/h (a triad without
/// temperature terms warming by 3 degC an hour drifts by 440 mGal/h).
pub const DRIFT_BOUND_MGAL_PER_H: f64 = 2000.0;

/// The results checked where they are formed (docs/formats.md 10): a tied level, a drift
/// or a filtered disturbance down beyond its bound is refused, naming the stretch and what
/// would make it so, rather than written with a sigma that cannot say so.
fn plausible(
    s: &Stretch,
    r: &Reduced,
    flags: &[u8],
    drift: Option<&reduce::Drift>,
    id: &str,
    number: u32,
) -> Result<(), GravityError> {
    let causes = "a mounting_deg, lever arm or attitude that is not the instrument's, a \
                  calibration of other accelerometers, or a tie's g_mgal mistyped";
    let refuse = |what: String| {
        Err(GravityError::Refused {
            message: format!("session {id}, stretch {number}: {what}; likely {causes}"),
        })
    };
    if let Some(d) = drift {
        if d.offset_mgal.abs() > OFFSET_BOUND_MGAL {
            return refuse(format!(
                "the ties' level is {:.3} mGal, beyond +/-{OFFSET_BOUND_MGAL} mGal",
                d.offset_mgal
            ));
        }
        if d.rate_mgal_per_h.abs() > DRIFT_BOUND_MGAL_PER_H {
            return refuse(format!(
                "the drift between the ties is {:.3} mGal/h, beyond +/-{DRIFT_BOUND_MGAL_PER_H} \
                 mGal/h",
                d.rate_mgal_per_h
            ));
        }
    }
    let worst = (0..s.time_gps_ns.len())
        .filter(|&k| flags[k] & gravity::EDGE == 0)
        .max_by(|&a, &b| {
            r.filtered_mgal[a]
                .abs()
                .total_cmp(&r.filtered_mgal[b].abs())
        });
    match worst {
        Some(k) if r.filtered_mgal[k].abs() > MAX_DISTURBANCE_MGAL => refuse(format!(
            "at {} the filtered disturbance down is {:.3} mGal, beyond \
             +/-{MAX_DISTURBANCE_MGAL} mGal",
            utc_iso(s.time_gps_ns[k]),
            r.filtered_mgal[k]
        )),
        _ => Ok(()),
    }
}

/// For gravity.json: how f_D was formed.
fn describe(force: &DownForce, survey: &SurveyConfig, tracks: &[Track<'_>]) -> String {
    let text = describe_turned(force, survey, tracks);
    let magnitude: Vec<&str> = tracks
        .iter()
        .filter(|t| t.array.is_some() && t.attitude.is_some())
        .map(|t| t.session.session.id.as_str())
        .collect();
    match survey.array_down {
        ArrayDown::Magnitude if !magnitude.is_empty() => format!(
            "{text}; down of the antenna arrays' sessions ({}) from the force's magnitude, \
             f_D = -sqrt(|f|^2 - |h|^2), h the track's horizontal force ([survey] array_down)",
            magnitude.join(", ")
        ),
        _ => text,
    }
}

/// [`describe`] of the force as it is turned, or taken levelled.
fn describe_turned(force: &DownForce, survey: &SurveyConfig, tracks: &[Track<'_>]) -> String {
    let with: Vec<&str> = tracks
        .iter()
        .filter(|t| t.attitude.is_some())
        .map(|t| t.session.session.id.as_str())
        .collect();
    let levelled = tracks.len() - with.len();
    match force {
        DownForce::Triad { row } if with.is_empty() || levelled > 0 => format!(
            "triad vector through the mounting (roll, pitch, yaw {:?} deg): f_D = \
             {:.6} f_x + {:.6} f_y + {:.6} f_z, the platform levelled{}",
            survey.mounting_deg,
            row[0],
            row[1],
            row[2],
            if with.is_empty() {
                String::new()
            } else {
                format!(
                    "; with attitude ({}): f^n = C_v^n C_b^v f^b, north, east and down",
                    with.join(", ")
                )
            }
        ),
        DownForce::Triad { .. } => format!(
            "triad vector through the mounting (roll, pitch, yaw {:?} deg) and the attitude: \
             f^n = C_v^n C_b^v f^b, north, east and down",
            survey.mounting_deg
        ),
        DownForce::Axis { id } => format!("{id} taken as the vertical axis pointing up: f_D = F"),
    }
}

/// The white noise of one sample of f_D the sigmas carry, and where it comes from.
struct SampleNoise {
    sd_mgal: f64,
    from: String,
}

/// A session's sample noise: `[survey] sample_noise_mgal` where declared, else the record's
/// spectral floor; a record without a floor and no noise declared is refused (its noise
/// cannot be measured from it, and any number the stage chose would be a guess).
fn sample_noise(
    floor: &Floor,
    declared: Option<f64>,
    session: &str,
) -> Result<SampleNoise, GravityError> {
    let bands = |band_sd: &[f64], segments: usize| {
        let b: Vec<String> = band_sd.iter().map(|v| format!("{v:.3}")).collect();
        format!(
            "its spectrum from an eighth to 0.4 of the sampling rate, in {} bands, is {} mGal \
             per sample (over {segments} segments of {} samples), with no two bands alike",
            band_sd.len(),
            b.join(", "),
            spectrum::SEGMENT
        )
    };
    let measured = match floor {
        Floor::Measured(v) => format!("the record's spectral floor, {v:.4} mGal"),
        Floor::ThirdDifferences(v) => format!(
            "the record's third differences, {v:.4} mGal (shorter than {} samples)",
            spectrum::SEGMENT
        ),
        Floor::NotFlat { band_sd, segments } => {
            format!("the record has no floor: {}", bands(band_sd, *segments))
        }
    };
    match (declared, floor) {
        (Some(v), _) => Ok(SampleNoise {
            sd_mgal: v,
            from: format!("declared (survey.sample_noise_mgal); {measured}"),
        }),
        (None, Floor::Measured(v) | Floor::ThirdDifferences(v)) => Ok(SampleNoise {
            sd_mgal: *v,
            from: measured,
        }),
        (None, Floor::NotFlat { band_sd, segments }) => Err(GravityError::Refused {
            message: format!(
                "session {session}: the noise of its specific force cannot be measured from \
                 the record: {}. A meter that filters its output before writing it does \
                 this; declare the noise of one sample at the stream's rate as \
                 survey.sample_noise_mgal (the maker's figure, or the sd of a still record's \
                 samples)",
                bands(band_sd, *segments)
            ),
        }),
    }
}

/// What every track's reduction shares.
#[derive(Clone, Copy)]
struct Context<'a> {
    survey: &'a SurveyConfig,
    ties: &'a [ResolvedTie],
    samples_per_s: f64,
    sample_noise: &'a SampleNoise,
    /// A triad model without temperature terms: the calibration's error from the
    /// parameters.
    triad: Option<&'a TriadFunction>,
    /// C_b^v, the mounting.
    mounting: [[f64; 3]; 3],
    /// [`Options::block_epochs`].
    block_epochs: Option<usize>,
    /// The session's cross-coupling correction ([`coupling_of`]).
    coupling: Option<coupling::Correction>,
}

/// C_b^v = Rz(yaw) Ry(pitch) Rx(roll) of `[survey] mounting_deg`.
fn mounting(survey: &SurveyConfig) -> [[f64; 3]; 3] {
    let [roll, pitch, yaw] = survey.mounting_deg.map(f64::to_radians);
    attitude::rotation(yaw, pitch, roll)
}

/// C_b^n at kept epoch `k` of a block with attitude: C_v^n C_b^v.
fn body_to_nav(b: &Block<'_>, k: usize, mounting: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let a = b.attitude(k)?;
    Some(attitude::product(&a.vehicle_to_nav(), mounting))
}

/// One session reduced: its epochs checked, cut into stretches, each reduced and its rows
/// pushed; the session's summary.
fn reduce_track(
    track: &Track<'_>,
    bins: &SpilledBins,
    ctx: &Context<'_>,
    rows: &mut Rows,
    ties: &mut [TieUsed],
) -> Result<SessionGravity, GravityError> {
    let interval = track.interval_ns;
    let expected = ctx.samples_per_s * interval as f64 * 1e-9;
    filter_longer_than_epochs(track, interval, ctx.survey.filter_s)?;
    let mut summary = session_summary(track, ctx);
    let (spans, gaps) = stretches(&track.times, bins, interval, expected, &mut summary.dropped)
        .map_err(|e| spill_error(bins, e))?;
    summary.gaps = gaps;
    let (correction, used) = coupling_of(track, bins, &spans, ctx)?;
    summary.cross_coupling = used;
    let ctx = &Context {
        coupling: correction,
        ..*ctx
    };
    let session = match ctx.survey.tie_level {
        TieLevel::Session => Some(session_ties(track, bins, &spans, ctx)?),
        TieLevel::Stretch => None,
    };
    for span in spans {
        let inside = ties_inside(ctx.ties, &track.times[span.clone()]);
        let number = summary.stretches.len() as u32;
        let of = StretchOf {
            track,
            bins,
            span: span.clone(),
            inside: &inside,
        };
        let Some(drift) = reduce_stretch(of, session.as_ref(), ctx, number, rows, &mut summary)?
        else {
            *summary
                .dropped
                .entry(dropped::STRETCH_TOO_SHORT.to_owned())
                .or_insert(0) += span.len() as u64;
            continue;
        };
        if drift.is_some() {
            for (k, _) in &inside {
                ties[*k].used_in = Some((summary.id.clone(), number));
            }
        }
        let times = &track.times[span];
        summary.stretches.push(StretchSummary {
            first: utc_iso(times[0]),
            last: utc_iso(times[times.len() - 1]),
            epochs: times.len() as u64,
            drift: drift.map(|d| DriftFitted {
                offset_mgal: d.offset_mgal,
                sigma_offset_mgal: d.sigma_offset_mgal,
                rate_mgal_per_h: d.rate_mgal_per_h,
                sigma_rate_mgal_per_h: d.sigma_rate_mgal_per_h,
                ties: d.ties_used,
            }),
        });
    }
    Ok(summary)
}

/// A session's summary before its stretches are reduced: what its track read and dropped,
/// its noise, antennas and meter status as declared.
fn session_summary(track: &Track<'_>, ctx: &Context<'_>) -> SessionGravity {
    SessionGravity {
        id: track.session.session.id.clone(),
        epochs_read: track.epochs_read,
        epochs_used: 0,
        dropped: track.dropped.clone(),
        flagged: BTreeMap::new(),
        gaps: 0,
        bad_lines: track.bad_lines.clone(),
        attitude_dropped: track.attitude_dropped.clone(),
        position_noise_m: track.noise_neu_m,
        position_sd_given_m: track.sd_given_median_m,
        sample_noise_mgal: ctx.sample_noise.sd_mgal,
        sample_noise_from: ctx.sample_noise.from.clone(),
        cross_coupling: None,
        antennas: track.array.as_ref().map(|(used, _)| used.clone()),
        meter_status: track
            .meter
            .as_ref()
            .map(|_| MeterStatus::declared(ctx.survey)),
        quantities: Quantities::new(track.heights, ctx.survey.geoid_height_m),
        stretches: Vec::new(),
    }
}

/// The blocks a stretch of `n` epochs is reduced in: pairs of the epochs reduced and, within
/// them, the epochs kept, consecutive kept ranges covering the stretch. Each block is at
/// most `block` epochs kept and `margin` more reduced either side (within the stretch);
/// one block when the stretch holds no more than `block`.
fn blocks(n: usize, block: usize, margin: usize) -> Vec<(Range<usize>, Range<usize>)> {
    let parts = n.div_ceil(block.max(1)).max(1);
    let size = n.div_ceil(parts);
    (0..parts)
        .map(|i| {
            let keep = i * size..((i + 1) * size).min(n);
            let reduced = keep.start.saturating_sub(margin)..(keep.end + margin).min(n);
            (reduced, keep)
        })
        .collect()
}

/// The epochs either side of a block reduced with it: twelve filter periods, over which the
/// filter's slowest pole (its envelope exp(-0.38 2 pi t / filter_s)) takes what the block's
/// ends are extended by down by 3e-13 (a kilometre's mismatch of an extended track, a
/// tenth of a microGal), and the 5 s over which a speed or a course is taken.
fn margin(filter_s: f64, interval_s: f64) -> usize {
    reduce::reach(2.0 * filter_s, interval_s) + (5.0 / interval_s).ceil() as usize + 2
}

/// One stretch `of` a track (number `number` of its session) reduced a block at a time
/// ([`blocks`]) and its rows pushed into `rows`, the flags counted into `summary`:
/// the drift fitted (Some(None) untied), or None for a stretch too short for the filter.
/// A stretch of more than one block is tied first, each tie's window reduced with the
/// filter's reach either side: every block then removes the same drift, and the blocks,
/// independent, are reduced two at a time on the two cores (a day at 1 Hz: its two blocks
/// at once), their rows pushed in order.
fn reduce_stretch(
    of: StretchOf<'_>,
    session: Option<&SessionTies>,
    ctx: &Context<'_>,
    number: u32,
    rows: &mut Rows,
    summary: &mut SessionGravity,
) -> Result<Option<Option<reduce::Drift>>, GravityError> {
    let (track, span) = (of.track, &of.span);
    let filter_s = ctx.survey.filter_s;
    let interval_s = track.interval_ns as f64 * 1e-9;
    if span.len() as f64 * interval_s < filter_s {
        return Ok(None);
    }
    let margin = margin(filter_s, interval_s);
    let size = match ctx.block_epochs {
        Some(b) => sensible_block(b, filter_s, track)?,
        None => BLOCK_EPOCHS.max(4 * margin),
    };
    let plan = blocks(span.len(), size, margin);
    let (at_tie, level) = match session {
        Some(t) => (t.at_tie.clone(), Some(t.level)),
        None => (
            match ctx.triad {
                Some(f) => tie_gradient(f, &of, ctx)?,
                None => None,
            },
            match plan.len() {
                1 => None,
                _ => Some(reduce::level(&tie_points(&of, ctx, margin)?)),
            },
        ),
    };
    let mut st = Reducing {
        at_tie,
        level,
        ends: (track.times[span.start], track.times[span.end - 1]),
        number,
        of,
    };
    let one = |st: &Reducing<'_>, (reduced, keep): &(Range<usize>, Range<usize>)| {
        let cut = keep.start - reduced.start..keep.end - reduced.start;
        reduce_block(ctx, st, reduced.clone(), cut)
    };
    // With the level fixed before the first block (a stretch of several), its blocks are
    // independent: two at a time, one on each core, and their rows written in order.
    let at_once = if st.level.is_some() { 2 } else { 1 };
    let mut done = Vec::new();
    for pair in plan.chunks(at_once) {
        match pair {
            [a, b] => {
                let (a, b) = rayon::join(|| one(&st, a), || one(&st, b));
                done.extend([a, b]);
            }
            _ => done.extend(pair.iter().map(|block| one(&st, block))),
        }
        // In order, as one after the other: the first block's error or shortness first.
        for reduced in done.drain(..) {
            let Some(rows_of) = reduced? else {
                return Ok(None);
            };
            push_block(rows_of, ctx, &mut st, rows, summary)?;
        }
    }
    Ok(Some(st.level.flatten().map(|l| l.drift)))
}

/// A block's rows counted into `summary` and pushed into `rows`; the first block of a
/// stretch of one fixes its level in `st`.
fn push_block(
    block: BlockRows,
    ctx: &Context<'_>,
    st: &mut Reducing<'_>,
    rows: &mut Rows,
    summary: &mut SessionGravity,
) -> Result<(), GravityError> {
    let track = st.of.track;
    let interval_s = track.interval_ns as f64 * 1e-9;
    st.level.get_or_insert(block.level);
    if let (Some(m), Some(words)) = (&mut summary.meter_status, &block.status) {
        super::meter::count(m, words);
    }
    for (name, n) in count_flags(&block.flags) {
        *summary.flagged.entry(name).or_insert(0) += n;
    }
    summary.epochs_used += block.s.time_gps_ns.len() as u64;
    let at = RowsOf {
        session: track.index,
        stretch: st.number,
        step: crossover::step(ctx.survey.filter_s, interval_s),
    };
    rows.push(at, track.named(ctx.survey), block)
}

/// The filtered values and their sigmas withheld (NaN) at the epochs flagged `edge`: within
/// a filter period of a stretch's ends the value leans on how the series is extended past
/// the end, which nothing in the data fixes (docs/model.md 7, "The ends of a stretch"), so
/// no value is given there rather than one whose sigma cannot say what the extension does.
/// The unfiltered values stay; the ties and crossovers were taken before.
fn withhold_edges(
    mut r: Reduced,
    mut h: Option<ReducedHorizontal>,
    flags: &[u8],
) -> (Reduced, Option<ReducedHorizontal>) {
    for (k, f) in flags.iter().enumerate() {
        if f & gravity::EDGE == 0 {
            continue;
        }
        for v in [
            &mut r.filtered_mgal,
            &mut r.sigma_mgal,
            &mut r.sigma_calibration_mgal,
            &mut r.sigma_positions_mgal,
            &mut r.sigma_noise_mgal,
            &mut r.sigma_tie_mgal,
            &mut r.sigma_attitude_mgal,
            &mut r.sigma_coupling_mgal,
        ] {
            v[k] = f64::NAN;
        }
        if let Some(h) = &mut h {
            for pair in [
                &mut h.filtered_mgal,
                &mut h.sigma_mgal,
                &mut h.sigma_calibration_mgal,
                &mut h.sigma_positions_mgal,
                &mut h.sigma_noise_mgal,
                &mut h.sigma_attitude_mgal,
            ] {
                for v in pair {
                    v[k] = f64::NAN;
                }
            }
        }
    }
    (r, h)
}

/// `--block-epochs` checked against the filter: each block is reduced with twelve filter
/// periods of margin either side, so a block shorter than one filter period costs over 25
/// times its own epochs (a block of one epoch took 446 s where the default took 0.3 s);
/// refused naming the option, the session's interval and the least it takes.
fn sensible_block(block: usize, filter_s: f64, track: &Track<'_>) -> Result<usize, GravityError> {
    let least = (filter_s / (track.interval_ns as f64 * 1e-9)).ceil() as usize;
    if block >= least {
        return Ok(block);
    }
    Err(GravityError::Refused {
        message: format!(
            "--block-epochs {block} is shorter than one filter period of session {}'s epochs \
             ({filter_s} s at an epoch every {} s: {least} epochs): each block is reduced with \
             twelve filter periods of margin either side; give at least {least}",
            track.session.session.id,
            track.interval_ns as f64 * 1e-9
        ),
    })
}

/// Whose rows a block's are: its session's index, its stretch's number, and one in how many
/// of them the crossover search keeps ([`crossover::step`]).
#[derive(Clone, Copy, Debug)]
struct RowsOf {
    session: u16,
    stretch: u32,
    step: usize,
}

/// A block reduced.
struct BlockRows {
    /// The level its ties fix: the stretch's (the block is one of several), or its own (the
    /// stretch's only block).
    level: Option<reduce::Level>,
    /// The stretch's series.
    s: Stretch,
    /// The reduction's.
    r: Reduced,
    /// North and east's, with attitude.
    h: Option<ReducedHorizontal>,
    /// Each epoch's flags.
    flags: Vec<u8>,
    /// Each epoch's meter status word, for a session whose samples are a meter's file.
    status: Option<Vec<Option<u32>>>,
}

/// A stretch of a track: its epochs `span` and the ties `inside` it, with the track and the
/// epochs' sums they are read from.
#[derive(Clone)]
struct StretchOf<'a> {
    track: &'a Track<'a>,
    bins: &'a SpilledBins,
    span: Range<usize>,
    inside: &'a [(usize, Tie)],
}

impl StretchOf<'_> {
    /// The epochs of the stretch within `tie`'s window (its time, half its duration either
    /// side), counted from the stretch's first.
    fn window(&self, tie: &Tie) -> Range<usize> {
        let times = &self.track.times[self.span.clone()];
        let half = (tie.duration_s * 0.5e9) as i64;
        let lo = times.partition_point(|&t| t < tie.time_gps_ns - half);
        let hi = times.partition_point(|&t| t <= tie.time_gps_ns + half);
        lo..hi
    }
}

/// A stretch being reduced: its epochs and ties, its number in its session, the
/// calibration's gradient at its drift's reference, the level its ties fix (None until
/// known), its first and last epochs' times.
struct Reducing<'a> {
    of: StretchOf<'a>,
    number: u32,
    at_tie: Option<Vec<f64>>,
    level: Option<Option<reduce::Level>>,
    ends: (i64, i64),
}

/// The epochs `reduced` (within the stretch) reduced and tied, cut to `cut` (within
/// them): the stretch's series, the reduction's, north and east's with attitude, the
/// flags, the meter's status, and the level it was tied to; None when too short for the
/// filter. The block of a stretch of one block fixes the level from its own reduction.
fn reduce_block(
    ctx: &Context<'_>,
    st: &Reducing<'_>,
    reduced: Range<usize>,
    cut: Range<usize>,
) -> Result<Option<BlockRows>, GravityError> {
    let StretchOf {
        track,
        bins,
        span,
        inside,
    } = &st.of;
    let filter_s = ctx.survey.filter_s;
    let range = span.start + reduced.start..span.start + reduced.end;
    let b = &block(track, bins, range.clone())?;
    let mut s = stretch(track, b, range.clone(), ctx)?;
    s.calibration_tied = ctx
        .triad
        .zip(st.at_tie.as_deref())
        .and_then(|(f, g)| calibration_gradient(f, b, range.clone(), ctx, g));
    let mut r = match reduce::untied(&s, filter_s) {
        Ok(r) => r,
        Err(GravityError::TooShort { .. }) => return Ok(None),
        Err(e) => return Err(e),
    };
    let level = match st.level {
        Some(level) => level,
        None => {
            let mut points = Vec::new();
            for (_, tie) in *inside {
                points.extend(reduce::tie_point(&s, &r, tie, filter_s)?);
            }
            reduce::level(&points)
        }
    };
    reduce::apply_level(&s, &mut r, level.as_ref(), filter_s)?;
    // Its gradients (one series per parameter) served the reduction alone.
    s.calibration_tied = None;
    let mut h = match &b.attitude {
        Some(att) => {
            let inputs = horizontal_inputs(b, att, range.clone(), ctx);
            Some(horizontal::reduce_horizontal(&s, &inputs, filter_s)?)
        }
        None => None,
    };
    let mut flags = flags_of(&s, b, range, st.ends, filter_s, &r, &track.replaced);
    let mut status = meter_status(track, &s.time_gps_ns, ctx.survey, &mut flags);
    s.keep(cut.clone());
    r.keep(cut.clone());
    if let Some(h) = &mut h {
        h.keep(cut.clone());
    }
    if let Some(status) = &mut status {
        reduce::cut(status, cut.clone());
    }
    reduce::cut(&mut flags, cut);
    numbers_only(&s, &r)?;
    plausible(
        &s,
        &r,
        &flags,
        level.as_ref().map(|l| &l.drift),
        &track.session.session.id,
        st.number,
    )?;
    Ok(Some(BlockRows {
        level,
        s,
        r,
        h,
        flags,
        status,
    }))
}

/// The meter's status word at each of the epochs `times` of `track` (None for a session
/// whose samples are not a meter's file), the epochs whose word has a bit of `[survey]
/// meter_status_flag_bits` set flagged [`gravity::METER_STATUS`] in `flags`.
fn meter_status(
    track: &Track<'_>,
    times: &[i64],
    survey: &SurveyConfig,
    flags: &mut [u8],
) -> Option<Vec<Option<u32>>> {
    let words = track.meter.as_ref()?.status_at(times, track.interval_ns);
    let mask = survey.meter_status_mask();
    for (f, w) in flags.iter_mut().zip(&words) {
        if w.is_some_and(|w| w & mask != 0) {
            *f |= gravity::METER_STATUS;
        }
    }
    Some(words)
}

/// What the ties inside the stretch `of` say of its level (fitted as one stretch's when it is
/// reduced in several blocks, or with the session's other ties): each tie's window reduced with
/// `margin` epochs either side (the filter's reach: what lies beyond does not change the
/// window's values), its point taken there.
fn tie_points(
    of: &StretchOf<'_>,
    ctx: &Context<'_>,
    margin: usize,
) -> Result<Vec<reduce::TiePoint>, GravityError> {
    let StretchOf {
        track, bins, span, ..
    } = of;
    let mut points = Vec::new();
    for (_, tie) in of.inside {
        let w = of.window(tie);
        let range = span.start + w.start.saturating_sub(margin)
            ..span.start + (w.end + margin).min(span.len());
        let s = stretch(track, &block(track, bins, range.clone())?, range, ctx)?;
        let r = reduce::untied(&s, ctx.survey.filter_s)?;
        points.extend(reduce::tie_point(&s, &r, tie, ctx.survey.filter_s)?);
    }
    Ok(points)
}

/// One level for every stretch of a session (`tie_level = "session"`, docs/formats.md 10):
/// the points of all its ties, in whichever stretch each lies, fitted as one offset and
/// drift; and the calibration's gradient at the first tie's window.
struct SessionTies {
    level: Option<reduce::Level>,
    at_tie: Option<Vec<f64>>,
}

/// [`SessionTies`] of `track` cut into `spans`; the stretches too short for the filter hold
/// no tie point.
fn session_ties(
    track: &Track<'_>,
    bins: &SpilledBins,
    spans: &[Range<usize>],
    ctx: &Context<'_>,
) -> Result<SessionTies, GravityError> {
    let interval_s = track.interval_ns as f64 * 1e-9;
    let margin = margin(ctx.survey.filter_s, interval_s);
    let mut points = Vec::new();
    let mut at_tie = None;
    for span in spans {
        if (span.len() as f64) * interval_s < ctx.survey.filter_s {
            continue;
        }
        let inside = ties_inside(ctx.ties, &track.times[span.clone()]);
        if inside.is_empty() {
            continue;
        }
        let of = StretchOf {
            track,
            bins,
            span: span.clone(),
            inside: &inside,
        };
        if at_tie.is_none()
            && let Some(f) = ctx.triad
        {
            at_tie = tie_gradient(f, &of, ctx)?;
        }
        points.extend(tie_points(&of, ctx, margin)?);
    }
    Ok(SessionTies {
        level: reduce::level(&points),
        at_tie,
    })
}

/// The filter's cut-off period against the trajectory's epochs: a period no longer than two
/// epoch intervals is one the epochs cannot show, refused naming the key and the file (the
/// filter's own check said only "a cut-off of 1 Hz at 1 Hz").
fn filter_longer_than_epochs(
    track: &Track<'_>,
    interval_ns: i64,
    filter_s: f64,
) -> Result<(), GravityError> {
    let interval_s = interval_ns as f64 * 1e-9;
    if filter_s > 2.0 * interval_s {
        return Ok(());
    }
    let file = track
        .session
        .trajectory
        .as_ref()
        .map(|t| t.path.display().to_string())
        .unwrap_or_default();
    Err(GravityError::Refused {
        message: format!(
            "survey.filter_s = {filter_s} s is not longer than two of session {}'s epoch \
             intervals ({file}: an epoch every {interval_s} s): the filter cannot keep a period \
             the epochs cannot show; choose more than {} s",
            track.session.session.id,
            2.0 * interval_s
        ),
    })
}

/// The ties whose window's centre lies inside the stretch of epochs `times`, with their
/// index.
fn ties_inside(ties: &[ResolvedTie], times: &[i64]) -> Vec<(usize, Tie)> {
    let span = times[0]..=times[times.len() - 1];
    ties.iter()
        .enumerate()
        .filter(|(_, t)| span.contains(&t.time_gps_ns))
        .map(|(k, t)| {
            let tie = Tie {
                time_gps_ns: t.time_gps_ns,
                duration_s: t.duration_s,
                g_mgal: t.g_mgal,
            };
            (k, tie)
        })
        .collect()
}

/// The stretches of valid, evenly spaced epochs (index ranges into the track's kept
/// epochs), with the epochs dropped counted by reason, and the gaps that cut them.
fn stretches(
    times: &[i64],
    spilled: &SpilledBins,
    interval: i64,
    expected: f64,
    dropped: &mut BTreeMap<String, u64>,
) -> std::io::Result<(Vec<Range<usize>>, u64)> {
    let need = (0.5 * expected).max(1.0);
    let mut out = Vec::new();
    let mut gaps = 0;
    let mut start: Option<usize> = None;
    let mut bins = spilled.read(0..0)?;
    for k in 0..=times.len() {
        if k < times.len() && k >= bins.end() {
            bins = spilled.read(k..(k + BLOCK_EPOCHS).min(times.len()))?;
        }
        let bin = (k < times.len()).then(|| bins.at(k));
        let valid = bin.as_ref().is_some_and(|b| b.value_weight >= need);
        if let Some(bin) = bin.as_ref().filter(|_| !valid) {
            let reason = if bin.weight >= need {
                dropped::NO_CALIBRATED_VALUE
            } else {
                dropped::NO_SPECIFIC_FORCE
            };
            *dropped.entry(reason.to_owned()).or_insert(0) += 1;
        }
        let uneven =
            k > 0 && k < times.len() && (times[k] - times[k - 1] - interval).abs() * 100 > interval;
        if let Some(s) = start
            && (!valid || uneven)
        {
            out.push(s..k);
            start = None;
            gaps += u64::from(valid && uneven);
        }
        if valid && start.is_none() {
            start = Some(k);
        }
    }
    Ok((out, gaps))
}

/// The reduction's input for the epochs `span` of `track`: with an attitude file, f_D from
/// the triad's mean vector through C_b^n, and with an antenna array's too unless
/// `[survey] array_down = "magnitude"` asks for the force's magnitude ([`magnitude`]);
/// levelled, the bins' own.
fn stretch(
    track: &Track<'_>,
    b: &Block<'_>,
    span: Range<usize>,
    ctx: &Context<'_>,
) -> Result<Stretch, GravityError> {
    let interval_s = track.interval_ns as f64 * 1e-9;
    let from_magnitude = track
        .array
        .as_ref()
        .filter(|_| ctx.survey.array_down == ArrayDown::Magnitude)
        .and_then(|(used, _)| magnitude::cutoff_hz(used, track.noise_neu_m, interval_s));
    let mut s = Stretch {
        attitude_errors: AttitudeErrors {
            // An antenna array's attitude errs as its positions do.
            model: match track.array {
                Some(_) => ctx.survey.position_error_model(),
                None => ctx.survey.attitude_error_model(),
            },
            interval_s: track.attitude.as_ref().map_or(0.0, |a| a.interval_s()),
        },
        position_errors: declared(ctx.survey.position_error_model()),
        normal: ctx.survey.normal_gravity,
        filter: ctx.survey.filter,
        ..Stretch::default()
    };
    let mut var_ne = Vec::new();
    for k in span.clone() {
        let [lat, lon, h] = b.positions.llh(k);
        s.time_gps_ns.push(track.times[k]);
        s.latitude_deg.push(lat);
        s.longitude_deg.push(lon);
        s.height_m.push(h);
        s.height_antenna_m.push(b.positions.antenna_height_m(k));
        let [white, given] = position_sds(&b.positions, k, s.position_errors);
        s.sd_up_m.push(white[2]);
        if s.position_errors.is_some() {
            s.sd_up_declared_m.push(given[2]);
        }
        if from_magnitude.is_some() {
            var_ne.push(white[0].powi(2) + white[1].powi(2));
        }
        push_down(&mut s, (b, k), ctx, from_magnitude.is_some());
    }
    if let Some(cutoff) = from_magnitude {
        let norms: Vec<f64> = span.map(|k| b.bins.at(k).mean_norm()).collect();
        magnitude::form_down(&mut s, &norms, &var_ne, (interval_s, cutoff))?;
    }
    if ctx.survey.earth_tide {
        s.tide_mgal = body_tide(&s);
    }
    if let (Some(correction), Some(m)) = (ctx.coupling, &track.meter) {
        s.coupling = Some(reduce::StretchCoupling {
            monitors: m.monitors_at(&s.time_gps_ns, track.interval_ns),
            correction,
        });
    }
    Ok(s)
}

/// Epoch `k` of block `b`'s down force, its calibration sigma and the attitude's effects on
/// it, pushed onto `s`: from the force's magnitude (`magnitude`, formed again after the
/// stretch's epochs by [`magnitude::form_down`]; no attitude enters it, and its calibration
/// sigma is along the body vector), turned by the attitude, or levelled.
fn push_down(s: &mut Stretch, (b, k): (&Block<'_>, usize), ctx: &Context<'_>, magnitude: bool) {
    let bin = b.bins.at(k);
    s.noise_f_mgal.push(bin.noise(ctx.sample_noise.sd_mgal));
    if magnitude {
        // No attitude is turned for it.
        let v = bin.mean_vector();
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        s.f_down_mgal.push(-norm);
        s.sigma_f_mgal.push(bin.sigma_along(v.map(|x| x / norm)));
        s.attitude_effects_mgal.push([0.0; 3]);
        return;
    }
    match body_to_nav(b, k, &ctx.mounting) {
        Some(c) => {
            let f = bin.mean_nav();
            s.f_down_mgal.push(f[2]);
            s.sigma_f_mgal.push(bin.sigma_along(c[2]));
            let a = b.attitude(k);
            let effects = a.map_or([0.0; 3], |a| attitude_effects_at(&a, f)[2]);
            s.attitude_effects_mgal.push(effects);
        }
        None => {
            s.f_down_mgal.push(bin.mean());
            s.sigma_f_mgal.push(bin.sigma_calibration());
            s.attitude_effects_mgal.push([0.0; 3]);
        }
    }
}

/// A track's cross-coupling correction as `[survey] cross_coupling` asks (docs/formats.md
/// 11.1): none; the coefficients given; or fitted by LaCoste's method over its stretches of
/// at least [`coupling::MIN_SEGMENT`] epochs (each reduced whole, untied: the regression
/// sees second derivatives, which no level changes), with what gravity.json says of it.
fn coupling_of(
    track: &Track<'_>,
    bins: &SpilledBins,
    spans: &[Range<usize>],
    ctx: &Context<'_>,
) -> Result<(Option<coupling::Correction>, Option<CouplingUsed>), GravityError> {
    use ingest::contract::survey::{CouplingWord, CrossCoupling};
    let refuse = |why: String| GravityError::Refused {
        message: format!(
            "survey.cross_coupling = \"fit\": session {}: {why}",
            track.session.session.id
        ),
    };
    match ctx.survey.cross_coupling {
        CrossCoupling::Word(CouplingWord::None) => Ok((None, None)),
        CrossCoupling::Given(g) => Ok((
            Some(coupling::Correction {
                coefficients: g.values(),
                covariance: [[0.0; 4]; 4],
            }),
            Some(CouplingUsed {
                how: "given".to_owned(),
                coefficients: g.values(),
                sigma: [0.0; 4],
                ols_sigma: None,
                rows: 0,
            }),
        )),
        CrossCoupling::Word(CouplingWord::Fit) => {
            let meter = track
                .meter
                .as_ref()
                .filter(|m| m.monitors.is_some())
                .ok_or_else(|| refuse("its file carries no monitors".to_owned()))?;
            let mut rows = Vec::new();
            for span in spans.iter().filter(|s| s.len() >= coupling::MIN_SEGMENT) {
                let b = block(track, bins, span.clone())?;
                let s = stretch(track, &b, span.clone(), ctx)?;
                let anomaly = reduce::unfiltered_disturbance(&s)?;
                rows.extend(coupling::segment_rows(
                    &anomaly,
                    &meter.monitors_at(&s.time_gps_ns, track.interval_ns),
                ));
            }
            let fitted = coupling::fit(&rows).ok_or_else(|| {
                refuse(format!(
                    "{} rows from its stretches of at least {} epochs do not determine the \
                     four coefficients (too short a record, or a monitor that never moves)",
                    rows.len(),
                    coupling::MIN_SEGMENT
                ))
            })?;
            let c = coupling::Correction::of(&fitted);
            let used = CouplingUsed {
                how: "fit".to_owned(),
                coefficients: c.coefficients,
                sigma: std::array::from_fn(|i| c.covariance[i][i].sqrt()),
                ols_sigma: Some(std::array::from_fn(|i| fitted.ols_sigma[i + 1])),
                rows: fitted.rows as u64,
            };
            Ok((Some(c), Some(used)))
        }
    }
}

/// The seconds between the epochs of a stretch the body tide is computed at ([`body_tide`]).
const TIDE_KNOT_S: f64 = 60.0;

/// The body tide's effect on gravity at each epoch of `s` where it is (align's model,
/// docs/model.md 6.3), mGal: computed at an epoch every [`TIDE_KNOT_S`] (and the last),
/// across the cores, and between them interpolated in time through the four nearest
/// (Lagrange's cubic), where computing it at each epoch of a day at 1 Hz took a tenth of
/// the stage. The tide's periods are half a day and longer, also along an aircraft's
/// track: on a straight track the cubic's error over a minute is under 1e-9 mGal. At a
/// turn the track's velocity kinks between two knots, and the tide's change with place
/// (0.1 mGal over the Earth's radius) follows the kink's tens of metres: survey-lines'
/// turns, 6.8e-7 mGal (both checked against the tide at every epoch in the tests).
fn body_tide(s: &Stretch) -> Vec<f64> {
    let times = &s.time_gps_ns;
    let n = times.len();
    // GPS less UTC, taken once: within a stretch a leap second moves the tide's time by a
    // second, where it changes by less than 1e-4 mGal.
    let leap_s = times.first().map_or(0.0, |&t| {
        t as f64 * 1e-9 - align::tide::utc_seconds_of_gps(t)
    });
    let at = |k: usize| {
        let site = align::tide::Site {
            latitude_deg: s.latitude_deg[k],
            longitude_deg: s.longitude_deg[k],
            height_m: s.height_m[k],
        };
        align::tide::body_tide_mgal(site, times[k] as f64 * 1e-9 - leap_s)
    };
    let span_s = match n {
        0 | 1 => 0.0,
        _ => (times[n - 1] - times[0]) as f64 * 1e-9 / (n - 1) as f64,
    };
    let step = match span_s > 0.0 {
        true => ((TIDE_KNOT_S / span_s).floor() as usize).max(1),
        false => 1,
    };
    let mut knots: Vec<usize> = (0..n).step_by(step).collect();
    if knots.last().is_some_and(|&k| k + 1 < n) {
        knots.push(n - 1);
    }
    // Too few knots for a cubic: every epoch its own.
    if knots.len() < 4 {
        return (0..n).map(at).collect();
    }
    use rayon::prelude::{IntoParallelRefIterator, ParallelIterator};
    let values: Vec<f64> = knots.par_iter().map(|&k| at(k)).collect();
    if knots.len() == n {
        return values;
    }
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let j = (k / step).min(knots.len() - 2);
        if knots[j] == k {
            out.push(values[j]);
            continue;
        }
        let first = j.saturating_sub(1).min(knots.len() - 4);
        out.push(lagrange_cubic(std::array::from_fn(|i| {
            let knot = knots[first + i];
            ((times[knot] - times[k]) as f64 * 1e-9, values[first + i])
        })));
    }
    out
}

/// The cubic through four points (x, y), at x = 0.
fn lagrange_cubic(p: [(f64, f64); 4]) -> f64 {
    (0..4)
        .map(|i| {
            let weight: f64 = (0..4)
                .filter(|&j| j != i)
                .map(|j| p[j].0 / (p[j].0 - p[i].0))
                .product();
            weight * p[i].1
        })
        .sum()
}

/// The effects of attitude `a`'s errors on the specific force `f` (N, E, D, mGal),
/// `[component][source]`: from its navigation-frame covariance where it has one (an
/// antenna array's), else from its angles' sds.
fn attitude_effects_at(a: &AttitudeAt, f: [f64; 3]) -> [[f64; 3]; 3] {
    match &a.nav_covariance {
        Some(c) => errors::attitude_effects_of_covariance(c, f),
        None => errors::attitude_effects(a.hpr_rad[0], a.sd_rad, f),
    }
}

/// The positions' error model where it is not white (None when white: the file's sds then
/// join the white part).
fn declared(model: ErrorModel) -> Option<ErrorModel> {
    (model != ErrorModel::White).then_some(model)
}

/// Epoch `k`'s sds north, east, up: the white part (the larger of the file's and the
/// positions' own white noise when the file's are white, the own noise alone otherwise) and
/// the file's, m.
fn position_sds(p: &super::track::Positions, k: usize, model: Option<ErrorModel>) -> [[f64; 3]; 2] {
    match model {
        None => [p.sd_m(k), [0.0; 3]],
        Some(_) => [p.noise_m(), p.sd_given_m(k)],
    }
}

/// North and east's inputs for the epochs `span` of a track with attitude: the specific
/// force through C_b^n, its calibration sigma along each row (or the parameters' gradients
/// with a triad without temperature terms), the attitude's sigma, the positions' sds.
fn horizontal_inputs(
    b: &Block<'_>,
    att: &[AttitudeAt],
    span: Range<usize>,
    ctx: &Context<'_>,
) -> Horizontal {
    let bins = &b.bins;
    let mut h = Horizontal::default();
    let mut gradients: [Option<Vec<Vec<f64>>>; 2] = match ctx.triad {
        Some(f) => std::array::from_fn(|_| Some(vec![Vec::new(); f.covariance().len().isqrt()])),
        None => [None, None],
    };
    let model = declared(ctx.survey.position_error_model());
    for k in span {
        let a = &att[k - b.bins.start];
        let c = attitude::product(&a.vehicle_to_nav(), &ctx.mounting);
        let bin = bins.at(k);
        let (v, f) = (bin.mean_vector(), bin.mean_nav());
        let effects = attitude_effects_at(a, f);
        let [sd, given] = position_sds(&b.positions, k, model);
        let x = ctx.triad.and_then(|t| t.readings_for(v));
        for i in 0..2 {
            h.f_mgal[i].push(f[i]);
            h.sigma_calibration_mgal[i].push(bin.sigma_along(c[i]));
            h.attitude_effects_mgal[i].push(effects[i]);
            h.sd_m[i].push(sd[i]);
            if model.is_some() {
                h.sd_declared_m[i].push(given[i]);
            }
            if let (Some(series), Some(t)) = (&mut gradients[i], ctx.triad) {
                match x {
                    Some(x) => {
                        for (s, g) in series.iter_mut().zip(t.gradient(x, c[i])) {
                            s.push(g);
                        }
                    }
                    None => gradients[i] = None,
                }
            }
        }
    }
    h.calibration = gradients.map(|g| {
        g.zip(ctx.triad).map(|(gradient, t)| CalibrationGradient {
            gradient,
            covariance: t.covariance().to_vec(),
        })
    });
    h
}

/// Each epoch's flags: extrapolated calibration, turning, within a filter period of the
/// stretch's ends (`t0`, `t1`), an attitude without sds, a position `replaced` as an
/// outlier.
fn flags_of(
    s: &Stretch,
    b: &Block<'_>,
    span: Range<usize>,
    (t0, t1): (i64, i64),
    filter_s: f64,
    r: &Reduced,
    replaced: &[usize],
) -> Vec<u8> {
    let turning = turning(s, &r.speed_m_s);
    let edge_ns = (filter_s * 1e9) as i64;
    span.enumerate()
        .map(|(i, k)| {
            let mut f = 0;
            if b.bins.at(k).flags
                & (applied::COUNTS_OUT_OF_RANGE | applied::TEMPERATURE_OUT_OF_RANGE)
                != 0
            {
                f |= gravity::OUTSIDE_CALIBRATION;
            }
            if turning[i] {
                f |= gravity::TURN;
            }
            let t = s.time_gps_ns[i];
            if t - t0 < edge_ns || t1 - t < edge_ns {
                f |= gravity::EDGE;
            }
            if b.attitude(k).is_some_and(|a| !a.sd_given) {
                f |= gravity::ATTITUDE_SD_UNKNOWN;
            }
            if replaced.binary_search(&k).is_ok() {
                f |= gravity::POSITION_OUTLIER;
            }
            f
        })
        .collect()
}

/// Epochs where the course over ground changes faster than [`gravity::TURN_DEG_PER_S`]:
/// the course from positions 5 s either side (so that cm noise does not turn it), its rate
/// over 10 s, where the vehicle moves at over 1 m/s.
fn turning(s: &Stretch, speed: &[f64]) -> Vec<bool> {
    let n = s.time_gps_ns.len();
    let dt = (s.time_gps_ns[n - 1] - s.time_gps_ns[0]) as f64 * 1e-9 / (n - 1) as f64;
    let w = ((5.0 / dt).round() as usize).max(1);
    let course = |k: usize| {
        let [north, east] =
            reduce::displacement_ne_m(s, (k.saturating_sub(w), (k + w).min(n - 1)), k);
        east.atan2(north)
    };
    (0..n)
        .map(|k| {
            if speed[k] < 1.0 || k < w || k + w >= n {
                return false;
            }
            let mut d = course(k + w) - course(k - w);
            d = (d + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI)
                - std::f64::consts::PI;
            d.abs().to_degrees() / (2.0 * w as f64 * dt) > gravity::TURN_DEG_PER_S
        })
        .collect()
}

fn count_flags(flags: &[u8]) -> Vec<(String, u64)> {
    gravity::FLAG_NAMES
        .iter()
        .map(|(bit, name)| {
            (
                (*name).to_owned(),
                flags.iter().filter(|f| *f & bit != 0).count() as u64,
            )
        })
        .filter(|(_, n)| *n > 0)
        .collect()
}

fn tie_entry(t: &ResolvedTie) -> TieUsed {
    TieUsed {
        time: utc_iso(t.time_gps_ns),
        g_mgal: t.g_mgal,
        used_in: None,
    }
}

/// The filter and the resolution at the median speed of the epochs moving faster than
/// 0.5 m/s (of `speeds`, the rows' sampled as [`Rows`] keeps them).
fn filter_used(speeds: &[f64], (kind, filter_s): (FilterKind, f64)) -> FilterUsed {
    let mut moving: Vec<f64> = speeds.iter().copied().filter(|v| *v > 0.5).collect();
    moving.sort_by(f64::total_cmp);
    let median = moving.get(moving.len() / 2).copied().unwrap_or(0.0);
    FilterUsed {
        name: kind,
        kind: match kind {
            FilterKind::Butterworth => format!(
                "Butterworth, order {} each way (zero phase, forward and backward)",
                super::filter::ORDER
            ),
            FilterKind::Gaussian => {
                "Gaussian kernel, sd 0.187 of the cut-off period, to four sds (zero phase, \
                 applied once, centred)"
                    .to_owned()
            }
            FilterKind::Blackman | FilterKind::Hamming => format!(
                "windowed sinc, {} window, two cut-off periods long (zero phase, applied once, \
                 centred)",
                if kind == FilterKind::Blackman {
                    "Blackman"
                } else {
                    "Hamming"
                }
            ),
        },
        filter_s,
        median_speed_m_s: median,
        resolution_m: median * filter_s / 2.0,
    }
}

/// gravity.parquet written as the blocks come: their rows gathered until
/// [`BLOCK_EPOCHS`], then written as a row group ([`gravity::Writer`]); what the crossover
/// search and the filter's resolution need of them kept as they pass (a row in
/// [`crossover::step`]).
struct Rows {
    table: gravity::Writer,
    /// The rows the crossover search takes.
    kept: crossover::Kept,
    /// One speed a step, m/s.
    speeds: Vec<f64>,
}

/// North's and east's columns of a block, by field.
fn components(h: ReducedHorizontal) -> [gravity::Component; 2] {
    let [dn, de] = h.disturbance_mgal;
    let [fn_, fe] = h.filtered_mgal;
    let [sn, se] = h.sigma_mgal;
    let [cn, ce] = h.sigma_calibration_mgal;
    let [pn, pe] = h.sigma_positions_mgal;
    let [nn, ne] = h.sigma_noise_mgal;
    let [an, ae] = h.sigma_attitude_mgal;
    let component = |mgal, filtered_mgal, sigma_mgal, c, p, n, a| gravity::Component {
        mgal,
        filtered_mgal,
        sigma_mgal,
        sigma_calibration_mgal: c,
        sigma_positions_mgal: p,
        sigma_noise_mgal: n,
        sigma_attitude_mgal: a,
    };
    [
        component(dn, fn_, sn, cn, pn, nn, an),
        component(de, fe, se, ce, pe, ne, ae),
    ]
}

impl Rows {
    /// Starts gravity.parquet in `dir`, for the sessions `names`.
    fn create(dir: &Path, names: &[String], with_horizontal: bool) -> Result<Self, GravityError> {
        Ok(Rows {
            table: gravity::Writer::create(dir, names, with_horizontal)?,
            kept: crossover::Kept::default(),
            speeds: Vec::new(),
        })
    }

    /// Appends a block's rows (whose, `at`), taking its series, flags and meter status;
    /// writes a row group once [`BLOCK_EPOCHS`] are gathered.
    fn push(
        &mut self,
        at: RowsOf,
        named: reduce::Named,
        block: BlockRows,
    ) -> Result<(), GravityError> {
        let BlockRows {
            s,
            r,
            h,
            flags,
            status,
            level: _,
        } = block;
        self.keep_for_crossovers(at, &s, &r, &flags);
        let (r, h) = withhold_edges(r, h, &flags);
        let quantities = (0..s.time_gps_ns.len())
            .map(|k| named.at(s.latitude_deg[k], s.height_m[k], r.filtered_mgal[k]))
            .collect();
        self.speeds
            .extend(r.speed_m_s.iter().step_by(at.step.max(1)));
        let floats = gravity::Floats {
            latitude_deg: s.latitude_deg,
            longitude_deg: s.longitude_deg,
            height_m: s.height_m,
            speed_m_s: r.speed_m_s,
            eotvos_mgal: r.eotvos_mgal,
            normal_mgal: r.normal_mgal,
            tide_mgal: r.tide_mgal,
            cross_coupling_mgal: r.coupling_mgal,
            down_mgal: r.disturbance_mgal,
            down_filtered_mgal: r.filtered_mgal,
            sigma_down_mgal: r.sigma_mgal,
            sigma_calibration_mgal: r.sigma_calibration_mgal,
            sigma_positions_mgal: r.sigma_positions_mgal,
            sigma_noise_mgal: r.sigma_noise_mgal,
            sigma_tie_mgal: r.sigma_tie_mgal,
            sigma_attitude_mgal: r.sigma_attitude_mgal,
            sigma_coupling_mgal: r.sigma_coupling_mgal,
            height_antenna_m: s.height_antenna_m,
        };
        self.table.push(gravity::Block {
            session_index: at.session,
            stretch: at.stretch,
            time_gps_ns: s.time_gps_ns,
            floats,
            horizontal: h.map(components),
            named: quantities,
            flags,
            meter_status: status,
        })?;
        if self.table.gathered() >= BLOCK_EPOCHS {
            self.table.write()?;
        }
        Ok(())
    }

    /// A block's rows offered to the crossover search ([`crossover::Kept`]).
    fn keep_for_crossovers(&mut self, at: RowsOf, s: &Stretch, r: &Reduced, flags: &[u8]) {
        for k in 0..s.time_gps_ns.len() {
            self.kept.push(
                &crossover::Row {
                    session: at.session,
                    stretch: at.stretch,
                    time_gps_ns: s.time_gps_ns[k],
                    latitude_deg: s.latitude_deg[k],
                    longitude_deg: s.longitude_deg[k],
                    speed_m_s: r.speed_m_s[k],
                    filtered_mgal: r.filtered_mgal[k],
                    sigma_mgal: r.sigma_mgal[k],
                    sigma_noise_mgal: r.sigma_noise_mgal[k],
                    sigma_positions_mgal: r.sigma_positions_mgal[k],
                    sigma_tie_mgal: r.sigma_tie_mgal[k],
                    flags: flags[k],
                },
                at.step,
            );
        }
    }

    /// Where the track crosses itself ([`crossover`]), among the rows kept.
    fn crossovers(
        &self,
        names: &[String],
        tracks: &[Track<'_>],
        sessions: &[SessionGravity],
        filter_s: f64,
    ) -> Vec<Crossover> {
        let rate_sigma = |session: u16, stretch: u32| {
            let k = tracks.iter().position(|t| t.index == session)?;
            let drift = sessions[k]
                .stretches
                .get(stretch as usize)?
                .drift
                .as_ref()?;
            drift.sigma_rate_mgal_per_h
        };
        crossover::crossovers(&self.kept.epochs(names), filter_s, rate_sigma)
    }

    /// Writes the last rows and closes gravity.parquet; returns the rows and the file's
    /// SHA-256 (hashed as it was written).
    fn finish(self) -> Result<(u64, String), GravityError> {
        Ok(self.table.finish_hashed()?)
    }
}

/// A session's cross-coupling as the console says it: how, the rows, each coefficient with
/// its sd (or exact, given).
fn coupling_line(c: &CouplingUsed) -> String {
    let terms: Vec<String> = coupling::MONITORS
        .iter()
        .enumerate()
        .map(|(i, m)| match c.sigma[i] {
            0.0 => format!("{m} {} (exact)", c.coefficients[i]),
            sd => format!(
                "{m} {}",
                ingest::contract::precision::value_with_sigma(c.coefficients[i], sd)
            ),
        })
        .collect();
    format!(
        "cross-coupling {} ({} rows): {}",
        c.how,
        c.rows,
        terms.join(", ")
    )
}

/// The command line of `cargo xtask gravity`: apply's, and what gravity adds.
#[derive(clap::Args, Clone, Debug)]
pub struct GravityArgs {
    /// The survey, the calibration and the output folder, as apply takes them.
    #[command(flatten)]
    pub apply: crate::survey::apply::stream::ApplyArgs,
    /// With an axis model of several accelerometers: the one taken as vertical.
    #[arg(long)]
    pub accelerometer: Option<String>,
    /// Set aside a trajectory's or attitude's line that breaks the format (counted as
    /// `bad_line` and listed in gravity.json) instead of failing on it.
    #[arg(long)]
    pub skip_bad_lines: bool,
    /// Epochs of a stretch reduced at a time (default 65536, or four times the filter's
    /// reach where it is longer); the result is the same to 1e-6 mGal, the memory a block's.
    /// At least one filter period of epochs (each block is reduced with twelve periods of
    /// margin either side): fewer is refused.
    #[arg(long)]
    pub block_epochs: Option<usize>,
}

impl GravityArgs {
    /// `dataset` reduced with `calibration` (a calibration.json, or
    /// [`crate::survey::apply::stream::VENDOR`]), every option at its default.
    pub fn new(dataset: &Path, calibration: &Path) -> Self {
        GravityArgs {
            apply: crate::survey::apply::stream::ApplyArgs {
                dataset: dataset.to_path_buf(),
                calibration: calibration.to_path_buf(),
                model: None,
                session: None,
                out: None,
            },
            accelerometer: None,
            skip_bad_lines: false,
            block_epochs: None,
        }
    }

    /// Runs the stage into `out`.
    pub fn run(&self, out: &Path) -> Result<GravityReport, GravityError> {
        run(
            &self.apply.dataset,
            out,
            &Options {
                apply: self.apply.options(),
                accelerometer: self.accelerometer.as_deref(),
                skip_bad_lines: self.skip_bad_lines,
                block_epochs: self.block_epochs,
            },
        )
    }
}

/// One session's lines of the summary: its epochs, the positions' noise, the lines and
/// samples set aside, each stretch's tie.
fn print_session(s: &SessionGravity, w: &mut impl std::io::Write) {
    let dropped: Vec<String> = s.dropped.iter().map(|(k, n)| format!("{n} {k}")).collect();
    let _ = writeln!(
        w,
        "gravity: {}: {} of {} epochs used, {} stretch(es), {} gap(s){}",
        s.id,
        s.epochs_used,
        s.epochs_read,
        s.stretches.len(),
        s.gaps,
        if dropped.is_empty() {
            String::new()
        } else {
            format!("; dropped: {}", dropped.join(", "))
        }
    );
    let [n, e, u] = s.position_noise_m.map(|v| v * 100.0);
    let given = s.position_sd_given_m.map_or_else(
        || "the trajectory gives no sd".to_owned(),
        |g| {
            let [gn, ge, gu] = g.map(|v| v * 100.0);
            format!("the trajectory's own median {gn:.2}, {ge:.2}, {gu:.2} cm")
        },
    );
    let _ = writeln!(
        w,
        "gravity: {}: positions' white noise north, east, up {n:.2}, {e:.2}, {u:.2} cm \
         (their third differences); {given}",
        s.id
    );
    let _ = writeln!(w, "gravity: {}: {}", s.id, s.quantities.describe());
    if let Some(c) = &s.cross_coupling {
        let _ = writeln!(w, "gravity: {}: {}", s.id, coupling_line(c));
    }
    if let Some(m) = &s.meter_status {
        let _ = writeln!(w, "gravity: {}: {}", s.id, status_line(m, s.epochs_used));
    }
    if let Some(a) = &s.antennas {
        let _ = writeln!(w, "gravity: {}: {}", s.id, antennas_line(a));
    }
    let _ = writeln!(
        w,
        "gravity: {}: a sample's noise {:.4} mGal, from {}",
        s.id, s.sample_noise_mgal, s.sample_noise_from
    );
    for b in &s.bad_lines {
        let _ = writeln!(w, "gravity: {}: set aside: {b}", s.id);
    }
    if !s.attitude_dropped.is_empty() {
        let d: Vec<String> = s
            .attitude_dropped
            .iter()
            .map(|(k, n)| format!("{n} {k}"))
            .collect();
        let _ = writeln!(
            w,
            "gravity: {}: attitude samples dropped by the time gate: {}",
            s.id,
            d.join(", ")
        );
    }
    for st in &s.stretches {
        let drift = st.drift.as_ref().map_or_else(
            || "untied (the calibration's level)".to_owned(),
            |d| {
                format!(
                    "{} tie(s): offset {:.3} +/- {:.3} mGal, drift {:.3} mGal/h",
                    d.ties, d.offset_mgal, d.sigma_offset_mgal, d.rate_mgal_per_h
                )
            },
        );
        let _ = writeln!(w, "gravity:   {} to {}: {}", st.first, st.last, drift);
    }
}

/// An antenna array's session as the console says it: its antennas, the epochs solved,
/// the antennas set aside, the attitude's and position's median sds.
fn antennas_line(a: &ingest::contract::gravity_ledger::AntennasUsed) -> String {
    let listed = |v: Vec<String>| match v.is_empty() {
        true => "none".to_owned(),
        false => v.join(", "),
    };
    let aside = listed(
        a.set_aside
            .iter()
            .map(|(id, n)| format!("{id} at {n}"))
            .collect(),
    );
    let gated = listed(
        (a.dropped.iter())
            .flat_map(|(id, d)| d.iter().map(move |(why, n)| format!("{id}: {n} {why}")))
            .collect(),
    );
    let angles: Vec<String> = ["heading", "pitch", "roll"]
        .iter()
        .zip(a.median_sd_hpr_deg)
        .map(|(name, sd)| match (sd, a.not_given.get(*name)) {
            (Some(sd), _) => format!("{name} {sd:.3} deg"),
            (None, Some(why)) => format!("{name} not given ({why})"),
            (None, None) => format!("{name} none"),
        })
        .collect();
    let [n, e, d] = a.median_sd_position_m.map(|v| v * 100.0);
    let estimated = listed(
        a.estimated
            .iter()
            .map(|(id, p)| {
                let [x, y, z] = p.position_m;
                let [sx, sy, sz] = p.sd_m.map(|v| v * 1e3);
                format!(
                    "{id} at [{x:.4}, {y:.4}, {z:.4}] m, sds [{sx:.2}, {sy:.2}, {sz:.2}] mm \
                     from {} epochs ({} screened out)",
                    p.epochs, p.screened
                )
            })
            .collect(),
    );
    format!(
        "antennas {}: attitude and position at {} epochs; dropped by an antenna's time gate: \
         {gated}; set aside (baseline length): {aside}; positions estimated: {estimated}; \
         median sd {}, position north {n:.2}, east {e:.2}, down {d:.2} cm \
         (OUT/gravity/attitude.parquet)",
        a.ids.join(", "),
        a.epochs_solved,
        angles.join(", "),
    )
}

/// A session's meter status as the console says it: each bit set, at every epoch or at
/// how many; the bits that flag an epoch.
fn status_line(m: &MeterStatus, epochs_used: u64) -> String {
    let (always, some): (Vec<_>, Vec<_>) = m.bits_set.iter().partition(|(_, n)| **n == m.epochs);
    let mut set = Vec::new();
    if !always.is_empty() {
        let bits: Vec<String> = always.iter().map(|(b, _)| b.to_string()).collect();
        set.push(format!("bits {} set at every one", bits.join(", ")));
    }
    if !some.is_empty() {
        let bits: Vec<String> = some.iter().map(|(b, n)| format!("{b} at {n}")).collect();
        set.push(format!("bits {}", bits.join(", ")));
    }
    if set.is_empty() {
        set.push("no bit set".to_owned());
    }
    let flag = match m.flag_bits.is_empty() {
        true => "no bit declared to flag an epoch (survey.meter_status_flag_bits)".to_owned(),
        false => format!("bits {:?} flag an epoch `meter_status`", m.flag_bits),
    };
    format!(
        "meter status (bit 0 the least significant) at {} of {epochs_used} epochs: {}; {flag}",
        m.epochs,
        set.join("; ")
    )
}

/// An error model in words.
fn describe_model(m: ErrorModel) -> String {
    match m {
        ErrorModel::White => "white".to_owned(),
        ErrorModel::Correlated { correlation_s } => format!("correlated over {correlation_s} s"),
        ErrorModel::Systematic => "systematic".to_owned(),
    }
}

/// A few lines: per session the epochs used and dropped, the stretches and their ties, the
/// filter's resolution, the error models.
pub fn print_summary(r: &GravityReport, w: &mut impl std::io::Write) {
    let f = &r.filter;
    let _ = writeln!(
        w,
        "gravity: {} rows; filter {} over {} s, resolution {:.0} m at {:.1} m/s",
        r.rows_written,
        f.name.name(),
        f.filter_s,
        f.resolution_m,
        f.median_speed_m_s
    );
    let m = &r.error_models;
    let _ = writeln!(
        w,
        "gravity: errors taken as: positions {}, attitude {} (docs/formats.md 10)",
        describe_model(m.positions),
        describe_model(m.attitude)
    );
    let _ = writeln!(
        w,
        "gravity: held to {} normal gravity; {}",
        r.normal_gravity.name(),
        if r.earth_tide {
            "the body tide removed at every epoch (tide_mgal)"
        } else {
            "the body tide not removed (earth_tide = false)"
        }
    );
    for s in &r.sessions {
        print_session(s, w);
    }
    for n in &r.not_reduced {
        let _ = writeln!(w, "gravity: {}: not reduced: {}", n.session, n.why);
    }
    for t in r.ties.iter().filter(|t| t.used_in.is_none()) {
        let _ = writeln!(
            w,
            "gravity: the tie at {} ({} mGal) is not used: no stretch holds its still window",
            t.time, t.g_mgal
        );
    }
    for c in &r.crossovers {
        let _ = writeln!(
            w,
            "gravity: crossover at {:.5} {:.5} ({} and {}, {:.0} deg): {:+.3} +/- {:.3} mGal",
            c.latitude_deg,
            c.longitude_deg,
            c.first.time,
            c.second.time,
            c.angle_deg,
            c.difference_mgal,
            c.sigma_mgal
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of `n` epochs: the stretch's and the reduction's columns all `n` long.
    fn rows_of(n: usize) -> (Stretch, Reduced, ReducedHorizontal) {
        let v = vec![1.0; n];
        let s = Stretch {
            time_gps_ns: (0..n as i64).collect(),
            latitude_deg: v.clone(),
            longitude_deg: v.clone(),
            height_m: v.clone(),
            height_antenna_m: v.clone(),
            ..Stretch::default()
        };
        let r = Reduced {
            speed_m_s: v.clone(),
            eotvos_mgal: v.clone(),
            normal_mgal: v.clone(),
            tide_mgal: v.clone(),
            coupling_mgal: v.clone(),
            sigma_coupling_mgal: v.clone(),
            disturbance_mgal: v.clone(),
            filtered_mgal: v.clone(),
            sigma_mgal: v.clone(),
            sigma_calibration_mgal: v.clone(),
            sigma_positions_mgal: v.clone(),
            sigma_noise_mgal: v.clone(),
            sigma_tie_mgal: v.clone(),
            sigma_attitude_mgal: v.clone(),
            ..Reduced::default()
        };
        // North's parts 10..=16 and east's 20..=26, in gravity::HORIZONTAL's order.
        let two = |part: usize| [10.0, 20.0].map(|base| vec![base + part as f64; n]);
        let h = ReducedHorizontal {
            disturbance_mgal: two(0),
            filtered_mgal: two(1),
            sigma_mgal: two(2),
            sigma_calibration_mgal: two(3),
            sigma_positions_mgal: two(4),
            sigma_noise_mgal: two(5),
            sigma_attitude_mgal: two(6),
        };
        (s, r, h)
    }

    /// The tide interpolated between its knots is the tide computed at every epoch to 1e-9
    /// mGal: a day of a jet flying east at 250 m/s at 10 Hz and 1 Hz, a ship's short
    /// stretch, and stretches of 1 to 5 epochs (computed at each).
    #[test]
    fn the_tide_between_its_knots_is_the_tide_at_each_epoch() {
        let start = 1_300_000_000_000_000_000i64;
        let track = |n: usize, dt_s: f64, speed_m_s: f64| {
            let times: Vec<i64> = (0..n)
                .map(|k| start + (k as f64 * dt_s * 1e9).round() as i64)
                .collect();
            let lon: Vec<f64> = (0..n)
                .map(|k| -40.0 + k as f64 * dt_s * speed_m_s / 111_000.0 / 0.7)
                .collect();
            Stretch {
                time_gps_ns: times,
                latitude_deg: vec![45.0; n],
                longitude_deg: lon,
                height_m: vec![10_000.0; n],
                ..Stretch::default()
            }
        };
        for (n, dt_s, speed) in [
            (864_000, 0.1, 250.0),
            (86_400, 1.0, 250.0),
            (3_601, 1.0, 6.0),
            (1, 1.0, 6.0),
            (3, 1.0, 6.0),
            (5, 20.0, 6.0),
            (241, 0.25, 6.0),
        ] {
            let s = track(n, dt_s, speed);
            let tide = body_tide(&s);
            let leap_s =
                s.time_gps_ns[0] as f64 * 1e-9 - align::tide::utc_seconds_of_gps(s.time_gps_ns[0]);
            let worst = (0..n)
                .map(|k| {
                    let site = align::tide::Site {
                        latitude_deg: s.latitude_deg[k],
                        longitude_deg: s.longitude_deg[k],
                        height_m: s.height_m[k],
                    };
                    let exact =
                        align::tide::body_tide_mgal(site, s.time_gps_ns[k] as f64 * 1e-9 - leap_s);
                    (tide[k] - exact).abs()
                })
                .fold(0.0, f64::max);
            assert!(worst < 1e-9, "{n} epochs at {dt_s} s: {worst:e} mGal");
        }
    }

    /// Heights above the ellipsoid, no geoid height.
    const NAMED: reduce::Named = reduce::Named {
        heights: ingest::contract::survey::Heights::Ellipsoidal,
        geoid_height_m: None,
        normal: super::super::normal::NormalGravity::Grs80,
    };

    /// The horizontal columns of the gravity.parquet in `dir`, read back: per column, its
    /// rows (None where null).
    fn horizontal_read_back(dir: &Path) -> Vec<Vec<Option<f64>>> {
        use arrow_array::Array;
        let path = dir.join(gravity::FILE);
        let mut columns = vec![Vec::new(); gravity::HORIZONTAL.len()];
        ingest::contract::tables::float_batches(
            &path,
            &gravity::HORIZONTAL,
            gravity::FLAGS,
            1 << 16,
            |b| {
                for (column, values) in columns.iter_mut().zip(&b.values) {
                    column.extend(
                        (0..values.len()).map(|i| values.is_valid(i).then(|| values.value(i))),
                    );
                }
                Ok(())
            },
        )
        .expect("read back");
        columns
    }

    /// North and east are held only where a track has attitude: without, their columns are
    /// null throughout; with, the rows of a stretch without attitude are null, and each of
    /// the reduction's parts stands under its own name.
    #[test]
    fn rows_without_attitude_are_null_in_north_and_east() {
        let names = ["a".to_owned(), "b".to_owned()];
        let block = |n: usize, with_horizontal: bool| {
            let (s, r, h) = rows_of(n);
            BlockRows {
                level: None,
                s,
                r,
                h: with_horizontal.then_some(h),
                flags: vec![0; n],
                status: None,
            }
        };
        let at = |session, stretch| RowsOf {
            session,
            stretch,
            step: 1,
        };
        let dir = tempfile::tempdir().expect("dir");
        let mut without = Rows::create(dir.path(), &names, false).expect("rows");
        without
            .push(at(0, 0), NAMED, block(2, false))
            .expect("pushed");
        assert_eq!(without.finish().expect("written").0, 2);
        for column in horizontal_read_back(dir.path()) {
            assert_eq!(column, [None; 2]);
        }
        let dir = tempfile::tempdir().expect("dir");
        let mut rows = Rows::create(dir.path(), &names, true).expect("rows");
        rows.push(at(0, 0), NAMED, block(2, false)).expect("pushed");
        rows.push(at(1, 0), NAMED, block(3, true)).expect("pushed");
        rows.push(at(0, 1), NAMED, block(1, false)).expect("pushed");
        assert_eq!(rows.finish().expect("written").0, 6);
        for (c, column) in horizontal_read_back(dir.path()).into_iter().enumerate() {
            let want = if c < 7 { 10 + c } else { 13 + c } as f64;
            let mut expected = vec![None; 6];
            expected[2..5].fill(Some(want));
            assert_eq!(column, expected, "{}", gravity::HORIZONTAL[c]);
        }
    }

    /// A stretch's blocks keep every epoch once, in order, each reduced with the margin
    /// either side where the stretch has it.
    #[test]
    fn blocks_cover_the_stretch_once() {
        for (n, block, margin) in [(10, 100, 5), (100, 10, 3), (101, 10, 30), (7, 1, 2)] {
            let plan = blocks(n, block, margin);
            let kept: Vec<usize> = plan.iter().flat_map(|(_, k)| k.clone()).collect();
            assert_eq!(kept, (0..n).collect::<Vec<_>>(), "{n} {block} {margin}");
            for (reduced, keep) in &plan {
                assert!(keep.len() <= block);
                assert_eq!(reduced.start, keep.start.saturating_sub(margin));
                assert_eq!(reduced.end, (keep.end + margin).min(n));
            }
        }
        assert_eq!(blocks(10, 100, 5).len(), 1);
    }
}
