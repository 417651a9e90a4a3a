//! Background-subtracted centroid.
//!
//! Background b = mean of the valid border pixels; weights `max(n − b, 0)`.
//! σ comes from the second moment (minus the pixel's own 1/12), and the
//! reported precision is the Poisson error propagated through the centroid,
//! `var x̂ = Σ n_k (x_k − x̂)² / S²` (b held fixed). The centroid is fast and
//! robust but biased towards the ROI centre when background is high.

use crate::fit::{Fit, FitOptions, FitStatus};
use crate::lm::{has_non_finite, Mapped, PixelModel, Uniform};
use crate::roi::RoiView;

/// Centroid of one ROI.
pub fn centroid(roi: &RoiView, opts: &FitOptions) -> Fit {
    let f = match roi.maps {
        None => run(roi.data, roi.side, &Uniform, opts),
        Some(maps) => run(roi.data, roi.side, &Mapped { maps, scmos: false }, opts),
    };
    f.sanitized(roi.side)
}

fn run<M: PixelModel>(data: &[f64], side: usize, m: &M, opts: &FitOptions) -> Fit {
    let sigma0 = opts.sigma.value();
    if data.len() != side * side || side == 0 {
        return Fit::failed(side, sigma0, FitStatus::NonFiniteInput);
    }
    if has_non_finite(data, m) {
        return Fit::failed(side, sigma0, FitStatus::NonFiniteInput);
    }
    let Some([_, _, _, b]) = crate::lm::initial_guess(data, side, m) else {
        return Fit::failed(side, sigma0, FitStatus::NoSignal);
    };
    let value = |k: usize| (data[k] - m.offset(k)) / m.gain(k);
    let (mut s, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if m.ignored(k) {
                continue;
            }
            let w = (value(k) - b).max(0.0);
            s += w;
            sx += w * (i as f64 + 0.5);
            sy += w * (j as f64 + 0.5);
        }
    }
    if s <= 0.0 {
        return Fit::failed(side, sigma0, FitStatus::NoSignal);
    }
    let (x, y) = (sx / s, sy / s);
    let (mut m2, mut vx, mut vy) = (0.0, 0.0, 0.0);
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if m.ignored(k) {
                continue;
            }
            let (dx, dy) = (i as f64 + 0.5 - x, j as f64 + 0.5 - y);
            let w = (value(k) - b).max(0.0);
            m2 += w * (dx * dx + dy * dy);
            // Only pixels that carried weight contribute noise to the estimate.
            if w > 0.0 {
                let n = data[k].max(0.0);
                vx += n * dx * dx;
                vy += n * dy * dy;
            }
        }
    }
    let sigma = (m2 / (2.0 * s) - 1.0 / 12.0).max(0.0).sqrt();
    let f2 = opts.noise.excess_noise();
    Fit {
        x,
        y,
        sigma,
        photons: s,
        background: b,
        bkgstd: (f2 * b).sqrt(),
        std_x: (f2 * vx).sqrt() / s,
        std_y: (f2 * vy).sqrt() / s,
        std_photons: (f2 * s).sqrt(),
        status: FitStatus::Ok,
        iterations: 0,
    }
}
