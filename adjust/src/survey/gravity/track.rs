//! A survey session's track, made ready for the stage, without holding the trajectory: the
//! file is read twice, once for its median interval (the time gate's nominal step), then
//! each epoch through ingest's time gate; with attitude, the attitude is interpolated at
//! each epoch kept (one without is dropped by name) and the lever arm applied through it
//! (levelled, its down component). The kept epochs' positions and sds are written aside
//! ([`super::spill`], 56 bytes an epoch) and read back a block at a time; only their times
//! (8 bytes an epoch) stay in memory; the attitude, written aside as it is read
//! ([`super::attitude::read_spilled`]), is interpolated again wherever it is needed. A
//! third pass over what was written gives the positions' white noise and the median of the
//! file's sds.

use super::attitude::{self, AttitudeAt, AttitudeCursor, SpilledAttitude};
use super::epochs::ThirdDifferences;
use super::meter::MeterLines;
use super::reduce::Steps;
use super::spill::{Spill, SpillWriter};
use super::trajectory::{self, Epoch, Values, count_dropped};
use super::{BadLine, GravityError};
use ingest::base::timegate::{Position, TimeGate};
use ingest::contract::gravity_ledger::dropped;
use ingest::contract::manifest::{AdcFormat, Dataset, ResolvedSession};
use ingest::contract::survey::{Heights, SurveyConfig, TrajectoryFormat};
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

/// A survey session's trajectory, read and made ready: the accelerometers' positions (the
/// lever arm applied: through the attitude where the session gives one, its down component
/// alone on a levelled platform otherwise), epochs outside the session's days, whose time
/// does not increase, or (with attitude) without an attitude dropped.
pub(super) struct Track<'a> {
    pub index: u16,
    pub session: &'a ResolvedSession,
    /// The trajectory's epochs read, with the lines set aside.
    pub epochs_read: u64,
    /// The kept epochs' times, GPS ns, increasing.
    pub times: Vec<i64>,
    /// Their median interval, ns (1 s for fewer than two).
    pub interval_ns: i64,
    /// The kept epochs' positions, written aside ([`Positions`]).
    positions: Spill,
    pub dropped: BTreeMap<String, u64>,
    /// The session's attitude, when it gives one: every kept epoch has one there.
    pub attitude: Option<SpilledAttitude>,
    /// The trajectory's and attitude's lines set aside, as listed in the ledger.
    pub bad_lines: Vec<String>,
    /// The attitude's samples the time gate dropped, by reason.
    pub attitude_dropped: BTreeMap<String, u64>,
    /// The positions' white noise north, east, up from their third differences, m.
    pub noise_neu_m: [f64; 3],
    /// The median over the kept epochs of the file's sds north, east, up (None where it
    /// gives none), m.
    pub sd_given_median_m: Option<[f64; 3]>,
    /// The kept epochs whose position was an outlier, replaced by its neighbours'
    /// prediction ([`screen`]), increasing.
    pub replaced: Vec<usize>,
    /// A platform meter's own record (its monitors and status words), when the session's
    /// samples come from its file.
    pub meter: Option<MeterLines>,
    /// An antenna array's session: what its antennas gave, and its attitude.parquet rows.
    pub array: Option<(
        ingest::contract::gravity_ledger::AntennasUsed,
        Vec<ingest::contract::tables::attitude::Row>,
    )>,
    /// What its heights are measured from (the format's, or an NMEA file's own).
    pub heights: Heights,
}

/// Doubles a kept epoch is written aside as: latitude, longitude, height (moved to the
/// accelerometers), the antenna's height, the file's sds north, east, up (NaN: none).
const WIDTH: usize = 7;

/// The kept epochs `start..` of a track, read back, indexed by the kept epoch's index.
pub(super) struct Positions {
    start: usize,
    values: Vec<f64>,
    noise_neu_m: [f64; 3],
}

impl Positions {
    fn at(&self, k: usize, i: usize) -> f64 {
        self.values[(k - self.start) * WIDTH + i]
    }

    /// Latitude, longitude (deg) and ellipsoidal height (m) of the accelerometers.
    pub fn llh(&self, k: usize) -> [f64; 3] {
        [self.at(k, 0), self.at(k, 1), self.at(k, 2)]
    }

