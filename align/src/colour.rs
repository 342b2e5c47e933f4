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

/// The covariances of means over windows of one length ([`Flicker::windowed`]).
#[derive(Clone, Debug)]
pub struct WindowedFlicker<'a> {
    flicker: &'a Flicker,
    window_s: f64,
    /// [`Flicker::window_factors`] at `window_s`.
    factors: Vec<(f64, f64)>,
}

impl WindowedFlicker<'_> {
    /// Covariance of two means over the windows whose centres are `dt_s` apart
    /// ([`Flicker::window_covariance`]).
    pub fn covariance(&self, dt_s: f64) -> f64 {
        let (flicker, window_s) = (self.flicker, self.window_s);
        let dt = dt_s.abs();
        if window_s <= 0.0 {
            return flicker.covariance(dt);
        }
        if dt == 0.0 || dt >= window_s {
            return flicker
                .time_constants_s
                .iter()
                .zip(&self.factors)
                .map(|(&t, &(f, g))| {
                    flicker.variance * if dt == 0.0 { g } else { f * (-dt / t).exp() }
                })
                .sum();
        }
        flicker.lag_averaged(dt, window_s, 400)
    }
}

/// The factor two means over windows of x time constants that do not overlap put on their
/// process's covariance ([`Flicker::window_factors`]' f).
fn apart_factor(x: f64) -> f64 {
    (2.0 * x.cosh() - 2.0) / (x * x)
}

/// The factor the mean over a window of x time constants puts on its process's variance
/// ([`Flicker::window_factors`]' g).
fn same_factor(x: f64) -> f64 {
    2.0 * (x - 1.0 + (-x).exp()) / (x * x)
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

    /// The Allan variance of this flicker at averaging time `tau_s`: the flicker floor
    /// (2 ln 2 / pi) B^2 from about 2 s up, less below, where the shortest processes bend it
    /// down (0.15 of the floor at 0.1 s, 0.72 at 1 s). A fit of the Allan curve takes
    /// this shape, so that the bend is not read as a random walk.
    pub fn allan_variance(&self, tau_s: f64) -> f64 {
        self.variance
            * self
                .time_constants_s
                .iter()
                .map(|&t| gauss_markov_avar(t, tau_s))
                .sum::<f64>()
    }

    /// Per time constant, the factors a mean over a window of `window_s` puts on its process's
    /// variance: (f, g), f for two such means whose windows do not overlap (their covariance
    /// is f variance exp(-|dt| / T), the exponential kept), g for one and the same window
    /// (its variance g variance, below the point's for T short beside the window).
    pub fn window_factors(&self, window_s: f64) -> Vec<(f64, f64)> {
        self.time_constants_s
            .iter()
            .map(|&t| (apart_factor(window_s / t), same_factor(window_s / t)))
            .collect()
    }

    /// Covariance of two means over windows of `window_s` whose centres are `dt_s` apart:
    /// the point covariance averaged over both windows, in closed form when they do not
    /// overlap or are one, by Simpson's rule over the lag when they overlap.
    pub fn window_covariance(&self, dt_s: f64, window_s: f64) -> f64 {
        self.windowed(window_s).covariance(dt_s)
    }

    /// [`Flicker::window_covariance`] for many pairs of windows of one length `window_s`:
    /// each time constant's factors computed once (the adjustment's Monte-Carlos ask for
    /// every pair of windows, and the factors' cosh and exp were most of their time).
    pub fn windowed(&self, window_s: f64) -> WindowedFlicker<'_> {
        WindowedFlicker {
            flicker: self,
            window_s,
            factors: self.window_factors(window_s),
        }
    }

    /// (1 / w^2) integral over r in [-w, w] of (w - |r|) C(dt + r), the point covariance
    /// averaged over two windows of `window_s`, by Simpson's rule on `intervals` (even).
    fn lag_averaged(&self, dt: f64, window_s: f64, intervals: u32) -> f64 {
        let n = intervals;
        let h = 2.0 * window_s / f64::from(n);
        let sum: f64 = (0..=n)
            .map(|i| {
                let r = -window_s + h * f64::from(i);
                let weight = if i == 0 || i == n {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                weight * (window_s - r.abs()) * self.covariance(dt + r)
            })
            .sum();
        sum * h / 3.0 / (window_s * window_s)
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

    /// The closed forms against Simpson's rule over the lag, and a window long beside T
    /// averaging the process's variance away.
    #[test]
    fn window_means_covary_as_their_averages() {
        let f = Flicker::new(1.0);
        let w = 2.56;
        let numeric = |dt: f64| f.lag_averaged(dt, w, 2000);
        for dt in [0.0, 2.56, 8.0, 60.0] {
            let (closed, num) = (f.window_covariance(dt, w), numeric(dt));
            assert!((closed / num - 1.0).abs() < 1e-4, "{dt}: {closed} vs {num}");
        }
        assert!(f.window_covariance(0.0, w) < f.covariance(0.0));
        let (_, g) = f.window_factors(1000.0)[0];
        assert!(g < 0.002, "{g}");
    }

    /// Flat within a tenth of the floor from 3 s to 1500 s; below, bent down (printed: the
    /// fractions of the floor at 0.1 s and 1 s that docs/model.md 6.2 quotes).
    #[test]
    fn the_floor_is_flat_and_scaled() {
        let f = Flicker::new(1.0);
        for tau in [3.0, 30.0, 300.0, 1500.0] {
            let avar = f.allan_variance(tau);
            assert!((avar / FLICKER_AVAR - 1.0).abs() < 0.1, "{tau}: {avar}");
        }
        let (short, one) = (
            f.allan_variance(0.1) / FLICKER_AVAR,
            f.allan_variance(1.0) / FLICKER_AVAR,
        );
        eprintln!("flicker's Allan variance over its floor: {short:.2} at 0.1 s, {one:.2} at 1 s");
        assert!(short < one && one < 0.9, "{short} {one}");
    }
}
