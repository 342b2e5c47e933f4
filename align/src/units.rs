//! The theodolite's declared unit held to its readings (issue 49). A log in gon declared
//! `deg` still reads as angles and passes ingest's range check; before this check the fits
//! then failed to converge and the run ended in "No calibration was fitted" with no word on
//! the unit.
//!
//! An accelerometer on a tilt table reads, to its noise and its small higher-order terms,
//! a + B cos(Dz + beta): the projection of gravity on its axis, beta its misalignment in the
//! plane of the turn, a fraction of a degree (docs/model.md 2). Fitted as
//! a + b cos(Dz) + c sin(Dz), that is beta = atan(-c / b). Read in another unit, the same
//! values either miss the curve by a good part of the counts' spread, or, over the narrow
//! range a table often turns through (esgt-2005's 109-140 deg), fit it only by a phase of
//! ten degrees or more: gon read as degrees is the same curve stretched by 0.9. A unit is
//! plausible for an accelerometer when the fit misses by less than [`FLOOR`] of the counts'
//! sd and its beta is within [`BETA_MAX_DEG`]. Each accelerometer of a tilt-table session
//! with at least [`MIN_READINGS`] readings at [`MIN_STATIONS`] stations is fitted in every
//! unit; when the declared unit is plausible for none of them and one other unit for all of
//! them, align stops and names the session, the manifest key and that unit.

use crate::{Error, Observation, Result};
use faer::prelude::*;
use ingest::contract::manifest::{AngleUnit, Dataset};

/// Readings an accelerometer needs before its fit is asked about the unit.
pub const MIN_READINGS: usize = 8;
/// Stations (distinct tilts) it needs as well: three parameters fit three tilts exactly in
/// any unit, so a unit is told from another only from a fourth on.
pub const MIN_STATIONS: usize = 4;
/// The largest rms misfit, as a fraction of the counts' sd, of a plausible unit: the
/// QA3000's second-order and cross-axis terms leave well under 1e-3 (esgt-2005: 1.5e-4).
pub const FLOOR: f64 = 0.01;
/// The largest misalignment in the plane of the turn of a plausible unit, degrees: a mounted
/// accelerometer's is a fraction of a degree (gon-gpst's, in gon: 0.00).
pub const BETA_MAX_DEG: f64 = 3.0;

/// The units a theodolite log may be declared in.
const UNITS: [AngleUnit; 3] = [AngleUnit::Deg, AngleUnit::Gon, AngleUnit::Rad];

/// Fails on the first tilt-table session of `ds` whose readings in `observations` fit
/// another unit than the one its manifest declares ([`FLOOR`], [`BETA_MAX_DEG`]).
pub(crate) fn check(ds: &Dataset, observations: &[Observation]) -> Result<()> {
    for s in ds.sessions.iter().filter(|s| s.is_tilt_table()) {
        let declared = s.session.theodolite_unit;
        let mut verdicts = Vec::new();
        for acc in &ds.manifest.instrument.accelerometer {
            // (station, logged value, counts) of each reading with counts.
            let used: Vec<(&str, f64, f64)> = observations
                .iter()
                .filter(|o| o.session == s.session.id && o.accelerometer == acc.id)
                .filter_map(|o| Some((o.station.as_str(), o.dz_rad / declared.to_rad(1.0), o.ng?)))
                .collect();
            let stations: std::collections::BTreeSet<&str> = used.iter().map(|u| u.0).collect();
            let (values, counts): (Vec<f64>, Vec<f64>) = used.iter().map(|u| (u.1, u.2)).unzip();
            if values.len() >= MIN_READINGS && stations.len() >= MIN_STATIONS {
                verdicts.push((acc.id.as_str(), fits(&values, &counts)));
            }
        }
        if let Some(message) = verdict(declared, &verdicts) {
            return Err(Error::TheodoliteUnit {
                session: s.session.id.clone(),
                message,
            });
        }
    }
    Ok(())
}

/// One unit's fit of an accelerometer's counts to a + b cos(Dz) + c sin(Dz).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Fit {
    /// The rms misfit as a fraction of the counts' sd (NaN where no fit could be made).
    misfit: f64,
    /// The misalignment the fit implies, atan(-c / b), degrees.
    beta_deg: f64,
}

impl Fit {
    /// Whether the fit is one a mounted accelerometer gives ([`FLOOR`], [`BETA_MAX_DEG`]).
    fn plausible(self) -> bool {
        self.misfit < FLOOR && self.beta_deg.abs() < BETA_MAX_DEG
    }
}