    /// The antenna's height as the trajectory gives it, m.
    pub fn antenna_height_m(&self, k: usize) -> f64 {
        self.at(k, 3)
    }

    /// The positions' sds north, east, up, m: the larger of the file's (none counts as 0)
    /// and the positions' own white noise, so that a file whose sds are smaller than the
    /// scatter its positions show is not believed over them.
    pub fn sd_m(&self, k: usize) -> [f64; 3] {
        let given = self.sd_given_m(k);
        std::array::from_fn(|i| given[i].max(self.noise_neu_m[i]))
    }

    /// The file's sds north, east, up at kept epoch `k`, m (none counts as 0).
    pub fn sd_given_m(&self, k: usize) -> [f64; 3] {
        std::array::from_fn(|i| {
            let given = self.at(k, 4 + i);
            if given.is_nan() { 0.0 } else { given }
        })
    }

    /// The positions' own white noise north, east, up, m (from their third differences).
    pub fn noise_m(&self) -> [f64; 3] {
        self.noise_neu_m
    }
}

impl Track<'_> {
    /// How its named quantities come from its filtered values, with the survey's geoid
    /// height and normal gravity.
    pub fn named(&self, survey: &SurveyConfig) -> super::reduce::Named {
        super::reduce::Named {
            heights: self.heights,
            geoid_height_m: survey.geoid_height_m,
            normal: survey.normal_gravity,
        }
    }

    /// The attitude at the kept epochs `range` (None without attitude).
    pub fn attitude_at(
        &self,
        range: Range<usize>,
    ) -> Result<Option<Vec<AttitudeAt>>, GravityError> {
        let Some(a) = &self.attitude else {
            return Ok(None);
        };
        let mut cursor = AttitudeCursor::new(a);
        let mut out = Vec::with_capacity(range.len());
        for &t in &self.times[range] {
            out.push(cursor.at(t)?.ok_or_else(|| {
                spill_error(
                    self.session,
                    format!(
                        "the attitude at {} cannot be interpolated again where it was when \
                         the epoch was kept",
                        ingest::base::time::utc_iso(t)
                    ),
                )
            })?);
        }
        Ok(Some(out))
    }

    /// The kept epochs `range`, read back.
    pub fn positions(&self, range: Range<usize>) -> Result<Positions, GravityError> {
        let values = self.positions.read(range.clone()).map_err(|e| {
            spill_error(
                self.session,
                format!("the kept epochs could not be read back: {e}"),
            )
        })?;
        Ok(Positions {
            start: range.start,
            values: values.into_owned(),
            noise_neu_m: self.noise_neu_m,
        })
    }
}

fn spill_error(s: &ResolvedSession, message: String) -> GravityError {
    GravityError::Refused {
        message: format!("session {}: {message}", s.session.id),
    }
}

/// Each survey session's trajectory read, in manifest order, its kept epochs written into
/// `dir`; none is an error.
pub(super) fn read_tracks<'a>(
    ds: &'a Dataset,
    survey: &SurveyConfig,
    skip: bool,
    dir: &Path,
) -> Result<Vec<Track<'a>>, GravityError> {
    let mut tracks = Vec::new();
    for (index, s) in ds.sessions.iter().enumerate() {
        let Some(src) = &s.trajectory else { continue };
        let attitude = match &src.attitude {
            Some((path, form)) => Some(attitude::read_spilled(
                path,
                s.times.reader(*form),
                s.gps_range_ns(),
                skip,
                dir,
            )?),
            None => None,
        };
        if !src.antennas.is_empty() {
            tracks.push(array_track(ds, index, s, skip, survey, dir)?);
            continue;
        }
        let along = Along {
            attitude: attitude.as_ref(),
            derived: None,
            lever_arm_m: survey.lever_arm_m,
            skip,
        };
        let (mut track, bad) = gated(index, s, &along, dir)?;
        track.bad_lines = listed(ds, &src.path, &bad);
        if let (Some(a), Some((path, _))) = (&attitude, &src.attitude) {
            track.bad_lines.extend(listed(ds, path, &a.bad_lines));
            track.attitude_dropped = a.dropped.clone();
        }
        track.attitude = attitude;
        tracks.push(track);
    }
    if tracks.is_empty() {
        return Err(GravityError::Refused {
            message: format!(
                "no survey session of {} has a `trajectory` (docs/formats.md 10): nothing to \
                 reduce",
                ds.manifest_path.display()
            ),
        });
    }
    Ok(tracks)
}

