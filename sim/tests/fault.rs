//! The harness catches faults: the spatial filter with an off-by-one tap
//! index (patched into the generated Verilog) must fail the comparison, and
//! the diagnosis must name the spatial filter (not the stages before it)
//! and write a VCD around the first difference.

use smartagg_sim::designs::{inject_filter_fault, Config, DesignSpec, REDUCED};
use smartagg_sim::harness::{threshold_at_quantile, Case, Cosim, Stage};
use smartagg_sim::scene::{generate, SceneSpec};

#[test]
fn an_injected_filter_fault_is_caught_and_named() {
    let spec = DesignSpec::new(Config::Projected150, REDUCED.0, REDUCED.1).unwrap();
    let top = spec.top_verilog().unwrap();
    let faulty = inject_filter_fault(&top).unwrap();
    assert_ne!(top, faulty);
    let mut c = Cosim::with_top_debug(spec, faulty).unwrap();
    let planes = generate(
        &SceneSpec {
            width: REDUCED.0,
            height: REDUCED.1,
            planes: 60,
            background: 0.003,
            emitters: 8,
            peak: 0.5,
            mean_on: 15.0,
            mean_off: 20.0,
            edge_fraction: 0.2,
            dip: 0.0,
            hot: Vec::new(),
            hot_rate: 0.0,
        },
        5,
    );
    let mut case = Case {
        input_stall: 10,
        read_stall: 10,
        seed: 9,
        ..Case::replay(8, 1, 1, 100, planes)
    };
    case.threshold = threshold_at_quantile(&c.model_config(&case).unwrap(), &case.planes, 0.99);
    let m = c
        .check(&case)
        .expect("the faulty design still runs")
        .expect_err("the harness must catch the fault");
    println!("{m}");
    assert_eq!(m.stage, Stage::SpatialFilter, "{m}");
    let vcd = m.vcd.as_ref().expect("a VCD of the window");
    let text = std::fs::read_to_string(vcd).unwrap();
    assert!(
        text.contains("$enddefinitions") && text.contains("filter"),
        "VCD {vcd:?}"
    );
}
