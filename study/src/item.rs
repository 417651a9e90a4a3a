//! One work item: one block of blinks at one point, every configuration of
//! the plan simulated on it (the same blinks), every scheme localised and
//! matched to the truth.

use crate::acquisition::{record_frames, record_planes, record_spad, Setup};
use crate::error::StudyError;
use crate::frames::{fit_options, FrameFitter, FrameMaps};
use crate::matching::{outcome, BlinkOutcome, Loc, SchemeOutcome, Truth};
use crate::spec::{Axis, Estimator, Method, Plan, MERGE_RADIUS_NM};
use crate::timeline::{derive_seed, key_hash, place, BlinkNm, Timeline, FRAME_S};
use smartagg_localize::merge::merge_consecutive;
use smartagg_localize::spad::{crlb_binomial, SpadEmitter};
use smartagg_localize::{
    fit_binomial, fit_roi, Fit, HotPixelMode, Localization, NoiseModel, PixelMaps, RoiView, SpadRoi,
};
use smartagg_model::config::PipelineConfig;
use smartagg_model::params::Camera;
use smartagg_model::record::{flags, BlinkRecord};
use std::time::Instant;

/// Wall time spent in one stage of a work item.
#[derive(Debug, Clone, PartialEq)]
pub struct Timing {
    /// Stage, e.g. `simulate spcimager-150x` or `fit spcimager-150x/smart`.
    pub stage: String,
    /// Units of work (bit-planes, frames, fits).
    pub count: u64,
    /// Seconds.
    pub seconds: f64,
}

/// The result of one work item.
#[derive(Debug, Clone, PartialEq)]
pub struct ItemResult {
    /// Point index.
    pub point: usize,
    /// Block index.
    pub block: usize,
    /// One outcome per scheme of the plan.
    pub outcomes: Vec<SchemeOutcome>,
    /// Where the time went (not part of the deterministic results).
    pub timings: Vec<Timing>,
}

/// The seed of work item (`point`, `block`). Blink-duration studies key it
/// on the duration (so the same duration gives the same blinks in every
/// study); the hot-pixel study uses the same blinks at every percentage, so
/// its points differ only in the hot pixels.
pub fn item_seed(plan: &Plan, point: usize, block: usize) -> u64 {
    let key = match plan.axis {
        Axis::BlinkMs => {
            key_hash("blink-us") ^ ((plan.points[point] * 1000.0).round() as u64).wrapping_mul(3)
        }
        Axis::HotPercent => key_hash("hot-pixel-frames"),
    };
    derive_seed(&[plan.options.seed, key, block as u64])
}

/// The timeline of a work item.
pub fn item_timeline(plan: &Plan, point: usize, block: usize) -> Timeline {
    let seed = item_seed(plan, point, block);
    let n = plan.blinks_in_block(block);
    match plan.axis {
        Axis::BlinkMs => Timeline::one_at_a_time(seed, n, plan.points[point] / 1000.0),
        Axis::HotPercent => Timeline::frame_aligned(seed, n),
    }
}

fn truth_of(blinks: &[BlinkNm]) -> Vec<Truth> {
    blinks.iter().map(Truth::from).collect()
}

