//! Reading align's observations and writing the adjust stage's outputs.

use crate::Error;
use arrow::array::{
    Array, ArrayRef, AsArray, BooleanArray, DictionaryArray, Float64Array, Int32Array, Int64Array,
    RecordBatch, StringArray, UInt32Array,
};
use arrow::datatypes::{Float64Type, Int32Type, Int64Type, UInt32Type};
use ingest::schema::{self, observations as col};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::path::Path;
use std::sync::Arc;

/// One row of observations.parquet.
#[derive(Clone, Debug)]
pub struct ObservationRow {
    /// Session id.
    pub session: String,
    /// Accelerometer id.
    pub accelerometer: String,
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
    /// Mean counts (None when align had none).
    pub ng: Option<f64>,
    /// Its sd.
    pub sigma_ng: Option<f64>,
    /// Temperature, degC.
    pub temperature_c: Option<f64>,
    /// Align's exclusion reason.
    pub excluded: Option<String>,
}

fn bad(path: &Path, message: String) -> Error {
    Error::Table {
        path: path.to_path_buf(),
        message,
    }
}

/// Reads OUT/align/observations.parquet.
pub fn read_observations(align_dir: &Path) -> Result<Vec<ObservationRow>, Error> {
    let path = align_dir.join(col::FILE);
    let f = std::fs::File::open(&path).map_err(|e| Error::Io {
        path: path.clone(),
        source: e,
    })?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .and_then(|b| b.build())
        .map_err(|e| bad(&path, e.to_string()))?;
    let mut out = Vec::new();
    for batch in reader {
        let b: RecordBatch = batch.map_err(|e| bad(&path, e.to_string()))?;
        let get = |name: &str| {
            b.column_by_name(name)
                .ok_or_else(|| bad(&path, format!("no column `{name}`")))
        };
        let dict = |name: &str| -> Result<Vec<String>, Error> {
            let c = get(name)?;
            let d = c
                .as_dictionary_opt::<Int32Type>()
                .ok_or_else(|| bad(&path, format!("column `{name}` is not a dictionary")))?;
            let values = d.values().as_string::<i32>();
            Ok(d.keys()
                .values()
                .iter()
                .map(|&k| values.value(k as usize).to_owned())
                .collect())
        };
        let f64s = |name: &str| -> Result<Float64Array, Error> {
            Ok(get(name)?
                .as_primitive_opt::<Float64Type>()
                .ok_or_else(|| bad(&path, format!("column `{name}` is not float64")))?
                .clone())
        };
        let session = dict(schema::SESSION)?;
        let acc = dict(col::ACCELEROMETER)?;
        let station = get(col::STATION)?
            .as_string_opt::<i32>()
            .ok_or_else(|| bad(&path, "station is not utf8".into()))?
            .clone();
        let line = get(col::LINE)?
            .as_primitive_opt::<UInt32Type>()
            .ok_or_else(|| bad(&path, "line is not uint32".into()))?
            .clone();
        let time = get(schema::TIME_GPS_NS)?
            .as_primitive_opt::<Int64Type>()
            .ok_or_else(|| bad(&path, "time is not int64".into()))?
            .clone();
        let (dz, sdz, ng, sng, temp) = (
            f64s(col::DZ_RAD)?,
            f64s(col::SIGMA_DZ_RAD)?,
            f64s(col::NG)?,
            f64s(col::SIGMA_NG)?,
            f64s(col::TEMPERATURE_C)?,
        );
        let excluded = get(col::EXCLUDED)?
            .as_string_opt::<i32>()
            .ok_or_else(|| bad(&path, "excluded is not utf8".into()))?
            .clone();
        let opt = |a: &Float64Array, i: usize| a.is_valid(i).then(|| a.value(i));
        for i in 0..b.num_rows() {
            out.push(ObservationRow {
                session: session[i].clone(),
                accelerometer: acc[i].clone(),
                station: station.value(i).to_owned(),
                line: line.value(i),
                time_gps_ns: time.value(i),
                dz_rad: dz.value(i),
                sigma_dz_rad: sdz.value(i),
                ng: opt(&ng, i),
                sigma_ng: opt(&sng, i),
                temperature_c: opt(&temp, i),
                excluded: excluded.is_valid(i).then(|| excluded.value(i).to_owned()),
            });
        }
    }
    Ok(out)
}

/// One row of residuals.parquet.
#[derive(Clone, Debug)]
pub struct ResidualRow<'a> {
    /// Model name.
    pub model: &'a str,
    /// Accelerometer.
    pub accelerometer: &'a str,
    /// The fit's session or `all`.
    pub fit_session: &'a str,
    /// The observation.
    pub obs: &'a ObservationRow,
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

fn dict(values: Vec<&str>) -> ArrayRef {
    let mut distinct = values.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let keys: Vec<i32> = values
        .iter()
        .map(|v| distinct.binary_search(v).map_or(0, |k| k as i32))
        .collect();
    Arc::new(
        DictionaryArray::<Int32Type>::try_new(
            Int32Array::from(keys),
            Arc::new(StringArray::from(distinct)),
        )
        .expect("keys index the distinct values"),
    )
}

