//! Which fits of a calibration to apply to a survey, after the checks docs/formats.md 8.5 asks
//! for before any work: the survey's accelerometers are the calibration's (ids and
//! serials), the model exists, and a model fitted per session is applied only with the
//! session named.

use super::CalibrationFunction;
use ingest::contract::calibration::{ALL_SESSIONS, Calibration, TriadResult};
use ingest::contract::manifest::{Accelerometer, Dataset};
use std::collections::BTreeSet;

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
) -> Result<Selection, String> {
    check_instrument(cal, survey)?;
    let unit = survey.manifest.instrument.reading_unit.name();
    if cal.reading_unit != unit {
        return Err(format!(
            "the calibration was fitted on readings in {}, the survey's are in {unit} \
             (the instrument's reading_unit)",
            cal.reading_unit
        ));
    }
    let mut models = BTreeSet::new();
    for (m, _) in fits(cal) {
        models.insert(m);
    }
    let model = match choice.model {
        Some(m) if models.contains(m) => m.to_owned(),
        Some(m) => {
            return Err(format!(
                "model `{m}` is not in the calibration (it has: {})",
                list(models.iter().copied())
            ));
        }
        None if models.len() == 1 => models.first().map(|m| (*m).to_owned()).unwrap_or_default(),
        None => {
            return Err(format!(
                "the calibration holds {} models ({}): name one with --model",
                models.len(),
                list(models.iter().copied())
            ));
        }
    };
    let sessions: BTreeSet<&str> = fits(cal)
        .filter(|(m, _)| *m == model)
        .map(|(_, s)| s)
        .collect();
    let session = if sessions.len() == 1 && sessions.contains(ALL_SESSIONS) {
        if let Some(s) = choice.session {
            return Err(format!(
                "model `{model}` is fitted over all sessions: --session {s} does not apply"
            ));
        }
        ALL_SESSIONS.to_owned()
    } else {
        match choice.session {
            Some(s) if sessions.contains(s) => s.to_owned(),
            Some(s) => {
                return Err(format!(
                    "model `{model}` has no fits for session `{s}` (it has: {})",
                    list(sessions.iter().copied())
                ));
            }
            None => {
                return Err(format!(
                    "model `{model}` is fitted per session ({}): name the one to apply with \
                     --session",
                    list(sessions.iter().copied())
                ));
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
) -> Result<Option<(&'c TriadResult, [usize; 3])>, String> {
    let Some(r) = cal
        .triad
        .iter()
        .find(|t| t.model == selection.model && t.session == selection.session)
    else {
        return Ok(None);
    };
    let unit = survey.manifest.instrument.reading_unit.name();
    if unit != r.reading_unit {
        return Err(format!(
            "triad {} was calibrated on readings in {}, the survey's are in {unit}",
            r.model, r.reading_unit
        ));
    }
    let mut channels = [0; 3];
    for (axis, slot) in channels.iter_mut().enumerate() {
        let id = cal
            .accelerometers
            .iter()
            .find(|a| usize::from(a.channel) == axis + 1)
            .map(|a| a.id.as_str())
            .ok_or_else(|| {
                format!(
                    "the calibration has no accelerometer on channel {}",
                    axis + 1
                )
            })?;
        let on = survey
            .manifest
            .instrument
            .accelerometer
            .iter()
            .find(|a| a.id == id)
            .ok_or_else(|| {
                format!(
                    "the triad's axis {} is accelerometer `{id}`, not in the survey",
                    ["x", "y", "z"][axis]
                )
            })?;
        *slot = usize::from(on.channel).saturating_sub(1);
    }
    Ok(Some((r, channels)))
}

/// Every accelerometer of the survey must be one the calibration calibrated, by id and serial.
fn check_instrument(cal: &Calibration, survey: &Dataset) -> Result<(), String> {
    if cal.accelerometers.is_empty() {
        return Err(
            "the calibration does not list its accelerometers (written before gravcal recorded \
             them): re-run adjust on its dataset"
                .to_owned(),
        );
    }
    for acc in &survey.manifest.instrument.accelerometer {
        let Some(c) = cal.accelerometers.iter().find(|c| c.id == acc.id) else {
            return Err(format!(
                "accelerometer `{}` of the survey is not in the calibration (which calibrated {})",
                acc.id,
                list(cal.accelerometers.iter().map(|c| c.id.as_str()))
            ));
        };
        if c.serial != acc.serial {
            let show =
                |s: &Option<String>| s.as_deref().map_or("none".to_owned(), |s| format!("`{s}`"));
            return Err(format!(
                "accelerometer `{}`: serial {} in the survey's manifest, {} in the calibration's: \
                 not the same instrument",
                acc.id,
                show(&acc.serial),
                show(&c.serial)
            ));
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
) -> Result<Target, String> {
    let result = cal
        .results
        .iter()
        .find(|r| r.model == model && r.session == session && r.accelerometer == acc.id);
    let function = match result {
        Some(r) => Ok(CalibrationFunction::new(r).map_err(|e| e.to_string())?),
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
