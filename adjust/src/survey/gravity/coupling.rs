//! Cross-coupling of a platform gravimeter (docs/model.md 7, "Cross-coupling"): the
//! meter's monitors (VE, VCC, AL, AX) times coefficients, added to its gravity. The
//! coefficients are fitted by LaCoste's method as shipgrav applies it
//! (`shipgrav.grav.calc_cross_coupling_coefficients`): over each continuous segment of at
//! least [`MIN_SEGMENT`] samples, the second derivatives of the anomaly and of the monitors
//! (a 10th-order Taylor stencil, twice, 10 samples trimmed at each end), each low-passed by
//! a 200-tap Blackman FIR (`scipy.signal.firwin`, run causally as `lfilter`, 200 samples
//! trimmed at each end); then -g'' = c0 + sum c_i m_i'' by least squares. The residuals of
//! that regression are filtered, and hold the anomaly's own swells: the coefficients'
//! covariance is taken frequency by frequency with a jackknife's leverage correction
//! ([`spectral_jackknife`]), not the ordinary one, which assumes independent residuals
//! (both are given; docs/model.md 7 says what each is worth). No I/O.

/// The monitors, in the order of the coefficients.
pub const MONITORS: [&str; 4] = ["ve", "vcc", "al", "ax"];

/// The shortest continuous segment the fit uses, samples (shipgrav's).
pub const MIN_SEGMENT: usize = 1000;

/// shipgrav's `tay10`: the first derivative per sample by a 10th-order central stencil.
const TAY10: [f64; 11] = [
    1.0 / 1260.0,
    -5.0 / 504.0,
    5.0 / 84.0,
    -5.0 / 21.0,
    5.0 / 6.0,
    0.0,
    -5.0 / 6.0,
    5.0 / 21.0,
    -5.0 / 84.0,
    5.0 / 504.0,
    -1.0 / 1260.0,
];

/// The Blackman FIR's taps (shipgrav's `2 * filterlength`).
pub const TAPS: usize = 200;

/// `np.convolve(x, kernel, 'same')` for an odd kernel: zeros beyond the ends.
fn convolve_same(x: &[f64], kernel: &[f64]) -> Vec<f64> {
    let half = kernel.len() / 2;
    (0..x.len())
        .map(|i| {
            kernel
                .iter()
                .enumerate()
                .filter_map(|(j, k)| {
                    let at = (i + half).checked_sub(j)?;
                    x.get(at).map(|v| k * v)
                })
                .sum()
        })
        .collect()
}

/// The second derivative per sample squared, the stencil applied twice, with 10 samples
/// trimmed at each end (where the zeros beyond the ends reach in).
pub fn second_derivative(x: &[f64]) -> Vec<f64> {
    let d2 = convolve_same(&convolve_same(x, &TAY10), &TAY10);
    if d2.len() <= 20 {
        return Vec::new();
    }
    d2[10..d2.len() - 10].to_vec()
}

/// `scipy.signal.firwin(taps, 1 / taps, window="blackman")`: a windowed sinc low-pass with
/// its cut-off at 1 / taps of the Nyquist frequency, scaled to 1 at 0 Hz.
pub fn blackman_lowpass(taps: usize) -> Vec<f64> {
    let cutoff = 1.0 / taps as f64;
    let alpha = 0.5 * (taps as f64 - 1.0);
    let m = (taps - 1) as f64;
    let pi = std::f64::consts::PI;
    let h: Vec<f64> = (0..taps)
        .map(|n| {
            let x = n as f64 - alpha;
            let sinc = if x == 0.0 {
                1.0
            } else {
                (pi * cutoff * x).sin() / (pi * cutoff * x)
            };
            let w = 0.42 - 0.5 * (2.0 * pi * n as f64 / m).cos()
                + 0.08 * (4.0 * pi * n as f64 / m).cos();
            cutoff * sinc * w
        })
        .collect();
    let sum: f64 = h.iter().sum();
    h.iter().map(|v| v / sum).collect()
}

