//! Verilog generation: Verilator lint (-Wall with the documented waivers)
//! and a yosys Spartan-6 synthesis of the test configuration's front half.
//! The tools are required: a missing tool fails with an install hint.

use smartagg_hdl::front_half::{
    spcimager150_config, test_front_half_verilog, verilog, Spcimager150FrontHalf,
};
use smartagg_hdl::synth::{verilator_lint, yosys_resources};

fn scratch(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("smartagg-hdl-{name}-{}", std::process::id()))
}

#[test]
fn generated_verilog_passes_verilator_lint() {
    let v = test_front_half_verilog().unwrap();
    assert!(v.contains("module top("));
    let dir = scratch("lint");
    if let Err(e) = verilator_lint(&v, &dir) {
        panic!("{e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn spcimager_150x_verilog_passes_verilator_lint() {
    let v = verilog(Spcimager150FrontHalf::new(&spcimager150_config()).unwrap());
    let dir = scratch("lint150");
    if let Err(e) = verilator_lint(&v, &dir) {
        panic!("{e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn yosys_maps_the_test_front_half_to_spartan6() {
    let v = test_front_half_verilog().unwrap();
    let dir = scratch("yosys");
    let r = yosys_resources(&v, &dir).unwrap_or_else(|e| panic!("{e}"));
    let _ = std::fs::remove_dir_all(dir);
    // Shift-and-add constant multipliers: no DSP slice.
    assert_eq!(r.dsp48a1, 0, "{r:?}");
    // The delay line (7 planes x 96 bits) and the counter memory are memories, not flip-flops.
    assert!(r.ramb8 + r.ramb16 + r.lutram > 0, "{r:?}");
    assert!(r.luts > 100 && r.ffs > 100, "{r:?}");
}
