//! Compression of a blink ROI's photon counts: one adaptive Rice code per ROI.
//!
//! The counts of an ROI are small non-negative integers (a few background
//! counts per pixel plus a PSF bump), so they are coded as their offset from
//! the ROI's minimum with a Golomb–Rice code whose parameter is chosen per ROI.
//! The scheme is meant for a hardware packetiser: every choice is a sum of
//! small per-count lengths that can be computed while the counts stream by.
//!
//! # Layout of a count block (normative, see also `model/PACKETS.md`)
//!
//! 1. `base`: the minimum count of the ROI, as an unsigned LEB128 varint
//!    (7 value bits per byte, least significant group first, bit 7 set on
//!    every byte but the last; 1 to 5 bytes, the 5th byte ≤ `0x0F` so that
//!    the value is < 2³², and the last byte of a multi-byte varint is not
//!    `0x00`, a redundant trailing group).
//! 2. `k`: one byte, the Rice parameter, `0..=31`.
//! 3. Every count `c`, in row-major order, as the Rice code of `d = c − base`:
//!    * `q = d >> k`. If `q < 32`: `q` one-bits, one zero-bit, then the `k`
//!      low bits of `d`, most significant first (`q + 1 + k` bits).
//!    * If `q ≥ 32` (escape): 32 one-bits, then `d` as 32 bits, most
//!      significant first (64 bits, no terminating zero).
//!
//!    Bits are packed most-significant-bit first into bytes; the last byte is
//!    padded with zero bits. The block ends with that byte.
//!
//! The encoder chooses `k` as the value in `0..=31` that minimises the total
//! number of code bits (sum over the counts of the lengths above); ties go to
//! the smallest `k`. A hardware packetiser keeps 32 length accumulators, one
//! per `k`, while the counts stream in: each code is at most 64 bits, so for
//! R ≤ 31 (961 counts) every accumulator fits in 16 bits (961 × 64 = 61 504).
//!
//! # Worst case
//!
//! With `k = 31` no count escapes (`d >> 31 ≤ 1`), so every code is at most
//! 33 bits; the chosen `k` can only be shorter. A block of `n` counts is
//! therefore at most `5 + 1 + ⌈33·n/8⌉` bytes ([`max_encoded_len`]): 3 971
//! bytes for a 31 × 31 ROI, whatever the counts.
//!
//! # Decoding
//!
//! [`decode_counts`] rejects, with an error and without panicking: a
//! truncated block, a varint that is overlong or exceeds `u32`, `k > 31`, an
//! escape whose value would have had a regular code (so every accepted block
//! re-encodes to itself when `base` and `k` are the encoder's choices), a
//! count that overflows `u32`, non-zero padding bits and bytes after the
//! padding. It allocates only the `n` counts it was asked for. It accepts any
//! `base` no larger than the counts and any `k`, so it does not depend on the
//! encoder's choice of either.

use thiserror::Error;

/// Largest Rice parameter.
pub const MAX_K: u8 = 31;

/// Unary quotients at or above this value are written as an escape.
pub const ESCAPE_Q: u32 = 32;

/// Bits of an escaped code: [`ESCAPE_Q`] one-bits and the raw 32-bit offset.
pub const ESCAPE_BITS: u32 = ESCAPE_Q + 32;

/// Longest LEB128 varint of a `u32`, bytes.
pub const MAX_VARINT_LEN: usize = 5;

/// A count block that cannot be decoded.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RiceError {
    /// The block ended inside the varint, the `k` byte or a code.
    #[error("count block truncated: ended while reading {what}")]
    Truncated {
        /// What was being read.
        what: &'static str,
    },
    /// The base varint has more than 5 bytes, encodes more than 32 bits, or
    /// has a redundant trailing group.
    #[error("base varint is malformed ({why})")]
    BadVarint {
        /// Why it is rejected.
        why: &'static str,
    },
    /// The Rice parameter is larger than [`MAX_K`].
    #[error("Rice parameter k = {0} is larger than 31")]
    BadK(u8),
    /// An escaped offset small enough to have had a regular code.
    #[error(
        "count {index}: escape code for offset {offset}, which has a regular code with k = {k}"
    )]
    NonCanonicalEscape {
        /// Index of the count in row-major order.
        index: usize,
        /// The escaped offset.
        offset: u32,
        /// The block's Rice parameter.
        k: u8,
    },
    /// `base + offset` does not fit in 32 bits.
    #[error("count {index}: base {base} + offset {offset} exceeds 2^32 - 1")]
    CountOverflow {
        /// Index of the count in row-major order.
        index: usize,
        /// The block's base.
        base: u32,
        /// The decoded offset.
        offset: u64,
    },
    /// Padding bits after the last code are not zero.
    #[error("padding bits after the last count are not zero")]
    NonZeroPadding,
    /// Bytes follow the padded last byte.
    #[error("{0} byte(s) of trailing data after the last count")]
    TrailingBytes(usize),
}

