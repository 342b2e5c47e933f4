//! An antenna array's session (docs/formats.md 10.2.1): each antenna's trajectory read as a
//! session's one trajectory is (the same readers, its own pass through ingest's time gate
//! at its median interval, its bad lines set aside), the antennas' epochs matched by time,
//! each epoch fitted ([`super::antennas`]), and the fit given to the session's track: the
//! accelerometers' positions with their sds, and the attitude with its covariance (an
//! attitude sample at every epoch); the fit is also written as `attitude.parquet`.
//!
//! The antennas' positions are taken to a local north-east-down frame at the first antenna
//! with a position at the epoch, and the accelerometers' position back from it, by the
//! radii of curvature there (baselines of metres: the frame's curvature is a micrometre). An
//! antenna whose file gives no sds at an epoch is weighed by its own white noise (its third
//! differences, as a single trajectory's are). The derived attitude's errors are those of
//! the positions: white per epoch when the positions are, as the stage carries them.

use super::antennas::{self, Fix};
use super::array_positions::{self, Sighting};
use super::attitude::{DerivedSample, SpilledAttitude};
use super::epochs::ThirdDifferences;
use super::{BadLine, GravityError};
use ingest::base::timegate::{Position, Sink, TimeGate};
use ingest::contract::gravity_ledger::{AntennasUsed, EstimatedPosition as Estimated};
use ingest::contract::manifest::ResolvedSession;
use ingest::contract::survey::{Antenna, SurveyConfig, TrajectorySource};
use ingest::contract::tables::attitude::Row as AttitudeRow;
use std::collections::BTreeMap;
use std::path::Path;

use super::trajectory::{Epoch, Values, count_dropped};

/// What an array gives its session's track.
pub(super) struct ArrayTrack {
    /// The accelerometers' positions with their sds, at the epochs solved.
    pub epochs: Vec<Epoch>,
    /// The attitude at the same epochs, with its covariance; None from two antennas (no
    /// roll: the track is reduced as without an attitude).
    pub attitude: Option<SpilledAttitude>,
    /// Each antenna's lines set aside, by antenna.
    pub bad: Vec<(usize, Vec<BadLine>)>,
    /// What gravity.json says of it.
    pub used: AntennasUsed,
    /// Epochs no fit could be made at.
    pub too_few: u64,
    /// The rows of attitude.parquet.
    pub rows: Vec<AttitudeRow>,
}

/// The epochs the time gate keeps, the others counted by reason.
#[derive(Default)]
struct Kept {
    epochs: Vec<Epoch>,
    dropped: BTreeMap<String, u64>,
}

impl Sink<Values> for Kept {
    type Error = GravityError;

    fn accept(&mut self, time_ns: i64, (llh, sd): Values) -> Result<(), GravityError> {
        self.epochs.push((time_ns, llh, sd));
        Ok(())
    }

    fn reject(&mut self, _: Position, why: &'static str, _: String, _: Values) {
        count_dropped(&mut self.dropped, why);
    }
}

/// Antenna `a`'s epochs through its own time gate, and its lines set aside.
fn antenna_epochs(
    s: &ResolvedSession,
    a: &Antenna,
    skip: bool,
) -> Result<(Kept, Vec<BadLine>), GravityError> {
    let mut one = s.clone();
    one.trajectory = Some(TrajectorySource {
        path: a.path.clone(),
        format: a.format,
        time: a.time,
        attitude: None,
        antennas: Vec::new(),
    });
    let mut all = Vec::new();
    let bad = super::track::each_epoch(&one, None, skip, |t, llh, sd| {
        all.push((t, llh, sd));
        Ok(())
    })?;
    let mut steps = super::reduce::Steps::default();
    for e in &all {
        steps.push(e.0);
    }
    let mut gate = TimeGate::new(steps.median().unwrap_or(1_000_000_000), s.gps_range_ns());
    let mut kept = Kept::default();
    for (k, (t, llh, sd)) in all.into_iter().enumerate() {
        gate.offer(t, Position::Line(k as u64), (llh, sd), &mut kept)?;
    }
    gate.finish(&mut kept)?;
    Ok((kept, bad))
}

