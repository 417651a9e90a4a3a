//! Stage 6 — ROI aggregation: per slot, R×R counters summing the raw
//! (masked) delayed plane `B_{t−N}` while the tracker says so (its ROI
//! view's `pre`, the model's `sums_delayed`: a segment sums its planes as
//! they leave the window, never the live plane), as
//! [`smartagg_model::roi_aggregator`].
//!
//! **Row skew.** A track opens only when its candidate has come out of the
//! front half, c + 1 rows after its row went in. The raw delayed and mask
//! bits therefore go into a ring of
//! [`BackHalfConfig::row_buffer_rows`] rows (c + h + 5 rows of lag plus the
//! sweep backlog), and raw row r of plane t is summed (*swept*) only once
//! the tracker has finished row `min(r + h + 2, H)` of plane t: by then
//! every slot whose ROI covers row r has its final flags for plane t in the
//! tracker's ROI view (see [`crate::blink_tracker`]), including tracks
//! opened by candidates up to row r + h. (Only the openings need the wait:
//! the tracker's on/off step at row `ay + 1` changes no view, so
//! `r + h + 1` rows would do; the margin is kept.) A ring overrun (the
//! sweep fell a whole ring behind) sets the sticky `overrun` flag.
//!
//! **Sweep.** For each raw row, the slots whose ROI covers it and that sum
//! this plane (`pre`) or start in it (`fresh`) ([`RowCover`]) are taken one
//! per clock, lowest slot first: the R bits of the row at columns
//! `ax − h … ax + h` are cut from the two words that hold them (even and
//! odd words in separate banks, both read in one clock; columns outside the
//! sensor read 0), and the R counters of that ROI row are read, incremented
//! by `delayed·pre`, and written back the next clock. Four stages, so that
//! no path between registers is long: S0 picks the slot ([`LowestSlot`])
//! and registers its index; SV reads its view entry ([`ViewMux`]); SA
//! computes the word and counter addresses; S1 cuts the ROI row
//! ([`RoiRow`]), adds and writes. The view of plane t stays untouched until
//! the sweep has finished t, so reading it at SV is as good as at the
//! row's start; `planes_done` and the rows the writer may reuse lag the
//! sweep's own counters by the two clocks that SV and SA add. `need` and
//! `rhi` (what row `ra` waits for, and `ra + h`) move with `ra` instead of
//! being computed from it. In the first plane of a segment (`fresh`) the
//! old counts read as zero, so counters never need clearing; as every
//! segment is swept in its first plane (even an opening at `t < N`, which
//! sums nothing yet), its counters and mask flags are its own from then
//! on, and a segment that sums no plane at all reads zero counts. ROI rows
//! outside the sensor are never swept; the packetiser reads them as 0. The
//! MASKED flag is the OR of the mask bits of the ROI, kept beside each
//! counter row.
//!
//! **Counters: block RAM.** R memories (one per ROI column) of
//! `(M + Q)·R` counter rows of RCW bits, plus one 1-bit memory for the mask
//! flags: for the SPCImager (M = 32, Q = 32, R = 9, RCW = 17) that is
//! 9 × 576 × 17 bits, nine 9-Kbit block RAMs, against 57 Kbit of LUT RAM
//! (≈ 900 LUTs as 64×1 RAM) — block RAM wins. Every slot owns one bank of R
//! rows; a completed segment hands its bank to the record queue and takes a
//! free one ([`BankPool`]). The packetiser reads queued banks through the
//! memories' read port whenever the sweep does not use it (`rd_grant`).
//!
//! **Throughput.** A row costs one clock plus one per relevant slot beyond
//! the first; R rows bring R·W/P word clocks at most, so the sweep keeps up
//! when `M + 1 ≤ W/P` and otherwise needs `⌈R·(M + 1 − W/P)/(W/P)⌉` rows of
//! slack, plus the rows the tracker may fall behind in a plane (`2M + 5`
//! clocks: its walk, and its replays after openings):
//! [`BackHalfConfig::default_row_slack`].

mod lowest_slot;
mod roi_row;
mod row_cover;
mod view_mux;

