//! A simple dual-port memory of exact depth (one clock, read-first), the
//! storage of the delay line, the counter memory, the line buffers and the
//! blink tracker's walk-only slot fields.
//!
//! rust-hdl's own `RAM` always declares `2^AW` words; with plane sizes that
//! are not powers of two that wastes block RAM, so this block declares
//! exactly `depth` words. A write and a read of the same address in one clock
//! return the *old* word (read-first), which is what every user here relies
//! on: the delay line reads `B_{t−N}` from the word it overwrites with `B_t`.

use rust_hdl::prelude::*;
use std::collections::BTreeMap;

/// Panics unless `depth` words need no more than `aw` address bits.
fn check_depth(depth: usize, aw: usize) {
    assert!(
        depth >= 1 && depth as u128 <= 1u128 << aw,
        "depth {depth} does not fit {aw} address bits"
    );
}

/// The simulated word at `address`: zero if never written, and past the
/// depth (no such word in [`Bram`]; never written in [`LutRam`]).
fn sim_read<const DW: usize, const AW: usize>(
    sim: &BTreeMap<u64, Bits<DW>>,
    depth: usize,
    address: Bits<AW>,
) -> Bits<DW> {
    let a = address.to_u64();
    if (a as usize) < depth {
        sim.get(&a).copied().unwrap_or_default()
    } else {
        Bits::default()
    }
}

/// Where yosys should put the memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RamStyle {
    /// Block RAM (RAMB16/RAMB8).
    Block,
    /// Distributed (LUT) RAM, for shallow memories.
    Distributed,
}

/// `depth` words of `DW` bits, registered read (one clock of latency).
#[derive(LogicBlock)]
pub struct Bram<const DW: usize, const AW: usize> {
    /// The one clock.
    pub clock: Signal<In, Clock>,
    /// Read address, sampled on the rising edge.
    pub read_address: Signal<In, Bits<AW>>,
    /// The word at the address of the previous clock.
    pub read_data: Signal<Out, Bits<DW>>,
    /// Write address.
    pub write_address: Signal<In, Bits<AW>>,
    /// Word to write.
    pub write_data: Signal<In, Bits<DW>>,
    /// Write strobe.
    pub write_enable: Signal<In, Bit>,
    _depth: usize,
    _style: RamStyle,
    _sim: BTreeMap<u64, Bits<DW>>,
}

impl<const DW: usize, const AW: usize> Bram<DW, AW> {
    /// A memory of `depth ≤ 2^AW` words, initially zero in simulation (the
    /// design never relies on the initial contents).
    pub fn new(depth: usize, style: RamStyle) -> Self {
        check_depth(depth, AW);
        Bram {
            clock: Default::default(),
            read_address: Default::default(),
            read_data: Default::default(),
            write_address: Default::default(),
            write_data: Default::default(),
            write_enable: Default::default(),
            _depth: depth,
            _style: style,
            _sim: BTreeMap::new(),
        }
    }

    /// Number of words.
    pub fn depth(&self) -> usize {
        self._depth
    }
}

impl<const DW: usize, const AW: usize> Logic for Bram<DW, AW> {
    fn update(&mut self) {
        if self.clock.pos_edge() {
            self.read_data.next = sim_read(&self._sim, self._depth, self.read_address.val());
            if self.write_enable.val() {
                let wa = self.write_address.val().to_u64();
                if (wa as usize) < self._depth {
                    self._sim.insert(wa, self.write_data.val());
                }
            }
        }
    }

    fn connect(&mut self) {
        self.read_data.connect();
    }

    fn hdl(&self) -> Verilog {
        let style = match self._style {
            RamStyle::Block => "block",
            RamStyle::Distributed => "distributed",
        };
        Verilog::Custom(format!(
            "\
(* ram_style = \"{style}\" *)
reg [{msb}:0] words [0:{last}];

always @(posedge clock) begin
   read_data <= words[read_address];
   if (write_enable) begin
      words[write_address] <= write_data;
   end
end
",
            msb = DW - 1,
            last = self._depth - 1,
        ))
    }

