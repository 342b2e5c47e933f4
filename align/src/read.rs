//! Reading ingest's tables and writing the observations table.

use crate::{Error, Observation, Result};
use arrow_array::types::{Float64Type, Int32Type, Int64Type, UInt8Type, UInt16Type, UInt32Type};
use arrow_array::{Array, ArrayRef, RecordBatch, StringArray, cast::AsArray};
use arrow_schema::DataType;
use ingest::contract::manifest::AngleUnit;
use ingest::contract::tables;
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

fn batches(path: &Path) -> Result<impl Iterator<Item = Result<RecordBatch>>> {
    batches_of(path, 1 << 16)
}

/// The record batches of a table, `rows` at a time.
fn batches_of(path: &Path, rows: usize) -> Result<impl Iterator<Item = Result<RecordBatch>>> {
    let f = std::fs::File::open(path).map_err(|e| ingest::Error::Io {
        path: path.to_path_buf(),
        source: e,
    })?;
    let reader = ParquetRecordBatchReaderBuilder::try_new(f)
        .map_err(|source| Error::Parquet {
            path: path.to_path_buf(),
            source,
        })?
        .with_batch_size(rows)
        .build()
        .map_err(|source| Error::Parquet {
            path: path.to_path_buf(),
            source,
        })?;
    let p = path.to_path_buf();
    Ok(reader.map(move |b| {
        b.map_err(|e| Error::Table {
            path: p.clone(),
            message: e.to_string(),
        })
    }))
}

fn column<'a>(
    path: &Path,
    batch: &'a RecordBatch,
    name: &str,
    ty: &DataType,
) -> Result<&'a ArrayRef> {
    let c = batch.column_by_name(name).ok_or_else(|| Error::Table {
        path: path.to_path_buf(),
        message: format!("no column `{name}`"),
    })?;
    if c.data_type() != ty {
        return Err(Error::Table {
            path: path.to_path_buf(),
            message: format!("column `{name}` is {}, expected {ty}", c.data_type()),
        });
    }
    Ok(c)
}

/// Session index of every row of a batch of the acceleration or temperature table.
fn session_index<'a>(path: &Path, batch: &'a RecordBatch) -> Result<&'a [u16]> {
    Ok(
        column(path, batch, tables::SESSION_INDEX, &DataType::UInt16)?
            .as_primitive::<UInt16Type>()
            .values(),
    )
}

/// Session id of every row of a batch: (distinct ids, index into them per row).
fn sessions(path: &Path, batch: &RecordBatch) -> Result<(Vec<String>, Vec<usize>)> {
    let c = column(path, batch, tables::SESSION, &tables::session_type())?;
    let d = c.as_dictionary::<Int32Type>();
    let values = d.values().as_string::<i32>();
    let ids = (0..values.len())
        .map(|i| values.value(i).to_owned())
        .collect();
    let keys = d
        .keys()
        .values()
        .iter()
        .map(|&k| usize::try_from(k).unwrap_or(0))
        .collect();
    Ok((ids, keys))
}

