//! Records written aside: the gravity stage's per-epoch data (the epochs' sums, the kept
//! positions) go to an unnamed file in the output folder as they are made, fixed-size
//! records of doubles, and come back a range at a time, so that memory holds a block of
//! epochs, not the survey. The file has no name: it is removed when closed, a crash
//! included.

use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::Path;

/// Records of `width` doubles being written.
pub(super) struct SpillWriter {
    out: BufWriter<File>,
    width: usize,
    len: usize,
}

/// Records of `width` doubles written, read back by range.
pub(super) struct Spill {
    file: File,
    width: usize,
    len: usize,
}

impl SpillWriter {
    /// An unnamed file in `dir` for records of `width` doubles.
    pub(super) fn new(dir: &Path, width: usize) -> std::io::Result<Self> {
        Ok(SpillWriter {
            out: BufWriter::new(tempfile::tempfile_in(dir)?),
            width,
            len: 0,
        })
    }

    /// Appends one record (`width` values).
    pub(super) fn push(&mut self, record: &[f64]) -> std::io::Result<()> {
        debug_assert_eq!(record.len(), self.width);
        for v in record {
            self.out.write_all(&v.to_le_bytes())?;
        }
        self.len += 1;
        Ok(())
    }

    /// The records written, to read back.
    pub(super) fn finish(mut self) -> std::io::Result<Spill> {
        self.out.flush()?;
        let file = self.out.into_inner().map_err(|e| e.into_error())?;
        Ok(Spill {
            file,
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

    /// The records `range`, one after another (`width` values each).
    pub(super) fn read(&self, range: Range<usize>) -> std::io::Result<Vec<f64>> {
        let bytes_per = self.width * 8;
        let mut bytes = vec![0u8; range.len() * bytes_per];
        let mut f = &self.file;
        f.seek(SeekFrom::Start((range.start * bytes_per) as u64))?;
        f.read_exact(&mut bytes)?;
        Ok(bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Records come back as written, by any range, bit for bit (a NaN and -0 too).
    #[test]
    fn records_come_back_by_range() {
        let dir = tempfile::tempdir().expect("dir");
        let mut w = SpillWriter::new(dir.path(), 3).expect("spill");
        let rows: Vec<[f64; 3]> = (0..1000_u32)
            .map(f64::from)
            .map(|k| [k, -0.0, if k % 7.0 == 0.0 { f64::NAN } else { 1.0 / k }])
            .collect();
        for r in &rows {
            w.push(r).expect("pushed");
        }
        let s = w.finish().expect("finished");
        assert_eq!(s.len(), 1000);
        for range in [0..0, 0..1, 3..17, 990..1000, 0..1000] {
            let got = s.read(range.clone()).expect("read");
            let want: Vec<f64> = rows[range].iter().flatten().copied().collect();
            assert_eq!(got.len(), want.len());
            assert!(
                got.iter()
                    .zip(&want)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
            );
        }
        assert!(s.read(999..1001).is_err());
    }
}
