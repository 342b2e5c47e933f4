//! Parquet's DELTA_BINARY_PACKED value encoding and the RLE / bit-packed hybrid for
//! definition levels, written by ingest itself for the sample streams' integer columns.
//!
//! parquet-rs's own delta encoder took a quarter of ingest's CPU time on a 250 Hz day
//! (`perf record`). This one takes the deltas of a block in lanes of the type's own width
//! and packs each miniblock with a loop specialised to its bit width;
//! `cargo run --release -p ingest --example delta_speed` times it alone (about 1.5-2.5 ns a
//! count here). Both follow the format spec
//! (<https://parquet.apache.org/docs/file-format/data-pages/encodings/>);
//! `tests/delta_columns.rs` reads what is written here back through parquet-rs.

/// Values per block, and miniblocks per block: 128 and 4, as parquet-rs and parquet-java
/// write them (32 values per miniblock).
const BLOCK: usize = 128;
const MINIBLOCKS: usize = 4;
const MINI: usize = BLOCK / MINIBLOCKS;

/// An integer type Parquet delta-encodes (INT32 or INT64): deltas are taken in the type's
/// own width, wrapping, as the spec asks, so that the work is done in lanes of that width.
pub trait DeltaValue: Copy {
    /// The value as i64 (sign-extended).
    fn widen(self) -> i64;
    /// Appends the blocks of the deltas from `first` through `rest`.
    fn put_blocks(first: Self, rest: &[Self], out: &mut Vec<u8>);
}

/// [`DeltaValue`] for `$int`, packing `$uint`s with `$packers`.
macro_rules! delta_value {
    ($int:ty, $uint:ty, $packers:ident) => {
        impl DeltaValue for $int {
            #[inline(always)]
            fn widen(self) -> i64 {
                i64::from(self)
            }

            fn put_blocks(first: Self, rest: &[Self], out: &mut Vec<u8>) {
                let mut prev = first;
                let mut packed: [$uint; BLOCK] = [0; BLOCK];
                for block in rest.chunks(BLOCK) {
                    let n = block.len();
                    // The first delta from the value before the block, the others within it:
                    // no chain from one value to the next, so the loops vectorise.
                    let mut deltas: [$int; BLOCK] = [0; BLOCK];
                    deltas[0] = block[0].wrapping_sub(prev);
                    for (d, w) in deltas[1..].iter_mut().zip(block.windows(2)) {
                        *d = w[1].wrapping_sub(w[0]);
                    }
                    prev = block[n - 1];
                    let deltas = &deltas[..n];
                    let min = deltas.iter().fold(<$int>::MAX, |m, &d| m.min(d));
                    put_zigzag(out, i64::from(min));
                    // Relative to the minimum: what is packed. Unused slots pack as 0.
                    for (p, &d) in packed.iter_mut().zip(deltas) {
                        *p = d.wrapping_sub(min) as $uint;
                    }
                    packed[n..].fill(0);
                    let used = n.div_ceil(MINI);
                    let mut widths = [0u8; MINIBLOCKS];
                    for (w, mini) in widths.iter_mut().zip(packed.chunks_exact(MINI)).take(used) {
                        let any = mini.iter().fold(0, |a, &p| a | p);
                        *w = (<$uint>::BITS - any.leading_zeros()) as u8;
                    }
                    out.extend_from_slice(&widths);
                    let mut bytes = [0u8; 4 * 64];
                    for (&w, mini) in widths.iter().zip(packed.chunks_exact(MINI)).take(used) {
                        let mini = mini.try_into().expect("chunks of MINI");
                        $packers[usize::from(w)](mini, &mut bytes);
                        out.extend_from_slice(&bytes[..4 * usize::from(w)]);
                    }
                }
            }
        }
    };
}

delta_value!(i32, u32, PACKERS_32);
delta_value!(i64, u64, PACKERS_64);