/// A theodolite reading as ingest wrote it.
#[derive(Clone, Debug)]
pub struct TheodoliteRow {
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

/// Readings per session.
pub fn theodolite(dir: &Path) -> Result<BTreeMap<String, Vec<TheodoliteRow>>> {
    let path = dir.join(tables::theodolite::FILE);
    let mut out: BTreeMap<String, Vec<TheodoliteRow>> = BTreeMap::new();
    for b in batches(&path)? {
        let b = b?;
        let (ids, keys) = sessions(&path, &b)?;
        let station =
            column(&path, &b, tables::theodolite::STATION, &DataType::Utf8)?.as_string::<i32>();
        let line = column(&path, &b, tables::theodolite::LINE, &DataType::UInt32)?
            .as_primitive::<UInt32Type>();
        let time =
            column(&path, &b, tables::TIME_GPS_NS, &DataType::Int64)?.as_primitive::<Int64Type>();
        let dz = column(&path, &b, tables::theodolite::DZ_RAD, &DataType::Float64)?
            .as_primitive::<Float64Type>();
        let value = column(&path, &b, tables::theodolite::DZ_VALUE, &DataType::Float64)?
            .as_primitive::<Float64Type>();
        let unit =
            column(&path, &b, tables::theodolite::DZ_UNIT, &DataType::Utf8)?.as_string::<i32>();
        for i in 0..b.num_rows() {
            out.entry(ids[keys[i]].clone())
                .or_default()
                .push(TheodoliteRow {
                    station: station.value(i).to_owned(),
                    line: line.value(i),
                    time_gps_ns: time.value(i),
                    dz_rad: dz.value(i),
                    step_rad: {
                        let unit = [AngleUnit::Deg, AngleUnit::Gon, AngleUnit::Rad]
                            .into_iter()
                            .find(|u| u.name() == unit.value(i))
                            .ok_or_else(|| Error::Table {
                                path: path.clone(),
                                message: format!("unknown angle unit `{}`", unit.value(i)),
                            })?;
                        unit.to_rad(logged_step(value.value(i)))
                    },
                });
        }
    }
    Ok(out)
}

/// Temperature series per (session index, channel 1..3): times (ns) and degC, non-null
/// samples only.
pub type Temperatures = BTreeMap<(u16, u8), (Vec<i64>, Vec<f64>)>;

/// The temperature table, by session and channel.
pub fn temperatures(dir: &Path) -> Result<Temperatures> {
    let path = dir.join(tables::temperature::FILE);
    let mut out = Temperatures::new();
    for b in batches(&path)? {
        let b = b?;
        let session = session_index(&path, &b)?;
        let time =
            column(&path, &b, tables::TIME_GPS_NS, &DataType::Int64)?.as_primitive::<Int64Type>();
        for (ch, name) in tables::temperature::TEMPERATURE_C.iter().enumerate() {
            let v = column(&path, &b, name, &DataType::Float64)?.as_primitive::<Float64Type>();
            for i in 0..b.num_rows() {
                if v.is_valid(i) {
                    let e = out.entry((session[i], ch as u8 + 1)).or_default();
                    e.0.push(time.value(i));
                    e.1.push(v.value(i));
                }
            }
        }
    }
    Ok(out)
}

/// A stream table's session index and GPS time columns.
fn session_and_time<'b>(path: &Path, b: &'b RecordBatch) -> Result<(&'b [u16], &'b [i64])> {
    Ok((
        session_index(path, b)?,
        column(path, b, tables::TIME_GPS_NS, &DataType::Int64)?
            .as_primitive::<Int64Type>()
            .values(),
    ))
}

/// One batch of the acceleration table, as stored: per row the session index, GPS time
/// (ns), the counts of channels 1..3 (null where not connected or over range) and the status.
pub struct AccelerationBatch<'a> {
    /// Session index per row.
    pub session: &'a [u16],
    /// GPS time per row, ns.
    pub time_ns: &'a [i64],
    /// Counts of channels 1..3.
    pub counts: [&'a arrow_array::Int32Array; 3],
    /// Status bits per row.
    pub status: &'a [u8],
}

/// Streams the acceleration table in file order, a batch of `batch_rows` rows at a time.
pub fn acceleration_batches(
    dir: &Path,
    batch_rows: usize,
    mut f: impl FnMut(AccelerationBatch<'_>) -> Result<()>,
) -> Result<()> {
    let path = dir.join(tables::acceleration::FILE);
    for b in batches_of(&path, batch_rows)? {
        let b = b?;
        let (session, time) = session_and_time(&path, &b)?;
        let status = column(&path, &b, tables::STATUS, &DataType::UInt8)?
            .as_primitive::<UInt8Type>()
            .values();
        let c: Vec<_> = tables::acceleration::COUNTS
            .iter()
            .map(|n| column(&path, &b, n, &DataType::Int32).map(|c| c.as_primitive::<Int32Type>()))
            .collect::<Result<_>>()?;
        f(AccelerationBatch {
            session,
            time_ns: time,
            counts: [c[0], c[1], c[2]],
            status,
        })?;
    }
    Ok(())
}

/// The samples of the sessions `wanted` (by index), as series of decimal readings: from
/// lab.parquet (lab streams) and from the acceleration table (counts; null where not
/// connected or over range).
pub fn series(dir: &Path, wanted: &[u16]) -> Result<BTreeMap<u16, crate::statics::Series>> {
    let mut out: BTreeMap<u16, crate::statics::Series> =
        wanted.iter().map(|&w| (w, Default::default())).collect();
    acceleration(dir, |session, time_ns, counts, _| {
        if let Some(s) = out.get_mut(&session) {
            s.time_ns.push(time_ns);
            s.values.push(counts.map(|c| c.map(f64::from)));
        }
    })?;
    lab_batches(dir, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            if let Some(s) = out.get_mut(&b.session[i]) {
                s.time_ns.push(b.time_ns[i]);
                s.values
                    .push(b.values.map(|v| v.is_valid(i).then(|| v.value(i))));
            }
        }
        Ok(())
    })?;
    Ok(out)
}

