//! The co-simulation harness: one bit-plane stream through the Verilated
//! gateware and through the golden model, the packet byte streams compared.
//!
//! **Host side.** Every shipped configuration is driven as the host drives
//! the XEM6310 through FrontPanel: RESET, the hot-pixel mask through pipe-in
//! 0x81 (only with MASK_ENABLE), wire-ins, START, the planes through the
//! block-throttled replay pipe-in 0x80 (or the sensor port's FIFO), STOP,
//! and the packet stream read in 16-byte blocks from pipe-out 0xA0, with
//! random host stalls on both pipes (a stalled reader makes the output FIFO
//! overflow). The wire-ins and the mask bytes are the host's own
//! ([`StreamRegisters`], which the host's `configure` writes too). The DDR2
//! designs run with the DDR2 behavioural model on their MCB port; the
//! block-RAM designs (projected SPCImager) with the port parked. The demo's
//! design is the pipeline itself, driven word by word with source stalls
//! and output back-pressure.
//!
//! **Comparison.** With no loss the bytes equal the model's exactly. With
//! output-FIFO overflow the stream is split into packets: every packet but
//! Overflow byte-identical to the model's packet of the same sequence
//! number, and every gap covered by exactly one Overflow record with its
//! exact first number and count ([`compare_lossy`]; docs/DESIGN.md §3). The
//! StreamStart's MASKED_PIXELS must count the pixels of the mask words
//! written through pipe-in 0x81. Coverage counts what the gateware
//! delivered (its packets decoded): every record kind, flag and sequence
//! wrap.
//!
//! **Diagnosis.** On a mismatch the same case runs again on a debug build
//! whose wrapper exposes every stage's output words (delay line, rolling
//! count, spatial filter, threshold and candidates); they are compared with
//! the model's stages plane by plane to name the first stage and bit-plane
//! that differ, and a third run writes a VCD of the clocks around it.
//!
//! The harness's parts, a file each: the case and its model configuration
//! (`case`), the hosts that drive the Verilated top (`xem_host`,
//! `bram_host`, and [`Device`] for the host's `cosim:` transport), the
//! words they stream (`words`), the stage probes that diagnose a mismatch
//! (`probes`), the comparison of the packet streams (`compare`) and the
//! coverage counters (`coverage`). This file holds the [`Cosim`] driver.

mod bram_host;
mod case;
mod compare;
mod coverage;
mod device;
mod probes;
mod words;
mod xem_host;

pub use case::{
    model_config, stream_registers, threshold_at_quantile, Case, Source, PLANE_PERIOD_NS,
};
pub use compare::{compare_lossy, split_packets, strip_padding, Framed};
pub use coverage::Coverage;
pub use device::Device;
pub use probes::{Mismatch, Stage, StageMismatch};
pub use words::block_words;

use crate::designs::{DesignError, DesignSpec};
use crate::verilator::{Build, Counters, Model};
use bram_host::BramHost;
use compare::{check_masked_pixels, first_differing_record_plane};
use coverage::{coverage_of, delivered_coverage};
use probes::Probes;
use smartagg_model::config::PipelineConfig;
use smartagg_model::packet::Encoder;
use smartagg_model::record::Record;
use smartagg_model::registers::StreamRegisters;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use xem_host::XemHost;

/// Clocks of a profile-guided build's training run (about 4 s of the
/// instrumented model).
pub const TRAINING_CLOCKS: usize = 400_000;

/// What one run of the gateware produced.
#[derive(Debug, Clone, Default)]
pub struct Outcome {
    /// The packet bytes (end padding removed).
    pub bytes: Vec<u8>,
    /// Clocks from START to the end of the stream.
    pub stream_cycles: u64,
    /// Clocks run in all.
    pub cycles: u64,
    /// Wall time of the run, seconds.
    pub seconds: f64,
    /// Final status wire.
    pub status: u32,
    /// DDR2 refreshes that began while commands waited.
    pub refresh_collisions: u64,
    /// DDR2 refreshes.
    pub refreshes: u64,
    /// The output overflowed (status).
    pub overflowed: bool,
    /// Stage probes: the first mismatch of each stage (debug builds).
    pub stage_mismatches: Vec<StageMismatch>,
    /// Calls into the Verilated model and its evaluations.
    pub driver: Counters,
    /// Pixels the mask words written through pipe-in 0x81 (the block-RAM
    /// mask's load port) mask, when `MASK_ENABLE` was written; 0 without:
    /// what the StreamStart's MASKED_PIXELS must say.
    pub mask_pixels: u32,
}

