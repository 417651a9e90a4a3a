//! The fast engine must give exactly the golden pipeline's records.

use proptest::prelude::*;
use smartagg_model::config::PipelineConfig;
use smartagg_model::delay_line::SharedPlane;
use smartagg_model::fast_engine::{
    default_chunk, fast_pipeline, run_parallel, FastFrontEnd, FrontResults, Isa, ParallelError,
    ParallelStats,
};
use smartagg_model::hot_pixel_mask::HotPixelMask;
use smartagg_model::pipeline::{run, run_with, FrontEnd, GoldenFrontEnd, PipelineError};
use smartagg_model::plane::BitPlane;
use smartagg_model::record::Record;
use smartagg_model::record_check::check_blink;
use std::sync::Arc;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        // splitmix64
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Background of probability `p` per pixel-plane plus Gaussian spots blinking
/// with `q_peak` detection probability per plane at their centre.
fn scene(
    seed: u64,
    w: usize,
    h: usize,
    planes: usize,
    spots: usize,
    p: f64,
    q_peak: f64,
) -> Vec<BitPlane> {
    let mut r = Rng(seed);
    let sp: Vec<(f64, f64, usize, usize)> = (0..spots)
        .map(|_| {
            let start = (r.next() % planes as u64) as usize;
            let len = 1 + (r.next() % 300) as usize;
            (r.unit() * w as f64, r.unit() * h as f64, start, start + len)
        })
        .collect();
    (0..planes)
        .map(|t| {
            BitPlane::from_fn(w, h, |x, y| {
                let mut q = p;
                for &(sx, sy, a, b) in &sp {
                    if (a..b).contains(&t) {
                        let d2 = (x as f64 + 0.5 - sx).powi(2) + (y as f64 + 0.5 - sy).powi(2);
                        q += q_peak * (-d2 / (2.0 * 1.5 * 1.5)).exp();
                    }
                }
                r.unit() < q
            })
        })
        .collect()
}

/// The parallel engine's records, the same whether the source gives its
/// planes away (the reader copies them into chunks) or lends them (the
/// workers copy them): this checks both and returns them.
fn parallel(
    cfg: PipelineConfig,
    planes: Vec<BitPlane>,
    threads: usize,
    chunk: usize,
) -> Vec<Record> {
    let mut lent = Vec::new();
    run_parallel::<(), _, _, _>(cfg.clone(), planes.iter().map(Ok), threads, chunk, |r| {
        lent.push(r)
    })
    .unwrap();
    let mut given = Vec::new();
    run_parallel::<(), _, _, _>(cfg, planes.into_iter().map(Ok), threads, chunk, |r| {
        given.push(r)
    })
    .unwrap();
    assert_eq!(
        lent, given,
        "lent and given planes, {threads} threads, chunk {chunk}"
    );
    given
}

/// k = 9 kernel for σ ≈ 1.5 px summing to 2^8, and a paper-like threshold.
fn spcimager_like(w: usize, h: usize, n: u32) -> PipelineConfig {
    let k1 = vec![2, 9, 26, 49, 84, 49, 26, 9, 2];
    let mut c = PipelineConfig::new(w, h, n, k1, 8, 0);
    // E(H_off) + 3 sd for p = 0.0118 (sum K^2 = 13380^2).
    let p = 0.0118;
    let mean = n as f64 * p * 65536.0;
    let sd = (n as f64 * p * (1.0 - p) * 13380f64.powi(2)).sqrt();
    c.threshold_int = (mean + 3.0 * sd).ceil() as u32;
    c.threshold_hold = c.threshold_int;
    c.roi_size = 9;
    c
}

