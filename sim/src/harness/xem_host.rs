//! The FrontPanel host: drives the XEM6310 core as the host does (RESET,
//! the mask through pipe-in 0x81, wire-ins, START, the planes through the
//! replay pipe-in or the sensor port, STOP, the stream read out in 16-byte
//! blocks), with random host stalls on both pipes.

use super::probes::{vcd_of, Probes, Shadow, Vcd};
use super::words::block_words;
use super::{strip_padding, Case, Cosim, HarnessError, Outcome, Source};
use crate::verilator::Model;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_hdl::registers::{control, status, trigger, wire_in, wire_out};
use smartagg_model::registers::replay_words;
use std::collections::VecDeque;
use std::path::Path;

/// Drives the XEM6310 core as the host does through FrontPanel.
pub(super) struct XemHost {
    pub(super) m: Model,
    pub(super) sh: Shadow,
    rng: ChaCha8Rng,
    pub(super) p: XemPorts,
    pub(super) read: Vec<u8>,
    pub(super) pending: usize,
    issued: bool,
    probes: Option<Probes>,
    vcd: Option<Vcd>,
    sensor: VecDeque<u64>,
    sensor_interval: u32,
    read_stall: u32,
    hold_reads: bool,
    pub(super) limit: u64,
    /// Set bits of the words written to the mask pipe-in.
    mask_loaded: u32,
}

pub(super) struct XemPorts {
    pub(super) wire_in: Vec<usize>,
    trigger: usize,
    replay_write: usize,
    replay_data: usize,
    pub(super) replay_ready: usize,
    mask_write: usize,
    mask_data: usize,
    mask_ready: usize,
    out_read: usize,
    out_data: usize,
    out_ready: usize,
    sensor_empty: usize,
    sensor_word: usize,
    sensor_read: usize,
    wire_out: Vec<usize>,
    /// The DDR2 model's ports (DDR2 designs): error, refresh collisions,
    /// refreshes.
    ddr: Option<[usize; 3]>,
}

impl XemHost {
    pub(super) fn new(
        m: Model,
        cosim: &Cosim,
        case: &Case,
        probes: Option<Probes>,
        vcd: Option<(&Path, u64, u64)>,
    ) -> Result<XemHost, HarnessError> {
        let b = m.build().clone();
        let port = |n: &str| b.port(n).map_err(|e| HarnessError::Design(e.into()));
        let p = XemPorts {
            wire_in: (0..wire_in::COUNT)
                .map(|i| port(&format!("wire_in_{i}")))
                .collect::<Result<_, _>>()?,
            trigger: port("trigger")?,
            replay_write: port("replay_write")?,
            replay_data: port("replay_data")?,
            replay_ready: port("replay_ready")?,
            mask_write: port("mask_write")?,
            mask_data: port("mask_data")?,
            mask_ready: port("mask_ready")?,
            out_read: port("out_read")?,
            out_data: port("out_data")?,
            out_ready: port("out_ready")?,
            sensor_empty: port("sensor_empty")?,
            sensor_word: port("sensor_word")?,
            sensor_read: port("sensor_read")?,
            wire_out: (0..8)
                .map(|i| port(&format!("wire_out_{i}")))
                .collect::<Result<_, _>>()?,
            ddr: if cosim.spec.ddr() {
                Some([
                    port("ddr_error")?,
                    port("ddr_refresh_collisions")?,
                    port("ddr_refreshes")?,
                ])
            } else {
                None
            },
        };
        let n = b.ports.len();
        let wpp = cosim.spec.width * cosim.spec.height / crate::designs::P;
        let mut h = XemHost {
            m,
            sh: Shadow {
                vals: vec![None; n],
            },
            rng: ChaCha8Rng::seed_from_u64(case.seed),
            p,
            read: Vec::new(),
            pending: 0,
            issued: false,
            probes,
            vcd: vcd_of(vcd),
            sensor: VecDeque::new(),
            sensor_interval: cosim.sensor_interval,
            read_stall: case.read_stall,
            hold_reads: case.hold_reads,
            limit: 100_000 + (case.planes.len() as u64 + case.n as u64 + 4) * wpp as u64 * 12,
            mask_loaded: 0,
        };
        let se = h.p.sensor_empty;
        h.sh.set(&mut h.m, se, 1);
        Ok(h)
    }

    pub(super) fn clock(&mut self) {
        let m = &mut self.m;
        if self.issued {
            let w = m.get(self.p.out_data) as u32;
            self.read.extend_from_slice(&w.to_le_bytes());
            self.pending -= 1;
        }
        // Sensor FIFO head (sop in bit P).
        if let Some(&w) = self.sensor.front() {
            self.sh.set(m, self.p.sensor_empty, 0);
            self.sh.set(m, self.p.sensor_word, w);
            if m.get(self.p.sensor_read) != 0 {
                self.sensor.pop_front();
            }
        } else {
            self.sh.set(m, self.p.sensor_empty, 1);
        }
        if let Some(pr) = &mut self.probes {
            pr.sample(m);
        }
        if let Some(v) = &mut self.vcd {
            v.step(m);
        }
        self.issued = self.sh.vals[self.p.out_read] == Some(1);
        m.tick(1);
        for i in [
            self.p.trigger,
            self.p.replay_write,
            self.p.mask_write,
            self.p.out_read,
        ] {
            self.sh.set(m, i, 0);
        }
    }

