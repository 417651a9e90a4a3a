//! The tracker's widths and word layouts, shared by the tracker and its
//! sub-blocks (a file that imports nothing of theirs, so that no two
//! files of the tracker import each other).

use crate::config::{BackHalfConfig, GatewareError};

/// Bits of a slot's ages (`age` and `dage`, and of the L_min, L_max and
/// N − end_trim they are compared with): they stay below
/// L_max,max + 2·N_max + 2 (a segment is cut at L_max, completes at most N
/// planes after its drop, and the stream end adds N drain planes), which
/// [`BlinkTracker::new`](super::BlinkTracker::new) checks against 2^18
/// (`fits`).
/// (`update` writes the width as the literal 18 where rust-hdl's `hdl_gen`
/// needs a number; the signal types make the compiler check the two agree.)
pub const AGE_BITS: usize = 18;

/// Bits of the tracker's pixel coordinates (anchors, window columns and
/// rows, association bounds): fields up to [`MAX_FIELD`] pixels a side with
/// room for `x + r_assoc` (checked by
/// [`BlinkTracker::new`](super::BlinkTracker::new)). The ports keep
/// 16-bit coordinates; only the per-slot state is this narrow (the M slots'
/// anchors, windows and ROI view are most of the tracker's registers).
/// (`update` writes the width as the literal 10, like [`AGE_BITS`].)
pub const COORD_BITS: usize = 10;

/// Offsets of the fields of a slot's `geo` word (one 64-bit register per
/// slot): the anchor, the window's two word columns and its last row, and
/// the counter bank (at most 14 bits). `update` writes them as literals
/// where rust-hdl's `hdl_gen` needs a number.
pub mod slot_word {
    /// Anchor column (`COORD_BITS`).
    pub const AX: usize = 0;
    /// Anchor row.
    pub const AY: usize = 10;
    /// Counter bank (`BW` bits, at most [`BANK_BITS_MAX`]).
    pub const BANK: usize = 20;
    /// Bits the bank may take in the word.
    pub const BANK_BITS_MAX: usize = 14;
    /// Word column of the window's low word.
    pub const WL: usize = 34;
    /// Word column of the window's high word.
    pub const WH: usize = 44;
    /// Row at whose end the window has streamed.
    pub const FROW: usize = 54;
}

/// Offsets of the fields of a ROI view entry, the words
/// [`BlinkTracker::sh`](super::BlinkTracker::sh) publishes and the ROI
/// aggregator reads. The anchor
/// and the bank sit where they sit in a slot's `geo` word, so that an
/// opening copies the bank without a shift.
pub mod shadow {
    /// Anchor column (`COORD_BITS`).
    pub const AX: usize = 0;
    /// Anchor row.
    pub const AY: usize = 10;
    /// Counter bank (`BW` bits).
    pub const BANK: usize = 20;
    /// Sum the delayed plane `B_{t−N}` (the only plane a segment sums).
    pub const PRE: usize = 62;
    /// First plane of the segment (its opening plane, or the plane after a
    /// cut): the counters and the ROI's mask flags start from zero. The
    /// aggregator sweeps the ROI in this plane even without `PRE` (an
    /// opening at `t < N`), so that they start there.
    pub const FRESH: usize = 63;
}

/// The widest and tallest field the tracker's [`COORD_BITS`] hold, pixels
/// (the SPCImager's is 320×240; the largest camera preset's 512×512).
pub const MAX_FIELD: usize = 512;

/// Whether a configuration fits the tracker's widths: its slot ages
/// ([`AGE_BITS`]), its banks and lane masks in a slot's words (`bw` bits,
/// `p` pixels a word), its field and `r_assoc` in [`COORD_BITS`]. (The
/// configuration's `validate` refuses more than `MAX_SLOTS` slots.)
pub fn fits(cfg: &BackHalfConfig, p: usize, bw: usize) -> Result<(), GatewareError> {
    if cfg.l_max_max as u64 + 2 * cfg.front.n_max as u64 + 2 >= 1 << AGE_BITS {
        return Err(GatewareError::Invalid {
            field: "l_max_max",
            value: cfg.l_max_max.to_string(),
            why: format!(
                "L_max,max + 2·N_max + 2 must stay below 2^{AGE_BITS}, the blink tracker's slot ages"
            ),
        });
    }
    if bw > slot_word::BANK_BITS_MAX || p > 32 {
        return Err(GatewareError::Invalid {
            field: "slots/pixels_per_clock",
            value: format!("{bw}-bit banks, P = {p}"),
            why: format!(
                "a slot's word holds banks of at most {} bits and a lane mask of at most 32",
                slot_word::BANK_BITS_MAX
            ),
        });
    }
    if cfg.front.width > MAX_FIELD || cfg.front.height > MAX_FIELD {
        return Err(GatewareError::Invalid {
            field: "width/height",
            value: format!("{}x{}", cfg.front.width, cfg.front.height),
            why: format!(
                "the blink tracker's {COORD_BITS}-bit coordinates hold fields up to {MAX_FIELD}x{MAX_FIELD}"
            ),
        });
    }
    if cfg.r_assoc as usize >= MAX_FIELD {
        return Err(GatewareError::Invalid {
            field: "r_assoc",
            value: cfg.r_assoc.to_string(),
            why: format!("must be below {MAX_FIELD} (the tracker's {COORD_BITS}-bit coordinates)"),
        });
    }
    Ok(())
}