/// Runs work item (`point`, `block`) of `plan`; `setups[c]` is the setup of
/// configuration `c`.
pub fn run_item(
    plan: &Plan,
    setups: &[Setup],
    point: usize,
    block: usize,
) -> Result<ItemResult, StudyError> {
    let timeline = item_timeline(plan, point, block);
    let item = item_seed(plan, point, block);
    let radius = plan.options.match_radius_nm;
    let mut outcomes: Vec<Option<SchemeOutcome>> = vec![None; plan.schemes.len()];
    let mut timings = Vec::new();
    for (c, config) in plan.configs.iter().enumerate() {
        let setup = &setups[c];
        let schemes: Vec<usize> = (0..plan.schemes.len())
            .filter(|&s| plan.schemes[s].config == c)
            .collect();
        if schemes.is_empty() {
            continue;
        }
        let seed = derive_seed(&[item, key_hash(&config.key)]);
        let blinks = place(&timeline.blinks, setup.field_nm(), setup.margin_nm);
        let truth = truth_of(&blinks);
        let methods: Vec<Method> = schemes.iter().map(|&s| plan.schemes[s].method).collect();
        let fit_sigma = plan.options.fit_sigma;
        if config.is_spad() {
            let spad = setup.spad.as_ref().expect("SPAD setup");
            let want_main = methods.iter().any(|m| {
                matches!(
                    m,
                    Method::Smart | Method::SmartSpadMle | Method::Estimator(_)
                )
            });
            let want_paper = methods.contains(&Method::SmartPaper);
            let paper_cfg = setup.paper.as_ref().expect("SPAD setup");
            let mut pipelines = Vec::new();
            if want_main {
                pipelines.push(spad.1.clone());
            }
            if want_paper {
                pipelines.push(paper_cfg.clone());
            }
            let frames = methods.iter().any(|m| {
                matches!(
                    m,
                    Method::Fixed | Method::HotIgnore | Method::HotInterpolate
                )
            });
            let hot = match plan.axis {
                Axis::HotPercent => Some(plan.points[point] / 100.0),
                Axis::BlinkMs => None,
            };
            let data = record_spad(
                setup,
                &blinks,
                timeline.end_s,
                seed,
                &pipelines,
                frames,
                hot,
            )?;
            let masked: &[bool] = if data.masked { &data.hot } else { &[] };
            let sensor = SensorView {
                masked,
                gain: &data.gain,
            };
            let main = if want_main { &data.records[0][..] } else { &[] };
            let paper = if want_paper {
                &data.records[pipelines.len() - 1][..]
            } else {
                &[]
            };
            timings.push(Timing {
                stage: format!("simulate {}", config.key),
                count: data.planes,
                seconds: data.simulate_s,
            });
            if !pipelines.is_empty() {
                timings.push(Timing {
                    stage: format!("pipeline {}", config.key),
                    count: data.planes,
                    seconds: data.pipeline_s,
                });
            }
            for &s in &schemes {
                let m = plan.schemes[s].method;
                let o = match m {
                    Method::Smart | Method::SmartPaper => {
                        let (recs, cfg) = if m == Method::Smart {
                            (main, &spad.1)
                        } else {
                            (paper, paper_cfg)
                        };
                        let a = Instant::now();
                        let opts = fit_options(setup.sigma_px, fit_sigma, NoiseModel::Poisson);
                        let r = localize_records(
                            setup,
                            &sensor,
                            cfg,
                            recs,
                            &truth,
                            radius,
                            |roi, _, maps| {
                                fit_roi(
                                    smartagg_localize::Estimator::Mle,
                                    &roi_view(roi, maps),
                                    &opts,
                                )
                            },
                        );
                        timings.push(Timing {
                            stage: format!("fit {}", plan.schemes[s].id),
                            count: r.fitted as u64,
                            seconds: a.elapsed().as_secs_f64(),
                        });
                        outcome(&truth, &r.locs, radius, recs.len() as u32, r.failed)
                    }
                    Method::SmartCrlb => crlb_outcome(setup, &blinks, fit_sigma),
                    Method::SmartSpadMle | Method::Estimator(_) => {
                        let est = match m {
                            Method::Estimator(e) => e,
                            _ => {
                                if fit_sigma {
                                    Estimator::SpadMle
                                } else {
                                    Estimator::SpadMleFixedSigma
                                }
                            }
                        };
                        let a = Instant::now();
                        let r = localize_records(
                            setup,
                            &sensor,
                            &spad.1,
                            main,
                            &truth,
                            radius,
                            |roi, rec, maps| estimate(est, setup.sigma_px, roi, rec, maps),
                        );
                        timings.push(Timing {
                            stage: format!("fit {}", plan.schemes[s].id),
                            count: r.fitted as u64,
                            seconds: a.elapsed().as_secs_f64(),
                        });
                        outcome(&truth, &r.locs, radius, main.len() as u32, r.failed)
                    }
                    Method::Fixed | Method::HotIgnore | Method::HotInterpolate => {
                        let mut fitter = FrameFitter::new(fit_options(
                            setup.sigma_px,
                            fit_sigma,
                            NoiseModel::Poisson,
                        ));
                        fitter.threshold_factor = plan.options.frame_threshold;
                        let maps = if matches!(m, Method::Fixed) {
                            FrameMaps::default()
                        } else {
                            fitter.hot_mode = if m == Method::HotIgnore {
                                HotPixelMode::Ignore
                            } else {
                                HotPixelMode::Interpolate
                            };
                            FrameMaps {
                                read_var: Vec::new(),
                                hot: data.hot.clone(),
                            }
                        };
                        let a = Instant::now();
                        let frames: Vec<Vec<f64>> = data
                            .frames
                            .iter()
                            .map(|f| f.iter().map(|&c| c as f64).collect())
                            .collect();
                        let all = localize_frames(setup, &fitter, &frames, &maps)?;
                        timings.push(Timing {
                            stage: format!("fit {}", plan.schemes[s].id),
                            count: all.len() as u64,
                            seconds: a.elapsed().as_secs_f64(),
                        });
                        frame_outcome(&truth, &all, radius)
                    }
                    Method::Frames | Method::FramesMerged => {
                        unreachable!("frame-camera method on a SPAD configuration")
                    }
                };
                outcomes[s] = Some(o);
            }
        } else {
            let data = record_frames(setup, &blinks, timeline.end_s, seed)?;
            timings.push(Timing {
                stage: format!("simulate {}", config.key),
                count: data.frames.len() as u64,
                seconds: data.simulate_s,
            });
            let noise = match setup.preset.camera {
                Camera::Emccd(_) => NoiseModel::Emccd,
                _ => NoiseModel::Scmos,
            };
            let mut fitter = FrameFitter::new(fit_options(setup.sigma_px, fit_sigma, noise));
            fitter.threshold_factor = plan.options.frame_threshold;
            let a = Instant::now();
            let all = localize_frames(setup, &fitter, &data.frames, &data.maps)?;
            timings.push(Timing {
                stage: format!("fit {}", config.key),
                count: all.len() as u64,
                seconds: a.elapsed().as_secs_f64(),
            });
            for &s in &schemes {
                let o = match plan.schemes[s].method {
                    Method::Frames => frame_outcome(&truth, &all, radius),
                    Method::FramesMerged => {
                        // Failed fits pass through unmerged (and stay failed).
                        let (merged, _) = merge_consecutive(&all, MERGE_RADIUS_NM, 0);
                        frame_outcome(&truth, &merged, radius)
                    }
                    other => unreachable!("{other:?} on a frame camera"),
                };
                outcomes[s] = Some(o);
            }
        }
    }
    Ok(ItemResult {
        point,
        block,
        outcomes: outcomes
            .into_iter()
            .map(|o| o.expect("every scheme has a configuration"))
            .collect(),
        timings,
    })
}

