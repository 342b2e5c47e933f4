//! Apply's calibrated samples brought onto a trajectory's epochs: each epoch the mean of the
//! samples within half an epoch interval of it, streamed a row group at a time (memory is
//! the epochs' accumulators, not the samples).
//!
//! The box mean over one interval T is the anti-alias step: its response sinc(f T) is zero
//! at every multiple of the epoch rate 1/T, and what aliases onto the band the gravity
//! filter keeps (below 1/filter_s) lies within 1/filter_s of those zeros, where the
//! response is below pi T / filter_s (3e-3 for 10 Hz epochs and a 100 s filter).
//!
//! The specific force down: with a triad model, the calibrated body-frame vector through
//! the mounting's third row, f_D = (C_b^v f^b)_z, the platform levelled (docs/formats.md
//! 10.2: without attitude); its variance m^T Sigma m from the vector's covariance. With an
//! axis model, the one accelerometer's F, taken as the vertical axis pointing up
//! (F = -f . u, so f_D = F).

use super::GravityError;
use ingest::contract::tables::{TIME_GPS_NS, applied};
use std::path::Path;

/// How the specific force down is read from apply's table.
#[derive(Clone, Debug)]
pub enum DownForce {
    /// A triad's vector: the mounting's third row `m`, f_D = m . f.
    Triad {
        /// Third row of C_b^v.
        row: [f64; 3],
    },
    /// One axis, taken as vertical and pointing up: f_D = F.
    Axis {
        /// The accelerometer's id.
        id: String,
    },
}

impl DownForce {
    /// The Float64 columns to read and the flags column.
    fn columns(&self) -> (Vec<String>, String) {
        match self {
            DownForce::Triad { .. } => (
                applied::TRIAD_COLUMNS[..9]
                    .iter()
                    .map(|s| (*s).to_owned())
                    .collect(),
                applied::TRIAD_COLUMNS[9].to_owned(),
            ),
            DownForce::Axis { id } => {
                let [a, s, _, f] = applied::columns(id);
                (vec![a, s], f)
            }
        }
    }

    /// f_D and its calibration variance from one row's values, or None where null.
    fn down(&self, v: &[Option<f64>]) -> Option<(f64, f64)> {
        match self {
            DownForce::Triad { row: m } => {
                let f = [v[0]?, v[1]?, v[2]?];
                let c = [v[3]?, v[4]?, v[5]?, v[6]?, v[7]?, v[8]?];
                let sym = |i: usize, j: usize| {
                    let (a, b) = (i.min(j), i.max(j));
                    c[a * 3 + b - a * (a + 1) / 2]
                };
                let down = m[0] * f[0] + m[1] * f[1] + m[2] * f[2];
                let mut var = 0.0;
                for i in 0..3 {
                    for j in 0..3 {
                        var += m[i] * m[j] * sym(i, j);
                    }
                }
                Some((down, var.max(0.0)))
            }
            DownForce::Axis { .. } => Some((v[0]?, v[1]?.powi(2))),
        }
    }
}

/// The third row of C_b^v = Rz(yaw) Ry(pitch) Rx(roll), from roll, pitch, yaw in deg.
pub fn mounting_down_row(mounting_deg: [f64; 3]) -> [f64; 3] {
    let [roll, pitch, _] = mounting_deg.map(f64::to_radians);
    [
        -pitch.sin(),
        pitch.cos() * roll.sin(),
        pitch.cos() * roll.cos(),
    ]
}

/// What the samples near one epoch sum to.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bin {
    /// Samples assigned.
    pub samples: u32,
    /// Of them, with a value.
    pub with_value: u32,
    sum: f64,
    sigma_sum: f64,
    /// The samples' apply flags, or-ed.
    pub flags: u8,
}

impl Bin {
    /// The mean f_D, mGal.
    pub fn mean(&self) -> f64 {
        self.sum / f64::from(self.with_value)
    }

    /// The mean's sd for samples of white noise `sample_sd`, mGal.
    pub fn noise(&self, sample_sd: f64) -> f64 {
        sample_sd / f64::from(self.with_value.max(1)).sqrt()
    }

    /// The calibration's sigma of the mean (its error is common to the samples), mGal.
    pub fn sigma_calibration(&self) -> f64 {
        self.sigma_sum / f64::from(self.with_value)
    }
}

/// One session's epochs to fill: its index in the tables, its epoch times (increasing) and
/// half the median interval.
pub struct Target<'a> {
    /// The session's index in ingest's tables.
    pub session: u16,
    /// Epoch times, GPS ns, increasing.
    pub times: &'a [i64],
    /// Half the median epoch interval, ns.
    pub half_ns: i64,
}

