//! Single-page greyscale images: 32-bit float (rendered densities, with
//! their ImageJ pixel size; calibration maps) and 8-bit (calibration flags).

use std::io::{Read, Seek, Write};

use tiff::encoder::{colortype, Rational, TiffEncoder};
use tiff::tags::{ResolutionUnit, Tag};

use crate::stack::StackReader;
use crate::{check_len, Error, ErrorKind, Samples};

/// Name of the stream in errors of the writers.
const OUTPUT: &str = "output image";

fn write_err(e: tiff::TiffError) -> Error {
    Error::new(OUTPUT, ErrorKind::Write(e))
}

/// The values of an image to write.
#[derive(Clone, Copy, Debug)]
pub enum Pixels<'a> {
    /// 32-bit float.
    F32(&'a [f32]),
    /// 8-bit unsigned.
    U8(&'a [u8]),
}

/// A decoded single-page image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Values, row-major, in the file's sample type.
    pub samples: Samples,
}

/// Writes a 32-bit float greyscale image (e.g. a rendered density).
pub fn write_f32<W: Write + Seek>(
    writer: W,
    width: usize,
    height: usize,
    data: &[f32],
) -> Result<(), Error> {
    let (w, h) = (width as u32, height as u32);
    check_len(OUTPUT, data.len(), w, h)?;
    TiffEncoder::new(writer)
        .map_err(write_err)?
        .write_image::<colortype::Gray32Float>(w, h, data)
        .map_err(write_err)
}

/// Writes a 32-bit float greyscale image with its pixel size in the form
/// ImageJ/Fiji read (`ij/io/TiffDecoder`, `FileOpener`): XResolution =
/// YResolution = pixels per nm, ResolutionUnit none, and an ImageDescription
/// starting `ImageJ=` with `unit=nm`, so that Fiji shows nm and measures in
/// them. The values are the image's own (e.g. localisations per pixel).
/// `pixel_nm` is rounded to 10⁻³ nm; the caller checks its range.
pub fn write_f32_calibrated<W: Write + Seek>(
    writer: W,
    width: usize,
    height: usize,
    data: &[f32],
    pixel_nm: f64,
) -> Result<(), Error> {
    let (w, h) = (width as u32, height as u32);
    check_len(OUTPUT, data.len(), w, h)?;
    let mut enc = TiffEncoder::new(writer).map_err(write_err)?;
    let mut image = enc
        .new_image::<colortype::Gray32Float>(w, h)
        .map_err(write_err)?;
    // 1/pixel_nm as a rational of 1e-3 nm steps (fits u32 over the range).
    let per_nm = Rational {
        n: 1000,
        d: (pixel_nm * 1000.0).round().max(1.0) as u32,
    };
    image.resolution(ResolutionUnit::None, per_nm);
    image
        .encoder()
        .write_tag(Tag::ImageDescription, "ImageJ=1.11a\nunit=nm\n")
        .map_err(write_err)?;
    image.write_data(data).map_err(write_err)
}

/// Writes a 32-bit float or 8-bit greyscale image whose ImageDescription tag
/// says what it holds (e.g. a calibration map).
pub fn write_described<W: Write + Seek>(
    writer: W,
    width: u32,
    height: u32,
    pixels: Pixels,
    description: &str,
) -> Result<(), Error> {
    match pixels {
        Pixels::F32(v) => {
            write_tagged::<colortype::Gray32Float, W>(writer, width, height, v, description)
        }
        Pixels::U8(v) => write_tagged::<colortype::Gray8, W>(writer, width, height, v, description),
    }
}

/// One page of colour type `C` with an ImageDescription.
fn write_tagged<C, W>(
    writer: W,
    width: u32,
    height: u32,
    data: &[C::Inner],
    description: &str,
) -> Result<(), Error>
where
    C: colortype::ColorType,
    [C::Inner]: tiff::encoder::TiffValue,
    W: Write + Seek,
{
    check_len(OUTPUT, data.len(), width, height)?;
    let mut enc = TiffEncoder::new(writer).map_err(write_err)?;
    let mut img = enc.new_image::<C>(width, height).map_err(write_err)?;
    img.encoder()
        .write_tag(Tag::ImageDescription, description)
        .map_err(write_err)?;
    img.write_data(data).map_err(write_err)
}

