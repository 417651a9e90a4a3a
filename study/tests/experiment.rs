//! The experiment studies (`nanoruler`, `emccd-frames`, `blink-durations`,
//! `detection`; smart aggregation is the field design) on `--quick` runs:
//! what the results must show (issue #11), the derived blink-duration bias,
//! the diagnosis of split blinks, and the analysis helpers on data with a
//! known answer.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use smartagg_model::config::PipelineConfig;
use smartagg_model::record::{flags, BlinkRecord};
use smartagg_study::acquisition::record_planes;
use smartagg_study::experiment::blink_durations::{self, join_segments};
use smartagg_study::experiment::common::TLoc;
use smartagg_study::experiment::nanoruler::{
    self, density_filter, gaussian_mixture, kmeans3, principal_axis, NanorulerOptions,
};
use smartagg_study::experiment::{detection, emccd_frames, run, Experiment, ExperimentOptions};

#[test]
fn nanoruler_distances_and_spreads() {
    let r = nanoruler::compute(&NanorulerOptions::new(1, true)).unwrap();
    assert!(r.rulers.len() >= 5);
    // Every marker blinks many times.
    assert!(
        r.blinks as f64 / (3 * r.rulers.len()) as f64 >= 30.0,
        "{}",
        r.blinks
    );
    for (s, name) in nanoruler::SCHEMES.iter().enumerate() {
        let d = r.median_distance(s).unwrap_or(f64::NAN);
        // Issue: median neighbour distance within a few nm (here 5 nm, as
        // the summary checks) of 80 nm for every scheme.
        assert!((d - 80.0).abs() <= 5.0, "{name}: median distance {d}");
        // At least 5 rulers with both distances.
        let rulers: std::collections::BTreeSet<usize> =
            r.schemes[s].distances.iter().map(|x| x.0).collect();
        assert!(rulers.len() >= 5, "{name}: {rulers:?}");
    }
    // Paired on the same blinks, smart aggregation localises more precisely
    // than fixed 640-plane frames.
    let (_, _, k, smart, fixed) = r
        .paired
        .iter()
        .find(|p| p.0 == 2 && p.1 == 1)
        .copied()
        .unwrap();
    assert!(k >= 100, "{k} blinks in common");
    assert!(smart < fixed, "paired RMS smart {smart} vs fixed {fixed}");
    // The spread claim of Fig. 7 is evaluated, not assumed: the EMCCD, with
    // about six times the SPCIMAGER's detected photons, is the most precise
    // in this simulation, and the summary says whether the claim holds.
    let em = r.median_spread(0).unwrap();
    let smart_spread = r.median_spread(2).unwrap();
    assert!(em < smart_spread, "EMCCD {em} vs smart {smart_spread}");
    // Smart aggregation (the field design, r_assoc = round(2σ) = 3) gives
    // one record per blink; with the paper's r_assoc = 1 the same bit-planes
    // give more (duplicated concurrent tracks).
    assert_eq!(r.smart.r_assoc, 3);
    assert!(
        r.schemes[2].locs_per_blink < 1.1,
        "{}",
        r.schemes[2].locs_per_blink
    );
    assert!(
        r.schemes[3].locs_per_blink > 1.25,
        "{}",
        r.schemes[3].locs_per_blink
    );
    // Detection and false positives are measured for every scheme. The
    // smart schemes' false positives are mostly background-only tracks (the
    // design allows up to 1 false blink/s over the field, 100 in this
    // 100 s acquisition) and short blinks' poor localisations.
    for (s, sr) in r.schemes.iter().enumerate() {
        assert!(sr.detection > 0.2 && sr.detection <= 1.0);
        let fp = if s >= 2 { 0.15 } else { 0.05 };
        assert!(
            sr.false_pos < fp,
            "{}: {}",
            nanoruler::SCHEMES[s],
            sr.false_pos
        );
        assert!(sr.kept <= sr.locs && sr.kept > 0);
    }
    let dir = tempfile::tempdir().unwrap();
    let (files, warnings) = nanoruler::write(dir.path(), &r).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    let md = std::fs::read_to_string(dir.path().join("summary.md")).unwrap();
    assert!(md.contains("does not hold** — smart gives a smaller marker spread"));
    assert!(files.iter().any(|f| f.ends_with("nanoruler.png")));
    let csv = std::fs::read_to_string(dir.path().join("points.csv")).unwrap();
    assert_eq!(
        csv.lines().count() - 1,
        r.markers.len(),
        "one CSV row per marker"
    );
}

