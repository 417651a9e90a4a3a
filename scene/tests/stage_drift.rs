//! Stage drift moves every blink by the trajectory at its time, and the truth
//! says where each blink was imaged.

use smartagg_model::params::{spcimager, Preset, PresetName, SceneLight};
use smartagg_scene::{
    Blinking, DriftTrajectory, ExplicitBlink, Layout, Position, Scene, SpadSimulator,
};

/// Mean x (pixels) of the detections of `planes` bit-planes of one blink at
/// the field's centre, seen with `drift`; and the truth.
fn centroid_x(drift: Option<DriftTrajectory>) -> (f64, Vec<smartagg_scene::BlinkTruth>) {
    let cam = spcimager();
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let px = p.pixel_nm();
    let scene = Scene {
        width: 32,
        height: 32,
        optics: p.optics,
        light: SceneLight {
            flux_hz: 200_000.0,
            background_per_um2_hz: 0.0,
        },
        layout: Layout::List(vec![]),
        blinking: Blinking::Explicit(vec![ExplicitBlink {
            emitter: 0,
            position: Position {
                x_nm: 12.0 * px,
                y_nm: 16.0 * px,
            },
            t_on_s: 0.0,
            t_off_s: 0.2,
            flux_factor: 1.0,
        }]),
        intensity_cv: 0.0,
        margin_px: 0.0,
    };
    // No dark counts: every detection is the molecule's.
    let mut maps = smartagg_scene::uniform_maps(&cam, 32, 32);
    maps.dcr_hz.iter_mut().for_each(|d| *d = 0.0);
    let mut sim = SpadSimulator::with_maps(&cam, &scene, maps, 7).unwrap();
    if let Some(d) = drift {
        sim.set_drift(d);
    }
    let (mut sum, mut n) = (0.0, 0.0);
    for _ in 0..2000 {
        for i in sim.next_plane().bits().iter_ones() {
            sum += (i % 32) as f64 + 0.5;
            n += 1.0;
        }
    }
    (sum / n * px, sim.truth().to_vec())
}

#[test]
fn a_drifting_stage_moves_the_blink_and_the_truth_says_by_how_much() {
    let (still, truth0) = centroid_x(None);
    assert_eq!((truth0[0].drift_x_nm, truth0[0].drift_y_nm), (0.0, 0.0));
    // 2000 nm/s for a blink centred at 0.1 s: imaged 200 nm to the right.
    let (moved, truth) = centroid_x(Some(DriftTrajectory::linear(2000.0, 0.0).unwrap()));
    assert!((truth[0].drift_x_nm - 200.0).abs() < 1e-9, "{:?}", truth[0]);
    assert_eq!(
        truth[0].x_nm, truth0[0].x_nm,
        "x_nm stays the sample position"
    );
    let shift = moved - still;
    assert!((shift - 200.0).abs() < 5.0, "centroid moved {shift} nm");
    // No drift asked: the same bit-planes as a simulator never told of drift.
    let (again, _) = centroid_x(Some(DriftTrajectory::none()));
    assert_eq!(again, still);
}