/// Streams every acceleration sample of the dataset as decimal readings: the acceleration
/// table (counts; null where not connected or over range, with the status bits), then the
/// lab table (readings in the instrument's unit; null where the line gave `nan`, status
/// not connected on that channel). `f(session index, time_ns, readings, status)`;
/// each session's samples come from one table, in time order.
pub fn samples(dir: &Path, mut f: impl FnMut(u16, i64, [Option<f64>; 3], u8)) -> Result<()> {
    acceleration(dir, |session, time_ns, counts, st| {
        f(session, time_ns, counts.map(|c| c.map(f64::from)), st);
    })?;
    lab_batches(dir, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            let v = b.values.map(|v| v.is_valid(i).then(|| v.value(i)));
            let mut st = 0u8;
            for (ch, x) in v.iter().enumerate() {
                if x.is_none() {
                    st |= ingest::contract::status::not_connected_bit(ch);
                }
            }
            f(b.session[i], b.time_ns[i], v, st);
        }
        Ok(())
    })
}

/// One batch of the lab table: per row the session index, GPS time (ns), and the readings
/// of channels 1..3 (null where the line gave `nan`).
pub struct LabBatch<'a> {
    /// Session index per row.
    pub session: &'a [u16],
    /// GPS time per row, ns.
    pub time_ns: &'a [i64],
    /// Readings of channels 1..3.
    pub values: [&'a arrow_array::Float64Array; 3],
}

/// Streams the lab table in file order, a batch of `batch_rows` rows at a time.
pub fn lab_batches(
    dir: &Path,
    batch_rows: usize,
    mut f: impl FnMut(LabBatch<'_>) -> Result<()>,
) -> Result<()> {
    let path = dir.join(tables::lab::FILE);
    for b in batches_of(&path, batch_rows)? {
        let b = b?;
        let (session, time) = session_and_time(&path, &b)?;
        let v: Vec<_> = tables::lab::VALUES
            .iter()
            .map(|n| {
                column(&path, &b, n, &DataType::Float64).map(|c| c.as_primitive::<Float64Type>())
            })
            .collect::<Result<_>>()?;
        f(LabBatch {
            session,
            time_ns: time,
            values: [v[0], v[1], v[2]],
        })?;
    }
    Ok(())
}

/// One batch of a table with per row a session index, a GPS time, some nullable Float64
/// columns and a UInt8 flags column: apply's `acceleration.parquet`, read by the gravity
/// stage.
pub struct FloatBatch<'a> {
    /// Session index per row.
    pub session: &'a [u16],
    /// GPS time per row, ns.
    pub time_ns: &'a [i64],
    /// The columns asked for, in the order asked.
    pub values: Vec<&'a arrow_array::Float64Array>,
    /// The flags column (empty for a table without one).
    pub flags: &'a [u8],
}

