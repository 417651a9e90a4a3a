use smartagg_localize::bench::*;
use smartagg_localize::*;
fn main() {
    let fitted = std::env::args().nth(1).map(|s| s == "fitted").unwrap_or(true);
    let set = simulate_frames(&FrameScenario::spcimager_blink(2000, 1));
    let sigma = if fitted { SigmaMode::Fitted { initial: 1.3 } } else { SigmaMode::Fixed(1.5) };
    let opts = FitOptions::new(sigma);
    let mut acc = 0.0;
    for roi in set.data.chunks_exact(81) {
        acc += fit_roi(Estimator::Mle, &RoiView { side: 9, data: roi, maps: None }, &opts).x;
    }
    println!("{acc}");
}
