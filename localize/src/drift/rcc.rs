//! Redundant cross-correlation (RCC).
//!
//! Each segment becomes a histogram of its localisations (bins of
//! `bin_nm`) in an image padded to hold every shift up to `max_drift_nm`
//! without wrap-around; its FFT is kept. For a pair `i < j` the correlation
//! `C(s) = Σ_r I_i(r) I_j(r + s)` is `IFFT(conj(F_i) · F_j)`, smoothed by a
//! Gaussian of one bin (applied in Fourier space, free) so that its peak is
//! a smooth hump whatever the localisations' sparseness; it peaks at
//! `s = d_j − d_i`. The peak is refined to sub-bin precision by a
//! three-point Gaussian fit along each axis (a parabola where a value is not
//! positive).

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

use rayon::prelude::*;

use super::{
    segments_from, split, DriftError, DriftEstimate, DriftOptions, DriftPoint, DEFAULT_BIN_NM,
    MAX_FFT_BINS,
};

/// Smoothing of the correlation, bins (σ of a Gaussian).
const SMOOTH_BINS: f64 = 1.0;

/// A segment image size: the smallest FFT-friendly size ≥ `n` (powers of
/// 2, 3 and 5 only, which rustfft does fastest).
fn fft_size(n: usize) -> usize {
    let mut m = n.max(1);
    loop {
        let mut r = m;
        for f in [2, 3, 5] {
            while r.is_multiple_of(f) {
                r /= f;
            }
        }
        if r == 1 {
            return m;
        }
        m += 1;
    }
}

/// The grid all segments are rendered on.
#[derive(Debug, Clone, Copy)]
struct Grid {
    x0: f64,
    y0: f64,
    bin: f64,
    nx: usize,
    ny: usize,
    /// Largest shift searched, bins.
    reach: usize,
}

impl Grid {
    /// The grid covering `points` at `bin_nm` (or the automatic bin) with
    /// room for shifts of `max_drift_nm`.
    fn new(points: &[DriftPoint], opts: &DriftOptions) -> Result<Grid, DriftError> {
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in points {
            x0 = x0.min(p.x_nm);
            x1 = x1.max(p.x_nm);
            y0 = y0.min(p.y_nm);
            y1 = y1.max(p.y_nm);
        }
        let span = (x1 - x0).max(y1 - y0);
        let size = |bin: f64| -> Option<(usize, usize, usize)> {
            let reach = (opts.max_drift_nm / bin).ceil() + 1.0;
            let nx = ((x1 - x0) / bin).floor() + 1.0 + reach;
            let ny = ((y1 - y0) / bin).floor() + 1.0 + reach;
            if !(nx * ny <= MAX_FFT_BINS as f64) {
                return None;
            }
            let (nx, ny) = (fft_size(nx as usize), fft_size(ny as usize));
            (nx * ny <= MAX_FFT_BINS).then_some((nx, ny, reach as usize))
        };
        let (bin, (nx, ny, reach)) = match opts.bin_nm {
            Some(b) => (
                b,
                size(b).ok_or(DriftError::ImageTooLarge {
                    span_nm: span + opts.max_drift_nm,
                    bin_nm: b,
                    max: MAX_FFT_BINS,
                })?,
            ),
            None => {
                // The default bin, coarsened until the images fit.
                let mut b = DEFAULT_BIN_NM;
                loop {
                    if let Some(s) = size(b) {
                        break (b, s);
                    }
                    b *= 1.25;
                    if !b.is_finite() {
                        return Err(DriftError::ImageTooLarge {
                            span_nm: span + opts.max_drift_nm,
                            bin_nm: b,
                            max: MAX_FFT_BINS,
                        });
                    }
                }
            }
        };
        Ok(Grid {
            x0,
            y0,
            bin,
            nx,
            ny,
            reach,
        })
    }
}

/// 2-D FFT in place, rows then columns.
struct Fft2 {
    nx: usize,
    ny: usize,
    row: Arc<dyn Fft<f64>>,
    col: Arc<dyn Fft<f64>>,
}

impl Fft2 {
    fn new(nx: usize, ny: usize, inverse: bool) -> Fft2 {
        let mut p = FftPlanner::new();
        let (row, col) = if inverse {
            (p.plan_fft_inverse(nx), p.plan_fft_inverse(ny))
        } else {
            (p.plan_fft_forward(nx), p.plan_fft_forward(ny))
        };
        Fft2 { nx, ny, row, col }
    }

    fn run(&self, data: &mut [Complex<f64>]) {
        self.row.process(data);
        let mut column = vec![Complex::new(0.0, 0.0); self.ny];
        for x in 0..self.nx {
            for y in 0..self.ny {
                column[y] = data[y * self.nx + x];
            }
            self.col.process(&mut column);
            for y in 0..self.ny {
                data[y * self.nx + x] = column[y];
            }
        }
    }
}

