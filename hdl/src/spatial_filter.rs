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
//! constant weight, then sum the c + 1 products. All sums stay below
//! N_max·2^a (resp. N_max·2^(2a)), so VW = CW + a and HW = CW + 2a bits
//! never wrap. A multiply ([`ConstMul`]) is shift-and-add in LUTs, one
//! adder or subtractor per non-zero canonical signed digit after the first
//! (29 = 32 − 4 + 1), or a DSP48A1 slice: the configuration gives the
//! device's slices (`dsp_multipliers`), and they take the multiplies that
//! would cost the most LUTs (adders × width; an operand of at most 17
//! bits). For the SPCImager at 150× (k1 = 2 10 29 54 66) the LX45's 58
//! slices take the 32 horizontal multiplies by 29 and 54 and 26 vertical
//! ones; the other 102 stay in LUTs.
//!
//! Latency: 4 clocks of vertical pipeline, then one word (the window waits
//! for the next word) and 4 clocks of horizontal pipeline.

use crate::bram::{Bram, RamStyle};
use crate::config::{GatewareConfig, GatewareError};
use crate::const_mul::{csd_adders, ConstMul, DSP_OPERAND_BITS};
use crate::stream::{lanes, EnableRegs, RowSkew, TagReg, Widen, WordWindow};
use rust_hdl::prelude::*;

