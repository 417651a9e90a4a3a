//! A publishable PNG of a rendered density: a colour map, a scale bar with
//! its label set in a real font (DejaVu Sans through plotters and
//! fontconfig, anti-aliased), sized to the image, and the pixel size in the
//! PNG's pHYs chunk (pixels per metre) and in a text chunk.
//!
//! ImageJ/Fiji open a PNG through Java's ImageIO (`ij/io/Opener`,
//! `openUsingImageIO`) and read no calibration from it: the pHYs chunk
//! serves other viewers; the 32-bit TIFF (`render --tiff`, with ImageJ's
//! calibration tags) is the file to measure in Fiji.
//!
//! Also the plot of a drift trajectory ([`drift_png`]).
//!
//! Built with the crate's `figure` feature (plotters and the system's
//! fontconfig and FreeType); its `clap` feature lets a command line take a
//! [`Colormap`] by name.

use crate::drift::{DriftEstimate, SegmentDrift};
use crate::error::LocalizeError;
use crate::render::{display_max, length_label, nice_length, Image};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// Why a figure could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum FigureError {
    /// The image has no pixels, or more than a PNG holds a side.
    #[error("cannot draw a {0}x{1} image")]
    Size(usize, usize),
    /// The display range could not be set (`saturate` out of range).
    #[error(transparent)]
    Range(#[from] LocalizeError),
    /// The font engine or the drawing failed; the message says which.
    #[error("{0}")]
    Draw(String),
    /// The PNG encoder failed at `step`.
    #[error("{step}")]
    Png {
        /// Which part of the PNG.
        step: &'static str,
        /// The encoder's error.
        #[source]
        source: png::EncodingError,
    },
}

/// Colour maps of `render --colormap`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum Colormap {
    /// Black to white.
    Gray,
    /// Black, red, yellow, white (ImageJ's and matplotlib's "hot").
    Hot,
    /// Perceptually uniform, black to pale yellow (Picasso's default).
    Magma,
    /// Perceptually uniform, black to yellow.
    Inferno,
    /// Perceptually uniform, dark blue to yellow.
    Viridis,
}

impl Colormap {
    /// RGB of a value in `[0, 1]`.
    pub fn rgb(self, v: f64) -> [u8; 3] {
        let v = if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let byte = |x: f64| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
        let grad = |g: colorous::Gradient| {
            let c = g.eval_continuous(v);
            [c.r, c.g, c.b]
        };
        match self {
            Colormap::Gray => [byte(v); 3],
            Colormap::Hot => [byte(3.0 * v), byte(3.0 * v - 1.0), byte(3.0 * v - 2.0)],
            Colormap::Magma => grad(colorous::MAGMA),
            Colormap::Inferno => grad(colorous::INFERNO),
            Colormap::Viridis => grad(colorous::VIRIDIS),
        }
    }
}

/// How the PNG is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FigureOptions {
    /// Colour map.
    pub colormap: Colormap,
    /// Percent of the non-empty pixels saturated.
    pub saturate: f64,
    /// Whether to draw the scale bar and its label.
    pub scale_bar: bool,
}

/// Where the scale bar went.
#[derive(Clone, Debug, PartialEq)]
pub struct ScaleBar {
    /// Length, nm (1, 2 or 5 × 10ⁿ, about a fifth of the width).
    pub length_nm: f64,
    /// Its label, e.g. "500 nm" or "1 µm".
    pub label: String,
    /// The bar: left, top, right, bottom (exclusive) pixel bounds.
    pub rect: [usize; 4],
    /// Font size of the label, pixels (0: the label did not fit).
    pub font_px: u32,
}

/// Font, bar and margin sizes for an image: the label's font is 4 % of
/// the image height (at least 9 px), the bar a quarter of that (at least
/// 2 px), the margin 3 % of the smaller side.
fn sizes(w: usize, h: usize) -> (u32, usize, usize) {
    let font = ((0.04 * h as f64).round() as u32).max(9);
    let thick = ((font as f64 / 4.0).round() as usize).max(2);
    let margin = ((0.03 * w.min(h) as f64).round() as usize).max(2);
    (font, thick, margin)
}

