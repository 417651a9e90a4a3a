//! The whole pipeline, gateware twin of `model/src/pipeline.rs`: stream
//! control, hot-pixel mask, delay line, front half (rolling count, filter,
//! threshold, candidates), back half (blink tracker, ROI aggregator,
//! packetiser) and the output FIFO. With no back-pressure it produces the
//! byte stream of `model::pipeline::run` + `model::packetiser::encode_stream`.
//!
//! **Stream start** ([`StreamControl`]): START checks the registers as the
//! model's `PipelineConfig::validate` does (1 ≤ N ≤ N_max, T_int ≥ 1,
//! 1 ≤ T_hold ≤ T_int, END_TRIM ≤ N − 1, L_min ≥ 1,
//! max(L_min, N) ≤ L_max ≤ L_max,max; otherwise `config_error` and nothing
//! starts; the check is a register of the START clock's values and decides
//! a clock later), latches N, T_int, T_hold, END_TRIM, L_min, L_max, the
//! plane period, the masked-pixel count and MASK_ENABLE, restarts every
//! block (the tracker then pushes StreamStart,
//! sequence 0) and waits for the first `sop`. The front half compares H with
//! `min(T_int, 2^HW − 1)` (candidates) and `min(T_hold, 2^HW − 1)` (the
//! tracker's on/off bits), which decide the same since
//! `H ≤ N_max·2^(2a) < 2^HW − 1`.
//!
//! **Stream end**: STOP takes effect at the next plane boundary (a partial
//! plane is completed first). The control then sends N *drain planes* —
//! stored in the delay line, so that `B_{p−N} … B_{p−1}` come out for the
//! sums still open, as the model's `Pipeline::finish` reads them from its
//! delay line — and one flush plane that pushes the last rows out of the
//! row-lagged stages; the tracker truncates the live tracks after plane
//! p − 1, completes their sums (and those of segments that dropped and
//! wait for their last planes) during the drain planes, emits the
//! remaining segments and StreamEnd. `ended` rises when the last byte is in
//! the output FIFO. With p = 0 planes nothing is drained.
//!
//! **Throughput.** Every stage takes one word per clock; the back half needs
//! one clock per word with an above-threshold pixel, one per extra candidate
//! in a word, one after each opening that another candidate follows (at most
//! M a plane), M + 5 per plane and one per ROI row per slot; the sensor's
//! 47.6 % duty cycle at P = 16 (see the crate docs) leaves that headroom.
//! A source that can wait (the replay) is paced by `ready` instead: the
//! stream accepts words and the back half has room (the tracker's FIFO and
//! the ROI ring each keep a margin for the words already on their way), so
//! it may send a word on every clock and a dense scene only slows it down.
//! Every place where a burst could exceed a buffer has a sticky flag
//! (`fault`): never a silent loss.

use crate::blink_tracker::{BlinkTracker, COORD_BITS};
use crate::bram::RamStyle;
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::delay_line::DelayLine;
use crate::delay_line_ddr::DelayLineDdr;
use crate::fifo::Fifo;
use crate::front_half::FrontHalf;
use crate::hot_pixel_mask::HotPixelMask;
use crate::packetiser::Packetiser;
use crate::record_finisher::RecordFinisher;
use crate::record_queue::RecordQueue;
use crate::roi_aggregator::{BankPool, RoiAggregator};
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// P one-bit lanes as one P-bit word (lane i in bit i).
#[derive(LogicBlock)]
pub struct PackLanes<const P: usize> {
    /// Lanes.
    pub lanes: Vec<Signal<In, Bit>>,
    /// Word.
    pub word: Signal<Out, Bits<P>>,
    part: Vec<Signal<Local, Bits<P>>>,
    one: Vec<Constant<Bits<P>>>,
}

impl<const P: usize> Default for PackLanes<P> {
    fn default() -> Self {
        PackLanes {
            lanes: lanes(P),
            word: Default::default(),
            part: lanes(P + 1),
            one: (0..P)
                .map(|i| Constant::new((1u64 << i).to_bits()))
                .collect(),
        }
    }
}

impl<const P: usize> Logic for PackLanes<P> {
    #[hdl_gen]
    fn update(&mut self) {
        self.part[0].next = 0.into();
        for i in 0..P {
            self.part[i + 1].next = self.part[i].val();
            if self.lanes[i].val() {
                self.part[i + 1].next = self.part[i].val() | self.one[i].val();
            }
        }
        for pp in P..(P + 1) {
            self.word.next = self.part[pp].val();
        }
    }
}

/// Tracker, ROI aggregator, bank pool, record queue, packetiser and output
/// FIFO, fed by the front half's words and by the raw words beside them.
#[derive(LogicBlock)]
pub struct BackHalf<
    const P: usize,
    const NW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start (or RESET, without `emit_start`).
    pub restart: Signal<In, Bit>,
    /// With `restart`: a stream starts (StreamStart first).
    pub emit_start: Signal<In, Bit>,
    /// N register.
    pub n_window: Signal<In, Bits<NW>>,
    /// T_int register (for StreamStart).
    pub threshold: Signal<In, Bits<32>>,
    /// T_hold register (for StreamStart).
    pub threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM register (≤ N − 1).
    pub end_trim: Signal<In, Bits<NW>>,
    /// L_min register.
    pub l_min: Signal<In, Bits<32>>,
    /// L_max register.
    pub l_max: Signal<In, Bits<32>>,
    /// Plane period register (StreamStart).
    pub plane_period: Signal<In, Bits<32>>,
    /// Masked-pixel count register (StreamStart).
    pub masked_pixels: Signal<In, Bits<32>>,
    /// No real plane after `planes_total`.
    pub stopping: Signal<In, Bit>,
    /// Real planes of the stream.
    pub planes_total: Signal<In, Bits<48>>,
    /// A front-half word.
    pub fh_valid: Signal<In, Bit>,
    /// Of a flush or drain plane.
    pub fh_flush: Signal<In, Bit>,
    /// Word column.
    pub fh_x: Signal<In, Bits<16>>,
    /// Row.
    pub fh_y: Signal<In, Bits<16>>,
    /// Above-threshold bits.
    pub fh_above: Vec<Signal<In, Bit>>,
    /// Candidate bits.
    pub fh_cand: Vec<Signal<In, Bit>>,
    /// A raw word of a real or drain plane.
    pub raw_valid: Signal<In, Bit>,
    /// Its column.
    pub raw_x: Signal<In, Bits<16>>,
    /// `B_{t−N}` (the only plane the ROIs sum).
    pub raw_delayed: Signal<In, Bits<P>>,
    /// Mask bits.
    pub raw_mask: Signal<In, Bits<P>>,
    /// A byte of the packet stream is available.
    pub out_valid: Signal<Out, Bit>,
    /// The byte.
    pub out_data: Signal<Out, Bits<8>>,
    /// Take it.
    pub out_pop: Signal<In, Bit>,
    /// Bytes in the output FIFO.
    pub out_count: Signal<Out, Bits<16>>,
    /// StreamEnd is in the output FIFO and nothing else is pending.
    pub done: Signal<Out, Bit>,
    /// Records were lost (sticky).
    pub overflowed: Signal<Out, Bit>,
    /// An internal buffer overflowed (sticky; the stream is then not exact).
    pub fault: Signal<Out, Bit>,
    /// The tracker's input FIFO and the ROI ring have room for the words
    /// already on their way ([`ROOM_MARGIN_WORDS`]): a source that can wait
    /// (the replay) sends only while this is high and then never overflows
    /// them, whatever the scene's density; the sensor cannot wait and relies
    /// on its duty cycle instead.
    pub room: Signal<Out, Bit>,
    pack_above: PackLanes<P>,
    pack_cand: PackLanes<P>,
    tfifo: Fifo<TW, TAW>,
    tracker: BlinkTracker<P, NW, BW>,
    agg: RoiAggregator<P, RAW, RCW, CAW, BW>,
    pool: BankPool<BW, QAW>,
    queue: RecordQueue<BW, QAW, QW>,
    fin: RecordFinisher<NW>,
    pkt: Packetiser<RCW, CAW, BW, NW, PW>,
    ofifo: Fifo<8, OAW>,
    faults: DFF<Bit>,
    /// `room` as a register: it gates the source through the control and
    /// the replay FIFO, which should not wait on the FIFO count's and the
    /// ring backlog's compares. One clock late, it lets through at most one
    /// word more, which [`ROOM_MARGIN_WORDS`] counts.
    room_q: DFF<Bit>,
    ofree: Signal<Local, Bits<16>>,
    last_word: Constant<Bits<16>>,
    off_p: Constant<Bits<16>>,
    off_2p: Constant<Bits<16>>,
    off_y: Constant<Bits<16>>,
    off_f: Constant<Bits<16>>,
    odepth: Constant<Bits<16>>,
    tfifo_room: Constant<Bits<16>>,
    ring_room: Constant<Bits<16>>,
    _m: usize,
    _r: usize,
}

