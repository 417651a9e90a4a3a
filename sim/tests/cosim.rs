//! Co-simulation of the generated Verilog against the golden model: random
//! scenes and registers (proptest, END_TRIM 0 ..= N − 1 included) within
//! each generated configuration on a reduced 64×32 field, directed cases
//! for slot exhaustion, output-FIFO overflow, the summation rule's corners
//! (END_TRIM 0 and N − 1, cuts, the stream end), N = N_max and L_max cuts
//! on purpose; the sensor port, sequence numbers across the 2³² wrap, a
//! wrong MASKED_PIXELS count, and the full 320×240 SPCImager field.
//! Every case's packet bytes must equal the model's (or, with overflow,
//! every surviving packet the model's packet of its sequence number, every
//! gap one exact Overflow record). Coverage counters of what the gateware
//! delivered are printed and asserted non-zero per configuration: each
//! record kind (Dropped: `burst`; Overflow: `directed` with reads held),
//! each flag (CONTINUATION, PREROLL_CLIPPED, L_max cuts, the empty
//! segment continued and the continuation of a cut at the last plane:
//! `cuts_on_purpose`; EDGE, MASKED, TRUNCATED: random and directed cases);
//! the sequence wrap in `sequence_numbers_wrap_as_the_model_numbers_them`.

use proptest::prelude::*;
use proptest::test_runner::{Config as PtConfig, TestCaseError, TestRunner};
use smartagg_model::pipeline::Pipeline;
use smartagg_model::plane::BitPlane;
use smartagg_model::record::{flags, Record};
use smartagg_sim::designs::{Config, DesignSpec, FULL, REDUCED};
use smartagg_sim::harness::{threshold_at_quantile, Case, Cosim, Coverage, Source};
use smartagg_sim::scene::{generate, SceneSpec};

/// Planes per random case on the reduced field.
const PLANES: usize = 480;
/// Random cases per configuration.
const CASES: u32 = 13;

#[derive(Debug, Clone)]
struct Params {
    seed: u64,
    n: u32,
    l_min: u32,
    extra: u32,
    mask_enable: bool,
    input_stall: u32,
    read_stall: u32,
    emitters: usize,
    background: f64,
    quantile: f64,
    edge: f64,
    /// T_hold as a fraction of T_int (1 or more: T_hold = T_int).
    hold: f64,
    /// END_TRIM as a fraction of N (0 or less: 0, the paper's rule).
    trim: f64,
}

fn params(n_max: u32) -> impl Strategy<Value = Params> {
    (
        any::<u64>(),
        1u32..=n_max.min(40),
        1u32..=5,
        0u32..80,
        any::<bool>(),
        0u32..40,
        0u32..70,
        2usize..24,
        0.0005f64..0.01,
        0.985f64..0.999,
        0.0f64..0.5,
        (
            // T_hold from about a third of T_int to T_int (a quarter of the
            // cases at T_int: the one-threshold rule).
            0.3f64..1.25,
            // END_TRIM from 0 (a quarter of the cases) to N − 1.
            -0.33f64..1.0,
        ),
    )
        .prop_map(
            |(
                seed,
                n,
                l_min,
                extra,
                mask_enable,
                input_stall,
                read_stall,
                emitters,
                background,
                quantile,
                edge,
                (hold, trim),
            )| Params {
                seed,
                n,
                l_min,
                extra,
                mask_enable,
                input_stall,
                read_stall,
                emitters,
                background,
                quantile,
                edge,
                hold,
                trim,
            },
        )
}

fn scene(w: usize, h: usize, planes: usize, p: &Params) -> (Vec<BitPlane>, Vec<(usize, usize)>) {
    let hot = vec![
        (
            (p.seed % w as u64) as usize,
            ((p.seed >> 8) % h as u64) as usize,
        ),
        (
            ((p.seed >> 16) % w as u64) as usize,
            ((p.seed >> 24) % h as u64) as usize,
        ),
    ];
    let spec = SceneSpec {
        width: w,
        height: h,
        planes,
        background: p.background,
        emitters: p.emitters,
        peak: 0.4,
        mean_on: 12.0,
        mean_off: 60.0,
        edge_fraction: p.edge,
        dip: 0.08,
        hot: hot.clone(),
        hot_rate: 0.3,
    };
    (generate(&spec, p.seed), hot)
}