    pub(super) fn wire_out(&mut self, addr: u8) -> u32 {
        let i = self.p.wire_out[(addr - wire_out::STATUS) as usize];
        self.m.get(i) as u32
    }

    pub(super) fn trigger(&mut self, bit: u8) {
        let t = self.p.trigger;
        self.sh.set(&mut self.m, t, 1 << bit);
        self.clock();
    }

    /// Reads one 16-byte block if the pipe-out offers one and the host is not stalled.
    pub(super) fn read_blocks(&mut self, ended: bool) {
        if self.hold_reads && !ended {
            return;
        }
        if self.pending == 0 && self.m.get(self.p.out_ready) != 0 {
            if !ended && self.read_stall > 0 && self.rng.gen_range(0..100) < self.read_stall {
                return;
            }
            for _ in 0..4 {
                let r = self.p.out_read;
                self.sh.set(&mut self.m, r, 1);
                self.pending += 1;
                self.clock();
            }
            self.clock();
        }
    }

    pub(super) fn write_pipe(
        &mut self,
        mask: bool,
        words: &[u32],
        stall: u32,
    ) -> Result<(), HarnessError> {
        let (ready, write, data) = if mask {
            (self.p.mask_ready, self.p.mask_write, self.p.mask_data)
        } else {
            (self.p.replay_ready, self.p.replay_write, self.p.replay_data)
        };
        for block in words.chunks(4) {
            let start = self.m.cycles;
            while self.m.get(ready) == 0 || (stall > 0 && self.rng.gen_range(0..100) < stall) {
                self.read_blocks(false);
                self.clock();
                if self.m.cycles - start > self.limit {
                    return Err(HarnessError::Gateware("pipe-in never ready".into()));
                }
            }
            for k in 0..4 {
                let w = block.get(k).copied().unwrap_or(0);
                if mask {
                    self.mask_loaded += w.count_ones();
                }
                self.sh.set(&mut self.m, write, 1);
                self.sh.set(&mut self.m, data, w as u64);
                self.clock();
            }
        }
        Ok(())
    }

    /// Runs a case: RESET, the mask (if the host sends one) through pipe-in
    /// 0x81, the wire-ins, START, the planes, STOP, the stream read out.
    pub(super) fn run(
        mut self,
        case: &Case,
        wire_ins: &[(u8, u32)],
        mask: Option<Vec<u8>>,
    ) -> Result<Outcome, HarnessError> {
        self.trigger(trigger::RESET);
        if let Some(bytes) = mask {
            self.write_pipe(true, &block_words(&bytes), 0)?;
        }
        let t0 = self.m.cycles;
        while self.wire_out(wire_out::STATUS) & status::MEM_READY == 0 {
            self.clock();
            if self.m.cycles - t0 > 1_000_000 {
                return Err(HarnessError::Gateware("DDR2 never calibrated".into()));
            }
        }
        let mut mask_enable = false;
        for &(a, v) in wire_ins {
            if a == wire_in::CONTROL {
                mask_enable = v & control::MASK_ENABLE != 0;
            }
            let i = *self
                .p
                .wire_in
                .get(a as usize)
                .ok_or_else(|| HarnessError::Gateware(format!("no wire-in {a:#04x}")))?;
            self.sh.set(&mut self.m, i, v as u64);
        }
        let mask_pixels = if mask_enable { self.mask_loaded } else { 0 };
        self.trigger(trigger::START);
        let start_cycle = self.m.cycles;
        let t0 = self.m.cycles;
        while self.wire_out(wire_out::STATUS) & status::RUNNING == 0 {
            if self.wire_out(wire_out::STATUS) & status::CONFIG_ERROR != 0 {
                return Err(HarnessError::Gateware(
                    "START refused the registers (CONFIG_ERROR)".into(),
                ));
            }
            self.clock();
            if self.m.cycles - t0 > 10_000 {
                return Err(HarnessError::Gateware("never RUNNING".into()));
            }
        }
        match case.source {
            Source::Replay => {
                self.write_pipe(false, &replay_words(&case.planes), case.input_stall)?;
            }
            Source::Sensor => self.feed_sensor(case)?,
        }
        self.trigger(trigger::STOP);
        let t0 = self.m.cycles;
        loop {
            let st = self.wire_out(wire_out::STATUS);
            let ended = st & status::ENDED != 0;
            if ended && self.wire_out(wire_out::FIFO_BYTES) == 0 && self.pending == 0 {
                break;
            }
            if st & status::FAULT != 0 {
                return Err(HarnessError::Gateware(self.fault_source()));
            }
            // After STOP the host reads (a held reader would deadlock: the
            // StreamEnd record needs room in the output FIFO).
            self.read_blocks(true);
            self.clock();
            if self.m.cycles - t0 > self.limit {
                return Err(HarnessError::Gateware(format!(
                    "the stream did not end (status {st:#x})"
                )));
            }
        }
        let status = self.wire_out(wire_out::STATUS);
        if status & (status::FAULT | status::FRAMING_ERROR | status::SENSOR_OVERFLOW) != 0 {
            return Err(HarnessError::Gateware(format!("status {status:#x}")));
        }
        let [mut ddr_error, mut collisions, mut refreshes] = [0; 3];
        if let Some([e, c, r]) = self.p.ddr {
            ddr_error = self.m.get(e);
            collisions = self.m.get(c);
            refreshes = self.m.get(r);
        }
        if ddr_error != 0 {
            return Err(HarnessError::Gateware("DDR2 model protocol error".into()));
        }
        let stream_cycles = self.m.cycles - start_cycle;
        let bytes = strip_padding(&self.read);
        if let Some(v) = &mut self.vcd {
            if v.open {
                self.m.trace_close();
            }
        }
        Ok(Outcome {
            bytes,
            stream_cycles,
            cycles: self.m.cycles,
            seconds: 0.0,
            status,
            refresh_collisions: collisions,
            refreshes,
            overflowed: status & status::OVERFLOWED != 0,
            mask_pixels,
            stage_mismatches: self
                .probes
                .as_ref()
                .map(|p| p.mismatches())
                .unwrap_or_default(),
            driver: self.m.counters,
        })
    }