/// Errors of the harness (not mismatches: those are [`Mismatch`]).
#[derive(Debug, thiserror::Error)]
pub enum HarnessError {
    /// Building the design.
    #[error(transparent)]
    Design(#[from] DesignError),
    /// The model refused the case.
    #[error("model: {0}")]
    Model(String),
    /// The gateware refused or broke the stream.
    #[error("gateware: {0}")]
    Gateware(String),
}

/// A configuration verilated and ready to run cases.
pub struct Cosim {
    /// The configuration.
    pub spec: DesignSpec,
    /// The generated top's Verilog (as `hdl` writes it; possibly with an injected fault).
    pub top: String,
    fast: Arc<Build>,
    debug: Option<Arc<Build>>,
    /// Directory for VCDs.
    pub vcd_dir: PathBuf,
    trace: Option<PathBuf>,
    sensor_interval: u32,
    /// Sequence number of the StreamStart (the gateware's `seq_init`).
    seq_start: u32,
    /// A wire-in write that replaces the host's (a host bug, for tests).
    wire_override: Option<(u8, u32)>,
}

/// How a run goes: which build, probes, VCD window.
struct RunMode<'a> {
    debug: bool,
    vcd: Option<(&'a Path, u64, u64)>,
}

impl Cosim {
    /// Generates, verilates (or loads from the cache) and loads `spec`.
    pub fn new(spec: DesignSpec) -> Result<Cosim, HarnessError> {
        let top = spec.top_verilog()?;
        Self::with_top(spec, top)
    }

    /// As [`Cosim::new`] with the given top Verilog (e.g. with a fault injected).
    pub fn with_top(spec: DesignSpec, top: String) -> Result<Cosim, HarnessError> {
        let v = spec.cosim_verilog(&top, false)?;
        // The fast build is profile-guided: its instrumented model runs the
        // training case once, when it is verilated (not when cached).
        let train = |build: Arc<Build>| -> Result<(), String> {
            let c = Cosim {
                spec: spec.clone(),
                top: String::new(),
                fast: build,
                debug: None,
                vcd_dir: PathBuf::new(),
                trace: None,
                sensor_interval: 2,
                seq_start: 0,
                wire_override: None,
            };
            let case = c.training_case().map_err(|e| e.to_string())?;
            c.run_on(
                &c.fast,
                &case,
                RunMode {
                    debug: false,
                    vcd: None,
                },
            )
            .map(|_| ())
            .map_err(|e| e.to_string())
        };
        let fast = Build::get_trained(&v, &DesignSpec::build_options(false), Some(&train))
            .map_err(DesignError::from)?;
        Ok(Cosim::with_build(spec, top, fast, None, 0))
    }

    /// A co-simulation of `top` on its verilated builds, the harness's
    /// defaults otherwise (what every constructor shares).
    fn with_build(
        spec: DesignSpec,
        top: String,
        fast: Arc<Build>,
        debug: Option<Arc<Build>>,
        seq_start: u32,
    ) -> Cosim {
        let vcd_dir = fast.dir.join("vcd");
        Cosim {
            spec,
            top,
            fast,
            debug,
            vcd_dir,
            trace: None,
            sensor_interval: 2,
            seq_start,
            wire_override: None,
        }
    }

    /// As [`Cosim::with_top`], running every case on the debug build (stage
    /// probes and tracing compiled in): one build instead of two for a
    /// design that is expected to fail, as in fault injection.
    pub fn with_top_debug(spec: DesignSpec, top: String) -> Result<Cosim, HarnessError> {
        let v = spec.cosim_verilog(&top, true)?;
        let b = Build::get(&v, &DesignSpec::build_options(true)).map_err(DesignError::from)?;
        Ok(Cosim::with_build(spec, top, b.clone(), Some(b), 0))
    }

    /// As [`Cosim::new`] with the gateware's first sequence number (the
    /// packetiser's `seq_init`, 0 in every shipped design) patched to
    /// `seq_start` in the generated Verilog, and the model's encoder
    /// starting there too: sequence numbers that wrap past 2³² − 1 within a
    /// short stream. A plain build (one compile, no profile, no tracing):
    /// this Verilog is verilated for the wrap test alone.
    pub fn with_seq_start(spec: DesignSpec, seq_start: u32) -> Result<Cosim, HarnessError> {
        let top = patch_seq_init(&spec.top_verilog()?, seq_start)?;
        let v = spec.cosim_verilog(&top, false)?;
        let opts = crate::verilator::BuildOptions {
            profile: false,
            ..DesignSpec::build_options(false)
        };
        let fast = Build::get(&v, &opts).map_err(DesignError::from)?;
        Ok(Cosim::with_build(spec, top, fast, None, seq_start))
    }

