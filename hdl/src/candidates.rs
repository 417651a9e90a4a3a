//! Stages 3–4 — threshold and candidates, with hysteresis: the *above*
//! bits (the tracker's on/off test) are `H ≥ T_hold`, and candidates are
//! pixels with `H ≥ T_int` (the open level, `T_int ≥ T_hold`) that are
//! maxima of their 3×3 neighbourhood with the tie rule of
//! [`smartagg_model::candidates`]: strictly greater than the four earlier
//! neighbours in raster order, greater than or equal to the four later ones.
//! Neighbours outside the sensor are zero, which an above-threshold pixel
//! (H ≥ T_int ≥ 1) always beats — the model's "ignored".
//!
//! A line buffer of H (row y − 1) gives the middle and bottom rows of each
//! word when row y arrives (output row y − 1, [`RowSkew`]); two
//! [`WordWindow`]s add one pixel of context each side.
//!
//! **Each neighbour pair compared once.** A pixel and a later neighbour
//! need `a ≥ b` and `b > a = ¬(a ≥ b)`: one comparator serves both. In the
//! middle row, each horizontal pair; between the middle and the bottom
//! row, the three pairs of each bottom pixel (3P + 2 comparators a word):
//! the middle pixels take their bottom tests now, and the bottom pixels'
//! top tests (negated) wait one row in a LUT RAM of 3 bits per pixel
//! ([`LutRam`], read and written by this stage one row apart), instead of
//! a second line buffer of H, a third window and 3P more comparators.
//! Output per word: the above-hold
//! bits and the candidate bits of its P pixels with the word's column and
//! row, in raster order — a candidate's position is `(x·P + lane, y)`.
//! Latency: 2 clocks, one word (window), 1 clock.

use crate::bram::{Bram, LutRam, RamStyle};
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
    /// T_int (runtime register): the open level of candidates.
    pub threshold: Signal<In, Bits<HW>>,
    /// T_hold (runtime register, ≤ T_int): the level of the `above` bits.
    pub threshold_hold: Signal<In, Bits<HW>>,
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
    /// `H ≥ T_hold` per pixel.
    pub above: Vec<Signal<Out, Bit>>,
    /// Candidate per pixel.
    pub candidate: Vec<Signal<Out, Bit>>,
    line: Vec<Bram<HW, LAW>>,
    t1: TagReg,
    h1: Vec<DFF<Bits<HW>>>,
    skew: RowSkew,
    bot_ok: Signal<Local, Bit>,
    wmid: WordWindow<HW>,
    wbot: WordWindow<HW>,
    /// `H ≥ T_int` (candidates).
    thr: Threshold<HW>,
    /// `H ≥ T_hold` (the above bits).
    thr_hold: Threshold<HW>,
    t3: TagReg,
    above_q: Vec<DFF<Bit>>,
    /// Middle row, `win[n + 1] > win[n]`: each horizontal neighbour pair is
    /// compared once, for the pixel on its right (strictly greater than
    /// the earlier one) and, negated, for the pixel on its left (greater
    /// than or equal to the later one).
    mid_gt: Vec<Signal<Local, Bit>>,
    /// `mid.win[n] ≥ bot.win[n + 1]` (n ≤ P): the bottom pixel's left neighbour above.
    ge_l: Vec<Signal<Local, Bit>>,
    /// `mid.win[i + 1] ≥ bot.win[i + 1]`: the pixel above.
    ge_c: Vec<Signal<Local, Bit>>,
    /// `mid.win[n + 1] ≥ bot.win[n]` (n ≤ P): the bottom pixel's right neighbour above.
    ge_r: Vec<Signal<Local, Bit>>,
    /// Per lane, the bottom pixel's strict tests against its three upper
    /// neighbours (bits 0, 1, 2: left, above, right), for the next row.
    top_wr: Vec<Signal<Local, Bits<3>>>,
    /// Per lane, the same bits of the middle row, written one row ago.
    top_mem: Vec<LutRam<3, LAW>>,
    top_ok2: Signal<Local, Bit>,
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
        Ok(Candidates {
            clock: Default::default(),
            restart: Default::default(),
            threshold: Default::default(),
            threshold_hold: Default::default(),
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
            // Block RAM even for short rows: a lane's row of H (HW ≤ 36
            // bits) is one RAMB8, where LUT RAM would take ⌈HW/6⌉ RAM32M (16
            // LUTs for the SPCImager's 24 bits) — LUTs are what the LX45
            // runs out of, block RAM is half free.
            line: (0..p).map(|_| Bram::new(wpr, RamStyle::Block)).collect(),
            t1: Default::default(),
            h1: lanes(p),
            skew: RowSkew::new(1, cfg.height),
            bot_ok: Default::default(),
            wmid: WordWindow::new(p, 1, wpr),
            wbot: WordWindow::new(p, 1, wpr),
            thr: Threshold::new(p),
            thr_hold: Threshold::new(p),
            t3: Default::default(),
            above_q: lanes(p),
            mid_gt: lanes(p + 1),
            ge_l: lanes(p + 1),
            ge_c: lanes(p),
            ge_r: lanes(p + 1),
            top_wr: lanes(p),
            top_mem: (0..p).map(|_| LutRam::new(wpr)).collect(),
            top_ok2: Default::default(),
            cand_q: lanes(p),
            _p: p,
        })
    }
}

