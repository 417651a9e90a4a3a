//! End-to-end tests across the crates live in `tests/tests/` (this library is
//! empty): `end_to_end.rs` runs a simulated molecule through the golden
//! pipeline, the packets, the host's decoder and the localiser.
