//! Plain USB transport (`rusb`/libusb) for firmware that exposes the packet
//! stream on a bulk IN endpoint and the registers through vendor control
//! requests ([`super::registers::vendor`]).
//!
//! The stock XEM6310 speaks only FrontPanel's protocol (use
//! `--source frontpanel` there); this transport is for a board whose USB
//! controller runs smartagg's own bulk firmware. Its identity is configurable
//! (`--vid`, `--pid`, `--interface`, `--endpoint`); the defaults are
//! [`DEFAULT_VID`] (Opal Kelly's vendor id) and the placeholder product id
//! [`DEFAULT_PID`], which no shipping firmware uses yet.
//!
//! Device-independent pieces (device selection, error mapping, the udev
//! rule) are plain functions, tested without a USB bus.

use super::registers::{self, vendor, RegisterBus};
use super::{Chunk, DeviceConfig, PacketSource, TransportError};
use rusb::UsbContext;
use std::time::Duration;

/// Opal Kelly's USB vendor id.
pub const DEFAULT_VID: u16 = 0x151F;
/// Placeholder product id of the smartagg bulk firmware ("SA", like the
/// packet magic). Not a product id Opal Kelly assigned: set `--pid` to what
/// the firmware reports.
pub const DEFAULT_PID: u16 = 0x5341;
/// Interface holding the stream endpoint.
pub const DEFAULT_INTERFACE: u8 = 0;
/// Bulk IN endpoint of the packet stream.
pub const DEFAULT_ENDPOINT: u8 = 0x81;
/// Time limit of one control request.
const CONTROL_TIMEOUT: Duration = Duration::from_secs(1);

/// Which device and endpoint to use.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsbOptions {
    /// Vendor id.
    pub vid: u16,
    /// Product id.
    pub pid: u16,
    /// Interface to claim.
    pub interface: u8,
    /// Bulk IN endpoint address (bit 7 set).
    pub endpoint: u8,
}

impl Default for UsbOptions {
    fn default() -> Self {
        UsbOptions {
            vid: DEFAULT_VID,
            pid: DEFAULT_PID,
            interface: DEFAULT_INTERFACE,
            endpoint: DEFAULT_ENDPOINT,
        }
    }
}

impl UsbOptions {
    /// Checks the endpoint direction (an IN endpoint has bit 7 set).
    pub fn validate(&self) -> Result<(), TransportError> {
        if self.endpoint & 0x80 == 0 {
            return Err(TransportError::Config(format!(
                "--endpoint 0x{:02x} is an OUT endpoint; the stream needs a bulk IN endpoint (0x81..=0x8f)",
                self.endpoint
            )));
        }
        Ok(())
    }

    /// `vvvv:pppp`, as lsusb prints it.
    pub fn id(&self) -> String {
        format!("{:04x}:{:04x}", self.vid, self.pid)
    }
}

/// A udev rule that lets logged-in users open the device.
pub fn udev_rule(vid: u16, pid: u16) -> String {
    format!(
        "SUBSYSTEM==\"usb\", ATTRS{{idVendor}}==\"{vid:04x}\", ATTRS{{idProduct}}==\"{pid:04x}\", MODE=\"0660\", TAG+=\"uaccess\""
    )
}

/// One device on the bus, as listed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UsbId {
    /// Bus number.
    pub bus: u8,
    /// Address on the bus.
    pub address: u8,
    /// Vendor id.
    pub vid: u16,
    /// Product id.
    pub pid: u16,
}

impl std::fmt::Display for UsbId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "bus {:03} device {:03}: {:04x}:{:04x}",
            self.bus, self.address, self.vid, self.pid
        )
    }
}

/// The index of the first listed device matching `opts`, or a
/// [`TransportError::NoDevice`] that lists what the bus has.
pub fn select_device(found: &[UsbId], opts: &UsbOptions) -> Result<usize, TransportError> {
    found
        .iter()
        .position(|d| d.vid == opts.vid && d.pid == opts.pid)
        .ok_or_else(|| TransportError::NoDevice {
            wanted: format!(
                "USB {} (set --vid/--pid to the firmware's ids; the stock XEM6310 needs --source frontpanel)",
                opts.id()
            ),
            found: found.iter().map(|d| d.to_string()).collect(),
        })
}