pub use crate::bank_pool::BankPool;
use crate::blink_tracker::COORD_BITS;
use crate::bram::{Bram, RamStyle};
use crate::config::MAX_SLOTS;
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::const_mul::ConstMul;
use crate::stream::lanes;
pub use lowest_slot::LowestSlot;
pub use roi_row::RoiRow;
pub use row_cover::RowCover;
use rust_hdl::prelude::*;
pub use view_mux::ViewMux;

/// The ROI aggregator. `P`: pixels per word; `RAW`: row-buffer bank address
/// bits; `RCW`: counter bits; `CAW`: counter address bits; `BW`: bank bits.
#[derive(LogicBlock)]
pub struct RoiAggregator<
    const P: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW: usize,
    const BW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: plane 0, row 0, empty ring.
    pub restart: Signal<In, Bit>,
    /// A raw word of a real or drain plane (raster order).
    pub in_valid: Signal<In, Bit>,
    /// Its word column.
    pub in_x: Signal<In, Bits<16>>,
    /// `B_{t−N}`.
    pub in_delayed: Signal<In, Bits<P>>,
    /// Hot-pixel mask bits.
    pub in_mask: Signal<In, Bits<P>>,
    /// Tracker plane.
    pub tr_plane: Signal<In, Bits<48>>,
    /// Tracker rows done in that plane.
    pub tr_rows: Signal<In, Bits<16>>,
    /// Tracker ROI view (index parity·M + slot): one word per entry, the
    /// fields at
    /// [`crate::blink_tracker::shadow`]'s offsets.
    pub sh: Vec<Signal<In, Bits<64>>>,
    /// Planes whose every row has been swept.
    pub planes_done: Signal<Out, Bits<48>>,
    /// The ring was overrun (sticky; sums are then wrong).
    pub overrun: Signal<Out, Bit>,
    /// Raw rows written and not yet swept: how far the ring is filled. A
    /// source that can wait (the replay) holds its words while this is near
    /// [`BackHalfConfig::row_buffer_rows`] ([`crate::back_half::BackHalf`]'s `room`).
    pub backlog: Signal<Out, Bits<16>>,
    /// Counter read request (packetiser).
    pub rd_req: Signal<In, Bit>,
    /// Counter row address: bank·R + ROI row.
    pub rd_addr: Signal<In, Bits<CAW>>,
    /// The request is taken this clock; the row follows next clock.
    pub rd_grant: Signal<Out, Bit>,
    /// The R counts of the row read.
    pub rd_counts: Vec<Signal<Out, Bits<RCW>>>,
    /// The row's mask flag.
    pub rd_masked: Signal<Out, Bit>,
    /// The row buffer: delayed and mask bits of even words (0, 1) and of
    /// odd words (2, 3).
    ring: Vec<Bram<P, RAW>>,
    cnt: Vec<Bram<RCW, CAW>>,
    msk: Bram<1, CAW>,
    bank_base: ConstMul<CAW>,
    /// A row's start: the slots it visits.
    row_cover: RowCover,
    /// S0: the lowest slot of `rel`.
    pick: LowestSlot,
    /// SV: the selected entry of the ROI view.
    views: ViewMux,
    /// S1: the ROI row's bits from the two ring words.
    row: RoiRow<P>,
    // Writer.
    wbase: DFF<Bits<RAW>>,
    wslot: DFF<Bits<16>>,
    gw: DFF<Bits<16>>,
    ovf: DFF<Bit>,
    // Sweep.
    sweeping: DFF<Bit>,
    /// Slots still to sweep in the row (bit i: slot i: one register, not one
    /// per slot, as in the tracker).
    rel: DFF<Bits<MAX_SLOTS>>,
    rbase: DFF<Bits<RAW>>,
    rslot: DFF<Bits<16>>,
    gs: DFF<Bits<16>>,
    ta: DFF<Bits<48>>,
    /// `ra + h`: the last ROI row that covers row `ra`, kept beside `ra`
    /// rather than computed from it.
    rhi: DFF<Bits<COORD_BITS>>,
    /// `gs` two clocks later: the rows the writer may reuse (a row's last
    /// slot reads the ring, at SA, two clocks after the row is done).
    gs_v: DFF<Bits<16>>,
    gs_w: DFF<Bits<16>>,
    /// `ta` two clocks later: a swept plane's last counter write, at S1,
    /// comes two clocks after its row is done.
    pd_v: DFF<Bits<48>>,
    pd: DFF<Bits<48>>,
    // View stage (SV): the selected entry's index, registered after the
    // slot priority logic; the entry is read through a binary multiplexer.
    v_valid: DFF<Bit>,
    /// The selected entry: bit 5 the plane's parity, bits 0–4 the slot.
    v_idx: DFF<Bits<6>>,
    v_row_hi: DFF<Bits<COORD_BITS>>,
    v_rbase: DFF<Bits<RAW>>,
    // Address stage (SA): the selected slot's view, registered after the
    // view multiplexer, with the row it sweeps.
    a_valid: DFF<Bit>,
    /// The selected slot's view entry (fields at
    /// [`crate::blink_tracker::shadow`]'s offsets).
    a_view: DFF<Bits<64>>,
    a_row_hi: DFF<Bits<COORD_BITS>>,
    a_rbase: DFF<Bits<RAW>>,
    ra: DFF<Bits<16>>,
    s1_valid: DFF<Bit>,
    s1_pre: DFF<Bit>,
    s1_fresh: DFF<Bit>,
    s1_off: DFF<Bits<16>>,
    /// P − `s1_off`, registered beside it: the window's shifts start from
    /// registers rather than behind a subtraction.
    s1_sh_hi: DFF<Bits<16>>,
    s1_lo_ok: DFF<Bit>,
    s1_hi_ok: DFF<Bit>,
    s1_odd: DFF<Bit>,
    s1_addr: DFF<Bits<CAW>>,
    // Combinational.
    pending: Signal<Local, Bits<16>>,
    par: Signal<Local, Bit>,
    /// Tracker rows that row `ra` waits for: `min(ra + h + 2, H)`, kept
    /// beside `ra` rather than computed from it.
    need: DFF<Bits<16>>,
    /// The tracker's plane minus the sweep's, low four bits.
    dplane: Signal<Local, Bits<4>>,
    trig: Signal<Local, Bit>,
    /// Start the sweep of row `ra`.
    go: Signal<Local, Bit>,
    /// `rhi + 1`.
    rhi1: Signal<Local, Bits<COORD_BITS>>,
    rest_any: Signal<Local, Bit>,
    row_done: Signal<Local, Bit>,
    s0: Signal<Local, Bit>,
    /// The selected entry: the lowest slot's index, the plane's parity at
    /// bit 5.
    slot_idx: Signal<Local, Bits<6>>,
    dy: Signal<Local, Bits<COORD_BITS>>,
    x0p: Signal<Local, Bits<16>>,
    wq: Signal<Local, Bits<16>>,
    half_wq: Signal<Local, Bits<16>>,
    odd_addr: Signal<Local, Bits<16>>,
    caddr: Signal<Local, Bits<CAW>>,
    inc: Vec<Signal<Local, Bits<RCW>>>,
    old: Vec<Signal<Local, Bits<RCW>>>,
    old_m: Signal<Local, Bit>,
    any_m: Signal<Local, Bit>,
    // Constants.
    h_c: Constant<Bits<COORD_BITS>>,
    /// `min(h + 2, H)`: `need` of row 0.
    need0: Constant<Bits<16>>,
    p_minus_h: Constant<Bits<16>>,
    pw: Constant<Bits<16>>,
    pm1: Constant<Bits<16>>,
    log2p: Constant<Bits<8>>,
    rows_h: Constant<Bits<16>>,
    last_row: Constant<Bits<16>>,
    last_word: Constant<Bits<16>>,
    words: Constant<Bits<16>>,
    half_words: Constant<Bits<RAW>>,
    ring_rows: Constant<Bits<16>>,
    last_slot_row: Constant<Bits<16>>,
    roi_mask: Constant<Bits<P>>,
    _m: usize,
    _r: usize,
}

