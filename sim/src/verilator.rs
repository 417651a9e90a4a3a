//! A thin binding of Verilator: Verilog text in, a loaded shared library out.
//!
//! [`Build::get`] writes the Verilog to a cache directory keyed by a hash of
//! the text and the build options (`target/verilator-cache/<hash>/`, or
//! `$SMARTAGG_VERILATOR_CACHE/<hash>/`), runs `verilator --cc --exe --build`
//! on it together with a C++ shim generated from the top module's port list,
//! links the lot into `libcosim.so` and loads it with `libloading`. The
//! same text with the same options is verilated once: later calls (in this
//! process or the next) load the cached library.
//!
//! The shim is generic over the top's ports: port `i` of the parsed
//! [`Port`] table is set and read as little-endian 32-bit words
//! (`sa_set(h, i, words)`, `sa_get(h, i, words)`), whatever its width.

mod build;
mod ico;
mod model;
mod ports;
mod shim;

pub use build::{text_hash, Build, BuildOptions, Training};
pub use model::{Counters, Model};
pub use ports::{declared_ports, parse_ports, Dir, Port};

use std::path::PathBuf;

/// Errors of building or loading a Verilated model.
#[derive(Debug, thiserror::Error)]
pub enum VerilatorError {
    /// A tool could not be started.
    #[error("cannot run `{tool}` (is it installed?): {source}")]
    Spawn {
        /// The tool.
        tool: String,
        /// Why.
        source: std::io::Error,
    },
    /// A tool ran and failed.
    #[error("`{tool}` failed in {dir}:\n{log}")]
    Failed {
        /// The tool.
        tool: String,
        /// Its working directory.
        dir: PathBuf,
        /// The tail of its output.
        log: String,
    },
    /// The cache directory could not be written.
    #[error("cache directory {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The Verilog has no module of that name, or a port the shim cannot handle.
    #[error("Verilog: {0}")]
    Verilog(String),
    /// The shared library could not be loaded.
    #[error("loading {path}: {source}")]
    Load {
        /// The library.
        path: PathBuf,
        /// Why.
        source: libloading::Error,
    },
    /// No port of that name.
    #[error("the Verilated top has no port `{0}`")]
    NoPort(String),
}
