//! Multi-page greyscale TIFF stacks: camera frames in, frames and exported
//! ROIs out.
//!
//! Writing: one uncompressed page (IFD) per frame, all the same size, which
//! ImageJ and Fiji open as a stack (File › Open) and ThunderSTORM reads
//! directly. [`StackWriter`] streams 16-bit frames as they come and switches
//! to BigTIFF (which Fiji opens through Bio-Formats) when the announced stack
//! would not fit classic TIFF's 4 GiB; [`write_stack`] writes integer pages
//! as 16-bit, or 32-bit float (exact to 2²⁴) if a value exceeds 65 535.
//!
//! Reading: [`StackReader`] decodes every page of a greyscale stack (8/16/32-
//! bit integer or 32/64-bit float, as written by ImageJ/Fiji, Micro-Manager
//! and the simulator) one at a time, so a long stack never has to fit in
//! memory. All pages must have the size of the first.

use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::Path;

use tiff::decoder::Decoder;
use tiff::encoder::{colortype, TiffEncoder, TiffKindBig, TiffKindStandard};

use crate::{check_len, Error, ErrorKind, Samples};

/// Name of the stream in errors of the writers.
const OUTPUT: &str = "output stack";

/// One greyscale frame, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame<T = f64> {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Pixel values.
    pub data: Vec<T>,
}

/// Opens a TIFF stack on disk for reading (buffered; `path` names it in
/// errors).
pub fn open_stack(path: &Path) -> Result<StackReader<SeekBufReader<File>>, Error> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|e| Error::new(&name, ErrorKind::File(e)))?;
    StackReader::new(SeekBufReader::new(file), &name)
}

/// Creates a file for one of the writers (buffered; `path` names it in
/// errors).
pub fn create(path: &Path) -> Result<BufWriter<File>, Error> {
    File::create(path)
        .map(BufWriter::new)
        .map_err(|e| Error::new(path.display(), ErrorKind::File(e)))
}

/// Pages of a TIFF stack, decoded one at a time. As an iterator it yields
/// every page as a [`Frame`] of f64 values and stops after the first error.
pub struct StackReader<R: Read + Seek> {
    decoder: Decoder<R>,
    name: String,
    /// Pages read so far.
    page: u64,
    size: Option<(u32, u32)>,
    done: bool,
}

impl<R: Read + Seek> std::fmt::Debug for StackReader<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StackReader")
            .field("name", &self.name)
            .field("page", &self.page)
            .field("size", &self.size)
            .finish()
    }
}

impl<R: Read + Seek> StackReader<R> {
    /// Reads the header of a TIFF stream (`name` is for messages).
    pub fn new(reader: R, name: &str) -> Result<Self, Error> {
        let decoder = Decoder::new(reader).map_err(|e| Error::new(name, ErrorKind::NotTiff(e)))?;
        Ok(StackReader {
            decoder,
            name: name.to_string(),
            page: 0,
            size: None,
            done: false,
        })
    }

    /// The name given for messages.
    pub fn name(&self) -> &str {
        &self.name
    }

    fn err(&self, kind: ErrorKind) -> Error {
        Error::new(&self.name, kind)
    }

    /// Decodes the current page: greyscale, the size of the first page, one
    /// sample per pixel.
    fn read_page(&mut self) -> Result<(u32, u32, Samples), Error> {
        let page = self.page + 1;
        let (w, h) = self
            .decoder
            .dimensions()
            .map_err(|source| self.err(ErrorKind::Page { page, source }))?;
        let ct = self
            .decoder
            .colortype()
            .map_err(|source| self.err(ErrorKind::Page { page, source }))?;
        if !matches!(ct, tiff::ColorType::Gray(_)) {
            return Err(self.err(ErrorKind::NotGrey {
                page,
                colour: format!("{ct:?}"),
            }));
        }
        if let Some((w0, h0)) = self.size {
            if (w, h) != (w0, h0) {
                return Err(self.err(ErrorKind::PageSize {
                    page,
                    width: w,
                    height: h,
                    first_width: w0,
                    first_height: h0,
                }));
            }
        }
        self.size = Some((w, h));
        let samples = Samples::from_decoded(
            self.decoder
                .read_image()
                .map_err(|source| self.err(ErrorKind::Page { page, source }))?,
        );
        if samples.len() != w as usize * h as usize {
            return Err(self.err(ErrorKind::SampleCount {
                page,
                found: samples.len(),
                width: w,
                height: h,
            }));
        }
        Ok((w, h, samples))
    }

