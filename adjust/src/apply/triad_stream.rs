//! A triad calibration applied (MODEL.md 6.7: "for a triad, the vector and its 3x3
//! covariance"): every sample's three readings to the calibrated vector a = T K (X - B) in
//! the body frame, its covariance J C J^T from the fit's 9 x 9 parameter covariance, and
//! flags (a reading outside the range the positions saw; saturated or not connected: no
//! value). Both sources of samples are streamed a row group at a time: ingest's
//! acceleration table (counts) and its lab table (a lab logger's readings).

use crate::Error;
use crate::triad;
use align::read;
use arrow::array::Array;
use ingest::contract::calibration::TriadResult;
use ingest::contract::status;
use ingest::contract::tables::{self, applied};
use ingest::table::{ColumnTableWriter, ColumnValues, Encodings, STREAM_ROWS_PER_GROUP};
use std::path::Path;

/// The fit's parameters and covariance, ready to evaluate.
pub struct TriadFunction {
    p: [f64; 9],
    cov: [[f64; 9]; 9],
    range: Option<[[f64; 2]; 3]>,
}

impl TriadFunction {
    /// From calibration.json's triad result.
    pub fn new(r: &TriadResult) -> Result<Self, String> {
        if r.parameters.len() != 9 || r.correlation.len() != 9 {
            return Err(format!("triad {} has not 9 parameters", r.model));
        }
        let p = std::array::from_fn(|j| r.parameters[j].value);
        let cov = std::array::from_fn(|i| {
            std::array::from_fn(|j| {
                r.parameters[i].sigma * r.parameters[j].sigma * r.correlation[i][j]
            })
        });
        Ok(TriadFunction {
            p,
            cov,
            range: r.readings_range,
        })
    }

    /// The vector and the six covariance elements (xx, xy, xz, yy, yz, zz) at readings `x`,
    /// and whether a reading lies outside the calibrated range.
    pub fn apply(&self, x: [f64; 3]) -> ([f64; 3], [f64; 6], bool) {
        let p = &self.p;
        let a = triad::calibrated(p, x);
        let (t, k, b) = (
            [[1.0, -p[0], p[1]], [0.0, 1.0, -p[2]], [0.0, 0.0, 1.0]],
            [p[3], p[4], p[5]],
            [p[6], p[7], p[8]],
        );
        let u: [f64; 3] = std::array::from_fn(|j| k[j] * (x[j] - b[j]));
        // J = da/dp, 3 x 9: the angles, then per axis T[:, j] (x_j - b_j) and -T[:, j] s_j.
        let mut jac = [[0.0; 9]; 3];
        jac[0][0] = -u[1];
        jac[0][1] = u[2];
        jac[1][2] = -u[2];
        for j in 0..3 {
            for r in 0..3 {
                jac[r][3 + j] = t[r][j] * (x[j] - b[j]);
                jac[r][6 + j] = -t[r][j] * k[j];
            }
        }
        let mut jc = [[0.0; 9]; 3];
        for r in 0..3 {
            for c in 0..9 {
                jc[r][c] = (0..9).map(|m| jac[r][m] * self.cov[m][c]).sum();
            }
        }
        let cov = |r: usize, s: usize| (0..9).map(|m| jc[r][m] * jac[s][m]).sum::<f64>();
        let out = self
            .range
            .is_some_and(|rg| (0..3).any(|j| !(rg[j][0]..=rg[j][1]).contains(&x[j])));
        (
            a,
            [
                cov(0, 0),
                cov(0, 1),
                cov(0, 2),
                cov(1, 1),
                cov(1, 2),
                cov(2, 2),
            ],
            out,
        )
    }
}

/// What the triad's table holds: rows, samples with a value, samples by flags byte.
pub struct TriadWritten {
    /// Rows written.
    pub rows: u64,
    /// SHA-256 of the table.
    pub sha256: String,
    /// Samples with a vector.
    pub with_value: u64,
    /// Samples by their flags byte.
    pub by_flags: [u64; 256],
}

/// One row group's columns being filled.
#[derive(Default)]
struct Columns {
    session: Vec<i32>,
    time: Vec<i64>,
    values: [Vec<f64>; 9],
    def: Vec<i16>,
    flags: Vec<i32>,
}

