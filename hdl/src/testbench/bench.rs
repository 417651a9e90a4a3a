//! The block tests' bench: a small clock-stepping harness over rust-hdl's
//! simulation engine (not the `sim/` co-simulation crate): settle the
//! combinational logic, sample, clock.

use rust_hdl::prelude::*;

/// Settles the circuit; panics (test failure) if it oscillates.
pub fn settle<B: Block>(uut: &mut B) {
    assert!(simulate(uut, 100_000), "the circuit did not settle");
}

/// A block under test and the clock input that drives it.
pub struct Bench<B: Block> {
    /// The block.
    pub uut: B,
    clock: fn(&mut B) -> &mut Signal<In, Clock>,
    /// Clock edges so far.
    pub cycles: u64,
}

impl<B: Block> Bench<B> {
    /// Connects the block, runs rust-hdl's design checks (every input
    /// driven, no combinational loop, no latch) and settles it.
    pub fn new(mut uut: B, clock: fn(&mut B) -> &mut Signal<In, Clock>) -> Self {
        uut.connect_all();
        check_all(&uut).expect("rust-hdl design checks");
        settle(&mut uut);
        Bench {
            uut,
            clock,
            cycles: 0,
        }
    }

    /// One rising and one falling edge; the inputs set before it are taken.
    /// They are settled first: without it a register could take an input
    /// before a change of it has gone through a sub-block.
    pub fn tick(&mut self) {
        settle(&mut self.uut);
        (self.clock)(&mut self.uut).next = Clock { clk: true };
        settle(&mut self.uut);
        (self.clock)(&mut self.uut).next = Clock { clk: false };
        settle(&mut self.uut);
        self.cycles += 1;
    }
}

/// A deterministic stall pattern: `true` when a word is offered this clock.
pub struct Stalls {
    state: u64,
    /// Percent of clocks without a word.
    pub stall_percent: u64,
}

impl Stalls {
    /// Seeded stalls; `stall_percent` of clocks carry no word.
    pub fn new(seed: u64, stall_percent: u64) -> Stalls {
        Stalls {
            state: seed | 1,
            stall_percent,
        }
    }

    /// Whether this clock carries a word.
    pub fn offer(&mut self) -> bool {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        self.state % 100 >= self.stall_percent
    }
}
