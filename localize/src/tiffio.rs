//! TIFF stacks: frame input (EMCCD, sCMOS, fixed-aggregation SPAD frames)
//! and aggregated-ROI export, so that ROIs can also be localised in
//! ThunderSTORM as in the paper.
//!
//! Input: every page of a multi-page greyscale TIFF (8/16/32-bit integer or
//! 32/64-bit float, as written by ImageJ/Fiji, Micro-Manager and the
//! simulator), read one page at a time so a long stack never has to fit in
//! memory. All pages must have the size of the first. Output: 16-bit pages
//! (32-bit float if a count exceeds 65 535, exact to 2²⁴), which ImageJ opens
//! as a stack.

use crate::error::LocalizeError;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, Write};
use std::path::Path;
use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::{colortype, TiffEncoder};

/// One greyscale frame, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Pixel values.
    pub data: Vec<f64>,
}

/// Pages of a TIFF file, decoded lazily.
pub struct TiffStack<R: Read + Seek> {
    decoder: Decoder<R>,
    name: String,
    page: usize,
    size: Option<(usize, usize)>,
    done: bool,
}

/// Opens a TIFF stack for reading.
pub fn open_stack(path: &Path) -> Result<TiffStack<SeekBufReader<File>>, LocalizeError> {
    let file = File::open(path).map_err(|e| tiff_err(path.display(), e))?;
    TiffStack::new(SeekBufReader::new(file), &path.display().to_string())
}

/// A buffered reader that keeps its buffer across seeks that land inside
/// it. The TIFF decoder seeks to every page's directory and strips, and
/// `BufReader` drops its buffer on every seek: on a stack of small frames
/// that was a system call per seek, a fifth of the run time.
pub struct SeekBufReader<R> {
    inner: R,
    buf: Box<[u8]>,
    /// Offset in `inner` of `buf[0]`; `inner` is positioned at `start + len`.
    start: u64,
    len: usize,
    pos: usize,
}

impl<R: Read + Seek> SeekBufReader<R> {
    /// Wraps a reader positioned at its start, with a 256 KiB buffer.
    pub fn new(inner: R) -> Self {
        SeekBufReader {
            inner,
            buf: vec![0; 256 << 10].into_boxed_slice(),
            start: 0,
            len: 0,
            pos: 0,
        }
    }
}

impl<R: Read + Seek> Read for SeekBufReader<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        if self.pos == self.len {
            if out.len() >= self.buf.len() {
                // Large reads bypass the buffer.
                let n = self.inner.read(out)?;
                self.start += (self.len + n) as u64;
                self.len = 0;
                self.pos = 0;
                return Ok(n);
            }
            self.start += self.len as u64;
            self.len = 0;
            self.pos = 0;
            self.len = self.inner.read(&mut self.buf)?;
        }
        let n = out.len().min(self.len - self.pos);
        out[..n].copy_from_slice(&self.buf[self.pos..self.pos + n]);
        self.pos += n;
        Ok(n)
    }
}

impl<R: Read + Seek> Seek for SeekBufReader<R> {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        use std::io::SeekFrom;
        let here = self.start + self.pos as u64;
        let target = match to {
            SeekFrom::Start(n) => Some(n),
            SeekFrom::Current(d) => here.checked_add_signed(d),
            SeekFrom::End(_) => None,
        };
        if let Some(t) = target {
            if t >= self.start && t <= self.start + self.len as u64 {
                self.pos = (t - self.start) as usize;
                return Ok(t);
            }
        }
        let to = match (to, target) {
            (SeekFrom::Current(_), Some(t)) => SeekFrom::Start(t),
            (SeekFrom::Current(_), None) => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    "seek before the start of the file",
                ))
            }
            (other, _) => other,
        };
        let t = self.inner.seek(to)?;
        self.start = t;
        self.len = 0;
        self.pos = 0;
        Ok(t)
    }
}

/// "FILE page N", formatted only for an error.
struct PageName<'a>(&'a str, usize);

impl std::fmt::Display for PageName<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} page {}", self.0, self.1)
    }
}

fn tiff_err(name: impl std::fmt::Display, e: impl std::fmt::Display) -> LocalizeError {
    LocalizeError::Tiff {
        path: name.to_string(),
        why: e.to_string(),
    }
}