impl Columns {
    fn push(&mut self, session: u16, time: i64, sample: Option<([f64; 3], [f64; 6])>, flags: u8) {
        self.session.push(i32::from(session));
        self.time.push(time);
        if let Some((a, c)) = sample {
            for k in 0..3 {
                self.values[k].push(a[k]);
            }
            for k in 0..6 {
                self.values[3 + k].push(c[k]);
            }
        }
        self.def.push(i16::from(sample.is_some()));
        self.flags.push(i32::from(flags));
    }

    fn take(&mut self) -> (usize, Vec<ColumnValues>) {
        let n = self.time.len();
        let all = self.values[0].len() == n;
        let def = std::mem::take(&mut self.def);
        let mut cols = vec![
            ColumnValues::Int32(std::mem::take(&mut self.session), None),
            ColumnValues::Int64(std::mem::take(&mut self.time), None),
        ];
        for v in &mut self.values {
            cols.push(ColumnValues::Double(
                std::mem::take(v),
                (!all).then(|| def.clone()),
            ));
        }
        cols.push(ColumnValues::Int32(std::mem::take(&mut self.flags), None));
        (n, cols)
    }
}

/// One sample: its vector and covariance, or why it has none.
fn one(
    f: &TriadFunction,
    cols: &mut Columns,
    out: &mut TriadWritten,
    (session, time): (u16, i64),
    x: [Option<f64>; 3],
    flags: u8,
) {
    let (sample, flags) = match (flags, x) {
        (0, [Some(a), Some(b), Some(c)]) => {
            let (v, cov, beyond) = f.apply([a, b, c]);
            (
                Some((v, cov)),
                u8::from(beyond) * applied::COUNTS_OUT_OF_RANGE,
            )
        }
        (0, _) => (None, applied::NOT_CONNECTED),
        (f, _) => (None, f),
    };
    out.with_value += u64::from(sample.is_some());
    out.by_flags[usize::from(flags)] += 1;
    out.rows += 1;
    cols.push(session, time, sample, flags);
}

/// Streams ingest's acceleration and lab tables through `f` into the triad table in `dir`;
/// `channels` are the survey's channels (0-based) of the triad's x, y and z.
pub fn write(
    sessions: &[String],
    ingest_dir: &Path,
    dir: &Path,
    f: &TriadFunction,
    channels: [usize; 3],
) -> Result<TriadWritten, Error> {
    let names = applied::TRIAD_COLUMNS;
    let mut writer = ColumnTableWriter::create(
        dir,
        applied::FILE,
        "applied triad",
        applied::triad_schema(sessions),
        Encodings {
            delta: &[tables::SESSION_INDEX, tables::TIME_GPS_NS, names[9]],
            byte_stream_split: &names[..9],
            ..Encodings::default()
        },
    )?;
    let mut out = TriadWritten {
        rows: 0,
        sha256: String::new(),
        with_value: 0,
        by_flags: [0; 256],
    };
    let mut cols = Columns::default();
    read::acceleration_batches(ingest_dir, STREAM_ROWS_PER_GROUP, |b| {
        for i in 0..b.time_ns.len() {
            let st = b.status[i];
            let mut flags = 0;
            for &ch in &channels {
                if status::not_connected(st, ch) {
                    flags |= applied::NOT_CONNECTED;
                } else if status::over_range(st, ch) {
                    flags |= applied::SATURATED;
                }
            }
            let x = channels.map(|ch| {
                let c = b.counts[ch];
                c.is_valid(i).then(|| f64::from(c.value(i)))
            });
            one(
                f,
                &mut cols,
                &mut out,
                (b.session[i], b.time_ns[i]),
                x,
                flags,
            );
        }
        let (n, c) = cols.take();
        writer.write_row_group(n, &c)?;
        Ok(())
    })?;
    read::lab_batches(ingest_dir, STREAM_ROWS_PER_GROUP, |b| {
        for i in 0..b.time_ns.len() {
            let x = channels.map(|ch| {
                let v = b.values[ch];
                v.is_valid(i).then(|| v.value(i))
            });
            one(f, &mut cols, &mut out, (b.session[i], b.time_ns[i]), x, 0);
        }
        let (n, c) = cols.take();
        writer.write_row_group(n, &c)?;
        Ok(())
    })?;
    let (_, sha256) = writer.finish_hashed()?;
    out.sha256 = sha256;
    Ok(out)
}
