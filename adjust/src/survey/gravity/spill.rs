//! Records written aside: the gravity stage's per-epoch data (the epochs' sums, the kept
//! positions) are kept as they are made, fixed-size records of doubles, and come back a
//! range at a time. Up to [`IN_MEMORY_BYTES`] a spill holds them in memory (a day at 1 Hz
//! needs a few MB, and a file cost a tenth of that day's reduction); beyond, it moves them
//! to an unnamed file in the output folder and goes on there, so that memory holds a block
//! of epochs, not the survey. The file has no name: it is removed when closed, a crash
//! included. It is read at offsets, never through its position, so that two threads may
//! read their blocks from it at once.

use std::borrow::Cow;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::ops::Range;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

/// The most one spill holds in memory before it moves to a file: 16 MB, the widest record
/// (the epochs' sums, 17 doubles) for 34 h at 1 Hz or 3.4 h at 10 Hz. (At 32 MB the 6 h
/// survey at 10 Hz peaked at 149 MB levelled, 51 MB above its flat memory.)
pub(super) const IN_MEMORY_BYTES: usize = 16 << 20;

/// Where a spill's records are.
enum Store {
    /// In memory, one after another.
    Memory(Vec<f64>),
    /// In an unnamed file.
    File(BufWriter<File>),
}

/// Records of `width` doubles being written.
pub(super) struct SpillWriter {
    store: Store,
    dir: PathBuf,
    width: usize,
    len: usize,
}

/// Records of `width` doubles written, read back by range.
pub(super) struct Spill {
    store: Finished,
    width: usize,
    len: usize,
}

/// A finished spill's records.
enum Finished {
    Memory(Vec<f64>),
    File(File),
}

impl SpillWriter {
    /// A spill for records of `width` doubles, its file (when it needs one) in `dir`.
    pub(super) fn new(dir: &Path, width: usize) -> std::io::Result<Self> {
        Ok(SpillWriter {
            store: Store::Memory(Vec::new()),
            dir: dir.to_path_buf(),
            width,
            len: 0,
        })
    }

    /// Appends one record (`width` values).
    pub(super) fn push(&mut self, record: &[f64]) -> std::io::Result<()> {
        debug_assert_eq!(record.len(), self.width);
        if let Store::Memory(v) = &self.store
            && (v.len() + record.len()) * 8 > IN_MEMORY_BYTES
        {
            self.move_to_file()?;
        }
        match &mut self.store {
            Store::Memory(v) => v.extend_from_slice(record),
            Store::File(out) => {
                for v in record {
                    out.write_all(&v.to_le_bytes())?;
                }
            }
        }
        self.len += 1;
        Ok(())
    }

    /// Moves the records held in memory to an unnamed file, where the rest go.
    fn move_to_file(&mut self) -> std::io::Result<()> {
        let mut out = BufWriter::new(tempfile::tempfile_in(&self.dir)?);
        if let Store::Memory(v) = &self.store {
            for x in v {
                out.write_all(&x.to_le_bytes())?;
            }
        }
        self.store = Store::File(out);
        Ok(())
    }

    /// The records written, to read back.
    pub(super) fn finish(self) -> std::io::Result<Spill> {
        let store = match self.store {
            Store::Memory(v) => Finished::Memory(v),
            Store::File(mut out) => {
                out.flush()?;
                Finished::File(out.into_inner().map_err(|e| e.into_error())?)
            }
        };
        Ok(Spill {
            store,
            width: self.width,
            len: self.len,
        })
    }
}

impl Spill {
    /// Records written.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// Whether the records went to a file.
    #[cfg(test)]
    fn in_file(&self) -> bool {
        matches!(self.store, Finished::File(_))
    }

    /// The records `range`, one after another (`width` values each): borrowed from memory,
    /// read from the file.
    pub(super) fn read(&self, range: Range<usize>) -> std::io::Result<Cow<'_, [f64]>> {
        if range.end > self.len || range.start > range.end {
            return Err(std::io::Error::new(
                std::io::ErrorKind::UnexpectedEof,
                format!("records {range:?} of {}", self.len),
            ));
        }
        let file = match &self.store {
            Finished::Memory(v) => {
                return Ok(Cow::Borrowed(
                    &v[range.start * self.width..range.end * self.width],
                ));
            }
            Finished::File(file) => file,
        };
        let bytes_per = self.width * 8;
        let mut bytes = vec![0u8; range.len() * bytes_per];
        // At an offset, not through the file's position: blocks are read on two threads.
        file.read_exact_at(&mut bytes, (range.start * bytes_per) as u64)?;
        Ok(Cow::Owned(
            bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records come back as written, by any range, bit for bit (a NaN and -0 too), from
    /// memory and, past [`IN_MEMORY_BYTES`], from the file the spill moved to.
    #[test]
    fn records_come_back_by_range() {
        let small = IN_MEMORY_BYTES / 24;
        for (n, in_file) in [(1000, false), (small + 1000, true)] {
            records_come_back(n, in_file);
        }
    }

    fn records_come_back(n: usize, in_file: bool) {
        let dir = tempfile::tempdir().expect("dir");
        let mut w = SpillWriter::new(dir.path(), 3).expect("spill");
        let rows: Vec<[f64; 3]> = (0..u32::try_from(n).expect("u32"))
            .map(f64::from)
            .map(|k| [k, -0.0, if k % 7.0 == 0.0 { f64::NAN } else { 1.0 / k }])
            .collect();
        for r in &rows {
            w.push(r).expect("pushed");
        }
        let s = w.finish().expect("finished");
        assert_eq!(s.len(), rows.len());
        assert_eq!(s.in_file(), in_file);
        let n = rows.len();
        for range in [0..0, 0..1, 3..17, n - 10..n, 0..n] {
            let got = s.read(range.clone()).expect("read");
            let want: Vec<f64> = rows[range].iter().flatten().copied().collect();
            assert_eq!(got.len(), want.len());
            assert!(
                got.iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
        assert!(s.read(n - 1..n + 1).is_err());
        // Two threads reading their ranges at once each get their own records.
        let ranges = [0..n / 2, n / 3..n, 5..n - 5];
        std::thread::scope(|scope| {
            for t in 0..2 {
                let (s, rows, ranges) = (&s, &rows, &ranges);
                scope.spawn(move || {
                    for k in 0..30 {
                        let range = ranges[(k + t) % ranges.len()].clone();
                        let got = s.read(range.clone()).expect("read");
                        let want = rows[range].iter().flatten();
                        assert!(
                            got.iter()
                                .zip(want)
                                .all(|(a, b)| a.to_bits() == b.to_bits())
                        );
                    }
                });
            }
        });
    }
}
