//! Opal Kelly FrontPanel transport: the stock XEM6310 speaks only
//! FrontPanel's (undocumented) USB protocol, so this source loads Opal Kelly's
//! own `libokFrontPanel` at run time when the user has installed the
//! FrontPanel SDK. The library is never a build dependency: without it every
//! other transport works, and this one says where it looked.
//!
//! # The C API used
//!
//! Signatures as declared in the SDK's `okFrontPanelDLL.h` (FrontPanel 4.x;
//! `okFrontPanel_HANDLE` is an opaque pointer, `ok_ErrorCode` a C enum, 0 =
//! no error, negative = error; `Bool` an `int`):
//!
//! ```c
//! okFrontPanel_HANDLE okFrontPanel_Construct(void);
//! void          okFrontPanel_Destruct(okFrontPanel_HANDLE);
//! int           okFrontPanel_GetDeviceCount(okFrontPanel_HANDLE);
//! ok_ErrorCode  okFrontPanel_OpenBySerial(okFrontPanel_HANDLE, const char *serial);
//! ok_ErrorCode  okFrontPanel_ConfigureFPGA(okFrontPanel_HANDLE, const char *bitfile);
//! Bool          okFrontPanel_IsFrontPanelEnabled(okFrontPanel_HANDLE);
//! void          okFrontPanel_SetTimeout(okFrontPanel_HANDLE, int milliseconds);
//! ok_ErrorCode  okFrontPanel_SetWireInValue(okFrontPanel_HANDLE, int ep, unsigned long val, unsigned long mask);
//! void          okFrontPanel_UpdateWireIns(okFrontPanel_HANDLE);
//! void          okFrontPanel_UpdateWireOuts(okFrontPanel_HANDLE);
//! unsigned long okFrontPanel_GetWireOutValue(okFrontPanel_HANDLE, int ep);
//! ok_ErrorCode  okFrontPanel_ActivateTriggerIn(okFrontPanel_HANDLE, int ep, int bit);
//! long          okFrontPanel_WriteToPipeIn(okFrontPanel_HANDLE, int ep, long length, unsigned char *data);
//! long          okFrontPanel_ReadFromPipeOut(okFrontPanel_HANDLE, int ep, long length, unsigned char *data);
//! ```
//!
//! Unsure, to check on a real installation: newer SDKs (5.x) may spell some
//! of these differently or add a required `okFrontPanelDLL_LoadLib` step (the
//! header's import side calls it; we `dlopen` the library ourselves instead);
//! an empty serial in `OpenBySerial` opens the first device; the USB 3.0 pipe
//! granularity is 16 bytes ([`registers::PIPE_BLOCK_BYTES`]). A missing function
//! is reported by name ([`TransportError::MissingSymbol`]).
//!
//! # What is tested here
//!
//! Without the SDK: the search for the library (absent → the message naming
//! every path tried), a library that lacks the functions (→ the missing one
//! named), the error-code names, and the stream-reading logic of
//! [`FrontPanelSource`] against a simulated device ([`PipeDevice`]): the
//! rounding to whole granules, the trimming of end-of-stream padding and the
//! end of the stream. The calls into the real library are not exercised.

use super::registers::{self, pipe, status, wire_out, RegisterBus, PIPE_BLOCK_BYTES};
use super::{Chunk, DeviceConfig, PacketSource, TransportError};
use libloading::Library;
use std::ffi::{c_char, c_int, c_long, c_ulong, c_void, CString};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Environment variable naming the library file (or name) to load.
pub const LIB_ENV: &str = "OKFP_LIB";

/// The library's file name on this platform.
#[cfg(target_os = "macos")]
pub const LIB_NAME: &str = "libokFrontPanel.dylib";
/// The library's file name on this platform.
#[cfg(windows)]
pub const LIB_NAME: &str = "okFrontPanel.dll";
/// The library's file name on this platform.
#[cfg(not(any(target_os = "macos", windows)))]
pub const LIB_NAME: &str = "libokFrontPanel.so";