/// Appends `values` in Parquet's BYTE_STREAM_SPLIT encoding: eight streams, the k-th
/// holding byte k (little-endian) of every value in order. Eight values at a time: their
/// 8 x 8 bytes transposed in registers by three rounds of swapping blocks (4 x 4, 2 x 2,
/// then single bytes), so that each stream is written a word at a time.
pub fn put_byte_stream_split(values: &[f64], out: &mut Vec<u8>) {
    let n = values.len();
    let start = out.len();
    out.resize(start + 8 * n, 0);
    let streams = &mut out[start..];
    let whole = n - n % 8;
    for (block, chunk) in values[..whole].chunks_exact(8).enumerate() {
        let mut r: [u64; 8] = std::array::from_fn(|i| chunk[i].to_bits());
        for i in 0..4 {
            let t = ((r[i] >> 32) ^ r[i + 4]) & 0x0000_0000_ffff_ffff;
            r[i] ^= t << 32;
            r[i + 4] ^= t;
        }
        for i in [0, 1, 4, 5] {
            let t = ((r[i] >> 16) ^ r[i + 2]) & 0x0000_ffff_0000_ffff;
            r[i] ^= t << 16;
            r[i + 2] ^= t;
        }
        for i in [0, 2, 4, 6] {
            let t = ((r[i] >> 8) ^ r[i + 1]) & 0x00ff_00ff_00ff_00ff;
            r[i] ^= t << 8;
            r[i + 1] ^= t;
        }
        for (k, word) in r.iter().enumerate() {
            let at = k * n + 8 * block;
            streams[at..at + 8].copy_from_slice(&word.to_le_bytes());
        }
    }
    for (i, v) in values.iter().enumerate().skip(whole) {
        for (k, b) in v.to_le_bytes().into_iter().enumerate() {
            streams[k * n + i] = b;
        }
    }
}

/// Appends `v` as an unsigned LEB128 varint.
fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Appends `v` zigzag-encoded as a varint.
fn put_zigzag(out: &mut Vec<u8>, v: i64) {
    put_varint(out, ((v << 1) ^ (v >> 63)) as u64);
}

/// Appends `values` DELTA_BINARY_PACKED-encoded: the header (block size, miniblocks per
/// block, value count, first value), then per block of 128 deltas its minimum delta, the
/// bit width of each of its 4 miniblocks and the miniblocks packed LSB first. A last block
/// that is not full has the widths of its unused miniblocks 0 and its last used miniblock
/// padded with zeros.
pub fn put_delta<T: DeltaValue>(values: &[T], out: &mut Vec<u8>) {
    put_varint(out, BLOCK as u64);
    put_varint(out, MINIBLOCKS as u64);
    put_varint(out, values.len() as u64);
    let Some((&first, rest)) = values.split_first() else {
        put_zigzag(out, 0);
        return;
    };
    put_zigzag(out, first.widen());
    // At most: per block a min delta and 4 widths, per value the type's width.
    out.reserve(rest.len().div_ceil(BLOCK) * (10 + MINIBLOCKS) + size_of_val(rest));
    T::put_blocks(first, rest, out);
}

/// Packs 32 values of `W` bits each (at most 32), LSB first, into the first `4 * W` bytes of
/// `out`. With the width a constant the compiler unrolls the loop and resolves every shift.
#[inline(always)]
fn pack_32<const W: u32>(values: &[u32; MINI], out: &mut [u8; 4 * 64]) {
    let mut acc: u64 = 0;
    let mut bits = 0;
    let mut o = 0;
    for &v in values {
        acc |= u64::from(v) << bits;
        bits += W;
        if bits >= 32 {
            out[o..o + 4].copy_from_slice(&(acc as u32).to_le_bytes());
            o += 4;
            acc >>= 32;
            bits -= 32;
        }
    }
}

/// [`pack_32`] for values of up to 64 bits.
#[inline(always)]
fn pack_64<const W: u32>(values: &[u64; MINI], out: &mut [u8; 4 * 64]) {
    let mut acc: u128 = 0;
    let mut bits = 0;
    let mut o = 0;
    for &v in values {
        acc |= u128::from(v) << bits;
        bits += W;
        if bits >= 64 {
            out[o..o + 8].copy_from_slice(&(acc as u64).to_le_bytes());
            o += 8;
            acc >>= 64;
            bits -= 64;
        }
    }
    // 32 * W bits: whole 64-bit words and, for an odd width, half of one more.
    if bits > 0 {
        out[o..o + 4].copy_from_slice(&(acc as u32).to_le_bytes());
    }
}

