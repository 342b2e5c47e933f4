//! Applying a calibration (docs/model.md 6.7, docs/formats.md 8.5), `cargo xtask apply`.
//!
//! This module is the arithmetic, free of I/O: counts and temperature to the acceleration
//! along the sensitive axis, its sigma from the parameters' covariance, sigma_a^2 = J C J^T
//! with J = dc/dp at (Ng, T), and flags for counts or temperatures outside the ranges the
//! calibration saw (flagged, never silently extrapolated). [`select`] checks a calibration
//! against a survey's instrument and picks the fits to apply; [`stream`] is the stage: the
//! survey's ingested samples to `OUT/apply/acceleration.parquet` and `apply.json`.

pub mod select;
pub mod stream;
pub mod triad_stream;

use ingest::contract::calibration::CalibrationResult;
pub use ingest::contract::tables::applied::{
    COUNTS_OUT_OF_RANGE, NO_TEMPERATURE, TEMPERATURE_OUT_OF_RANGE,
};

/// One sample calibrated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Applied {
    /// Acceleration along the sensitive axis, mGal (None without a needed temperature).
    pub acceleration_mgal: Option<f64>,
    /// Its sd from the parameters' covariance, mGal.
    pub sigma_mgal: Option<f64>,
    /// The flags above, or-ed.
    pub flags: u8,
}

/// Why a calibration cannot be applied.
#[derive(Debug, thiserror::Error)]
pub enum ApplyError {
    /// The result lacks what applying needs.
    #[error("model {model} of {accelerometer}: {what}")]
    Unusable {
        /// Model name.
        model: String,
        /// Accelerometer.
        accelerometer: String,
        /// What is missing.
        what: String,
    },
}

/// A fitted calibration function, ready to apply: the coefficients of
/// `c = b + k Ng + k2 Ng^2 + k3 Ng^3 + (b_t + k_t Ng)(T - t_ref)` and their covariance,
/// gathered into polynomials in Ng and tau.
#[derive(Clone, Debug)]
pub struct CalibrationFunction {
    /// The value and the variance as polynomials in Ng, one per power of tau = T - t_ref
    /// (0..=2): `value[q][p]` multiplies Ng^p tau^q (what a sample's evaluation reads).
    value_poly: Polynomial,
    variance_poly: Polynomial,
    temperature: bool,
    t_ref_c: f64,
    counts_range: Option<[f64; 2]>,
    temperature_range_c: Option<[f64; 2]>,
}

/// A polynomial in Ng per power of tau, `c[q][p]` multiplying Ng^p tau^q, with the degrees
/// it has (the terms beyond are 0 and not evaluated).
#[derive(Clone, Debug)]
struct Polynomial {
    c: [[f64; 7]; 3],
    /// Per power of tau, the number of coefficients in Ng up to the last non-zero one.
    len: [usize; 3],
    /// Powers of tau up to the last non-empty one.
    rows: usize,
}

impl Polynomial {
    fn new(c: [[f64; 7]; 3]) -> Self {
        let len = c.map(|row| row.iter().rposition(|&x| x != 0.0).map_or(0, |i| i + 1));
        let rows = len.iter().rposition(|&n| n > 0).map_or(0, |i| i + 1);
        Polynomial { c, len, rows }
    }

    /// Horner in Ng for each power of tau, then in tau.
    #[inline]
    fn at(&self, ng: f64, tau: f64) -> f64 {
        let mut acc = 0.0;
        for q in (0..self.rows).rev() {
            let row = &self.c[q][..self.len[q]];
            acc = acc * tau + row.iter().rev().fold(0.0, |h, k| h * ng + k);
        }
        acc
    }
}

/// Powers of (Ng, tau) of each slot's derivative: J = [1, Ng, Ng^2, Ng^3, tau, tau Ng].
const POWERS: [(usize, usize); 6] = [(0, 0), (1, 0), (2, 0), (3, 0), (0, 1), (1, 1)];

/// J c and J C J^T as polynomials in Ng per power of tau, so that a sample costs two
/// Horner evaluations (the same sums, gathered by power; `apply` is checked against the
/// plain J C J^T in the tests).
fn polynomials(coef: &[f64; 6], cov: &[[f64; 6]; 6]) -> ([[f64; 7]; 3], [[f64; 7]; 3]) {
    let mut value = [[0.0; 7]; 3];
    let mut variance = [[0.0; 7]; 3];
    for a in 0..6 {
        let (pa, qa) = POWERS[a];
        value[qa][pa] += coef[a];
        for b in 0..6 {
            let (pb, qb) = POWERS[b];
            variance[qa + qb][pa + pb] += cov[a][b];
        }
    }
    (value, variance)
}

