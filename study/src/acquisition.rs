//! Recordings of one work item: the scene simulator's bit-planes through the
//! real smart-aggregation pipeline and packet path, the same bit-planes
//! summed into fixed frames, and EMCCD/sCMOS frames of the same blinks.
//!
//! **Smart aggregation** runs the model's pipeline with the fast engine
//! (`model::fast_engine::fast_pipeline`: the golden stages 5–7 with
//! incremental stages 1–4, proven byte-identical to the golden pipeline by
//! the model's tests). Its parameters are the **field design** of the study
//! field ([`field_design_config`], what `smartagg aggregate` defaults to on
//! a recording of that size and plane rate): the paper's statistics for the
//! preset (`stats::derive`: N, kernel, Eq. 7's T) and
//! `model::field_design::design` with the default budget of 1 false
//! blink/s over the field (T_open, T_hold, r_assoc, L_min, end_trim), a 9×9
//! ROI and the default slots. [`Setup::with_pipeline`] applies the study's
//! overrides (`--l-min`, `--r-assoc`) to it; [`Setup::paper`] is the
//! paper's literal scheme on the same field ([`paper_config`]: one
//! threshold T, L_min 1, r_assoc 1, end_trim 0), never overridden.
//! Every record then goes through `packetiser::encode_stream` and
//! `packet::decode_all`, the real packet path; any decoder loss is an error.

use crate::error::StudyError;
use crate::frames::FrameMaps;
use crate::sensor::{CalibratedSetup, SensorCalibration};
use crate::spec::{LMin, FIXED_FRAME_PLANES, ROI_SIDE};
use crate::timeline::BlinkNm;
use smartagg_model::config::PipelineConfig;
use smartagg_model::fast_engine::fast_pipeline;
use smartagg_model::field_design::{self, FieldDesign, DEFAULT_FALSE_BLINKS_PER_S};
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::packet::decode_all;
use smartagg_model::packetiser::encode_stream;
use smartagg_model::params::{Camera, Preset, PresetName, SpadCamera};
use smartagg_model::record::{BlinkRecord, Record};
use smartagg_model::record_check::summed_planes_by;
use smartagg_model::stats::{self, Detection, DetectionInputs};
use smartagg_scene::{
    Blinking, EmccdSimulator, ExplicitBlink, Position, Scene, ScmosSimulator, SpadSimulator,
};
use std::ops::Range;
use std::time::Instant;

/// A camera configuration with everything derived from its preset.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The preset (camera, optics, light).
    pub preset: Preset,
    /// Side of the simulated square field, pixels.
    pub field: u32,
    /// Pixel size in the sample plane, nm.
    pub pixel_nm: f64,
    /// PSF σ, pixels.
    pub sigma_px: f64,
    /// Margin kept free of molecules, nm (3σ, at most a quarter of the field).
    pub margin_nm: f64,
    /// SPAD only: the paper's statistics and the smart scheme's pipeline
    /// configuration (the field design, with the study's overrides).
    pub spad: Option<(Detection, PipelineConfig)>,
    /// SPAD only: the field design the smart scheme was built from (before
    /// the study's overrides), with what it predicts.
    pub design: Option<FieldDesign>,
    /// SPAD only: the paper's literal scheme on the same field (one
    /// threshold T, L_min 1, r_assoc 1, end_trim 0).
    pub paper: Option<PipelineConfig>,
    /// SPCImager only: a calibrated sensor whose maps replace the synthetic ones.
    pub sensor: Option<CalibratedSetup>,
}

impl Setup {
    /// Derives the setup of `preset` with `objective`: the field design as
    /// the smart scheme, the paper's literal scheme beside it.
    pub fn new(preset: PresetName, objective: u32) -> Result<Setup, StudyError> {
        let preset = Preset::new(preset, objective)?;
        let field = preset.study_field_px;
        let sigma_px = preset.sigma_px();
        let pixel_nm = preset.pixel_nm();
        let margin_nm = (3.0 * sigma_px).min(field as f64 / 4.0) * pixel_nm;
        let (spad, design, paper) = match preset.camera {
            Camera::Spad(ref cam) => {
                let det = stats::derive(&DetectionInputs::from_preset(&preset, None)?)?;
                let period = cam.plane_period_s;
                let (design, cfg) = field_design_config(&det, field, field, period)?;
                let paper = paper_config(&det, field, field, period)?;
                (Some((det, cfg)), Some(design), Some(paper))
            }
            _ => (None, None, None),
        };
        Ok(Setup {
            preset,
            field,
            pixel_nm,
            sigma_px,
            margin_nm,
            spad,
            design,
            paper,
            sensor: None,
        })
    }

