//! Crossovers (docs/model.md 7): where the track crosses itself, the two passes' filtered
//! disturbances differ by their errors alone, a check of the sigmas nobody had to simulate.
//!
//! The epochs that may take part are those moving (over 1 m/s) and carrying no flag (not
//! turning, not within a filter period of a stretch's end, not outside the calibration);
//! consecutive such epochs of one stretch make the segments of the track. Two segments at
//! least twice the filter's period apart in time (so that the filter's windows do not
//! overlap and the noise is independent) that intersect give a crossover. The search is in
//! latitude and longitude with the longitude scaled by the cosine of the mean latitude: a
//! map that is affine, so that where two segments cross, as fractions along each, is the
//! same as in any local metric frame. Segments are hashed into square cells four median
//! segment lengths wide, and a pair is tested (once) only where both fall into one cell. Intersections of one pair of
//! passes within a filter period of each other (a track that wanders across a line under
//! its noise) count as one crossover.
//!
//! The difference (second pass minus first) is interpolated linearly along each segment.
//! Its sigma takes the parts independent between the passes: the noise and the positions
//! of each pass, and the tie's: on one stretch the drift's rate over the time between the
//! passes (the offset is common), on two stretches each pass's tie sigma in full. The
//! calibration's part is common to both passes (one calibration, the same specific force
//! on a levelled platform) and cancels to first order, so it is left out.

use super::navigation::{longitude_step_deg, longitude_wrapped_like};
use ingest::base::time::utc_iso;
use ingest::contract::gravity_ledger::{Crossover, Pass};
use std::collections::{HashMap, HashSet};

/// The epochs written, as the stage gathered them (rows of gravity.parquet, in order).
#[derive(Clone, Copy, Debug)]
pub struct Epochs<'a> {
    /// The rows.
    pub rows: &'a [Row],
    /// Session ids, indexed by a row's `session`.
    pub names: &'a [String],
}

/// Slowest speed at which an epoch may take part, m/s.
const MOVING_M_S: f64 = 1.0;

/// One row of gravity.parquet as the crossover search sees it.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    /// The session's index into the names.
    pub session: u16,
    /// The stretch's number.
    pub stretch: u32,
    /// GPS ns.
    pub time_gps_ns: i64,
    /// Deg.
    pub latitude_deg: f64,
    /// Deg.
    pub longitude_deg: f64,
    /// m/s.
    pub speed_m_s: f64,
    /// mGal.
    pub filtered_mgal: f64,
    /// mGal.
    pub sigma_mgal: f64,
    /// mGal.
    pub sigma_noise_mgal: f64,
    /// mGal.
    pub sigma_positions_mgal: f64,
    /// mGal.
    pub sigma_tie_mgal: f64,
    /// gravity.parquet's flags.
    pub flags: u8,
}

/// The rows the search keeps as the stage writes them, so that it does not hold the whole
/// survey: of each run of rows that take part (moving, unflagged, on one stretch), one every
/// `step` ([`step`]: a fiftieth of the filter's period, over which a straight line departs
/// from a wave at the cut-off by 0.2 % of its amplitude), and the first row
/// after a run, which ends it as it ends it in the rows themselves. About 90 bytes a kept
/// row: 4 MB for a day of epochs with a 100 s filter.
#[derive(Clone, Debug, Default)]
pub struct Kept {
    rows: Vec<Row>,
    /// Rows of the run taking part so far.
    run: usize,
}

/// Rows kept per run of rows taking part: one every fiftieth of the filter's period.
pub fn step(filter_s: f64, interval_s: f64) -> usize {
    ((filter_s / interval_s / 50.0).floor() as usize).max(1)
}

impl Kept {
    /// Offers the next row written, its epochs `step` rows per kept row.
    pub fn push(&mut self, r: &Row, step: usize) {
        let same_stretch = self
            .rows
            .last()
            .is_some_and(|l| l.session == r.session && l.stretch == r.stretch);
        if !same_stretch {
            self.run = 0;
        }
        let takes_part = r.flags == 0 && r.speed_m_s > MOVING_M_S;
        let keep = if takes_part {
            let first = self.run.is_multiple_of(step.max(1));
            self.run += 1;
            first
        } else {
            std::mem::take(&mut self.run) > 0
        };
        if !keep {
            return;
        }
        self.rows.push(*r);
    }

