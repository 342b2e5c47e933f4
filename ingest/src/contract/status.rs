//! The status bits of a sample (docs/formats.md section 3), as logged in a binary frame and as
//! stored in the `status` column of the stream tables: bit n-1 (n = 1..3) is channel n over
//! range, bit n+3 channel n not connected; bits 3 and 7 are reserved.

/// Status bit: channel `ch` (0-based) over range (saturated).
pub const fn over_range_bit(ch: usize) -> u8 {
    1 << ch
}

/// Status bit: channel `ch` (0-based) not connected (its value is meaningless).
pub const fn not_connected_bit(ch: usize) -> u8 {
    1 << (ch + 4)
}

/// Bits that must be 0.
pub const RESERVED_BITS: u8 = 0b1000_1000;

/// Whether channel `ch` (0-based) is flagged not connected in `status`.
pub const fn not_connected(status: u8, ch: usize) -> bool {
    status & not_connected_bit(ch) != 0
}

/// Whether channel `ch` (0-based) is flagged over range in `status`.
pub const fn over_range(status: u8, ch: usize) -> bool {
    status & over_range_bit(ch) != 0
}