#[test]
fn spcimager_like_field_matches_golden_single_and_parallel() {
    let cfg = spcimager_like(64, 48, 108);
    let planes = scene(7, 64, 48, 900, 12, 0.0118, 0.05);
    let golden = run(cfg.clone(), planes.clone()).unwrap();
    let blinks = golden
        .iter()
        .filter(|r| matches!(r, Record::Blink(_)))
        .count();
    assert!(
        blinks >= 5,
        "the scene must exercise the tracker: {blinks} blinks"
    );
    let fast = run_with(fast_pipeline(cfg.clone()).unwrap(), planes.clone()).unwrap();
    assert_eq!(fast, golden);
    for (threads, chunk) in [(1, 900), (2, 100), (3, 37), (2, 1), (2, 250), (9, 100)] {
        assert_eq!(
            parallel(cfg.clone(), planes.clone(), threads, chunk),
            golden,
            "threads {threads} chunk {chunk}"
        );
    }
    // Stages 5–7 alone on precomputed stages 1–4: the same records, with
    // the ROI sums in 1 to 4 threads.
    let fronts = FrontResults::compute(&cfg, &planes);
    assert_eq!(fronts.len(), planes.len());
    for threads in [1, 9, 17, 25] {
        assert_eq!(
            fronts.clone().replay_back_end(threads).unwrap(),
            golden,
            "{threads} threads"
        );
    }
}

/// The parallel engine and the replay mask each plane once, in the reader or
/// the worker (or `FrontResults::compute`), and hand the back end planes already
/// masked: the records stay the golden ones, and the back end's
/// `push_shared_plane` really does not mask again.
#[test]
fn hot_pixels_are_masked_once_and_the_records_stay_golden() {
    let mut cfg = spcimager_like(64, 48, 108);
    let mut planes = scene(11, 64, 48, 700, 12, 0.0118, 0.05);
    // A hot pixel, on in every plane, in the middle of the field.
    for p in &mut planes {
        p.set(30, 20, true);
    }
    let (mask, _) = HotPixelMask::from_pixels(64, 48, &[(30, 20)]);
    cfg.hot_mask = Some(mask.clone());
    let golden = run(cfg.clone(), planes.clone()).unwrap();
    for (threads, chunk) in [(1, 700), (2, 64), (3, 1), (17, 64)] {
        assert_eq!(
            parallel(cfg.clone(), planes.clone(), threads, chunk),
            golden
        );
    }
    assert_eq!(
        FrontResults::compute(&cfg, &planes)
            .replay_back_end(9)
            .unwrap(),
        golden
    );

    // `push_shared_plane` on planes masked by the caller = `push_plane`.
    let masked = Arc::new(planes.iter().map(|p| mask.apply(p)).collect::<Vec<_>>());
    let raw = Arc::new(planes.clone());
    let mut by_caller = fast_pipeline(cfg.clone()).unwrap();
    let mut by_pipeline = fast_pipeline(cfg.clone()).unwrap();
    let mut unmasked = fast_pipeline(cfg).unwrap();
    let (mut a, mut b, mut c) = (Vec::new(), Vec::new(), Vec::new());
    let shared = SharedPlane::every(&masked).zip(SharedPlane::every(&raw));
    for ((m, r), plane) in shared.zip(&planes) {
        a.extend(by_caller.push_shared_plane(m).unwrap());
        b.extend(by_pipeline.push_plane(plane).unwrap());
        c.extend(unmasked.push_shared_plane(r).unwrap());
    }
    assert_eq!(a, b);
    // The raw planes through `push_shared_plane` keep the hot pixel's
    // bits: the rolling counts, hence the records, differ.
    assert_ne!(c, b, "push_shared_plane must not mask the plane itself");
}

#[test]
fn the_default_chunk_covers_the_warm_up() {
    assert_eq!(default_chunk(18), 512);
    assert_eq!(default_chunk(109), 512);
    assert_eq!(default_chunk(1009), 1009);
}

#[test]
fn saturated_planes_take_the_dense_path_and_match() {
    let mut cfg = PipelineConfig::new(20, 10, 6, vec![1, 2, 1], 2, 30);
    cfg.l_max = 20;
    let planes: Vec<BitPlane> = (0..80)
        .map(|t| {
            if (10..50).contains(&t) {
                BitPlane::ones(20, 10)
            } else {
                BitPlane::zeros(20, 10)
            }
        })
        .collect();
    let golden = run(cfg.clone(), planes.clone()).unwrap();
    assert!(golden.iter().any(|r| matches!(r, Record::Blink(_))));
    assert_eq!(
        run_with(fast_pipeline(cfg.clone()).unwrap(), planes.clone()).unwrap(),
        golden
    );
    assert_eq!(parallel(cfg, planes, 2, 7), golden);
}

