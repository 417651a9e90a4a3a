//! Simulated frame stacks with known truth, and scoring a localisation table
//! against them: the end-to-end test of the frame path (`smartagg bench
//! frames`), where every frame holds one spot and the whole chain — TIFF
//! decoding, detection, ROI, fit, CSV — is measured.

use crate::crlb::{crlb_frame, Emitter};
use crate::fit::NoiseModel;
use crate::synth::{expected_frame, poisson};
use crate::table::Localization;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// A stack of `count` frames of `width × height` pixels, one ideal Poisson
/// spot per frame, its position uniform within ±`jitter` px of the frame's
/// centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StackScenario {
    /// Frame width, pixels.
    pub width: usize,
    /// Frame height, pixels.
    pub height: usize,
    /// PSF σ, pixels.
    pub sigma: f64,
    /// Emitter photons.
    pub photons: f64,
    /// Background photons per pixel.
    pub background: f64,
    /// Half-width of the uniform position jitter around the centre, pixels.
    pub jitter: f64,
    /// Frames.
    pub count: usize,
    /// Random seed.
    pub seed: u64,
}

impl StackScenario {
    /// Issue #37's stack: 9×9 frames, σ = 1.5 px (the SPCImager blink of
    /// `bench localize`), 230 photons, 5.9 background photons per pixel,
    /// the spot within ±1.5 px of the centre (so that many maxima are off
    /// the centre pixel).
    pub fn issue37(count: usize, seed: u64) -> StackScenario {
        StackScenario {
            width: 9,
            height: 9,
            sigma: 1.5,
            photons: 230.0,
            background: 5.9,
            jitter: 1.5,
            count,
            seed,
        }
    }
}

/// Draws the stack: the frames (photon counts, row-major) and each frame's
/// emitter in frame pixel coordinates (pixel `i` spans `[i, i + 1)`).
pub fn simulate_stack(sc: &StackScenario) -> (Vec<Vec<u32>>, Vec<Emitter>) {
    let mut rng = StdRng::seed_from_u64(sc.seed);
    let (cx, cy) = (sc.width as f64 / 2.0, sc.height as f64 / 2.0);
    let j = sc.jitter.max(0.0);
    let mut pages = Vec::with_capacity(sc.count);
    let mut truth = Vec::with_capacity(sc.count);
    for _ in 0..sc.count {
        let em = Emitter {
            x: cx + if j > 0.0 { rng.gen_range(-j..=j) } else { 0.0 },
            y: cy + if j > 0.0 { rng.gen_range(-j..=j) } else { 0.0 },
            sigma: sc.sigma,
            photons: sc.photons,
            background: sc.background,
        };
        let mu = expected_frame(
            sc.width,
            sc.height,
            &[(em.x, em.y, em.photons)],
            em.sigma,
            em.background,
        );
        pages.push(
            mu.iter()
                .map(|&m| poisson(&mut rng, m).min(u32::MAX as f64) as u32)
                .collect(),
        );
        truth.push(em);
    }
    (pages, truth)
}

/// How a table compares with the truth of a one-spot-per-frame stack.
#[derive(Clone, Debug, PartialEq)]
pub struct StackScore {
    /// Frames (= spots).
    pub spots: usize,
    /// Spots with an ok localisation within `radius` px in their frame.
    pub found: usize,
    /// Ok localisations that matched no spot (a second one in a frame, or
    /// one too far away).
    pub spurious: usize,
    /// Localisations whose fit failed.
    pub failed: usize,
    /// Per-axis RMSE of the found spots, pixels.
    pub rmse: f64,
    /// Per-axis Cramér–Rao bound of the found spots, pixels:
    /// `sqrt(mean((var_x + var_y)/2))` of the Poisson model with σ fitted,
    /// over the whole frame.
    pub crlb: f64,
}

impl StackScore {
    /// Fraction of the spots found.
    pub fn recall(&self) -> f64 {
        self.found as f64 / self.spots.max(1) as f64
    }