/// North, east, down of `llh` from `origin` (deg, deg, m), m, by the radii at the origin.
fn ned_of(origin: [f64; 3], llh: [f64; 3]) -> [f64; 3] {
    let (r_m, r_n) = super::navigation::radii(&super::normal::GRS80, origin[0]);
    let phi = origin[0].to_radians();
    [
        (llh[0] - origin[0]).to_radians() * (r_m + origin[2]),
        super::navigation::longitude_step_deg(origin[1], llh[1]).to_radians()
            * (r_n + origin[2])
            * phi.cos(),
        origin[2] - llh[2],
    ]
}

/// The point `ned` (m) from `origin`, as latitude, longitude (deg) and height (m), by the
/// radii at the origin (a lever arm's offset, [`super::track`], is made so too).
pub(super) fn llh_of(origin: [f64; 3], ned: [f64; 3]) -> [f64; 3] {
    let (r_m, r_n) = super::navigation::radii(&super::normal::GRS80, origin[0]);
    let phi = origin[0].to_radians();
    [
        origin[0] + (ned[0] / (r_m + origin[2])).to_degrees(),
        origin[1] + (ned[1] / ((r_n + origin[2]) * phi.cos())).to_degrees(),
        origin[2] - ned[2],
    ]
}

/// An antenna's white noise north, east and up, m: its positions' third differences (in
/// its local frame at its first epoch), as a single trajectory's are measured
/// ([`super::epochs::ThirdDifferences`], at the epochs' median interval); NaN where too few
/// epochs give none.
fn white_noise(epochs: &[Epoch]) -> [f64; 3] {
    let Some(first) = epochs.first() else {
        return [f64::NAN; 3];
    };
    let mut steps = super::reduce::Steps::default();
    for e in epochs {
        steps.push(e.0);
    }
    let interval = steps.median().unwrap_or(1_000_000_000);
    let mut d: [ThirdDifferences; 3] = std::array::from_fn(|_| ThirdDifferences::new(interval));
    for (t, llh, _) in epochs {
        for (d, v) in d.iter_mut().zip(ned_of(first.1, *llh)) {
            d.push(*t, v);
        }
    }
    d.map(|d| Some(d.sd()).filter(|s| *s > 0.0).unwrap_or(f64::NAN))
}

/// Reads session `s`'s antennas and fits every epoch where at least three give a position,
/// or, with two antennas fore and aft, takes heading and pitch where both do
/// ([`Solved::two`]); each baseline checked at `[survey] baseline_length_sigmas`; the
/// attitude samples written aside into `dir`.
pub(super) fn read_array(
    s: &ResolvedSession,
    survey: &SurveyConfig,
    skip: bool,
    dir: &Path,
) -> Result<ArrayTrack, GravityError> {
    let src = s
        .trajectory
        .as_ref()
        .expect("an array session has its antennas");
    let antennas = &src.antennas;
    let read = read_antennas(s, antennas, skip)?;
    let limit = survey.baseline_length_sigmas;
    let noise: Vec<[f64; 3]> = read.epochs.iter().map(|e| white_noise(e)).collect();
    let Placed {
        positions,
        estimated,
    } = positions((&read.epochs, &noise), antennas, limit)?;
    let out = solve_epochs((&read.epochs, &noise), &positions, limit);
    let two = antennas.len() == 2;
    let attitude = match two {
        true => None,
        false => Some(super::attitude::spill_derived(
            &src.path,
            out.samples.iter().copied(),
            dir,
        )?),
    };
    let used = AntennasUsed {
        ids: antennas.iter().map(|a| a.id.clone()).collect(),
        epochs_read: read.epochs.iter().map(|e| e.len() as u64).collect(),
        dropped: read.dropped,
        epochs_solved: out.epochs.len() as u64,
        set_aside: antennas
            .iter()
            .zip(&out.set_aside)
            .filter(|(_, n)| **n > 0)
            .map(|(a, n)| (a.id.clone(), *n))
            .collect(),
        median_sd_hpr_deg: std::array::from_fn(|k| {
            let sd = |r: &AttitudeRow| [r.sd_heading_deg, r.sd_pitch_deg, r.sd_roll_deg][k];
            Some(median(out.rows.iter().map(sd))).filter(|v| !v.is_nan())
        }),
        not_given: match two {
            true => BTreeMap::from([("roll".to_owned(), TWO_ANTENNAS.to_owned())]),
            false => BTreeMap::new(),
        },
        median_sd_position_m: std::array::from_fn(|k| {
            median(out.epochs.iter().filter_map(|e| e.2.map(|sd| sd[k])))
        }),
        estimated,
    };
    Ok(ArrayTrack {
        epochs: out.epochs,
        attitude,
        bad: read.bad,
        used,
        too_few: out.too_few,
        rows: out.rows,
    })
}