    /// The same setup with the study's overrides of the smart scheme (the
    /// field design): `L_min` ([`LMin::Design`] keeps the design's) and the
    /// association radius. [`Setup::paper`] stays the paper's literal scheme.
    pub fn with_pipeline(mut self, l_min: LMin, r_assoc: Option<u32>) -> Result<Setup, StudyError> {
        if let Some((_, cfg)) = self.spad.as_mut() {
            if let LMin::Planes(l) = l_min {
                cfg.l_min = l;
                cfg.l_max = cfg.l_max.max(l);
            }
            if let Some(r) = r_assoc {
                cfg.r_assoc = r;
            }
            cfg.validate()?;
        }
        Ok(self)
    }

    /// The same setup simulating a calibrated sensor, if it applies: only the
    /// SPCImager presets (the other cameras are not the calibrated one).
    /// Errors if the sensor is smaller than the study field, if the maps are
    /// bad, or if the hot-pixel criterion cannot be derived for this N and
    /// T_hold.
    /// Without maps (options read back from a manifest) nothing changes:
    /// [`crate::run::run`] refuses to simulate then.
    pub fn with_sensor(mut self, cal: Option<&SensorCalibration>) -> Result<Setup, StudyError> {
        let Some(cal) = cal else { return Ok(self) };
        if self.preset.name != PresetName::Spcimager {
            return Ok(self);
        }
        let bad = |why: String| StudyError::Option {
            name: "calibration",
            why,
        };
        // Read back from a manifest (merge, report): the identity only.
        let Some(sensor) = cal.sensor.clone() else {
            return Ok(self);
        };
        let maps = &sensor.maps;
        maps.validate()
            .map_err(|e| bad(format!("{}: {e}", cal.id)))?;
        if maps.width < self.field || maps.height < self.field {
            return Err(bad(format!(
                "{}: the calibrated sensor is {}x{} pixels, smaller than the {}x{} study field",
                cal.id, maps.width, maps.height, self.field, self.field
            )));
        }
        // A hot pixel at the hold level would keep a neighbouring track on
        // (as `aggregate --calibration` judges it); the paper's scheme has
        // the same N and its one threshold is the design's T_hold.
        let (n, t) = match &self.spad {
            Some((_, cfg)) => (cfg.n_window, u64::from(cfg.threshold_hold)),
            None => return Ok(self),
        };
        let critical_dcr_hz = (sensor.critical_dcr)(n, t).map_err(|e| {
            bad(format!(
                "{}: hot-pixel criterion for N = {n}, T_hold = {t}: {e}",
                cal.id
            ))
        })?;
        self.sensor = Some(CalibratedSetup {
            sensor,
            critical_dcr_hz,
        });
        Ok(self)
    }

    /// Field width in the sample plane, nm.
    pub fn field_nm(&self) -> f64 {
        self.field as f64 * self.pixel_nm
    }

    /// The SPAD camera, if this is one.
    pub fn spad_camera(&self) -> Option<&SpadCamera> {
        match &self.preset.camera {
            Camera::Spad(c) => Some(c),
            _ => None,
        }
    }

    /// The study scene of this setup with exactly `blinks`.
    fn scene(&self, blinks: &[BlinkNm]) -> Scene {
        let mut s = Scene::study(&self.preset, 0.05);
        s.blinking = Blinking::Explicit(
            blinks
                .iter()
                .enumerate()
                .map(|(i, b)| ExplicitBlink {
                    emitter: i as u64,
                    position: Position {
                        x_nm: b.x_nm,
                        y_nm: b.y_nm,
                    },
                    t_on_s: b.t_on_s,
                    t_off_s: b.t_off_s,
                    flux_factor: 1.0,
                })
                .collect(),
        );
        s
    }
}

