//! Apply's calibrated samples brought onto a trajectory's epochs, streamed a row group at a
//! time (memory is the epochs' accumulators, not the samples).
//!
//! Each epoch takes the samples within one epoch interval T of it, weighted by the triangle
//! 1 - |t - t_k| / T: the response of the second difference that makes the kinematic
//! acceleration from the positions (its kernel is that same triangle), so that both sides
//! of g_D = a_D - f_D see the vehicle's accelerations through the same smoothing and a step
//! in them (a gust, the start of a climb) cancels instead of leaving a pulse the filter
//! passes. (A box mean over T, tried first, left 1 mGal at a simulated aircraft's climb.)
//! The triangle's response sinc^2(f T) is zero at every multiple of the epoch rate, so what
//! aliases onto the band the gravity filter keeps (below 1/filter_s) is attenuated below
//! (pi T / filter_s)^2 (1e-5 for 10 Hz epochs and a 100 s filter).
//!
//! The specific force down: with a triad model, the calibrated body-frame vector through
//! the mounting's third row, f_D = (C_b^v f^b)_z, the platform levelled (docs/formats.md
//! 10.2: without attitude); its variance m^T Sigma m from the vector's covariance. With
//! attitude, each sample's vector is also turned into the navigation frame by C_b^n at its
//! own time (the attitude interpolated between the epochs either side) and that mean kept
//! ([`Bin::mean_nav`]). With an axis model, the one accelerometer's F, taken as the
//! vertical axis pointing up (F = -f . u, so f_D = F).

use super::GravityError;
use super::attitude::{self, AttitudeAt, AttitudeCursor};
use super::spectrum::{Floor, SpectralFloor};
use super::spill::{Spill, SpillWriter};
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

/// What the samples near one epoch sum to, each weighted by the triangle.
#[derive(Clone, Copy, Debug, Default)]
pub struct Bin {
    /// Weight of the samples taken (about the samples in one interval when none is lost).
    pub weight: f64,
    /// Of it, the samples with a value.
    pub value_weight: f64,
    sum: f64,
    sigma_sum: f64,
    vector_sum: [f64; 3],
    /// A triad's covariance elements (xx, xy, xz, yy, yz, zz), summed.
    covariance_sum: [f64; 6],
    /// With attitude: each sample's vector turned into the navigation frame, summed.
    nav_sum: [f64; 3],
    /// A triad's: each sample's magnitude |f|, summed (no attitude enters it).
    norm_sum: f64,
    /// The samples' apply flags, or-ed.
    pub flags: u8,
}

impl Bin {
    /// Adds a sample at weight `w`: its flags, and with a value (f_D and its variance) its
    /// sums; a triad's vector and covariance elements too, and with attitude its vector
    /// turned into the navigation frame, `nav`.
    fn add(
        &mut self,
        w: f64,
        sample: &Sample<'_>,
        value: Option<(f64, f64)>,
        nav: Option<[f64; 3]>,
        triad: bool,
    ) {
        self.weight += w;
        self.flags |= sample.flags;
        let Some((down, var)) = value else {
            return;
        };
        self.value_weight += w;
        self.sum += w * down;
        self.sigma_sum += w * var.sqrt();
        if !triad {
            return;
        }
        let v = sample.values;
        for (sum, v) in self.vector_sum.iter_mut().zip(v) {
            *sum += w * v.unwrap_or(0.0);
        }
        for (sum, v) in self.covariance_sum.iter_mut().zip(&v[3..]) {
            *sum += w * v.unwrap_or(0.0);
        }
        self.norm_sum += w * v[..3]
            .iter()
            .map(|x| x.unwrap_or(0.0).powi(2))
            .sum::<f64>()
            .sqrt();
        if let Some(n) = nav {
            for (sum, v) in self.nav_sum.iter_mut().zip(n) {
                *sum += w * v;
            }
        }
    }

    /// The weighted mean f_D, mGal.
    pub fn mean(&self) -> f64 {
        self.sum / self.value_weight
    }

    /// The sd per epoch that white samples of sd `sample_sd` contribute to the filtered
    /// series: their variance density, as for a mean of the samples in one interval (the
    /// triangles of neighbouring epochs share samples, which the low frequencies do not
    /// see).
    pub fn noise(&self, sample_sd: f64) -> f64 {
        sample_sd / self.value_weight.max(1.0).sqrt()
    }

    /// A triad's weighted mean calibrated vector, mGal (zero for an axis).
    pub fn mean_vector(&self) -> [f64; 3] {
        self.vector_sum.map(|v| v / self.value_weight)
    }

