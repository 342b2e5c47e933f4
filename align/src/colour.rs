//! gravcal's model of ADC noise that is not white (docs/model.md 6.2), shared by the simulator
//! (which generates it) and adjust (which propagates it into the parameters' covariance).
//!
//! Flicker is the sum of first-order Gauss-Markov processes of equal variance with time
//! constants two to a decade from [`FLICKER_T_MIN_S`] to [`FLICKER_T_MAX_S`]: its Allan
//! variance is flat to within a few per cent between about 2 s and 2000 s, scaled so that the
//! flat part is Allan's flicker floor (2 ln 2 / pi) B^2. Pure 1/f noise has no variance; a
//! real sensor's flicker bends to white somewhere below its lowest frequency, and that corner
//! cannot be seen in a calibration's two-minute stations: gravcal assumes it at
//! [`FLICKER_T_MAX_S`], about the length of a session. The random walk has Allan variance
//! K^2 tau / 3 and starts afresh with each session.

/// Shortest time constant of the flicker's processes, s.
pub const FLICKER_T_MIN_S: f64 = 0.5;
/// Longest, s: the assumed corner of the flicker.
pub const FLICKER_T_MAX_S: f64 = 5000.0;
/// Allan's flicker coefficient: sigma^2(tau) = (2 ln 2 / pi) B^2.
pub const FLICKER_AVAR: f64 = 2.0 * std::f64::consts::LN_2 / std::f64::consts::PI;

/// Flicker of bias instability B as a sum of Gauss-Markov processes.
#[derive(Clone, Debug, PartialEq)]
pub struct Flicker {
    /// Time constants, s.
    pub time_constants_s: Vec<f64>,
    /// Variance of each process, unit^2.
    pub variance: f64,
}

/// Allan variance of a first-order Gauss-Markov process of unit variance and time constant
/// `t` at averaging time `tau`.
fn gauss_markov_avar(t: f64, tau: f64) -> f64 {
    let x = tau / t;
    (2.0 * x - 3.0 + 4.0 * (-x).exp() - (-2.0 * x).exp()) / (x * x)
}

impl Flicker {
    /// The processes of bias instability `b` (unit of the series).
    pub fn new(b: f64) -> Self {
        let decades = (FLICKER_T_MAX_S / FLICKER_T_MIN_S).log10();
        let n = (2.0 * decades).round() as i32;
        let t: Vec<f64> = (0..=n)
            .map(|i| FLICKER_T_MIN_S * 10f64.powf(f64::from(i) / 2.0))
            .collect();
        // Unit-variance processes' mean Allan variance over the flat part, 2 s..2000 s.
        let taus: Vec<f64> = (0..=30)
            .map(|i| 2.0 * 10f64.powf(f64::from(i) / 10.0))
            .collect();
        let unit = taus
            .iter()
            .map(|&tau| t.iter().map(|&tk| gauss_markov_avar(tk, tau)).sum::<f64>())
            .sum::<f64>()
            / taus.len() as f64;
        Self {
            time_constants_s: t,
            variance: FLICKER_AVAR * b * b / unit,
        }
    }

    /// Covariance of two values `dt_s` apart.
    pub fn covariance(&self, dt_s: f64) -> f64 {
        self.time_constants_s
            .iter()
            .map(|&t| self.variance * (-dt_s.abs() / t).exp())
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_floor_is_flat_and_scaled() {
        let f = Flicker::new(1.0);
        for tau in [3.0, 30.0, 300.0, 1500.0] {
            let avar: f64 = f
                .time_constants_s
                .iter()
                .map(|&t| f.variance * gauss_markov_avar(t, tau))
                .sum();
            assert!((avar / FLICKER_AVAR - 1.0).abs() < 0.1, "{tau}: {avar}");
        }
    }
}
