//! Not gateware: what the block tests simulate the gateware with. The
//! clock-stepping [`bench`](mod@bench) over rust-hdl's simulation engine, and the
//! behavioural DDR2 memory behind the MCB user port ([`mcb_model`]), which
//! the hardware replaces with the MIG core. Nothing here is written to the
//! generated Verilog of a shipped design.

pub mod bench;
pub mod mcb_model;
