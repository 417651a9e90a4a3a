//! A first-word-fall-through FIFO over a registered-read [`Bram`]: the head
//! entry is always visible on `out_data` while `out_valid` is high, and one
//! entry can be pushed and one popped every clock.
//!
//! The memory holds up to `2^AW` entries; two output registers (the head and
//! a one-entry landing register) hide the memory's read latency. A fetch is
//! issued only when at most one entry is held or arriving, so the landing
//! register never overflows and a steady pop every clock is sustained.
//! A push while the memory is full is refused and sets the sticky
//! `overflow` flag (the owner reports it; nothing is lost silently).

use crate::bram::{Bram, RamStyle};
use crate::stream::EnableRegs;
use rust_hdl::prelude::*;

/// FWFT FIFO of `DW`-bit entries, `2^AW` in memory (plus up to two in the
/// output registers).
#[derive(LogicBlock)]
pub struct Fifo<const DW: usize, const AW: usize> {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// Empties the FIFO and clears `overflow`.
    pub restart: Signal<In, Bit>,
    /// Push `push_data` (ignored and flagged when `room` is low).
    pub push: Signal<In, Bit>,
    /// Entry to push.
    pub push_data: Signal<In, Bits<DW>>,
    /// Pop the head (ignored while `out_valid` is low).
    pub pop: Signal<In, Bit>,
    /// The head is valid.
    pub out_valid: Signal<Out, Bit>,
    /// The head entry.
    pub out_data: Signal<Out, Bits<DW>>,
    /// A push this clock is accepted.
    pub room: Signal<Out, Bit>,
    /// Entries held (memory, in flight and output registers).
    pub count: Signal<Out, Bits<16>>,
    /// A push was refused since the last restart (sticky).
    pub overflow: Signal<Out, Bit>,
    mem: Bram<DW, AW>,
    wr: DFF<Bits<16>>,
    rd: DFF<Bits<16>>,
    o_valid: DFF<Bit>,
    // The data registers take a clock enable: wide entries are copied only
    // on the clocks that move one.
    o_data: EnableRegs<Bits<DW>>,
    l_valid: DFF<Bit>,
    l_data: EnableRegs<Bits<DW>>,
    f_valid: DFF<Bit>,
    ovf: DFF<Bit>,
    /// `count` as a register: accepted pushes minus pops, the same number
    /// as the memory's, in-flight and output registers' entries, without
    /// the adders between those registers and the readers of `count`.
    held: DFF<Bits<16>>,
    /// The memory is full, as a register (its next value from the memory's
    /// count and this clock's write and fetch), so that `room` reaches the
    /// producer from a register.
    full: DFF<Bit>,
    mem_count: Signal<Local, Bits<16>>,
    wpush: Signal<Local, Bit>,
    consume: Signal<Local, Bit>,
    keep: Signal<Local, Bit>,
    issue: Signal<Local, Bit>,
    o_load: Signal<Local, Bit>,
    l_load: Signal<Local, Bit>,
    depth: Constant<Bits<16>>,
    depth_m1: Constant<Bits<16>>,
}

impl<const DW: usize, const AW: usize> Fifo<DW, AW> {
    /// A FIFO with its memory in block or distributed RAM.
    pub fn new(style: RamStyle) -> Self {
        assert!(
            AW <= 15,
            "FIFO depth 2^{AW} does not fit the 16-bit pointers"
        );
        Fifo {
            clock: Default::default(),
            restart: Default::default(),
            push: Default::default(),
            push_data: Default::default(),
            pop: Default::default(),
            out_valid: Default::default(),
            out_data: Default::default(),
            room: Default::default(),
            count: Default::default(),
            overflow: Default::default(),
            mem: Bram::new(1 << AW, style),
            wr: Default::default(),
            rd: Default::default(),
            o_valid: Default::default(),
            o_data: EnableRegs::new(1),
            l_valid: Default::default(),
            l_data: EnableRegs::new(1),
            f_valid: Default::default(),
            ovf: Default::default(),
            held: Default::default(),
            full: Default::default(),
            mem_count: Default::default(),
            wpush: Default::default(),
            consume: Default::default(),
            keep: Default::default(),
            issue: Default::default(),
            o_load: Default::default(),
            l_load: Default::default(),
            depth: Constant::new((1u64 << AW).to_bits()),
            depth_m1: Constant::new(((1u64 << AW) - 1).to_bits()),
        }
    }
}

