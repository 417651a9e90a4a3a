//! The `.spad` bit-plane container and raw packed bit-planes.
//!
//! A recording is a stream of [`BitPlane`]s of one size, one after the other,
//! each packed to one bit per pixel. It is written and read plane by plane
//! ([`RecordingWriter`], [`RecordingReader`]): nothing ever holds the whole
//! file in memory, so recordings may be far longer than memory (2³² pixel-planes
//! and more).
//!
//! # Packed plane
//!
//! Pixel `i` of a plane (raster index `i = y·W + x`) is stored in byte `i / 8`
//! of the plane, at bit `i % 8` ([`BitOrder::LsbFirst`]) or at bit
//! `7 − i % 8` ([`BitOrder::MsbFirst`]), where bit 0 is the least significant
//! bit of the byte. Each plane is padded with zero bits to a whole number of
//! bytes, so a plane takes [`plane_bytes`]`(W, H) = ⌈W·H / 8⌉` bytes and the
//! next plane starts on a byte boundary. Readers ignore the padding bits.
//!
//! # `.spad` file layout (version 1)
//!
//! A 48-byte header, then `planes` packed planes back to back, then nothing.
//! Every integer is little-endian.
//!
//! | offset | size | field             | meaning |
//! |-------:|-----:|-------------------|---------|
//! |      0 |    8 | magic             | ASCII `SPADBITS` |
//! |      8 |    2 | version           | `u16`, 1 for this layout; a reader rejects newer versions |
//! |     10 |    2 | header length     | `u16`, bytes from offset 0 to the first plane: 48 in version 1. A version-1 reader accepts a larger value and skips the extra bytes, so fields can be appended without breaking old readers |
//! |     12 |    4 | width             | `u32`, pixels, ≥ 1 |
//! |     16 |    4 | height            | `u32`, pixels, ≥ 1; `width·height` ≤ 2³¹ |
//! |     20 |    8 | plane period      | `u64`, ns from the start of one plane to the next, 1 ..= [`MAX_PLANE_PERIOD_NS`] (2³² − 1 ns, 4.29 s: the pipeline's 32-bit register) |
//! |     28 |    8 | exposure          | `u64`, ns of exposure within a plane, 1 ..= plane period |
//! |     36 |    1 | bit order         | `u8`: 0 = [`BitOrder::LsbFirst`], 1 = [`BitOrder::MsbFirst`] |
//! |     37 |    3 | reserved          | zero |
//! |     40 |    8 | planes            | `u64`, number of planes that follow; `u64::MAX` ([`PLANES_UNKNOWN`]) = "until end of file" (a live capture whose length was not known when the header was written) |
//!
//! A reader reads the first plane (when the header declares any) before
//! [`RecordingReader::open`] returns, into a buffer that grows only with the
//! bytes actually present: a short file whose header claims huge planes is
//! [`RecordingError::Truncated`] at once, before the caller allocates
//! anything sized by the header. Raw planes ([`RecordingReader::open_raw`])
//! must hold at least one whole plane ([`RecordingError::NoPlanes`]).
//!
//! A reader checks that the file holds exactly `planes` whole planes: a
//! partial last plane is [`RecordingError::Truncated`] (naming the plane and
//! the bytes found), fewer whole planes than declared is
//! [`RecordingError::MissingPlanes`], data after the last declared plane is
//! [`RecordingError::TrailingBytes`].
//!
//! # Raw packed planes
//!
//! [`RecordingReader::open_raw`] reads headerless files of packed planes (as
//! a camera's FPGA or another tool may dump them) given width, height, bit
//! order and plane period; the number of planes is whatever the file holds.

use std::io::{ErrorKind, Read, Write};

use bitvec::prelude::*;
use thiserror::Error;

use crate::plane::BitPlane;

mod planes_at;
pub use planes_at::{unpack_plane_into, PlaneAt, PlaneFile};

/// The eight bytes every `.spad` file starts with.
pub const MAGIC: [u8; 8] = *b"SPADBITS";
/// The newest container version this code reads and the one it writes.
pub const VERSION: u16 = 1;
/// Header length of version 1, bytes.
pub const HEADER_LEN_V1: u16 = 48;
/// Largest number of pixels of one plane (2³¹).
pub const MAX_PIXELS: u64 = 1 << 31;
/// `planes` value meaning "as many planes as the file holds".
pub const PLANES_UNKNOWN: u64 = u64::MAX;
/// Longest plane period, ns (2³² − 1, 4.29 s): the pipeline's period register
/// is 32 bits wide, and a SPAD bit-plane lasts microseconds.
pub const MAX_PLANE_PERIOD_NS: u64 = u32::MAX as u64;

/// Where pixel `i` sits within its byte of a packed plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BitOrder {
    /// Pixel `i` is bit `i % 8` (bit 0 = least significant) of byte `i / 8`.
    LsbFirst,
    /// Pixel `i` is bit `7 − i % 8` of byte `i / 8` (first pixel in the top bit).
    MsbFirst,
}

impl BitOrder {
    /// The header byte of this order.
    pub fn code(self) -> u8 {
        match self {
            BitOrder::LsbFirst => 0,
            BitOrder::MsbFirst => 1,
        }
    }

    /// The order of a header byte, if valid.
    pub fn from_code(code: u8) -> Option<BitOrder> {
        match code {
            0 => Some(BitOrder::LsbFirst),
            1 => Some(BitOrder::MsbFirst),
            _ => None,
        }
    }
}

