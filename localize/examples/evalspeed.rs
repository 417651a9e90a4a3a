use smartagg_localize::bench::*;
fn main() {
    let set = simulate_frames(&FrameScenario::spcimager_blink(1, 1));
    let n = 1_000_000;
    let t = CpuTimer::start();
    let s =
        smartagg_localize::lm::bench_evaluate(&set.data[..81], 9, [4.5, 4.5, 230.0, 5.9, 1.5], n);
    let e = t.seconds();
    let t = CpuTimer::start();
    let s2 = smartagg_localize::lm::bench_axis(n);
    let a = t.seconds();
    println!(
        "{s} {s2} eval {:.1} ns, axis {:.1} ns ({:.0} / {:.0} cycles @2.445)",
        e * 1e9 / n as f64,
        a * 1e9 / n as f64,
        e * 2.445e9 / n as f64,
        a * 2.445e9 / n as f64
    );
}