/// The name of an `ok_ErrorCode`.
pub fn error_name(code: i32) -> &'static str {
    match code {
        0 => "NoError",
        -1 => "Failed",
        -2 => "Timeout",
        -3 => "DoneNotHigh",
        -4 => "TransferError",
        -5 => "CommunicationError",
        -6 => "InvalidBitstream",
        -7 => "FileError",
        -8 => "DeviceNotOpen",
        -9 => "InvalidEndpoint",
        -10 => "InvalidBlockSize",
        -11 => "I2CRestrictedAddress",
        -12 => "I2CBitError",
        -13 => "I2CNack",
        -14 => "I2CUnknownStatus",
        -15 => "UnsupportedFeature",
        -16 => "FIFOUnderflow",
        -17 => "FIFOOverflow",
        -18 => "DataAlignmentError",
        -19 => "InvalidResetProfile",
        -20 => "InvalidParameter",
        _ => "unknown error code",
    }
}

/// Where to look for the library: `$OKFP_LIB` alone when set; otherwise the
/// dynamic loader's own search (LD_LIBRARY_PATH, ld.so cache) and the usual
/// install folders of the SDK.
pub fn candidates(env: Option<&std::ffi::OsStr>) -> Vec<PathBuf> {
    if let Some(p) = env.filter(|p| !p.is_empty()) {
        return vec![PathBuf::from(p)];
    }
    let mut v = vec![PathBuf::from(LIB_NAME)];
    for dir in [
        "/usr/local/lib",
        "/usr/lib",
        "/usr/lib/x86_64-linux-gnu",
        "/opt/opalkelly/FrontPanel/API",
        "/opt/FrontPanel/API",
        "/usr/local/lib/FrontPanel/API",
    ] {
        v.push(Path::new(dir).join(LIB_NAME));
    }
    if let Some(home) = std::env::var_os("HOME") {
        v.push(Path::new(&home).join("FrontPanel/API").join(LIB_NAME));
    }
    v
}

type FnConstruct = unsafe extern "C" fn() -> *mut c_void;
type FnHandle = unsafe extern "C" fn(*mut c_void);
type FnCount = unsafe extern "C" fn(*mut c_void) -> c_int;
type FnStr = unsafe extern "C" fn(*mut c_void, *const c_char) -> c_int;
type FnSetTimeout = unsafe extern "C" fn(*mut c_void, c_int);
type FnSetWire = unsafe extern "C" fn(*mut c_void, c_int, c_ulong, c_ulong) -> c_int;
type FnGetWire = unsafe extern "C" fn(*mut c_void, c_int) -> c_ulong;
type FnTrigger = unsafe extern "C" fn(*mut c_void, c_int, c_int) -> c_int;
type FnPipe = unsafe extern "C" fn(*mut c_void, c_int, c_long, *mut u8) -> c_long;

/// The FrontPanel functions, resolved from a loaded library.
pub struct FrontPanelLib {
    path: String,
    construct: FnConstruct,
    destruct: FnHandle,
    get_device_count: FnCount,
    open_by_serial: FnStr,
    configure_fpga: FnStr,
    is_front_panel_enabled: FnCount,
    set_timeout: FnSetTimeout,
    set_wire_in_value: FnSetWire,
    update_wire_ins: FnHandle,
    update_wire_outs: FnHandle,
    get_wire_out_value: FnGetWire,
    activate_trigger_in: FnTrigger,
    write_to_pipe_in: FnPipe,
    read_from_pipe_out: FnPipe,
    // Last: the function pointers above are valid while this lives.
    _lib: Library,
}

impl FrontPanelLib {
    /// Loads the library from the first candidate that exists (see [`candidates`]).
    pub fn load() -> Result<FrontPanelLib, TransportError> {
        Self::load_from(&candidates(std::env::var_os(LIB_ENV).as_deref()))
    }

