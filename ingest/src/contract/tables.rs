//! The tables ingest writes (OUT/ingest/), in one place: file names, column names, types and
//! units. Downstream stages read them through these constants.
//!
//! | table | column | type | unit / meaning |
//! |---|---|---|---|
//! | acceleration.parquet | session_index | uint16 | position of the session in dataset.toml (ids in the schema metadata `gravcal.sessions`) |
//! | | time_gps_ns | int64 | GPS time, ns since 1980-01-06 |
//! | | counts_ch1..3 | int32, null | ADC counts; null where not connected or over range |
//! | | status | uint8 | status bits as logged (bit n-1 over range, bit n+3 not connected) |
//! | temperature.parquet | session_index, time_gps_ns, status | as above | |
//! | | temperature_ch1..3_c | float64, null | degC; null where not connected |
//! | theodolite.parquet | session | utf8 (dictionary) | session id |
//! | | station | utf8 | tilt position id |
//! | | time_gps_ns | int64 | GPS time of the reading, ns |
//! | | dz_rad | float64 | zenith distance, rad, in [0, 2 pi) |
//! | | dz_value | float64 | zenith distance as read |
//! | | dz_unit | utf8 | unit as read: deg, gon or rad |
//! | | time_as_read | utf8 | the time field as written in the log |
//! | | time_scale | utf8 | UTC, GPST or TAI |
//! | | line | uint32 | line number in the log |
//!
//! Rows are in session order (as in the manifest), then time order. The two large tables
//! carry the session as an index rather than a string: a string per sample costs more to
//! write than the sample itself.

use arrow_schema::{DataType, Field, Schema, SchemaRef};
use std::sync::Arc;

/// Session id column (all tables).
pub const SESSION: &str = "session";
/// GPS time column (all tables), i64 ns.
pub const TIME_GPS_NS: &str = "time_gps_ns";
/// Status bits column (acceleration, temperature).
pub const STATUS: &str = "status";
/// Session index column (acceleration, temperature): position in the manifest's sessions.
pub const SESSION_INDEX: &str = "session_index";
/// Schema metadata key holding the session ids, in index order, as a JSON array.
pub const SESSIONS_METADATA: &str = "gravcal.sessions";

fn with_sessions(fields: Vec<Field>, sessions: &[String]) -> SchemaRef {
    let ids = serde_json::to_string(sessions).expect("strings serialise");
    Arc::new(Schema::new_with_metadata(
        fields,
        arrow_schema::Metadata::new().with(SESSIONS_METADATA, ids),
    ))
}

/// The schema of a sample stream's table (acceleration, temperature, lab): the session
/// index, the GPS time, channels 1..3 of type `ty` (nullable), then `last`.
fn three_channels(names: [&str; 3], ty: DataType, last: Field, sessions: &[String]) -> SchemaRef {
    let mut fields = vec![
        Field::new(SESSION_INDEX, DataType::UInt16, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
    ];
    fields.extend(names.map(|n| Field::new(n, ty.clone(), true)));
    fields.push(last);
    with_sessions(fields, sessions)
}

/// A table's columns given by name, put in its schema's order: a column named twice, one
/// the schema lacks or one not given is an error naming the table (a bug, never data), so a
/// reordered list can never write one column's values under another's name.
pub(crate) fn in_schema_order<'s>(
    path: &std::path::Path,
    schema: &'s Schema,
    columns: Vec<(&str, arrow_array::ArrayRef)>,
) -> crate::Result<Vec<(&'s str, arrow_array::ArrayRef)>> {
    let bad = |message: String| crate::Error::Table {
        path: path.to_path_buf(),
        message,
    };
    let mut slots: Vec<Option<arrow_array::ArrayRef>> = vec![None; schema.fields().len()];
    for (name, column) in columns {
        let (i, _) = schema
            .column_with_name(name)
            .ok_or_else(|| bad(format!("column `{name}` is not in the schema")))?;
        if slots[i].replace(column).is_some() {
            return Err(bad(format!("column `{name}` given twice")));
        }
    }
    slots
        .into_iter()
        .zip(schema.fields())
        .map(|(c, f)| {
            c.map(|c| (f.name().as_str(), c))
                .ok_or_else(|| bad(format!("column `{}` not given", f.name())))
        })
        .collect()
}

/// Data type of the session column.
pub fn session_type() -> DataType {
    DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8))
}

pub mod acceleration;
pub mod applied;
pub mod attitude;
pub mod gravity;
pub mod lab;
pub mod observations;
pub mod residuals;
pub mod temperature;
pub mod theodolite;

mod read;
mod write;
pub use read::{FloatBatch, float_batches, float_batches_unflagged, float_batches_with};
pub use write::{GroupWriter, Nullable, RowGroup, Stored, StreamNames, StreamRows};

