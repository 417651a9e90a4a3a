//! Verilog generation: Verilator lint (-Wall with the line-narrowed waivers
//! of the generated `top.vlt`, no warning left) of the front halves and of
//! the XEM6310 top, a yosys Spartan-6 synthesis
//! of the test configuration's front half, and the XEM6310 constraints
//! (`constraints/xem6310.ucf`) against the top's ports.
//! The tools are required: a missing tool fails with an install hint.

use smartagg_hdl::designs::on_generation_stack;
use smartagg_hdl::designs::Spcimager150Xem;
use smartagg_hdl::designs::TestXem;
use smartagg_hdl::front_half::{
    spcimager150_config, test_front_half_verilog, verilog, Spcimager150FrontHalf,
};
use smartagg_hdl::lint_waivers::verilator_config;
use smartagg_hdl::pipeline::{spcimager150_back_config, test_back_config};
use smartagg_hdl::synth::{
    verilator_lint, yosys_resources, yosys_script, LUT_LEVELS_TARGET, MAPPINGS,
};

fn scratch(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("smartagg-hdl-{name}-{}", std::process::id()))
}

#[test]
fn generated_verilog_passes_verilator_lint() {
    let v = test_front_half_verilog().unwrap();
    assert!(v.contains("module top("));
    let dir = scratch("lint");
    if let Err(e) = verilator_lint(&v, &dir) {
        panic!("{e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn spcimager_150x_verilog_passes_verilator_lint() {
    let v = verilog(Spcimager150FrontHalf::new(&spcimager150_config()).unwrap());
    let dir = scratch("lint150");
    if let Err(e) = verilator_lint(&v, &dir) {
        panic!("{e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn yosys_maps_the_test_front_half_to_spartan6() {
    let v = test_front_half_verilog().unwrap();
    let dir = scratch("yosys");
    let s = yosys_resources(&v, &dir, &MAPPINGS).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("{s:?}");
    // The script that made the figures is left beside them.
    let script = std::fs::read_to_string(dir.join("synth.ys")).unwrap();
    assert_eq!(script, yosys_script(&MAPPINGS));
    let _ = std::fs::remove_dir_all(dir);
    // The delay line alone is 7 x 96 bits of memory; no multiplier.
    assert!(s.memory_bits >= 7 * 96, "{s:?}");
    assert_eq!(s.multipliers, 0, "{s:?}");
    let names: Vec<&str> = s.netlists.iter().map(|n| n.mapping.name).collect();
    assert_eq!(names, ["abc-d7", "abc-d7-il", "abc", "abc9"]);
    for n in &s.netlists {
        let r = &n.resources;
        let name = n.mapping.name;
        assert!(
            r.logic_depth.is_some_and(|d| d > 2 && d < 100),
            "{name} {r:?}"
        );
        // LUT levels never exceed the cells yosys counts on the longest path.
        let l = r.lut_levels.as_ref().expect("LUT levels");
        assert!(
            l.levels >= 1 && u64::from(l.levels) <= r.logic_depth.unwrap(),
            "{name} {r:?}"
        );
        assert!(!l.path.is_empty(), "{name} {r:?}");
        assert_eq!(l.ends.first().map(|e| e.1), Some(l.levels), "{name} {r:?}");
        assert_eq!(
            l.ends_per_level().iter().sum::<usize>(),
            l.ends.len(),
            "{name}"
        );
        // The test configuration gives the filter no DSP slice: every
        // multiply is shift-and-add.
        assert_eq!(r.dsp48a1, 0, "{name} {r:?}");
        // The delay line (7 planes x 96 bits) and the counter memory are
        // memories, not flip-flops.
        assert!(r.ramb8 + r.ramb16 + r.lutram > 0, "{name} {r:?}");
        assert!(r.luts > 100 && r.ffs > 100, "{name} {r:?}");
        assert!(r.inverters <= r.luts, "{name} {r:?}");
    }
    // The same prepared design under every mapping: the same flip-flops
    // and memories; only the LUTs differ.
    let first = &s.netlists[0].resources;
    for n in &s.netlists[1..] {
        assert_eq!(n.resources.ffs, first.ffs, "{}", n.mapping.name);
        assert_eq!(
            (n.resources.ramb16, n.resources.ramb8),
            (first.ramb16, first.ramb8),
            "{}",
            n.mapping.name
        );
    }
    // The bounded mapping keeps to its target wherever the level-optimal
    // one can.
    let levels = |name: &str| {
        s.netlist(name)
            .and_then(|n| n.resources.lut_levels.as_ref())
            .map(|l| l.levels)
            .unwrap()
    };
    assert!(
        levels("abc-d7") <= LUT_LEVELS_TARGET.max(levels("abc")),
        "{s:?}"
    );
}

/// The bits of the top module's ports: `name` for one bit, `name[i]` for
/// each bit of a vector.
fn top_port_bits(v: &str) -> Vec<String> {
    let start = v.find("module top(").expect("top module");
    let body = &v[start..];
    let end = body.find("endmodule").expect("end of top");
    let mut bits = Vec::new();
    for line in body[..end].lines() {
        let line = line.trim();
        let Some(decl) = ["input wire ", "output reg ", "output wire ", "inout wire "]
            .iter()
            .find_map(|k| line.strip_prefix(k))
        else {
            continue;
        };
        let decl = decl.trim().trim_end_matches(';').trim();
        if let Some(rest) = decl.strip_prefix('[') {
            let (range, name) = rest.split_once(']').unwrap();
            let (hi, lo) = range.split_once(':').unwrap();
            let (hi, lo): (usize, usize) = (hi.parse().unwrap(), lo.parse().unwrap());
            for i in lo..=hi {
                bits.push(format!("{}[{i}]", name.trim()));
            }
        } else {
            bits.push(decl.to_string());
        }
    }
    bits
}

/// `(net, location)` of every `NET "..." LOC = "..."` line of a UCF.
fn ucf_locations(ucf: &str) -> Vec<(String, String)> {
    ucf.lines()
        .map(|l| l.split('#').next().unwrap())
        .filter(|l| l.contains("LOC"))
        .map(|l| {
            let q: Vec<&str> = l.split('"').collect();
            assert!(q.len() >= 4 && q[0].trim() == "NET", "malformed line {l}");
            (q[1].replace('<', "[").replace('>', "]"), q[3].to_string())
        })
        .collect()
}

#[test]
fn ucf_places_every_port_of_the_xem6310_top_and_nothing_else() {
    let cfg = spcimager150_back_config().unwrap();
    let v = on_generation_stack(|| verilog(Spcimager150Xem::new(&cfg).unwrap()));
    let ports = top_port_bits(&v);
    assert!(ports.len() > 100, "{ports:?}");
    let ucf_path = concat!(env!("CARGO_MANIFEST_DIR"), "/../constraints/xem6310.ucf");
    let ucf = std::fs::read_to_string(ucf_path).unwrap();
    let locs = ucf_locations(&ucf);
    let mut seen = std::collections::HashSet::new();
    let mut pins = std::collections::HashSet::new();
    for (net, pin) in &locs {
        assert!(
            ports.contains(net),
            "LOC for {net}, which is not a port of the top"
        );
        assert!(seen.insert(net.clone()), "{net} placed twice");
        assert!(pins.insert(pin.clone()), "pin {pin} used twice");
    }
    for p in &ports {
        assert!(seen.contains(p), "port bit {p} has no LOC");
    }
    // The host-interface clock period of the XEM6310.
    assert!(ucf.contains("PERIOD \"okHostClk\" 9.92 ns"));
    assert!(ucf.contains("NET \"okUH[0]\" TNM_NET = \"okHostClk\""));
}

#[test]
fn xem6310_top_verilog_passes_verilator_lint() {
    let cfg = test_back_config(4, 3, 1).unwrap();
    let v = on_generation_stack(|| verilog(TestXem::new(&cfg).unwrap()));
    // The black boxes are declared once each.
    assert_eq!(v.matches("module okHost(").count(), 1);
    assert_eq!(v.matches("module smartagg_mig(").count(), 1);
    let dir = scratch("lintxem");
    if let Err(e) = verilator_lint(&v, &dir) {
        panic!("{e}");
    }
    let _ = std::fs::remove_dir_all(dir);
}

/// Every generated design (each preset at each objective, the files
/// `smartagg hdl generate` writes: `top.v` with its `top.vlt`) is lint-clean
/// under `-Wall`, `UNOPTFLAT` included:
/// the scheduling hints of `smartagg_hdl::schedule` cut every false loop.
#[test]
fn every_generated_design_passes_verilator_lint() {
    for design in smartagg_hdl::designs::Design::all().unwrap() {
        let v = design.verilog().unwrap();
        assert!(
            v.contains(smartagg_hdl::schedule::ISOLATE),
            "{}: no scheduling hint",
            design.name()
        );
        // The waivers are the configuration file `hdl generate` writes,
        // each on named lines (or none): never a rule for the whole file.
        let vlt = verilator_config(&v);
        let waivers: Vec<&str> = vlt.lines().filter(|l| l.starts_with("lint_off")).collect();
        assert!(!waivers.is_empty(), "{}", design.name());
        for w in &waivers {
            assert!(
                w.contains(" -file \"*top.v\" -lines "),
                "{}: waiver not narrowed to lines: {w}",
                design.name()
            );
        }
        let dir = scratch(&format!("lint-{}", design.name()));
        // `verilator --lint-only -Wall --top-module top top.vlt top.v`: exit
        // 0 and no `%Warning` (a missing Verilator fails).
        match verilator_lint(&v, &dir) {
            Ok(out) => assert!(!out.contains("%Warning"), "{}: {out}", design.name()),
            Err(e) => panic!("{}: {e}", design.name()),
        }
        assert_eq!(std::fs::read_to_string(dir.join("top.vlt")).unwrap(), vlt);
        let _ = std::fs::remove_dir_all(dir);
    }
}