    /// Loads the library from the first of `paths` that loads. A bare file
    /// name goes through the dynamic loader's search; a path that does not
    /// exist is skipped; one that exists but fails to load is an error.
    pub fn load_from(paths: &[PathBuf]) -> Result<FrontPanelLib, TransportError> {
        for p in paths {
            let bare = p.components().count() == 1;
            if !bare && !p.exists() {
                continue;
            }
            // SAFETY: loading runs the library's initialisers; we only load
            // files named as the FrontPanel library by the user or the SDK's
            // install locations.
            match unsafe { Library::new(p) } {
                Ok(lib) => return Self::resolve(lib, &p.display().to_string()),
                Err(e) if !bare => {
                    return Err(TransportError::LibraryLoad {
                        path: p.display().to_string(),
                        reason: e.to_string(),
                    })
                }
                Err(_) => continue,
            }
        }
        Err(TransportError::LibraryNotFound {
            looked_in: paths
                .iter()
                .map(|p| {
                    if p.components().count() == 1 {
                        format!("{} on the loader's path", p.display())
                    } else {
                        p.display().to_string()
                    }
                })
                .collect(),
        })
    }

    fn resolve(lib: Library, path: &str) -> Result<FrontPanelLib, TransportError> {
        fn sym<T: Copy>(
            lib: &Library,
            path: &str,
            name: &'static str,
        ) -> Result<T, TransportError> {
            let mut c = name.as_bytes().to_vec();
            c.push(0);
            // SAFETY: the type T is the C signature documented in the module
            // docs for this symbol name.
            unsafe { lib.get::<T>(&c) }
                .map(|s| *s)
                .map_err(|_| TransportError::MissingSymbol {
                    path: path.to_string(),
                    symbol: name,
                })
        }
        Ok(FrontPanelLib {
            path: path.to_string(),
            construct: sym(&lib, path, "okFrontPanel_Construct")?,
            destruct: sym(&lib, path, "okFrontPanel_Destruct")?,
            get_device_count: sym(&lib, path, "okFrontPanel_GetDeviceCount")?,
            open_by_serial: sym(&lib, path, "okFrontPanel_OpenBySerial")?,
            configure_fpga: sym(&lib, path, "okFrontPanel_ConfigureFPGA")?,
            is_front_panel_enabled: sym(&lib, path, "okFrontPanel_IsFrontPanelEnabled")?,
            set_timeout: sym(&lib, path, "okFrontPanel_SetTimeout")?,
            set_wire_in_value: sym(&lib, path, "okFrontPanel_SetWireInValue")?,
            update_wire_ins: sym(&lib, path, "okFrontPanel_UpdateWireIns")?,
            update_wire_outs: sym(&lib, path, "okFrontPanel_UpdateWireOuts")?,
            get_wire_out_value: sym(&lib, path, "okFrontPanel_GetWireOutValue")?,
            activate_trigger_in: sym(&lib, path, "okFrontPanel_ActivateTriggerIn")?,
            write_to_pipe_in: sym(&lib, path, "okFrontPanel_WriteToPipeIn")?,
            read_from_pipe_out: sym(&lib, path, "okFrontPanel_ReadFromPipeOut")?,
            _lib: lib,
        })
    }

    /// The file the functions come from.
    pub fn path(&self) -> &str {
        &self.path
    }
}

/// Register access plus the pipe-out read that [`FrontPanelSource`] needs.
pub trait PipeDevice: RegisterBus {
    /// Reads exactly `buf.len()` bytes (a multiple of [`PIPE_BLOCK_BYTES`]) from a pipe-out.
    fn read_pipe_out(&mut self, addr: u8, buf: &mut [u8]) -> Result<(), TransportError>;
}

/// How [`FrontPanelSource::open`] finds the board.
#[derive(Debug, Clone, Default)]
pub struct FrontPanelOptions {
    /// Serial number; `None` opens the first device.
    pub serial: Option<String>,
    /// Bitfile to load into the FPGA first.
    pub bitfile: Option<PathBuf>,
}

