//! Gateware of the smart-aggregation pipeline (rust-hdl, XEM6310): phase 1,
//! the streaming front half — delay line, rolling count, spatial filter,
//! threshold and candidates. Each stage lives in the file named like its
//! twin in `model/src/` and equals it bit for bit (tests in `hdl/tests/`).

pub mod bram;
pub mod candidates;
pub mod config;
pub mod delay_line;
pub mod front_half;
pub mod rolling_count;
pub mod sim;
pub mod spatial_filter;
pub mod stream;
pub mod synth;
pub mod threshold;

/// The model crate this gateware mirrors.
pub use smartagg_model as model;
