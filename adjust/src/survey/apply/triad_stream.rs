//! A triad calibration applied (docs/model.md 6.7: "for a triad, the vector and its 3x3
//! covariance"): every sample's three readings (and, with temperature terms, the axes'
//! temperatures interpolated as align does) to the calibrated vector in the body frame
//! ([`crate::calibration::triad::TriadModel::evaluate`]), its covariance J C J^T from the fit's
//! parameter covariance, and flags (a reading or temperature outside the range the
//! positions saw; saturated, not connected or no temperature: no value). Both sources of
//! samples are streamed a row group at a time: ingest's acceleration table (counts) and its
//! lab table (a lab logger's readings).

use crate::Error;
use crate::calibration::triad::{MAX_PARAMS, TriadModel};
use align::window::Interpolator;
use arrow_array::Array;
use ingest::contract::calibration::TriadResult;
use ingest::contract::status;
use ingest::contract::tables::temperature::Temperatures;
use ingest::contract::tables::{self, applied};
use ingest::parquet_io::table::STREAM_ROWS_PER_GROUP;
use std::path::Path;

/// A calibrated vector and the six elements of its covariance (xx, xy, xz, yy, yz, zz).
pub type Vector = ([f64; 3], [f64; 6]);

/// The fit's parameters and covariance, ready to evaluate.
pub struct TriadFunction {
    model: TriadModel,
    p: Vec<f64>,
    /// Row-major n x n.
    cov: Vec<f64>,
    range: Option<[[f64; 2]; 3]>,
    t_ref_c: f64,
    temperature_range_c: Option<[f64; 2]>,
}

impl TriadFunction {
    /// From calibration.json's triad result.
    pub fn new(r: &TriadResult) -> Result<Self, String> {
        let model = TriadModel {
            order: r.order,
            temperature: r.temperature,
        };
        let names = model.names();
        let n = names.len();
        let found: Vec<&str> = r.parameters.iter().map(|p| p.name.as_str()).collect();
        if found != names || r.correlation.len() != n || r.correlation.iter().any(|c| c.len() != n)
        {
            return Err(format!(
                "triad {}: its parameters ({}) are not those of order {} {} temperature terms ({})",
                r.model,
                found.join(", "),
                r.order,
                if r.temperature { "with" } else { "without" },
                names.join(", ")
            ));
        }
        ingest::contract::calibration::check_parameters(&r.parameters, &r.correlation)
            .map_err(|e| format!("triad {}: {e}", r.model))?;
        let t_ref_c = match (r.temperature, r.t_ref_c) {
            (true, Some(t)) => t,
            (true, None) => {
                return Err(format!(
                    "triad {}: temperature terms without t_ref_c",
                    r.model
                ));
            }
            (false, _) => 0.0,
        };
        let p = r.parameters.iter().map(|q| q.value).collect();
        let cov = (0..n * n)
            .map(|k| {
                let (i, j) = (k / n, k % n);
                r.parameters[i].sigma * r.parameters[j].sigma * r.correlation[i][j]
            })
            .collect();
        let f = TriadFunction {
            model,
            p,
            cov,
            range: r.readings_range,
            t_ref_c,
            temperature_range_c: r.temperature_range_c,
        };
        f.finite_where_used()
            .map_err(|e| format!("triad {}: {e}", r.model))?;
        Ok(f)
    }