type Packer<U> = fn(&[U; MINI], &mut [u8; 4 * 64]);

macro_rules! packers {
    ($pack:ident, $u:ty, $($w:literal)*) => { [$($pack::<$w> as Packer<$u>),*] };
}

/// [`pack_32`] for each width 0..=32.
const PACKERS_32: [Packer<u32>; 33] = packers!(pack_32, u32,
    0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
);

/// [`pack_64`] for each width 0..=64.
const PACKERS_64: [Packer<u64>; 65] = packers!(pack_64, u64,
    0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32
    33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59 60 61 62
    63 64
);

/// Appends definition levels of a column with maximum level 1 (0 = null, 1 = value) as a
/// version 1 data page stores them: a 4-byte little-endian length, then the RLE /
/// bit-packed hybrid with bit width 1. Levels are taken in groups of 8: runs of two or
/// more whole groups of one value become RLE runs, other groups are bit-packed; the last
/// group, if shorter than 8, is an RLE run if it holds one value and is bit-packed, padded
/// with zeros, if not (a reader stops at the page's value count).
///
/// Levels other than 0 and 1 are read as 1 where odd; the caller checks them.
pub fn put_levels(levels: &[i16], out: &mut Vec<u8>) {
    if let Some(&first) = levels.first()
        && levels.iter().all(|&l| l == first)
    {
        // One value throughout (as nearly always): a single RLE run.
        put_level_run(levels.len(), (first & 1) as u8, out);
        return;
    }
    let start = out.len();
    out.extend_from_slice(&[0; 4]);
    let mut hybrid = Hybrid::default();
    let mut groups = levels.chunks_exact(8);
    // The bits of each whole group, and whether it is uniform.
    let bytes: Vec<u8> = groups
        .by_ref()
        .map(|g| {
            g.iter()
                .enumerate()
                .fold(0u8, |b, (i, &l)| b | (((l & 1) as u8) << i))
        })
        .collect();
    let uniform = |b: u8| b == 0 || b == 0xff;
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        let mut j = i + 1;
        if uniform(b) {
            while j < bytes.len() && bytes[j] == b {
                j += 1;
            }
        }
        if uniform(b) && (j - i >= 2 || hybrid.rle_value == Some(b & 1)) {
            hybrid.rle(out, b & 1, 8 * (j - i));
        } else {
            hybrid.packed(out, b);
            j = i + 1;
        }
        i = j;
    }
    let tail = groups.remainder();
    if let Some(&first) = tail.first() {
        let v = (first & 1) as u8;
        if tail.iter().all(|&l| (l & 1) as u8 == v) {
            hybrid.rle(out, v, tail.len());
        } else {
            let b = tail
                .iter()
                .enumerate()
                .fold(0u8, |b, (i, &l)| b | (((l & 1) as u8) << i));
            hybrid.packed(out, b);
        }
    }
    hybrid.finish(out);
    let len = (out.len() - start - 4) as u32;
    out[start..start + 4].copy_from_slice(&len.to_le_bytes());
}

/// Appends the definition levels of `n` rows that all have a value, as [`put_levels`]
/// would: one RLE run.
pub fn put_all_defined(n: usize, out: &mut Vec<u8>) {
    put_level_run(n, 1, out);
}

/// Appends `n` levels of `value` (0 or 1), with their length: one RLE run.
fn put_level_run(n: usize, value: u8, out: &mut Vec<u8>) {
    let start = out.len();
    out.extend_from_slice(&[0; 4]);
    put_varint(out, (n as u64) << 1);
    out.push(value);
    let len = (out.len() - start - 4) as u32;
    out[start..start + 4].copy_from_slice(&len.to_le_bytes());
}

/// The run being built by [`put_levels`]: an RLE run (value and count) or bit-packed groups.
#[derive(Default)]
struct Hybrid {
    rle_value: Option<u8>,
    rle_count: usize,
    packed: Vec<u8>,
}

impl Hybrid {
    fn rle(&mut self, out: &mut Vec<u8>, value: u8, count: usize) {
        if self.rle_value != Some(value) {
            self.finish(out);
            self.rle_value = Some(value);
        }
        self.rle_count += count;
    }

