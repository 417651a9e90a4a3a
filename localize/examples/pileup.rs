use smartagg_localize::bench::*;
use smartagg_localize::*;
fn main() {
    for s in [0.2, 1.0, 3.0, 10.0] {
        for off in [(0.0, 0.0), (0.3, 0.0)] {
            let sc = SpadScenario {
                side: 9,
                sigma: 1.5,
                signal_per_plane: s,
                background_per_plane: 0.0118,
                n_on: 200,
                n_off: 108,
                offset: off,
                jitter: 0.0,
                count: 2000,
                seed: 3,
            };
            let set = simulate_spad(&sc);
            for est in [Estimator::Mle, Estimator::SpadMle] {
                for fitted in [false, true] {
                    let sigma = if fitted {
                        SigmaMode::Fitted { initial: 1.3 }
                    } else {
                        SigmaMode::Fixed(1.5)
                    };
                    let sc = score_spad(&set, est, &FitOptions::new(sigma));
                    println!("S={s} off={:?} {:?} fitted={fitted}: ph {:+.4} sg {:+.4} bx {:+.4} rmse {:.4} crlb {:.4} ratio {:.3} fail {} {:.0} fits/s it {:.1}", off, est, sc.photon_bias, sc.sigma_bias, sc.bias_x, sc.rmse, sc.crlb, sc.ratio(), sc.failures, sc.fits_per_s, sc.iterations);
                }
            }
        }
    }
}