/// Length in bits of the code of offset `d` with parameter `k`.
pub fn code_len(d: u32, k: u8) -> u32 {
    let q = d >> k;
    if q < ESCAPE_Q {
        q + 1 + k as u32
    } else {
        ESCAPE_BITS
    }
}

/// Total code bits of `counts` coded against `base` with parameter `k`.
///
/// Every count must be at least `base`.
pub fn total_bits(counts: &[u32], base: u32, k: u8) -> u64 {
    counts.iter().map(|&c| code_len(c - base, k) as u64).sum()
}

/// The encoder's choice: `(base, k, code bits)` for `counts`.
///
/// `base` is the minimum (0 for an empty slice); `k` minimises the code bits,
/// the smallest `k` winning ties.
pub fn choose(counts: &[u32]) -> (u32, u8, u64) {
    let base = counts.iter().copied().min().unwrap_or(0);
    let mut best = (0u8, u64::MAX);
    for k in 0..=MAX_K {
        let bits = total_bits(counts, base, k);
        if bits < best.1 {
            best = (k, bits);
        }
    }
    (base, best.0, best.1)
}

/// Bytes of `value` as an unsigned LEB128 varint.
pub fn varint_len(value: u32) -> usize {
    let bits = 32 - value.leading_zeros() as usize;
    bits.div_ceil(7).max(1)
}

/// Exact length in bytes of the block [`encode_counts`] writes for `counts`.
pub fn encoded_len(counts: &[u32]) -> usize {
    let (base, _, bits) = choose(counts);
    varint_len(base) + 1 + bits.div_ceil(8) as usize
}

/// Upper bound of the block length for `n` counts, whatever their values.
pub fn max_encoded_len(n: usize) -> usize {
    MAX_VARINT_LEN + 1 + (33 * n).div_ceil(8)
}

/// MSB-first bit packer.
struct BitWriter<'a> {
    out: &'a mut Vec<u8>,
    acc: u64,
    nbits: u32,
}

impl<'a> BitWriter<'a> {
    fn new(out: &'a mut Vec<u8>) -> Self {
        BitWriter {
            out,
            acc: 0,
            nbits: 0,
        }
    }

    /// Appends the `n` (≤ 32) low bits of `value`, most significant first.
    fn put(&mut self, value: u32, n: u32) {
        debug_assert!(n <= 32);
        if n == 0 {
            return;
        }
        let v = (value as u64) & ((1u64 << n) - 1);
        self.acc = (self.acc << n) | v;
        self.nbits += n;
        while self.nbits >= 8 {
            self.nbits -= 8;
            self.out.push((self.acc >> self.nbits) as u8);
        }
        // Keep only the bits not yet written so the shift above never overflows.
        self.acc &= (1u64 << self.nbits) - 1;
    }

    /// Appends `n` one-bits.
    fn ones(&mut self, mut n: u32) {
        while n > 0 {
            let m = n.min(32);
            self.put(u32::MAX, m);
            n -= m;
        }
    }

    /// Writes the last, zero-padded byte.
    fn finish(self) {
        if self.nbits > 0 {
            self.out.push((self.acc << (8 - self.nbits)) as u8);
        }
    }
}