    fn timing(&self) -> Vec<TimingInfo> {
        vec![TimingInfo {
            name: "bram".into(),
            clock: "clock".into(),
            inputs: vec![
                "read_address".into(),
                "write_address".into(),
                "write_data".into(),
                "write_enable".into(),
            ],
            outputs: vec!["read_data".into()],
        }]
    }
}

/// `depth` words of `DW` bits in LUT RAM with an *asynchronous* read: the
/// word at `read_address` now, the write taking effect at the clock edge
/// (so a read of the word being written in the same clock sees the old
/// word). For shallow per-row state that is written and read by the same
/// pipeline stage one row apart, which a registered read could not reach
/// in time on rows of one or two words.
#[derive(LogicBlock)]
pub struct LutRam<const DW: usize, const AW: usize> {
    /// The one clock.
    pub clock: Signal<In, Clock>,
    /// Read address.
    pub read_address: Signal<In, Bits<AW>>,
    /// The word at `read_address` (combinational).
    pub read_data: Signal<Out, Bits<DW>>,
    /// Write address.
    pub write_address: Signal<In, Bits<AW>>,
    /// Word to write.
    pub write_data: Signal<In, Bits<DW>>,
    /// Write strobe.
    pub write_enable: Signal<In, Bit>,
    _depth: usize,
    _sim: BTreeMap<u64, Bits<DW>>,
}

impl<const DW: usize, const AW: usize> LutRam<DW, AW> {
    /// A memory of `depth ≤ 2^AW` words, initially zero in simulation (the
    /// design never relies on the initial contents).
    pub fn new(depth: usize) -> Self {
        check_depth(depth, AW);
        LutRam {
            clock: Default::default(),
            read_address: Default::default(),
            read_data: Default::default(),
            write_address: Default::default(),
            write_data: Default::default(),
            write_enable: Default::default(),
            _depth: depth,
            _sim: BTreeMap::new(),
        }
    }
}

impl<const DW: usize, const AW: usize> Logic for LutRam<DW, AW> {
    fn update(&mut self) {
        if self.clock.pos_edge() && self.write_enable.val() {
            let wa = self.write_address.val().to_u64();
            if (wa as usize) < self._depth {
                self._sim.insert(wa, self.write_data.val());
            }
        }
        self.read_data.next = sim_read(&self._sim, self._depth, self.read_address.val());
    }

    fn connect(&mut self) {
        self.read_data.connect();
    }

    fn hdl(&self) -> Verilog {
        // 2^AW words, so that no read address is out of range (the design
        // reads only the first `depth`).
        Verilog::Custom(format!(
            "\
(* ram_style = \"distributed\" *)
reg [{msb}:0] words [0:{last}];

always @(posedge clock) begin
   if (write_enable) begin
      words[write_address] <= write_data;
   end
end

always @(*) read_data = words[read_address];
",
            msb = DW - 1,
            last = (1usize << AW) - 1,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testbench::bench::Bench;

    #[test]
    fn lut_ram_reads_now_and_writes_at_the_edge() {
        let mut b = Bench::new(LutRam::<4, 2>::new(3), |u| &mut u.clock);
        for (a, v) in [(0u64, 5u64), (1, 9), (2, 12)] {
            b.uut.write_address.next = a.to_bits();
            b.uut.write_data.next = v.to_bits();
            b.uut.write_enable.next = true;
            b.uut.read_address.next = a.to_bits();
            crate::testbench::bench::settle(&mut b.uut);
            // Before the edge: the old word (zero).
            assert_eq!(b.uut.read_data.val().to_u64(), 0);
            b.tick();
            assert_eq!(b.uut.read_data.val().to_u64(), v);
        }
        b.uut.write_enable.next = false;
        for (a, v) in [(2u64, 12u64), (0, 5), (1, 9), (3, 0)] {
            b.uut.read_address.next = a.to_bits();
            crate::testbench::bench::settle(&mut b.uut);
            assert_eq!(b.uut.read_data.val().to_u64(), v, "word {a}");
        }
    }
}
