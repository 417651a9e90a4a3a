use smartagg_localize::bench::*;
use smartagg_localize::*;
fn main() {
    for photons in [230.0, 1000.0] {
        let mut sc = FrameScenario::spcimager_blink(20000, 1);
        sc.photons = photons;
        let set = simulate_frames(&sc);
        for sigma in [SigmaMode::Fixed(1.5), SigmaMode::Fitted { initial: 1.3 }] {
            let (med, best) = one_core_rate(&set, Estimator::Mle, &FitOptions::new(sigma), 1000, 3);
            println!("{photons} {sigma:?}: median {med:.0} best {best:.0}");
        }
    }
}