    /// The calibration's sigma of the mean (its error is common to the samples), mGal.
    pub fn sigma_calibration(&self) -> f64 {
        self.sigma_sum / self.value_weight
    }

    /// With attitude, the weighted mean specific force in the navigation frame (north,
    /// east, down), mGal: each sample turned by the attitude at its own time before the
    /// mean, so that a vehicle rolling within the epoch's interval leaves no bias (turning
    /// the mean vector by the epoch's attitude biases down: the mean of a product of two
    /// swells, tenths of a mGal on a boat rolling 3 deg at 8 s).
    pub fn mean_nav(&self) -> [f64; 3] {
        self.nav_sum.map(|v| v / self.value_weight)
    }

    /// A triad's weighted mean magnitude of the specific force, mGal: each sample's |f|,
    /// which no attitude enters, before the mean.
    pub fn mean_norm(&self) -> f64 {
        self.norm_sum / self.value_weight
    }

    /// A triad's calibration sigma of the mean vector along `m` (a unit row), mGal: from
    /// the samples' mean covariance, their errors being common.
    pub fn sigma_along(&self, m: [f64; 3]) -> f64 {
        let c = self.covariance_sum.map(|v| v / self.value_weight);
        let sym = |i: usize, j: usize| {
            let (a, b) = (i.min(j), i.max(j));
            c[a * 3 + b - a * (a + 1) / 2]
        };
        let mut var = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                var += m[i] * m[j] * sym(i, j);
            }
        }
        var.max(0.0).sqrt()
    }
}

/// The doubles of one [`Bin`] written aside: its seventeen sums, then its flags.
const BIN_WIDTH: usize = 18;

impl Bin {
    fn to_record(self) -> [f64; BIN_WIDTH] {
        let mut out = [0.0; BIN_WIDTH];
        let values = [self.weight, self.value_weight, self.sum, self.sigma_sum]
            .into_iter()
            .chain(self.vector_sum)
            .chain(self.covariance_sum)
            .chain(self.nav_sum)
            .chain([self.norm_sum, f64::from(self.flags)]);
        for (o, v) in out.iter_mut().zip(values) {
            *o = v;
        }
        out
    }

    fn from_record(v: &[f64]) -> Self {
        Bin {
            weight: v[0],
            value_weight: v[1],
            sum: v[2],
            sigma_sum: v[3],
            vector_sum: [v[4], v[5], v[6]],
            covariance_sum: [v[7], v[8], v[9], v[10], v[11], v[12]],
            nav_sum: [v[13], v[14], v[15]],
            norm_sum: v[16],
            flags: v[17] as u8,
        }
    }
}

/// One target's bins, written aside as they are completed ([`super::spill`]) and read
/// back a range at a time: the reduction holds a block's bins, not the survey's.
pub struct SpilledBins(Spill);

/// Bins of epochs `start..` of a target, indexed by the epoch's index in the target.
pub struct BinsAt<'a> {
    /// The first epoch's index.
    pub start: usize,
    /// The bins' records, [`BIN_WIDTH`] values each: borrowed from the spill where it holds
    /// them in memory, each bin formed as it is asked for (a day at 1 Hz's 12 MB of bins
    /// copied into a vector of bins was a sixth of the stage's page faults).
    records: std::borrow::Cow<'a, [f64]>,
}

impl BinsAt<'_> {
    /// The bin of epoch `k`.
    pub fn at(&self, k: usize) -> Bin {
        let i = (k - self.start) * BIN_WIDTH;
        Bin::from_record(&self.records[i..i + BIN_WIDTH])
    }

    /// The epoch after the last held.
    pub fn end(&self) -> usize {
        self.start + self.records.len() / BIN_WIDTH
    }
}

impl SpilledBins {
    /// The epochs it holds a bin for.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.0.len() == 0
    }

    /// The bins of epochs `range`.
    pub fn read(&self, range: std::ops::Range<usize>) -> std::io::Result<BinsAt<'_>> {
        Ok(BinsAt {
            start: range.start,
            records: self.0.read(range)?,
        })
    }
}

/// A target's bins being filled: those samples may still reach, the ones before written.
struct Window {
    /// Index of the first bin held.
    base: usize,
    bins: std::collections::VecDeque<Bin>,
    out: SpillWriter,
}

impl Window {
    fn new(dir: &Path) -> std::io::Result<Self> {
        Ok(Window {
            base: 0,
            bins: std::collections::VecDeque::new(),
            out: SpillWriter::new(dir, BIN_WIDTH)?,
        })
    }

