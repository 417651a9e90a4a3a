//! Checks of the detection statistics (paper Eq. 1–7), the integer kernel
//! and the false-alarm predictions.
//!
//! Formula checks recompute N and T with a separate, plain implementation
//! (Simpson integration of the Gaussian instead of erf, `1 − exp` instead of
//! expm1, plain loops); Monte-Carlo checks are seeded and sized to run in
//! about a second in the optimised test profile. Figures are printed
//! (`cargo test -p smartagg-model --test statistics -- --nocapture`).

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_model::false_alarm::{
    detection_probability, false_alarm_report, l_min_for_target, tail_probability,
    tail_probability_saddle_point, BackgroundProcess, Method, Neighbourhood,
};
use smartagg_model::kernel::IntegerKernel;
use smartagg_model::params::{Preset, PresetName};
use smartagg_model::stats::{derive, Detection, DetectionInputs, StatsError};
use std::sync::OnceLock;

// ---------------------------------------------------------------------------
// Independent reference implementation

/// ∫ of the N(0, σ²) density over [d − ½, d + ½], composite Simpson.
fn simpson_pixel(sigma: f64, d: f64) -> f64 {
    simpson_pixel_n(sigma, d, 4000)
}

/// The same with `n` (even) intervals.
fn simpson_pixel_n(sigma: f64, d: f64, n: usize) -> f64 {
    let (a, b) = (d - 0.5, d + 0.5);
    let h = (b - a) / n as f64;
    let f = |x: f64| {
        (-x * x / (2.0 * sigma * sigma)).exp() / (sigma * (2.0 * std::f64::consts::PI).sqrt())
    };
    let mut s = f(a) + f(b);
    for i in 1..n {
        let x = a + i as f64 * h;
        s += if i % 2 == 1 { 4.0 * f(x) } else { 2.0 * f(x) };
    }
    s * h / 3.0
}

/// `1 − e^{−x}`, with the Taylor series where the subtraction would cancel.
fn one_minus_exp(x: f64) -> f64 {
    if x < 1e-5 {
        x * (1.0 - x / 2.0 * (1.0 - x / 3.0))
    } else {
        1.0 - (-x).exp()
    }
}

struct Reference {
    n_real: f64,
    n: u32,
    t: f64,
    t_int: u64,
}

/// Eq. 1–7 written out plainly, with the kernel weights as given.
fn reference(inp: &DetectionInputs, weights: &[u32], shift: u8) -> Reference {
    let k = weights.len();
    let h = (k / 2) as f64;
    let norm = (1u64 << (2 * shift)) as f64;
    let g: Vec<f64> = (0..k)
        .map(|i| simpson_pixel(inp.sigma_px, i as f64 - h))
        .collect();
    let (mut ef_on, mut ef_off, mut vf_on, mut vf_off) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..k {
        for j in 0..k {
            let kk = weights[i] as f64 * weights[j] as f64 / norm;
            let x_on = inp.flux_hz * g[i] * g[j] * inp.eta * inp.tau_s
                + inp.background_rate_hz * inp.tau_s;
            let x_off = inp.background_rate_hz * inp.tau_s;
            let (p_on, p_off) = (one_minus_exp(x_on), one_minus_exp(x_off));
            ef_on += kk * p_on;
            ef_off += kk * p_off;
            vf_on += kk * kk * (1.0 - p_on) * p_on;
            vf_off += kk * kk * (1.0 - p_off) * p_off;
        }
    }
    let n_real = 9.0 * (vf_off.sqrt() + vf_on.sqrt()).powi(2) / (ef_on - ef_off).powi(2);
    let n = (n_real.ceil() as u32).max(1);
    let t = n as f64 * ef_off + 3.0 * (n as f64 * vf_off).sqrt();
    let t_int = ((t * norm).ceil() as u64).max(1);
    Reference {
        n_real,
        n,
        t,
        t_int,
    }
}

fn inputs(eta: f64, b: f64, flux: f64, tau: f64, sigma: f64) -> DetectionInputs {
    DetectionInputs {
        eta,
        background_rate_hz: b,
        flux_hz: flux,
        tau_s: tau,
        sigma_px: sigma,
        kernel_size: None,
        kernel_shift: 8,
    }
}

fn preset_detection(name: PresetName, objective: u32) -> Detection {
    let p = Preset::new(name, objective).unwrap();
    derive(&DetectionInputs::from_preset(&p, None).unwrap()).unwrap()
}

// ---------------------------------------------------------------------------
// Kernel

fn assert_kernel_invariants(k: &IntegerKernel, size: usize, shift: u8) {
    let w = &k.weights;
    assert_eq!(w.len(), size);
    assert_eq!(k.shift, shift);
    assert_eq!(
        w.iter().map(|&x| x as u64).sum::<u64>(),
        1u64 << shift,
        "{w:?}"
    );
    let c = size / 2;
    for d in 1..=c {
        assert_eq!(w[c + d], w[c - d], "not symmetric: {w:?}");
        assert!(w[c + d] <= w[c + d - 1], "not unimodal: {w:?}");
        assert!(w[c] >= w[c + d], "centre not largest: {w:?}");
    }
    assert_eq!(k.sum_2d(), 1u64 << (2 * shift));
    let total: u64 = (0..size)
        .flat_map(|i| (0..size).map(move |j| (i, j)))
        .map(|(i, j)| k.weight_2d(i, j))
        .sum();
    assert_eq!(total, k.sum_2d());
    let n2: f64 = k.normalised_2d().iter().flatten().sum();
    assert!((n2 - 1.0).abs() < 1e-15);
}