/// Per unit of [`UNITS`], the fit of `counts` to a + b cos(Dz) + c sin(Dz) with Dz the
/// logged `values` in that unit (faer's least squares by QR).
fn fits(values: &[f64], counts: &[f64]) -> [Fit; 3] {
    let n = counts.len();
    let mean = counts.iter().sum::<f64>() / n as f64;
    let sd = (counts.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
    UNITS.map(|unit| {
        let design = Mat::<f64>::from_fn(n, 3, |i, j| {
            let dz = unit.to_rad(values[i]);
            [1.0, dz.cos(), dz.sin()][j]
        });
        let y = Mat::<f64>::from_fn(n, 1, |i, _| counts[i] - mean);
        let p = design.qr().solve_lstsq(&y);
        let rss = (&y - &design * &p).squared_norm_l2();
        Fit {
            misfit: (rss / n as f64).sqrt() / sd,
            beta_deg: (-p[(2, 0)] / p[(1, 0)]).atan().to_degrees(),
        }
    })
}

/// What to say when the `declared` unit is plausible for none of the accelerometers'
/// `fits` and one other unit for all of them; None otherwise.
fn verdict(declared: AngleUnit, verdicts: &[(&str, [Fit; 3])]) -> Option<String> {
    let at = |u: AngleUnit| UNITS.iter().position(|x| *x == u).unwrap_or(0);
    if verdicts.is_empty() || verdicts.iter().any(|(_, f)| f[at(declared)].plausible()) {
        return None;
    }
    let mut others = UNITS
        .into_iter()
        .filter(|&u| u != declared && verdicts.iter().all(|(_, f)| f[at(u)].plausible()));
    let unit = others.next()?;
    if others.next().is_some() {
        return None;
    }
    let said = |f: Fit, u: AngleUnit| {
        format!(
            "in {} it misses by {:.1e} of its counts' sd with a misalignment of {:.2} deg",
            u.name(),
            f.misfit,
            f.beta_deg
        )
    };
    let fits: Vec<String> = verdicts
        .iter()
        .map(|(acc, f)| {
            format!(
                "{acc}: {}, {}",
                said(f[at(declared)], declared),
                said(f[at(unit)], unit)
            )
        })
        .collect();
    Some(format!(
        "the theodolite log is declared `theodolite_unit = \"{}\"` in the manifest, but its readings are in {} (a mounted accelerometer misses a + b cos(Dz) + c sin(Dz) by under {FLOOR} of its counts' sd, with a misalignment under {BETA_MAX_DEG} deg): {}. Set `theodolite_unit = \"{}\"`",
        declared.name(),
        unit.name(),
        fits.join("; "),
        unit.name()
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts of an accelerometer at the zenith distances `dz_deg`, misaligned by 0.05 deg
    /// (b, k of esgt-2005's order, 0.3 counts of noise from a fixed sequence).
    fn counts(dz_deg: &[f64]) -> Vec<f64> {
        dz_deg
            .iter()
            .enumerate()
            .map(|(i, d)| {
                let a = -981_000.0 * (d + 0.05f64).to_radians().cos();
                (a - 20.0) / 0.243 + 0.3 * ((i * 7919 % 13) as f64 / 6.0 - 1.0)
            })
            .collect()
    }

    /// Over esgt-2005's narrow range (109-140 deg), a log in degrees declared gon, or in gon
    /// declared degrees, is named with the unit its values fit; declared as it is, it
    /// passes; over a wide range too; two accelerometers that disagree name nothing.
    #[test]
    fn a_unit_the_readings_do_not_fit_is_named() {
        for (from, step) in [(109.0, 2.5), (5.0, 15.0)] {
            let dz_deg: Vec<f64> = (0..13).map(|i| from + step * f64::from(i)).collect();
            let c = counts(&dz_deg);
            let as_deg = fits(&dz_deg, &c);
            assert!(
                as_deg[0].plausible() && !as_deg[1].plausible(),
                "{as_deg:?}"
            );
            assert!((as_deg[0].beta_deg - 0.05).abs() < 1e-3, "{as_deg:?}");
            assert_eq!(verdict(AngleUnit::Deg, &[("acc1", as_deg)]), None);
            let said = verdict(AngleUnit::Gon, &[("acc1", as_deg), ("acc2", as_deg)])
                .expect("deg declared gon is named");
            assert!(
                said.contains("declared `theodolite_unit = \"gon\"`")
                    && said.ends_with("Set `theodolite_unit = \"deg\"`"),
                "{said}"
            );
            let dz_gon: Vec<f64> = dz_deg.iter().map(|d| d / 0.9).collect();
            let as_gon = fits(&dz_gon, &c);
            let said = verdict(AngleUnit::Deg, &[("acc1", as_gon)]).expect("gon declared deg");
            assert!(said.ends_with("Set `theodolite_unit = \"gon\"`"), "{said}");
            let mixed = [("acc1", as_deg), ("acc2", as_gon)];
            assert_eq!(verdict(AngleUnit::Rad, &mixed), None);
        }
    }
}
