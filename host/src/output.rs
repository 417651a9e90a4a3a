//! The host's anyhow face of [`smartagg_io::output`], for the commands whose
//! helpers return `anyhow::Result` directly (`hdl`). Everything else uses
//! `smartagg_io::output` itself.

use std::path::Path;

/// Writes `bytes` to `target` atomically
/// ([`smartagg_io::output::write_atomic`]).
pub fn write_atomic(target: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    Ok(smartagg_io::output::write_atomic(target, bytes)?)
}
