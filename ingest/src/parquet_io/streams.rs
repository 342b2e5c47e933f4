//! Collects accepted acceleration and temperature samples into row groups and writes them
//! to `acceleration.parquet` and `temperature.parquet`; counts the values stored as null.

use crate::contract::status::{not_connected_bit, over_range_bit};
use crate::contract::tables;
use crate::contract::tables::acceleration::RowGroup as AccelerationGroup;
use crate::contract::tables::temperature::RowGroup as TemperatureGroup;
use crate::contract::tables::{GroupWriter, Nullable};
use crate::error::{Error, Result};
use crate::parquet_io::rowgroup::{N, Spare, column, nullable, session_values, whole};
use crate::parquet_io::table::{ColumnValues, STREAM_ROWS_PER_GROUP, Written};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::mpsc::{Receiver, Sender, SyncSender, channel, sync_channel};
use std::thread::JoinHandle;

/// Temperature samples not yet handed to the writer.
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

/// Acceleration samples not yet handed to the writer, as logged: which values are null
/// follows from the status bits, worked out per row group in
/// [`StreamWriter::flush_acceleration`] rather than per sample. The columns are arrays of a
/// whole row group with one count of the rows in them: a sample is stored with one bound
/// check and one count updated, where five vectors' pushes checked and updated five.
struct AccelerationColumns {
    len: usize,
    time: Box<[i64; N]>,
    counts: [Box<[i32; N]>; 3],
    status: Box<[u8; N]>,
}

impl AccelerationColumns {
    fn new() -> Self {
        AccelerationColumns {
            len: 0,
            time: whole(Vec::new()),
            counts: std::array::from_fn(|_| whole(Vec::new())),
            status: whole(Vec::new()),
        }
    }
}

/// Status bits, stored as Parquet INT32 (UInt8 in the Arrow schema), in `buf` (whatever it
/// held).
fn status_values(status: &[u8], mut buf: Vec<i32>) -> Vec<i32> {
    buf.clear();
    buf.extend(status.iter().map(|&s| i32::from(s)));
    buf
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
    /// A row group of either table.
    Acceleration(AccelerationGroup),
    Temperature(TemperatureGroup),
    /// All row groups sent: close the files and rename them into place.
    Finish,
}