impl<const P: usize, const RAW: usize, const RCW: usize, const CAW: usize, const BW: usize>
    RoiAggregator<P, RAW, RCW, CAW, BW>
{
    /// The aggregator of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        let f = &cfg.front;
        GatewareConfig::check_width("RoiAggregator", "P", P, f.pixels_per_clock)?;
        GatewareConfig::check_width("RoiAggregator", "RAW", RAW, cfg.row_addr_bits())?;
        GatewareConfig::check_width("RoiAggregator", "RCW", RCW, cfg.roi_count_bits())?;
        GatewareConfig::check_width("RoiAggregator", "CAW", CAW, cfg.counter_addr_bits())?;
        GatewareConfig::check_width("RoiAggregator", "BW", BW, cfg.bank_bits())?;
        let (m, r, h) = (cfg.slots, cfg.roi_size, cfg.roi_half());
        let c16 = |v: u64| Constant::new(v.to_bits());
        let ring_depth = cfg.row_buffer_rows() * cfg.half_words_per_row();
        let ring_style = if ring_depth <= 64 {
            RamStyle::Distributed
        } else {
            RamStyle::Block
        };
        let counter_rows = cfg.banks() * r;
        Ok(RoiAggregator {
            clock: Default::default(),
            restart: Default::default(),
            in_valid: Default::default(),
            in_x: Default::default(),
            in_delayed: Default::default(),
            in_mask: Default::default(),
            tr_plane: Default::default(),
            tr_rows: Default::default(),
            sh: lanes(2 * m),
            planes_done: Default::default(),
            overrun: Default::default(),
            backlog: Default::default(),
            rd_req: Default::default(),
            rd_addr: Default::default(),
            rd_grant: Default::default(),
            rd_counts: lanes(r),
            rd_masked: Default::default(),
            ring: (0..4).map(|_| Bram::new(ring_depth, ring_style)).collect(),
            cnt: (0..r)
                .map(|_| Bram::new(counter_rows, RamStyle::Block))
                .collect(),
            // Block RAM: 1 × (M + Q)·R bits is one RAMB8, 14 RAM64M of LUT RAM
            // for the SPCImager.
            msk: Bram::new(counter_rows, RamStyle::Block),
            bank_base: ConstMul::new(r as u32),
            row_cover: RowCover::new(m, h),
            pick: LowestSlot::new(),
            views: ViewMux::new(m),
            row: Default::default(),
            wbase: Default::default(),
            wslot: Default::default(),
            gw: Default::default(),
            ovf: Default::default(),
            sweeping: Default::default(),
            rel: Default::default(),
            rbase: Default::default(),
            rslot: Default::default(),
            gs: Default::default(),
            ta: Default::default(),
            rhi: Default::default(),
            gs_v: Default::default(),
            gs_w: Default::default(),
            pd_v: Default::default(),
            pd: Default::default(),
            v_valid: Default::default(),
            v_idx: Default::default(),
            v_row_hi: Default::default(),
            v_rbase: Default::default(),
            a_valid: Default::default(),
            a_view: Default::default(),
            a_row_hi: Default::default(),
            a_rbase: Default::default(),
            ra: Default::default(),
            s1_valid: Default::default(),
            s1_pre: Default::default(),
            s1_fresh: Default::default(),
            s1_off: Default::default(),
            s1_sh_hi: Default::default(),
            s1_lo_ok: Default::default(),
            s1_hi_ok: Default::default(),
            s1_odd: Default::default(),
            s1_addr: Default::default(),
            pending: Default::default(),
            par: Default::default(),
            need: Default::default(),
            dplane: Default::default(),
            trig: Default::default(),
            go: Default::default(),
            rhi1: Default::default(),
            rest_any: Default::default(),
            row_done: Default::default(),
            s0: Default::default(),
            slot_idx: Default::default(),
            dy: Default::default(),
            x0p: Default::default(),
            wq: Default::default(),
            half_wq: Default::default(),
            odd_addr: Default::default(),
            caddr: Default::default(),
            inc: lanes(r),
            old: lanes(r),
            old_m: Default::default(),
            any_m: Default::default(),
            h_c: Constant::new((h as u64).to_bits()),
            need0: c16((h as u64 + 2).min(f.height as u64)),
            p_minus_h: c16((P - h) as u64),
            pw: c16(P as u64),
            pm1: c16(P as u64 - 1),
            log2p: Constant::new((cfg.log2_p() as u64).to_bits()),
            rows_h: c16(f.height as u64),
            last_row: c16(f.height as u64 - 1),
            last_word: c16(f.words_per_row() as u64 - 1),
            words: c16(f.words_per_row() as u64),
            half_words: Constant::new((cfg.half_words_per_row() as u64).to_bits()),
            ring_rows: c16(cfg.row_buffer_rows() as u64),
            last_slot_row: c16(cfg.row_buffer_rows() as u64 - 1),
            roi_mask: Constant::new(((1u64 << r) - 1).to_bits()),
            _m: m,
            _r: r,
        })
    }
}

