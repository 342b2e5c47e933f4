//! `theodolite.parquet`.

use super::{Arc, DataType, Field, SESSION, Schema, SchemaRef, TIME_GPS_NS, session_type};
use crate::contract::manifest::{AngleUnit, TimeScale};
use crate::parquet_io::table::{Encodings, TableWriter, Written, session_column};
use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray, UInt32Array};
use std::path::Path;
/// File name.
pub const FILE: &str = "theodolite.parquet";
/// Station id.
pub const STATION: &str = "station";
/// Zenith distance, rad.
pub const DZ_RAD: &str = "dz_rad";
/// Zenith distance as read.
pub const DZ_VALUE: &str = "dz_value";
/// Unit as read.
pub const DZ_UNIT: &str = "dz_unit";
/// Time field as written.
pub const TIME_AS_READ: &str = "time_as_read";
/// Time scale of the log.
pub const TIME_SCALE: &str = "time_scale";
/// Line number in the log.
pub const LINE: &str = "line";
/// The Arrow schema.
pub fn schema() -> SchemaRef {
    Arc::new(Schema::new(vec![
        Field::new(SESSION, session_type(), false),
        Field::new(STATION, DataType::Utf8, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
        Field::new(DZ_RAD, DataType::Float64, false),
        Field::new(DZ_VALUE, DataType::Float64, false),
        Field::new(DZ_UNIT, DataType::Utf8, false),
        Field::new(TIME_AS_READ, DataType::Utf8, false),
        Field::new(TIME_SCALE, DataType::Utf8, false),
        Field::new(LINE, DataType::UInt32, false),
    ]))
}

/// A reading as the log gave it, as ingest writes it.
#[derive(Clone, Debug, PartialEq)]
pub struct Logged {
    /// Station id.
    pub station: String,
    /// GPS time, ns.
    pub time_gps_ns: i64,
    /// Zenith distance, rad, in [0, 2 pi).
    pub dz_rad: f64,
    /// Zenith distance as read.
    pub dz_value: f64,
    /// The time field as written.
    pub time_as_read: String,
    /// 1-based line number.
    pub line: u32,
}

fn scale_name(s: TimeScale) -> &'static str {
    match s {
        TimeScale::Utc => "UTC",
        TimeScale::Gpst => "GPST",
        TimeScale::Tai => "TAI",
    }
}

/// Writes `theodolite.parquet`, session by session.
pub struct Writer {
    table: TableWriter,
}

impl Writer {
    /// Starts the table in `dir`.
    pub fn create(dir: &Path) -> crate::Result<Self> {
        Ok(Writer {
            table: TableWriter::create(
                dir,
                FILE,
                schema(),
                Encodings {
                    dictionary: &[SESSION, STATION, DZ_UNIT, TIME_SCALE],
                    ..Default::default()
                },
            )?,
        })
    }

    /// Appends one session's readings.
    pub fn write(
        &mut self,
        session: &str,
        unit: AngleUnit,
        scale: TimeScale,
        readings: &[Logged],
    ) -> crate::Result<()> {
        let n = readings.len();
        let cols: Vec<(&str, ArrayRef)> = vec![
            (SESSION, session_column(session, n)),
            (
                STATION,
                Arc::new(StringArray::from_iter_values(
                    readings.iter().map(|r| r.station.as_str()),
                )),
            ),
            (
                TIME_GPS_NS,
                Arc::new(Int64Array::from_iter_values(
                    readings.iter().map(|r| r.time_gps_ns),
                )),
            ),
            (
                DZ_RAD,
                Arc::new(Float64Array::from_iter_values(
                    readings.iter().map(|r| r.dz_rad),
                )),
            ),
            (
                DZ_VALUE,
                Arc::new(Float64Array::from_iter_values(
                    readings.iter().map(|r| r.dz_value),
                )),
            ),
            (
                DZ_UNIT,
                Arc::new(StringArray::from_iter_values(std::iter::repeat_n(
                    unit.name(),
                    n,
                ))),
            ),
            (
                TIME_AS_READ,
                Arc::new(StringArray::from_iter_values(
                    readings.iter().map(|r| r.time_as_read.as_str()),
                )),
            ),
            (
                TIME_SCALE,
                Arc::new(StringArray::from_iter_values(std::iter::repeat_n(
                    scale_name(scale),
                    n,
                ))),
            ),
            (
                LINE,
                Arc::new(UInt32Array::from_iter_values(
                    readings.iter().map(|r| r.line),
                )),
            ),
        ];
        self.table.write(cols)
    }

    /// Closes and renames the table; returns its rows and SHA-256.
    pub fn finish(self) -> crate::Result<Written> {
        self.table.finish_hashed()
    }
}

/// A theodolite reading as ingest wrote it.
#[derive(Clone, Debug)]
pub struct Reading {
    /// Station id.
    pub station: String,
    /// Line in the log.
    pub line: u32,
    /// GPS time, ns.
    pub time_gps_ns: i64,
    /// Zenith distance, rad.
    pub dz_rad: f64,
    /// The step of the last decimal the reading was logged with, rad.
    pub step_rad: f64,
}

/// The step of the last decimal of `value` as logged (e.g. 0.001 for `121.112`): the finest
/// power of ten, down to 1e-9, of which the value is a whole multiple.
pub fn logged_step(value: f64) -> f64 {
    let mut step = 1.0;
    for d in 0..=9 {
        let x = value * 10f64.powi(d);
        if (x - x.round()).abs() < 1e-3 {
            return step;
        }
        step /= 10.0;
    }
    step
}

/// `dir`'s theodolite table: the readings per session.
pub fn read(dir: &Path) -> crate::Result<std::collections::BTreeMap<String, Vec<Reading>>> {
    use super::read::{bad, batches_of, column, floats, sessions};
    use crate::contract::manifest::AngleUnit;
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Int64Type, UInt32Type};
    let path = dir.join(FILE);
    let mut out: std::collections::BTreeMap<String, Vec<Reading>> = Default::default();
    for b in batches_of(&path, 1 << 16)? {
        let b = b?;
        let (ids, keys) = sessions(&path, &b)?;
        let station = column(&path, &b, STATION, &DataType::Utf8)?.as_string::<i32>();
        let line = column(&path, &b, LINE, &DataType::UInt32)?.as_primitive::<UInt32Type>();
        let time = column(&path, &b, TIME_GPS_NS, &DataType::Int64)?.as_primitive::<Int64Type>();
        let (dz, value) = (floats(&path, &b, DZ_RAD)?, floats(&path, &b, DZ_VALUE)?);
        let unit = column(&path, &b, DZ_UNIT, &DataType::Utf8)?.as_string::<i32>();
        for i in 0..b.num_rows() {
            let as_read = [AngleUnit::Deg, AngleUnit::Gon, AngleUnit::Rad]
                .into_iter()
                .find(|u| u.name() == unit.value(i))
                .ok_or_else(|| bad(&path, format!("unknown angle unit `{}`", unit.value(i))))?;
            out.entry(ids[keys[i]].clone()).or_default().push(Reading {
                station: station.value(i).to_owned(),
                line: line.value(i),
                time_gps_ns: time.value(i),
                dz_rad: dz.value(i),
                step_rad: as_read.to_rad(logged_step(value.value(i))),
            });
        }
    }
    Ok(out)
}