/// Streams the table at `path` in file order, `batch_rows` at a time, reading the Float64
/// columns `names` and the UInt8 column `flags`.
pub fn float_batches(
    path: &Path,
    names: &[&str],
    flags: &str,
    batch_rows: usize,
    f: impl FnMut(FloatBatch<'_>) -> Result<()>,
) -> Result<()> {
    float_batches_with(path, names, flags, batch_rows, f)
}

/// [`float_batches`] with a callback that stops with an error of its own, `E` (the
/// table's errors converted into it): a stage's error comes out as itself, not dressed as
/// a table's.
pub fn float_batches_with<E: From<Error>>(
    path: &Path,
    names: &[&str],
    flags: &str,
    batch_rows: usize,
    f: impl FnMut(FloatBatch<'_>) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    float_batches_of(path, names, Some(flags), batch_rows, f)
}

/// [`float_batches`] of a table without a flags column (attitude.parquet): `flags` empty,
/// the columns nullable.
pub fn float_batches_unflagged(
    path: &Path,
    names: &[&str],
    batch_rows: usize,
    f: impl FnMut(FloatBatch<'_>) -> Result<()>,
) -> Result<()> {
    float_batches_of(path, names, None, batch_rows, f)
}

/// The batches of [`float_batches_with`], with a flags column or none.
fn float_batches_of<E: From<Error>>(
    path: &Path,
    names: &[&str],
    flags: Option<&str>,
    batch_rows: usize,
    mut f: impl FnMut(FloatBatch<'_>) -> std::result::Result<(), E>,
) -> std::result::Result<(), E> {
    for b in batches_of(path, batch_rows)? {
        let b = b?;
        let (session, time) = session_and_time(path, &b)?;
        let values: Vec<_> = names
            .iter()
            .map(|n| {
                column(path, &b, n, &DataType::Float64).map(|c| c.as_primitive::<Float64Type>())
            })
            .collect::<Result<_>>()?;
        let flags: &[u8] = match flags {
            Some(name) => column(path, &b, name, &DataType::UInt8)?
                .as_primitive::<UInt8Type>()
                .values(),
            None => &[],
        };
        f(FloatBatch {
            session,
            time_ns: time,
            values,
            flags,
        })?;
    }
    Ok(())
}

/// Streams the acceleration table in file order: `f(session index, time_ns, counts, status)`.
pub fn acceleration(dir: &Path, mut f: impl FnMut(u16, i64, [Option<i32>; 3], u8)) -> Result<()> {
    acceleration_batches(dir, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            let counts = b.counts.map(|c| c.is_valid(i).then(|| c.value(i)));
            f(b.session[i], b.time_ns[i], counts, b.status[i]);
        }
        Ok(())
    })
}

/// Writes `observations.parquet` into `dir`; returns the rows written.
pub fn write_observations(dir: &Path, obs: &[Observation]) -> Result<u64> {
    use arrow_array::{Float64Array, Int64Array, UInt8Array, UInt32Array};
    let mut table = ingest::parquet_io::table::TableWriter::create(
        dir,
        tables::observations::FILE,
        tables::observations::schema(),
        ingest::parquet_io::table::Encodings {
            dictionary: &[
                tables::SESSION,
                tables::observations::ACCELEROMETER,
                tables::observations::STATION,
            ],
            ..Default::default()
        },
    )?;
    let cols: Vec<ArrayRef> = vec![
        ingest::parquet_io::table::dictionary_column(obs.iter().map(|o| o.session.as_str())),
        ingest::parquet_io::table::dictionary_column(obs.iter().map(|o| o.accelerometer.as_str())),
        Arc::new(UInt8Array::from_iter_values(obs.iter().map(|o| o.channel))),
        Arc::new(StringArray::from_iter_values(
            obs.iter().map(|o| o.station.as_str()),
        )),
        Arc::new(UInt32Array::from_iter_values(obs.iter().map(|o| o.line))),
        Arc::new(Int64Array::from_iter_values(
            obs.iter().map(|o| o.time_gps_ns),
        )),
        Arc::new(Float64Array::from_iter_values(obs.iter().map(|o| o.dz_rad))),
        Arc::new(Float64Array::from_iter_values(
            obs.iter().map(|o| o.sigma_dz_rad),
        )),
        Arc::new(StringArray::from_iter_values(
            obs.iter().map(|o| o.sigma_dz_source),
        )),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.sigma_dz_dof))),
        Arc::new(Float64Array::from_iter_values(
            obs.iter().map(|o| o.sigma_dz_loo_rad),
        )),
        Arc::new(Float64Array::from_iter(
            obs.iter().map(|o| o.sigma_dz_loo_dof),
        )),
        Arc::new(Float64Array::from_iter_values(
            obs.iter().map(|o| o.sigma_am_mgal),
        )),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.ng))),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.sigma_ng))),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.sigma_ng_dof))),
        Arc::new(UInt32Array::from_iter_values(
            obs.iter().map(|o| o.n_samples),
        )),
        Arc::new(Float64Array::from_iter_values(
            obs.iter().map(|o| o.expected_samples),
        )),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.temperature_c))),
        Arc::new(Float64Array::from_iter(
            obs.iter().map(|o| o.sigma_temperature_c),
        )),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.drift_t))),
        Arc::new(StringArray::from_iter(obs.iter().map(|o| o.excluded))),
        Arc::new(Float64Array::from_iter(obs.iter().map(|o| o.tide_mgal))),
        Arc::new(Float64Array::from_iter_values(
            obs.iter().map(|o| o.gravity_mgal),
        )),
    ];
    table.write(cols)?;
    Ok(table.finish()?)
}