#[test]
fn sparse_and_dense_paths_are_both_taken_and_agree() {
    let (w, h, n) = (40, 30, 5);
    let cfg = PipelineConfig::new(w, h, n, vec![1, 4, 6, 4, 1], 4, 100);
    let zero = BitPlane::zeros(w, h);
    // Light planes (about 2 % of pixels on) keep to the sparse path; every
    // tenth plane half on forces the dense one, twice (entering and leaving).
    let mut r = Rng(11);
    let stream: Vec<BitPlane> = (0..60)
        .map(|t| {
            let p = if t % 10 == 9 { 0.5 } else { 0.02 };
            BitPlane::from_fn(w, h, |_, _| r.unit() < p)
        })
        .collect();
    let mut golden = GoldenFrontEnd::new(&cfg);
    let mut fast = FastFrontEnd::new(&cfg);
    let mut candidates = 0;
    for t in 0..stream.len() {
        let delayed = if t >= n as usize {
            &stream[t - n as usize]
        } else {
            &zero
        };
        golden.push(&stream[t], delayed);
        fast.push(&stream[t], delayed);
        let h_fast: Vec<u32> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| fast.filtered_at(x, y))
            .collect();
        assert_eq!(h_fast, golden.filtered(), "H at plane {t}");
        assert_eq!(fast.candidates(), golden.candidates(), "plane {t}");
        candidates += fast.candidates().len();
    }
    // 6 half-on planes entering, 5 leaving (the last leaves after the end).
    assert_eq!(fast.dense_planes(), 11);
    assert!(candidates > 0, "the threshold must be reached somewhere");
}

/// The dense path starts above an eighth of the field changed: with the
/// changes counted during the sparse pass (which gives up part-way through
/// the plane), a plane of exactly an eighth stays sparse and one more change
/// goes dense, and H and the candidates equal the golden front end's both
/// ways, whichever word the count crosses in.
#[test]
fn the_dense_path_starts_above_an_eighth_of_the_field() {
    let (w, h, n) = (24, 16, 3);
    let cfg = PipelineConfig::new(w, h, n, vec![1, 2, 1], 2, 4);
    let limit = w * h / 8;
    let zero = BitPlane::zeros(w, h);
    for (changes, dense) in [(limit, 0), (limit + 1, 1)] {
        for offset in [0, 77, w * h - changes] {
            // `changes` pixels on from raster index `offset` (wrapping): the
            // count crosses the limit at a different word each time.
            let on = |x: usize, y: usize| (y * w + x + w * h - offset) % (w * h) < changes;
            let plane = BitPlane::from_fn(w, h, on);
            let mut golden = GoldenFrontEnd::new(&cfg);
            golden.push(&plane, &zero);
            for mut fast in [FastFrontEnd::new(&cfg), FastFrontEnd::new(&cfg).portable()] {
                fast.push(&plane, &zero);
                assert_eq!(
                    fast.dense_planes(),
                    dense,
                    "{changes} changes from {offset}"
                );
                let h_fast: Vec<u32> = (0..h)
                    .flat_map(|y| (0..w).map(move |x| (x, y)))
                    .map(|(x, y)| fast.filtered_at(x, y))
                    .collect();
                assert_eq!(h_fast, golden.filtered(), "{changes} changes from {offset}");
                assert_eq!(fast.candidates(), golden.candidates());
                assert_eq!(fast.above(), golden_above(&golden, cfg.threshold_hold));
            }
        }
    }
}

/// The raster indices of the pixels of `golden`'s H at or above `thr`.
fn golden_above(golden: &GoldenFrontEnd, thr: u32) -> Vec<u32> {
    (0..golden.filtered().len() as u32)
        .filter(|&i| golden.filtered()[i as usize] >= thr)
        .collect()
}

