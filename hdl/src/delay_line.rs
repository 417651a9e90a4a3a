//! Stage 1a — the N-plane delay line in block RAM (phase 1; the DDR2 version
//! for large N follows the same interface).
//!
//! The entry of the pipeline: takes the live bit-plane stream (P bits per
//! word, a [`PlaneWord`]), numbers its words, and returns beside each live
//! word `B_t` the word of the same pixels N planes ago, `B_{t−N}` (a
//! [`DelayedWordOut`]), read from the memory slot it overwrites
//! (read-first). N is a runtime register (1 ≤ N ≤ N_max), taken at
//! `restart`. Planes before the stream are zero as
//! in the model ([`smartagg_model::delay_line`]): a saturating plane count
//! forces the output to zero for `t < N`, so whatever the memory held before
//! (power-up garbage, an earlier stream) never leaks out.
//!
//! Memory: N_max slots of `W·H/P` words, slot `t mod N` for plane t. Planes
//! arrive whole (`W·H/P` words from `sop`, as the stream control frames
//! them), so the address runs on from word to word in a register.
//! Latency: one clock (the registered read).

use crate::bram::{Bram, RamStyle};
use crate::bundles::{DelayedWordOut, PlaneWord};
use crate::config::{GatewareConfig, GatewareError};
use crate::stream::RasterPosition;
use rust_hdl::prelude::*;

/// Block-RAM delay line of up to N_max planes of P-pixel words.
/// `P`: pixels per clock; `AW`: address bits of N_max planes; `NW`: bits of N.
#[derive(LogicBlock)]
pub struct DelayLine<const P: usize, const AW: usize, const NW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: forget all planes, take `n_window`.
    pub restart: Signal<In, Bit>,
    /// Window N (1..=N_max), used from the next `restart` on.
    pub n_window: Signal<In, Bits<NW>>,
    /// The word in: `B_t` and whether it starts a plane, belongs to the
    /// flush plane (neither stored nor read) or to a drain plane (its
    /// `B_{t−N}` is read; flush downstream).
    pub word: PlaneWord<P>,
    /// Bits carried along with the word (its masked pixels, for the ROI
    /// sums' MASKED flag).
    pub side: Signal<In, Bits<P>>,
    /// The word out, beside `B_{t−N}` (zero for t < N and for flush
    /// words), numbered, with `side`, one clock later.
    pub out: DelayedWordOut<P>,
    pos: RasterPosition,
    mem: Bram<P, AW>,
    n_reg: DFF<Bits<NW>>,
    planes: DFF<Bits<NW>>,
    zero: DFF<Bit>,
    /// The slot of the next stored plane, whether it is the ring's last
    /// (N − 1, after which the ring starts again at slot 0), and that
    /// plane's base address (slot · W·H/P): registers, decided a plane
    /// ahead, so a plane's start needs no compare or adder before them.
    next_slot: DFF<Bits<NW>>,
    next_slot_last: DFF<Bit>,
    next_base: DFF<Bits<AW>>,
    /// The memory address of the next word: this plane's next word, or
    /// after a plane's last word the next stored plane's base. A register
    /// straight into the memory: no plane-start test, multiplexer or adder
    /// in front of the address decode. (A flush plane runs through the
    /// addresses of the plane after it; it neither writes nor reads out.)
    addr: DFF<Bits<AW>>,
    /// N − 2 and N ≤ 1, latched with N (slot N − 1 comes after slot N − 2;
    /// with N ≤ 1 every plane takes slot 0).
    n_before_last: DFF<Bits<NW>>,
    n_le1: DFF<Bit>,
    next_base_now: Signal<Local, Bits<AW>>,
    zero_now: Signal<Local, Bit>,
    v1: DFF<Bit>,
    f1: DFF<Bit>,
    x1: DFF<Bits<16>>,
    y1: DFF<Bits<16>>,
    i1: DFF<Bits<32>>,
    live1: DFF<Bits<P>>,
    zero1: DFF<Bit>,
    drain1: DFF<Bit>,
    side1: DFF<Bits<P>>,
    words_per_plane: Constant<Bits<AW>>,
    last_idx: Constant<Bits<32>>,
}

