//! The back half of the pipeline: blink tracker ([`crate::blink_tracker`]),
//! ROI aggregator with its bank pool ([`crate::roi_aggregator`],
//! [`crate::bank_pool`]), record queue and finisher
//! ([`crate::record_queue`], [`crate::record_finisher`]), packetiser
//! ([`crate::packetiser`]) and the output FIFO, fed by the front half's
//! words and by the raw words beside them; `room` paces a source that can
//! wait. A block of the whole pipeline ([`crate::pipeline`]; its model
//! twin is the back of `model/src/pipeline.rs`, stages 5–7).

use crate::bank_pool::BankPool;
use crate::blink_tracker::{BlinkTracker, COORD_BITS};
use crate::bram::RamStyle;
use crate::bundles::{CandidateWord, DelayedWord, StreamSettings};
use crate::config::{BackHalfConfig, GatewareConfig, GatewareError};
use crate::fifo::Fifo;
use crate::packetiser::Packetiser;
use crate::record_finisher::RecordFinisher;
use crate::record_queue::RecordQueue;
use crate::roi_aggregator::RoiAggregator;
use rust_hdl::prelude::*;

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
    /// The stream's settings, latched at START.
    pub settings: StreamSettings<NW>,
    /// No real plane after `planes_total`.
    pub stopping: Signal<In, Bit>,
    /// Real planes of the stream.
    pub planes_total: Signal<In, Bits<48>>,
    /// The front half's word: above-threshold bits and candidates.
    pub fh: CandidateWord<P>,
    /// The delay line's word (the same stream, ahead of `fh` by the front
    /// half's latency): the ROIs sum its `B_{t−N}` over the real and the
    /// drain planes, and its masked pixels set their MASKED flag.
    pub raw: DelayedWord<P>,
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
            settings: Default::default(),
            stopping: Default::default(),
            planes_total: Default::default(),
            fh: Default::default(),
            raw: Default::default(),
            out_valid: Default::default(),
            out_data: Default::default(),
            out_pop: Default::default(),
            out_count: Default::default(),
            done: Default::default(),
            overflowed: Default::default(),
            fault: Default::default(),
            room: Default::default(),
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
        self.tfifo.push.next = self.fh.valid.val()
            & (self.fh.above.val().any() | (self.fh.x.val() == self.last_word.val()));
        self.tfifo.push_data.next = bit_cast::<TW, P>(self.fh.above.val())
            | (bit_cast::<TW, P>(self.fh.candidate.val()) << self.off_p.val())
            | (bit_cast::<TW, COORD_BITS>(bit_cast::<COORD_BITS, 16>(self.fh.x.val()))
                << self.off_2p.val())
            | (bit_cast::<TW, COORD_BITS>(bit_cast::<COORD_BITS, 16>(self.fh.y.val()))
                << self.off_y.val())
            | (bit_cast::<TW, 1>(self.fh.flush.val().into()) << self.off_f.val());
        self.tfifo.pop.next = self.tracker.in_pop.val();
        self.room_q.d.next = (self.tfifo.count.val() < self.tfifo_room.val())
            & (self.agg.backlog.val() < self.ring_room.val());
        self.room.next = self.room_q.q.val();

        // Tracker.
        self.tracker.n_window.next = self.settings.n_window.val();
        self.tracker.end_trim.next = self.settings.end_trim.val();
        self.tracker.l_min.next = self.settings.l_min.val();
        self.tracker.l_max.next = self.settings.l_max.val();
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
        self.tracker.swept.next = self.agg.planes_done.val();
        self.tracker.fb_valid.next = self.pool.valid.val();
        self.tracker.fb_bank.next = self.pool.bank.val();
        self.pool.pop.next = self.tracker.fb_pop.val();

        // ROI aggregator: raw words and the tracker's ROI view.
        // A drain plane's word is flush for the tracker but a plane for
        // the sums; the flush plane's is neither.
        self.agg.in_valid.next =
            self.raw.valid.val() & (!self.raw.flush.val() | self.raw.drain.val());
        self.agg.in_x.next = self.raw.x.val();
        self.agg.in_delayed.next = self.raw.delayed.val();
        self.agg.in_mask.next = self.raw.side.val();
        self.agg.tr_plane.next = self.tracker.plane.val();
        self.agg.tr_rows.next = self.tracker.rows_done.val();
        for q in 0..(2 * self._m) {
            self.agg.sh[q].next = self.tracker.sh[q].val();
        }

        // Record queue: the tracker's descriptor, field by field (a `join`
        // would write a process per field, which made the co-simulation 3 %
        // slower: docs/COSIM.md, 2026-11-30).
        self.tracker.record.room.next = self.queue.record.room.val();
        self.queue.record.push.next = self.tracker.record.push.val();
        self.queue.record.kind.next = self.tracker.record.kind.val();
        self.queue.record.lost.next = self.tracker.record.lost.val();
        self.queue.record.slot.next = self.tracker.record.slot.val();
        self.queue.record.flags.next = self.tracker.record.flags.val();
        self.queue.record.ax.next = self.tracker.record.ax.val();
        self.queue.record.ay.next = self.tracker.record.ay.val();
        self.queue.record.t0.next = self.tracker.record.t0.val();
        self.queue.record.t1.next = self.tracker.record.t1.val();
        self.queue.record.tag.next = self.tracker.record.tag.val();
        self.queue.record.bank.next = self.tracker.record.bank.val();
        self.queue.h_pop.next = self.pkt.r_pop.val();

        // Derived Blink fields.
        self.fin.n_window.next = self.settings.n_window.val();
        self.fin.end_trim.next = self.settings.end_trim.val();
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
        StreamSettings::<NW>::link(&mut self.settings, &mut self.pkt.settings);
        self.pkt.c_planes.next = bit_cast::<64, 48>(self.planes_total.val());
        // (Field by field: a join is a process per field in the Verilog.)
        self.pkt.totals.blinks.next = self.tracker.totals.blinks.val();
        self.pkt.totals.unconfirmed.next = self.tracker.totals.unconfirmed.val();
        self.pkt.totals.dropped.next = self.tracker.totals.dropped.val();
        self.pkt.totals.bridged.next = self.tracker.totals.bridged.val();
        self.pkt.totals.cuts.next = self.tracker.totals.cuts.val();
        self.pkt.record.valid.next = self.queue.h_valid.val();
        self.pkt.record.kind.next = self.queue.h_kind.val();
        self.pkt.record.lost.next = self.queue.h_lost.val();
        self.pkt.record.slot.next = self.queue.h_slot.val();
        self.pkt.record.flags.next = self.fin.o_flags.val();
        self.pkt.record.ax.next = self.queue.h_x.val();
        self.pkt.record.ay.next = self.queue.h_y.val();
        self.pkt.record.t0.next = self.queue.h_t0.val();
        self.pkt.record.t1.next = self.queue.h_t1.val();
        self.pkt.record.ts.next = self.fin.o_ts.val();
        self.pkt.record.te.next = self.fin.o_te.val();
        self.pkt.record.planes.next = self.fin.o_planes.val();
        self.pkt.record.bank.next = self.queue.h_bank.val();
        self.pkt.record.ready.next = self.fin.o_ready.val();
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
