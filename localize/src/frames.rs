//! Frame-based detection and localisation for EMCCD, sCMOS and
//! fixed-aggregation SPAD frames, with ThunderSTORM's defaults:
//!
//! 1. **Filter**: the B-spline wavelet of ThunderSTORM (à trous, cubic
//!    B-spline kernel `[1 4 6 4 1]/16`): `V1 = I ⊛ k`, `V2 = V1 ⊛ k↑2` (the
//!    kernel dilated by 2), wavelet planes `F1 = I − V1` (noise) and
//!    `F2 = V1 − V2` (spots). Border pixels are duplicated outwards, as
//!    ThunderSTORM's wavelet filter does.
//! 2. **Threshold**: `F2 ≥ factor · std(F1)` with `factor` 1.5 by default;
//!    std is estimated robustly (1.4826 × median absolute deviation) so that
//!    bright molecules do not raise it.
//! 3. **Candidates**: 8-neighbour local maxima of F2 above the threshold
//!    (ties: strictly greater than earlier neighbours in raster order, not
//!    less than later ones — one candidate per plateau).
//! 4. **Fit**: an `R × R` ROI around each candidate, fitted with the chosen
//!    estimator and noise model. Near an edge the ROI is shifted to stay
//!    inside the frame: the likelihood runs over pixels that exist only, as
//!    with ThunderSTORM's clipped ROI, plus those on the far side that a
//!    clipped ROI would lose. A frame smaller than `R` is fitted with the
//!    largest odd ROI that fits ([`FramePipeline::roi_for`]); frames under
//!    3 × 3 pixels are refused.
//!
//! Frames are converted from ADU to photo-electrons first:
//! `(ADU − offset) · e⁻/ADU / EM gain`.

use crate::error::{check_option, LocalizeError};
use crate::fit::{fit_roi, Estimator, FitOptions, NoiseModel};
use crate::roi::{apply_hot_pixels, HotPixelMode, PixelMaps, RoiView};
use crate::spad::{fit_binomial, SpadRoi};
use crate::table::Localization;
use smartagg_io::stack::Frame;

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

/// Smallest fitting ROI side, hence smallest frame side: 3 × 3 pixels
/// for the four or five parameters of a fit.
pub const MIN_SIDE: usize = 3;

impl FramePipeline {
    /// The fitting ROI side used on frames of this size: `roi_side`, or the
    /// largest odd side that fits in the frame when the frame is smaller
    /// (a 9 × 9 frame is fitted whole; the caller says so once).
    pub fn roi_for(&self, width: usize, height: usize) -> usize {
        let fit = width.min(height);
        let odd = if fit.is_multiple_of(2) {
            fit.saturating_sub(1)
        } else {
            fit
        };
        self.roi_side.min(odd).max(1)
    }