/// Words a source may still send after `room` falls (the stages between
/// the source and the tracker's FIFO or the ROI ring hold fewer, with the
/// clock by which `room`, a register, lags the counts), so that `room`
/// keeps that margin.
pub const ROOM_MARGIN_WORDS: usize = 32;

/// Rows of the ROI ring that `room` allows to fill: all but the margin
/// that [`ROOM_MARGIN_WORDS`] can bring, and never fewer than the fixed
/// lag (c + h + 5 rows), which the sweep waits out while the source holds
/// its words (fewer would stop the stream for good).
pub fn ring_room_rows(cfg: &BackHalfConfig) -> usize {
    let margin = ROOM_MARGIN_WORDS.div_ceil(cfg.front.words_per_row()) + 1;
    cfg.row_buffer_rows()
        .saturating_sub(margin)
        .max(cfg.row_lag())
}

impl<
        const P: usize,
        const NW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > BackHalf<P, NW, RAW, RCW, CAW, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The back half of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        // The tracker FIFO's word: above and candidate lanes, the tracker's
        // COORD_BITS-bit column and row, flush (2P + 21 bits: 53 for P = 16,
        // a simulator's native 64-bit word rather than an array).
        GatewareConfig::check_width("BackHalf", "TW", TW, 2 * P + 2 * COORD_BITS + 1)?;
        GatewareConfig::check_width("BackHalf", "TAW", TAW, cfg.tracker_fifo_log2)?;
        GatewareConfig::check_width("BackHalf", "OAW", OAW, cfg.output_fifo_log2)?;
        let c16 = |v: u64| Constant::new(v.to_bits());
        Ok(BackHalf {
            clock: Default::default(),
            restart: Default::default(),
            emit_start: Default::default(),
            n_window: Default::default(),
            threshold: Default::default(),
            threshold_hold: Default::default(),
            end_trim: Default::default(),
            l_min: Default::default(),
            l_max: Default::default(),
            plane_period: Default::default(),
            masked_pixels: Default::default(),
            stopping: Default::default(),
            planes_total: Default::default(),
            fh_valid: Default::default(),
            fh_flush: Default::default(),
            fh_x: Default::default(),
            fh_y: Default::default(),
            fh_above: lanes(P),
            fh_cand: lanes(P),
            raw_valid: Default::default(),
            raw_x: Default::default(),
            raw_delayed: Default::default(),
            raw_mask: Default::default(),
            out_valid: Default::default(),
            out_data: Default::default(),
            out_pop: Default::default(),
            out_count: Default::default(),
            done: Default::default(),
            overflowed: Default::default(),
            fault: Default::default(),
            room: Default::default(),
            pack_above: Default::default(),
            pack_cand: Default::default(),
            tfifo: Fifo::new(RamStyle::Block),
            tracker: BlinkTracker::new(cfg)?,
            agg: RoiAggregator::new(cfg)?,
            pool: BankPool::new(cfg)?,
            queue: RecordQueue::new(cfg)?,
            fin: RecordFinisher::new(cfg)?,
            pkt: Packetiser::new(cfg)?,
            ofifo: Fifo::new(RamStyle::Block),
            faults: Default::default(),
            room_q: Default::default(),
            ofree: Default::default(),
            last_word: c16(cfg.front.words_per_row() as u64 - 1),
            off_p: c16(P as u64),
            off_2p: c16(2 * P as u64),
            off_y: c16((2 * P + COORD_BITS) as u64),
            off_f: c16((2 * P + 2 * COORD_BITS) as u64),
            odepth: c16(1u64 << OAW),
            // A FIFO of fewer than 64 words keeps half of it as the margin.
            tfifo_room: c16(((1usize << TAW) - ROOM_MARGIN_WORDS.min((1usize << TAW) / 2)) as u64),
            ring_room: c16(ring_room_rows(cfg) as u64),
            _m: cfg.slots,
            _r: cfg.roi_size,
        })
    }
}

