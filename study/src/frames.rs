//! Frame localisation for fixed SPAD frames, EMCCD and sCMOS frames, and the
//! hot-pixel frames.
//!
//! **Detection** (ThunderSTORM's defaults, written here because the localize
//! crate's frame pipeline had not landed when the study was built): the frame
//! is filtered with the B-spline wavelet (à trous, kernel `[1 4 6 4 1]/16`,
//! mirrored edges); with `V1`, `V2` the first two smoothed levels,
//! `F1 = I − V1` and `F2 = V1 − V2`. A molecule candidate is an 8-neighbour
//! local maximum of `F2` (ties: strictly above the earlier neighbours in
//! raster order, at least the later ones) above `1.5 · std(F1)`.
//!
//! **Fit**: a 9×9 ROI of the unfiltered frame centred on the candidate
//! (shifted inwards at the frame's edge) is fitted with the Poisson MLE
//! (EMCCD: excess noise F² = 2 in the bound; sCMOS: the per-pixel read
//! variance model) with σ fitted or fixed as the study says. Fits that do not
//! end with status `ok` are dropped and counted.

use crate::spec::ROI_SIDE;
use smartagg_localize::{
    fit_roi, Estimator, Fit, FitOptions, HotPixelMode, NoiseModel, PixelMaps, RoiView,
};

/// Per-pixel knowledge of a whole frame (raster order).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameMaps {
    /// sCMOS read-noise variance, e⁻² (empty: none).
    pub read_var: Vec<f64>,
    /// Known hot pixels (empty: none).
    pub hot: Vec<bool>,
}

/// One frame localisation, frame pixel coordinates (pixel `i` spans `[i, i+1)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameFit {
    /// Column, pixels.
    pub x_px: f64,
    /// Row, pixels.
    pub y_px: f64,
    /// Fitted photons.
    pub photons: f64,
}

const B3: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// Mirrored index (`-1 → 1`, `n → n − 2`), valid for any offset.
fn mirror(i: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let period = 2 * (n as isize - 1);
    let mut j = i.rem_euclid(period);
    if j >= n as isize {
        j = period - j;
    }
    j as usize
}

/// One separable B-spline smoothing with holes of `step` (1, 2, …).
fn smooth(img: &[f64], w: usize, h: usize, step: usize) -> Vec<f64> {
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, c) in B3.iter().enumerate() {
                let dx = (k as isize - 2) * step as isize;
                s += c * img[y * w + mirror(x as isize + dx, w)];
            }
            tmp[y * w + x] = s;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (k, c) in B3.iter().enumerate() {
                let dy = (k as isize - 2) * step as isize;
                s += c * tmp[mirror(y as isize + dy, h) * w + x];
            }
            out[y * w + x] = s;
        }
    }
    out
}

/// Candidate positions `(x, y)` of a frame, raster order (see the module docs).
pub fn detect(img: &[f64], w: usize, h: usize, threshold_factor: f64) -> Vec<(usize, usize)> {
    assert_eq!(img.len(), w * h, "frame size");
    let v1 = smooth(img, w, h, 1);
    let v2 = smooth(&v1, w, h, 2);
    let n = (w * h) as f64;
    let f1: Vec<f64> = img.iter().zip(&v1).map(|(a, b)| a - b).collect();
    let mean1 = f1.iter().sum::<f64>() / n;
    let sd1 = (f1.iter().map(|v| (v - mean1).powi(2)).sum::<f64>() / n).sqrt();
    let thr = threshold_factor * sd1;
    let f2: Vec<f64> = v1.iter().zip(&v2).map(|(a, b)| a - b).collect();
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let v = f2[y * w + x];
            if !(v > thr) {
                continue;
            }
            let mut is_max = true;
            'n: for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let (xx, yy) = (x as isize + dx, y as isize + dy);
                    if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
                        continue;
                    }
                    let u = f2[yy as usize * w + xx as usize];
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

