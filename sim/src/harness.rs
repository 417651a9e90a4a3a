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

use crate::designs::{DesignError, DesignSpec};
use crate::verilator::{Build, Counters, Model};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_hdl::registers::{control, status, trigger, wire_in, wire_out};
use smartagg_model::config::PipelineConfig;
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::packet::decode_all;
use smartagg_model::packet::Encoder;
use smartagg_model::plane::BitPlane;
use smartagg_model::record::{flags, Record};
use smartagg_model::registers::StreamRegisters;
use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Where the planes enter the design.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The replay pipe-in (hardware-in-the-loop path).
    Replay,
    /// The sensor port's FIFO (DDR2 configurations).
    Sensor,
}

/// One co-simulation case: runtime registers, planes, host behaviour.
#[derive(Debug, Clone)]
pub struct Case {
    /// Rolling window N.
    pub n: u32,
    /// Threshold T_int (the open level of candidates).
    pub threshold: u32,
    /// Threshold T_hold (the hold level of live tracks, 1 ..= T_int);
    /// `None`: T_hold = T_int (the one-threshold rule), whatever T_int is
    /// set to later.
    pub threshold_hold: Option<u32>,
    /// END_TRIM (0 ..= N − 1): a dropped segment sums up to
    /// `t_drop − end_trim` (0: the paper's rule).
    pub end_trim: u32,
    /// L_min.
    pub l_min: u32,
    /// L_max.
    pub l_max: u32,
    /// The bit-planes.
    pub planes: Vec<BitPlane>,
    /// Hot pixels of the mask (loaded through pipe-in 0x81 and applied if
    /// `mask_enable`, as the host sends a mask: [`StreamRegisters`]).
    pub hot: Vec<(usize, usize)>,
    /// MASK_ENABLE.
    pub mask_enable: bool,
    /// Input path.
    pub source: Source,
    /// Percent of host opportunities skipped on the input side.
    pub input_stall: u32,
    /// Percent of host opportunities skipped on the output side.
    pub read_stall: u32,
    /// The host reads nothing until every plane has gone in (forces overflow).
    pub hold_reads: bool,
    /// Seed of the host stalls.
    pub seed: u64,
}

impl Case {
    /// The bit-planes replayed through the pipe-in with these registers
    /// (T_hold = T_int, END_TRIM 0: the paper's rules): no hot-pixel mask,
    /// no host stalls on either side (stall seed 1). Other cases change
    /// fields from this one (`Case { .., ..Case::replay(..) }`).
    pub fn replay(n: u32, threshold: u32, l_min: u32, l_max: u32, planes: Vec<BitPlane>) -> Case {
        Case {
            n,
            threshold,
            threshold_hold: None,
            end_trim: 0,
            l_min,
            l_max,
            planes,
            hot: Vec::new(),
            mask_enable: false,
            source: Source::Replay,
            input_stall: 0,
            read_stall: 0,
            hold_reads: false,
            seed: 1,
        }
    }

    /// The bit-planes replayed with a shipped design's register defaults,
    /// the field design's ([`smartagg_hdl::configs::Design`]): its N, the
    /// open level T_open as T_int, the hold level T_hold, its END_TRIM
    /// (⌊N/2⌋), L_min = 1 and
    /// L_max = 10,000 (the model's default). The design's r_assoc is a
    /// generation parameter: pass it to [`crate::designs::DesignSpec::with_r_assoc`].
    pub fn design_defaults(design: &smartagg_hdl::configs::Design, planes: Vec<BitPlane>) -> Case {
        let t = |v: u64| u32::try_from(v).unwrap_or(u32::MAX);
        Case {
            threshold_hold: Some(t(design.threshold_hold)),
            end_trim: design.end_trim,
            ..Case::replay(
                design.n_window,
                t(design.threshold_int),
                1,
                smartagg_model::config::DEFAULT_L_MAX.max(design.n_window),
                planes,
            )
        }
    }

    /// The T_hold register: [`Case::threshold_hold`], or T_int.
    pub fn hold(&self) -> u32 {
        self.threshold_hold.unwrap_or(self.threshold)
    }
}

/// Clocks of a profile-guided build's training run (about 4 s of the
/// instrumented model).
pub const TRAINING_CLOCKS: usize = 400_000;

/// Plane period written to the register (ns).
pub const PLANE_PERIOD_NS: u32 = 100_000;

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

/// A pipeline stage with a probe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stage {
    /// Stage 0 + 1a: the masked live word `B_t` out of the delay line.
    MaskAndDelayLive,
    /// Stage 1a: `B_{t−N}` out of the delay line.
    DelayLine,
    /// Stage 1: rolling count S.
    RollingCount,
    /// Stage 2: spatial filter H.
    SpatialFilter,
    /// Stage 3: threshold `H ≥ T_hold` (the tracker's on/off bits).
    Threshold,
    /// Stage 4: candidates (3×3 local maxima).
    Candidates,
    /// Stages 5–7: tracker, ROI aggregator, packetiser, output FIFO.
    BackHalf,
}

impl Stage {
    /// The stage's name in the paper's and the model's words.
    pub fn name(self) -> &'static str {
        match self {
            Stage::MaskAndDelayLive => "hot-pixel mask (live bit-plane)",
            Stage::DelayLine => "delay line (B_{t-N})",
            Stage::RollingCount => "rolling count",
            Stage::SpatialFilter => "spatial filter",
            Stage::Threshold => "threshold",
            Stage::Candidates => "candidates",
            Stage::BackHalf => "back half (blink tracker, ROI aggregator, packetiser)",
        }
    }
}

/// The first difference of one stage.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StageMismatch {
    /// Which stage.
    pub stage: Stage,
    /// Bit-plane.
    pub plane: u64,
    /// Word within the plane (P pixels, raster order).
    pub word: usize,
    /// Clock of the run at which it came out.
    pub cycle: u64,
    /// Lane values, gateware.
    pub got: Vec<u64>,
    /// Lane values, model.
    pub want: Vec<u64>,
}