fn case_of(
    c: &Cosim,
    planes: Vec<BitPlane>,
    hot: Vec<(usize, usize)>,
    p: &Params,
    source: Source,
) -> Case {
    let mut case = Case {
        n: p.n,
        threshold: 1,
        threshold_hold: None,
        end_trim: trim_of(p.n, p.trim),
        l_min: p.l_min,
        l_max: p.n.max(p.l_min) + p.extra,
        planes,
        hot,
        mask_enable: p.mask_enable,
        source,
        input_stall: p.input_stall,
        read_stall: p.read_stall,
        hold_reads: false,
        seed: p.seed,
    };
    let cfg = c.model_config(&case).expect("model configuration");
    case.threshold = threshold_at_quantile(&cfg, &case.planes, p.quantile);
    case.threshold_hold = Some(hold_of(case.threshold, p.hold));
    case
}

/// END_TRIM at `fraction` of N, within 0 ..= N − 1.
fn trim_of(n: u32, fraction: f64) -> u32 {
    ((n as f64 * fraction.max(0.0)) as u32).min(n - 1)
}

/// T_hold at `fraction` of T_int, within 1 ..= T_int.
fn hold_of(threshold: u32, fraction: f64) -> u32 {
    ((threshold as f64 * fraction.min(1.0)).round() as u32).clamp(1, threshold)
}

/// Runs one case; panics with the named mismatch.
fn check(c: &mut Cosim, case: &Case) -> Result<Coverage, String> {
    let named = |m: String| {
        format!(
            "{m} (case: n {} T {} T_hold {} END_TRIM {} L_min {} L_max {} seed {})",
            case.n,
            case.threshold,
            case.hold(),
            case.end_trim,
            case.l_min,
            case.l_max,
            case.seed
        )
    };
    match c.check(case) {
        Ok(Ok(cov)) => Ok(cov),
        Ok(Err(m)) => Err(named(m.to_string())),
        Err(e) => Err(named(e.to_string())),
    }
}

/// A dense scene for slot exhaustion and, with reads held, output overflow:
/// more emitters on at once than the M = 32 slots. (Records must stay below
/// the packetiser's byte per clock on average: a 64×32 plane is only 256
/// clocks, so a Blink record a plane is the reduced field's sustained limit,
/// and the back half raises FAULT beyond it, as designed.)
fn directed(c: &mut Cosim, seed: u64, hold_reads: bool) -> Coverage {
    let (w, h) = (c.spec.width, c.spec.height);
    let p = Params {
        seed,
        n: 4,
        l_min: 1,
        extra: 60,
        mask_enable: true,
        input_stall: 10,
        read_stall: 0,
        emitters: 50,
        background: 0.002,
        quantile: 0.98,
        edge: 0.3,
        hold: 1.0,
        trim: 0.5,
    };
    let spec = SceneSpec {
        width: w,
        height: h,
        planes: 400,
        background: p.background,
        emitters: p.emitters,
        peak: 0.6,
        mean_on: 40.0,
        mean_off: 20.0,
        edge_fraction: p.edge,
        dip: 0.05,
        hot: vec![(5, 5)],
        hot_rate: 0.5,
    };
    // The stream stops with ~30 tracks live: the stream end truncates them
    // all and emits their Blinks in one burst into a full record queue.
    let planes = generate(&spec, seed);
    let mut case = case_of(c, planes, vec![(5, 5)], &p, Source::Replay);
    case.hold_reads = hold_reads;
    check(c, &case).unwrap_or_else(|e| panic!("{e}"))
}