/// `scipy.signal.lfilter(b, 1, x)`: the causal FIR from rest.
fn lfilter(b: &[f64], x: &[f64]) -> Vec<f64> {
    (0..x.len())
        .map(|n| {
            b.iter()
                .take(n + 1)
                .enumerate()
                .map(|(k, c)| c * x[n - k])
                .sum()
        })
        .collect()
}

/// A segment's rows of the regression: (-g'', the monitors''), filtered and trimmed; empty
/// for a segment too short to leave any.
pub fn segment_rows(anomaly_mgal: &[f64], monitors: &[[f64; 4]]) -> Vec<(f64, [f64; 4])> {
    let fir = blackman_lowpass(TAPS);
    let prepare = |x: &[f64]| {
        let f = lfilter(&fir, &second_derivative(x));
        if f.len() <= 2 * TAPS {
            Vec::new()
        } else {
            f[TAPS..f.len() - TAPS].to_vec()
        }
    };
    let g = prepare(anomaly_mgal);
    let m: Vec<Vec<f64>> = (0..4)
        .map(|i| prepare(&monitors.iter().map(|r| r[i]).collect::<Vec<_>>()))
        .collect();
    (0..g.len())
        .map(|k| (-g[k], [m[0][k], m[1][k], m[2][k], m[3][k]]))
        .collect()
}

/// The fitted coefficients: a constant and one per monitor ([`MONITORS`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Fitted {
    /// c0 (mGal per sample squared), then VE, VCC, AL, AX.
    pub coefficients: [f64; 5],
    /// Their covariance by the frequency-domain jackknife (the one to quote).
    pub covariance: [[f64; 5]; 5],
    /// Their sds as ordinary least squares gives them (independent residuals assumed).
    pub ols_sigma: [f64; 5],
    /// Rows used.
    pub rows: usize,
}

