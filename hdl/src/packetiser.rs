//! Stage 7 — packetiser: records become the bytes of `model/PACKETS.md`
//! exactly as [`smartagg_model::packet::encode_record`] writes them — header
//! (magic, version, type, sequence number, length), payload with the ROI
//! counts as one Rice-coded count block, CRC-32C — one byte per clock into
//! the output FIFO.
//!
//! **Blink count block.** The counts are read from the record's counter bank
//! ([`crate::roi_aggregator`]) three times, one count per clock: pass 1 finds
//! the minimum `base` (and ORs the rows' mask flags into MASKED), pass 2 feeds
//! RCW + 1 length accumulators, one per Rice parameter k ≤ RCW (with
//! `q = (c − base) >> k`, a code is `q + 1 + k` bits when `q < 32` and 64
//! bits, an escape, when `q ≥ 32`: an accumulator
//! starts at R² (k + 1) and adds q, or 63 − k for an escape; 16 bits suffice
//! for R ≤ 31; no larger k can win: [`rice_candidates`]), an (RCW + 1)-clock
//! scan takes the smallest total (ties: smallest k), and
//! pass 3 emits the codes MSB first through a bit packer. A row of counts
//! shifts down a lane per count taken, and the scan shifts the accumulators
//! down a lane per clock, so that the count and the total of the clock are
//! registers (lane 0), not multiplexers. Passes 2 and 3
//! read each offset from a register; pass 2 registers its code lengths for
//! every k (stage L, one clock more a Blink) before the accumulators add
//! them, and pass 3 builds a code in two more
//! registered steps (quotient, then code and length), so that no path is
//! deeper than one barrel shifter or thermometer; the packer's fill less 8
//! (its byte's shift) and "this prefix byte is the last" are registers too.
//! ROI rows outside
//! the sensor read as 0. The header's length is known after pass 2; the
//! room check for the whole packet is a register too (Decide acts on its
//! second clock).
//!
//! **Sequence numbers and overflow.** Every record but Overflow takes the
//! next number (from `seq_init` at stream start). A record the tracker could
//! not queue (its record queue full) arrives as `r_lost` on the next one and
//! is numbered and announced like a record the output FIFO dropped. Before emitting a record
//! the packetiser checks that the output FIFO has room for the whole packet
//! (and for an Overflow packet if records were lost); if not, the record is
//! dropped whole and counted. The next record that fits is preceded by one
//! Overflow record (first lost number, count), whose header carries the first
//! lost number and consumes none — the gateware stream is the model's with
//! records missing and every gap announced exactly. StreamStart and
//! StreamEnd are never dropped: they wait for room (nothing else is in
//! flight then).
//!
//! **CRC-32C** is updated a byte per clock with the table-free form
//! `crc' = (crc >> 8) ^ ⊕ᵢ vᵢ·T(2ⁱ)`, `v = (crc ^ byte) & 0xFF`, where T is
//! the reflected byte table of polynomial 0x82F63B78 (linear in v).

use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::const_mul::ConstMul;
use crate::stream::{lanes, EnableRegs};
use rust_hdl::prelude::*;
use smartagg_model::packet::VERSION as PACKET_VERSION;

/// Packetiser states.
#[derive(Copy, Clone, Debug, PartialEq, LogicState)]
pub enum PacketState {
    /// Waiting for a record.
    Idle,
    /// Blink: waiting until its counts are final.
    Wait,
    /// Blink pass 1: minimum and mask flag.
    Pass1,
    /// Blink pass 2: code lengths for every k.
    Pass2,
    /// Blink: the best k.
    Choose,
    /// Room check: emit or drop.
    Decide,
    /// Header and payload bytes of the Overflow packet.
    Ovf,
    /// Header and fixed payload bytes of the record.
    Emit,
    /// Blink pass 3: the codes.
    Codes,
    /// The four CRC bytes.
    Crc,
    /// Return the bank, next sequence number.
    Finish,
}

/// Rice parameters worth a length accumulator for counts of `rcw` bits:
/// 0 ..= `rcw` (at most the model's 0 ..= 31). An offset from the base is
/// below 2^rcw, so for every k ≥ rcw each code is 1 + k bits and the total
/// grows with k: k = rcw beats every larger k, and the model's choice
/// ([`smartagg_model::rice::choose`], smallest k on ties) is always in
/// 0 ..= rcw.
pub fn rice_candidates(rcw: usize) -> usize {
    (rcw + 1).min(smartagg_model::rice::MAX_K as usize + 1)
}

/// CRC-32C table entries of the single-bit bytes 2⁰ … 2⁷.
fn crc_bit_entries() -> [u32; 8] {
    let mut t = [0u32; 8];
    for (i, e) in t.iter_mut().enumerate() {
        let mut c = 1u32 << i;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0x82F6_3B78
            } else {
                c >> 1
            };
        }
        *e = c;
    }
    t
}