/// Pixel maps of a record's ROI: pixels outside the sensor are left out.
pub(crate) fn record_maps(rec: &BlinkRecord, field: u32) -> Option<PixelMaps> {
    record_maps_calibrated(rec, field, &SensorView::default())
}

/// What the localisers know of a calibrated field: the pixels the pipeline
/// masked (they read 0) and the relative detection efficiency, raster order
/// over the field (empty when absent).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct SensorView<'a> {
    /// Masked pixels.
    pub masked: &'a [bool],
    /// PRNU.
    pub gain: &'a [f64],
}

/// Pixel maps of a record's ROI on a calibrated field: pixels outside the
/// sensor and masked pixels are left out of the likelihood, the PRNU scales
/// each pixel's light; `None` when every pixel is nominal.
pub(crate) fn record_maps_calibrated(
    rec: &BlinkRecord,
    field: u32,
    sensor: &SensorView,
) -> Option<PixelMaps> {
    let masked = rec.has(flags::MASKED) && !sensor.masked.is_empty();
    if !rec.has(flags::EDGE) && !masked && sensor.gain.is_empty() {
        return None;
    }
    let side = rec.roi_size as usize;
    let mut m = PixelMaps::uniform(side);
    for j in 0..side {
        for i in 0..side {
            let (x, y) = (rec.roi_x0() + i as i32, rec.roi_y0() + j as i32);
            let k = j * side + i;
            if x < 0 || y < 0 || x >= field as i32 || y >= field as i32 {
                m.ignore[k] = true;
                continue;
            }
            let f = y as usize * field as usize + x as usize;
            if masked {
                m.ignore[k] = sensor.masked[f];
            }
            if let Some(&g) = sensor.gain.get(f) {
                m.gain[k] = g;
            }
        }
    }
    Some(m)
}

