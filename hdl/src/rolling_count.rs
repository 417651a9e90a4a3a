//! Stage 1 — rolling count `S_t = S_{t−1} + B_t − B_{t−N}` per pixel, as in
//! [`smartagg_model::rolling_count`].
//!
//! The counter memory holds W·H counters of CW bits in block RAM, one memory
//! per lane (P counters per word), read-modify-write: the word is read when
//! the pixel word arrives and written back one clock later. Each word is
//! touched once per plane, so the next read of an address is a whole plane
//! later and there is no read-after-write hazard. The first plane after
//! `restart` reads its old counts as zero (the memory is not cleared), which
//! equals the model's all-zero start. Flush words pass with zero counts and
//! touch no counter. Latency: two clocks.

use crate::bram::{Bram, RamStyle};
use crate::config::{GatewareConfig, GatewareError};
use crate::stream::lanes;
use rust_hdl::prelude::*;

/// Rolling counts of P pixels per clock. `CW`: count bits; `AW`: counter
/// memory address bits.
#[derive(LogicBlock)]
pub struct RollingCount<const P: usize, const CW: usize, const AW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Stream start: the next plane is plane 0.
    pub restart: Signal<In, Bit>,
    /// Input word present.
    pub valid: Signal<In, Bit>,
    /// Word of a flush plane.
    pub flush: Signal<In, Bit>,
    /// Word column.
    pub x: Signal<In, Bits<16>>,
    /// Row.
    pub y: Signal<In, Bits<16>>,
    /// Word index within the plane (counter address).
    pub idx: Signal<In, Bits<32>>,
    /// `B_t`.
    pub live: Signal<In, Bits<P>>,
    /// `B_{t−N}`.
    pub delayed: Signal<In, Bits<P>>,
    /// Output word present.
    pub out_valid: Signal<Out, Bit>,
    /// Output of a flush plane.
    pub out_flush: Signal<Out, Bit>,
    /// Word column.
    pub out_x: Signal<Out, Bits<16>>,
    /// Row.
    pub out_y: Signal<Out, Bits<16>>,
    /// `S_t` of the word's P pixels.
    pub counts: Vec<Signal<Out, Bits<CW>>>,
    mem: Vec<Bram<CW, AW>>,
    seen: DFF<Bit>,
    first: DFF<Bit>,
    first_now: Signal<Local, Bit>,
    v1: DFF<Bit>,
    f1: DFF<Bit>,
    x1: DFF<Bits<16>>,
    y1: DFF<Bits<16>>,
    a1: DFF<Bits<AW>>,
    live1: DFF<Bits<P>>,
    del1: DFF<Bits<P>>,
    first1: DFF<Bit>,
    old: Vec<Signal<Local, Bits<CW>>>,
    new: Vec<Signal<Local, Bits<CW>>>,
    /// +1, 0 or −1 (all ones): one adder per lane instead of an
    /// incrementer, a decrementer and their multiplexer.
    step: Vec<Signal<Local, Bits<CW>>>,
    minus_one: Constant<Bits<CW>>,
    v2: DFF<Bit>,
    f2: DFF<Bit>,
    x2: DFF<Bits<16>>,
    y2: DFF<Bits<16>>,
    s2: Vec<DFF<Bits<CW>>>,
}

