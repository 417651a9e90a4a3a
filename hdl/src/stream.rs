//! The pixel stream and the small blocks every stage shares.
//!
//! **Stream.** Words of P pixels arrive in raster order with a `valid`
//! strobe; stalls (valid low) may occur at any clock and the pipeline has no
//! back-pressure: every stage takes a word whenever one is valid. The entry
//! stage ([`crate::delay_line`]) turns the start-of-plane marker `sop` into an
//! explicit position; from there on every word carries its word column `x`,
//! its row `y` and a `flush` flag.
//!
//! **Flush planes.** The spatial filter and the 3×3 candidate window emit row
//! y of a plane only when row `y + c` (resp. `y + 1`) arrives, so the last
//! rows of a plane come out while the next plane streams in. At stream end the
//! source sends one *flush plane* (`flush` high on each of its words): it
//! pushes the tail of the last plane out, touches neither the delay line nor
//! the counters, and its own outputs carry `flush` so consumers drop them.

use rust_hdl::prelude::*;

/// Position of the word at the input: from `sop` and the plane geometry.
#[derive(LogicBlock)]
pub struct RasterPosition {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// A word is present.
    pub valid: Signal<In, Bit>,
    /// The word is the first of a plane.
    pub sop: Signal<In, Bit>,
    /// Word column of the present word.
    pub x: Signal<Out, Bits<16>>,
    /// Row of the present word.
    pub y: Signal<Out, Bits<16>>,
    /// Word index within the plane.
    pub idx: Signal<Out, Bits<32>>,
    next_x: DFF<Bits<16>>,
    next_y: DFF<Bits<16>>,
    next_idx: DFF<Bits<32>>,
    cur_x: Signal<Local, Bits<16>>,
    cur_y: Signal<Local, Bits<16>>,
    cur_idx: Signal<Local, Bits<32>>,
    last_x: Constant<Bits<16>>,
    last_y: Constant<Bits<16>>,
}

impl RasterPosition {
    /// Position counter for planes of `words_per_row × height` words.
    pub fn new(words_per_row: usize, height: usize) -> Self {
        RasterPosition {
            clock: Default::default(),
            valid: Default::default(),
            sop: Default::default(),
            x: Default::default(),
            y: Default::default(),
            idx: Default::default(),
            next_x: Default::default(),
            next_y: Default::default(),
            next_idx: Default::default(),
            cur_x: Default::default(),
            cur_y: Default::default(),
            cur_idx: Default::default(),
            last_x: Constant::new((words_per_row as u64 - 1).to_bits()),
            last_y: Constant::new((height as u64 - 1).to_bits()),
        }
    }
}

impl Logic for RasterPosition {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, next_x, next_y, next_idx);
        self.cur_x.next = self.next_x.q.val();
        self.cur_y.next = self.next_y.q.val();
        self.cur_idx.next = self.next_idx.q.val();
        if self.sop.val() {
            self.cur_x.next = 0.into();
            self.cur_y.next = 0.into();
            self.cur_idx.next = 0.into();
        }
        if self.valid.val() {
            self.next_idx.d.next = self.cur_idx.val() + 1;
            self.next_x.d.next = self.cur_x.val() + 1;
            if self.cur_x.val() == self.last_x.val() {
                self.next_x.d.next = 0.into();
                self.next_y.d.next = self.cur_y.val() + 1;
                if self.cur_y.val() == self.last_y.val() {
                    self.next_y.d.next = 0.into();
                    self.next_idx.d.next = 0.into();
                }
            }
        }
        self.x.next = self.cur_x.val();
        self.y.next = self.cur_y.val();
        self.idx.next = self.cur_idx.val();
    }
}

/// Row skew: a stage that emits row `y − s` when row `y` arrives. Words of
/// rows `y < s` belong to the *previous* plane (row `y + H − s`); they are
/// valid only if there was a previous plane, and carry its flush flag.
#[derive(LogicBlock)]
pub struct RowSkew {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Clears the plane history (stream start).
    pub restart: Signal<In, Bit>,
    /// Input word present.
    pub valid: Signal<In, Bit>,
    /// Input word is of a flush plane.
    pub flush: Signal<In, Bit>,
    /// The input word is the plane's first (column 0 of row 0): a
    /// register's output ([`TagReg`]'s `out_origin`), so that the plane
    /// history does not wait on two 16-bit compares.
    pub origin: Signal<In, Bit>,
    /// Input row.
    pub y: Signal<In, Bits<16>>,
    /// An output row is due.
    pub out_valid: Signal<Out, Bit>,
    /// The output row belongs to a flush plane.
    pub out_flush: Signal<Out, Bit>,
    /// Output row.
    pub out_y: Signal<Out, Bits<16>>,
    started: DFF<Bit>,
    cur_flush: DFF<Bit>,
    prev_started: DFF<Bit>,
    prev_flush: DFF<Bit>,
    sop: Signal<Local, Bit>,
    lag: Constant<Bits<16>>,
    wrap: Constant<Bits<16>>,
}