/// Appends the count block of `counts` (layout in the module docs) to `out`.
pub fn encode_counts(counts: &[u32], out: &mut Vec<u8>) {
    let (base, k, bits) = choose(counts);
    out.reserve(varint_len(base) + 1 + bits.div_ceil(8) as usize);
    let mut v = base;
    loop {
        let group = (v & 0x7F) as u8;
        v >>= 7;
        if v == 0 {
            out.push(group);
            break;
        }
        out.push(group | 0x80);
    }
    out.push(k);
    let mut w = BitWriter::new(out);
    for &c in counts {
        let d = c - base;
        let q = d >> k;
        if q < ESCAPE_Q {
            w.ones(q);
            w.put(0, 1);
            w.put(d, k as u32);
        } else {
            w.ones(ESCAPE_Q);
            w.put(d, 32);
        }
    }
    w.finish();
}

/// MSB-first bit reader over a byte slice: a 64-bit window refilled a byte
/// at a time, its valid bits left-aligned.
struct BitReader<'a> {
    bytes: &'a [u8],
    /// Next byte to load into the window.
    next: usize,
    window: u64,
    /// Valid bits in the window.
    n: u32,
}

impl<'a> BitReader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        BitReader {
            bytes,
            next: 0,
            window: 0,
            n: 0,
        }
    }

    /// Fills the window to at least 57 bits, or with every remaining byte.
    fn refill(&mut self) {
        while self.n <= 56 && self.next < self.bytes.len() {
            self.window |= (self.bytes[self.next] as u64) << (56 - self.n);
            self.n += 8;
            self.next += 1;
        }
    }

    fn consume(&mut self, bits: u32) {
        debug_assert!(bits <= self.n && bits < 64);
        self.window <<= bits;
        self.n -= bits;
    }

    /// The unary part: the number of leading one-bits, at most [`ESCAPE_Q`],
    /// with the terminating zero consumed when there is one.
    fn unary(&mut self) -> Option<u32> {
        self.refill();
        let ones = self.window.leading_ones().min(self.n);
        if ones >= ESCAPE_Q {
            self.consume(ESCAPE_Q);
            Some(ESCAPE_Q)
        } else if ones < self.n {
            self.consume(ones + 1);
            Some(ones)
        } else {
            None
        }
    }

    /// The next `k` (≤ 32) bits as an integer.
    fn bits(&mut self, k: u32) -> Option<u32> {
        if k == 0 {
            return Some(0);
        }
        self.refill();
        if self.n < k {
            return None;
        }
        let v = (self.window >> (64 - k)) as u32;
        self.consume(k);
        Some(v)
    }

    /// Bits consumed so far.
    fn position(&self) -> usize {
        self.next * 8 - self.n as usize
    }
}