/// An antenna array's session's track ([`super::array`]): the accelerometers' positions
/// the antennas give, through the time gate as a trajectory's, with the attitude they give.
fn array_track<'a>(
    ds: &Dataset,
    index: usize,
    s: &'a ResolvedSession,
    skip: bool,
    survey: &SurveyConfig,
    dir: &Path,
) -> Result<Track<'a>, GravityError> {
    let array = super::array::read_array(s, survey, skip, dir)?;
    let along = Along {
        attitude: array.attitude.as_ref(),
        derived: Some(&array.epochs[..]),
        lever_arm_m: [0.0; 3],
        skip,
    };
    let (mut track, _) = gated(index, s, &along, dir)?;
    let antennas = &s.trajectory.as_ref().expect("an array").antennas;
    for (k, lines) in &array.bad {
        track
            .bad_lines
            .extend(listed(ds, &antennas[*k].path, lines));
    }
    // An antenna's line set aside costs that antenna the epoch, not the epoch: counted
    // under the antenna (`antennas.dropped`), listed in the session's bad lines.
    if array.too_few > 0 {
        track
            .dropped
            .insert(dropped::TOO_FEW_ANTENNAS.to_owned(), array.too_few);
    }
    track.epochs_read += array.too_few;
    track.attitude = array.attitude;
    track.array = Some((array.used, array.rows));
    Ok(track)
}

/// The meters' own records of the sessions with a trajectory, in [`read_tracks`]'s order
/// (None for a session whose samples are not a meter's file).
pub(super) fn read_meters(ds: &Dataset) -> Result<Vec<Option<MeterLines>>, GravityError> {
    ds.sessions
        .iter()
        .filter(|s| s.trajectory.is_some())
        .map(|s| match &s.acquisition {
            ingest::contract::manifest::Acquisition::Lab { stream, .. }
                if !meter_in_trajectory(s) =>
            {
                super::meter::read(stream, s.session.adc_format, s.times.scale)
            }
            _ => Ok(None),
        })
        .collect()
}

/// Whether session `s`'s meter record is its trajectory's file (a DGS laptop file gives
/// both), read in the trajectory's first pass ([`first_pass`]) rather than again.
pub(super) fn meter_in_trajectory(s: &ResolvedSession) -> bool {
    match (&s.acquisition, &s.trajectory) {
        (ingest::contract::manifest::Acquisition::Lab { stream, .. }, Some(src)) => {
            s.session.adc_format == AdcFormat::DgsLaptop
                && src.format == TrajectoryFormat::DgsLaptop
                && src.antennas.is_empty()
                && *stream == src.path
        }
        _ => false,
    }
}

/// A file's lines set aside, as the ledger lists them (the first
/// [`ingest::contract::ingest_ledger::MAX_LISTED`]).
fn listed(ds: &Dataset, path: &Path, bad: &[BadLine]) -> Vec<String> {
    let rel = path
        .strip_prefix(&ds.dir)
        .unwrap_or(path)
        .display()
        .to_string();
    bad.iter()
        .take(ingest::contract::ingest_ledger::MAX_LISTED)
        .map(|b| format!("{rel}:{}: {}: {}", b.line, b.field, b.message))
        .collect()
}

/// Calls `f` with each epoch of session `s`'s trajectory (time, position, sds), an NMEA
/// file's as its first pass `nmea` found it; the lines set aside.
pub(super) fn each_epoch(
    s: &ResolvedSession,
    nmea: Option<trajectory::NmeaScan>,
    skip: bool,
    f: impl FnMut(i64, [f64; 3], Option<[f64; 3]>) -> Result<(), GravityError>,
) -> Result<Vec<BadLine>, GravityError> {
    each_epoch_and_meter(s, nmea, None, skip, f)
}