/// Solves the symmetric positive definite 5 x 5 system `a x = b` for each column of `b`
/// (Cholesky, the matrix equilibrated by its diagonal first); None when it is singular.
fn solve(a: &[[f64; 5]; 5], b: &[[f64; 5]; 5]) -> Option<[[f64; 5]; 5]> {
    let d: [f64; 5] = std::array::from_fn(|i| a[i][i].sqrt());
    if d.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return None;
    }
    let s: [[f64; 5]; 5] =
        std::array::from_fn(|i| std::array::from_fn(|j| a[i][j] / (d[i] * d[j])));
    let mut l = [[0.0; 5]; 5];
    for i in 0..5 {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                let v = s[i][i] - sum;
                if v <= 1e-12 {
                    return None;
                }
                l[i][i] = v.sqrt();
            } else {
                l[i][j] = (s[i][j] - sum) / l[j][j];
            }
        }
    }
    let mut x = [[0.0; 5]; 5];
    for c in 0..5 {
        let mut y = [0.0; 5];
        for i in 0..5 {
            y[i] = (b[i][c] / d[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
        }
        for i in (0..5).rev() {
            x[i][c] = (y[i] - (i + 1..5).map(|k| l[k][i] * x[k][c]).sum::<f64>()) / l[i][i];
        }
        for (i, row) in x.iter_mut().enumerate() {
            row[c] /= d[i];
        }
    }
    Some(x)
}

/// The least leverage's complement a frequency is given, so that a frequency one monitor
/// alone determines does not divide by zero.
const MIN_FREE: f64 = 1e-2;

/// Least squares of `rows` (y, x) with a constant, the covariance by the frequency-domain
/// jackknife ([`spectral_jackknife`]); None with fewer rows than ten or a design the rows
/// do not determine (a monitor that never moves).
pub fn fit(rows: &[(f64, [f64; 4])]) -> Option<Fitted> {
    if rows.len() < 10 {
        return None;
    }
    let design: Vec<[f64; 5]> = rows
        .iter()
        .map(|(_, x)| [1.0, x[0], x[1], x[2], x[3]])
        .collect();
    let mut n = [[0.0; 5]; 5];
    let mut u = [0.0; 5];
    for (a, (y, _)) in design.iter().zip(rows) {
        for i in 0..5 {
            u[i] += a[i] * y;
            for j in 0..5 {
                n[i][j] += a[i] * a[j];
            }
        }
    }
    let identity: [[f64; 5]; 5] =
        std::array::from_fn(|i| std::array::from_fn(|j| f64::from(u8::from(i == j))));
    let inverse = solve(&n, &identity)?;
    let coefficients: [f64; 5] =
        std::array::from_fn(|i| (0..5).map(|j| inverse[i][j] * u[j]).sum());
    let residuals: Vec<f64> = design
        .iter()
        .zip(rows)
        .map(|(a, (y, _))| y - a.iter().zip(&coefficients).map(|(a, c)| a * c).sum::<f64>())
        .collect();
    let dof = rows.len() - 5;
    let s2 = residuals.iter().map(|e| e * e).sum::<f64>() / dof as f64;
    Some(Fitted {
        coefficients,
        covariance: spectral_jackknife(&design, &residuals, &inverse),
        ols_sigma: std::array::from_fn(|i| (s2 * inverse[i][i]).sqrt()),
        rows: rows.len(),
    })
}

/// The coefficients' covariance `inverse * M * inverse` of a regression whose residuals are
/// a stationary series of unknown spectrum (docs/model.md 7, "Cross-coupling"). Transformed
/// (a unitary DFT), the regression's frequencies are nearly independent, each with the
/// residuals' spectrum at it as variance: heteroscedastic, where the ordinary covariance
/// assumes them alike. M sums, over the frequencies, each one's design outer product times
/// its residual's power divided by (1 - h)^2, h its leverage (MacKinnon and White's HC3,
/// the jackknife): a monitor swelling at a few frequencies takes up, there, part of what
/// the anomaly itself does, and the residual left at those frequencies is that much too
/// small. Zero frequency, which the constant alone determines, takes its neighbour's power.
fn spectral_jackknife(
    design: &[[f64; 5]],
    residuals: &[f64],
    inverse: &[[f64; 5]; 5],
) -> [[f64; 5]; 5] {
    let t = residuals.len();
    let norm = 1.0 / (t as f64).sqrt();
    let zeros = vec![0.0; t];
    let unitary = |x: &[f64]| {
        let (re, im) = super::spectrum::dft(x, &zeros);
        let scaled = |v: Vec<f64>| v.into_iter().map(|a| a * norm).collect::<Vec<_>>();
        (scaled(re), scaled(im))
    };
    let columns: Vec<(Vec<f64>, Vec<f64>)> = (0..5)
        .map(|i| unitary(&design.iter().map(|a| a[i]).collect::<Vec<_>>()))
        .collect();
    let (e_re, e_im) = unitary(residuals);
    let power = |f: usize| {
        let x: [(f64, f64); 5] = std::array::from_fn(|i| (columns[i].0[f], columns[i].1[f]));
        let mut h = 0.0;
        for i in 0..5 {
            for j in 0..5 {
                h += inverse[i][j] * (x[i].0 * x[j].0 + x[i].1 * x[j].1);
            }
        }
        let free = (1.0 - h).max(MIN_FREE);
        (e_re[f] * e_re[f] + e_im[f] * e_im[f]) / (free * free)
    };
    let mut meat = [[0.0; 5]; 5];
    for f in 0..t {
        let p = if f == 0 && t > 1 { power(1) } else { power(f) };
        for i in 0..5 {
            for j in 0..5 {
                let (a, b) = (&columns[i], &columns[j]);
                meat[i][j] += p * (a.0[f] * b.0[f] + a.1[f] * b.1[f]);
            }
        }
    }
    std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            (0..5)
                .flat_map(|k| (0..5).map(move |l| (k, l)))
                .map(|(k, l)| inverse[i][k] * meat[k][l] * inverse[l][j])
                .sum::<f64>()
        })
    })
}

/// The correction applied to a session: its coefficients for VE, VCC, AL, AX (mGal per
/// unit of each monitor) and their covariance (zero when given).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Correction {
    /// VE, VCC, AL, AX.
    pub coefficients: [f64; 4],
    /// Their covariance (the frequency-domain jackknife's when fitted).
    pub covariance: [[f64; 4]; 4],
}