#[test]
fn source_errors_stop_the_parallel_run() {
    let cfg = PipelineConfig::new(8, 8, 4, vec![1, 2, 1], 2, 8);
    let src = (0..50).map(|t| {
        if t == 30 {
            Err("disk on fire")
        } else {
            Ok(BitPlane::zeros(8, 8))
        }
    });
    let mut n = 0;
    let e = run_parallel(cfg, src, 2, 4, |_| n += 1).unwrap_err();
    assert!(matches!(e, ParallelError::Source("disk on fire")));
}

/// A molecule on through the whole stream that moves one pixel after its
/// track opens: its anchor is a candidate in the first planes only, so the
/// workers answer its track's tests ahead only because the tracker publishes
/// its live anchors. A worker takes chunk k once the back end is done with
/// chunk k − (3·threads + 1), hence sees the anchors of a chunk start at
/// least that late: from chunk 3·threads + 2 on, every test is answered
/// ahead. The records are the golden ones throughout.
#[test]
fn the_workers_answer_a_long_tracks_tests_ahead() {
    let (w, h) = (20, 16);
    let cfg = PipelineConfig::new(w, h, 4, vec![1, 2, 1], 2, 40);
    let planes: Vec<BitPlane> = (0..2000usize)
        .map(|t| {
            let cx = if t < 8 { 8 } else { 9 };
            BitPlane::from_fn(w, h, |x, y| x.abs_diff(cx) <= 1 && y.abs_diff(7) <= 1)
        })
        .collect();
    let golden = run(cfg.clone(), planes.clone()).unwrap();
    assert_eq!(golden.len(), 3, "start, one truncated blink, end");
    for threads in [1, 2, 3] {
        let chunk = 64;
        let mut got = Vec::new();
        let stats: ParallelStats =
            run_parallel::<(), _, _, _>(cfg.clone(), planes.iter().map(Ok), threads, chunk, |r| {
                got.push(r)
            })
            .unwrap();
        assert_eq!(got, golden, "{threads} threads");
        // Tested from the plane after it opened (plane 2) to the last.
        assert_eq!(stats.tracker_tests, 1997, "{threads} threads");
        let unanswered = stats.tracker_tests - stats.answered_ahead;
        assert!(
            unanswered <= ((3 * threads + 2) * chunk) as u64,
            "{threads} threads: {unanswered} of {} tests not answered ahead",
            stats.tracker_tests
        );
    }
}

#[test]
fn a_plane_of_another_size_stops_the_parallel_run_with_its_number() {
    let cfg = PipelineConfig::new(8, 8, 4, vec![1, 2, 1], 2, 8);
    for (threads, chunk) in [(1, 1), (2, 4), (3, 7)] {
        let src = (0..200).map(|t| {
            Ok::<_, ()>(if t == 61 {
                BitPlane::zeros(8, 9)
            } else {
                BitPlane::zeros(8, 8)
            })
        });
        let e = run_parallel(cfg.clone(), src, threads, chunk, |_| {}).unwrap_err();
        match e {
            ParallelError::Pipeline(PipelineError::PlaneSize { plane, got_h, .. }) => {
                assert_eq!((plane, got_h), (61, 9), "{threads} threads, chunk {chunk}")
            }
            other => panic!("{other:?}"),
        }
        // Lent planes: the reader checks them too, before any worker copies one.
        let planes: Vec<BitPlane> = (0..200)
            .map(|t| BitPlane::zeros(8, if t == 61 { 9 } else { 8 }))
            .collect();
        let src = planes.iter().map(Ok::<_, ()>);
        let e = run_parallel(cfg.clone(), src, threads, chunk, |_| {}).unwrap_err();
        assert!(
            matches!(
                e,
                ParallelError::Pipeline(PipelineError::PlaneSize {
                    plane: 61,
                    got_h: 9,
                    ..
                })
            ),
            "{e:?}"
        );
    }
}

