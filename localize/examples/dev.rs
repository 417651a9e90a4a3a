use smartagg_localize::bench::*;
use smartagg_localize::*;
fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(20000);
    for photons in [230.0, 1000.0] {
        let mut sc = FrameScenario::spcimager_blink(n, 1);
        sc.photons = photons;
        let set = simulate_frames(&sc);
        for (est, fitted) in [
            (Estimator::Centroid, false),
            (Estimator::Lsq, true),
            (Estimator::Mle, false),
            (Estimator::Mle, true),
        ] {
            let sigma = if fitted {
                SigmaMode::Fitted {
                    initial: std::env::var("S0")
                        .map(|s| s.parse().unwrap())
                        .unwrap_or(1.3),
                }
            } else {
                SigmaMode::Fixed(1.5)
            };
            let opts = FitOptions::new(sigma);
            let s = score_frames(&set, est, &opts);
            println!("{photons} {:?} fitted={fitted}: {:.0} fits/s rmse {:.4} crlb {:.4} ratio {:.4} rep/rmse {:.3} fail {} it {:.2} bias {:.4} {:.4} ph {:.4} sg {:.4}",
                est, s.fits_per_s, s.rmse, s.crlb, s.ratio(), s.reported_over_rmse, s.failures, s.iterations, s.bias_x, s.bias_y, s.photon_bias, s.sigma_bias);
        }
    }
}