#[test]
fn kernel_invariants_on_a_fine_sigma_grid_for_every_shift() {
    let mut repaired = 0;
    for shift in 4..=12u8 {
        for i in 0..=1140 {
            let sigma = 0.3 + i as f64 * 0.005;
            let size = IntegerKernel::default_size(sigma);
            let k = IntegerKernel::gaussian(sigma, size, shift).unwrap();
            assert_kernel_invariants(&k, size, shift);
            // The rounding contract against an independent ideal (Simpson):
            // sides within 1 unit, centre within 2, unless the monotone
            // repair had to move units.
            let h = size / 2;
            let raw: Vec<f64> = (0..=h)
                .map(|d| simpson_pixel_n(sigma, d as f64, 200))
                .collect();
            let tot = raw[0] + 2.0 * raw[1..].iter().sum::<f64>();
            let scale = (1u64 << shift) as f64;
            let within = (0..=h).all(|d| {
                let err = (k.weights[h + d] as f64 - raw[d] / tot * scale).abs();
                err < if d == 0 { 2.0 } else { 1.0 } + 1e-9
            });
            if !within {
                repaired += 1;
            }
        }
    }
    // The repair only acts for wide kernels with few units.
    println!(
        "kernels needing the monotone repair: {repaired} of {}",
        9 * 1141
    );
    assert!(repaired < 9 * 1141 / 20, "{repaired}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]
    #[test]
    fn kernel_invariants_random(sigma in 0.3f64..=6.0, shift in 4u8..=12, half in 0usize..=31, default in any::<bool>()) {
        let size = if default { IntegerKernel::default_size(sigma) } else { 2 * half + 1 };
        let k = IntegerKernel::gaussian(sigma, size, shift).unwrap();
        assert_kernel_invariants(&k, size, shift);
    }
}

#[test]
fn kernel_quantisation_shrinks_with_shift() {
    let sigma = 1.5144827586206897;
    let q = |shift| {
        IntegerKernel::gaussian(sigma, 9, shift)
            .unwrap()
            .quantisation()
    };
    let (q4, q8, q12) = (q(4), q(8), q(12));
    println!(
        "sigma 1.51 k 9: Σ K² rel. error shift 4 {:.2e}, 8 {:.2e}, 12 {:.2e}",
        q4.sum_sq_rel_error, q8.sum_sq_rel_error, q12.sum_sq_rel_error
    );
    assert!(
        q12.max_abs_error_2d < q8.max_abs_error_2d && q8.max_abs_error_2d < q4.max_abs_error_2d
    );
    // Side taps are within one unit of the ideal, the centre within two.
    assert!(q8.max_abs_error_1d <= 2.0 / 256.0 && q12.max_abs_error_1d <= 2.0 / 4096.0);
    assert!(q8.sum_sq_rel_error.abs() < 5e-3, "{}", q8.sum_sq_rel_error);
    assert!(q12.sum_sq_rel_error.abs() < 5e-4);
}

// ---------------------------------------------------------------------------
// Eq. 1–7

fn formula_points() -> Vec<(&'static str, DetectionInputs)> {
    let spc = DetectionInputs::from_preset(&Preset::new(PresetName::Spcimager, 150).unwrap(), None)
        .unwrap();
    let (eta, b, tau, s) = (spc.eta, spc.background_rate_hz, spc.tau_s, spc.sigma_px);
    vec![
        ("spcimager 150x", spc.clone()),
        ("b = 0", inputs(eta, 0.0, 5e4, tau, s)),
        ("flux 1e3", inputs(eta, b, 1e3, tau, s)),
        ("flux 1e6", inputs(eta, b, 1e6, tau, s)),
        ("b tau = 1e-9", inputs(eta, 1e-5, 5e4, 1e-4, s)),
        ("I tau = 1e4", inputs(eta, b, 1e8, 1e-4, s)),
        ("sigma 0.3", inputs(eta, b, 5e4, tau, 0.3)),
        ("sigma 6", inputs(eta, b, 5e4, tau, 6.0)),
        (
            "shift 4, k 3",
            DetectionInputs {
                kernel_size: Some(3),
                kernel_shift: 4,
                ..spc.clone()
            },
        ),
        (
            "shift 12, k 15",
            DetectionInputs {
                kernel_size: Some(15),
                kernel_shift: 12,
                ..spc.clone()
            },
        ),
        ("eta 1, bright background", inputs(1.0, 2e3, 2e5, 1e-4, 2.2)),
    ]
}

#[test]
fn window_and_threshold_match_an_independent_implementation() {
    for (label, inp) in formula_points() {
        let d = derive(&inp).unwrap_or_else(|e| panic!("{label}: {e}"));
        let r = reference(&inp, &d.kernel_weights, d.kernel_shift);
        println!(
            "{label:>24}: N = {:.6} -> {} (ref {:.6} -> {}), T = {:.6} (ref {:.6}), T_int = {} (ref {})",
            d.n_window_real, d.n_window, r.n_real, r.n, d.threshold, r.t, d.threshold_int, r.t_int
        );
        assert!(
            ((d.n_window_real - r.n_real) / r.n_real).abs() < 1e-8,
            "{label}: N"
        );
        assert_eq!(d.n_window, r.n, "{label}: integer N");
        if r.t > 0.0 {
            assert!(((d.threshold - r.t) / r.t).abs() < 1e-8, "{label}: T");
        } else {
            assert_eq!(d.threshold, 0.0, "{label}: T");
        }
        assert!(d.threshold_int.abs_diff(r.t_int) <= 1, "{label}: T_int");
        // The reported moments follow from the same sums.
        let nf = d.n_window as f64;
        assert!((d.e_h_off - nf * d.e_f_off).abs() <= 1e-12 * d.e_h_off.max(1e-300));
        assert!((d.sd_h_on - (nf * d.var_f_on).sqrt()).abs() <= 1e-12 * d.sd_h_on.max(1e-300));
    }
}

#[test]
fn zero_background_gives_threshold_one_unit() {
    let spc = DetectionInputs::from_preset(&Preset::new(PresetName::Spcimager, 150).unwrap(), None)
        .unwrap();
    let d = derive(&DetectionInputs {
        background_rate_hz: 0.0,
        ..spc
    })
    .unwrap();
    assert_eq!(d.var_f_off, 0.0);
    assert_eq!(d.threshold, 0.0);
    assert_eq!(d.threshold_int, 1);
    assert_eq!(d.threshold_quantisation_rel, None);
    assert_eq!(d.gaussian_false_alarm_probability, 0.0);
}

#[test]
fn window_decreases_with_flux() {
    let spc = DetectionInputs::from_preset(&Preset::new(PresetName::Spcimager, 150).unwrap(), None)
        .unwrap();
    let mut last = (f64::INFINITY, u32::MAX);
    for i in 0..=60 {
        let flux = 1e3 * 10f64.powf(i as f64 / 10.0); // 1e3 .. 1e9
        let d = derive(&DetectionInputs {
            flux_hz: flux,
            ..spc.clone()
        })
        .unwrap();
        assert!(
            d.n_window_real < last.0,
            "flux {flux}: {} !< {}",
            d.n_window_real,
            last.0
        );
        assert!(d.n_window <= last.1);
        last = (d.n_window_real, d.n_window);
    }
    assert_eq!(last.1, 1, "a very bright molecule needs one plane");
}

#[test]
fn presets_give_the_papers_windows() {
    for (name, obj, lo, hi) in [
        (PresetName::Spcimager, 150, 100, 110),
        (PresetName::Spcimager, 60, 60, 70),
        (PresetName::SpcimagerProjected, 150, 15, 21),
    ] {
        let d = preset_detection(name, obj);
        println!(
            "{name} {obj}x: sigma {:.4} px, k {} {:?}, p_off {:.5}, N {:.3} -> {} (ideal kernel {:.3}), T {:.6}, T_int {} (rel. quantisation {:.1e}), Gaussian P(detect) {:.5}, P(false alarm) {:.3e}",
            d.sigma_px, d.kernel_size, d.kernel_weights, d.p_off, d.n_window_real, d.n_window,
            d.n_window_real_ideal_kernel, d.threshold, d.threshold_int,
            d.threshold_quantisation_rel.unwrap(), d.gaussian_detection_probability,
            d.gaussian_false_alarm_probability
        );
        assert!(
            (lo..=hi).contains(&d.n_window),
            "{name} {obj}: N = {}",
            d.n_window
        );
        let json = serde_json::to_value(&d).unwrap();
        for field in [
            "eta",
            "background_rate_hz",
            "flux_hz",
            "tau_s",
            "sigma_px",
            "kernel_size",
            "kernel_weights",
            "n_window",
            "threshold",
            "threshold_int",
        ] {
            assert!(json.get(field).is_some(), "JSON lacks {field}");
        }
    }
}

fn all_finite(d: &Detection) -> bool {
    let q = &d.kernel_quantisation;
    let scalars = [
        d.eta,
        d.background_rate_hz,
        d.flux_hz,
        d.tau_s,
        d.sigma_px,
        d.p_off,
        d.var_b_off,
        d.psf_fraction_in_window,
        d.e_f_off,
        d.var_f_off,
        d.e_f_on,
        d.var_f_on,
        d.n_window_real,
        d.n_window_real_ideal_kernel,
        d.threshold,
        d.threshold_unit,
        d.threshold_quantisation_abs,
        d.threshold_quantisation_rel.unwrap_or(0.0),
        d.e_h_off,
        d.sd_h_off,
        d.e_h_on,
        d.sd_h_on,
        d.gaussian_detection_probability,
        d.gaussian_false_alarm_probability,
        q.max_abs_error_1d,
        q.max_abs_error_2d,
        q.centre_rel_error_2d,
        q.sum_sq,
        q.sum_sq_ideal,
        q.sum_sq_rel_error,
    ];
    scalars
        .iter()
        .chain(&d.e_b_on)
        .chain(&d.var_b_on)
        .all(|v| v.is_finite())
}

#[test]
fn extreme_inputs_give_finite_results_or_an_undetectable_error() {
    let (mut ok, mut undetectable) = (0, 0);
    for eta in [1e-6, 0.091, 1.0] {
        for b in [0.0, 1e-5, 118.0, 1e5, 1e8] {
            for flux in [1e-3, 1e3, 5e4, 1e8, 1e12] {
                for tau in [1e-6, 1e-4, 1e-2] {
                    for sigma in [0.3, 1.5, 6.0] {
                        for shift in [4u8, 8, 12] {
                            let inp = DetectionInputs {
                                kernel_shift: shift,
                                ..inputs(eta, b, flux, tau, sigma)
                            };
                            match derive(&inp) {
                                Ok(d) => {
                                    ok += 1;
                                    assert!(all_finite(&d), "{inp:?} -> {d:?}");
                                    assert!(d.n_window >= 1 && d.threshold_int >= 1);
                                    for p in [
                                        d.gaussian_detection_probability,
                                        d.gaussian_false_alarm_probability,
                                        d.p_off,
                                    ] {
                                        assert!((0.0..=1.0).contains(&p));
                                    }
                                    // JSON must not carry nulls from NaN.
                                    let s = serde_json::to_string(&d).unwrap();
                                    assert!(
                                        !s.contains("null")
                                            || d.threshold_quantisation_rel.is_none(),
                                        "{s}"
                                    );
                                }
                                Err(StatsError::Undetectable { .. }) => undetectable += 1,
                                Err(e) => panic!("{inp:?}: unexpected error {e}"),
                            }
                        }
                    }
                }
            }
        }
    }
    println!("extreme grid: {ok} derived, {undetectable} undetectable");
    assert!(ok > 500 && undetectable > 100);
}

#[test]
fn undetectable_molecules_are_errors_that_say_why() {
    let base = inputs(0.091, 118.0, 5e4, 1e-4, 1.5);
    let cases = [
        (
            DetectionInputs {
                flux_hz: 0.0,
                ..base.clone()
            },
            "flux_hz = 0",
        ),
        (
            DetectionInputs {
                eta: 0.0,
                ..base.clone()
            },
            "eta = 0",
        ),
        (
            DetectionInputs {
                background_rate_hz: 1e9,
                ..base.clone()
            },
            "saturates",
        ),
        (
            DetectionInputs {
                flux_hz: 1e-2,
                ..base.clone()
            },
            "cap",
        ),
    ];
    for (inp, needle) in cases {
        let e = derive(&inp).unwrap_err();
        assert!(matches!(e, StatsError::Undetectable { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains("undetectable") && msg.contains(needle),
            "{msg}"
        );
    }
}

#[test]
fn invalid_inputs_name_the_parameter() {
    let base = inputs(0.091, 118.0, 5e4, 1e-4, 1.5);
    let cases = [
        (
            DetectionInputs {
                eta: 1.5,
                ..base.clone()
            },
            "`eta`",
        ),
        (
            DetectionInputs {
                eta: -0.1,
                ..base.clone()
            },
            "`eta`",
        ),
        (
            DetectionInputs {
                background_rate_hz: -1.0,
                ..base.clone()
            },
            "background_rate_hz",
        ),
        (
            DetectionInputs {
                flux_hz: f64::NAN,
                ..base.clone()
            },
            "flux_hz",
        ),
        (
            DetectionInputs {
                flux_hz: f64::INFINITY,
                ..base.clone()
            },
            "flux_hz",
        ),
        (
            DetectionInputs {
                tau_s: 0.0,
                ..base.clone()
            },
            "tau_s",
        ),
        (
            DetectionInputs {
                sigma_px: 7.0,
                ..base.clone()
            },
            "sigma_px",
        ),
        (
            DetectionInputs {
                kernel_shift: 3,
                ..base.clone()
            },
            "shift = 3",
        ),
        (
            DetectionInputs {
                kernel_size: Some(4),
                ..base.clone()
            },
            "size = 4",
        ),
    ];
    for (inp, needle) in cases {
        let msg = derive(&inp).unwrap_err().to_string();
        assert!(msg.contains(needle), "{needle}: {msg}");
    }
    let msg = derive(&inputs(1.0, 0.0, 1e308, 1e10, 1.0))
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("flux_hz") && msg.contains("overflows"),
        "{msg}"
    );
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let msg = DetectionInputs::from_preset(&p, Some(-5.0))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("flux_hz"), "{msg}");
}

// ---------------------------------------------------------------------------
// Exact tail: brute force and saddle point

/// P(H ≥ t) for all t by enumerating every Bernoulli pixel-plane (k = 3, N = 2).
#[test]
fn lattice_tail_equals_brute_force_enumeration() {
    for kernel in [
        IntegerKernel::gaussian(0.7, 3, 4).unwrap(),
        IntegerKernel {
            shift: 4,
            weights: vec![5, 6, 5],
            sigma_px: 2.0,
        },
    ] {
        let w: Vec<u64> = (0..9).map(|i| kernel.weight_2d(i / 3, i % 3)).collect();
        for p in [0.03f64, 0.4] {
            // Bits: 9 pixels × 2 planes.
            let max = 2 * 256;
            let mut pmf = vec![0.0f64; max + 1];
            for bits in 0u32..(1 << 18) {
                let ones = bits.count_ones() as i32;
                let prob = p.powi(ones) * (1.0 - p).powi(18 - ones);
                let h: u64 = (0..18)
                    .filter(|b| (bits >> b) & 1 == 1)
                    .map(|b| w[b % 9])
                    .sum();
                pmf[h as usize] += prob;
            }
            let mut tail = 0.0;
            for t in (0..=max).rev() {
                tail += pmf[t];
                let got = tail_probability(&kernel, 2, p, t as u64).unwrap();
                assert_eq!(got.method, Method::Exact);
                assert!(
                    (got.p - tail).abs() <= 1e-12 * tail + 1e-300,
                    "{:?} p {p} t {t}: {} vs {tail}",
                    kernel.weights,
                    got.p
                );
            }
        }
    }
}

/// Same with pixel counts (k = 3, N = 3): 4^9 count combinations.
#[test]
fn lattice_tail_equals_enumeration_of_counts() {
    let kernel = IntegerKernel {
        shift: 5,
        weights: vec![7, 18, 7],
        sigma_px: 1.0,
    };
    let (n, p) = (3usize, 0.2f64);
    let binom = [1.0, 3.0, 3.0, 1.0];
    let pc: Vec<f64> = (0..=n)
        .map(|s| binom[s] * p.powi(s as i32) * (1.0 - p).powi((n - s) as i32))
        .collect();
    let w: Vec<u64> = (0..9).map(|i| kernel.weight_2d(i / 3, i % 3)).collect();
    let max = (n as u64) * 1024;
    let mut pmf = vec![0.0f64; max as usize + 1];
    for combo in 0..4usize.pow(9) {
        let (mut c, mut prob, mut h) = (combo, 1.0, 0u64);
        for wi in &w {
            let s = c % 4;
            c /= 4;
            prob *= pc[s];
            h += wi * s as u64;
        }
        pmf[h as usize] += prob;
    }
    let mut tail = 0.0;
    for t in (0..=max).rev() {
        tail += pmf[t as usize];
        if t % 7 == 0 || tail < 1e-6 {
            let got = tail_probability(&kernel, n as u32, p, t).unwrap().p;
            assert!(
                (got - tail).abs() <= 1e-13 * tail + 1e-300,
                "t {t}: {got} vs {tail}"
            );
        }
    }
}

#[test]
fn saddle_point_agrees_with_the_exact_tail() {
    // (sigma, shift, N, p): a preset-like lumpy case and smoother ones.
    let cases = [
        (1.5144827586206897, 8u8, 109u32, 0.011742424348639889),
        (0.6057931034482759, 6, 65, 0.0211),
        (1.0, 6, 400, 0.02),
        (2.0, 5, 1000, 0.01),
        (0.5, 4, 50, 0.05),
        (3.0, 4, 2000, 0.001),
    ];
    let mut overall: f64 = 0.0;
    for (sigma, shift, n, p) in cases {
        let k = IntegerKernel::gaussian(sigma, IntegerKernel::default_size(sigma), shift).unwrap();
        let q = k.quantisation();
        let unit = k.sum_2d() as f64;
        let mean = n as f64 * p * unit;
        let sd = (n as f64 * p * (1.0 - p) * q.sum_sq).sqrt() * unit;
        let (mut worst, mut count, mut z) = (0.0f64, 0, 1.5);
        loop {
            let t = (mean + z * sd).ceil() as u64;
            let exact = tail_probability(&k, n, p, t).unwrap();
            assert_eq!(exact.method, Method::Exact);
            if exact.p < 1e-9 {
                break;
            }
            if exact.p <= 1e-2 {
                let sp = tail_probability_saddle_point(&k, n, p, t).unwrap();
                worst = worst.max(((sp - exact.p) / exact.p).abs());
                count += 1;
            }
            z += 0.25;
        }
        println!("saddle point vs exact, sigma {sigma} shift {shift} N {n} p {p}: max rel. error {worst:.2e} over {count} thresholds (tails 1e-2..1e-9)");
        assert!(count >= 8);
        overall = overall.max(worst);
    }
    assert!(overall < 0.05, "{overall}");
}

// ---------------------------------------------------------------------------
// Pair probabilities against a plain joint enumeration

/// Joint law of two windows sharing `shared` planes with `a` and `d`
/// private planes, built pixel by pixel from (a, c, d) counts:
/// X = Σ w(a + c), Y = Σ w(c + d), values clamped at T.
fn joint_reference(
    kernel: &IntegerKernel,
    shared: u32,
    a: u32,
    d: u32,
    p: f64,
    t: u64,
) -> Vec<Vec<f64>> {
    let binom = |m: u32| -> Vec<f64> {
        let mut v = vec![0.0; m as usize + 1];
        for (s, x) in v.iter_mut().enumerate() {
            let mut c = 1.0;
            for i in 0..s {
                c = c * (m as usize - i) as f64 / (i + 1) as f64;
            }
            *x = c * p.powi(s as i32) * (1.0 - p).powi((m as usize - s) as i32);
        }
        v
    };
    let (pa, pc, pd) = (binom(a), binom(shared), binom(d));
    let ts = t as usize + 1;
    let mut joint = vec![vec![0.0; ts]; ts];
    joint[0][0] = 1.0;
    let k = kernel.size();
    for i in 0..k * k {
        let w = kernel.weight_2d(i / k, i % k) as usize;
        let mut next = vec![vec![0.0; ts]; ts];
        for (x, row) in joint.iter().enumerate() {
            for (y, &m) in row.iter().enumerate() {
                if m == 0.0 {
                    continue;
                }
                for (sa, &qa) in pa.iter().enumerate() {
                    for (sc, &qc) in pc.iter().enumerate() {
                        for (sd, &qd) in pd.iter().enumerate() {
                            let nx = (x + w * (sa + sc)).min(t as usize);
                            let ny = (y + w * (sc + sd)).min(t as usize);
                            next[nx][ny] += m * qa * qc * qd;
                        }
                    }
                }
            }
        }
        joint = next;
    }
    joint
}

#[test]
fn two_window_probabilities_match_a_joint_enumeration() {
    let kernel = IntegerKernel {
        shift: 3,
        weights: vec![1, 6, 1],
        sigma_px: 0.5,
    };
    let (n, p) = (4u32, 0.15);
    let t = 120u64;
    let ti = t as usize;
    let bp = BackgroundProcess::new(&kernel, n, p, t).unwrap();
    for r in 1..n {
        // (H_t, H_{t+r}): N − r shared planes, r private each.
        let j = joint_reference(&kernel, n - r, r, r, p, t);
        let both = j[ti][ti];
        let got = bp.pair(r).unwrap();
        assert!((got - both).abs() < 1e-13, "r {r}: {got} vs {both}");
        let single: f64 = (0..=ti).map(|y| j[ti][y]).sum();
        assert!((bp.single().p - single).abs() < 1e-13);
        if r == 1 {
            // E = {X ≥ T or Y ≥ T}; U = {X < T ≤ Y} (X one plane earlier).
            let either: f64 = 1.0
                - (0..ti)
                    .flat_map(|x| (0..ti).map(move |y| (x, y)))
                    .map(|(x, y)| j[x][y])
                    .sum::<f64>();
            let up: f64 = (0..ti).map(|x| j[x][ti]).sum();
            assert!(
                (bp.either() - either).abs() < 1e-13,
                "{} vs {either}",
                bp.either()
            );
            assert!(
                (bp.upcrossing() - up).abs() < 1e-13,
                "{} vs {up}",
                bp.upcrossing()
            );
        }
        // (H_t, W) with W over N + 1 planes: r and r + 1 private planes.
        let jw = joint_reference(&kernel, n - r, r, r + 1, p, t);
        let got = bp.pair_with_wide_window(r).unwrap();
        assert!(
            (got - jw[ti][ti]).abs() < 1e-13,
            "wide r {r}: {got} vs {}",
            jw[ti][ti]
        );
        assert!(got >= bp.pair(r).unwrap() && got >= bp.pair(r + 1).unwrap());
    }
    assert!((bp.pair(n).unwrap() - bp.single().p.powi(2)).abs() < 1e-15);
    assert_eq!(bp.pair_with_wide_window(0), None);
}

// ---------------------------------------------------------------------------
// Monte-Carlo

/// Inverse-CDF table of Binomial(n, p) (the number of successes among n
/// independent Bernoulli(p) pixel-planes), from plain products.
fn binomial_cdf(n: u32, p: f64) -> Vec<f64> {
    let mut cdf = Vec::with_capacity(n as usize + 1);
    let mut term = (1.0 - p).powi(n as i32);
    let mut acc = 0.0;
    for s in 0..=n {
        acc += term;
        cdf.push(acc);
        term *= (n - s) as f64 / (s + 1) as f64 * p / (1.0 - p);
    }
    cdf
}

fn draw(cdf: &[f64], rng: &mut ChaCha8Rng) -> usize {
    let u: f64 = rng.gen();
    cdf.iter().position(|&c| u < c).unwrap_or(cdf.len() - 1)
}

#[test]
fn monte_carlo_detection_probability_meets_eq5() {
    let d = preset_detection(PresetName::Spcimager, 150);
    let kernel = d.kernel();
    let k = kernel.size();
    let exact = detection_probability(&d).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_0001);
    // Each pixel's count over the N planes is the sum of N Bernoulli(E(B_on))
    // bits, i.e. Binomial(N, E(B_on)); drawn by inverse CDF.
    let cdfs: Vec<Vec<f64>> = d
        .e_b_on
        .iter()
        .map(|&p| binomial_cdf(d.n_window, p))
        .collect();
    let weights: Vec<u64> = (0..k * k).map(|i| kernel.weight_2d(i / k, i % k)).collect();
    let trials = 200_000;
    let mut detected = 0u64;
    for _ in 0..trials {
        let h: u64 = cdfs
            .iter()
            .zip(&weights)
            .map(|(c, w)| w * draw(c, &mut rng) as u64)
            .sum();
        if h >= d.threshold_int {
            detected += 1;
        }
    }
    let rate = detected as f64 / trials as f64;
    let se = (rate * (1.0 - rate) / trials as f64).sqrt();
    println!(
        "detection (SPCIMAGER 150x, N {}, T_int {}): Monte-Carlo {rate:.5} ± {se:.5}, exact {:.6}, Gaussian {:.6}",
        d.n_window, d.threshold_int, exact.detection, d.gaussian_detection_probability
    );
    assert!(rate >= 0.99, "Eq. 5 promises ~99 %: {rate}");
    assert!(
        (rate - exact.detection).abs() < 4.0 * se,
        "MC {rate} vs exact {}",
        exact.detection
    );
    assert!(exact.detection >= 0.99 && (exact.detection + exact.miss - 1.0).abs() < 1e-12);
}

