//! The back half's generation parameters: [`BackHalfConfig`] and the
//! widths of the tracker, the ROI aggregator and the packetiser.

use super::{bits_for, invalid, GatewareConfig, GatewareError, MAX_SLOTS};
use smartagg_model::config::PipelineConfig;

/// Generation parameters of the back half (tracker, ROI aggregator,
/// packetiser) on top of the front half's [`GatewareConfig`].
///
/// Widths derived here (all checked by the blocks' `new`):
/// * bank bits `BW = ⌈log2(M + Q)⌉`: every slot owns one bank of ROI
///   counters, and up to Q more wait in the record queue for the packetiser;
/// * ROI count bits `RCW = ⌈log2(N_max + L_max,max + 2)⌉`: a segment sums at
///   most `N + L_max + 1` planes (the model's `max_planes_summed`);
/// * counter address bits: `(M + Q)·R` rows of R counters.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BackHalfConfig {
    /// The front half (sensor size, P, N_max, kernel).
    pub front: GatewareConfig,
    /// Tracking slots M (1..=[`MAX_SLOTS`]: the
    /// tracker and the aggregator keep one bit per slot of each flag in one
    /// register).
    pub slots: usize,
    /// ROI side R (odd, 1..=31, at most P).
    pub roi_size: usize,
    /// Association radius (Chebyshev, pixels).
    pub r_assoc: u32,
    /// Largest L_max register value the counters are sized for.
    pub l_max_max: u32,
    /// Record queue depth `2^queue_log2` (also the number of spare banks Q).
    pub queue_log2: usize,
    /// Extra rows of ROI row buffer beyond the fixed lag (sweep backlog).
    pub row_slack: usize,
    /// Depth `2^tracker_fifo_log2` of the FIFO of front-half words before the tracker.
    pub tracker_fifo_log2: usize,
    /// Depth `2^output_fifo_log2` bytes of the output FIFO.
    pub output_fifo_log2: usize,
}

impl BackHalfConfig {
    /// The back half for a model configuration (M, R, r_assoc from it), with
    /// the default record queue (Q = the power of two above M + 1: one plane
    /// can complete every slot and drop candidates while the packetiser is
    /// still busy), FIFO depths and the row slack of
    /// [`BackHalfConfig::default_row_slack`].
    pub fn new(
        cfg: &PipelineConfig,
        front: GatewareConfig,
        l_max_max: u32,
    ) -> Result<BackHalfConfig, GatewareError> {
        cfg.validate()?;
        let queue_log2 = bits_for(cfg.slots as u64 + 1);
        let mut b = BackHalfConfig {
            front,
            slots: cfg.slots,
            roi_size: cfg.roi_size,
            r_assoc: cfg.r_assoc,
            l_max_max,
            queue_log2,
            row_slack: 0,
            tracker_fifo_log2: 9,
            output_fifo_log2: 12,
        };
        b.row_slack = b.default_row_slack();
        b.validate()?;
        if cfg.l_max > l_max_max {
            return Err(invalid(
                "l_max",
                cfg.l_max,
                format!("must not exceed the generated L_max,max = {l_max_max}"),
            ));
        }
        Ok(b)
    }

    /// Checks the back-half parameters against the front half.
    pub fn validate(&self) -> Result<(), GatewareError> {
        self.front.validate()?;
        let p = self.front.pixels_per_clock;
        if !p.is_power_of_two() {
            return Err(invalid(
                "pixels_per_clock",
                p,
                "the back half needs a power of two (word and lane of a column by shifts)",
            ));
        }
        let max_slots = MAX_SLOTS;
        if self.slots == 0 || self.slots > max_slots {
            return Err(invalid(
                "slots",
                self.slots,
                format!("must be 1..={max_slots} (one bit per slot of each flag register)"),
            ));
        }
        let r = self.roi_size;
        if r == 0 || r.is_multiple_of(2) || r > 31 || r > p {
            return Err(invalid(
                "roi_size",
                r,
                format!("must be odd, 1..=31 and at most P = {p} (an ROI row spans two words)"),
            ));
        }
        if r >= self.front.height {
            return Err(invalid(
                "roi_size",
                r,
                format!("must be less than the height {}", self.front.height),
            ));
        }
        if self.front.width as u64 + self.r_assoc as u64 > 65535 || self.r_assoc > 255 {
            return Err(invalid(
                "r_assoc",
                self.r_assoc,
                "must be 0..=255 with width + r_assoc below 2^16",
            ));
        }
        if self.l_max_max < self.front.n_max || self.l_max_max >= 1 << 31 {
            return Err(invalid(
                "l_max_max",
                self.l_max_max,
                format!("must be N_max = {}..2^31", self.front.n_max),
            ));
        }
        if !(1..=10).contains(&self.queue_log2) {
            return Err(invalid("queue_log2", self.queue_log2, "must be 1..=10"));
        }
        for (field, v) in [
            ("tracker_fifo_log2", self.tracker_fifo_log2),
            ("output_fifo_log2", self.output_fifo_log2),
        ] {
            if !(2..=15).contains(&v) {
                return Err(invalid(field, v, "must be 2..=15"));
            }
        }
        if self.output_fifo_log2 < 13
            && (1usize << self.output_fifo_log2) < self.max_packet_bytes() + 22
        {
            return Err(invalid(
                "output_fifo_log2",
                self.output_fifo_log2,
                format!(
                    "the output FIFO must hold the largest packet ({} bytes) and an overflow packet",
                    self.max_packet_bytes()
                ),
            ));
        }
        Ok(())
    }