/// The first mismatch of a case, named.
#[derive(Debug, Clone)]
pub struct Mismatch {
    /// The first stage that differs.
    pub stage: Stage,
    /// The first bit-plane at which it differs.
    pub plane: u64,
    /// What differs.
    pub detail: String,
    /// VCD of the clocks around it, if written.
    pub vcd: Option<PathBuf>,
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "first mismatch in stage `{}` at bit-plane {}: {}",
            self.stage.name(),
            self.plane,
            self.detail
        )?;
        if let Some(v) = &self.vcd {
            write!(f, " (VCD: {})", v.display())?;
        }
        Ok(())
    }
}

/// Coverage of what the cases exercised (summed over cases).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Coverage {
    /// Cases run.
    pub cases: u64,
    /// Bit-planes streamed.
    pub planes: u64,
    /// Packets compared (model records).
    pub packets: u64,
    /// Confirmed blinks (Blink records).
    pub confirmed_blinks: u64,
    /// Single-plane dips bridged.
    pub bridged_dips: u64,
    /// Tracks shorter than L_min (unconfirmed).
    pub unconfirmed_tracks: u64,
    /// Candidates dropped for want of a free slot.
    pub slot_exhaustion: u64,
    /// Cases whose output FIFO overflowed.
    pub output_fifo_full: u64,
    /// Records lost to output overflow, all announced.
    pub records_lost: u64,
    /// DDR2 refreshes that collided with waiting commands.
    pub refresh_collisions: u64,
    /// Blink ROIs touching the field's edge.
    pub edge_rois: u64,
    /// Segments cut at L_max.
    pub cut_segments: u64,
    /// Blinks truncated by the stream end.
    pub truncated_blinks: u64,
    /// Blinks that summed no plane (a first segment that ended before its
    /// first plane left the window).
    pub empty_blinks: u64,
    /// StreamStart records the gateware delivered (its bytes decoded, as
    /// are all the counters from here to [`Coverage::seq_wraps`]).
    pub start_records: u64,
    /// Blink records delivered.
    pub blink_records: u64,
    /// Dropped records delivered.
    pub dropped_records: u64,
    /// Overflow records delivered.
    pub overflow_records: u64,
    /// StreamEnd records delivered.
    pub end_records: u64,
    /// Delivered Blinks flagged EDGE.
    pub flag_edge: u64,
    /// Delivered Blinks flagged MASKED.
    pub flag_masked: u64,
    /// Delivered Blinks flagged TRUNCATED.
    pub flag_truncated: u64,
    /// Delivered Blinks flagged CONTINUATION.
    pub flag_continuation: u64,
    /// Delivered Blinks flagged PREROLL_CLIPPED.
    pub flag_preroll_clipped: u64,
    /// Delivered Blinks cut at L_max (flag CUT).
    pub lmax_cuts: u64,
    /// Delivered empty segments (no plane summed) that were cut at L_max
    /// and continued: the empty segment of a continued blink. (A
    /// CONTINUATION segment itself always sums a plane under the version-3
    /// rule, PACKETS.md §8.6; [`Coverage::empty_continuations`] counts any.)
    pub empty_continued: u64,
    /// Delivered CONTINUATION segments that summed no plane (0 under the
    /// version-3 rule).
    pub empty_continuations: u64,
    /// Delivered continuations of a cut at the stream's last plane
    /// (CONTINUATION | TRUNCATED, `t_drop = t_cross − 1`).
    pub continued_at_last_plane: u64,
    /// Times the delivered sequence numbers (Overflow ranges included)
    /// wrapped from 2³² − 1 to 0.
    pub seq_wraps: u64,
    /// Clock cycles simulated.
    pub cycles: u64,
    /// Clock cycles from START to the end of the stream (of [`Coverage::cycles`]).
    pub stream_cycles: u64,
    /// Wall time simulating, seconds.
    pub seconds: f64,
    /// Calls into the Verilated model and its evaluations.
    pub driver: Counters,
}

impl Coverage {
    /// Adds another's counts.
    pub fn add(&mut self, o: &Coverage) {
        self.cases += o.cases;
        self.planes += o.planes;
        self.packets += o.packets;
        self.confirmed_blinks += o.confirmed_blinks;
        self.bridged_dips += o.bridged_dips;
        self.unconfirmed_tracks += o.unconfirmed_tracks;
        self.slot_exhaustion += o.slot_exhaustion;
        self.output_fifo_full += o.output_fifo_full;
        self.records_lost += o.records_lost;
        self.refresh_collisions += o.refresh_collisions;
        self.edge_rois += o.edge_rois;
        self.cut_segments += o.cut_segments;
        self.truncated_blinks += o.truncated_blinks;
        self.empty_blinks += o.empty_blinks;
        self.start_records += o.start_records;
        self.blink_records += o.blink_records;
        self.dropped_records += o.dropped_records;
        self.overflow_records += o.overflow_records;
        self.end_records += o.end_records;
        self.flag_edge += o.flag_edge;
        self.flag_masked += o.flag_masked;
        self.flag_truncated += o.flag_truncated;
        self.flag_continuation += o.flag_continuation;
        self.flag_preroll_clipped += o.flag_preroll_clipped;
        self.lmax_cuts += o.lmax_cuts;
        self.empty_continued += o.empty_continued;
        self.empty_continuations += o.empty_continuations;
        self.continued_at_last_plane += o.continued_at_last_plane;
        self.seq_wraps += o.seq_wraps;
        self.cycles += o.cycles;
        self.stream_cycles += o.stream_cycles;
        self.seconds += o.seconds;
        self.driver.add(&o.driver);
    }
}

impl Coverage {
    /// Clocks per bit-plane from START to the stream's end (W·H/P when the
    /// source and the pipeline sustain a word of P pixels every clock).
    pub fn clocks_per_plane(&self) -> f64 {
        self.stream_cycles as f64 / self.planes.max(1) as f64
    }

