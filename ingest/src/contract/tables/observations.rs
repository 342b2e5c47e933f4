//! `observations.parquet`, written by align (OUT/align/): one row per (theodolite reading,
//! accelerometer), in session, accelerometer, time order.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session | utf8 (dictionary) | session id |
//! | accelerometer | utf8 (dictionary) | accelerometer id |
//! | channel | uint8 | 1..3 |
//! | station | utf8 | tilt position id |
//! | line | uint32 | line of the reading in the theodolite log |
//! | time_gps_ns | int64 | GPS time of the reading, ns |
//! | dz_rad | float64 | zenith distance, rad |
//! | sigma_dz_rad | float64 | sd of one reading at this station, rad (eq. 4) |
//! | sigma_dz_source | utf8 | `moderated`, `station_sd`, `manifest` or `resolution` ([`super::align_ledger::sigma_source`]) |
//! | sigma_dz_dof | float64, null | degrees of freedom of sigma_dz when estimated from readings (moderated: prior + own); null when taken as known |
//! | sigma_dz_loo_rad | float64 | sigma_dz of the station formed as above without this reading, rad: the reference of its w-test |
//! | sigma_dz_loo_dof | float64, null | its degrees of freedom; null when taken as known |
//! | sigma_am_mgal | float64 | g sin(Dz) sigma_Dz, mGal |
//! | ng | float64, null | mean counts in the window |
//! | sigma_ng | float64, null | sd of that mean, counts |
//! | sigma_ng_dof | float64, null | degrees of freedom of sigma_ng (the window's own sample variance, n - 1, Satterthwaite's with the coloured noise's known part); null when taken as known (the quantisation floor) |
//! | n_samples | uint32 | samples in the window |
//! | expected_samples | float64 | window_s x sample_rate_hz |
//! | temperature_c | float64, null | accelerometer temperature at the reading, degC |
//! | sigma_temperature_c | float64, null | its sd from the thermometer's noise (the session's estimate for the channel times the root of the interpolation weights' squares), degC; null when there is no temperature or no estimate |
//! | drift_t | float64, null | t statistic of a linear trend of the counts in the window |
//! | tide_mgal | float64, null | body tide at the reading's time, mGal; null when none is applied |
//! | gravity_mgal | float64 | gravity at the proof masses at the reading: g (+ tide), mGal |
//! | excluded | utf8, null | why the observation is not used; null when used |