    /// The next page in its own sample type: `(width, height, samples)`;
    /// `None` after the last page or after an error.
    pub fn next_page(&mut self) -> Option<Result<(u32, u32, Samples), Error>> {
        if self.done {
            return None;
        }
        let page = self.read_page();
        self.page += 1;
        if page.is_err() || !self.decoder.more_images() {
            self.done = true;
        } else if let Err(source) = self.decoder.next_image() {
            self.done = true;
            // The page read is good; report the broken link with the next.
            return Some(Err(self.err(ErrorKind::NextPage {
                page: self.page,
                source,
            })));
        }
        Some(page)
    }

    /// True if another page follows the ones read (false after an error).
    pub fn has_more(&self) -> bool {
        !self.done
    }

    /// The next page, which must be 16-bit unsigned (camera ADU).
    pub fn next_u16(&mut self) -> Option<Result<Frame<u16>, Error>> {
        let page = self.page + 1;
        Some(self.next_page()?.and_then(|(w, h, s)| match s {
            Samples::U16(data) => Ok(Frame {
                width: w as usize,
                height: h as usize,
                data,
            }),
            other => {
                self.done = true;
                Err(self.err(ErrorKind::SampleType {
                    page,
                    found: other.type_name(),
                    wanted: "u16",
                }))
            }
        }))
    }
}

impl<R: Read + Seek> Iterator for StackReader<R> {
    type Item = Result<Frame, Error>;

    fn next(&mut self) -> Option<Self::Item> {
        Some(self.next_page()?.map(|(w, h, s)| Frame {
            width: w as usize,
            height: h as usize,
            data: s.into_f64(),
        }))
    }
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
    fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
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

enum Encoder<W: Write + Seek> {
    Standard(TiffEncoder<W, TiffKindStandard>),
    Big(TiffEncoder<W, TiffKindBig>),
}

/// Writes 16-bit frames one page at a time.
pub struct StackWriter<W: Write + Seek> {
    inner: Encoder<W>,
    width: u32,
    height: u32,
    frames: u64,
}

impl<W: Write + Seek> std::fmt::Debug for StackWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StackWriter")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("frames", &self.frames)
            .finish()
    }
}

/// Bytes of pixel data above which a stack is written as BigTIFF (leaves room
/// for the directories below the 4 GiB limit of classic TIFF).
const CLASSIC_LIMIT: u64 = 4_000_000_000;

fn write_err(e: tiff::TiffError) -> Error {
    Error::new(OUTPUT, ErrorKind::Write(e))
}

impl<W: Write + Seek> StackWriter<W> {
    /// A classic TIFF stack of `width × height` frames.
    pub fn new(w: W, width: u32, height: u32) -> Result<Self, Error> {
        Ok(StackWriter {
            inner: Encoder::Standard(TiffEncoder::new(w).map_err(write_err)?),
            width,
            height,
            frames: 0,
        })
    }

    /// A stack for about `expected_frames` frames: classic TIFF if it fits in
    /// 4 GiB, BigTIFF otherwise.
    pub fn create(w: W, width: u32, height: u32, expected_frames: u64) -> Result<Self, Error> {
        let bytes = width as u64 * height as u64 * 2 * expected_frames;
        let inner = if bytes > CLASSIC_LIMIT {
            Encoder::Big(TiffEncoder::new_big(w).map_err(write_err)?)
        } else {
            Encoder::Standard(TiffEncoder::new(w).map_err(write_err)?)
        };
        Ok(StackWriter {
            inner,
            width,
            height,
            frames: 0,
        })
    }

    /// Whether the file is BigTIFF.
    pub fn is_big(&self) -> bool {
        matches!(self.inner, Encoder::Big(_))
    }

    /// Appends one frame (raster order, `width·height` values).
    pub fn write_frame(&mut self, adu: &[u16]) -> Result<(), Error> {
        check_len(OUTPUT, adu.len(), self.width, self.height)?;
        let (w, h) = (self.width, self.height);
        match &mut self.inner {
            Encoder::Standard(e) => e.write_image::<colortype::Gray16>(w, h, adu),
            Encoder::Big(e) => e.write_image::<colortype::Gray16>(w, h, adu),
        }
        .map_err(write_err)?;
        self.frames += 1;
        Ok(())
    }

    /// Frames written so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }
}