/// Each antenna's epochs after its own time gate, what the gates dropped and the lines set
/// aside, by antenna.
struct AntennasRead {
    epochs: Vec<Vec<Epoch>>,
    dropped: BTreeMap<String, BTreeMap<String, u64>>,
    bad: Vec<(usize, Vec<BadLine>)>,
}

/// Reads each of `antennas` through its own time gate ([`antenna_epochs`]).
fn read_antennas(
    s: &ResolvedSession,
    antennas: &[Antenna],
    skip: bool,
) -> Result<AntennasRead, GravityError> {
    let mut read = AntennasRead {
        epochs: Vec::new(),
        dropped: BTreeMap::new(),
        bad: Vec::new(),
    };
    for (k, a) in antennas.iter().enumerate() {
        let (mut kept, lines) = antenna_epochs(s, a, skip)?;
        if !lines.is_empty() {
            let bad_line = ingest::contract::gravity_ledger::dropped::BAD_LINE.to_owned();
            kept.dropped.insert(bad_line, lines.len() as u64);
        }
        read.bad.push((k, lines));
        read.epochs.push(kept.epochs);
        if !kept.dropped.is_empty() {
            read.dropped.insert(a.id.clone(), kept.dropped);
        }
    }
    Ok(read)
}

/// Every epoch any antenna gives, matched by time across `per` (each antenna's epochs):
/// `f(t, at)` with antenna k's epoch at `at[k]` (None where it has none at `t`).
fn each_matched(per: &[Vec<Epoch>], mut f: impl FnMut(i64, &[Option<(usize, Epoch)>])) {
    let times: std::collections::BTreeSet<i64> =
        per.iter().flat_map(|e| e.iter().map(|x| x.0)).collect();
    let mut cursor = vec![0usize; per.len()];
    for t in times {
        let mut at: Vec<Option<(usize, Epoch)>> = vec![None; per.len()];
        for (k, e) in per.iter().enumerate() {
            while cursor[k] < e.len() && e[cursor[k]].0 < t {
                cursor[k] += 1;
            }
            if cursor[k] < e.len() && e[cursor[k]].0 == t {
                at[k] = Some((k, e[cursor[k]]));
            }
        }
        f(t, &at);
    }
}

/// The antennas' fixes at an epoch in the local frame at the first antenna with one (the
/// frame's origin, returned beside them), each weighed by its file's sds or else by its
/// own `noise`; None where no antenna has a position.
fn fixes_at(
    at: &[Option<(usize, Epoch)>],
    noise: &[[f64; 3]],
) -> Option<([f64; 3], Vec<Option<Fix>>)> {
    let origin = at.iter().flatten().next().map(|(_, e)| e.1)?;
    let fixes = at
        .iter()
        .map(|a| {
            a.map(|(k, (_, llh, sd))| {
                // The file's sds are north, east, up; down's is up's.
                let sd = sd
                    .filter(|s| s.iter().all(|v| *v > 0.0))
                    .unwrap_or(noise[k]);
                Fix {
                    ned_m: ned_of(origin, llh),
                    sd_m: sd,
                }
            })
        })
        .collect();
    Some((origin, fixes))
}

/// Every epoch of `per` (each antenna's epochs, and its white `noise`) solved
/// ([`Solved::epoch`], or [`Solved::two`] for two antennas) with each baseline checked at
/// `limit` sds, the antennas at `positions` (declared, or estimated).
fn solve_epochs(
    (per, noise): (&[Vec<Epoch>], &[[f64; 3]]),
    positions: &[[f64; 3]],
    limit: f64,
) -> Solved {
    let mut out = Solved::default();
    each_matched(per, |t, at| {
        out.epoch(t, fixes_at(at, noise), positions, limit)
    });
    out
}

/// The antennas' positions, in the manifest's order, and those estimated, by id.
struct Placed {
    positions: Vec<[f64; 3]>,
    estimated: BTreeMap<String, Estimated>,
}

