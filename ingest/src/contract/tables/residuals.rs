//! `residuals.parquet`, written by adjust (OUT/adjust/): one row per observation and fit.
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | model | utf8 (dictionary) | model name |
//! | accelerometer | utf8 (dictionary) | accelerometer id |
//! | fit_session | utf8 (dictionary) | the fit's session id, or `all` |
//! | session | utf8 (dictionary) | the observation's session |
//! | station | utf8 | tilt position |
//! | line | uint32 | line in the theodolite log |
//! | time_gps_ns | int64 | GPS time, ns |
//! | dz_rad, sigma_dz_rad | float64 | zenith distance and its sd, rad |
//! | ng, sigma_ng | float64 | mean counts and its sd |
//! | temperature_c | float64 | degC |
//! | v_dz_rad | float64, null | residual of Dz, rad (null when removed) |
//! | v_ng | float64, null | residual of Ng, counts |
//! | residual_mgal | float64, null | condition residual B v, mGal |
//! | redundancy | float64, null | redundancy number |
//! | w | float64 | normalised residual, its Dz referred to the station's sigma_dz without it, as the normal quantile of its tail (at removal, for a removed observation) |
//! | removed | boolean | removed by data snooping |

use super::{Arc, DataType, Field, SESSION, Schema, SchemaRef, TIME_GPS_NS, session_type};
/// File name.
pub const FILE: &str = "residuals.parquet";
/// Model name.
pub const MODEL: &str = "model";
/// Accelerometer id.
pub const ACCELEROMETER: &str = "accelerometer";
/// The fit's session id, or `all`.
pub const FIT_SESSION: &str = "fit_session";
/// Station id.
pub const STATION: &str = "station";
/// Line in the theodolite log.
pub const LINE: &str = "line";
/// Zenith distance, rad.
pub const DZ_RAD: &str = "dz_rad";
/// Its sd, rad.
pub const SIGMA_DZ_RAD: &str = "sigma_dz_rad";
/// Mean counts.
pub const NG: &str = "ng";
/// Their sd.
pub const SIGMA_NG: &str = "sigma_ng";
/// Temperature, degC.
pub const TEMPERATURE_C: &str = "temperature_c";
/// Residual of Dz, rad.
pub const V_DZ_RAD: &str = "v_dz_rad";
/// Residual of Ng, counts.
pub const V_NG: &str = "v_ng";
/// Condition residual, mGal.
pub const RESIDUAL_MGAL: &str = "residual_mgal";
/// Redundancy number.
pub const REDUNDANCY: &str = "redundancy";
/// Normalised residual.
pub const W: &str = "w";
/// Removed by data snooping.
pub const REMOVED: &str = "removed";
/// The Arrow schema.
pub fn schema() -> SchemaRef {
    let dict = session_type;
    Arc::new(Schema::new(vec![
        Field::new(MODEL, dict(), false),
        Field::new(ACCELEROMETER, dict(), false),
        Field::new(FIT_SESSION, dict(), false),
        Field::new(SESSION, dict(), false),
        Field::new(STATION, DataType::Utf8, false),
        Field::new(LINE, DataType::UInt32, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
        Field::new(DZ_RAD, DataType::Float64, false),
        Field::new(SIGMA_DZ_RAD, DataType::Float64, false),
        Field::new(NG, DataType::Float64, false),
        Field::new(SIGMA_NG, DataType::Float64, false),
        Field::new(TEMPERATURE_C, DataType::Float64, false),
        Field::new(V_DZ_RAD, DataType::Float64, true),
        Field::new(V_NG, DataType::Float64, true),
        Field::new(RESIDUAL_MGAL, DataType::Float64, true),
        Field::new(REDUNDANCY, DataType::Float64, true),
        Field::new(W, DataType::Float64, false),
        Field::new(REMOVED, DataType::Boolean, false),
    ]))
}

/// One row to write: an observation's residuals in one fit.
#[derive(Clone, Debug)]
pub struct Fitted<'a> {
    /// Model name.
    pub model: &'a str,
    /// Accelerometer.
    pub accelerometer: &'a str,
    /// The fit's session or `all`.
    pub fit_session: &'a str,
    /// The observation.
    pub obs: &'a super::observations::Observation,
    /// Residual of Dz, rad.
    pub v_dz_rad: Option<f64>,
    /// Residual of Ng.
    pub v_ng: Option<f64>,
    /// Condition residual, mGal.
    pub residual_mgal: Option<f64>,
    /// Redundancy number.
    pub redundancy: Option<f64>,
    /// w-test.
    pub w: f64,
    /// Removed by snooping.
    pub removed: bool,
}