impl<
        const P: usize,
        const NW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic for BackHalf<P, NW, RAW, RCW, CAW, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, tfifo, tracker, agg, pool, queue, pkt, ofifo);
        dff_setup!(self, clock, faults, room_q);
        self.tfifo.restart.next = self.restart.val();
        self.tracker.restart.next = self.restart.val();
        self.tracker.emit_start.next = self.emit_start.val();
        self.agg.restart.next = self.restart.val();
        self.pool.restart.next = self.restart.val();
        self.queue.restart.next = self.restart.val();
        self.pkt.restart.next = self.restart.val();
        self.ofifo.restart.next = self.restart.val();

        // Front-half words with an above-threshold pixel, and every row's
        // last word, go to the tracker.
        for i in 0..P {
            self.pack_above.lanes[i].next = self.fh_above[i].val();
            self.pack_cand.lanes[i].next = self.fh_cand[i].val();
        }
        self.tfifo.push.next = self.fh_valid.val()
            & (self.pack_above.word.val().any() | (self.fh_x.val() == self.last_word.val()));
        self.tfifo.push_data.next = bit_cast::<TW, P>(self.pack_above.word.val())
            | (bit_cast::<TW, P>(self.pack_cand.word.val()) << self.off_p.val())
            | (bit_cast::<TW, COORD_BITS>(bit_cast::<COORD_BITS, 16>(self.fh_x.val()))
                << self.off_2p.val())
            | (bit_cast::<TW, COORD_BITS>(bit_cast::<COORD_BITS, 16>(self.fh_y.val()))
                << self.off_y.val())
            | (bit_cast::<TW, 1>(self.fh_flush.val().into()) << self.off_f.val());
        self.tfifo.pop.next = self.tracker.in_pop.val();
        self.room_q.d.next = (self.tfifo.count.val() < self.tfifo_room.val())
            & (self.agg.backlog.val() < self.ring_room.val());
        self.room.next = self.room_q.q.val();

        // Tracker.
        self.tracker.n_window.next = self.n_window.val();
        self.tracker.end_trim.next = self.end_trim.val();
        self.tracker.l_min.next = self.l_min.val();
        self.tracker.l_max.next = self.l_max.val();
        self.tracker.stopping.next = self.stopping.val();
        self.tracker.planes_total.next = self.planes_total.val();
        self.tracker.in_valid.next = self.tfifo.out_valid.val();
        self.tracker.in_above.next = self.tfifo.out_data.val().get_bits::<P>(0);
        self.tracker.in_cand.next = self
            .tfifo
            .out_data
            .val()
            .get_bits::<P>(self.off_p.val().index());
        self.tracker.in_x.next = bit_cast::<16, COORD_BITS>(
            self.tfifo
                .out_data
                .val()
                .get_bits::<COORD_BITS>(self.off_2p.val().index()),
        );
        self.tracker.in_y.next = bit_cast::<16, COORD_BITS>(
            self.tfifo
                .out_data
                .val()
                .get_bits::<COORD_BITS>(self.off_y.val().index()),
        );
        self.tracker.in_flush.next = self
            .tfifo
            .out_data
            .val()
            .get_bits::<1>(self.off_f.val().index())
            .any();
        self.tracker.rec_room.next = self.queue.room.val();
        self.tracker.swept.next = self.agg.planes_done.val();
        self.tracker.fb_valid.next = self.pool.valid.val();
        self.tracker.fb_bank.next = self.pool.bank.val();
        self.pool.pop.next = self.tracker.fb_pop.val();

        // ROI aggregator: raw words and the tracker's ROI view.
        self.agg.in_valid.next = self.raw_valid.val();
        self.agg.in_x.next = self.raw_x.val();
        self.agg.in_delayed.next = self.raw_delayed.val();
        self.agg.in_mask.next = self.raw_mask.val();
        self.agg.tr_plane.next = self.tracker.plane.val();
        self.agg.tr_rows.next = self.tracker.rows_done.val();
        for q in 0..(2 * self._m) {
            self.agg.sh[q].next = self.tracker.sh[q].val();
        }

        // Record queue.
        self.queue.push.next = self.tracker.rec_push.val();
        self.queue.kind.next = self.tracker.rec_kind.val();
        self.queue.lost.next = self.tracker.rec_lost.val();
        self.queue.slot.next = self.tracker.rec_slot.val();
        self.queue.flags.next = self.tracker.rec_flags.val();
        self.queue.x.next = self.tracker.rec_ax.val();
        self.queue.y.next = self.tracker.rec_ay.val();
        self.queue.t0.next = self.tracker.rec_t0.val();
        self.queue.t1.next = self.tracker.rec_t1.val();
        self.queue.tag.next = self.tracker.rec_tag.val();
        self.queue.bank.next = self.tracker.rec_bank.val();
        self.queue.h_pop.next = self.pkt.r_pop.val();

        // Derived Blink fields.
        self.fin.n_window.next = self.n_window.val();
        self.fin.end_trim.next = self.end_trim.val();
        self.fin.planes_done.next = self.agg.planes_done.val();
        self.fin.kind.next = self.queue.h_kind.val();
        self.fin.flags.next = self.queue.h_flags.val();
        self.fin.ax.next = self.queue.h_x.val();
        self.fin.ay.next = self.queue.h_y.val();
        self.fin.t0.next = self.queue.h_t0.val();
        self.fin.t1.next = self.queue.h_t1.val();
        self.fin.tag.next = self.queue.h_tag.val();

        // Packetiser.
        self.pkt.seq_init.next = 0.into();
        self.pkt.n_window.next = self.n_window.val();
        self.pkt.threshold.next = self.threshold.val();
        self.pkt.threshold_hold.next = self.threshold_hold.val();
        self.pkt.end_trim.next = self.end_trim.val();
        self.pkt.l_min.next = self.l_min.val();
        self.pkt.l_max.next = self.l_max.val();
        self.pkt.plane_period.next = self.plane_period.val();
        self.pkt.masked_pixels.next = self.masked_pixels.val();
        self.pkt.c_planes.next = bit_cast::<64, 48>(self.planes_total.val());
        self.pkt.c_blinks.next = self.tracker.blinks.val();
        self.pkt.c_unconf.next = self.tracker.unconfirmed.val();
        self.pkt.c_dropped.next = self.tracker.dropped.val();
        self.pkt.c_bridged.next = self.tracker.bridged.val();
        self.pkt.c_cuts.next = self.tracker.cuts.val();
        self.pkt.r_valid.next = self.queue.h_valid.val();
        self.pkt.r_kind.next = self.queue.h_kind.val();
        self.pkt.r_lost.next = self.queue.h_lost.val();
        self.pkt.r_slot.next = self.queue.h_slot.val();
        self.pkt.r_flags.next = self.fin.o_flags.val();
        self.pkt.r_ax.next = self.queue.h_x.val();
        self.pkt.r_ay.next = self.queue.h_y.val();
        self.pkt.r_t0.next = self.queue.h_t0.val();
        self.pkt.r_t1.next = self.queue.h_t1.val();
        self.pkt.r_ts.next = self.fin.o_ts.val();
        self.pkt.r_te.next = self.fin.o_te.val();
        self.pkt.r_planes.next = self.fin.o_planes.val();
        self.pkt.r_bank.next = self.queue.h_bank.val();
        self.pkt.r_ready.next = self.fin.o_ready.val();
        self.agg.rd_req.next = self.pkt.rd_req.val();
        self.agg.rd_addr.next = self.pkt.rd_addr.val();
        self.pkt.rd_grant.next = self.agg.rd_grant.val();
        for dx in 0..self._r {
            self.pkt.rd_counts[dx].next = self.agg.rd_counts[dx].val();
        }
        self.pkt.rd_masked.next = self.agg.rd_masked.val();
        self.pool.ret.next = self.pkt.fb_ret.val();
        self.pool.ret_bank.next = self.pkt.fb_ret_bank.val();

        // Output FIFO: the packetiser checks the room before each packet.
        self.ofree.next = 0.into();
        if self.ofifo.count.val() < self.odepth.val() {
            self.ofree.next = self.odepth.val() - self.ofifo.count.val();
        }
        self.pkt.fifo_free.next = self.ofree.val();
        self.ofifo.push.next = self.pkt.out_valid.val();
        self.ofifo.push_data.next = self.pkt.out_byte.val();
        self.ofifo.pop.next = self.out_pop.val();
        self.out_valid.next = self.ofifo.out_valid.val();
        self.out_data.next = self.ofifo.out_data.val();
        self.out_count.next = self.ofifo.count.val();

        // The queue's count includes records still on their way to its head.
        self.done.next = self.tracker.done.val() & self.queue.empty.val() & self.pkt.idle.val();
        self.overflowed.next = self.pkt.overflowed.val();
        if self.tfifo.overflow.val()
            | self.agg.overrun.val()
            | self.tracker.bank_error.val()
            | self.queue.overflow.val()
            | self.ofifo.overflow.val()
        {
            self.faults.d.next = true;
        }
        if self.restart.val() {
            self.faults.d.next = false;
        }
        self.fault.next = self.faults.q.val();
    }
}

/// Stream-control states.
#[derive(Copy, Clone, Debug, PartialEq, LogicState)]
pub enum ControlState {
    /// No stream.
    Idle,
    /// START taken, the registers latched: their check (`regs_ok`, a
    /// register of the START clock's values) decides, a clock later.
    Check,
    /// Registers latched: restart every block.
    Restart,
    /// Passing the source's planes.
    Run,
    /// Sending the N drain planes.
    Drain,
    /// Sending the flush plane.
    Flush,
    /// Waiting for the last records.
    Ending,
}

/// Stream start and end: register check and latch, source gating at plane
/// boundaries, drain and flush planes. `NW`: bits of N; `HW`: bits of H.
#[derive(LogicBlock)]
pub struct StreamControl<const P: usize, const NW: usize, const HW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// START (one clock).
    pub start: Signal<In, Bit>,
    /// STOP (one clock).
    pub stop: Signal<In, Bit>,
    /// RESET (one clock, while stopped): clears the blocks and the status.
    pub reset: Signal<In, Bit>,
    /// N register as written by the host.
    pub reg_n: Signal<In, Bits<32>>,
    /// T_int register.
    pub reg_threshold: Signal<In, Bits<32>>,
    /// T_hold register.
    pub reg_threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM register.
    pub reg_end_trim: Signal<In, Bits<32>>,
    /// L_min register.
    pub reg_l_min: Signal<In, Bits<32>>,
    /// L_max register.
    pub reg_l_max: Signal<In, Bits<32>>,
    /// Plane period register.
    pub reg_period: Signal<In, Bits<32>>,
    /// Masked-pixel count register.
    pub reg_masked: Signal<In, Bits<32>>,
    /// MASK_ENABLE.
    pub reg_mask_enable: Signal<In, Bit>,
    /// Back half done (StreamEnd out).
    pub back_done: Signal<In, Bit>,
    /// A source word.
    pub in_valid: Signal<In, Bit>,
    /// The source's first word of a plane.
    pub in_sop: Signal<In, Bit>,
    /// Its pixels.
    pub in_live: Signal<In, Bits<P>>,
    /// Restart every block (one clock).
    pub restart: Signal<Out, Bit>,
    /// The restart starts a stream (not a RESET).
    pub starting: Signal<Out, Bit>,
    /// No stream is being checked, started or run: the mask may be loaded.
    pub idle: Signal<Out, Bit>,
    /// Latched N.
    pub n_window: Signal<Out, Bits<NW>>,
    /// Latched T_int, clamped to HW bits (front half).
    pub threshold_hw: Signal<Out, Bits<HW>>,
    /// Latched T_int (StreamStart).
    pub threshold: Signal<Out, Bits<32>>,
    /// Latched T_hold, clamped to HW bits (front half).
    pub threshold_hold_hw: Signal<Out, Bits<HW>>,
    /// Latched T_hold (StreamStart).
    pub threshold_hold: Signal<Out, Bits<32>>,
    /// Latched END_TRIM (< N, so NW bits hold it).
    pub end_trim: Signal<Out, Bits<NW>>,
    /// Latched L_min.
    pub l_min: Signal<Out, Bits<32>>,
    /// Latched L_max.
    pub l_max: Signal<Out, Bits<32>>,
    /// Latched plane period.
    pub plane_period: Signal<Out, Bits<32>>,
    /// Latched masked-pixel count (0 without MASK_ENABLE).
    pub masked_pixels: Signal<Out, Bits<32>>,
    /// Latched MASK_ENABLE.
    pub mask_enable: Signal<Out, Bit>,
    /// A word into the pipeline.
    pub w_valid: Signal<Out, Bit>,
    /// First word of a plane.
    pub w_sop: Signal<Out, Bit>,
    /// Word of the flush plane.
    pub w_flush: Signal<Out, Bit>,
    /// Word of a drain plane.
    pub w_drain: Signal<Out, Bit>,
    /// Its pixels.
    pub w_live: Signal<Out, Bits<P>>,
    /// No real plane after `planes_total`.
    pub stopping: Signal<Out, Bit>,
    /// Real planes of the stream.
    pub planes_total: Signal<Out, Bits<48>>,
    /// A stream is running.
    pub running: Signal<Out, Bit>,
    /// Source words are taken (the stream runs and STOP has not taken effect).
    pub accepting: Signal<Out, Bit>,
    /// The stream has ended (StreamEnd is in the output FIFO).
    pub ended: Signal<Out, Bit>,
    /// START was refused: a register is out of range (sticky until START/RESET).
    pub config_error: Signal<Out, Bit>,
    /// A source `sop` arrived inside a plane (sticky).
    pub framing_error: Signal<Out, Bit>,
    state: DFF<ControlState>,
    n: DFF<Bits<NW>>,
    thr: DFF<Bits<32>>,
    thr_hold: DFF<Bits<32>>,
    trim: DFF<Bits<NW>>,
    lmin: DFF<Bits<32>>,
    lmax: DFF<Bits<32>>,
    period: DFF<Bits<32>>,
    masked: DFF<Bits<32>>,
    men: DFF<Bit>,
    synced: DFF<Bit>,
    stop_req: DFF<Bit>,
    widx: DFF<Bits<32>>,
    /// `widx = 0` and `widx` = the plane's last word, as registers set
    /// beside `widx`: the source's gate (`accepting`, and so the replay
    /// FIFO's pop) and the word's plane end do not wait on 32-bit compares.
    w_zero: DFF<Bit>,
    w_last: DFF<Bit>,
    planes_in: DFF<Bits<48>>,
    drains: DFF<Bits<NW>>,
    /// N − 1, latched with N: the last drain plane is found by an equality
    /// with a register rather than behind an increment.
    n_last: DFF<Bits<NW>>,
    ended_q: DFF<Bit>,
    cfg_err: DFF<Bit>,
    frm_err: DFF<Bit>,
    /// `restart` as a register (it reaches every block): set on the clock
    /// that enters Restart, or that takes a RESET in Idle.
    rst: DFF<Bit>,
    /// The registers pass the model's validation: a register (the compares
    /// are 32-bit, and their result gates some fifty latching registers).
    regs_ok: DFF<Bit>,
    plane_end: Signal<Local, Bit>,
    /// A word enters the pipeline: `widx` steps (to 0 after the plane's
    /// last word).
    w_step: Signal<Local, Bit>,
    n_max: Constant<Bits<32>>,
    l_max_max: Constant<Bits<32>>,
    thr_max: Constant<Bits<32>>,
    last_widx: Constant<Bits<32>>,
    /// The word before the last (wraps for one-word planes, where it is
    /// never compared: every word is then the last).
    before_last_widx: Constant<Bits<32>>,
}