/// An open FrontPanel device.
pub struct FrontPanelDevice {
    lib: FrontPanelLib,
    handle: *mut c_void,
}

impl FrontPanelDevice {
    fn check(call: &'static str, code: c_int) -> Result<(), TransportError> {
        if code < 0 {
            return Err(TransportError::FrontPanel { call, code });
        }
        Ok(())
    }

    /// Loads the library, opens the board and (optionally) configures the FPGA.
    pub fn open(opts: &FrontPanelOptions) -> Result<FrontPanelDevice, TransportError> {
        let lib = FrontPanelLib::load()?;
        // SAFETY: FrontPanel C API calls with the handle it returned; the
        // handle is used from this thread only and destructed in Drop.
        let handle = unsafe { (lib.construct)() };
        if handle.is_null() {
            return Err(TransportError::FrontPanel {
                call: "Construct",
                code: -1,
            });
        }
        let dev = FrontPanelDevice { lib, handle };
        let count = unsafe { (dev.lib.get_device_count)(dev.handle) };
        if count <= 0 {
            return Err(TransportError::NoDevice {
                wanted: "an Opal Kelly board (FrontPanel found none)".into(),
                found: Vec::new(),
            });
        }
        let serial = CString::new(opts.serial.clone().unwrap_or_default())
            .map_err(|_| TransportError::Config("the serial number contains a NUL byte".into()))?;
        Self::check("OpenBySerial", unsafe {
            (dev.lib.open_by_serial)(dev.handle, serial.as_ptr())
        })?;
        if let Some(bitfile) = &opts.bitfile {
            let c = CString::new(bitfile.display().to_string()).map_err(|_| {
                TransportError::Config("the bitfile path contains a NUL byte".into())
            })?;
            Self::check("ConfigureFPGA", unsafe {
                (dev.lib.configure_fpga)(dev.handle, c.as_ptr())
            })?;
        }
        if unsafe { (dev.lib.is_front_panel_enabled)(dev.handle) } == 0 {
            return Err(TransportError::Unavailable(
                "the FPGA configuration has no FrontPanel host interface: load the smartagg bitfile (--bitfile)".into(),
            ));
        }
        unsafe { (dev.lib.set_timeout)(dev.handle, 2000) };
        Ok(dev)
    }
}

impl Drop for FrontPanelDevice {
    fn drop(&mut self) {
        // SAFETY: the handle came from Construct and is destructed once.
        unsafe { (self.lib.destruct)(self.handle) }
    }
}

impl RegisterBus for FrontPanelDevice {
    fn set_wire_in(&mut self, addr: u8, value: u32) -> Result<(), TransportError> {
        Self::check("SetWireInValue", unsafe {
            (self.lib.set_wire_in_value)(self.handle, addr as c_int, value as c_ulong, 0xFFFF_FFFF)
        })
    }

    fn commit_wire_ins(&mut self) -> Result<(), TransportError> {
        unsafe { (self.lib.update_wire_ins)(self.handle) };
        Ok(())
    }

    fn wire_out(&mut self, addr: u8) -> Result<u32, TransportError> {
        unsafe {
            (self.lib.update_wire_outs)(self.handle);
            Ok((self.lib.get_wire_out_value)(self.handle, addr as c_int) as u32)
        }
    }

    fn trigger(&mut self, addr: u8, bit: u8) -> Result<(), TransportError> {
        Self::check("ActivateTriggerIn", unsafe {
            (self.lib.activate_trigger_in)(self.handle, addr as c_int, bit as c_int)
        })
    }

