//! Reading align's observations and writing the adjust stage's outputs.

use crate::Error;
use arrow_array::types::{Float64Type, Int32Type, Int64Type, UInt32Type};
use arrow_array::{
    Array, ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, UInt32Array,
    cast::AsArray,
};
use ingest::contract::tables::{self, observations as col};
use ingest::parquet_io::table::dictionary_column;
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
    /// Degrees of freedom of that sd (None: known, or an older table without the column).
    pub sigma_dz_dof: Option<f64>,
    /// sigma_Dz without this reading, rad (None: an older table without the column).
    pub sigma_dz_loo_rad: Option<f64>,
    /// Its degrees of freedom (None: known).
    pub sigma_dz_loo_dof: Option<f64>,
    /// Mean counts (None when align had none).
    pub ng: Option<f64>,
    /// Its sd.
    pub sigma_ng: Option<f64>,
    /// Degrees of freedom of that sd (None: known, or an older table without the column).
    pub sigma_ng_dof: Option<f64>,
    /// Temperature, degC.
    pub temperature_c: Option<f64>,
    /// Its sd from the thermometer's noise (None: none estimated, or an older table).
    pub sigma_temperature_c: Option<f64>,
    /// Align's exclusion reason.
    pub excluded: Option<String>,
    /// Body tide at the reading, mGal (None when none is applied).
    pub tide_mgal: Option<f64>,
}

fn bad(path: &Path, message: String) -> Error {
    Error::Table {
        path: path.to_path_buf(),
        message,
    }
}

/// The record batches of a Parquet table.
fn batches(path: &Path) -> Result<Vec<RecordBatch>, Error> {
    let f = std::fs::File::open(path).map_err(|e| ingest::Error::io(path.to_path_buf(), e))?;
    ParquetRecordBatchReaderBuilder::try_new(f)
        .and_then(|b| b.build())
        .map_err(|e| bad(path, e.to_string()))?
        .map(|b| b.map_err(|e| bad(path, e.to_string())))
        .collect()
}

/// The columns of one batch, by name and type; errors name the table and the column.
struct Columns<'a> {
    path: &'a Path,
    batch: &'a RecordBatch,
}

impl Columns<'_> {
    fn get(&self, name: &str) -> Result<&ArrayRef, Error> {
        self.batch
            .column_by_name(name)
            .ok_or_else(|| bad(self.path, format!("no column `{name}`")))
    }
    fn wrong(&self, name: &str, ty: &str) -> Error {
        bad(self.path, format!("column `{name}` is not {ty}"))
    }
    fn dict(&self, name: &str) -> Result<Vec<String>, Error> {
        let d = self
            .get(name)?
            .as_dictionary_opt::<Int32Type>()
            .ok_or_else(|| self.wrong(name, "a dictionary"))?;
        let values = d.values().as_string::<i32>();
        Ok(d.keys()
            .values()
            .iter()
            .map(|&k| values.value(k as usize).to_owned())
            .collect())
    }
    fn f64s(&self, name: &str) -> Result<Float64Array, Error> {
        Ok(self
            .get(name)?
            .as_primitive_opt::<Float64Type>()
            .ok_or_else(|| self.wrong(name, "float64"))?
            .clone())
    }
    fn strings(&self, name: &str) -> Result<StringArray, Error> {
        Ok(self
            .get(name)?
            .as_string_opt::<i32>()
            .ok_or_else(|| self.wrong(name, "utf8"))?
            .clone())
    }
    fn u32s(&self, name: &str) -> Result<UInt32Array, Error> {
        Ok(self
            .get(name)?
            .as_primitive_opt::<UInt32Type>()
            .ok_or_else(|| self.wrong(name, "uint32"))?
            .clone())
    }
    fn i64s(&self, name: &str) -> Result<Int64Array, Error> {
        Ok(self
            .get(name)?
            .as_primitive_opt::<Int64Type>()
            .ok_or_else(|| self.wrong(name, "int64"))?
            .clone())
    }
    fn bools(&self, name: &str) -> Result<BooleanArray, Error> {
        Ok(self
            .get(name)?
            .as_boolean_opt()
            .ok_or_else(|| self.wrong(name, "boolean"))?
            .clone())
    }
}

fn opt(a: &Float64Array, i: usize) -> Option<f64> {
    a.is_valid(i).then(|| a.value(i))
}