/// What a `.spad` header says about the planes that follow it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RecordingHeader {
    /// Plane width, pixels.
    pub width: u32,
    /// Plane height, pixels.
    pub height: u32,
    /// Time from the start of one bit-plane to the next, ns.
    pub plane_period_ns: u64,
    /// Exposure of one bit-plane, ns (≤ the period).
    pub exposure_ns: u64,
    /// How pixels are packed into bytes.
    pub bit_order: BitOrder,
    /// Number of planes; [`PLANES_UNKNOWN`] for "until end of file".
    pub planes: u64,
}

impl RecordingHeader {
    /// Checks the fields a reader or writer relies on; the error names the field.
    pub fn validate(&self) -> Result<(), RecordingError> {
        if self.width == 0 {
            return Err(bad("width", "must be at least 1 pixel".into()));
        }
        if self.height == 0 {
            return Err(bad("height", "must be at least 1 pixel".into()));
        }
        let pixels = self.width as u64 * self.height as u64;
        if pixels > MAX_PIXELS {
            return Err(bad(
                "width x height",
                format!(
                    "{}x{} = {pixels} pixels exceeds the limit of 2^31 pixels per plane",
                    self.width, self.height
                ),
            ));
        }
        if self.plane_period_ns == 0 || self.plane_period_ns > MAX_PLANE_PERIOD_NS {
            return Err(bad(
                "plane_period_ns",
                format!(
                    "{} ns is outside 1 ..= {MAX_PLANE_PERIOD_NS} ns (4.29 s, the pipeline's 32-bit period register)",
                    self.plane_period_ns
                ),
            ));
        }
        if self.exposure_ns == 0 {
            return Err(bad("exposure_ns", "must be at least 1 ns".into()));
        }
        if self.exposure_ns > self.plane_period_ns {
            return Err(bad(
                "exposure_ns",
                format!(
                    "{} ns exceeds the plane period of {} ns",
                    self.exposure_ns, self.plane_period_ns
                ),
            ));
        }
        Ok(())
    }

    /// Bytes of one packed plane.
    pub fn plane_bytes(&self) -> usize {
        plane_bytes(self.width, self.height)
    }

    /// The 48 header bytes of version 1.
    pub fn to_bytes(&self) -> [u8; HEADER_LEN_V1 as usize] {
        let mut b = [0u8; HEADER_LEN_V1 as usize];
        b[0..8].copy_from_slice(&MAGIC);
        b[8..10].copy_from_slice(&VERSION.to_le_bytes());
        b[10..12].copy_from_slice(&HEADER_LEN_V1.to_le_bytes());
        b[12..16].copy_from_slice(&self.width.to_le_bytes());
        b[16..20].copy_from_slice(&self.height.to_le_bytes());
        b[20..28].copy_from_slice(&self.plane_period_ns.to_le_bytes());
        b[28..36].copy_from_slice(&self.exposure_ns.to_le_bytes());
        b[36] = self.bit_order.code();
        // 37..40 reserved, zero.
        b[40..48].copy_from_slice(&self.planes.to_le_bytes());
        b
    }
}

fn bad(field: &'static str, why: String) -> RecordingError {
    RecordingError::BadHeader { field, why }
}

/// Anything wrong with a recording, its header or its use.
#[derive(Debug, Error)]
pub enum RecordingError {
    /// The underlying reader or writer failed.
    #[error("recording I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// The file holds no bytes at all.
    #[error("the recording is empty (0 bytes): not a .spad file")]
    Empty,
    /// The file ends inside its header.
    #[error("the recording ends inside its header: {found} of {expected} header bytes")]
    TruncatedHeader {
        /// Bytes the header needs.
        expected: usize,
        /// Bytes the file holds.
        found: usize,
    },
    /// Raw packed planes (no header) with not a single byte.
    #[error("the raw recording is empty (0 bytes): it holds no plane of {width}x{height} pixels ({bytes} bytes each)")]
    NoPlanes {
        /// Plane width given.
        width: u32,
        /// Plane height given.
        height: u32,
        /// Bytes of one packed plane.
        bytes: usize,
    },
    /// The file does not start with `SPADBITS`.
    #[error("not a .spad recording: the file starts with {found:02x?}, expected \"SPADBITS\"")]
    BadMagic {
        /// The first bytes found.
        found: Vec<u8>,
    },
    /// Written by a newer version of the container.
    #[error("recording container version {found} is newer than the supported version {supported}")]
    UnsupportedVersion {
        /// Version in the file.
        found: u16,
        /// Newest version this code reads.
        supported: u16,
    },
    /// A header field outside its range.
    #[error("bad recording header field `{field}`: {why}")]
    BadHeader {
        /// The field.
        field: &'static str,
        /// What is wrong with it.
        why: String,
    },
    /// The file ends inside a plane.
    #[error(
        "recording truncated inside plane {plane}: {bytes_found} of the {bytes_expected} bytes of a plane present (the header's width x height may be wrong)"
    )]
    Truncated {
        /// Index of the incomplete plane (from 0).
        plane: u64,
        /// Bytes of one packed plane.
        bytes_expected: usize,
        /// Bytes of that plane present in the file.
        bytes_found: usize,
    },
    /// The file ends on a plane boundary before the declared number of planes.
    #[error("recording holds {found} planes but its header declares {declared}")]
    MissingPlanes {
        /// Planes the header declares.
        declared: u64,
        /// Whole planes present.
        found: u64,
    },
    /// Data follows the last plane the header declares.
    #[error("recording has data after its {declared} declared planes (at least {extra_bytes} extra bytes)")]
    TrailingBytes {
        /// Planes the header declares.
        declared: u64,
        /// Extra bytes seen (a lower bound: the reader stops looking after one plane's worth).
        extra_bytes: usize,
    },
    /// A plane of the wrong size was given to a writer.
    #[error("plane {plane} is {found_width}x{found_height}, the recording is {width}x{height}")]
    SizeMismatch {
        /// Index the plane would have had.
        plane: u64,
        /// Recording width.
        width: u32,
        /// Recording height.
        height: u32,
        /// Width of the plane given.
        found_width: usize,
        /// Height of the plane given.
        found_height: usize,
    },
    /// More planes written than the header declares.
    #[error("too many planes: the header declares {declared}")]
    TooManyPlanes {
        /// Planes the header declares.
        declared: u64,
    },
    /// `finish` called before all declared planes were written.
    #[error("recording finished after {written} planes but its header declares {declared}")]
    TooFewPlanes {
        /// Planes the header declares.
        declared: u64,
        /// Planes written.
        written: u64,
    },
}

