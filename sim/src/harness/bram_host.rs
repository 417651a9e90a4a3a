//! The word-port host of the demo's design (projected SPCImager): the
//! block-RAM pipeline itself, driven word by word with source stalls and
//! output back-pressure.

use super::probes::{vcd_of, Probes, Shadow, Vcd};
use super::{Case, Cosim, HarnessError, Outcome};
use crate::verilator::Model;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_hdl::registers::{control, wire_in};
use smartagg_model::plane::BitPlane;
use std::path::Path;

/// Drives the block-RAM pipeline directly (projected SPCImager).
pub(super) struct BramHost {
    m: Model,
    sh: Shadow,
    rng: ChaCha8Rng,
    probes: Option<Probes>,
    vcd: Option<Vcd>,
    wpp: usize,
    width: usize,
    height: usize,
    limit: u64,
}

impl BramHost {
    pub(super) fn new(
        m: Model,
        cosim: &Cosim,
        case: &Case,
        probes: Option<Probes>,
        vcd: Option<(&Path, u64, u64)>,
    ) -> Result<BramHost, HarnessError> {
        let n = m.build().ports.len();
        let wpp = cosim.spec.width * cosim.spec.height / crate::designs::P;
        Ok(BramHost {
            m,
            sh: Shadow {
                vals: vec![None; n],
            },
            rng: ChaCha8Rng::seed_from_u64(case.seed),
            probes,
            vcd: vcd_of(vcd),
            wpp,
            width: cosim.spec.width,
            height: cosim.spec.height,
            limit: 100_000 + (case.planes.len() as u64 + case.n as u64 + 4) * wpp as u64 * 12,
        })
    }

    fn port(&self, n: &str) -> Result<usize, HarnessError> {
        self.m
            .build()
            .port(n)
            .map_err(|e| HarnessError::Design(e.into()))
    }

    fn clock(&mut self) {
        if let Some(pr) = &mut self.probes {
            pr.sample(&mut self.m);
        }
        if let Some(v) = &mut self.vcd {
            v.step(&mut self.m);
        }
        self.m.tick(1);
    }