/// RGB pixels of the figure and its scale bar (`None` when not asked for
/// or when the image is too small for one).
pub fn figure_rgb(
    img: &Image,
    opts: &FigureOptions,
) -> Result<(Vec<u8>, Option<ScaleBar>), FigureError> {
    let (w, h) = (img.width, img.height);
    if w == 0 || h == 0 || w > u32::MAX as usize || h > u32::MAX as usize {
        return Err(FigureError::Size(w, h));
    }
    let vmax = f64::from(display_max(&img.data, opts.saturate)?);
    let mut rgb = Vec::with_capacity(w * h * 3);
    for &v in &img.data {
        rgb.extend_from_slice(&opts.colormap.rgb(f64::from(v) / vmax));
    }
    if !opts.scale_bar {
        return Ok((rgb, None));
    }
    let length_nm = nice_length(w as f64 * img.pixel_nm / 5.0);
    let length_px = (length_nm / img.pixel_nm).round() as usize;
    let (font, thick, margin) = sizes(w, h);
    if length_px < 2 || length_px + 2 * margin > w || thick + 2 * margin > h {
        return Ok((rgb, None));
    }
    let label = length_label(length_nm);
    let rect = [
        w - margin - length_px,
        h - margin - thick,
        w - margin,
        h - margin,
    ];
    // The bar, pixel-exact; the font engine only sets the label.
    for y in rect[1]..rect[3] {
        rgb[(y * w + rect[0]) * 3..(y * w + rect[2]) * 3].fill(255);
    }
    let mut font_px = 0;
    {
        let area = BitMapBackend::with_buffer(&mut rgb, (w as u32, h as u32)).into_drawing_area();
        let style = ("sans-serif", f64::from(font))
            .into_font()
            .color(&WHITE)
            .pos(Pos::new(HPos::Center, VPos::Bottom));
        let (tw, th) = area.estimate_text_size(&label, &style).map_err(|e| {
            FigureError::Draw(format!(
                "the font for the scale bar's label (fonts-dejavu-core, through fontconfig): {e}"
            ))
        })?;
        let (tw, th) = (tw as usize, th as usize);
        // Centred over the bar, kept inside the image; left out if too big.
        let bottom = rect[1].saturating_sub(thick);
        if tw + 2 * margin <= w && bottom >= th + margin / 2 {
            // tw + 2·margin ≤ w, so the clamp's bounds are ordered.
            let cx = ((rect[0] + rect[2]) / 2).clamp(margin + tw / 2, w - margin - tw / 2);
            area.draw_text(&label, &style, (cx as i32, bottom as i32))
                .map_err(|e| FigureError::Draw(format!("drawing the scale bar's label: {e}")))?;
            font_px = font;
        }
        area.present()
            .map_err(|e| FigureError::Draw(format!("drawing the scale bar: {e}")))?;
    }
    Ok((
        rgb,
        Some(ScaleBar {
            length_nm,
            label,
            rect,
            font_px,
        }),
    ))
}

fn draw_err(e: impl std::fmt::Display) -> FigureError {
    FigureError::Draw(format!("drawing the drift plot: {e}"))
}

fn png_err(step: &'static str) -> impl FnOnce(png::EncodingError) -> FigureError {
    move |source| FigureError::Png { step, source }
}

/// The figure as an 8-bit RGB PNG with the pixel size in pHYs (pixels per
/// metre, rounded) and in a `Comment` text chunk.
pub fn figure_png(
    img: &Image,
    opts: &FigureOptions,
) -> Result<(Vec<u8>, Option<ScaleBar>), FigureError> {
    let (rgb, bar) = figure_rgb(img, opts)?;
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, img.width as u32, img.height as u32);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let ppm = (1e9 / img.pixel_nm).round().clamp(1.0, u32::MAX as f64) as u32;
        enc.set_pixel_dims(Some(png::PixelDimensions {
            xppu: ppm,
            yppu: ppm,
            unit: png::Unit::Meter,
        }));
        enc.add_text_chunk(
            "Comment".into(),
            format!(
                "smartagg render: pixel size {} nm{}",
                img.pixel_nm,
                bar.as_ref()
                    .map(|b| format!(", scale bar {}", b.label))
                    .unwrap_or_default()
            ),
        )
        .map_err(png_err("PNG text chunk"))?;
        let mut wr = enc.write_header().map_err(png_err("PNG header"))?;
        wr.write_image_data(&rgb).map_err(png_err("PNG data"))?;
        wr.finish().map_err(png_err("PNG end"))?;
    }
    Ok((out, bar))
}