/// Replaces every hot pixel by the mean of its valid (not hot) 4-neighbours
/// (0 when it has none) — the detection step's view of a frame with hot pixels.
pub fn interpolate_hot(img: &[f64], w: usize, h: usize, hot: &[bool]) -> Vec<f64> {
    let mut out = img.to_vec();
    for y in 0..h {
        for x in 0..w {
            if !hot[y * w + x] {
                continue;
            }
            let (mut s, mut n) = (0.0, 0);
            for (dx, dy) in [(-1isize, 0isize), (1, 0), (0, -1), (0, 1)] {
                let (xx, yy) = (x as isize + dx, y as isize + dy);
                if xx < 0 || yy < 0 || xx >= w as isize || yy >= h as isize {
                    continue;
                }
                let k = yy as usize * w + xx as usize;
                if !hot[k] {
                    s += img[k];
                    n += 1;
                }
            }
            out[y * w + x] = if n > 0 { s / n as f64 } else { 0.0 };
        }
    }
    out
}

/// Top-left corner of the ROI of side `side` centred on `c`, kept inside `0..n`.
pub fn roi_origin(c: usize, n: usize, side: usize) -> usize {
    let half = side / 2;
    c.saturating_sub(half).min(n.saturating_sub(side))
}

/// How to fit the ROIs of a frame.
#[derive(Debug, Clone, Copy)]
pub struct FrameFitter {
    /// Fit options (σ mode, noise model).
    pub opts: FitOptions,
    /// Detection threshold in units of std(F1).
    pub threshold_factor: f64,
    /// What to do with known hot pixels in the fit.
    pub hot_mode: HotPixelMode,
}

impl FrameFitter {
    /// Defaults: 1.5 × std(F1), hot pixels ignored.
    pub fn new(opts: FitOptions) -> FrameFitter {
        FrameFitter {
            opts,
            threshold_factor: 1.5,
            hot_mode: HotPixelMode::Ignore,
        }
    }

    /// Detects and fits every candidate of a frame in photon units;
    /// returns the fits with status `ok` and the number of failed ones.
    pub fn localize(
        &self,
        img: &[f64],
        w: usize,
        h: usize,
        maps: &FrameMaps,
    ) -> (Vec<FrameFit>, u32) {
        let side = ROI_SIDE.min(w).min(h);
        let has_hot = !maps.hot.is_empty() && maps.hot.iter().any(|&b| b);
        let det_img;
        let detect_on = if has_hot {
            det_img = interpolate_hot(img, w, h, &maps.hot);
            &det_img
        } else {
            img
        };
        let mut fits = Vec::new();
        let mut failed = 0;
        for (cx, cy) in detect(detect_on, w, h, self.threshold_factor) {
            let (x0, y0) = (roi_origin(cx, w, side), roi_origin(cy, h, side));
            let mut data = Vec::with_capacity(side * side);
            for y in y0..y0 + side {
                data.extend_from_slice(&img[y * w + x0..y * w + x0 + side]);
            }
            let fit = self.fit_roi(&mut data, side, x0, y0, w, maps);
            match fit {
                Some(f) if f.status.is_ok() => fits.push(FrameFit {
                    x_px: x0 as f64 + f.x,
                    y_px: y0 as f64 + f.y,
                    photons: f.photons,
                }),
                _ => failed += 1,
            }
        }
        (fits, failed)
    }

    fn fit_roi(
        &self,
        data: &mut [f64],
        side: usize,
        x0: usize,
        y0: usize,
        w: usize,
        maps: &FrameMaps,
    ) -> Option<Fit> {
        let needs_maps = !maps.read_var.is_empty() || !maps.hot.is_empty();
        if !needs_maps {
            let roi = RoiView::new(side, data, None).ok()?;
            return Some(fit_roi(Estimator::Mle, &roi, &self.opts));
        }
        let mut pm = PixelMaps::uniform(side);
        let mut hot = vec![false; side * side];
        for j in 0..side {
            for i in 0..side {
                let k = (y0 + j) * w + x0 + i;
                if !maps.read_var.is_empty() {
                    pm.read_var[j * side + i] = maps.read_var[k];
                }
                if !maps.hot.is_empty() {
                    hot[j * side + i] = maps.hot[k];
                }
            }
        }
        if hot.iter().any(|&b| b) {
            smartagg_localize::roi::apply_hot_pixels(data, &hot, self.hot_mode, &mut pm).ok()?;
        }
        let roi = RoiView::new(side, data, Some(&pm)).ok()?;
        Some(fit_roi(Estimator::Mle, &roi, &self.opts))
    }
}