#[cfg(test)]
mod tests {
    use super::observations::{self, Observation};
    use super::{in_schema_order, residuals};
    use arrow_array::{ArrayRef, Float64Array};

    fn observation(line: u32, excluded: Option<&str>) -> Observation {
        Observation {
            session: "day1".into(),
            accelerometer: "acc1".into(),
            channel: 1,
            station: "s3".into(),
            line,
            time_gps_ns: 1_000_000_000 * i64::from(line),
            dz_rad: 0.5,
            sigma_dz_rad: 2e-5,
            sigma_dz_source: "moderated".into(),
            sigma_dz_dof: Some(12.0),
            sigma_dz_loo_rad: 2.1e-5,
            sigma_dz_loo_dof: None,
            sigma_am_mgal: 9.4,
            ng: Some(1.25e6),
            sigma_ng: Some(0.8),
            sigma_ng_dof: None,
            n_samples: 938,
            expected_samples: 937.5,
            temperature_c: Some(21.5),
            sigma_temperature_c: None,
            drift_t: Some(-0.7),
            excluded: excluded.map(str::to_owned),
            tide_mgal: None,
            gravity_mgal: 980_855.7,
        }
    }

    #[test]
    fn observations_read_back_as_written() {
        let dir = tempfile::tempdir().expect("a scratch folder");
        let obs = vec![observation(7, None), observation(9, Some("window_drift"))];
        assert_eq!(observations::write(dir.path(), &obs).expect("written"), 2);
        assert_eq!(observations::read(dir.path()).expect("read"), obs);
        let fitted: Vec<_> = obs
            .iter()
            .map(|o| residuals::Fitted {
                model: "linear",
                accelerometer: "acc1",
                fit_session: "all",
                obs: o,
                v_dz_rad: Some(1e-6),
                v_ng: None,
                residual_mgal: Some(0.2),
                redundancy: Some(0.9),
                w: 1.5,
                removed: o.excluded.is_some(),
            })
            .collect();
        residuals::write(dir.path(), &fitted).expect("written");
        let back = residuals::read(dir.path()).expect("read");
        assert_eq!(back.len(), 2);
        assert_eq!((back[1].line, back[1].removed, back[1].w), (9, true, 1.5));
        assert_eq!((back[0].residual_mgal, back[0].ng), (Some(0.2), 1.25e6));
    }

    #[test]
    fn columns_by_name_are_put_in_the_schemas_order_and_every_slip_is_refused() {
        let schema = arrow_schema::Schema::new(vec![
            arrow_schema::Field::new("a", arrow_schema::DataType::Float64, false),
            arrow_schema::Field::new("b", arrow_schema::DataType::Float64, false),
        ]);
        let col = |x: f64| -> ArrayRef { std::sync::Arc::new(Float64Array::from(vec![x])) };
        let path = std::path::Path::new("t.parquet");
        let ordered = in_schema_order(path, &schema, vec![("b", col(2.0)), ("a", col(1.0))])
            .expect("both given");
        assert_eq!(ordered[0].0, "a");
        assert_eq!(ordered[0].1.as_ref(), col(1.0).as_ref());
        assert_eq!(ordered[1].0, "b");
        for (given, says) in [
            (vec![("a", col(1.0))], "column `b` not given"),
            (
                vec![("a", col(1.0)), ("a", col(1.0))],
                "column `a` given twice",
            ),
            (
                vec![("a", col(1.0)), ("c", col(1.0))],
                "column `c` is not in the schema",
            ),
        ] {
            let e = in_schema_order(path, &schema, given).expect_err("a slip");
            assert_eq!(e.to_string(), format!("t.parquet: {says}"));
        }
    }

    #[test]
    fn a_table_without_a_column_its_schema_declares_is_refused_naming_it() {
        let dir = tempfile::tempdir().expect("a scratch folder");
        observations::write(dir.path(), &[observation(7, None)]).expect("written");
        let path = dir.path().join(observations::FILE);
        let batch = {
            let f = std::fs::File::open(&path).expect("the table");
            let mut r = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(f)
                .and_then(|b| b.build())
                .expect("a reader");
            r.next().expect("a batch").expect("decoded")
        };
        let i = batch
            .schema()
            .index_of(observations::SIGMA_NG_DOF)
            .expect("there");
        let mut older = batch.clone();
        older.remove_column(i);
        let f = std::fs::File::create(&path).expect("rewritten");
        let mut w = parquet::arrow::ArrowWriter::try_new(f, older.schema(), None).expect("writer");
        w.write(&older).expect("written");
        w.close().expect("closed");
        let e = observations::read(dir.path()).expect_err("an older table");
        assert!(e.to_string().ends_with("no column `sigma_ng_dof`"), "{e}");
    }
}