impl<const P: usize, const NW: usize, const HW: usize> StreamControl<P, NW, HW> {
    /// The control of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        let f = &cfg.front;
        GatewareConfig::check_width("StreamControl", "P", P, f.pixels_per_clock)?;
        GatewareConfig::check_width("StreamControl", "NW", NW, f.count_bits())?;
        GatewareConfig::check_width("StreamControl", "HW", HW, f.filtered_bits())?;
        if HW > 32 {
            return Err(GatewareError::Invalid {
                field: "n_max",
                value: f.n_max.to_string(),
                why: "H must fit 32 bits (the T_int register)".into(),
            });
        }
        let c32 = |v: u64| Constant::new(v.to_bits());
        Ok(StreamControl {
            clock: Default::default(),
            start: Default::default(),
            stop: Default::default(),
            reset: Default::default(),
            reg_n: Default::default(),
            reg_threshold: Default::default(),
            reg_threshold_hold: Default::default(),
            reg_end_trim: Default::default(),
            reg_l_min: Default::default(),
            reg_l_max: Default::default(),
            reg_period: Default::default(),
            reg_masked: Default::default(),
            reg_mask_enable: Default::default(),
            back_done: Default::default(),
            in_valid: Default::default(),
            in_sop: Default::default(),
            in_live: Default::default(),
            restart: Default::default(),
            starting: Default::default(),
            idle: Default::default(),
            n_window: Default::default(),
            threshold_hw: Default::default(),
            threshold: Default::default(),
            threshold_hold_hw: Default::default(),
            threshold_hold: Default::default(),
            end_trim: Default::default(),
            l_min: Default::default(),
            l_max: Default::default(),
            plane_period: Default::default(),
            masked_pixels: Default::default(),
            mask_enable: Default::default(),
            w_valid: Default::default(),
            w_sop: Default::default(),
            w_flush: Default::default(),
            w_drain: Default::default(),
            w_live: Default::default(),
            stopping: Default::default(),
            planes_total: Default::default(),
            running: Default::default(),
            accepting: Default::default(),
            ended: Default::default(),
            config_error: Default::default(),
            framing_error: Default::default(),
            state: Default::default(),
            n: Default::default(),
            thr: Default::default(),
            thr_hold: Default::default(),
            trim: Default::default(),
            lmin: Default::default(),
            lmax: Default::default(),
            period: Default::default(),
            masked: Default::default(),
            men: Default::default(),
            synced: Default::default(),
            stop_req: Default::default(),
            widx: Default::default(),
            w_zero: Default::default(),
            w_last: Default::default(),
            planes_in: Default::default(),
            drains: Default::default(),
            n_last: Default::default(),
            ended_q: Default::default(),
            cfg_err: Default::default(),
            frm_err: Default::default(),
            rst: Default::default(),
            regs_ok: Default::default(),
            plane_end: Default::default(),
            w_step: Default::default(),
            n_max: c32(f.n_max as u64),
            l_max_max: c32(cfg.l_max_max as u64),
            thr_max: c32((1u64 << HW) - 1),
            last_widx: c32(f.words_per_plane() as u64 - 1),
            before_last_widx: c32((f.words_per_plane() as u64).wrapping_sub(2) & 0xFFFF_FFFF),
        })
    }
}