/// Writes residuals.parquet into `dir`; returns the rows written.
pub fn write(dir: &std::path::Path, rows: &[Fitted<'_>]) -> crate::Result<u64> {
    use crate::parquet_io::table::{Encodings, TableWriter, dictionary_column};
    use arrow_array::{ArrayRef, BooleanArray, Float64Array, Int64Array, StringArray, UInt32Array};
    let f = |g: fn(&Fitted<'_>) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(rows.iter().map(g)))
    };
    let fo = |g: fn(&Fitted<'_>) -> Option<f64>| -> ArrayRef {
        Arc::new(Float64Array::from_iter(rows.iter().map(g)))
    };
    let columns: Vec<(&str, ArrayRef)> = vec![
        (MODEL, dictionary_column(rows.iter().map(|r| r.model))),
        (
            ACCELEROMETER,
            dictionary_column(rows.iter().map(|r| r.accelerometer)),
        ),
        (
            FIT_SESSION,
            dictionary_column(rows.iter().map(|r| r.fit_session)),
        ),
        (
            SESSION,
            dictionary_column(rows.iter().map(|r| r.obs.session.as_str())),
        ),
        (
            STATION,
            Arc::new(StringArray::from_iter_values(
                rows.iter().map(|r| &r.obs.station),
            )),
        ),
        (
            LINE,
            Arc::new(UInt32Array::from_iter_values(
                rows.iter().map(|r| r.obs.line),
            )),
        ),
        (
            TIME_GPS_NS,
            Arc::new(Int64Array::from_iter_values(
                rows.iter().map(|r| r.obs.time_gps_ns),
            )),
        ),
        (DZ_RAD, f(|r| r.obs.dz_rad)),
        (SIGMA_DZ_RAD, f(|r| r.obs.sigma_dz_rad)),
        (NG, f(|r| r.obs.ng.unwrap_or(f64::NAN))),
        (SIGMA_NG, f(|r| r.obs.sigma_ng.unwrap_or(f64::NAN))),
        (
            TEMPERATURE_C,
            f(|r| r.obs.temperature_c.unwrap_or(f64::NAN)),
        ),
        (V_DZ_RAD, fo(|r| r.v_dz_rad)),
        (V_NG, fo(|r| r.v_ng)),
        (RESIDUAL_MGAL, fo(|r| r.residual_mgal)),
        (REDUNDANCY, fo(|r| r.redundancy)),
        (W, f(|r| r.w)),
        (
            REMOVED,
            Arc::new(BooleanArray::from_iter(
                rows.iter().map(|r| Some(r.removed)),
            )),
        ),
    ];
    let schema = schema();
    let columns = super::in_schema_order(&dir.join(FILE), &schema, columns)?;
    let mut t = TableWriter::create(
        dir,
        FILE,
        schema.clone(),
        Encodings {
            dictionary: &[MODEL, ACCELEROMETER, FIT_SESSION, SESSION, STATION],
            ..Default::default()
        },
    )?;
    t.write(columns)?;
    t.finish()
}

/// One row of residuals.parquet, as read back.
#[derive(Clone, Debug)]
pub struct Residual {
    /// Model name.
    pub model: String,
    /// Accelerometer.
    pub accelerometer: String,
    /// The fit's session or `all`.
    pub fit_session: String,
    /// The observation's session.
    pub session: String,
    /// Station.
    pub station: String,
    /// Line in the theodolite log.
    pub line: u32,
    /// GPS time, ns.
    pub time_gps_ns: i64,
    /// Zenith distance, rad.
    pub dz_rad: f64,
    /// Its sd, rad.
    pub sigma_dz_rad: f64,
    /// Mean counts.
    pub ng: f64,
    /// Its sd.
    pub sigma_ng: f64,
    /// Temperature, degC.
    pub temperature_c: f64,
    /// Condition residual, mGal (None for a removed observation).
    pub residual_mgal: Option<f64>,
    /// Redundancy number (None for a removed observation).
    pub redundancy: Option<f64>,
    /// w-test (at removal for a removed observation).
    pub w: f64,
    /// Removed by data snooping.
    pub removed: bool,
}

/// Reads `dir`'s residuals.parquet (OUT/adjust/).
pub fn read(dir: &std::path::Path) -> crate::Result<Vec<Residual>> {
    use super::read::{batches_of, column, dictionary, floats, opt};
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Int64Type, UInt32Type};
    let path = dir.join(FILE);
    let mut out = Vec::new();
    for b in batches_of(&path, 1 << 16)? {
        let b = b?;
        let d = |name| dictionary(&path, &b, name);
        let (model, acc, fit_session, session) =
            (d(MODEL)?, d(ACCELEROMETER)?, d(FIT_SESSION)?, d(SESSION)?);
        let station = column(&path, &b, STATION, &DataType::Utf8)?.as_string::<i32>();
        let line = column(&path, &b, LINE, &DataType::UInt32)?.as_primitive::<UInt32Type>();
        let time = column(&path, &b, TIME_GPS_NS, &DataType::Int64)?.as_primitive::<Int64Type>();
        let removed = column(&path, &b, REMOVED, &DataType::Boolean)?.as_boolean();
        let x = |name| floats(&path, &b, name);
        let (dz, sdz, ng, sng) = (x(DZ_RAD)?, x(SIGMA_DZ_RAD)?, x(NG)?, x(SIGMA_NG)?);
        let (temp, res, red, w) = (x(TEMPERATURE_C)?, x(RESIDUAL_MGAL)?, x(REDUNDANCY)?, x(W)?);
        for i in 0..b.num_rows() {
            out.push(Residual {
                model: model[i].clone(),
                accelerometer: acc[i].clone(),
                fit_session: fit_session[i].clone(),
                session: session[i].clone(),
                station: station.value(i).to_owned(),
                line: line.value(i),
                time_gps_ns: time.value(i),
                dz_rad: dz.value(i),
                sigma_dz_rad: sdz.value(i),
                ng: ng.value(i),
                sigma_ng: sng.value(i),
                temperature_c: temp.value(i),
                residual_mgal: opt(res, i),
                redundancy: opt(red, i),
                w: w.value(i),
                removed: removed.value(i),
            });
        }
    }
    Ok(out)
}