    fn write_pipe_in(&mut self, addr: u8, data: &[u8]) -> Result<(), TransportError> {
        // Whole granules: pad the last one with zeros (the mask's padding bits are unused).
        let mut padded = data.to_vec();
        padded.resize(data.len().div_ceil(PIPE_BLOCK_BYTES) * PIPE_BLOCK_BYTES, 0);
        let n = unsafe {
            (self.lib.write_to_pipe_in)(
                self.handle,
                addr as c_int,
                padded.len() as c_long,
                padded.as_mut_ptr(),
            )
        };
        Self::check("WriteToPipeIn", n.clamp(c_int::MIN as c_long, 0) as c_int)
    }
}

impl PipeDevice for FrontPanelDevice {
    fn read_pipe_out(&mut self, addr: u8, buf: &mut [u8]) -> Result<(), TransportError> {
        let n = unsafe {
            (self.lib.read_from_pipe_out)(
                self.handle,
                addr as c_int,
                buf.len() as c_long,
                buf.as_mut_ptr(),
            )
        };
        if n < 0 {
            return Err(TransportError::FrontPanel {
                call: "ReadFromPipeOut",
                code: n.max(c_int::MIN as c_long) as c_int,
            });
        }
        if n as usize != buf.len() {
            return Err(TransportError::FrontPanel {
                call: "ReadFromPipeOut (short read)",
                code: -4,
            });
        }
        Ok(())
    }
}

/// Streams the packet pipe-out of a FrontPanel device, reading only what the
/// output FIFO holds (see the register-map docs in [`registers`]).
pub struct FrontPanelSource<D: PipeDevice> {
    dev: D,
    label: String,
    /// Pause between two polls of the FIFO level.
    poll: Duration,
    ended: bool,
}

impl FrontPanelSource<FrontPanelDevice> {
    /// Loads the library and opens the board.
    pub fn open(opts: &FrontPanelOptions) -> Result<Self, TransportError> {
        let dev = FrontPanelDevice::open(opts)?;
        let label = format!(
            "FrontPanel board {} (library {})",
            opts.serial.as_deref().unwrap_or("(first found)"),
            dev.lib.path()
        );
        Ok(FrontPanelSource::new(dev, label))
    }
}

impl<D: PipeDevice> FrontPanelSource<D> {
    /// A source over an opened device.
    pub fn new(dev: D, label: String) -> Self {
        FrontPanelSource {
            dev,
            label,
            poll: Duration::from_millis(1),
            ended: false,
        }
    }

    /// The device.
    #[cfg(test)]
    pub fn device(&self) -> &D {
        &self.dev
    }
}

impl<D: PipeDevice> PacketSource for FrontPanelSource<D> {
    fn describe(&self) -> String {
        self.label.clone()
    }

    fn configure(&mut self, cfg: &DeviceConfig) -> Result<(), TransportError> {
        registers::configure(&mut self.dev, cfg)
    }

    fn start(&mut self) -> Result<(), TransportError> {
        self.ended = false;
        registers::start(&mut self.dev)
    }