// Match guards do not translate to Verilog, so the ifs stay inside the arms.
#[allow(clippy::collapsible_match)]
impl<const P: usize, const NW: usize, const HW: usize> Logic for StreamControl<P, NW, HW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, state, n, thr, thr_hold, trim, lmin, lmax, period, masked, men, synced,
            stop_req, widx, w_zero, w_last, planes_in, drains, n_last, ended_q, cfg_err, frm_err,
            rst, regs_ok
        );
        // The model's PipelineConfig::validate, for the runtime registers.
        self.regs_ok.d.next = (self.reg_n.val() != 0)
            & (self.reg_n.val() <= self.n_max.val())
            & (self.reg_threshold.val() != 0)
            & (self.reg_threshold_hold.val() != 0)
            & (self.reg_threshold_hold.val() <= self.reg_threshold.val())
            & (self.reg_end_trim.val() < self.reg_n.val())
            & (self.reg_l_min.val() != 0)
            & (self.reg_l_max.val() >= self.reg_l_min.val())
            & (self.reg_l_max.val() >= self.reg_n.val())
            & (self.reg_l_max.val() <= self.l_max_max.val());
        self.plane_end.next = self.w_last.q.val();
        self.restart.next = self.rst.q.val();
        self.rst.d.next = false;
        self.starting.next = self.state.q.val() == ControlState::Restart;
        self.idle.next = self.state.q.val() == ControlState::Idle;
        self.w_valid.next = false;
        self.w_sop.next = self.w_zero.q.val();
        self.w_flush.next = false;
        self.w_drain.next = false;
        self.w_live.next = 0.into();
        self.w_step.next = false;

        match self.state.q.val() {
            ControlState::Idle => {
                if self.start.val() {
                    self.n.d.next = bit_cast::<NW, 32>(self.reg_n.val());
                    self.n_last.d.next = bit_cast::<NW, 32>(self.reg_n.val()) - 1;
                    self.thr.d.next = self.reg_threshold.val();
                    self.thr_hold.d.next = self.reg_threshold_hold.val();
                    self.trim.d.next = bit_cast::<NW, 32>(self.reg_end_trim.val());
                    self.lmin.d.next = self.reg_l_min.val();
                    self.lmax.d.next = self.reg_l_max.val();
                    self.period.d.next = self.reg_period.val();
                    self.masked.d.next = 0.into();
                    if self.reg_mask_enable.val() {
                        self.masked.d.next = self.reg_masked.val();
                    }
                    self.men.d.next = self.reg_mask_enable.val();
                    self.state.d.next = ControlState::Check;
                } else if self.reset.val() {
                    self.rst.d.next = true;
                    self.cfg_err.d.next = false;
                    self.frm_err.d.next = false;
                    self.ended_q.d.next = false;
                }
            }
            ControlState::Check => {
                if self.regs_ok.q.val() {
                    self.cfg_err.d.next = false;
                    self.frm_err.d.next = false;
                    self.ended_q.d.next = false;
                    self.state.d.next = ControlState::Restart;
                    self.rst.d.next = true;
                } else {
                    self.cfg_err.d.next = true;
                    self.state.d.next = ControlState::Idle;
                }
            }
            ControlState::Restart => {
                self.synced.d.next = false;
                self.stop_req.d.next = false;
                self.widx.d.next = 0.into();
                self.w_zero.d.next = true;
                self.w_last.d.next = self.last_widx.val() == 0;
                self.planes_in.d.next = 0.into();
                self.state.d.next = ControlState::Run;
            }
            ControlState::Run => {
                if self.stop.val() {
                    self.stop_req.d.next = true;
                }
                if self.stop_req.q.val() & self.w_zero.q.val() {
                    // At a plane boundary: no more real planes.
                    self.drains.d.next = 0.into();
                    if self.planes_in.q.val() == 0 {
                        self.state.d.next = ControlState::Ending;
                    } else {
                        self.state.d.next = ControlState::Drain;
                    }
                } else if self.in_valid.val() & (self.synced.q.val() | self.in_sop.val()) {
                    self.synced.d.next = true;
                    if self.in_sop.val() & !self.w_zero.q.val() {
                        self.frm_err.d.next = true;
                    }
                    self.w_valid.next = true;
                    self.w_live.next = self.in_live.val();
                    self.w_step.next = true;
                    if self.plane_end.val() {
                        self.planes_in.d.next = self.planes_in.q.val() + 1;
                    }
                }
            }
            ControlState::Drain => {
                self.w_valid.next = true;
                self.w_drain.next = true;
                self.w_step.next = true;
                if self.plane_end.val() {
                    self.drains.d.next = self.drains.q.val() + 1;
                    if self.drains.q.val() == self.n_last.q.val() {
                        self.state.d.next = ControlState::Flush;
                    }
                }
            }
            ControlState::Flush => {
                self.w_valid.next = true;
                self.w_flush.next = true;
                self.w_step.next = true;
                if self.plane_end.val() {
                    self.state.d.next = ControlState::Ending;
                }
            }
            ControlState::Ending => {
                if self.back_done.val() {
                    self.ended_q.d.next = true;
                    self.state.d.next = ControlState::Idle;
                }
            }
            _ => {}
        }
        if self.w_step.val() {
            if self.plane_end.val() {
                self.widx.d.next = 0.into();
                self.w_zero.d.next = true;
                self.w_last.d.next = self.last_widx.val() == 0;
            } else {
                self.widx.d.next = self.widx.q.val() + 1;
                self.w_zero.d.next = false;
                self.w_last.d.next = self.widx.q.val() == self.before_last_widx.val();
            }
        }

        self.n_window.next = self.n.q.val();
        self.threshold.next = self.thr.q.val();
        self.threshold_hw.next = bit_cast::<HW, 32>(self.thr.q.val());
        if self.thr.q.val() > self.thr_max.val() {
            self.threshold_hw.next = bit_cast::<HW, 32>(self.thr_max.val());
        }
        self.threshold_hold.next = self.thr_hold.q.val();
        self.end_trim.next = self.trim.q.val();
        self.threshold_hold_hw.next = bit_cast::<HW, 32>(self.thr_hold.q.val());
        if self.thr_hold.q.val() > self.thr_max.val() {
            self.threshold_hold_hw.next = bit_cast::<HW, 32>(self.thr_max.val());
        }
        self.l_min.next = self.lmin.q.val();
        self.l_max.next = self.lmax.q.val();
        self.plane_period.next = self.period.q.val();
        self.masked_pixels.next = self.masked.q.val();
        self.mask_enable.next = self.men.q.val();
        self.stopping.next = (self.state.q.val() == ControlState::Drain)
            | (self.state.q.val() == ControlState::Flush)
            | (self.state.q.val() == ControlState::Ending);
        self.planes_total.next = self.planes_in.q.val();
        self.running.next = (self.state.q.val() != ControlState::Idle)
            & (self.state.q.val() != ControlState::Check)
            & (self.state.q.val() != ControlState::Restart);
        // STOP waits for the plane in progress to complete.
        self.accepting.next = (self.state.q.val() == ControlState::Run)
            & !(self.stop_req.q.val() & self.w_zero.q.val());
        self.ended.next = self.ended_q.q.val();
        self.config_error.next = self.cfg_err.q.val();
        self.framing_error.next = self.frm_err.q.val();
    }
}

/// The whole pipeline with the block-RAM delay line: from the raw bit-plane
/// words to the packet bytes. Type parameters: the front half's
/// (`P, DAW, CW, CAW, VW, HW, LAW`, see [`crate::front_half`]) and the back
/// half's (`RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW`, see
/// [`BackHalf`] and [`BackHalfConfig`]).
#[derive(LogicBlock)]
pub struct Pipeline<
    const P: usize,
    const DAW: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW2: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// START.
    pub start: Signal<In, Bit>,
    /// STOP.
    pub stop: Signal<In, Bit>,
    /// RESET.
    pub reset: Signal<In, Bit>,
    /// N register.
    pub reg_n: Signal<In, Bits<32>>,
    /// T_int register.
    pub reg_threshold: Signal<In, Bits<32>>,
    /// T_hold register.
    pub reg_threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM register.
    pub reg_end_trim: Signal<In, Bits<32>>,
    /// L_min register.
    pub reg_l_min: Signal<In, Bits<32>>,
    /// L_max register.
    pub reg_l_max: Signal<In, Bits<32>>,
    /// Plane period register.
    pub reg_period: Signal<In, Bits<32>>,
    /// Masked-pixel count register.
    pub reg_masked: Signal<In, Bits<32>>,
    /// MASK_ENABLE.
    pub reg_mask_enable: Signal<In, Bit>,
    /// Mask load strobe (while stopped).
    pub load: Signal<In, Bit>,
    /// Mask word index.
    pub load_address: Signal<In, Bits<CAW>>,
    /// Mask word.
    pub load_data: Signal<In, Bits<P>>,
    /// A source word.
    pub in_valid: Signal<In, Bit>,
    /// First word of a plane.
    pub in_sop: Signal<In, Bit>,
    /// Its pixels (pixel i in bit i).
    pub in_live: Signal<In, Bits<P>>,
    /// A packet byte is available.
    pub out_valid: Signal<Out, Bit>,
    /// The byte.
    pub out_data: Signal<Out, Bits<8>>,
    /// Take it.
    pub out_pop: Signal<In, Bit>,
    /// Bytes waiting.
    pub out_count: Signal<Out, Bits<16>>,
    /// A stream is running.
    pub running: Signal<Out, Bit>,
    /// Source words are taken now.
    pub accepting: Signal<Out, Bit>,
    /// Source words are taken now and the back half has room for them
    /// ([`BackHalf`]'s `room`): a source that can wait, such as the replay,
    /// sends only while this is high and may then send a word every clock.
    pub ready: Signal<Out, Bit>,
    /// The stream has ended.
    pub ended: Signal<Out, Bit>,
    /// START refused: register out of range.
    pub config_error: Signal<Out, Bit>,
    /// `sop` inside a plane.
    pub framing_error: Signal<Out, Bit>,
    /// Records were lost (Overflow records tell how many).
    pub overflowed: Signal<Out, Bit>,
    /// An internal buffer overflowed.
    pub fault: Signal<Out, Bit>,
    /// The mask load port is open: no stream is starting or running. Loads
    /// while it is low are ignored, so the mask a stream uses is the one
    /// loaded before its START.
    pub mask_loadable: Signal<Out, Bit>,
    /// Always high: no DDR2 to wait for. This and the MCB port below are
    /// [`PipelineDdr`]'s, idle here (inputs unread, outputs 0), so that one
    /// XEM6310 core ([`crate::xem6310`]) serves both delay lines.
    pub mem_ready: Signal<Out, Bit>,
    /// MCB: calibration done.
    pub calib_done: Signal<In, Bit>,
    /// MCB port: command enable.
    pub cmd_en: Signal<Out, Bit>,
    /// MCB port: instruction.
    pub cmd_instr: Signal<Out, Bits<3>>,
    /// MCB port: burst length − 1.
    pub cmd_bl: Signal<Out, Bits<6>>,
    /// MCB port: byte address.
    pub cmd_addr: Signal<Out, Bits<30>>,
    /// MCB port: command FIFO full.
    pub cmd_full: Signal<In, Bit>,
    /// MCB port: write enable.
    pub wr_en: Signal<Out, Bit>,
    /// MCB port: write mask.
    pub wr_mask: Signal<Out, Bits<4>>,
    /// MCB port: write data.
    pub wr_data: Signal<Out, Bits<32>>,
    /// MCB port: write FIFO full.
    pub wr_full: Signal<In, Bit>,
    /// MCB port: read enable.
    pub rd_en: Signal<Out, Bit>,
    /// MCB port: read data.
    pub rd_data: Signal<In, Bits<32>>,
    /// MCB port: read FIFO empty.
    pub rd_empty: Signal<In, Bit>,
    control: StreamControl<P, CW, HW>,
    mask: HotPixelMask<P, CAW>,
    delay: DelayLine<P, DAW, CW>,
    front: FrontHalf<P, CW, CAW, VW, HW, LAW>,
    back: BackHalf<P, CW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>,
}