/// Maps a libusb error met while opening or claiming `device`.
pub fn open_error(error: rusb::Error, device: &str, opts: &UsbOptions) -> TransportError {
    match error {
        rusb::Error::Access => TransportError::PermissionDenied {
            device: device.to_string(),
            udev_rule: udev_rule(opts.vid, opts.pid),
        },
        rusb::Error::NoDevice => TransportError::Disconnected {
            device: device.to_string(),
        },
        rusb::Error::Busy => TransportError::Usb {
            during: format!(
                "claiming interface {} of {device} (another program holds it; close it, e.g. a FrontPanel application)",
                opts.interface
            ),
            error,
        },
        rusb::Error::NotFound => TransportError::Usb {
            during: format!(
                "claiming interface {} of {device} (the firmware has no such interface: check --interface)",
                opts.interface
            ),
            error,
        },
        _ => TransportError::Usb {
            during: format!("opening {device}"),
            error,
        },
    }
}

/// Maps the result of a bulk read: a timeout is [`Chunk::Idle`], an
/// unplugged device [`TransportError::Disconnected`].
pub fn read_result(
    result: rusb::Result<usize>,
    device: &str,
    endpoint: u8,
) -> Result<Chunk, TransportError> {
    match result {
        Ok(0) | Err(rusb::Error::Timeout) | Err(rusb::Error::Interrupted) => Ok(Chunk::Idle),
        Ok(n) => Ok(Chunk::Data(n)),
        Err(rusb::Error::NoDevice) => Err(TransportError::Disconnected {
            device: device.to_string(),
        }),
        Err(rusb::Error::Pipe) => Err(TransportError::Usb {
            during: format!("reading endpoint 0x{endpoint:02x} of {device} (the endpoint stalled)"),
            error: rusb::Error::Pipe,
        }),
        Err(rusb::Error::Overflow) => Err(TransportError::Usb {
            during: format!(
                "reading endpoint 0x{endpoint:02x} of {device} (the device sent more than asked: the read size must be a multiple of the endpoint's packet size)"
            ),
            error: rusb::Error::Overflow,
        }),
        Err(error) => Err(TransportError::Usb {
            during: format!("reading endpoint 0x{endpoint:02x} of {device}"),
            error,
        }),
    }
}

/// Lists the devices of a libusb context.
fn list(ctx: &rusb::Context) -> Result<Vec<(rusb::Device<rusb::Context>, UsbId)>, TransportError> {
    let devices = ctx
        .devices()
        .map_err(|e| TransportError::UsbUnavailable(e.to_string()))?;
    let mut out = Vec::new();
    for d in devices.iter() {
        // A device whose descriptor cannot be read cannot be ours; skip it.
        if let Ok(desc) = d.device_descriptor() {
            let id = UsbId {
                bus: d.bus_number(),
                address: d.address(),
                vid: desc.vendor_id(),
                pid: desc.product_id(),
            };
            out.push((d, id));
        }
    }
    Ok(out)
}

/// The bulk-endpoint source.
pub struct UsbSource {
    handle: rusb::DeviceHandle<rusb::Context>,
    opts: UsbOptions,
    label: String,
}

impl UsbSource {
    /// Finds, opens and claims the device.
    pub fn open(opts: &UsbOptions) -> Result<UsbSource, TransportError> {
        opts.validate()?;
        let ctx =
            rusb::Context::new().map_err(|e| TransportError::UsbUnavailable(e.to_string()))?;
        let mut devices = list(&ctx)?;
        let ids: Vec<UsbId> = devices.iter().map(|(_, id)| id.clone()).collect();
        let index = select_device(&ids, opts)?;
        let (device, id) = devices.swap_remove(index);
        let label = format!("USB {id} endpoint 0x{:02x}", opts.endpoint);
        let handle = device.open().map_err(|e| open_error(e, &label, opts))?;
        // Not every platform can detach kernel drivers; claiming tells.
        let _ = handle.set_auto_detach_kernel_driver(true);
        handle
            .claim_interface(opts.interface)
            .map_err(|e| open_error(e, &label, opts))?;
        Ok(UsbSource {
            handle,
            opts: opts.clone(),
            label,
        })
    }