pub(crate) fn roi_view<'a>(data: &'a [f64], maps: Option<&'a PixelMaps>) -> RoiView<'a> {
    let side = (data.len() as f64).sqrt().round() as usize;
    RoiView { side, data, maps }
}

/// Localisations of the smart records.
struct RecordLocs {
    /// Successful fits.
    locs: Vec<Loc>,
    /// Records fitted.
    fitted: u32,
    /// Fits that failed.
    failed: u32,
}

/// Whether a localisation from `rec`, a record of a pipeline configured with
/// `cfg`, could match any blink of `truth`: its summed planes
/// ([`record_planes`]) must overlap the blink's on-time, and an accepted fit lies
/// within half a pixel of the ROI (outside it the fit reports
/// `OutsideRoi`), so the ROI grown by that and by the match radius must
/// contain the blink. Records that cannot match are false positives
/// whatever their fit and are not fitted (most of the pipeline's false
/// blinks, far from the molecule, are skipped this way).
fn could_match(
    rec: &BlinkRecord,
    cfg: &PipelineConfig,
    truth: &[Truth],
    radius: f64,
    pixel_nm: f64,
    period: f64,
) -> bool {
    let planes = record_planes(rec, cfg);
    let first = planes.start as f64 * period;
    let last = planes.end as f64 * period;
    let side = rec.roi_size as f64;
    let x0 = (rec.roi_x0() as f64 - 0.5) * pixel_nm;
    let y0 = (rec.roi_y0() as f64 - 0.5) * pixel_nm;
    let x1 = x0 + (side + 1.0) * pixel_nm;
    let y1 = y0 + (side + 1.0) * pixel_nm;
    truth.iter().any(|b| {
        if !(first < b.t_off_s && last > b.t_on_s) {
            return false;
        }
        let dx = (x0 - b.x_nm).max(b.x_nm - x1).max(0.0);
        let dy = (y0 - b.y_nm).max(b.y_nm - y1).max(0.0);
        dx * dx + dy * dy <= radius * radius
    })
}

/// Localises with `fit` the records, of a pipeline configured with `cfg`,
/// that could match a blink; a localisation spans the planes its record
/// summed.
fn localize_records(
    setup: &Setup,
    sensor: &SensorView,
    cfg: &PipelineConfig,
    records: &[BlinkRecord],
    truth: &[Truth],
    radius: f64,
    fit: impl Fn(&[f64], &BlinkRecord, Option<&PixelMaps>) -> Fit,
) -> RecordLocs {
    let period = setup.spad_camera().map_or(1e-4, |c| c.plane_period_s);
    let mut out = RecordLocs {
        locs: Vec::new(),
        fitted: 0,
        failed: 0,
    };
    for rec in records {
        if !could_match(rec, cfg, truth, radius, setup.pixel_nm, period) {
            continue;
        }
        out.fitted += 1;
        let maps = record_maps_calibrated(rec, setup.field, sensor);
        let data: Vec<f64> = rec.counts.iter().map(|&c| c as f64).collect();
        let f = fit(&data, rec, maps.as_ref());
        if !f.status.is_ok() {
            out.failed += 1;
            continue;
        }
        let planes = record_planes(rec, cfg);
        out.locs.push(Loc {
            x_nm: (rec.roi_x0() as f64 + f.x) * setup.pixel_nm,
            y_nm: (rec.roi_y0() as f64 + f.y) * setup.pixel_nm,
            t0_s: planes.start as f64 * period,
            t1_s: planes.end as f64 * period,
            photons: f.photons,
        });
    }
    out
}