    /// ROI half side h = R/2.
    pub fn roi_half(&self) -> usize {
        self.roi_size / 2
    }

    /// log2 P.
    pub fn log2_p(&self) -> usize {
        self.front.pixels_per_clock.trailing_zeros() as usize
    }

    /// Spare banks Q = record queue depth.
    pub fn queue_depth(&self) -> usize {
        1 << self.queue_log2
    }

    /// Banks of ROI counters: one per slot plus Q.
    pub fn banks(&self) -> usize {
        self.slots + self.queue_depth()
    }

    /// BW: bits of a bank index.
    pub fn bank_bits(&self) -> usize {
        bits_for(self.banks() as u64 - 1)
    }

    /// RCW: bits of an ROI counter.
    pub fn roi_count_bits(&self) -> usize {
        bits_for(self.front.n_max as u64 + self.l_max_max as u64 + 1)
    }

    /// Address bits of the counter memory (banks × R rows).
    pub fn counter_addr_bits(&self) -> usize {
        bits_for((self.banks() * self.roi_size) as u64 - 1)
    }

    /// Row skew of the ROI sweep behind the raw stream, rows: the filter's
    /// c rows, the candidate window's one, the ROI's h, and margins.
    pub fn row_lag(&self) -> usize {
        self.front.half() + self.roi_half() + 5
    }

    /// Sweep backlog bound, rows: all M ROIs on the same R rows need
    /// R·(M + 1) sweep clocks while R rows bring R·W/P word clocks (at the
    /// full input rate); the tracker pauses at most 2M + 5 clocks a plane
    /// (M + 5 at its end: the walk's M slots through its three stages and
    /// WalkEnd; and one replay after each of at most M openings); plus one
    /// row of margin.
    pub fn default_row_slack(&self) -> usize {
        let wpr = self.front.words_per_row();
        let excess = (self.roi_size * (self.slots + 1)).saturating_sub(self.roi_size * wpr);
        excess.div_ceil(wpr) + (2 * self.slots + 5).div_ceil(wpr) + 1
    }

    /// Rows of the ROI row buffer (a ring).
    pub fn row_buffer_rows(&self) -> usize {
        self.row_lag() + self.row_slack
    }

    /// Words per row in each of the two (even/odd word) banks of the row buffer.
    pub fn half_words_per_row(&self) -> usize {
        self.front.words_per_row().div_ceil(2)
    }

    /// Address bits of one row-buffer bank.
    pub fn row_addr_bits(&self) -> usize {
        bits_for((self.row_buffer_rows() * self.half_words_per_row()) as u64 - 1)
    }

    /// Bytes of the largest packet: a Blink with the worst-case count block.
    pub fn max_packet_bytes(&self) -> usize {
        let n = self.roi_size * self.roi_size;
        14 + 35 + 5 + 1 + (33 * n).div_ceil(8)
    }

    /// Bytes of the StreamStart packet before its CRC: the header (10) and
    /// the payload (41, and 2 a kernel tap).
    pub fn stream_start_bytes(&self) -> usize {
        51 + 2 * self.front.kernel.len()
    }

    /// Bytes of the header and fixed payload the packetiser assembles before
    /// streaming a packet (`PW = 8 ×` this): the largest of StreamStart
    /// ([`Self::stream_start_bytes`]), StreamEnd (10 + 48) and Blink (10 +
    /// 35 + 5 + 1).
    pub fn prefix_bytes(&self) -> usize {
        self.stream_start_bytes().max(58)
    }
}
