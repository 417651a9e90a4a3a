//! Stages 3–4 — threshold and candidates: above-threshold pixels that are
//! maxima of their 3×3 neighbourhood with the tie rule of
//! [`smartagg_model::candidates`]: strictly greater than the four earlier
//! neighbours in raster order, greater than or equal to the four later ones.
//! Neighbours outside the sensor are zero, which an above-threshold pixel
//! (H ≥ T_int ≥ 1) always beats — the model's "ignored".
//!
//! Two line buffers of H (rows y−1, y−2) give the 3-row column of each word
//! when row y arrives (output row y − 1, [`RowSkew`]); three [`WordWindow`]s
//! add one pixel of context each side. Output per word: the above-threshold
//! bits and the candidate bits of its P pixels with the word's column and
//! row, in raster order — a candidate's position is `(x·P + lane, y)`.
//! Latency: 2 clocks, one word (window), 1 clock.

use crate::bram::{Bram, RamStyle};
use crate::config::{GatewareConfig, GatewareError};
use crate::stream::{lanes, RowSkew, TagReg, WordWindow};
use crate::threshold::Threshold;
use rust_hdl::prelude::*;

/// Threshold and 3×3-maximum candidates on P lanes. `HW`: bits of H;
/// `LAW`: line-buffer address bits.
#[derive(LogicBlock)]
pub struct Candidates<const HW: usize, const LAW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start.
    pub restart: Signal<In, Bit>,
    /// T_int (runtime register).
    pub threshold: Signal<In, Bits<HW>>,
    /// Input word present.
    pub valid: Signal<In, Bit>,
    /// Word of a flush plane.
    pub flush: Signal<In, Bit>,
    /// Word column.
    pub x: Signal<In, Bits<16>>,
    /// Row.
    pub y: Signal<In, Bits<16>>,
    /// H of the word's P pixels.
    pub filtered: Vec<Signal<In, Bits<HW>>>,
    /// Output word present.
    pub out_valid: Signal<Out, Bit>,
    /// Output of a flush plane.
    pub out_flush: Signal<Out, Bit>,
    /// Output word column.
    pub out_x: Signal<Out, Bits<16>>,
    /// Output row.
    pub out_y: Signal<Out, Bits<16>>,
    /// `H ≥ T_int` per pixel.
    pub above: Vec<Signal<Out, Bit>>,
    /// Candidate per pixel.
    pub candidate: Vec<Signal<Out, Bit>>,
    line: Vec<Bram<HW, LAW>>,
    t1: TagReg,
    h1: Vec<DFF<Bits<HW>>>,
    skew: RowSkew,
    last_y: Constant<Bits<16>>,
    top_ok: Signal<Local, Bit>,
    bot_ok: Signal<Local, Bit>,
    wtop: WordWindow<HW>,
    wmid: WordWindow<HW>,
    wbot: WordWindow<HW>,
    thr: Threshold<HW>,
    t3: TagReg,
    above_q: Vec<DFF<Bit>>,
    /// Middle row, `win[n + 1] > win[n]`: each horizontal neighbour pair is
    /// compared once, for the pixel on its right (strictly greater than
    /// the earlier one) and, negated, for the pixel on its left (greater
    /// than or equal to the later one).
    mid_gt: Vec<Signal<Local, Bit>>,
    cand_q: Vec<DFF<Bit>>,
    _p: usize,
}

impl<const HW: usize, const LAW: usize> Candidates<HW, LAW> {
    /// The candidate finder of a configuration; errors if the widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        GatewareConfig::check_width("Candidates", "HW", HW, cfg.filtered_bits())?;
        GatewareConfig::check_width("Candidates", "LAW", LAW, cfg.line_addr_bits())?;
        let p = cfg.pixels_per_clock;
        let wpr = cfg.words_per_row();
        let style = if wpr <= 64 {
            RamStyle::Distributed
        } else {
            RamStyle::Block
        };
        Ok(Candidates {
            clock: Default::default(),
            restart: Default::default(),
            threshold: Default::default(),
            valid: Default::default(),
            flush: Default::default(),
            x: Default::default(),
            y: Default::default(),
            filtered: lanes(p),
            out_valid: Default::default(),
            out_flush: Default::default(),
            out_x: Default::default(),
            out_y: Default::default(),
            above: lanes(p),
            candidate: lanes(p),
            line: (0..2 * p).map(|_| Bram::new(wpr, style)).collect(),
            t1: Default::default(),
            h1: lanes(p),
            skew: RowSkew::new(1, cfg.height),
            last_y: Constant::new((cfg.height as u64 - 1).to_bits()),
            top_ok: Default::default(),
            bot_ok: Default::default(),
            wtop: WordWindow::new(p, 1, wpr),
            wmid: WordWindow::new(p, 1, wpr),
            wbot: WordWindow::new(p, 1, wpr),
            thr: Threshold::new(p),
            t3: Default::default(),
            above_q: lanes(p),
            mid_gt: lanes(p + 1),
            cand_q: lanes(p),
            _p: p,
        })
    }
}