/// [`each_epoch`], a DGS laptop file's lines also added to `meter` where given.
fn each_epoch_and_meter(
    s: &ResolvedSession,
    nmea: Option<trajectory::NmeaScan>,
    meter: Option<&mut MeterLines>,
    skip: bool,
    mut f: impl FnMut(i64, [f64; 3], Option<[f64; 3]>) -> Result<(), GravityError>,
) -> Result<Vec<BadLine>, GravityError> {
    let Some(src) = &s.trajectory else {
        return Ok(Vec::new());
    };
    let g = |_: u64, t: i64, llh: [f64; 3], sd: Option<[f64; 3]>| f(t, llh, sd);
    match src.format {
        TrajectoryFormat::Rtklib => trajectory::for_each_rtklib(&src.path, skip, g),
        TrajectoryFormat::DgsLaptop => {
            let mut meter = meter;
            trajectory::for_each_dgs_laptop(&src.path, skip, |_, r| {
                if let Some(m) = meter.as_deref_mut() {
                    m.push_laptop(r);
                }
                f(r.gps_ns, [r.latitude_deg, r.longitude_deg, 0.0], None)
            })
        }
        TrajectoryFormat::Nmea => {
            let scan = match nmea {
                Some(scan) => scan,
                None => trajectory::nmea_scan(&src.path)?,
            };
            trajectory::for_each_nmea(&src.path, scan, s.date, skip, g)
        }
        TrajectoryFormat::Csv => {
            let form = src.time.unwrap_or(ingest::base::time::TimeForm::Iso);
            trajectory::for_each_csv(&src.path, s.times.reader(form), skip, g)
        }
    }
}

/// The trajectory's side of the time gate: the epochs kept, the others counted by the
/// gravity ledger's reason.
struct EpochSink<'a> {
    session: &'a ResolvedSession,
    times: Vec<i64>,
    out: SpillWriter,
    dropped: BTreeMap<String, u64>,
    attitude: Option<AttitudeCursor<'a>>,
    lever_arm_m: [f64; 3],
}

impl ingest::base::timegate::Sink<Values> for EpochSink<'_> {
    type Error = GravityError;

    fn accept(&mut self, time_ns: i64, (llh, sd): Values) -> Result<(), Self::Error> {
        let at = match &mut self.attitude {
            None => None,
            Some(cursor) => match cursor.at(time_ns)? {
                Some(at) => Some(at),
                None => {
                    count_dropped(&mut self.dropped, dropped::NO_ATTITUDE);
                    return Ok(());
                }
            },
        };
        let [lat, lon, h] = moved(llh, at.as_ref(), self.lever_arm_m);
        let [sn, se, su] = sd.unwrap_or([f64::NAN; 3]);
        self.times.push(time_ns);
        self.out
            .push(&[lat, lon, h, llh[2], sn, se, su])
            .map_err(|e| spill_error(self.session, format!("its epochs written aside: {e}")))
    }

    fn reject(&mut self, _: Position, why: &'static str, _: String, _: Values) {
        use ingest::contract::ingest_ledger::reason;
        let name = match why {
            reason::OUTSIDE_SESSION => dropped::OUTSIDE_SESSION,
            reason::TIME_OUTLIER => dropped::TIME_OUTLIER,
            _ => dropped::NOT_INCREASING,
        };
        count_dropped(&mut self.dropped, name);
    }
}

/// The most epochs a trajectory's first pass keeps for its second, 16 MB: 3 days at 1 Hz,
/// 7 h at 10 Hz. A longer trajectory is read twice.
const HELD_EPOCHS: usize = 1 << 18;

/// What a trajectory's first pass finds.
struct FirstPass {
    /// The median step between its epochs in file order, ns (1 s when it has fewer than 2).
    interval_ns: i64,
    /// Its epochs in file order, when there are at most [`HELD_EPOCHS`].
    held: Option<Vec<Epoch>>,
    /// Its lines set aside.
    bad: Vec<BadLine>,
    /// The meter's record, where it is the trajectory's file ([`meter_in_trajectory`]).
    meter: Option<MeterLines>,
}

