use smartagg_localize::bench::*;
use smartagg_localize::*;
fn main() {
    let fitted = std::env::args()
        .nth(1)
        .map(|s| s == "fitted")
        .unwrap_or(true);
    let reps: usize = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(10);
    let set = simulate_frames(&FrameScenario::spcimager_blink(10000, 1));
    let sigma = if fitted {
        SigmaMode::Fitted { initial: 1.3 }
    } else {
        SigmaMode::Fixed(1.5)
    };
    let opts = FitOptions::new(sigma);
    let t = CpuTimer::start();
    let mut acc = 0.0;
    for _ in 0..reps {
        for roi in set.data.chunks_exact(81) {
            let v = RoiView {
                side: 9,
                data: roi,
                maps: None,
            };
            acc += fit_roi(Estimator::Mle, &v, &opts).x;
        }
    }
    let s = t.seconds();
    println!(
        "{acc} {:.0} fits/s cpu, {:.0} wall",
        (reps * 10000) as f64 / s,
        (reps * 10000) as f64 / t.wall_seconds()
    );
}