impl<const P: usize, const AW: usize, const NW: usize> DelayLine<P, AW, NW> {
    /// The delay line of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        GatewareConfig::check_width("DelayLine", "P", P, cfg.pixels_per_clock)?;
        GatewareConfig::check_width("DelayLine", "AW", AW, cfg.delay_addr_bits())?;
        GatewareConfig::check_width("DelayLine", "NW", NW, cfg.count_bits())?;
        let wpp = cfg.words_per_plane();
        Ok(DelayLine {
            clock: Default::default(),
            restart: Default::default(),
            n_window: Default::default(),
            word: Default::default(),
            side: Default::default(),
            out: Default::default(),
            pos: RasterPosition::new(cfg.words_per_row(), cfg.height),
            mem: Bram::new(cfg.n_max as usize * wpp, RamStyle::Block),
            n_reg: Default::default(),
            planes: Default::default(),
            zero: Default::default(),
            next_slot: Default::default(),
            next_slot_last: Default::default(),
            next_base: Default::default(),
            addr: Default::default(),
            n_before_last: Default::default(),
            n_le1: Default::default(),
            next_base_now: Default::default(),
            zero_now: Default::default(),
            v1: Default::default(),
            f1: Default::default(),
            x1: Default::default(),
            y1: Default::default(),
            i1: Default::default(),
            live1: Default::default(),
            zero1: Default::default(),
            drain1: Default::default(),
            side1: Default::default(),
            words_per_plane: Constant::new((wpp as u64).to_bits()),
            last_idx: Constant::new((wpp as u64 - 1).to_bits()),
        })
    }
}

impl<const P: usize, const AW: usize, const NW: usize> Logic for DelayLine<P, AW, NW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self,
            clock,
            n_reg,
            planes,
            zero,
            next_slot,
            next_slot_last,
            next_base,
            addr,
            n_before_last,
            n_le1,
            v1,
            f1,
            x1,
            y1,
            i1,
            live1,
            zero1,
            drain1,
            side1
        );
        self.pos.clock.next = self.clock.val();
        self.pos.valid.next = self.word.valid.val();
        self.pos.sop.next = self.word.sop.val();
        self.mem.clock.next = self.clock.val();

        // At each stored plane's start, the ring moves a slot on.
        self.next_base_now.next = self.next_base.q.val();
        self.zero_now.next = self.zero.q.val();
        if self.word.valid.val() & self.word.sop.val() & !self.word.flush.val() {
            self.zero_now.next = self.planes.q.val() < self.n_reg.q.val();
            if self.planes.q.val() < self.n_reg.q.val() {
                self.planes.d.next = self.planes.q.val() + 1;
            }
            // This plane takes `next_slot`; the next one the slot after,
            // or slot 0 after slot N − 1.
            if self.next_slot_last.q.val() {
                self.next_slot.d.next = 0.into();
                self.next_slot_last.d.next = self.n_le1.q.val();
                self.next_base_now.next = 0.into();
            } else {
                self.next_slot.d.next = self.next_slot.q.val() + 1;
                self.next_slot_last.d.next = self.next_slot.q.val() == self.n_before_last.q.val();
                self.next_base_now.next = self.next_base.q.val() + self.words_per_plane.val();
            }
            self.next_base.d.next = self.next_base_now.val();
            self.zero.d.next = self.zero_now.val();
        }
        if self.word.valid.val() {
            if self.pos.idx.val() == self.last_idx.val() {
                self.addr.d.next = self.next_base_now.val();
            } else {
                self.addr.d.next = self.addr.q.val() + 1;
            }
        }

        // Read B_{t−N} from the word that B_t overwrites (read-first).
        self.mem.read_address.next = self.addr.q.val();
        self.mem.write_address.next = self.addr.q.val();
        self.mem.write_data.next = self.word.live.val();
        self.mem.write_enable.next = self.word.valid.val() & !self.word.flush.val();

        self.v1.d.next = self.word.valid.val();
        if self.word.valid.val() {
            self.f1.d.next = self.word.flush.val();
            self.x1.d.next = self.pos.x.val();
            self.y1.d.next = self.pos.y.val();
            self.i1.d.next = self.pos.idx.val();
            self.live1.d.next = self.word.live.val();
            self.zero1.d.next = self.zero_now.val() | self.word.flush.val();
            self.drain1.d.next = self.word.drain.val();
            self.side1.d.next = self.side.val();
        }
        if self.restart.val() {
            self.n_reg.d.next = self.n_window.val();
            self.n_before_last.d.next = self.n_window.val() - 2;
            self.n_le1.d.next = self.n_window.val() <= 1;
            self.planes.d.next = 0.into();
            self.next_slot.d.next = 0.into();
            self.next_slot_last.d.next = self.n_window.val() <= 1;
            self.next_base.d.next = 0.into();
            self.addr.d.next = 0.into();
            self.v1.d.next = false;
        }

        self.out.valid.next = self.v1.q.val();
        self.out.flush.next = self.f1.q.val() | self.drain1.q.val();
        self.out.drain.next = self.drain1.q.val();
        self.out.side.next = self.side1.q.val();
        self.out.x.next = self.x1.q.val();
        self.out.y.next = self.y1.q.val();
        self.out.idx.next = self.i1.q.val();
        self.out.live.next = self.live1.q.val();
        self.out.delayed.next = self.mem.read_data.val();
        if self.zero1.q.val() {
            self.out.delayed.next = 0.into();
        }
    }
}
