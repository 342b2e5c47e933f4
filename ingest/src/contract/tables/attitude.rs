//! `OUT/gravity/attitude.parquet` (docs/formats.md 10.2.1): the attitude an antenna array
//! gives, one row per epoch solved, in time order per session:
//!
//! | column | type | unit / meaning |
//! |---|---|---|
//! | session_index | uint16 | as in ingest's tables (ids in `gravcal.sessions`) |
//! | time_gps_ns | int64 | GPS time of the epoch, ns |
//! | heading_deg, pitch_deg, roll_deg | float64 | C_v^n = Rz(heading) Ry(pitch) Rx(roll), deg |
//! | sd_heading_deg, sd_pitch_deg, sd_roll_deg | float64 | their sds, deg |
//! | corr_heading_pitch, corr_heading_roll, corr_pitch_roll | float64 | their correlations |
//!
//! A value the array does not give is null: two antennas' roll, its sd and correlations
//! (gravity.json's `antennas.not_given` says why).
//! | antennas_used | uint32 | bit k: the session's k-th antenna in the fit |
//! | antennas_set_aside | uint32 | bit k: set aside, its baselines' lengths off |

use super::{Arc, DataType, Field, SESSION_INDEX, SchemaRef, TIME_GPS_NS, with_sessions};
/// File name.
pub const FILE: &str = "attitude.parquet";
/// The Float64 columns after session_index and time_gps_ns, in order.
pub const FLOATS: [&str; 9] = [
    "heading_deg",
    "pitch_deg",
    "roll_deg",
    "sd_heading_deg",
    "sd_pitch_deg",
    "sd_roll_deg",
    "corr_heading_pitch",
    "corr_heading_roll",
    "corr_pitch_roll",
];
/// The antennas' masks, after [`FLOATS`].
pub const MASKS: [&str; 2] = ["antennas_used", "antennas_set_aside"];

/// The Arrow schema for the dataset's `sessions`.
pub fn schema(sessions: &[String]) -> SchemaRef {
    let mut fields = vec![
        Field::new(SESSION_INDEX, DataType::UInt16, false),
        Field::new(TIME_GPS_NS, DataType::Int64, false),
    ];
    for name in FLOATS {
        fields.push(Field::new(name, DataType::Float64, true));
    }
    for name in MASKS {
        fields.push(Field::new(name, DataType::UInt32, false));
    }
    with_sessions(fields, sessions)
}

/// A row of the table, a field per column (but the session's index).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Row {
    /// GPS time, ns.
    pub time_gps_ns: i64,
    /// `heading_deg`.
    pub heading_deg: f64,
    /// `pitch_deg`.
    pub pitch_deg: f64,
    /// `roll_deg` (NaN where the array does not give it: stored as null, as every NaN).
    pub roll_deg: f64,
    /// `sd_heading_deg`.
    pub sd_heading_deg: f64,
    /// `sd_pitch_deg`.
    pub sd_pitch_deg: f64,
    /// `sd_roll_deg`.
    pub sd_roll_deg: f64,
    /// `corr_heading_pitch`.
    pub corr_heading_pitch: f64,
    /// `corr_heading_roll`.
    pub corr_heading_roll: f64,
    /// `corr_pitch_roll`.
    pub corr_pitch_roll: f64,
    /// `antennas_used`.
    pub antennas_used: u32,
    /// `antennas_set_aside`.
    pub antennas_set_aside: u32,
}

impl Row {
    /// The [`FLOATS`] values, each under its column's name.
    fn floats(&self) -> [(&'static str, f64); 9] {
        [
            ("heading_deg", self.heading_deg),
            ("pitch_deg", self.pitch_deg),
            ("roll_deg", self.roll_deg),
            ("sd_heading_deg", self.sd_heading_deg),
            ("sd_pitch_deg", self.sd_pitch_deg),
            ("sd_roll_deg", self.sd_roll_deg),
            ("corr_heading_pitch", self.corr_heading_pitch),
            ("corr_heading_roll", self.corr_heading_roll),
            ("corr_pitch_roll", self.corr_pitch_roll),
        ]
    }
}

/// Writes the table in `dir` for the dataset's `sessions`: every array session's rows, as
/// (session index, rows); returns its rows and SHA-256.
pub fn write(
    dir: &std::path::Path,
    sessions: &[String],
    tables: &[(u16, &[Row])],
) -> crate::Result<crate::parquet_io::table::Written> {
    use crate::parquet_io::table::{Encodings, TableWriter};
    use arrow_array::{ArrayRef, Float64Array, Int64Array, UInt16Array, UInt32Array};
    let mut w = TableWriter::create(dir, FILE, schema(sessions), Encodings::default())?;
    for (index, rows) in tables {
        let times: Vec<i64> = rows.iter().map(|r| r.time_gps_ns).collect();
        let mut columns: Vec<(&str, ArrayRef)> = vec![
            (
                SESSION_INDEX,
                Arc::new(UInt16Array::from(vec![*index; rows.len()])),
            ),
            (TIME_GPS_NS, Arc::new(Int64Array::from(times))),
        ];
        let floats: Vec<[(&str, f64); 9]> = rows.iter().map(Row::floats).collect();
        for c in 0..FLOATS.len() {
            let name = floats.first().map_or(FLOATS[c], |f| f[c].0);
            // A value the array does not give (NaN: two antennas' roll) is null.
            let values: Vec<Option<f64>> = floats
                .iter()
                .map(|f| Some(f[c].1).filter(|v| !v.is_nan()))
                .collect();
            columns.push((name, Arc::new(Float64Array::from(values))));
        }
        let used: Vec<u32> = rows.iter().map(|r| r.antennas_used).collect();
        let aside: Vec<u32> = rows.iter().map(|r| r.antennas_set_aside).collect();
        columns.push((MASKS[0], Arc::new(UInt32Array::from(used))));
        columns.push((MASKS[1], Arc::new(UInt32Array::from(aside))));
        w.write(columns)?;
    }
    w.finish_hashed()
}