impl<
        const P: usize,
        const DAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Pipeline<P, DAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The pipeline of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        let f = &cfg.front;
        Ok(Pipeline {
            clock: Default::default(),
            start: Default::default(),
            stop: Default::default(),
            reset: Default::default(),
            reg_n: Default::default(),
            reg_threshold: Default::default(),
            reg_threshold_hold: Default::default(),
            reg_end_trim: Default::default(),
            reg_l_min: Default::default(),
            reg_l_max: Default::default(),
            reg_period: Default::default(),
            reg_masked: Default::default(),
            reg_mask_enable: Default::default(),
            load: Default::default(),
            load_address: Default::default(),
            load_data: Default::default(),
            in_valid: Default::default(),
            in_sop: Default::default(),
            in_live: Default::default(),
            out_valid: Default::default(),
            out_data: Default::default(),
            out_pop: Default::default(),
            out_count: Default::default(),
            running: Default::default(),
            accepting: Default::default(),
            ready: Default::default(),
            ended: Default::default(),
            config_error: Default::default(),
            framing_error: Default::default(),
            overflowed: Default::default(),
            fault: Default::default(),
            mask_loadable: Default::default(),
            mem_ready: Default::default(),
            calib_done: Default::default(),
            cmd_en: Default::default(),
            cmd_instr: Default::default(),
            cmd_bl: Default::default(),
            cmd_addr: Default::default(),
            cmd_full: Default::default(),
            wr_en: Default::default(),
            wr_mask: Default::default(),
            wr_data: Default::default(),
            wr_full: Default::default(),
            rd_en: Default::default(),
            rd_data: Default::default(),
            rd_empty: Default::default(),
            control: StreamControl::new(cfg)?,
            mask: HotPixelMask::new(f)?,
            delay: DelayLine::new(f)?,
            front: FrontHalf::new(f)?,
            back: BackHalf::new(cfg)?,
        })
    }
}

impl<
        const P: usize,
        const DAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic
    for Pipeline<P, DAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, control, mask, delay, front, back);
        // Control.
        self.control.start.next = self.start.val();
        self.control.stop.next = self.stop.val();
        self.control.reset.next = self.reset.val();
        self.control.reg_n.next = self.reg_n.val();
        self.control.reg_threshold.next = self.reg_threshold.val();
        self.control.reg_threshold_hold.next = self.reg_threshold_hold.val();
        self.control.reg_end_trim.next = self.reg_end_trim.val();
        self.control.reg_l_min.next = self.reg_l_min.val();
        self.control.reg_l_max.next = self.reg_l_max.val();
        self.control.reg_period.next = self.reg_period.val();
        self.control.reg_masked.next = self.reg_masked.val();
        self.control.reg_mask_enable.next = self.reg_mask_enable.val();
        self.control.back_done.next = self.back.done.val();
        self.control.in_valid.next = self.in_valid.val();
        self.control.in_sop.next = self.in_sop.val();
        self.control.in_live.next = self.in_live.val();
        // Stage 0: hot-pixel mask.
        // The mask is latched with the registers: loads only while stopped.
        self.mask_loadable.next = self.control.idle.val();
        self.mask.load.next = self.load.val() & self.mask_loadable.val();
        self.mask.load_address.next = self.load_address.val();
        self.mask.load_data.next = self.load_data.val();
        self.mask.valid.next = self.control.w_valid.val();
        self.mask.sop.next = self.control.w_sop.val();
        self.mask.flush.next = self.control.w_flush.val();
        self.mask.drain.next = self.control.w_drain.val();
        self.mask.enable.next = self.control.mask_enable.val();
        self.mask.live.next = self.control.w_live.val();
        // Stage 1a: delay line.
        self.delay.restart.next = self.control.restart.val();
        self.delay.n_window.next = self.control.n_window.val();
        self.delay.valid.next = self.mask.out_valid.val();
        self.delay.sop.next = self.mask.out_sop.val();
        self.delay.flush.next = self.mask.out_flush.val();
        self.delay.drain.next = self.mask.out_drain.val();
        self.delay.live.next = self.mask.out_live.val();
        self.delay.side.next = self.mask.out_mask.val();
        // Stages 1-4.
        self.front.restart.next = self.control.restart.val();
        self.front.threshold.next = self.control.threshold_hw.val();
        self.front.threshold_hold.next = self.control.threshold_hold_hw.val();
        self.front.valid.next = self.delay.out_valid.val();
        self.front.flush.next = self.delay.out_flush.val();
        self.front.x.next = self.delay.out_x.val();
        self.front.y.next = self.delay.out_y.val();
        self.front.idx.next = self.delay.out_idx.val();
        self.front.live.next = self.delay.out_live.val();
        self.front.delayed.next = self.delay.out_delayed.val();
        // Stages 5-7.
        self.back.restart.next = self.control.restart.val();
        self.back.emit_start.next = self.control.starting.val();
        self.back.n_window.next = self.control.n_window.val();
        self.back.threshold.next = self.control.threshold.val();
        self.back.threshold_hold.next = self.control.threshold_hold.val();
        self.back.end_trim.next = self.control.end_trim.val();
        self.back.l_min.next = self.control.l_min.val();
        self.back.l_max.next = self.control.l_max.val();
        self.back.plane_period.next = self.control.plane_period.val();
        self.back.masked_pixels.next = self.control.masked_pixels.val();
        self.back.stopping.next = self.control.stopping.val();
        self.back.planes_total.next = self.control.planes_total.val();
        self.back.fh_valid.next = self.front.out_valid.val();
        self.back.fh_flush.next = self.front.out_flush.val();
        self.back.fh_x.next = self.front.out_x.val();
        self.back.fh_y.next = self.front.out_y.val();
        for i in 0..P {
            self.back.fh_above[i].next = self.front.above[i].val();
            self.back.fh_cand[i].next = self.front.candidate[i].val();
        }
        self.back.raw_valid.next =
            self.delay.out_valid.val() & (!self.delay.out_flush.val() | self.delay.out_drain.val());
        self.back.raw_x.next = self.delay.out_x.val();
        self.back.raw_delayed.next = self.delay.out_delayed.val();
        self.back.raw_mask.next = self.delay.out_side.val();
        self.back.out_pop.next = self.out_pop.val();
        self.out_valid.next = self.back.out_valid.val();
        self.out_data.next = self.back.out_data.val();
        self.out_count.next = self.back.out_count.val();
        self.running.next = self.control.running.val();
        self.accepting.next = self.control.accepting.val();
        self.ready.next = self.control.accepting.val() & self.back.room.val();
        self.ended.next = self.control.ended.val();
        self.config_error.next = self.control.config_error.val();
        self.framing_error.next = self.control.framing_error.val();
        self.overflowed.next = self.back.overflowed.val();
        self.fault.next = self.back.fault.val();
        // The idle MCB port.
        self.mem_ready.next = true;
        self.cmd_en.next = false;
        self.cmd_instr.next = 0.into();
        self.cmd_bl.next = 0.into();
        self.cmd_addr.next = 0.into();
        self.wr_en.next = false;
        self.wr_mask.next = 0.into();
        self.wr_data.next = 0.into();
        self.rd_en.next = false;
    }
}

