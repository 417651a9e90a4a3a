//! `--source cosim:PRESET[:PLANES]`: the Verilated gateware played as if it
//! were the board.
//!
//! The XEM6310 core generated for the preset (smartagg-sim; SPCImager 150×
//! on its full 320×240 field) runs in Verilator with its behavioural DDR2.
//! [`super::registers::configure`] drives it through the same
//! [`super::registers::RegisterBus`] as a real board (wire-ins, triggers,
//! the mask pipe-in, the generation wire-outs); `start` waits for the DDR2
//! calibration and pulses START; `read` steps the simulation, replays
//! simulated bit-planes of a scene through the replay pipe-in (the
//! hardware-in-the-loop path, `SOURCE_REPLAY`) and returns the pipe-out's
//! packet bytes. After `PLANES` planes (default 200) the source sends STOP
//! itself, and the stream ends with the device's StreamEnd.

use super::registers::{self, control, trigger, wire_in, RegisterBus};
use super::{Chunk, DeviceConfig, PacketSource, TransportError};
use smartagg_model::params::PresetName;
use smartagg_sim::designs::{Config, DesignSpec, FULL};
use smartagg_sim::harness::Device;
use smartagg_sim::scene::{generate, SceneSpec};
use std::time::{Duration, Instant};

/// Planes replayed when the source spec names no count.
pub const DEFAULT_PLANES: usize = 200;

/// Planes generated and queued at a time.
const BATCH: usize = 20;

/// The co-simulated board.
pub struct CosimSource {
    dev: Device,
    name: String,
    planes_left: usize,
    batch: u64,
    seed: u64,
    started: bool,
    stopping: bool,
    done: bool,
    pending: Vec<u8>,
    width: usize,
    height: usize,
}

fn sim_err(what: &str, e: impl std::fmt::Display) -> TransportError {
    TransportError::Unavailable(format!("co-simulation ({what}): {e}"))
}

/// Opens the co-simulation source: `PRESET` or `PRESET:PLANES`.
pub fn open(spec: &str) -> Result<Box<dyn PacketSource>, TransportError> {
    let (preset, planes) = match spec.split_once(':') {
        Some((p, n)) => (
            p,
            n.parse::<usize>().ok().filter(|&n| n > 0).ok_or_else(|| {
                TransportError::BadSource(format!(
                    "--source cosim:{spec}: `{n}` is not a positive number of planes"
                ))
            })?,
        ),
        None => (spec, DEFAULT_PLANES),
    };
    let name = PresetName::parse(preset)
        .map_err(|e| TransportError::BadSource(format!("--source cosim:{spec}: {e}")))?;
    let config = Config::for_preset(name, 150).map_err(|e| sim_err("preset", e))?;
    // The association radius is a generation constant: the shipped design's.
    let shipped = smartagg_hdl::designs::Design::new(name, 150)
        .map_err(|e| sim_err("the shipped design", e))?;
    let design = DesignSpec::new(config, FULL.0, FULL.1)
        .and_then(|d| d.with_r_assoc(shipped.config.r_assoc))
        .map_err(|e| TransportError::Unavailable(format!("--source cosim:{spec}: {e}")))?;
    let dev = Device::open(design).map_err(|e| sim_err("building the design", e))?;
    Ok(Box::new(CosimSource {
        dev,
        name: format!("co-simulated XEM6310 ({})", config.name()),
        planes_left: planes,
        batch: 0,
        seed: 0x5a11,
        started: false,
        stopping: false,
        done: false,
        pending: Vec::new(),
        width: FULL.0,
        height: FULL.1,
    }))
}

impl RegisterBus for CosimSource {
    fn set_wire_in(&mut self, addr: u8, value: u32) -> Result<(), TransportError> {
        // The planes come through the replay pipe-in, not a sensor.
        let value = if addr == wire_in::CONTROL {
            value | control::SOURCE_REPLAY
        } else {
            value
        };
        self.dev
            .set_wire_in(addr, value)
            .map_err(|e| sim_err("wire-in", e))
    }