use super::{Arc, DataType, Field, SESSION, Schema, SchemaRef, TIME_GPS_NS, session_type};
/// File name.
pub const FILE: &str = "observations.parquet";
/// Accelerometer id.
pub const ACCELEROMETER: &str = "accelerometer";
/// Channel 1..3.
pub const CHANNEL: &str = "channel";
/// Station id.
pub const STATION: &str = "station";
/// Line in the theodolite log.
pub const LINE: &str = "line";
/// Zenith distance, rad.
pub const DZ_RAD: &str = "dz_rad";
/// Sd of one reading, rad.
pub const SIGMA_DZ_RAD: &str = "sigma_dz_rad";
/// Where sigma_dz comes from.
pub const SIGMA_DZ_SOURCE: &str = "sigma_dz_source";
/// Degrees of freedom of sigma_dz (null: known).
pub const SIGMA_DZ_DOF: &str = "sigma_dz_dof";
/// sigma_dz without the reading, rad.
pub const SIGMA_DZ_LOO_RAD: &str = "sigma_dz_loo_rad";
/// Its degrees of freedom (null: known).
pub const SIGMA_DZ_LOO_DOF: &str = "sigma_dz_loo_dof";
/// Acceleration sd implied by sigma_dz, mGal.
pub const SIGMA_AM_MGAL: &str = "sigma_am_mgal";
/// Mean counts.
pub const NG: &str = "ng";
/// Sd of the mean counts.
pub const SIGMA_NG: &str = "sigma_ng";
/// Degrees of freedom of sigma_ng (null: known).
pub const SIGMA_NG_DOF: &str = "sigma_ng_dof";
/// Samples in the window.
pub const N_SAMPLES: &str = "n_samples";
/// Samples a full window holds.
pub const EXPECTED_SAMPLES: &str = "expected_samples";
/// Temperature, degC.
pub const TEMPERATURE_C: &str = "temperature_c";
/// Its sd from the thermometer's noise, degC.
pub const SIGMA_TEMPERATURE_C: &str = "sigma_temperature_c";
/// Trend t statistic.
pub const DRIFT_T: &str = "drift_t";
/// Body tide, mGal.
pub const TIDE_MGAL: &str = "tide_mgal";
/// Gravity at the reading, mGal.
pub const GRAVITY_MGAL: &str = "gravity_mgal";
/// Exclusion reason.
pub const EXCLUDED: &str = "excluded";
/// The Arrow schema.
pub fn schema() -> SchemaRef {
    Arc::new(Schema::new(vec![
        Field::new(SESSION, session_type(), false),
        Field::new(ACCELEROMETER, session_type(), false),
        Field::new(CHANNEL, DataType::UInt8, false),
        Field::new(STATION, DataType::Utf8, false),
        Field::new(LINE, DataType::UInt32, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
        Field::new(DZ_RAD, DataType::Float64, false),
        Field::new(SIGMA_DZ_RAD, DataType::Float64, false),
        Field::new(SIGMA_DZ_SOURCE, DataType::Utf8, false),
        Field::new(SIGMA_DZ_DOF, DataType::Float64, true),
        Field::new(SIGMA_DZ_LOO_RAD, DataType::Float64, false),
        Field::new(SIGMA_DZ_LOO_DOF, DataType::Float64, true),
        Field::new(SIGMA_AM_MGAL, DataType::Float64, false),
        Field::new(NG, DataType::Float64, true),
        Field::new(SIGMA_NG, DataType::Float64, true),
        Field::new(SIGMA_NG_DOF, DataType::Float64, true),
        Field::new(N_SAMPLES, DataType::UInt32, false),
        Field::new(EXPECTED_SAMPLES, DataType::Float64, false),
        Field::new(TEMPERATURE_C, DataType::Float64, true),
        Field::new(SIGMA_TEMPERATURE_C, DataType::Float64, true),
        Field::new(DRIFT_T, DataType::Float64, true),
        Field::new(EXCLUDED, DataType::Utf8, true),
        Field::new(TIDE_MGAL, DataType::Float64, true),
        Field::new(GRAVITY_MGAL, DataType::Float64, false),
    ]))
}

/// One row of observations.parquet: a theodolite reading and one accelerometer's window
/// around it.
#[derive(Clone, Debug, PartialEq)]
pub struct Observation {
    /// Session id.
    pub session: String,
    /// Accelerometer id.
    pub accelerometer: String,
    /// Channel 1..3.
    pub channel: u8,
    /// Station id.
    pub station: String,
    /// Line in the theodolite log.
    pub line: u32,
    /// GPS time of the reading, ns.
    pub time_gps_ns: i64,
    /// Zenith distance, rad.
    pub dz_rad: f64,
    /// Sd of one reading at the station, rad.
    pub sigma_dz_rad: f64,
    /// `moderated`, `station_sd`, `manifest` or `resolution`.
    pub sigma_dz_source: String,
    /// Degrees of freedom of sigma_dz when estimated from readings: the moderated
    /// variance's prior dof plus the station's own, or the station's own (eq. 4); None when
    /// taken as known (manifest, resolution floor).
    pub sigma_dz_dof: Option<f64>,
    /// sigma_Dz of the station formed without this reading (the w-test's reference), rad.
    pub sigma_dz_loo_rad: f64,
    /// Its degrees of freedom; None when taken as known.
    pub sigma_dz_loo_dof: Option<f64>,
    /// g |sin Dz| sigma_Dz, mGal.
    pub sigma_am_mgal: f64,
    /// Mean count (None when the window has none).
    pub ng: Option<f64>,
    /// Sd of the mean count.
    pub sigma_ng: Option<f64>,
    /// Its degrees of freedom; None when taken as known.
    pub sigma_ng_dof: Option<f64>,
    /// Valid samples in the window.
    pub n_samples: u32,
    /// Samples a full window holds.
    pub expected_samples: f64,
    /// Temperature at the reading, degC.
    pub temperature_c: Option<f64>,
    /// Its sd from the thermometer's noise, degC.
    pub sigma_temperature_c: Option<f64>,
    /// Trend t statistic.
    pub drift_t: Option<f64>,
    /// Why it is not used (None: used).
    pub excluded: Option<String>,
    /// Body tide at the reading's time, mGal (None when no tide is applied).
    pub tide_mgal: Option<f64>,
    /// Gravity at the proof masses at the reading: g, plus the tide when applied, mGal.
    pub gravity_mgal: f64,
}

/// Writes `observations.parquet` into `dir`; returns the rows written.
pub fn write(dir: &std::path::Path, obs: &[Observation]) -> crate::Result<u64> {
    use crate::parquet_io::table::{Encodings, TableWriter};
    let schema = schema();
    let columns = super::in_schema_order(&dir.join(FILE), &schema, columns(obs))?;
    let mut table = TableWriter::create(
        dir,
        FILE,
        schema.clone(),
        Encodings {
            dictionary: &[SESSION, ACCELEROMETER, STATION],
            ..Default::default()
        },
    )?;
    table.write(columns)?;
    table.finish()
}

/// The table's columns of `obs`, by name.
fn columns(obs: &[Observation]) -> Vec<(&'static str, arrow_array::ArrayRef)> {
    use crate::parquet_io::table::dictionary_column;
    use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray, UInt8Array, UInt32Array};
    let f = |g: fn(&Observation) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(obs.iter().map(g)))
    };
    let fo = |g: fn(&Observation) -> Option<f64>| -> ArrayRef {
        Arc::new(Float64Array::from_iter(obs.iter().map(g)))
    };
    vec![
        (
            SESSION,
            dictionary_column(obs.iter().map(|o| o.session.as_str())),
        ),
        (
            ACCELEROMETER,
            dictionary_column(obs.iter().map(|o| o.accelerometer.as_str())),
        ),
        (
            CHANNEL,
            Arc::new(UInt8Array::from_iter_values(obs.iter().map(|o| o.channel))),
        ),
        (
            STATION,
            Arc::new(StringArray::from_iter_values(
                obs.iter().map(|o| &o.station),
            )),
        ),
        (
            LINE,
            Arc::new(UInt32Array::from_iter_values(obs.iter().map(|o| o.line))),
        ),
        (
            TIME_GPS_NS,
            Arc::new(Int64Array::from_iter_values(
                obs.iter().map(|o| o.time_gps_ns),
            )),
        ),
        (DZ_RAD, f(|o| o.dz_rad)),
        (SIGMA_DZ_RAD, f(|o| o.sigma_dz_rad)),
        (
            SIGMA_DZ_SOURCE,
            Arc::new(StringArray::from_iter_values(
                obs.iter().map(|o| &o.sigma_dz_source),
            )),
        ),
        (SIGMA_DZ_DOF, fo(|o| o.sigma_dz_dof)),
        (SIGMA_DZ_LOO_RAD, f(|o| o.sigma_dz_loo_rad)),
        (SIGMA_DZ_LOO_DOF, fo(|o| o.sigma_dz_loo_dof)),
        (SIGMA_AM_MGAL, f(|o| o.sigma_am_mgal)),
        (NG, fo(|o| o.ng)),
        (SIGMA_NG, fo(|o| o.sigma_ng)),
        (SIGMA_NG_DOF, fo(|o| o.sigma_ng_dof)),
        (
            N_SAMPLES,
            Arc::new(UInt32Array::from_iter_values(
                obs.iter().map(|o| o.n_samples),
            )),
        ),
        (EXPECTED_SAMPLES, f(|o| o.expected_samples)),
        (TEMPERATURE_C, fo(|o| o.temperature_c)),
        (SIGMA_TEMPERATURE_C, fo(|o| o.sigma_temperature_c)),
        (DRIFT_T, fo(|o| o.drift_t)),
        (
            EXCLUDED,
            Arc::new(StringArray::from_iter(
                obs.iter().map(|o| o.excluded.as_deref()),
            )),
        ),
        (TIDE_MGAL, fo(|o| o.tide_mgal)),
        (GRAVITY_MGAL, f(|o| o.gravity_mgal)),
    ]
}