/// The whole pipeline with the DDR2 delay line ([`DelayLineDdr`]) for
/// configurations whose N_max planes do not fit block RAM: as [`Pipeline`],
/// plus the MCB user port, and START waits for the memory's calibration
/// (`mem_ready`). `PAW`: prefetch FIFO address bits.
#[derive(LogicBlock)]
pub struct PipelineDdr<
    const P: usize,
    const PAW: usize,
    const CW: usize,
    const CAW: usize,
    const VW: usize,
    const HW: usize,
    const LAW: usize,
    const RAW: usize,
    const RCW: usize,
    const CAW2: usize,
    const BW: usize,
    const QAW: usize,
    const QW: usize,
    const PW: usize,
    const TW: usize,
    const TAW: usize,
    const OAW: usize,
> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// START.
    pub start: Signal<In, Bit>,
    /// STOP.
    pub stop: Signal<In, Bit>,
    /// RESET.
    pub reset: Signal<In, Bit>,
    /// N register.
    pub reg_n: Signal<In, Bits<32>>,
    /// T_int register.
    pub reg_threshold: Signal<In, Bits<32>>,
    /// T_hold register.
    pub reg_threshold_hold: Signal<In, Bits<32>>,
    /// END_TRIM register.
    pub reg_end_trim: Signal<In, Bits<32>>,
    /// L_min register.
    pub reg_l_min: Signal<In, Bits<32>>,
    /// L_max register.
    pub reg_l_max: Signal<In, Bits<32>>,
    /// Plane period register.
    pub reg_period: Signal<In, Bits<32>>,
    /// Masked-pixel count register.
    pub reg_masked: Signal<In, Bits<32>>,
    /// MASK_ENABLE.
    pub reg_mask_enable: Signal<In, Bit>,
    /// Mask load strobe (while stopped).
    pub load: Signal<In, Bit>,
    /// Mask word index.
    pub load_address: Signal<In, Bits<CAW>>,
    /// Mask word.
    pub load_data: Signal<In, Bits<P>>,
    /// A source word.
    pub in_valid: Signal<In, Bit>,
    /// First word of a plane.
    pub in_sop: Signal<In, Bit>,
    /// Its pixels (pixel i in bit i).
    pub in_live: Signal<In, Bits<P>>,
    /// A packet byte is available.
    pub out_valid: Signal<Out, Bit>,
    /// The byte.
    pub out_data: Signal<Out, Bits<8>>,
    /// Take it.
    pub out_pop: Signal<In, Bit>,
    /// Bytes waiting.
    pub out_count: Signal<Out, Bits<16>>,
    /// A stream is running.
    pub running: Signal<Out, Bit>,
    /// Source words are taken now.
    pub accepting: Signal<Out, Bit>,
    /// Source words are taken now and the back half has room for them
    /// ([`BackHalf`]'s `room`): a source that can wait, such as the replay,
    /// sends only while this is high and may then send a word every clock.
    pub ready: Signal<Out, Bit>,
    /// The stream has ended.
    pub ended: Signal<Out, Bit>,
    /// START refused: register out of range.
    pub config_error: Signal<Out, Bit>,
    /// `sop` inside a plane.
    pub framing_error: Signal<Out, Bit>,
    /// Records were lost (Overflow records tell how many).
    pub overflowed: Signal<Out, Bit>,
    /// An internal buffer overflowed, or the DDR2 delay line under-ran.
    pub fault: Signal<Out, Bit>,
    /// The mask load port is open: no stream is starting or running. Loads
    /// while it is low are ignored, so the mask a stream uses is the one
    /// loaded before its START.
    pub mask_loadable: Signal<Out, Bit>,
    /// The DDR2 memory has calibrated (START waits for it).
    pub mem_ready: Signal<Out, Bit>,
    /// MCB: calibration done.
    pub calib_done: Signal<In, Bit>,
    /// MCB port: command enable.
    pub cmd_en: Signal<Out, Bit>,
    /// MCB port: instruction.
    pub cmd_instr: Signal<Out, Bits<3>>,
    /// MCB port: burst length − 1.
    pub cmd_bl: Signal<Out, Bits<6>>,
    /// MCB port: byte address.
    pub cmd_addr: Signal<Out, Bits<30>>,
    /// MCB port: command FIFO full.
    pub cmd_full: Signal<In, Bit>,
    /// MCB port: write enable.
    pub wr_en: Signal<Out, Bit>,
    /// MCB port: write mask.
    pub wr_mask: Signal<Out, Bits<4>>,
    /// MCB port: write data.
    pub wr_data: Signal<Out, Bits<32>>,
    /// MCB port: write FIFO full.
    pub wr_full: Signal<In, Bit>,
    /// MCB port: read enable.
    pub rd_en: Signal<Out, Bit>,
    /// MCB port: read data.
    pub rd_data: Signal<In, Bits<32>>,
    /// MCB port: read FIFO empty.
    pub rd_empty: Signal<In, Bit>,
    control: StreamControl<P, CW, HW>,
    mask: HotPixelMask<P, CAW>,
    delay: DelayLineDdr<P, CW, PAW>,
    front: FrontHalf<P, CW, CAW, VW, HW, LAW>,
    back: BackHalf<P, CW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>,
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > PipelineDdr<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    /// The pipeline of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &BackHalfConfig) -> Result<Self, GatewareError> {
        let f = &cfg.front;
        Ok(PipelineDdr {
            clock: Default::default(),
            start: Default::default(),
            stop: Default::default(),
            reset: Default::default(),
            reg_n: Default::default(),
            reg_threshold: Default::default(),
            reg_threshold_hold: Default::default(),
            reg_end_trim: Default::default(),
            reg_l_min: Default::default(),
            reg_l_max: Default::default(),
            reg_period: Default::default(),
            reg_masked: Default::default(),
            reg_mask_enable: Default::default(),
            load: Default::default(),
            load_address: Default::default(),
            load_data: Default::default(),
            in_valid: Default::default(),
            in_sop: Default::default(),
            in_live: Default::default(),
            out_valid: Default::default(),
            out_data: Default::default(),
            out_pop: Default::default(),
            out_count: Default::default(),
            running: Default::default(),
            accepting: Default::default(),
            ready: Default::default(),
            ended: Default::default(),
            config_error: Default::default(),
            framing_error: Default::default(),
            overflowed: Default::default(),
            fault: Default::default(),
            mask_loadable: Default::default(),
            mem_ready: Default::default(),
            calib_done: Default::default(),
            cmd_en: Default::default(),
            cmd_instr: Default::default(),
            cmd_bl: Default::default(),
            cmd_addr: Default::default(),
            cmd_full: Default::default(),
            wr_en: Default::default(),
            wr_mask: Default::default(),
            wr_data: Default::default(),
            wr_full: Default::default(),
            rd_en: Default::default(),
            rd_data: Default::default(),
            rd_empty: Default::default(),
            control: StreamControl::new(cfg)?,
            mask: HotPixelMask::new(f)?,
            delay: DelayLineDdr::new(f)?,
            front: FrontHalf::new(f)?,
            back: BackHalf::new(cfg)?,
        })
    }
}