/// Decodes a count block that must hold exactly `n` counts and nothing else.
///
/// Never panics; allocates `n` counts (callers bound `n`).
pub fn decode_counts(block: &[u8], n: usize) -> Result<Vec<u32>, RiceError> {
    // base varint
    let mut base: u64 = 0;
    let mut i = 0;
    loop {
        let &byte = block.get(i).ok_or(RiceError::Truncated {
            what: "the base varint",
        })?;
        if i == MAX_VARINT_LEN - 1 && byte > 0x0F {
            return Err(RiceError::BadVarint {
                why: "more than 32 bits",
            });
        }
        base |= ((byte & 0x7F) as u64) << (7 * i);
        i += 1;
        if byte & 0x80 == 0 {
            if i > 1 && byte == 0 {
                return Err(RiceError::BadVarint {
                    why: "redundant trailing zero group",
                });
            }
            break;
        }
    }
    let base = base as u32;
    let &k = block.get(i).ok_or(RiceError::Truncated {
        what: "the Rice parameter k",
    })?;
    if k > MAX_K {
        return Err(RiceError::BadK(k));
    }
    let codes = &block[i + 1..];
    let mut r = BitReader::new(codes);
    let truncated = RiceError::Truncated {
        what: "a count code",
    };
    let mut counts = Vec::with_capacity(n);
    for index in 0..n {
        let q = r.unary().ok_or(truncated.clone())?;
        let offset: u64 = if q == ESCAPE_Q {
            let d = r.bits(32).ok_or(truncated.clone())?;
            if d >> k < ESCAPE_Q {
                return Err(RiceError::NonCanonicalEscape {
                    index,
                    offset: d,
                    k,
                });
            }
            d as u64
        } else {
            let low = r.bits(k as u32).ok_or(truncated.clone())?;
            ((q as u64) << k) | low as u64
        };
        let c = base as u64 + offset;
        if c > u32::MAX as u64 {
            return Err(RiceError::CountOverflow {
                index,
                base,
                offset,
            });
        }
        counts.push(c as u32);
    }
    // Padding: the rest of the current byte must be zero, then nothing more.
    let pad = ((8 - r.position() % 8) % 8) as u32;
    if pad > 0 && r.bits(pad) != Some(0) {
        return Err(RiceError::NonZeroPadding);
    }
    let rest = codes.len() - r.position() / 8;
    if rest > 0 {
        return Err(RiceError::TrailingBytes(rest));
    }
    Ok(counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_block() {
        // base 2, offsets 0,1,5,2: k = 0 needs 1+2+6+3 = 12 bits, k = 1
        // needs 2+2+4+3 = 11, k = 2 needs 13.
        assert_eq!(choose(&[2, 3, 7, 4]), (2, 1, 11));
        let mut out = Vec::new();
        encode_counts(&[2, 3, 7, 4], &mut out);
        // k = 1: 0|0 0|1 110|1 10|0 -> 0001 1101 100 + 5 padding zeros
        assert_eq!(out, vec![0x02, 0x01, 0x1D, 0x80]);
        assert_eq!(decode_counts(&out, 4).unwrap(), vec![2, 3, 7, 4]);
    }

    #[test]
    fn extremes_round_trip_and_fit_the_bound() {
        let cases: Vec<Vec<u32>> = vec![
            vec![],
            vec![0],
            vec![u32::MAX; 961],
            (0..961)
                .map(|i| if i % 2 == 0 { 0 } else { u32::MAX })
                .collect(),
            (0..961u32).map(|i| i.wrapping_mul(2_654_435_761)).collect(),
            (0..961u32)
                .map(|i| if i == 480 { 1 << 20 } else { 3 })
                .collect(),
        ];
        for counts in cases {
            let mut out = Vec::new();
            encode_counts(&counts, &mut out);
            assert_eq!(out.len(), encoded_len(&counts));
            assert!(out.len() <= max_encoded_len(counts.len()));
            assert_eq!(decode_counts(&out, counts.len()).unwrap(), counts);
        }
    }

    #[test]
    fn rejects_malformed_blocks() {
        let mut out = Vec::new();
        encode_counts(&[5, 6, 9, 5], &mut out);
        assert!(matches!(
            decode_counts(&out[..out.len() - 1], 4),
            Err(RiceError::Truncated { .. })
        ));
        let mut trailing = out.clone();
        trailing.push(0);
        assert_eq!(
            decode_counts(&trailing, 4),
            Err(RiceError::TrailingBytes(1))
        );
        let mut bad_k = out.clone();
        bad_k[1] = 32;
        assert_eq!(decode_counts(&bad_k, 4), Err(RiceError::BadK(32)));
        assert!(matches!(
            decode_counts(&[0x80, 0x00, 0x00], 1),
            Err(RiceError::BadVarint { .. })
        ));
        assert!(matches!(
            decode_counts(&[0xFF, 0xFF, 0xFF, 0xFF, 0x1F, 0x00, 0x00], 1),
            Err(RiceError::BadVarint { .. })
        ));
        // Non-zero padding: one count 0 with k = 0 is the single bit 0.
        assert_eq!(
            decode_counts(&[0x00, 0x00, 0x01], 1),
            Err(RiceError::NonZeroPadding)
        );
        // base 2^32-1 and offset 1 overflow.
        assert!(matches!(
            decode_counts(&[0xFF, 0xFF, 0xFF, 0xFF, 0x0F, 0x00, 0x80], 1),
            Err(RiceError::CountOverflow { .. })
        ));
        // Escape of offset 0 with k = 0 is not canonical.
        assert!(matches!(
            decode_counts(&[0x00, 0x00, 0xFF, 0xFF, 0xFF, 0xFF, 0, 0, 0, 0], 1),
            Err(RiceError::NonCanonicalEscape { .. })
        ));
    }
}