/// The packetiser. `R` counts per ROI row come from the counter memory.
/// `RCW`: count bits; `CAW`: counter address bits; `BW`: bank bits; `NW`:
/// bits of N; `PW`: bits of the assembled header and fixed payload
/// (`8 ×` [`BackHalfConfig::prefix_bytes`]).
#[derive(LogicBlock)]
pub struct Packetiser<
    const RCW: usize,
    const CAW: usize,
    const BW: usize,
    const NW: usize,
    const PW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: sequence number `seq_init` next, nothing pending.
    pub restart: Signal<In, Bit>,
    /// First sequence number (0 in the pipeline; the vectors start later).
    pub seq_init: Signal<In, Bits<32>>,
    /// N register (StreamStart).
    pub n_window: Signal<In, Bits<NW>>,
    /// T_int register (StreamStart).
    pub threshold: Signal<In, Bits<32>>,
    /// T_hold register (StreamStart).
    pub threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM register (StreamStart; ≤ N − 1, so NW bits hold it).
    pub end_trim: Signal<In, Bits<NW>>,
    /// L_min register (StreamStart).
    pub l_min: Signal<In, Bits<32>>,
    /// L_max register (StreamStart).
    pub l_max: Signal<In, Bits<32>>,
    /// Plane period, ns (StreamStart).
    pub plane_period: Signal<In, Bits<32>>,
    /// Masked pixels (StreamStart).
    pub masked_pixels: Signal<In, Bits<32>>,
    /// StreamEnd: planes.
    pub c_planes: Signal<In, Bits<64>>,
    /// StreamEnd: blinks.
    pub c_blinks: Signal<In, Bits<64>>,
    /// StreamEnd: unconfirmed.
    pub c_unconf: Signal<In, Bits<64>>,
    /// StreamEnd: dropped candidates.
    pub c_dropped: Signal<In, Bits<64>>,
    /// StreamEnd: bridged dips.
    pub c_bridged: Signal<In, Bits<64>>,
    /// StreamEnd: cut segments.
    pub c_cuts: Signal<In, Bits<64>>,
    /// A record is at the head of the queue (held until `r_pop`).
    pub r_valid: Signal<In, Bit>,
    /// Its kind ([`crate::blink_tracker::record_kind`]).
    pub r_kind: Signal<In, Bits<2>>,
    /// Records lost just before it.
    pub r_lost: Signal<In, Bits<32>>,
    /// Blink: slot.
    pub r_slot: Signal<In, Bits<8>>,
    /// Blink: flags (MASKED is added from the counter rows).
    pub r_flags: Signal<In, Bits<8>>,
    /// Blink: anchor column; Dropped: first column.
    pub r_ax: Signal<In, Bits<16>>,
    /// Blink: anchor row; Dropped: first row.
    pub r_ay: Signal<In, Bits<16>>,
    /// Blink: t_cross; Dropped: plane.
    pub r_t0: Signal<In, Bits<48>>,
    /// Blink: t_drop; Dropped: count.
    pub r_t1: Signal<In, Bits<48>>,
    /// Blink: t_s (two's complement, 48 bits).
    pub r_ts: Signal<In, Bits<48>>,
    /// Blink: t_e.
    pub r_te: Signal<In, Bits<48>>,
    /// Blink: planes summed.
    pub r_planes: Signal<In, Bits<32>>,
    /// Blink: counter bank.
    pub r_bank: Signal<In, Bits<BW>>,
    /// Blink: its counts are final.
    pub r_ready: Signal<In, Bit>,
    /// Done with the head record.
    pub r_pop: Signal<Out, Bit>,
    /// Counter row read request.
    pub rd_req: Signal<Out, Bit>,
    /// Counter row address.
    pub rd_addr: Signal<Out, Bits<CAW>>,
    /// The request is taken; the row follows next clock.
    pub rd_grant: Signal<In, Bit>,
    /// The counts of the row.
    pub rd_counts: Vec<Signal<In, Bits<RCW>>>,
    /// The row's mask flag.
    pub rd_masked: Signal<In, Bit>,
    /// Return a bank to the free list.
    pub fb_ret: Signal<Out, Bit>,
    /// The bank returned.
    pub fb_ret_bank: Signal<Out, Bits<BW>>,
    /// Free bytes in the output FIFO.
    pub fifo_free: Signal<In, Bits<16>>,
    /// A byte is emitted.
    pub out_valid: Signal<Out, Bit>,
    /// The byte.
    pub out_byte: Signal<Out, Bits<8>>,
    /// Nothing in flight and no record waiting.
    pub idle: Signal<Out, Bit>,
    /// Records were lost since stream start (sticky; Overflow records tell how many).
    pub overflowed: Signal<Out, Bit>,
    state: DFF<PacketState>,
    seq_ctr: DFF<Bits<32>>,
    pend_first: DFF<Bits<32>>,
    pend_cnt: DFF<Bits<32>>,
    ovf_flag: DFF<Bit>,
    in_ovf: DFF<Bit>,
    // Count streamer.
    cs_active: DFF<Bit>,
    cs_wait: DFF<Bit>,
    row_valid: DFF<Bit>,
    cs_dy: DFF<Bits<8>>,
    cs_dx: DFF<Bits<8>>,
    row: Vec<DFF<Bits<RCW>>>,
    base: DFF<Bits<RCW>>,
    masked: DFF<Bit>,
    /// The ROI row `cs_dy` lies on the sensor: a register of the clock that
    /// requests the row (`cs_dy` and the record hold still until the row
    /// arrives), so the row's add and compare stay out of the MASKED flag's
    /// and the counts' paths.
    in_sensor: DFF<Bit>,
    acc: Vec<DFF<Bits<16>>>,
    /// Pass 2's stage L: the code lengths of the offset in stage A, for
    /// every k, registered before the accumulators add them (the escape
    /// tests and the adders are not in series: synthesis lets the logic on
    /// either side of a carry chain take the whole depth).
    lv: DFF<Bit>,
    lq: Vec<DFF<Bits<16>>>,
    best: DFF<Bits<16>>,
    /// Bytes of the codes, ⌈best / 8⌉, set with best (for the length).
    best_bytes: DFF<Bits<16>>,
    /// k + 1 and the code's masks of bit k + 1 up and of the k low bits,
    /// a clock behind bestk: it last changes in Choose, and they are read
    /// only in Codes (Decide and Emit lie between).
    bk1: DFF<Bits<8>>,
    k_hi: DFF<Bits<64>>,
    k_lo: DFF<Bits<64>>,
    bestk: DFF<Bits<8>>,
    scan: DFF<Bits<8>>,
    // Emission.
    /// The packet's prefix bytes, loaded once a packet (see `prefix_load`).
    prefix: EnableRegs<Bits<8>>,
    /// Prefix bytes after the one of this clock (down-counted).
    prefix_rest: DFF<Bits<16>>,
    /// The byte of this clock is the prefix's last (`prefix_rest` = 0, as a
    /// register so that Ovf and Emit decide without a compare).
    prefix_last: DFF<Bit>,
    bidx: DFF<Bits<16>>,
    /// `r_planes` a clock late: the finisher's arithmetic ends in a register.
    /// It is read when a Blink's prefix loads (Decide's second clock on, or
    /// Crc after an Overflow), when the head record has been the same for
    /// clocks (it changes only after Finish's pop).
    planes_r: DFF<Bits<32>>,
    crc: DFF<Bits<32>>,
    crc_i: DFF<Bits<8>>,
    nb: DFF<Bits<8>>,
    /// `nb − 8` (mod 256), kept beside nb: the byte's shift reads a register.
    nb8: DFF<Bits<8>>,
    pk: DFF<Bits<72>>,
    /// The output FIFO has room for the packet (`need`), as of last clock.
    room: DFF<Bit>,
    /// Decide's second clock on: `room` speaks of this record.
    dec_ready: DFF<Bit>,
    // The code pipeline (Codes): A offset, B quotient, C code.
    ca_v: DFF<Bit>,
    ca_d: DFF<Bits<RCW>>,
    cb_v: DFF<Bit>,
    cb_q: DFF<Bits<32>>,
    cb_d: DFF<Bits<RCW>>,
    cc_v: DFF<Bit>,
    cc_code: DFF<Bits<64>>,
    cc_len: DFF<Bits<8>>,
    bank_base: ConstMul<CAW>,
    // Combinational.
    is_blink: Signal<Local, Bit>,
    take: Signal<Local, Bit>,
    c_valid: Signal<Local, Bit>,
    c_val: Signal<Local, Bits<RCW>>,
    row_y: Signal<Local, Bits<16>>,
    dd: Signal<Local, Bits<RCW>>,
    d32: Signal<Local, Bits<32>>,
    /// Bit i: some bit ≥ i of the offset in `ca_d` is set (64 bits: the
    /// escape test of k ≤ 31 reads bit k + 5).
    d_sfx: Signal<Local, Bits<64>>,
    q: Vec<Signal<Local, Bits<32>>>,
    len: Vec<Signal<Local, Bits<32>>>,
    acc_j: Signal<Local, Bits<16>>,
    /// LEB128 bytes of the base (a register: read only from Decide on).
    vlen: DFF<Bits<16>>,
    tb0: Signal<Local, Bits<8>>,
    tb1: Signal<Local, Bits<8>>,
    tb2: Signal<Local, Bits<8>>,
    tb3: Signal<Local, Bits<8>>,
    tb4: Signal<Local, Bits<8>>,
    tb5: Signal<Local, Bits<8>>,
    vb: Vec<Signal<Local, Bits<8>>>,
    payload_len: Signal<Local, Bits<16>>,
    /// The record's prefix length minus one.
    rec_prefix_rest: Signal<Local, Bits<16>>,
    need: Signal<Local, Bits<16>>,
    type_code: Signal<Local, Bits<8>>,
    n16: Signal<Local, Bits<16>>,
    /// END_TRIM widened to its StreamStart field.
    trim32: Signal<Local, Bits<32>>,
    sel_tree: Vec<Signal<Local, Bits<8>>>,
    rec_prefix: Vec<Signal<Local, Bits<8>>>,
    ovf_prefix: Vec<Signal<Local, Bits<8>>>,
    /// The prefix registers load this clock: with `ovf_prefix` if
    /// `prefix_ovf`, else `rec_prefix`.
    prefix_load: Signal<Local, Bit>,
    prefix_ovf: Signal<Local, Bit>,
    the_byte: Signal<Local, Bits<8>>,
    /// A state that sends bytes.
    emitting: Signal<Local, Bit>,
    pk_shift: Signal<Local, Bits<72>>,
    pk_low: Signal<Local, Bits<72>>,
    pad_shift: Signal<Local, Bits<72>>,
    crc_shift: Signal<Local, Bits<32>>,
    pk_byte: Signal<Local, Bits<8>>,
    pad_byte: Signal<Local, Bits<8>>,
    crc_v: Signal<Local, Bits<8>>,
    ct: Vec<Signal<Local, Bits<32>>>,
    crc_next: Signal<Local, Bits<32>>,
    bk: Signal<Local, Bits<8>>,
    cesc: Signal<Local, Bit>,
    clen: Signal<Local, Bits<8>>,
    /// The offset of stage B, 64 bits wide.
    cd64: Signal<Local, Bits<64>>,
    in_codes: Signal<Local, Bit>,
    in_pass2: Signal<Local, Bit>,
    free_a: Signal<Local, Bit>,
    free_b: Signal<Local, Bit>,
    free_c: Signal<Local, Bit>,
    code: Signal<Local, Bits<64>>,
    // Constants.
    kc: Vec<Constant<Bits<8>>>,
    /// 63 − k: an escaped code's 64 bits less the k + 1 in `acc0`.
    k63c: Vec<Constant<Bits<32>>>,
    /// R² (k + 1): the 1 + k bits of every code, where the totals start.
    acc0: Vec<Constant<Bits<16>>>,
    crc_t: Vec<Constant<Bits<32>>>,
    start_bytes: Vec<Constant<Bits<8>>>,
    start_len: Constant<Bits<16>>,
    /// The packet format version ([`PACKET_VERSION`]), every header's byte 2.
    version: Constant<Bits<8>>,
    tree_bit: Vec<Constant<Bits<8>>>,
    roi_side: Constant<Bits<8>>,
    h: Constant<Bits<16>>,
    h_plus_rows: Constant<Bits<16>>,
    last_idx: Constant<Bits<8>>,
    /// The largest Rice parameter scanned (`_kn − 1`).
    k_last: Constant<Bits<8>>,
    /// Covers every k below `_kn` (a power of two minus one).
    k_mask: Constant<Bits<8>>,
    low_byte: Constant<Bits<72>>,
    all64: Constant<Bits<64>>,
    all_ones: Constant<Bits<RCW>>,
    _r: usize,
    /// Rice parameters with a length accumulator: 0 ..= RCW (see
    /// [`rice_candidates`]).
    _kn: usize,
    /// Bytes of the assembled header and fixed payload (PW / 8).
    _pb: usize,
    /// Leaves of the byte-select tree (the power of two at or above `_pb`).
    _leaves: usize,
    /// Byte offsets in StreamStart of the plane period, masked pixels and
    /// T_hold.
    _o_period: usize,
    _o_masked: usize,
    _o_hold: usize,
    _o_trim: usize,
}