/// Background-only H over a long run at one pixel and the 3×3 around it.
struct BackgroundRun {
    planes: u64,
    /// Planes with H ≥ T at the centre pixel, per batch.
    batches: Vec<u64>,
    /// Excursions of the centre pixel with on-length ≥ L, index L.
    pixel_excursions: Vec<u64>,
    /// Tracks anchored at the centre, kept on by the 3×3 max, on-length ≥ L.
    max3_excursions: Vec<u64>,
}

struct Excursion {
    active: bool,
    start: u64,
    below_prev: bool,
}

impl Excursion {
    /// Advances one plane; returns the on-length of an excursion that ended.
    fn step(&mut self, t: u64, start_now: bool, on_now: bool) -> Option<u64> {
        if !self.active {
            if start_now {
                *self = Excursion {
                    active: true,
                    start: t,
                    below_prev: false,
                };
            }
            return None;
        }
        if on_now {
            self.below_prev = false;
            None
        } else if self.below_prev {
            self.active = false;
            Some(t - 1 - self.start) // t_drop = t − 1
        } else {
            self.below_prev = true;
            None
        }
    }
}

fn simulate_background(d: &Detection, planes: u64, batches: usize, seed: u64) -> BackgroundRun {
    let kernel = d.kernel();
    let k = kernel.size();
    let h = k / 2;
    let side = k + 2; // region covering the kernels of the 3×3 centre pixels
    let n = d.n_window as usize;
    // For each region pixel: (target index 0..9, weight) it feeds.
    let mut feeds: Vec<Vec<(usize, u64)>> = vec![Vec::new(); side * side];
    for (y, x) in (0..side).flat_map(|y| (0..side).map(move |x| (y, x))) {
        for t in 0..9 {
            let (cy, cx) = (side / 2 + t / 3 - 1, side / 2 + t % 3 - 1);
            let (ky, kx) = (
                y as isize - cy as isize + h as isize,
                x as isize - cx as isize + h as isize,
            );
            if (0..k as isize).contains(&ky) && (0..k as isize).contains(&kx) {
                feeds[y * side + x].push((t, kernel.weight_2d(ky as usize, kx as usize)));
            }
        }
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    // Each plane: how many of the region's pixels fire (Binomial), then which
    // (distinct, uniformly): exactly independent Bernoulli(p_off) pixels.
    let px = side * side;
    let cdf = binomial_cdf(px as u32, d.p_off);
    let warm = n as u64;
    let total = planes + warm;
    let mut ring = vec![[0u64; 9]; n];
    let mut hsum = [0u64; 9];
    let t_int = d.threshold_int;
    let cap = 4 * n + 64;
    let mut run = BackgroundRun {
        planes,
        batches: vec![0; batches],
        pixel_excursions: vec![0; cap + 1],
        max3_excursions: vec![0; cap + 1],
    };
    let per_batch = planes / batches as u64;
    let (mut pix, mut max3) = (
        Excursion {
            active: false,
            start: 0,
            below_prev: false,
        },
        Excursion {
            active: false,
            start: 0,
            below_prev: false,
        },
    );
    let record = |hist: &mut Vec<u64>, len: u64| {
        let len = (len as usize).min(cap);
        hist[len] += 1;
    };
    for t in 0..total {
        let mut f = [0u64; 9];
        let hits = draw(&cdf, &mut rng);
        let mut fired = [usize::MAX; 32];
        assert!(hits < fired.len(), "this sampler is for sparse planes");
        for i in 0..hits {
            let pixel = loop {
                let c = rng.gen_range(0..px);
                if !fired[..i].contains(&c) {
                    break c;
                }
            };
            fired[i] = pixel;
            for &(target, w) in &feeds[pixel] {
                f[target] += w;
            }
        }
        let slot = (t % n as u64) as usize;
        for i in 0..9 {
            hsum[i] = hsum[i] + f[i] - ring[slot][i];
        }
        ring[slot] = f;
        if t < warm {
            continue;
        }
        let tt = t - warm;
        let centre_on = hsum[4] >= t_int;
        let any_on = hsum.iter().any(|&v| v >= t_int);
        if centre_on {
            run.batches[((tt / per_batch) as usize).min(batches - 1)] += 1;
        }
        if let Some(len) = pix.step(tt, centre_on, centre_on) {
            record(&mut run.pixel_excursions, len);
        }
        if let Some(len) = max3.step(tt, centre_on, any_on) {
            record(&mut run.max3_excursions, len);
        }
    }
    // Excursions still on at the end count with their length so far.
    if pix.active {
        record(&mut run.pixel_excursions, planes - pix.start);
    }
    if max3.active {
        record(&mut run.max3_excursions, planes - max3.start);
    }
    // Turn histograms into "on-length ≥ L" counts.
    for hist in [&mut run.pixel_excursions, &mut run.max3_excursions] {
        for l in (0..cap).rev() {
            hist[l] += hist[l + 1];
        }
    }
    run
}

struct Shared {
    det: Detection,
    process: BackgroundProcess,
    run: BackgroundRun,
}

fn shared() -> &'static Shared {
    static SHARED: OnceLock<Shared> = OnceLock::new();
    SHARED.get_or_init(|| {
        let det = preset_detection(PresetName::Spcimager, 150);
        let process = BackgroundProcess::from_detection(&det).unwrap();
        let run = simulate_background(&det, 10_000_000, 100, 0x5eed_0002);
        Shared { det, process, run }
    })
}