/// Fit options of the study: σ fitted from (or fixed to) the optics' σ.
pub fn fit_options(sigma_px: f64, fit_sigma: bool, noise: NoiseModel) -> FitOptions {
    let sigma = if fit_sigma {
        smartagg_localize::SigmaMode::Fitted { initial: sigma_px }
    } else {
        smartagg_localize::SigmaMode::Fixed(sigma_px)
    };
    let mut o = FitOptions::new(sigma);
    o.noise = noise;
    o
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn gaussian_frame(
        w: usize,
        h: usize,
        x: f64,
        y: f64,
        photons: f64,
        bg: f64,
        seed: u64,
    ) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let em = smartagg_localize::crlb::Emitter {
            x,
            y,
            sigma: 1.5,
            photons,
            background: bg,
        };
        // A square frame is an ROI of side w as far as the synthesiser goes.
        assert_eq!(w, h);
        smartagg_localize::synth::poisson_roi(&mut rng, w, &em, None)
    }

    #[test]
    fn mirror_reflects_without_repeating_the_edge() {
        assert_eq!(mirror(-1, 5), 1);
        assert_eq!(mirror(-2, 5), 2);
        assert_eq!(mirror(5, 5), 3);
        assert_eq!(mirror(6, 5), 2);
        assert_eq!(mirror(3, 5), 3);
        assert_eq!(mirror(-4, 1), 0);
    }

    #[test]
    fn a_bright_molecule_is_found_and_background_alone_rarely_is() {
        let fitter = FrameFitter::new(fit_options(1.5, true, NoiseModel::Poisson));
        let mut found = 0;
        let mut false_pos = 0;
        for seed in 0..40 {
            let img = gaussian_frame(32, 32, 12.3, 20.6, 400.0, 6.0, seed);
            let (fits, _) = fitter.localize(&img, 32, 32, &FrameMaps::default());
            for f in &fits {
                if (f.x_px - 12.3).abs() < 1.0 && (f.y_px - 20.6).abs() < 1.0 {
                    found += 1;
                } else {
                    false_pos += 1;
                }
            }
            let bg = gaussian_frame(32, 32, 12.3, 20.6, 0.0, 6.0, 1000 + seed);
            false_pos += fitter.localize(&bg, 32, 32, &FrameMaps::default()).0.len();
        }
        assert!(found >= 38, "found {found} of 40");
        assert!(false_pos <= 4, "{false_pos} false positives in 80 frames");
    }

    #[test]
    fn hot_pixels_do_not_become_molecules() {
        let mut img = gaussian_frame(32, 32, 16.0, 16.0, 400.0, 6.0, 3);
        let mut hot = vec![false; 32 * 32];
        for k in [5 * 32 + 5, 25 * 32 + 7, 16 * 32 + 17] {
            img[k] = 300.0;
            hot[k] = true;
        }
        let maps = FrameMaps {
            read_var: Vec::new(),
            hot,
        };
        for mode in [HotPixelMode::Ignore, HotPixelMode::Interpolate] {
            let mut fitter = FrameFitter::new(fit_options(1.5, true, NoiseModel::Poisson));
            fitter.hot_mode = mode;
            let (fits, _) = fitter.localize(&img, 32, 32, &maps);
            assert_eq!(fits.len(), 1, "{mode:?}: {fits:?}");
            assert!((fits[0].x_px - 16.0).abs() < 0.5 && (fits[0].y_px - 16.0).abs() < 0.5);
        }
    }

    #[test]
    fn roi_stays_inside_the_frame() {
        assert_eq!(roi_origin(0, 32, 9), 0);
        assert_eq!(roi_origin(10, 32, 9), 6);
        assert_eq!(roi_origin(31, 32, 9), 23);
        assert_eq!(roi_origin(3, 5, 9), 0);
    }
}