impl<R: Read + Seek> TiffStack<R> {
    /// Reads the header of a TIFF stream (`name` is for messages).
    pub fn new(reader: R, name: &str) -> Result<Self, LocalizeError> {
        let decoder = Decoder::new(reader).map_err(|e| tiff_err(name, e))?;
        Ok(TiffStack {
            decoder,
            name: name.to_string(),
            page: 0,
            size: None,
            done: false,
        })
    }

    fn read_page(&mut self) -> Result<Frame, LocalizeError> {
        // Messages name the page; built only when needed.
        let name = PageName(&self.name, self.page + 1);
        let (w, h) = self.decoder.dimensions().map_err(|e| tiff_err(&name, e))?;
        let ct = self.decoder.colortype().map_err(|e| tiff_err(&name, e))?;
        if !matches!(ct, tiff::ColorType::Gray(_)) {
            return Err(tiff_err(
                &name,
                format!("colour type {ct:?}: expected a greyscale image"),
            ));
        }
        let (w, h) = (w as usize, h as usize);
        if let Some((w0, h0)) = self.size {
            if (w, h) != (w0, h0) {
                return Err(tiff_err(
                    &name,
                    format!("{w}x{h} pixels, but the first page is {w0}x{h0}"),
                ));
            }
        }
        self.size = Some((w, h));
        let img = self.decoder.read_image().map_err(|e| tiff_err(&name, e))?;
        let data: Vec<f64> = match img {
            DecodingResult::U8(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::U16(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::U32(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::U64(v) => v.into_iter().map(|x| x as f64).collect(),
            DecodingResult::I8(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::I16(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::I32(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::I64(v) => v.into_iter().map(|x| x as f64).collect(),
            DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
            DecodingResult::F64(v) => v,
        };
        if data.len() != w * h {
            return Err(tiff_err(
                &name,
                format!("{} samples for {w}x{h} pixels", data.len()),
            ));
        }
        Ok(Frame {
            width: w,
            height: h,
            data,
        })
    }
}

impl<R: Read + Seek> Iterator for TiffStack<R> {
    type Item = Result<Frame, LocalizeError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let frame = self.read_page();
        self.page += 1;
        if frame.is_err() || !self.decoder.more_images() {
            self.done = true;
        } else if let Err(e) = self.decoder.next_image() {
            self.done = true;
            if frame.is_ok() {
                // The page read is good; report the broken link with the next.
                return Some(Err(tiff_err(
                    &self.name,
                    format!("after page {}: {e}", self.page),
                )));
            }
        }
        Some(frame)
    }
}

/// Writes integer pages as a stack: 16-bit if every value fits, else 32-bit
/// float. Returns whether 16 bits were used.
pub fn write_stack<W: Write + Seek>(
    writer: W,
    width: usize,
    height: usize,
    pages: &[Vec<u32>],
) -> Result<bool, LocalizeError> {
    let name = "output stack";
    if pages.iter().any(|p| p.len() != width * height) {
        return Err(tiff_err(name, "a page does not have width × height values"));
    }
    let fits16 = pages.iter().flatten().all(|&v| v <= u16::MAX as u32);
    let mut enc = TiffEncoder::new(writer).map_err(|e| tiff_err(name, e))?;
    for p in pages {
        if fits16 {
            let v: Vec<u16> = p.iter().map(|&x| x as u16).collect();
            enc.write_image::<colortype::Gray16>(width as u32, height as u32, &v)
                .map_err(|e| tiff_err(name, e))?;
        } else {
            let v: Vec<f32> = p.iter().map(|&x| x as f32).collect();
            enc.write_image::<colortype::Gray32Float>(width as u32, height as u32, &v)
                .map_err(|e| tiff_err(name, e))?;
        }
    }
    Ok(fits16)
}

/// Writes a 32-bit float greyscale image (e.g. a rendered density).
pub fn write_f32<W: Write + Seek>(
    writer: W,
    width: usize,
    height: usize,
    data: &[f32],
) -> Result<(), LocalizeError> {
    let mut enc = TiffEncoder::new(writer).map_err(|e| tiff_err("output image", e))?;
    enc.write_image::<colortype::Gray32Float>(width as u32, height as u32, data)
        .map_err(|e| tiff_err("output image", e))
}

/// Writes a 32-bit float greyscale image with its pixel size in the form
/// ImageJ/Fiji read (`ij/io/TiffDecoder`, `FileOpener`): XResolution =
/// YResolution = pixels per nm, ResolutionUnit none, and an ImageDescription
/// starting `ImageJ=` with `unit=nm`, so that Fiji shows nm and measures in
/// them. The values are the image's own (e.g. localisations per pixel).
pub fn write_f32_calibrated<W: Write + Seek>(
    writer: W,
    width: usize,
    height: usize,
    data: &[f32],
    pixel_nm: f64,
) -> Result<(), LocalizeError> {
    crate::error::check_option("pixel-nm", pixel_nm, 1e-3, 1e6)?;
    let err = |e| tiff_err("output image", e);
    let mut enc = TiffEncoder::new(writer).map_err(err)?;
    let mut image = enc
        .new_image::<colortype::Gray32Float>(width as u32, height as u32)
        .map_err(err)?;
    // 1/pixel_nm as a rational of 1e-3 nm steps (fits u32 over the range).
    let per_nm = tiff::encoder::Rational {
        n: 1000,
        d: (pixel_nm * 1000.0).round().max(1.0) as u32,
    };
    image.resolution(tiff::tags::ResolutionUnit::None, per_nm);
    image
        .encoder()
        .write_tag(tiff::tags::Tag::ImageDescription, "ImageJ=1.11a\nunit=nm\n")
        .map_err(err)?;
    image.write_data(data).map_err(err)
}

/// Creates a file for one of the writers above.
pub fn create(path: &Path) -> Result<BufWriter<File>, LocalizeError> {
    Ok(BufWriter::new(File::create(path)?))
}

/// An ROI to export: its top-left sensor pixel, side and counts.
#[derive(Clone, Copy, Debug)]
pub struct RoiPage<'a> {
    /// Column of the ROI's left edge (may be negative at the sensor edge).
    pub x0: i32,
    /// Row of the ROI's top edge.
    pub y0: i32,
    /// ROI side.
    pub side: usize,
    /// Counts, row-major.
    pub counts: &'a [u32],
}

/// How exported ROIs are laid out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoiLayout {
    /// One page per ROI of the largest ROI side (smaller ROIs padded with 0
    /// at the right and bottom); positions from ThunderSTORM are then in ROI
    /// coordinates — the caller writes the page → origin table.
    Compact,
    /// One sensor-sized page per ROI with the ROI at its place (zeros
    /// elsewhere, parts off the sensor dropped): ThunderSTORM's positions
    /// are sensor positions directly.
    Sensor {
        /// Sensor width.
        width: usize,
        /// Sensor height.
        height: usize,
    },
}

/// Builds the pages of an ROI export; returns (width, height, pages).
pub fn roi_pages(rois: &[RoiPage], layout: RoiLayout) -> (usize, usize, Vec<Vec<u32>>) {
    match layout {
        RoiLayout::Compact => {
            let side = rois.iter().map(|r| r.side).max().unwrap_or(1).max(1);
            let pages = rois
                .iter()
                .map(|r| {
                    let mut p = vec![0u32; side * side];
                    for j in 0..r.side {
                        for i in 0..r.side {
                            p[j * side + i] = r.counts.get(j * r.side + i).copied().unwrap_or(0);
                        }
                    }
                    p
                })
                .collect();
            (side, side, pages)
        }
        RoiLayout::Sensor { width, height } => {
            let pages = rois
                .iter()
                .map(|r| {
                    let mut p = vec![0u32; width * height];
                    for j in 0..r.side {
                        for i in 0..r.side {
                            let (x, y) = (r.x0 + i as i32, r.y0 + j as i32);
                            if x >= 0 && y >= 0 && (x as usize) < width && (y as usize) < height {
                                p[y as usize * width + x as usize] =
                                    r.counts.get(j * r.side + i).copied().unwrap_or(0);
                            }
                        }
                    }
                    p
                })
                .collect();
            (width, height, pages)
        }
    }
}