impl RowSkew {
    /// A skew of `skew < height` rows on planes of `height` rows.
    pub fn new(skew: usize, height: usize) -> Self {
        assert!(skew < height);
        RowSkew {
            clock: Default::default(),
            restart: Default::default(),
            valid: Default::default(),
            flush: Default::default(),
            origin: Default::default(),
            y: Default::default(),
            out_valid: Default::default(),
            out_flush: Default::default(),
            out_y: Default::default(),
            started: Default::default(),
            cur_flush: Default::default(),
            prev_started: Default::default(),
            prev_flush: Default::default(),
            sop: Default::default(),
            lag: Constant::new((skew as u64).to_bits()),
            wrap: Constant::new(((height - skew) as u64).to_bits()),
        }
    }
}

impl Logic for RowSkew {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, started, cur_flush, prev_started, prev_flush);
        self.sop.next = self.valid.val() & self.origin.val();
        if self.sop.val() {
            self.started.d.next = true;
            self.cur_flush.d.next = self.flush.val();
            self.prev_started.d.next = self.started.q.val();
            self.prev_flush.d.next = self.cur_flush.q.val();
        }
        if self.y.val() >= self.lag.val() {
            self.out_y.next = self.y.val() - self.lag.val();
            self.out_valid.next = self.valid.val();
            self.out_flush.next = self.flush.val();
        } else {
            self.out_y.next = self.y.val() + self.wrap.val();
            if self.sop.val() {
                self.out_valid.next = self.valid.val() & self.started.q.val();
                self.out_flush.next = self.cur_flush.q.val();
            } else {
                self.out_valid.next = self.valid.val() & self.prev_started.q.val();
                self.out_flush.next = self.prev_flush.q.val();
            }
        }
        if self.restart.val() {
            self.started.d.next = false;
            self.prev_started.d.next = false;
        }
    }
}

/// Horizontal context: holds the last two words and, when the next word
/// arrives, emits the current word's P lanes with `ctx` lanes of context on
/// each side (zero beyond the row ends) — `P + 2·ctx` lanes, registered.
/// The word of a row end is emitted when any following word arrives.
#[derive(LogicBlock)]
pub struct WordWindow<const DW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Drops the held word (stream start).
    pub restart: Signal<In, Bit>,
    /// Input word present.
    pub valid: Signal<In, Bit>,
    /// Input is of a flush plane.
    pub flush: Signal<In, Bit>,
    /// Input word column.
    pub x: Signal<In, Bits<16>>,
    /// Input row.
    pub y: Signal<In, Bits<16>>,
    /// Input lanes (P).
    pub lanes: Vec<Signal<In, Bits<DW>>>,
    /// Output word present.
    pub out_valid: Signal<Out, Bit>,
    /// Output of a flush plane.
    pub out_flush: Signal<Out, Bit>,
    /// Output word column.
    pub out_x: Signal<Out, Bits<16>>,
    /// Output row.
    pub out_y: Signal<Out, Bits<16>>,
    /// Window lanes `P + 2·ctx`: lane `ctx + i` is pixel i of the word.
    pub win: Vec<Signal<Out, Bits<DW>>>,
    // Lane registers with a clock enable: they move only with a word.
    cur: EnableRegs<Bits<DW>>,
    prev: EnableRegs<Bits<DW>>,
    win_q: EnableRegs<Bits<DW>>,
    /// A word arrives while one is held: the window is emitted.
    emit: Signal<Local, Bit>,
    cur_valid: DFF<Bit>,
    cur_flush: DFF<Bit>,
    cur_x: DFF<Bits<16>>,
    cur_y: DFF<Bits<16>>,
    o_valid: DFF<Bit>,
    o_flush: DFF<Bit>,
    o_x: DFF<Bits<16>>,
    o_y: DFF<Bits<16>>,
    last_x: Constant<Bits<16>>,
    _p: usize,
    _ctx: usize,
}