    fn control_error(&self, what: String, error: rusb::Error) -> TransportError {
        match error {
            rusb::Error::NoDevice => TransportError::Disconnected {
                device: self.label.clone(),
            },
            error => TransportError::Usb {
                during: what,
                error,
            },
        }
    }

    fn write_request(
        &mut self,
        request: u8,
        value: u16,
        index: u16,
        data: &[u8],
    ) -> Result<(), TransportError> {
        let n = self
            .handle
            .write_control(
                vendor::REQUEST_TYPE_OUT,
                request,
                value,
                index,
                data,
                CONTROL_TIMEOUT,
            )
            .map_err(|e| {
                self.control_error(
                    format!(
                        "sending vendor request 0x{request:02x} (wValue 0x{value:04x}) to {}",
                        self.label
                    ),
                    e,
                )
            })?;
        if n != data.len() {
            return Err(TransportError::Usb {
                during: format!(
                    "sending vendor request 0x{request:02x}: {n} of {} bytes accepted",
                    data.len()
                ),
                error: rusb::Error::Io,
            });
        }
        Ok(())
    }
}

impl RegisterBus for UsbSource {
    fn set_wire_in(&mut self, addr: u8, value: u32) -> Result<(), TransportError> {
        self.write_request(vendor::WRITE_WIRE_IN, addr as u16, 0, &value.to_le_bytes())
    }

    fn commit_wire_ins(&mut self) -> Result<(), TransportError> {
        Ok(())
    }

    fn wire_out(&mut self, addr: u8) -> Result<u32, TransportError> {
        let mut b = [0u8; 4];
        let n = self
            .handle
            .read_control(
                vendor::REQUEST_TYPE_IN,
                vendor::READ_WIRE_OUT,
                addr as u16,
                0,
                &mut b,
                CONTROL_TIMEOUT,
            )
            .map_err(|e| self.control_error(format!("reading wire-out 0x{addr:02x}"), e))?;
        if n != 4 {
            return Err(TransportError::Usb {
                during: format!("reading wire-out 0x{addr:02x}: {n} of 4 bytes"),
                error: rusb::Error::Io,
            });
        }
        Ok(u32::from_le_bytes(b))
    }

    fn trigger(&mut self, addr: u8, bit: u8) -> Result<(), TransportError> {
        self.write_request(vendor::ACTIVATE_TRIGGER, addr as u16, bit as u16, &[])
    }

    fn write_pipe_in(&mut self, addr: u8, data: &[u8]) -> Result<(), TransportError> {
        for part in data.chunks(vendor::MAX_CONTROL_DATA) {
            self.write_request(vendor::WRITE_PIPE_IN, addr as u16, 0, part)?;
        }
        Ok(())
    }
}

impl PacketSource for UsbSource {
    fn describe(&self) -> String {
        self.label.clone()
    }

    fn configure(&mut self, cfg: &DeviceConfig) -> Result<(), TransportError> {
        registers::configure(self, cfg)
    }

    fn start(&mut self) -> Result<(), TransportError> {
        registers::start(self)
    }

    fn read(&mut self, buf: &mut [u8], wait: Duration) -> Result<Chunk, TransportError> {
        // libusb treats a zero timeout as "wait forever".
        let wait = wait.max(Duration::from_millis(1));
        let r = self.handle.read_bulk(self.opts.endpoint, buf, wait);
        read_result(r, &self.label, self.opts.endpoint)
    }

    fn stop(&mut self) -> Result<(), TransportError> {
        registers::stop(self)
    }
}

