//! Applying a calibration (MODEL.md 6.7, FORMATS.md 8.5), `cargo xtask apply`.
//!
//! This module is the arithmetic, free of I/O: counts and temperature to the acceleration
//! along the sensitive axis, its sigma from the parameters' covariance, sigma_a^2 = J C J^T
//! with J = dc/dp at (Ng, T), and flags for counts or temperatures outside the ranges the
//! calibration saw (flagged, never silently extrapolated). [`select`] checks a calibration
//! against a survey's instrument and picks the fits to apply; [`stream`] is the stage: the
//! survey's ingested samples to `OUT/apply/acceleration.parquet` and `apply.json`.

pub mod select;
pub mod stream;

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
/// `c = b + k Ng + k2 Ng^2 + k3 Ng^3 + (b_t + k_t Ng)(T - t_ref)` and their covariance.
#[derive(Clone, Debug)]
pub struct CalibrationFunction {
    /// b, k, k2, k3, b_t, k_t (0 where the model has none).
    coef: [f64; 6],
    /// Their covariance (6 x 6, zero rows for absent terms).
    cov: [[f64; 6]; 6],
    temperature: bool,
    t_ref_c: f64,
    counts_range: Option<[f64; 2]>,
    temperature_range_c: Option<[f64; 2]>,
}

/// Where each parameter of the calibration function sits in `coef`.
const SLOTS: [&str; 6] = ["b", "k", "k2", "k3", "b_t", "k_t"];

impl CalibrationFunction {
    /// From a result of calibration.json: its parameters, sigmas and correlations (the
    /// misalignment's parameters describe the reference, not the function, and are left).
    pub fn new(r: &CalibrationResult) -> Result<Self, ApplyError> {
        let unusable = |what: String| ApplyError::Unusable {
            model: r.model.clone(),
            accelerometer: r.accelerometer.clone(),
            what,
        };
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
        Ok(Self {
            coef,
            cov,
            temperature: r.temperature,
            t_ref_c,
            counts_range: r.counts_range,
            temperature_range_c: r.temperature_range_c,
        })
    }

    /// Calibrates counts `ng` at temperature `temperature_c`.
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
        let j = [1.0, ng, ng * ng, ng * ng * ng, tau, tau * ng];
        let value: f64 = j.iter().zip(&self.coef).map(|(a, c)| a * c).sum();
        let var: f64 = (0..6)
            .map(|a| (0..6).map(|b| j[a] * self.cov[a][b] * j[b]).sum::<f64>())
            .sum();
        Applied {
            acceleration_mgal: Some(value),
            sigma_mgal: Some(var.max(0.0).sqrt()),
            flags,
        }
    }
}