/// The spectrum of one segment's histogram.
fn spectrum(points: &[DriftPoint], g: &Grid, fft: &Fft2) -> Vec<Complex<f64>> {
    let mut img = vec![Complex::new(0.0, 0.0); g.nx * g.ny];
    for p in points {
        let i = ((p.x_nm - g.x0) / g.bin).floor() as usize;
        let j = ((p.y_nm - g.y0) / g.bin).floor() as usize;
        if i < g.nx && j < g.ny {
            img[j * g.nx + i].re += 1.0;
        }
    }
    fft.run(&mut img);
    img
}

/// Sub-bin offset of a peak from its value and its two neighbours.
fn refine(minus: f64, centre: f64, plus: f64) -> f64 {
    let offset = if minus > 0.0 && centre > 0.0 && plus > 0.0 {
        let (a, b, c) = (minus.ln(), centre.ln(), plus.ln());
        let den = a - 2.0 * b + c;
        if den < 0.0 {
            0.5 * (a - c) / den
        } else {
            0.0
        }
    } else {
        let den = minus - 2.0 * centre + plus;
        if den < 0.0 {
            0.5 * (minus - plus) / den
        } else {
            0.0
        }
    };
    offset.clamp(-1.0, 1.0)
}

/// The shift `d_j − d_i` (nm) from two spectra, or `None` if the
/// correlation is empty within the search range.
fn pair_shift(
    fi: &[Complex<f64>],
    fj: &[Complex<f64>],
    g: &Grid,
    ifft: &Fft2,
    smooth: &[f64],
) -> Option<(f64, f64)> {
    let mut c: Vec<Complex<f64>> = fi
        .iter()
        .zip(fj)
        .zip(smooth)
        .map(|((a, b), &s)| a.conj() * b * s)
        .collect();
    ifft.run(&mut c);
    let (nx, ny) = (g.nx as isize, g.ny as isize);
    let at = |sx: isize, sy: isize| -> f64 {
        let x = sx.rem_euclid(nx) as usize;
        let y = sy.rem_euclid(ny) as usize;
        c[y * g.nx + x].re
    };
    let r = g.reach as isize;
    let mut best = (0isize, 0isize, f64::NEG_INFINITY);
    for sy in -r..=r {
        for sx in -r..=r {
            let v = at(sx, sy);
            if v > best.2 {
                best = (sx, sy, v);
            }
        }
    }
    let (sx, sy, v) = best;
    // The correlation of non-empty images is positive at its peak; rounding
    // leaves ~1e-12 of the total where there is nothing.
    if !(v > 1e-9 * c.len() as f64) {
        return None;
    }
    let fx = refine(at(sx - 1, sy), v, at(sx + 1, sy));
    let fy = refine(at(sx, sy - 1), v, at(sx, sy + 1));
    Some(((sx as f64 + fx) * g.bin, (sy as f64 + fy) * g.bin))
}

/// Least-squares drifts (`d_0 = 0`) from the kept pairs `(i, j, rx, ry)`;
/// `None` if some segment is not connected to the first.
fn solve(k: usize, pairs: &[(usize, usize, f64, f64)]) -> Option<Vec<(f64, f64)>> {
    let m = k - 1;
    // Normal equations of r_ij = d_j − d_i over the unknowns d_1 … d_{k−1}.
    let mut a = vec![0.0f64; m * m];
    let mut bx = vec![0.0; m];
    let mut by = vec![0.0; m];
    for &(i, j, rx, ry) in pairs {
        let (ui, uj) = (i.checked_sub(1), j.checked_sub(1));
        if let Some(u) = uj {
            a[u * m + u] += 1.0;
            bx[u] += rx;
            by[u] += ry;
        }
        if let Some(u) = ui {
            a[u * m + u] += 1.0;
            bx[u] -= rx;
            by[u] -= ry;
        }
        if let (Some(p), Some(q)) = (ui, uj) {
            a[p * m + q] -= 1.0;
            a[q * m + p] -= 1.0;
        }
    }
    // Cholesky: the matrix is positive definite exactly when every segment
    // is connected to the first through kept pairs.
    let mut l = vec![0.0f64; m * m];
    for r in 0..m {
        for c in 0..=r {
            let mut s = a[r * m + c];
            for q in 0..c {
                s -= l[r * m + q] * l[c * m + q];
            }
            if r == c {
                if !(s > 1e-9) {
                    return None;
                }
                l[r * m + r] = s.sqrt();
            } else {
                l[r * m + c] = s / l[c * m + c];
            }
        }
    }
    let back = |b: &[f64]| -> Vec<f64> {
        let mut z = vec![0.0; m];
        for r in 0..m {
            let mut s = b[r];
            for q in 0..r {
                s -= l[r * m + q] * z[q];
            }
            z[r] = s / l[r * m + r];
        }
        let mut x = vec![0.0; m];
        for r in (0..m).rev() {
            let mut s = z[r];
            for q in r + 1..m {
                s -= l[q * m + r] * x[q];
            }
            x[r] = s / l[r * m + r];
        }
        x
    };
    let (x, y) = (back(&bx), back(&by));
    let mut d = vec![(0.0, 0.0)];
    d.extend(x.into_iter().zip(y));
    Some(d)
}

