//! File input and output for the smartagg workspace: TIFF stacks and
//! images (the one place that talks to the `tiff` crate), and outputs that
//! are never left half-written.
//!
//! * [`stack`]: multi-page greyscale stacks — camera frames and exported
//!   ROIs. [`stack::StackWriter`] streams 16-bit frames (BigTIFF past 4 GiB),
//!   [`stack::write_stack`] writes integer pages (16-bit, or 32-bit float if a
//!   value needs it) and [`stack::StackReader`] reads any greyscale stack one
//!   page at a time.
//! * [`image`]: single-page 32-bit float and 8-bit images — rendered
//!   densities with their ImageJ pixel size, calibration maps with their
//!   description.
//! * [`output`]: writing any output file without losing anything: it
//!   appears at its target only once complete ([`output::AtomicFile`],
//!   [`output::write_atomic`]) and never over one of the inputs
//!   ([`output::refuse_overwriting`]).
//!
//! Users: `smartagg-scene` (simulated camera stacks), `smartagg-localize`
//! (frame input, ROI export), `smartagg-calibration` (calibration stacks,
//! maps and report files) and the `smartagg` host (rendered images, every
//! output file). The crate depends on no project crate; every TIFF failure
//! is an [`Error`] that names the file or stream, every output failure an
//! [`output::OutputError`] that names the file, which each user converts
//! into its own error type.

pub mod image;
pub mod output;
mod samples;
pub mod stack;

pub use samples::Samples;

use std::fmt;

/// A TIFF read or write that failed: which file or stream, and what failed.
#[derive(Debug, thiserror::Error)]
#[error("{name}: {kind}")]
pub struct Error {
    /// The file (or a description of the stream, e.g. `output stack`).
    pub name: String,
    /// What went wrong.
    pub kind: ErrorKind,
}

/// What went wrong in an [`Error`]. Pages count from 1, as ImageJ's slices.
#[derive(Debug, thiserror::Error)]
pub enum ErrorKind {
    /// Opening or creating the file failed.
    #[error("{0}")]
    File(std::io::Error),
    /// The header is not that of a TIFF file.
    #[error("not a readable TIFF file: {0}")]
    NotTiff(tiff::TiffError),
    /// Decoding a page failed (a broken directory, truncated data, ...).
    #[error("page {page}: {source}")]
    Page {
        /// The page, from 1.
        page: u64,
        /// The decoder's error.
        source: tiff::TiffError,
    },
    /// The link from a good page to the next one is broken.
    #[error("after page {page}: {source}")]
    NextPage {
        /// The last page read, from 1.
        page: u64,
        /// The decoder's error.
        source: tiff::TiffError,
    },
    /// A page is not greyscale.
    #[error("page {page}: colour type {colour}: expected a greyscale image")]
    NotGrey {
        /// The page, from 1.
        page: u64,
        /// The TIFF colour type, as `tiff` names it.
        colour: String,
    },
    /// A page has another size than the first.
    #[error("page {page} is {width}x{height} pixels, but the first page is {first_width}x{first_height}")]
    PageSize {
        /// The page, from 1.
        page: u64,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
        /// Width of the first page.
        first_width: u32,
        /// Height of the first page.
        first_height: u32,
    },
    /// A page holds another number of samples than pixels.
    #[error("page {page} holds {found} samples for {width}x{height} pixels (colour or multi-sample pages are not frames)")]
    SampleCount {
        /// The page, from 1.
        page: u64,
        /// Samples decoded.
        found: usize,
        /// Page width.
        width: u32,
        /// Page height.
        height: u32,
    },
    /// A page has another sample type than the one asked for.
    #[error("page {page} is {found}, not {wanted} greyscale")]
    SampleType {
        /// The page, from 1.
        page: u64,
        /// The sample type found (`u8`, `f32`, ...).
        found: &'static str,
        /// The sample type wanted.
        wanted: &'static str,
    },
    /// A single-page image has more pages.
    #[error("has more than one page; an image has one")]
    MorePages,
    /// Data handed to a writer do not have width × height values.
    #[error("{found} values for a {width}x{height} page")]
    DataSize {
        /// Values given.
        found: usize,
        /// Page width.
        width: u32,
        /// Page height.
        height: u32,
    },
    /// The encoder failed.
    #[error("writing: {0}")]
    Write(tiff::TiffError),
}

impl Error {
    /// An error about `name`.
    pub fn new(name: impl fmt::Display, kind: ErrorKind) -> Self {
        Error {
            name: name.to_string(),
            kind,
        }
    }

    /// What failed, without the file name (for errors that carry the name
    /// separately).
    pub fn why(&self) -> String {
        self.kind.to_string()
    }
}

/// Checks that `len` values fill a `width × height` page.
fn check_len(name: &str, len: usize, width: u32, height: u32) -> Result<(), Error> {
    if len == width as usize * height as usize {
        Ok(())
    } else {
        Err(Error::new(
            name,
            ErrorKind::DataSize {
                found: len,
                width,
                height,
            },
        ))
    }
}