/// The smart scheme of every study on a `width × height` field recorded at
/// one plane per `plane_period_s`: the **field design**
/// (`model::field_design::design` with the default budget,
/// [`DEFAULT_FALSE_BLINKS_PER_S`] false blinks/s over the field), built as
/// `smartagg aggregate` builds its default pipeline for a recording of that
/// size and plane period: `T_int` = T_open, `T_hold`, `r_assoc`, `L_min`
/// and `end_trim` (⌊N/2⌋: a blink sums `[t_cross − N, t_drop − end_trim]`)
/// from the design, N and the kernel from `det`. The study's one
/// difference: every fitted ROI is [`ROI_SIDE`] pixels wide (aggregate's
/// default is the kernel's size), as the study's frame fits are. The
/// studies' only construction of it.
pub fn field_design_config(
    det: &Detection,
    width: u32,
    height: u32,
    plane_period_s: f64,
) -> Result<(FieldDesign, PipelineConfig), StudyError> {
    let mut cfg = paper_config(det, width, height, plane_period_s)?;
    let rate = 1e9 / cfg.plane_period_ns as f64;
    let design = field_design::design(det, width, height, rate, DEFAULT_FALSE_BLINKS_PER_S)
        .map_err(|e| StudyError::Option {
            name: "field design",
            why: e.to_string(),
        })?;
    design.apply(&mut cfg)?;
    cfg.validate()?;
    Ok((design, cfg))
}

/// The paper's literal scheme on a `width × height` field recorded at one
/// plane per `plane_period_s`: one threshold, Eq. 7's `T_int` from `det`
/// (opens and holds), `L_min = 1`, `r_assoc = 1`, `end_trim = 0` (a blink
/// sums `[t_cross − N, t_drop]`), a [`ROI_SIDE`]-wide ROI.
pub fn paper_config(
    det: &Detection,
    width: u32,
    height: u32,
    plane_period_s: f64,
) -> Result<PipelineConfig, StudyError> {
    let period_ns = (plane_period_s * 1e9).round();
    if !(period_ns >= 1.0 && period_ns <= u32::MAX as f64) {
        return Err(StudyError::Option {
            name: "plane period",
            why: format!("{plane_period_s} s is not 1 ns ..= 4.29 s"),
        });
    }
    let mut cfg = PipelineConfig::new(
        width as usize,
        height as usize,
        det.n_window,
        det.kernel_weights.clone(),
        det.kernel_shift,
        threshold32(det.threshold_int)?,
    );
    cfg.l_min = 1;
    cfg.r_assoc = 1;
    cfg.end_trim = 0;
    cfg.roi_size = ROI_SIDE;
    cfg.plane_period_ns = period_ns as u32;
    cfg.validate()?;
    Ok(cfg)
}

fn threshold32(t: u64) -> Result<u32, StudyError> {
    u32::try_from(t).map_err(|_| StudyError::Option {
        name: "threshold",
        why: format!("T_int = {t} does not fit 32 bits"),
    })
}

/// What a SPAD recording gave.
#[derive(Debug, Clone, Default)]
pub struct SpadData {
    /// Per pipeline asked for: the blink records decoded from its packet
    /// stream, in stream order.
    pub records: Vec<Vec<BlinkRecord>>,
    /// Fixed frames: counts of consecutive 500-plane groups, raster order.
    pub frames: Vec<Vec<u32>>,
    /// The hot-pixel map of the simulated camera.
    pub hot: Vec<bool>,
    /// Whether the pipelines masked the pixels of `hot` (calibrated sensor).
    pub masked: bool,
    /// Relative detection efficiency of the field's pixels (calibrated PRNU),
    /// raster order; empty when uniform.
    pub gain: Vec<f64>,
    /// Bit-planes simulated.
    pub planes: u64,
    /// Packet bytes of the smart-aggregation streams.
    pub packet_bytes: u64,
    /// Wall time in the scene simulator, s.
    pub simulate_s: f64,
    /// Wall time in the pipelines, packetiser and decoder, s.
    pub pipeline_s: f64,
}

