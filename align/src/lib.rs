//! gravcal's `align` stage: from the raw streams to observations (docs/model.md section 1).
//!
//! One observation per (theodolite reading, accelerometer): the mean ADC count in a window of
//! `window_s` centred on the reading's GPS time (half-open, `[t - w/2, t + w/2)`, so a
//! 2.56 s window at 31.25 Hz holds exactly 80 samples), the sd of that mean, the
//! accelerometer's temperature interpolated at the reading's time, and sigma_Dz, the sample
//! sd of the station's readings (eq. 4 of the paper). An observation that cannot be used is
//! kept with the reason (the first that applies, in this order): a sample flagged not
//! connected, a saturated sample, too few samples, no temperature near enough, or a trend in
//! the window (the platform was not still). A channel not connected for a whole session
//! yields no observations, and one line saying so.
//!
//! Reads OUT/ingest/ (the tables of [`ingest::contract::tables`] and `ingest.json`), writes
//! OUT/align/observations.parquet and OUT/align/align.json. The acceleration table is
//! streamed once, in order: time is linear in the number of samples and memory does not
//! grow with it.

pub mod allan;
pub mod colour;
pub mod samples;
pub mod statics;
pub mod thermometer;
pub mod tide;
pub mod weights;
pub mod window;

mod observe;
mod positions;
mod stations;
mod units;

pub use observe::print_summary;
use observe::{Formed, Setup, observe_session, write_outputs};
use positions::{allan_row, multi_positions, print_positions};
use stations::{
    Pending, StationSigma, StillInterval, adc_noise, coloured_variance, fill_windows, open_windows,
    station_sigmas, still_intervals,
};

use ingest::contract::align_ledger::{
    AdcNoise, AlignReport, AllanRow, Counts, DRIFT_T_LIMIT, Disconnected, LEDGER_FILE,
    LEDGER_FORMAT, MultiPosition, STAGE_DIR, StaticNoise, StaticPosition, reason, sigma_source,
};
use ingest::contract::custody::{Custody, Folders, Root};
use ingest::contract::ingest_ledger;
use ingest::contract::manifest::{
    self, AlignConfig, Dataset, Location, ReadingUnit, SessionKind, SigmaDzMethod, Thermometers,
};
use ingest::contract::{status, tables};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use window::{WindowStats, WindowSums, interpolate, sample_sd};

/// What can go wrong in align.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// Reading the manifest or ingest's outputs, or writing a table.
    #[error(transparent)]
    Ingest(#[from] ingest::Error),
    /// An input table is not what ingest writes (a missing column, a wrong type).
    #[error("{}: {message}", path.display())]
    Table {
        /// The table.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A session's theodolite readings fit another unit than the manifest declares
    /// (align/src/units.rs).
    #[error("session `{session}`: {message}")]
    TheodoliteUnit {
        /// The session.
        session: String,
        /// The declared unit, the one the readings suggest and each accelerometer's misfits.
        message: String,
    },
}

/// Result with this crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// One observation: a theodolite reading and one accelerometer's window around it, as
/// observations.parquet holds it.
pub use ingest::contract::tables::observations::Observation;

/// Aligns the dataset: reads OUT/ingest, writes OUT/align. Returns the ledger.
pub fn run(dataset: &Path, out: &Path) -> Result<AlignReport> {
    let ds = Dataset::load(dataset)?;
    let _lock = ingest::base::lock::OutputLock::acquire(out)?;
    let ingest_dir = out.join(ingest_ledger::STAGE_DIR);
    let ingest_report = ingest_ledger::IngestReport::load_verified(&ds, out)?;
    let setup = Setup::new(&ds);
    let temperatures = tables::temperature::read(&ingest_dir)?;
    let mut pending = open_windows(&ds, &tables::theodolite::read(&ingest_dir)?, setup.half_ns);
    let mut still: Vec<Vec<StillInterval>> = pending.iter().map(|p| still_intervals(p)).collect();
    let tau0_s = 1.0 / ds.manifest.instrument.sample_rate_hz;
    fill_windows(
        &ingest_dir,
        &mut pending,
        &mut still,
        (tau0_s * 1e9).round() as i64,
    )?;
    let mut formed = Formed {
        noise: adc_noise(&ds, &still, tau0_s),
        ..Formed::default()
    };
    for (si, s) in ds.sessions.iter().enumerate() {
        if !s.is_tilt_table() {
            continue;
        }
        let never = ingest_report
            .sessions
            .iter()
            .find(|x| x.id == s.session.id)
            .map(|x| x.channels_never_connected.clone())
            .unwrap_or_default();
        let temps = |channel: u8| {
            u16::try_from(si)
                .ok()
                .and_then(|i| temperatures.get(&(i, channel)))
        };
        observe_session(
            &ds,
            &setup,
            &s.session.id,
            &pending[si],
            &never,
            temps,
            &mut formed,
        );
    }
    units::check(&ds, &formed.observations)?;
    formed.multi_position = multi_positions(&ds, &setup, &ingest_dir, &temperatures)?;
    write_outputs(&ds, out, setup, formed)
}
