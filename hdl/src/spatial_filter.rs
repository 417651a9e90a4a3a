//! Stage 2 — spatial filter `H = K ⊛ S` with the separable integer kernel
//! `K = k1 ⊗ k1` and zero padding at all four edges, exactly as
//! [`smartagg_model::spatial_filter::SpatialFilter::apply`].
//!
//! **Order of the passes (a deviation from the brief, same result).** The
//! vertical pass runs first, on the counts S (CW bits), and the horizontal
//! pass second. The filter is linear and exact in integers, so the order does
//! not change a single bit of H, but the k − 1 line buffers then hold CW-bit
//! counts instead of (CW + a)-bit horizontal sums: about half the memory.
//!
//! **Vertical pass.** Per lane, k − 1 one-row delays (memories of W/P words,
//! LUT RAM for short rows) hold rows y−1 … y−(k−1); when row y arrives the
//! column of k values gives output row `y − c` (rows `y < c` finish the
//! previous plane, see [`RowSkew`]). Taps whose source row lies outside the
//! plane are zeroed (the edge padding, and the rows of the neighbouring
//! plane). **Horizontal pass.** A [`WordWindow`] adds c lanes of context on
//! each side (zero beyond the row ends). **Arithmetic.** Both passes use the
//! symmetry `k1[j] = k1[k−1−j]`: pre-add the two taps, then multiply by the
//! constant weight with shift-and-add ([`ConstMul`]: one adder per set bit, no
//! DSP), then sum the c + 1 products. All sums stay below N_max·2^a (resp.
//! N_max·2^(2a)), so VW = CW + a and HW = CW + 2a bits never wrap.
//!
//! Latency: 4 clocks of vertical pipeline, then one word (the window waits
//! for the next word) and 4 clocks of horizontal pipeline.

use crate::bram::{Bram, RamStyle};
use crate::config::{GatewareConfig, GatewareError};
use crate::stream::{lanes, RowSkew, TagReg, Widen, WordWindow};
use rust_hdl::prelude::*;

/// `y = w · x` for a constant weight w, as a chain of shifted adds.
#[derive(LogicBlock)]
pub struct ConstMul<const W: usize> {
    /// Operand.
    pub x: Signal<In, Bits<W>>,
    /// Product (the caller guarantees it fits W bits).
    pub y: Signal<Out, Bits<W>>,
    shifts: Vec<Constant<Bits<8>>>,
    part: Vec<Signal<Local, Bits<W>>>,
    _n: usize,
}

impl<const W: usize> ConstMul<W> {
    /// Multiplier by `weight`.
    pub fn new(weight: u32) -> Self {
        let shifts: Vec<Constant<Bits<8>>> = (0..32)
            .filter(|b| weight >> b & 1 == 1)
            .map(|b| Constant::new((b as u64).to_bits()))
            .collect();
        let n = shifts.len();
        ConstMul {
            x: Default::default(),
            y: Default::default(),
            shifts,
            part: lanes(n + 1),
            _n: n,
        }
    }
}

impl<const W: usize> Logic for ConstMul<W> {
    #[hdl_gen]
    fn update(&mut self) {
        self.part[0].next = 0.into();
        for b in 0..self._n {
            self.part[b + 1].next = self.part[b].val() + (self.x.val() << self.shifts[b].val());
        }
        for nn in self._n..(self._n + 1) {
            self.y.next = self.part[nn].val();
        }
    }
}