#[test]
fn emccd_frames_merging_helps_long_blinks_and_dead_time_costs_short_ones() {
    let r = emccd_frames::compute(1, true, None).unwrap();
    let at = |ms, s| emccd_frames::EmccdFramesResult::get(&r, ms, s).unwrap();
    // 100 ms blinks span two or three 64 ms frames: merging joins them and
    // lowers the error (its 95 % interval below the unmerged estimate).
    let (plain, merged) = (at(100.0, 0), at(100.0, 1));
    assert!(plain.matches as f64 / plain.detected as f64 > 1.5);
    assert!((merged.matches as f64) / (merged.detected as f64) < 1.1);
    assert!(
        merged.rms.hi.unwrap() < plain.rms.value.unwrap(),
        "{merged:?} vs {plain:?}"
    );
    // 30 ms of every 64 ms are dead: a 20 ms blink is missed about a third
    // of the time, a 100 ms blink never.
    let short = at(20.0, 0);
    let d20 = short.detected as f64 / short.blinks as f64;
    assert!((0.55..0.9).contains(&d20), "{d20}");
    assert!(plain.detected as f64 / plain.blinks as f64 > 0.98);
    // Error falls with blink duration.
    assert!(plain.rms.value.unwrap() < short.rms.value.unwrap());
}