impl<const RCW: usize, const CAW: usize, const BW: usize, const NW: usize, const PW: usize>
    Packetiser<RCW, CAW, BW, NW, PW>
{
    /// The packetiser of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        let f = &cfg.front;
        GatewareConfig::check_width("Packetiser", "RCW", RCW, cfg.roi_count_bits())?;
        GatewareConfig::check_width("Packetiser", "CAW", CAW, cfg.counter_addr_bits())?;
        GatewareConfig::check_width("Packetiser", "BW", BW, cfg.bank_bits())?;
        GatewareConfig::check_width("Packetiser", "NW", NW, f.count_bits())?;
        GatewareConfig::check_width("Packetiser", "PW", PW, 8 * cfg.prefix_bytes())?;
        let r = cfg.roi_size;
        let k = f.kernel.len();
        let kn = rice_candidates(RCW);
        // The constant bytes of StreamStart: header (seq and the registers
        // are added at run time) and the generation parameters.
        let start_payload = 41 + 2 * k;
        let mut sb = vec![0u8; 10 + start_payload];
        sb[..4].copy_from_slice(&[0x53, 0x41, PACKET_VERSION, 0x01]);
        sb[8..10].copy_from_slice(&(start_payload as u16).to_le_bytes());
        sb[10..12].copy_from_slice(&(f.width as u16).to_le_bytes());
        sb[12..14].copy_from_slice(&(f.height as u16).to_le_bytes());
        sb[30] = cfg.r_assoc as u8;
        sb[31] = cfg.slots as u8;
        sb[32] = r as u8;
        sb[33] = f.kernel_shift;
        sb[34] = k as u8;
        for (i, w) in f.kernel.iter().enumerate() {
            sb[35 + 2 * i..37 + 2 * i].copy_from_slice(&(*w as u16).to_le_bytes());
        }
        let c8 = |v: u64| Constant::new(v.to_bits());
        Ok(Packetiser {
            clock: Default::default(),
            restart: Default::default(),
            seq_init: Default::default(),
            n_window: Default::default(),
            threshold: Default::default(),
            threshold_hold: Default::default(),
            end_trim: Default::default(),
            l_min: Default::default(),
            l_max: Default::default(),
            plane_period: Default::default(),
            masked_pixels: Default::default(),
            c_planes: Default::default(),
            c_blinks: Default::default(),
            c_unconf: Default::default(),
            c_dropped: Default::default(),
            c_bridged: Default::default(),
            c_cuts: Default::default(),
            r_valid: Default::default(),
            r_kind: Default::default(),
            r_lost: Default::default(),
            r_slot: Default::default(),
            r_flags: Default::default(),
            r_ax: Default::default(),
            r_ay: Default::default(),
            r_t0: Default::default(),
            r_t1: Default::default(),
            r_ts: Default::default(),
            r_te: Default::default(),
            r_planes: Default::default(),
            r_bank: Default::default(),
            r_ready: Default::default(),
            r_pop: Default::default(),
            rd_req: Default::default(),
            rd_addr: Default::default(),
            rd_grant: Default::default(),
            rd_counts: lanes(r),
            rd_masked: Default::default(),
            fb_ret: Default::default(),
            fb_ret_bank: Default::default(),
            fifo_free: Default::default(),
            out_valid: Default::default(),
            out_byte: Default::default(),
            idle: Default::default(),
            overflowed: Default::default(),
            state: Default::default(),
            seq_ctr: Default::default(),
            pend_first: Default::default(),
            pend_cnt: Default::default(),
            ovf_flag: Default::default(),
            in_ovf: Default::default(),
            cs_active: Default::default(),
            cs_wait: Default::default(),
            row_valid: Default::default(),
            cs_dy: Default::default(),
            cs_dx: Default::default(),
            row: lanes(r),
            base: Default::default(),
            masked: Default::default(),
            acc: lanes(kn),
            lv: Default::default(),
            lq: lanes(kn),
            best: Default::default(),
            best_bytes: Default::default(),
            bk1: Default::default(),
            k_hi: Default::default(),
            k_lo: Default::default(),
            bestk: Default::default(),
            scan: Default::default(),
            prefix: EnableRegs::new(PW / 8),
            prefix_rest: Default::default(),
            prefix_last: Default::default(),
            bidx: Default::default(),
            planes_r: Default::default(),
            crc: Default::default(),
            crc_i: Default::default(),
            nb: Default::default(),
            nb8: Default::default(),
            pk: Default::default(),
            room: Default::default(),
            dec_ready: Default::default(),
            ca_v: Default::default(),
            ca_d: Default::default(),
            cb_v: Default::default(),
            cb_q: Default::default(),
            cb_d: Default::default(),
            cc_v: Default::default(),
            cc_code: Default::default(),
            cc_len: Default::default(),
            bank_base: ConstMul::new(r as u32),
            is_blink: Default::default(),
            take: Default::default(),
            c_valid: Default::default(),
            c_val: Default::default(),
            row_y: Default::default(),
            in_sensor: Default::default(),
            dd: Default::default(),
            d32: Default::default(),
            d_sfx: Default::default(),
            q: lanes(kn),
            len: lanes(kn),
            acc_j: Default::default(),
            vlen: Default::default(),
            tb0: Default::default(),
            tb1: Default::default(),
            tb2: Default::default(),
            tb3: Default::default(),
            tb4: Default::default(),
            tb5: Default::default(),
            vb: lanes(5),
            payload_len: Default::default(),
            rec_prefix_rest: Default::default(),
            need: Default::default(),
            type_code: Default::default(),
            n16: Default::default(),
            trim32: Default::default(),
            sel_tree: lanes(2 * (PW / 8).next_power_of_two()),
            rec_prefix: lanes(PW / 8),
            ovf_prefix: lanes(PW / 8),
            prefix_load: Default::default(),
            prefix_ovf: Default::default(),
            the_byte: Default::default(),
            emitting: Default::default(),
            pk_shift: Default::default(),
            pk_low: Default::default(),
            pad_shift: Default::default(),
            crc_shift: Default::default(),
            pk_byte: Default::default(),
            pad_byte: Default::default(),
            crc_v: Default::default(),
            ct: lanes(8),
            crc_next: Default::default(),
            bk: Default::default(),
            cesc: Default::default(),
            clen: Default::default(),
            cd64: Default::default(),
            in_codes: Default::default(),
            in_pass2: Default::default(),
            free_a: Default::default(),
            free_b: Default::default(),
            free_c: Default::default(),
            code: Default::default(),
            kc: (0..kn).map(|k| c8(k as u64)).collect(),
            k63c: (0..kn)
                .map(|k| Constant::new((63 - k as u64).to_bits()))
                .collect(),
            acc0: (0..kn)
                .map(|k| Constant::new(((r * r * (k + 1)) as u64).to_bits()))
                .collect(),
            crc_t: crc_bit_entries()
                .iter()
                .map(|&e| Constant::new((e as u64).to_bits()))
                .collect(),
            start_bytes: (0..PW / 8)
                .map(|j| c8(sb.get(j).copied().unwrap_or(0) as u64))
                .collect(),
            start_len: Constant::new(((10 + start_payload) as u64).to_bits()),
            version: c8(PACKET_VERSION as u64),
            // Node i (depth ⌊log2 i⌋ below the root) selects by bit
            // log2(leaves) − 1 − depth of the byte index (node 0 is unused).
            tree_bit: (0..(PW / 8).next_power_of_two())
                .map(|i: usize| {
                    let levels = (PW / 8).next_power_of_two().trailing_zeros();
                    let depth = if i == 0 { 0 } else { i.ilog2() };
                    c8(levels.saturating_sub(1 + depth) as u64)
                })
                .collect(),
            roi_side: c8(r as u64),
            h: Constant::new((cfg.roi_half() as u64).to_bits()),
            h_plus_rows: Constant::new(((cfg.roi_half() + f.height) as u64).to_bits()),
            last_idx: c8(r as u64 - 1),
            k_last: c8(kn as u64 - 1),
            k_mask: c8(kn.next_power_of_two() as u64 - 1),
            low_byte: Constant::new(0xFFu64.to_bits()),
            all64: Constant::new(u64::MAX.to_bits()),
            all_ones: Constant::new(Bits::<RCW>::mask()),
            _r: r,
            _kn: kn,
            _pb: PW / 8,
            _leaves: (PW / 8).next_power_of_two(),
            _o_period: 35 + 2 * k,
            _o_masked: 39 + 2 * k,
            _o_hold: 43 + 2 * k,
            _o_trim: 47 + 2 * k,
        })
    }
}

