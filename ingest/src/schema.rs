//! The tables ingest writes (OUT/ingest/), in one place: file names, column names, types and
//! units. Downstream stages read them through these constants.
//!
//! | table | column | type | unit / meaning |
//! |---|---|---|---|
//! | acceleration.parquet | session | utf8 (dictionary) | session id |
//! | | time_gps_ns | int64 | GPS time, ns since 1980-01-06 |
//! | | counts_ch1..3 | int32, null | ADC counts; null where not connected or over range |
//! | | status | uint8 | status bits as logged (bit n-1 over range, bit n+3 not connected) |
//! | temperature.parquet | session, time_gps_ns, status | as above | |
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
//! Rows are in session order (as in the manifest), then time order.

use arrow::datatypes::{DataType, Field, Schema, SchemaRef};
use std::sync::Arc;

/// Session id column (all tables).
pub const SESSION: &str = "session";
/// GPS time column (all tables), i64 ns.
pub const TIME_GPS_NS: &str = "time_gps_ns";
/// Status bits column (acceleration, temperature).
pub const STATUS: &str = "status";

/// Data type of the session column.
pub fn session_type() -> DataType {
    DataType::Dictionary(Box::new(DataType::Int32), Box::new(DataType::Utf8))
}

/// `acceleration.parquet`.
pub mod acceleration {
    use super::*;
    /// File name.
    pub const FILE: &str = "acceleration.parquet";
    /// Counts of channels 1..3.
    pub const COUNTS: [&str; 3] = ["counts_ch1", "counts_ch2", "counts_ch3"];
    /// The Arrow schema.
    pub fn schema() -> SchemaRef {
        Arc::new(Schema::new(vec![
            Field::new(SESSION, session_type(), false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
            Field::new(COUNTS[0], DataType::Int32, true),
            Field::new(COUNTS[1], DataType::Int32, true),
            Field::new(COUNTS[2], DataType::Int32, true),
            Field::new(STATUS, DataType::UInt8, false),
        ]))
    }
}

/// `temperature.parquet`.
pub mod temperature {
    use super::*;
    /// File name.
    pub const FILE: &str = "temperature.parquet";
    /// Temperatures of channels 1..3, degC.
    pub const TEMPERATURE_C: [&str; 3] = [
        "temperature_ch1_c",
        "temperature_ch2_c",
        "temperature_ch3_c",
    ];
    /// The Arrow schema.
    pub fn schema() -> SchemaRef {
        Arc::new(Schema::new(vec![
            Field::new(SESSION, session_type(), false),
            Field::new(TIME_GPS_NS, DataType::Int64, false),
            Field::new(TEMPERATURE_C[0], DataType::Float64, true),
            Field::new(TEMPERATURE_C[1], DataType::Float64, true),
            Field::new(TEMPERATURE_C[2], DataType::Float64, true),
            Field::new(STATUS, DataType::UInt8, false),
        ]))
    }
}

/// `theodolite.parquet`.
pub mod theodolite {
    use super::*;
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
}