#[test]
fn blink_durations_bias_is_derived_and_splits_are_concurrent_tracks() {
    let r = blink_durations::compute(1, true, None).unwrap();
    // Derived bias (N − k_open − k_hold + 1 planes) against the measurement
    // on blinks with exactly one record: within 1 ms, and the corrected
    // estimator is unbiased to within 1 ms.
    let (measured, sd, k) = r.bias(0, false).unwrap();
    assert!(k >= 50, "{k}");
    assert!(
        (measured - r.derived_bias_ms).abs() < 1.0,
        "measured {measured} ms, derived {} ms",
        r.derived_bias_ms
    );
    let (corrected, _, _) = r.bias(0, true).unwrap();
    assert!(
        corrected.abs() < 1.0 + 2.0 * sd / (k as f64).sqrt(),
        "{corrected}"
    );
    // The window does not add N − 1 planes: the open and hold on-counts are
    // large parts of N (the open level's, above Eq. 7's, more than half).
    assert!(r.derived_bias_ms < 0.5 * (r.n_window as f64 - 1.0) * 0.1);
    assert!(r.k_open > r.k_hold && r.k_open < r.n_window as f64);
    // Split blinks: the field design (r_assoc = round(2σ) = 3) gives about
    // one record per 40–60 ms blink, the paper's r_assoc = 1 well over one;
    // the extra records are concurrent tracks (opened while the first was
    // on), not drops and restarts.
    assert_eq!(r.r_assoc, [3, 1]);
    let r3 = r.records_per_blink(0, 40.0, 60.0).unwrap();
    let r1 = r.records_per_blink(1, 40.0, 60.0).unwrap();
    assert!(r1 > 1.3 && r3 < 1.15, "{r1} {r3}");
    let conc: u32 = r.blinks.iter().map(|b| b.split[1].concurrent).sum();
    let seq: u32 = r.blinks.iter().map(|b| b.split[1].sequential).sum();
    assert!(conc > 5 * seq.max(1), "concurrent {conc}, sequential {seq}");
    // Concurrent anchors are more than r_assoc = 1 apart by construction.
    assert!(r
        .blinks
        .iter()
        .filter(|b| b.split[1].concurrent > 0)
        .all(|b| b.anchor_spread[1] >= 2));
    // EMCCD chains: long blinks span more frames than short ones.
    let frames = |lo: f64, hi: f64| {
        let v: Vec<f64> = r
            .blinks
            .iter()
            .filter(|b| b.duration_ms >= lo && b.duration_ms < hi && b.emccd_frames > 0)
            .map(|b| b.emccd_frames as f64)
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    assert!(frames(80.0, 1e9) > frames(0.0, 20.0) + 0.5);
}

#[test]
fn detection_promise_and_the_gaussian_tail() {
    let r = detection::compute(1, true, None).unwrap();
    let d = r.derived().unwrap();
    // Eq. 5's ≈ 99 %: holds at the derived N and T.
    assert!(d.p_det >= 0.99, "{d:?}");
    // The model's exact statistics predict the measurement; the Gaussian
    // misses the false-alarm tail by about 2× at z = 3.
    assert!((d.p_det - d.p_det_exact).abs() < 0.002);
    let ratio = d.p_fa / d.p_fa_exact;
    assert!((0.8..1.25).contains(&ratio), "measured/exact {ratio}");
    assert!(d.p_fa / d.p_fa_gauss > 1.6, "{d:?}");
    // Along N at z = 3: detection rises with N; at N/4 it is far below 99 %.
    let z3: Vec<_> = r
        .windows
        .iter()
        .filter(|w| (w.z - 3.0).abs() < 1e-9)
        .collect();
    assert!(z3.first().unwrap().p_det < 0.8);
    for w in z3.windows(2) {
        assert!(w[1].p_det >= w[0].p_det - 0.002);
    }
    // Part B (the field design at each N): the shortest window localises
    // less precisely, its noisy H splitting blinks into several records; the
    // longest misses more short blinks than the best window, whose T_hold is
    // Eq. 7's at that N and T_open keeps 1 false blink/s over the field.
    let first = r.precision.first().unwrap();
    let last = r.precision.last().unwrap();
    assert!(first.n < last.n);
    assert!(r
        .precision
        .iter()
        .all(|p| p.t_int > p.t_hold && p.l_min == 1));
    assert!(first.rms.value.unwrap() > last.rms.value.unwrap());
    assert!(first.matches as f64 / first.detected as f64 > 1.5);
    let best = r.precision.iter().map(|p| p.detected).max().unwrap();
    assert!(last.detected < best);
    let dir = tempfile::tempdir().unwrap();
    detection::write(dir.path(), &r).unwrap();
    let md = std::fs::read_to_string(dir.path().join("summary.md")).unwrap();
    assert!(md.contains("**Yes**: at the derived N"));
}

#[test]
fn run_writes_every_output_of_a_study() {
    let dir = tempfile::tempdir().unwrap();
    let o = ExperimentOptions {
        seed: 3,
        quick: true,
        blinks_per_point: Some(60),
    };
    let (files, warnings) = run(Experiment::EmccdFrames, &o, dir.path()).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    for f in ["points.csv", "emccd-frames.png", "summary.md"] {
        assert!(files.iter().any(|p| p.ends_with(f)), "{f}");
        assert!(std::fs::metadata(dir.path().join(f)).unwrap().len() > 100);
    }
    // A quick run with another seed: the notes' figures are named as the
    // default run's, with its command, not as this run's.
    let md = std::fs::read_to_string(dir.path().join("summary.md")).unwrap();
    assert!(
        md.contains("earlier results, not this run's")
            && md.contains("`smartagg study emccd-frames --out DIR`"),
        "{md}"
    );
    assert_eq!(
        Experiment::parse("blink-durations"),
        Some(Experiment::BlinkDurations)
    );
    assert_eq!(Experiment::parse("smart-vs-fixed"), None);
}

#[test]
fn analysis_helpers_find_known_markers() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let noise = Normal::new(0.0, 12.0).unwrap();
    let angle: f64 = 0.7;
    let (ux, uy) = (angle.cos(), angle.sin());
    let mut locs = Vec::new();
    for m in [-1.0, 0.0, 1.0] {
        for _ in 0..60 {
            locs.push(TLoc {
                x_nm: 500.0 + 80.0 * m * ux + noise.sample(&mut rng),
                y_nm: 400.0 + 80.0 * m * uy + noise.sample(&mut rng),
                t0_s: 0.0,
                t1_s: 0.1,
                photons: 100.0,
                frames: 1,
            });
        }
    }
    // Lone localisations far away are removed by the density filter.
    for k in 0..5 {
        locs.push(TLoc {
            x_nm: 2000.0 + 300.0 * k as f64 + rng.gen::<f64>(),
            y_nm: 2000.0,
            t0_s: 0.0,
            t1_s: 0.1,
            photons: 10.0,
            frames: 1,
        });
    }
    let kept = density_filter(&locs, 30.0, 3);
    assert!(kept.len() >= 170 && kept.len() <= 180, "{}", kept.len());
    let pts: Vec<(f64, f64)> = kept.iter().map(|l| (l.x_nm, l.y_nm)).collect();
    let ((ax, ay), (mx, my)) = principal_axis(&pts);
    assert!((ax * ux + ay * uy).abs() > 0.99);
    let proj: Vec<f64> = pts
        .iter()
        .map(|p| (p.0 - mx) * ax + (p.1 - my) * ay)
        .collect();
    let a = kmeans3(&proj);
    let comps = gaussian_mixture(&pts, &a);
    let mut along: Vec<f64> = comps
        .iter()
        .map(|c| (c.x - 500.0) * ux + (c.y - 400.0) * uy)
        .collect();
    along.sort_by(f64::total_cmp);
    for (got, want) in along.iter().zip([-80.0, 0.0, 80.0]) {
        assert!((got - want).abs() < 5.0, "{along:?}");
    }
    for c in &comps {
        assert!((c.sigma - 12.0).abs() < 3.0, "{c:?}");
    }
}

