//! Collects accepted acceleration and temperature samples into Arrow batches and writes them
//! to `acceleration.parquet` and `temperature.parquet`; counts the values stored as null.

use crate::error::{Error, Result};
use crate::schema;
use crate::table::{Encodings, ROWS_PER_BATCH, TableWriter};
use arrow::array::{ArrayRef, Float64Array, Int32Array, Int64Array, UInt8Array, UInt16Array};
use arrow::buffer::NullBuffer;
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use std::sync::mpsc::{Receiver, SyncSender, sync_channel};
use std::thread::JoinHandle;

/// Status bit: channel `ch` (0-based) over range.
pub fn over_range_bit(ch: usize) -> u8 {
    1 << ch
}
/// Status bit: channel `ch` (0-based) not connected.
pub fn not_connected_bit(ch: usize) -> u8 {
    1 << (ch + 4)
}

#[derive(Default)]
struct Columns<T> {
    time: Vec<i64>,
    values: [Vec<T>; 3],
    valid: [Vec<bool>; 3],
    status: Vec<u8>,
}

impl<T: Default> Columns<T> {
    fn len(&self) -> usize {
        self.time.len()
    }
    fn take(&mut self) -> Self {
        Columns {
            time: std::mem::take(&mut self.time),
            values: std::mem::take(&mut self.values),
            valid: std::mem::take(&mut self.valid),
            status: std::mem::take(&mut self.status),
        }
    }
}

fn nulls(valid: Vec<bool>) -> Option<NullBuffer> {
    if valid.iter().all(|&v| v) {
        None
    } else {
        Some(NullBuffer::from(valid))
    }
}

/// What the current session's streams held.
#[derive(Clone, Debug, Default)]
pub struct SessionStats {
    /// Acceleration samples.
    pub acceleration: u64,
    /// Temperature samples.
    pub temperature: u64,
    /// GPS time of the first acceleration sample, ns.
    pub first_gps_ns: Option<i64>,
    /// GPS time of the last acceleration sample, ns.
    pub last_gps_ns: Option<i64>,
    /// Whether channel 1..3 was connected in any acceleration sample.
    pub connected_seen: [bool; 3],
}

enum Message {
    Acceleration(Vec<ArrayRef>),
    Temperature(Vec<ArrayRef>),
    /// All batches sent: close the files and rename them into place.
    Finish,
}

/// The writer thread: writes batches until told to finish. If the sender goes away without
/// `Finish` (the reading failed), the tables are dropped and their partial files removed.
fn write_tables(
    mut acceleration: TableWriter,
    mut temperature: TableWriter,
    rx: Receiver<Message>,
) -> Result<(u64, u64)> {
    for m in rx {
        match m {
            Message::Acceleration(cols) => acceleration.write(cols)?,
            Message::Temperature(cols) => temperature.write(cols)?,
            Message::Finish => return Ok((acceleration.finish()?, temperature.finish()?)),
        }
    }
    Err(Error::io(
        "acceleration.parquet",
        std::io::Error::other("ingest stopped before the tables were complete"),
    ))
}

/// The two stream tables of a dataset, being written session by session.
pub struct StreamWriter {
    /// Batches go to a thread that encodes and compresses them (the second core).
    to_writer: Option<SyncSender<Message>>,
    writer: Option<JoinHandle<Result<(u64, u64)>>>,
    session: u16,
    stats: SessionStats,
    /// Per channel: acceleration values null because not connected, because over range;
    /// temperature values null because not connected.
    nulls: [[u64; 3]; 3],
    acc: Columns<i32>,
    temp: Columns<f64>,
}

impl StreamWriter {
    /// Starts both tables in `dir`, for a dataset with `sessions` (ids in manifest order).
    pub fn create(dir: &Path, sessions: &[String]) -> Result<Self> {
        let acceleration = TableWriter::create(
            dir,
            schema::acceleration::FILE,
            "acceleration",
            schema::acceleration::schema(sessions),
            Encodings {
                dictionary: &[],
                delta: &[
                    schema::SESSION_INDEX,
                    schema::acceleration::COUNTS[0],
                    schema::acceleration::COUNTS[1],
                    schema::acceleration::COUNTS[2],
                    schema::STATUS,
                ],
            },
        )?;
        let temperature = TableWriter::create(
            dir,
            schema::temperature::FILE,
            "temperature",
            schema::temperature::schema(sessions),
            Encodings {
                dictionary: &[],
                delta: &[schema::SESSION_INDEX, schema::STATUS],
            },
        )?;
        let (tx, rx) = sync_channel(4);
        let writer = std::thread::Builder::new()
            .name("parquet-writer".to_owned())
            .spawn(move || write_tables(acceleration, temperature, rx))
            .map_err(|e| Error::io(dir, e))?;
        Ok(StreamWriter {
            to_writer: Some(tx),
            writer: Some(writer),
            session: 0,
            stats: SessionStats::default(),
            nulls: [[0; 3]; 3],
            acc: Columns::default(),
            temp: Columns::default(),
        })
    }

    /// Rows that follow belong to the session at `index` in the manifest.
    pub fn start_session(&mut self, index: u16) -> Result<()> {
        self.flush()?;
        self.session = index;
        self.stats = SessionStats::default();
        Ok(())
    }

    /// What the current session's streams held so far.
    pub fn stats(&self) -> &SessionStats {
        &self.stats
    }