    /// RMSE / CRLB.
    pub fn ratio(&self) -> f64 {
        self.rmse / self.crlb.max(1e-300)
    }
}

/// Scores localisations (`frame` 1-based, positions in nm) against the
/// truth of [`simulate_stack`]: in each frame the ok localisation nearest
/// the spot is matched if it lies within `radius` px.
pub fn score_stack(
    rows: &[Localization],
    truth: &[Emitter],
    width: usize,
    height: usize,
    pixel_nm: f64,
    radius: f64,
) -> StackScore {
    // Per frame: (squared distance, dx, dy) of the nearest ok localisation.
    let mut best: Vec<Option<(f64, f64, f64)>> = vec![None; truth.len()];
    let mut ok = 0usize;
    let mut failed = 0usize;
    for r in rows {
        if !r.status.is_ok() {
            failed += 1;
            continue;
        }
        ok += 1;
        let Some(em) = (r.frame as usize)
            .checked_sub(1)
            .and_then(|i| truth.get(i).map(|e| (i, e)))
        else {
            continue;
        };
        let (i, em) = em;
        let (dx, dy) = (r.x_nm / pixel_nm - em.x, r.y_nm / pixel_nm - em.y);
        let d2 = dx * dx + dy * dy;
        if d2 <= radius * radius && best[i].is_none_or(|b| d2 < b.0) {
            best[i] = Some((d2, dx, dy));
        }
    }
    let (mut se, mut var, mut found) = (0.0, 0.0, 0usize);
    let mut side_bound = 0usize;
    for (b, em) in best.iter().zip(truth) {
        let Some((d2, _, _)) = b else { continue };
        found += 1;
        se += d2 / 2.0;
        // The bound over the frame's pixels: a square frame is one ROI.
        let side = width.min(height);
        if let Some(c) = crlb_frame(side, em, None, NoiseModel::Poisson, true) {
            var += (c.var_x + c.var_y) / 2.0;
            side_bound += 1;
        }
    }
    StackScore {
        spots: truth.len(),
        found,
        spurious: ok - found,
        failed,
        rmse: (se / found.max(1) as f64).sqrt(),
        crlb: (var / side_bound.max(1) as f64).sqrt(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{Fit, FitStatus};

    #[test]
    fn a_stack_is_reproducible_and_scored() {
        let sc = StackScenario {
            count: 20,
            ..StackScenario::issue37(20, 3)
        };
        let (p1, t1) = simulate_stack(&sc);
        let (p2, t2) = simulate_stack(&sc);
        assert_eq!((p1.len(), &p1, &t1), (20, &p2, &t2));
        assert!(t1
            .iter()
            .all(|e| (e.x - 4.5).abs() <= 1.5 && (e.y - 4.5).abs() <= 1.5));
        // A table with every spot found 0.1 px off in x, one spurious and
        // one failed row.
        let mut rows: Vec<Localization> = t1
            .iter()
            .enumerate()
            .map(|(i, e)| {
                let f = Fit {
                    x: e.x + 0.1,
                    y: e.y,
                    status: FitStatus::Ok,
                    ..Fit::failed(9, 1.5, FitStatus::Ok)
                };
                Localization::from_fit(&f, 0.0, 0.0, 100.0, i as u64 + 1)
            })
            .collect();
        let mut far = rows[0].clone();
        far.x_nm += 500.0;
        rows.push(far);
        let mut bad = rows[1].clone();
        bad.status = FitStatus::NotConverged;
        rows.push(bad);
        let s = score_stack(&rows, &t1, 9, 9, 100.0, 2.0);
        assert_eq!((s.spots, s.found, s.spurious, s.failed), (20, 20, 1, 1));
        assert!((s.rmse - 0.1 / 2f64.sqrt()).abs() < 1e-9, "{}", s.rmse);
        assert!(s.crlb > 0.05 && s.crlb < 0.3, "{}", s.crlb);
    }
}