/// Slot exhaustion in a burst: a quiet scene in which, for four planes, 40
/// bright spots light up at once on an 8×5 grid — more candidates than the
/// M = 32 slots. (A sustained 32 ROIs would exceed the reduced field's ROI
/// sweep rate — a 64×32 plane is only 256 clocks — and the back half would
/// raise FAULT, as designed.)
fn burst(c: &mut Cosim, seed: u64) -> Coverage {
    let (w, h) = (c.spec.width, c.spec.height);
    let p = Params {
        seed,
        n: 3,
        l_min: 2,
        extra: 20,
        mask_enable: false,
        input_stall: 5,
        read_stall: 10,
        emitters: 2,
        background: 0.001,
        quantile: 0.99,
        edge: 0.0,
        hold: 1.0,
        trim: 0.5,
    };
    let (mut planes, hot) = scene(w, h, 160, &p);
    for plane in planes.iter_mut().skip(80).take(4) {
        let old = plane.clone();
        *plane = BitPlane::from_fn(w, h, |x, y| {
            let (gx, gy) = (x % 8, y % 6);
            old.get(x, y) || ((3..=5).contains(&gx) && (2..=4).contains(&gy) && y < 30)
        });
    }
    let mut case = case_of(c, planes, hot, &p, Source::Replay);
    // A threshold the spots cross and the background does not.
    case.threshold_hold = None;
    case.threshold = threshold_at_quantile(&c.model_config(&case).unwrap(), &case.planes, 0.999);
    check(c, &case).unwrap_or_else(|e| panic!("{e}"))
}

/// The summation rule's corners on one scene, with END_TRIM 0 (the
/// paper's) and N − 1: long blinks cut every L_max planes, drops whose
/// last sums come after the stream end (summed from the drain planes),
/// and the stream stopped while tracks are live (TRUNCATED, and the
/// continuation of a cut at the last plane when one falls there). Blinks
/// stay below the reduced field's sustained rate of about one a plane.
fn trim_corners(c: &mut Cosim, seed: u64) -> Coverage {
    let (w, h) = (c.spec.width, c.spec.height);
    let p = Params {
        seed,
        n: 4,
        l_min: 1,
        extra: 6,
        mask_enable: true,
        input_stall: 10,
        read_stall: 10,
        emitters: 6,
        background: 0.001,
        quantile: 0.99,
        edge: 0.2,
        hold: 0.7,
        trim: 0.0,
    };
    let spec = SceneSpec {
        width: w,
        height: h,
        planes: 240,
        background: p.background,
        emitters: p.emitters,
        peak: 0.6,
        mean_on: 40.0,
        mean_off: 30.0,
        edge_fraction: p.edge,
        dip: 0.05,
        hot: vec![(7, 7)],
        hot_rate: 0.3,
    };
    let planes = generate(&spec, seed);
    let mut total = Coverage::default();
    for end_trim in [0, p.n - 1] {
        let mut case = case_of(c, planes.clone(), vec![(7, 7)], &p, Source::Replay);
        case.end_trim = end_trim;
        total.add(&check(c, &case).unwrap_or_else(|e| panic!("{e}")));
    }
    assert!(
        total.cut_segments > 0 && total.truncated_blinks > 0,
        "END_TRIM corners: {total}"
    );
    total.add(&empty_first_segment(c));
    total
}

/// A blink that crosses T_int at plane 0 with L_max = N: its first segment
/// is cut at N − 1, before its first plane has left the window, and sums
/// nothing (its counts read as zero; MASKED from the hot pixel in its ROI:
/// the aggregator sweeps a segment's ROI in its opening plane even when it
/// sums nothing); its continuations, the drop and the stream end follow.
/// (A dropped segment can sum nothing only if it drops before plane N,
/// which H, non-decreasing before plane N, never does.)
fn empty_first_segment(c: &mut Cosim) -> Coverage {
    let (w, h) = (c.spec.width, c.spec.height);
    let n = 6;
    let hot = vec![(21, 13)];
    let planes: Vec<BitPlane> = (0..40)
        .map(|t| {
            BitPlane::from_fn(w, h, |x, y| {
                t < 20 && (18..23).contains(&x) && (10..15).contains(&y)
            })
        })
        .collect();
    let mut total = Coverage::default();
    for end_trim in [0, n - 1] {
        let mut case = Case {
            hot: hot.clone(),
            mask_enable: true,
            end_trim,
            ..Case::replay(n, 1, 1, n, planes.clone())
        };
        // T_int: the blob's H at plane 0, so that it crosses at once.
        let mut model = Pipeline::new(c.model_config(&case).unwrap()).unwrap();
        model.push_plane(&planes[0]).unwrap();
        case.threshold = model.filtered().iter().copied().max().unwrap();
        let records =
            smartagg_model::pipeline::run(c.model_config(&case).unwrap(), planes.clone()).unwrap();
        assert!(
            records.iter().any(|r| matches!(r, Record::Blink(b)
                if b.planes_summed == 0 && b.flags & flags::MASKED != 0)),
            "END_TRIM {end_trim}: no empty MASKED Blink: {records:#?}"
        );
        let cov = check(c, &case).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            cov.empty_blinks > 0 && cov.cut_segments > 0,
            "END_TRIM {end_trim}: {cov}"
        );
        total.add(&cov);
    }
    total
}