    /// Simulated clock cycles per wall-clock second, millions.
    pub fn mcycles_per_second(&self) -> f64 {
        self.cycles as f64 / self.seconds.max(1e-9) / 1e6
    }
}

impl std::fmt::Display for Coverage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cases {} planes {} packets {} | confirmed blinks {} bridged dips {} unconfirmed tracks {} \
             slot exhaustion {} output FIFO full {} (records lost {}) DDR2 refresh collisions {} edge ROIs {} \
             cuts {} truncated {} empty {} | delivered: StreamStart {} Blink {} Dropped {} Overflow {} StreamEnd {}; \
             EDGE {} MASKED {} TRUNCATED {} CONTINUATION {} PREROLL_CLIPPED {} L_max cuts {} empty continued {} \
             empty continuations {} continued at the last plane {} sequence wraps {} | {} cycles in {:.2} s ({:.2} M cycles/s; per clock {:.2} shim calls, {:.2} evals, {:.2} input-combinational passes)",
            self.cases,
            self.planes,
            self.packets,
            self.confirmed_blinks,
            self.bridged_dips,
            self.unconfirmed_tracks,
            self.slot_exhaustion,
            self.output_fifo_full,
            self.records_lost,
            self.refresh_collisions,
            self.edge_rois,
            self.cut_segments,
            self.truncated_blinks,
            self.empty_blinks,
            self.start_records,
            self.blink_records,
            self.dropped_records,
            self.overflow_records,
            self.end_records,
            self.flag_edge,
            self.flag_masked,
            self.flag_truncated,
            self.flag_continuation,
            self.flag_preroll_clipped,
            self.lmax_cuts,
            self.empty_continued,
            self.empty_continuations,
            self.continued_at_last_plane,
            self.seq_wraps,
            self.cycles,
            self.seconds,
            self.cycles as f64 / self.seconds.max(1e-9) / 1e6,
            self.driver.ffi_calls as f64 / self.cycles.max(1) as f64,
            self.driver.evals as f64 / self.cycles.max(1) as f64,
            self.driver.ico_evals as f64 / self.cycles.max(1) as f64,
        )
    }
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
        let vcd_dir = fast.dir.join("vcd");
        Ok(Cosim {
            spec,
            top,
            fast,
            debug: None,
            vcd_dir,
            trace: None,
            sensor_interval: 2,
            seq_start: 0,
            wire_override: None,
        })
    }

    /// As [`Cosim::with_top`], running every case on the debug build (stage
    /// probes and tracing compiled in): one build instead of two for a
    /// design that is expected to fail, as in fault injection.
    pub fn with_top_debug(spec: DesignSpec, top: String) -> Result<Cosim, HarnessError> {
        let v = spec.cosim_verilog(&top, true)?;
        let b = Build::get(&v, &DesignSpec::build_options(true)).map_err(DesignError::from)?;
        let vcd_dir = b.dir.join("vcd");
        Ok(Cosim {
            spec,
            top,
            fast: b.clone(),
            debug: Some(b),
            vcd_dir,
            trace: None,
            sensor_interval: 2,
            seq_start: 0,
            wire_override: None,
        })
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
        let vcd_dir = fast.dir.join("vcd");
        Ok(Cosim {
            spec,
            top,
            fast,
            debug: None,
            vcd_dir,
            trace: None,
            sensor_interval: 2,
            seq_start,
            wire_override: None,
        })
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

/// Counters of the model's records for a case.
fn coverage_of(records: &[Record], case: &Case) -> Coverage {
    let mut c = Coverage {
        cases: 1,
        planes: case.planes.len() as u64,
        packets: records.len() as u64,
        ..Default::default()
    };
    for r in records {
        match r {
            Record::Blink(b) => {
                c.confirmed_blinks += 1;
                if b.flags & flags::EDGE != 0 {
                    c.edge_rois += 1;
                }
                if b.flags & flags::TRUNCATED != 0 {
                    c.truncated_blinks += 1;
                }
                if b.planes_summed == 0 {
                    c.empty_blinks += 1;
                }
            }
            Record::End(e) => {
                c.bridged_dips += e.bridged_dips;
                c.unconfirmed_tracks += e.unconfirmed;
                c.slot_exhaustion += e.dropped_candidates;
                c.cut_segments += e.cut_segments;
            }
            _ => {}
        }
    }
    c
}

/// One packet of a byte stream: its header sequence number, its record and
/// its bytes (header to CRC).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Framed<'a> {
    /// Header sequence number (an Overflow's `first_seq`).
    pub seq: u32,
    /// The decoded record.
    pub record: Record,
    /// The packet's bytes.
    pub bytes: &'a [u8],
}

/// Splits a packet stream into its packets, back to back from the first
/// byte to the last, every one with a valid CRC and payload; or names the
/// byte at which that fails.
pub fn split_packets(bytes: &[u8]) -> Result<Vec<Framed<'_>>, String> {
    use smartagg_model::packet::{decode_frame, CRC_LEN, HEADER_LEN};
    let mut out = Vec::new();
    let mut p = 0;
    while p < bytes.len() {
        let rest = &bytes[p..];
        if rest.len() < HEADER_LEN {
            return Err(format!("byte {p}: {} bytes left, no packet", rest.len()));
        }
        let total = HEADER_LEN + u16::from_le_bytes([rest[8], rest[9]]) as usize + CRC_LEN;
        let frame = rest
            .get(..total)
            .ok_or_else(|| format!("byte {p}: a packet of {total} bytes runs past the end"))?;
        let packet = decode_frame(frame).map_err(|e| format!("byte {p}: {e}"))?;
        out.push(Framed {
            seq: packet.seq,
            record: packet.record,
            bytes: frame,
        });
        p += total;
    }
    Ok(out)
}

