//! # smartagg-sim — Verilator co-simulation of the generated gateware
//!
//! The Verilog that `smartagg-hdl` generates (the same text that yosys
//! synthesises) is verilated ([`verilator`]), driven from Rust through the
//! XEM6310 core's FrontPanel endpoint ports (replay pipe-in, mask pipe-in,
//! packet pipe-out with host stalls, wire-ins, triggers) or its sensor port,
//! with a behavioural DDR2 controller ([`ddr2`]) verilated beside it, and its
//! packet bytes compared with the golden model's ([`harness`]). On a
//! mismatch a debug build with probes on every stage names the first stage
//! and bit-plane that differ and writes a VCD around it.

pub mod ddr2;
pub mod designs;
pub mod harness;
pub mod scene;
pub mod verilator;

/// The gateware crate under test.
pub use smartagg_hdl as hdl;