/// Bytes of one packed plane of `width × height` pixels, `⌈W·H / 8⌉`.
pub fn plane_bytes(width: u32, height: u32) -> usize {
    (width as usize * height as usize).div_ceil(8)
}

/// Reverses the bit order within each byte of a word (LSB-first ↔ MSB-first),
/// keeping the byte order.
#[inline]
fn flip_bytes(w: u64) -> u64 {
    w.reverse_bits().swap_bytes()
}

/// Calls `f` with each 64-pixel word of the plane (pixel `i` at bit `i % 64`
/// of word `i / 64`), the last word zero-padded.
fn for_each_word(bits: &BitSlice<u64, Lsb0>, mut f: impl FnMut(u64)) {
    use bitvec::domain::Domain;
    match bits.domain() {
        Domain::Enclave(e) => f(e.load_value() >> e.head().into_inner()),
        Domain::Region {
            head: None,
            body,
            tail,
        } => {
            body.iter().for_each(|&w| f(w));
            if let Some(t) = tail {
                f(t.load_value());
            }
        }
        // A slice not starting on a word boundary (never the case for a
        // BitPlane, which owns its storage): slow but correct.
        Domain::Region { .. } => bits.chunks(64).for_each(|c| f(c.load_le::<u64>())),
    }
}

/// Appends the packed bytes of `plane` (see the module docs) to `out`.
///
/// Works on whole 64-bit words: a 320×240 plane is 1,200 words.
pub fn pack_plane(plane: &BitPlane, order: BitOrder, out: &mut Vec<u8>) {
    let n = plane.width() * plane.height();
    let nbytes = n.div_ceil(8);
    out.reserve(nbytes.div_ceil(8) * 8);
    let start = out.len();
    // LSB-first packing is exactly the little-endian bytes of the Lsb0 words.
    match order {
        BitOrder::LsbFirst => {
            for_each_word(plane.bits(), |w| out.extend_from_slice(&w.to_le_bytes()))
        }
        BitOrder::MsbFirst => for_each_word(plane.bits(), |w| {
            out.extend_from_slice(&flip_bytes(w).to_le_bytes())
        }),
    }
    out.truncate(start + nbytes);
}

/// Unpacks one plane from `bytes` (at least [`plane_bytes`]`(width, height)`
/// bytes; extra bytes and padding bits are ignored).
///
/// # Panics
/// If `bytes` is shorter than one plane (a programming error: readers check
/// lengths before calling this).
pub fn unpack_plane(bytes: &[u8], width: u32, height: u32, order: BitOrder) -> BitPlane {
    let mut plane = BitPlane::zeros(width as usize, height as usize);
    unpack_plane_into(bytes, order, &mut plane);
    plane
}

/// Writes a `.spad` recording plane by plane.
///
/// Wrap files in a [`std::io::BufWriter`] only for tiny planes: each plane is
/// written with one `write_all`.
#[derive(Debug)]
pub struct RecordingWriter<W: Write> {
    w: W,
    header: RecordingHeader,
    written: u64,
    buf: Vec<u8>,
}

impl<W: Write> RecordingWriter<W> {
    /// Validates `header` and writes it.
    pub fn new(mut w: W, header: RecordingHeader) -> Result<Self, RecordingError> {
        header.validate()?;
        w.write_all(&header.to_bytes())?;
        Ok(RecordingWriter {
            w,
            header,
            written: 0,
            buf: Vec::with_capacity(header.plane_bytes() + 8),
        })
    }

    /// The header written.
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// Planes written so far.
    pub fn planes_written(&self) -> u64 {
        self.written
    }

    /// Appends one plane; it must have the header's size, and no more planes
    /// than the header declares may be written.
    pub fn write_plane(&mut self, plane: &BitPlane) -> Result<(), RecordingError> {
        if plane.width() != self.header.width as usize
            || plane.height() != self.header.height as usize
        {
            return Err(RecordingError::SizeMismatch {
                plane: self.written,
                width: self.header.width,
                height: self.header.height,
                found_width: plane.width(),
                found_height: plane.height(),
            });
        }
        if self.header.planes != PLANES_UNKNOWN && self.written >= self.header.planes {
            return Err(RecordingError::TooManyPlanes {
                declared: self.header.planes,
            });
        }
        self.buf.clear();
        pack_plane(plane, self.header.bit_order, &mut self.buf);
        self.w.write_all(&self.buf)?;
        self.written += 1;
        Ok(())
    }