/// Whether the gateware's `bytes` are the model's stream `want` with
/// records lost on the device: split into packets, every packet but
/// Overflow byte-identical to the model's packet of the same sequence number
/// (the model's encoding of that record as its own packet), in order, and
/// every gap covered by exactly one Overflow record with the gap's first
/// sequence number and count, placed where the gap is (PACKETS.md §5);
/// nothing else. Ok(records lost) or what is wrong.
pub fn compare_lossy(bytes: &[u8], want: &[u8]) -> Result<u64, String> {
    let first = bytes.iter().zip(want).position(|(a, b)| a != b);
    let head = format!(
        "byte streams differ ({} bytes vs the model's {}, first difference at byte {:?})",
        bytes.len(),
        want.len(),
        first.or(Some(bytes.len().min(want.len())))
    );
    let got = split_packets(bytes).map_err(|e| format!("{head}; gateware stream: {e}"))?;
    let model = split_packets(want).map_err(|e| format!("{head}; model stream: {e}"))?;
    let base = model.first().map_or(0, |p| p.seq);
    // The model's packet of each sequence number, in order, none Overflow.
    for (i, m) in model.iter().enumerate() {
        if matches!(m.record, Record::Overflow(_)) || m.seq != base.wrapping_add(i as u32) {
            return Err(format!(
                "{head}; the model's packet {i} is not numbered in order"
            ));
        }
    }
    let index = |seq: u32| seq.wrapping_sub(base) as usize;
    let mut next = 0usize;
    let mut lost = 0u64;
    let mut after_overflow = false;
    for (k, g) in got.iter().enumerate() {
        match &g.record {
            Record::Overflow(o) => {
                if after_overflow {
                    return Err(format!("{head}; packet {k}: two Overflow records in a row"));
                }
                if index(o.first_seq) != next || o.count == 0 {
                    return Err(format!(
                        "{head}; packet {k}: Overflow of {} from seq {} where the next record is seq {}",
                        o.count,
                        o.first_seq,
                        base.wrapping_add(next as u32)
                    ));
                }
                next += o.count as usize;
                lost += o.count as u64;
                after_overflow = true;
            }
            _ => {
                let i = index(g.seq);
                if i != next {
                    return Err(format!(
                        "{head}; packet {k} has seq {} where seq {} is next (a gap no Overflow record announces, or out of order)",
                        g.seq,
                        base.wrapping_add(next as u32)
                    ));
                }
                let m = model.get(i).ok_or_else(|| {
                    format!(
                        "{head}; packet {k}: seq {} is past the model's stream",
                        g.seq
                    )
                })?;
                if g.bytes != m.bytes {
                    return Err(format!(
                        "{head}; packet {k} (seq {}) differs from the model's packet: gateware {:?}, model {:?} (bytes {:02x?} vs {:02x?})",
                        g.seq, g.record, m.record, g.bytes, m.bytes
                    ));
                }
                next += 1;
                after_overflow = false;
            }
        }
    }
    if next != model.len() || after_overflow {
        return Err(format!(
            "{head}; the stream accounts for {next} of the model's {} records{}",
            model.len(),
            if after_overflow {
                " and ends with an Overflow record"
            } else {
                ""
            }
        ));
    }
    if lost == 0 {
        return Err(format!("{head}; no Overflow record accounts for it"));
    }
    Ok(lost)
}

/// Counters of what the gateware delivered: its packets (split and decoded
/// by [`split_packets`]; the `delivered` fields of [`Coverage`]).
fn delivered_coverage(packets: &[Framed]) -> Coverage {
    let mut c = Coverage::default();
    // Sequence numbers unwrapped: each packet's number (an Overflow's
    // range) follows the previous one's end.
    let (mut first, mut end) = (None::<u64>, 0u64);
    for p in packets {
        let len = match &p.record {
            Record::Overflow(o) => o.count as u64,
            _ => 1,
        };
        let at = match first {
            None => {
                first = Some(p.seq as u64);
                p.seq as u64
            }
            Some(_) => end + (p.seq.wrapping_sub(end as u32)) as u64,
        };
        end = at + len;
        match &p.record {
            Record::Start(_) => c.start_records += 1,
            Record::Dropped(_) => c.dropped_records += 1,
            Record::Overflow(_) => c.overflow_records += 1,
            Record::End(_) => c.end_records += 1,
            Record::Blink(b) => {
                c.blink_records += 1;
                let has = |f: u8| (b.flags & f != 0) as u64;
                c.flag_edge += has(flags::EDGE);
                c.flag_masked += has(flags::MASKED);
                c.flag_truncated += has(flags::TRUNCATED);
                c.flag_continuation += has(flags::CONTINUATION);
                c.flag_preroll_clipped += has(flags::PREROLL_CLIPPED);
                c.lmax_cuts += has(flags::CUT);
                let empty = (b.planes_summed == 0) as u64;
                c.empty_continued += empty * has(flags::CUT);
                c.empty_continuations += empty * has(flags::CONTINUATION);
                if b.has(flags::CONTINUATION)
                    && b.has(flags::TRUNCATED)
                    && b.t_drop + 1 == b.t_cross
                {
                    c.continued_at_last_plane += 1;
                }
            }
        }
    }
    if let Some(f) = first {
        c.seq_wraps = (end.max(f + 1) - 1) / (1 << 32) - f / (1 << 32);
    }
    c
}

/// Whether the StreamStart the gateware sent first says MASKED_PIXELS =
/// the pixels of the mask loaded through pipe-in 0x81 (0 without
/// MASK_ENABLE), whatever the registers said.
fn check_masked_pixels(packets: &[Framed], loaded: u32) -> Result<(), String> {
    match packets.first().map(|p| &p.record) {
        Some(Record::Start(s)) if s.masked_pixels == loaded => Ok(()),
        Some(Record::Start(s)) => Err(format!(
            "StreamStart says MASKED_PIXELS {} but the mask loaded through pipe-in 0x81 masks {loaded} pixels",
            s.masked_pixels
        )),
        other => Err(format!("the stream does not begin with StreamStart: {other:?}")),
    }
}

