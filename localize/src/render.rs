//! Super-resolution rendering: ThunderSTORM's "normalized Gaussian".
//!
//! Each localisation adds a 2-D Gaussian of standard deviation equal to its
//! uncertainty, integrated over each output pixel (erf differences) and
//! normalised so that it adds exactly 1 to the image: the image is a density
//! in localisations per pixel. The Gaussian is truncated at ±4σ (at least
//! one pixel around the centre) and the truncated stamp renormalised. σ is
//! clamped below at `min_sigma_nm` (default 2 nm) so that a zero uncertainty
//! cannot make a singular stamp; below half a pixel the stamp is one pixel.
//!
//! The PNG is 8-bit grey: density divided by its `(100 − saturate)`th
//! percentile over non-empty pixels (default 0.5 % saturated), with a white
//! scale bar (1, 2 or 5 × 10ⁿ nm, about a fifth of the width) and its label
//! in the lower-right corner.

use crate::erf::erf;
use crate::error::{check_option, LocalizeError};

/// Largest image rendered (pixels).
pub const MAX_PIXELS: u64 = 200_000_000;

/// A rendered density image, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Left edge of the image in sample coordinates, nm.
    pub origin_x_nm: f64,
    /// Top edge, nm.
    pub origin_y_nm: f64,
    /// Pixel size, nm.
    pub pixel_nm: f64,
    /// Localisations per pixel.
    pub data: Vec<f32>,
}

impl Image {
    /// Value at pixel `(i, j)`.
    pub fn at(&self, i: usize, j: usize) -> f32 {
        self.data[j * self.width + i]
    }
}

/// A point to render: position and σ, nm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// x, nm.
    pub x_nm: f64,
    /// y, nm.
    pub y_nm: f64,
    /// Standard deviation of its Gaussian, nm (the uncertainty).
    pub sigma_nm: f64,
}

/// Where and how finely to render.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Output pixel size, nm.
    pub pixel_nm: f64,
    /// Smallest σ drawn, nm.
    pub min_sigma_nm: f64,
    /// Left edge, nm.
    pub origin_x_nm: f64,
    /// Top edge, nm.
    pub origin_y_nm: f64,
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
}

impl RenderOptions {
    /// Covers every point with a margin of 4 × the largest σ drawn (at least
    /// 10 pixels), at `pixel_nm`. Errors if the image would exceed
    /// [`MAX_PIXELS`].
    pub fn covering(
        points: &[Point],
        pixel_nm: f64,
        min_sigma_nm: f64,
    ) -> Result<RenderOptions, LocalizeError> {
        check_option("pixel-nm", pixel_nm, 1e-3, 1e6)?;
        check_option("min-sigma-nm", min_sigma_nm, 1e-3, 1e6)?;
        let (mut x0, mut y0, mut x1, mut y1) = (
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        );
        let mut smax: f64 = 0.0;
        for p in points {
            x0 = x0.min(p.x_nm);
            y0 = y0.min(p.y_nm);
            x1 = x1.max(p.x_nm);
            y1 = y1.max(p.y_nm);
            smax = smax.max(p.sigma_nm.max(min_sigma_nm));
        }
        if points.is_empty() {
            (x0, y0, x1, y1) = (0.0, 0.0, 0.0, 0.0);
        }
        let margin = (4.0 * smax).max(10.0 * pixel_nm);
        let ox = ((x0 - margin) / pixel_nm).floor() * pixel_nm;
        let oy = ((y0 - margin) / pixel_nm).floor() * pixel_nm;
        let w = ((x1 + margin - ox) / pixel_nm).ceil().max(1.0);
        let h = ((y1 + margin - oy) / pixel_nm).ceil().max(1.0);
        if w * h > MAX_PIXELS as f64 {
            return Err(LocalizeError::ImageTooLarge {
                width: w as u64,
                height: h as u64,
                limit: MAX_PIXELS,
            });
        }
        Ok(RenderOptions {
            pixel_nm,
            min_sigma_nm,
            origin_x_nm: ox,
            origin_y_nm: oy,
            width: w as usize,
            height: h as usize,
        })
    }
}