/// The bit-planes summed into `rec`, a record of a pipeline configured with
/// `cfg` (half-open, `first..end`): the model's rule
/// (`record_check::summed_planes_by`) with the configuration's window N and
/// `end_trim` — `[t_cross − N, t_drop − end_trim]` for a segment that ended
/// by a drop, `t_drop − N` the last plane of a CUT segment, `t_drop` of a
/// TRUNCATED one. The studies' only copy of the rule.
pub fn record_planes(rec: &BlinkRecord, cfg: &PipelineConfig) -> Range<u64> {
    summed_planes_by(rec, cfg.n_window, Some(cfg.end_trim))
}

/// The blink records of a finished stream, through the packet path: every
/// record is encoded by the packetiser and decoded back; any loss is an error.
pub(crate) fn through_packets(records: &[Record]) -> Result<(Vec<BlinkRecord>, u64), StudyError> {
    let bytes = encode_stream(records)?;
    let decoded = decode_all(&bytes);
    if decoded.stats.any_loss() {
        return Err(StudyError::PacketLoss(decoded.stats.to_string()));
    }
    if decoded.packets.len() != records.len() {
        return Err(StudyError::PacketLoss(format!(
            "{} records encoded, {} decoded",
            records.len(),
            decoded.packets.len()
        )));
    }
    let blinks = decoded
        .packets
        .into_iter()
        .filter_map(|p| match p.record {
            Record::Blink(b) => Some(b),
            _ => None,
        })
        .collect();
    Ok((blinks, bytes.len() as u64))
}

