//! The XEM6310 core as an interactive device, one host operation at a
//! time: what the host's `cosim:` transport talks to.

use super::words::block_words;
use super::xem_host::XemHost;
use super::{strip_padding, Case, Cosim, HarnessError};
use crate::designs::{DesignError, DesignSpec};
use crate::verilator::Model;
use smartagg_hdl::registers::{status, wire_out};
use smartagg_model::plane::BitPlane;
use smartagg_model::registers::replay_words;
use std::collections::VecDeque;

/// The XEM6310 core as a device: its FrontPanel endpoints driven one host
/// operation at a time, for the host's `cosim:` transport. Clocks run only
/// inside these calls.
pub struct Device {
    host: XemHost,
    /// Pipe words of planes still to replay.
    replay: VecDeque<u32>,
    /// Bytes read and not yet handed out.
    taken: usize,
}

impl Device {
    /// Verilates (or loads) a shipped configuration's XEM6310 core and
    /// powers it up.
    pub fn open(spec: DesignSpec) -> Result<Device, HarnessError> {
        if !spec.xem() {
            return Err(HarnessError::Design(DesignError::Unsupported {
                what: format!("{} as a device", spec.config.name()),
                why: "the demo's design is a pipeline without the XEM6310 core".into(),
            }));
        }
        let cosim = Cosim::new(spec)?;
        let model = Model::new(cosim.fast.clone()).map_err(DesignError::from)?;
        let case = Case::replay(1, 1, 1, 1, Vec::new());
        let mut host = XemHost::new(model, &cosim, &case, None, None)?;
        host.limit = u64::MAX;
        Ok(Device {
            host,
            replay: VecDeque::new(),
            taken: 0,
        })
    }

    /// Reads a wire-out.
    pub fn wire_out(&mut self, addr: u8) -> u32 {
        self.host.wire_out(addr)
    }

    /// Sets a wire-in (takes effect at the next clock).
    pub fn set_wire_in(&mut self, addr: u8, value: u32) -> Result<(), HarnessError> {
        let i = *self
            .host
            .p
            .wire_in
            .get(addr as usize)
            .ok_or_else(|| HarnessError::Gateware(format!("no wire-in {addr:#04x}")))?;
        self.host.sh.set(&mut self.host.m, i, value as u64);
        Ok(())
    }

    /// Pulses a trigger bit for one clock.
    pub fn trigger(&mut self, bit: u8) {
        self.host.trigger(bit);
    }

    /// Writes the mask pipe-in (whole 16-byte blocks; the end is zero-padded).
    pub fn write_mask(&mut self, bytes: &[u8]) -> Result<(), HarnessError> {
        self.host.write_pipe(true, &block_words(bytes), 0)
    }

    /// Queues bit-planes for the replay pipe-in (sent while [`Device::run`] runs).
    pub fn queue_planes(&mut self, planes: &[BitPlane]) {
        self.replay.extend(replay_words(planes));
    }

    /// Replay words not yet sent.
    pub fn queued_words(&self) -> usize {
        self.replay.len()
    }

    /// Runs up to `clocks` clocks: replays queued words when the pipe-in
    /// takes a block, reads pipe-out blocks when offered. Returns the new
    /// packet bytes (the pipe-out's end padding is withheld once the stream
    /// has ended and FIFO_BYTES says nothing is left).
    pub fn run(&mut self, clocks: u64) -> Result<Vec<u8>, HarnessError> {
        let end = self.host.m.cycles + clocks;
        while self.host.m.cycles < end {
            if self.replay.len() >= 4 && self.host.m.get(self.host.p.replay_ready) != 0 {
                let block: Vec<u32> = self.replay.drain(..4).collect();
                self.host.write_pipe(false, &block, 0)?;
            }
            self.host.read_blocks(true);
            self.host.clock();
            if self.wire_out(wire_out::STATUS) & status::FAULT != 0 {
                return Err(HarnessError::Gateware(self.host.fault_source()));
            }
        }
        let ended = self.ended();
        let upto = if ended {
            strip_padding(&self.host.read).len()
        } else {
            // Hold back a block: it may be padding.
            self.host.read.len().saturating_sub(16)
        };
        let out = self.host.read[self.taken.min(upto)..upto].to_vec();
        self.taken = self.taken.max(upto);
        Ok(out)
    }

    /// The stream has ended and every byte has been read.
    pub fn ended(&mut self) -> bool {
        self.wire_out(wire_out::STATUS) & status::ENDED != 0
            && self.wire_out(wire_out::FIFO_BYTES) == 0
            && self.host.pending == 0
    }

    /// Clocks run.
    pub fn cycles(&self) -> u64 {
        self.host.m.cycles
    }
}