    /// The training run of the profile-guided build: what the co-simulation
    /// runs (`smartagg cosim`'s kind of scene: sparse blinks over background,
    /// host stalls on both pipes) for about [`TRAINING_CLOCKS`] clocks, with
    /// N small enough that blinks complete and their packets are coded
    /// within it. Only the gateware runs it: what it trains is which
    /// branches of the model's code are hot.
    fn training_case(&self) -> Result<Case, HarnessError> {
        let (w, h) = (self.spec.width, self.spec.height);
        // The replay pipe-in brings a word every other clock; the pipeline
        // core takes one a clock while it is ready.
        let clocks_per_word = if self.spec.xem() { 2 } else { 1 };
        let clocks_per_plane = (clocks_per_word * w * h / crate::designs::P).max(1);
        let planes = (TRAINING_CLOCKS / clocks_per_plane).max(48);
        let n = ((planes / 8) as u32).clamp(8, self.spec.n_max());
        let planes = crate::scene::generate(&crate::scene::SceneSpec::sparse(w, h, planes), 1);
        let mut case = Case {
            input_stall: 10,
            read_stall: 20,
            ..Case::replay(n, 1, 3, n + 100, planes)
        };
        case.threshold = threshold_at_quantile(&self.model_config(&case)?, &case.planes, 0.995);
        Ok(case)
    }

    /// The fast build.
    pub fn build(&self) -> &Arc<Build> {
        &self.fast
    }

    fn debug_build(&mut self) -> Result<Arc<Build>, HarnessError> {
        if let Some(b) = &self.debug {
            return Ok(b.clone());
        }
        let v = self.spec.cosim_verilog(&self.top, true)?;
        let b = Build::get(&v, &DesignSpec::build_options(true)).map_err(DesignError::from)?;
        self.debug = Some(b.clone());
        Ok(b)
    }

    /// The model configuration of a case ([`model_config`]).
    pub fn model_config(&self, case: &Case) -> Result<PipelineConfig, HarnessError> {
        model_config(&self.spec, case)
    }

    /// Clocks between the sensor port's words ([`Source::Sensor`], DDR2
    /// configurations): 2 by default, the sensor's duty cycle at P = 16;
    /// 1 feeds a word every clock, the rate the pipeline must sustain for
    /// W·H/P clocks per bit-plane. (Host stalls skip further opportunities.)
    pub fn set_sensor_interval(&mut self, clocks: u32) {
        self.sensor_interval = clocks.max(1);
    }

    /// Makes every run write `value` to wire-in `addr` instead of what the
    /// host's configuration ([`StreamRegisters`]) writes there: a host bug,
    /// for tests that the harness catches it (`None`: the host's writes).
    pub fn override_wire_in(&mut self, write: Option<(u8, u32)>) {
        self.wire_override = write;
    }

    /// The registers the host writes for a case: the model configuration's
    /// ([`StreamRegisters::of`], the host's own code), planes from the
    /// replay pipe-in or the sensor port as the case says.
    pub fn registers(&self, case: &Case) -> Result<StreamRegisters, HarnessError> {
        stream_registers(&self.spec, case)
    }

    /// The model's packet bytes of `records`, numbered from the
    /// StreamStart's sequence number (0 but for [`Cosim::with_seq_start`]).
    pub fn encode(&self, records: &[Record]) -> Result<Vec<u8>, HarnessError> {
        let mut enc = Encoder::starting_at(self.seq_start);
        let mut out = Vec::new();
        for r in records {
            enc.push(r, &mut out)
                .map_err(|e| HarnessError::Model(e.to_string()))?;
        }
        Ok(out)
    }

    /// Makes [`Cosim::check`] run the traced debug build and write a VCD
    /// of the whole run to `path` (slow: for short runs).
    pub fn trace_whole_run(&mut self, path: PathBuf) {
        self.trace = Some(path);
    }

    /// Runs the case on the gateware only.
    pub fn run(&mut self, case: &Case) -> Result<Outcome, HarnessError> {
        if let Some(path) = self.trace.clone() {
            let debug = self.debug_build()?;
            return self.run_on(
                &debug,
                case,
                RunMode {
                    debug: false,
                    vcd: Some((&path, 0, u64::MAX)),
                },
            );
        }
        self.run_on(
            &self.fast,
            case,
            RunMode {
                debug: false,
                vcd: None,
            },
        )
    }

    fn run_on(
        &self,
        build: &Arc<Build>,
        case: &Case,
        mode: RunMode,
    ) -> Result<Outcome, HarnessError> {
        let model = Model::new(build.clone()).map_err(DesignError::from)?;
        let probes = if mode.debug {
            Some(Probes::new(&model, self, case)?)
        } else {
            None
        };
        let mut writes = self.registers(case)?;
        let mut wire_ins = writes.wire_ins();
        if let Some((a, v)) = self.wire_override {
            if let Some(w) = wire_ins.get_mut(a as usize) {
                w.1 = v;
            }
        }
        // The mask goes in only with MASK_ENABLE, as the host sends it.
        let mask = writes.mask.take();
        let started = std::time::Instant::now();
        let mut out = if self.spec.xem() {
            XemHost::new(model, self, case, probes, mode.vcd)?.run(case, &wire_ins, mask)?
        } else {
            BramHost::new(model, self, case, probes, mode.vcd)?.run(case, &wire_ins, mask)?
        };
        out.seconds = started.elapsed().as_secs_f64();
        Ok(out)
    }