/// The index of the epoch k whose interval [t_k - half_ns, t_k + half_ns) holds `t`, if
/// any (the nearer when intervals overlap).
fn epoch_of(times: &[i64], half_ns: i64, t: i64) -> Option<usize> {
    let k = times.partition_point(|&e| e <= t);
    let before = k.checked_sub(1).filter(|&j| t - times[j] < half_ns);
    let after = (k < times.len() && times[k] - t <= half_ns).then_some(k);
    match (before, after) {
        (Some(b), Some(a)) if times[a] - t < t - times[b] => Some(a),
        (Some(b), _) => Some(b),
        (None, a) => a,
    }
}

/// The samples' white noise from their third differences (var = 20 sigma^2 for white
/// noise; a swell's third difference over three sample intervals is far below it), over
/// runs of consecutive samples.
#[derive(Clone, Debug, Default)]
struct ThirdDifferences {
    last: Vec<(i64, f64)>,
    sum_sq: f64,
    count: u64,
    interval_ns: i64,
}

impl ThirdDifferences {
    fn push(&mut self, t: i64, v: f64) {
        if self
            .last
            .last()
            .is_some_and(|(p, _)| (t - p - self.interval_ns).abs() * 2 > self.interval_ns)
        {
            self.last.clear();
        }
        self.last.push((t, v));
        if self.last.len() == 4 {
            let x: Vec<f64> = self.last.iter().map(|(_, v)| *v).collect();
            let d3 = x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0];
            self.sum_sq += d3 * d3;
            self.count += 1;
            self.last.remove(0);
        }
    }

    fn sd(&self) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        (self.sum_sq / self.count as f64 / 20.0).sqrt()
    }
}

/// Per target, the bins of its epochs and its samples' white noise (mGal).
pub struct Filled {
    /// One bin per epoch.
    pub bins: Vec<Vec<Bin>>,
    /// The sd of one sample's f_D from its white noise, mGal.
    pub sample_sd_mgal: Vec<f64>,
}

/// Reads apply's table at `path` and returns one bin per epoch of each target; samples
/// are `interval_ns` apart.
pub fn fill(
    path: &Path,
    force: &DownForce,
    targets: &[Target<'_>],
    interval_ns: i64,
) -> Result<Filled, GravityError> {
    let mut bins: Vec<Vec<Bin>> = targets
        .iter()
        .map(|t| vec![Bin::default(); t.times.len()])
        .collect();
    let mut noise = vec![
        ThirdDifferences {
            interval_ns,
            ..ThirdDifferences::default()
        };
        targets.len()
    ];
    let (names, flags) = force.columns();
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut values = vec![None; refs.len()];
    align::read::float_batches(path, &refs, &flags, 1 << 17, |b| {
        use arrow::array::Array;
        for i in 0..b.time_ns.len() {
            let Some(ti) = targets.iter().position(|t| t.session == b.session[i]) else {
                continue;
            };
            let t = &targets[ti];
            let Some(k) = epoch_of(t.times, t.half_ns, b.time_ns[i]) else {
                continue;
            };
            for (v, c) in values.iter_mut().zip(&b.values) {
                *v = c.is_valid(i).then(|| c.value(i));
            }
            let bin = &mut bins[ti][k];
            bin.samples += 1;
            bin.flags |= b.flags[i];
            if let Some((down, var)) = force.down(&values) {
                bin.with_value += 1;
                bin.sum += down;
                bin.sigma_sum += var.sqrt();
                noise[ti].push(b.time_ns[i], down);
            }
        }
        Ok(())
    })
    .map_err(|e| GravityError::File {
        path: path.to_path_buf(),
        message: format!("{e} (reading {TIME_GPS_NS} and the calibrated columns)"),
    })?;
    Ok(Filled {
        bins,
        sample_sd_mgal: noise.iter().map(ThirdDifferences::sd).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_go_to_the_nearest_epoch_within_half_an_interval() {
        let t = [0, 100, 200, 400];
        assert_eq!(epoch_of(&t, 50, -50), Some(0));
        assert_eq!(epoch_of(&t, 50, -51), None);
        assert_eq!(epoch_of(&t, 50, 49), Some(0));
        assert_eq!(epoch_of(&t, 50, 50), Some(1));
        assert_eq!(epoch_of(&t, 50, 51), Some(1));
        assert_eq!(epoch_of(&t, 50, 300), None);
        assert_eq!(epoch_of(&t, 50, 449), Some(3));
    }

    #[test]
    fn the_mounting_row_is_that_of_rz_ry_rx() {
        // Upright: the body's z is the vehicle's.
        let r = mounting_down_row([0.0, 0.0, 37.0]);
        assert!(r[0].abs() < 1e-15 && r[1].abs() < 1e-15 && (r[2] - 1.0).abs() < 1e-15);
        // Rolled over: the body's z points up.
        let r = mounting_down_row([180.0, 0.0, 0.0]);
        assert!((r[2] + 1.0).abs() < 1e-15 && r[1].abs() < 1e-15);
        // Pitched 90 deg nose up: the body's x points up, its down is -x.
        let r = mounting_down_row([0.0, 90.0, 0.0]);
        assert!((r[0] + 1.0).abs() < 1e-15 && r[2].abs() < 1e-15);
    }
}