    /// Checks the options against a frame size (at least [`MIN_SIDE`]
    /// pixels each way; a frame smaller than the ROI gets a smaller ROI,
    /// see [`FramePipeline::roi_for`]).
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
        if width < MIN_SIDE || height < MIN_SIDE {
            return Err(LocalizeError::FrameTooSmall {
                width,
                height,
                side: MIN_SIDE,
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

/// Index into `[0, n)` of an image whose border pixels are duplicated
/// outwards (ThunderSTORM's `PADDING_DUPLICATE`). Mirroring, used before,
/// put a spot's mirror image beside a spot near the edge, which raised V2
/// there and lowered F2: on 9 × 9 frames a spot off the centre was missed
/// five times in a hundred.
#[inline]
fn edge_index(i: isize, n: usize) -> usize {
    i.clamp(0, n as isize - 1) as usize
}

/// Separable convolution with the cubic B-spline kernel dilated by `step`.
fn bspline(img: &[f64], w: usize, h: usize, step: isize) -> Vec<f64> {
    const K: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
    let mut tmp = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (t, k) in K.iter().enumerate() {
                s += k * img[y * w + edge_index(x as isize + (t as isize - 2) * step, w)];
            }
            tmp[y * w + x] = s;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (t, k) in K.iter().enumerate() {
                s += k * tmp[edge_index(y as isize + (t as isize - 2) * step, h) * w + x];
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
    robust_std_in(v, &mut Vec::new())
}

/// 8-neighbour local maxima of `f` at or above `threshold`, raster order.
pub fn local_maxima(f: &[f64], w: usize, h: usize, threshold: f64) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    local_maxima_into(f, w, h, threshold, &mut out);
    out
}

/// [`local_maxima`] into a reused vector (cleared first).
fn local_maxima_into(f: &[f64], w: usize, h: usize, threshold: f64, out: &mut Vec<(usize, usize)>) {
    out.clear();
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

/// A thread's work space for [`localize_frame_with`]: the frame's planes,
/// the border tables of the wavelet and the ROI buffers, sized on the first
/// frame and reused by every frame of that size (nothing is allocated per
/// frame or per candidate; per-frame allocations cost more than the fits
/// on small frames).
#[derive(Clone, Debug, Default)]
pub struct FrameScratch {
    size: (usize, usize),
    /// Column (row) indices of the five taps at steps 1 and 2, borders
    /// duplicated.
    taps_x: [Vec<usize>; 2],
    taps_y: [Vec<usize>; 2],
    img: Vec<f64>,
    filt: Vec<f64>,
    tmp: Vec<f64>,
    v1: Vec<f64>,
    v2: Vec<f64>,
    sorted: Vec<f64>,
    cands: Vec<(usize, usize)>,
    data: Vec<f64>,
    counts: Vec<u32>,
    hot: Vec<bool>,
    maps: Option<PixelMaps>,
}

impl FrameScratch {
    fn resize(&mut self, w: usize, h: usize) {
        if self.size == (w, h) {
            return;
        }
        self.size = (w, h);
        for (s, step) in [1isize, 2].into_iter().enumerate() {
            let taps = |n: usize| -> Vec<usize> {
                (0..n)
                    .flat_map(|i| (-2isize..=2).map(move |t| edge_index(i as isize + t * step, n)))
                    .collect()
            };
            self.taps_x[s] = taps(w);
            self.taps_y[s] = taps(h);
        }
        for v in [
            &mut self.img,
            &mut self.filt,
            &mut self.tmp,
            &mut self.v1,
            &mut self.v2,
        ] {
            v.clear();
            v.resize(w * h, 0.0);
        }
    }
}

const KERNEL: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];

/// [`bspline`] with precomputed border tables, into `out` (via `tmp`).
fn bspline_into(
    img: &[f64],
    w: usize,
    h: usize,
    tx: &[usize],
    ty: &[usize],
    tmp: &mut [f64],
    out: &mut [f64],
) {
    for y in 0..h {
        let row = &img[y * w..(y + 1) * w];
        for x in 0..w {
            let t = &tx[5 * x..5 * x + 5];
            tmp[y * w + x] = KERNEL[0] * row[t[0]]
                + KERNEL[1] * row[t[1]]
                + KERNEL[2] * row[t[2]]
                + KERNEL[3] * row[t[3]]
                + KERNEL[4] * row[t[4]];
        }
    }
    for y in 0..h {
        let t = &ty[5 * y..5 * y + 5];
        let rows: [&[f64]; 5] = std::array::from_fn(|i| &tmp[t[i] * w..(t[i] + 1) * w]);
        for x in 0..w {
            out[y * w + x] = KERNEL[0] * rows[0][x]
                + KERNEL[1] * rows[1][x]
                + KERNEL[2] * rows[2][x]
                + KERNEL[3] * rows[3][x]
                + KERNEL[4] * rows[4][x];
        }
    }
}

/// [`robust_std`] sorting in a reused buffer.
fn robust_std_in(v: &[f64], a: &mut Vec<f64>) -> f64 {
    a.clear();
    a.extend(v.iter().copied().filter(|x| x.is_finite()));
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

/// Detects and localises the molecules of one frame (raw ADU values).
/// `frame_no` is written to the table (1-based by convention).
pub fn localize_frame(
    p: &FramePipeline,
    raw: &[f64],
    width: usize,
    height: usize,
    frame_no: u64,
) -> Result<FrameResult, LocalizeError> {
    let mut out = Vec::new();
    let (candidates, threshold) = localize_frame_with(
        p,
        raw,
        width,
        height,
        frame_no,
        &mut FrameScratch::default(),
        &mut out,
    )?;
    Ok(FrameResult {
        localizations: out,
        candidates,
        threshold,
    })
}

/// [`localize_frame`] with a reused work space, appending the
/// localisations to `out`; returns (candidates, threshold on F2).
///
/// The fitting ROI is [`FramePipeline::roi_for`] the frame; each
/// candidate's ROI is the window of that side nearest to it that lies in
/// the frame — centred on the candidate except near an edge, where it is
/// shifted inwards: the likelihood runs over pixels that exist only (never
/// padded), and a spot on the edge is still fitted (its position may be
/// anywhere in the ROI, up to its border).
pub fn localize_frame_with(
    p: &FramePipeline,
    raw: &[f64],
    width: usize,
    height: usize,
    frame_no: u64,
    s: &mut FrameScratch,
    out: &mut Vec<Localization>,
) -> Result<(usize, f64), LocalizeError> {
    p.validate(width, height)?;
    if raw.len() != width * height {
        return Err(LocalizeError::MapShape {
            map: "frame",
            len: raw.len(),
            expected: width * height,
        });
    }
    s.resize(width, height);
    s.img.copy_from_slice(raw);
    p.conversion.apply(&mut s.img);
    // Non-finite pixels are detected as nothing and fitted as flagged input.
    for (f, &v) in s.filt.iter_mut().zip(&s.img) {
        *f = if v.is_finite() { v } else { 0.0 };
    }
    // Wavelet planes: V1 = I ⊛ k, V2 = V1 ⊛ k↑2; F1 = I − V1, F2 = V1 − V2.
    bspline_into(
        &s.filt,
        width,
        height,
        &s.taps_x[0],
        &s.taps_y[0],
        &mut s.tmp,
        &mut s.v1,
    );
    bspline_into(
        &s.v1,
        width,
        height,
        &s.taps_x[1],
        &s.taps_y[1],
        &mut s.tmp,
        &mut s.v2,
    );
    // F1 into `tmp`, F2 into `v2`.
    for k in 0..width * height {
        s.tmp[k] = s.filt[k] - s.v1[k];
        s.v2[k] = s.v1[k] - s.v2[k];
    }
    let threshold = p.threshold_factor * robust_std_in(&s.tmp, &mut s.sorted);
    local_maxima_into(
        &s.v2,
        width,
        height,
        threshold.max(f64::MIN_POSITIVE),
        &mut s.cands,
    );
    let r = p.roi_for(width, height);
    let with_maps = p.read_var.is_some() || p.hot.is_some();
    if with_maps && s.maps.as_ref().is_none_or(|m| m.side != r) {
        s.maps = Some(PixelMaps::uniform(r));
    }
    let opts = if p.read_var.is_some() {
        FitOptions {
            noise: NoiseModel::Scmos,
            ..p.fit
        }
    } else {
        p.fit
    };
    out.reserve(s.cands.len());
    for &(cx, cy) in &s.cands {
        let x0 = cx.saturating_sub(r / 2).min(width - r);
        let y0 = cy.saturating_sub(r / 2).min(height - r);
        s.data.clear();
        for j in 0..r {
            let q = (y0 + j) * width + x0;
            s.data.extend_from_slice(&s.img[q..q + r]);
        }
        if let Some(maps) = s.maps.as_mut().filter(|_| with_maps) {
            // Fresh neutral maps (a hot pixel of the previous ROI must not
            // stay ignored), then this ROI's values.
            maps.gain.fill(1.0);
            maps.dark.fill(0.0);
            maps.ignore.fill(false);
            s.hot.clear();
            s.hot.resize(r * r, false);
            for j in 0..r {
                for i in 0..r {
                    let q = (y0 + j) * width + x0 + i;
                    maps.read_var[j * r + i] = p.read_var.as_ref().map_or(0.0, |v| v[q]);
                    if let Some((h, _)) = &p.hot {
                        s.hot[j * r + i] = h[q];
                    }
                }
            }
            if let Some((_, mode)) = &p.hot {
                apply_hot_pixels(&mut s.data, &s.hot, *mode, maps)?;
            }
        }
        let maps = s.maps.as_ref().filter(|_| with_maps);
        let fit = match (p.estimator, p.spad_planes) {
            (Estimator::SpadMle, Some(planes)) => {
                s.counts.clear();
                s.counts.extend(s.data.iter().map(|&v| {
                    if v.is_finite() {
                        v.round().clamp(0.0, u32::MAX as f64) as u32
                    } else {
                        0
                    }
                }));
                let roi = SpadRoi {
                    side: r,
                    counts: &s.counts,
                    n_on: planes,
                    n_off: 0,
                    maps,
                };
                fit_binomial(&roi, &p.fit)
            }
            (est, _) => {
                let view = RoiView {
                    side: r,
                    data: &s.data,
                    maps,
                };
                fit_roi(est, &view, &opts)
            }
        };
        out.push(Localization::from_fit(
            &fit, x0 as f64, y0 as f64, p.pixel_nm, frame_no,
        ));
    }
    Ok((s.cands.len(), threshold))
}

/// Localises a batch of `(frame number, frame)` on the current rayon pool,
/// appending the localisations to `out` in frame order; returns the number
/// of candidates. Each worker takes a run of consecutive frames and one
/// [`FrameScratch`] (a task per frame costs more than a small frame's fits).
pub fn localize_batch(
    p: &FramePipeline,
    frames: &[(u64, Frame)],
    out: &mut Vec<Localization>,
) -> Result<usize, LocalizeError> {
    use rayon::prelude::*;
    let runs = 4 * rayon::current_num_threads();
    let per = frames.len().div_ceil(runs).max(1);
    let parts: Vec<Result<(Vec<Localization>, usize), LocalizeError>> = frames
        .par_chunks(per)
        .map_init(FrameScratch::default, |s, run| {
            let mut locs = Vec::with_capacity(run.len());
            let mut cands = 0;
            for (no, f) in run {
                cands += localize_frame_with(p, &f.data, f.width, f.height, *no, s, &mut locs)?.0;
            }
            Ok((locs, cands))
        })
        .collect();
    let mut candidates = 0;
    for part in parts {
        let (mut locs, c) = part?;
        out.append(&mut locs);
        candidates += c;
    }
    Ok(candidates)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn borders_are_duplicated() {
        assert_eq!(edge_index(-1, 5), 0);
        assert_eq!(edge_index(-4, 5), 0);
        assert_eq!(edge_index(2, 5), 2);
        assert_eq!(edge_index(5, 5), 4);
        assert_eq!(edge_index(9, 5), 4);
        assert_eq!(edge_index(3, 1), 0);
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