/// The first pass over session `s`'s trajectory: the interval the time gate judges by, and
/// the epochs kept for the gate when they fit.
fn first_pass(
    s: &ResolvedSession,
    nmea: Option<trajectory::NmeaScan>,
    skip: bool,
    derived: Option<&[Epoch]>,
) -> Result<FirstPass, GravityError> {
    let mut steps = Steps::default();
    if let Some(epochs) = derived {
        for e in epochs {
            steps.push(e.0);
        }
        return Ok(FirstPass {
            interval_ns: steps.median().unwrap_or(1_000_000_000),
            held: Some(epochs.to_vec()),
            bad: Vec::new(),
            meter: None,
        });
    }
    let mut held = Some(Vec::new());
    let mut meter = meter_in_trajectory(s).then(|| MeterLines::empty(AdcFormat::DgsLaptop));
    let bad = each_epoch_and_meter(s, nmea, meter.as_mut(), skip, |t, llh, sd| {
        steps.push(t);
        match &mut held {
            Some(h) if h.len() < HELD_EPOCHS => h.push((t, llh, sd)),
            _ => held = None,
        }
        Ok(())
    })?;
    Ok(FirstPass {
        interval_ns: steps.median().unwrap_or(1_000_000_000),
        held,
        bad,
        meter,
    })
}

/// An NMEA trajectory's first pass, once: which sentences carry its fixes, its heights'
/// datum (None for another format).
fn nmea_scan(s: &ResolvedSession) -> Result<Option<trajectory::NmeaScan>, GravityError> {
    match &s.trajectory {
        Some(src) if src.format == TrajectoryFormat::Nmea => {
            trajectory::nmea_scan(&src.path).map(Some)
        }
        _ => Ok(None),
    }
}

/// What a trajectory's epochs are taken along to the accelerometers by: the attitude that
/// turns the lever arm (a file's, spilled), the epochs an antenna array derived (read in
/// place of a trajectory file, their positions already the accelerometers'), the lever arm,
/// and whether bad lines are skipped.
#[derive(Clone, Copy)]
struct Along<'a> {
    attitude: Option<&'a SpilledAttitude>,
    derived: Option<&'a [Epoch]>,
    lever_arm_m: [f64; 3],
    skip: bool,
}

/// The track of session `s` (the `index`-th), its trajectory in two passes (over the epochs
/// held in memory, [`HELD_EPOCHS`], or the file again): the median
/// interval between its epochs in file order, then each epoch through ingest's time gate
/// (every log's: outside the session's days, a time that repeats or goes back, one that
/// jumps away from its neighbours and back, each dropped alone, at that interval) and, with
/// attitude, dropped where none can be interpolated; each dropped epoch counted, each kept
/// moved by the lever arm and written aside into `dir`; the trajectory's lines set aside.
fn gated<'a>(
    index: usize,
    s: &'a ResolvedSession,
    along: &Along<'_>,
    dir: &Path,
) -> Result<(Track<'a>, Vec<BadLine>), GravityError> {
    let nmea = nmea_scan(s)?;
    let first = first_pass(s, nmea, along.skip, along.derived)?;
    let io = |e: std::io::Error| spill_error(s, format!("its epochs written aside: {e}"));
    let mut sink = EpochSink {
        session: s,
        times: Vec::new(),
        out: SpillWriter::new(dir, WIDTH).map_err(io)?,
        dropped: BTreeMap::new(),
        attitude: along.attitude.map(AttitudeCursor::new),
        lever_arm_m: along.lever_arm_m,
    };
    let mut gate = TimeGate::new(first.interval_ns, s.gps_range_ns());
    let mut read = 0u64;
    let mut offer = |(t, llh, sd)| {
        let at = Position::Line(read);
        read += 1;
        gate.offer(t, at, (llh, sd), &mut sink)
    };
    let bad = match first.held {
        Some(held) => {
            held.into_iter().try_for_each(&mut offer)?;
            first.bad
        }
        // Too long to hold: read again.
        None => each_epoch(s, nmea, along.skip, |t, llh, sd| offer((t, llh, sd)))?,
    };
    gate.finish(&mut sink)?;
    let EpochSink {
        times,
        out,
        mut dropped,
        ..
    } = sink;
    if !bad.is_empty() {
        dropped.insert(dropped::BAD_LINE.to_owned(), bad.len() as u64);
    }
    let positions = out.finish().map_err(io)?;
    let mut track = Track {
        index: u16::try_from(index).unwrap_or(u16::MAX),
        session: s,
        epochs_read: read + bad.len() as u64,
        times,
        positions,
        dropped,
        attitude: None,
        bad_lines: Vec::new(),
        attitude_dropped: BTreeMap::new(),
        interval_ns: 1_000_000_000,
        noise_neu_m: [0.0; 3],
        sd_given_median_m: None,
        replaced: Vec::new(),
        meter: first.meter,
        array: None,
        heights: s
            .trajectory
            .as_ref()
            .and_then(|src| src.format.heights())
            .or(nmea.map(|scan| scan.heights))
            .unwrap_or(Heights::Ellipsoidal),
    };
    let mut steps = Steps::default();
    for &t in &track.times {
        steps.push(t);
    }
    track.interval_ns = steps.median().unwrap_or(1_000_000_000);
    (track.noise_neu_m, track.sd_given_median_m) = noise_and_sds(&track)?;
    screen(&mut track, dir)?;
    Ok((track, bad))
}

