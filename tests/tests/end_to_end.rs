//! The chain across crates, as a user runs it: the scene simulator's
//! bit-planes (`smartagg-scene`) → the golden pipeline with the field design
//! of the model (`smartagg-model`) → packets → the host's decoder → the SPAD
//! binomial MLE (`smartagg-localize`), checked against the known position of
//! the molecule.

use smartagg_localize::table::Localization;
use smartagg_localize::{fit_binomial, FitOptions, SigmaMode, SpadRoi};
use smartagg_model::config::PipelineConfig;
use smartagg_model::field_design;
use smartagg_model::packet::{decode_all, Encoder};
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::pipeline::Pipeline;
use smartagg_model::record::Record;
use smartagg_model::stats::{self, DetectionInputs};
use smartagg_scene::scene::{Blinking, Layout, OnTime, Position, Scene};
use smartagg_scene::spad::SpadSimulator;

#[test]
fn one_blinking_molecule_is_found_where_it_is() {
    let preset = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(cam) = &preset.camera else {
        panic!("the SPCImager is a SPAD camera")
    };
    let (w, h) = (24u32, 24u32);
    let px = preset.pixel_nm();
    // Off the pixel grid on purpose.
    let truth = Position {
        x_nm: 11.3 * px,
        y_nm: 12.6 * px,
    };
    let scene = Scene {
        layout: Layout::List(vec![truth]),
        blinking: Blinking::Independent {
            on: OnTime::Exponential { mean_s: 0.040 },
            mean_off_s: 0.15,
        },
        ..Scene::nanorulers(&preset).with_field(w, h)
    };

    // The model's design for this field, as `smartagg aggregate` derives it.
    let det = stats::derive(&DetectionInputs::from_preset(&preset, None).unwrap()).unwrap();
    let rate = 1.0 / cam.plane_period_s;
    let d = field_design::design(&det, w, h, rate, 1.0).unwrap();
    let mut cfg = PipelineConfig::new(
        w as usize,
        h as usize,
        det.n_window,
        det.kernel_weights.clone(),
        det.kernel_shift,
        d.threshold_open as u32,
    );
    cfg.threshold_hold = d.threshold_hold as u32;
    cfg.r_assoc = d.r_assoc;
    cfg.l_min = d.l_min;
    cfg.plane_period_ns = (cam.plane_period_s * 1e9).round() as u32;

    // 3 s of bit-planes through the golden pipeline, encoded as packets.
    let planes = (3.0 * rate) as u64;
    let mut sim = SpadSimulator::new(cam, &scene, 5).unwrap();
    let mut pipe = Pipeline::new(cfg).unwrap();
    let mut enc = Encoder::new();
    let mut bytes = Vec::new();
    let mut sent = vec![pipe.start_record()];
    for _ in 0..planes {
        sent.extend(pipe.push_plane(&sim.next_plane()).unwrap());
    }
    sent.extend(pipe.finish());
    for r in &sent {
        enc.push(r, &mut bytes).unwrap();
    }

    // The host's decoder gives back exactly the records, nothing lost.
    let decoded = decode_all(&bytes);
    assert!(!decoded.stats.any_loss(), "{}", decoded.stats);
    let got: Vec<Record> = decoded.packets.into_iter().map(|p| p.record).collect();
    assert_eq!(got, sent);
    let Some(Record::End(end)) = got.last() else {
        panic!("the stream ends with StreamEnd")
    };
    assert_eq!(end.planes, planes);

    // Localise every blink; they must sit on the molecule.
    let opts = FitOptions::new(SigmaMode::Fitted {
        initial: preset.sigma_px(),
    });
    let mut errors: Vec<f64> = Vec::new();
    for (i, r) in got.iter().enumerate() {
        let Record::Blink(b) = r else { continue };
        let roi = SpadRoi::from_record(b, None).unwrap();
        let fit = fit_binomial(&roi, &opts);
        let loc = Localization::from_fit(&fit, b.roi_x0() as f64, b.roi_y0() as f64, px, i as u64);
        errors.push((loc.x_nm - truth.x_nm).hypot(loc.y_nm - truth.y_nm));
    }
    // About 3 s / (40 + 150) ms ≈ 16 blinks, most longer than L_min.
    assert!(
        errors.len() >= 5,
        "only {} blink records in {planes} planes",
        errors.len()
    );
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    assert!(
        median < 0.5 * px,
        "median localisation error {median:.1} nm (pixel {px:.1} nm): {errors:?}"
    );
}