/// Where each parameter of the calibration function sits in `coef`.
const SLOTS: [&str; 6] = ["b", "k", "k2", "k3", "b_t", "k_t"];
/// The misalignment's parameters: they describe the reference, not the function.
const REFERENCE: [&str; 3] = ["beta", "theta_x", "theta_y"];

impl CalibrationFunction {
    /// From a result of calibration.json: its parameters, sigmas and correlations (the
    /// misalignment's parameters describe the reference, not the function, and are left).
    pub fn new(r: &CalibrationResult) -> Result<Self, ApplyError> {
        let unusable = |what: String| ApplyError::Unusable {
            model: r.model.clone(),
            accelerometer: r.accelerometer.clone(),
            what,
        };
        ingest::contract::calibration::check_parameters(&r.parameters, &r.correlation)
            .map_err(unusable)?;
        if let Some(p) = r
            .parameters
            .iter()
            .find(|p| !SLOTS.contains(&p.name.as_str()) && !REFERENCE.contains(&p.name.as_str()))
        {
            return Err(unusable(format!(
                "a term `{}` this version cannot evaluate (it knows {} and the misalignment's {})",
                p.name,
                SLOTS.join(", "),
                REFERENCE.join(", ")
            )));
        }
        let mut index = [None; 6];
        for (slot, name) in SLOTS.iter().enumerate() {
            index[slot] = r.parameters.iter().position(|p| p.name == *name);
        }
        if index[0].is_none() || index[1].is_none() {
            return Err(unusable("no b or k".to_owned()));
        }
        let n = r.parameters.len();
        if r.correlation.len() != n || r.correlation.iter().any(|row| row.len() != n) {
            return Err(unusable(format!(
                "a correlation matrix that is not {n} x {n}"
            )));
        }
        let mut coef = [0.0; 6];
        let mut cov = [[0.0; 6]; 6];
        for (a, ia) in index.iter().enumerate() {
            let Some(ia) = *ia else { continue };
            coef[a] = r.parameters[ia].value;
            for (b, ib) in index.iter().enumerate() {
                let Some(ib) = *ib else { continue };
                cov[a][b] = r.parameters[ia].sigma * r.parameters[ib].sigma * r.correlation[ia][ib];
            }
        }
        let t_ref_c = match (r.temperature, r.t_ref_c) {
            (true, Some(t)) => t,
            (true, None) => return Err(unusable("temperature terms without t_ref_c".to_owned())),
            (false, _) => 0.0,
        };
        if let Some((a, b)) = (0..6)
            .flat_map(|a| (0..6).map(move |b| (a, b)))
            .find(|&(a, b)| !cov[a][b].is_finite())
        {
            return Err(unusable(format!(
                "the covariance of {} and {} overflows",
                SLOTS[a], SLOTS[b]
            )));
        }
        let (value, variance) = polynomials(&coef, &cov);
        let (value_poly, variance_poly) = (Polynomial::new(value), Polynomial::new(variance));
        let function = Self {
            value_poly,
            variance_poly,
            temperature: r.temperature,
            t_ref_c,
            counts_range: r.counts_range,
            temperature_range_c: r.temperature_range_c,
        };
        function.finite_where_used().map_err(unusable)?;
        Ok(function)
    }

    /// A calibration its maker states (docs/formats.md 11.1): the meter's gravity `offset +
    /// scale * reading`, given in the axis models' convention, F = -(offset + scale *
    /// reading) (an axis's F is minus the specific force along it: -g pointing up); its
    /// variance from the stated sds (none: exact), uncorrelated; no range it was fitted
    /// over, so no sample is flagged as beyond one.
    pub fn vendor(v: &ingest::contract::manifest::VendorCalibration) -> Self {
        let mut coef = [0.0; 6];
        let mut cov = [[0.0; 6]; 6];
        coef[0] = -v.offset_mgal;
        coef[1] = -v.scale;
        cov[0][0] = v.sd_offset_mgal.unwrap_or(0.0).powi(2);
        cov[1][1] = v.sd_scale.unwrap_or(0.0).powi(2);
        let (value, variance) = polynomials(&coef, &cov);
        Self {
            value_poly: Polynomial::new(value),
            variance_poly: Polynomial::new(variance),
            temperature: false,
            t_ref_c: 0.0,
            counts_range: None,
            temperature_range_c: None,
        }
    }