/// The accelerometers' position from the antenna's, r_acc = r_ant + C_v^n l: through the
/// attitude where there is one; levelled without, where only the down component (a
/// constant) can be applied.
fn moved(llh: [f64; 3], attitude: Option<&AttitudeAt>, lever_arm_m: [f64; 3]) -> [f64; 3] {
    let [lat, lon, h] = llh;
    let Some(a) = attitude else {
        return [lat, lon, h - lever_arm_m[2]];
    };
    super::array::llh_of(llh, attitude::apply(&a.vehicle_to_nav(), lever_arm_m))
}

/// The kept positions' white noise north, east and up, m: their third differences, as the
/// samples' ([`ThirdDifferences`]; a vehicle's motion is smooth at the epochs' rate, a
/// swell's third difference at 10 Hz a hundredth of a cm), the angles turned into metres on
/// a sphere of 6371 km (ample for a noise level), at the kept epochs' median interval; and
/// the median over the kept epochs of the file's sds (None where it gives none).
fn noise_and_sds(track: &Track<'_>) -> Result<([f64; 3], Option<[f64; 3]>), GravityError> {
    let mut d: [ThirdDifferences; 3] =
        std::array::from_fn(|_| ThirdDifferences::new(track.interval_ns));
    // The file's sds by their order (exact medians; as many entries as distinct values).
    let mut sds: [BTreeMap<u64, u64>; 3] = Default::default();
    // East summed step by step at each step's own latitude: a longitude times the cosine of
    // the latitude carried the latitude's noise into east, in proportion to the longitude
    // (2.4 cm east from 1 cm north at 180 deg).
    let mut east = 0.0;
    let mut last: Option<[f64; 2]> = None;
    let n = track.times.len();
    let mut start = 0;
    while start < n {
        let range = start..(start + super::stage::BLOCK_EPOCHS).min(n);
        let p = track.positions(range.clone())?;
        for k in range.clone() {
            let [lat_deg, lon_deg, h] = p.llh(k);
            let lat = lat_deg.to_radians();
            if let Some([lat0, lon0]) = last {
                let mid = 0.5 * (lat + lat0.to_radians());
                east += super::navigation::longitude_step_deg(lon0, lon_deg).to_radians()
                    * 6.371e6
                    * mid.cos();
            }
            last = Some([lat_deg, lon_deg]);
            let ne = [lat * 6.371e6, east, h];
            for (d, v) in d.iter_mut().zip(ne) {
                d.push(track.times[k], v);
            }
            for (i, map) in sds.iter_mut().enumerate() {
                let v = p.at(k, 4 + i);
                if !v.is_nan() {
                    *map.entry(order_key(v)).or_insert(0) += 1;
                }
            }
        }
        start = range.end;
    }
    let median = |m: &BTreeMap<u64, u64>| {
        let n: u64 = m.values().sum();
        let mut seen = 0;
        m.iter().find_map(|(&key, &c)| {
            seen += c;
            (seen > n / 2).then(|| from_order_key(key))
        })
    };
    let given = sds
        .iter()
        .map(median)
        .collect::<Option<Vec<f64>>>()
        .map(|v| [v[0], v[1], v[2]]);
    Ok((d.map(|d| d.sd()), given))
}

