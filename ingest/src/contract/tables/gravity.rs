//! `OUT/gravity/gravity.parquet` (docs/formats.md 10.3): one row per trajectory epoch used,
//! in time order per session.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
//! | time_gps_ns | int64 | GPS time of the epoch, ns |
//! | stretch | uint32 | the stretch of track (cut at gaps) the epoch belongs to, from 0 per session |
//! | latitude_deg, longitude_deg | float64 | the accelerometers' position, deg |
//! | height_m | float64 | their ellipsoidal height (the antenna's with the lever arm), m |
//! | speed_m_s | float64 | speed over ground, m/s |
//! | eotvos_mgal, normal_mgal | float64 | the Eotvos term and normal gravity (`[survey] normal_gravity`'s ellipsoid), mGal |
//! | tide_mgal | float64 | the body tide's effect on gravity, removed (0 with `earth_tide = false`), mGal |
//! | cross_coupling_mgal | float64 | a platform meter's cross-coupling correction, added (0 without `cross_coupling`), mGal |
//! | down_mgal | float64 | the gravity disturbance down, unfiltered (ties applied), mGal |
//! | down_filtered_mgal | float64 | the same after the low-pass filter, mGal; NaN within a filter period of its stretch's ends (flag 4), as its sigma and parts, north's and east's |
//! | sigma_down_mgal | float64 | the filtered value's sigma: the six below in quadrature, mGal |
//! | sigma_calibration_mgal, sigma_positions_mgal, sigma_noise_mgal, sigma_tie_mgal, sigma_attitude_mgal, sigma_coupling_mgal | float64 | its parts, mGal (the attitude's 0 without attitude, the cross-coupling's without a fitted correction) |
//! | height_antenna_m | float64 | the antenna's height as the trajectory gives it, m |
//! | north_mgal, north_filtered_mgal, sigma_north_mgal | float64, null without attitude | the disturbance north, unfiltered and filtered, and the filtered value's sigma: the four below in quadrature |
//! | sigma_north_calibration_mgal, sigma_north_positions_mgal, sigma_north_noise_mgal, sigma_north_attitude_mgal | float64, null without attitude | its parts |
//! | east_... | float64, null without attitude | the same seven east |
//! | flags | uint8 | the bits of this module's flags, or-ed |
//! | meter_status | uint32, null | a platform meter's status word at the epoch (its lines' within half an epoch interval, or-ed; docs/formats.md 11.1), null where the session's samples carry none |