/// The separable filter on P lanes. `CW`: count bits; `VW = CW + a`;
/// `HW = CW + 2a`; `LAW`: line-buffer address bits.
#[derive(LogicBlock)]
pub struct SpatialFilter<const CW: usize, const VW: usize, const HW: usize, const LAW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start.
    pub restart: Signal<In, Bit>,
    /// Input word present.
    pub valid: Signal<In, Bit>,
    /// Word of a flush plane.
    pub flush: Signal<In, Bit>,
    /// Word column.
    pub x: Signal<In, Bits<16>>,
    /// Row.
    pub y: Signal<In, Bits<16>>,
    /// Counts S of the word's P pixels.
    pub counts: Vec<Signal<In, Bits<CW>>>,
    /// Output word present.
    pub out_valid: Signal<Out, Bit>,
    /// Output of a flush plane.
    pub out_flush: Signal<Out, Bit>,
    /// Output word column.
    pub out_x: Signal<Out, Bits<16>>,
    /// Output row.
    pub out_y: Signal<Out, Bits<16>>,
    /// H of the output word's P pixels.
    pub filtered: Vec<Signal<Out, Bits<HW>>>,
    // Vertical pass.
    line: Vec<Bram<CW, LAW>>,
    t1: TagReg,
    s1: Vec<DFF<Bits<CW>>>,
    skew: RowSkew,
    yoc: Signal<Local, Bits<16>>,
    tap_lo: Vec<Constant<Bits<16>>>,
    tap_hi: Vec<Constant<Bits<16>>>,
    half: Constant<Bits<16>>,
    mask: Vec<Signal<Local, Bit>>,
    vwid: Vec<Widen<CW, VW>>,
    tap: Vec<Signal<Local, Bits<VW>>>,
    t2: TagReg,
    vpair: Vec<DFF<Bits<VW>>>,
    vmul: Vec<ConstMul<VW>>,
    t3: TagReg,
    vprod: Vec<DFF<Bits<VW>>>,
    vsum: Vec<Signal<Local, Bits<VW>>>,
    t4: TagReg,
    vout: Vec<DFF<Bits<VW>>>,
    // Horizontal pass.
    window: WordWindow<VW>,
    hwid: Vec<Widen<VW, HW>>,
    t5: TagReg,
    hpair: Vec<DFF<Bits<HW>>>,
    hmul: Vec<ConstMul<HW>>,
    t6: TagReg,
    hprod: Vec<DFF<Bits<HW>>>,
    hsum: Vec<Signal<Local, Bits<HW>>>,
    t7: TagReg,
    hout: Vec<DFF<Bits<HW>>>,
    _p: usize,
    _k: usize,
    _c: usize,
}

impl<const CW: usize, const VW: usize, const HW: usize, const LAW: usize>
    SpatialFilter<CW, VW, HW, LAW>
{
    /// The filter of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        GatewareConfig::check_width("SpatialFilter", "CW", CW, cfg.count_bits())?;
        GatewareConfig::check_width("SpatialFilter", "VW", VW, cfg.vertical_bits())?;
        GatewareConfig::check_width("SpatialFilter", "HW", HW, cfg.filtered_bits())?;
        GatewareConfig::check_width("SpatialFilter", "LAW", LAW, cfg.line_addr_bits())?;
        let (p, k, c) = (cfg.pixels_per_clock, cfg.kernel.len(), cfg.half());
        let wpr = cfg.words_per_row();
        let style = if wpr <= 64 {
            RamStyle::Distributed
        } else {
            RamStyle::Block
        };
        let c16 = |v: usize| Constant::new((v as u64).to_bits());
        // Tap m (0 = newest row) of output row yo reads source row yo + c − m,
        // inside the plane iff m ≤ yo + c < H + m.
        let tap_lo = (1..k).map(c16).collect();
        let tap_hi = (0..k).map(|m| c16(cfg.height + m)).collect();
        let muls = |n: usize| -> Vec<u32> { (0..n).map(|q| cfg.kernel[q % (c + 1)]).collect() };
        Ok(SpatialFilter {
            clock: Default::default(),
            restart: Default::default(),
            valid: Default::default(),
            flush: Default::default(),
            x: Default::default(),
            y: Default::default(),
            counts: lanes(p),
            out_valid: Default::default(),
            out_flush: Default::default(),
            out_x: Default::default(),
            out_y: Default::default(),
            filtered: lanes(p),
            line: (0..p * (k - 1)).map(|_| Bram::new(wpr, style)).collect(),
            t1: Default::default(),
            s1: lanes(p),
            skew: RowSkew::new(c, cfg.height),
            yoc: Default::default(),
            tap_lo,
            tap_hi,
            half: c16(c),
            mask: lanes(k),
            vwid: lanes(p * k),
            tap: lanes(p * k),
            t2: Default::default(),
            vpair: lanes(p * (c + 1)),
            vmul: muls(p * (c + 1)).into_iter().map(ConstMul::new).collect(),
            t3: Default::default(),
            vprod: lanes(p * (c + 1)),
            vsum: lanes(p * (c + 2)),
            t4: Default::default(),
            vout: lanes(p),
            window: WordWindow::new(p, c, wpr),
            hwid: lanes(p + 2 * c),
            t5: Default::default(),
            hpair: lanes(p * (c + 1)),
            hmul: muls(p * (c + 1)).into_iter().map(ConstMul::new).collect(),
            t6: Default::default(),
            hprod: lanes(p * (c + 1)),
            hsum: lanes(p * (c + 2)),
            t7: Default::default(),
            hout: lanes(p),
            _p: p,
            _k: k,
            _c: c,
        })
    }
}