/// The outlier test's level, in sds of the difference between a position and its
/// prediction: a Gaussian error passes it but for 6e-7 of epochs per axis, and both
/// predictions must fail it.
const OUTLIER_SDS: f64 = 5.0;
/// The longest step a prediction reaches over, in epoch intervals: past it (a gap) an epoch
/// is not tested.
const PREDICTION_REACH: f64 = 5.0;

/// A kept epoch's record and time, for [`screen`].
type Record = (i64, [f64; WIDTH]);

/// Every kept position tested against its neighbours (docs/formats.md 10.1): the quadratic
/// through the three before it (as corrected), extrapolated to its time, and the one
/// through the three after it, back. An epoch both predictions reject (by more than
/// [`OUTLIER_SDS`] sds of the difference, on any axis, the sd the larger of the file's and
/// the positions' own noise, at least 1 mm) is an outlier: the first two of a run are
/// replaced by the forward prediction with its sd and listed in `track.replaced`
/// (flagged `position_outlier`), the third and later dropped and counted as
/// `position_outlier`, cutting the track. A vehicle's own motion passes: where the track
/// turns, the prediction from the side it has turned to holds (the curvature steps, the
/// position does not).
fn screen(track: &mut Track<'_>, dir: &Path) -> Result<(), GravityError> {
    let n = track.times.len();
    let io = |e: std::io::Error| spill_error(track.session, format!("its epochs screened: {e}"));
    let mut out = SpillWriter::new(dir, WIDTH).map_err(io)?;
    let mut times = Vec::with_capacity(n);
    let mut history: Vec<Record> = Vec::new();
    let (mut run, mut dropped) = (0usize, 0u64);
    let mut replaced = Vec::new();
    let mut block = (0..0, Vec::new());
    let interval = track.interval_ns as f64;
    let noise = track.noise_neu_m;
    let record = |k: usize, block: &mut (Range<usize>, Vec<f64>)| -> Result<Record, GravityError> {
        if !block.0.contains(&k) {
            let range = k..(k + super::stage::BLOCK_EPOCHS).min(n);
            block.1 = track.positions(range.clone())?.values;
            block.0 = range;
        }
        let at = (k - block.0.start) * WIDTH;
        Ok((track.times[k], std::array::from_fn(|i| block.1[at + i])))
    };
    // The next three epochs, on the stack.
    let mut next: [Record; 3] = [(0, [0.0; WIDTH]); 3];
    for k in 0..n {
        let this = record(k, &mut block)?;
        let count = (k + 4).min(n) - (k + 1);
        for (slot, j) in next.iter_mut().zip(k + 1..k + 1 + count) {
            *slot = record(j, &mut block)?;
        }
        let ahead = &next[..count];
        let last3 = &history[history.len().saturating_sub(3)..];
        let sigma = |r: &Record| -> [f64; 3] {
            std::array::from_fn(|i| {
                let given = r.1[4 + i];
                (if given.is_nan() { 0.0 } else { given })
                    .max(noise[i])
                    .max(1e-3)
            })
        };
        let forward = predict(last3, this.0, interval);
        let backward = predict(ahead, this.0, interval);
        let rejects = |p: &Option<([f64; 4], f64)>| {
            p.as_ref()
                .is_some_and(|(v, gain)| departs(&this.1, v, sigma(&this), *gain))
        };
        let outlier =
            forward.is_some() && rejects(&forward) && (backward.is_none() || rejects(&backward));
        if !outlier {
            run = 0;
            out.push(&this.1).map_err(io)?;
            times.push(this.0);
            history.push(this);
        } else if run < 2 {
            run += 1;
            let (v, gain) = forward.unwrap_or(([0.0; 4], 1.0));
            let s = sigma(&this).map(|x| x * gain);
            let r = [v[0], v[1], v[2], v[3], s[0], s[1], s[2]];
            out.push(&r).map_err(io)?;
            replaced.push(times.len());
            times.push(this.0);
            history.push((this.0, r));
        } else {
            run += 1;
            dropped += 1;
        }
        if history.len() > 3 {
            history.remove(0);
        }
    }
    let positions = out.finish().map_err(io)?;
    track.positions = positions;
    track.times = times;
    track.replaced = replaced;
    if dropped > 0 {
        *track
            .dropped
            .entry(dropped::POSITION_OUTLIER.to_owned())
            .or_insert(0) += dropped;
    }
    Ok(())
}