impl Correction {
    /// A fit's monitor coefficients (its constant, which only levels the second
    /// derivatives, left out).
    pub fn of(f: &Fitted) -> Self {
        Correction {
            coefficients: std::array::from_fn(|i| f.coefficients[i + 1]),
            covariance: std::array::from_fn(|i| {
                std::array::from_fn(|j| f.covariance[i + 1][j + 1])
            }),
        }
    }

    /// The correction at monitors `m`, mGal.
    pub fn value(&self, m: &[f64; 4]) -> f64 {
        (0..4).map(|i| self.coefficients[i] * m[i]).sum()
    }

    /// The sd the coefficients' errors give a combination `m` of the monitors (the
    /// monitors filtered as the value is), mGal.
    pub fn sigma(&self, m: &[f64; 4]) -> f64 {
        let mut v = 0.0;
        for i in 0..4 {
            for j in 0..4 {
                v += m[i] * self.covariance[i][j] * m[j];
            }
        }
        v.max(0.0).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stencil differentiates a cubic exactly (per sample squared), away from the ends.
    #[test]
    fn the_stencil_twice_is_the_second_derivative() {
        let x: Vec<f64> = (0..100)
            .map(|k| f64::from(k).powi(3) * 1e-3 + 2.0 * f64::from(k))
            .collect();
        let d2 = second_derivative(&x);
        for (i, v) in d2.iter().enumerate().skip(10).take(60) {
            let k = (i + 10) as f64;
            assert!((v - 6e-3 * k).abs() < 1e-9, "{i}: {v}");
        }
    }

    /// The FIR's amplitude response is scipy's: `python -c "from scipy.signal import
    /// firwin, freqz; import numpy as np; h = firwin(200, 1/200, window='blackman');
    /// print([abs(freqz(h, worN=[2*np.pi*f])[1][0]) for f in (0.0025, 0.005, 0.01)])"` in
    /// the peers' venv (cycles per sample; the window's main lobe, wider than the cut-off,
    /// sets the response: 0.89 at the nominal cut-off, not a half).
    #[test]
    fn the_blackman_lowpass_responds_as_scipys() {
        let h = blackman_lowpass(TAPS);
        let gain = |cycles_per_sample: f64| {
            let (re, im) = h.iter().enumerate().fold((0.0, 0.0), |(re, im), (n, c)| {
                let phase = std::f64::consts::TAU * cycles_per_sample * n as f64;
                (re + c * phase.cos(), im - c * phase.sin())
            });
            f64::hypot(re, im)
        };
        assert!((gain(0.0) - 1.0).abs() < 1e-12);
        for (f, scipy) in [
            (0.0025, 0.889_783_012_097_226_5),
            (0.005, 0.620_870_351_133_985_3),
            (0.01, 0.122_911_017_635_112_81),
        ] {
            assert!((gain(f) - scipy).abs() < 1e-9, "{f}: {}", gain(f));
        }
    }

    /// Monitors that explain the anomaly exactly give their coefficients back.
    #[test]
    fn a_known_coupling_is_recovered() {
        let n = 2000;
        let mut rng = fixtures::rng::Rng::new(7, "coupling-test");
        let mut noise = || rng.normal();
        let monitors: Vec<[f64; 4]> = (0..n)
            .map(|k| {
                let t = f64::from(k);
                [
                    (t / 37.0).sin() + 0.1 * noise(),
                    (t / 23.0).cos() * 0.5 + 0.1 * noise(),
                    (t / 51.0).sin() * 2.0 + 0.1 * noise(),
                    (t / 17.0).cos() + 0.1 * noise(),
                ]
            })
            .collect();
        let truth = [0.3, -1.2, 0.05, 2.0];
        let anomaly: Vec<f64> = monitors
            .iter()
            .map(|m| -(0..4).map(|i| truth[i] * m[i]).sum::<f64>())
            .collect();
        let f = fit(&segment_rows(&anomaly, &monitors)).expect("fit");
        for i in 0..4 {
            assert!(
                (f.coefficients[i + 1] - truth[i]).abs() < 1e-6,
                "{i}: {:?}",
                f.coefficients
            );
        }
    }
}