/// Reads OUT/align/observations.parquet.
pub fn read_observations(align_dir: &Path) -> Result<Vec<ObservationRow>, Error> {
    let path = align_dir.join(col::FILE);
    let mut out = Vec::new();
    for b in batches(&path)? {
        let c = Columns {
            path: &path,
            batch: &b,
        };
        let (session, acc) = (c.dict(tables::SESSION)?, c.dict(col::ACCELEROMETER)?);
        let (station, excluded) = (c.strings(col::STATION)?, c.strings(col::EXCLUDED)?);
        let (line, time) = (c.u32s(col::LINE)?, c.i64s(tables::TIME_GPS_NS)?);
        let (dz, sdz) = (c.f64s(col::DZ_RAD)?, c.f64s(col::SIGMA_DZ_RAD)?);
        let (ng, sng, temp) = (
            c.f64s(col::NG)?,
            c.f64s(col::SIGMA_NG)?,
            c.f64s(col::TEMPERATURE_C)?,
        );
        let tide = c.f64s(col::TIDE_MGAL)?;
        let dof = match b.column_by_name(col::SIGMA_DZ_DOF) {
            Some(_) => Some(c.f64s(col::SIGMA_DZ_DOF)?),
            None => None,
        };
        let ng_dof = match b.column_by_name(col::SIGMA_NG_DOF) {
            Some(_) => Some(c.f64s(col::SIGMA_NG_DOF)?),
            None => None,
        };
        let sigma_temp = match b.column_by_name(col::SIGMA_TEMPERATURE_C) {
            Some(_) => Some(c.f64s(col::SIGMA_TEMPERATURE_C)?),
            None => None,
        };
        let loo = match b.column_by_name(col::SIGMA_DZ_LOO_RAD) {
            Some(_) => Some((
                c.f64s(col::SIGMA_DZ_LOO_RAD)?,
                c.f64s(col::SIGMA_DZ_LOO_DOF)?,
            )),
            None => None,
        };
        for i in 0..b.num_rows() {
            out.push(ObservationRow {
                session: session[i].clone(),
                accelerometer: acc[i].clone(),
                station: station.value(i).to_owned(),
                line: line.value(i),
                time_gps_ns: time.value(i),
                dz_rad: dz.value(i),
                sigma_dz_rad: sdz.value(i),
                sigma_dz_dof: dof.as_ref().and_then(|d| opt(d, i)),
                sigma_dz_loo_rad: loo.as_ref().and_then(|(s, _)| opt(s, i)),
                sigma_dz_loo_dof: loo.as_ref().and_then(|(_, d)| opt(d, i)),
                ng: opt(&ng, i),
                sigma_ng: opt(&sng, i),
                sigma_ng_dof: ng_dof.as_ref().and_then(|d| opt(d, i)),
                temperature_c: opt(&temp, i),
                sigma_temperature_c: sigma_temp.as_ref().and_then(|s| opt(s, i)),
                excluded: excluded.is_valid(i).then(|| excluded.value(i).to_owned()),
                tide_mgal: opt(&tide, i),
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

/// Writes residuals.parquet into `dir`.
pub fn write_residuals(dir: &Path, rows: &[ResidualRow<'_>]) -> Result<u64, Error> {
    let mut t = ingest::parquet_io::table::TableWriter::create(
        dir,
        tables::residuals::FILE,
        tables::residuals::schema(),
        ingest::parquet_io::table::Encodings {
            dictionary: &[
                tables::residuals::MODEL,
                tables::residuals::ACCELEROMETER,
                tables::residuals::FIT_SESSION,
                tables::SESSION,
                tables::residuals::STATION,
            ],
            ..Default::default()
        },
    )?;
    let f = |g: &dyn Fn(&ResidualRow<'_>) -> f64| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(rows.iter().map(g)))
    };
    let fo = |g: &dyn Fn(&ResidualRow<'_>) -> Option<f64>| -> ArrayRef {
        Arc::new(Float64Array::from_iter(rows.iter().map(g)))
    };
    let cols: Vec<ArrayRef> = vec![
        dictionary_column(rows.iter().map(|r| r.model)),
        dictionary_column(rows.iter().map(|r| r.accelerometer)),
        dictionary_column(rows.iter().map(|r| r.fit_session)),
        dictionary_column(rows.iter().map(|r| r.obs.session.as_str())),
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
    let path = adjust_dir.join(tables::residuals::FILE);
    let mut out = Vec::new();
    for b in batches(&path)? {
        let c = Columns {
            path: &path,
            batch: &b,
        };
        let (model, acc) = (
            c.dict(tables::residuals::MODEL)?,
            c.dict(tables::residuals::ACCELEROMETER)?,
        );
        let (fit_session, session) = (
            c.dict(tables::residuals::FIT_SESSION)?,
            c.dict(tables::SESSION)?,
        );
        let (station, line, time, removed) = (
            c.strings(tables::residuals::STATION)?,
            c.u32s(tables::residuals::LINE)?,
            c.i64s(tables::TIME_GPS_NS)?,
            c.bools(tables::residuals::REMOVED)?,
        );
        let (dz, sdz, ng, sng) = (
            c.f64s(tables::residuals::DZ_RAD)?,
            c.f64s(tables::residuals::SIGMA_DZ_RAD)?,
            c.f64s(tables::residuals::NG)?,
            c.f64s(tables::residuals::SIGMA_NG)?,
        );
        let (temp, res, red, w) = (
            c.f64s(tables::residuals::TEMPERATURE_C)?,
            c.f64s(tables::residuals::RESIDUAL_MGAL)?,
            c.f64s(tables::residuals::REDUNDANCY)?,
            c.f64s(tables::residuals::W)?,
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
                residual_mgal: opt(&res, i),
                redundancy: opt(&red, i),
                w: w.value(i),
                removed: removed.value(i),
            });
        }
    }
    Ok(out)
}
