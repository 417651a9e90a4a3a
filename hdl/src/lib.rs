//! # smartagg-hdl — gateware of the smart-aggregation pipeline (rust-hdl 0.46)
//!
//! The whole smart-aggregation pipeline as rust-hdl blocks, each in the file
//! named like its twin in `model/src/` and simulated against that model stage
//! bit for bit (`hdl/tests/`): the streaming front half — hot-pixel mask,
//! delay line (block RAM, or DDR2 for large N: [`delay_line_ddr`], with its
//! write and read sides), rolling count, spatial filter, threshold and
//! candidates ([`front_half`]) — and the
//! back half — blink tracker, ROI aggregator and packetiser, which writes the
//! packet stream of `model/PACKETS.md` ([`pipeline`]); the XEM6310 top with
//! its register map ([`xem6310`], [`registers`]); Verilog generation,
//! Verilator lint and a yosys Spartan-6 resource report ([`synth`]). The whole
//! pipeline is co-simulated byte for byte against the golden model in
//! Verilator (`sim/`).
//!
//! ## Stream and throughput
//! Pixels arrive in raster order, P per clock, with `valid` (stalls allowed at
//! any clock), `sop` (first word of a plane) and `flush` (see [`stream`]).
//! The core runs on the FrontPanel host-interface clock, 100.8 MHz, with
//! **P = 16**: a 320×240 plane is 4,800 words, 10,000 planes/s need
//! 48.0 Mword/s = 47.6 % of the clock, leaving 52 % for DDR2 refresh, host
//! stalls and the delay line's DDR2 traffic (≥ 25 % required; P = 8 would
//! leave 5 %). The pipeline itself never inserts a bubble: one word in per
//! clock sustained, so the figure above is also its cycles per plane.
//!
//! ## Front-half blocks (order of work of `model/src/pipeline.rs`, stages 0–4)
//! * [`hot_pixel_mask::HotPixelMask`]: `B AND NOT mask`, the mask a W·H-bit
//!   memory loaded before the stream;
//! * [`delay_line::DelayLine`]: block-RAM ring of N_max planes, runtime N,
//!   zero for t < N (a saturating plane count), read-first `B_{t−N}` beside
//!   `B_t`; numbers the words (column, row, index);
//! * [`rolling_count::RollingCount`]: W·H counters in block RAM, one memory
//!   per lane, read-modify-write `S += b_new − b_old`;
//! * [`spatial_filter::SpatialFilter`]: vertical pass first (k − 1 line
//!   buffers of counts), then horizontal; pre-added symmetric taps and
//!   constant multipliers ([`const_mul::ConstMul`]: shift-and-add over
//!   signed digits or, for the costliest, the device's DSP48A1 slices);
//!   zero padding on all four edges;
//! * [`threshold::Threshold`] and [`candidates::Candidates`]: `H ≥ T_hold`
//!   (the tracker's on/off bits), and `H ≥ T_int` with the 3×3 maximum and
//!   the model's raster tie rule (candidates), two line buffers of H;
//! * [`front_half`]: the chain, its configurations and its Verilog.
//!
//! ## Back-half blocks (stages 5–7) and the whole pipeline
//! * [`back_half::BackHalf`]: the blink tracker ([`blink_tracker`], with
//!   its sequencer, item stage, compare stage (with the opening windows and
//!   the slot compare), association, slots' flags (with the on/off step),
//!   slots' words, counters, walk pipeline (with the read multiplexer, walk
//!   memory, walk stages and walk step), walk gate and record port),
//!   the ROI aggregator ([`roi_aggregator`], with its row cover, lowest
//!   slot, view multiplexer and ROI row) and its bank pool
//!   ([`bank_pool`]), the
//!   record queue and finisher ([`record_queue::RecordQueue`],
//!   [`record_finisher::RecordFinisher`], sub-blocks of the packetiser
//!   stage), the packetiser ([`packetiser`], with its count streamer,
//!   Rice choice, code pipeline and Rice code, bit packer, record prefix, prefix bytes,
//!   count-block head, prefix cursor, CRC step and packet CRC, packet length
//!   and sequence numbers) and
//!   the output FIFO;
//! * [`stream_control::StreamControl`]: START's register check and latch,
//!   the source gated at plane boundaries, the drain and flush planes after
//!   STOP;
//! * [`pipeline`]: stream control, hot-pixel mask, delay line, front half
//!   and back half, with its configurations ([`pipeline::Pipeline`] and
//!   [`pipeline::PipelineDdr`], one text for the two delay lines);
//! * [`designs`]: the shipped designs, one per (preset, objective);
//!   [`ise`]: each one's ISE 14.7 project script;
//! * [`xem6310_core`]: the register map, the pipeline and the replay, mask
//!   and packet pipes between the FrontPanel endpoints (what the
//!   co-simulation drives); [`xem6310`]: the XEM6310 top around it, with the
//!   FrontPanel endpoints as black boxes ([`frontpanel`]) and the DDR2
//!   controller as a black box or the DDR2 pins parked ([`mig_ddr2`]).
//!
//! Widths are const generics checked against [`config::GatewareConfig`].
//! Ports that travel together from block to block are bundles declared
//! once in [`bundles`].

pub mod back_half;
pub mod bank_pool;
pub mod blink_tracker;
pub mod bram;
pub mod bundles;
pub mod candidates;
pub mod config;
pub mod const_mul;
pub mod delay_line;
pub mod delay_line_ddr;
pub mod designs;
pub mod device;
pub mod fifo;
pub mod front_half;
pub mod frontpanel;
pub mod hot_pixel_mask;
pub mod ise;
pub mod lint_waivers;
pub mod lut_levels;
pub mod mig_ddr2;
pub mod packetiser;
pub mod pipeline;
pub mod record_finisher;
pub mod record_queue;
pub mod registers;
pub mod roi_aggregator;
pub mod rolling_count;
pub mod schedule;
pub mod spatial_filter;
pub mod stream;
pub mod stream_control;
pub mod synth;
pub mod testbench;
pub mod threshold;
pub mod xem6310;
pub mod xem6310_core;

/// The model crate this gateware mirrors.
pub use smartagg_model as model;