/// The antennas' positions: each declared one as declared, each to estimate from its
/// sightings at the epochs of `per` (with each antenna's white `noise`) that the declared
/// ones solve ([`array_positions`]), screened at `limit`. An antenna that no two epochs see
/// is refused, naming it.
fn positions(
    (per, noise): (&[Vec<Epoch>], &[[f64; 3]]),
    antennas: &[Antenna],
    limit: f64,
) -> Result<Placed, GravityError> {
    let mut positions: Vec<[f64; 3]> = antennas
        .iter()
        .map(|a| a.position_m.unwrap_or_default())
        .collect();
    if antennas.iter().all(|a| a.position_m.is_some()) {
        return Ok(Placed {
            positions,
            estimated: BTreeMap::new(),
        });
    }
    let mut seen: Vec<Vec<Sighting>> = vec![Vec::new(); antennas.len()];
    each_matched(per, |_, at| {
        let Some((_, fixes)) = fixes_at(at, noise) else {
            return;
        };
        let declared: Vec<Option<Fix>> = fixes
            .iter()
            .zip(antennas)
            .map(|(f, a)| f.filter(|_| a.position_m.is_some()))
            .collect();
        let Ok(s) = antennas::solve(&positions, &declared, limit) else {
            return;
        };
        for (k, f) in fixes.iter().enumerate() {
            if let (Some(f), None) = (f, antennas[k].position_m) {
                seen[k].push(array_positions::sighting(&s, *f));
            }
        }
    });
    let mut estimated = BTreeMap::new();
    for (k, a) in antennas.iter().enumerate() {
        if a.position_m.is_some() {
            continue;
        }
        let e =
            array_positions::estimate(&seen[k], limit).ok_or_else(|| GravityError::Refused {
                message: format!(
                    "antenna `{}` (position_m = \"estimate\"): {} epoch(s) where the declared \
                 antennas solve see it; its position needs two at least",
                    a.id,
                    seen[k].len()
                ),
            })?;
        positions[k] = e.position_m;
        estimated.insert(a.id.clone(), e);
    }
    Ok(Placed {
        positions,
        estimated,
    })
}

/// Why two antennas give no roll (gravity.json's `antennas.not_given`).
pub(super) const TWO_ANTENNAS: &str = "two antennas fore and aft give heading and pitch; \
     roll turns the vehicle about their baseline: north and east are not given, and down is \
     reduced as without an attitude (docs/formats.md 10.2.1)";

