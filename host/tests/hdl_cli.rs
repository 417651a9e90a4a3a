//! `smartagg hdl`: generate writes the design's Verilog, hash, Verilator
//! configuration (`top.vlt`), UCF and ISE script; the UCF places every port of the generated top; resources runs
//! yosys on a given file (a small one here) and reports its hash.

use smartagg_hdl::designs::text_hash;
use std::collections::HashSet;
use std::path::Path;

mod common;
use common::*;

fn read(dir: &Path, name: &str) -> String {
    std::fs::read_to_string(dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The bits of the top module's ports (`name` or `name[i]`).
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

/// Generates `preset` at 150× and checks the files: the hash, the UCF
/// against the top's ports, the ISE script for `part`.
fn check_generate(preset: &str, part: &str, delay_line: &str, mig: bool) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join(preset);
    let o = out.to_str().unwrap();
    let stdout = ok(&[
        "hdl",
        "generate",
        "--preset",
        preset,
        "--objective",
        "150",
        "--out",
        o,
    ]);
    let v = read(&out, "top.v");
    let hash = text_hash(&v);
    // The printed and the written hash are those of the file on disk.
    assert!(stdout.contains(&hash), "{stdout}");
    assert_eq!(read(&out, "top.v.hash").trim(), format!("{hash}  top.v"));
    assert!(
        stdout.contains(part) && stdout.contains(delay_line),
        "{stdout}"
    );
    // The Verilator configuration beside it: the waivers of that very text,
    // each on named lines.
    let vlt = read(&out, "top.vlt");
    assert_eq!(vlt, smartagg_hdl::lint_waivers::verilator_config(&v));
    assert!(vlt.starts_with("`verilator_config\n"), "{vlt}");
    assert!(vlt.contains("lint_off -rule WIDTH -file \"*top.v\" -lines "));
    assert!(vlt
        .lines()
        .filter(|l| l.starts_with("lint_off"))
        .all(|l| l.contains(" -lines ")));
    assert!(stdout.contains("top.vlt"), "{stdout}");
    // The UCF places every bit of every top port, once, on distinct pins,
    // and nothing else.
    let ucf = read(&out, "xem6310.ucf");
    let ports = top_port_bits(&v);
    assert!(ports.iter().any(|p| p == "okUH[0]"), "{ports:?}");
    let mut placed = HashSet::new();
    let mut pins = HashSet::new();
    for line in ucf.lines().map(|l| l.split('#').next().unwrap()) {
        if !line.contains("LOC") {
            continue;
        }
        let q: Vec<&str> = line.split('"').collect();
        let net = q[1].replace('<', "[").replace('>', "]");
        assert!(ports.contains(&net), "LOC for {net}, not a port of top.v");
        assert!(placed.insert(net.clone()), "{net} placed twice");
        assert!(pins.insert(q[3].to_string()), "pin {} used twice", q[3]);
    }
    for p in &ports {
        assert!(placed.contains(p), "port bit {p} has no LOC");
    }
    // The ISE script adds the generated files for the part and asks for the
    // vendor cores (the MIG only where the DDR2 holds the delay line).
    let tcl = read(&out, "build.tcl");
    for needle in [
        "top.v",
        "xem6310.ucf",
        &part.to_ascii_lowercase(),
        "fgg484",
        &hash,
        "fp_dir",
    ] {
        assert!(tcl.contains(needle), "build.tcl lacks {needle}:\n{tcl}");
    }
    assert_eq!(tcl.contains("mig_dir"), mig, "{tcl}");
}

#[test]
fn generate_writes_the_verilog_its_hash_the_ucf_and_the_ise_script() {
    check_generate("spcimager", "XC6SLX45", "DDR2", true);
}

#[test]
fn generate_writes_the_on_chip_design_for_the_lx150_board() {
    check_generate("spcimager-projected", "XC6SLX150", "block-RAM", false);
}

#[test]
fn generate_rejects_a_frame_camera_and_an_unknown_objective() {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("x");
    let o = o.to_str().unwrap();
    let e = err(&["hdl", "generate", "--preset", "emccd", "--out", o]);
    assert!(e.contains("emccd") && e.contains("bit-planes"), "{e}");
    let e = err(&["hdl", "generate", "--preset", "nope", "--out", o]);
    assert!(e.contains("nope"), "{e}");
    let e = err(&[
        "hdl",
        "generate",
        "--preset",
        "spcimager",
        "--objective",
        "100",
        "--out",
        o,
    ]);
    assert!(e.contains("100"), "{e}");
    assert!(!dir.path().join("x").join("top.v").exists());
}

/// A small design: a counter and a 32-word memory.
const SMALL: &str = "module top(input wire clock, input wire [4:0] a, input wire we,
    input wire [7:0] d, output reg [7:0] q, output reg [7:0] count);