    /// Runs a case: the mask words (zero without a mask) through the load
    /// port, the registers (the host's wire-ins, by address), start, the
    /// planes with stalls, stop, the stream popped.
    pub(super) fn run(
        mut self,
        case: &Case,
        wire_ins: &[(u8, u32)],
        mask: Option<Vec<u8>>,
    ) -> Result<Outcome, HarnessError> {
        let p = crate::designs::P;
        let [load, load_address, load_data] =
            ["load", "load_address", "load_data"].map(|n| self.port(n));
        let (load, load_address, load_data) = (load?, load_address?, load_data?);
        // The pipe-in's bytes as a plane: pixel i is bit i of the stream.
        let bytes = mask.unwrap_or_default();
        let mask_plane = BitPlane::from_fn(self.width, self.height, |x, y| {
            let i = y * self.width + x;
            bytes.get(i / 8).is_some_and(|b| (b >> (i % 8)) & 1 != 0)
        });
        let mut loaded = 0;
        for idx in 0..self.wpp {
            let word = mask_plane.stream_word(p, idx);
            loaded += word.count_ones();
            self.sh.set(&mut self.m, load, 1);
            self.sh.set(&mut self.m, load_address, idx as u64);
            self.sh.set(&mut self.m, load_data, word);
            self.clock();
        }
        self.sh.set(&mut self.m, load, 0);
        let mut mask_enable = false;
        for &(a, v) in wire_ins {
            let (name, v) = match a {
                wire_in::CONTROL => {
                    mask_enable = v & control::MASK_ENABLE != 0;
                    ("regs_mask_enable", mask_enable as u32)
                }
                wire_in::N_WINDOW => ("regs_n", v),
                wire_in::THRESHOLD_INT => ("regs_threshold", v),
                wire_in::THRESHOLD_HOLD => ("regs_threshold_hold", v),
                wire_in::END_TRIM => ("regs_end_trim", v),
                wire_in::L_MIN => ("regs_l_min", v),
                wire_in::L_MAX => ("regs_l_max", v),
                wire_in::PLANE_PERIOD_NS => ("regs_period", v),
                wire_in::MASKED_PIXELS => ("regs_masked", v),
                _ => return Err(HarnessError::Gateware(format!("no register {a:#04x}"))),
            };
            let i = self.port(name)?;
            self.sh.set(&mut self.m, i, v as u64);
        }
        let mask_pixels = if mask_enable { loaded } else { 0 };
        let start = self.port("start")?;
        self.sh.set(&mut self.m, start, 1);
        self.clock();
        self.sh.set(&mut self.m, start, 0);
        let [running, ready, config_error, in_valid, in_sop, in_live, stop, out_pop, out_valid, out_data, ended, fault, framing, overflowed] =
            [
                "running",
                "ready",
                "config_error",
                "in_valid",
                "in_sop",
                "in_live",
                "stop",
                "out_pop",
                "out_valid",
                "out_data",
                "ended",
                "fault",
                "framing_error",
                "overflowed",
            ]
            .map(|n| self.port(n));
        let (running, ready, config_error, in_valid, in_sop, in_live) = (
            running?,
            ready?,
            config_error?,
            in_valid?,
            in_sop?,
            in_live?,
        );
        let (stop, out_pop, out_valid, out_data, ended, fault, framing, overflowed) = (
            stop?,
            out_pop?,
            out_valid?,
            out_data?,
            ended?,
            fault?,
            framing?,
            overflowed?,
        );
        if self.m.get(config_error) != 0 {
            return Err(HarnessError::Gateware(
                "START refused the registers (config_error)".into(),
            ));
        }
        let start_cycle = self.m.cycles;
        while self.m.get(running) == 0 {
            self.clock();
            if self.m.cycles - start_cycle > 10_000 {
                return Err(HarnessError::Gateware("never running".into()));
            }
        }
        let total = case.planes.len() * self.wpp;
        let mut sent = 0;
        let mut bytes = Vec::new();
        loop {
            // A word on every clock on which the pipeline is ready (the
            // replay's pacing: the back half's room holds it back), with
            // random stalls.
            let offer = sent < total
                && !(case.input_stall > 0 && self.rng.gen_range(0..100) < case.input_stall);
            let mut took = false;
            if offer && self.m.get(ready) != 0 {
                let (t, idx) = (sent / self.wpp, sent % self.wpp);
                self.sh.set(&mut self.m, in_valid, 1);
                self.sh.set(&mut self.m, in_sop, (idx == 0) as u64);
                self.sh
                    .set(&mut self.m, in_live, case.planes[t].stream_word(p, idx));
                took = true;
            } else {
                self.sh.set(&mut self.m, in_valid, 0);
            }
            self.sh
                .set(&mut self.m, stop, (sent + took as usize == total) as u64);
            let held = case.hold_reads && sent < total;
            let stalled = case.read_stall > 0 && self.rng.gen_range(0..100) < case.read_stall;
            let pop = !held && !stalled;
            self.sh.set(&mut self.m, out_pop, pop as u64);
            if pop && self.m.get(out_valid) != 0 {
                bytes.push(self.m.get(out_data) as u8);
            }
            if self.m.get(fault) != 0 {
                return Err(HarnessError::Gateware(format!(
                    "fault at clock {}: a back-half buffer overflowed (input too dense for the tracker)",
                    self.m.cycles
                )));
            }
            let done = self.m.get(ended) != 0 && self.m.get(out_valid) == 0;
            if took {
                sent += 1;
            }
            self.clock();
            if done {
                break;
            }
            if self.m.cycles - start_cycle > self.limit {
                return Err(HarnessError::Gateware("the stream did not end".into()));
            }
        }
        if self.m.get(framing) != 0 {
            return Err(HarnessError::Gateware("framing error".into()));
        }
        if let Some(v) = &mut self.vcd {
            if v.open {
                self.m.trace_close();
            }
        }
        Ok(Outcome {
            bytes,
            stream_cycles: self.m.cycles - start_cycle,
            cycles: self.m.cycles,
            seconds: 0.0,
            status: 0,
            refresh_collisions: 0,
            refreshes: 0,
            overflowed: self.m.get(overflowed) != 0,
            mask_pixels,
            stage_mismatches: self
                .probes
                .as_ref()
                .map(|p| p.mismatches())
                .unwrap_or_default(),
            driver: self.m.counters,
        })
    }
}
