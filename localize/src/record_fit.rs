//! Fitting a blink record's ROI where it lies on the sensor.
//!
//! A [`BlinkRecord`] holds the R×R ROI of photon-detection counts a blink
//! left over its summed bit-planes, placed by its anchor on the sensor.
//! [`fit_record`] leaves the ROI's pixels off the sensor out of the fit, cuts
//! the sensor's calibration maps ([`SensorMaps`]: dark-count rates, PRNU, hot
//! pixels; dark counts per bit-plane from the plane period) to the ROI, and fits it, giving a [`Localization`] in
//! sensor nanometres with the blink's timing and flags as extra columns.

use crate::fit::{fit_roi, Estimator, Fit, FitOptions, FitStatus, NoiseModel};
use crate::psf::MAX_SIDE;
use crate::roi::{apply_hot_pixels, HotPixelMode, PixelMaps, RoiView};
use crate::spad::{fit_binomial, on_off_split, SpadRoi};
use crate::table::Localization;
use smartagg_model::record::BlinkRecord;
use smartagg_model::sensor_maps::SensorMaps;

/// How the blink records of one stream are fitted: the estimator and its
/// options, the camera, and what is known of the sensor.
#[derive(Clone, Copy, Debug)]
pub struct RecordFitConfig<'a> {
    /// Estimator: [`Estimator::SpadMle`] fits the counts with the binomial
    /// likelihood and the record's on/off bit-plane split; the others fit
    /// them as one frame of photon counts.
    pub estimator: Estimator,
    /// Fit options; σ's fixed or initial value is also the σ of a failed
    /// fit. The frame estimators fit with Poisson noise whatever `noise`
    /// says: the counts are photon detections.
    pub opts: FitOptions,
    /// Sample-plane pixel size, nm.
    pub pixel_nm: f64,
    /// Sensor size `(width, height)`, pixels, from the stream's start record;
    /// without it only pixels left of or above the sensor are known to be off.
    pub sensor: Option<(usize, usize)>,
    /// Calibration maps of the sensor, if any (raster order, the size of
    /// the sensor).
    pub maps: Option<&'a SensorMaps>,
    /// Bit-plane period, s: a pixel's expected dark counts in one plane are
    /// its dark-count rate times it. Only read with `maps`.
    pub plane_period_s: f64,
    /// What to do with the maps' hot pixels.
    pub hot_pixels: HotPixelMode,
}

/// Fits one blink record's ROI. `frame` is the row's frame number (the
/// caller's blink index); the extra columns are the record's `t_s`, `t_e`,
/// `planes_summed` and `flags`.
///
/// A record whose counts are not `roi_size²` values (or whose side is 0 or
/// above [`MAX_SIDE`]) gives a failed fit with
/// [`FitStatus::InconsistentCounts`], not an error: one bad record must not
/// stop a stream.
pub fn fit_record(rec: &BlinkRecord, frame: u64, cfg: &RecordFitConfig) -> Localization {
    let side = rec.roi_size as usize;
    let (x0, y0) = (rec.roi_x0(), rec.roi_y0());
    let extra = vec![
        rec.t_s as f64,
        rec.t_e as f64,
        rec.planes_summed as f64,
        rec.flags as f64,
    ];
    let localization = |fit: &Fit| {
        let mut l = Localization::from_fit(fit, x0 as f64, y0 as f64, cfg.pixel_nm, frame);
        l.extra = extra;
        l
    };
    if side == 0 || side > MAX_SIDE || rec.counts.len() != side * side {
        let sigma = cfg.opts.sigma.value();
        return localization(&Fit::failed(
            side.max(1),
            sigma,
            FitStatus::InconsistentCounts,
        ));
    }
    let (mut pm, hot) = roi_maps(rec, cfg);
    let mut data: Vec<f64> = rec.counts.iter().map(|&c| c as f64).collect();
    if cfg.maps.is_some() {
        // Shapes agree by construction.
        let _ = apply_hot_pixels(&mut data, &hot, cfg.hot_pixels, &mut pm);
    }
    let fit = if cfg.estimator == Estimator::SpadMle {
        // Interpolated hot pixels are fitted as (whole) counts.
        let counts: Vec<u32> = if cfg.maps.is_some() && cfg.hot_pixels == HotPixelMode::Interpolate
        {
            data.iter().map(|&v| v.round().max(0.0) as u32).collect()
        } else {
            rec.counts.clone()
        };
        let (n_on, n_off) = on_off_split(rec);
        let roi = SpadRoi {
            side,
            counts: &counts,
            n_on,
            n_off,
            maps: Some(&pm),
        };
        fit_binomial(&roi, &cfg.opts)
    } else {
        // Frame estimators see totals: dark counts over all planes summed.
        let planes = rec.planes_summed as f64;
        for d in pm.dark.iter_mut() {
            *d *= planes;
        }
        let opts = FitOptions {
            noise: NoiseModel::Poisson,
            ..cfg.opts
        };
        let roi = RoiView {
            side,
            data: &data,
            maps: Some(&pm),
        };
        fit_roi(cfg.estimator, &roi, &opts)
    };
    localization(&fit)
}