use super::{DataType, Field, SESSION_INDEX, SchemaRef, TIME_GPS_NS, with_sessions};
use crate::parquet_io::rowgroup;
use crate::parquet_io::table::{ColumnTableWriter, ColumnValues, Encodings, Written};
use std::mem::take;
use std::path::Path;
/// File name.
pub const FILE: &str = "gravity.parquet";
/// The epoch's specific force was extrapolated beyond the calibration's range.
pub const OUTSIDE_CALIBRATION: u8 = 1;
/// The vehicle was turning (course changing faster than [`TURN_DEG_PER_S`]).
pub const TURN: u8 = 2;
/// Within one filter period of its stretch's ends, where the filter sees only one side.
pub const EDGE: u8 = 4;
/// The attitude file gives no sd at the epoch: north's and east's sigmas (and their
/// attitude parts) are null, not known; down's attitude part is taken as 0 (it is
/// second order but in turns).
pub const ATTITUDE_SD_UNKNOWN: u8 = 8;
/// The epoch's position failed the outlier test against its neighbours: it was
/// replaced by their prediction, with the prediction's sd (docs/formats.md 10.1).
pub const POSITION_OUTLIER: u8 = 16;
/// The meter's status word has a bit set that `[survey] meter_status_flag_bits`
/// declares.
pub const METER_STATUS: u8 = 32;
/// The course rate above which an epoch is flagged [`TURN`], deg/s.
pub const TURN_DEG_PER_S: f64 = 0.5;
/// Every flag with its name in gravity.json, in bit order.
pub const FLAG_NAMES: [(u8, &str); 6] = [
    (OUTSIDE_CALIBRATION, "outside_calibration"),
    (TURN, "turn"),
    (EDGE, "edge"),
    (ATTITUDE_SD_UNKNOWN, "attitude_sd_unknown"),
    (POSITION_OUTLIER, "position_outlier"),
    (METER_STATUS, "meter_status"),
];
/// The columns of [`HORIZONTAL`] null where [`ATTITUDE_SD_UNKNOWN`] is set.
pub const NEEDS_ATTITUDE_SD: [&str; 4] = [
    "sigma_north_mgal",
    "sigma_north_attitude_mgal",
    "sigma_east_mgal",
    "sigma_east_attitude_mgal",
];
/// Column `latitude_deg`.
pub const LATITUDE_DEG: &str = "latitude_deg";
/// Column `longitude_deg`.
pub const LONGITUDE_DEG: &str = "longitude_deg";
/// Column `height_m`.
pub const HEIGHT_M: &str = "height_m";
/// Column `speed_m_s`.
pub const SPEED_M_S: &str = "speed_m_s";
/// Column `eotvos_mgal`.
pub const EOTVOS_MGAL: &str = "eotvos_mgal";
/// Column `normal_mgal`.
pub const NORMAL_MGAL: &str = "normal_mgal";
/// Column `tide_mgal`.
pub const TIDE_MGAL: &str = "tide_mgal";
/// Column `cross_coupling_mgal`.
pub const CROSS_COUPLING_MGAL: &str = "cross_coupling_mgal";
/// Column `sigma_coupling_mgal`.
pub const SIGMA_COUPLING_MGAL: &str = "sigma_coupling_mgal";
/// Column `down_mgal`.
pub const DOWN_MGAL: &str = "down_mgal";
/// Column `down_filtered_mgal`.
pub const DOWN_FILTERED_MGAL: &str = "down_filtered_mgal";
/// Column `sigma_down_mgal`.
pub const SIGMA_DOWN_MGAL: &str = "sigma_down_mgal";
/// Column `sigma_calibration_mgal`.
pub const SIGMA_CALIBRATION_MGAL: &str = "sigma_calibration_mgal";
/// Column `sigma_positions_mgal`.
pub const SIGMA_POSITIONS_MGAL: &str = "sigma_positions_mgal";
/// Column `sigma_noise_mgal`.
pub const SIGMA_NOISE_MGAL: &str = "sigma_noise_mgal";
/// Column `sigma_tie_mgal`.
pub const SIGMA_TIE_MGAL: &str = "sigma_tie_mgal";
/// Column `sigma_attitude_mgal`.
pub const SIGMA_ATTITUDE_MGAL: &str = "sigma_attitude_mgal";
/// Column `height_antenna_m`.
pub const HEIGHT_ANTENNA_M: &str = "height_antenna_m";
/// The Float64 columns after session_index, time_gps_ns and stretch, in order.
pub const FLOATS: [&str; 18] = [
    LATITUDE_DEG,
    LONGITUDE_DEG,
    HEIGHT_M,
    SPEED_M_S,
    EOTVOS_MGAL,
    NORMAL_MGAL,
    TIDE_MGAL,
    CROSS_COUPLING_MGAL,
    DOWN_MGAL,
    DOWN_FILTERED_MGAL,
    SIGMA_DOWN_MGAL,
    SIGMA_CALIBRATION_MGAL,
    SIGMA_POSITIONS_MGAL,
    SIGMA_NOISE_MGAL,
    SIGMA_TIE_MGAL,
    SIGMA_ATTITUDE_MGAL,
    SIGMA_COUPLING_MGAL,
    HEIGHT_ANTENNA_M,
];
/// The nullable Float64 columns of north and east (docs/formats.md 10.3), after
/// [`FLOATS`]: values only with attitude and a triad model, null elsewhere.
pub const HORIZONTAL: [&str; 14] = [
    "north_mgal",
    "north_filtered_mgal",
    "sigma_north_mgal",
    "sigma_north_calibration_mgal",
    "sigma_north_positions_mgal",
    "sigma_north_noise_mgal",
    "sigma_north_attitude_mgal",
    "east_mgal",
    "east_filtered_mgal",
    "sigma_east_mgal",
    "sigma_east_calibration_mgal",
    "sigma_east_positions_mgal",
    "sigma_east_noise_mgal",
    "sigma_east_attitude_mgal",
];
/// The nullable Float64 columns of the named quantities (docs/formats.md 10.3), after
/// [`HORIZONTAL`]: the filtered gravity disturbance and free-air anomaly, each null in a
/// session that cannot form it (`quantities` in gravity.json), NaN where
/// `down_filtered_mgal` is.
pub const NAMED: [&str; 2] = [
    "disturbance_filtered_mgal",
    "free_air_anomaly_filtered_mgal",
];
/// The stretch column.
pub const STRETCH: &str = "stretch";
/// The flags column.
pub const FLAGS: &str = "flags";
/// The meter's status column, after [`FLAGS`].
pub const METER_STATUS_WORD: &str = "meter_status";