impl<const P: usize, const RAW: usize, const RCW: usize, const CAW: usize, const BW: usize> Logic
    for RoiAggregator<P, RAW, RCW, CAW, BW>
{
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, wbase, wslot, gw, ovf, sweeping, rbase, rslot, gs, ta, rhi, gs_v, gs_w,
            pd_v, pd, v_valid, v_idx, v_row_hi, v_rbase, ra, need, a_valid, a_view, a_row_hi,
            a_rbase, s1_valid, s1_pre, s1_fresh, s1_off, s1_sh_hi, s1_lo_ok, s1_hi_ok, s1_odd,
            s1_addr, rel
        );
        for q in 0..4 {
            self.ring[q].clock.next = self.clock.val();
        }
        for dx in 0..self._r {
            self.cnt[dx].clock.next = self.clock.val();
        }
        self.msk.clock.next = self.clock.val();

        // ---- Writer: even words to ring 0..1, odd words to ring 2..3.
        self.pending.next = self.gw.q.val() - self.gs_w.q.val();
        self.gs_v.d.next = self.gs.q.val();
        self.gs_w.d.next = self.gs_v.q.val();
        self.pd_v.d.next = self.ta.q.val();
        self.pd.d.next = self.pd_v.q.val();
        for q in 0..4 {
            self.ring[q].write_address.next =
                self.wbase.q.val() + bit_cast::<RAW, 16>(self.in_x.val() >> 1);
        }
        self.ring[0].write_data.next = self.in_delayed.val();
        self.ring[1].write_data.next = self.in_mask.val();
        self.ring[2].write_data.next = self.in_delayed.val();
        self.ring[3].write_data.next = self.in_mask.val();
        for q in 0..2 {
            self.ring[q].write_enable.next = self.in_valid.val() & !self.in_x.val().get_bit(0);
        }
        for q in 2..4 {
            self.ring[q].write_enable.next = self.in_valid.val() & self.in_x.val().get_bit(0);
        }
        if self.in_valid.val() {
            if self.pending.val() >= self.ring_rows.val() {
                self.ovf.d.next = true;
            }
            if self.in_x.val() == self.last_word.val() {
                self.gw.d.next = self.gw.q.val() + 1;
                if self.wslot.q.val() == self.last_slot_row.val() {
                    self.wslot.d.next = 0.into();
                    self.wbase.d.next = 0.into();
                } else {
                    self.wslot.d.next = self.wslot.q.val() + 1;
                    self.wbase.d.next = self.wbase.q.val() + self.half_words.val();
                }
            }
        }

        // ---- Is the next raw row (ta, ra) ready to sweep?
        self.par.next = self.ta.q.val().get_bit(0);
        // The tracker never runs more than a plane ahead of the sweep (its
        // plane ends wait for `planes_done`) and the sweep never passes it,
        // so the low four bits of the planes' difference decide.
        self.dplane.next = self.tr_plane.val().get_bits::<4>(0) - self.ta.q.val().get_bits::<4>(0);
        self.trig.next = (self.gw.q.val() != self.gs.q.val())
            & (((self.dplane.val() != 0) & !self.dplane.val().get_bit(3))
                | ((self.dplane.val() == 0) & (self.tr_rows.val() >= self.need.q.val())));
        self.go.next = self.trig.val() & !self.sweeping.q.val();

        // ---- Slots whose ROI covers row ra and that sum this plane or start
        // in it ([`RowCover`]): read only when a row's sweep starts.
        for q in 0..(2 * self._m) {
            // (Offsets: `shadow`; literals for hdl_gen.)
            self.row_cover.anchor_rows[q].next = self.sh[q].val().get_bits::<10>(10);
            self.row_cover.sums_or_starts[q].next =
                self.sh[q].val().get_bit(62) | self.sh[q].val().get_bit(63);
        }
        self.row_cover.parity.next = self.par.val();
        self.row_cover.row_hi.next = self.rhi.q.val();
        self.row_cover.enable.next = self.go.val();

        // ---- S0: the lowest relevant slot ([`LowestSlot`]).
        self.pick.slots.next = self.rel.q.val();
        self.s0.next = self.sweeping.q.val() & self.pick.any.val();
        self.slot_idx.next = bit_cast::<6, 5>(self.pick.index.val());
        self.slot_idx.next = self.slot_idx.val().replace_bit(5, self.par.val());

        // ---- S0 → SV: the selected entry's index and its row, registered
        // (the priority logic is S0's).
        self.v_valid.d.next = self.s0.val();
        self.v_idx.d.next = self.slot_idx.val();
        self.v_row_hi.d.next = self.rhi.q.val();
        self.v_rbase.d.next = self.rbase.q.val();

        // ---- SV → SA: the selected slot's view ([`ViewMux`]) and its row,
        // registered. Entries of plane t stay untouched until the sweep has
        // finished t (`planes_done` lags S1), so reading one at SV is as
        // good as at the row's start.
        for q in 0..(2 * self._m) {
            self.views.entries[q].next = self.sh[q].val();
        }
        self.views.valid.next = self.v_valid.q.val();
        self.views.index.next = self.v_idx.q.val();
        self.a_valid.d.next = self.v_valid.q.val();
        self.a_view.d.next = self.views.entry.val();
        self.a_row_hi.d.next = self.v_row_hi.q.val();
        self.a_rbase.d.next = self.v_rbase.q.val();

        // ---- SA: addresses of the two words and of the counter row.
        self.dy.next = self.a_row_hi.q.val() - self.a_view.q.val().get_bits::<10>(10);
        // Column ax − h, shifted by one word so that it is never negative.
        self.x0p.next =
            bit_cast::<16, 10>(self.a_view.q.val().get_bits::<10>(0)) + self.p_minus_h.val();
        self.wq.next = self.x0p.val() >> self.log2p.val();
        self.half_wq.next = self.wq.val() >> 1;
        self.odd_addr.next = self.half_wq.val();
        if !self.wq.val().get_bit(0) {
            self.odd_addr.next = self.half_wq.val() - 1;
        }
        for q in 0..2 {
            self.ring[q].read_address.next =
                self.a_rbase.q.val() + bit_cast::<RAW, 16>(self.half_wq.val());
        }
        for q in 2..4 {
            self.ring[q].read_address.next =
                self.a_rbase.q.val() + bit_cast::<RAW, 16>(self.odd_addr.val());
        }
        self.bank_base.x.next = bit_cast::<CAW, BW>(self.a_view.q.val().get_bits::<BW>(20));
        self.caddr.next = self.bank_base.y.val() + bit_cast::<CAW, 10>(self.dy.val());
        for dx in 0..self._r {
            self.cnt[dx].read_address.next = self.rd_addr.val();
            if self.a_valid.q.val() {
                self.cnt[dx].read_address.next = self.caddr.val();
            }
        }
        self.msk.read_address.next = self.rd_addr.val();
        if self.a_valid.q.val() {
            self.msk.read_address.next = self.caddr.val();
        }
        self.rd_grant.next = self.rd_req.val() & !self.a_valid.q.val();
        self.s1_valid.d.next = self.a_valid.q.val();
        self.s1_pre.d.next = self.a_view.q.val().get_bit(62);
        self.s1_fresh.d.next = self.a_view.q.val().get_bit(63);
        self.s1_off.d.next = self.x0p.val() & self.pm1.val();
        self.s1_sh_hi.d.next = self.pw.val() - (self.x0p.val() & self.pm1.val());
        self.s1_lo_ok.d.next = self.wq.val() != 0;
        self.s1_hi_ok.d.next = self.wq.val() < self.words.val();
        self.s1_odd.d.next = self.wq.val().get_bit(0);
        self.s1_addr.d.next = self.caddr.val();

        // ---- S1: the R columns of the ROI row ([`RoiRow`]), added to its
        // counters.
        self.row.even_delayed.next = self.ring[0].read_data.val();
        self.row.even_mask.next = self.ring[1].read_data.val();
        self.row.odd_delayed.next = self.ring[2].read_data.val();
        self.row.odd_mask.next = self.ring[3].read_data.val();
        self.row.wq_odd.next = self.s1_odd.q.val();
        self.row.lo_ok.next = self.s1_lo_ok.q.val();
        self.row.hi_ok.next = self.s1_hi_ok.q.val();
        self.row.off.next = self.s1_off.q.val();
        self.row.sh_hi.next = self.s1_sh_hi.q.val();
        for dx in 0..self._r {
            self.old[dx].next = self.cnt[dx].read_data.val();
            if self.s1_fresh.q.val() {
                self.old[dx].next = 0.into();
            }
            self.inc[dx].next = 0.into();
            if self.s1_pre.q.val() & self.row.delayed.val().get_bit(dx) {
                self.inc[dx].next = 1.into();
            }
            self.cnt[dx].write_address.next = self.s1_addr.q.val();
            self.cnt[dx].write_data.next = self.old[dx].val() + self.inc[dx].val();
            self.cnt[dx].write_enable.next = self.s1_valid.q.val();
            self.rd_counts[dx].next = self.cnt[dx].read_data.val();
        }
        self.old_m.next = self.msk.read_data.val().any() & !self.s1_fresh.q.val();
        self.any_m.next = (self.row.mask.val() & self.roi_mask.val()).any();
        self.msk.write_address.next = self.s1_addr.q.val();
        self.msk.write_data.next = (self.old_m.val() | self.any_m.val()).into();
        self.msk.write_enable.next = self.s1_valid.q.val();
        self.rd_masked.next = self.msk.read_data.val().any();

        // ---- Sweep control: a row costs its start and one clock per
        // relevant slot (at least one; a row no slot covers is done on the
        // clock after its start, which reads `rel` rather than an OR of the
        // comparisons it is loaded from); the row is done with its last slot.
        self.rest_any.next = self.pick.rest.val().any();
        self.row_done.next = false;
        if self.go.val() {
            self.sweeping.d.next = true;
            self.rel.d.next = self.row_cover.slots.val();
        }
        if self.sweeping.q.val() {
            self.rel.d.next = self.pick.rest.val();
            if !self.rest_any.val() {
                self.sweeping.d.next = false;
                self.row_done.next = true;
            }
        }
        self.rhi1.next = self.rhi.q.val() + 1;
        if self.row_done.val() {
            self.gs.d.next = self.gs.q.val() + 1;
            if self.rslot.q.val() == self.last_slot_row.val() {
                self.rslot.d.next = 0.into();
                self.rbase.d.next = 0.into();
            } else {
                self.rslot.d.next = self.rslot.q.val() + 1;
                self.rbase.d.next = self.rbase.q.val() + self.half_words.val();
            }
            if self.ra.q.val() == self.last_row.val() {
                self.ra.d.next = 0.into();
                self.ta.d.next = self.ta.q.val() + 1;
                self.need.d.next = self.need0.val();
                self.rhi.d.next = self.h_c.val();
            } else {
                self.ra.d.next = self.ra.q.val() + 1;
                self.rhi.d.next = self.rhi1.val();
                if self.need.q.val() != self.rows_h.val() {
                    self.need.d.next = self.need.q.val() + 1;
                }
            }
        }

        if self.restart.val() {
            self.wbase.d.next = 0.into();
            self.wslot.d.next = 0.into();
            self.gw.d.next = 0.into();
            self.ovf.d.next = false;
            self.sweeping.d.next = false;
            self.rbase.d.next = 0.into();
            self.rslot.d.next = 0.into();
            self.gs.d.next = 0.into();
            self.ta.d.next = 0.into();
            self.need.d.next = self.need0.val();
            self.gs_v.d.next = 0.into();
            self.gs_w.d.next = 0.into();
            self.pd_v.d.next = 0.into();
            self.pd.d.next = 0.into();
            self.rhi.d.next = self.h_c.val();
            self.v_valid.d.next = false;
            self.a_valid.d.next = false;
            self.ra.d.next = 0.into();
            self.s1_valid.d.next = false;
            self.rel.d.next = 0.into();
        }
        self.planes_done.next = self.pd.q.val();
        self.overrun.next = self.ovf.q.val();
        self.backlog.next = self.pending.val();
    }
}
