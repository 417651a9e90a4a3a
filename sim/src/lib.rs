//! # smartagg-sim — Verilator co-simulation of the generated gateware
//!
//! The Verilog that `smartagg-hdl` generates (the same text that yosys
//! synthesises) is verilated ([`verilator`]), driven from Rust through the
//! XEM6310 core's FrontPanel endpoint ports (replay pipe-in, mask pipe-in,
//! packet pipe-out with host stalls, wire-ins, triggers) or its sensor port,
//! with a behavioural DDR2 controller ([`ddr2`]) verilated beside it for a
//! DDR2 design and the MCB port parked for a block-RAM one (the demo's
//! pipeline alone is driven through its word port, paced by its `ready`),
//! and its packet bytes compared with the golden model's ([`harness`]).
//! Every configuration that `smartagg hdl generate` ships runs this way, on
//! its full field (`tests/full_field.rs`, in CI) or on any smaller field of
//! its sensor, generated and verilated on demand ([`designs::DesignSpec`];
//! `smartagg cosim --width W --height H`). On a
//! mismatch a debug build with probes on every stage names the first stage
//! and bit-plane that differ and writes a VCD around it.
//!
//! How the simulation got fast, today's cycles per second and the
//! history of each measurement: `docs/COSIM.md`.
//!
//! ## A second, 4-state simulator
//!
//! Verilator is 2-state: a memory word never written reads as some value.
//! [`icarus`] runs the reduced 64×32 SPCImager 150× XEM6310 core with its
//! DDR2 model under Icarus Verilog from power-up, every memory (block and
//! LUT RAMs, the DDR2 model's words) X until written, the flip-flops at
//! their configuration values, and a host script played by a Verilog
//! testbench (RESET, mask, wire-ins, START, replay, STOP, pipe-out reads).
//! Its test (`cargo test -p smartagg-sim --test icarus`; needs `iverilog`,
//! which `scripts/setup.sh` installs) requires the packet bytes of 300
//! planes with masked hot pixels to have no X bit and to equal the model's,
//! and checks that a never-written word reaching the packets is reported as
//! X. ≈ 80,000 clocks at ≈ 420 clocks/s: ≈ 3.2 min on this machine.

pub mod ddr2;
pub mod designs;
pub mod harness;
pub mod icarus;
pub mod scene;
pub mod verilator;

/// The gateware crate under test.
pub use smartagg_hdl as hdl;
