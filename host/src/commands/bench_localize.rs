//! `smartagg bench localize`: error beside run time for every estimator on
//! simulated ROIs (figures printed, nothing asserted).
//!
//! 1. Accuracy and speed on the ideal ROIs (9×9, σ = 1.5 px, 5.9
//!    background photons per pixel, 230 and 1000 photons; emitter uniform
//!    within ±0.5 px of the centre): RMSE, the Cramér–Rao bound of the model
//!    fitted, their ratio, the mean reported uncertainty over the RMSE,
//!    failures, iterations, and fits per second on one core — thread CPU
//!    time per batch of `--batch` ROIs, median and best over batches and
//!    `--repeats` passes (the machine may be shared). The SPAD binomial MLE
//!    runs on the equivalent SPAD blink (500 on-planes + 108 off-planes).
//! 2. Throughput on all cores.
//! 3. EMCCD and sCMOS noise models.
//! 4. Pile-up: Poisson vs binomial MLE on bit-plane aggregates of growing
//!    signal (S detections per on-plane; S = 10 puts ~0.5 detections per
//!    plane on the centre pixel), and the asymmetric case (PRNU gradient).
//! 5. Hot pixels ignored vs interpolated.

use rand::SeedableRng;
use smartagg_localize::bench::{
    one_core_rate, score_frames, score_hot_pixels, score_spad, score_spad_hot_pixels,
    simulate_frames, simulate_spad, throughput_parallel, FrameScenario, Score, SpadScenario,
};
use smartagg_localize::spad::{fit_binomial, SpadEmitter, SpadRoi};
use smartagg_localize::{
    lm, synth, Estimator, FitOptions, HotPixelMode, NoiseModel, PixelMaps, RoiView, SigmaMode,
};
use std::time::Instant;

/// Arguments of `smartagg bench localize`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// ROIs per accuracy case.
    #[arg(long, default_value_t = 20_000)]
    pub rois: usize,
    /// SPAD ROIs per pile-up and hot-pixel case (the binomial fit is slower).
    #[arg(long, default_value_t = 4_000)]
    pub spad_rois: usize,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// ROIs per timed batch.
    #[arg(long, default_value_t = 1_000)]
    pub batch: usize,
    /// Timed passes over each set.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Pixel size for the nm column.
    #[arg(long, default_value_t = 53.33)]
    pub pixel_nm: f64,
}

fn fixed() -> FitOptions {
    FitOptions::new(SigmaMode::Fixed(1.5))
}

fn fitted() -> FitOptions {
    FitOptions::new(SigmaMode::Fitted { initial: 1.3 })
}

fn row(label: &str, sigma: &str, rate: (f64, f64), s: &Score, pixel_nm: f64) {
    println!(
        "  {label:<22} {sigma:<7} {:>10.0} {:>10.0}   {:>7.4} {:>6.2}  {:>7.4}   {:>6.3}   {:>6.3}  {:>6} {:>5.2}",
        rate.0,
        rate.1,
        s.rmse,
        s.rmse * pixel_nm,
        s.crlb,
        s.ratio(),
        s.reported_over_rmse,
        s.failures,
        s.iterations
    );
}