    /// Values stored as null since the last call, by channel and reason (for a file's ledger).
    pub fn take_null_counts(&mut self) -> BTreeMap<String, u64> {
        let mut out = BTreeMap::new();
        let what = ["not connected", "over range", "temperature not connected"];
        for (k, per_channel) in self.nulls.iter().enumerate() {
            for (ch, &n) in per_channel.iter().enumerate() {
                if n > 0 {
                    out.insert(format!("ch{} {}", ch + 1, what[k]), n);
                }
            }
        }
        self.nulls = [[0; 3]; 3];
        out
    }

    /// One acceleration sample; over-range and unconnected channels are stored as null and
    /// counted (see [`StreamWriter::take_null_counts`]).
    pub fn acceleration(&mut self, time_ns: i64, counts: [i32; 3], status: u8) -> Result<()> {
        self.acc.time.push(time_ns);
        self.stats.acceleration += 1;
        self.stats.first_gps_ns.get_or_insert(time_ns);
        self.stats.last_gps_ns = Some(time_ns);
        for ch in 0..3 {
            self.stats.connected_seen[ch] |= status & not_connected_bit(ch) == 0;
            let null = if status & not_connected_bit(ch) != 0 {
                Some(0)
            } else if status & over_range_bit(ch) != 0 {
                Some(1)
            } else {
                None
            };
            if let Some(k) = null {
                self.nulls[k][ch] += 1;
            }
            self.acc.values[ch].push(if null.is_none() { counts[ch] } else { 0 });
            self.acc.valid[ch].push(null.is_none());
        }
        self.acc.status.push(status);
        if self.acc.len() >= ROWS_PER_BATCH {
            self.flush_acceleration()?;
        }
        Ok(())
    }

    /// One temperature sample (degC, `None` where the channel is not connected).
    pub fn temperature(
        &mut self,
        time_ns: i64,
        celsius: [Option<f64>; 3],
        status: u8,
    ) -> Result<()> {
        self.temp.time.push(time_ns);
        self.stats.temperature += 1;
        for ch in 0..3 {
            let v = if status & not_connected_bit(ch) != 0 {
                None
            } else {
                celsius[ch]
            };
            if v.is_none() {
                self.nulls[2][ch] += 1;
            }
            self.temp.values[ch].push(v.unwrap_or(0.0));
            self.temp.valid[ch].push(v.is_some());
        }
        self.temp.status.push(status);
        if self.temp.len() >= ROWS_PER_BATCH {
            self.flush_temperature()?;
        }
        Ok(())
    }

    fn flush_acceleration(&mut self) -> Result<()> {
        if self.acc.len() == 0 {
            return Ok(());
        }
        let c = self.acc.take();
        let n = c.time.len();
        let [v0, v1, v2] = c.values;
        let [m0, m1, m2] = c.valid;
        let cols: Vec<ArrayRef> = vec![
            Arc::new(UInt16Array::from(vec![self.session; n])),
            Arc::new(Int64Array::from(c.time)),
            Arc::new(Int32Array::new(v0.into(), nulls(m0))),
            Arc::new(Int32Array::new(v1.into(), nulls(m1))),
            Arc::new(Int32Array::new(v2.into(), nulls(m2))),
            Arc::new(UInt8Array::from(c.status)),
        ];
        self.send(Message::Acceleration(cols))
    }

    fn flush_temperature(&mut self) -> Result<()> {
        if self.temp.len() == 0 {
            return Ok(());
        }
        let c = self.temp.take();
        let n = c.time.len();
        let [v0, v1, v2] = c.values;
        let [m0, m1, m2] = c.valid;
        let cols: Vec<ArrayRef> = vec![
            Arc::new(UInt16Array::from(vec![self.session; n])),
            Arc::new(Int64Array::from(c.time)),
            Arc::new(Float64Array::new(v0.into(), nulls(m0))),
            Arc::new(Float64Array::new(v1.into(), nulls(m1))),
            Arc::new(Float64Array::new(v2.into(), nulls(m2))),
            Arc::new(UInt8Array::from(c.status)),
        ];
        self.send(Message::Temperature(cols))
    }

    /// Hands a message to the writer thread; if it has stopped, returns its error.
    fn send(&mut self, m: Message) -> Result<()> {
        let sent = self.to_writer.as_ref().is_some_and(|tx| tx.send(m).is_ok());
        if sent {
            Ok(())
        } else {
            Err(self.join().err().unwrap_or_else(|| {
                Error::io(
                    "acceleration.parquet",
                    std::io::Error::other("the Parquet writer stopped"),
                )
            }))
        }
    }

    fn join(&mut self) -> Result<(u64, u64)> {
        self.to_writer = None;
        match self.writer.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            Some(Err(_)) => Err(Error::io(
                "acceleration.parquet",
                std::io::Error::other("the Parquet writer thread panicked"),
            )),
            None => Err(Error::io(
                "acceleration.parquet",
                std::io::Error::other("the Parquet writer already stopped"),
            )),
        }
    }

    fn flush(&mut self) -> Result<()> {
        self.flush_acceleration()?;
        self.flush_temperature()
    }

    /// Writes what is buffered and renames both tables into place; returns (acceleration rows,
    /// temperature rows).
    pub fn finish(mut self) -> Result<(u64, u64)> {
        self.flush()?;
        self.send(Message::Finish)?;
        self.join()
    }
}

impl Drop for StreamWriter {
    fn drop(&mut self) {
        // Dropped without `finish`: closing the channel makes the writer discard its tables.
        self.to_writer = None;
        if let Some(h) = self.writer.take() {
            let _ = h.join();
        }
    }
}