/// The median of the values not NaN (NaN for none).
fn median(v: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = v.filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// The fits so far.
#[derive(Default)]
struct Solved {
    epochs: Vec<Epoch>,
    samples: Vec<DerivedSample>,
    rows: Vec<AttitudeRow>,
    set_aside: Vec<u64>,
    too_few: u64,
}

impl Solved {
    /// The epoch at `t` fitted from the antennas' `fixes` (in the local frame at the origin
    /// beside them; [`fixes_at`]) at their `positions`.
    fn epoch(
        &mut self,
        t: i64,
        fixes: Option<([f64; 3], Vec<Option<Fix>>)>,
        positions: &[[f64; 3]],
        limit: f64,
    ) {
        self.set_aside.resize(positions.len(), 0);
        let Some((origin, fixes)) = fixes else {
            return;
        };
        if positions.len() == 2 {
            return self.two(t, (origin, [fixes[0], fixes[1]]), positions, limit);
        }
        let s = match antennas::solve(positions, &fixes, limit) {
            Ok(s) => s,
            Err(why) => {
                self.count_set_aside(why.set_aside);
                self.too_few += 1;
                return;
            }
        };
        self.count_set_aside(s.set_aside);
        let sd_p: [f64; 3] = std::array::from_fn(|k| s.covariance[k][k].sqrt());
        self.epochs
            .push((t, llh_of(origin, s.origin_ned_m), Some(sd_p)));
        let c = s.hpr_covariance();
        let sd: [f64; 3] = std::array::from_fn(|k| c[k][k].sqrt());
        let corr = |i: usize, j: usize| c[i][j] / (sd[i] * sd[j]);
        let hpr_deg = s.hpr_rad.map(f64::to_degrees);
        let sd_deg = sd.map(f64::to_degrees);
        self.samples.push(DerivedSample {
            time_gps_ns: t,
            hpr_deg,
            sd_deg,
            nav_covariance: std::array::from_fn(|i| {
                std::array::from_fn(|j| s.covariance[3 + i][3 + j])
            }),
        });
        let [h, p, r] = hpr_deg;
        let [a, b, cc] = sd_deg;
        self.rows.push(AttitudeRow {
            time_gps_ns: t,
            heading_deg: h,
            pitch_deg: p,
            roll_deg: r,
            sd_heading_deg: a,
            sd_pitch_deg: b,
            sd_roll_deg: cc,
            corr_heading_pitch: corr(0, 1),
            corr_heading_roll: corr(0, 2),
            corr_pitch_roll: corr(1, 2),
            antennas_used: s.used,
            antennas_set_aside: s.set_aside,
        });
    }

    /// The epoch at `t` from two antennas fore and aft (their fixes in the local frame at
    /// `origin`, and their declared `positions`): where both give a position and their
    /// baseline's length holds,
    /// heading and pitch from it ([`antennas::heading_pitch`]), roll not given (NaN); the
    /// accelerometers' position the mean of each antenna less its position turned by
    /// heading and pitch (roll taken as 0 for it: the lever arms' vertical part z moves the
    /// position by z sin(roll) across and z (1 - cos(roll)) down, which its sds do not
    /// carry), its sd the antennas' mean's with the angles' errors through the lever arms.
    fn two(
        &mut self,
        t: i64,
        (origin, fixes): ([f64; 3], [Option<Fix>; 2]),
        positions: &[[f64; 3]],
        limit: f64,
    ) {
        let [Some(fa), Some(fb)] = fixes else {
            self.too_few += 1;
            return;
        };
        let fore = positions[1][0] > positions[0][0];
        let (aft, ahead) = if fore { (fa, fb) } else { (fb, fa) };
        if antennas::baseline_z(positions, (0, fa), (1, fb)).abs() > limit {
            self.count_set_aside(0b11);
            self.too_few += 1;
            return;
        }
        let ([h, p], [sd_h, sd_p]) = antennas::heading_pitch(aft, ahead, true);
        let c = super::attitude::rotation(h, p, 0.0);
        let lever: [f64; 3] = std::array::from_fn(|k| (positions[0][k] + positions[1][k]) / 2.0);
        let turned = super::attitude::apply(&c, lever);
        let ned: [f64; 3] = std::array::from_fn(|k| (fa.ned_m[k] + fb.ned_m[k]) / 2.0 - turned[k]);
        // Heading turns the lever arm about down; pitch about the vehicle's y axis, level.
        let by_heading = [-turned[1], turned[0], 0.0];
        let y = [-h.sin(), h.cos(), 0.0];
        let by_pitch = [
            y[1] * turned[2] - y[2] * turned[1],
            y[2] * turned[0] - y[0] * turned[2],
            y[0] * turned[1] - y[1] * turned[0],
        ];
        let sd: [f64; 3] = std::array::from_fn(|k| {
            ((fa.sd_m[k].powi(2) + fb.sd_m[k].powi(2)) / 4.0
                + (sd_h * by_heading[k]).powi(2)
                + (sd_p * by_pitch[k]).powi(2))
            .sqrt()
        });
        self.epochs.push((t, llh_of(origin, ned), Some(sd)));
        let nan = f64::NAN;
        let [h, p, sd_h, sd_p] = [h, p, sd_h, sd_p].map(f64::to_degrees);
        self.rows.push(AttitudeRow {
            time_gps_ns: t,
            heading_deg: h,
            pitch_deg: p,
            roll_deg: nan,
            sd_heading_deg: sd_h,
            sd_pitch_deg: sd_p,
            sd_roll_deg: nan,
            corr_heading_pitch: 0.0,
            corr_heading_roll: nan,
            corr_pitch_roll: nan,
            antennas_used: 0b11,
            antennas_set_aside: 0,
        });
    }

    fn count_set_aside(&mut self, mask: u32) {
        for (k, n) in self.set_aside.iter_mut().enumerate() {
            *n += u64::from(mask >> k & 1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point's local north-east-down offsets and back agree to a micrometre over metres.
    #[test]
    fn the_local_frame_goes_there_and_back() {
        let origin = [48.07, -10.3, 35.0];
        let ned = [2.1, -1.3, 0.7];
        let back = ned_of(origin, llh_of(origin, ned));
        for k in 0..3 {
            assert!((back[k] - ned[k]).abs() < 1e-9, "{back:?}");
        }
    }
}