reg [7:0] mem [0:31];
always @(posedge clock) begin
    q <= mem[a];
    if (we) mem[a] <= d;
    count <= count + d;
end
endmodule
";

#[test]
fn resources_synthesises_the_given_file_and_reports_its_hash() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("small.v");
    std::fs::write(&file, SMALL).unwrap();
    let out = ok(&[
        "hdl",
        "resources",
        "--verilog",
        file.to_str().unwrap(),
        "--json",
    ]);
    let j: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(j["verilog_crc64"], text_hash(SMALL));
    assert_eq!(j["memory_bits"], 32 * 8);
    assert_eq!(j["ramb16_floor"], 1);
    assert_eq!(j["lut_levels_target"], 7);
    // One entry per mapping, each measured on its own netlist; the script
    // that made them is in the report.
    let maps = j["mappings"].as_array().unwrap();
    let names: Vec<&str> = maps
        .iter()
        .map(|m| m["mapping"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["abc-d7", "abc-d7-il", "abc", "abc9"], "{j}");
    // The smallest netlist within the target depth is named, and it is
    // no larger than any other such netlist.
    let within = |m: &serde_json::Value| m["lut_levels"].as_u64().unwrap() <= 7;
    let size = |m: &serde_json::Value| m["luts"].as_u64().unwrap() + m["lut_ram"].as_u64().unwrap();
    let best = j["smallest_within_levels"].as_str().unwrap();
    let b = maps.iter().find(|m| m["mapping"] == best).unwrap();
    assert!(within(b), "{j}");
    assert!(
        maps.iter()
            .filter(|m| within(m))
            .all(|m| size(b) <= size(m)),
        "{j}"
    );
    let script = j["yosys_script"].as_str().unwrap();
    for m in maps {
        assert!(script.contains(&format!("netlist-{}.json", m["mapping"].as_str().unwrap())));
        assert!(m["luts"].as_u64().unwrap() >= 8, "{m}");
        assert!(m["ffs"].as_u64().unwrap() >= 16, "{m}");
        let depth = m["logic_depth"].as_u64().unwrap();
        assert!((1..20).contains(&depth), "{m}");
        let levels = m["lut_levels"].as_u64().unwrap();
        assert!(levels >= 1 && levels <= depth, "{m}");
        let per = m["ends_per_level"].as_array().unwrap();
        assert_eq!(per.len() as u64, levels + 1, "{m}");
        assert!(!m["worst_path"].as_array().unwrap().is_empty(), "{m}");
        let devices = m["devices"].as_array().unwrap();
        assert_eq!(devices[0]["device"], "XC6SLX45");
        assert_eq!(devices[0]["fits"], true);
        assert_eq!(devices[0]["fits_within_levels"], levels <= 7, "{m}");
    }
    // A work folder that is a file is refused before yosys runs.
    let e = err(&[
        "hdl",
        "resources",
        "--verilog",
        file.to_str().unwrap(),
        "--work",
        file.to_str().unwrap(),
    ]);
    assert!(e.contains("--work") && e.contains("not a directory"), "{e}");
    // A file without a `top` module is refused by name.
    let bad = dir.path().join("bad.v");
    std::fs::write(&bad, "module other(); endmodule\n").unwrap();
    let e = err(&["hdl", "resources", "--verilog", bad.to_str().unwrap()]);
    assert!(e.contains("bad.v") && e.contains("top"), "{e}");
}