impl<const CW: usize, const VW: usize, const HW: usize, const LAW: usize> Logic
    for SpatialFilter<CW, VW, HW, LAW>
{
    #[hdl_gen]
    fn update(&mut self) {
        // Clocks and restarts of the tag pipeline.
        clock!(self, clock, t1, t2, t3, t4, t5, t6, t7, skew, window);
        self.t1.restart.next = self.restart.val();
        self.t2.restart.next = self.restart.val();
        self.t3.restart.next = self.restart.val();
        self.t4.restart.next = self.restart.val();
        self.t5.restart.next = self.restart.val();
        self.t6.restart.next = self.restart.val();
        self.t7.restart.next = self.restart.val();
        self.skew.restart.next = self.restart.val();
        self.window.restart.next = self.restart.val();

        // V0: read the k − 1 older rows of this column word.
        self.t1.valid.next = self.valid.val();
        self.t1.flush.next = self.flush.val();
        self.t1.x.next = self.x.val();
        self.t1.y.next = self.y.val();
        for i in 0..self._p {
            self.s1[i].clock.next = self.clock.val();
            self.s1[i].d.next = self.counts[i].val();
        }
        for q in 0..(self._p * (self._k - 1)) {
            self.line[q].clock.next = self.clock.val();
            self.line[q].read_address.next = bit_cast::<LAW, 16>(self.x.val());
            self.line[q].write_address.next = bit_cast::<LAW, 16>(self.t1.out_x.val());
            self.line[q].write_enable.next = self.t1.out_valid.val();
        }

        // V1: output row, tap masks, shift the column down, pre-add pairs.
        self.skew.valid.next = self.t1.out_valid.val();
        self.skew.flush.next = self.t1.out_flush.val();
        self.skew.x.next = self.t1.out_x.val();
        self.skew.y.next = self.t1.out_y.val();
        self.yoc.next = self.skew.out_y.val() + self.half.val();
        // Tap 0 (the newest row) is never above the plane.
        self.mask[0].next = self.yoc.val() < self.tap_hi[0].val();
        for m in 1..self._k {
            self.mask[m].next = (self.tap_lo[m - 1].val() <= self.yoc.val())
                & (self.yoc.val() < self.tap_hi[m].val());
        }
        for kk in self._k..(self._k + 1) {
            for km in (self._k - 1)..self._k {
                for i in 0..self._p {
                    self.line[i * km].write_data.next = self.s1[i].q.val();
                    self.vwid[i * kk].x.next = self.s1[i].q.val();
                    for m in 1..self._k {
                        self.vwid[i * kk + m].x.next = self.line[i * km + m - 1].read_data.val();
                    }
                    for m in 0..self._k {
                        self.tap[i * kk + m].next = 0.into();
                        if self.mask[m].val() {
                            self.tap[i * kk + m].next = self.vwid[i * kk + m].y.val();
                        }
                    }
                    for m in 1..(self._k - 1) {
                        self.line[i * km + m].write_data.next =
                            self.line[i * km + m - 1].read_data.val();
                    }
                }
            }
        }
        self.t2.valid.next = self.skew.out_valid.val();
        self.t2.flush.next = self.skew.out_flush.val();
        self.t2.x.next = self.t1.out_x.val();
        self.t2.y.next = self.skew.out_y.val();
        for kk in self._k..(self._k + 1) {
            for c1 in (self._c + 1)..(self._c + 2) {
                for cc in self._c..(self._c + 1) {
                    for i in 0..self._p {
                        for j in 0..self._c {
                            self.vpair[i * c1 + j].d.next =
                                self.tap[i * kk + j].val() + self.tap[i * kk + kk - 1 - j].val();
                        }
                        self.vpair[i * c1 + cc].d.next = self.tap[i * kk + cc].val();
                    }
                }
            }
        }

        // V2: constant multiplies. V3: sum of the c + 1 products.
        for q in 0..(self._p * (self._c + 1)) {
            self.vpair[q].clock.next = self.clock.val();
            self.vmul[q].x.next = self.vpair[q].q.val();
            self.vprod[q].clock.next = self.clock.val();
            self.vprod[q].d.next = self.vmul[q].y.val();
        }
        self.t3.valid.next = self.t2.out_valid.val();
        self.t3.flush.next = self.t2.out_flush.val();
        self.t3.x.next = self.t2.out_x.val();
        self.t3.y.next = self.t2.out_y.val();
        for c1 in (self._c + 1)..(self._c + 2) {
            for c2 in (self._c + 2)..(self._c + 3) {
                for i in 0..self._p {
                    self.vsum[i * c2].next = 0.into();
                    for j in 0..(self._c + 1) {
                        self.vsum[i * c2 + j + 1].next =
                            self.vsum[i * c2 + j].val() + self.vprod[i * c1 + j].q.val();
                    }
                    self.vout[i].clock.next = self.clock.val();
                    self.vout[i].d.next = self.vsum[i * c2 + c1].val();
                }
            }
        }
        self.t4.valid.next = self.t3.out_valid.val();
        self.t4.flush.next = self.t3.out_flush.val();
        self.t4.x.next = self.t3.out_x.val();
        self.t4.y.next = self.t3.out_y.val();

        // H0: the word with c lanes of context each side.
        self.window.valid.next = self.t4.out_valid.val();
        self.window.flush.next = self.t4.out_flush.val();
        self.window.x.next = self.t4.out_x.val();
        self.window.y.next = self.t4.out_y.val();
        for i in 0..self._p {
            self.window.lanes[i].next = self.vout[i].q.val();
        }

        // H1: pre-add pairs; H2: multiplies; H3: sums.
        for n in 0..(self._p + 2 * self._c) {
            self.hwid[n].x.next = self.window.win[n].val();
        }
        self.t5.valid.next = self.window.out_valid.val();
        self.t5.flush.next = self.window.out_flush.val();
        self.t5.x.next = self.window.out_x.val();
        self.t5.y.next = self.window.out_y.val();
        for kk in self._k..(self._k + 1) {
            for c1 in (self._c + 1)..(self._c + 2) {
                for cc in self._c..(self._c + 1) {
                    for i in 0..self._p {
                        for j in 0..self._c {
                            self.hpair[i * c1 + j].d.next =
                                self.hwid[i + j].y.val() + self.hwid[i + kk - 1 - j].y.val();
                        }
                        self.hpair[i * c1 + cc].d.next = self.hwid[i + cc].y.val();
                    }
                }
            }
        }
        for q in 0..(self._p * (self._c + 1)) {
            self.hpair[q].clock.next = self.clock.val();
            self.hmul[q].x.next = self.hpair[q].q.val();
            self.hprod[q].clock.next = self.clock.val();
            self.hprod[q].d.next = self.hmul[q].y.val();
        }
        self.t6.valid.next = self.t5.out_valid.val();
        self.t6.flush.next = self.t5.out_flush.val();
        self.t6.x.next = self.t5.out_x.val();
        self.t6.y.next = self.t5.out_y.val();
        for c1 in (self._c + 1)..(self._c + 2) {
            for c2 in (self._c + 2)..(self._c + 3) {
                for i in 0..self._p {
                    self.hsum[i * c2].next = 0.into();
                    for j in 0..(self._c + 1) {
                        self.hsum[i * c2 + j + 1].next =
                            self.hsum[i * c2 + j].val() + self.hprod[i * c1 + j].q.val();
                    }
                    self.hout[i].clock.next = self.clock.val();
                    self.hout[i].d.next = self.hsum[i * c2 + c1].val();
                    self.filtered[i].next = self.hout[i].q.val();
                }
            }
        }
        self.t7.valid.next = self.t6.out_valid.val();
        self.t7.flush.next = self.t6.out_flush.val();
        self.t7.x.next = self.t6.out_x.val();
        self.t7.y.next = self.t6.out_y.val();
        self.out_valid.next = self.t7.out_valid.val();
        self.out_flush.next = self.t7.out_flush.val();
        self.out_x.next = self.t7.out_x.val();
        self.out_y.next = self.t7.out_y.val();
    }
}