/// Reads a single-page greyscale image of any sample type (`name` is for
/// messages); a file with more pages is an error.
pub fn read_image<R: Read + Seek>(reader: R, name: &str) -> Result<Image, Error> {
    let mut stack = StackReader::new(reader, name)?;
    let (width, height, samples) = match stack.next_page() {
        Some(page) => page?,
        None => unreachable!("a stack read from its start has a first page"),
    };
    if stack.has_more() {
        return Err(Error::new(name, ErrorKind::MorePages));
    }
    Ok(Image {
        width,
        height,
        samples,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn tag(bytes: &[u8], tag: Tag) -> Option<tiff::decoder::ifd::Value> {
        let mut d = tiff::decoder::Decoder::new(Cursor::new(bytes)).unwrap();
        d.find_tag(tag).unwrap()
    }

    #[test]
    fn float_and_byte_images_round_trip_with_their_description() {
        let f: Vec<f32> = (0..6).map(|i| i as f32 * 0.25 - 1.0).collect();
        let mut buf = Cursor::new(Vec::new());
        write_described(&mut buf, 3, 2, Pixels::F32(&f), "a map (unit): what").unwrap();
        let bytes = buf.into_inner();
        let img = read_image(Cursor::new(&bytes), "f.tif").unwrap();
        assert_eq!((img.width, img.height), (3, 2));
        assert_eq!(img.samples, Samples::F32(f.clone()));
        assert_eq!(
            tag(&bytes, Tag::ImageDescription)
                .unwrap()
                .into_string()
                .unwrap(),
            "a map (unit): what"
        );
        let b = vec![0u8, 1, 2, 4, 8, 16];
        let mut buf = Cursor::new(Vec::new());
        write_described(&mut buf, 2, 3, Pixels::U8(&b), "flags").unwrap();
        let img = read_image(Cursor::new(buf.into_inner()), "b.tif").unwrap();
        assert_eq!((img.width, img.height, img.samples), (2, 3, Samples::U8(b)));
        let mut buf = Cursor::new(Vec::new());
        write_f32(&mut buf, 3, 2, &f).unwrap();
        let img = read_image(Cursor::new(buf.into_inner()), "plain").unwrap();
        assert_eq!(img.samples.into_f64()[5], 0.25);
        let e = write_described(Cursor::new(Vec::new()), 4, 4, Pixels::U8(&[0]), "x");
        assert!(matches!(e.unwrap_err().kind, ErrorKind::DataSize { .. }));
    }

    #[test]
    fn calibrated_image_carries_the_imagej_pixel_size() {
        let mut buf = Cursor::new(Vec::new());
        write_f32_calibrated(&mut buf, 2, 2, &[1.0, 2.0, 3.0, 4.0], 12.5).unwrap();
        let bytes = buf.into_inner();
        let desc = tag(&bytes, Tag::ImageDescription)
            .unwrap()
            .into_string()
            .unwrap();
        assert!(
            desc.starts_with("ImageJ=") && desc.contains("unit=nm"),
            "{desc}"
        );
        match tag(&bytes, Tag::XResolution).unwrap() {
            tiff::decoder::ifd::Value::Rational(n, d) => assert_eq!((n, d), (1000, 12_500)),
            v => panic!("{v:?}"),
        }
        let img = read_image(Cursor::new(bytes), "c").unwrap();
        assert_eq!(img.samples, Samples::F32(vec![1.0, 2.0, 3.0, 4.0]));
    }

    #[test]
    fn stacks_garbage_and_truncated_files_are_errors() {
        let mut buf = Cursor::new(Vec::new());
        crate::stack::write_stack(&mut buf, 1, 1, &[vec![1], vec![2]]).unwrap();
        let e = read_image(Cursor::new(buf.into_inner()), "two.tif").unwrap_err();
        assert_eq!(
            e.to_string(),
            "two.tif: has more than one page; an image has one"
        );
        let e = read_image(Cursor::new(b"II*\0garbage".to_vec()), "g").unwrap_err();
        assert!(e.to_string().starts_with("g: "), "{e}");
        let mut buf = Cursor::new(Vec::new());
        write_f32(&mut buf, 8, 8, &[0.5; 64]).unwrap();
        let bytes = buf.into_inner();
        for cut in 0..bytes.len() {
            assert!(
                read_image(Cursor::new(&bytes[..cut]), "cut").is_err(),
                "cut {cut}"
            );
        }
    }
}