    fn read(&mut self, buf: &mut [u8], wait: Duration) -> Result<Chunk, TransportError> {
        if self.ended {
            return Ok(Chunk::End);
        }
        if buf.len() < PIPE_BLOCK_BYTES {
            return Err(TransportError::Config(format!(
                "FrontPanel reads need a buffer of at least {PIPE_BLOCK_BYTES} bytes"
            )));
        }
        let deadline = Instant::now() + wait;
        loop {
            // STATUS before FIFO_BYTES: once ENDED is seen, the level read
            // after it is final.
            let st = self.dev.wire_out(wire_out::STATUS)?;
            let avail = self.dev.wire_out(wire_out::FIFO_BYTES)? as usize;
            let whole = avail.min(buf.len()) / PIPE_BLOCK_BYTES * PIPE_BLOCK_BYTES;
            if whole > 0 {
                self.dev
                    .read_pipe_out(pipe::STREAM_OUT, &mut buf[..whole])?;
                return Ok(Chunk::Data(whole));
            }
            if st & status::ENDED != 0 {
                if avail == 0 {
                    self.ended = true;
                    return Ok(Chunk::End);
                }
                if avail < PIPE_BLOCK_BYTES {
                    // The last, padded granule: keep only the stream's bytes.
                    let mut last = [0u8; PIPE_BLOCK_BYTES];
                    self.dev.read_pipe_out(pipe::STREAM_OUT, &mut last)?;
                    let n = avail.min(buf.len());
                    buf[..n].copy_from_slice(&last[..n]);
                    return Ok(Chunk::Data(n));
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(Chunk::Idle);
            }
            std::thread::sleep(self.poll.min(deadline - now));
        }
    }

    fn stop(&mut self) -> Result<(), TransportError> {
        registers::stop(&mut self.dev)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registers::tests::{bus_for, pipeline, MockBus};
    use crate::registers::trigger;

    /// A FrontPanel device simulated at the register level: a FIFO that the
    /// gateware fills in bursts, padded to a granule at the end.
    struct SimDevice {
        bus: MockBus,
        stream: Vec<u8>,
        /// Bytes the "gateware" has pushed into the FIFO so far.
        produced: usize,
        /// Bytes read by the host.
        consumed: usize,
        /// Burst added at every status poll.
        burst: usize,
        stopped: bool,
        reads: Vec<usize>,
    }

    impl SimDevice {
        fn new(stream: Vec<u8>, burst: usize) -> Self {
            let cfg = DeviceConfig::from_pipeline(&pipeline()).unwrap();
            SimDevice {
                bus: bus_for(&cfg),
                stream,
                produced: 0,
                consumed: 0,
                burst,
                stopped: false,
                reads: Vec::new(),
            }
        }
        fn ended(&self) -> bool {
            self.stopped && self.produced == self.stream.len()
        }
    }

    impl RegisterBus for SimDevice {
        fn set_wire_in(&mut self, a: u8, v: u32) -> Result<(), TransportError> {
            self.bus.set_wire_in(a, v)
        }
        fn commit_wire_ins(&mut self) -> Result<(), TransportError> {
            self.bus.commit_wire_ins()
        }
        fn wire_out(&mut self, addr: u8) -> Result<u32, TransportError> {
            match addr {
                wire_out::STATUS => {
                    self.produced = (self.produced + self.burst).min(self.stream.len());
                    Ok(if self.ended() {
                        status::ENDED
                    } else {
                        status::RUNNING
                    })
                }
                wire_out::FIFO_BYTES => Ok((self.produced - self.consumed) as u32),
                a => self.bus.wire_out(a),
            }
        }
        fn trigger(&mut self, addr: u8, bit: u8) -> Result<(), TransportError> {
            if (addr, bit) == (trigger::CONTROL, trigger::STOP) {
                self.stopped = true;
            }
            self.bus.trigger(addr, bit)
        }
        fn write_pipe_in(&mut self, a: u8, d: &[u8]) -> Result<(), TransportError> {
            self.bus.write_pipe_in(a, d)
        }
    }

    impl PipeDevice for SimDevice {
        fn read_pipe_out(&mut self, addr: u8, buf: &mut [u8]) -> Result<(), TransportError> {
            assert_eq!(addr, pipe::STREAM_OUT);
            assert_eq!(
                buf.len() % PIPE_BLOCK_BYTES,
                0,
                "pipe reads are whole granules"
            );
            let avail = self.produced - self.consumed;
            let padded_end =
                self.ended() && buf.len() == PIPE_BLOCK_BYTES && avail < PIPE_BLOCK_BYTES;
            assert!(buf.len() <= avail || padded_end, "read past the FIFO");
            for (i, b) in buf.iter_mut().enumerate() {
                // Padding reads as zeros.
                *b = self.stream.get(self.consumed + i).copied().unwrap_or(0);
            }
            self.consumed = (self.consumed + buf.len()).min(self.produced);
            self.reads.push(buf.len());
            Ok(())
        }
    }

    fn run(stream_len: usize, burst: usize, buf_len: usize) -> (Vec<u8>, Vec<u8>, Vec<usize>) {
        let stream: Vec<u8> = (0..stream_len).map(|i| (i * 31 % 251) as u8 + 1).collect();
        let mut src = FrontPanelSource::new(SimDevice::new(stream.clone(), burst), "sim".into());
        let cfg = DeviceConfig::from_pipeline(&pipeline()).unwrap();
        src.configure(&cfg).unwrap();
        src.start().unwrap();
        let mut got = Vec::new();
        let mut buf = vec![0u8; buf_len];
        let mut polls = 0;
        loop {
            match src.read(&mut buf, Duration::from_millis(5)).unwrap() {
                Chunk::Data(n) => got.extend_from_slice(&buf[..n]),
                Chunk::Idle => {}
                Chunk::End => break,
            }
            polls += 1;
            if polls == 3 {
                src.stop().unwrap();
            }
            assert!(polls < 100_000, "never ended");
        }
        (stream, got, src.device().reads.clone())
    }

    #[test]
    fn reads_whole_granules_and_drops_the_end_padding() {
        for (len, burst, buf) in [
            (1000, 7, 4096),
            (1003, 100, 64),
            (5, 1, 4096),
            (16, 16, 16),
            (0, 3, 64),
        ] {
            let (stream, got, reads) = run(len, burst, buf);
            assert_eq!(got, stream, "len {len} burst {burst} buf {buf}");
            assert!(reads
                .iter()
                .all(|r| r % PIPE_BLOCK_BYTES == 0 && *r <= buf.max(PIPE_BLOCK_BYTES)));
        }
    }

    #[test]
    fn a_missing_library_names_every_place_looked() {
        let paths = vec![
            PathBuf::from("/nonexistent/dir/libokFrontPanel.so"),
            PathBuf::from("libokFrontPanel-does-not-exist.so"),
        ];
        let e = FrontPanelLib::load_from(&paths).err().unwrap().to_string();
        assert!(e.starts_with("Opal Kelly FrontPanel library not found (looked in /nonexistent/dir/libokFrontPanel.so, libokFrontPanel-does-not-exist.so on the loader's path)"), "{e}");
        assert!(
            e.contains("install the FrontPanel SDK") && e.contains("--source usb"),
            "{e}"
        );
        assert!(e.contains(LIB_ENV), "{e}");
    }

    #[test]
    fn a_library_without_the_api_is_named_with_the_missing_function() {
        // The C library is always loadable and has none of FrontPanel's functions.
        let e = FrontPanelLib::load_from(&[PathBuf::from("libc.so.6")])
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("libc.so.6 has no function okFrontPanel_Construct"),
            "{e}"
        );
        assert!(e.contains("not Opal Kelly's FrontPanel library"), "{e}");
    }

    #[test]
    fn a_file_that_is_not_a_library_is_a_load_error() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(LIB_NAME);
        std::fs::write(&p, b"not an ELF file").unwrap();
        let e = FrontPanelLib::load_from(std::slice::from_ref(&p))
            .err()
            .unwrap()
            .to_string();
        assert!(
            e.contains("cannot load the FrontPanel library") && e.contains(&*p.to_string_lossy()),
            "{e}"
        );
    }

    #[test]
    fn search_order_prefers_the_environment_variable() {
        let c = candidates(Some(std::ffi::OsStr::new("/x/lib.so")));
        assert_eq!(c, vec![PathBuf::from("/x/lib.so")]);
        let c = candidates(None);
        assert_eq!(c[0], PathBuf::from(LIB_NAME));
        assert!(c.iter().any(|p| p.starts_with("/usr/local/lib")));
        assert_eq!(error_name(-8), "DeviceNotOpen");
        assert_eq!(error_name(-99), "unknown error code");
        let e = TransportError::FrontPanel {
            call: "OpenBySerial",
            code: -8,
        }
        .to_string();
        assert_eq!(
            e,
            "FrontPanel OpenBySerial failed: error -8 (DeviceNotOpen)"
        );
    }
}
