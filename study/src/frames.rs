//! Frame localisation for fixed SPAD frames, EMCCD and sCMOS frames and the
//! hot-pixel frames: the localize crate's frame pipeline
//! (`smartagg_localize::frames`, ThunderSTORM's defaults: B-spline wavelet,
//! threshold `1.5 × robust std(F1)` on `F2`, 8-neighbour local maxima, ROI
//! fits) and its merging of consecutive frames (`smartagg_localize::merge`).
//!
//! What the study adds: frames arrive already in photo-electrons (the
//! camera simulators' calibration is applied in [`crate::acquisition`]), every fit
//! is a 9×9 Poisson MLE (EMCCD: F² = 2 in the bound; sCMOS: per-pixel read
//! variance), and known hot pixels are replaced by the mean of their valid
//! 4-neighbours *before* detection — a 10 kHz hot pixel is a bright
//! one-pixel spot that the wavelet filter would otherwise report as a
//! molecule — and then ignored or interpolated in the fit as the study says.

use crate::error::StudyError;
use crate::spec::ROI_SIDE;
use smartagg_localize::frames::{localize_frame, Conversion, FramePipeline};
use smartagg_localize::{Estimator, FitOptions, HotPixelMode, Localization, NoiseModel};

/// Per-pixel knowledge of a whole frame (raster order).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameMaps {
    /// sCMOS read-noise variance, e⁻² (empty: none).
    pub read_var: Vec<f64>,
    /// Known hot pixels (empty: none).
    pub hot: Vec<bool>,
}

/// Replaces every hot pixel by the mean of its valid (not hot) 4-neighbours
/// (0 when it has none).
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

/// How to localise the frames of a configuration.
#[derive(Debug, Clone, Copy)]
pub struct FrameFitter {
    /// Fit options (σ mode, noise model).
    pub opts: FitOptions,
    /// Detection threshold in units of the robust std of F1.
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

    /// Detects and fits every candidate of a frame in photo-electrons;
    /// returns one localisation per candidate (failed fits flagged), with
    /// `frame` written to each.
    pub fn localize(
        &self,
        img: &[f64],
        w: usize,
        h: usize,
        maps: &FrameMaps,
        pixel_nm: f64,
        frame: u64,
    ) -> Result<Vec<Localization>, StudyError> {
        let has_hot = maps.hot.iter().any(|&b| b);
        let pipeline = FramePipeline {
            conversion: Conversion::IDENTITY,
            roi_side: ROI_SIDE.min(w).min(h) | 1,
            threshold_factor: self.threshold_factor,
            estimator: Estimator::Mle,
            fit: self.opts,
            pixel_nm,
            read_var: (!maps.read_var.is_empty()).then(|| maps.read_var.clone()),
            hot: has_hot.then(|| (maps.hot.clone(), self.hot_mode)),
            spad_planes: None,
        };
        let r = if has_hot {
            localize_frame(
                &pipeline,
                &interpolate_hot(img, w, h, &maps.hot),
                w,
                h,
                frame,
            )?
        } else {
            localize_frame(&pipeline, img, w, h, frame)?
        };
        Ok(r.localizations)
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

    fn frame(x: f64, y: f64, photons: f64, bg: f64, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let em = smartagg_localize::crlb::Emitter {
            x,
            y,
            sigma: 1.5,
            photons,
            background: bg,
        };
        smartagg_localize::synth::poisson_roi(&mut rng, 32, &em, None)
    }

    #[test]
    fn a_bright_molecule_is_found_and_background_alone_rarely_is() {
        let fitter = FrameFitter::new(fit_options(1.5, true, NoiseModel::Poisson));
        let (mut found, mut false_pos) = (0, 0);
        for seed in 0..40 {
            let img = frame(12.3, 20.6, 400.0, 6.0, seed);
            let locs = fitter
                .localize(&img, 32, 32, &FrameMaps::default(), 1.0, 1)
                .unwrap();
            for l in locs.iter().filter(|l| l.status.is_ok()) {
                if (l.x_nm - 12.3).abs() < 1.0 && (l.y_nm - 20.6).abs() < 1.0 {
                    found += 1;
                } else {
                    false_pos += 1;
                }
            }
            let bg = frame(12.3, 20.6, 0.0, 6.0, 1000 + seed);
            false_pos += fitter
                .localize(&bg, 32, 32, &FrameMaps::default(), 1.0, 1)
                .unwrap()
                .iter()
                .filter(|l| l.status.is_ok())
                .count();
        }
        assert!(found >= 38, "found {found} of 40");
        assert!(false_pos <= 8, "{false_pos} false positives in 80 frames");
    }

    #[test]
    fn hot_pixels_do_not_become_molecules() {
        let mut img = frame(16.0, 16.0, 400.0, 6.0, 3);
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
            let locs: Vec<_> = fitter
                .localize(&img, 32, 32, &maps, 1.0, 1)
                .unwrap()
                .into_iter()
                .filter(|l| l.status.is_ok())
                .collect();
            assert_eq!(locs.len(), 1, "{mode:?}: {locs:?}");
            assert!((locs[0].x_nm - 16.0).abs() < 0.5 && (locs[0].y_nm - 16.0).abs() < 0.5);
        }
        // Without the known map the hot pixels are found as spots.
        let fitter = FrameFitter::new(fit_options(1.5, true, NoiseModel::Poisson));
        let n = fitter
            .localize(&img, 32, 32, &FrameMaps::default(), 1.0, 1)
            .unwrap()
            .len();
        assert!(n > 1, "{n}");
    }

    #[test]
    fn interpolation_uses_valid_neighbours() {
        let img = vec![1.0, 2.0, 3.0, 4.0, 100.0, 6.0];
        let hot = vec![false, true, false, false, true, false];
        let out = interpolate_hot(&img, 3, 2, &hot);
        assert_eq!(out[1], 2.0); // (1 + 3) / 2; the hot pixel below is left out
        assert_eq!(out[4], 5.0); // (4 + 6) / 2
    }
}
