//! Sizing an antenna array before buying it (docs/planning.md, "An antenna array"): what a
//! declared array, its antennas' position noise and the survey's filter give in attitude
//! and in north and east gravity, per epoch and filtered, at each heading of a level
//! vehicle. The fit is the one the stage makes ([`super::antennas`]) on noise-free
//! positions, its covariance the prediction; north's and east's errors are g times the
//! tilt about east and north (white per epoch, as the positions are), through the filter's
//! noise gain (the square root of the sum of its row's squares). No I/O.

use super::antennas::{self, Fix};
use serde::{Deserialize, Serialize};

/// An array plan: `[array]`.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ArrayPlan {
    /// What it is.
    #[serde(default)]
    pub description: String,
    /// The array.
    pub array: PlanArray,
}

/// `[array]`: the antennas, their noise, the epochs' rate and the survey's filter.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct PlanArray {
    /// Each antenna's phase centre, vehicle frame (x forward, y right, z down), m, from the
    /// accelerometers.
    pub positions_m: Vec<[f64; 3]>,
    /// One position's sd, horizontal and vertical, m.
    pub sd_m: [f64; 2],
    /// The positions' rate, Hz.
    pub rate_hz: f64,
    /// The survey's Butterworth filter period, s.
    pub filter_s: f64,
    /// Gravity, mGal (default 980 000).
    #[serde(default = "default_g")]
    pub g_mgal: f64,
}

fn default_g() -> f64 {
    980_000.0
}

/// What the array gives at one heading.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct AtHeading {
    /// The heading, deg (level).
    pub heading_deg: f64,
    /// The sds of heading, pitch and roll per epoch, mrad.
    pub sd_hpr_mrad: [f64; 3],
    /// North's and east's sds per epoch, mGal.
    pub sd_epoch_mgal: [f64; 2],
    /// Through the filter, mGal.
    pub sd_filtered_mgal: [f64; 2],
    /// The accelerometers' position's sds north, east, down per epoch, m.
    pub sd_position_m: [f64; 3],
}

/// Why a plan cannot be predicted.
#[derive(Debug, thiserror::Error)]
#[error("array.{key}: {message}")]
pub struct PlanArrayError {
    key: &'static str,
    message: String,
}

/// The array's prediction at headings 0 to 315 deg, every 45.
pub fn predict(plan: &ArrayPlan) -> Result<Vec<AtHeading>, PlanArrayError> {
    let a = &plan.array;
    let bad = |key, message: String| PlanArrayError { key, message };
    if a.positions_m.len() < 3 || a.positions_m.len() > 8 {
        return Err(bad(
            "positions_m",
            format!("{} antennas: the fit needs 3 to 8", a.positions_m.len()),
        ));
    }
    if !(a.sd_m.iter().all(|s| *s > 0.0 && *s < 10.0)) {
        return Err(bad("sd_m", format!("{:?}: sds in (0, 10) m", a.sd_m)));
    }
    if !(a.rate_hz > 0.0 && a.rate_hz <= 100.0 && a.filter_s * a.rate_hz > 2.0) {
        return Err(bad(
            "filter_s",
            format!(
                "{} s at {} Hz: the rate in (0, 100] Hz, the filter longer than two epochs",
                a.filter_s, a.rate_hz
            ),
        ));
    }
    let dt = 1.0 / a.rate_hz;
    let lowpass = super::filter::Lowpass::design(
        ingest::contract::survey::FilterKind::Butterworth,
        1.0 / a.filter_s,
        a.rate_hz,
    )
    .map_err(|e| bad("filter_s", e.to_string()))?;
    let row = super::reduce::row(&lowpass, super::reduce::reach(a.filter_s, dt), None);
    let gain = row.iter().map(|w| w * w).sum::<f64>().sqrt();
    let sd = [a.sd_m[0], a.sd_m[0], a.sd_m[1]];
    (0..8)
        .map(|k| {
            let heading = f64::from(k) * 45.0;
            let c = super::attitude::rotation(heading.to_radians(), 0.0, 0.0);
            let fixes: Vec<Option<Fix>> = (a.positions_m.iter())
                .map(|b| {
                    Some(Fix {
                        ned_m: super::attitude::apply(&c, *b),
                        sd_m: sd,
                    })
                })
                .collect();
            let s = antennas::solve(&a.positions_m, &fixes, f64::INFINITY).map_err(|_| {
                bad(
                    "positions_m",
                    "the antennas lie in a line: roll about it is not seen".to_owned(),
                )
            })?;
            let hpr = s.hpr_covariance();
            // North's error is g times the tilt about east, east's g times the tilt about
            // north.
            let epoch = [
                a.g_mgal * s.covariance[4][4].sqrt(),
                a.g_mgal * s.covariance[3][3].sqrt(),
            ];
            Ok(AtHeading {
                heading_deg: heading,
                sd_hpr_mrad: std::array::from_fn(|i| hpr[i][i].sqrt() * 1e3),
                sd_epoch_mgal: epoch,
                sd_filtered_mgal: epoch.map(|v| v * gain),
                sd_position_m: std::array::from_fn(|i| s.covariance[i][i].sqrt()),
            })
        })
        .collect()
}