/// A drift trajectory drawn as a 900×520 PNG: dx and dy (nm) against time
/// (seconds when `frame_s`, the length of a time unit, is known, else in
/// `unit`s).
pub fn drift_png(
    est: &DriftEstimate,
    frame_s: Option<f64>,
    unit: &str,
) -> Result<Vec<u8>, FigureError> {
    let (w, h) = (900u32, 520u32);
    let scale = frame_s.unwrap_or(1.0);
    let x_desc = if frame_s.is_some() {
        "time (s)".to_string()
    } else {
        format!("time ({unit})")
    };
    let pts = |f: fn(&SegmentDrift) -> f64| -> Vec<(f64, f64)> {
        est.segments
            .iter()
            .map(|g| (g.t_mean * scale, f(g)))
            .collect()
    };
    let (xs, ys) = (pts(|g| g.dx_nm), pts(|g| g.dy_nm));
    let t0 = est.segments.first().map_or(0.0, |g| g.t_start * scale);
    let t1 = est
        .segments
        .last()
        .map_or(1.0, |g| g.t_end * scale)
        .max(t0 + 1e-9);
    let (mut lo, mut hi) = (0.0f64, 0.0f64);
    for &(_, v) in xs.iter().chain(&ys) {
        lo = lo.min(v);
        hi = hi.max(v);
    }
    let pad = ((hi - lo) * 0.1).max(5.0);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(draw_err)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("Estimated stage drift", ("sans-serif", 22))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(60)
            .build_cartesian_2d(t0..t1, (lo - pad)..(hi + pad))
            .map_err(draw_err)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc("drift (nm)")
            .draw()
            .map_err(draw_err)?;
        for (series, colour, name) in [(&xs, BLUE, "dx"), (&ys, RED, "dy")] {
            chart
                .draw_series(LineSeries::new(
                    series.iter().copied(),
                    colour.stroke_width(2),
                ))
                .map_err(draw_err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            chart
                .draw_series(series.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(draw_err)?;
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(draw_err)?;
        root.present().map_err(draw_err)?;
    }
    let mut png_bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png_bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut wr = enc.write_header().map_err(png_err("PNG header"))?;
        wr.write_image_data(&buf).map_err(png_err("PNG data"))?;
    }
    Ok(png_bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, pixel_nm: f64) -> Image {
        Image {
            width: w,
            height: h,
            origin_x_nm: 0.0,
            origin_y_nm: 0.0,
            pixel_nm,
            data: vec![0.0; w * h],
        }
    }

    #[test]
    fn colour_maps_run_dark_to_bright() {
        for m in [
            Colormap::Gray,
            Colormap::Hot,
            Colormap::Magma,
            Colormap::Inferno,
            Colormap::Viridis,
        ] {
            let lum = |c: [u8; 3]| c.iter().map(|&x| u32::from(x)).sum::<u32>();
            assert!(lum(m.rgb(0.0)) < 160, "{m:?} {:?}", m.rgb(0.0));
            assert!(lum(m.rgb(1.0)) > 400, "{m:?} {:?}", m.rgb(1.0));
            assert_eq!(m.rgb(f64::NAN), m.rgb(0.0));
        }
        assert_eq!(Colormap::Hot.rgb(0.5), [255, 128, 0]);
    }

    #[test]
    fn bar_and_label_sit_bottom_right_in_a_real_font() {
        let img = image(400, 300, 10.0);
        let opts = FigureOptions {
            colormap: Colormap::Gray,
            saturate: 0.5,
            scale_bar: true,
        };
        let (rgb, bar) = figure_rgb(&img, &opts).unwrap();
        let bar = bar.unwrap();
        // A fifth of 4 µm is 800 nm: the nice length is 1 µm, 100 px.
        assert_eq!(bar.label, "1 µm");
        assert_eq!(bar.rect[2] - bar.rect[0], 100);
        let (font, thick, margin) = sizes(400, 300);
        assert_eq!(
            bar.rect,
            [
                400 - margin - 100,
                300 - margin - thick,
                400 - margin,
                300 - margin
            ]
        );
        assert_eq!(bar.font_px, font);
        let at = |x: usize, y: usize| rgb[(y * 400 + x) * 3];
        // Every pixel of the bar is white, the row below it black.
        let row = bar.rect[1] + thick / 2;
        let white = (0..400).filter(|&x| at(x, row) == 255).count();
        assert_eq!(white, 100);
        assert_eq!(at(bar.rect[0] + 50, bar.rect[3]), 0);
        // The label above the bar: white pixels and anti-aliased grey ones.
        let label: Vec<u8> = (0..bar.rect[1])
            .flat_map(|y| (0..400).map(move |x| (x, y)))
            .map(|(x, y)| at(x, y))
            .collect();
        let bright = label.iter().filter(|&&v| v >= 160).count();
        let partial = label.iter().filter(|&&v| v > 0 && v < 160).count();
        let max = label.iter().max().copied().unwrap_or(0);
        assert!(
            bright > 20 && max > 200,
            "{bright} bright label pixels, max {max}"
        );
        assert!(
            partial > 20,
            "{partial} grey label pixels: no anti-aliasing"
        );
        // Images too small for the label, or for the bar, still render.
        for (w, h) in [(60, 40), (25, 300), (3, 3), (1, 1)] {
            let (_, bar) = figure_rgb(&image(w, h, 10.0), &opts).unwrap();
            if let Some(b) = bar {
                assert!(b.rect[2] <= w && b.rect[3] <= h, "{w}x{h}: {b:?}");
            }
        }
        // Without a bar the image is the density alone.
        let (plain, none) = figure_rgb(
            &img,
            &FigureOptions {
                scale_bar: false,
                ..opts
            },
        )
        .unwrap();
        assert!(none.is_none());
        assert!(plain.iter().all(|&v| v == 0));
    }

    #[test]
    fn the_png_holds_the_density_and_the_pixel_size() {
        // Two localisations 80 nm apart, rendered at 5 nm.
        use crate::render::{render, Point, RenderOptions};
        let pts: Vec<Point> = [200.0, 280.0]
            .iter()
            .map(|&x_nm| Point {
                x_nm,
                y_nm: 150.0,
                sigma_nm: 8.0,
            })
            .collect();
        let (img, _) = render(&pts, &RenderOptions::covering(&pts, 5.0, 2.0).unwrap()).unwrap();
        let opts = FigureOptions {
            colormap: Colormap::Gray,
            saturate: 0.5,
            scale_bar: false,
        };
        let (bytes, bar) = figure_png(&img, &opts).unwrap();
        assert!(bar.is_none());
        let mut reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        let dims = reader.info().pixel_dims.unwrap();
        // 5 nm pixels: 2 × 10⁸ per metre.
        assert_eq!((dims.xppu, dims.unit), (200_000_000, png::Unit::Meter));
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!(
            (info.width as usize, info.height as usize),
            (img.width, img.height)
        );
        let grey = |x_nm: f64| {
            let i = ((x_nm - img.origin_x_nm) / img.pixel_nm) as usize;
            let j = ((150.0 - img.origin_y_nm) / img.pixel_nm) as usize;
            buf[(j * img.width + i) * 3]
        };
        // Each peak near full scale, nothing between them.
        assert!(grey(200.0) > 200, "{}", grey(200.0));
        assert!(grey(280.0) > 200, "{}", grey(280.0));
        assert_eq!(grey(240.0), 0);
    }

    #[test]
    fn a_drift_plot_is_a_png_of_its_size() {
        let seg = |k: f64| SegmentDrift {
            t_start: 10.0 * k,
            t_end: 10.0 * (k + 1.0),
            t_mean: 10.0 * k + 5.0,
            count: 100,
            dx_nm: 3.0 * k,
            dy_nm: -2.0 * k,
        };
        let est = DriftEstimate {
            segments: (0..3).map(|k| seg(k as f64)).collect(),
            bin_nm: 15.0,
            used: 3,
            total: 3,
            residual_rms_nm: 1.0,
        };
        let bytes = drift_png(&est, Some(1e-4), "plane").unwrap();
        let reader = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .unwrap();
        assert_eq!((reader.info().width, reader.info().height), (900, 520));
    }
}