/// The plane of the first record that differs (its completion plane), for
/// back-half mismatches.
fn first_differing_record_plane(bytes: &[u8], records: &[Record]) -> u64 {
    let d = decode_all(bytes);
    for (i, r) in records.iter().enumerate() {
        let got = d
            .packets
            .iter()
            .find(|p| p.seq as usize == i)
            .map(|p| &p.record);
        if got != Some(r) {
            return match r {
                Record::Blink(b) => b.t_drop,
                Record::Dropped(x) => x.plane,
                Record::End(e) => e.planes,
                _ => 0,
            };
        }
    }
    0
}

/// Pipe words of planes: 32 pixels a word, pixel i of the stream in bit i.
pub fn pipe_words(planes: &[BitPlane]) -> Vec<u32> {
    let mut words = Vec::new();
    let mut acc = 0u32;
    let mut n = 0;
    for p in planes {
        for b in p.bits().iter().by_vals() {
            acc |= (b as u32) << n;
            n += 1;
            if n == 32 {
                words.push(acc);
                acc = 0;
                n = 0;
            }
        }
    }
    if n > 0 {
        words.push(acc);
    }
    words
}

/// Stream word `idx` (P pixels) of a plane.
fn stream_word(plane: &BitPlane, p: usize, idx: usize) -> u64 {
    let bits = plane.bits();
    let mut w = 0u64;
    for i in 0..p {
        if bits[idx * p + i] {
            w |= 1 << i;
        }
    }
    w
}

/// Expected stage outputs of one plane (model).
struct ExpPlane {
    live: BitPlane,
    delayed: BitPlane,
    counts: Vec<u32>,
    filtered: Vec<u32>,
    cand: Vec<bool>,
}

/// The model's stages, advanced plane by plane as the probes need them.
struct Expect {
    model: smartagg_model::pipeline::Pipeline,
    mask: Option<HotPixelMask>,
    planes: Vec<BitPlane>,
    n: u64,
    cache: BTreeMap<u64, ExpPlane>,
    masked: VecDeque<BitPlane>,
    next: u64,
}

impl Expect {
    fn get(&mut self, t: u64) -> Option<&ExpPlane> {
        if t as usize >= self.planes.len() {
            return None;
        }
        while self.next <= t {
            let i = self.next as usize;
            let live = match &self.mask {
                Some(m) => m.apply(&self.planes[i]),
                None => self.planes[i].clone(),
            };
            let (w, h) = (live.width(), live.height());
            self.masked.push_back(live.clone());
            let delayed = if self.masked.len() as u64 > self.n {
                self.masked
                    .pop_front()
                    .unwrap_or_else(|| BitPlane::zeros(w, h))
            } else {
                BitPlane::zeros(w, h)
            };
            self.model.push_plane(&self.planes[i]).ok()?;
            let mut cand = vec![false; w * h];
            for c in self.model.candidates() {
                cand[c.y as usize * w + c.x as usize] = true;
            }
            self.cache.insert(
                self.next,
                ExpPlane {
                    live,
                    delayed,
                    counts: self.model.counts().to_vec(),
                    filtered: self.model.filtered().to_vec(),
                    cand,
                },
            );
            self.next += 1;
            // Keep a few planes: the stages lag each other by less than one.
            while self.cache.len() > 4 {
                let k = *self.cache.keys().next().unwrap_or(&0);
                self.cache.remove(&k);
            }
        }
        self.cache.get(&t)
    }
}

/// Probe ports of one stage and how many words it has put out.
struct StageProbe {
    stage: Stage,
    valid: usize,
    flush: usize,
    data: usize,
    words: u64,
    first: Option<StageMismatch>,
}

/// Stage probes of a debug build, compared with the model as words come out.
struct Probes {
    stages: Vec<StageProbe>,
    expect: Expect,
    threshold: u32,
    wpp: usize,
    width: usize,
    cw: usize,
    hw: usize,
}

impl Probes {
    fn new(m: &Model, cosim: &Cosim, case: &Case) -> Result<Probes, HarnessError> {
        let b = m.build();
        let port = |n: &str| b.port(n).map_err(|e| HarnessError::Design(e.into()));
        let mut stages = Vec::new();
        for (stage, tag, data) in [
            (Stage::MaskAndDelayLive, "d", "d_live"),
            (Stage::DelayLine, "d", "d_delayed"),
            (Stage::RollingCount, "c", "c_counts"),
            (Stage::SpatialFilter, "f", "f_h"),
            (Stage::Threshold, "k", "k_above"),
            (Stage::Candidates, "k", "k_cand"),
        ] {
            stages.push(StageProbe {
                stage,
                valid: port(&format!("{tag}_valid"))?,
                flush: port(&format!("{tag}_flush"))?,
                data: port(data)?,
                words: 0,
                first: None,
            });
        }
        let cfg = cosim.model_config(case)?;
        let f = cosim.spec.front()?;
        Ok(Probes {
            stages,
            expect: Expect {
                model: smartagg_model::pipeline::Pipeline::new(cfg.clone())
                    .map_err(|e| HarnessError::Model(e.to_string()))?,
                mask: cfg.hot_mask.clone(),
                planes: case.planes.clone(),
                n: case.n as u64,
                cache: BTreeMap::new(),
                masked: VecDeque::new(),
                next: 0,
            },
            threshold: case.hold(),
            wpp: f.words_per_plane(),
            width: f.width,
            cw: f.count_bits(),
            hw: f.filtered_bits(),
        })
    }