/// A recording's planes read by the workers at their indices
/// (`PlaneFile`): the golden records for any chunk and thread count, hot
/// pixels masked; a file cut short meanwhile stops the run with the plane
/// it was cut in, and no stream-end record.
#[test]
fn a_recording_read_at_its_planes_gives_the_golden_records() {
    use smartagg_model::recording::{
        BitOrder, PlaneFile, RecordingError, RecordingHeader, RecordingReader, RecordingWriter,
    };
    let (w, h) = (40, 24);
    let mut cfg = spcimager_like(w, h, 108);
    let planes = scene(5, w, h, 900, 6, 0.0118, 0.05);
    let header = RecordingHeader {
        width: w as u32,
        height: h as u32,
        plane_period_ns: 100_000,
        exposure_ns: 100_000,
        bit_order: BitOrder::MsbFirst,
        planes: planes.len() as u64,
    };
    let file = tempfile::NamedTempFile::new().unwrap();
    let mut writer = RecordingWriter::new(file.reopen().unwrap(), header).unwrap();
    planes.iter().for_each(|p| writer.write_plane(p).unwrap());
    writer.finish().unwrap();
    let open = || {
        let reader = RecordingReader::open(file.reopen().unwrap()).unwrap();
        PlaneFile::of(file.reopen().unwrap(), &reader)
            .unwrap()
            .unwrap()
    };
    for masked in [false, true] {
        if masked {
            cfg.hot_mask = Some(HotPixelMask::from_pixels(w, h, &[(20, 12), (0, 0)]).0);
        }
        let golden = run(cfg.clone(), planes.clone()).unwrap();
        for (threads, chunk) in [(1, 900), (2, 64), (3, 37), (2, 1), (10, 50)] {
            let at = open();
            let mut got = Vec::new();
            run_parallel(cfg.clone(), at.planes(), threads, chunk, |r| got.push(r)).unwrap();
            assert_eq!(
                got, golden,
                "masked {masked}, {threads} threads, chunk {chunk}"
            );
        }
    }
    // Cut inside plane 500 after opening (120 bytes a plane).
    let at = open();
    file.as_file().set_len(48 + 500 * 120 + 7).unwrap();
    let mut got = Vec::new();
    let e = run_parallel(cfg, at.planes(), 2, 64, |r| got.push(r)).unwrap_err();
    match e {
        ParallelError::Source(RecordingError::Truncated {
            plane: 500,
            bytes_found: 7,
            ..
        }) => {}
        other => panic!("{other:?}"),
    }
    assert!(!got.iter().any(|r| matches!(r, Record::End(_))));
}

/// 1-D kernels of the tests: the specialised lengths 3, 5, 1 and 9 (the
/// SPCImager's), and 17, which takes the any-length path.
fn kernels() -> Vec<(Vec<u32>, u8)> {
    let mut k17 = vec![1u32; 17];
    k17[8] = 16;
    vec![
        (vec![1, 2, 1], 2),
        (vec![1, 4, 6, 4, 1], 4),
        (vec![16], 4),
        (vec![2, 9, 26, 49, 84, 49, 26, 9, 2], 8),
        (k17, 5),
    ]
}

