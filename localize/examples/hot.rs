use smartagg_localize::bench::*;
use smartagg_localize::crlb::*;
use smartagg_localize::*;
fn main() {
    for frac in [0.05, 0.1, 0.2] {
        let sc = FrameScenario::spcimager_blink(3000, 11);
        for fitted in [false, true] {
            let sigma = if fitted {
                SigmaMode::Fitted { initial: 1.3 }
            } else {
                SigmaMode::Fixed(1.5)
            };
            let o = FitOptions::new(sigma);
            let a = score_hot_pixels(&sc, frac, HotPixelMode::Ignore, &o);
            let b = score_hot_pixels(&sc, frac, HotPixelMode::Interpolate, &o);
            println!("frac {frac} fitted {fitted}: ignore rmse {:.4} fail {} | interp rmse {:.4} fail {} | crlb(no hot) {:.4}", a.rmse, a.failures, b.rmse, b.failures, a.crlb);
        }
    }
    for frac in [0.1, 0.2] {
        for seed in [1, 2] {
            let sc = SpadScenario {
                side: 9,
                sigma: 1.5,
                signal_per_plane: 0.45,
                background_per_plane: 0.0118,
                n_on: 500,
                n_off: 108,
                offset: (0.0, 0.0),
                jitter: 0.5,
                count: 2000,
                seed,
            };
            let set = simulate_spad(&sc);
            let o = FitOptions::new(SigmaMode::Fixed(1.5));
            let a = score_spad_hot_pixels(&set, frac, HotPixelMode::Ignore, &o);
            let b = score_spad_hot_pixels(&set, frac, HotPixelMode::Interpolate, &o);
            println!("SPAD frac {frac} seed {seed}: ignore rmse {:.4} fail {} | interp rmse {:.4} fail {} | crlb {:.4}", a.rmse, a.failures, b.rmse, b.failures, a.crlb);
            let fs = FrameScenario {
                count: 2000,
                seed,
                ..FrameScenario::spcimager_blink(2000, seed)
            };
            let a = score_hot_pixels(&fs, frac, HotPixelMode::Ignore, &o);
            let b = score_hot_pixels(&fs, frac, HotPixelMode::Interpolate, &o);
            println!(
                "Poisson frac {frac} seed {seed}: ignore rmse {:.4} | interp rmse {:.4}",
                a.rmse, b.rmse
            );
        }
    }
    for (n, b, side) in [
        (1000.0, 1.0, 25usize),
        (1000.0, 10.0, 25),
        (300.0, 2.0, 25),
        (5000.0, 0.5, 31),
    ] {
        let em = Emitter {
            x: side as f64 / 2.0,
            y: side as f64 / 2.0,
            sigma: 1.5,
            photons: n,
            background: b,
        };
        let c = crlb_frame(side, &em, None, NoiseModel::Poisson, false).unwrap();
        let m = mortensen_mle_variance(1.5, 1.0, n, b, 1.0);
        let cf = crlb_frame(side, &em, None, NoiseModel::Poisson, true).unwrap();
        println!(
            "N {n} b {b}: crlb fixed {:.5} fitted {:.5} mortensen {:.5} ratio {:.4} {:.4}",
            c.var_x,
            cf.var_x,
            m,
            c.var_x / m,
            cf.var_x / m
        );
    }
}
#[allow(dead_code)]
fn spad() {}