// Match guards do not translate to Verilog, so the ifs stay inside the arms.
#[allow(clippy::collapsible_match)]
impl<const RCW: usize, const CAW: usize, const BW: usize, const NW: usize, const PW: usize> Logic
    for Packetiser<RCW, CAW, BW, NW, PW>
{
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self,
            clock,
            state,
            seq_ctr,
            pend_first,
            pend_cnt,
            ovf_flag,
            in_ovf,
            cs_active,
            cs_wait,
            row_valid,
            cs_dy,
            cs_dx,
            base,
            masked,
            in_sensor,
            best,
            best_bytes,
            bk1,
            k_hi,
            k_lo,
            bestk,
            scan,
            prefix_rest,
            prefix_last,
            bidx,
            planes_r,
            crc,
            crc_i,
            nb,
            nb8,
            pk,
            vlen,
            room,
            dec_ready,
            ca_v,
            ca_d,
            lv,
            cb_v,
            cb_q,
            cb_d,
            cc_v,
            cc_code,
            cc_len
        );
        self.prefix.clock.next = self.clock.val();
        self.prefix_load.next = false;
        self.prefix_ovf.next = false;
        for dx in 0..self._r {
            self.row[dx].clock.next = self.clock.val();
            self.row[dx].d.next = self.row[dx].q.val();
        }
        for k in 0..self._kn {
            self.acc[k].clock.next = self.clock.val();
            self.acc[k].d.next = self.acc[k].q.val();
            self.lq[k].clock.next = self.clock.val();
        }
        self.is_blink.next = self.r_kind.val() == 1;
        self.planes_r.d.next = self.r_planes.val();

        // ---- Count streamer: one ROI row at a time from the counter bank.
        self.bank_base.x.next = bit_cast::<CAW, BW>(self.r_bank.val());
        self.rd_addr.next = self.bank_base.y.val() + bit_cast::<CAW, 8>(self.cs_dy.q.val());
        self.rd_req.next = false;
        self.row_y.next = self.r_ay.val() + bit_cast::<16, 8>(self.cs_dy.q.val());
        self.in_sensor.d.next =
            (self.row_y.val() >= self.h.val()) & (self.row_y.val() < self.h_plus_rows.val());
        self.c_valid.next = self.row_valid.q.val();
        // Each take shifts the row down a lane: the count of column cs_dx is
        // always in lane 0 (a register, not a multiplexer by cs_dx).
        self.c_val.next = self.row[0].q.val();
        // The code pipeline's room (see below: "The codes").
        self.bk.next = self.bestk.q.val() & self.k_mask.val();
        self.bk1.d.next = self.bk.val() + 1;
        self.k_hi.d.next = self.all64.val() << (self.bk.val() + 1);
        self.k_lo.d.next = !(self.all64.val() << self.bk.val());
        self.in_codes.next = self.state.q.val() == PacketState::Codes;
        self.in_pass2.next = self.state.q.val() == PacketState::Pass2;
        self.free_c.next = !self.cc_v.q.val() | (self.in_codes.val() & (self.nb.q.val() < 8));
        self.free_b.next = !self.cb_v.q.val() | self.free_c.val();
        self.free_a.next = !self.ca_v.q.val() | self.free_b.val();
        // `take` (set below by the pass that consumes) advances the streamer.
        self.take.next = false;
        match self.state.q.val() {
            PacketState::Pass1 => {
                self.take.next = true;
            }
            PacketState::Pass2 => {
                self.take.next = true;
            }
            PacketState::Codes => {
                self.take.next = self.free_a.val();
            }
            _ => {}
        }
        if self.cs_active.q.val() {
            if !self.row_valid.q.val() & !self.cs_wait.q.val() {
                self.rd_req.next = true;
                if self.rd_grant.val() {
                    self.cs_wait.d.next = true;
                }
            }
            if self.cs_wait.q.val() {
                for dx in 0..self._r {
                    self.row[dx].d.next = 0.into();
                    if self.in_sensor.q.val() {
                        self.row[dx].d.next = self.rd_counts[dx].val();
                    }
                }
                if (self.state.q.val() == PacketState::Pass1)
                    & self.in_sensor.q.val()
                    & self.rd_masked.val()
                {
                    self.masked.d.next = true;
                }
                self.row_valid.d.next = true;
                self.cs_wait.d.next = false;
            }
            if self.row_valid.q.val() & self.take.val() {
                for dx in 0..(self._r - 1) {
                    self.row[dx].d.next = self.row[dx + 1].q.val();
                }
                self.cs_dx.d.next = self.cs_dx.q.val() + 1;
                if self.cs_dx.q.val() == self.last_idx.val() {
                    self.cs_dx.d.next = 0.into();
                    self.row_valid.d.next = false;
                    self.cs_dy.d.next = self.cs_dy.q.val() + 1;
                    if self.cs_dy.q.val() == self.last_idx.val() {
                        self.cs_active.d.next = false;
                    }
                }
            }
        }

        // ---- Offsets from the base, and the code lengths for every k.
        self.dd.next = self.c_val.val() - self.base.q.val();
        // Pass 2 reads the offsets from stage A of the code pipeline.
        self.d32.next = bit_cast::<32, RCW>(self.ca_d.q.val());
        // The suffix OR as a parallel prefix (log depth).
        self.d_sfx.next = bit_cast::<64, RCW>(self.ca_d.q.val());
        self.d_sfx.next = self.d_sfx.val() | (self.d_sfx.val() >> 1);
        self.d_sfx.next = self.d_sfx.val() | (self.d_sfx.val() >> 2);
        self.d_sfx.next = self.d_sfx.val() | (self.d_sfx.val() >> 4);
        self.d_sfx.next = self.d_sfx.val() | (self.d_sfx.val() >> 8);
        self.d_sfx.next = self.d_sfx.val() | (self.d_sfx.val() >> 16);
        for k in 0..self._kn {
            self.q[k].next = self.d32.val() >> self.kc[k].val();
            // A code's bits less its 1 + k, which `acc0` holds for all R²
            // codes: one adder after the escape test, not two.
            self.len[k].next = self.q[k].val();
            // An escape at k: q ≥ 32, some bit ≥ k + 5 of the offset set.
            if self.d_sfx.val().get_bit(k + 5) {
                self.len[k].next = self.k63c[k].val();
            }
            self.lq[k].d.next = self.len[k].val().get_bits::<16>(0);
        }
        self.lv.d.next = self.ca_v.q.val() & self.in_pass2.val();
        // Choose shifts the accumulators down a lane a clock: the total of
        // k = scan is always in lane 0 (a register, not a multiplexer).
        self.acc_j.next = self.acc[0].q.val();

        // ---- The codes (Codes), in three registered steps so that none is
        // deeper than a barrel shifter or a thermometer: A the offset from
        // the base (also pass 2's input), B its quotient by 2^k, C the code
        // and its length, which the bit packer appends. A stage takes the
        // one before it when it is empty or its content moves on this clock
        // (`free_*`).
        // The masks change no value (bestk < _kn; cq < 32 unless escaped,
        // when the code is replaced) but tell synthesis how few shift
        // stages the barrel shifters need.
        // C from B: the code is 1…1 (q ones) 0 (bit k) and the k low bits
        // of the offset: bits k + 1 … clen − 1 set, as the difference of two
        // thermometers.
        self.cd64.next = bit_cast::<64, RCW>(self.cb_d.q.val());
        self.cesc.next = (self.cb_q.q.val() >> 5).any();
        self.clen.next = bit_cast::<8, 32>(self.cb_q.q.val() & 31) + self.bk1.q.val();
        self.code.next = (!(self.all64.val() << self.clen.val()) & self.k_hi.q.val())
            | (self.cd64.val() & self.k_lo.q.val());
        if self.cesc.val() {
            self.code.next = (bit_cast::<64, 32>(0xFFFF_FFFF_u64.into()) << 32) | self.cd64.val();
            self.clen.next = 64.into();
        }
        if self.free_c.val() {
            self.cc_v.d.next = self.cb_v.q.val();
            self.cc_code.d.next = self.code.val();
            self.cc_len.d.next = self.clen.val();
        }
        if self.free_b.val() {
            self.cb_v.d.next = self.ca_v.q.val() & self.in_codes.val();
            self.cb_q.d.next = bit_cast::<32, RCW>(self.ca_d.q.val()) >> self.bk.val();
            self.cb_d.d.next = self.ca_d.q.val();
        }
        if self.free_a.val() {
            self.ca_v.d.next = (self.in_codes.val() | self.in_pass2.val()) & self.c_valid.val();
            self.ca_d.d.next = self.dd.val();
        }

        // ---- Count block tail of the header: base as LEB128, then k.
        self.vlen.d.next = 5.into();
        if (self.base.q.val() >> 28) == 0 {
            self.vlen.d.next = 4.into();
        }
        if (self.base.q.val() >> 21) == 0 {
            self.vlen.d.next = 3.into();
        }
        if (self.base.q.val() >> 14) == 0 {
            self.vlen.d.next = 2.into();
        }
        if (self.base.q.val() >> 7) == 0 {
            self.vlen.d.next = 1.into();
        }
        self.vb[0].next = bit_cast::<8, RCW>(self.base.q.val()) & 0x7F;
        self.vb[1].next = bit_cast::<8, RCW>(self.base.q.val() >> 7) & 0x7F;
        self.vb[2].next = bit_cast::<8, RCW>(self.base.q.val() >> 14) & 0x7F;
        self.vb[3].next = bit_cast::<8, RCW>(self.base.q.val() >> 21) & 0x7F;
        self.vb[4].next = bit_cast::<8, RCW>(self.base.q.val() >> 28) & 0x7F;
        self.tb0.next = self.vb[0].val();
        if self.vlen.q.val() > 1 {
            self.tb0.next = self.vb[0].val() | 0x80;
        }
        self.tb1.next = 0.into();
        if self.vlen.q.val() == 1 {
            self.tb1.next = self.bestk.q.val();
        }
        if self.vlen.q.val() == 2 {
            self.tb1.next = self.vb[1].val();
        }
        if self.vlen.q.val() > 2 {
            self.tb1.next = self.vb[1].val() | 0x80;
        }
        self.tb2.next = 0.into();
        if self.vlen.q.val() == 2 {
            self.tb2.next = self.bestk.q.val();
        }
        if self.vlen.q.val() == 3 {
            self.tb2.next = self.vb[2].val();
        }
        if self.vlen.q.val() > 3 {
            self.tb2.next = self.vb[2].val() | 0x80;
        }
        self.tb3.next = 0.into();
        if self.vlen.q.val() == 3 {
            self.tb3.next = self.bestk.q.val();
        }
        if self.vlen.q.val() == 4 {
            self.tb3.next = self.vb[3].val();
        }
        if self.vlen.q.val() > 4 {
            self.tb3.next = self.vb[3].val() | 0x80;
        }
        self.tb4.next = 0.into();
        if self.vlen.q.val() == 4 {
            self.tb4.next = self.bestk.q.val();
        }
        if self.vlen.q.val() == 5 {
            self.tb4.next = self.vb[4].val();
        }
        self.tb5.next = 0.into();
        if self.vlen.q.val() == 5 {
            self.tb5.next = self.bestk.q.val();
        }

        // ---- Lengths and the assembled header + fixed payload of each kind.
        self.payload_len.next = 37.into();
        self.rec_prefix_rest.next = self.start_len.val() - 1;
        self.type_code.next = 1.into();
        match self.r_kind.val().index() {
            1 => {
                self.type_code.next = 2.into();
                self.payload_len.next = self.vlen.q.val() + 36 + self.best_bytes.q.val();
                self.rec_prefix_rest.next = self.vlen.q.val() + 45;
            }
            2 => {
                self.type_code.next = 3.into();
                self.payload_len.next = 14.into();
                self.rec_prefix_rest.next = 23.into();
            }
            3 => {
                self.type_code.next = 4.into();
                self.payload_len.next = 48.into();
                self.rec_prefix_rest.next = 57.into();
            }
            _ => {
                self.payload_len.next = self.start_len.val() - 10;
            }
        }
        self.need.next = self.payload_len.val() + 14;
        if self.pend_cnt.q.val() != 0 {
            self.need.next = self.payload_len.val() + 36;
        }
        // The room check is registered: Decide acts from its second clock,
        // when `room` was computed from this record's final lengths.
        self.room.d.next = self.fifo_free.val() >= self.need.val();
        self.dec_ready.d.next = self.state.q.val() == PacketState::Decide;
        // Byte by byte: a byte lane per prefix byte (the same multiplexers as
        // one wide vector, without the wide shifts that dominated the
        // packetiser's simulation).
        for j in 0..self._pb {
            self.rec_prefix[j].next = 0.into();
            self.ovf_prefix[j].next = 0.into();
        }
        // (Verilog cannot slice an expression: N widened into a signal first.)
        self.n16.next = bit_cast::<16, NW>(self.n_window.val());
        self.trim32.next = bit_cast::<32, NW>(self.end_trim.val());
        // Read only when a packet starts (Decide, and Crc after an Overflow
        // packet), and computed only then.
        if (self.state.q.val() == PacketState::Decide) | (self.state.q.val() == PacketState::Crc) {
            // Header: magic "SA", version `PACKET_VERSION`, type, sequence number, length.
            self.rec_prefix[0].next = 0x53.into();
            self.rec_prefix[1].next = 0x41.into();
            self.rec_prefix[2].next = self.version.val();
            self.rec_prefix[3].next = self.type_code.val();
            for b in 0..4 {
                self.rec_prefix[4 + b].next = self.seq_ctr.q.val().get_bits::<8>(8 * b);
            }
            for b in 0..2 {
                self.rec_prefix[8 + b].next = self.payload_len.val().get_bits::<8>(8 * b);
            }
            match self.r_kind.val().index() {
                1 => {
                    self.rec_prefix[10].next = self.r_slot.val();
                    self.rec_prefix[11].next =
                        self.r_flags.val() | (bit_cast::<8, 1>(self.masked.q.val().into()) << 1);
                    for b in 0..2 {
                        self.rec_prefix[12 + b].next = self.r_ax.val().get_bits::<8>(8 * b);
                        self.rec_prefix[14 + b].next = self.r_ay.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..6 {
                        self.rec_prefix[16 + b].next = self.r_t0.val().get_bits::<8>(8 * b);
                        self.rec_prefix[22 + b].next = self.r_t1.val().get_bits::<8>(8 * b);
                        self.rec_prefix[28 + b].next = self.r_ts.val().get_bits::<8>(8 * b);
                        self.rec_prefix[34 + b].next = self.r_te.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..4 {
                        self.rec_prefix[40 + b].next = self.planes_r.q.val().get_bits::<8>(8 * b);
                    }
                    self.rec_prefix[44].next = self.roi_side.val();
                    self.rec_prefix[45].next = self.tb0.val();
                    self.rec_prefix[46].next = self.tb1.val();
                    self.rec_prefix[47].next = self.tb2.val();
                    self.rec_prefix[48].next = self.tb3.val();
                    self.rec_prefix[49].next = self.tb4.val();
                    self.rec_prefix[50].next = self.tb5.val();
                }
                2 => {
                    for b in 0..6 {
                        self.rec_prefix[10 + b].next = self.r_t0.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..4 {
                        self.rec_prefix[16 + b].next = self.r_t1.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..2 {
                        self.rec_prefix[20 + b].next = self.r_ax.val().get_bits::<8>(8 * b);
                        self.rec_prefix[22 + b].next = self.r_ay.val().get_bits::<8>(8 * b);
                    }
                }
                3 => {
                    for b in 0..8 {
                        self.rec_prefix[10 + b].next = self.c_planes.val().get_bits::<8>(8 * b);
                        self.rec_prefix[18 + b].next = self.c_blinks.val().get_bits::<8>(8 * b);
                        self.rec_prefix[26 + b].next = self.c_unconf.val().get_bits::<8>(8 * b);
                        self.rec_prefix[34 + b].next = self.c_dropped.val().get_bits::<8>(8 * b);
                        self.rec_prefix[42 + b].next = self.c_bridged.val().get_bits::<8>(8 * b);
                        self.rec_prefix[50 + b].next = self.c_cuts.val().get_bits::<8>(8 * b);
                    }
                }
                _ => {
                    // StreamStart: the generation's constant bytes (field, kernel)
                    // with the runtime registers in their zero bytes.
                    for j in 10..self._pb {
                        self.rec_prefix[j].next = self.start_bytes[j].val();
                    }
                    for b in 0..2 {
                        self.rec_prefix[14 + b].next = self.n16.val().get_bits::<8>(8 * b);
                    }
                    for b in 0..4 {
                        self.rec_prefix[18 + b].next = self.threshold.val().get_bits::<8>(8 * b);
                        self.rec_prefix[22 + b].next = self.l_min.val().get_bits::<8>(8 * b);
                        self.rec_prefix[26 + b].next = self.l_max.val().get_bits::<8>(8 * b);
                    }
                    for o in self._o_period..(self._o_period + 1) {
                        for b in 0..4 {
                            self.rec_prefix[o + b].next =
                                self.plane_period.val().get_bits::<8>(8 * b);
                        }
                    }
                    for o in self._o_masked..(self._o_masked + 1) {
                        for b in 0..4 {
                            self.rec_prefix[o + b].next =
                                self.masked_pixels.val().get_bits::<8>(8 * b);
                        }
                    }
                    for o in self._o_hold..(self._o_hold + 1) {
                        for b in 0..4 {
                            self.rec_prefix[o + b].next =
                                self.threshold_hold.val().get_bits::<8>(8 * b);
                        }
                    }
                    for o in self._o_trim..(self._o_trim + 1) {
                        for b in 0..4 {
                            self.rec_prefix[o + b].next = self.trim32.val().get_bits::<8>(8 * b);
                        }
                    }
                }
            }
            // Overflow: header (type 0x7F, the first lost number), length 8,
            // first lost number and count.
            self.ovf_prefix[0].next = 0x53.into();
            self.ovf_prefix[1].next = 0x41.into();
            self.ovf_prefix[2].next = self.version.val();
            self.ovf_prefix[3].next = 0x7F.into();
            self.ovf_prefix[8].next = 8.into();
            for b in 0..4 {
                self.ovf_prefix[4 + b].next = self.pend_first.q.val().get_bits::<8>(8 * b);
                self.ovf_prefix[10 + b].next = self.pend_first.q.val().get_bits::<8>(8 * b);
                self.ovf_prefix[14 + b].next = self.pend_cnt.q.val().get_bits::<8>(8 * b);
            }
        }

        // ---- The byte of this clock and the CRC.
        // (Verilog cannot slice an expression: shift into a signal first.)
        // Read only when nb ≥ 8, when nb − 8 ≤ 63 (nb < 8 + 64 after an
        // append): the mask changes no byte sent.
        self.pk_shift.next = self.pk.q.val() >> (self.nb8.q.val() & 63);
        self.pk_byte.next = self.pk_shift.val().get_bits::<8>(0);
        // Only the low nb < 8 bits of pk are still to be sent when it is
        // padded or a code is appended (older bits have left as bytes).
        self.pk_low.next = self.pk.q.val() & self.low_byte.val();
        // The nb bits to the top of the byte: `<< (8 − nb)` as `<< 8 >> nb`
        // (no subtraction before the shifter; nb < 8 when padding).
        self.pad_shift.next = (self.pk_low.val() << 8) >> (self.nb.q.val() & 7);
        self.pad_byte.next = self.pad_shift.val().get_bits::<8>(0);
        self.crc_shift.next = !(self.crc.q.val() >> (bit_cast::<32, 8>(self.crc_i.q.val()) << 3));
        // Read only while bytes go out (Ovf, Emit, Codes), and computed only
        // then: free in hardware, and a simulator skips the tree and the CRC
        // step on the other clocks.
        self.emitting.next = (self.state.q.val() == PacketState::Ovf)
            | (self.state.q.val() == PacketState::Emit)
            | (self.state.q.val() == PacketState::Codes);
        for j in 0..(2 * self._leaves) {
            self.sel_tree[j].next = 0.into();
        }
        self.the_byte.next = 0.into();
        self.crc_v.next = 0.into();
        for i in 0..8 {
            self.ct[i].next = 0.into();
        }
        self.crc_next.next = 0.into();
        if self.emitting.val() {
            // Byte `bidx` of the prefix through a binary tree of 2:1 byte
            // multiplexers (node i of the heap layout selects between 2i and
            // 2i + 1 by one bit of bidx; the leaves are the prefix bytes).
            // (rust-hdl's Verilog indexes with loop variables only.)
            self.sel_tree[0].next = 0.into();
            for lv in self._leaves..(self._leaves + 1) {
                for j in 0..self._leaves {
                    self.sel_tree[lv + j].next = 0.into();
                }
                for j in 0..self._pb {
                    self.sel_tree[lv + j].next = self.prefix.q[j].val();
                }
            }
            // Deepest nodes first (i = leaves − k), so that the process assigns
            // every node before it reads it.
            for lv in self._leaves..(self._leaves + 1) {
                for k in 1..self._leaves {
                    self.sel_tree[lv - k].next = self.sel_tree[2 * (lv - k)].val();
                    if self
                        .bidx
                        .q
                        .val()
                        .get_bit(self.tree_bit[lv - k].val().index())
                    {
                        self.sel_tree[lv - k].next = self.sel_tree[2 * (lv - k) + 1].val();
                    }
                }
            }
            self.the_byte.next = self.sel_tree[1].val();
            if self.state.q.val() == PacketState::Codes {
                self.the_byte.next = self.pad_byte.val();
                if self.nb.q.val() >= 8 {
                    self.the_byte.next = self.pk_byte.val();
                }
            }
            self.crc_v.next = self.crc.q.val().get_bits::<8>(0) ^ self.the_byte.val();
            for i in 0..8 {
                self.ct[i].next = 0.into();
                if self.crc_v.val().get_bit(i) {
                    self.ct[i].next = self.crc_t[i].val();
                }
            }
            self.crc_next.next = (self.crc.q.val() >> 8)
                ^ self.ct[0].val()
                ^ self.ct[1].val()
                ^ self.ct[2].val()
                ^ self.ct[3].val()
                ^ self.ct[4].val()
                ^ self.ct[5].val()
                ^ self.ct[6].val()
                ^ self.ct[7].val();
        }

        self.out_valid.next = false;
        self.out_byte.next = self.the_byte.val();
        self.r_pop.next = false;
        self.fb_ret.next = false;
        self.fb_ret_bank.next = self.r_bank.val();

        match self.state.q.val() {
            PacketState::Idle => {
                if self.r_valid.val() {
                    if self.r_lost.val() != 0 {
                        self.ovf_flag.d.next = true;
                        if self.pend_cnt.q.val() == 0 {
                            self.pend_first.d.next = self.seq_ctr.q.val();
                        }
                        self.pend_cnt.d.next = self.pend_cnt.q.val() + self.r_lost.val();
                    }
                    self.seq_ctr.d.next = self.seq_ctr.q.val() + self.r_lost.val();
                    if self.is_blink.val() {
                        self.state.d.next = PacketState::Wait;
                    } else {
                        self.state.d.next = PacketState::Decide;
                    }
                }
            }
            PacketState::Wait => {
                if self.r_ready.val() {
                    self.base.d.next = self.all_ones.val();
                    self.masked.d.next = false;
                    self.cs_active.d.next = true;
                    self.cs_dy.d.next = 0.into();
                    self.cs_dx.d.next = 0.into();
                    self.row_valid.d.next = false;
                    self.cs_wait.d.next = false;
                    self.state.d.next = PacketState::Pass1;
                }
            }
            PacketState::Pass1 => {
                if self.c_valid.val() & (self.c_val.val() < self.base.q.val()) {
                    self.base.d.next = self.c_val.val();
                }
                if !self.cs_active.q.val() {
                    for k in 0..self._kn {
                        self.acc[k].d.next = self.acc0[k].val();
                    }
                    self.cs_active.d.next = true;
                    self.cs_dy.d.next = 0.into();
                    self.cs_dx.d.next = 0.into();
                    self.state.d.next = PacketState::Pass2;
                }
            }
            PacketState::Pass2 => {
                // (The last offset is in stage A on the clock the streamer
                // stops, in stage L on the next, and is added on the clock
                // that leaves Pass2.)
                if self.lv.q.val() {
                    for k in 0..self._kn {
                        self.acc[k].d.next = self.acc[k].q.val() + self.lq[k].q.val();
                    }
                }
                if !self.cs_active.q.val() & !self.ca_v.q.val() {
                    self.best.d.next = 0xFFFF.into();
                    self.best_bytes.d.next = 0.into();
                    self.bestk.d.next = 0.into();
                    self.scan.d.next = 0.into();
                    self.state.d.next = PacketState::Choose;
                }
            }
            PacketState::Choose => {
                for k in 0..(self._kn - 1) {
                    self.acc[k].d.next = self.acc[k + 1].q.val();
                }
                if self.acc_j.val() < self.best.q.val() {
                    self.best.d.next = self.acc_j.val();
                    self.best_bytes.d.next = (self.acc_j.val() + 7) >> 3;
                    self.bestk.d.next = self.scan.q.val();
                }
                self.scan.d.next = self.scan.q.val() + 1;
                if self.scan.q.val() == self.k_last.val() {
                    self.state.d.next = PacketState::Decide;
                }
            }
            PacketState::Decide => {
                if self.dec_ready.q.val() & self.room.q.val() {
                    self.bidx.d.next = 0.into();
                    self.crc.d.next = 0xFFFF_FFFF_u64.into();
                    self.prefix_load.next = true;
                    // Every prefix has 18 bytes or more: its first is not its last.
                    self.prefix_last.d.next = false;
                    if self.pend_cnt.q.val() != 0 {
                        self.prefix_ovf.next = true;
                        self.prefix_rest.d.next = 17.into();
                        self.in_ovf.d.next = true;
                        self.state.d.next = PacketState::Ovf;
                    } else {
                        self.prefix_rest.d.next = self.rec_prefix_rest.val();
                        self.in_ovf.d.next = false;
                        self.state.d.next = PacketState::Emit;
                    }
                } else if self.dec_ready.q.val()
                    & ((self.r_kind.val() == 1) | (self.r_kind.val() == 2))
                {
                    // No room for the whole packet: drop the record, count it.
                    self.ovf_flag.d.next = true;
                    if self.pend_cnt.q.val() == 0 {
                        self.pend_first.d.next = self.seq_ctr.q.val();
                    }
                    self.pend_cnt.d.next = self.pend_cnt.q.val() + 1;
                    self.state.d.next = PacketState::Finish;
                }
            }
            PacketState::Ovf => {
                self.out_valid.next = true;
                self.crc.d.next = self.crc_next.val();
                self.bidx.d.next = self.bidx.q.val() + 1;
                self.prefix_rest.d.next = self.prefix_rest.q.val() - 1;
                self.prefix_last.d.next = self.prefix_rest.q.val() == 1;
                if self.prefix_last.q.val() {
                    self.crc_i.d.next = 0.into();
                    self.state.d.next = PacketState::Crc;
                }
            }
            PacketState::Emit => {
                self.out_valid.next = true;
                self.crc.d.next = self.crc_next.val();
                self.bidx.d.next = self.bidx.q.val() + 1;
                self.prefix_rest.d.next = self.prefix_rest.q.val() - 1;
                self.prefix_last.d.next = self.prefix_rest.q.val() == 1;
                if self.prefix_last.q.val() {
                    self.crc_i.d.next = 0.into();
                    if self.is_blink.val() {
                        self.nb.d.next = 0.into();
                        self.nb8.d.next = 0xF8.into();
                        self.cs_active.d.next = true;
                        self.cs_dy.d.next = 0.into();
                        self.cs_dx.d.next = 0.into();
                        self.state.d.next = PacketState::Codes;
                    } else {
                        self.state.d.next = PacketState::Crc;
                    }
                }
            }
            PacketState::Codes => {
                if self.nb.q.val() >= 8 {
                    self.out_valid.next = true;
                    self.crc.d.next = self.crc_next.val();
                    self.nb.d.next = self.nb.q.val() - 8;
                    self.nb8.d.next = self.nb8.q.val() - 8;
                } else if self.cc_v.q.val() {
                    self.pk.d.next = (self.pk_low.val() << self.cc_len.q.val())
                        | bit_cast::<72, 64>(self.cc_code.q.val());
                    self.nb.d.next = self.nb.q.val() + self.cc_len.q.val();
                    self.nb8.d.next = self.nb8.q.val() + self.cc_len.q.val();
                } else if !self.cs_active.q.val() & !self.ca_v.q.val() & !self.cb_v.q.val() {
                    if self.nb.q.val() != 0 {
                        self.out_valid.next = true;
                        self.crc.d.next = self.crc_next.val();
                        self.nb.d.next = 0.into();
                        self.nb8.d.next = 0xF8.into();
                    } else {
                        self.state.d.next = PacketState::Crc;
                    }
                }
            }
            PacketState::Crc => {
                self.out_valid.next = true;
                self.out_byte.next = self.crc_shift.val().get_bits::<8>(0);
                self.crc_i.d.next = self.crc_i.q.val() + 1;
                if self.crc_i.q.val() == 3 {
                    if self.in_ovf.q.val() {
                        // The Overflow packet is out: now the record.
                        self.pend_cnt.d.next = 0.into();
                        self.in_ovf.d.next = false;
                        self.prefix_load.next = true;
                        self.prefix_rest.d.next = self.rec_prefix_rest.val();
                        self.prefix_last.d.next = false;
                        self.bidx.d.next = 0.into();
                        self.crc.d.next = 0xFFFF_FFFF_u64.into();
                        self.state.d.next = PacketState::Emit;
                    } else {
                        self.state.d.next = PacketState::Finish;
                    }
                }
            }
            PacketState::Finish => {
                self.r_pop.next = true;
                self.fb_ret.next = self.is_blink.val();
                self.seq_ctr.d.next = self.seq_ctr.q.val() + 1;
                self.state.d.next = PacketState::Idle;
            }
            _ => {}
        }

        if self.restart.val() {
            self.state.d.next = PacketState::Idle;
            self.seq_ctr.d.next = self.seq_init.val();
            self.pend_cnt.d.next = 0.into();
            self.ovf_flag.d.next = false;
            self.cs_active.d.next = false;
            self.ca_v.d.next = false;
            self.cb_v.d.next = false;
            self.lv.d.next = false;
            self.cc_v.d.next = false;
        }
        // The prefix registers hold between packets without a copy a clock
        // (a clock enable): their next value exists only when they load.
        self.prefix.enable.next = self.prefix_load.val();
        for j in 0..self._pb {
            self.prefix.d[j].next = 0.into();
            if self.prefix_load.val() {
                self.prefix.d[j].next = self.rec_prefix[j].val();
                if self.prefix_ovf.val() {
                    self.prefix.d[j].next = self.ovf_prefix[j].val();
                }
            }
        }
        self.idle.next = (self.state.q.val() == PacketState::Idle) & !self.r_valid.val();
        self.overflowed.next = self.ovf_flag.q.val();
    }
}
