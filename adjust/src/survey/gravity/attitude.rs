//! Attitude (docs/formats.md 10.2): a CSV `time,heading_deg,pitch_deg,roll_deg[,
//! sd_heading_deg,sd_pitch_deg,sd_roll_deg]`, the time in any form of docs/formats.md 9.1,
//! from a multi-antenna GNSS or an INS; vehicle frame x forward, y right, z down, the
//! rotation from vehicle to navigation frame Rz(heading) Ry(pitch) Rx(roll). A line that
//! breaks the format is an error naming file, line and field; the samples then pass
//! ingest's time gate, as every log's do (a time that repeats, goes back or jumps away from
//! its neighbours and back is dropped alone, counted by reason). Brought onto the
//! trajectory's epochs by linear interpolation (the heading unwrapped), only between two
//! attitude epochs no further apart than twice their median interval: an epoch outside
//! that is not reduced (`no_attitude`).

use super::reduce::Steps;
use super::spill::{Spill, SpillWriter};
use super::trajectory::{Columns, Values, bad, count_dropped, epoch_line, three_within};
use super::{BadLine, GravityError, set_aside};
use ingest::base::time::TimeReader;
use ingest::base::timegate::{Position, Sink, TimeGate};
use std::collections::BTreeMap;
use std::path::Path;

/// Attitude epochs, as columns.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Attitude {
    /// GPS time, ns.
    pub time_gps_ns: Vec<i64>,
    /// Heading, pitch, roll, deg (heading unwrapped: continuous across north).
    pub hpr_deg: Vec<[f64; 3]>,
    /// Their sds, deg, where the file gives them.
    pub sd_deg: Vec<Option<[f64; 3]>>,
    /// Lines set aside (`--skip-bad-lines`).
    pub bad_lines: Vec<BadLine>,
    /// Samples the time gate dropped, by ingest's reason (`duplicate`, `time_backwards`,
    /// `time_outlier`, `outside_session`).
    pub dropped: BTreeMap<String, u64>,
}

/// The attitude at one trajectory epoch.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AttitudeAt {
    /// Heading, pitch, roll, rad.
    pub hpr_rad: [f64; 3],
    /// Their sds, rad (0 where the file gives none).
    pub sd_rad: [f64; 3],
    /// Whether the file gives the sds of both samples it is interpolated between.
    pub sd_given: bool,
    /// The covariance of the attitude's error as a small rotation of the navigation frame
    /// (north, east, down), rad^2, where the attitude comes with one (an antenna array's,
    /// [`super::antennas`]); None: its angles' errors are independent, of `sd_rad`.
    pub nav_covariance: Option<[[f64; 3]; 3]>,
}

impl AttitudeAt {
    /// C_v^n = Rz(heading) Ry(pitch) Rx(roll), row-major.
    pub fn vehicle_to_nav(&self) -> [[f64; 3]; 3] {
        let [h, p, r] = self.hpr_rad;
        rotation(h, p, r)
    }
}