impl<const DW: usize> WordWindow<DW> {
    /// A window over words of `p` lanes, `ctx ≤ p` lanes of context, rows of
    /// `words_per_row` words.
    pub fn new(p: usize, ctx: usize, words_per_row: usize) -> Self {
        assert!(ctx <= p);
        let n = p + 2 * ctx;
        WordWindow {
            clock: Default::default(),
            restart: Default::default(),
            valid: Default::default(),
            flush: Default::default(),
            x: Default::default(),
            y: Default::default(),
            lanes: lanes(p),
            out_valid: Default::default(),
            out_flush: Default::default(),
            out_x: Default::default(),
            out_y: Default::default(),
            win: lanes(n),
            cur: EnableRegs::new(p),
            prev: EnableRegs::new(ctx),
            win_q: EnableRegs::new(n),
            emit: Default::default(),
            cur_valid: Default::default(),
            cur_flush: Default::default(),
            cur_x: Default::default(),
            cur_y: Default::default(),
            o_valid: Default::default(),
            o_flush: Default::default(),
            o_x: Default::default(),
            o_y: Default::default(),
            last_x: Constant::new((words_per_row as u64 - 1).to_bits()),
            _p: p,
            _ctx: ctx,
        }
    }
}

impl<const DW: usize> Logic for WordWindow<DW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, cur_valid, cur_flush, cur_x, cur_y, o_flush, o_x, o_y);
        self.o_valid.clock.next = self.clock.val();
        self.o_valid.d.next = false;
        self.emit.next = self.valid.val() & self.cur_valid.q.val();
        clock!(self, clock, cur, prev, win_q);
        self.cur.enable.next = self.valid.val();
        self.prev.enable.next = self.valid.val();
        self.win_q.enable.next = self.emit.val();
        for i in 0..self._p {
            self.cur.d[i].next = 0.into();
        }
        for i in 0..self._ctx {
            self.prev.d[i].next = 0.into();
        }
        for i in 0..(self._p + 2 * self._ctx) {
            self.win_q.d[i].next = 0.into();
            self.win[i].next = self.win_q.q[i].val();
        }
        if self.valid.val() {
            self.cur_valid.d.next = true;
            self.cur_flush.d.next = self.flush.val();
            self.cur_x.d.next = self.x.val();
            self.cur_y.d.next = self.y.val();
            for i in 0..self._p {
                self.cur.d[i].next = self.lanes[i].val();
            }
            // Only the last ctx lanes of the previous word are context
            // (more would be registers that synthesis prunes and a simulator copies).
            for pp in self._p..(self._p + 1) {
                for cc in self._ctx..(self._ctx + 1) {
                    for i in 0..self._ctx {
                        self.prev.d[i].next = self.cur.q[i + pp - cc].val();
                    }
                }
            }
            if self.emit.val() {
                self.o_valid.d.next = true;
                self.o_flush.d.next = self.cur_flush.q.val();
                self.o_x.d.next = self.cur_x.q.val();
                self.o_y.d.next = self.cur_y.q.val();
                // One-value loops name generation-time constants (P, ctx)
                // for rust-hdl's index expressions.
                for pp in self._p..(self._p + 1) {
                    for cc in self._ctx..(self._ctx + 1) {
                        for i in 0..self._ctx {
                            self.win_q.d[i].next = 0.into();
                            if self.cur_x.q.val() != 0 {
                                self.win_q.d[i].next = self.prev.q[i].val();
                            }
                        }
                        for i in 0..self._p {
                            self.win_q.d[i + cc].next = self.cur.q[i].val();
                        }
                        for i in 0..self._ctx {
                            self.win_q.d[i + cc + pp].next = 0.into();
                            if self.cur_x.q.val() != self.last_x.val() {
                                self.win_q.d[i + cc + pp].next = self.lanes[i].val();
                            }
                        }
                    }
                }
            }
        }
        if self.restart.val() {
            self.cur_valid.d.next = false;
        }
        self.out_valid.next = self.o_valid.q.val();
        self.out_flush.next = self.o_flush.q.val();
        self.out_x.next = self.o_x.q.val();
        self.out_y.next = self.o_y.q.val();
    }
}

/// `n` default-constructed lanes (signals or registers).
pub fn lanes<T: Default>(n: usize) -> Vec<T> {
    (0..n).map(|_| T::default()).collect()
}

