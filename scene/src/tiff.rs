//! Frame stacks as multi-page 16-bit greyscale TIFF.
//!
//! One uncompressed page (IFD) per frame, all the same size: ImageJ and Fiji
//! open such a file as a stack (File › Open), ThunderSTORM reads it directly.
//! Frames are written as they come (streaming). Classic TIFF addresses at most
//! 4 GiB; [`TiffStackWriter::create`] switches to BigTIFF (which Fiji opens
//! through Bio-Formats) when the announced stack would not fit.

use std::io::{Read, Seek, Write};

use ::tiff::decoder::{Decoder, DecodingResult};
use ::tiff::encoder::{colortype::Gray16, TiffEncoder, TiffKindBig, TiffKindStandard};

use crate::SceneError;

enum Inner<W: Write + Seek> {
    Standard(TiffEncoder<W, TiffKindStandard>),
    Big(TiffEncoder<W, TiffKindBig>),
}

/// Writes u16 frames one page at a time.
pub struct TiffStackWriter<W: Write + Seek> {
    inner: Inner<W>,
    width: u32,
    height: u32,
    frames: u64,
}

impl<W: Write + Seek> std::fmt::Debug for TiffStackWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TiffStackWriter")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("frames", &self.frames)
            .finish()
    }
}

/// Bytes of pixel data above which a stack is written as BigTIFF (leaves room
/// for the directories below the 4 GiB limit of classic TIFF).
const CLASSIC_LIMIT: u64 = 4_000_000_000;

impl<W: Write + Seek> TiffStackWriter<W> {
    /// A classic TIFF stack of `width × height` frames.
    pub fn new(w: W, width: u32, height: u32) -> Result<Self, SceneError> {
        Ok(TiffStackWriter {
            inner: Inner::Standard(TiffEncoder::new(w)?),
            width,
            height,
            frames: 0,
        })
    }

    /// A stack for about `expected_frames` frames: classic TIFF if it fits in
    /// 4 GiB, BigTIFF otherwise.
    pub fn create(w: W, width: u32, height: u32, expected_frames: u64) -> Result<Self, SceneError> {
        let bytes = width as u64 * height as u64 * 2 * expected_frames;
        let inner = if bytes > CLASSIC_LIMIT {
            Inner::Big(TiffEncoder::new_big(w)?)
        } else {
            Inner::Standard(TiffEncoder::new(w)?)
        };
        Ok(TiffStackWriter {
            inner,
            width,
            height,
            frames: 0,
        })
    }

    /// Whether the file is BigTIFF.
    pub fn is_big(&self) -> bool {
        matches!(self.inner, Inner::Big(_))
    }

    /// Appends one frame (raster order, `width·height` values).
    pub fn write_frame(&mut self, adu: &[u16]) -> Result<(), SceneError> {
        if adu.len() != self.width as usize * self.height as usize {
            return Err(SceneError::FrameSize {
                width: self.width,
                height: self.height,
                found: adu.len(),
            });
        }
        match &mut self.inner {
            Inner::Standard(e) => e.write_image::<Gray16>(self.width, self.height, adu)?,
            Inner::Big(e) => e.write_image::<Gray16>(self.width, self.height, adu)?,
        }
        self.frames += 1;
        Ok(())
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }
}

/// Reads every page of a 16-bit greyscale TIFF stack: (width, height, frames).
pub fn read_stack<R: Read + Seek>(r: R) -> Result<(u32, u32, Vec<Vec<u16>>), SceneError> {
    let mut d = Decoder::new(r)?;
    let (w, h) = d.dimensions()?;
    let mut frames = Vec::new();
    loop {
        let (fw, fh) = d.dimensions()?;
        match d.read_image()? {
            DecodingResult::U16(v) if fw == w && fh == h => frames.push(v),
            DecodingResult::U16(v) => {
                return Err(SceneError::FrameSize {
                    width: w,
                    height: h,
                    found: v.len(),
                })
            }
            _ => {
                return Err(SceneError::Tiff(::tiff::TiffError::UnsupportedError(
                    ::tiff::TiffUnsupportedError::UnsupportedDataType,
                )))
            }
        }
        if !d.more_images() {
            break;
        }
        d.next_image()?;
    }
    Ok((w, h, frames))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    #[test]
    fn stack_round_trip() {
        let frames: Vec<Vec<u16>> = (0..3)
            .map(|k| (0..12u16).map(|i| i * 1000 + k).collect())
            .collect();
        for big in [false, true] {
            let mut buf = Cursor::new(Vec::new());
            {
                let mut w = if big {
                    TiffStackWriter::create(&mut buf, 4, 3, 1 << 40).unwrap()
                } else {
                    TiffStackWriter::create(&mut buf, 4, 3, 3).unwrap()
                };
                assert_eq!(w.is_big(), big);
                for f in &frames {
                    w.write_frame(f).unwrap();
                }
                assert!(w.write_frame(&[1, 2]).is_err());
                assert_eq!(w.frames(), 3);
            }
            buf.set_position(0);
            let (w, h, back) = read_stack(buf).unwrap();
            assert_eq!((w, h), (4, 3));
            assert_eq!(back, frames);
        }
    }
}