fn residual(p: &(usize, usize, f64, f64), d: &[(f64, f64)]) -> f64 {
    let (i, j, rx, ry) = *p;
    (rx - (d[j].0 - d[i].0)).hypot(ry - (d[j].1 - d[i].1))
}

/// Estimates the drift by redundant cross-correlation (see the module docs).
pub fn rcc(points: &[DriftPoint], opts: &DriftOptions) -> Result<DriftEstimate, DriftError> {
    let (bounds, groups) = split(points, opts)?;
    let all: Vec<DriftPoint> = groups.iter().flatten().copied().collect();
    let g = Grid::new(&all, opts)?;
    let fwd = Fft2::new(g.nx, g.ny, false);
    let inv = Fft2::new(g.nx, g.ny, true);
    let spectra: Vec<Vec<Complex<f64>>> = groups
        .par_iter()
        .map(|pts| spectrum(pts, &g, &fwd))
        .collect();
    // Gaussian smoothing of the correlation, as a transfer function.
    let freq = |i: usize, n: usize| {
        let f = if i <= n / 2 {
            i as f64
        } else {
            i as f64 - n as f64
        };
        f / n as f64
    };
    let two_pi2 = 2.0 * std::f64::consts::PI.powi(2) * SMOOTH_BINS * SMOOTH_BINS;
    let mut smooth = vec![0.0; g.nx * g.ny];
    for y in 0..g.ny {
        for x in 0..g.nx {
            let (u, v) = (freq(x, g.nx), freq(y, g.ny));
            smooth[y * g.nx + x] = (-two_pi2 * (u * u + v * v)).exp();
        }
    }
    let k = groups.len();
    let pairs_ij: Vec<(usize, usize)> = (0..k)
        .flat_map(|i| (i + 1..k).map(move |j| (i, j)))
        .collect();
    let found: Vec<Option<(usize, usize, f64, f64)>> = pairs_ij
        .par_iter()
        .map(|&(i, j)| {
            pair_shift(&spectra[i], &spectra[j], &g, &inv, &smooth).map(|(x, y)| (i, j, x, y))
        })
        .collect();
    let total = found.len();
    let mut pairs: Vec<(usize, usize, f64, f64)> = found.into_iter().flatten().collect();
    let mut d = solve(k, &pairs).ok_or_else(|| {
        let connected = |s: usize| pairs.iter().any(|p| p.0 == s || p.1 == s);
        DriftError::NoCorrelation {
            segment: (0..k).find(|&s| !connected(s)).unwrap_or(0) + 1,
        }
    })?;
    // Drop the worst pair while it is beyond the threshold and the rest
    // still connects every segment.
    while let Some((worst, r)) = pairs
        .iter()
        .enumerate()
        .map(|(n, p)| (n, residual(p, &d)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
    {
        if r <= opts.reject_nm {
            break;
        }
        let mut fewer = pairs.clone();
        fewer.remove(worst);
        match solve(k, &fewer) {
            Some(e) => {
                pairs = fewer;
                d = e;
            }
            None => break,
        }
    }
    let rms = (pairs.iter().map(|p| residual(p, &d).powi(2)).sum::<f64>()
        / pairs.len().max(1) as f64)
        .sqrt();
    Ok(DriftEstimate {
        segments: segments_from(&bounds, &groups, &d),
        bin_nm: g.bin,
        used: pairs.len(),
        total,
        residual_rms_nm: rms,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_sizes_have_small_factors() {
        assert_eq!(fft_size(1), 1);
        assert_eq!(fft_size(7), 8);
        assert_eq!(fft_size(121), 125);
        assert_eq!(fft_size(1025), 1080);
    }

    #[test]
    fn a_gaussian_peak_is_refined_exactly() {
        let g = |x: f64| (-(x - 0.3f64).powi(2) / 2.0).exp();
        let o = refine(g(-1.0), g(0.0), g(1.0));
        assert!((o - 0.3).abs() < 1e-12, "{o}");
        assert_eq!(refine(1.0, 1.0, 1.0), 0.0);
    }

    #[test]
    fn least_squares_recovers_consistent_pairs_and_sees_disconnection() {
        let d = [(0.0, 0.0), (1.0, 2.0), (3.0, -1.0)];
        let pairs: Vec<_> = [(0, 1), (0, 2), (1, 2)]
            .iter()
            .map(|&(i, j)| (i, j, d[j].0 - d[i].0, d[j].1 - d[i].1))
            .collect();
        let s = solve(3, &pairs).unwrap();
        for (a, b) in s.iter().zip(d) {
            assert!((a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12);
        }
        assert!(solve(3, &pairs[..1]).is_none());
    }
}
