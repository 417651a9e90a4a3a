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
        assert!(
            depth >= 1 && depth as u128 <= 1u128 << AW,
            "depth {depth} does not fit {AW} address bits"
        );
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
            let ra = self.read_address.val().to_u64();
            // Addresses past the depth do not exist in hardware; read zero.
            self.read_data.next = if (ra as usize) < self._depth {
                self._sim.get(&ra).copied().unwrap_or_default()
            } else {
                Bits::default()
            };
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