/// Writes residuals.parquet into `dir`.
pub fn write_residuals(dir: &Path, rows: &[ResidualRow<'_>]) -> Result<u64, Error> {
    let mut t = ingest::table::TableWriter::create(
        dir,
        schema::residuals::FILE,
        "residuals",
        schema::residuals::schema(),
        ingest::table::Encodings {
            dictionary: &[
                "model",
                "accelerometer",
                "fit_session",
                schema::SESSION,
                "station",
            ],
            delta: &[],
        },
    )?;
    let f = |g: &dyn Fn(&ResidualRow<'_>) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(rows.iter().map(g)))
    };
    let fo = |g: &dyn Fn(&ResidualRow<'_>) -> Option<f64>| -> ArrayRef {
        Arc::new(Float64Array::from_iter(rows.iter().map(g)))
    };
    let cols: Vec<ArrayRef> = vec![
        dict(rows.iter().map(|r| r.model).collect()),
        dict(rows.iter().map(|r| r.accelerometer).collect()),
        dict(rows.iter().map(|r| r.fit_session).collect()),
        dict(rows.iter().map(|r| r.obs.session.as_str()).collect()),
        Arc::new(StringArray::from_iter_values(
            rows.iter().map(|r| r.obs.station.as_str()),
        )),
        Arc::new(UInt32Array::from_iter_values(
            rows.iter().map(|r| r.obs.line),
        )),
        Arc::new(Int64Array::from_iter_values(
            rows.iter().map(|r| r.obs.time_gps_ns),
        )),
        f(&|r| r.obs.dz_rad),
        f(&|r| r.obs.sigma_dz_rad),
        f(&|r| r.obs.ng.unwrap_or(f64::NAN)),
        f(&|r| r.obs.sigma_ng.unwrap_or(f64::NAN)),
        f(&|r| r.obs.temperature_c.unwrap_or(f64::NAN)),
        fo(&|r| r.v_dz_rad),
        fo(&|r| r.v_ng),
        fo(&|r| r.residual_mgal),
        fo(&|r| r.redundancy),
        f(&|r| r.w),
        Arc::new(BooleanArray::from_iter(
            rows.iter().map(|r| Some(r.removed)),
        )),
    ];
    t.write(cols)?;
    Ok(t.finish()?)
}

/// One row of residuals.parquet, as read back.
#[derive(Clone, Debug)]
pub struct ResidualRecord {
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

/// Reads OUT/adjust/residuals.parquet.
pub fn read_residuals(adjust_dir: &Path) -> Result<Vec<ResidualRecord>, Error> {
    let path = adjust_dir.join(schema::residuals::FILE);
    let f = std::fs::File::open(&path).map_err(|e| Error::Io {
        path: path.clone(),
        source: e,
    })?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .and_then(|b| b.build())
        .map_err(|e| bad(&path, e.to_string()))?;
    let mut out = Vec::new();
    for batch in reader {
        let b: RecordBatch = batch.map_err(|e| bad(&path, e.to_string()))?;
        let get = |name: &str| {
            b.column_by_name(name)
                .ok_or_else(|| bad(&path, format!("no column `{name}`")))
        };
        let dict = |name: &str| -> Result<Vec<String>, Error> {
            let d = get(name)?
                .as_dictionary_opt::<Int32Type>()
                .ok_or_else(|| bad(&path, format!("`{name}` is not a dictionary")))?;
            let values = d.values().as_string::<i32>();
            Ok(d.keys()
                .values()
                .iter()
                .map(|&k| values.value(k as usize).to_owned())
                .collect())
        };
        let f64s = |name: &str| -> Result<Float64Array, Error> {
            Ok(get(name)?
                .as_primitive_opt::<Float64Type>()
                .ok_or_else(|| bad(&path, format!("`{name}` is not float64")))?
                .clone())
        };
        let (model, acc, fit_session, session) = (
            dict("model")?,
            dict("accelerometer")?,
            dict("fit_session")?,
            dict(schema::SESSION)?,
        );
        let station = get("station")?
            .as_string_opt::<i32>()
            .ok_or_else(|| bad(&path, "station is not utf8".into()))?
            .clone();
        let line = get("line")?
            .as_primitive_opt::<UInt32Type>()
            .ok_or_else(|| bad(&path, "line is not uint32".into()))?
            .clone();
        let time = get(schema::TIME_GPS_NS)?
            .as_primitive_opt::<Int64Type>()
            .ok_or_else(|| bad(&path, "time is not int64".into()))?
            .clone();
        let removed = get("removed")?
            .as_boolean_opt()
            .ok_or_else(|| bad(&path, "removed is not boolean".into()))?
            .clone();
        let (dz, sdz, ng, sng, temp, res, red, w) = (
            f64s("dz_rad")?,
            f64s("sigma_dz_rad")?,
            f64s("ng")?,
            f64s("sigma_ng")?,
            f64s("temperature_c")?,
            f64s("residual_mgal")?,
            f64s("redundancy")?,
            f64s("w")?,
        );
        for i in 0..b.num_rows() {
            out.push(ResidualRecord {
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
                residual_mgal: res.is_valid(i).then(|| res.value(i)),
                redundancy: red.is_valid(i).then(|| red.value(i)),
                w: w.value(i),
                removed: removed.value(i),
            });
        }
    }
    Ok(out)
}