    /// The rows kept, for [`crossovers`].
    pub fn epochs<'a>(&'a self, names: &'a [String]) -> Epochs<'a> {
        Epochs {
            rows: &self.rows,
            names,
        }
    }
}

/// The crossovers of `e`; `rate_sigma(session, stretch)` is the sigma of the drift's rate
/// fitted on a stretch, mGal/h (none without one).
pub fn crossovers(
    e: &Epochs<'_>,
    filter_s: f64,
    rate_sigma: impl Fn(u16, u32) -> Option<f64>,
) -> Vec<Crossover> {
    let segments = segments(e);
    let plane = Plane::new(e, &segments);
    let separation_ns = (2.0 * filter_s * 1e9) as i64;
    let mut found = Vec::new();
    let mut tested = HashSet::new();
    for members in plane.cells(&segments).values() {
        for (x, &a) in members.iter().enumerate() {
            for &b in &members[x + 1..] {
                let (a, b) = (a.min(b), a.max(b));
                if (e.rows[b].time_gps_ns - e.rows[a].time_gps_ns).abs() < separation_ns
                    || !tested.insert((a, b))
                {
                    continue;
                }
                if let Some((s, u)) = plane.intersect(a, b) {
                    found.push((a, s, b, u));
                }
            }
        }
    }
    found.sort_by_key(|p| (p.0, p.2));
    let found = merged(e, found, (filter_s * 1e9) as i64);
    found
        .into_iter()
        .map(|(a, s, b, u)| crossover(e, &plane, (a, s), (b, u), &rate_sigma))
        .collect()
}

/// The segments: epoch k to k + 1, both taking part, on one stretch.
fn segments(e: &Epochs<'_>) -> Vec<usize> {
    let takes_part = |k: usize| e.rows[k].flags == 0 && e.rows[k].speed_m_s > MOVING_M_S;
    (0..e.rows.len().saturating_sub(1))
        .filter(|&k| {
            takes_part(k)
                && takes_part(k + 1)
                && e.rows[k].session == e.rows[k + 1].session
                && e.rows[k].stretch == e.rows[k + 1].stretch
        })
        .collect()
}

/// Intersections of one pair of passes within `window_ns` on both kept once (the first).
fn merged(
    e: &Epochs<'_>,
    found: Vec<(usize, f64, usize, f64)>,
    window_ns: i64,
) -> Vec<(usize, f64, usize, f64)> {
    let mut kept: Vec<(usize, f64, usize, f64)> = Vec::new();
    for f in found {
        let near = kept.iter().any(|k| {
            (e.rows[k.0].time_gps_ns - e.rows[f.0].time_gps_ns).abs() < window_ns
                && (e.rows[k.2].time_gps_ns - e.rows[f.2].time_gps_ns).abs() < window_ns
        });
        if !near {
            kept.push(f);
        }
    }
    kept
}

/// Latitude and scaled longitude, deg, and the hashing cell's size.
struct Plane {
    xy: Vec<[f64; 2]>,
    cell_deg: f64,
}

impl Plane {
    /// The plane of `e`'s positions, its cells sized by `segments`' median length.
    fn new(e: &Epochs<'_>, segments: &[usize]) -> Self {
        let n = e.rows.len();
        let mean = e.rows.iter().map(|r| r.latitude_deg).sum::<f64>() / n.max(1) as f64;
        let c = mean.to_radians().cos();
        // Longitudes from the first epoch's, the short way round: a survey across the
        // antimeridian stays one piece of plane.
        let lon0 = e.rows.first().map_or(0.0, |r| r.longitude_deg);
        let xy: Vec<[f64; 2]> = (0..n)
            .map(|k| {
                let x = longitude_step_deg(lon0, e.rows[k].longitude_deg);
                [x * c, e.rows[k].latitude_deg]
            })
            .collect();
        let mut lengths: Vec<f64> = segments
            .iter()
            .map(|&k| (xy[k + 1][0] - xy[k][0]).hypot(xy[k + 1][1] - xy[k][1]))
            .collect();
        lengths.sort_by(f64::total_cmp);
        let median = lengths.get(lengths.len() / 2).copied().unwrap_or(1e-5);
        Plane {
            xy,
            cell_deg: (4.0 * median).max(1e-7),
        }
    }