/// Writes integer pages as a classic TIFF stack: 16-bit if every value fits,
/// else 32-bit float. Returns whether 16 bits were used.
pub fn write_stack<W: Write + Seek>(
    writer: W,
    width: usize,
    height: usize,
    pages: &[Vec<u32>],
) -> Result<bool, Error> {
    let (w, h) = (width as u32, height as u32);
    for p in pages {
        check_len(OUTPUT, p.len(), w, h)?;
    }
    let fits16 = pages.iter().flatten().all(|&v| v <= u16::MAX as u32);
    let mut enc = TiffEncoder::new(writer).map_err(write_err)?;
    for p in pages {
        if fits16 {
            let v: Vec<u16> = p.iter().map(|&x| x as u16).collect();
            enc.write_image::<colortype::Gray16>(w, h, &v)
        } else {
            let v: Vec<f32> = p.iter().map(|&x| x as f32).collect();
            enc.write_image::<colortype::Gray32Float>(w, h, &v)
        }
        .map_err(write_err)?;
    }
    Ok(fits16)
}

/// numpy's name of the sample type of a TIFF's first page (`uint16`,
/// `float32`, `int8`, ...), as Picasso's movie loaders write it in the
/// `Data Type` of a localisation table's YAML sidecar. Anything that does
/// not say (a missing or unreadable file, a colour page) is `"unknown"`:
/// the name is informative, never a reason to fail.
pub fn numpy_data_type(path: &Path) -> String {
    use tiff::tags::Tag;
    let Ok(mut d) = File::open(path)
        .map_err(|_| ())
        .and_then(|f| Decoder::new(std::io::BufReader::new(f)).map_err(|_| ()))
    else {
        return "unknown".into();
    };
    let bits = match d.colortype() {
        Ok(tiff::ColorType::Gray(b)) => b,
        _ => return "unknown".into(),
    };
    // SampleFormat: 1 unsigned (the default), 2 signed, 3 IEEE float.
    let kind = match d.find_tag_unsigned::<u16>(Tag::SampleFormat) {
        Ok(Some(2)) => "int",
        Ok(Some(3)) => "float",
        _ => "uint",
    };
    format!("{kind}{bits}")
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn frames() -> Vec<Vec<u16>> {
        (0..3)
            .map(|k| (0..12u16).map(|i| i * 1000 + k).collect())
            .collect()
    }

    #[test]
    fn u16_stack_round_trip_classic_and_big() {
        let frames = frames();
        for big in [false, true] {
            let mut buf = Cursor::new(Vec::new());
            {
                let expected = if big { 1 << 40 } else { 3 };
                let mut w = StackWriter::create(&mut buf, 4, 3, expected).unwrap();
                assert_eq!(w.is_big(), big);
                for f in &frames {
                    w.write_frame(f).unwrap();
                }
                let e = w.write_frame(&[1, 2]).unwrap_err();
                assert!(
                    matches!(e.kind, ErrorKind::DataSize { found: 2, .. }),
                    "{e}"
                );
                assert_eq!(w.frames(), 3);
            }
            let mut r = StackReader::new(Cursor::new(buf.into_inner()), "mem").unwrap();
            let mut back = Vec::new();
            while let Some(f) = r.next_u16() {
                let f = f.unwrap();
                assert_eq!((f.width, f.height), (4, 3));
                back.push(f.data);
            }
            assert_eq!(back, frames);
        }
    }

    #[test]
    fn write_stack_picks_16_bit_or_float_and_reads_back_as_f64() {
        let pages = vec![vec![1u32, 2, 3, 4, 5, 6], vec![7, 8, 9, 10, 11, 12]];
        let mut buf = Cursor::new(Vec::new());
        assert!(write_stack(&mut buf, 3, 2, &pages).unwrap());
        let back: Vec<Frame> = StackReader::new(Cursor::new(buf.into_inner()), "mem")
            .unwrap()
            .map(Result::unwrap)
            .collect();
        assert_eq!(back.len(), 2);
        assert_eq!(back[1].data, vec![7.0, 8.0, 9.0, 10.0, 11.0, 12.0]);
        let wide = vec![vec![70_000u32, 0, 1, 2]];
        let mut buf = Cursor::new(Vec::new());
        assert!(!write_stack(&mut buf, 2, 2, &wide).unwrap());
        let mut r = StackReader::new(Cursor::new(buf.into_inner()), "mem").unwrap();
        assert_eq!(r.next().unwrap().unwrap().data[0], 70_000.0);
        assert!(r.next().is_none());
        // A float page is not a camera frame.
        let mut buf = Cursor::new(Vec::new());
        write_stack(&mut buf, 2, 2, &wide).unwrap();
        let mut r = StackReader::new(Cursor::new(buf.into_inner()), "floats").unwrap();
        let e = r.next_u16().unwrap().unwrap_err().to_string();
        assert_eq!(e, "floats: page 1 is f32, not u16 greyscale");
        assert!(r.next_u16().is_none());
        let e = write_stack(Cursor::new(Vec::new()), 3, 2, &[vec![1]]).unwrap_err();
        assert!(e.to_string().contains("1 values for a 3x2 page"), "{e}");
    }

    #[test]
    fn pages_of_another_size_are_named() {
        let mut buf = Cursor::new(Vec::new());
        {
            let mut e = TiffEncoder::new(&mut buf).unwrap();
            e.write_image::<colortype::Gray16>(3, 2, &[0; 6]).unwrap();
            e.write_image::<colortype::Gray16>(4, 4, &[0; 16]).unwrap();
        }
        let mut r = StackReader::new(Cursor::new(buf.into_inner()), "mixed.tif").unwrap();
        assert!(r.next().unwrap().is_ok());
        let e = r.next().unwrap().unwrap_err().to_string();
        assert_eq!(
            e,
            "mixed.tif: page 2 is 4x4 pixels, but the first page is 3x2"
        );
        assert!(r.next().is_none());
    }

    #[test]
    fn garbage_and_truncated_files_give_errors_not_panics() {
        let e = StackReader::new(Cursor::new(b"hello, world".to_vec()), "junk").unwrap_err();
        assert!(
            e.to_string().starts_with("junk: not a readable TIFF file"),
            "{e}"
        );
        let mut buf = Cursor::new(Vec::new());
        write_stack(&mut buf, 4, 3, &[vec![5; 12], vec![6; 12]]).unwrap();
        let bytes = buf.into_inner();
        for cut in 0..bytes.len() {
            if let Ok(r) = StackReader::new(Cursor::new(bytes[..cut].to_vec()), "cut") {
                let read: Vec<_> = r.collect();
                assert!(
                    read.iter().any(Result::is_err) || read.len() < 2,
                    "cut {cut}"
                );
            }
        }
        let e = open_stack(Path::new("/nonexistent/absent.tif")).unwrap_err();
        assert!(matches!(e.kind, ErrorKind::File(_)));
        assert!(e.to_string().contains("absent.tif"), "{e}");
    }

    #[test]
    fn seek_buf_reader_reads_like_the_inner_reader() {
        let data: Vec<u8> = (0..1_000_000u32).map(|i| (i * 7 % 251) as u8).collect();
        let mut r = SeekBufReader::new(Cursor::new(data.clone()));
        let mut b = [0u8; 10];
        for &at in &[0u64, 5, 300_000, 299_990, 999_990, 17] {
            r.seek(SeekFrom::Start(at)).unwrap();
            r.read_exact(&mut b).unwrap();
            assert_eq!(&b[..], &data[at as usize..at as usize + 10]);
        }
        r.seek(SeekFrom::Current(-20)).unwrap();
        r.read_exact(&mut b).unwrap();
        assert_eq!(&b[..], &data[7..17]);
        assert!(r.seek(SeekFrom::Current(-1_000)).is_err());
    }

    #[test]
    fn numpy_data_type_names_the_first_pages_samples() {
        let dir = std::env::temp_dir().join(format!("smartagg-io-dtype-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let u16_path = dir.join("u16.tif");
        write_stack(create(&u16_path).unwrap(), 2, 1, &[vec![1, 2]]).unwrap();
        assert_eq!(numpy_data_type(&u16_path), "uint16");
        let f32_path = dir.join("f32.tif");
        write_stack(create(&f32_path).unwrap(), 2, 1, &[vec![1, 70_000]]).unwrap();
        assert_eq!(numpy_data_type(&f32_path), "float32");
        let i8_path = dir.join("i8.tif");
        TiffEncoder::new(create(&i8_path).unwrap())
            .unwrap()
            .write_image::<colortype::GrayI8>(2, 1, &[-1, 1])
            .unwrap();
        assert_eq!(numpy_data_type(&i8_path), "int8");
        let text = dir.join("not.tif");
        std::fs::write(&text, "not a TIFF").unwrap();
        assert_eq!(numpy_data_type(&text), "unknown");
        assert_eq!(numpy_data_type(&dir.join("missing.tif")), "unknown");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