    /// Which sticky fault flag rose.
    pub(super) fn fault_source(&mut self) -> String {
        let b = self.m.build().clone();
        let mut why = Vec::new();
        for (port, what) in [
            (
                "fault_back",
                "a back-half buffer overflowed (input too dense for the tracker)",
            ),
            ("fault_tracker_fifo", "the tracker's input FIFO overflowed"),
            ("fault_roi_ring", "the ROI aggregator's row ring overran"),
            ("fault_bank", "the tracker found no free counter bank"),
            ("fault_record_queue", "the record queue overflowed"),
            ("fault_output_fifo", "the output FIFO overflowed"),
            ("fault_underrun", "the DDR2 delay line underran"),
            ("fault_write", "the DDR2 write FIFO was full"),
        ] {
            if let Ok(i) = b.port(port) {
                if self.m.get(i) != 0 {
                    why.push(what);
                }
            }
        }
        format!("FAULT at clock {}: {}", self.m.cycles, why.join(", "))
    }

    fn geometry(&mut self) -> (usize, usize) {
        let g = self.wire_out(wire_out::GEOMETRY);
        ((g & 0xffff) as usize, (g >> 16) as usize)
    }

    /// The sensor port: a word every `sensor_interval` clocks (by default
    /// every other clock, the sensor's duty cycle at P = 16), with random
    /// extra gaps, into a 32-word FIFO.
    fn feed_sensor(&mut self, case: &Case) -> Result<(), HarnessError> {
        let p = crate::designs::P;
        let wpp = self.geometry();
        let wpp = wpp.0 * wpp.1 / p;
        let total = case.planes.len() * wpp;
        let mut sent = 0;
        let every = self.sensor_interval.max(1) as u64;
        let mut turn = 0u64;
        while sent < total {
            let phase = turn.is_multiple_of(every);
            turn += 1;
            let stall = case.input_stall > 0 && self.rng.gen_range(0..100) < case.input_stall;
            if phase && !stall {
                if self.sensor.len() >= 1 << smartagg_hdl::xem6310::SENSOR_FIFO_BITS {
                    return Err(HarnessError::Gateware("sensor FIFO overflow".into()));
                }
                let (t, idx) = (sent / wpp, sent % wpp);
                let word = case.planes[t].stream_word(p, idx) | ((idx == 0) as u64) << p;
                self.sensor.push_back(word);
                sent += 1;
                // A sticky FAULT named when it rises, not at STOP.
                if idx == 0 && self.wire_out(wire_out::STATUS) & status::FAULT != 0 {
                    return Err(HarnessError::Gateware(format!(
                        "{} (sensor port, bit-plane {t})",
                        self.fault_source()
                    )));
                }
            }
            self.read_blocks(false);
            self.clock();
        }
        let t0 = self.m.cycles;
        while !self.sensor.is_empty() {
            self.clock();
            if self.m.cycles - t0 > 10_000 {
                return Err(HarnessError::Gateware("sensor FIFO not drained".into()));
            }
        }
        Ok(())
    }
}