    fn cell_of(&self, p: [f64; 2]) -> (i64, i64) {
        (
            (p[0] / self.cell_deg).floor() as i64,
            (p[1] / self.cell_deg).floor() as i64,
        )
    }

    /// Each cell with the segments whose bounding box touches it.
    fn cells(&self, segments: &[usize]) -> HashMap<(i64, i64), Vec<usize>> {
        let mut cells: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        for &k in segments {
            let (p, q) = (self.xy[k], self.xy[k + 1]);
            let lo = self.cell_of([p[0].min(q[0]), p[1].min(q[1])]);
            let hi = self.cell_of([p[0].max(q[0]), p[1].max(q[1])]);
            for i in lo.0..=hi.0 {
                for j in lo.1..=hi.1 {
                    cells.entry((i, j)).or_default().push(k);
                }
            }
        }
        cells
    }

    /// The point a fraction `s` along segment `k`.
    fn along(&self, k: usize, s: f64) -> [f64; 2] {
        let (p, q) = (self.xy[k], self.xy[k + 1]);
        [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])]
    }

    /// Where segments `a` and `b` cross, as fractions along each in [0, 1) (half open, so
    /// that a crossing through an epoch counts once).
    fn intersect(&self, a: usize, b: usize) -> Option<(f64, f64)> {
        let (p, r) = (self.xy[a], sub(self.xy[a + 1], self.xy[a]));
        let (q, d) = (self.xy[b], sub(self.xy[b + 1], self.xy[b]));
        let den = cross(r, d);
        if den == 0.0 {
            return None;
        }
        let w = sub(q, p);
        let (s, u) = (cross(w, d) / den, cross(w, r) / den);
        ((0.0..1.0).contains(&s) && (0.0..1.0).contains(&u)).then_some((s, u))
    }

    /// The angle between the courses at segments `a` and `b`, deg in 0-90: each course
    /// over 5 s either side (a segment's own direction turns with the positions' noise).
    fn angle_deg(&self, e: &Epochs<'_>, a: usize, b: usize) -> f64 {
        let (r, d) = (self.course(e, a), self.course(e, b));
        let cos = (r[0] * d[0] + r[1] * d[1]) / (r[0].hypot(r[1]) * d[0].hypot(d[1]));
        let angle = cos.clamp(-1.0, 1.0).acos().to_degrees();
        angle.min(180.0 - angle)
    }

    /// The displacement from 5 s before segment `k` to 5 s after, on its stretch.
    fn course(&self, e: &Epochs<'_>, k: usize) -> [f64; 2] {
        let same = |j: usize| {
            e.rows[j].session == e.rows[k].session && e.rows[j].stretch == e.rows[k].stretch
        };
        let within =
            |j: usize| (e.rows[j].time_gps_ns - e.rows[k].time_gps_ns).abs() <= 5_000_000_000;
        let mut lo = k;
        while lo > 0 && same(lo - 1) && within(lo - 1) {
            lo -= 1;
        }
        let mut hi = k + 1;
        while hi + 1 < e.rows.len() && same(hi + 1) && within(hi + 1) {
            hi += 1;
        }
        sub(self.xy[hi], self.xy[lo])
    }
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// `v` interpolated a fraction `s` from epoch k to k + 1.
fn at(e: &Epochs<'_>, field: impl Fn(&Row) -> f64, k: usize, s: f64) -> f64 {
    let (a, b) = (field(&e.rows[k]), field(&e.rows[k + 1]));
    a + s * (b - a)
}

fn pass(e: &Epochs<'_>, k: usize, s: f64) -> Pass {
    let t = e.rows[k].time_gps_ns
        + (s * (e.rows[k + 1].time_gps_ns - e.rows[k].time_gps_ns) as f64) as i64;
    Pass {
        session: e.names[usize::from(e.rows[k].session)].clone(),
        stretch: e.rows[k].stretch,
        time: utc_iso(t),
        time_gps_ns: t,
        filtered_mgal: at(e, |r| r.filtered_mgal, k, s),
        sigma_mgal: at(e, |r| r.sigma_mgal, k, s),
    }
}

