//! Verilator co-simulation of the generated gateware against the golden model.
//!
//! Not built yet: arrives with the co-simulation issue.

/// The gateware crate under test.
pub use smartagg_hdl as hdl;