/// The writer thread: writes row groups until told to finish, and hands the acceleration
/// columns' buffers back for the next row groups. If the sender goes away without `Finish`
/// (the reading failed), the tables are dropped and their partial files removed.
fn write_tables(
    mut acceleration: GroupWriter<AccelerationGroup>,
    mut temperature: GroupWriter<TemperatureGroup>,
    rx: Receiver<Message>,
    spent: Sender<Vec<ColumnValues>>,
) -> Result<(Written, Written)> {
    for m in rx {
        match m {
            Message::Acceleration(group) => {
                let buffers = acceleration.write(group)?;
                // The reader may have gone; then the buffers are simply freed.
                let _ = spent.send(buffers);
            }
            Message::Temperature(group) => {
                temperature.write(group)?;
            }
            Message::Finish => {
                return Ok((acceleration.finish_hashed()?, temperature.finish_hashed()?));
            }
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
    writer: Option<JoinHandle<Result<(Written, Written)>>>,
    session: u16,
    stats: SessionStats,
    /// Per channel: acceleration values null because not connected, because over range;
    /// temperature values null because not connected.
    nulls: [[u64; 3]; 3],
    acc: AccelerationColumns,
    temp: Columns<f64>,
    /// Row groups' columns back from the writer, and their buffers kept for reuse: fresh
    /// buffers for every row group cost a page fault per 4 KiB written to them.
    spent: Receiver<Vec<ColumnValues>>,
    spare: Spare,
}

impl StreamWriter {
    /// Starts both tables in `dir`, for a dataset with `sessions` (ids in manifest order).
    pub fn create(dir: &Path, sessions: &[String]) -> Result<Self> {
        let acceleration = tables::acceleration::writer(dir, sessions)?;
        let temperature = tables::temperature::writer(dir, sessions)?;
        // Two row groups queued keep both threads busy.
        let (tx, rx) = sync_channel(2);
        let (spent_tx, spent) = channel();
        let writer = std::thread::Builder::new()
            .name("parquet-writer".to_owned())
            .spawn(move || write_tables(acceleration, temperature, rx, spent_tx))
            .map_err(|e| Error::io(dir, e))?;
        Ok(StreamWriter {
            to_writer: Some(tx),
            writer: Some(writer),
            session: 0,
            stats: SessionStats::default(),
            nulls: [[0; 3]; 3],
            acc: AccelerationColumns::new(),
            temp: Columns::default(),
            spent,
            spare: Spare::default(),
        })
    }

    /// Rows that follow belong to the session at `index` in the manifest.
    pub fn start_session(&mut self, index: u16) -> Result<()> {
        self.flush()?;
        self.session = index;
        self.stats = SessionStats::default();
        Ok(())
    }

    /// What the current session's streams held so far (hands what is buffered to the writer).
    pub fn stats(&mut self) -> Result<SessionStats> {
        self.flush()?;
        Ok(self.stats.clone())
    }

    /// Values stored as null since the last call, by channel and reason (for a file's ledger;
    /// hands what is buffered to the writer).
    pub fn take_null_counts(&mut self) -> Result<BTreeMap<String, u64>> {
        self.flush()?;
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
        Ok(out)
    }

    /// One acceleration sample; over-range and unconnected channels are stored as null and
    /// counted (see [`StreamWriter::take_null_counts`]).
    #[inline(always)]
    pub fn acceleration(&mut self, time_ns: i64, counts: [i32; 3], status: u8) -> Result<()> {
        let a = &mut self.acc;
        // Below N: the row group is handed on as soon as it is full.
        let i = a.len;
        a.time[i] = time_ns;
        for (column, value) in a.counts.iter_mut().zip(counts) {
            column[i] = value;
        }
        a.status[i] = status;
        a.len = i + 1;
        if a.len >= N {
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
        if self.temp.len() >= STREAM_ROWS_PER_GROUP {
            self.flush_temperature()?;
        }
        Ok(())
    }

    #[inline(never)]
    fn flush_acceleration(&mut self) -> Result<()> {
        let n = self.acc.len;
        if n == 0 {
            return Ok(());
        }
        let (first, last) = (self.acc.time[0], self.acc.time[n - 1]);
        for columns in self.spent.try_iter() {
            self.spare.keep(columns);
        }
        let spare = &mut self.spare;
        let time = std::mem::replace(&mut self.acc.time, whole(spare.int64()));
        let time = column(time, n);
        let counts = std::array::from_fn::<_, 3, _>(|ch| {
            column(
                std::mem::replace(&mut self.acc.counts[ch], whole(spare.int32())),
                n,
            )
        });
        self.acc.len = 0;
        // The status bits stay: read below, then overwritten by the next row group.
        let status = &self.acc.status[..n];
        self.stats.acceleration += n as u64;
        self.stats.first_gps_ns.get_or_insert(first);
        self.stats.last_gps_ns = Some(last);
        // Nearly always no status bit is set in a whole row group: nothing to look at per row.
        let any_bit = status.iter().fold(0u8, |a, &s| a | s);
        let mut columns: [Nullable<i32>; 3] = Default::default();
        for ((ch, values), out) in counts.into_iter().enumerate().zip(&mut columns) {
            let (nc, or) = (not_connected_bit(ch), over_range_bit(ch));
            if any_bit & (nc | or) == 0 {
                self.stats.connected_seen[ch] = true;
                *out = (values, None);
                continue;
            }
            let valid: Vec<bool> = status
                .iter()
                .map(|&s| {
                    if s & nc != 0 {
                        self.nulls[0][ch] += 1;
                        false
                    } else {
                        self.stats.connected_seen[ch] = true;
                        if s & or != 0 {
                            self.nulls[1][ch] += 1;
                        }
                        s & or == 0
                    }
                })
                .collect();
            *out = nullable(values, &valid);
        }
        let group = AccelerationGroup {
            session_index: session_values(self.session, n, self.spare.int32()),
            time_gps_ns: time,
            channels: columns,
            last: status_values(status, self.spare.int32()),
        };
        self.send(Message::Acceleration(group))
    }

    fn flush_temperature(&mut self) -> Result<()> {
        if self.temp.len() == 0 {
            return Ok(());
        }
        let c = self.temp.take();
        let n = c.time.len();
        let mut temperature_c: [Nullable<f64>; 3] = Default::default();
        for ((values, valid), out) in c.values.into_iter().zip(&c.valid).zip(&mut temperature_c) {
            *out = nullable(values, valid);
        }
        let group = TemperatureGroup {
            session_index: session_values(self.session, n, Vec::new()),
            time_gps_ns: c.time,
            channels: temperature_c,
            last: status_values(&c.status, Vec::new()),
        };
        self.send(Message::Temperature(group))
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

    fn join(&mut self) -> Result<(Written, Written)> {
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

    /// Hands what is buffered to the writer and tells it to finish, without waiting for it:
    /// the caller can do other work (the theodolite table) meanwhile.
    pub fn close(mut self) -> Result<Closing> {
        self.flush()?;
        self.send(Message::Finish)?;
        Ok(Closing(self))
    }
}

/// Stream tables being finished by the writer thread ([`StreamWriter::close`]).
pub struct Closing(StreamWriter);

impl Closing {
    /// Waits until both tables are renamed into place; returns (acceleration, temperature),
    /// each its rows and SHA-256.
    pub fn wait(mut self) -> Result<(Written, Written)> {
        self.0.join()
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