    /// Writes the bins before epoch `upto` (none from a sample before them can come).
    fn complete(&mut self, upto: usize) -> std::io::Result<()> {
        while self.base < upto {
            let bin = self.bins.pop_front().unwrap_or_default();
            self.out.push(&bin.to_record())?;
            self.base += 1;
        }
        Ok(())
    }

    /// The bin of epoch `k`, at or after the first held (None before it).
    fn bin(&mut self, k: usize) -> Option<&mut Bin> {
        let i = k.checked_sub(self.base)?;
        if self.bins.len() <= i {
            self.bins.resize(i + 1, Bin::default());
        }
        self.bins.get_mut(i)
    }

    /// Every bin of the `n` epochs written; the file to read them back.
    fn finish(mut self, n: usize) -> std::io::Result<SpilledBins> {
        self.complete(n)?;
        Ok(SpilledBins(self.out.finish()?))
    }
}

/// One session's epochs to fill: its index in the tables, its epoch times (increasing) and
/// the median interval, and with attitude how to turn a sample into the navigation frame.
pub struct Target<'a> {
    /// The session's index in ingest's tables.
    pub session: u16,
    /// Epoch times, GPS ns, increasing.
    pub times: &'a [i64],
    /// The median epoch interval, ns.
    pub interval_ns: i64,
    /// With attitude: the attitude, read back as the samples come, and C_b^v.
    attitude: Option<(AttitudeCursor<'a>, [[f64; 3]; 3])>,
    /// The attitude at the last two epochs asked for (a sample's two epochs are its
    /// neighbours', most of the time).
    cached: [Option<(usize, AttitudeAt)>; 2],
}

