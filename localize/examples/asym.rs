use rand::SeedableRng;
use smartagg_localize::spad::{fit_binomial, SpadEmitter, SpadRoi};
use smartagg_localize::*;
fn main() {
    let side = 9;
    let mut maps = PixelMaps::uniform(side);
    for j in 0..side {
        for i in 0..side {
            maps.gain[j * side + i] = 0.6 + 0.8 * i as f64 / 8.0;
        }
    }
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for s in [1.0, 10.0] {
        let em = SpadEmitter {
            x: 4.5,
            y: 4.5,
            sigma: 1.5,
            signal_per_plane: s,
            background_per_plane: 0.0118,
        };
        let (mut bp, mut bb, mut pp, mut pb) = (0.0, 0.0, 0.0, 0.0);
        let n = 2000;
        for _ in 0..n {
            let c = synth::spad_roi(&mut rng, side, &em, 200, 108, Some(&maps));
            let f: Vec<f64> = c.iter().map(|&v| v as f64).collect();
            let opts = FitOptions::new(SigmaMode::Fitted { initial: 1.3 });
            let a = lm::fit_mle(
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
            bp += a.x - 4.5;
            pp += a.photons / (s * 200.0) - 1.0;
            bb += b.x - 4.5;
            pb += b.photons / (s * 200.0) - 1.0;
        }
        println!(
            "S={s}: poisson x-bias {:+.4} ph {:+.4} | binomial x-bias {:+.4} ph {:+.4}",
            bp / n as f64,
            pp / n as f64,
            bb / n as f64,
            pb / n as f64
        );
    }
}