fn crossover(
    e: &Epochs<'_>,
    plane: &Plane,
    (a, s): (usize, f64),
    (b, u): (usize, f64),
    rate_sigma: &impl Fn(u16, u32) -> Option<f64>,
) -> Crossover {
    let ((a, s), (b, u)) = if e.rows[b].time_gps_ns < e.rows[a].time_gps_ns {
        ((b, u), (a, s))
    } else {
        ((a, s), (b, u))
    };
    let independent = |k: usize, f: f64| {
        at(e, |r| r.sigma_noise_mgal, k, f).hypot(at(e, |r| r.sigma_positions_mgal, k, f))
    };
    let same = e.rows[a].session == e.rows[b].session && e.rows[a].stretch == e.rows[b].stretch;
    let tie = if same {
        let hours = (e.rows[b].time_gps_ns - e.rows[a].time_gps_ns) as f64 / 3.6e12;
        rate_sigma(e.rows[a].session, e.rows[a].stretch).unwrap_or(0.0) * hours
    } else {
        at(e, |r| r.sigma_tie_mgal, a, s).hypot(at(e, |r| r.sigma_tie_mgal, b, u))
    };
    let sigma = independent(a, s).hypot(independent(b, u)).hypot(tie);
    let point = plane.along(a, s);
    let (first, second) = (pass(e, a, s), pass(e, b, u));
    Crossover {
        latitude_deg: point[1],
        longitude_deg: longitude_wrapped_like(
            e.rows[a].longitude_deg
                + s * longitude_step_deg(e.rows[a].longitude_deg, e.rows[a + 1].longitude_deg),
            e.rows[a].longitude_deg,
        ),
        angle_deg: plane.angle_deg(e, a, b),
        difference_mgal: second.filtered_mgal - first.filtered_mgal,
        sigma_mgal: sigma,
        first,
        second,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two straight passes: east along latitude 43 and back north-west across it, epochs
    /// every 0.5 s, with a disturbance that is x on the first and x + 1 on the second.
    fn track(wander: f64) -> Vec<Row> {
        let row = |k: usize, lat: f64, lon: f64, v: f64| Row {
            session: 0,
            stretch: 0,
            time_gps_ns: k as i64 * 500_000_000,
            latitude_deg: lat,
            longitude_deg: lon,
            speed_m_s: 5.0,
            filtered_mgal: v,
            sigma_mgal: 0.3,
            sigma_noise_mgal: 0.3,
            sigma_positions_mgal: 0.3,
            sigma_tie_mgal: 0.3,
            flags: 0,
        };
        let mut t = Vec::new();
        // 2000 epochs east from lon 5.0 to 5.02, then 2000 back crossing at lon 5.01.
        for k in 0..2000 {
            let lon = 5.0 + 1e-5 * k as f64;
            t.push(row(k, 43.0, lon, lon));
        }
        for k in 0..2000 {
            let lon = 5.02 - 1e-5 * k as f64;
            // Crosses latitude 43 at k = 1000; a wander of `wander` deg about the line.
            let jitter = if k % 2 == 0 { wander } else { -wander };
            let lat = 43.0 + 1e-6 * (1000.0 - k as f64) + jitter;
            t.push(row(2000 + k, lat, lon, lon + 1.0));
        }
        t
    }

    fn epochs<'a>(rows: &'a [Row], names: &'a [String]) -> Epochs<'a> {
        Epochs { rows, names }
    }

    #[test]
    fn two_passes_cross_once_where_they_cross_with_the_difference_between_them() {
        let t = track(0.0);
        let names = ["s".to_owned()];
        let e = epochs(&t, &names);
        let found = crossovers(&e, 100.0, |_, _| Some(0.5));
        assert_eq!(found.len(), 1, "{found:?}");
        let c = &found[0];
        assert!((c.longitude_deg - 5.01).abs() < 1e-7, "{c:?}");
        assert!((c.latitude_deg - 43.0).abs() < 1e-9, "{c:?}");
        assert!((c.difference_mgal - 1.0).abs() < 1e-9, "{c:?}");
        // Noise and positions of each pass (0.3 each), the rate's sigma over the time
        // between the passes (1000 s = 0.278 h at 0.5 mGal/h).
        let hours: f64 = 1000.0 / 3600.0;
        let expect = (4.0 * 0.09 + (0.5 * hours).powi(2)).sqrt();
        assert!(
            (c.sigma_mgal - expect).abs() < 1e-3,
            "{c:?} against {expect}"
        );
        let slope = 1e-6 / (1e-5 * 43f64.to_radians().cos());
        assert!(
            (c.angle_deg - slope.atan().to_degrees()).abs() < 1e-3,
            "{c:?}"
        );
    }

    /// Two passes across the antimeridian, the file writing -180..180, crossing at
    /// 180.000001 deg, between two epochs of the first pass (179.999993 and -179.999997):
    /// the crossover's longitude is -179.999999, in the file's range (not 180.000001).
    #[test]
    fn a_crossover_on_the_antimeridian_is_in_the_files_range() {
        let mut t = track(0.0);
        let wrap = |lon: f64| (lon + 180.0).rem_euclid(360.0) - 180.0;
        for k in 0..2000 {
            t[k].longitude_deg = wrap(179.99 + 3e-6 + 1e-5 * k as f64);
            let lon = 180.01 + 3e-6 - 1e-5 * k as f64;
            t[2000 + k].longitude_deg = wrap(lon);
            t[2000 + k].latitude_deg = 43.0 + 1e-6 * (1000.2 - k as f64);
        }
        let names = ["s".to_owned()];
        let found = crossovers(&epochs(&t, &names), 100.0, |_, _| None);
        assert_eq!(found.len(), 1, "{found:?}");
        let lon = found[0].longitude_deg;
        assert!((lon + 179.999_999).abs() < 1e-7, "{lon}");
    }

    #[test]
    fn a_wandering_pass_crosses_once_and_flagged_or_close_epochs_take_no_part() {
        // A wander larger than a step across the line: several intersections, one crossover.
        let t = track(2.5e-6);
        let names = ["s".to_owned()];
        let e = epochs(&t, &names);
        assert_eq!(crossovers(&e, 100.0, |_, _| None).len(), 1);
        // Passes within twice the filter's period of each other do not cross.
        assert!(crossovers(&e, 600.0, |_, _| None).is_empty());
        let mut t = track(0.0);
        for k in 2990..3010 {
            t[k].flags = 2;
        }
        assert!(crossovers(&epochs(&t, &names), 100.0, |_, _| None).is_empty());
    }

    /// The rows kept a step apart find the crossover all rows find, at the same place and
    /// with the same difference; a flagged row ends its run (kept, so that no segment spans
    /// it), and the rows of another stretch start a run of their own.
    #[test]
    fn the_rows_kept_find_the_crossover_and_keep_the_runs_apart() {
        let t = track(0.0);
        let row = |k: usize| Row {
            stretch: t[k].stretch + u32::from(k >= 3500),
            flags: u8::from((500..510).contains(&k)),
            ..t[k]
        };
        let mut kept = Kept::default();
        for k in 0..t.len() {
            kept.push(&row(k), 10);
        }
        let names = ["s".to_owned()];
        let e = kept.epochs(&names);
        // Rows 0-499 (50 kept), the first of the ten flagged, rows 510-3499 as one run (299),
        // and the second stretch's 500 (50).
        assert_eq!(e.rows.len(), 50 + 1 + 299 + 50);
        assert_eq!(e.rows.iter().filter(|r| r.flags != 0).count(), 1);
        let found = crossovers(&e, 100.0, |_, _| Some(0.5));
        let all = crossovers(&epochs(&t, &names), 100.0, |_, _| Some(0.5));
        assert_eq!(found.len(), 1, "{found:?}");
        let (c, d) = (&found[0], &all[0]);
        assert!((c.longitude_deg - d.longitude_deg).abs() < 1e-9, "{c:?}");
        assert!((c.latitude_deg - d.latitude_deg).abs() < 1e-9, "{c:?}");
        assert!(
            (c.difference_mgal - d.difference_mgal).abs() < 1e-9,
            "{c:?}"
        );
        assert_eq!(step(100.0, 0.1), 20);
        assert_eq!(step(1.0, 0.1), 1);
    }
}