    fn packed(&mut self, out: &mut Vec<u8>, bits: u8) {
        if self.rle_value.is_some() {
            self.finish(out);
        }
        self.packed.push(bits);
    }

    /// Writes the run being built.
    fn finish(&mut self, out: &mut Vec<u8>) {
        if let Some(v) = self.rle_value.take() {
            put_varint(out, (self.rle_count as u64) << 1);
            out.push(v);
            self.rle_count = 0;
        } else if !self.packed.is_empty() {
            put_varint(out, ((self.packed.len() as u64) << 1) | 1);
            out.append(&mut self.packed);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The transposition in registers is the format's byte k of value i at k n + i, after
    /// what the buffer held, for every length around the block of eight.
    #[test]
    fn byte_stream_split_is_the_format() {
        for n in 0..40 {
            let values: Vec<f64> = (0..n)
                .map(|i| f64::from_bits(0x0123_4567_89ab_cdefu64.rotate_left(7 * i as u32)))
                .collect();
            let mut out = vec![0xaa];
            put_byte_stream_split(&values, &mut out);
            let mut expected = vec![0xaa; 1 + 8 * n];
            for (i, v) in values.iter().enumerate() {
                for (k, b) in v.to_le_bytes().into_iter().enumerate() {
                    expected[1 + k * n + i] = b;
                }
            }
            assert_eq!(out, expected, "{n} values");
        }
    }

    #[test]
    fn varints_and_zigzag() {
        let mut out = Vec::new();
        put_varint(&mut out, 300);
        assert_eq!(out, [0xac, 0x02]);
        out.clear();
        for v in [0, -1, 1, -2, i64::MIN, i64::MAX] {
            put_zigzag(&mut out, v);
        }
        assert_eq!(&out[..4], [0, 1, 2, 3]);
        assert_eq!(out.len(), 4 + 10 + 10);
    }

    /// The example of the format spec: 1..=5 is a header, min delta 1 and widths 0.
    #[test]
    fn delta_of_the_spec_example() {
        let mut out = Vec::new();
        put_delta(&[1i32, 2, 3, 4, 5], &mut out);
        assert_eq!(out, [128, 1, 4, 5, 2, 2, 0, 0, 0, 0]);
    }

    #[test]
    fn miniblock_packing_is_lsb_first() {
        let mut out = [0u8; 256];
        let values: [u64; 32] = std::array::from_fn(|i| i as u64 % 8);
        PACKERS_64[3](&values, &mut out);
        let narrow: [u32; 32] = values.map(|v| v as u32);
        let mut out32 = [0u8; 256];
        PACKERS_32[3](&narrow, &mut out32);
        assert_eq!(out32[..12], out[..12]);
        // 0,1,2,3,4,5,6,7 in 3 bits each: 0b_111_110_101_100_011_010_001_000.
        assert_eq!(&out[..3], [0b1000_1000, 0b1100_0110, 0b1111_1010]);
        assert_eq!(&out[..12], [&out[..3]; 4].concat());
        // 64 bits: the values as they are.
        let values: [u64; 32] = std::array::from_fn(|i| u64::MAX - i as u64);
        PACKERS_64[64](&values, &mut out);
        assert_eq!(&out[248..], (u64::MAX - 31).to_le_bytes());
    }

    #[test]
    fn levels_hybrid_runs() {
        let mut out = Vec::new();
        put_levels(&[1; 20], &mut out);
        assert_eq!(out, [2, 0, 0, 0, 40, 1]);
        out.clear();
        put_all_defined(20, &mut out);
        assert_eq!(out, [2, 0, 0, 0, 40, 1]);
        out.clear();
        put_levels(&[1, 0, 1], &mut out);
        assert_eq!(out, [2, 0, 0, 0, 3, 0b101]);
        out.clear();
        // 16 ones, then 8 mixed, then 3 zeros.
        let mut l = vec![1; 16];
        l.extend([0, 1, 0, 1, 0, 1, 0, 1]);
        l.extend([0; 3]);
        put_levels(&l, &mut out);
        assert_eq!(out, [6, 0, 0, 0, 32, 1, 3, 0b1010_1010, 6, 0]);
    }
}