/// N = N_max, the longest window the design's delay line holds (128 on the
/// reduced field's DDR2 designs, 24 in the projected design's block RAM;
/// the random cases stop at N = 40): long blinks over sparse background,
/// the mask on, host stalls on both pipes.
fn n_max_case(c: &mut Cosim, seed: u64) -> Coverage {
    let (w, h) = (c.spec.width, c.spec.height);
    let n = c.spec.n_max();
    let p = Params {
        seed,
        n,
        l_min: 2,
        extra: 40,
        mask_enable: true,
        input_stall: 5,
        read_stall: 10,
        emitters: 8,
        background: 0.001,
        quantile: 0.995,
        edge: 0.2,
        hold: 0.8,
        trim: 0.5,
    };
    let spec = SceneSpec {
        width: w,
        height: h,
        planes: n as usize + 200,
        background: p.background,
        emitters: p.emitters,
        peak: 0.5,
        mean_on: 50.0,
        mean_off: 80.0,
        edge_fraction: p.edge,
        dip: 0.05,
        hot: vec![(9, 9)],
        hot_rate: 0.3,
    };
    let case = case_of(c, generate(&spec, seed), vec![(9, 9)], &p, Source::Replay);
    let cov = check(c, &case).unwrap_or_else(|e| panic!("N = N_max = {n}: {e}"));
    assert!(cov.blink_records > 0, "N = N_max = {n}: no Blink: {cov}");
    cov
}

/// L_max cuts on purpose, with END_TRIM 0 and N − 1: N = L_max = 6 and
/// 36 planes. Blob A is on from plane 0 to the end with a hot pixel in its
/// ROI (mask on): its first segment is PREROLL_CLIPPED, cut at N − 1 and
/// empty; it is cut every 6 planes, the last time at the last plane, so
/// its last continuation is the continuation of a cut at the last plane
/// (TRUNCATED, `t_drop = t_cross − 1`). Blob B, on in planes 3 ..= 20,
/// opens at plane 3 < N (PREROLL_CLIPPED, not empty), is cut twice and its
/// last continuation drops.
fn cuts_on_purpose(c: &mut Cosim) -> Coverage {
    let (w, h) = (c.spec.width, c.spec.height);
    let n = 6;
    let hot = vec![(21, 13)];
    let planes = cut_planes(w, h);
    let mut total = Coverage::default();
    for end_trim in [0, n - 1] {
        let mut case = Case {
            hot: hot.clone(),
            mask_enable: true,
            end_trim,
            input_stall: 10,
            read_stall: 10,
            ..Case::replay(n, 1, 1, n, planes.clone())
        };
        case.threshold = crossing_at_plane_0(c, &case);
        let cov = check(c, &case).unwrap_or_else(|e| panic!("END_TRIM {end_trim}: {e}"));
        assert!(
            cov.lmax_cuts >= 8
                && cov.flag_continuation >= 7
                && cov.empty_continued == 1
                && cov.continued_at_last_plane == 1
                && cov.flag_preroll_clipped >= 2
                && cov.flag_masked >= 6
                && cov.flag_truncated >= 1,
            "END_TRIM {end_trim}: {cov}"
        );
        // Under the version-3 rule (PACKETS.md §8.6) a continuation sums
        // from `t_cross − N ≥ 0` to at least `t_cross − 1`: never empty.
        assert_eq!(cov.empty_continuations, 0, "END_TRIM {end_trim}: {cov}");
        total.add(&cov);
    }
    total
}