    /// Where the calibration is meant to be used (the corners of its counts' and
    /// temperatures' ranges), its value and sigma must be numbers.
    fn finite_where_used(&self) -> Result<(), String> {
        let counts = self.counts_range.map_or(vec![0.0], |[lo, hi]| vec![lo, hi]);
        let taus = match (self.temperature, self.temperature_range_c) {
            (true, Some([lo, hi])) => vec![lo - self.t_ref_c, hi - self.t_ref_c],
            _ => vec![0.0],
        };
        for &ng in &counts {
            for &tau in &taus {
                let (v, var) = (self.value_poly.at(ng, tau), self.variance_poly.at(ng, tau));
                if !(v.is_finite() && var.is_finite()) {
                    return Err(format!(
                        "at {ng} counts the function gives {v} (variance {var}): its \
                         parameters overflow the arithmetic"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Calibrates counts `ng` at temperature `temperature_c`.
    #[inline]
    pub fn apply(&self, ng: f64, temperature_c: Option<f64>) -> Applied {
        let mut flags = 0;
        if self
            .counts_range
            .is_some_and(|[lo, hi]| !(lo..=hi).contains(&ng))
        {
            flags |= COUNTS_OUT_OF_RANGE;
        }
        if let (Some(t), Some([lo, hi])) = (temperature_c, self.temperature_range_c)
            && !(lo..=hi).contains(&t)
        {
            flags |= TEMPERATURE_OUT_OF_RANGE;
        }
        let tau = match (self.temperature, temperature_c) {
            (false, _) => 0.0,
            (true, Some(t)) => t - self.t_ref_c,
            (true, None) => {
                return Applied {
                    acceleration_mgal: None,
                    sigma_mgal: None,
                    flags: flags | NO_TEMPERATURE,
                };
            }
        };
        let (value, var) = (self.value_poly.at(ng, tau), self.variance_poly.at(ng, tau));
        Applied {
            acceleration_mgal: Some(value),
            sigma_mgal: Some(var.max(0.0).sqrt()),
            flags,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The polynomials give J c and J C J^T summed plainly, to rounding.
    #[test]
    fn polynomials_are_the_plain_sums() {
        let coef = [-29_440.4, 0.242_92, 3.1e-9, -2.0e-16, 14.16, -3.2e-5];
        let sd = [0.42, 1.7e-7, 4.0e-12, 3.0e-19, 0.14, 5.5e-8];
        let mut cov = [[0.0; 6]; 6];
        for a in 0..6 {
            for b in 0..6 {
                let rho = if a == b {
                    1.0
                } else {
                    0.9 * (-0.5f64).powi((a + b) as i32 % 3)
                };
                cov[a][b] = rho * sd[a] * sd[b];
            }
        }
        let (value, variance) = polynomials(&coef, &cov);
        let f = CalibrationFunction {
            value_poly: Polynomial::new(value),
            variance_poly: Polynomial::new(variance),
            temperature: true,
            t_ref_c: 28.0,
            counts_range: None,
            temperature_range_c: None,
        };
        for (ng, t) in [(1.4e6, 24.8), (2.6e6, 31.0), (3.3e6, 33.5), (-1.0e5, 28.0)] {
            let tau = t - 28.0;
            let j = [1.0, ng, ng * ng, ng * ng * ng, tau, tau * ng];
            let want_value: f64 = (0..6).map(|a| j[a] * coef[a]).sum();
            let want_var: f64 = (0..6)
                .map(|a| (0..6).map(|b| j[a] * cov[a][b] * j[b]).sum::<f64>())
                .sum();
            let got = f.apply(ng, Some(t));
            let value = got.acceleration_mgal.expect("value");
            let sigma = got.sigma_mgal.expect("sigma");
            assert!(
                (value - want_value).abs() <= 1e-12 * want_value.abs(),
                "{value} {want_value}"
            );
            assert!(
                (sigma - want_var.sqrt()).abs() <= 1e-9 * want_var.sqrt(),
                "{sigma} {}",
                want_var.sqrt()
            );
        }
    }
}
