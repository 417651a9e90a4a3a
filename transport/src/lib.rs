//! `smartagg-transport`: where the blink-ROI packet stream comes from — a
//! board, a recorded file or the co-simulated gateware — and the download
//! loop that turns any of them into a `.rois` file (`smartagg download`).
//!
//! Every source implements [`PacketSource`]: configure the device from a
//! preset, start, read chunks of bytes with a time limit, stop. The
//! device-independent work (writing the raw stream to disk, decoding,
//! counting losses, stall detection, progress) lives in [`download`], which
//! drives any source the same way.
//!
//! | `--source`      | type                              | notes |
//! |-----------------|-----------------------------------|-------|
//! | `frontpanel`    | [`frontpanel::FrontPanelSource`]  | stock XEM6310: Opal Kelly's `libokFrontPanel`, loaded at run time |
//! | `usb`           | [`usb::UsbSource`]                | firmware with the stream on a bulk endpoint (`rusb`) |
//! | `file:PATH`     | [`file::FileSource`]              | a recorded `.rois` stream (or a named pipe), optionally rate-limited |
//! | `cosim:PRESET`  | [`cosim`]                         | the Verilated gateware played as if it were the board (sim crate) |
//!
//! The register map the device sources share is in [`registers`].
//!
//! Cargo features (all on by default): `usb` (the `usb` module, `rusb`),
//! `frontpanel` (the `frontpanel` module, `libloading`) and `cosim` (the
//! `cosim` module, `smartagg-sim`). The file source, the download loop and
//! the register map are always built.

#[cfg(feature = "cosim")]
pub mod cosim;
pub mod download;
pub mod file;
#[cfg(feature = "frontpanel")]
pub mod frontpanel;
#[cfg(test)]
mod fuzz_tests;
pub mod registers;
#[cfg(feature = "usb")]
pub mod usb;

use std::fmt;
use std::path::PathBuf;
use std::time::Duration;

pub use registers::DeviceConfig;

/// What one [`PacketSource::read`] produced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chunk {
    /// This many bytes were written to the start of the buffer (≥ 1).
    Data(usize),
    /// No byte arrived within the wait; the source may still deliver more.
    Idle,
    /// The source has nothing more to give (end of file, device finished).
    End,
}

/// A source of packet-stream bytes: a board, a file or a simulation.
///
/// Call order: [`configure`](PacketSource::configure) (devices only, see
/// [`PacketSource::is_device`]), [`start`](PacketSource::start), any number
/// of [`read`](PacketSource::read)s, [`stop`](PacketSource::stop) (which asks
/// the device to finish: it then sends the rest of the stream and its
/// StreamEnd record, so keep reading), and reads until the stream ends.
pub trait PacketSource {
    /// One line naming the source, for messages ("USB 151f:5341 endpoint 0x81").
    fn describe(&self) -> String;

    /// Whether this source is a device that takes a configuration (N, T_int,
    /// L_min, L_max, mask) and ends its stream with a StreamEnd record after
    /// [`PacketSource::stop`]. A recording carries its own configuration in
    /// its StreamStart records and may hold several concatenated streams.
    fn is_device(&self) -> bool {
        true
    }

    /// Checks that the device was generated for `cfg` and writes the runtime
    /// registers. Sources that are not devices accept any configuration.
    fn configure(&mut self, cfg: &DeviceConfig) -> Result<(), TransportError>;

    /// Starts the stream.
    fn start(&mut self) -> Result<(), TransportError>;

    /// Waits at most about `wait` for bytes and puts them at the start of `buf`.
    fn read(&mut self, buf: &mut [u8], wait: Duration) -> Result<Chunk, TransportError>;

    /// Asks the source to finish. A device completes its stream (StreamEnd);
    /// a file source ends at its next read.
    fn stop(&mut self) -> Result<(), TransportError>;
}

/// Why a transport failed; every message says what to do about it. The
/// FrontPanel and libusb variants exist with their features.
#[derive(Debug)]
pub enum TransportError {
    /// A `--source` value that does not parse.
    BadSource(String),
    /// The Opal Kelly FrontPanel library is not installed where we looked.
    #[cfg(feature = "frontpanel")]
    LibraryNotFound {
        /// Every path tried.
        looked_in: Vec<String>,
    },
    /// A library was found but could not be loaded.
    #[cfg(feature = "frontpanel")]
    LibraryLoad {
        /// Path or name.
        path: String,
        /// The loader's message.
        reason: String,
    },
    /// The library lacks a function we need.
    #[cfg(feature = "frontpanel")]
    MissingSymbol {
        /// Path or name of the library.
        path: String,
        /// Missing function.
        symbol: &'static str,
    },
    /// A FrontPanel call returned an error code.
    #[cfg(feature = "frontpanel")]
    FrontPanel {
        /// The call.
        call: &'static str,
        /// Its `ok_ErrorCode`.
        code: i32,
    },
    /// No device matches the requested identity.
    NoDevice {
        /// What we looked for.
        wanted: String,
        /// What the bus has (one line per device), possibly empty.
        found: Vec<String>,
    },
    /// The system has no usable USB stack (no bus, no permission to list it).
    UsbUnavailable(String),
    /// The device exists but the user may not open it.
    PermissionDenied {
        /// Which device.
        device: String,
        /// A udev rule that grants access.
        udev_rule: String,
    },
    /// The device went away during the transfer.
    Disconnected {
        /// Which device.
        device: String,
    },
    /// Another USB error.
    #[cfg(feature = "usb")]
    Usb {
        /// What we were doing.
        during: String,
        /// libusb's error.
        error: rusb::Error,
    },
    /// The gateware was generated for another configuration.
    GenerationMismatch(Vec<String>),
    /// The pipeline configuration is invalid.
    Config(String),
    /// A file could not be opened or read.
    Io {
        /// Path.
        path: PathBuf,
        /// The error.
        error: std::io::Error,
    },
    /// The source type exists but is not available in this build.
    Unavailable(String),
}