fn header() {
    println!(
        "  {:<22} {:<7} {:>10} {:>10}   {:>7} {:>6}  {:>7}   {:>6}   {:>6}  {:>6} {:>5}",
        "estimator",
        "sigma",
        "fits/s med",
        "fits/s max",
        "RMSE px",
        "nm",
        "CRLB px",
        "ratio",
        "unc/R",
        "failed",
        "iter"
    );
}

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.rois == 0 || args.spad_rois == 0 {
        anyhow::bail!("--rois and --spad-rois must be at least 1");
    }
    let started = Instant::now();
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|s| s.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "?".into());
    #[cfg(target_arch = "x86_64")]
    let simd = if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
        "AVX2+FMA build"
    } else {
        "baseline build"
    };
    #[cfg(not(target_arch = "x86_64"))]
    let simd = "baseline build";
    println!(
        "smartagg bench localize: {} cores, load average {load}, fits use the {simd}; rates are thread CPU time on one core",
        rayon::current_num_threads()
    );

    // 1. Accuracy and speed.
    for photons in [230.0, 1000.0] {
        let mut sc = FrameScenario::spcimager_blink(args.rois, args.seed);
        sc.photons = photons;
        let set = simulate_frames(&sc);
        println!();
        println!(
            "{} ROIs 9x9, sigma 1.5 px, {photons} photons, 5.9 background photons/px (ratio = RMSE/CRLB of the model fitted; unc/R = mean reported uncertainty / RMSE)",
            args.rois
        );
        header();
        for (label, est, opts, sig) in [
            ("centroid", Estimator::Centroid, fixed(), "-"),
            ("lsq", Estimator::Lsq, fitted(), "fitted"),
            ("mle", Estimator::Mle, fixed(), "fixed"),
            ("mle", Estimator::Mle, fitted(), "fitted"),
        ] {
            let s = score_frames(&set, est, &opts);
            let rate = one_core_rate(&set, est, &opts, args.batch, args.repeats);
            row(label, sig, rate, &s, args.pixel_nm);
        }
        // The same blink on a SPAD: S per on-plane over 500 planes.
        let spad = SpadScenario {
            side: 9,
            sigma: 1.5,
            signal_per_plane: photons / 500.0,
            background_per_plane: 0.0118,
            n_on: 500,
            n_off: 108,
            offset: (0.0, 0.0),
            jitter: 0.5,
            count: args.spad_rois,
            seed: args.seed,
        };
        let sset = simulate_spad(&spad);
        for (label, est, opts, sig) in [
            (
                "spad-mle (SPAD blink)",
                Estimator::SpadMle,
                fixed(),
                "fixed",
            ),
            (
                "spad-mle (SPAD blink)",
                Estimator::SpadMle,
                fitted(),
                "fitted",
            ),
            ("mle (SPAD blink)", Estimator::Mle, fitted(), "fitted"),
        ] {
            let s = score_spad(&sset, est, &opts);
            row(label, sig, (s.fits_per_s, s.fits_per_s), &s, args.pixel_nm);
        }
    }

    // 2. All cores.
    let set = simulate_frames(&FrameScenario::spcimager_blink(args.rois, args.seed + 1));
    println!();
    for (label, opts) in [("sigma fixed", fixed()), ("sigma fitted", fitted())] {
        let r = throughput_parallel(&set, Estimator::Mle, &opts);
        println!(
            "MLE on all {} cores, {label}: {r:.0} fits/s (wall clock)",
            rayon::current_num_threads()
        );
    }

    // 3. Camera noise models.
    println!();
    println!(
        "Camera noise models, MLE sigma fixed, 500 photons, 3 background photons/px ({} ROIs)",
        args.rois / 2
    );
    header();
    for (label, noise, var) in [
        ("mle emccd (F2 = 2)", NoiseModel::Emccd, 0.0),
        ("mle scmos (1.4 e- rms)", NoiseModel::Scmos, 1.96),
    ] {
        let mut sc = FrameScenario::spcimager_blink(args.rois / 2, args.seed + 2);
        sc.photons = 500.0;
        sc.background = 3.0;
        sc.noise = noise;
        sc.read_var = var;
        let set = simulate_frames(&sc);
        let mut o = fixed();
        o.noise = noise;
        let s = score_frames(&set, Estimator::Mle, &o);
        row(
            label,
            "fixed",
            (s.fits_per_s, s.fits_per_s),
            &s,
            args.pixel_nm,
        );
    }

    // 4. Pile-up.
    println!();
    println!(
        "Pile-up: SPAD ROIs 9x9, sigma 1.5 px, 200 on-planes + 108 off-planes, B = 0.0118/plane, sigma fitted ({} ROIs each)",
        args.spad_rois
    );
    println!(
        "  {:>6} {:>11}  {:>22}  {:>22}",
        "S", "p(centre)", "Poisson MLE: ph %, sg px", "binomial MLE: ph %, sg px"
    );
    for s in [0.46, 2.0, 5.0, 10.0] {
        let sc = SpadScenario {
            side: 9,
            sigma: 1.5,
            signal_per_plane: s,
            background_per_plane: 0.0118,
            n_on: 200,
            n_off: 108,
            offset: (0.0, 0.0),
            jitter: 0.0,
            count: args.spad_rois,
            seed: args.seed + 3,
        };
        let set = simulate_spad(&sc);
        let p = score_spad(&set, Estimator::Mle, &fitted());
        let b = score_spad(&set, Estimator::SpadMle, &fitted());
        let centre = smartagg_localize::psf::psf_image(9, 4.5, 4.5, 1.5)[40];
        let p_centre = -(-(s * centre + 0.0118f64)).exp_m1();
        println!(
            "  {s:>6.2} {p_centre:>11.3}  {:>+10.1} {:>+10.3}  {:>+10.1} {:>+10.3}   (RMSE/CRLB {:.3} vs {:.3})",
            100.0 * p.photon_bias,
            p.sigma_bias,
            100.0 * b.photon_bias,
            b.sigma_bias,
            p.ratio(),
            b.ratio()
        );
    }
    let (bp, bb, n) = asymmetric_bias(args.spad_rois, args.seed + 4);
    println!(
        "  asymmetric (PRNU 0.6 → 1.4 across the ROI, S = 10, {n} ROIs): x bias Poisson {:+.4} px ({:+.2} nm), binomial {:+.4} px ({:+.2} nm)",
        bp,
        bp * args.pixel_nm,
        bb,
        bb * args.pixel_nm
    );

    // 5. Hot pixels.
    println!();
    println!("Hot pixels masked by the pipeline (read 0): RMSE px when ignored vs interpolated, sigma fixed");
    println!(
        "  {:>8}  {:>24}  {:>24}",
        "fraction", "Poisson MLE (230 ph)", "SPAD binomial MLE"
    );
    let spad = SpadScenario {
        side: 9,
        sigma: 1.5,
        signal_per_plane: 0.46,
        background_per_plane: 0.0118,
        n_on: 500,
        n_off: 108,
        offset: (0.0, 0.0),
        jitter: 0.5,
        count: args.spad_rois,
        seed: args.seed + 5,
    };
    let sset = simulate_spad(&spad);
    let fsc = FrameScenario::spcimager_blink(args.spad_rois, args.seed + 5);
    for frac in [0.05, 0.1, 0.2] {
        let fi = score_hot_pixels(&fsc, frac, HotPixelMode::Ignore, &fixed());
        let fp = score_hot_pixels(&fsc, frac, HotPixelMode::Interpolate, &fixed());
        let si = score_spad_hot_pixels(&sset, frac, HotPixelMode::Ignore, &fixed());
        let sp = score_spad_hot_pixels(&sset, frac, HotPixelMode::Interpolate, &fixed());
        println!(
            "  {:>7.0}%  {:>10.4} vs {:>10.4}  {:>10.4} vs {:>10.4}",
            frac * 100.0,
            fi.rmse,
            fp.rmse,
            si.rmse,
            sp.rmse
        );
    }
    println!();
    println!("done in {:.1} s", started.elapsed().as_secs_f64());
    Ok(())
}