impl<'a> Target<'a> {
    /// The epochs `times` (`interval_ns` apart) of session `session`, with `attitude` and
    /// C_b^v where it has one.
    pub fn new(
        session: u16,
        (times, interval_ns): (&'a [i64], i64),
        attitude: Option<(AttitudeCursor<'a>, [[f64; 3]; 3])>,
    ) -> Self {
        Target {
            session,
            times,
            interval_ns,
            attitude,
            cached: [None; 2],
        }
    }

    /// The attitude at epoch `k` (every kept epoch has one: the track kept only those).
    fn attitude_at(&mut self, k: usize) -> Result<AttitudeAt, GravityError> {
        if let Some((_, a)) = self.cached.iter().flatten().find(|(j, _)| *j == k) {
            return Ok(*a);
        }
        let t = self.times[k];
        let a = match &mut self.attitude {
            Some((cursor, _)) => cursor.at(t)?,
            None => None,
        };
        let a = a.ok_or_else(|| GravityError::Refused {
            message: format!(
                "the attitude at {} cannot be interpolated again where it was when the \
                 epoch was kept",
                ingest::base::time::utc_iso(t)
            ),
        })?;
        self.cached = [self.cached[1], Some((k, a))];
        Ok(a)
    }

    /// C_b^n at time `t` from the attitude at the epochs either side (linear in the angles
    /// between them; the one epoch's where there is one), None without attitude.
    fn body_to_nav(
        &mut self,
        t: i64,
        epochs: &[Option<(usize, f64)>; 2],
    ) -> Result<Option<[[f64; 3]; 3]>, GravityError> {
        let Some((_, mounting)) = &self.attitude else {
            return Ok(None);
        };
        let mounting = *mounting;
        let hpr = match (epochs[0], epochs[1]) {
            (Some((a, _)), Some((b, _))) => {
                let (x, y) = (self.attitude_at(a)?, self.attitude_at(b)?);
                let f = (t - self.times[a]) as f64 / (self.times[b] - self.times[a]) as f64;
                std::array::from_fn(|j| x.hpr_rad[j] + f * (y.hpr_rad[j] - x.hpr_rad[j]))
            }
            (Some((a, _)), None) | (None, Some((a, _))) => self.attitude_at(a)?.hpr_rad,
            (None, None) => return Ok(None),
        };
        let [h, p, r] = hpr;
        Ok(Some(attitude::product(
            &attitude::rotation(h, p, r),
            &mounting,
        )))
    }
}

/// The epochs within `interval_ns` of `t` and their triangle weights: the one at or before
/// it and the one after.
fn epochs_of(times: &[i64], interval_ns: i64, t: i64) -> [Option<(usize, f64)>; 2] {
    let k = times.partition_point(|&e| e <= t);
    let weight = |j: usize| {
        let w = 1.0 - (t - times[j]).abs() as f64 / interval_ns as f64;
        (w > 0.0).then_some((j, w))
    };
    [
        k.checked_sub(1).and_then(weight),
        (k < times.len()).then(|| weight(k)).flatten(),
    ]
}

/// Third differences in a block of [`ThirdDifferences`].
const BLOCK: u64 = 1024;

/// A series' white noise from its third differences (var = 20 sigma^2 for white noise; a
/// swell's third difference over three sample intervals is far below it), over runs of
/// consecutive values: the mean square per block of [`BLOCK`] differences, and the median
/// over the blocks, so that a step (a climb's jerk, a knock) does not pass for noise. The
/// samples' specific force, and the trajectory's positions.
#[derive(Clone, Debug, Default)]
pub(super) struct ThirdDifferences {
    /// The run's last values (the first `held` of them), oldest first.
    last: [(i64, f64); 4],
    held: usize,
    sum_sq: f64,
    count: u64,
    blocks: Vec<f64>,
    interval_ns: i64,
}

impl ThirdDifferences {
    /// For values `interval_ns` apart (a longer step starts a new run).
    pub(super) fn new(interval_ns: i64) -> Self {
        ThirdDifferences {
            interval_ns,
            ..ThirdDifferences::default()
        }
    }

    pub(super) fn push(&mut self, t: i64, v: f64) {
        let previous = self.held.checked_sub(1).map(|k| self.last[k].0);
        if previous.is_some_and(|p| (t - p - self.interval_ns).abs() * 2 > self.interval_ns) {
            self.held = 0;
        }
        self.last[self.held] = (t, v);
        self.held += 1;
        if self.held == 4 {
            let x = self.last.map(|(_, v)| v);
            let d3 = x[3] - 3.0 * x[2] + 3.0 * x[1] - x[0];
            self.sum_sq += d3 * d3;
            self.count += 1;
            self.last.copy_within(1.., 0);
            self.held = 3;
            if self.count == BLOCK {
                self.blocks.push(self.sum_sq / BLOCK as f64);
                (self.sum_sq, self.count) = (0.0, 0);
            }
        }
    }

    /// The white noise's sd (0 before the first difference).
    pub(super) fn sd(&self) -> f64 {
        let mut b = self.blocks.clone();
        if b.is_empty() && self.count > 0 {
            b.push(self.sum_sq / self.count as f64);
        }
        b.sort_by(f64::total_cmp);
        b.get(b.len() / 2).map_or(0.0, |m| (m / 20.0).sqrt())
    }
}

/// Per target, the bins of its epochs and its samples' white noise (mGal).
pub struct Filled {
    /// One bin per epoch, on disk.
    pub bins: Vec<SpilledBins>,
    /// What each target's samples of f_D say of their white noise, mGal (the floor of
    /// their spectrum, [`super::spectrum`]).
    pub floors: Vec<Floor>,
}

/// Why filling stopped: the table could not be read, or one of its samples not used.
enum Stop {
    Table(ingest::Error),
    Stage(GravityError),
}

impl From<ingest::Error> for Stop {
    fn from(e: ingest::Error) -> Self {
        Stop::Table(e)
    }
}

/// One target's filling: its bins being summed and its samples' noise floor.
struct Filling {
    window: Window,
    noise: SpectralFloor,
}

/// Reads apply's table at `path` and returns one bin per epoch of each target, written
/// into `dir` as they are completed ([`SpilledBins`]); samples are `interval_ns` apart.
pub fn fill(
    path: &Path,
    force: &DownForce,
    targets: &mut [Target<'_>],
    interval_ns: i64,
    dir: &Path,
) -> Result<Filled, GravityError> {
    let spill = |e| spill_error(dir, e);
    let mut fillings = targets
        .iter()
        .map(|_| {
            Window::new(dir).map(|window| Filling {
                window,
                noise: SpectralFloor::new(interval_ns),
            })
        })
        .collect::<std::io::Result<Vec<_>>>()
        .map_err(spill)?;
    let mut backwards: Option<i64> = None;
    let (names, flags) = force.columns();
    let refs: Vec<&str> = names.iter().map(String::as_str).collect();
    let mut values = vec![None; refs.len()];
    ingest::contract::tables::float_batches_with(path, &refs, &flags, 1 << 17, |b| {
        use arrow_array::Array;
        for i in 0..b.time_ns.len() {
            let Some(ti) = targets.iter().position(|t| t.session == b.session[i]) else {
                continue;
            };
            for (v, c) in values.iter_mut().zip(&b.values) {
                *v = c.is_valid(i).then(|| c.value(i));
            }
            let sample = Sample {
                time_ns: b.time_ns[i],
                flags: b.flags[i],
                values: &values,
            };
            let (t, f) = (&mut targets[ti], &mut fillings[ti]);
            if !add_sample(force, &sample, t, f, dir).map_err(Stop::Stage)? {
                backwards.get_or_insert(sample.time_ns);
            }
        }
        Ok(())
    })
    .map_err(|e| match e {
        Stop::Stage(e) => e,
        Stop::Table(e) => GravityError::File {
            path: path.to_path_buf(),
            message: format!("{e} (reading {TIME_GPS_NS} and the calibrated columns)"),
        },
    })?;
    if let Some(t) = backwards {
        return Err(GravityError::File {
            path: path.to_path_buf(),
            message: format!(
                "a sample at {} comes after later ones of its session: the table is not in \
                 time order (written by another version of apply?)",
                ingest::base::time::utc_iso(t)
            ),
        });
    }
    let (bins, floors) = fillings
        .into_iter()
        .zip(targets)
        .map(|(f, t)| Ok((f.window.finish(t.times.len())?, f.noise.floor())))
        .collect::<std::io::Result<(Vec<_>, Vec<_>)>>()
        .map_err(spill)?;
    Ok(Filled { bins, floors })
}

/// One row of apply's table.
struct Sample<'v> {
    time_ns: i64,
    flags: u8,
    /// The calibrated columns [`DownForce::columns`] names, None where null.
    values: &'v [Option<f64>],
}

/// The epochs' sums not written aside into `dir`.
fn spill_error(dir: &Path, e: std::io::Error) -> GravityError {
    GravityError::File {
        path: dir.to_path_buf(),
        message: format!("the epochs' sums written aside: {e}"),
    }
}

/// Adds `sample` to its target's epochs (the two whose triangles cover it), completing the
/// epochs no later sample reaches; false when one of its epochs was completed already (the
/// table goes back in time).
fn add_sample(
    force: &DownForce,
    sample: &Sample<'_>,
    t: &mut Target<'_>,
    f: &mut Filling,
    dir: &Path,
) -> Result<bool, GravityError> {
    let value = force.down(sample.values);
    if let Some((down, _)) = value {
        f.noise.push(sample.time_ns, down);
    }
    let near = epochs_of(t.times, t.interval_ns, sample.time_ns);
    // Samples come in time within a session (ingest's time gate): an epoch an interval
    // behind this sample is reached by no later one.
    let done = t
        .times
        .partition_point(|&e| e + t.interval_ns <= sample.time_ns);
    f.window.complete(done).map_err(|e| spill_error(dir, e))?;
    let to_nav = match value {
        Some(_) => t.body_to_nav(sample.time_ns, &near)?,
        None => None,
    };
    let v = &sample.values;
    let nav = to_nav.map(|c| attitude::apply(&c, [v[0], v[1], v[2]].map(|x| x.unwrap_or(0.0))));
    let triad = matches!(force, DownForce::Triad { .. });
    let mut in_order = true;
    for (k, w) in near.into_iter().flatten() {
        match f.window.bin(k) {
            Some(bin) => bin.add(w, sample, value, nav.filter(|_| triad), triad),
            None => in_order = false,
        }
    }
    Ok(in_order)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_is_shared_by_its_two_epochs_by_the_triangle() {
        let t = [0, 100, 200, 400];
        assert_eq!(epochs_of(&t, 100, 25), [Some((0, 0.75)), Some((1, 0.25))]);
        assert_eq!(epochs_of(&t, 100, 100), [Some((1, 1.0)), None]);
        assert_eq!(epochs_of(&t, 100, -50), [None, Some((0, 0.5))]);
        assert_eq!(epochs_of(&t, 100, 300), [None, None]);
        assert_eq!(epochs_of(&t, 100, 450), [Some((3, 0.5)), None]);
    }

    #[test]
    fn a_step_does_not_pass_for_noise() {
        let mut d = ThirdDifferences::new(10);
        let mut state = 7u64;
        for k in 0..20_000i64 {
            // A uniform deviate of sd 1 (an LCG: enough here), and a step of 1000 halfway.
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1);
            let u = ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt();
            d.push(k * 10, u + if k > 10_000 { 1000.0 } else { 0.0 });
        }
        assert!((d.sd() - 1.0).abs() < 0.05, "{}", d.sd());
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