/// Renders points as normalised Gaussians. Points with a non-finite
/// coordinate are skipped (their number is returned).
pub fn render(points: &[Point], opts: &RenderOptions) -> Result<(Image, usize), LocalizeError> {
    check_option("pixel-nm", opts.pixel_nm, 1e-3, 1e6)?;
    check_option("min-sigma-nm", opts.min_sigma_nm, 1e-3, 1e6)?;
    let (w, h) = (opts.width, opts.height);
    if w == 0 || h == 0 || (w as u64) * (h as u64) > MAX_PIXELS {
        return Err(LocalizeError::ImageTooLarge {
            width: w as u64,
            height: h as u64,
            limit: MAX_PIXELS,
        });
    }
    let mut data = vec![0.0f32; w * h];
    let mut skipped = 0;
    let mut wx = Vec::new();
    let mut wy = Vec::new();
    for p in points {
        if !(p.x_nm.is_finite() && p.y_nm.is_finite()) {
            skipped += 1;
            continue;
        }
        let s = if p.sigma_nm.is_finite() {
            p.sigma_nm.max(opts.min_sigma_nm)
        } else {
            opts.min_sigma_nm
        } / opts.pixel_nm;
        // Centre in image pixels (pixel i spans [i, i+1)).
        let cx = (p.x_nm - opts.origin_x_nm) / opts.pixel_nm;
        let cy = (p.y_nm - opts.origin_y_nm) / opts.pixel_nm;
        let reach = (4.0 * s).max(1.0);
        let (i0, i1) = span(cx, reach, w);
        let (j0, j1) = span(cy, reach, h);
        if i0 >= i1 || j0 >= j1 {
            skipped += 1;
            continue;
        }
        weights(cx, s, i0, i1, &mut wx);
        weights(cy, s, j0, j1, &mut wy);
        let total: f64 = wx.iter().sum::<f64>() * wy.iter().sum::<f64>();
        if total <= 0.0 {
            skipped += 1;
            continue;
        }
        let norm = 1.0 / total;
        for (dj, &vy) in wy.iter().enumerate() {
            let row = (j0 + dj) * w;
            for (di, &vx) in wx.iter().enumerate() {
                data[row + i0 + di] += (vx * vy * norm) as f32;
            }
        }
    }
    Ok((
        Image {
            width: w,
            height: h,
            origin_x_nm: opts.origin_x_nm,
            origin_y_nm: opts.origin_y_nm,
            pixel_nm: opts.pixel_nm,
            data,
        },
        skipped,
    ))
}

/// Pixel range `[a, b)` within `[0, n)` covering `c ± reach`.
fn span(c: f64, reach: f64, n: usize) -> (usize, usize) {
    let a = (c - reach).floor().max(0.0);
    let b = (c + reach).ceil().min(n as f64);
    if b <= a {
        return (0, 0);
    }
    (a as usize, b as usize)
}

/// Pixel integrals of N(c, s) over pixels `[a, b)`.
fn weights(c: f64, s: f64, a: usize, b: usize, out: &mut Vec<f64>) {
    out.clear();
    let k = 1.0 / (s * std::f64::consts::SQRT_2);
    let mut lo = erf((a as f64 - c) * k);
    for i in a..b {
        let hi = erf((i as f64 + 1.0 - c) * k);
        out.push(0.5 * (hi - lo).max(0.0));
        lo = hi;
    }
}

/// The scale bar drawn on a PNG.
#[derive(Clone, Debug, PartialEq)]
pub struct ScaleBar {
    /// Length, nm.
    pub length_nm: f64,
    /// Length, image pixels.
    pub length_px: usize,
    /// Its label, e.g. "500 nm" or "1 µm".
    pub label: String,
    /// Whether the label fitted in the image (the bar is always drawn when
    /// at least 2 pixels long).
    pub label_drawn: bool,
}

/// The density shown as full scale: the `(100 − saturate)`th percentile of
/// the non-empty pixels (1 for an empty image), so that `saturate` percent
/// of them saturate.
pub fn display_max(data: &[f32], saturate_percent: f64) -> Result<f32, LocalizeError> {
    check_option("saturate", saturate_percent, 0.0, 100.0)?;
    let mut nonzero: Vec<f32> = data
        .iter()
        .copied()
        .filter(|&v| v > 0.0 && v.is_finite())
        .collect();
    if nonzero.is_empty() {
        return Ok(1.0);
    }
    let q = 1.0 - saturate_percent / 100.0;
    let k = ((nonzero.len() as f64 - 1.0) * q).round() as usize;
    let k = k.min(nonzero.len() - 1);
    let (_, v, _) = nonzero.select_nth_unstable_by(k, |a, b| a.total_cmp(b));
    Ok(if *v > 0.0 { *v } else { 1.0 })
}

/// 8-bit grey pixels of the image with a scale bar, ready for PNG.
pub fn to_gray8(img: &Image, saturate_percent: f64) -> Result<(Vec<u8>, ScaleBar), LocalizeError> {
    let vmax = display_max(&img.data, saturate_percent)?;
    let mut px: Vec<u8> = img
        .data
        .iter()
        .map(|&v| ((v / vmax).clamp(0.0, 1.0) * 255.0).round() as u8)
        .collect();
    let bar = draw_scale_bar(&mut px, img.width, img.height, img.pixel_nm);
    Ok((px, bar))
}

/// Encodes an image as an 8-bit grey PNG with a scale bar.
pub fn to_png(img: &Image, saturate_percent: f64) -> Result<(Vec<u8>, ScaleBar), LocalizeError> {
    let (px, bar) = to_gray8(img, saturate_percent)?;
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, img.width as u32, img.height as u32);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        // Physical pixel size, so that viewers can show the scale.
        let ppm = (1e9 / img.pixel_nm).round().clamp(1.0, u32::MAX as f64) as u32;
        enc.set_pixel_dims(Some(png::PixelDimensions {
            xppu: ppm,
            yppu: ppm,
            unit: png::Unit::Meter,
        }));
        let mut w = enc
            .write_header()
            .map_err(|e| LocalizeError::Png(e.to_string()))?;
        w.write_image_data(&px)
            .map_err(|e| LocalizeError::Png(e.to_string()))?;
        w.finish().map_err(|e| LocalizeError::Png(e.to_string()))?;
    }
    Ok((out, bar))
}