/// The planes of [`cuts_on_purpose`]: two solid 5×5 blobs.
fn cut_planes(w: usize, h: usize) -> Vec<BitPlane> {
    (0..36)
        .map(|t| {
            BitPlane::from_fn(w, h, |x, y| {
                let a = (18..23).contains(&x) && (10..15).contains(&y);
                let b = (3..=20).contains(&t) && (40..45).contains(&x) && (10..15).contains(&y);
                a || b
            })
        })
        .collect()
}

/// T_int = the largest H of plane 0: a solid blob on from plane 0 crosses
/// there, and one that lights up later crosses at its first plane.
fn crossing_at_plane_0(c: &Cosim, case: &Case) -> u32 {
    let mut model = Pipeline::new(c.model_config(case).unwrap()).unwrap();
    model.push_plane(&case.planes[0]).unwrap();
    model.filtered().iter().copied().max().unwrap()
}

fn run_configuration(config: Config, seed: u64) -> Coverage {
    let spec = DesignSpec::new(config, REDUCED.0, REDUCED.1).unwrap();
    let (ddr, n_max) = (spec.ddr(), spec.n_max());
    let mut c = Cosim::new(spec).unwrap();
    let mut total = Coverage::default();
    let mut runner = TestRunner::new_with_rng(
        PtConfig {
            cases: CASES,
            max_shrink_iters: 0,
            failure_persistence: None,
            ..PtConfig::default()
        },
        proptest::test_runner::TestRng::from_seed(
            proptest::test_runner::RngAlgorithm::ChaCha,
            &[seed as u8; 32],
        ),
    );
    let cov = std::cell::RefCell::new(Coverage::default());
    let cell = std::cell::RefCell::new(&mut c);
    runner
        .run(&params(n_max), |p| {
            let mut c = cell.borrow_mut();
            let (planes, hot) = scene(REDUCED.0, REDUCED.1, PLANES, &p);
            let case = case_of(&c, planes, hot, &p, Source::Replay);
            let r = check(&mut c, &case).map_err(TestCaseError::fail)?;
            cov.borrow_mut().add(&r);
            Ok(())
        })
        .unwrap_or_else(|e| panic!("{}: {e}", config.name()));
    total.add(&cov.borrow());
    println!("{} random cases: {total}", config.name());
    let c = cell.into_inner();
    total.add(&directed(c, seed ^ 1, false));
    total.add(&directed(c, seed ^ 2, true));
    total.add(&burst(c, seed ^ 3));
    total.add(&trim_corners(c, seed ^ 4));
    total.add(&n_max_case(c, seed ^ 5));
    total.add(&cuts_on_purpose(c));
    println!("{}: {total}", config.name());
    assert!(total.planes >= 6_000, "{total}");
    assert!(total.confirmed_blinks > 0, "confirmed blinks: {total}");
    assert!(total.bridged_dips > 0, "bridged dips: {total}");
    assert!(total.unconfirmed_tracks > 0, "unconfirmed tracks: {total}");
    assert!(total.slot_exhaustion > 0, "slot exhaustion: {total}");
    assert!(total.output_fifo_full > 0, "output FIFO full: {total}");
    assert!(total.edge_rois > 0, "edge ROIs: {total}");
    assert!(total.cut_segments > 0, "cut segments: {total}");
    assert!(total.truncated_blinks > 0, "truncated blinks: {total}");
    // What the gateware delivered (its bytes decoded): every record kind
    // and flag. Sequence wraps: `sequence_numbers_wrap_as_the_model_numbers_them`.
    for (what, count) in [
        ("StreamStart records", total.start_records),
        ("Blink records", total.blink_records),
        ("Dropped records (burst)", total.dropped_records),
        ("Overflow records (held reads)", total.overflow_records),
        ("StreamEnd records", total.end_records),
        ("EDGE", total.flag_edge),
        ("MASKED", total.flag_masked),
        ("TRUNCATED", total.flag_truncated),
        ("CONTINUATION (cuts on purpose)", total.flag_continuation),
        (
            "PREROLL_CLIPPED (cuts on purpose)",
            total.flag_preroll_clipped,
        ),
        ("L_max cuts (cuts on purpose)", total.lmax_cuts),
        (
            "empty segments continued (cuts on purpose)",
            total.empty_continued,
        ),
        (
            "continuations of a cut at the last plane (cuts on purpose)",
            total.continued_at_last_plane,
        ),
    ] {
        assert!(count > 0, "{}: no {what} delivered: {total}", config.name());
    }
    assert_eq!(total.start_records, total.cases, "{total}");
    assert_eq!(total.end_records, total.cases, "{total}");
    if ddr {
        assert!(
            total.refresh_collisions > 0,
            "DDR2 refresh collisions: {total}"
        );
    }
    total
}