    /// Flushes and returns the inner writer; fails if fewer planes were
    /// written than the header declares.
    pub fn finish(mut self) -> Result<W, RecordingError> {
        self.w.flush()?;
        if self.header.planes != PLANES_UNKNOWN && self.written != self.header.planes {
            return Err(RecordingError::TooFewPlanes {
                declared: self.header.planes,
                written: self.written,
            });
        }
        Ok(self.w)
    }
}

/// Reads `buf.len()` bytes or up to end of file; returns the bytes read.
fn read_fully<R: Read>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match r.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(k) => got += k,
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

/// Reads a `.spad` recording or raw packed planes, one plane at a time.
#[derive(Debug)]
pub struct RecordingReader<R: Read> {
    r: R,
    header: RecordingHeader,
    /// Bytes before the first plane: the header's, or none (raw planes).
    data_offset: u64,
    read: u64,
    buf: Vec<u8>,
    /// `buf` holds the first plane, read by `open` and not yet returned.
    first_pending: bool,
    /// Set after the end or an error: further reads return `Ok(None)`.
    done: bool,
}

impl<R: Read> RecordingReader<R> {
    /// Reads and checks a `.spad` header.
    pub fn open(mut r: R) -> Result<Self, RecordingError> {
        let mut fixed = [0u8; HEADER_LEN_V1 as usize];
        let got = read_fully(&mut r, &mut fixed)?;
        if got == 0 {
            return Err(RecordingError::Empty);
        }
        // Check what we have of the magic before complaining about length,
        // so a short non-.spad file says "not a .spad file".
        let m = got.min(8);
        if fixed[..m] != MAGIC[..m] {
            return Err(RecordingError::BadMagic {
                found: fixed[..m].to_vec(),
            });
        }
        if got >= 10 {
            let version = u16::from_le_bytes([fixed[8], fixed[9]]);
            if version > VERSION {
                return Err(RecordingError::UnsupportedVersion {
                    found: version,
                    supported: VERSION,
                });
            }
            if version == 0 {
                return Err(bad("version", "0 is not a valid version".into()));
            }
        }
        if got < fixed.len() {
            return Err(RecordingError::TruncatedHeader {
                expected: HEADER_LEN_V1 as usize,
                found: got,
            });
        }
        let u32_at = |o: usize| u32::from_le_bytes(fixed[o..o + 4].try_into().expect("4 bytes"));
        let u64_at = |o: usize| u64::from_le_bytes(fixed[o..o + 8].try_into().expect("8 bytes"));
        let header_len = u16::from_le_bytes([fixed[10], fixed[11]]);
        if header_len < HEADER_LEN_V1 {
            return Err(bad(
                "header_length",
                format!("{header_len} bytes, version 1 needs at least {HEADER_LEN_V1}"),
            ));
        }
        let bit_order = BitOrder::from_code(fixed[36]).ok_or_else(|| {
            bad(
                "bit_order",
                format!("{} is neither 0 (LSB first) nor 1 (MSB first)", fixed[36]),
            )
        })?;
        if fixed[37..40] != [0, 0, 0] {
            return Err(bad("reserved", "bytes 37..40 must be zero".into()));
        }
        let header = RecordingHeader {
            width: u32_at(12),
            height: u32_at(16),
            plane_period_ns: u64_at(20),
            exposure_ns: u64_at(28),
            bit_order,
            planes: u64_at(40),
        };
        header.validate()?;
        // Skip header bytes appended by later minor revisions.
        let extra = (header_len - HEADER_LEN_V1) as usize;
        if extra > 0 {
            let mut skip = vec![0u8; extra];
            let got2 = read_fully(&mut r, &mut skip)?;
            if got2 < extra {
                return Err(RecordingError::TruncatedHeader {
                    expected: header_len as usize,
                    found: HEADER_LEN_V1 as usize + got2,
                });
            }
        }
        let mut rd = Self::with_header(r, header, header_len.into());
        rd.read_first_plane(false)?;
        Ok(rd)
    }

    /// Reads headerless packed planes of the given size and order; the
    /// exposure is taken equal to the period and the number of planes is
    /// [`PLANES_UNKNOWN`] (read until end of file; a partial last plane is
    /// [`RecordingError::Truncated`], an empty input
    /// [`RecordingError::NoPlanes`]).
    pub fn open_raw(
        r: R,
        width: u32,
        height: u32,
        bit_order: BitOrder,
        plane_period_ns: u64,
    ) -> Result<Self, RecordingError> {
        let header = RecordingHeader {
            width,
            height,
            plane_period_ns,
            exposure_ns: plane_period_ns,
            bit_order,
            planes: PLANES_UNKNOWN,
        };
        header.validate()?;
        let mut rd = Self::with_header(r, header, 0);
        rd.read_first_plane(true)?;
        Ok(rd)
    }

    fn with_header(r: R, header: RecordingHeader, data_offset: u64) -> Self {
        RecordingReader {
            r,
            header,
            data_offset,
            read: 0,
            buf: Vec::new(),
            first_pending: false,
            done: false,
        }
    }

