//! Every shipped configuration on its full 320×240 field through its
//! XEM6310 core, byte for byte against the golden model, in CI.
//!
//! The SPCImager 150× field for 2,000 bit-planes:
//! the Verilated gateware (XEM6310 core, DDR2 delay line) against the
//! golden model, byte for byte, with the planes fed through the sensor port
//! at up to a word of P = 16 pixels every clock (10 % of the clocks
//! skipped at random), so a bit-plane takes ≈ W·H/P / 0.9 ≈ 5,300 clocks
//! (W·H/P = 4,800). The registers and the association radius are the
//! shipped design's defaults, the field design's (`smartagg_hdl::designs::
//! Design`: N, T_open, T_hold < T_open, END_TRIM = ⌊N/2⌋, r_assoc,
//! L_min = 1), so the hysteresis and the trimmed sums of the full field
//! are what runs. Prints the
//! coverage counters, clocks per bit-plane and simulated cycles per second
//! (speed is printed, never asserted).

use smartagg_hdl::designs::{DelayLineKind, Design};
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

/// The scene's planes, then [`QUIET`] background-only planes: no track is
/// left live at STOP (the back half's stream end with many live tracks is
/// the reduced cases' concern).
fn with_quiet_end(scene: &SceneSpec, seed: u64) -> Vec<smartagg_model::plane::BitPlane> {
    let mut planes = generate(scene, seed);
    planes.extend(generate(
        &SceneSpec {
            planes: QUIET,
            emitters: 0,
            ..scene.clone()
        },
        seed ^ 1,
    ));
    planes
}

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
    let planes = with_quiet_end(&scene, seed);
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

/// A shipped configuration on its full field with its design's register
/// defaults (the field design's N, T_open, T_hold, END_TRIM, r_assoc;
/// L_min = 1), `planes` bit-planes of a sparse SMLM scene with two hot
/// pixels masked, through `source`: the packets must equal the model's byte
/// for byte. Prints the coverage, clocks per bit-plane and simulated cycles
/// per second.
fn shipped_full_field(config: Config, planes: usize, source: Source, seed: u64) {
    let (w, h) = FULL;
    let design = config.shipped().expect("the shipped design");
    assert_eq!(
        (design.config.front.width, design.config.front.height),
        FULL,
        "{}: the sensor's field",
        config.name()
    );
    let spec = DesignSpec::new(config, w, h)
        .and_then(|s| s.with_r_assoc(design.config.r_assoc))
        .expect("full-field design");
    assert_eq!(spec.back().expect("back half"), design.config);
    assert_eq!(spec.ddr(), design.delay_line == DelayLineKind::Ddr2);
    let mut c = Cosim::new(spec).expect("verilated full-field design");
    c.set_sensor_interval(2);
    let hot = vec![(17, 200), (300, 3)];
    let scene = SceneSpec {
        width: w,
        height: h,
        planes: planes - QUIET,
        background: 0.0008,
        emitters: 40,
        peak: 0.5,
        mean_on: 3.0 * design.n_window as f64,
        mean_off: 4.0 * design.n_window as f64,
        edge_fraction: 0.15,
        dip: 0.05,
        hot: hot.clone(),
        hot_rate: 0.3,
    };
    let stream = with_quiet_end(&scene, seed);
    let case = Case {
        hot,
        mask_enable: true,
        source,
        input_stall: 5,
        read_stall: 20,
        hold_reads: false,
        seed,
        ..Case::design_defaults(&design, stream)
    };
    let cov = match c.check(&case).expect("co-simulation ran") {
        Ok(cov) => cov,
        Err(m) => panic!("{} full field, {planes} planes: {m}", config.name()),
    };
    println!(
        "{} full field {w}x{h} ({}, N {}, T_open {}, T_hold {}, END_TRIM {}, r_assoc {}), {planes} bit-planes through the {}: {cov}\n  \
         {:.0} clocks per bit-plane ({} words of P = {P} pixels), {:.3} M simulated clock cycles/s",
        config.name(),
        if design.delay_line == DelayLineKind::Ddr2 { "DDR2 delay line" } else { "block-RAM delay line" },
        case.n,
        case.threshold,
        case.hold(),
        case.end_trim,
        design.config.r_assoc,
        match source {
            Source::Replay => "replay pipe-in",
            Source::Sensor => "sensor port",
        },
        cov.clocks_per_plane(),
        w * h / P,
        cov.mcycles_per_second()
    );
    assert_eq!(cov.planes as usize, planes);
    assert!(cov.confirmed_blinks > 0, "confirmed blinks: {cov}");
    assert!(cov.edge_rois > 0, "edge ROIs: {cov}");
    if design.delay_line == DelayLineKind::Ddr2 {
        assert!(cov.refresh_collisions > 0, "DDR2 refresh collisions: {cov}");
    }
}

#[test]
fn spcimager60_full_field_equals_the_model() {
    shipped_full_field(Config::Spcimager60, 500, Source::Replay, 60);
}

#[test]
fn projected150_full_field_equals_the_model() {
    shipped_full_field(Config::Projected150, 300, Source::Sensor, 150);
}

#[test]
fn projected60_full_field_equals_the_model() {
    shipped_full_field(Config::Projected60, 300, Source::Replay, 61);
}