#[test]
fn spcimager150_reduced_field_equals_the_model() {
    run_configuration(Config::Spcimager150, 150);
}

#[test]
fn spcimager60_reduced_field_equals_the_model() {
    run_configuration(Config::Spcimager60, 60);
}

#[test]
fn projected150_reduced_field_equals_the_model() {
    run_configuration(Config::Projected150, 24);
}

#[test]
fn sensor_port_equals_the_model() {
    let spec = DesignSpec::new(Config::Spcimager150, REDUCED.0, REDUCED.1).unwrap();
    let mut c = Cosim::new(spec).unwrap();
    let p = Params {
        seed: 77,
        n: 12,
        l_min: 2,
        extra: 30,
        mask_enable: true,
        input_stall: 15,
        read_stall: 30,
        emitters: 12,
        background: 0.003,
        quantile: 0.99,
        edge: 0.3,
        // Hysteresis through the sensor port too.
        hold: 0.6,
        trim: 0.5,
    };
    let (planes, hot) = scene(REDUCED.0, REDUCED.1, 600, &p);
    let case = case_of(&c, planes, hot, &p, Source::Sensor);
    let cov = check(&mut c, &case).unwrap_or_else(|e| panic!("{e}"));
    println!("sensor port: {cov}");
    assert!(cov.confirmed_blinks > 0, "{cov}");
}

