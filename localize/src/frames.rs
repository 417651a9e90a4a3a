//! Frame-based detection and localisation for EMCCD, sCMOS and
//! fixed-aggregation SPAD frames, with ThunderSTORM's defaults:
//!
//! 1. **Filter**: the B-spline wavelet of ThunderSTORM (à trous, cubic
//!    B-spline kernel `[1 4 6 4 1]/16`): `V1 = I ⊛ k`, `V2 = V1 ⊛ k↑2` (the
//!    kernel dilated by 2), wavelet planes `F1 = I − V1` (noise) and
//!    `F2 = V1 − V2` (spots). Borders are mirrored.
//! 2. **Threshold**: `F2 ≥ factor · std(F1)` with `factor` 1.5 by default;
//!    std is estimated robustly (1.4826 × median absolute deviation) so that
//!    bright molecules do not raise it.
//! 3. **Candidates**: 8-neighbour local maxima of F2 above the threshold
//!    (ties: strictly greater than earlier neighbours in raster order, not
//!    less than later ones — one candidate per plateau).
//! 4. **Fit**: an `R × R` ROI around each candidate (shifted to stay inside
//!    the frame), fitted with the chosen estimator and noise model.
//!
//! Frames are converted from ADU to photo-electrons first:
//! `(ADU − offset) · e⁻/ADU / EM gain`.

use crate::error::{check_option, LocalizeError};
use crate::fit::{fit_roi, Estimator, FitOptions, NoiseModel};
use crate::roi::{apply_hot_pixels, HotPixelMode, PixelMaps, RoiView};
use crate::spad::{fit_binomial, SpadRoi};
use crate::table::Localization;

/// ADU → photo-electron conversion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conversion {
    /// Camera bias, ADU.
    pub offset_adu: f64,
    /// Electrons per ADU (after multiplication for an EMCCD).
    pub e_per_adu: f64,
    /// Electron-multiplication gain (1 for sCMOS and SPAD).
    pub em_gain: f64,
}

impl Conversion {
    /// No conversion (data already in photons or counts).
    pub const IDENTITY: Conversion = Conversion {
        offset_adu: 0.0,
        e_per_adu: 1.0,
        em_gain: 1.0,
    };

    /// Checks the values, naming the first bad one.
    pub fn validate(&self) -> Result<(), LocalizeError> {
        check_option("offset-adu", self.offset_adu, -1e9, 1e9)?;
        check_option("e-per-adu", self.e_per_adu, 1e-9, 1e9)?;
        check_option("em-gain", self.em_gain, 1.0, 1e5)?;
        Ok(())
    }

    /// Converts a frame in place.
    pub fn apply(&self, data: &mut [f64]) {
        let k = self.e_per_adu / self.em_gain;
        for v in data {
            *v = (*v - self.offset_adu) * k;
        }
    }
}

/// Everything the frame pipeline needs.
#[derive(Clone, Debug)]
pub struct FramePipeline {
    /// ADU conversion.
    pub conversion: Conversion,
    /// Fitting ROI side (odd).
    pub roi_side: usize,
    /// Threshold on F2 in units of the noise std of F1.
    pub threshold_factor: f64,
    /// Estimator.
    pub estimator: Estimator,
    /// Fit options (σ, noise model).
    pub fit: FitOptions,
    /// Sample-plane pixel size, nm.
    pub pixel_nm: f64,
    /// sCMOS read-noise variance per frame pixel, e⁻² (noise model sCMOS).
    pub read_var: Option<Vec<f64>>,
    /// Hot pixels of the frame, and what to do with them.
    pub hot: Option<(Vec<bool>, HotPixelMode)>,
    /// Bit-planes per frame, for the SPAD binomial fit of fixed-aggregation
    /// frames (the molecule is taken as on during every plane).
    pub spad_planes: Option<u32>,
}