impl<const DW: usize, const AW: usize> Logic for Fifo<DW, AW> {
    #[hdl_gen]
    fn update(&mut self) {
        dff_setup!(self, clock, wr, rd, o_valid, l_valid, f_valid, ovf, held, full);
        clock!(self, clock, o_data, l_data);
        self.mem.clock.next = self.clock.val();
        self.mem_count.next = self.wr.q.val() - self.rd.q.val();
        self.consume.next = self.o_valid.q.val() & self.pop.val();
        self.keep.next = self.o_valid.q.val() & !self.consume.val();
        // Fetch only when at most one entry will be held after this clock.
        self.issue.next = (self.mem_count.val() != 0)
            & !((self.keep.val() & self.l_valid.q.val())
                | (self.keep.val() & self.f_valid.q.val())
                | (self.l_valid.q.val() & self.f_valid.q.val()));

        // Write side.
        self.mem.write_address.next = bit_cast::<AW, 16>(self.wr.q.val());
        self.mem.write_data.next = self.push_data.val();
        self.wpush.next = self.push.val() & !self.full.q.val();
        self.mem.write_enable.next = self.wpush.val();
        if self.wpush.val() {
            self.wr.d.next = self.wr.q.val() + 1;
            if !self.consume.val() {
                self.held.d.next = self.held.q.val() + 1;
            }
        } else if self.consume.val() {
            self.held.d.next = self.held.q.val() - 1;
        }
        if self.push.val() & self.full.q.val() {
            self.ovf.d.next = true;
        }

        // Fetch: the entry at `rd` arrives next clock.
        self.mem.read_address.next = bit_cast::<AW, 16>(self.rd.q.val());
        self.f_valid.d.next = self.issue.val();
        // Full next clock: the memory's count + write − fetch = 2^AW.
        self.full.d.next = ((self.mem_count.val() == self.depth.val()) & !self.issue.val())
            | ((self.mem_count.val() == self.depth_m1.val())
                & self.wpush.val()
                & !self.issue.val());
        if self.issue.val() {
            self.rd.d.next = self.rd.q.val() + 1;
        }

        // Landing: head first, then the landing register.
        if !self.keep.val() {
            self.o_valid.d.next = self.l_valid.q.val() | self.f_valid.q.val();
            if self.l_valid.q.val() {
                self.l_valid.d.next = self.f_valid.q.val();
            }
        } else if self.f_valid.q.val() {
            self.l_valid.d.next = true;
        }
        // The head takes the landing register's entry, else the arriving
        // one; the landing register takes an arriving entry the head cannot.
        self.o_load.next = !self.keep.val() & (self.l_valid.q.val() | self.f_valid.q.val());
        self.l_load.next = self.f_valid.q.val() & (self.keep.val() | self.l_valid.q.val());
        self.o_data.enable.next = self.o_load.val();
        self.o_data.d[0].next = 0.into();
        if self.o_load.val() {
            self.o_data.d[0].next = self.mem.read_data.val();
            if self.l_valid.q.val() {
                self.o_data.d[0].next = self.l_data.q[0].val();
            }
        }
        self.l_data.enable.next = self.l_load.val();
        self.l_data.d[0].next = 0.into();
        if self.l_load.val() {
            self.l_data.d[0].next = self.mem.read_data.val();
        }

        if self.restart.val() {
            self.wr.d.next = 0.into();
            self.rd.d.next = 0.into();
            self.o_valid.d.next = false;
            self.l_valid.d.next = false;
            self.f_valid.d.next = false;
            self.ovf.d.next = false;
            self.held.d.next = 0.into();
            self.full.d.next = false;
        }

        self.out_valid.next = self.o_valid.q.val();
        self.out_data.next = self.o_data.q[0].val();
        self.room.next = !self.full.q.val();
        self.count.next = self.held.q.val();
        self.overflow.next = self.ovf.q.val();
    }
}