impl<const HW: usize, const LAW: usize> Logic for Candidates<HW, LAW> {
    #[hdl_gen]
    fn update(&mut self) {
        clock!(self, clock, t1, skew, wmid, wbot, t3);
        self.t1.restart.next = self.restart.val();
        self.skew.restart.next = self.restart.val();
        self.wmid.restart.next = self.restart.val();
        self.wbot.restart.next = self.restart.val();
        self.t3.restart.next = self.restart.val();

        // C0: read row y − 1 of this column word.
        self.t1.valid.next = self.valid.val();
        self.t1.flush.next = self.flush.val();
        self.t1.x.next = self.x.val();
        self.t1.y.next = self.y.val();
        for q in 0..self._p {
            self.line[q].clock.next = self.clock.val();
            self.line[q].read_address.next = bit_cast::<LAW, 16>(self.x.val());
            self.line[q].write_address.next = bit_cast::<LAW, 16>(self.t1.out_x.val());
            self.line[q].write_enable.next = self.t1.out_valid.val();
        }

        // C1: the column (mid, bottom) of output row y − 1, the bottom zero
        // outside the plane.
        self.skew.valid.next = self.t1.out_valid.val();
        self.skew.flush.next = self.t1.out_flush.val();
        self.skew.origin.next = self.t1.out_origin.val();
        self.skew.y.next = self.t1.out_y.val();
        // The output row y − 1 is the last row exactly when the input row is
        // 0 (it wraps to H − 1): compared on the input's register, not
        // behind the skew's subtraction.
        self.bot_ok.next = self.t1.out_y.val() != 0;
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
            self.line[i].write_data.next = self.h1[i].q.val();
            self.wmid.lanes[i].next = self.line[i].read_data.val();
            self.wbot.lanes[i].next = 0.into();
            if self.bot_ok.val() {
                self.wbot.lanes[i].next = self.h1[i].q.val();
            }
        }

        // C2: compare with T_int, T_hold and the 8 neighbours, register.
        self.t3.valid.next = self.wmid.out_valid.val();
        self.t3.flush.next = self.wmid.out_flush.val();
        self.t3.x.next = self.wmid.out_x.val();
        self.t3.y.next = self.wmid.out_y.val();
        self.thr.threshold.next = self.threshold.val();
        self.thr_hold.threshold.next = self.threshold_hold.val();
        for n in 0..(self._p + 1) {
            self.mid_gt[n].next = self.wmid.win[n + 1].val() > self.wmid.win[n].val();
            self.ge_l[n].next = self.wmid.win[n].val() >= self.wbot.win[n + 1].val();
            self.ge_r[n].next = self.wmid.win[n + 1].val() >= self.wbot.win[n].val();
        }
        // Row 0 has no row above (the LUT RAM holds the previous plane's
        // last row, or nothing): its top tests pass, as against the model's
        // ignored neighbours.
        self.top_ok2.next = self.wmid.out_y.val() != 0;
        for i in 0..self._p {
            self.ge_c[i].next = self.wmid.win[i + 1].val() >= self.wbot.win[i + 1].val();
            self.top_mem[i].clock.next = self.clock.val();
            self.top_mem[i].read_address.next = bit_cast::<LAW, 16>(self.wmid.out_x.val());
            self.top_mem[i].write_address.next = bit_cast::<LAW, 16>(self.wmid.out_x.val());
            self.top_mem[i].write_enable.next = self.wmid.out_valid.val();
            self.top_wr[i].next = 0.into();
            if !self.ge_l[i].val() {
                self.top_wr[i].next = self.top_wr[i].val() | 1;
            }
            if !self.ge_c[i].val() {
                self.top_wr[i].next = self.top_wr[i].val() | 2;
            }
            if !self.ge_r[i + 1].val() {
                self.top_wr[i].next = self.top_wr[i].val() | 4;
            }
            self.top_mem[i].write_data.next = self.top_wr[i].val();
        }
        for i in 0..self._p {
            self.thr.filtered[i].next = self.wmid.win[i + 1].val();
            self.thr_hold.filtered[i].next = self.wmid.win[i + 1].val();
            self.above_q[i].clock.next = self.clock.val();
            self.cand_q[i].clock.next = self.clock.val();
            self.above_q[i].d.next = self.thr_hold.above[i].val();
            self.cand_q[i].d.next = self.thr.above[i].val()
                & (!self.top_ok2.val() | (self.top_mem[i].read_data.val() == 7))
                & self.mid_gt[i].val()
                & !self.mid_gt[i + 1].val()
                & self.ge_r[i].val()
                & self.ge_c[i].val()
                & self.ge_l[i + 1].val();
            self.above[i].next = self.above_q[i].q.val();
            self.candidate[i].next = self.cand_q[i].q.val();
        }
        self.out_valid.next = self.t3.out_valid.val();
        self.out_flush.next = self.t3.out_flush.val();
        self.out_x.next = self.t3.out_x.val();
        self.out_y.next = self.t3.out_y.val();
    }
}