impl<const P: usize, const CW: usize, const AW: usize> RollingCount<P, CW, AW> {
    /// The rolling count of a configuration; errors if the type's widths differ.
    pub fn new(cfg: &GatewareConfig) -> Result<Self, GatewareError> {
        cfg.validate()?;
        GatewareConfig::check_width("RollingCount", "P", P, cfg.pixels_per_clock)?;
        GatewareConfig::check_width("RollingCount", "CW", CW, cfg.count_bits())?;
        GatewareConfig::check_width("RollingCount", "AW", AW, cfg.count_addr_bits())?;
        let wpp = cfg.words_per_plane();
        Ok(RollingCount {
            clock: Default::default(),
            restart: Default::default(),
            valid: Default::default(),
            flush: Default::default(),
            x: Default::default(),
            y: Default::default(),
            idx: Default::default(),
            live: Default::default(),
            delayed: Default::default(),
            out_valid: Default::default(),
            out_flush: Default::default(),
            out_x: Default::default(),
            out_y: Default::default(),
            counts: lanes(P),
            mem: (0..P).map(|_| Bram::new(wpp, RamStyle::Block)).collect(),
            seen: Default::default(),
            first: Default::default(),
            first_now: Default::default(),
            v1: Default::default(),
            f1: Default::default(),
            x1: Default::default(),
            y1: Default::default(),
            a1: Default::default(),
            live1: Default::default(),
            del1: Default::default(),
            first1: Default::default(),
            old: lanes(P),
            new: lanes(P),
            step: lanes(P),
            minus_one: Constant::new(Bits::<CW>::mask()),
            v2: Default::default(),
            f2: Default::default(),
            x2: Default::default(),
            y2: Default::default(),
            s2: lanes(P),
        })
    }
}

impl<const P: usize, const CW: usize, const AW: usize> Logic for RollingCount<P, CW, AW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(
            self, clock, seen, first, v1, f1, x1, y1, a1, live1, del1, first1, v2, f2, x2, y2
        );
        // Plane 0 after restart reads its old counts as zero.
        self.first_now.next = self.first.q.val();
        if self.valid.val() & !self.flush.val() & (self.x.val() == 0) & (self.y.val() == 0) {
            self.first_now.next = !self.seen.q.val();
            self.first.d.next = !self.seen.q.val();
            self.seen.d.next = true;
        }
        // Clock 0: read the counters of the word.
        self.v1.d.next = self.valid.val();
        if self.valid.val() {
            self.f1.d.next = self.flush.val();
            self.x1.d.next = self.x.val();
            self.y1.d.next = self.y.val();
            self.a1.d.next = bit_cast::<AW, 32>(self.idx.val());
            self.live1.d.next = self.live.val();
            self.del1.d.next = self.delayed.val();
            self.first1.d.next = self.first_now.val();
        }
        // Clock 1: S += b_new − b_old, write back, register the output.
        self.v2.d.next = self.v1.q.val();
        self.f2.d.next = self.f1.q.val();
        self.x2.d.next = self.x1.q.val();
        self.y2.d.next = self.y1.q.val();
        for i in 0..P {
            self.mem[i].clock.next = self.clock.val();
            self.mem[i].read_address.next = bit_cast::<AW, 32>(self.idx.val());
            self.old[i].next = self.mem[i].read_data.val();
            if self.first1.q.val() {
                self.old[i].next = 0.into();
            }
            self.step[i].next = 0.into();
            if self.live1.q.val().get_bit(i) & !self.del1.q.val().get_bit(i) {
                self.step[i].next = 1.into();
            }
            if !self.live1.q.val().get_bit(i) & self.del1.q.val().get_bit(i) {
                self.step[i].next = self.minus_one.val();
            }
            self.new[i].next = self.old[i].val() + self.step[i].val();
            self.mem[i].write_address.next = self.a1.q.val();
            self.mem[i].write_data.next = self.new[i].val();
            self.mem[i].write_enable.next = self.v1.q.val() & !self.f1.q.val();
            self.s2[i].clock.next = self.clock.val();
            self.s2[i].d.next = self.new[i].val();
            if self.f1.q.val() {
                self.s2[i].d.next = 0.into();
            }
            self.counts[i].next = self.s2[i].q.val();
        }
        if self.restart.val() {
            self.seen.d.next = false;
            self.v1.d.next = false;
            self.v2.d.next = false;
        }
        self.out_valid.next = self.v2.q.val();
        self.out_flush.next = self.f2.q.val();
        self.out_x.next = self.x2.q.val();
        self.out_y.next = self.y2.q.val();
    }
}