impl FramePipeline {
    /// Checks the options against a frame size.
    pub fn validate(&self, width: usize, height: usize) -> Result<(), LocalizeError> {
        self.conversion.validate()?;
        self.fit.validate()?;
        check_option("threshold-factor", self.threshold_factor, 0.0, 1e6)?;
        check_option("pixel-nm", self.pixel_nm, 1e-3, 1e6)?;
        if self.roi_side < 3
            || self.roi_side.is_multiple_of(2)
            || self.roi_side > crate::psf::MAX_SIDE
        {
            return Err(LocalizeError::InvalidOption {
                name: "roi",
                value: self.roi_side as f64,
                why: format!(
                    "the fitting ROI side must be odd, 3 to {}",
                    crate::psf::MAX_SIDE
                ),
            });
        }
        if width < self.roi_side || height < self.roi_side {
            return Err(LocalizeError::FrameTooSmall {
                width,
                height,
                side: self.roi_side,
            });
        }
        if let Some(v) = &self.read_var {
            if v.len() != width * height {
                return Err(LocalizeError::MapShape {
                    map: "read-variance",
                    len: v.len(),
                    expected: width * height,
                });
            }
        }
        if let Some((h, _)) = &self.hot {
            if h.len() != width * height {
                return Err(LocalizeError::MapShape {
                    map: "hot-pixel",
                    len: h.len(),
                    expected: width * height,
                });
            }
        }
        if self.estimator == Estimator::SpadMle && self.spad_planes.is_none() {
            return Err(LocalizeError::InvalidOption {
                name: "planes",
                value: 0.0,
                why: "the SPAD binomial fit of frames needs the number of bit-planes per frame"
                    .into(),
            });
        }
        Ok(())
    }
}

/// Mirrored index into `[0, n)`.
#[inline]
fn mirror(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n == 1 {
        return 0;
    }
    let mut i = i;
    // Reflect (without repeating the edge) until inside.
    while i < 0 || i >= n {
        i = if i < 0 { -i } else { 2 * (n - 1) - i };
    }
    i as usize
}

/// Separable convolution with the cubic B-spline kernel dilated by `step`.
fn bspline(img: &[f64], w: usize, h: usize, step: isize) -> Vec<f64> {
    const K: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (t, k) in K.iter().enumerate() {
                s += k * img[y * w + mirror(x as isize + (t as isize - 2) * step, w)];
            }
            tmp[y * w + x] = s;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (t, k) in K.iter().enumerate() {
                s += k * tmp[mirror(y as isize + (t as isize - 2) * step, h) * w + x];
            }
            out[y * w + x] = s;
        }
    }
    out
}

/// Wavelet planes `(F1, F2)` of a frame.
pub fn wavelet(img: &[f64], w: usize, h: usize) -> (Vec<f64>, Vec<f64>) {
    let v1 = bspline(img, w, h, 1);
    let v2 = bspline(&v1, w, h, 2);
    let f1 = img.iter().zip(&v1).map(|(a, b)| a - b).collect();
    let f2 = v1.iter().zip(&v2).map(|(a, b)| a - b).collect();
    (f1, f2)
}

/// Robust standard deviation: 1.4826 × median absolute deviation (0 for an
/// empty input). Non-finite values are ignored.
pub fn robust_std(v: &[f64]) -> f64 {
    let mut a: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if a.is_empty() {
        return 0.0;
    }
    let mid = a.len() / 2;
    let (_, m, _) = a.select_nth_unstable_by(mid, |x, y| x.total_cmp(y));
    let med = *m;
    for x in a.iter_mut() {
        *x = (*x - med).abs();
    }
    let (_, d, _) = a.select_nth_unstable_by(mid, |x, y| x.total_cmp(y));
    1.4826 * *d
}

/// 8-neighbour local maxima of `f` at or above `threshold`, raster order.
pub fn local_maxima(f: &[f64], w: usize, h: usize, threshold: f64) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = f[y * w + x];
            if !(v >= threshold) {
                continue;
            }
            let mut is_max = true;
            'n: for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let (nx, ny) = (x as isize + dx, y as isize + dy);
                    if nx < 0 || ny < 0 || nx >= w as isize || ny >= h as isize {
                        continue;
                    }
                    let u = f[ny as usize * w + nx as usize];
                    let earlier = dy < 0 || (dy == 0 && dx < 0);
                    if (earlier && u >= v) || (!earlier && u > v) {
                        is_max = false;
                        break 'n;
                    }
                }
            }
            if is_max {
                out.push((x, y));
            }
        }
    }
    out
}

/// What a frame gave.
#[derive(Clone, Debug, Default)]
pub struct FrameResult {
    /// Localisations (failed fits included, flagged).
    pub localizations: Vec<Localization>,
    /// Candidates found.
    pub candidates: usize,
    /// The threshold used on F2, photons.
    pub threshold: f64,
}

