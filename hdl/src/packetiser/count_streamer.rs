//! A Blink's ROI counts, one a clock, from its bank of the counter memory
//! ([`crate::roi_aggregator`]): a row of R counts is requested (`rd_req`
//! until `rd_grant`), arrives the clock after the grant, and is taken a
//! count at a time in row-major order; after the R-th row the streamer
//! stops. The packetiser streams the ROI three times (passes 1 to 3).
//!
//! ROI rows outside the sensor read as 0: whether row `dy` lies on it is a
//! register of the clock that requests the row (`dy` and the record hold
//! still until the row arrives), so the row's add and compare stay out of
//! the counts' and the mask flag's paths. Each take shifts the row down a
//! lane: the count taken is always lane 0 (a register, not a multiplexer by
//! the column).

use crate::config::BackHalfConfig;
use crate::const_mul::ConstMul;
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// The count streamer. `RCW`: count bits; `CAW`: counter address bits;
/// `BW`: bank bits.
#[derive(LogicBlock)]
pub struct CountStreamer<const RCW: usize, const CAW: usize, const BW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: stop.
    pub restart: Signal<In, Bit>,
    /// Stream the ROI from its first count.
    pub start: Signal<In, Bit>,
    /// The count `count` is taken (when `valid`).
    pub take: Signal<In, Bit>,
    /// The record's counter bank.
    pub bank: Signal<In, Bits<BW>>,
    /// The record's anchor row: the ROI's rows are `ay − R/2 ..= ay + R/2`.
    pub anchor_row: Signal<In, Bits<16>>,
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
    /// A count is ready.
    pub valid: Signal<Out, Bit>,
    /// The count.
    pub count: Signal<Out, Bits<RCW>>,
    /// The streamer runs (some count not yet taken).
    pub active: Signal<Out, Bit>,
    /// A row on the sensor with its mask flag set arrives this clock.
    pub masked_row: Signal<Out, Bit>,
    run: DFF<Bit>,
    waiting: DFF<Bit>,
    row_valid: DFF<Bit>,
    dy: DFF<Bits<8>>,
    dx: DFF<Bits<8>>,
    row: Vec<DFF<Bits<RCW>>>,
    /// The ROI row `dy` lies on the sensor.
    in_sensor: DFF<Bit>,
    bank_base: ConstMul<CAW>,
    /// `rd_req` and `masked_row`, computed here and assigned once (see
    /// [`super`]: outputs without transients).
    req: Signal<Local, Bit>,
    flag: Signal<Local, Bit>,
    /// `anchor_row + dy`: the sensor row of ROI row dy, plus R / 2.
    row_y: Signal<Local, Bits<16>>,
    /// R / 2 and R / 2 + H: the sensor's rows in `row_y`.
    h: Constant<Bits<16>>,
    h_plus_rows: Constant<Bits<16>>,
    last_idx: Constant<Bits<8>>,
    _r: usize,
}

impl<const RCW: usize, const CAW: usize, const BW: usize> CountStreamer<RCW, CAW, BW> {
    /// The streamer of a configuration's ROI side and sensor height.
    pub fn new(cfg: &BackHalfConfig) -> Self {
        let r = cfg.roi_size;
        CountStreamer {
            clock: Default::default(),
            restart: Default::default(),
            start: Default::default(),
            take: Default::default(),
            bank: Default::default(),
            anchor_row: Default::default(),
            rd_req: Default::default(),
            rd_addr: Default::default(),
            rd_grant: Default::default(),
            rd_counts: lanes(r),
            rd_masked: Default::default(),
            valid: Default::default(),
            count: Default::default(),
            active: Default::default(),
            masked_row: Default::default(),
            run: Default::default(),
            waiting: Default::default(),
            row_valid: Default::default(),
            dy: Default::default(),
            dx: Default::default(),
            row: lanes(r),
            in_sensor: Default::default(),
            bank_base: ConstMul::new(r as u32),
            req: Default::default(),
            flag: Default::default(),
            row_y: Default::default(),
            h: Constant::new((cfg.roi_half() as u64).to_bits()),
            h_plus_rows: Constant::new(((cfg.roi_half() + cfg.front.height) as u64).to_bits()),
            last_idx: Constant::new((r as u64 - 1).to_bits()),
            _r: r,
        }
    }
}

impl<const RCW: usize, const CAW: usize, const BW: usize> Logic for CountStreamer<RCW, CAW, BW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, run, waiting, row_valid, dy, dx, in_sensor);
        for dx in 0..self._r {
            self.row[dx].clock.next = self.clock.val();
            self.row[dx].d.next = self.row[dx].q.val();
        }
        self.bank_base.x.next = bit_cast::<CAW, BW>(self.bank.val());
        self.rd_addr.next = self.bank_base.y.val() + bit_cast::<CAW, 8>(self.dy.q.val());
        self.req.next = false;
        self.row_y.next = self.anchor_row.val() + bit_cast::<16, 8>(self.dy.q.val());
        self.in_sensor.d.next =
            (self.row_y.val() >= self.h.val()) & (self.row_y.val() < self.h_plus_rows.val());
        self.valid.next = self.row_valid.q.val();
        self.count.next = self.row[0].q.val();
        self.active.next = self.run.q.val();
        self.flag.next = false;
        if self.run.q.val() {
            if !self.row_valid.q.val() & !self.waiting.q.val() {
                self.req.next = true;
                if self.rd_grant.val() {
                    self.waiting.d.next = true;
                }
            }
            if self.waiting.q.val() {
                for dx in 0..self._r {
                    self.row[dx].d.next = 0.into();
                    if self.in_sensor.q.val() {
                        self.row[dx].d.next = self.rd_counts[dx].val();
                    }
                }
                self.flag.next = self.in_sensor.q.val() & self.rd_masked.val();
                self.row_valid.d.next = true;
                self.waiting.d.next = false;
            }
            if self.row_valid.q.val() & self.take.val() {
                for dx in 0..(self._r - 1) {
                    self.row[dx].d.next = self.row[dx + 1].q.val();
                }
                self.dx.d.next = self.dx.q.val() + 1;
                if self.dx.q.val() == self.last_idx.val() {
                    self.dx.d.next = 0.into();
                    self.row_valid.d.next = false;
                    self.dy.d.next = self.dy.q.val() + 1;
                    if self.dy.q.val() == self.last_idx.val() {
                        self.run.d.next = false;
                    }
                }
            }
        }
        self.rd_req.next = self.req.val();
        self.masked_row.next = self.flag.val();
        if self.start.val() {
            self.run.d.next = true;
            self.dy.d.next = 0.into();
            self.dx.d.next = 0.into();
            self.row_valid.d.next = false;
            self.waiting.d.next = false;
        }
        if self.restart.val() {
            self.run.d.next = false;
        }
    }
}