impl<
        const P: usize,
        const PAW: usize,
        const CW: usize,
        const CAW: usize,
        const VW: usize,
        const HW: usize,
        const LAW: usize,
        const RAW: usize,
        const RCW: usize,
        const CAW2: usize,
        const BW: usize,
        const QAW: usize,
        const QW: usize,
        const PW: usize,
        const TW: usize,
        const TAW: usize,
        const OAW: usize,
    > Logic
    for PipelineDdr<P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, control, mask, delay, front, back);
        // Control.
        self.control.start.next = self.start.val() & self.calib_done.val();
        self.control.stop.next = self.stop.val();
        self.control.reset.next = self.reset.val();
        self.control.reg_n.next = self.reg_n.val();
        self.control.reg_threshold.next = self.reg_threshold.val();
        self.control.reg_threshold_hold.next = self.reg_threshold_hold.val();
        self.control.reg_end_trim.next = self.reg_end_trim.val();
        self.control.reg_l_min.next = self.reg_l_min.val();
        self.control.reg_l_max.next = self.reg_l_max.val();
        self.control.reg_period.next = self.reg_period.val();
        self.control.reg_masked.next = self.reg_masked.val();
        self.control.reg_mask_enable.next = self.reg_mask_enable.val();
        self.control.back_done.next = self.back.done.val();
        self.control.in_valid.next = self.in_valid.val();
        self.control.in_sop.next = self.in_sop.val();
        self.control.in_live.next = self.in_live.val();
        // Stage 0: hot-pixel mask.
        // The mask is latched with the registers: loads only while stopped.
        self.mask_loadable.next = self.control.idle.val();
        self.mask.load.next = self.load.val() & self.mask_loadable.val();
        self.mask.load_address.next = self.load_address.val();
        self.mask.load_data.next = self.load_data.val();
        self.mask.valid.next = self.control.w_valid.val();
        self.mask.sop.next = self.control.w_sop.val();
        self.mask.flush.next = self.control.w_flush.val();
        self.mask.drain.next = self.control.w_drain.val();
        self.mask.enable.next = self.control.mask_enable.val();
        self.mask.live.next = self.control.w_live.val();
        // Stage 1a: delay line.
        self.delay.restart.next = self.control.restart.val();
        self.delay.n_window.next = self.control.n_window.val();
        self.delay.valid.next = self.mask.out_valid.val();
        self.delay.sop.next = self.mask.out_sop.val();
        self.delay.flush.next = self.mask.out_flush.val();
        self.delay.drain.next = self.mask.out_drain.val();
        self.delay.live.next = self.mask.out_live.val();
        self.delay.side.next = self.mask.out_mask.val();
        self.delay.calib_done.next = self.calib_done.val();
        self.delay.cmd_full.next = self.cmd_full.val();
        self.delay.wr_full.next = self.wr_full.val();
        self.delay.rd_data.next = self.rd_data.val();
        self.delay.rd_empty.next = self.rd_empty.val();
        self.cmd_en.next = self.delay.cmd_en.val();
        self.cmd_instr.next = self.delay.cmd_instr.val();
        self.cmd_bl.next = self.delay.cmd_bl.val();
        self.cmd_addr.next = self.delay.cmd_addr.val();
        self.wr_en.next = self.delay.wr_en.val();
        self.wr_mask.next = self.delay.wr_mask.val();
        self.wr_data.next = self.delay.wr_data.val();
        self.rd_en.next = self.delay.rd_en.val();
        self.mem_ready.next = self.calib_done.val();
        // Stages 1-4.
        self.front.restart.next = self.control.restart.val();
        self.front.threshold.next = self.control.threshold_hw.val();
        self.front.threshold_hold.next = self.control.threshold_hold_hw.val();
        self.front.valid.next = self.delay.out_valid.val();
        self.front.flush.next = self.delay.out_flush.val();
        self.front.x.next = self.delay.out_x.val();
        self.front.y.next = self.delay.out_y.val();
        self.front.idx.next = self.delay.out_idx.val();
        self.front.live.next = self.delay.out_live.val();
        self.front.delayed.next = self.delay.out_delayed.val();
        // Stages 5-7.
        self.back.restart.next = self.control.restart.val();
        self.back.emit_start.next = self.control.starting.val();
        self.back.n_window.next = self.control.n_window.val();
        self.back.threshold.next = self.control.threshold.val();
        self.back.threshold_hold.next = self.control.threshold_hold.val();
        self.back.end_trim.next = self.control.end_trim.val();
        self.back.l_min.next = self.control.l_min.val();
        self.back.l_max.next = self.control.l_max.val();
        self.back.plane_period.next = self.control.plane_period.val();
        self.back.masked_pixels.next = self.control.masked_pixels.val();
        self.back.stopping.next = self.control.stopping.val();
        self.back.planes_total.next = self.control.planes_total.val();
        self.back.fh_valid.next = self.front.out_valid.val();
        self.back.fh_flush.next = self.front.out_flush.val();
        self.back.fh_x.next = self.front.out_x.val();
        self.back.fh_y.next = self.front.out_y.val();
        for i in 0..P {
            self.back.fh_above[i].next = self.front.above[i].val();
            self.back.fh_cand[i].next = self.front.candidate[i].val();
        }
        self.back.raw_valid.next =
            self.delay.out_valid.val() & (!self.delay.out_flush.val() | self.delay.out_drain.val());
        self.back.raw_x.next = self.delay.out_x.val();
        self.back.raw_delayed.next = self.delay.out_delayed.val();
        self.back.raw_mask.next = self.delay.out_side.val();
        self.back.out_pop.next = self.out_pop.val();
        self.out_valid.next = self.back.out_valid.val();
        self.out_data.next = self.back.out_data.val();
        self.out_count.next = self.back.out_count.val();
        self.running.next = self.control.running.val();
        self.accepting.next = self.control.accepting.val();
        self.ready.next = self.control.accepting.val() & self.back.room.val();
        self.ended.next = self.control.ended.val();
        self.config_error.next = self.control.config_error.val();
        self.framing_error.next = self.control.framing_error.val();
        self.overflowed.next = self.back.overflowed.val();
        self.fault.next =
            self.back.fault.val() | self.delay.underrun.val() | self.delay.write_error.val();
    }
}

/// The small simulation configuration: the front half's
/// [`crate::front_half::test_config`] (16×6, P = 4, k1 = [1 4 6 4 1],
/// N_max = 7) with M slots, R×R ROIs, r_assoc, L_max ≤ 64, a record queue
/// of 16 (its planes are so short that a Blink's packet takes several
/// planes), a 32-word tracker FIFO and a 2-KiB output FIFO.
pub fn test_back_config(
    slots: usize,
    roi_size: usize,
    r_assoc: u32,
) -> Result<BackHalfConfig, GatewareError> {
    let front = crate::front_half::test_config();
    let mut cfg = smartagg_model::config::PipelineConfig::new(
        front.width,
        front.height,
        front.n_max,
        front.kernel.clone(),
        front.kernel_shift,
        1,
    );
    cfg.slots = slots;
    cfg.roi_size = roi_size;
    cfg.r_assoc = r_assoc;
    cfg.l_max = 64;
    let mut b = BackHalfConfig::new(&cfg, front, 64)?;
    b.queue_log2 = 4;
    b.tracker_fifo_log2 = 5;
    b.output_fifo_log2 = 11;
    // Six rows beyond the default, so that `room` lets a paced source run
    // ahead of the sweep by more than its fixed lag even in this 6-row
    // field (with the default, `ring_room_rows` is the lag itself).
    b.row_slack = b.default_row_slack() + 6;
    b.validate()?;
    Ok(b)
}

/// [`Pipeline`] of [`test_back_config`]`(4, 3, 1)`.
pub type TestPipeline = Pipeline<4, 8, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11>;

/// [`PipelineDdr`] of [`test_back_config`]`(4, 3, 1)`, prefetch of 64 words.
pub type TestPipelineDdr = PipelineDdr<4, 6, 3, 5, 7, 11, 2, 6, 7, 6, 5, 4, 231, 488, 29, 5, 11>;

/// The SPCImager at 150× (320×240, P = 16, N_max = 128, the model's kernel
/// for σ = 1.51 px) with the model's defaults M = 32, 9×9 ROIs (R = k),
/// r_assoc = 1 and L_max up to 65,535 planes (6.5 s).
pub fn spcimager150_back_config() -> Result<BackHalfConfig, GatewareError> {
    let front = crate::front_half::spcimager150_config();
    back_config_for(front, 108)
}

/// The projected SPCImager (78 % fill, 25 Hz DCR) at 150×: N ≈ 18, so the
/// delay line of N_max = 24 planes (1.84 Mbit) fits the block RAM of an
/// LX150; otherwise as [`spcimager150_back_config`].
pub fn projected150_back_config() -> Result<BackHalfConfig, GatewareError> {
    let front = GatewareConfig {
        n_max: 24,
        dsp_multipliers: crate::device::device_for(
            smartagg_model::params::PresetName::SpcimagerProjected,
        )
        .dsp48a1 as usize,
        ..crate::front_half::spcimager150_config()
    };
    back_config_for(front, 18)
}

fn back_config_for(front: GatewareConfig, n: u32) -> Result<BackHalfConfig, GatewareError> {
    let mut cfg = smartagg_model::config::PipelineConfig::new(
        front.width,
        front.height,
        n,
        front.kernel.clone(),
        front.kernel_shift,
        1,
    );
    cfg.slots = 32;
    cfg.roi_size = front.kernel.len();
    cfg.r_assoc = 1;
    BackHalfConfig::new(&cfg, front, 65_535)
}

/// [`Pipeline`] of [`projected150_back_config`] (block-RAM delay line).
pub type Projected150Pipeline =
    Pipeline<16, 17, 5, 13, 13, 21, 5, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12>;

/// [`PipelineDdr`] of [`spcimager150_back_config`].
pub type Spcimager150PipelineDdr =
    PipelineDdr<16, 9, 8, 13, 16, 24, 5, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12>;
