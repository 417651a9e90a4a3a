//! A recording's planes read at any index ([`PlaneFile`]), so that the
//! workers of [`run_parallel`](crate::fast_engine::run_parallel) each read
//! and unpack their own chunk's planes: reading a file is no longer one
//! thread's work (a reader decoding every plane took a fifth of the CPU of
//! a 2-thread run on a SPAD512S recording).

use super::{
    flip_bytes, read_fully, BitOrder, RecordingError, RecordingHeader, RecordingReader,
    PLANES_UNKNOWN,
};
use crate::fast_engine::SourcePlane;
use crate::hot_pixel_mask::HotPixelMask;
use crate::plane::BitPlane;
use std::fs::File;
use std::io::Read;

/// A `.spad` recording or raw packed planes in a regular file, read at any
/// plane. [`PlaneFile::planes`] gives the planes a [`RecordingReader`] over
/// the same file gives, in the same order, then the same error if the file
/// ends wrong (cut short, or bytes past the planes its header declares).
#[derive(Debug)]
pub struct PlaneFile {
    file: File,
    header: RecordingHeader,
    /// Bytes before plane 0.
    offset: u64,
    /// Whole planes to read.
    planes: u64,
    /// What ends the planes, if they end wrong.
    end: Option<WrongEnd>,
}

#[derive(Debug, Clone, Copy)]
enum WrongEnd {
    /// A last plane of this many bytes.
    Truncated(usize),
    /// Fewer planes than declared.
    Missing,
    /// Bytes past the declared planes (as many as a reader probes for).
    Trailing(usize),
}

impl PlaneFile {
    /// The planes of `file`, as `reader` (opened on the same file, header
    /// read and checked) would read them; `None` if `file` is not a regular
    /// file (a pipe or a device has no plane at an index).
    pub fn of<R: Read>(
        file: File,
        reader: &RecordingReader<R>,
    ) -> Result<Option<PlaneFile>, RecordingError> {
        let meta = file.metadata()?;
        if !meta.is_file() {
            return Ok(None);
        }
        let header = *reader.header();
        let offset = reader.data_offset();
        let plane = header.plane_bytes() as u64;
        let body = meta.len().saturating_sub(offset);
        let (whole, rem) = (body / plane, (body % plane) as usize);
        let declared = header.planes;
        let (planes, end) = if declared == PLANES_UNKNOWN {
            (whole, (rem > 0).then_some(WrongEnd::Truncated(rem)))
        } else if whole >= declared {
            // The reader probes for trailing bytes with at most a plane, and
            // at most 64 KiB.
            let extra = (body - declared * plane).min(plane.min(1 << 16)) as usize;
            (declared, (extra > 0).then_some(WrongEnd::Trailing(extra)))
        } else if rem > 0 {
            (whole, Some(WrongEnd::Truncated(rem)))
        } else {
            (whole, Some(WrongEnd::Missing))
        };
        Ok(Some(PlaneFile {
            file,
            header,
            offset,
            planes,
            end,
        }))
    }

    /// The header.
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// Every plane, then the error that ends them if they end wrong.
    pub fn planes(&self) -> impl Iterator<Item = Result<PlaneAt<'_>, RecordingError>> + Send + '_ {
        let end = self.end.map(|end| {
            let (declared, plane_bytes) = (self.header.planes, self.header.plane_bytes());
            Err(match end {
                WrongEnd::Truncated(found) => RecordingError::Truncated {
                    plane: self.planes,
                    bytes_expected: plane_bytes,
                    bytes_found: found,
                },
                WrongEnd::Missing => RecordingError::MissingPlanes {
                    declared,
                    found: self.planes,
                },
                WrongEnd::Trailing(extra_bytes) => RecordingError::TrailingBytes {
                    declared,
                    extra_bytes,
                },
            })
        });
        (0..self.planes)
            .map(move |index| Ok(PlaneAt { file: self, index }))
            .chain(end)
    }

    /// Reads plane `index` into `bytes` (resized to a plane).
    fn read(&self, index: u64, bytes: &mut Vec<u8>) -> Result<(), RecordingError> {
        let need = self.header.plane_bytes();
        bytes.resize(need, 0);
        let at = self.offset + index * need as u64;
        let got = read_fully(&mut ReadAt(&self.file, at), bytes)?;
        if got < need {
            // Cut short since it was opened.
            return Err(RecordingError::Truncated {
                plane: index,
                bytes_expected: need,
                bytes_found: got,
            });
        }
        Ok(())
    }
}

/// A file read from a position of its own (`pread`): the workers share one
/// handle without moving its offset.
struct ReadAt<'a>(&'a File, u64);

impl Read for ReadAt<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        #[cfg(unix)]
        let n = std::os::unix::fs::FileExt::read_at(self.0, buf, self.1)?;
        #[cfg(windows)]
        let n = std::os::windows::fs::FileExt::seek_read(self.0, buf, self.1)?;
        self.1 += n as u64;
        Ok(n)
    }
}