#[test]
fn cut_segments_are_joined_with_their_continuations() {
    // N = 109 (⌊N/2⌋ = 54): a blink cut at plane 10,154 goes on from 10,155
    // in the same slot; another blink in slot 1 meanwhile.
    let rec = |slot: u8, fl: u8, t_cross: u64, t_drop: u64, t_s: i64, t_e: i64| BlinkRecord {
        slot,
        flags: fl,
        anchor_x: 5,
        anchor_y: 5,
        t_cross,
        t_drop,
        t_s,
        t_e,
        planes_summed: 0,
        roi_size: 1,
        counts: vec![1],
    };
    let recs = vec![
        rec(0, flags::CUT, 154, 10_154, 100, 10_154),
        rec(1, 0, 554, 954, 500, 900),
        rec(0, flags::CONTINUATION, 10_155, 12_054, 10_155, 12_000),
    ];
    for end_trim in [0, 54] {
        let mut cfg = PipelineConfig::new(32, 32, 109, vec![1, 2, 1], 2, 100);
        cfg.end_trim = end_trim;
        // The cut segment sums to t_drop − N, its continuation from
        // t_cross − N: contiguous, every plane once.
        assert_eq!(record_planes(&recs[0], &cfg), 45..10_046);
        assert_eq!(
            record_planes(&recs[2], &cfg),
            10_046..12_055 - end_trim as u64
        );
        let j = join_segments(&recs, &cfg);
        assert_eq!(j.len(), 2);
        assert_eq!((j[0].t_s, j[0].t_e, j[0].segments), (100, 12_000, 2));
        assert_eq!((j[0].first, j[0].last), (45, 12_055 - end_trim as u64));
        assert_eq!((j[1].t_s, j[1].t_e, j[1].segments), (500, 900, 1));
        assert_eq!((j[1].first, j[1].last), (445, 955 - end_trim as u64));
    }
}