/// The prediction as a table.
pub fn render(plan: &ArrayPlan, rows: &[AtHeading]) -> String {
    let a = &plan.array;
    let mut out = format!(
        "{} antennas, {} m horizontal and {} m vertical at {} Hz, a {} s Butterworth; level:\n\n\
         | heading deg | sd heading, pitch, roll mrad | sd north, east per epoch mGal | \
         filtered mGal | sd position N, E, D cm |\n|---|---|---|---|---|\n",
        a.positions_m.len(),
        a.sd_m[0],
        a.sd_m[1],
        a.rate_hz,
        a.filter_s
    );
    for r in rows {
        let [h, p, ro] = r.sd_hpr_mrad;
        let [n, e] = r.sd_epoch_mgal;
        let [fnn, fe] = r.sd_filtered_mgal;
        let [pn, pe, pd] = r.sd_position_m.map(|v| v * 100.0);
        out += &format!(
            "| {:.0} | {h:.2}, {p:.2}, {ro:.2} | {n:.0}, {e:.0} | {fnn:.1}, {fe:.1} | {pn:.2}, \
             {pe:.2}, {pd:.2} |\n",
            r.heading_deg
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The boat's array of `fixtures::survey_lines::four_antennas` at 5 mm and 10 mm:
    /// pitch and roll come from the vertical noise and heading from the horizontal, so
    /// heading's sd is below pitch's and roll's; a 3 m baseline of 5 mm ends turns by
    /// about sqrt(2) 5 mm / 3 m; filtered, the sds scale by the filter's noise gain.
    #[test]
    fn the_boats_array_is_sized() {
        let plan = ArrayPlan {
            description: String::new(),
            array: PlanArray {
                positions_m: vec![
                    [1.6, 0.0, -2.1],
                    [-1.4, 0.0, -2.0],
                    [0.0, 1.3, -1.9],
                    [0.1, -1.2, -2.2],
                ],
                sd_m: [0.005, 0.010],
                rate_hz: 10.0,
                filter_s: 100.0,
                g_mgal: 980_000.0,
            },
        };
        let rows = predict(&plan).expect("predicted");
        eprintln!("{}", render(&plan, &rows));
        let r = &rows[2];
        assert!(r.sd_hpr_mrad[0] < r.sd_hpr_mrad[1] && r.sd_hpr_mrad[0] < r.sd_hpr_mrad[2]);
        assert!((1.0..3.0).contains(&r.sd_hpr_mrad[0]), "{r:?}");
        let ratio = r.sd_filtered_mgal[0] / r.sd_epoch_mgal[0];
        assert!((0.01..0.2).contains(&ratio), "{ratio}");
        let mut bad = plan.clone();
        bad.array.positions_m.truncate(2);
        assert!(predict(&bad).is_err());
    }
}