    /// Reads the first plane into `buf` with a buffer that grows only with
    /// the bytes present, so that a header claiming planes far larger than
    /// the input fails here, before anything sized by the header is
    /// allocated. `raw`: an empty input is an error.
    fn read_first_plane(&mut self, raw: bool) -> Result<(), RecordingError> {
        let declared = self.header.planes;
        if declared == 0 {
            return Ok(());
        }
        let need = self.header.plane_bytes();
        let mut first = Vec::new();
        loop {
            match (&mut self.r).take(need as u64).read_to_end(&mut first) {
                Ok(_) => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
        if first.is_empty() {
            if raw {
                return Err(RecordingError::NoPlanes {
                    width: self.header.width,
                    height: self.header.height,
                    bytes: need,
                });
            }
            if declared != PLANES_UNKNOWN {
                return Err(RecordingError::MissingPlanes { declared, found: 0 });
            }
            // A live capture that ended before its first plane: no planes.
            self.done = true;
            return Ok(());
        }
        if first.len() < need {
            return Err(RecordingError::Truncated {
                plane: 0,
                bytes_expected: need,
                bytes_found: first.len(),
            });
        }
        self.buf = first;
        self.first_pending = true;
        Ok(())
    }

    /// The header (for raw planes: the one given to [`Self::open_raw`]).
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// Bytes before the first plane in the input: the header's length, or 0
    /// for raw planes.
    pub fn data_offset(&self) -> u64 {
        self.data_offset
    }

    /// Planes returned so far.
    pub fn planes_read(&self) -> u64 {
        self.read
    }

    /// The next plane, `Ok(None)` at the end. After an error or the end, every
    /// further call returns `Ok(None)`.
    pub fn read_plane(&mut self) -> Result<Option<BitPlane>, RecordingError> {
        if self.done {
            return Ok(None);
        }
        let result = self.read_plane_inner();
        if !matches!(result, Ok(Some(_))) {
            self.done = true;
        }
        result
    }

    fn read_plane_inner(&mut self) -> Result<Option<BitPlane>, RecordingError> {
        if std::mem::take(&mut self.first_pending) {
            self.read += 1;
            return Ok(Some(unpack_plane(
                &self.buf,
                self.header.width,
                self.header.height,
                self.header.bit_order,
            )));
        }
        let declared = self.header.planes;
        if declared != PLANES_UNKNOWN && self.read == declared {
            // All declared planes read: the file must end here (a small
            // buffer: a header declaring 0 planes of a huge size allocates
            // nothing sized by it).
            let mut probe = vec![0u8; self.header.plane_bytes().min(1 << 16)];
            let got = read_fully(&mut self.r, &mut probe)?;
            if got > 0 {
                return Err(RecordingError::TrailingBytes {
                    declared,
                    extra_bytes: got,
                });
            }
            return Ok(None);
        }
        if self.buf.len() != self.header.plane_bytes() {
            // Only after a first whole plane was found (see `open`).
            self.buf = vec![0u8; self.header.plane_bytes()];
        }
        let got = read_fully(&mut self.r, &mut self.buf)?;
        if got == 0 {
            if declared == PLANES_UNKNOWN {
                return Ok(None);
            }
            return Err(RecordingError::MissingPlanes {
                declared,
                found: self.read,
            });
        }
        if got < self.buf.len() {
            return Err(RecordingError::Truncated {
                plane: self.read,
                bytes_expected: self.buf.len(),
                bytes_found: got,
            });
        }
        self.read += 1;
        Ok(Some(unpack_plane(
            &self.buf,
            self.header.width,
            self.header.height,
            self.header.bit_order,
        )))
    }
}

impl<R: Read> Iterator for RecordingReader<R> {
    type Item = Result<BitPlane, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.read_plane().transpose()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{Rng, SeedableRng};

    /// A header of `w × h` planes at 10 kHz (the planes' tests share it).
    pub(super) fn header(w: u32, h: u32, planes: u64, order: BitOrder) -> RecordingHeader {
        RecordingHeader {
            width: w,
            height: h,
            plane_period_ns: 100_000,
            exposure_ns: 100_000,
            bit_order: order,
            planes,
        }
    }

    /// A plane of 30 % ones (the planes' tests share it).
    pub(super) fn random_plane(w: usize, h: usize, seed: u64) -> BitPlane {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        BitPlane::from_fn(w, h, |_, _| rng.gen_bool(0.3))
    }

    fn write_all(h: RecordingHeader, planes: &[BitPlane]) -> Vec<u8> {
        let mut wr = RecordingWriter::new(Vec::new(), h).unwrap();
        for p in planes {
            wr.write_plane(p).unwrap();
        }
        wr.finish().unwrap()
    }

    #[test]
    fn header_layout_is_byte_exact() {
        let h = RecordingHeader {
            width: 320,
            height: 240,
            plane_period_ns: 100_000,
            exposure_ns: 90_000,
            bit_order: BitOrder::MsbFirst,
            planes: 0x0102_0304_0506_0708,
        };
        let b = h.to_bytes();
        let expected = "5350414442495453 0100 3000 40010000 f0000000 a086010000000000 905f010000000000 01 000000 0807060504030201";
        assert_eq!(hex::encode(b), expected.replace(' ', ""));
    }

    #[test]
    fn both_bit_orders_place_pixels_as_documented() {
        // 3x4 = 12 pixels, pixels 0, 2 and 9 set -> 2 bytes.
        let mut p = BitPlane::zeros(3, 4);
        p.set(0, 0, true); // i = 0
        p.set(2, 0, true); // i = 2
        p.set(0, 3, true); // i = 9
        let mut lsb = Vec::new();
        pack_plane(&p, BitOrder::LsbFirst, &mut lsb);
        assert_eq!(lsb, vec![0b0000_0101, 0b0000_0010]);
        let mut msb = Vec::new();
        pack_plane(&p, BitOrder::MsbFirst, &mut msb);
        assert_eq!(msb, vec![0b1010_0000, 0b0100_0000]);
        assert_eq!(unpack_plane(&lsb, 3, 4, BitOrder::LsbFirst), p);
        assert_eq!(unpack_plane(&msb, 3, 4, BitOrder::MsbFirst), p);
        // The orders are not interchangeable.
        assert_ne!(unpack_plane(&msb, 3, 4, BitOrder::LsbFirst), p);
    }

    #[test]
    fn padding_bits_are_ignored_and_zero_on_write() {
        let p = BitPlane::ones(3, 3); // 9 bits -> 2 bytes, 7 padding bits
        let mut v = Vec::new();
        pack_plane(&p, BitOrder::LsbFirst, &mut v);
        assert_eq!(v, vec![0xff, 0x01]);
        assert_eq!(unpack_plane(&[0xff, 0xff], 3, 3, BitOrder::LsbFirst), p);
    }

    #[test]
    fn word_packing_matches_bit_by_bit_packing() {
        for (w, h) in [(320, 240), (7, 13), (64, 1), (65, 2), (1, 1)] {
            let p = random_plane(w, h, (w * h) as u64);
            for order in [BitOrder::LsbFirst, BitOrder::MsbFirst] {
                let mut slow = vec![0u8; (w * h).div_ceil(8)];
                for i in 0..w * h {
                    if p.get(i % w, i / w) {
                        let bit = match order {
                            BitOrder::LsbFirst => i % 8,
                            BitOrder::MsbFirst => 7 - i % 8,
                        };
                        slow[i / 8] |= 1 << bit;
                    }
                }
                let mut fast = Vec::new();
                pack_plane(&p, order, &mut fast);
                assert_eq!(fast, slow, "{w}x{h} {order:?}");
            }
        }
    }

    #[test]
    fn round_trip_file_and_iterator() {
        let planes: Vec<_> = (0..5).map(|s| random_plane(17, 5, s)).collect();
        let h = header(17, 5, 5, BitOrder::MsbFirst);
        let bytes = write_all(h, &planes);
        assert_eq!(bytes.len(), 48 + 5 * plane_bytes(17, 5));
        let rd = RecordingReader::open(&bytes[..]).unwrap();
        assert_eq!(*rd.header(), h);
        let back: Vec<_> = rd.map(|r| r.unwrap()).collect();
        assert_eq!(back, planes);
    }

    #[test]
    fn raw_planes_read_until_eof() {
        let planes: Vec<_> = (0..4).map(|s| random_plane(10, 3, s)).collect();
        let mut raw = Vec::new();
        for p in &planes {
            pack_plane(p, BitOrder::LsbFirst, &mut raw);
        }
        let mut rd =
            RecordingReader::open_raw(&raw[..], 10, 3, BitOrder::LsbFirst, 100_000).unwrap();
        assert_eq!(rd.header().planes, PLANES_UNKNOWN);
        let mut back = Vec::new();
        while let Some(p) = rd.read_plane().unwrap() {
            back.push(p);
        }
        assert_eq!(back, planes);
        assert_eq!(rd.planes_read(), 4);
        // A partial last plane names the plane and the bytes.
        raw.push(0xaa);
        let mut rd =
            RecordingReader::open_raw(&raw[..], 10, 3, BitOrder::LsbFirst, 100_000).unwrap();
        for _ in 0..4 {
            rd.read_plane().unwrap().unwrap();
        }
        match rd.read_plane() {
            Err(RecordingError::Truncated {
                plane: 4,
                bytes_expected: 4,
                bytes_found: 1,
            }) => {}
            other => panic!("{other:?}"),
        }
        assert!(
            rd.read_plane().unwrap().is_none(),
            "reads stop after an error"
        );
        assert!(RecordingReader::open_raw(&raw[..], 0, 3, BitOrder::LsbFirst, 1).is_err());
        assert!(RecordingReader::open_raw(&raw[..], 3, 3, BitOrder::LsbFirst, 0).is_err());
    }

    #[test]
    fn a_short_file_claiming_huge_planes_fails_at_open() {
        // 4 KB claiming 65535x32768 pixels (268 MB per plane).
        let mut b = header(65535, 32768, 10, BitOrder::LsbFirst)
            .to_bytes()
            .to_vec();
        b.resize(4096, 0x5a);
        let e = RecordingReader::open(&b[..]).unwrap_err();
        assert!(
            matches!(
                e,
                RecordingError::Truncated {
                    plane: 0,
                    bytes_expected: 268_431_360,
                    bytes_found: 4048
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("width x height"), "{e}");
        // Unknown length too; a header alone declaring planes is missing them.
        b[40..48].copy_from_slice(&PLANES_UNKNOWN.to_le_bytes());
        assert!(RecordingReader::open(&b[..]).is_err());
        let e = RecordingReader::open(&b[..48]).map(|r| r.header().planes);
        assert_eq!(
            e.unwrap(),
            PLANES_UNKNOWN,
            "a live capture with no plane yet"
        );
        let h = header(65535, 32768, 10, BitOrder::LsbFirst).to_bytes();
        let e = RecordingReader::open(&h[..]).unwrap_err();
        assert!(
            matches!(
                e,
                RecordingError::MissingPlanes {
                    declared: 10,
                    found: 0
                }
            ),
            "{e}"
        );
        // Zero planes of a huge size: the trailing-byte check reads little.
        let h = header(65535, 32768, 0, BitOrder::LsbFirst).to_bytes();
        let mut rd = RecordingReader::open(&h[..]).unwrap();
        assert!(rd.read_plane().unwrap().is_none());
    }

    #[test]
    fn raw_input_without_a_plane_is_an_error() {
        let e = RecordingReader::open_raw(&[][..], 64, 64, BitOrder::LsbFirst, 10_000).unwrap_err();
        assert!(
            matches!(e, RecordingError::NoPlanes { bytes: 512, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("empty"), "{e}");
        let e = RecordingReader::open_raw(&[1u8; 100][..], 64, 64, BitOrder::LsbFirst, 10_000)
            .unwrap_err();
        assert!(
            matches!(e, RecordingError::Truncated { plane: 0, .. }),
            "{e}"
        );
    }

    #[test]
    fn plane_periods_beyond_the_32_bit_register_are_refused() {
        let mut h = header(8, 8, 0, BitOrder::LsbFirst);
        h.plane_period_ns = MAX_PLANE_PERIOD_NS;
        assert!(h.validate().is_ok());
        h.plane_period_ns = MAX_PLANE_PERIOD_NS + 1;
        let e = h.validate().unwrap_err().to_string();
        assert!(
            e.contains("plane_period_ns") && e.contains("4294967295 ns"),
            "{e}"
        );
    }

    #[test]
    fn empty_file() {
        let e = RecordingReader::open(&[][..]).unwrap_err();
        assert!(matches!(e, RecordingError::Empty), "{e}");
        assert!(e.to_string().contains("empty"));
    }

    #[test]
    fn bad_magic_and_short_garbage() {
        let h = header(4, 4, 0, BitOrder::LsbFirst);
        let mut b = write_all(h, &[]);
        b[0] = b'X';
        assert!(matches!(
            RecordingReader::open(&b[..]),
            Err(RecordingError::BadMagic { .. })
        ));
        // A short text file is "not a .spad file", not "truncated".
        let e = RecordingReader::open(&b"hello"[..]).unwrap_err();
        assert!(matches!(e, RecordingError::BadMagic { .. }), "{e}");
        // A genuine header cut short is a truncated header.
        let b = write_all(h, &[]);
        let e = RecordingReader::open(&b[..20]).unwrap_err();
        assert!(
            matches!(
                e,
                RecordingError::TruncatedHeader {
                    expected: 48,
                    found: 20
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn newer_version_is_refused() {
        let mut b = write_all(header(4, 4, 0, BitOrder::LsbFirst), &[]);
        b[8..10].copy_from_slice(&2u16.to_le_bytes());
        match RecordingReader::open(&b[..]) {
            Err(RecordingError::UnsupportedVersion {
                found: 2,
                supported: 1,
            }) => {}
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn longer_header_is_skipped() {
        let p = random_plane(9, 9, 1);
        let mut b = write_all(
            header(9, 9, 1, BitOrder::LsbFirst),
            std::slice::from_ref(&p),
        );
        b[10..12].copy_from_slice(&56u16.to_le_bytes());
        b.splice(48..48, [0xee; 8]);
        let mut rd = RecordingReader::open(&b[..]).unwrap();
        assert_eq!(rd.read_plane().unwrap().unwrap(), p);
        assert!(rd.read_plane().unwrap().is_none());
    }

    #[test]
    fn bad_header_fields_are_named() {
        let cases: [(usize, Vec<u8>, &str); 7] = [
            (12, 0u32.to_le_bytes().to_vec(), "width"),
            (16, 0u32.to_le_bytes().to_vec(), "height"),
            (12, 65536u32.to_le_bytes().to_vec(), "width x height"),
            (20, 0u64.to_le_bytes().to_vec(), "plane_period_ns"),
            (28, 200_000u64.to_le_bytes().to_vec(), "exposure_ns"),
            (36, vec![7], "bit_order"),
            (10, 20u16.to_le_bytes().to_vec(), "header_length"),
        ];
        for (off, bytes, field) in cases {
            let mut b = write_all(header(4, 40_000, 0, BitOrder::LsbFirst), &[]);
            b[off..off + bytes.len()].copy_from_slice(&bytes);
            match RecordingReader::open(&b[..]) {
                Err(RecordingError::BadHeader { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
        // The writer refuses the same things.
        let e = RecordingWriter::new(Vec::new(), header(65536, 65536, 1, BitOrder::LsbFirst))
            .unwrap_err();
        assert!(e.to_string().contains("2^31"), "{e}");
    }

    #[test]
    fn truncated_last_plane_names_plane_and_bytes() {
        let planes: Vec<_> = (0..3).map(|s| random_plane(32, 32, s)).collect();
        let b = write_all(header(32, 32, 3, BitOrder::LsbFirst), &planes);
        let cut = &b[..b.len() - 100];
        let rd = RecordingReader::open(cut).unwrap();
        let items: Vec<_> = rd.collect();
        assert_eq!(items.len(), 3);
        assert!(items[0].is_ok() && items[1].is_ok());
        let e = items[2].as_ref().unwrap_err();
        assert!(
            matches!(
                e,
                RecordingError::Truncated {
                    plane: 2,
                    bytes_expected: 128,
                    bytes_found: 28
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("plane 2"));
    }

    #[test]
    fn fewer_or_more_planes_than_declared() {
        let planes: Vec<_> = (0..3).map(|s| random_plane(8, 8, s)).collect();
        let b = write_all(header(8, 8, 3, BitOrder::LsbFirst), &planes);
        // One whole plane missing.
        let short = &b[..b.len() - 8];
        let r: Result<Vec<_>, _> = RecordingReader::open(short).unwrap().collect();
        assert!(
            matches!(
                r,
                Err(RecordingError::MissingPlanes {
                    declared: 3,
                    found: 2
                })
            ),
            "{r:?}"
        );
        // Extra data after the last plane.
        let mut long = b.clone();
        long.extend_from_slice(&[1, 2, 3]);
        let r: Result<Vec<_>, _> = RecordingReader::open(&long[..]).unwrap().collect();
        assert!(
            matches!(
                r,
                Err(RecordingError::TrailingBytes {
                    declared: 3,
                    extra_bytes: 3
                })
            ),
            "{r:?}"
        );
        // Exactly right.
        let r: Result<Vec<_>, _> = RecordingReader::open(&b[..]).unwrap().collect();
        assert_eq!(r.unwrap(), planes);
    }

    #[test]
    fn writer_checks_size_and_count() {
        let mut wr = RecordingWriter::new(Vec::new(), header(8, 8, 1, BitOrder::LsbFirst)).unwrap();
        let e = wr.write_plane(&BitPlane::zeros(8, 7)).unwrap_err();
        assert!(
            matches!(
                e,
                RecordingError::SizeMismatch {
                    found_height: 7,
                    ..
                }
            ),
            "{e}"
        );
        wr.write_plane(&BitPlane::zeros(8, 8)).unwrap();
        let e = wr.write_plane(&BitPlane::zeros(8, 8)).unwrap_err();
        assert!(
            matches!(e, RecordingError::TooManyPlanes { declared: 1 }),
            "{e}"
        );
        assert!(wr.finish().is_ok());
        let wr = RecordingWriter::new(Vec::new(), header(8, 8, 2, BitOrder::LsbFirst)).unwrap();
        let e = wr.finish().unwrap_err();
        assert!(
            matches!(
                e,
                RecordingError::TooFewPlanes {
                    declared: 2,
                    written: 0
                }
            ),
            "{e}"
        );
        // Unknown length: any count is fine and the reader stops at EOF.
        let mut wr =
            RecordingWriter::new(Vec::new(), header(8, 8, PLANES_UNKNOWN, BitOrder::LsbFirst))
                .unwrap();
        wr.write_plane(&BitPlane::ones(8, 8)).unwrap();
        let b = wr.finish().unwrap();
        let r: Vec<_> = RecordingReader::open(&b[..])
            .unwrap()
            .map(|p| p.unwrap())
            .collect();
        assert_eq!(r, vec![BitPlane::ones(8, 8)]);
    }

    /// A reader that returns at most 3 bytes per call and sometimes `Interrupted`.
    struct Dribble<'a>(&'a [u8], u32);
    impl Read for Dribble<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.1 += 1;
            if self.1.is_multiple_of(5) {
                return Err(std::io::Error::new(ErrorKind::Interrupted, "again"));
            }
            let k = buf.len().min(3).min(self.0.len());
            buf[..k].copy_from_slice(&self.0[..k]);
            self.0 = &self.0[k..];
            Ok(k)
        }
    }

    #[test]
    fn short_reads_are_assembled() {
        let planes: Vec<_> = (0..3).map(|s| random_plane(13, 11, s)).collect();
        let b = write_all(header(13, 11, 3, BitOrder::MsbFirst), &planes);
        let back: Vec<_> = RecordingReader::open(Dribble(&b, 0))
            .unwrap()
            .map(|p| p.unwrap())
            .collect();
        assert_eq!(back, planes);
    }

    proptest! {
        #[test]
        fn prop_round_trip(w in 1u32..70, h in 1u32..20, n in 0usize..5, msb: bool, seed: u64) {
            let order = if msb { BitOrder::MsbFirst } else { BitOrder::LsbFirst };
            let planes: Vec<_> = (0..n).map(|i| random_plane(w as usize, h as usize, seed ^ i as u64)).collect();
            let b = write_all(header(w, h, n as u64, order), &planes);
            prop_assert_eq!(b.len(), 48 + n * plane_bytes(w, h));
            let back: Vec<_> = RecordingReader::open(&b[..]).unwrap().map(|p| p.unwrap()).collect();
            prop_assert_eq!(back, planes);
        }

        #[test]
        fn prop_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200), prefix: bool) {
            let mut b = if prefix { header(5, 3, 4, BitOrder::LsbFirst).to_bytes().to_vec() } else { Vec::new() };
            b.extend_from_slice(&bytes);
            if let Ok(rd) = RecordingReader::open(&b[..]) {
                // Bounded: every item consumes bytes or ends the stream.
                for item in rd.take(1000) {
                    let _ = item;
                }
            }
        }
    }
}