    /// Samples every probe for this clock (before the edge).
    fn sample(&mut self, m: &mut Model) {
        let p = crate::designs::P;
        for s in &mut self.stages {
            if s.first.is_some() {
                continue;
            }
            if m.get(s.valid) == 0 || m.get(s.flush) != 0 {
                continue;
            }
            let t = s.words / self.wpp as u64;
            let idx = (s.words % self.wpp as u64) as usize;
            s.words += 1;
            let words = m.get_words(s.data);
            let Some(e) = self.expect.get(t) else {
                continue;
            };
            let lane_bits = match s.stage {
                Stage::RollingCount => self.cw,
                Stage::SpatialFilter => self.hw,
                _ => 1,
            };
            let got: Vec<u64> = (0..p)
                .map(|i| extract(&words, i * lane_bits, lane_bits))
                .collect();
            let want: Vec<u64> = (0..p)
                .map(|i| {
                    let px = idx * p + i;
                    let (x, y) = (px % self.width, px / self.width);
                    match s.stage {
                        Stage::MaskAndDelayLive => e.live.get(x, y) as u64,
                        Stage::DelayLine => e.delayed.get(x, y) as u64,
                        Stage::RollingCount => e.counts[px] as u64,
                        Stage::SpatialFilter => e.filtered[px] as u64,
                        Stage::Threshold => (e.filtered[px] >= self.threshold) as u64,
                        Stage::Candidates => e.cand[px] as u64,
                        Stage::BackHalf => 0,
                    }
                })
                .collect();
            if got != want {
                s.first = Some(StageMismatch {
                    stage: s.stage,
                    plane: t,
                    word: idx,
                    cycle: m.cycles,
                    got,
                    want,
                });
            }
        }
    }

    fn mismatches(&self) -> Vec<StageMismatch> {
        self.stages.iter().filter_map(|s| s.first.clone()).collect()
    }
}

/// Bits `at .. at + n` of little-endian 32-bit words.
fn extract(words: &[u32], at: usize, n: usize) -> u64 {
    let mut v = 0u64;
    for k in 0..n {
        let b = at + k;
        if (words[b / 32] >> (b % 32)) & 1 != 0 {
            v |= 1 << k;
        }
    }
    v
}

/// Input shadow: sets a port only when its value changes.
struct Shadow {
    vals: Vec<Option<u64>>,
}

impl Shadow {
    fn set(&mut self, m: &mut Model, i: usize, v: u64) {
        if self.vals[i] != Some(v) {
            m.set(i, v);
            self.vals[i] = Some(v);
        }
    }
}

/// The VCD window of a run.
struct Vcd {
    path: PathBuf,
    from: u64,
    to: u64,
    open: bool,
}

impl Vcd {
    fn step(&mut self, m: &mut Model) {
        if !self.open && m.cycles >= self.from && m.cycles < self.to {
            self.open = m.trace_open(&self.path);
        } else if self.open && m.cycles >= self.to {
            m.trace_close();
            self.open = false;
        }
    }
}

/// Drives the XEM6310 core as the host does through FrontPanel.
struct XemHost {
    m: Model,
    sh: Shadow,
    rng: ChaCha8Rng,
    p: XemPorts,
    read: Vec<u8>,
    pending: usize,
    issued: bool,
    probes: Option<Probes>,
    vcd: Option<Vcd>,
    sensor: VecDeque<u64>,
    sensor_interval: u32,
    read_stall: u32,
    hold_reads: bool,
    limit: u64,
    /// Set bits of the words written to the mask pipe-in.
    mask_loaded: u32,
}

