//! Which fits of a calibration to apply to a survey, after the checks docs/formats.md 8.5 asks
//! for before any work: the survey's accelerometers are the calibration's (ids and
//! serials), the model exists, and a model fitted per session is applied only with the
//! session named.

use super::CalibrationFunction;
use ingest::contract::calibration::{ALL_SESSIONS, Calibration, TriadResult};
use ingest::contract::manifest::{Accelerometer, Dataset};
use std::collections::BTreeSet;

/// Why a calibration cannot be applied to a survey as asked; each says what to change.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelectError {
    /// A calibration.json older than its accelerometers' list.
    #[error(
        "the calibration does not list its accelerometers (written before gravcal recorded \
         them): re-run adjust on its dataset"
    )]
    NoAccelerometers,
    /// An accelerometer of the survey the calibration did not calibrate.
    #[error(
        "accelerometer `{id}` of the survey is not in the calibration (which calibrated {calibrated})"
    )]
    NotCalibrated {
        /// The survey's accelerometer.
        id: String,
        /// The calibration's, listed.
        calibrated: String,
    },
    /// One id, two serials.
    #[error(
        "accelerometer `{id}`: serial {survey} in the survey's manifest, {calibration} in the \
         calibration's: not the same instrument"
    )]
    OtherSerial {
        /// The accelerometer.
        id: String,
        /// The survey's serial, quoted, or none.
        survey: String,
        /// The calibration's.
        calibration: String,
    },
    /// Counts against volts, or the other way.
    #[error(
        "the calibration was fitted on readings in {fitted}, the survey's are in {survey} \
         (the instrument's reading_unit)"
    )]
    ReadingUnit {
        /// The calibration's unit.
        fitted: String,
        /// The survey's.
        survey: String,
    },
    /// `--model` names a model the calibration has not.
    #[error("model `{model}` is not in the calibration (it has: {has})")]
    NoSuchModel {
        /// As asked.
        model: String,
        /// The calibration's models, listed.
        has: String,
    },
    /// Several models and no `--model`.
    #[error("the calibration holds {count} models ({has}): name one with --model")]
    WhichModel {
        /// How many.
        count: usize,
        /// Listed.
        has: String,
    },
    /// `--session` for a model fitted over all sessions.
    #[error("model `{model}` is fitted over all sessions: --session {session} does not apply")]
    SessionNotApplicable {
        /// The model.
        model: String,
        /// As asked.
        session: String,
    },
    /// `--session` names a session the model has no fits for.
    #[error("model `{model}` has no fits for session `{session}` (it has: {has})")]
    NoSuchSession {
        /// The model.
        model: String,
        /// As asked.
        session: String,
        /// Its sessions, listed.
        has: String,
    },
    /// A model fitted per session and no `--session`.
    #[error(
        "model `{model}` is fitted per session ({has}): name the one to apply with \
         --session"
    )]
    WhichSession {
        /// The model.
        model: String,
        /// Its sessions, listed.
        has: String,
    },
    /// A result that is there but cannot be evaluated.
    #[error(transparent)]
    Unusable(#[from] super::ApplyError),
    /// A triad calibrated on readings in another unit.
    #[error("triad {model} was calibrated on readings in {fitted}, the survey's are in {survey}")]
    TriadReadingUnit {
        /// The triad's model.
        model: String,
        /// Its unit.
        fitted: String,
        /// The survey's.
        survey: String,
    },
    /// No accelerometer on one of the triad's channels.
    #[error("the calibration has no accelerometer on channel {channel}")]
    NoChannel {
        /// 1-based.
        channel: usize,
    },
    /// A triad axis whose accelerometer the survey does not have.
    #[error("the triad's axis {axis} is accelerometer `{id}`, not in the survey")]
    AxisNotInSurvey {
        /// x, y or z.
        axis: &'static str,
        /// The accelerometer.
        id: String,
    },
}

/// What the user asked to apply.
#[derive(Clone, Debug, Default)]
pub struct Choice<'a> {
    /// `--model`: needed when the calibration holds more than one model.
    pub model: Option<&'a str>,
    /// `--session`: needed, and only allowed, when the model is fitted per session.
    pub session: Option<&'a str>,
}

/// One accelerometer of the survey and its calibration function, or why it has none.
#[derive(Clone, Debug)]
pub struct Target {
    /// As the survey's manifest declares it.
    pub accelerometer: Accelerometer,
    /// The function to apply, or why the model gives none.
    pub function: Result<CalibrationFunction, String>,
    /// The counts range the fit saw.
    pub counts_range: Option<[f64; 2]>,
    /// The temperature range it saw, degC.
    pub temperature_range_c: Option<[f64; 2]>,
}

/// The fits chosen.
#[derive(Clone, Debug)]
pub struct Selection {
    /// The model.
    pub model: String,
    /// The session its fits belong to (`all` for a model fitted over all sessions).
    pub session: String,
    /// One per accelerometer of the survey, in its manifest's order.
    pub targets: Vec<Target>,
}

fn list<'a>(items: impl IntoIterator<Item = &'a str>) -> String {
    items.into_iter().collect::<Vec<_>>().join(", ")
}