    /// Where the calibration is meant to be used (the corners of its readings' and
    /// temperatures' ranges, or the biases without them), its vector and covariance must be
    /// numbers, as an axis function's must.
    fn finite_where_used(&self) -> Result<(), String> {
        let corners: Vec<[f64; 3]> = match self.range {
            Some(rg) => (0..8)
                .map(|c| std::array::from_fn(|j| rg[j][(c >> j) & 1]))
                .collect(),
            None => vec![std::array::from_fn(|j| self.p[6 + j])],
        };
        let temperatures: Vec<Option<[f64; 3]>> =
            match (self.model.temperature, self.temperature_range_c) {
                (false, _) => vec![None],
                (true, Some([lo, hi])) => vec![Some([lo; 3]), Some([hi; 3])],
                (true, None) => vec![Some([self.t_ref_c; 3])],
            };
        for x in &corners {
            for &t in &temperatures {
                let (v, _) = self.apply(*x, t);
                let finite = v.is_some_and(|(a, c)| a.iter().chain(&c).all(|x| x.is_finite()));
                if !finite {
                    return Err(format!(
                        "at readings {x:?} the function gives no finite vector and \
                         covariance: its parameters overflow the arithmetic"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The readings the function maps to the vector `a` (Newton's method on the model, from
    /// the biases; models without temperature terms only): what an epoch's mean specific
    /// force was read as. None where it does not converge or the model has temperature
    /// terms.
    pub fn readings_for(&self, a: [f64; 3]) -> Option<[f64; 3]> {
        if self.model.temperature {
            return None;
        }
        let mut x: [f64; 3] = std::array::from_fn(|j| self.p[6 + j] + a[j] / self.p[3 + j]);
        for _ in 0..20 {
            let (got, d) = self.model.evaluate(&self.p, x, [0.0; 3], None);
            let r: [f64; 3] = std::array::from_fn(|j| got[j] - a[j]);
            // d is upper triangular (T times the axes' derivatives): back-substitution.
            let mut step = [0.0; 3];
            for i in (0..3).rev() {
                let rest: f64 = (i + 1..3).map(|j| d[i][j] * step[j]).sum();
                step[i] = (r[i] - rest) / d[i][i];
            }
            for j in 0..3 {
                x[j] -= step[j];
            }
            if step.iter().all(|v| v.abs() < 1e-9) {
                return x.iter().all(|v| v.is_finite()).then_some(x);
            }
        }
        None
    }

    /// The gradient by the parameters of m . c(x): how the calibration's error along `m` at
    /// readings `x` depends on the parameters' errors (the difference of two such is what a
    /// tie read at the second does not take away: a bias cancels, scales and angles act on
    /// the difference of the vectors). Models without temperature terms.
    pub fn gradient(&self, x: [f64; 3], m: [f64; 3]) -> Vec<f64> {
        let n = self.p.len();
        let mut j = [0.0; 3 * MAX_PARAMS];
        self.model.evaluate(&self.p, x, [0.0; 3], Some(&mut j));
        (0..n)
            .map(|c| (0..3).map(|r| m[r] * j[r * n + c]).sum())
            .collect()
    }

    /// The parameters' covariance, row-major n x n.
    pub fn covariance(&self) -> &[f64] {
        &self.cov
    }

    /// Whether the model needs temperatures.
    pub fn needs_temperature(&self) -> bool {
        self.model.temperature
    }

    /// The vector and the six covariance elements (xx, xy, xz, yy, yz, zz) at readings `x`
    /// and the axes' temperatures, and the flags (out of the calibrated readings or
    /// temperatures; no temperature where the model needs one: no value).
    pub fn apply(&self, x: [f64; 3], temperature_c: Option<[f64; 3]>) -> (Option<Vector>, u8) {
        let mut flags = 0;
        if self
            .range
            .is_some_and(|rg| (0..3).any(|j| !(rg[j][0]..=rg[j][1]).contains(&x[j])))
        {
            flags |= applied::COUNTS_OUT_OF_RANGE;
        }
        let tau = match (self.model.temperature, temperature_c) {
            (false, _) => [0.0; 3],
            (true, None) => return (None, flags | applied::NO_TEMPERATURE),
            (true, Some(t)) => {
                if self
                    .temperature_range_c
                    .is_some_and(|[lo, hi]| t.iter().any(|v| !(lo..=hi).contains(v)))
                {
                    flags |= applied::TEMPERATURE_OUT_OF_RANGE;
                }
                t.map(|v| v - self.t_ref_c)
            }
        };
        let n = self.p.len();
        let mut jac = [0.0; 3 * MAX_PARAMS];
        let (a, _) = self.model.evaluate(&self.p, x, tau, Some(&mut jac));
        // J C, 3 x n, then (J C) J^T.
        let mut jc = [[0.0; MAX_PARAMS]; 3];
        for (r, row) in jc.iter_mut().enumerate() {
            for (c, out) in row.iter_mut().enumerate().take(n) {
                *out = (0..n).map(|m| jac[r * n + m] * self.cov[m * n + c]).sum();
            }
        }
        let cov = |r: usize, s: usize| (0..n).map(|m| jc[r][m] * jac[s * n + m]).sum::<f64>();
        let c = [
            cov(0, 0),
            cov(0, 1),
            cov(0, 2),
            cov(1, 1),
            cov(1, 2),
            cov(2, 2),
        ];
        (Some((a, c)), flags)
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
    vector: [Vec<f64>; 3],
    covariance: [Vec<f64>; 6],
    def: Vec<i16>,
    flags: Vec<i32>,
}

impl Columns {
    fn push(&mut self, session: u16, time: i64, sample: Option<Vector>, flags: u8) {
        self.session.push(i32::from(session));
        self.time.push(time);
        if let Some((a, c)) = sample {
            for (column, x) in self.vector.iter_mut().zip(a) {
                column.push(x);
            }
            for (column, x) in self.covariance.iter_mut().zip(c) {
                column.push(x);
            }
        }
        self.def.push(i16::from(sample.is_some()));
        self.flags.push(i32::from(flags));
    }

    /// The row group's columns, each under its field of the triad table's row group.
    fn take(&mut self) -> applied::TriadRowGroup {
        let all = self.def.iter().all(|&d| d == 1);
        let def = std::mem::take(&mut self.def);
        let levels = || (!all).then(|| def.clone());
        let nullable = |v: &mut Vec<f64>| (std::mem::take(v), levels());
        applied::TriadRowGroup {
            session_index: std::mem::take(&mut self.session),
            time_gps_ns: std::mem::take(&mut self.time),
            vector_mgal: self.vector.each_mut().map(nullable),
            covariance_mgal2: self.covariance.each_mut().map(nullable),
            flags: std::mem::take(&mut self.flags),
        }
    }
}

/// The axes' temperatures per session, interpolated along the stream.
struct AxisTemperatures<'t> {
    /// Per session index, per axis.
    series: Vec<[Option<Interpolator<'t>>; 3]>,
    max_gap_ns: i64,
}

impl<'t> AxisTemperatures<'t> {
    fn new(
        temperatures: &'t Temperatures,
        sessions: usize,
        channels: [usize; 3],
        max_gap_ns: i64,
    ) -> Self {
        let series = (0..sessions)
            .map(|s| {
                channels.map(|ch| {
                    let s = u16::try_from(s).ok()?;
                    let ch = u8::try_from(ch + 1).ok()?;
                    let (t, v) = temperatures.get(&(s, ch))?;
                    Some(Interpolator::new(t, v))
                })
            })
            .collect();
        AxisTemperatures { series, max_gap_ns }
    }

    fn at(&mut self, session: u16, time_ns: i64) -> Option<[f64; 3]> {
        let gap = self.max_gap_ns;
        let axes = self.series.get_mut(usize::from(session))?;
        let [a, b, c] = axes.each_mut().map(|it| {
            it.as_mut()
                .and_then(|it| it.at(time_ns, gap))
                .map(|(v, _)| v)
        });
        Some([a?, b?, c?])
    }
}

/// Where the samples go: the function applied with the axes' temperatures, into the
/// columns of the next row group, counted.
struct Applier<'a, 'b> {
    f: &'a TriadFunction,
    temperatures: AxisTemperatures<'b>,
    cols: Columns,
    out: TriadWritten,
}

impl Applier<'_, '_> {
    /// One sample: its vector and covariance, or why it has none.
    fn one(&mut self, (session, time): (u16, i64), x: [Option<f64>; 3], flags: u8) {
        let (sample, flags) = match (flags, x) {
            (0, [Some(a), Some(b), Some(c)]) => {
                let t = if self.f.needs_temperature() {
                    self.temperatures.at(session, time)
                } else {
                    None
                };
                self.f.apply([a, b, c], t)
            }
            (0, _) => (None, applied::NOT_CONNECTED),
            (f, _) => (None, f),
        };
        self.out.with_value += u64::from(sample.is_some());
        self.out.by_flags[usize::from(flags)] += 1;
        self.out.rows += 1;
        self.cols.push(session, time, sample, flags);
    }
}

/// The flags a sample's status gives the triad: not connected or saturated on any of its
/// `channels`.
fn status_flags(st: u8, channels: [usize; 3]) -> u8 {
    let mut flags = 0;
    for &ch in &channels {
        if status::not_connected(st, ch) {
            flags |= applied::NOT_CONNECTED;
        } else if status::over_range(st, ch) {
            flags |= applied::SATURATED;
        }
    }
    flags
}

/// Streams ingest's acceleration and lab tables through `f` into the triad table in `dir`;
/// `channels` are the survey's channels (0-based) of the triad's x, y and z; a temperature
/// farther than `max_gap_ns` from a sample is none.
pub fn write(
    sessions: &[String],
    ingest_dir: &Path,
    dir: &Path,
    f: &TriadFunction,
    channels: [usize; 3],
    max_gap_ns: i64,
) -> Result<TriadWritten, Error> {
    let series = if f.needs_temperature() {
        tables::temperature::read(ingest_dir)?
    } else {
        Temperatures::new()
    };
    let mut writer = applied::triad_writer(dir, sessions)?;
    let mut to = Applier {
        f,
        temperatures: AxisTemperatures::new(&series, sessions.len(), channels, max_gap_ns),
        cols: Columns::default(),
        out: TriadWritten {
            rows: 0,
            sha256: String::new(),
            with_value: 0,
            by_flags: [0; 256],
        },
    };
    tables::acceleration::batches(ingest_dir, STREAM_ROWS_PER_GROUP, |b| {
        for i in 0..b.time_ns.len() {
            let x = channels.map(|ch| {
                let c = b.counts[ch];
                c.is_valid(i).then(|| f64::from(c.value(i)))
            });
            let flags = status_flags(b.status[i], channels);
            to.one((b.session[i], b.time_ns[i]), x, flags);
        }
        writer.write(to.cols.take()).map(drop)
    })?;
    tables::lab::batches(ingest_dir, STREAM_ROWS_PER_GROUP, |b| {
        for i in 0..b.time_ns.len() {
            let x = channels.map(|ch| {
                let v = b.values[ch];
                v.is_valid(i).then(|| v.value(i))
            });
            to.one((b.session[i], b.time_ns[i]), x, 0);
        }
        writer.write(to.cols.take()).map(drop)
    })?;
    let (_, sha256) = writer.finish_hashed()?;
    to.out.sha256 = sha256;
    Ok(to.out)
}