/// Reads `dir`'s observations.parquet (OUT/align/). Every column of [`schema`] must be
/// there: a table from an older gravcal is refused with the column it lacks (re-run align).
pub fn read(dir: &std::path::Path) -> crate::Result<Vec<Observation>> {
    use super::read::{batches_of, column, dictionary, floats, opt};
    use arrow_array::Array;
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Int64Type, UInt8Type, UInt32Type};
    let path = dir.join(FILE);
    let mut out = Vec::new();
    for b in batches_of(&path, 1 << 16)? {
        let b = b?;
        let (session, acc) = (
            dictionary(&path, &b, SESSION)?,
            dictionary(&path, &b, ACCELEROMETER)?,
        );
        let strings = |name| column(&path, &b, name, &DataType::Utf8).map(|c| c.as_string::<i32>());
        let (station, source, excluded) = (
            strings(STATION)?,
            strings(SIGMA_DZ_SOURCE)?,
            strings(EXCLUDED)?,
        );
        let u32s = |name| {
            column(&path, &b, name, &DataType::UInt32).map(|c| c.as_primitive::<UInt32Type>())
        };
        let (line, n_samples) = (u32s(LINE)?, u32s(N_SAMPLES)?);
        let channel = column(&path, &b, CHANNEL, &DataType::UInt8)?.as_primitive::<UInt8Type>();
        let time = column(&path, &b, TIME_GPS_NS, &DataType::Int64)?.as_primitive::<Int64Type>();
        let x = |name| floats(&path, &b, name);
        let (dz, sdz, sdz_dof) = (x(DZ_RAD)?, x(SIGMA_DZ_RAD)?, x(SIGMA_DZ_DOF)?);
        let (loo, loo_dof, sam) = (
            x(SIGMA_DZ_LOO_RAD)?,
            x(SIGMA_DZ_LOO_DOF)?,
            x(SIGMA_AM_MGAL)?,
        );
        let (ng, sng, sng_dof) = (x(NG)?, x(SIGMA_NG)?, x(SIGMA_NG_DOF)?);
        let (expected, temp, stemp) = (
            x(EXPECTED_SAMPLES)?,
            x(TEMPERATURE_C)?,
            x(SIGMA_TEMPERATURE_C)?,
        );
        let (drift, tide, gravity) = (x(DRIFT_T)?, x(TIDE_MGAL)?, x(GRAVITY_MGAL)?);
        for i in 0..b.num_rows() {
            out.push(Observation {
                session: session[i].clone(),
                accelerometer: acc[i].clone(),
                channel: channel.value(i),
                station: station.value(i).to_owned(),
                line: line.value(i),
                time_gps_ns: time.value(i),
                dz_rad: dz.value(i),
                sigma_dz_rad: sdz.value(i),
                sigma_dz_source: source.value(i).to_owned(),
                sigma_dz_dof: opt(sdz_dof, i),
                sigma_dz_loo_rad: loo.value(i),
                sigma_dz_loo_dof: opt(loo_dof, i),
                sigma_am_mgal: sam.value(i),
                ng: opt(ng, i),
                sigma_ng: opt(sng, i),
                sigma_ng_dof: opt(sng_dof, i),
                n_samples: n_samples.value(i),
                expected_samples: expected.value(i),
                temperature_c: opt(temp, i),
                sigma_temperature_c: opt(stemp, i),
                drift_t: opt(drift, i),
                excluded: excluded.is_valid(i).then(|| excluded.value(i).to_owned()),
                tide_mgal: opt(tide, i),
                gravity_mgal: gravity.value(i),
            });
        }
    }
    Ok(out)
}