/// The quadratic through `points` (three, in time order, or fewer: None) at time `t`:
/// latitude, longitude (unwrapped from the first point's), height, the antenna's height,
/// and sqrt(1 + sum of the weights squared), the sd of a position less the prediction in
/// units of one position's sd; None beyond [`PREDICTION_REACH`] intervals of the nearest.
fn predict(points: &[Record], t: i64, interval: f64) -> Option<([f64; 4], f64)> {
    let [a, b, c] = points else { return None };
    let nearest = [a.0, b.0, c.0].iter().map(|s| (t - s).abs()).min()?;
    if nearest as f64 > PREDICTION_REACH * interval {
        return None;
    }
    let x = [a.0, b.0, c.0].map(|s| (s - t) as f64 / interval);
    // Lagrange weights at 0.
    let w = [
        x[1] * x[2] / ((x[0] - x[1]) * (x[0] - x[2])),
        x[0] * x[2] / ((x[1] - x[0]) * (x[1] - x[2])),
        x[0] * x[1] / ((x[2] - x[0]) * (x[2] - x[1])),
    ];
    let lon0 = a.1[1];
    let unwrapped = |r: &Record| lon0 + super::navigation::longitude_step_deg(lon0, r.1[1]);
    let p: [[f64; 4]; 3] = [a, b, c].map(|r| [r.1[0], unwrapped(r), r.1[2], r.1[3]]);
    let v = std::array::from_fn(|i| w[0] * p[0][i] + w[1] * p[1][i] + w[2] * p[2][i]);
    let gain = (1.0 + w.iter().map(|x| x * x).sum::<f64>()).sqrt();
    Some((v, gain))
}

/// Whether position `r` (latitude, longitude, height) lies further from the prediction `v`
/// than [`OUTLIER_SDS`] times `gain` times its sd `sigma` (north, east, up, m) on any axis.
fn departs(r: &[f64; WIDTH], v: &[f64; 4], sigma: [f64; 3], gain: f64) -> bool {
    let [north, east] = super::navigation::step_ne_m([v[0], v[1]], [r[0], r[1]], r[0]);
    let d = [north, east, r[2] - v[2]];
    (0..3).any(|i| d[i].abs() > OUTLIER_SDS * gain * sigma[i])
}

/// A key whose order is `v`'s (total order of doubles).
fn order_key(v: f64) -> u64 {
    let b = v.to_bits();
    if b >> 63 == 1 { !b } else { b | 1 << 63 }
}

fn from_order_key(k: u64) -> f64 {
    f64::from_bits(if k >> 63 == 1 { k & !(1 << 63) } else { !k })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The order key sorts doubles as they compare, and comes back to the same bits.
    #[test]
    fn order_keys_sort_as_the_values() {
        let v = [-3.5, -0.0, 0.0, 1e-300, 0.01, 0.02, 7.0];
        for w in v.windows(2) {
            assert!(order_key(w[0]) < order_key(w[1]), "{w:?}");
        }
        assert!(
            v.iter()
                .all(|x| from_order_key(order_key(*x)).to_bits() == x.to_bits())
        );
        let times = [0, 50, 150, 250, 350, 550];
        let mut steps = Steps::default();
        for t in times {
            steps.push(t);
        }
        assert_eq!(steps.median(), Some(100));
        let mut sorted: Vec<i64> = times.windows(2).map(|w| w[1] - w[0]).collect();
        sorted.sort_unstable();
        assert_eq!(steps.median(), Some(sorted[sorted.len() / 2]));
        assert_eq!(Steps::default().median(), None);
    }
}