/// A "nice" length (1, 2 or 5 × 10ⁿ nm) close to `target` nm.
pub fn nice_length(target: f64) -> f64 {
    if !(target > 0.0 && target.is_finite()) {
        return 1.0;
    }
    let p = 10f64.powf(target.log10().floor());
    let m = target / p;
    let n = if m < 1.5 {
        1.0
    } else if m < 3.5 {
        2.0
    } else if m < 7.5 {
        5.0
    } else {
        10.0
    };
    n * p
}

/// Label of a length: nm below 1 µm, µm above.
pub fn length_label(nm: f64) -> String {
    if nm >= 1000.0 {
        let um = nm / 1000.0;
        if um.fract() == 0.0 {
            format!("{um:.0} µm")
        } else {
            format!("{um} µm")
        }
    } else {
        format!("{nm:.0} nm")
    }
}

fn draw_scale_bar(px: &mut [u8], w: usize, h: usize, pixel_nm: f64) -> ScaleBar {
    let length_nm = nice_length(w as f64 * pixel_nm / 5.0);
    let length_px = (length_nm / pixel_nm).round() as usize;
    let label = length_label(length_nm);
    let margin = (w.min(h) / 20).max(1);
    let thick = (h / 100).max(2);
    let mut label_drawn = false;
    if length_px >= 2 && length_px + 2 * margin <= w && thick + 2 * margin <= h {
        let x1 = w - margin;
        let x0 = x1 - length_px;
        let y1 = h - margin;
        let y0 = y1 - thick;
        for y in y0..y1 {
            px[y * w + x0..y * w + x1].fill(255);
        }
        // Label above the bar, right-aligned, glyph scale ~h/60.
        let scale = (h / 60).max(1);
        let text_w = label.chars().count() * 6 * scale;
        let text_h = 7 * scale;
        if text_w <= w.saturating_sub(margin) && y0 >= text_h + scale + margin / 2 {
            let ty = y0 - scale - text_h;
            let tx = x1.saturating_sub(text_w);
            for (ci, ch) in label.chars().enumerate() {
                let glyph = glyph(ch);
                for (row, bits) in glyph.iter().enumerate() {
                    for col in 0..5 {
                        if bits & (0b10000 >> col) != 0 {
                            for dy in 0..scale {
                                for dx in 0..scale {
                                    let x = tx + (ci * 6 + col) * scale + dx;
                                    let y = ty + row * scale + dy;
                                    if x < w && y < h {
                                        px[y * w + x] = 255;
                                    }
                                }
                            }
                        }
                    }
                }
            }
            label_drawn = true;
        }
    }
    ScaleBar {
        length_nm,
        length_px,
        label,
        label_drawn,
    }
}

/// 5×7 bitmap glyphs (rows top to bottom, 5 bits each) of the characters a
/// scale-bar label needs.
fn glyph(c: char) -> [u8; 7] {
    match c {
        '0' => [0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e],
        '1' => [0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e],
        '2' => [0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f],
        '3' => [0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e],
        '4' => [0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02],
        '5' => [0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e],
        '6' => [0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e],
        '7' => [0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08],
        '8' => [0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e],
        '9' => [0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c],
        '.' => [0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c],
        'n' => [0x00, 0x00, 0x16, 0x19, 0x11, 0x11, 0x11],
        'm' => [0x00, 0x00, 0x1a, 0x15, 0x15, 0x11, 0x11],
        'µ' => [0x00, 0x00, 0x11, 0x11, 0x11, 0x13, 0x1d],
        _ => [0; 7],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_lengths_and_labels() {
        assert_eq!(nice_length(430.0), 500.0);
        assert_eq!(nice_length(180.0), 200.0);
        assert_eq!(nice_length(1100.0), 1000.0);
        assert_eq!(length_label(500.0), "500 nm");
        assert_eq!(length_label(2000.0), "2 µm");
    }

    #[test]
    fn each_localisation_adds_one() {
        let pts = [
            Point {
                x_nm: 100.0,
                y_nm: 100.0,
                sigma_nm: 10.0,
            },
            Point {
                x_nm: 140.0,
                y_nm: 90.0,
                sigma_nm: 0.0,
            },
        ];
        let o = RenderOptions::covering(&pts, 5.0, 2.0).unwrap();
        let (img, skipped) = render(&pts, &o).unwrap();
        assert_eq!(skipped, 0);
        let total: f64 = img.data.iter().map(|&v| v as f64).sum();
        assert!((total - 2.0).abs() < 1e-5, "{total}");
    }
}
