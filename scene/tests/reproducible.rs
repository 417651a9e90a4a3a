//! Seeds reproduce bit-identical output; different seeds differ.

use smartagg_io::stack::StackWriter;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::recording::{BitOrder, RecordingWriter};
use smartagg_scene::{truth, EmccdSimulator, Scene, ScmosSimulator, SpadSimulator};

fn spad_bytes(seed: u64) -> (Vec<u8>, Vec<u8>) {
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(cam) = &p.camera else {
        unreachable!()
    };
    let mut sc = Scene::nanorulers(&p).with_field(64, 48);
    // Dense enough to have blinks in 2,000 planes.
    sc.layout = smartagg_scene::Layout::gatta_paint_80g(40.0);
    sc.intensity_cv = 0.3;
    let mut sim = SpadSimulator::new(cam, &sc, seed).unwrap();
    let planes = 2000;
    let mut w =
        RecordingWriter::new(Vec::new(), sim.recording_header(planes, BitOrder::LsbFirst)).unwrap();
    for _ in 0..planes {
        w.write_plane(&sim.next_plane()).unwrap();
    }
    let mut t = Vec::new();
    truth::write_csv(&mut t, sim.truth()).unwrap();
    assert!(sim.truth().len() > 3, "{} blinks", sim.truth().len());
    (w.finish().unwrap(), t)
}

#[test]
fn spad_recordings_and_truth_are_bit_identical_per_seed() {
    let a = spad_bytes(1);
    let b = spad_bytes(1);
    let c = spad_bytes(2);
    assert_eq!(a.0, b.0);
    assert_eq!(a.1, b.1);
    assert_ne!(a.0, c.0);
    assert_ne!(a.1, c.1);
}

fn frame_bytes(preset: PresetName, seed: u64) -> (Vec<u8>, Vec<u8>) {
    let p = Preset::new(preset, 150).unwrap();
    let sc = Scene::study(&p, 0.03);
    let mut tif = std::io::Cursor::new(Vec::new());
    let mut w = StackWriter::new(&mut tif, sc.width, sc.height).unwrap();
    let truth_rows: Vec<smartagg_scene::BlinkTruth> = match &p.camera {
        Camera::Emccd(c) => {
            let mut sim = EmccdSimulator::new(c, &sc, seed).unwrap();
            for _ in 0..20 {
                w.write_frame(&sim.next_frame().adu).unwrap();
            }
            sim.truth().to_vec()
        }
        Camera::Scmos(c) => {
            let mut sim = ScmosSimulator::new(c, &sc, seed).unwrap();
            for _ in 0..20 {
                w.write_frame(&sim.next_frame().adu).unwrap();
            }
            sim.truth().to_vec()
        }
        Camera::Spad(_) => unreachable!(),
    };
    assert_eq!(w.frames(), 20);
    let mut t = Vec::new();
    truth::write_csv(&mut t, &truth_rows).unwrap();
    (tif.into_inner(), t)
}

#[test]
fn frame_stacks_are_bit_identical_per_seed() {
    for preset in [PresetName::Emccd, PresetName::Scmos] {
        let a = frame_bytes(preset, 10);
        assert_eq!(a, frame_bytes(preset, 10), "{preset}");
        let c = frame_bytes(preset, 11);
        assert_ne!(a.0, c.0, "{preset}");
        assert_ne!(a.1, c.1, "{preset}");
    }
}

#[test]
fn the_blink_timeline_does_not_depend_on_the_camera() {
    // Same seed, same field in nm: 64 SPAD pixels of 53.3 nm = 32 EMCCD
    // pixels of 106.7 nm at 150x.
    let ps = Preset::new(PresetName::Spcimager, 150).unwrap();
    let pe = Preset::new(PresetName::Emccd, 150).unwrap();
    let ss = Scene::smlm(&ps).with_field(64, 64);
    let se = Scene::smlm(&pe).with_field(32, 32);
    let (Camera::Spad(cs), Camera::Emccd(ce)) = (&ps.camera, &pe.camera) else {
        unreachable!()
    };
    let spad = SpadSimulator::new(cs, &ss, 5).unwrap();
    let emccd = EmccdSimulator::new(ce, &se, 5).unwrap();
    assert_eq!(spad.emitters().len(), emccd.emitters().len());
    assert!(!spad.emitters().is_empty());
    for (a, b) in spad.emitters().iter().zip(emccd.emitters()) {
        assert!((a.x_nm - b.x_nm).abs() < 1e-9 && (a.y_nm - b.y_nm).abs() < 1e-9);
    }
}