/// Detects and localises the molecules of one frame (raw ADU values).
/// `frame_no` is written to the table (1-based by convention).
pub fn localize_frame(
    p: &FramePipeline,
    raw: &[f64],
    width: usize,
    height: usize,
    frame_no: u64,
) -> Result<FrameResult, LocalizeError> {
    p.validate(width, height)?;
    if raw.len() != width * height {
        return Err(LocalizeError::MapShape {
            map: "frame",
            len: raw.len(),
            expected: width * height,
        });
    }
    let mut img = raw.to_vec();
    p.conversion.apply(&mut img);
    // Non-finite pixels are detected as nothing and fitted as flagged input.
    let filt: Vec<f64> = img
        .iter()
        .map(|&v| if v.is_finite() { v } else { 0.0 })
        .collect();
    let (f1, f2) = wavelet(&filt, width, height);
    let threshold = p.threshold_factor * robust_std(&f1);
    let cands = local_maxima(&f2, width, height, threshold.max(f64::MIN_POSITIVE));
    let r = p.roi_side;
    let mut locs = Vec::with_capacity(cands.len());
    for &(cx, cy) in &cands {
        let x0 = cx.saturating_sub(r / 2).min(width - r);
        let y0 = cy.saturating_sub(r / 2).min(height - r);
        let mut data = Vec::with_capacity(r * r);
        let mut maps = PixelMaps::uniform(r);
        let mut hot = vec![false; r * r];
        for j in 0..r {
            for i in 0..r {
                let q = (y0 + j) * width + x0 + i;
                data.push(img[q]);
                if let Some(v) = &p.read_var {
                    maps.read_var[j * r + i] = v[q];
                }
                if let Some((h, _)) = &p.hot {
                    hot[j * r + i] = h[q];
                }
            }
        }
        if let Some((_, mode)) = &p.hot {
            apply_hot_pixels(&mut data, &hot, *mode, &mut maps)?;
        }
        let with_maps = p.read_var.is_some() || p.hot.is_some();
        let fit = match (p.estimator, p.spad_planes) {
            (Estimator::SpadMle, Some(planes)) => {
                let counts: Vec<u32> = data
                    .iter()
                    .map(|&v| {
                        if v.is_finite() {
                            v.round().clamp(0.0, u32::MAX as f64) as u32
                        } else {
                            0
                        }
                    })
                    .collect();
                let roi = SpadRoi {
                    side: r,
                    counts: &counts,
                    n_on: planes,
                    n_off: 0,
                    maps: with_maps.then_some(&maps),
                };
                fit_binomial(&roi, &p.fit)
            }
            (est, _) => {
                let opts = if p.read_var.is_some() {
                    FitOptions {
                        noise: NoiseModel::Scmos,
                        ..p.fit
                    }
                } else {
                    p.fit
                };
                let view = RoiView {
                    side: r,
                    data: &data,
                    maps: with_maps.then_some(&maps),
                };
                fit_roi(est, &view, &opts)
            }
        };
        locs.push(Localization::from_fit(
            &fit, x0 as f64, y0 as f64, p.pixel_nm, frame_no,
        ));
    }
    Ok(FrameResult {
        localizations: locs,
        candidates: cands.len(),
        threshold,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mirror_reflects() {
        assert_eq!(mirror(-1, 5), 1);
        assert_eq!(mirror(-2, 5), 2);
        assert_eq!(mirror(5, 5), 3);
        assert_eq!(mirror(6, 5), 2);
        assert_eq!(mirror(-7, 3), 1);
        assert_eq!(mirror(3, 1), 0);
    }

    #[test]
    fn wavelet_of_a_constant_is_zero_and_a_spot_is_found() {
        let (w, h) = (20, 16);
        let img = vec![7.0; w * h];
        let (f1, f2) = wavelet(&img, w, h);
        assert!(f1.iter().chain(&f2).all(|v| v.abs() < 1e-12));
        let img = crate::synth::expected_frame(w, h, &[(9.3, 7.6, 500.0)], 1.4, 5.0);
        let (_, f2) = wavelet(&img, w, h);
        let m = local_maxima(&f2, w, h, 1.0);
        assert_eq!(m, vec![(9, 7)]);
    }

    #[test]
    fn robust_std_ignores_outliers() {
        let mut v: Vec<f64> = (0..1000)
            .map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5)
            .collect();
        let s0 = robust_std(&v);
        v.extend([1e6; 20]);
        let s1 = robust_std(&v);
        assert!((s1 / s0 - 1.0).abs() < 0.05, "{s0} {s1}");
    }
}
