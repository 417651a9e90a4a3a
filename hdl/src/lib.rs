//! Gateware of the smart-aggregation pipeline (rust-hdl, XEM6310).
//!
//! Not built yet: the blocks arrive with the gateware issue. Each stage will
//! live in the file named like its twin in `model/src/`.

/// The model crate this gateware mirrors.
pub use smartagg_model as model;
