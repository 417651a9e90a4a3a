//! Molecule photons: from the blink timeline to detections in pixels.
//!
//! For a blink overlapping an exposure window for time `t`, the photons
//! reaching the sensor plane are Poisson of mean `flux · t`. Each lands in
//! pixel (i, j) with probability `gx[i]·gy[j]` (pixel-integrated Gaussian, see
//! [`crate::psf`]) and is detected there with probability `η(i, j)`. By the
//! splitting property of the Poisson process this is sampled exactly as:
//! `K ~ Poisson(flux · t · η_max · Σgx · Σgy)` candidate photons, each placed
//! by inverting the two 1-D cumulative profiles and kept with probability
//! `η(i, j)/η_max`; the photons that are not candidates are an independent
//! `Poisson(flux · t · (1 − η_max Σgx Σgy))`, added to the emitted count only.
//! Cost is proportional to the photons, not to the pixels, and no PSF
//! truncation is involved (the profiles reach 40 σ, beyond which f64 holds 0).
//!
//! Above [`PER_PIXEL_ABOVE`] expected candidate photons (a very bright
//! molecule or a very long exposure) the cost would grow without bound, so
//! the detections are sampled per pixel instead: by the same splitting
//! property, the counts of pixel (i, j) are independent
//! `Poisson(flux · t · gx[i]·gy[j]·η(i, j))`, and the undetected photons an
//! independent `Poisson(flux · t · (1 − Σ gx gy η))`. Cost is then
//! proportional to the pixels under the PSF, whatever the photon count.

use rand::Rng;

use crate::drift::DriftTrajectory;
use crate::psf::AxisProfile;
use crate::sampling::poisson;
use crate::timeline::Timeline;

/// Expected candidate photons of one blink in one exposure above which the
/// detections are sampled per pixel rather than photon by photon.
pub(crate) const PER_PIXEL_ABOVE: f64 = 1e5;

#[derive(Debug)]
struct Footprint {
    x: AxisProfile,
    y: AxisProfile,
    /// Fraction of the blink's photons landing inside the field.
    frac: f64,
}

/// Molecule light of one scene on one field.
#[derive(Debug)]
pub(crate) struct Emission {
    pub(crate) timeline: Timeline,
    width: usize,
    height: usize,
    pixel_nm: f64,
    sigma_px: f64,
    /// Footprints of the open blinks, ascending blink index.
    cache: Vec<(usize, Footprint)>,
    spare: Vec<(usize, Footprint)>,
    open: Vec<usize>,
}

impl Emission {
    pub(crate) fn new(
        timeline: Timeline,
        width: usize,
        height: usize,
        pixel_nm: f64,
        sigma_px: f64,
    ) -> Emission {
        Emission {
            timeline,
            width,
            height,
            pixel_nm,
            sigma_px,
            cache: Vec::new(),
            spare: Vec::new(),
            open: Vec::new(),
        }
    }

    /// Images every blink with `drift` from now on (footprints already built
    /// are dropped so that none keeps the old position).
    pub(crate) fn set_drift(&mut self, drift: DriftTrajectory) {
        self.timeline.set_drift(drift);
        self.cache.clear();
    }

    /// Samples the molecule detections of the exposure window `[t0, t1)`:
    /// calls `hit(pixel, n)` with `n ≥ 1` detected photons (raster index; a
    /// pixel may be hit more than once) and updates the ground truth. `eff` is the
    /// per-pixel detection efficiency, `eff_min` and `eff_max` its extremes.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn deposit<R: Rng>(
        &mut self,
        t0: f64,
        t1: f64,
        eff: &[f64],
        eff_min: f64,
        eff_max: f64,
        rng: &mut R,
        mut hit: impl FnMut(usize, u64),
    ) {
        self.open.clear();
        self.open
            .extend_from_slice(self.timeline.open_blinks(t0, t1));
        // Keep the footprints of blinks still open, build the new ones
        // (both lists ascend by blink index).
        let mut old = std::mem::take(&mut self.cache);
        let mut next = std::mem::take(&mut self.spare);
        next.clear();
        let mut old_iter = old.drain(..).peekable();
        for &idx in &self.open {
            while old_iter.peek().is_some_and(|(i, _)| *i < idx) {
                old_iter.next();
            }
            let fp = match old_iter.peek() {
                Some((i, _)) if *i == idx => old_iter.next().expect("peeked").1,
                _ => {
                    let (x_nm, y_nm) = self.timeline.blinks[idx].imaged_nm();
                    let x = AxisProfile::new(x_nm / self.pixel_nm, self.sigma_px, self.width);
                    let y = AxisProfile::new(y_nm / self.pixel_nm, self.sigma_px, self.height);
                    let frac = x.total() * y.total();
                    Footprint { x, y, frac }
                }
            };
            next.push((idx, fp));
        }
        drop(old_iter);
        self.spare = old;
        self.cache = next;

        for (idx, fp) in &self.cache {
            let b = &mut self.timeline.blinks[*idx];
            let overlap = t1.min(b.t_off_s) - t0.max(b.t_on_s);
            if overlap.is_nan() || overlap <= 0.0 {
                continue;
            }
            b.on_exposed_s += overlap;
            let photons = b.flux_hz * overlap;
            let p_cand = eff_max * fp.frac;
            if photons * p_cand > PER_PIXEL_ABOVE {
                let mut detected = 0u64;
                let mut mean_detected = 0.0;
                for y in fp.y.support() {
                    let gy = fp.y.mass(y);
                    for x in fp.x.support() {
                        let i = y * self.width + x;
                        let m = photons * gy * fp.x.mass(x) * eff[i];
                        mean_detected += m;
                        let c = poisson(rng, m);
                        if c > 0 {
                            hit(i, c);
                            detected = detected.saturating_add(c);
                        }
                    }
                }
                let rest = poisson(rng, (photons - mean_detected).max(0.0));
                b.photons_emitted = b
                    .photons_emitted
                    .saturating_add(detected.saturating_add(rest));
                b.photons_detected = b.photons_detected.saturating_add(detected);
                continue;
            }
            let k = poisson(rng, photons * p_cand);
            let rest = poisson(rng, photons * (1.0 - p_cand));
            b.photons_emitted += k + rest;
            let mut detected = 0u64;
            for _ in 0..k {
                let x = fp.x.sample(rng.gen::<f64>());
                let y = fp.y.sample(rng.gen::<f64>());
                let i = y * self.width + x;
                // Thinning by η(i, j)/η_max. A draw below η_min/η_max keeps the
                // photon whatever the pixel, so the (cache-missing) map is
                // only read for the rest.
                let u = rng.gen::<f64>() * eff_max;
                if u < eff_min || u < eff[i] {
                    hit(i, 1);
                    detected += 1;
                }
            }
            b.photons_detected += detected;
        }
    }
}
