//! `--source cosim:PRESET`: the Verilated gateware played as if it were the
//! board.
//!
//! The co-simulation harness belongs to the `sim` crate (smartagg-sim), which
//! does not build the gateware model yet. When it does, its source implements
//! [`super::PacketSource`]: `configure` goes through
//! [`super::registers::configure`] on a [`super::registers::RegisterBus`]
//! backed by the simulated okHost endpoints, `start`/`stop` pulse the same
//! triggers, and `read` steps the simulation until the pipe-out FIFO holds
//! bytes or the wait is used up. Until then [`open`] says so.

use super::{PacketSource, TransportError};

/// Opens the co-simulation source for a scene preset.
pub fn open(preset: &str) -> Result<Box<dyn PacketSource>, TransportError> {
    Err(TransportError::Unavailable(format!(
        "co-simulation source `cosim:{preset}`: the sim crate (smartagg-sim) does not provide the Verilated gateware yet; use --source file:PATH with a stream from `smartagg aggregate` meanwhile"
    )))
}

#[cfg(test)]
mod tests {
    #[test]
    fn says_the_sim_crate_does_not_provide_it_yet() {
        let e = super::open("spcimager").err().unwrap().to_string();
        assert!(
            e.contains("cosim:spcimager") && e.contains("smartagg-sim"),
            "{e}"
        );
    }
}