/// Simulates `end_s` of bit-planes of `setup` watching `blinks` (seeded
/// with `seed`), running every pipeline of `pipelines` on the same
/// bit-planes and summing fixed frames when `frames`. `hot_fraction`
/// overrides the camera's hot pixels.
pub fn record_spad(
    setup: &Setup,
    blinks: &[BlinkNm],
    end_s: f64,
    seed: u64,
    pipelines: &[PipelineConfig],
    frames: bool,
    hot_fraction: Option<f64>,
) -> Result<SpadData, StudyError> {
    let mut camera = setup
        .spad_camera()
        .expect("record_spad on a SPAD setup")
        .clone();
    if let Some(f) = hot_fraction {
        camera.hot_pixel_fraction = f;
    }
    let scene = setup.scene(blinks);
    let t0 = Instant::now();
    let field = setup.field;
    // A calibrated sensor: this item's crop of the measured maps, its hot
    // pixels masked in every pipeline (as `aggregate --calibration` does).
    let (mut sim, mask, gain) = match &setup.sensor {
        Some(cal) if hot_fraction.is_none() => {
            let at = cal.sensor.offset(field, seed);
            let maps = cal
                .sensor
                .crop(field, at, cal.critical_dcr_hz)
                .map_err(smartagg_scene::SceneError::from)?;
            let gain: Vec<f64> = (0..maps.pixels()).map(|i| maps.prnu_of(i)).collect();
            let hot: Vec<(usize, usize)> = (0..maps.hot.len())
                .filter(|&i| maps.hot[i])
                .map(|i| (i % field as usize, i / field as usize))
                .collect();
            let (mask, _) = HotPixelMask::from_pixels(field as usize, field as usize, &hot);
            let sim = SpadSimulator::with_maps(&camera, &scene, maps, seed)?;
            (sim, Some(mask), gain)
        }
        _ => (SpadSimulator::new(&camera, &scene, seed)?, None, Vec::new()),
    };
    let mut simulate_s = t0.elapsed().as_secs_f64();
    let planes = (end_s / camera.plane_period_s).round() as u64;
    let n_px = (field * field) as usize;
    let mut pipes = pipelines
        .iter()
        .map(|c| {
            let mut c = c.clone();
            if mask.is_some() {
                c.hot_mask = mask.clone();
            }
            fast_pipeline(c)
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut streams: Vec<Vec<Record>> = pipes.iter().map(|p| vec![p.start_record()]).collect();
    let mut pipeline_s = 0.0;
    let mut out_frames = Vec::new();
    let mut acc = vec![0u32; n_px];
    for t in 0..planes {
        let a = Instant::now();
        let plane = sim.next_plane();
        let b = Instant::now();
        simulate_s += (b - a).as_secs_f64();
        if !pipes.is_empty() {
            for (p, out) in pipes.iter_mut().zip(streams.iter_mut()) {
                out.extend(p.push_plane(&plane)?);
            }
            pipeline_s += b.elapsed().as_secs_f64();
        }
        if frames {
            for (wi, &word) in plane.words().iter().enumerate() {
                let mut bits = word;
                while bits != 0 {
                    let i = wi * 64 + bits.trailing_zeros() as usize;
                    if i < n_px {
                        acc[i] += 1;
                    }
                    bits &= bits - 1;
                }
            }
            if (t + 1) % FIXED_FRAME_PLANES == 0 {
                out_frames.push(std::mem::replace(&mut acc, vec![0u32; n_px]));
            }
        }
    }
    let mut data = SpadData {
        frames: out_frames,
        hot: sim.maps().hot.clone(),
        masked: mask.is_some(),
        gain,
        planes,
        simulate_s,
        ..Default::default()
    };
    let a = Instant::now();
    for (mut p, mut out) in pipes.into_iter().zip(streams) {
        out.extend(p.finish());
        let (recs, bytes) = through_packets(&out)?;
        data.records.push(recs);
        data.packet_bytes += bytes;
    }
    data.pipeline_s = pipeline_s + a.elapsed().as_secs_f64();
    Ok(data)
}

/// Frames of an EMCCD or sCMOS in photon units (photo-electrons) and what
/// the fit knows about their pixels.
#[derive(Debug, Clone, Default)]
pub struct FrameData {
    /// One frame per 50 ms, raster order.
    pub frames: Vec<Vec<f64>>,
    /// sCMOS read variance (e⁻²); empty for the EMCCD.
    pub maps: FrameMaps,
    /// Wall time in the simulator, s.
    pub simulate_s: f64,
}

/// Simulates `end_s` of EMCCD or sCMOS frames of `setup` watching `blinks`.
///
/// ADU become photo-electrons with the camera's calibration, as a user
/// would convert them: EMCCD `(ADU − offset)·e_per_adu / gain`; sCMOS
/// `(ADU − offset_i) / gain_i` with the per-pixel maps, whose read-noise
/// variance goes to the sCMOS likelihood.
pub fn record_frames(
    setup: &Setup,
    blinks: &[BlinkNm],
    end_s: f64,
    seed: u64,
) -> Result<FrameData, StudyError> {
    let scene = setup.scene(blinks);
    let t0 = Instant::now();
    let mut out = FrameData::default();
    match &setup.preset.camera {
        Camera::Emccd(c) => {
            let mut sim = EmccdSimulator::new(c, &scene, seed)?;
            let n = (end_s / c.frame_period_s).round() as usize;
            let k = c.e_per_adu / c.em_gain;
            for _ in 0..n {
                let f = sim.next_frame();
                out.frames.push(
                    f.adu
                        .iter()
                        .map(|&a| (a as f64 - c.offset_adu) * k)
                        .collect(),
                );
            }
        }
        Camera::Scmos(c) => {
            let mut sim = ScmosSimulator::new(c, &scene, seed)?;
            let n = (end_s / c.frame_period_s).round() as usize;
            let maps = sim.maps().clone();
            for _ in 0..n {
                let f = sim.next_frame();
                out.frames.push(
                    f.adu
                        .iter()
                        .enumerate()
                        .map(|(i, &a)| (a as f64 - maps.offset_adu[i]) / maps.gain_adu_per_e[i])
                        .collect(),
                );
            }
            out.maps.read_var = maps.read_noise_e.iter().map(|r| r * r).collect();
        }
        Camera::Spad(_) => unreachable!("record_frames on a SPAD setup"),
    }
    out.simulate_s = t0.elapsed().as_secs_f64();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timeline::{place, Timeline};

    #[test]
    fn presets_give_the_papers_windows() {
        let n = |p, o| Setup::new(p, o).unwrap().spad.unwrap().1.n_window;
        assert_eq!(n(PresetName::Spcimager, 150), 109);
        assert_eq!(n(PresetName::Spcimager, 60), 65);
        assert_eq!(n(PresetName::SpcimagerProjected, 150), 18);
        assert!(Setup::new(PresetName::Emccd, 150).unwrap().spad.is_none());
    }

    #[test]
    fn the_smart_scheme_is_the_field_design_and_the_papers_stays_literal() {
        let s = Setup::new(PresetName::Spcimager, 150).unwrap();
        let (det, cfg) = s.spad.clone().unwrap();
        let d = s.design.clone().unwrap();
        // The model's design of the 32x32 study field at 10 kHz, as
        // `aggregate` makes it for such a recording.
        let direct = field_design::design(&det, 32, 32, 1e4, DEFAULT_FALSE_BLINKS_PER_S).unwrap();
        assert_eq!(d, direct);
        assert_eq!(
            (
                u64::from(cfg.threshold_int),
                u64::from(cfg.threshold_hold),
                cfg.r_assoc,
                cfg.l_min,
                cfg.end_trim
            ),
            (
                d.threshold_open,
                d.threshold_hold,
                d.r_assoc,
                d.l_min,
                d.end_trim
            )
        );
        assert_eq!(u64::from(cfg.threshold_hold), det.threshold_int);
        assert!(cfg.threshold_int > cfg.threshold_hold);
        assert_eq!(
            (cfg.end_trim, cfg.r_assoc, cfg.l_min),
            (det.n_window / 2, 3, 1)
        );
        assert_eq!((cfg.roi_size, cfg.plane_period_ns), (ROI_SIDE, 100_000));
        let paper = s.paper.clone().unwrap();
        let literal = |p: &PipelineConfig| {
            assert_eq!(
                (
                    u64::from(p.threshold_int),
                    u64::from(p.threshold_hold),
                    p.l_min,
                    p.r_assoc,
                    p.end_trim
                ),
                (det.threshold_int, det.threshold_int, 1, 1, 0)
            );
            assert_eq!(
                (&p.kernel, p.n_window, p.roi_size),
                (&cfg.kernel, cfg.n_window, cfg.roi_size)
            );
        };
        literal(&paper);
        // The study's overrides change the smart scheme only.
        let o = s.with_pipeline(LMin::Planes(150), Some(2)).unwrap();
        let c = &o.spad.as_ref().unwrap().1;
        assert_eq!((c.l_min, c.r_assoc, c.l_max), (150, 2, cfg.l_max.max(150)));
        assert_eq!(c.threshold_int, cfg.threshold_int);
        literal(o.paper.as_ref().unwrap());
        let same = Setup::new(PresetName::Spcimager, 150)
            .unwrap()
            .with_pipeline(LMin::Design, None)
            .unwrap();
        assert_eq!(same.spad.unwrap().1, cfg);
    }

    #[test]
    fn a_long_blink_gives_a_record_near_it_through_the_packet_path() {
        let s = Setup::new(PresetName::Spcimager, 150).unwrap();
        let t = Timeline::one_at_a_time(3, 3, 0.08);
        let blinks = place(&t.blinks, s.field_nm(), s.margin_nm);
        let cfg = s.spad.as_ref().unwrap().1.clone();
        let d = record_spad(
            &s,
            &blinks,
            t.end_s,
            11,
            std::slice::from_ref(&cfg),
            true,
            None,
        )
        .unwrap();
        assert_eq!(d.planes, (t.end_s / 1e-4).round() as u64);
        assert_eq!(d.frames.len() as u64, d.planes / 500);
        assert!(d.packet_bytes > 0);
        for b in &blinks {
            let near = d.records[0].iter().any(|r| {
                let p = record_planes(r, &cfg);
                let (first, last) = (p.start as f64 * 1e-4, p.end as f64 * 1e-4);
                let (ax, ay) = (
                    (r.anchor_x as f64 + 0.5) * s.pixel_nm,
                    (r.anchor_y as f64 + 0.5) * s.pixel_nm,
                );
                first < b.t_off_s
                    && last > b.t_on_s
                    && (ax - b.x_nm).abs() < 2.0 * s.pixel_nm
                    && (ay - b.y_nm).abs() < 2.0 * s.pixel_nm
            });
            assert!(near, "no record for {b:?}");
        }
        // Fixed frames hold every detection of the planes.
        let total: u64 = d.frames.iter().flatten().map(|&c| c as u64).sum();
        assert!(total > 0);
    }
}
