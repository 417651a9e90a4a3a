//! The generated designs of `smartagg_hdl::designs`: every (preset,
//! objective) generates, its widths match its type, its kernel is the
//! model's; the SPCImager 150× top passes Verilator lint with its generated
//! `top.vlt` (all four are linted by `tests/verilog.rs` and by `cargo run -p
//! smartagg-hdl --release --example resources -- lint`).

use smartagg_hdl::designs::{text_hash, DelayLineKind, Design, TopKind};
use smartagg_hdl::device::{XC6SLX150, XC6SLX45};
use smartagg_hdl::synth::verilator_lint;
use smartagg_model::field_design;
use smartagg_model::params::{Preset, PresetName};
use smartagg_model::stats::{self, DetectionInputs};

#[test]
fn every_design_generates_and_the_spcimager_150x_top_passes_verilator_lint() {
    let designs = Design::all().unwrap();
    assert_eq!(designs.len(), 4);
    for d in &designs {
        let det = stats::derive(
            &DetectionInputs::from_preset(&Preset::new(d.preset, d.objective).unwrap(), None)
                .unwrap(),
        )
        .unwrap();
        // Kernel constants, ROI side and N_max follow from the model.
        assert_eq!(d.config.front.kernel, det.kernel_weights, "{}", d.name());
        assert_eq!(d.config.front.kernel_shift, det.kernel_shift);
        assert_eq!(d.config.roi_size, det.kernel_size);
        assert!(det.n_window <= d.config.front.n_max, "{}", d.name());
        // The detection follows the field design: open and hold levels and
        // the end trim (register defaults) and the association radius
        // (generated).
        let preset = Preset::new(d.preset, d.objective).unwrap();
        let (w, h) = preset.camera.size();
        let fd = field_design::design(
            &det,
            w,
            h,
            1.0 / preset.period_s(),
            field_design::DEFAULT_FALSE_BLINKS_PER_S,
        )
        .unwrap();
        assert_eq!(d.threshold_int, fd.threshold_open, "{}", d.name());
        assert_eq!(d.threshold_hold, fd.threshold_hold, "{}", d.name());
        // The END_TRIM default: the field design's ⌊N/2⌋ (a dropped
        // segment sums up to its estimated end), within 0 ..= N − 1.
        assert_eq!(d.end_trim, fd.end_trim, "{}", d.name());
        assert!(d.end_trim < d.n_window, "{}", d.name());
        assert_eq!(d.config.r_assoc, fd.r_assoc, "{}", d.name());
        assert!(
            1 <= d.threshold_hold && d.threshold_hold <= d.threshold_int,
            "{}",
            d.name()
        );
        // The delay line stays on chip exactly when it takes at most half the block RAM.
        let on_chip = 2 * d.delay_line_bits() <= d.device.block_ram_bits();
        assert_eq!(
            on_chip,
            d.delay_line == DelayLineKind::BlockRam,
            "{}",
            d.name()
        );
        let v = d.verilog().unwrap_or_else(|e| panic!("{}: {e}", d.name()));
        assert!(v.contains("module top("), "{}", d.name());
        // Both tops are the board's: FrontPanel endpoints, the UCF's pins.
        assert!(v.contains("module okHost("), "{}", d.name());
        assert!(d.ucf().contains("okUH"));
        match d.top {
            TopKind::Xem6310 => {
                assert!(v.contains("smartagg_mig mig("), "{}", d.name());
                assert!(!v.contains("smartagg_ddr2_parked"), "{}", d.name());
            }
            TopKind::Xem6310OnChip => {
                assert!(v.contains("smartagg_ddr2_parked parked("), "{}", d.name());
                assert!(!v.contains("smartagg_mig mig("), "{}", d.name());
            }
        }
        // Generation is deterministic: the hash names the file.
        assert_eq!(text_hash(&v), text_hash(&d.verilog().unwrap()));
        if d.name() != "spcimager-150x" {
            continue;
        }
        let dir = std::env::temp_dir().join(format!(
            "smartagg-hdl-cfg-{}-{}",
            d.name(),
            std::process::id()
        ));
        if let Err(e) = verilator_lint(&v, &dir) {
            panic!("{}: {e}", d.name());
        }
        let _ = std::fs::remove_dir_all(dir);
    }
    let spc = Design::new(PresetName::Spcimager, 150).unwrap();
    assert_eq!(
        (spc.device, spc.delay_line),
        (XC6SLX45, DelayLineKind::Ddr2)
    );
    let proj = Design::new(PresetName::SpcimagerProjected, 150).unwrap();
    assert_eq!(
        (proj.device, proj.delay_line),
        (XC6SLX150, DelayLineKind::BlockRam)
    );
}