/// Mean x error of the Poisson and binomial MLE (σ fitted, gain map known to
/// both) under pile-up with a PRNU gradient across the ROI.
fn asymmetric_bias(n: usize, seed: u64) -> (f64, f64, usize) {
    let side = 9;
    let mut maps = PixelMaps::uniform(side);
    for j in 0..side {
        for i in 0..side {
            maps.gain[j * side + i] = 0.6 + 0.8 * i as f64 / 8.0;
        }
    }
    let em = SpadEmitter {
        x: 4.5,
        y: 4.5,
        sigma: 1.5,
        signal_per_plane: 10.0,
        background_per_plane: 0.0118,
    };
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let opts = fitted();
    let (mut bp, mut bb, mut k) = (0.0, 0.0, 0usize);
    for _ in 0..n {
        let c = synth::spad_roi(&mut rng, side, &em, 200, 108, Some(&maps));
        let f: Vec<f64> = c.iter().map(|&v| v as f64).collect();
        let p = lm::fit_mle(
            &RoiView {
                side,
                data: &f,
                maps: Some(&maps),
            },
            &opts,
        );
        let b = fit_binomial(
            &SpadRoi {
                side,
                counts: &c,
                n_on: 200,
                n_off: 108,
                maps: Some(&maps),
            },
            &opts,
        );
        if p.status.is_ok() && b.status.is_ok() {
            bp += p.x - em.x;
            bb += b.x - em.x;
            k += 1;
        }
    }
    let k1 = k.max(1) as f64;
    (bp / k1, bb / k1, k)
}