/// The per-ROI maps of a record of well-formed shape, and its hot pixels:
/// pixels off the sensor ignored, the sensor maps cut out.
fn roi_maps(rec: &BlinkRecord, cfg: &RecordFitConfig) -> (PixelMaps, Vec<bool>) {
    let (sensor, maps) = (cfg.sensor, cfg.maps);
    let side = rec.roi_size as usize;
    let (x0, y0) = (rec.roi_x0(), rec.roi_y0());
    let mut pm = PixelMaps::uniform(side);
    let mut hot = vec![false; side * side];
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            let (x, y) = (x0 + i as i32, y0 + j as i32);
            let off =
                x < 0 || y < 0 || sensor.is_some_and(|(w, h)| x as usize >= w || y as usize >= h);
            if off {
                pm.ignore[k] = true;
                continue;
            }
            let Some(m) = maps else { continue };
            // x, y ≥ 0 here (off the sensor otherwise).
            if let Some(q) = m.index(x as u32, y as u32) {
                pm.dark[k] = m.dark_per_plane(q, cfg.plane_period_s);
                if let Some(g) = &m.prnu {
                    // A dead pixel (response 0) is left out rather than
                    // given an impossible gain.
                    if g[q] > 0.0 {
                        pm.gain[k] = g[q];
                    } else {
                        pm.ignore[k] = true;
                    }
                }
                hot[k] = m.hot[q];
            }
        }
    }
    (pm, hot)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::crlb::Emitter;
    use crate::fit::SigmaMode;
    use crate::synth::expected_roi;

    const PIXEL_NM: f64 = 50.0;
    const SENSOR: (usize, usize) = (64, 48);

    /// A 9×9 record anchored at `(x, y)` (ROI origin `(x − 4, y − 4)`).
    fn record(x: u16, y: u16, counts: Vec<u32>) -> BlinkRecord {
        BlinkRecord {
            slot: 0,
            flags: 0,
            anchor_x: x,
            anchor_y: y,
            t_cross: 1000,
            t_drop: 1500,
            t_s: 946,
            t_e: 1446,
            planes_summed: 609,
            roi_size: 9,
            counts,
        }
    }

    /// A noiseless blink spot at ROI position `(x, y)`, counts.
    fn spot(x: f64, y: f64) -> Vec<u32> {
        let em = Emitter {
            x,
            y,
            sigma: 1.5,
            photons: 2000.0,
            background: 7.0,
        };
        expected_roi(9, &em, None)
            .into_iter()
            .map(|v| v.round() as u32)
            .collect()
    }

    fn config(estimator: Estimator, maps: Option<&SensorMaps>) -> RecordFitConfig<'_> {
        RecordFitConfig {
            estimator,
            opts: FitOptions::new(SigmaMode::Fitted { initial: 1.5 }),
            pixel_nm: PIXEL_NM,
            sensor: Some(SENSOR),
            maps,
            plane_period_s: 1e-3,
            hot_pixels: HotPixelMode::Ignore,
        }
    }

    /// Maps with no dark counts, no PRNU, and the given hot pixels.
    fn maps_with_hot(hot_at: &[(usize, usize)]) -> SensorMaps {
        let n = SENSOR.0 * SENSOR.1;
        let mut hot = vec![false; n];
        for &(x, y) in hot_at {
            hot[y * SENSOR.0 + x] = true;
        }
        SensorMaps {
            hot,
            ..SensorMaps::uniform(SENSOR.0 as u32, SENSOR.1 as u32, 0.0)
        }
    }

    /// Fitted position, sensor pixels.
    fn px(l: &Localization) -> (f64, f64) {
        (l.x_nm / PIXEL_NM, l.y_nm / PIXEL_NM)
    }

    #[test]
    fn counts_that_do_not_fill_the_roi_give_inconsistent_counts() {
        let cfg = config(Estimator::Mle, None);
        let mut short = record(20, 30, spot(4.5, 4.5));
        short.counts.pop();
        let l = fit_record(&short, 7, &cfg);
        assert_eq!(l.status, FitStatus::InconsistentCounts);
        assert_eq!(l.frame, 7);
        // Placed at the ROI's centre (origin 16, 26), timing kept.
        assert_eq!(px(&l), (16.0 + 4.5, 26.0 + 4.5));
        assert_eq!(l.extra, vec![946.0, 1446.0, 609.0, 0.0]);
        assert_eq!(l.sigma_nm, 1.5 * PIXEL_NM);
        let mut empty = record(20, 30, Vec::new());
        empty.roi_size = 0;
        let l = fit_record(&empty, 1, &config(Estimator::SpadMle, None));
        assert_eq!(l.status, FitStatus::InconsistentCounts);
        // The well-formed record fits.
        let l = fit_record(&record(20, 30, spot(4.5, 4.5)), 7, &cfg);
        assert!(l.status.is_ok(), "{:?}", l.status);
    }

    #[test]
    fn a_clean_spot_fits_near_its_centre() {
        for est in [Estimator::Mle, Estimator::Lsq, Estimator::SpadMle] {
            let rec = record(20, 30, spot(4.8, 4.3));
            let l = fit_record(&rec, 1, &config(est, None));
            assert!(l.status.is_ok(), "{est:?}: {:?}", l.status);
            let (x, y) = px(&l);
            assert!((x - 20.8).abs() < 0.05, "{est:?}: x {x}");
            assert!((y - 30.3).abs() < 0.05, "{est:?}: y {y}");
        }
    }

    #[test]
    fn pixels_off_the_sensor_are_left_out() {
        // Garbage where the ROI leaves the sensor: fitted, it would pull
        // the spot away.
        let garbage = |x0: i32, y0: i32, counts: &mut [u32]| {
            for j in 0..9 {
                for i in 0..9 {
                    let (x, y) = (x0 + i, y0 + j);
                    if x < 0 || y < 0 || x >= SENSOR.0 as i32 || y >= SENSOR.1 as i32 {
                        counts[(j * 9 + i) as usize] = 500;
                    }
                }
            }
        };
        for est in [Estimator::Mle, Estimator::SpadMle] {
            // Top-left corner: ROI origin (−4, −4), spot at sensor (1.3, 1.6).
            let mut counts = spot(5.3, 5.6);
            garbage(-4, -4, &mut counts);
            let l = fit_record(&record(0, 0, counts), 1, &config(est, None));
            assert!(l.status.is_ok(), "{est:?}: {:?}", l.status);
            assert!(l.x_nm.is_finite() && l.y_nm.is_finite() && l.uncertainty_nm.is_finite());
            let (x, y) = px(&l);
            assert!(
                (x - 1.3).abs() < 0.1 && (y - 1.6).abs() < 0.1,
                "{est:?}: ({x}, {y})"
            );

            // Bottom-right corner: ROI origin (59, 43); only the sensor's
            // size tells the pixels beyond (63, 47) apart.
            let (w, h) = SENSOR;
            let mut counts = spot(3.4, 3.7);
            garbage(w as i32 - 5, h as i32 - 5, &mut counts);
            let rec = record(w as u16 - 1, h as u16 - 1, counts);
            let l = fit_record(&rec, 1, &config(est, None));
            assert!(l.status.is_ok(), "{est:?}: {:?}", l.status);
            let (x, y) = px(&l);
            let (tx, ty) = (w as f64 - 5.0 + 3.4, h as f64 - 5.0 + 3.7);
            assert!(
                (x - tx).abs() < 0.1 && (y - ty).abs() < 0.1,
                "{est:?}: ({x}, {y})"
            );
            let blind = RecordFitConfig {
                sensor: None,
                ..config(est, None)
            };
            let l = fit_record(&rec, 1, &blind);
            let (x, y) = px(&l);
            assert!(
                !l.status.is_ok() || (x - tx).abs() > 0.3 || (y - ty).abs() > 0.3,
                "{est:?}: fitting the garbage should have moved the spot: ({x}, {y})"
            );
        }
    }

    #[test]
    fn hot_pixels_are_ignored_or_interpolated() {
        // ROI origin (16, 26); hot pixel at ROI (6, 4), a pixel from the spot.
        let hot_at = (16 + 6, 26 + 4);
        let hot_k = 4 * 9 + 6;
        let mut clean = record(20, 30, spot(4.8, 4.5));
        // Neighbours whose mean is a whole count, so that the interpolated
        // ROI is also a record.
        let around = [hot_k - 9, hot_k - 1, hot_k + 1, hot_k + 9];
        let sum: u32 = around.iter().map(|&k| clean.counts[k]).sum();
        clean.counts[hot_k + 1] -= sum % 4;
        let mean = (sum - sum % 4) / 4;
        let mut hot = clean.clone();
        hot.counts[hot_k] = 600;
        let mut interpolated = clean.clone();
        interpolated.counts[hot_k] = mean;
        let flagged = maps_with_hot(&[hot_at]);
        let unflagged = maps_with_hot(&[]);
        for est in [Estimator::Mle, Estimator::SpadMle] {
            let truth = px(&fit_record(&clean, 1, &config(est, None)));
            // Not known to be hot, the pixel drags the fit towards it.
            let l = fit_record(&hot, 1, &config(est, Some(&unflagged)));
            let (x, _) = px(&l);
            assert!(
                !l.status.is_ok() || (x - truth.0).abs() > 0.2,
                "{est:?}: {x} vs {}",
                truth.0
            );
            for mode in [HotPixelMode::Ignore, HotPixelMode::Interpolate] {
                let cfg = RecordFitConfig {
                    hot_pixels: mode,
                    ..config(est, Some(&flagged))
                };
                let l = fit_record(&hot, 1, &cfg);
                assert!(l.status.is_ok(), "{est:?} {mode:?}: {:?}", l.status);
                let (x, y) = px(&l);
                assert!(
                    (x - truth.0).abs() < 0.05 && (y - truth.1).abs() < 0.05,
                    "{est:?} {mode:?}: ({x}, {y}) vs {truth:?}"
                );
                // The hot pixel's own count no longer matters.
                let mut hotter = hot.clone();
                hotter.counts[hot_k] = 300;
                assert_eq!(fit_record(&hotter, 1, &cfg), l, "{est:?} {mode:?}");
                // Interpolated, it is fitted as the mean of its neighbours;
                // ignored, it is not fitted at all.
                let as_mean = fit_record(&interpolated, 1, &config(est, Some(&unflagged)));
                assert_eq!(
                    as_mean == l,
                    mode == HotPixelMode::Interpolate,
                    "{est:?} {mode:?}"
                );
            }
        }
    }

    #[test]
    fn dark_counts_per_plane_are_summed_over_the_planes_for_frame_fits() {
        // 5 Hz at 1 ms planes: 0.005 counts per plane, 3.045 over 609 planes.
        let maps = SensorMaps::uniform(SENSOR.0 as u32, SENSOR.1 as u32, 5.0);
        let rec = record(20, 30, spot(4.5, 4.5));
        let bare = fit_record(&rec, 1, &config(Estimator::Mle, None));
        let dark = fit_record(&rec, 1, &config(Estimator::Mle, Some(&maps)));
        let drop = bare.offset - dark.offset;
        assert!(
            (drop - 5e-3 * 609.0).abs() < 0.1,
            "background fell by {drop}"
        );
    }

    #[test]
    fn a_dead_pixel_is_left_out() {
        let n = SENSOR.0 * SENSOR.1;
        let mut gain = vec![1.0; n];
        gain[30 * SENSOR.0 + 21] = 0.0;
        let maps = SensorMaps {
            prnu: Some(gain),
            ..SensorMaps::uniform(SENSOR.0 as u32, SENSOR.1 as u32, 0.0)
        };
        let mut rec = record(20, 30, spot(4.5, 4.5));
        let cfg = config(Estimator::Mle, Some(&maps));
        let l = fit_record(&rec, 1, &cfg);
        // ROI (5, 4) is sensor (21, 30): its count is not fitted.
        rec.counts[4 * 9 + 5] = 0;
        assert_eq!(fit_record(&rec, 1, &cfg), l);
        assert!(l.status.is_ok());
    }
}
