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

use super::{DataType, Field, SESSION_INDEX, SchemaRef, TIME_GPS_NS, with_sessions};
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
