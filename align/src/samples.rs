//! The acceleration samples of a dataset as decimal readings, whichever of ingest's two
//! stream tables holds them: acceleration.parquet (ADC counts) or lab.parquet (a lab
//! logger's readings). The tables themselves are read in `ingest::contract::tables`.

use crate::Result;
use arrow_array::Array;
use ingest::contract::tables;
use std::collections::BTreeMap;
use std::path::Path;

/// The samples of the sessions `wanted` (by index), as series of decimal readings: from
/// lab.parquet (lab streams) and from the acceleration table (counts; null where not
/// connected or over range).
pub fn series(dir: &Path, wanted: &[u16]) -> Result<BTreeMap<u16, crate::statics::Series>> {
    let mut out: BTreeMap<u16, crate::statics::Series> =
        wanted.iter().map(|&w| (w, Default::default())).collect();
    tables::acceleration::for_each(dir, |session, time_ns, counts, _| {
        if let Some(s) = out.get_mut(&session) {
            s.time_ns.push(time_ns);
            s.values.push(counts.map(|c| c.map(f64::from)));
        }
    })?;
    tables::lab::batches(dir, 1 << 16, |b| {
        for i in 0..b.time_ns.len() {
            if let Some(s) = out.get_mut(&b.session[i]) {
                s.time_ns.push(b.time_ns[i]);
                s.values
                    .push(b.values.map(|v| v.is_valid(i).then(|| v.value(i))));
            }
        }
        Ok::<(), ingest::Error>(())
    })?;
    Ok(out)
}

/// Streams every acceleration sample of the dataset as decimal readings: the acceleration
/// table (counts; null where not connected or over range, with the status bits), then the
/// lab table (readings in the instrument's unit; null where the line gave `nan`, status
/// not connected on that channel). `f(session index, time_ns, readings, status)`;
/// each session's samples come from one table, in time order.
pub fn samples(dir: &Path, mut f: impl FnMut(u16, i64, [Option<f64>; 3], u8)) -> Result<()> {
    tables::acceleration::for_each(dir, |session, time_ns, counts, st| {
        f(session, time_ns, counts.map(|c| c.map(f64::from)), st);
    })?;
    tables::lab::batches(dir, 1 << 16, |b| {
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
        Ok::<(), ingest::Error>(())
    })?;
    Ok(())
}