/// Rz(z) Ry(y) Rx(x), row-major.
pub fn rotation(z: f64, y: f64, x: f64) -> [[f64; 3]; 3] {
    let (sz, cz) = z.sin_cos();
    let (sy, cy) = y.sin_cos();
    let (sx, cx) = x.sin_cos();
    [
        [cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
        [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
        [-sy, cy * sx, cy * cx],
    ]
}

/// a b, 3 x 3.
pub fn product(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

/// m v.
pub fn apply(m: &[[f64; 3]; 3], v: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}

/// Reads an attitude CSV whose times `time` reads, its samples through the time gate for
/// the session's `range_ns`, whole ([`read_spilled`], then read back). With `skip`, a line
/// that breaks the format is set aside instead of failing the file.
pub fn read_csv(
    path: &Path,
    time: TimeReader,
    range_ns: (i64, i64),
    skip: bool,
) -> Result<Attitude, GravityError> {
    let dir = tempfile::tempdir().map_err(|e| GravityError::File {
        path: path.to_path_buf(),
        message: format!("a folder to read it through: {e}"),
    })?;
    let s = read_spilled(path, time, range_ns, skip, dir.path())?;
    let values = s.values.read(0..s.times.len()).map_err(|e| s.io(e))?;
    let hpr_deg = values.chunks_exact(WIDTH).map(|v| [v[0], v[1], v[2]]);
    let sd_deg = values.chunks_exact(WIDTH).map(sd_of);
    Ok(Attitude {
        hpr_deg: hpr_deg.collect(),
        sd_deg: sd_deg.collect(),
        time_gps_ns: s.times,
        bad_lines: s.bad_lines,
        dropped: s.dropped,
    })
}

/// Doubles an attitude sample is written aside as: heading (unwrapped), pitch, roll, their
/// sds (NaN: none), deg; the navigation-frame error's covariance NN, NE, ND, EE, ED, DD,
/// rad^2 (NaN: none).
const WIDTH: usize = 12;

fn nav_covariance_of(v: &[f64]) -> Option<[[f64; 3]; 3]> {
    (!v[6].is_nan()).then(|| {
        [
            [v[6], v[7], v[8]],
            [v[7], v[9], v[10]],
            [v[8], v[10], v[11]],
        ]
    })
}

fn sd_of(v: &[f64]) -> Option<[f64; 3]> {
    (!v[3].is_nan()).then(|| [v[3], v[4], v[5]])
}

/// An attitude file through the time gate, its samples written aside ([`super::spill`]),
/// only their times held (8 bytes a sample); [`AttitudeCursor`] interpolates it.
pub struct SpilledAttitude {
    path: std::path::PathBuf,
    /// The samples' times, GPS ns, increasing.
    pub times: Vec<i64>,
    values: Spill,
    max_gap_ns: i64,
    /// Lines set aside (`--skip-bad-lines`).
    pub bad_lines: Vec<BadLine>,
    /// Samples the time gate dropped, by ingest's reason.
    pub dropped: BTreeMap<String, u64>,
}

impl SpilledAttitude {
    /// The samples' median interval, s.
    pub fn interval_s(&self) -> f64 {
        self.max_gap_ns as f64 * 0.5e-9
    }

    fn io(&self, e: std::io::Error) -> GravityError {
        GravityError::File {
            path: self.path.clone(),
            message: format!("its samples written aside: {e}"),
        }
    }
}

/// The samples kept by the time gate, written aside, and the others counted.
struct Kept {
    times: Vec<i64>,
    out: SpillWriter,
    /// The last kept heading, deg (unwrapped).
    heading: Option<f64>,
    dropped: BTreeMap<String, u64>,
}

impl Sink<Values> for Kept {
    type Error = std::io::Error;

    fn accept(&mut self, time_ns: i64, (hpr, sd): Values) -> Result<(), Self::Error> {
        let h = continuous(self.heading, hpr[0]);
        self.heading = Some(h);
        self.times.push(time_ns);
        let [a, b, c] = sd.unwrap_or([f64::NAN; 3]);
        let none = f64::NAN;
        self.out.push(&[
            h, hpr[1], hpr[2], a, b, c, none, none, none, none, none, none,
        ])
    }

    fn reject(&mut self, _: Position, why: &'static str, _: String, _: Values) {
        count_dropped(&mut self.dropped, why);
    }
}

/// Reads an attitude CSV whose times `time` reads twice: its median interval, then its
/// samples through ingest's time gate at that interval for the session's `range_ns`, the
/// kept ones written into `dir`. With `skip`, a line that breaks the format is set aside
/// instead of failing the file.
pub fn read_spilled(
    path: &Path,
    mut time: TimeReader,
    range_ns: (i64, i64),
    skip: bool,
    dir: &Path,
) -> Result<SpilledAttitude, GravityError> {
    let mut steps = Steps::default();
    let mut first = time;
    super::trajectory::for_each_csv_line(path, |line, fields| {
        match fields.and_then(|f| epoch_line((path, line), f, &mut first, &ANGLE_COLUMNS)) {
            Ok((t, _, _)) => steps.push(t),
            Err(e) => set_aside(e, skip, &mut Vec::new())?,
        }
        Ok(())
    })?;
    let interval_ns = steps.median().unwrap_or(1_000_000_000);
    let io = |e: std::io::Error| GravityError::File {
        path: path.to_path_buf(),
        message: format!("its samples written aside: {e}"),
    };
    let mut kept = Kept {
        times: Vec::new(),
        out: SpillWriter::new(dir, WIDTH).map_err(io)?,
        heading: None,
        dropped: BTreeMap::new(),
    };
    let mut gate = TimeGate::new(interval_ns, range_ns);
    let mut bad_lines = Vec::new();
    super::trajectory::for_each_csv_line(path, |line, fields| {
        match fields.and_then(|f| epoch_line((path, line), f, &mut time, &ANGLE_COLUMNS)) {
            Ok((t, hpr, sd)) => gate
                .offer(t, Position::Line(line), (hpr, sd), &mut kept)
                .map_err(io)?,
            Err(e) => set_aside(e, skip, &mut bad_lines)?,
        }
        Ok(())
    })?;
    gate.finish(&mut kept).map_err(io)?;
    let Kept {
        times,
        out,
        dropped,
        ..
    } = kept;
    let mut kept_steps = Steps::default();
    for &t in &times {
        kept_steps.push(t);
    }
    let max_gap_ns = 2 * kept_steps.median().unwrap_or(0);
    Ok(SpilledAttitude {
        path: path.to_path_buf(),
        times,
        values: out.finish().map_err(io)?,
        max_gap_ns,
        bad_lines,
        dropped,
    })
}

/// The attitude of a [`SpilledAttitude`] at increasing times, its samples read back a
/// block at a time.
pub struct AttitudeCursor<'a> {
    att: &'a SpilledAttitude,
    start: usize,
    values: Vec<f64>,
}

/// Samples read back at a time.
const CURSOR_SAMPLES: usize = 1 << 14;

impl<'a> AttitudeCursor<'a> {
    /// A cursor at the start of `att`.
    pub fn new(att: &'a SpilledAttitude) -> Self {
        AttitudeCursor {
            att,
            start: 0,
            values: Vec::new(),
        }
    }

    /// Sample `k`'s values, reading its block back if it is not the one held.
    fn sample(&mut self, k: usize) -> Result<[f64; WIDTH], GravityError> {
        let held = self.values.len() / WIDTH;
        if k < self.start || k >= self.start + held {
            self.start = k.saturating_sub(1);
            let end = (self.start + CURSOR_SAMPLES).min(self.att.times.len());
            self.values = self
                .att
                .values
                .read(self.start..end)
                .map_err(|e| self.att.io(e))?
                .into_owned();
        }
        let i = (k - self.start) * WIDTH;
        Ok(std::array::from_fn(|j| self.values[i + j]))
    }

    /// The attitude at `x` (`x` increasing from call to call, for the block read back to
    /// serve), linear between the samples either side (the heading unwrapped); None where
    /// it cannot be interpolated: outside the file's span, or between two samples more than
    /// twice their median interval apart.
    pub fn at(&mut self, x: i64) -> Result<Option<AttitudeAt>, GravityError> {
        let t = &self.att.times;
        if t.is_empty() || x < t[0] || x > t[t.len() - 1] {
            return Ok(None);
        }
        let k = t.partition_point(|&a| a < x).saturating_sub(1);
        if t[k] == x {
            let a = self.sample(k)?;
            return Ok(Some(interpolated(&a, &a, 0.0)));
        }
        let next = (k + 1).min(t.len() - 1);
        if t[next] - t[k] > self.att.max_gap_ns {
            return Ok(None);
        }
        let f = (x - t[k]) as f64 / (t[next] - t[k]) as f64;
        let (a, b) = (self.sample(k)?, self.sample(next)?);
        Ok(Some(interpolated(&a, &b, f)))
    }
}

/// The attitude a fraction `f` from sample `a` to `b` (each as written aside).
fn interpolated(a: &[f64; WIDTH], b: &[f64; WIDTH], f: f64) -> AttitudeAt {
    let (sa, sb) = (sd_of(a), sd_of(b));
    let sd = |s: Option<[f64; 3]>| s.unwrap_or([0.0; 3]);
    let nav_covariance = nav_covariance_of(a)
        .zip(nav_covariance_of(b))
        .map(|(ca, cb)| {
            std::array::from_fn(|i| std::array::from_fn(|j| ca[i][j] + f * (cb[i][j] - ca[i][j])))
        });
    AttitudeAt {
        hpr_rad: std::array::from_fn(|j| (a[j] + f * (b[j] - a[j])).to_radians()),
        sd_rad: std::array::from_fn(|j| (sd(sa)[j] + f * (sd(sb)[j] - sd(sa)[j])).to_radians()),
        sd_given: sa.is_some() && sb.is_some(),
        nav_covariance,
    }
}

/// The heading `h` (deg) made continuous with the `last` one: the step taken as the shortest
/// turn.
fn continuous(last: Option<f64>, h: f64) -> f64 {
    match last {
        Some(last) => last + ((h - last + 180.0).rem_euclid(360.0) - 180.0),
        None => h,
    }
}

/// One sample of an attitude derived at the trajectory's own epochs (an antenna array's):
/// its time, heading, pitch, roll (deg), their sds (deg) and the navigation-frame error's
/// covariance (rad^2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DerivedSample {
    /// GPS time, ns.
    pub time_gps_ns: i64,
    /// Heading, pitch, roll, deg.
    pub hpr_deg: [f64; 3],
    /// Their sds, deg.
    pub sd_deg: [f64; 3],
    /// The error's covariance as a small rotation of the navigation frame, rad^2.
    pub nav_covariance: [[f64; 3]; 3],
}

/// Writes derived attitude samples, increasing in time (the trajectory's epochs, which
/// passed the time gate), aside into `dir` as a file's would be, the heading made
/// continuous; `path` names them in errors.
pub fn spill_derived(
    path: &Path,
    samples: impl IntoIterator<Item = DerivedSample>,
    dir: &Path,
) -> Result<SpilledAttitude, GravityError> {
    let io = |e: std::io::Error| GravityError::File {
        path: path.to_path_buf(),
        message: format!("its samples written aside: {e}"),
    };
    let mut out = SpillWriter::new(dir, WIDTH).map_err(io)?;
    let (mut times, mut steps, mut heading) = (Vec::new(), Steps::default(), None::<f64>);
    for s in samples {
        let h = continuous(heading, s.hpr_deg[0]);
        heading = Some(h);
        let c = s.nav_covariance;
        let [sh, sp, sr] = s.sd_deg;
        out.push(&[
            h,
            s.hpr_deg[1],
            s.hpr_deg[2],
            sh,
            sp,
            sr,
            c[0][0],
            c[0][1],
            c[0][2],
            c[1][1],
            c[1][2],
            c[2][2],
        ])
        .map_err(io)?;
        times.push(s.time_gps_ns);
        steps.push(s.time_gps_ns);
    }
    Ok(SpilledAttitude {
        path: path.to_path_buf(),
        max_gap_ns: 2 * steps.median().unwrap_or(0),
        times,
        values: out.finish().map_err(io)?,
        bad_lines: Vec::new(),
        dropped: BTreeMap::new(),
    })
}

/// An attitude CSV's: time, heading, pitch and roll, and their sds if given.
const ANGLE_COLUMNS: Columns = Columns {
    expected: "time, heading_deg, pitch_deg, roll_deg and optionally sd_heading_deg, \
               sd_pitch_deg, sd_roll_deg",
    values: angles,
    sds,
};

/// Heading in [-360, 360], pitch in [-90, 90], roll in [-180, 180].
fn angles(path: &Path, line: u64, f: &[&str]) -> Result<[f64; 3], GravityError> {
    let names = ["heading_deg", "pitch_deg", "roll_deg"];
    let limits = [(-360.0, 360.0), (-90.0, 90.0), (-180.0, 180.0)];
    three_within(path, line, f, (names, limits, " deg"))
}

/// Three sds (deg), each finite, not negative and under 90.
fn sds(path: &Path, line: u64, f: &[&str]) -> Result<[f64; 3], GravityError> {
    let mut out = [0.0; 3];
    for (k, name) in ["sd_heading_deg", "sd_pitch_deg", "sd_roll_deg"]
        .iter()
        .enumerate()
    {
        out[k] = f[k]
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite() && (0.0..90.0).contains(v))
            .ok_or_else(|| bad(path, line, name, format!("`{}` is not an sd in deg", f[k])))?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::test_logs::{unix_utc, written};
    use super::*;

    fn read(text: &str) -> Result<Attitude, GravityError> {
        let (_d, p) = written("att.csv", text);
        read_csv(&p, unix_utc(), (i64::MIN, i64::MAX), false)
    }

    #[test]
    fn headings_across_north_interpolate_the_short_way() {
        let text = "time,heading_deg,pitch_deg,roll_deg,sd_heading_deg,sd_pitch_deg,sd_roll_deg\n\
                    1773479523.0,359.0,1.0,-2.0,0.1,0.01,0.01\n\
                    1773479523.1,1.0,1.2,-2.2,0.1,0.01,0.01\n";
        let (d, p) = written("att.csv", text);
        let a = read_spilled(&p, unix_utc(), (i64::MIN, i64::MAX), false, d.path()).expect("reads");
        let t0 = a.times[0];
        let mut cursor = AttitudeCursor::new(&a);
        let at: Vec<Option<AttitudeAt>> =
            [t0 - 1, t0 + 50_000_000, t0 + 100_000_000, t0 + 100_000_001]
                .map(|x| cursor.at(x).expect("read back"))
                .to_vec();
        assert_eq!(at[0], None);
        assert_eq!(at[3], None);
        let mid = at[1].expect("inside");
        assert!(
            (mid.hpr_rad[0].to_degrees() - 360.0).abs() < 1e-9,
            "{mid:?}"
        );
        assert!((mid.hpr_rad[1].to_degrees() - 1.1).abs() < 1e-9, "{mid:?}");
        assert!((mid.sd_rad[1].to_degrees() - 0.01).abs() < 1e-12, "{mid:?}");
    }

    #[test]
    fn the_rotation_is_z_y_x() {
        // A heading of 90 deg takes the vehicle's x (forward) to east.
        let m = rotation(90f64.to_radians(), 0.0, 0.0);
        let v = apply(&m, [1.0, 0.0, 0.0]);
        assert!((v[1] - 1.0).abs() < 1e-12 && v[0].abs() < 1e-12, "{v:?}");
        // A roll of 90 deg takes y (right) to down.
        let m = rotation(0.0, 0.0, 90f64.to_radians());
        let v = apply(&m, [0.0, 1.0, 0.0]);
        assert!((v[2] - 1.0).abs() < 1e-12, "{v:?}");
        // The product is Rz (Ry Rx).
        let (z, y, x) = (0.3, -0.2, 0.1);
        let p = product(
            &rotation(z, 0.0, 0.0),
            &product(&rotation(0.0, y, 0.0), &rotation(0.0, 0.0, x)),
        );
        let r = rotation(z, y, x);
        for i in 0..3 {
            for j in 0..3 {
                assert!((p[i][j] - r[i][j]).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn bad_lines_are_named() {
        let e = read("time,heading_deg,pitch_deg,roll_deg\n1773479523.0,10.0,95.0,0.0\n")
            .expect_err("pitch 95")
            .to_string();
        assert!(e.contains(":2: pitch_deg: 95 is outside"), "{e}");
        let e = read("1773479523.0,10.0,1.0\n")
            .expect_err("short")
            .to_string();
        assert!(e.contains(":1: line: 3 fields"), "{e}");
        // With skip, a line that breaks the format is set aside and the rest read.
        let (_d, p) = written(
            "att.csv",
            "1773479523.0,10.0,1.0,0.0\n1773479523.1,10.0,95.0,0.0\n1773479523.2,10.0,1.0,0.0\n",
        );
        let a = read_csv(&p, unix_utc(), (i64::MIN, i64::MAX), true).expect("skips");
        assert_eq!(a.time_gps_ns.len(), 2);
        assert_eq!(
            (a.bad_lines[0].line, a.bad_lines[0].field.as_str()),
            (2, "pitch_deg")
        );
    }

    /// Times pass the time gate as every log's do: a repeated time, and one an hour ahead
    /// of its neighbours, each dropped alone and counted; the samples after them kept.
    #[test]
    fn times_out_of_place_are_dropped_alone() {
        let mut text = String::new();
        for k in 0..40 {
            let t = 1_773_479_523.0 + 0.1 * f64::from(k);
            let t = match k {
                10 => t - 0.1,
                20 => t + 3600.0,
                _ => t,
            };
            text.push_str(&format!("{t:.1},10.0,1.0,0.0\n"));
        }
        let a = read(&text).expect("read");
        assert_eq!(a.time_gps_ns.len(), 38, "{:?}", a.dropped);
        assert_eq!(a.dropped.get("duplicate"), Some(&1), "{:?}", a.dropped);
        assert_eq!(a.dropped.get("time_outlier"), Some(&1), "{:?}", a.dropped);
        assert!(a.time_gps_ns.windows(2).all(|w| w[0] < w[1]));
    }
}