/// Bits of a lane's column word in the vertical pass's line buffer: the
/// k − 1 rows of CW bits must fit ((k − 1)·CW ≤ 64; the SPCImager's 150×
/// kernel needs 8 × 8 = 64). Two RAMB8s at 32 bits hold it, as they would
/// 72; 64 rather than the RAMB8s' 72 because it is a simulator's widest
/// native word: at 72 bits Verilator shifts and copies the 16 lanes' words
/// as arrays, 7 % of the full-field co-simulation's time.
pub const LINE_BITS: usize = 64;

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
    /// Per lane, the column of rows y−1 … y−(k−1) in one word (row y − 1 −
    /// m at bits m·CW): one memory per lane, so that block RAM holds the
    /// k − 1 rows in a few RAMB8s instead of k − 1 narrow memories each.
    line: Vec<Bram<LINE_BITS, LAW>>,
    /// The column word shifted down by m·CW bits, cut to tap m + 1.
    lrow: Vec<Widen<LINE_BITS, CW>>,
    /// The new row, widened to a column word.
    lwid: Vec<Widen<CW, LINE_BITS>>,
    lup: Vec<Signal<Local, Bits<LINE_BITS>>>,
    lnew: Vec<Signal<Local, Bits<LINE_BITS>>>,
    /// CW: one row down the column word.
    row_step: Constant<Bits<8>>,
    /// m·CW for m = 0 … k − 2: row y − 1 − m.
    row_shift: Vec<Constant<Bits<8>>>,
    /// The (k − 1)·CW bits of a column word.
    line_mask: Constant<Bits<LINE_BITS>>,
    t1: TagReg,
    s1: EnableRegs<Bits<CW>>,
    skew: RowSkew,
    tap_lo: Vec<Constant<Bits<16>>>,
    tap_hi: Vec<Constant<Bits<16>>>,
    /// Tap m's lowest input row `m − H` in a plane's first c rows, for
    /// m > H (entry m − `_kw`); the highest is `tap_lo[m − 1] − 1`.
    wrap_lo: Vec<Constant<Bits<16>>>,
    half: Constant<Bits<16>>,
    /// The tap masks (tap m's row lies in the plane), computed from `yoc`
    /// as the word enters V0 and registered with its tag, so that V1's taps
    /// start from registers.
    mask: Vec<DFF<Bit>>,
    vwid: Vec<Widen<CW, VW>>,
    tap: Vec<Signal<Local, Bits<VW>>>,
    t2: TagReg,
    vpair: EnableRegs<Bits<VW>>,
    vmul: Vec<ConstMul<VW>>,
    t3: TagReg,
    vprod: EnableRegs<Bits<VW>>,
    vsum: Vec<Signal<Local, Bits<VW>>>,
    t4: TagReg,
    vout: EnableRegs<Bits<VW>>,
    // Horizontal pass.
    window: WordWindow<VW>,
    hwid: Vec<Widen<VW, HW>>,
    t5: TagReg,
    hpair: EnableRegs<Bits<HW>>,
    hmul: Vec<ConstMul<HW>>,
    t6: TagReg,
    hprod: EnableRegs<Bits<HW>>,
    hsum: Vec<Signal<Local, Bits<HW>>>,
    t7: TagReg,
    hout: EnableRegs<Bits<HW>>,
    _p: usize,
    _k: usize,
    /// Taps 1 … `_kw − 1` have no lower bound in a plane's first c rows
    /// (m ≤ H); taps `_kw` … k − 1 do (the plane is shorter than the kernel).
    _kw: usize,
    /// k − `_kw`.
    _kn: usize,
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
        if (k - 1) * CW > LINE_BITS {
            return Err(GatewareError::Invalid {
                field: "kernel",
                value: format!("{k} taps of {CW}-bit counts"),
                why: format!("the line buffer's column word holds (k − 1)·CW ≤ {LINE_BITS} bits"),
            });
        }
        let c16 = |v: usize| Constant::new((v as u64).to_bits());
        // Tap m (0 = newest row) of output row yo reads source row yo + c − m,
        // inside the plane iff m ≤ yo + c < H + m. For an input row y ≥ c
        // (yo = y − c) that is m ≤ y < H + m; for y < c, a row that finishes
        // the previous plane (yo = y + H − c), it is m − H ≤ y < m.
        let tap_lo = (1..k).map(c16).collect();
        let tap_hi = (0..k).map(|m| c16(cfg.height + m)).collect();
        let wrap_lo = (cfg.height + 1..k).map(|m| c16(m - cfg.height)).collect();
        // The multiplies (q = lane·(c + 1) + j, weight k1[j]; the operand is a
        // pre-added pair but for the centre tap j = c), and which of them go
        // to DSP slices: those that save the most LUTs (adders × width),
        // the horizontal pass first on a tie, then in order.
        let n_mul = p * (c + 1);
        let operand_bits = |j: usize, w: usize| if j < c { w + 1 } else { w };
        let mut saving: Vec<(usize, usize, usize)> = (0..2 * n_mul)
            .filter_map(|m| {
                let (horizontal, q) = (m < n_mul, m % n_mul);
                let j = q % (c + 1);
                let (bits, width) = if horizontal {
                    (operand_bits(j, VW), HW)
                } else {
                    (operand_bits(j, CW), VW)
                };
                let adders = csd_adders(cfg.kernel[j]);
                (adders > 0 && bits <= DSP_OPERAND_BITS).then_some((adders * width, m, bits))
            })
            .collect();
        saving.sort_by_key(|&(saved, m, _)| (std::cmp::Reverse(saved), m));
        let mut dsp_bits = vec![None; 2 * n_mul];
        for &(_, m, bits) in saving.iter().take(cfg.dsp_multipliers) {
            dsp_bits[m] = Some(bits);
        }
        let mul =
            |m: usize| -> (u32, Option<usize>) { (cfg.kernel[(m % n_mul) % (c + 1)], dsp_bits[m]) };
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
            // Block RAM even for short rows: a lane's column word is two
            // RAMB8s, where LUT RAM would take 16 RAM32M (64 LUTs) for the
            // SPCImager.
            line: (0..p).map(|_| Bram::new(wpr, RamStyle::Block)).collect(),
            lrow: (0..p * (k - 1)).map(|_| Widen::default()).collect(),
            lwid: (0..p).map(|_| Widen::default()).collect(),
            lup: lanes(p),
            lnew: lanes(p),
            row_step: Constant::new((CW as u64).to_bits()),
            row_shift: (0..k - 1)
                .map(|m| Constant::new(((m * CW) as u64).to_bits()))
                .collect(),
            line_mask: Constant::new(
                (0..(k - 1) * CW).fold(Bits::<LINE_BITS>::default(), |b, i| b.replace_bit(i, true)),
            ),
            t1: Default::default(),
            s1: EnableRegs::new(p),
            skew: RowSkew::new(c, cfg.height),
            tap_lo,
            tap_hi,
            wrap_lo,
            half: c16(c),
            mask: (0..k).map(|_| Default::default()).collect(),
            vwid: lanes(p * k),
            tap: lanes(p * k),
            t2: Default::default(),
            vpair: EnableRegs::new(p * (c + 1)),
            vmul: (n_mul..2 * n_mul).map(|m| ConstMul::of(mul(m))).collect(),
            t3: Default::default(),
            vprod: EnableRegs::new(p * (c + 1)),
            vsum: lanes(p * (c + 2)),
            t4: Default::default(),
            vout: EnableRegs::new(p),
            window: WordWindow::new(p, c, wpr),
            hwid: lanes(p + 2 * c),
            t5: Default::default(),
            hpair: EnableRegs::new(p * (c + 1)),
            hmul: (0..n_mul).map(|m| ConstMul::of(mul(m))).collect(),
            t6: Default::default(),
            hprod: EnableRegs::new(p * (c + 1)),
            hsum: lanes(p * (c + 2)),
            t7: Default::default(),
            hout: EnableRegs::new(p),
            _p: p,
            _k: k,
            _kw: k.min(cfg.height + 1),
            _kn: k - k.min(cfg.height + 1),
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
        clock!(
            self, clock, t1, t2, t3, t4, t5, t6, t7, skew, window, s1, vpair, vprod, vout, hpair,
            hprod, hout
        );
        // The lane registers load only with a word (one clock enable per
        // stage, its word's valid tag), and their next values are computed
        // only then: most clocks carry no word.
        self.s1.enable.next = self.valid.val();
        self.vpair.enable.next = self.skew.out_valid.val();
        self.vprod.enable.next = self.t2.out_valid.val();
        self.vout.enable.next = self.t3.out_valid.val();
        self.hpair.enable.next = self.window.out_valid.val();
        self.hprod.enable.next = self.t5.out_valid.val();
        self.hout.enable.next = self.t6.out_valid.val();
        self.t1.restart.next = self.restart.val();
        self.t2.restart.next = self.restart.val();
        self.t3.restart.next = self.restart.val();
        self.t4.restart.next = self.restart.val();
        self.t5.restart.next = self.restart.val();
        self.t6.restart.next = self.restart.val();
        self.t7.restart.next = self.restart.val();
        self.skew.restart.next = self.restart.val();
        self.window.restart.next = self.restart.val();

        // V0: read the k − 1 older rows of this column word; its tap masks
        // (compares of the input row with constants; see `new`). Tap 0 (the
        // newest row) is never above the plane.
        for m in 0..self._k {
            self.mask[m].clock.next = self.clock.val();
        }
        self.mask[0].d.next =
            (self.y.val() >= self.half.val()) & (self.y.val() < self.tap_hi[0].val());
        for m in 1..self._k {
            self.mask[m].d.next = self.y.val() < self.tap_lo[m - 1].val();
        }
        for kw in self._kw..(self._kw + 1) {
            for j in 0..self._kn {
                self.mask[j + kw].d.next = (self.wrap_lo[j].val() <= self.y.val())
                    & (self.y.val() < self.tap_lo[j + kw - 1].val());
            }
        }
        for m in 1..self._k {
            if self.y.val() >= self.half.val() {
                self.mask[m].d.next = (self.tap_lo[m - 1].val() <= self.y.val())
                    & (self.y.val() < self.tap_hi[m].val());
            }
        }
        self.t1.valid.next = self.valid.val();
        self.t1.flush.next = self.flush.val();
        self.t1.x.next = self.x.val();
        self.t1.y.next = self.y.val();
        for i in 0..self._p {
            if self.valid.val() {
                self.s1.d[i].next = self.counts[i].val();
            } else {
                self.s1.d[i].next = 0.into();
            }
        }
        for i in 0..self._p {
            self.line[i].clock.next = self.clock.val();
            self.line[i].read_address.next = bit_cast::<LAW, 16>(self.x.val());
            self.line[i].write_address.next = bit_cast::<LAW, 16>(self.t1.out_x.val());
            self.line[i].write_enable.next = self.t1.out_valid.val();
        }

        // V1: output row, shift the column down, pre-add pairs.
        self.skew.valid.next = self.t1.out_valid.val();
        self.skew.flush.next = self.t1.out_flush.val();
        self.skew.origin.next = self.t1.out_origin.val();
        self.skew.y.next = self.t1.out_y.val();
        for kk in self._k..(self._k + 1) {
            for km in (self._k - 1)..self._k {
                for i in 0..self._p {
                    // The column moves down a row: the new row at the bottom
                    // bits, the oldest row shifted out (and masked off).
                    // (Only a word's clock writes the line or reads its taps.)
                    self.lwid[i].x.next = self.s1.q[i].val();
                    self.vwid[i * kk].x.next = self.s1.q[i].val();
                    if self.t1.out_valid.val() {
                        self.lup[i].next = self.line[i].read_data.val() << self.row_step.val();
                        self.lnew[i].next = self.lup[i].val() | self.lwid[i].y.val();
                        self.line[i].write_data.next = self.lnew[i].val() & self.line_mask.val();
                        for m in 1..self._k {
                            self.lrow[i * km + m - 1].x.next =
                                self.line[i].read_data.val() >> self.row_shift[m - 1].val();
                        }
                    } else {
                        self.lup[i].next = 0.into();
                        self.lnew[i].next = 0.into();
                        self.line[i].write_data.next = 0.into();
                        for m in 1..self._k {
                            self.lrow[i * km + m - 1].x.next = 0.into();
                        }
                    }
                    for m in 1..self._k {
                        self.vwid[i * kk + m].x.next = self.lrow[i * km + m - 1].y.val();
                    }
                    for m in 0..self._k {
                        self.tap[i * kk + m].next = 0.into();
                    }
                    // (Not gated by the skew's `out_valid`: `vpair` loads
                    // only with it, so the gate was only depth.)
                    for m in 0..self._k {
                        if self.mask[m].q.val() {
                            self.tap[i * kk + m].next = self.vwid[i * kk + m].y.val();
                        }
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
                            self.vpair.d[i * c1 + j].next =
                                self.tap[i * kk + j].val() + self.tap[i * kk + kk - 1 - j].val();
                        }
                        self.vpair.d[i * c1 + cc].next = self.tap[i * kk + cc].val();
                    }
                }
            }
        }

        // V2: constant multiplies. V3: sum of the c + 1 products.
        for q in 0..(self._p * (self._c + 1)) {
            self.vmul[q].x.next = self.vpair.q[q].val();
            if self.t2.out_valid.val() {
                self.vprod.d[q].next = self.vmul[q].y.val();
            } else {
                self.vprod.d[q].next = 0.into();
            }
        }
        self.t3.valid.next = self.t2.out_valid.val();
        self.t3.flush.next = self.t2.out_flush.val();
        self.t3.x.next = self.t2.out_x.val();
        self.t3.y.next = self.t2.out_y.val();
        for c1 in (self._c + 1)..(self._c + 2) {
            for c2 in (self._c + 2)..(self._c + 3) {
                for i in 0..self._p {
                    self.vsum[i * c2].next = 0.into();
                    if self.t3.out_valid.val() {
                        for j in 0..(self._c + 1) {
                            self.vsum[i * c2 + j + 1].next =
                                self.vsum[i * c2 + j].val() + self.vprod.q[i * c1 + j].val();
                        }
                    } else {
                        for j in 0..(self._c + 1) {
                            self.vsum[i * c2 + j + 1].next = 0.into();
                        }
                    }
                    self.vout.d[i].next = self.vsum[i * c2 + c1].val();
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
            self.window.lanes[i].next = self.vout.q[i].val();
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
                        if self.window.out_valid.val() {
                            for j in 0..self._c {
                                self.hpair.d[i * c1 + j].next =
                                    self.hwid[i + j].y.val() + self.hwid[i + kk - 1 - j].y.val();
                            }
                            self.hpair.d[i * c1 + cc].next = self.hwid[i + cc].y.val();
                        } else {
                            for j in 0..(self._c + 1) {
                                self.hpair.d[i * c1 + j].next = 0.into();
                            }
                        }
                    }
                }
            }
        }
        for q in 0..(self._p * (self._c + 1)) {
            self.hmul[q].x.next = self.hpair.q[q].val();
            if self.t5.out_valid.val() {
                self.hprod.d[q].next = self.hmul[q].y.val();
            } else {
                self.hprod.d[q].next = 0.into();
            }
        }
        self.t6.valid.next = self.t5.out_valid.val();
        self.t6.flush.next = self.t5.out_flush.val();
        self.t6.x.next = self.t5.out_x.val();
        self.t6.y.next = self.t5.out_y.val();
        for c1 in (self._c + 1)..(self._c + 2) {
            for c2 in (self._c + 2)..(self._c + 3) {
                for i in 0..self._p {
                    self.hsum[i * c2].next = 0.into();
                    if self.t6.out_valid.val() {
                        for j in 0..(self._c + 1) {
                            self.hsum[i * c2 + j + 1].next =
                                self.hsum[i * c2 + j].val() + self.hprod.q[i * c1 + j].val();
                        }
                    } else {
                        for j in 0..(self._c + 1) {
                            self.hsum[i * c2 + j + 1].next = 0.into();
                        }
                    }
                    self.hout.d[i].next = self.hsum[i * c2 + c1].val();
                    self.filtered[i].next = self.hout.q[i].val();
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
