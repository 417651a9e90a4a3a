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
//! For display, the density is divided by its `(100 − saturate)`th
//! percentile over non-empty pixels ([`display_max`], default 0.5 %
//! saturated); the scale bar is 1, 2 or 5 × 10ⁿ nm, about a fifth of the
//! width ([`nice_length`], [`length_label`]). The PNG figure with its colour
//! map and scale bar is the `figure` module's (crate feature `figure`).

use crate::erf::erf;
use crate::error::{check_option, LocalizeError};
use crate::table::{CsvTable, MissingColumn};

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

/// The points of a localisation table to render, and the rows left out.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TablePoints {
    /// The localisations to render, nm.
    pub points: Vec<Point>,
    /// Rows left out as failed fits (`fit_status` ≠ 0).
    pub failed: usize,
    /// Rows without a finite position.
    pub unusable: usize,
    /// Rows that are not rows of numbers (counted by the reader).
    pub not_numbers: usize,
}

impl TablePoints {
    /// Keeps a point with a finite position; counts the others.
    pub fn push(&mut self, x_nm: f64, y_nm: f64, sigma_nm: f64) {
        if x_nm.is_finite() && y_nm.is_finite() {
            self.points.push(Point {
                x_nm,
                y_nm,
                sigma_nm,
            });
        } else {
            self.unusable += 1;
        }
    }

    /// The points of a ThunderSTORM CSV table (nm): `x [nm]`, `y [nm]` and
    /// the uncertainty as the Gaussian's σ; rows whose `fit_status` is not
    /// 0 are left out unless `include_failed`. `not_numbers`: rows the
    /// reader skipped.
    pub fn from_csv(
        t: &CsvTable,
        not_numbers: usize,
        include_failed: bool,
    ) -> Result<TablePoints, MissingColumn> {
        let (cx, cy) = (t.require(&["x [nm]"])?, t.require(&["y [nm]"])?);
        let cu = t.require(&[
            "uncertainty [nm]",
            "uncertainty_xy [nm]",
            "uncertainty_xy",
            "uncertainty",
        ])?;
        let cs = t.column(&["fit_status"]);
        let mut out = TablePoints {
            points: Vec::with_capacity(t.rows.len()),
            not_numbers,
            ..Default::default()
        };
        for r in &t.rows {
            if let Some(c) = cs {
                if r[c] != 0.0 && !include_failed {
                    out.failed += 1;
                    continue;
                }
            }
            out.push(r[cx], r[cy], r[cu]);
        }
        Ok(out)
    }
}

/// Leaves out the points too far from the median position (or too blurred)
/// for one image of at most [`MAX_PIXELS`] pixels at `pixel_nm`; returns
/// how many were left out.
pub fn drop_outliers(points: &mut Vec<Point>, pixel_nm: f64) -> usize {
    if points.is_empty() {
        return 0;
    }
    let median = |f: fn(&Point) -> f64| {
        let mut v: Vec<f64> = points.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (mx, my) = (median(|p| p.x_nm), median(|p| p.y_nm));
    // A square image of MAX_PIXELS, with room for the margins.
    let half = 0.35 * (MAX_PIXELS as f64).sqrt() * pixel_nm;
    let before = points.len();
    points.retain(|p| {
        (p.x_nm - mx).abs() <= half && (p.y_nm - my).abs() <= half && p.sigma_nm <= half / 8.0
    });
    before - points.len()
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

    #[test]
    fn table_points_leave_out_failed_fits_and_count_the_rest() {
        let text = "\"x [nm]\",\"y [nm]\",\"uncertainty [nm]\",\"fit_status\"\n1,2,3,0\n4,5,6,2\nnan,1,1,0\n";
        let t = CsvTable::read(text.as_bytes()).unwrap();
        let p = TablePoints::from_csv(&t, 7, false).unwrap();
        assert_eq!(
            (p.points.len(), p.failed, p.unusable, p.not_numbers),
            (1, 1, 1, 7)
        );
        assert_eq!(
            p.points[0],
            Point {
                x_nm: 1.0,
                y_nm: 2.0,
                sigma_nm: 3.0
            }
        );
        assert_eq!(TablePoints::from_csv(&t, 0, true).unwrap().points.len(), 2);
        let t = CsvTable::read("\"x [nm]\",\"q\"\n1,2\n".as_bytes()).unwrap();
        let e = TablePoints::from_csv(&t, 0, false).unwrap_err().to_string();
        assert_eq!(e, "has no column \"y [nm]\" (columns: x [nm], q)");
    }

    #[test]
    fn outliers_far_from_the_median_are_left_out() {
        let p = |x_nm: f64, sigma_nm: f64| Point {
            x_nm,
            y_nm: 0.0,
            sigma_nm,
        };
        let mut pts = vec![
            p(0.0, 1.0),
            p(10.0, 1.0),
            p(20.0, 1.0),
            p(1e9, 1.0),
            p(5.0, 1e9),
        ];
        assert_eq!(drop_outliers(&mut pts, 10.0), 2);
        assert_eq!(pts.len(), 3);
        assert_eq!(drop_outliers(&mut Vec::new(), 10.0), 0);
    }
}