    /// Runs the case on the gateware and the model and compares the packet
    /// streams; on a mismatch, names the first stage and bit-plane that
    /// differ and writes a VCD around it.
    pub fn check(&mut self, case: &Case) -> Result<Result<Coverage, Mismatch>, HarnessError> {
        let cfg = self.model_config(case)?;
        let records = smartagg_model::pipeline::run(cfg, case.planes.clone())
            .map_err(|e| HarnessError::Model(e.to_string()))?;
        let want = self.encode(&records)?;
        let out = self.run(case)?;
        let mut cov = coverage_of(&records, case);
        cov.cycles = out.cycles;
        cov.stream_cycles = out.stream_cycles;
        cov.driver = out.driver;
        cov.seconds = out.seconds;
        cov.refresh_collisions = out.refresh_collisions;
        // The mask's pixel count as the gateware sent it, against the mask
        // that went in (not against the model, which the registers follow).
        if let Ok(packets) = split_packets(&out.bytes) {
            if let Err(detail) = check_masked_pixels(&packets, out.mask_pixels) {
                return Ok(Err(Mismatch {
                    stage: Stage::BackHalf,
                    plane: 0,
                    detail: format!("registers: {detail}"),
                    vcd: None,
                }));
            }
        }
        let verdict = if out.bytes == want {
            if out.overflowed {
                Err("status OVERFLOWED set but every record arrived".to_string())
            } else {
                Ok(0)
            }
        } else {
            compare_lossy(&out.bytes, &want)
        };
        match verdict {
            Ok(lost) => {
                if lost > 0 {
                    cov.output_fifo_full = 1;
                    cov.records_lost = lost;
                }
                let packets = split_packets(&out.bytes).map_err(HarnessError::Gateware)?;
                cov.add(&delivered_coverage(&packets));
                Ok(Ok(cov))
            }
            Err(detail) => Ok(Err(self.diagnose(case, &records, detail)?)),
        }
    }

    /// Reruns a failing case with probes and names the first stage that differs.
    fn diagnose(
        &mut self,
        case: &Case,
        records: &[Record],
        detail: String,
    ) -> Result<Mismatch, HarnessError> {
        let debug = self.debug_build()?;
        let out = self.run_on(
            &debug,
            case,
            RunMode {
                debug: true,
                vcd: None,
            },
        )?;
        let first = out
            .stage_mismatches
            .iter()
            .min_by_key(|m| (m.stage, m.plane))
            .cloned();
        let wpp = self.spec.width * self.spec.height / crate::designs::P;
        let (stage, plane, detail, cycle) = match first {
            Some(m) => (
                m.stage,
                m.plane,
                format!(
                    "word {} (row {}, column {}): gateware lanes {:?}, model lanes {:?}; packets: {detail}",
                    m.word,
                    m.word * crate::designs::P / self.spec.width,
                    m.word * crate::designs::P % self.spec.width,
                    m.got,
                    m.want
                ),
                Some(m.cycle),
            ),
            None => {
                let plane = first_differing_record_plane(&out.bytes, records);
                (Stage::BackHalf, plane, detail, None)
            }
        };
        let vcd = match cycle {
            Some(c) => {
                std::fs::create_dir_all(&self.vcd_dir).ok();
                let path = self
                    .vcd_dir
                    .join(format!("mismatch-seed{}-plane{plane}.vcd", case.seed));
                let margin = 4 * wpp as u64 + 200;
                self.run_on(
                    &debug,
                    case,
                    RunMode {
                        debug: false,
                        vcd: Some((&path, c.saturating_sub(margin), c + margin)),
                    },
                )?;
                path.exists().then_some(path)
            }
            None => None,
        };
        Ok(Mismatch {
            stage,
            plane,
            detail,
            vcd,
        })
    }
}

/// The generated top with the packetiser's first sequence number tied to
/// `seq_start` instead of 0 (the one assignment `…pkt$seq_init = 32'h0;`).
pub fn patch_seq_init(top: &str, seq_start: u32) -> Result<String, HarnessError> {
    let from = "pkt$seq_init = 32'h0;";
    if top.matches(from).count() != 1 {
        return Err(HarnessError::Gateware(format!(
            "the generated top has {} assignments `{from}`, not one",
            top.matches(from).count()
        )));
    }
    Ok(top.replace(from, &format!("pkt$seq_init = 32'h{seq_start:08x};")))
}