/// Checks the survey's accelerometers against the calibration's (by id, with the same
/// serial; the channel may differ) and picks the model's fits. Every error says what to
/// change.
pub fn select(
    cal: &Calibration,
    survey: &Dataset,
    choice: &Choice<'_>,
) -> Result<Selection, SelectError> {
    check_instrument(cal, survey)?;
    let unit = survey.manifest.instrument.reading_unit.name();
    if cal.reading_unit != unit {
        return Err(SelectError::ReadingUnit {
            fitted: cal.reading_unit.clone(),
            survey: unit.to_owned(),
        });
    }
    let mut models = BTreeSet::new();
    for (m, _) in fits(cal) {
        models.insert(m);
    }
    let model = match choice.model {
        Some(m) if models.contains(m) => m.to_owned(),
        Some(m) => {
            return Err(SelectError::NoSuchModel {
                model: m.to_owned(),
                has: list(models.iter().copied()),
            });
        }
        None if models.len() == 1 => models.first().map(|m| (*m).to_owned()).unwrap_or_default(),
        None => {
            return Err(SelectError::WhichModel {
                count: models.len(),
                has: list(models.iter().copied()),
            });
        }
    };
    let sessions: BTreeSet<&str> = fits(cal)
        .filter(|(m, _)| *m == model)
        .map(|(_, s)| s)
        .collect();
    let session = if sessions.len() == 1 && sessions.contains(ALL_SESSIONS) {
        if let Some(s) = choice.session {
            return Err(SelectError::SessionNotApplicable {
                model,
                session: s.to_owned(),
            });
        }
        ALL_SESSIONS.to_owned()
    } else {
        match choice.session {
            Some(s) if sessions.contains(s) => s.to_owned(),
            Some(s) => {
                return Err(SelectError::NoSuchSession {
                    model,
                    session: s.to_owned(),
                    has: list(sessions.iter().copied()),
                });
            }
            None => {
                return Err(SelectError::WhichSession {
                    model,
                    has: list(sessions.iter().copied()),
                });
            }
        }
    };
    let targets = survey
        .manifest
        .instrument
        .accelerometer
        .iter()
        .map(|acc| target(cal, &model, &session, acc))
        .collect::<Result<_, _>>()?;
    Ok(Selection {
        model,
        session,
        targets,
    })
}

/// Every (model, session) the calibration has a result or a skipped fit for.
fn fits(cal: &Calibration) -> impl Iterator<Item = (&str, &str)> {
    cal.results
        .iter()
        .map(|r| (r.model.as_str(), r.session.as_str()))
        .chain(
            cal.skipped
                .iter()
                .map(|s| (s.model.as_str(), s.session.as_str())),
        )
        .chain(
            cal.triad
                .iter()
                .map(|t| (t.model.as_str(), t.session.as_str())),
        )
}

/// The triad result of the selection, if its model is a triad model; with the survey's
/// channels (0-based) of the triad's x, y and z (the calibration's channels 1, 2, 3).
pub fn triad_of<'c>(
    cal: &'c Calibration,
    survey: &Dataset,
    selection: &Selection,
) -> Result<Option<(&'c TriadResult, [usize; 3])>, SelectError> {
    let Some(r) = cal
        .triad
        .iter()
        .find(|t| t.model == selection.model && t.session == selection.session)
    else {
        return Ok(None);
    };
    let unit = survey.manifest.instrument.reading_unit.name();
    if unit != r.reading_unit {
        return Err(SelectError::TriadReadingUnit {
            model: r.model.clone(),
            fitted: r.reading_unit.clone(),
            survey: unit.to_owned(),
        });
    }
    let mut channels = [0; 3];
    for (axis, slot) in channels.iter_mut().enumerate() {
        let id = cal
            .accelerometers
            .iter()
            .find(|a| usize::from(a.channel) == axis + 1)
            .map(|a| a.id.as_str())
            .ok_or(SelectError::NoChannel { channel: axis + 1 })?;
        let on = survey
            .manifest
            .instrument
            .accelerometer
            .iter()
            .find(|a| a.id == id)
            .ok_or_else(|| SelectError::AxisNotInSurvey {
                axis: ["x", "y", "z"][axis],
                id: id.to_owned(),
            })?;
        *slot = usize::from(on.channel).saturating_sub(1);
    }
    Ok(Some((r, channels)))
}

/// Every accelerometer of the survey must be one the calibration calibrated, by id and serial.
fn check_instrument(cal: &Calibration, survey: &Dataset) -> Result<(), SelectError> {
    if cal.accelerometers.is_empty() {
        return Err(SelectError::NoAccelerometers);
    }
    for acc in &survey.manifest.instrument.accelerometer {
        let Some(c) = cal.accelerometers.iter().find(|c| c.id == acc.id) else {
            return Err(SelectError::NotCalibrated {
                id: acc.id.clone(),
                calibrated: list(cal.accelerometers.iter().map(|c| c.id.as_str())),
            });
        };
        if c.serial != acc.serial {
            let show =
                |s: &Option<String>| s.as_deref().map_or("none".to_owned(), |s| format!("`{s}`"));
            return Err(SelectError::OtherSerial {
                id: acc.id.clone(),
                survey: show(&acc.serial),
                calibration: show(&c.serial),
            });
        }
    }
    Ok(())
}

/// The accelerometer's fit: its function, or why the calibration has none for it (a skipped
/// fit); a result that is there but cannot be trusted refuses the calibration.
fn target(
    cal: &Calibration,
    model: &str,
    session: &str,
    acc: &Accelerometer,
) -> Result<Target, SelectError> {
    let result = cal
        .results
        .iter()
        .find(|r| r.model == model && r.session == session && r.accelerometer == acc.id);
    let function = match result {
        Some(r) => Ok(CalibrationFunction::new(r)?),
        None => Err(cal
            .skipped
            .iter()
            .find(|s| s.model == model && s.session == session && s.accelerometer == acc.id)
            .map_or_else(
                || "no fit in the calibration".to_owned(),
                |s| format!("fit skipped: {}", s.reason),
            )),
    };
    Ok(Target {
        accelerometer: acc.clone(),
        function,
        counts_range: result.and_then(|r| r.counts_range),
        temperature_range_c: result.and_then(|r| r.temperature_range_c),
    })
}
