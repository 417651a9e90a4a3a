use smartagg_sim::designs::{Config, DesignSpec, REDUCED};
use smartagg_sim::harness::{threshold_at_quantile, Case, Cosim, Source};
use smartagg_sim::scene::{generate, SceneSpec};

#[test]
fn smoke() {
    for cfg in [Config::Spcimager150] {
    let spec = DesignSpec::new(cfg, REDUCED.0, REDUCED.1).unwrap();
    let t = std::time::Instant::now();
    let mut c = Cosim::new(spec).unwrap();
    eprintln!("build {:?} {:?}", t.elapsed(), c.build());
    let planes = generate(&SceneSpec { width: 64, height: 32, planes: 200, background: 0.01, emitters: 6, peak: 0.5, mean_on: 20.0, mean_off: 40.0, edge_fraction: 0.3, dip: 0.05, hot: vec![(3,4)], hot_rate: 0.5 }, 1);
    let mut case = Case { n: 10, threshold: 1, l_min: 3, l_max: 200, planes, hot: vec![(3,4)], mask_enable: true, source: Source::Replay, input_stall: 20, read_stall: 20, hold_reads: false, seed: 3 };
    case.threshold = threshold_at_quantile(&c.model_config(&case).unwrap(), &case.planes, 0.99);
    let t = std::time::Instant::now();
    let r = c.check(&case).unwrap();
    eprintln!("run {:?} {:?}", t.elapsed(), r);
    }
}