impl<const HW: usize, const LAW: usize> Logic for Candidates<HW, LAW> {
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, t1, skew, wtop, wmid, wbot, t3);
        self.t1.restart.next = self.restart.val();
        self.skew.restart.next = self.restart.val();
        self.wtop.restart.next = self.restart.val();
        self.wmid.restart.next = self.restart.val();
        self.wbot.restart.next = self.restart.val();
        self.t3.restart.next = self.restart.val();

        // C0: read rows y−1 and y−2 of this column word.
        self.t1.valid.next = self.valid.val();
        self.t1.flush.next = self.flush.val();
        self.t1.x.next = self.x.val();
        self.t1.y.next = self.y.val();
        for q in 0..(2 * self._p) {
            self.line[q].clock.next = self.clock.val();
            self.line[q].read_address.next = bit_cast::<LAW, 16>(self.x.val());
            self.line[q].write_address.next = bit_cast::<LAW, 16>(self.t1.out_x.val());
            self.line[q].write_enable.next = self.t1.out_valid.val();
        }

        // C1: the column (top, mid, bottom) of output row y − 1, zero outside the plane.
        self.skew.valid.next = self.t1.out_valid.val();
        self.skew.flush.next = self.t1.out_flush.val();
        self.skew.x.next = self.t1.out_x.val();
        self.skew.y.next = self.t1.out_y.val();
        self.top_ok.next = self.skew.out_y.val() != 0;
        self.bot_ok.next = self.skew.out_y.val() != self.last_y.val();
        self.wtop.valid.next = self.skew.out_valid.val();
        self.wtop.flush.next = self.skew.out_flush.val();
        self.wtop.x.next = self.t1.out_x.val();
        self.wtop.y.next = self.skew.out_y.val();
        self.wmid.valid.next = self.skew.out_valid.val();
        self.wmid.flush.next = self.skew.out_flush.val();
        self.wmid.x.next = self.t1.out_x.val();
        self.wmid.y.next = self.skew.out_y.val();
        self.wbot.valid.next = self.skew.out_valid.val();
        self.wbot.flush.next = self.skew.out_flush.val();
        self.wbot.x.next = self.t1.out_x.val();
        self.wbot.y.next = self.skew.out_y.val();
        for i in 0..self._p {
            self.h1[i].clock.next = self.clock.val();
            self.h1[i].d.next = self.filtered[i].val();
            self.line[2 * i].write_data.next = self.h1[i].q.val();
            self.line[2 * i + 1].write_data.next = self.line[2 * i].read_data.val();
            self.wmid.lanes[i].next = self.line[2 * i].read_data.val();
            self.wtop.lanes[i].next = 0.into();
            if self.top_ok.val() {
                self.wtop.lanes[i].next = self.line[2 * i + 1].read_data.val();
            }
            self.wbot.lanes[i].next = 0.into();
            if self.bot_ok.val() {
                self.wbot.lanes[i].next = self.h1[i].q.val();
            }
        }

        // C2: compare with T_int and the 8 neighbours, register.
        self.t3.valid.next = self.wmid.out_valid.val();
        self.t3.flush.next = self.wmid.out_flush.val();
        self.t3.x.next = self.wmid.out_x.val();
        self.t3.y.next = self.wmid.out_y.val();
        self.thr.threshold.next = self.threshold.val();
        for n in 0..(self._p + 1) {
            self.mid_gt[n].next = self.wmid.win[n + 1].val() > self.wmid.win[n].val();
        }
        for i in 0..self._p {
            self.thr.filtered[i].next = self.wmid.win[i + 1].val();
            self.above_q[i].clock.next = self.clock.val();
            self.cand_q[i].clock.next = self.clock.val();
            self.above_q[i].d.next = self.thr.above[i].val();
            self.cand_q[i].d.next = self.thr.above[i].val()
                & (self.wmid.win[i + 1].val() > self.wtop.win[i].val())
                & (self.wmid.win[i + 1].val() > self.wtop.win[i + 1].val())
                & (self.wmid.win[i + 1].val() > self.wtop.win[i + 2].val())
                & self.mid_gt[i].val()
                & !self.mid_gt[i + 1].val()
                & (self.wmid.win[i + 1].val() >= self.wbot.win[i].val())
                & (self.wmid.win[i + 1].val() >= self.wbot.win[i + 1].val())
                & (self.wmid.win[i + 1].val() >= self.wbot.win[i + 2].val());
            self.above[i].next = self.above_q[i].q.val();
            self.candidate[i].next = self.cand_q[i].q.val();
        }
        self.out_valid.next = self.t3.out_valid.val();
        self.out_flush.next = self.t3.out_flush.val();
        self.out_x.next = self.t3.out_x.val();
        self.out_y.next = self.t3.out_y.val();
    }
}
