//! Stage-by-stage timing of the fast engine on a synthetic 320×240 stream
//! (background p per pixel-plane plus blinking Gaussian spots), next to the
//! golden front end. `cargo run --release -p smartagg-model --example
//! fast_engine_profile [planes] [p]`.

use smartagg_model::config::PipelineConfig;
use smartagg_model::fast_engine::{fast_pipeline, run_parallel, FastFrontEnd};
use smartagg_model::pipeline::{FrontEnd, GoldenFrontEnd, Pipeline};
use smartagg_model::plane::BitPlane;
use std::time::Instant;

/// CPU time of the calling thread, ns (robust to other jobs sharing the cores).
fn cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}

/// A stopwatch of wall and thread CPU time.
struct Watch(Instant, u64);
impl Watch {
    fn start() -> Watch {
        Watch(Instant::now(), cpu_ns())
    }
    /// (planes per wall second, planes per CPU second of this thread).
    fn rates(&self, planes: usize) -> (f64, f64) {
        (
            planes as f64 / self.0.elapsed().as_secs_f64(),
            planes as f64 / ((cpu_ns() - self.1) as f64 * 1e-9),
        )
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let planes: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(3000);
    let p: f64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(0.0118);
    let (w, h, n) = (320usize, 240usize, 108u32);
    let k1 = vec![2, 9, 26, 49, 84, 49, 26, 9, 2];
    let mut cfg = PipelineConfig::new(w, h, n, k1, 8, 0);
    let mean = n as f64 * p * 65536.0;
    let sd = (n as f64 * p * (1.0 - p) * 13380f64.powi(2)).sqrt();
    cfg.threshold_int = (mean + 4.0 * sd).ceil().max(1.0) as u32;
    cfg.threshold_hold = cfg.threshold_int;
    let mut s = 0x1234_5678_9abc_def1u64;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    };
    let cut = (p * u64::MAX as f64) as u64;
    let spots: Vec<(usize, usize)> = (0..12)
        .map(|i| (20 + (i * 97) % 280, 20 + (i * 53) % 200))
        .collect();
    let stream: Vec<BitPlane> = (0..planes)
        .map(|t| {
            BitPlane::from_fn(w, h, |x, y| {
                let on = spots.iter().enumerate().any(|(i, &(sx, sy))| {
                    (t / 200 + i) % 4 == 0 && x.abs_diff(sx) <= 1 && y.abs_diff(sy) <= 1
                });
                rnd() < cut || (on && rnd() % 4 == 0)
            })
        })
        .collect();
    let zero = BitPlane::zeros(w, h);
    let delayed = |i: usize| {
        if i >= n as usize {
            &stream[i - n as usize]
        } else {
            &zero
        }
    };
    let gp = planes.min(300);
    let t = Watch::start();
    let mut g = GoldenFrontEnd::new(&cfg);
    for (i, plane) in stream.iter().enumerate().take(gp) {
        g.push(plane, delayed(i));
    }
    let golden_front = t.rates(gp);
    let t = Watch::start();
    let mut f = FastFrontEnd::new(&cfg);
    let mut cands = 0;
    for (i, plane) in stream.iter().enumerate() {
        f.push(plane, delayed(i));
        cands += f.candidates().len();
    }
    let fast_front = t.rates(planes);
    let t = Watch::start();
    let mut pl = fast_pipeline(cfg.clone()).unwrap();
    let mut recs = 0;
    for pl_ in &stream {
        recs += pl.push_plane(pl_).unwrap().len();
    }
    let fast_pipe = t.rates(planes);
    let t = Watch::start();
    let mut gpipe = Pipeline::new(cfg.clone()).unwrap();
    for pl_ in &stream[..gp] {
        gpipe.push_plane(pl_).unwrap();
    }
    let golden_pipe = t.rates(gp);
    let mut par = [(0.0, 0.0); 2];
    for (k, threads) in [1usize, 2].into_iter().enumerate() {
        let t = Watch::start();
        let mut r = 0;
        run_parallel::<(), _, _, _>(
            cfg.clone(),
            stream.iter().cloned().map(Ok),
            threads,
            1024,
            |_| r += 1,
        )
        .unwrap();
        par[k] = t.rates(planes);
    }
    let (mask, _) = smartagg_model::hot_pixel_mask::HotPixelMask::from_pixels(
        w,
        h,
        &(0..200)
            .map(|i| ((i * 37) % w, (i * 91) % h))
            .collect::<Vec<_>>(),
    );
    let t = Watch::start();
    let mut ones = 0;
    for pl_ in &stream {
        ones += mask.apply(pl_).count_ones();
    }
    println!(
        "hot-pixel mask apply: {:.0?} planes/s ({ones} ones)",
        t.rates(planes)
    );
    println!(
        "T_int {} candidates {cands} records {recs}",
        cfg.threshold_int
    );
    println!("planes/s (wall, per CPU-s of the main thread):");
    println!("  golden front {golden_front:.0?}  golden pipeline {golden_pipe:.0?}");
    println!("  fast front {fast_front:.0?}  fast pipeline {fast_pipe:.0?}");
    println!("  parallel x1 {:.0?} x2 {:.0?}", par[0], par[1]);
}