/// Planes of the full-field run: `SMARTAGG_COSIM_FULL_PLANES` (the
/// 2,000-plane run of the issue), 250 by default — Verilator 5.006 runs
/// this design at a few tens of thousands of clocks per second and a plane
/// is 9,600 clocks, so 2,000 planes take tens of minutes on 2 cores.
fn full_planes() -> usize {
    std::env::var("SMARTAGG_COSIM_FULL_PLANES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(250)
        .max(1)
}

/// The full field with the shipped design's defaults (the field design:
/// N, T_open, T_hold < T_open, END_TRIM = ⌊N/2⌋, r_assoc, L_min = 1):
/// hysteresis and the trimmed sums on the whole sensor.
#[test]
fn spcimager150_full_field_equals_the_model() {
    let design =
        smartagg_hdl::designs::Design::new(smartagg_model::params::PresetName::Spcimager, 150)
            .unwrap();
    assert!(design.threshold_hold < design.threshold_int);
    let spec = DesignSpec::new(Config::Spcimager150, FULL.0, FULL.1)
        .and_then(|s| s.with_r_assoc(design.config.r_assoc))
        .unwrap();
    let mut c = Cosim::new(spec).unwrap();
    let p = Params {
        seed: 2026,
        n: design.n_window,
        l_min: 1,
        extra: 0,
        mask_enable: true,
        input_stall: 5,
        read_stall: 20,
        emitters: 60,
        background: 0.0008,
        quantile: 0.999,
        edge: 0.1,
        hold: 1.0,
        trim: 0.5,
    };
    let (planes, hot) = scene(FULL.0, FULL.1, full_planes(), &p);
    let case = Case {
        hot,
        mask_enable: p.mask_enable,
        input_stall: p.input_stall,
        read_stall: p.read_stall,
        seed: p.seed,
        ..Case::design_defaults(&design, planes)
    };
    let cov = check(&mut c, &case).unwrap_or_else(|e| panic!("{e}"));
    let wpp = (FULL.0 * FULL.1 / smartagg_sim::designs::P) as f64;
    println!(
        "full field (T_open {}, T_hold {}, END_TRIM {}, r_assoc {}): {cov}; {:.0} clocks per plane ({} words per plane)",
        case.threshold,
        case.hold(),
        case.end_trim,
        design.config.r_assoc,
        cov.cycles as f64 / cov.planes as f64,
        wpp
    );
    assert_eq!(cov.planes as usize, full_planes());
    assert!(cov.confirmed_blinks > 0, "{cov}");
}

/// Sequence numbers that wrap: the projected design's Verilog with the
/// packetiser's first number patched to 2³² − 5 (a plain build of its own;
/// 2³² records cannot be simulated) against the model's encoder starting
/// there, byte for byte; then with reads held, so that records are lost
/// and announced by Overflow records numbered across the wrap. The model's
/// decoder agrees: the wrap is no gap (its only complaint is the stream's
/// first number, which is not 0).
#[test]
fn sequence_numbers_wrap_as_the_model_numbers_them() {
    use smartagg_model::packet::decode_all;
    let spec = DesignSpec::new(Config::Projected150, REDUCED.0, REDUCED.1).unwrap();
    let start = u32::MAX - 4;
    let mut c = Cosim::with_seq_start(spec, start).unwrap();
    let (w, h) = (c.spec.width, c.spec.height);
    let mut case = Case {
        hot: vec![(21, 13)],
        mask_enable: true,
        read_stall: 20,
        ..Case::replay(6, 1, 1, 6, cut_planes(w, h))
    };
    case.threshold = crossing_at_plane_0(&c, &case);
    let cov = check(&mut c, &case).unwrap_or_else(|e| panic!("{e}"));
    println!("wrap, no loss: {cov}");
    assert_eq!((cov.seq_wraps, cov.records_lost), (1, 0), "{cov}");
    assert!(cov.packets > 6, "{cov}");
    let out = c.run(&case).unwrap();
    let d = decode_all(&out.bytes);
    let seqs: Vec<u32> = d.packets.iter().map(|p| p.seq).collect();
    assert_eq!(seqs[0], start);
    assert!(
        seqs.windows(2).all(|s| s[1] == s[0].wrapping_add(1)),
        "{seqs:?}"
    );
    assert!(seqs.contains(&u32::MAX) && seqs.contains(&0), "{seqs:?}");
    assert_eq!(
        (
            d.stats.out_of_order,
            d.stats.lost_in_transport,
            d.stats.lost_on_device
        ),
        (1, 0, 0),
        "{}",
        d.stats
    );
    // Losses across the wrap.
    let lossy = directed(&mut c, 91, true);
    println!("wrap, held reads: {lossy}");
    assert!(
        lossy.seq_wraps == 1 && lossy.overflow_records > 0 && lossy.records_lost > 0,
        "{lossy}"
    );
}

/// The mask goes in the host's way (the model's `StreamRegisters`, the
/// host's own code) and the StreamStart's MASKED_PIXELS is checked against
/// the pixels of the mask words actually written through pipe-in 0x81: a
/// MASKED_PIXELS register one off (a host bug) is caught and named.
#[test]
fn a_wrong_masked_pixels_count_is_caught() {
    let spec = DesignSpec::new(Config::Spcimager150, REDUCED.0, REDUCED.1).unwrap();
    let mut c = Cosim::new(spec).unwrap();
    let (w, h) = (c.spec.width, c.spec.height);
    let hot = vec![(21, 13), (3, 4), (60, 30)];
    let mut case = Case {
        hot: hot.clone(),
        mask_enable: true,
        ..Case::replay(6, 1, 1, 6, cut_planes(w, h))
    };
    case.threshold = crossing_at_plane_0(&c, &case);
    let regs = c.registers(&case).unwrap();
    assert_eq!(regs.masked_pixels(), 3);
    let cov = check(&mut c, &case).unwrap_or_else(|e| panic!("{e}"));
    assert!(cov.flag_masked > 0, "{cov}");
    c.override_wire_in(Some((smartagg_model::registers::wire_in::MASKED_PIXELS, 4)));
    let m = c
        .check(&case)
        .unwrap()
        .expect_err("a wrong MASKED_PIXELS must be caught");
    println!("{m}");
    assert!(
        m.detail.contains("MASKED_PIXELS 4") && m.detail.contains("masks 3 pixels"),
        "{m}"
    );
    // Without MASK_ENABLE the host sends no mask and the count is 0.
    c.override_wire_in(None);
    case.mask_enable = false;
    assert_eq!(c.registers(&case).unwrap().mask, None);
    check(&mut c, &case).unwrap_or_else(|e| panic!("{e}"));
}