    fn commit_wire_ins(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    fn wire_out(&mut self, addr: u8) -> Result<u32, TransportError> {
        Ok(self.dev.wire_out(addr))
    }

    fn trigger(&mut self, addr: u8, bit: u8) -> Result<(), TransportError> {
        if addr != trigger::CONTROL {
            return Err(sim_err("trigger", format!("no trigger-in {addr:#04x}")));
        }
        self.dev.trigger(bit);
        Ok(())
    }

    fn write_pipe_in(&mut self, addr: u8, data: &[u8]) -> Result<(), TransportError> {
        if addr != registers::pipe::MASK_IN {
            return Err(sim_err(
                "pipe-in",
                format!("no pipe-in {addr:#04x} for the host"),
            ));
        }
        self.dev
            .write_mask(data)
            .map_err(|e| sim_err("mask pipe-in", e))
    }
}

impl CosimSource {
    fn queue_more(&mut self) {
        if self.planes_left == 0 || self.dev.queued_words() > 0 {
            return;
        }
        let n = self.planes_left.min(BATCH);
        let (w, h) = (self.width, self.height);
        let planes = generate(
            &SceneSpec {
                width: w,
                height: h,
                planes: n,
                background: 0.001,
                emitters: 200,
                peak: 0.4,
                mean_on: 12.0,
                mean_off: 60.0,
                edge_fraction: 0.1,
                dip: 0.05,
                hot: Vec::new(),
                hot_rate: 0.0,
            },
            self.seed ^ self.batch,
        );
        self.batch += 1;
        self.planes_left -= n;
        self.dev.queue_planes(&planes);
    }
}

impl PacketSource for CosimSource {
    fn describe(&self) -> String {
        self.name.clone()
    }

    fn configure(&mut self, cfg: &DeviceConfig) -> Result<(), TransportError> {
        registers::configure(self, cfg)
    }

    fn start(&mut self) -> Result<(), TransportError> {
        // START is taken once the DDR2 has calibrated.
        let mut clocks = 0;
        while self.dev.wire_out(registers::wire_out::STATUS)
            & smartagg_hdl::registers::status::MEM_READY
            == 0
        {
            self.dev.run(64).map_err(|e| sim_err("calibration", e))?;
            clocks += 64;
            if clocks > 1_000_000 {
                return Err(sim_err("calibration", "the DDR2 model never calibrated"));
            }
        }
        registers::start(self)?;
        self.started = true;
        self.queue_more();
        Ok(())
    }

    fn read(&mut self, buf: &mut [u8], wait: Duration) -> Result<Chunk, TransportError> {
        if !self.pending.is_empty() {
            let n = self.pending.len().min(buf.len());
            buf[..n].copy_from_slice(&self.pending[..n]);
            self.pending.drain(..n);
            return Ok(Chunk::Data(n));
        }
        if self.done {
            return Ok(Chunk::End);
        }
        if !self.started {
            return Ok(Chunk::Idle);
        }
        let t0 = Instant::now();
        while t0.elapsed() < wait {
            self.queue_more();
            if self.planes_left == 0 && self.dev.queued_words() == 0 && !self.stopping {
                registers::stop(self)?;
                self.stopping = true;
            }
            let bytes = self.dev.run(4096).map_err(|e| sim_err("run", e))?;
            if self.stopping && self.dev.ended() {
                self.done = true;
            }
            if !bytes.is_empty() {
                self.pending = bytes;
                return self.read(buf, wait);
            }
            if self.done {
                return Ok(Chunk::End);
            }
        }
        Ok(Chunk::Idle)
    }

    fn stop(&mut self) -> Result<(), TransportError> {
        // No more planes after those queued (whole planes: the one in
        // progress completes, as STOP requires).
        self.planes_left = 0;
        if !self.stopping && self.dev.queued_words() == 0 {
            registers::stop(self)?;
            self.stopping = true;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn bad_specs_are_named() {
        let e = super::open("nosuch").err().unwrap().to_string();
        assert!(e.contains("nosuch"), "{e}");
        let e = super::open("spcimager:zero").err().unwrap().to_string();
        assert!(e.contains("zero") && e.contains("planes"), "{e}");
        let e = super::open("emccd").err().unwrap().to_string();
        assert!(e.contains("emccd"), "{e}");
    }
}