#[test]
fn monte_carlo_false_alarms_match_the_exact_tail_not_the_gaussian() {
    let s = shared();
    let d = &s.det;
    let exact = s.process.single();
    assert_eq!(exact.method, Method::Exact);
    let per_batch = (s.run.planes / s.run.batches.len() as u64) as f64;
    let rates: Vec<f64> = s
        .run
        .batches
        .iter()
        .map(|&c| c as f64 / per_batch)
        .collect();
    let nb = rates.len() as f64;
    let mean = rates.iter().sum::<f64>() / nb;
    let var = rates.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (nb - 1.0);
    let se = (var / nb).sqrt(); // batch means: valid despite overlapping windows
    let gauss = d.gaussian_false_alarm_probability;
    let report = false_alarm_report(d, 320, 240, 1e4).unwrap();
    println!(
        "false alarms per pixel-plane (SPCIMAGER 150x): Monte-Carlo {mean:.5e} ± {se:.1e} ({} planes), exact {:.5e}, Gaussian {gauss:.5e} (exact/Gaussian = {:.2}); full field at 10 kHz: {:.3e}/s exact, {:.3e}/s Gaussian",
        s.run.planes, exact.p, exact.p / gauss, report.per_second, report.gaussian_per_second
    );
    assert!(
        (mean - exact.p).abs() < 4.0 * se,
        "MC {mean} ± {se} vs exact {}",
        exact.p
    );
    assert!(
        mean - gauss > 10.0 * se,
        "the Gaussian should be clearly too low"
    );
    assert!((report.per_pixel_plane - exact.p).abs() < 1e-15);
    assert_eq!(report.field_pixels, 76_800);
}