impl Drop for UsbSource {
    fn drop(&mut self) {
        let _ = self.handle.release_interface(self.opts.interface);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn id(vid: u16, pid: u16) -> UsbId {
        UsbId {
            bus: 1,
            address: 4,
            vid,
            pid,
        }
    }

    #[test]
    fn selection_finds_the_match_or_lists_the_bus() {
        let opts = UsbOptions::default();
        let bus = [id(0x1d6b, 0x0002), id(0x151f, 0x5341)];
        assert_eq!(select_device(&bus, &opts).unwrap(), 1);
        let e = select_device(&bus[..1], &opts).unwrap_err().to_string();
        assert!(e.contains("no device matches USB 151f:5341"), "{e}");
        assert!(
            e.contains("connected: bus 001 device 004: 1d6b:0002"),
            "{e}"
        );
        let e = select_device(&[], &opts).unwrap_err().to_string();
        assert!(e.contains("no USB device is connected at all"), "{e}");
    }

    #[test]
    fn open_errors_say_what_to_do() {
        let opts = UsbOptions {
            vid: 0x151f,
            pid: 0x0123,
            ..Default::default()
        };
        let e = open_error(rusb::Error::Access, "USB x", &opts).to_string();
        assert!(e.contains("permission denied opening USB x"), "{e}");
        assert!(
            e.contains(r#"ATTRS{idVendor}=="151f", ATTRS{idProduct}=="0123""#),
            "{e}"
        );
        assert!(e.contains("udevadm control --reload-rules"), "{e}");
        let e = open_error(rusb::Error::Busy, "USB x", &opts).to_string();
        assert!(e.contains("another program holds it"), "{e}");
        let e = open_error(rusb::Error::NotFound, "USB x", &opts).to_string();
        assert!(e.contains("check --interface"), "{e}");
        let e = open_error(rusb::Error::NoDevice, "USB x", &opts).to_string();
        assert!(e.contains("USB x disappeared"), "{e}");
    }

    #[test]
    fn read_results_map_timeouts_to_idle_and_unplugging_to_an_error() {
        assert_eq!(read_result(Ok(512), "d", 0x81).unwrap(), Chunk::Data(512));
        assert_eq!(read_result(Ok(0), "d", 0x81).unwrap(), Chunk::Idle);
        assert_eq!(
            read_result(Err(rusb::Error::Timeout), "d", 0x81).unwrap(),
            Chunk::Idle
        );
        let e = read_result(Err(rusb::Error::NoDevice), "USB d", 0x81)
            .unwrap_err()
            .to_string();
        assert!(e.contains("USB d disappeared (unplugged or reset)"), "{e}");
        let e = read_result(Err(rusb::Error::Pipe), "d", 0x82)
            .unwrap_err()
            .to_string();
        assert!(e.contains("endpoint 0x82") && e.contains("stalled"), "{e}");
        let e = read_result(Err(rusb::Error::Overflow), "d", 0x81)
            .unwrap_err()
            .to_string();
        assert!(e.contains("multiple of the endpoint's packet size"), "{e}");
        let e = read_result(Err(rusb::Error::Io), "d", 0x81)
            .unwrap_err()
            .to_string();
        assert!(e.contains("USB error while reading endpoint 0x81"), "{e}");
    }

    #[test]
    fn out_endpoints_are_refused() {
        let opts = UsbOptions {
            endpoint: 0x01,
            ..Default::default()
        };
        let e = opts.validate().unwrap_err().to_string();
        assert!(e.contains("0x01 is an OUT endpoint"), "{e}");
        let e = UsbSource::open(&opts).err().unwrap().to_string();
        assert!(e.contains("OUT endpoint"), "{e}");
    }

    /// On a machine without a USB bus libusb either fails to start or lists
    /// no device: either way opening gives a clear message, never a panic.
    /// (With a bus, the placeholder id matches nothing unless the firmware is
    /// plugged in, which the message then reports.)
    #[test]
    fn opening_without_the_device_is_a_clear_error() {
        let opts = UsbOptions {
            vid: 0xfffe,
            pid: 0xfffd,
            ..Default::default()
        };
        let e = UsbSource::open(&opts).err().unwrap().to_string();
        assert!(
            e.contains("no device matches USB fffe:fffd") || e.contains("cannot list USB devices"),
            "{e}"
        );
    }
}