/// A group of pipeline registers that load their `d` only on clocks with
/// `enable` high and hold otherwise: flip-flops on one clock-enable net in
/// the fabric. In a Verilated model the whole group's copy is one branch an
/// idle clock skips, where a register held by `d = q` is copied twice every
/// clock; one enable for the group, because one per register would be a
/// variable and a branch each. The owner drives `d` only when it loads
/// (zero otherwise, which synthesis folds into the flip-flops' reset when
/// that choice is the outermost one of `d`, on the enable's own net; a
/// register written at the end of a chain of conditions, as the blink
/// tracker's slot words, would pay a multiplexer a bit and stays on a
/// `d = q` hold: `hdl/RESOURCES.md`).
#[derive(Clone, Debug, LogicBlock)]
pub struct EnableRegs<T: Synth> {
    /// Next values, taken when `enable` is high.
    pub d: Vec<Signal<In, T>>,
    /// Load every `d` at this clock's edge.
    pub enable: Signal<In, Bit>,
    /// The registers.
    pub q: Vec<Signal<Out, T>>,
    /// Clock.
    pub clock: Signal<In, Clock>,
}

impl<T: Synth> EnableRegs<T> {
    /// `n` registers on one enable.
    pub fn new(n: usize) -> Self {
        Self {
            d: lanes(n),
            enable: Signal::default(),
            q: lanes(n),
            clock: Signal::default(),
        }
    }
}

impl<T: Synth> Logic for EnableRegs<T> {
    fn update(&mut self) {
        if self.clock.pos_edge() && self.enable.val() {
            for (q, d) in self.q.iter_mut().zip(&self.d) {
                q.next = d.val();
            }
        }
    }
    fn connect(&mut self) {
        for q in &mut self.q {
            q.connect();
        }
    }
    fn hdl(&self) -> Verilog {
        let zero = T::default().verilog();
        let n = self.q.len();
        let init: String = (0..n).map(|i| format!("   q${i} = {zero:x};\n")).collect();
        let load: String = (0..n).map(|i| format!("      q${i} <= d${i};\n")).collect();
        Verilog::Custom(format!(
            "initial begin\n{init}end\n\nalways @(posedge clock) begin\n   if (enable) begin\n{load}   end\nend\n"
        ))
    }
    fn timing(&self) -> Vec<TimingInfo> {
        vec![TimingInfo {
            name: "enable_regs".into(),
            clock: "clock".into(),
            inputs: vec!["d".into(), "enable".into()],
            outputs: vec!["q".into()],
        }]
    }
}

/// One pipeline register of a word's tag: valid, flush, column, row.
#[derive(LogicBlock, Default)]
pub struct TagReg {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Clears `valid` (stream start).
    pub restart: Signal<In, Bit>,
    /// Word present.
    pub valid: Signal<In, Bit>,
    /// Flush plane.
    pub flush: Signal<In, Bit>,
    /// Word column.
    pub x: Signal<In, Bits<16>>,
    /// Row.
    pub y: Signal<In, Bits<16>>,
    /// `valid`, one clock later.
    pub out_valid: Signal<Out, Bit>,
    /// `flush`, one clock later.
    pub out_flush: Signal<Out, Bit>,
    /// `x`, one clock later.
    pub out_x: Signal<Out, Bits<16>>,
    /// `y`, one clock later.
    pub out_y: Signal<Out, Bits<16>>,
    /// The registered word is column 0 of row 0 (a plane's first word).
    pub out_origin: Signal<Out, Bit>,
    v: DFF<Bit>,
    f: DFF<Bit>,
    xr: DFF<Bits<16>>,
    yr: DFF<Bits<16>>,
    org: DFF<Bit>,
}

impl Logic for TagReg {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, v, f, xr, yr, org);
        self.v.d.next = self.valid.val() & !self.restart.val();
        self.f.d.next = self.flush.val();
        self.xr.d.next = self.x.val();
        self.yr.d.next = self.y.val();
        self.out_valid.next = self.v.q.val();
        self.out_flush.next = self.f.q.val();
        self.out_x.next = self.xr.q.val();
        self.org.d.next = (self.x.val() == 0) & (self.y.val() == 0);
        self.out_y.next = self.yr.q.val();
        self.out_origin.next = self.org.q.val();
    }
}

/// Zero-extends (or truncates) A bits to B bits: a wire, as a block because
/// rust-hdl cannot cast an indexed signal inside a loop.
#[derive(LogicBlock, Default)]
pub struct Widen<const A: usize, const B: usize> {
    /// Input.
    pub x: Signal<In, Bits<A>>,
    /// Output.
    pub y: Signal<Out, Bits<B>>,
}

impl<const A: usize, const B: usize> Logic for Widen<A, B> {
    #[hdl_gen]
    fn update(&mut self) {
        self.y.next = bit_cast::<B, A>(self.x.val());
    }
}

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
