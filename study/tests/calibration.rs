//! A calibrated sensor in the study: its maps are what the SPCImager
//! configurations simulate, its hot pixels are masked where they fall.

use smartagg_model::params::PresetName;
use smartagg_model::record::flags;
use smartagg_model::sensor_maps::SensorMaps;
use smartagg_study::acquisition::{record_spad, Setup};
use smartagg_study::sensor::{CalibratedSensor, SensorCalibration};
use smartagg_study::spec::{LMin, StudyOptions};
use smartagg_study::timeline::{place, Timeline};
use smartagg_study::{Plan, StudyName};
use std::sync::{Arc, Mutex};

const HOT_HZ: f64 = 200_000.0;

fn is_lattice_hot(x: u32, y: u32) -> bool {
    (x * 7 + y * 3).is_multiple_of(23)
}

/// A 320×240 sensor: 100 Hz, a lattice of 200 kHz pixels, a PRNU gradient;
/// the criterion says 50 kHz for every N, T and records what it was asked.
fn calibration(asked: Arc<Mutex<Vec<(u32, u64)>>>) -> SensorCalibration {
    let (w, h) = (320u32, 240u32);
    let mut dcr = Vec::new();
    let mut prnu = Vec::new();
    for y in 0..h {
        for x in 0..w {
            dcr.push(if is_lattice_hot(x, y) { HOT_HZ } else { 100.0 });
            prnu.push(0.8 + 0.4 * x as f64 / w as f64);
        }
    }
    SensorCalibration {
        id: "test-sensor (CRC 0)".into(),
        sensor: Some(Arc::new(CalibratedSensor {
            maps: SensorMaps {
                width: w,
                height: h,
                dcr_hz: dcr,
                prnu: Some(prnu),
                hot: vec![false; (w * h) as usize],
            },
            critical_dcr: Box::new(move |n, t| {
                asked.lock().unwrap().push((n, t));
                Ok(Some(50_000.0))
            }),
        })),
    }
}

#[test]
fn the_calibrated_hot_pixels_are_simulated_and_masked_at_the_items_crop() {
    let asked = Arc::new(Mutex::new(Vec::new()));
    let cal = calibration(asked.clone());
    let s = Setup::new(PresetName::Spcimager, 150)
        .unwrap()
        .with_pipeline(LMin::Planes(1), None)
        .unwrap()
        .with_sensor(Some(&cal))
        .unwrap();
    let cfg = s.spad.as_ref().unwrap().1.clone();
    assert_eq!(
        asked.lock().unwrap().as_slice(),
        &[(cfg.n_window, u64::from(cfg.threshold_hold))],
        "the criterion is asked for this configuration's N and hold level"
    );
    // The field design's hold level is the paper's one threshold.
    assert_eq!(cfg.threshold_hold, s.paper.as_ref().unwrap().threshold_int);
    assert!(cfg.threshold_int > cfg.threshold_hold);
    let sensor = s.sensor.as_ref().expect("SPCImager takes the calibration");
    assert_eq!(sensor.critical_dcr_hz, Some(50_000.0));

    let t = Timeline::one_at_a_time(2, 5, 0.05);
    let blinks = place(&t.blinks, s.field_nm(), s.margin_nm);
    let seed = 77;
    let d = record_spad(
        &s,
        &blinks,
        t.end_s,
        seed,
        std::slice::from_ref(&cfg),
        true,
        None,
    )
    .unwrap();
    // The hot map is the lattice at this item's crop offset.
    let (x0, y0) = sensor.sensor.offset(s.field, seed);
    let f = s.field;
    let expect: Vec<bool> = (0..f * f)
        .map(|i| is_lattice_hot(x0 + i % f, y0 + i / f))
        .collect();
    assert_eq!(d.hot, expect);
    assert!(d.hot.iter().filter(|&&h| h).count() >= 20);
    assert!(d.masked);
    assert_eq!(d.gain.len(), (f * f) as usize);
    assert!((d.gain[0] - (0.8 + 0.4 * x0 as f64 / 320.0)).abs() < 1e-12);
    // Hot pixels fire in ≈ 2 % of the planes: the fixed frames see them...
    let frame_hot: u64 = d.frames[0]
        .iter()
        .zip(&d.hot)
        .filter(|(_, &h)| h)
        .map(|(&c, _)| c as u64)
        .sum();
    assert!(
        frame_hot > 100,
        "hot pixels count in the frames: {frame_hot}"
    );
    // ...the pipeline reads them as 0: every ROI pixel on a hot pixel is 0,
    // and the ROIs that cover one say so.
    let mut masked_records = 0;
    for r in &d.records[0] {
        let side = r.roi_size as i32;
        let mut covers = false;
        for j in 0..side {
            for i in 0..side {
                let (x, y) = (r.roi_x0() + i, r.roi_y0() + j);
                if x < 0 || y < 0 || x >= f as i32 || y >= f as i32 {
                    continue;
                }
                if d.hot[(y as u32 * f + x as u32) as usize] {
                    covers = true;
                    assert_eq!(r.counts[(j * side + i) as usize], 0, "hot pixel summed");
                }
            }
        }
        assert_eq!(covers, r.has(flags::MASKED));
        masked_records += covers as u32;
    }
    assert!(masked_records > 0, "some ROI covers a hot pixel");
}

#[test]
fn other_cameras_keep_their_maps_and_bad_calibrations_are_refused() {
    let cal = calibration(Arc::new(Mutex::new(Vec::new())));
    let p = Setup::new(PresetName::SpcimagerProjected, 150)
        .unwrap()
        .with_sensor(Some(&cal))
        .unwrap();
    assert!(
        p.sensor.is_none(),
        "the projected SPAD is not the calibrated sensor"
    );

    let small = SensorCalibration {
        id: "tiny".into(),
        sensor: Some(Arc::new(CalibratedSensor {
            maps: SensorMaps::uniform(8, 8, 100.0),
            critical_dcr: Box::new(|_, _| Ok(None)),
        })),
    };
    let e = Setup::new(PresetName::Spcimager, 150)
        .unwrap()
        .with_sensor(Some(&small))
        .unwrap_err()
        .to_string();
    assert!(e.contains("8x8") && e.contains("smaller"), "{e}");

    let no_rule = SensorCalibration {
        id: "norule".into(),
        sensor: Some(Arc::new(CalibratedSensor {
            maps: SensorMaps::uniform(64, 64, 100.0),
            critical_dcr: Box::new(|_, _| Err("kernel mismatch".into())),
        })),
    };
    let e = Setup::new(PresetName::Spcimager, 60)
        .unwrap()
        .with_sensor(Some(&no_rule))
        .unwrap_err()
        .to_string();
    assert!(e.contains("kernel mismatch") && e.contains("N = 65"), "{e}");

    let opts = StudyOptions {
        calibration: Some(cal.clone()),
        ..Default::default()
    };
    let e = Plan::new(StudyName::HotPixels, opts.clone())
        .unwrap_err()
        .to_string();
    assert!(e.contains("hot-pixels study"), "{e}");

    // Options read back from a manifest carry the identity only: running
    // them is refused, not silently simulated with synthetic maps.
    let back: StudyOptions = serde_json::from_str(&serde_json::to_string(&opts).unwrap()).unwrap();
    assert_eq!(back.calibration.as_ref().unwrap().id, "test-sensor (CRC 0)");
    assert!(back.calibration.as_ref().unwrap().sensor.is_none());
    let plan = Plan::new(StudyName::SmartVsFixed, back).unwrap();
    let e = smartagg_study::run::run(&plan, smartagg_study::Shard::ALL, &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("not loaded"), "{e}");
}
