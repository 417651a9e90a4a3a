//! The full 320×240 SPCImager 150× field for 2,000 bit-planes, in CI:
//! the Verilated gateware (XEM6310 core, DDR2 delay line) against the
//! golden model, byte for byte, with the planes fed through the sensor port
//! at up to a word of P = 16 pixels every clock (10 % of the clocks
//! skipped at random), so a bit-plane takes ≈ W·H/P / 0.9 ≈ 5,300 clocks
//! (W·H/P = 4,800). The registers and the association radius are the
//! shipped design's defaults, the field design's (`smartagg_hdl::configs::
//! Design`: N, T_open, T_hold < T_open, END_TRIM = ⌊N/2⌋, r_assoc,
//! L_min = 1), so the hysteresis and the trimmed sums of the full field
//! are what runs. Prints the
//! coverage counters, clocks per bit-plane and simulated cycles per second
//! (speed is printed, never asserted).

use smartagg_hdl::configs::Design;
use smartagg_model::params::PresetName;
use smartagg_sim::designs::{Config, DesignSpec, FULL, P};
use smartagg_sim::harness::{Case, Cosim, Source};
use smartagg_sim::scene::{generate, SceneSpec};

/// Bit-planes of the run (issue 7: at least 2,000 on the full field).
const PLANES: usize = 2_000;
/// Of those, background-only bit-planes at the end.
const QUIET: usize = 40;
/// Percent of the source's clocks skipped.
const STALL: u32 = 10;

#[test]
fn spcimager150_full_field_2000_planes_at_near_a_word_per_clock_equals_the_model() {
    let (w, h) = FULL;
    let design = Design::new(PresetName::Spcimager, 150).expect("the shipped design");
    assert!(
        design.threshold_hold < design.threshold_int,
        "the field design has hysteresis: T_hold {} < T_open {}",
        design.threshold_hold,
        design.threshold_int
    );
    assert!(
        design.end_trim > 0 && design.end_trim == design.n_window / 2,
        "the field design trims the sums to t_e: END_TRIM {} of N {}",
        design.end_trim,
        design.n_window
    );
    let spec = DesignSpec::new(Config::Spcimager150, w, h)
        .and_then(|s| s.with_r_assoc(design.config.r_assoc))
        .expect("full-field design");
    assert_eq!(
        spec.back().expect("back half"),
        design.config,
        "the shipped generation"
    );
    let mut c = Cosim::new(spec).expect("verilated full-field design");
    c.set_sensor_interval(1);
    let hot = vec![(17, 200), (300, 3)];
    let seed = 7_2026;
    let scene = SceneSpec {
        width: w,
        height: h,
        planes: PLANES - QUIET,
        background: 0.0008,
        emitters: 80,
        peak: 0.4,
        mean_on: 12.0,
        mean_off: 60.0,
        edge_fraction: 0.15,
        dip: 0.08,
        hot: hot.clone(),
        hot_rate: 0.3,
    };
    let mut planes = generate(&scene, seed);
    // Background only at the end: no track left live at STOP (the back
    // half's stream end with many live tracks is the reduced cases' concern).
    planes.extend(generate(
        &SceneSpec {
            planes: QUIET,
            emitters: 0,
            ..scene.clone()
        },
        seed ^ 1,
    ));
    let case = Case {
        hot,
        mask_enable: true,
        source: Source::Sensor,
        // 10 % of the source's clocks skipped: at exactly a word every
        // clock the DDR2 delay line's write FIFO fills within two bit-planes
        // (FAULT, reported to hdl); the sensor's own duty cycle is a word
        // every other clock.
        input_stall: STALL,
        read_stall: 20,
        hold_reads: false,
        seed,
        ..Case::design_defaults(&design, planes)
    };
    let cov = match c.check(&case).expect("co-simulation ran") {
        Ok(cov) => cov,
        Err(m) => panic!("full field, {PLANES} planes: {m}"),
    };
    let wpp = (w * h / P) as f64;
    println!(
        "full field {w}x{h}, {PLANES} bit-planes through the sensor port: {cov}\n  \
         {:.0} clocks per bit-plane ({wpp} words of P = {P} pixels), {:.3} M simulated clock cycles/s",
        cov.clocks_per_plane(),
        cov.mcycles_per_second()
    );
    assert_eq!(cov.planes as usize, PLANES);
    assert!(cov.confirmed_blinks > 0, "confirmed blinks: {cov}");
    assert!(cov.edge_rois > 0, "edge ROIs: {cov}");
    assert!(cov.refresh_collisions > 0, "DDR2 refresh collisions: {cov}");
    // The pipeline keeps up with the source: no more than a few percent
    // over the source's W·H/P words at 90 % of the clocks per bit-plane
    // (the stream's start, DDR2 refreshes the delay line absorbs), plus the
    // stream end's N drain planes and flush plane, spread over the run.
    let cpp = cov.clocks_per_plane();
    let source = wpp / (1.0 - STALL as f64 / 100.0);
    let drain = (case.n as f64 + 1.0) * wpp / PLANES as f64;
    assert!(
        cpp >= wpp && cpp < source * 1.05 + drain,
        "{cpp:.0} clocks per bit-plane, {wpp} words per bit-plane, {source:.0} at the source's rate, {drain:.0} of drain"
    );
}