/// Plane `index` of a [`PlaneFile`]: lent to
/// [`run_parallel`](crate::fast_engine::run_parallel), whose worker reads
/// and unpacks it into its chunk.
#[derive(Debug, Clone, Copy)]
pub struct PlaneAt<'a> {
    file: &'a PlaneFile,
    index: u64,
}

impl SourcePlane<RecordingError> for PlaneAt<'_> {
    const WRITTEN_BY_READER: bool = false;

    fn size(&self) -> (usize, usize) {
        let h = &self.file.header;
        (h.width as usize, h.height as usize)
    }

    fn write_into(
        &self,
        dst: &mut BitPlane,
        mask: Option<&HotPixelMask>,
        scratch: &mut Vec<u8>,
    ) -> Result<(), RecordingError> {
        self.file.read(self.index, scratch)?;
        unpack_plane_into(scratch, self.file.header.bit_order, dst);
        if let Some(m) = mask {
            dst.mask_in_place(m);
        }
        Ok(())
    }
}

/// Unpacks one plane from `bytes` into `dst`, a plane of the size packed,
/// whose storage is reused (at least a plane's bytes; extra bytes and
/// padding bits are ignored). [`unpack_plane`](super::unpack_plane) is this
/// into a new plane.
///
/// # Panics
/// If `bytes` is shorter than one plane of `dst`'s size (a programming
/// error: readers check lengths before calling this).
pub fn unpack_plane_into(bytes: &[u8], order: BitOrder, dst: &mut BitPlane) {
    let n = dst.width() * dst.height();
    let nbytes = n.div_ceil(8);
    assert!(
        bytes.len() >= nbytes,
        "unpack_plane: {} bytes given, a {}x{} plane needs {nbytes}",
        bytes.len(),
        dst.width(),
        dst.height()
    );
    let words = dst.words_mut();
    let mut chunks = bytes[..nbytes].chunks_exact(8);
    for (w, c) in words.iter_mut().zip(&mut chunks) {
        *w = u64::from_le_bytes(c.try_into().expect("8-byte chunk"));
    }
    let rem = chunks.remainder();
    if !rem.is_empty() {
        let mut last = [0u8; 8];
        last[..rem.len()].copy_from_slice(rem);
        if let Some(w) = words.last_mut() {
            *w = u64::from_le_bytes(last);
        }
    }
    if order == BitOrder::MsbFirst {
        words.iter_mut().for_each(|w| *w = flip_bytes(*w));
    }
    // Clear padding bits so equal planes compare equal whatever the padding held.
    if !n.is_multiple_of(64) {
        if let Some(last) = words.last_mut() {
            *last &= (1u64 << (n % 64)) - 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{header, random_plane};
    use super::super::PLANES_UNKNOWN;
    use super::*;
    use std::io::Write;

    fn random_planes(seed: u64, w: usize, h: usize, n: usize) -> Vec<BitPlane> {
        (0..n as u64)
            .map(|i| random_plane(w, h, seed * 1000 + i))
            .collect()
    }

    /// The bytes of a recording of `planes` whose header declares `declared`.
    fn spad(planes: &[BitPlane], order: BitOrder, declared: u64) -> Vec<u8> {
        let (w, h) = (planes[0].width() as u32, planes[0].height() as u32);
        let mut out = Vec::new();
        out.extend_from_slice(&header(w, h, declared, order).to_bytes());
        for p in planes {
            super::super::pack_plane(p, order, &mut out);
        }
        out
    }

    /// Planes read, or the error text that ended them.
    type Planes = Vec<Result<BitPlane, String>>;
    /// Headerless planes' width, height and order.
    type Raw = Option<(u32, u32, BitOrder)>;

    /// What the sequential reader reads from `bytes`, and what a
    /// `PlaneFile` over the same bytes in a file reads (each plane written
    /// into a reused plane, masked by `mask`), as planes and error texts.
    fn both(bytes: &[u8], raw: Raw, mask: Option<&HotPixelMask>) -> (Planes, Planes) {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(bytes).unwrap();
        let open = |r: File| match raw {
            Some((w, h, o)) => RecordingReader::open_raw(r, w, h, o, 100_000),
            None => RecordingReader::open(r),
        };
        let reader = open(f.reopen().unwrap()).unwrap();
        let masked = |p: BitPlane| mask.map_or(p.clone(), |m| m.apply(&p));
        let at = PlaneFile::of(f.reopen().unwrap(), &reader)
            .unwrap()
            .unwrap();
        let seq = reader
            .map(|p| p.map(masked).map_err(|e| e.to_string()))
            .collect();
        let (mut dst, mut scratch) = (BitPlane::zeros(1, 1), Vec::new());
        let par = at
            .planes()
            .map(|p| {
                let p = p.map_err(|e| e.to_string())?;
                let (w, h) = p.size();
                if dst.width() != w || dst.height() != h {
                    dst = BitPlane::ones(w, h);
                }
                p.write_into(&mut dst, mask, &mut scratch)
                    .map_err(|e| e.to_string())?;
                Ok(dst.clone())
            })
            .collect();
        (seq, par)
    }

    #[test]
    fn a_plane_file_reads_what_the_reader_reads_any_size_and_order() {
        for (w, h) in [(13, 7), (64, 2), (8, 8), (1, 1), (70, 3)] {
            for order in [BitOrder::LsbFirst, BitOrder::MsbFirst] {
                let planes = random_planes(w as u64 * 31 + h as u64, w, h, 9);
                let (seq, par) = both(&spad(&planes, order, 9), None, None);
                assert_eq!(seq.len(), 9);
                assert!(seq.iter().zip(&planes).all(|(s, p)| s.as_ref() == Ok(p)));
                assert_eq!(par, seq, "{w}x{h} {order:?}");
                // Headerless, the same planes.
                let body = &spad(&planes, order, 9)[48..];
                let (seq, par) = both(body, Some((w as u32, h as u32, order)), None);
                assert_eq!(seq.len(), 9);
                assert_eq!(par, seq, "raw {w}x{h} {order:?}");
            }
        }
        // Hot pixels masked as the reader's planes masked.
        let planes: Vec<BitPlane> = (0..4).map(|_| BitPlane::ones(10, 4)).collect();
        let (mask, _) = HotPixelMask::from_pixels(10, 4, &[(3, 2), (9, 3)]);
        let (seq, par) = both(&spad(&planes, BitOrder::LsbFirst, 4), None, Some(&mask));
        assert_eq!(par, seq);
        assert_eq!(par[0].as_ref().unwrap().count_ones(), 38);
    }

    #[test]
    fn a_plane_file_ends_with_the_readers_error() {
        let planes = random_planes(7, 12, 5, 6);
        let order = BitOrder::MsbFirst;
        let full = spad(&planes, order, 6);
        let plane = 8; // 60 pixels
        let cases: [(&str, Vec<u8>, Raw); 6] = [
            // Declared 8, 6 there.
            ("missing", spad(&planes, order, 8), None),
            // Declared 6, 4 and a half there.
            ("truncated", full[..48 + 4 * plane + 3].to_vec(), None),
            // Declared 4, 6 there.
            ("trailing", spad(&planes, order, 4), None),
            // Declared 0, 6 there.
            ("trailing from 0", spad(&planes, order, 0), None),
            // Unknown count, a partial last plane.
            (
                "live, truncated",
                spad(&planes, order, PLANES_UNKNOWN)[..48 + 5 * plane + 1].to_vec(),
                None,
            ),
            // Raw, a partial last plane.
            (
                "raw, truncated",
                full[48..48 + 3 * plane + 5].to_vec(),
                Some((12, 5, order)),
            ),
        ];
        for (what, bytes, raw) in cases {
            let (seq, par) = both(&bytes, raw, None);
            let last = seq.last().unwrap();
            assert!(last.is_err(), "{what}: the reader ends wrong: {last:?}");
            assert_eq!(par, seq, "{what}");
        }
        // The right end: no error.
        let (seq, par) = both(&spad(&planes, order, PLANES_UNKNOWN), None, None);
        assert!(seq.iter().all(Result::is_ok) && seq.len() == 6);
        assert_eq!(par, seq);
    }

    #[test]
    fn a_plane_file_cut_short_after_opening_says_which_plane() {
        let planes = random_planes(3, 16, 4, 5);
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(&spad(&planes, BitOrder::LsbFirst, 5)).unwrap();
        let reader = RecordingReader::open(f.reopen().unwrap()).unwrap();
        let at = PlaneFile::of(f.reopen().unwrap(), &reader)
            .unwrap()
            .unwrap();
        // Cut inside plane 3 (8 bytes a plane).
        f.as_file().set_len(48 + 3 * 8 + 2).unwrap();
        let (mut dst, mut scratch) = (BitPlane::zeros(16, 4), Vec::new());
        let got: Vec<_> = at
            .planes()
            .map(|p| p.unwrap().write_into(&mut dst, None, &mut scratch))
            .collect();
        assert!(got[..3].iter().all(Result::is_ok));
        match &got[3] {
            Err(RecordingError::Truncated {
                plane: 3,
                bytes_expected: 8,
                bytes_found: 2,
            }) => {}
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            &got[4],
            Err(RecordingError::Truncated {
                plane: 4,
                bytes_found: 0,
                ..
            })
        ));
    }

    #[cfg(unix)]
    #[test]
    fn a_stream_that_is_not_a_file_has_no_planes_at_an_index() {
        let planes = random_planes(5, 8, 8, 2);
        let bytes = spad(&planes, BitOrder::LsbFirst, 2);
        let reader = RecordingReader::open(&bytes[..]).unwrap();
        let dev = File::open("/dev/null").unwrap();
        assert!(PlaneFile::of(dev, &reader).unwrap().is_none());
    }
}