#[test]
fn false_blink_bound_holds_in_monte_carlo() {
    let s = shared();
    let n = s.det.n_window;
    for (nb, hist) in [
        (Neighbourhood::Pixel, &s.run.pixel_excursions),
        (Neighbourhood::Max3x3, &s.run.max3_excursions),
    ] {
        for l in [
            1,
            2,
            5,
            10,
            20,
            40,
            60,
            80,
            100,
            n + 1,
            n + 2,
            n + 20,
            2 * n,
        ] {
            let measured = hist[(l as usize).min(hist.len() - 1)];
            let bound = s.process.false_blink_bound(l, nb).unwrap();
            let expected_max = bound.per_pixel_plane * s.run.planes as f64;
            println!(
                "{nb:?} L {l:>3}: measured {measured:>6} excursions, bound {expected_max:>10.1} (measured/bound {:.3})",
                measured as f64 / expected_max
            );
            // The bound is on the expectation; allow 3 sd of Poisson noise.
            assert!(
                (measured as f64) <= expected_max + 3.0 * expected_max.sqrt() + 1.0,
                "{nb:?} L {l}: {measured} > bound {expected_max}"
            );
        }
    }
}

#[test]
fn l_min_for_the_full_field() {
    let s = shared();
    let d = &s.det;
    let (pixels, rate, target) = (320u64 * 240, 1e4, 1.0);
    let l = s
        .process
        .l_min_for_target(Neighbourhood::Pixel, pixels, rate, target)
        .unwrap();
    let l3 = s
        .process
        .l_min_for_target(Neighbourhood::Max3x3, pixels, rate, target)
        .unwrap();
    let at =
        |l, nb| s.process.false_blink_bound(l, nb).unwrap().per_pixel_plane * pixels as f64 * rate;
    println!(
        "L_min for 320x240 at 10 kHz, 1 false blink/s (N = {}): {l} planes (pixel rule, bound {:.2}/s), {l3} planes (3x3 rule, bound {:.2}/s)",
        d.n_window,
        at(l, Neighbourhood::Pixel),
        at(l3, Neighbourhood::Max3x3)
    );
    assert!(at(l, Neighbourhood::Pixel) <= target && at(l - 1, Neighbourhood::Pixel) > target);
    assert!(at(l3, Neighbourhood::Max3x3) <= target && at(l3 - 1, Neighbourhood::Max3x3) > target);
    assert!(l > d.n_window && l3 >= l);
    // One molecule in a small field with a lenient target: the paper's L = 1.
    assert_eq!(
        s.process
            .l_min_for_target(Neighbourhood::Pixel, 1, 1e4, 100.0)
            .unwrap(),
        1
    );
    // The free function gives the same as the method (cheaper preset).
    let dp = preset_detection(PresetName::SpcimagerProjected, 150);
    let free = l_min_for_target(
        &dp.kernel(),
        dp.n_window,
        dp.p_off,
        dp.threshold_int,
        pixels,
        rate,
        target,
    )
    .unwrap();
    let method = BackgroundProcess::from_detection(&dp)
        .unwrap()
        .l_min_for_target(Neighbourhood::Pixel, pixels, rate, target)
        .unwrap();
    println!("projected 150x (N = {}): L_min {free}", dp.n_window);
    assert_eq!(free, method);
}