/// One estimator of the `localizers` study on one record.
fn estimate(
    est: Estimator,
    sigma_px: f64,
    data: &[f64],
    rec: &BlinkRecord,
    maps: Option<&PixelMaps>,
) -> Fit {
    let fitted = fit_options(sigma_px, true, NoiseModel::Poisson);
    let fixed = fit_options(sigma_px, false, NoiseModel::Poisson);
    let view = roi_view(data, maps);
    match est {
        Estimator::Centroid => fit_roi(smartagg_localize::Estimator::Centroid, &view, &fitted),
        Estimator::Lsq => fit_roi(smartagg_localize::Estimator::Lsq, &view, &fitted),
        Estimator::MleFixedSigma => fit_roi(smartagg_localize::Estimator::Mle, &view, &fixed),
        Estimator::Mle => fit_roi(smartagg_localize::Estimator::Mle, &view, &fitted),
        Estimator::SpadMleFixedSigma | Estimator::SpadMle => {
            let opts = if est == Estimator::SpadMle {
                fitted
            } else {
                fixed
            };
            match SpadRoi::from_record(rec, maps) {
                Ok(roi) => fit_binomial(&roi, &opts),
                Err(_) => Fit::failed(
                    rec.roi_size as usize,
                    sigma_px,
                    smartagg_localize::FitStatus::InconsistentCounts,
                ),
            }
        }
    }
}

/// Localises frames: every candidate of every frame (failed fits flagged),
/// frame `k` (0-based) written as `k + 1` (ThunderSTORM's 1-based frames).
fn localize_frames(
    setup: &Setup,
    fitter: &FrameFitter,
    frames: &[Vec<f64>],
    maps: &FrameMaps,
) -> Result<Vec<Localization>, StudyError> {
    let w = setup.field as usize;
    let mut all = Vec::new();
    for (k, f) in frames.iter().enumerate() {
        all.extend(fitter.localize(f, w, w, maps, setup.pixel_nm, k as u64 + 1)?);
    }
    Ok(all)
}

/// The outcome of frame localisations: frame `f` (1-based) exposes
/// `[(f − 1)·50 ms, f·50 ms)`; a merged localisation of `d` detections in
/// consecutive frames spans `d` frames. Every candidate is a detection;
/// failed fits give no localisation.
fn frame_outcome(truth: &[Truth], all: &[Localization], radius: f64) -> SchemeOutcome {
    let locs: Vec<Loc> = all
        .iter()
        .filter(|l| l.status.is_ok())
        .map(|l| Loc {
            x_nm: l.x_nm,
            y_nm: l.y_nm,
            t0_s: (l.frame - 1) as f64 * FRAME_S,
            t1_s: (l.frame - 1 + l.detections.max(1) as u64) as f64 * FRAME_S,
            photons: l.intensity,
        })
        .collect();
    let failed = (all.len() - locs.len()) as u32;
    outcome(truth, &locs, radius, all.len() as u32, failed)
}

/// The reference: for every blink, the Cramér–Rao bound (`var_x + var_y`,
/// nm²) of the SPAD binomial model for an ideal aggregation of exactly its
/// on-planes (no off-plane), at its true position in a 9×9 ROI centred on
/// its pixel, with the preset's molecule and background rates per plane and
/// σ fixed or fitted as the study fits it.
fn crlb_outcome(setup: &Setup, blinks: &[BlinkNm], fit_sigma: bool) -> SchemeOutcome {
    let cam = setup.spad_camera().expect("SPAD setup");
    let signal = setup.preset.light.flux_hz * cam.eta() * cam.exposure_s;
    let background = setup.preset.background_rate_hz() * cam.exposure_s;
    let side = crate::spec::ROI_SIDE;
    let half = (side / 2) as f64;
    let blinks_out = blinks
        .iter()
        .map(|b| {
            let (x, y) = (b.x_nm / setup.pixel_nm, b.y_nm / setup.pixel_nm);
            let n_on = ((b.t_off_s - b.t_on_s) / cam.plane_period_s)
                .round()
                .max(1.0) as u32;
            let em = SpadEmitter {
                x: x - (x.floor() - half),
                y: y - (y.floor() - half),
                sigma: setup.sigma_px,
                signal_per_plane: signal,
                background_per_plane: background,
            };
            match crlb_binomial(side, &em, n_on, 0, None, fit_sigma) {
                Some((vx, vy)) if (vx + vy).is_finite() => BlinkOutcome {
                    matches: 1,
                    sse_nm2: (vx + vy) * setup.pixel_nm * setup.pixel_nm,
                    sum_dx_nm: 0.0,
                    sum_dy_nm: 0.0,
                },
                _ => BlinkOutcome::default(),
            }
        })
        .collect::<Vec<_>>();
    SchemeOutcome {
        detections: blinks_out.iter().map(|b| b.matches).sum(),
        blinks: blinks_out,
        false_pos: 0,
        failed_fits: 0,
    }
}