impl fmt::Display for TransportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TransportError::BadSource(s) => write!(f, "{s}"),
            #[cfg(feature = "frontpanel")]
            TransportError::LibraryNotFound { looked_in } => write!(
                f,
                "Opal Kelly FrontPanel library not found (looked in {}): install the FrontPanel SDK, set {}=/path/to/{}, or use --source usb",
                looked_in.join(", "),
                frontpanel::LIB_ENV,
                frontpanel::LIB_NAME
            ),
            #[cfg(feature = "frontpanel")]
            TransportError::LibraryLoad { path, reason } => write!(
                f,
                "cannot load the FrontPanel library {path}: {reason}"
            ),
            #[cfg(feature = "frontpanel")]
            TransportError::MissingSymbol { path, symbol } => write!(
                f,
                "{path} has no function {symbol}: it is not Opal Kelly's FrontPanel library, or a version without the C API (install the FrontPanel SDK, or point {} at libokFrontPanel)",
                frontpanel::LIB_ENV
            ),
            #[cfg(feature = "frontpanel")]
            TransportError::FrontPanel { call, code } => write!(
                f,
                "FrontPanel {call} failed: error {code} ({})",
                frontpanel::error_name(*code)
            ),
            TransportError::NoDevice { wanted, found } => {
                write!(f, "no device matches {wanted}")?;
                if found.is_empty() {
                    write!(f, "; no USB device is connected at all (check the cable and power)")
                } else {
                    write!(f, "; connected: {}", found.join("; "))
                }
            }
            TransportError::UsbUnavailable(why) => write!(
                f,
                "cannot list USB devices: {why} (is there a USB bus, and may this user read /dev/bus/usb?)"
            ),
            TransportError::PermissionDenied { device, udev_rule } => write!(
                f,
                "permission denied opening {device}: allow your user with a udev rule, e.g. put\n  {udev_rule}\ninto /etc/udev/rules.d/60-smartagg.rules, then run `sudo udevadm control --reload-rules && sudo udevadm trigger` and replug the board"
            ),
            TransportError::Disconnected { device } => {
                write!(f, "{device} disappeared (unplugged or reset)")
            }
            #[cfg(feature = "usb")]
            TransportError::Usb { during, error } => write!(f, "USB error while {during}: {error}"),
            TransportError::GenerationMismatch(diffs) => write!(
                f,
                "the device's gateware was generated for another configuration ({}): load the bitfile generated for this preset",
                diffs.join("; ")
            ),
            TransportError::Config(e) => write!(f, "{e}"),
            TransportError::Io { path, error } => write!(f, "{}: {error}", path.display()),
            TransportError::Unavailable(what) => write!(f, "{what}"),
        }
    }
}

impl std::error::Error for TransportError {}

/// Which source `--source` names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SourceSpec {
    /// Opal Kelly FrontPanel.
    FrontPanel,
    /// Plain USB bulk endpoint.
    Usb,
    /// A recorded stream.
    File(PathBuf),
    /// The co-simulated gateware with a scene preset.
    Cosim(String),
}

impl std::str::FromStr for SourceSpec {
    type Err = TransportError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let bad = |why: &str| {
            TransportError::BadSource(format!(
                "--source `{s}`: {why}; expected frontpanel, usb, file:PATH or cosim:PRESET"
            ))
        };
        match s {
            "frontpanel" => Ok(SourceSpec::FrontPanel),
            "usb" => Ok(SourceSpec::Usb),
            _ => {
                if let Some(path) = s.strip_prefix("file:") {
                    if path.is_empty() {
                        return Err(bad("the file path is empty"));
                    }
                    Ok(SourceSpec::File(PathBuf::from(path)))
                } else if let Some(preset) = s.strip_prefix("cosim:") {
                    if preset.is_empty() {
                        return Err(bad("the preset is empty"));
                    }
                    Ok(SourceSpec::Cosim(preset.to_string()))
                } else {
                    Err(bad("unknown source"))
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn source_specs_parse_and_bad_ones_say_what_is_expected() {
        assert_eq!("usb".parse::<SourceSpec>().unwrap(), SourceSpec::Usb);
        assert_eq!(
            "frontpanel".parse::<SourceSpec>().unwrap(),
            SourceSpec::FrontPanel
        );
        assert_eq!(
            "file:a/b.rois".parse::<SourceSpec>().unwrap(),
            SourceSpec::File("a/b.rois".into())
        );
        assert_eq!(
            "file:c:with:colons".parse::<SourceSpec>().unwrap(),
            SourceSpec::File("c:with:colons".into())
        );
        assert_eq!(
            "cosim:spcimager".parse::<SourceSpec>().unwrap(),
            SourceSpec::Cosim("spcimager".into())
        );
        for (bad, why) in [
            ("serial", "unknown source"),
            ("file:", "file path is empty"),
            ("cosim:", "preset is empty"),
            ("", "unknown source"),
        ] {
            let e = bad.parse::<SourceSpec>().unwrap_err().to_string();
            assert!(e.contains(why), "{e}");
            assert!(
                e.contains("frontpanel, usb, file:PATH or cosim:PRESET"),
                "{e}"
            );
        }
    }
}