struct XemPorts {
    wire_in: Vec<usize>,
    trigger: usize,
    replay_write: usize,
    replay_data: usize,
    replay_ready: usize,
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

fn vcd_of(vcd: Option<(&Path, u64, u64)>) -> Option<Vcd> {
    vcd.map(|(p, from, to)| Vcd {
        path: p.to_path_buf(),
        from,
        to,
        open: false,
    })
}

impl XemHost {
    fn new(
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

    fn clock(&mut self) {
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

    fn wire_out(&mut self, addr: u8) -> u32 {
        let i = self.p.wire_out[(addr - wire_out::STATUS) as usize];
        self.m.get(i) as u32
    }

    fn trigger(&mut self, bit: u8) {
        let t = self.p.trigger;
        self.sh.set(&mut self.m, t, 1 << bit);
        self.clock();
    }

    /// Reads one 16-byte block if the pipe-out offers one and the host is not stalled.
    fn read_blocks(&mut self, ended: bool) {
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

    fn write_pipe(&mut self, mask: bool, words: &[u32], stall: u32) -> Result<(), HarnessError> {
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
    fn run(
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
                self.write_pipe(false, &pipe_words(&case.planes), case.input_stall)?;
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
    fn fault_source(&mut self) -> String {
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
                let word = stream_word(&case.planes[t], p, idx) | ((idx == 0) as u64) << p;
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

/// The model configuration of a case on a design: the design's kernel,
/// slots, ROI side and r_assoc, the case's registers and hot-pixel mask.
pub fn model_config(spec: &DesignSpec, case: &Case) -> Result<PipelineConfig, HarnessError> {
    let back = spec.back()?;
    let f = &back.front;
    let mut cfg = PipelineConfig::new(
        f.width,
        f.height,
        case.n,
        f.kernel.clone(),
        f.kernel_shift,
        case.threshold,
    );
    cfg.threshold_hold = case.hold();
    cfg.end_trim = case.end_trim;
    cfg.slots = back.slots;
    cfg.roi_size = back.roi_size;
    cfg.r_assoc = back.r_assoc;
    cfg.l_min = case.l_min;
    cfg.l_max = case.l_max;
    cfg.plane_period_ns = PLANE_PERIOD_NS;
    if case.mask_enable {
        cfg.hot_mask = Some(HotPixelMask::from_pixels(f.width, f.height, &case.hot).0);
    }
    cfg.validate()
        .map_err(|e| HarnessError::Model(e.to_string()))?;
    Ok(cfg)
}

/// The registers the host writes for a case on a design
/// ([`StreamRegisters::of`] of [`model_config`], the host's own code),
/// planes from the replay pipe-in or the sensor port as the case says.
pub fn stream_registers(spec: &DesignSpec, case: &Case) -> Result<StreamRegisters, HarnessError> {
    Ok(StreamRegisters {
        source_replay: case.source == Source::Replay,
        ..StreamRegisters::of(&model_config(spec, case)?)
    })
}

/// Pipe-in bytes as 32-bit little-endian words in whole 16-byte blocks
/// (the end zero-padded), as the block-throttled pipe-ins take them.
pub fn block_words(bytes: &[u8]) -> Vec<u32> {
    let mut words: Vec<u32> = bytes
        .chunks(4)
        .map(|c| {
            let mut b = [0u8; 4];
            b[..c.len()].copy_from_slice(c);
            u32::from_le_bytes(b)
        })
        .collect();
    words.resize(words.len().div_ceil(4) * 4, 0);
    words
}

/// The packet bytes without the pipe-out's end padding: the shortest
/// prefix (at most 15 zero bytes removed) that decodes cleanly to a stream
/// ending with StreamEnd.
pub fn strip_padding(read: &[u8]) -> Vec<u8> {
    let zeros = read.iter().rev().take(15).take_while(|&&b| b == 0).count();
    for k in (0..=zeros).rev() {
        let cand = &read[..read.len() - k];
        let d = decode_all(cand);
        let s = &d.stats;
        if s.crc_errors + s.malformed + s.bytes_skipped + s.truncated_tail_bytes == 0
            && matches!(d.packets.last().map(|p| &p.record), Some(Record::End(_)))
        {
            return cand.to_vec();
        }
    }
    read.to_vec()
}

/// Drives the block-RAM pipeline directly (projected SPCImager).
struct BramHost {
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
    fn new(
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
    fn run(
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
            let word = stream_word(&mask_plane, p, idx);
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
                    ("reg_mask_enable", mask_enable as u32)
                }
                wire_in::N_WINDOW => ("reg_n", v),
                wire_in::THRESHOLD_INT => ("reg_threshold", v),
                wire_in::THRESHOLD_HOLD => ("reg_threshold_hold", v),
                wire_in::END_TRIM => ("reg_end_trim", v),
                wire_in::L_MIN => ("reg_l_min", v),
                wire_in::L_MAX => ("reg_l_max", v),
                wire_in::PLANE_PERIOD_NS => ("reg_period", v),
                wire_in::MASKED_PIXELS => ("reg_masked", v),
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
                    .set(&mut self.m, in_live, stream_word(&case.planes[t], p, idx));
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

/// A threshold T_int at quantile `q` (0..1) of the model's H over the
/// planes (ignoring zeros): the cases' way to put the threshold where some
/// but few pixels cross it, whatever the scene's density.
pub fn threshold_at_quantile(cfg: &PipelineConfig, planes: &[BitPlane], q: f64) -> u32 {
    let Ok(mut p) = smartagg_model::pipeline::Pipeline::new(cfg.clone()) else {
        return 1;
    };
    let mut hist: BTreeMap<u32, u64> = BTreeMap::new();
    let mut total = 0u64;
    for pl in planes {
        if p.push_plane(pl).is_err() {
            break;
        }
        for &h in p.filtered() {
            if h > 0 {
                *hist.entry(h).or_default() += 1;
                total += 1;
            }
        }
    }
    let target = (total as f64 * q.clamp(0.0, 1.0)) as u64;
    let mut acc = 0;
    for (&h, &n) in &hist {
        acc += n;
        if acc > target {
            return h.max(1);
        }
    }
    hist.keys().next_back().copied().unwrap_or(1).max(1)
}

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
        self.replay.extend(pipe_words(planes));
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

#[cfg(test)]
mod tests {
    use super::*;
    use smartagg_model::config::PipelineConfig;
    use smartagg_model::packet::{crc32c, encode_record, BLINK_FIXED_LEN, HEADER_LEN};
    use smartagg_model::record::OverflowRecord;

    /// A model stream with a few Blinks: its records and bytes.
    fn stream() -> (Vec<Record>, Vec<u8>) {
        let cfg = PipelineConfig::new(24, 12, 3, vec![1, 2, 1], 2, 8);
        let planes = (0..60).map(|t| {
            BitPlane::from_fn(24, 12, |x, y| {
                (t % 12 < 6 && x == 4 + t / 12 * 3 && y == 5) || (t % 12 >= 6 && x == 18 && y == 6)
            })
        });
        let records = smartagg_model::pipeline::run(cfg, planes).unwrap();
        assert!(
            records
                .iter()
                .filter(|r| matches!(r, Record::Blink(_)))
                .count()
                >= 4
        );
        let bytes = encode_stream(&records);
        (records, bytes)
    }

    fn encode_stream(records: &[Record]) -> Vec<u8> {
        smartagg_model::packetiser::encode_stream(records).unwrap()
    }

    /// The packets of `records` (numbered from 0) with records `lost` left
    /// out and announced by one Overflow record; `replace` swaps in other
    /// bytes for the packet of one sequence number.
    fn lossy(
        records: &[Record],
        lost: std::ops::Range<u32>,
        replace: Option<(u32, Vec<u8>)>,
    ) -> Vec<u8> {
        let mut out = Vec::new();
        for (i, r) in records.iter().enumerate() {
            let seq = i as u32;
            if seq == lost.start && !lost.is_empty() {
                let o = Record::Overflow(OverflowRecord {
                    first_seq: lost.start,
                    count: lost.len() as u32,
                });
                encode_record(&o, lost.start, &mut out).unwrap();
            }
            if lost.contains(&seq) {
                continue;
            }
            match &replace {
                Some((s, b)) if *s == seq => out.extend_from_slice(b),
                _ => encode_record(r, seq, &mut out).unwrap(),
            }
        }
        out
    }

    /// A packet re-framed around another payload (length and CRC fixed).
    fn reframe(packet: &[u8], payload: &[u8]) -> Vec<u8> {
        let mut p = packet[..HEADER_LEN].to_vec();
        p[8..10].copy_from_slice(&(payload.len() as u16).to_le_bytes());
        p.extend_from_slice(payload);
        let crc = crc32c(&p);
        p.extend_from_slice(&crc.to_le_bytes());
        p
    }

    /// A Rice count block with parameter `k` (PACKETS.md §4).
    fn rice_block(counts: &[u32], k: u8) -> Vec<u8> {
        let base = *counts.iter().min().unwrap();
        let mut out = Vec::new();
        let mut v = base;
        loop {
            let g = (v & 0x7f) as u8;
            v >>= 7;
            if v == 0 {
                out.push(g);
                break;
            }
            out.push(g | 0x80);
        }
        out.push(k);
        let mut bits = Vec::new();
        for &c in counts {
            let d = c - base;
            let q = d >> k;
            assert!(q < 32, "test counts stay below the escape");
            bits.extend(std::iter::repeat_n(true, q as usize));
            bits.push(false);
            bits.extend((0..k).rev().map(|i| d >> i & 1 != 0));
        }
        for chunk in bits.chunks(8) {
            let mut b = 0u8;
            for (i, &bit) in chunk.iter().enumerate() {
                b |= (bit as u8) << (7 - i);
            }
            out.push(b);
        }
        out
    }

    #[test]
    fn compare_lossy_takes_announced_losses_and_refuses_unannounced_ones() {
        let (records, want) = stream();
        let n = records.len() as u32;
        assert_eq!(compare_lossy(&lossy(&records, 2..4, None), &want), Ok(2));
        // Losses just before StreamEnd.
        assert_eq!(
            compare_lossy(&lossy(&records, n - 3..n - 1, None), &want),
            Ok(2)
        );
        // A gap with no Overflow record, a miscounted one, none at all.
        let mut silent = Vec::new();
        for (i, r) in records.iter().enumerate() {
            if i != 2 {
                encode_record(r, i as u32, &mut silent).unwrap();
            }
        }
        assert!(compare_lossy(&silent, &want).is_err());
        assert_eq!(compare_lossy(&lossy(&records, 2..5, None), &want), Ok(3));
        let mut miscounted = Vec::new();
        for (i, r) in records.iter().enumerate() {
            if i == 2 {
                let o = Record::Overflow(OverflowRecord {
                    first_seq: 2,
                    count: 3,
                });
                encode_record(&o, 2, &mut miscounted).unwrap();
            }
            if i != 2 && i != 3 {
                encode_record(r, i as u32, &mut miscounted).unwrap();
            }
        }
        assert!(compare_lossy(&miscounted, &want).is_err());
        assert!(
            compare_lossy(&want, &want).is_err(),
            "no loss is not a lossy stream"
        );
    }

    /// A surviving packet whose bytes differ from the model's but still
    /// decode with a valid CRC is refused: the same counts Rice-coded with
    /// another parameter (decoding to the very same record, so a comparison
    /// of records would pass it), and a count changed and re-encoded.
    #[test]
    fn compare_lossy_refuses_a_reencoded_packet_that_still_decodes() {
        let (records, want) = stream();
        let packets = split_packets(&want).unwrap();
        let (i, b) = records
            .iter()
            .enumerate()
            .find_map(|(i, r)| match r {
                Record::Blink(b) if i > 4 => Some((i, b.clone())),
                _ => None,
            })
            .expect("a Blink after the loss");
        let model = packets[i].bytes;
        let fixed = &model[HEADER_LEN..HEADER_LEN + BLINK_FIXED_LEN];
        let base = *b.counts.iter().min().unwrap();
        let k = model[HEADER_LEN + BLINK_FIXED_LEN + smartagg_model::rice::varint_len(base)];
        assert_eq!(
            k,
            smartagg_model::rice::choose(&b.counts).1,
            "the model's k"
        );
        // Another Rice parameter: the same record, other bytes.
        let mut payload = fixed.to_vec();
        payload.extend(rice_block(&b.counts, k + 1));
        let recoded = reframe(model, &payload);
        assert_ne!(recoded, model);
        let back = smartagg_model::packet::decode_frame(&recoded).expect("it decodes");
        assert_eq!(back.record, records[i], "the same record");
        assert_eq!(compare_lossy(&lossy(&records, 1..3, None), &want), Ok(2));
        let err = compare_lossy(&lossy(&records, 1..3, Some((i as u32, recoded))), &want)
            .expect_err("a re-encoded packet must be refused");
        assert!(err.contains(&format!("seq {i}")), "{err}");
        // A count changed: another record, a valid packet.
        let mut other = b.clone();
        other.counts[0] += 1;
        let mut changed = Vec::new();
        encode_record(&Record::Blink(other), i as u32, &mut changed).unwrap();
        assert!(smartagg_model::packet::decode_frame(&changed).is_ok());
        assert!(compare_lossy(&lossy(&records, 1..3, Some((i as u32, changed))), &want).is_err());
    }

    #[test]
    fn delivered_coverage_counts_records_flags_and_wraps() {
        let (records, _) = stream();
        let mut bytes = Vec::new();
        let mut enc = Encoder::starting_at(u32::MAX - 2);
        for r in &records {
            enc.push(r, &mut bytes).unwrap();
        }
        let packets = split_packets(&bytes).unwrap();
        let c = delivered_coverage(&packets);
        assert_eq!((c.start_records, c.end_records, c.seq_wraps), (1, 1, 1));
        assert_eq!(
            c.blink_records as usize,
            records
                .iter()
                .filter(|r| matches!(r, Record::Blink(_)))
                .count()
        );
        let plain = delivered_coverage(&split_packets(&want_of(&records)).unwrap());
        assert_eq!(plain.seq_wraps, 0);
        // An Overflow whose range crosses the wrap.
        let mut ovf = Vec::new();
        encode_record(&records[0], u32::MAX - 1, &mut ovf).unwrap();
        let o = Record::Overflow(OverflowRecord {
            first_seq: u32::MAX,
            count: 3,
        });
        encode_record(&o, u32::MAX, &mut ovf).unwrap();
        encode_record(records.last().unwrap(), 2, &mut ovf).unwrap();
        let c = delivered_coverage(&split_packets(&ovf).unwrap());
        assert_eq!((c.overflow_records, c.seq_wraps), (1, 1));
    }

    fn want_of(records: &[Record]) -> Vec<u8> {
        encode_stream(records)
    }
}