/// Random planes with per-plane density drawn from `p_max`, so that some
/// planes take the sparse path and others (more than 1/8 of the pixels
/// changing) the dense one.
fn random_planes(seed: u64, w: usize, h: usize, planes: usize, p_max: f64) -> Vec<BitPlane> {
    let mut r = Rng(seed);
    (0..planes)
        .map(|_| {
            let p = if r.next().is_multiple_of(3) {
                r.unit() * p_max
            } else {
                r.unit() * 0.03
            };
            BitPlane::from_fn(w, h, |_, _| r.unit() < p)
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Stages 1–2 of the fast front end equal the golden ones at every pixel
    /// of every plane (counts and H), on sparse and dense planes, for every
    /// kernel path; and the candidates are the same.
    #[test]
    fn fast_front_end_equals_golden_stage_outputs(
        seed in any::<u64>(), w in 1usize..140, h in 1usize..12, planes in 1usize..60,
        n in 1u32..12, kernel in 0usize..5, p_max in 0.0f64..0.6, thr in 1u32..200,
        hold_pct in 1u32..=100,
    ) {
        let (k1, shift) = kernels()[kernel].clone();
        let thr = ((thr as u64 * (1u64 << (2 * shift))) / 16).max(1) as u32;
        let mut cfg = PipelineConfig::new(w, h, n, k1, shift, thr);
        // Hysteresis: the hold level anywhere from 1 % of the open level to it.
        cfg.threshold_hold = ((thr as u64 * hold_pct as u64) / 100).max(1) as u32;
        let stream = random_planes(seed, w, h, planes, p_max);
        let mut golden = GoldenFrontEnd::new(&cfg);
        let mut fast = FastFrontEnd::new(&cfg);
        prop_assert_eq!(fast.isa(), Isa::detect());
        // Every slower build this CPU runs (the portable one where AVX2 is used).
        let mut slower: Vec<FastFrontEnd> = Isa::detect()
            .up_to()
            .filter(|&i| i < Isa::detect())
            .map(|i| FastFrontEnd::new(&cfg).with_isa(i))
            .collect();
        prop_assert!(!FastFrontEnd::new(&cfg).portable().uses_avx2());
        let zero = BitPlane::zeros(w, h);
        let mut changed = 0u64;
        for t in 0..planes {
            let delayed = if t >= n as usize { &stream[t - n as usize] } else { &zero };
            golden.push(&stream[t], delayed);
            fast.push(&stream[t], delayed);
            changed += (0..h)
                .flat_map(|y| (0..w).map(move |x| (x, y)))
                .filter(|&(x, y)| stream[t].get(x, y) != delayed.get(x, y))
                .count() as u64;
            prop_assert_eq!(fast.changed_pixels(), changed, "plane {}", t);
            for other in &mut slower {
                other.push(&stream[t], delayed);
                prop_assert_eq!(other.changed_pixels(), changed);
                prop_assert_eq!(other.above(), fast.above(), "{:?}", other.isa());
                prop_assert_eq!(other.candidates(), fast.candidates(), "{:?}", other.isa());
                prop_assert_eq!(other.dense_planes(), fast.dense_planes());
                for y in 0..h {
                    for x in 0..w {
                        prop_assert_eq!(other.filtered_at(x, y), fast.filtered_at(x, y));
                    }
                }
            }
            for y in 0..h {
                for x in 0..w {
                    prop_assert_eq!(fast.count_at(x, y), golden.counts()[y * w + x], "S at ({}, {}) plane {}", x, y, t);
                    prop_assert_eq!(fast.filtered_at(x, y), golden.filtered()[y * w + x], "H at ({}, {}) plane {}", x, y, t);
                    prop_assert_eq!(golden.neighbourhood_on(x, y), fast.neighbourhood_on(x, y));
                }
            }
            // `above` lists the pixels at the hold level (the tracker's on-test).
            let above = golden_above(&golden, cfg.threshold_hold);
            prop_assert_eq!(fast.above(), &above[..]);
            prop_assert_eq!(fast.candidates(), golden.candidates());
        }
    }

    /// A front end warmed up on the N planes before a point of the stream
    /// continues exactly like one that ran from the start.
    #[test]
    fn warmed_up_front_end_continues_like_a_running_one(
        seed in any::<u64>(), w in 1usize..70, h in 1usize..10, n in 1u32..10, start in 0usize..25, p_max in 0.0f64..0.5,
    ) {
        let cfg = PipelineConfig::new(w, h, n, vec![1, 4, 6, 4, 1], 4, 40);
        let planes = start + 10;
        let stream = random_planes(seed, w, h, planes, p_max);
        let zero = BitPlane::zeros(w, h);
        let delayed = |t: usize| if t >= n as usize { &stream[t - n as usize] } else { &zero };
        let mut running = FastFrontEnd::new(&cfg);
        for (t, plane) in stream.iter().enumerate().take(start) {
            running.push(plane, delayed(t));
        }
        let mut warmed = FastFrontEnd::warmed_up(&cfg, &stream[start.saturating_sub(n as usize)..start]);
        for (t, plane) in stream.iter().enumerate().skip(start) {
            running.push(plane, delayed(t));
            warmed.push(plane, delayed(t));
            for y in 0..h {
                for x in 0..w {
                    prop_assert_eq!(warmed.filtered_at(x, y), running.filtered_at(x, y));
                }
            }
            prop_assert_eq!(warmed.candidates(), running.candidates());
        }
    }

    /// Hot-pixel masking (applied word by word) reads 0 exactly at the masked
    /// pixels and passes every other pixel unchanged.
    #[test]
    fn hot_pixel_mask_zeroes_exactly_the_masked_pixels(
        seed in any::<u64>(), w in 1usize..150, h in 1usize..6, hot in 0usize..20,
    ) {
        let mut r = Rng(seed);
        let px: Vec<(usize, usize)> = (0..hot).map(|_| ((r.next() % w as u64) as usize, (r.next() % h as u64) as usize)).collect();
        let (mask, outside) = HotPixelMask::from_pixels(w, h, &px);
        prop_assert!(outside.is_empty());
        let plane = BitPlane::from_fn(w, h, |_, _| r.next().is_multiple_of(2));
        let out = mask.apply(&plane);
        for y in 0..h {
            for x in 0..w {
                let masked = px.contains(&(x, y));
                prop_assert_eq!(out.get(x, y), plane.get(x, y) && !masked, "pixel ({}, {})", x, y);
            }
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn fast_and_parallel_equal_golden_on_random_scenes(
        seed in any::<u64>(), w in 3usize..72, h in 3usize..16, planes in 1usize..160, n in 1u32..20,
        spots in 0usize..8, p in 0.0f64..0.08, thr in 1u32..400, slots in 1usize..6, l_min in 1u32..8,
        threads in 1usize..4, chunk in 1usize..50, masked in 0usize..4, kernel in 0usize..5,
        hold_pct in 1u32..=100, r_assoc in 0u32..4, trim in 0u32..20,
    ) {
        let (k1, shift) = kernels()[kernel].clone();
        // Thresholds scaled to the kernel's sum so that every kernel sees blinks.
        let thr = ((thr as u64 * (1u64 << (2 * shift))) / 16).max(1) as u32;
        let mut cfg = PipelineConfig::new(w, h, n, k1, shift, thr);
        cfg.threshold_hold = ((thr as u64 * hold_pct as u64) / 100).max(1) as u32;
        cfg.r_assoc = r_assoc;
        cfg.end_trim = trim % n;
        cfg.slots = slots;
        cfg.l_min = l_min;
        cfg.l_max = n.max(l_min).max(25);
        cfg.roi_size = 5;
        if masked > 0 {
            let px: Vec<(usize, usize)> = (0..masked).map(|i| ((seed as usize >> (4 * i)) % w, (seed as usize >> (4 * i + 2)) % h)).collect();
            cfg.hot_mask = Some(HotPixelMask::from_pixels(w, h, &px).0);
        }
        let stream = scene(seed, w, h, planes, spots, p, 0.6);
        let golden = run(cfg.clone(), stream.clone()).unwrap();
        // Every record the pipeline writes passes the consumer's plausibility
        // check (continuations, cuts, truncation, masks, pre-roll clipping,
        // end_trim).
        let start = cfg.stream_start();
        let total = golden.iter().find_map(|r| match r { Record::End(e) => Some(e.planes), _ => None });
        prop_assert_eq!(total, Some(planes as u64));
        for r in &golden {
            if let Record::Blink(b) = r {
                prop_assert_eq!(check_blink(b, &start, total), Ok(()), "{:?}", b);
            }
        }
        let fast = run_with(fast_pipeline(cfg.clone()).unwrap(), stream.clone()).unwrap();
        prop_assert_eq!(&fast, &golden);
        prop_assert_eq!(&parallel(cfg, stream, threads, chunk), &golden);
    }
}