/// The Arrow schema for the dataset's `sessions`.
pub fn schema(sessions: &[String]) -> SchemaRef {
    let mut fields = vec![
        Field::new(SESSION_INDEX, DataType::UInt16, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
        Field::new(STRETCH, DataType::UInt32, false),
    ];
    for name in FLOATS {
        fields.push(Field::new(name, DataType::Float64, false));
    }
    for name in HORIZONTAL.iter().chain(&NAMED) {
        fields.push(Field::new(*name, DataType::Float64, true));
    }
    fields.push(Field::new(FLAGS, DataType::UInt8, false));
    fields.push(Field::new(METER_STATUS_WORD, DataType::UInt32, true));
    with_sessions(fields, sessions)
}

/// A block's values of the [`FLOATS`] columns, a field per column.
#[derive(Default)]
pub struct Floats {
    /// `latitude_deg`.
    pub latitude_deg: Vec<f64>,
    /// `longitude_deg`.
    pub longitude_deg: Vec<f64>,
    /// `height_m`.
    pub height_m: Vec<f64>,
    /// `speed_m_s`.
    pub speed_m_s: Vec<f64>,
    /// `eotvos_mgal`.
    pub eotvos_mgal: Vec<f64>,
    /// `normal_mgal`.
    pub normal_mgal: Vec<f64>,
    /// `tide_mgal`.
    pub tide_mgal: Vec<f64>,
    /// `cross_coupling_mgal`.
    pub cross_coupling_mgal: Vec<f64>,
    /// `down_mgal`.
    pub down_mgal: Vec<f64>,
    /// `down_filtered_mgal`.
    pub down_filtered_mgal: Vec<f64>,
    /// `sigma_down_mgal`.
    pub sigma_down_mgal: Vec<f64>,
    /// `sigma_calibration_mgal`.
    pub sigma_calibration_mgal: Vec<f64>,
    /// `sigma_positions_mgal`.
    pub sigma_positions_mgal: Vec<f64>,
    /// `sigma_noise_mgal`.
    pub sigma_noise_mgal: Vec<f64>,
    /// `sigma_tie_mgal`.
    pub sigma_tie_mgal: Vec<f64>,
    /// `sigma_attitude_mgal`.
    pub sigma_attitude_mgal: Vec<f64>,
    /// `sigma_coupling_mgal`.
    pub sigma_coupling_mgal: Vec<f64>,
    /// `height_antenna_m`.
    pub height_antenna_m: Vec<f64>,
}

impl Floats {
    /// Each field under its column's name (in any order: the writer puts them in the
    /// schema's).
    fn named(self) -> [(&'static str, Vec<f64>); 18] {
        [
            (LATITUDE_DEG, self.latitude_deg),
            (LONGITUDE_DEG, self.longitude_deg),
            (HEIGHT_M, self.height_m),
            (SPEED_M_S, self.speed_m_s),
            (EOTVOS_MGAL, self.eotvos_mgal),
            (NORMAL_MGAL, self.normal_mgal),
            (TIDE_MGAL, self.tide_mgal),
            (CROSS_COUPLING_MGAL, self.cross_coupling_mgal),
            (DOWN_MGAL, self.down_mgal),
            (DOWN_FILTERED_MGAL, self.down_filtered_mgal),
            (SIGMA_DOWN_MGAL, self.sigma_down_mgal),
            (SIGMA_CALIBRATION_MGAL, self.sigma_calibration_mgal),
            (SIGMA_POSITIONS_MGAL, self.sigma_positions_mgal),
            (SIGMA_NOISE_MGAL, self.sigma_noise_mgal),
            (SIGMA_TIE_MGAL, self.sigma_tie_mgal),
            (SIGMA_ATTITUDE_MGAL, self.sigma_attitude_mgal),
            (SIGMA_COUPLING_MGAL, self.sigma_coupling_mgal),
            (HEIGHT_ANTENNA_M, self.height_antenna_m),
        ]
    }
}

/// A block's values of one horizontal component's seven columns (north's or east's), a
/// field per column.
#[derive(Default)]
pub struct Component {
    /// `<side>_mgal`: the disturbance, unfiltered.
    pub mgal: Vec<f64>,
    /// `<side>_filtered_mgal`.
    pub filtered_mgal: Vec<f64>,
    /// `sigma_<side>_mgal`.
    pub sigma_mgal: Vec<f64>,
    /// `sigma_<side>_calibration_mgal`.
    pub sigma_calibration_mgal: Vec<f64>,
    /// `sigma_<side>_positions_mgal`.
    pub sigma_positions_mgal: Vec<f64>,
    /// `sigma_<side>_noise_mgal`.
    pub sigma_noise_mgal: Vec<f64>,
    /// `sigma_<side>_attitude_mgal`.
    pub sigma_attitude_mgal: Vec<f64>,
}

impl Component {
    /// Each field under its column's name for `side` (north or east).
    fn named(self, side: &str) -> [(String, Vec<f64>); 7] {
        [
            (format!("{side}_mgal"), self.mgal),
            (format!("{side}_filtered_mgal"), self.filtered_mgal),
            (format!("sigma_{side}_mgal"), self.sigma_mgal),
            (
                format!("sigma_{side}_calibration_mgal"),
                self.sigma_calibration_mgal,
            ),
            (
                format!("sigma_{side}_positions_mgal"),
                self.sigma_positions_mgal,
            ),
            (format!("sigma_{side}_noise_mgal"), self.sigma_noise_mgal),
            (
                format!("sigma_{side}_attitude_mgal"),
                self.sigma_attitude_mgal,
            ),
        ]
    }
}

/// A block of consecutive epochs of one stretch, a field per column.
pub struct Block {
    /// The session's index.
    pub session_index: u16,
    /// The stretch's number in its session.
    pub stretch: u32,
    /// GPS time per epoch, ns.
    pub time_gps_ns: Vec<i64>,
    /// The [`FLOATS`] columns.
    pub floats: Floats,
    /// North and east ([`HORIZONTAL`]), none where the block has no attitude.
    pub horizontal: Option<[Component; 2]>,
    /// The [`NAMED`] quantities per epoch: the filtered disturbance and free-air anomaly,
    /// none where the session cannot form them.
    pub named: Vec<[Option<f64>; 2]>,
    /// Flags per epoch.
    pub flags: Vec<u8>,
    /// The meter's status word per epoch, none where the session's samples carry none.
    pub meter_status: Option<Vec<Option<u32>>>,
}

/// gravity.parquet being written: blocks gathered, then written as row groups.
pub struct Writer {
    table: ColumnTableWriter,
    /// Whether any track has attitude: then north and east are held, and whether each row
    /// has them; otherwise their columns are null throughout.
    with_horizontal: bool,
    session: Vec<u16>,
    time: Vec<i64>,
    stretch: Vec<u32>,
    floats: [Vec<f64>; FLOATS.len()],
    horizontal: [Vec<f64>; HORIZONTAL.len()],
    horizontal_valid: Vec<bool>,
    named: [Vec<f64>; NAMED.len()],
    named_valid: [Vec<bool>; NAMED.len()],
    flags: Vec<u8>,
    status: Vec<Option<u32>>,
}

/// Appends `src` to `dst`, taking it whole where `dst` is empty.
fn append<T: Copy>(dst: &mut Vec<T>, src: Vec<T>) {
    if dst.is_empty() {
        *dst = src;
    } else {
        dst.extend_from_slice(&src);
    }
}

/// Where column `name` stands in `names` (a bug if it is not there).
fn column_at(names: &[&str], name: &str) -> crate::Result<usize> {
    names
        .iter()
        .position(|n| *n == name)
        .ok_or_else(|| crate::Error::Table {
            path: FILE.into(),
            message: format!("a bug: `{name}` is not a column of {FILE}"),
        })
}

impl Writer {
    /// Starts the table in `dir` for the dataset's `sessions`; north and east are held
    /// `with_horizontal` (any track has attitude).
    pub fn create(dir: &Path, sessions: &[String], with_horizontal: bool) -> crate::Result<Self> {
        Ok(Writer {
            table: ColumnTableWriter::create(dir, FILE, schema(sessions), Encodings::default())?,
            with_horizontal,
            session: Vec::new(),
            time: Vec::new(),
            stretch: Vec::new(),
            floats: Default::default(),
            horizontal: Default::default(),
            horizontal_valid: Vec::new(),
            named: Default::default(),
            named_valid: Default::default(),
            flags: Vec::new(),
            status: Vec::new(),
        })
    }

    /// The epochs gathered and not yet written.
    pub fn gathered(&self) -> usize {
        self.time.len()
    }

    /// Gathers a block's epochs.
    pub fn push(&mut self, b: Block) -> crate::Result<()> {
        let n = b.time_gps_ns.len();
        self.session.extend(std::iter::repeat_n(b.session_index, n));
        append(&mut self.time, b.time_gps_ns);
        self.stretch.extend(std::iter::repeat_n(b.stretch, n));
        for (name, src) in b.floats.named() {
            append(&mut self.floats[column_at(&FLOATS, name)?], src);
        }
        self.push_horizontal(b.horizontal, n)?;
        for values in b.named {
            let columns = self.named.iter_mut().zip(&mut self.named_valid);
            for ((dst, valid), v) in columns.zip(values) {
                dst.push(v.unwrap_or(0.0));
                valid.push(v.is_some());
            }
        }
        append(&mut self.flags, b.flags);
        match b.meter_status {
            Some(words) => append(&mut self.status, words),
            None => self.status.extend(std::iter::repeat_n(None, n)),
        }
        Ok(())
    }

    /// North and east of the `n` epochs just pushed (zero and not valid without).
    fn push_horizontal(&mut self, h: Option<[Component; 2]>, n: usize) -> crate::Result<()> {
        if !self.with_horizontal {
            return Ok(());
        }
        let Some([north, east]) = h else {
            for dst in &mut self.horizontal {
                dst.extend(std::iter::repeat_n(0.0, n));
            }
            self.horizontal_valid.extend(std::iter::repeat_n(false, n));
            return Ok(());
        };
        for (name, src) in north.named("north").into_iter().chain(east.named("east")) {
            append(&mut self.horizontal[column_at(&HORIZONTAL, &name)?], src);
        }
        self.horizontal_valid.extend(std::iter::repeat_n(true, n));
        Ok(())
    }

    /// Writes the epochs gathered as one row group (none if there are none): Parquet's
    /// column writers on the values directly, the columns encoded on the pool (the Arrow
    /// path's arrays and casts were a tenth of the marine benchmark's gravity stage).
    pub fn write(&mut self) -> crate::Result<()> {
        let n_rows = self.time.len();
        if n_rows == 0 {
            return Ok(());
        }
        let int32 = |v: Vec<i32>| ColumnValues::Int32(v, None);
        let mut columns: Vec<(&str, ColumnValues)> = vec![
            (
                SESSION_INDEX,
                int32(take(&mut self.session).into_iter().map(i32::from).collect()),
            ),
            (TIME_GPS_NS, ColumnValues::Int64(take(&mut self.time), None)),
            (
                STRETCH,
                // UINT_32 is stored in INT32 as its bits.
                int32(
                    take(&mut self.stretch)
                        .into_iter()
                        .map(|v| v as i32)
                        .collect(),
                ),
            ),
        ];
        for (f, name) in self.floats.iter_mut().zip(FLOATS) {
            columns.push((name, ColumnValues::Double(take(f), None)));
        }
        let flags = take(&mut self.flags);
        // A sigma that needs the attitude's sds is null where the file gives none.
        let horizontal_valid = take(&mut self.horizontal_valid);
        let sd_known: Vec<bool> = (horizontal_valid.iter().zip(&flags))
            .map(|(v, f)| *v && f & ATTITUDE_SD_UNKNOWN == 0)
            .collect();
        for (f, name) in self.horizontal.iter_mut().zip(HORIZONTAL) {
            let f = take(f);
            let column = match self.with_horizontal {
                true if !NEEDS_ATTITUDE_SD.contains(&name) => nullable(f, &horizontal_valid),
                true => nullable(f, &sd_known),
                false => ColumnValues::Double(Vec::new(), Some(vec![0; n_rows])),
            };
            columns.push((name, column));
        }
        let named = self.named.iter_mut().zip(&mut self.named_valid);
        for ((f, valid), name) in named.zip(NAMED) {
            columns.push((name, nullable(take(f), &take(valid))));
        }
        columns.push((FLAGS, int32(flags.into_iter().map(i32::from).collect())));
        let status = take(&mut self.status);
        let levels = status.iter().map(|w| i16::from(w.is_some())).collect();
        let words = status.into_iter().flatten().map(|w| w as i32).collect();
        columns.push((METER_STATUS_WORD, ColumnValues::Int32(words, Some(levels))));
        self.table.write_row_group(n_rows, &columns)
    }

    /// Writes what is gathered and closes the table; returns its rows and SHA-256 (hashed
    /// as it was written).
    pub fn finish_hashed(mut self) -> crate::Result<Written> {
        self.write()?;
        self.table.finish_hashed()
    }
}

/// A nullable column of doubles: the values where `valid`, and their definition levels
/// ([`rowgroup::nullable`]).
fn nullable(values: Vec<f64>, valid: &[bool]) -> ColumnValues {
    let (kept, levels) = rowgroup::nullable(values, valid);
    ColumnValues::Double(kept, levels)
}
