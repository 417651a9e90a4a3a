//! A behavioural model of one MCB user port, for simulation only: the
//! DDR2 behind [`crate::delay_line_ddr::DelayLineDdr`] in the block and
//! XEM6310 tests (the hardware is the MIG core; its Verilog is empty). Kept
//! apart from the gateware sources.

use crate::bundles::{McbMemory, McbPort};
use rust_hdl::prelude::*;
use std::collections::{HashMap, VecDeque};

/// Behavioural model of one bidirectional MCB user port (32 bits), for
/// simulation only: a 4-entry command FIFO executed in order, 64-word write
/// and read data FIFOs, a command's first word no sooner than `latency`
/// clocks after it was issued (latencies of queued commands overlap), one
/// word per clock, a refresh gap of `refresh_gap` clocks every
/// `refresh_every` clocks, calibration done after `calib` clocks, and a
/// pseudo-random word at every address never written (DDR2 after power-up).
#[derive(LogicBlock)]
pub struct McbModel {
    /// Clock.
    pub clock: Signal<In, Clock>,
    /// The user port.
    pub mcb: McbMemory,
    /// Protocol errors seen (a FIFO overflowed, a write found too little
    /// data, a read of an empty FIFO, a command other than read or write)
    /// (sticky).
    pub error: Signal<Out, Bit>,
    _s: McbState,
}

/// The model's state (plain Rust, no hardware).
#[derive(Debug, Clone, Default)]
struct McbState {
    latency: u64,
    refresh_every: u64,
    refresh_gap: u64,
    calib: u64,
    seed: u64,
    cycle: u64,
    mem: HashMap<u32, u32>,
    /// (is_write, word address, words, cycle issued)
    cmd: VecDeque<(bool, u32, u32, u64)>,
    wdata: VecDeque<u32>,
    rdata: VecDeque<u32>,
    /// (is_write, next word address, words left)
    op: Option<(bool, u32, u32)>,
    refresh_left: u64,
    next_refresh: u64,
    error: bool,
}

impl McbModel {
    /// A model with the given command latency, refresh interval and gap,
    /// calibration time (clocks) and garbage seed.
    pub fn new(latency: u64, refresh_every: u64, refresh_gap: u64, calib: u64, seed: u64) -> Self {
        McbModel {
            clock: Default::default(),
            mcb: Default::default(),
            error: Default::default(),
            _s: McbState {
                latency,
                refresh_every,
                refresh_gap,
                calib,
                seed: seed | 1,
                next_refresh: refresh_every,
                ..Default::default()
            },
        }
    }

    /// Distinct words written so far.
    pub fn words_written(&self) -> usize {
        self._s.mem.len()
    }
}

impl McbState {
    fn garbage(&self, addr: u32) -> u32 {
        let mut x = self.seed ^ (addr as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        x ^= x >> 29;
        x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        (x ^ (x >> 32)) as u32
    }
}

impl Logic for McbModel {
    fn update(&mut self) {
        if !self.clock.pos_edge() {
            return;
        }
        let s = &mut self._s;
        s.cycle += 1;
        // The user side of this clock.
        if self.mcb.cmd_en.val() {
            let instr = self.mcb.cmd_instr.val().to_u64();
            if s.cmd.len() < 4 && instr <= 1 {
                s.cmd.push_back((
                    instr == 0,
                    self.mcb.cmd_addr.val().to_u64() as u32 >> 2,
                    self.mcb.cmd_bl.val().to_u64() as u32 + 1,
                    s.cycle,
                ));
            } else {
                s.error = true;
            }
        }
        if self.mcb.wr_en.val() {
            if s.wdata.len() < 64 && self.mcb.wr_mask.val().to_u64() == 0 {
                s.wdata.push_back(self.mcb.wr_data.val().to_u64() as u32);
            } else {
                s.error = true;
            }
        }
        if self.mcb.rd_en.val() && s.rdata.pop_front().is_none() {
            s.error = true;
        }
        // The controller side, one command at a time in order.
        if s.refresh_left > 0 {
            s.refresh_left -= 1;
        } else if let Some((is_write, addr, left)) = s.op {
            if is_write {
                match s.wdata.pop_front() {
                    Some(d) => {
                        s.mem.insert(addr, d);
                        s.op = (left > 1).then_some((true, addr + 1, left - 1));
                    }
                    None => s.error = true,
                }
            } else if s.rdata.len() < 64 {
                let d = s.mem.get(&addr).copied().unwrap_or_else(|| s.garbage(addr));
                s.rdata.push_back(d);
                s.op = (left > 1).then_some((false, addr + 1, left - 1));
            } else {
                s.error = true;
            }
        } else if s.cycle >= s.next_refresh {
            s.refresh_left = s.refresh_gap;
            s.next_refresh = s.cycle + s.refresh_every;
        } else if s.cycle >= s.calib {
            if let Some(&(w, a, n, at)) = s.cmd.front() {
                if s.cycle >= at + s.latency {
                    s.cmd.pop_front();
                    s.op = Some((w, a, n));
                }
            }
        }
        self.mcb.calib_done.next = s.cycle >= s.calib;
        self.mcb.cmd_full.next = s.cmd.len() >= 4;
        self.mcb.wr_full.next = s.wdata.len() >= 64;
        self.mcb.rd_empty.next = s.rdata.is_empty();
        self.mcb.rd_data.next = (s.rdata.front().copied().unwrap_or(0) as u64).to_bits();
        self.error.next = s.error;
    }

    fn connect(&mut self) {
        self.mcb.calib_done.connect();
        self.mcb.cmd_full.connect();
        self.mcb.wr_full.connect();
        self.mcb.rd_data.connect();
        self.mcb.rd_empty.connect();
        self.error.connect();
    }

    fn hdl(&self) -> Verilog {
        // Simulation only: the hardware is the MIG core (see `xem6310`).
        Verilog::Empty
    }
}

/// Hands the memory's flags and read data to the port, for one settle of a
/// test bench (plain Rust; a design connects the two in its own process).
pub fn mcb_to_port(memory: &McbMemory, port: &mut McbPort) {
    port.calib_done.next = memory.calib_done.val();
    port.cmd_full.next = memory.cmd_full.val();
    port.wr_full.next = memory.wr_full.val();
    port.rd_data.next = memory.rd_data.val();
    port.rd_empty.next = memory.rd_empty.val();
}

/// The port's commands, write data and read enable into the memory (the
/// other half of [`mcb_to_port`]).
pub fn port_to_mcb(port: &McbPort, memory: &mut McbMemory) {
    memory.cmd_en.next = port.cmd_en.val();
    memory.cmd_instr.next = port.cmd_instr.val();
    memory.cmd_bl.next = port.cmd_bl.val();
    memory.cmd_addr.next = port.cmd_addr.val();
    memory.wr_en.next = port.wr_en.val();
    memory.wr_mask.next = port.wr_mask.val();
    memory.wr_data.next = port.wr_data.val();
    memory.rd_en.next = port.rd_en.val();
}
