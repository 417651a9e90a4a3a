//! Tool helpers: Verilator lint and a yosys `synth_xilinx -family xc6s`
//! resource report of generated Verilog.
//!
//! The figures of a mapped netlist and the parsers of yosys's reports are
//! in `synth/report.rs` ([`Resources`], [`Synthesis`], [`parse_cells`]).
//!
//! Both tools are required: a missing tool is an error that says how to
//! install it, never a skipped check.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use thiserror::Error;

mod report;

pub use report::{
    lut_ram_luts, parse_cells, parse_floors, parse_ltp, Netlist, Resources, Synthesis,
};

/// Why a tool run failed.
#[derive(Debug, Error)]
pub enum ToolError {
    /// The tool is not installed.
    #[error("`{tool}` is not installed or not on PATH ({error}); install it, e.g. `apt-get install -y verilator yosys`")]
    Missing {
        /// Tool name.
        tool: &'static str,
        /// The spawn error (in the message; not chained, so that it is said once).
        error: std::io::Error,
    },
    /// A file could not be written or read.
    #[error("{action} {path}: {error}")]
    Io {
        /// `writing` or `reading`.
        action: &'static str,
        /// The path.
        path: PathBuf,
        /// The error (in the message; not chained, so that it is said once).
        error: std::io::Error,
    },
    /// The tool ran and reported problems.
    #[error("`{tool}` failed (exit {code:?}):\n{output}")]
    Failed {
        /// Tool name.
        tool: &'static str,
        /// Exit code.
        code: Option<i32>,
        /// Its output (stdout and stderr).
        output: String,
    },
    /// The yosys report had no statistics to parse.
    #[error("no cell statistics found in the yosys log")]
    NoStatistics,
    /// The mapped netlist (`netlist.json`) could not be measured.
    #[error("LUT levels of the mapped netlist: {0}")]
    Levels(#[from] crate::lut_levels::LevelsError),
}

fn write_file(dir: &Path, name: &str, text: &str) -> Result<PathBuf, ToolError> {
    std::fs::create_dir_all(dir).map_err(|error| ToolError::Io {
        action: "writing",
        path: dir.to_path_buf(),
        error,
    })?;
    let path = dir.join(name);
    let mut f = std::fs::File::create(&path).map_err(|error| ToolError::Io {
        action: "writing",
        path: path.clone(),
        error,
    })?;
    f.write_all(text.as_bytes())
        .map_err(|error| ToolError::Io {
            action: "writing",
            path: path.clone(),
            error,
        })?;
    Ok(path)
}

fn run(tool: &'static str, cmd: &mut Command) -> Result<String, ToolError> {
    let out = cmd
        .output()
        .map_err(|error| ToolError::Missing { tool, error })?;
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    if out.status.success() {
        Ok(text)
    } else {
        Err(ToolError::Failed {
            tool,
            code: out.status.code(),
            output: text,
        })
    }
}

/// Runs `verilator --lint-only -Wall --top-module top top.vlt top.v` in
/// `dir`: the Verilog as `top.v` beside its configuration file
/// ([`crate::lint_waivers::verilator_config`], the very `top.vlt` that
/// `smartagg hdl generate` writes), no other waiver. Any warning fails, also
/// one Verilator would only print. Returns the tool's output.
pub fn verilator_lint(verilog: &str, dir: &Path) -> Result<String, ToolError> {
    write_file(dir, crate::lint_waivers::VERILOG_FILE, verilog)?;
    write_file(
        dir,
        crate::lint_waivers::VLT_FILE,
        &crate::lint_waivers::verilator_config(verilog),
    )?;
    let out = run(
        "verilator",
        Command::new("verilator")
            .current_dir(dir)
            .arg("--lint-only")
            .arg("-Wall")
            .arg("--top-module")
            .arg("top")
            .arg(crate::lint_waivers::VLT_FILE)
            .arg(crate::lint_waivers::VERILOG_FILE),
    )?;
    if out.contains("%Warning") {
        return Err(ToolError::Failed {
            tool: "verilator",
            code: Some(0),
            output: out,
        });
    }
    Ok(out)
}

/// One LUT mapping of the prepared netlist: the yosys commands that take
/// [`PREPARE`]'s design (`design -load prepared`) to a mapped Spartan-6
/// netlist. Every mapping starts from the same design, so their figures
/// differ only by how the LUTs were mapped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mapping {
    /// Short name (`abc-d7`, `abc-d7-il`, `abc`, `abc9`), used in reports
    /// and file names.
    pub name: &'static str,
    /// What the mapping optimises, one line.
    pub about: &'static str,
    /// The yosys commands, one per line.
    pub commands: &'static str,
    /// Maps the prepared design as written to [`PREPARED_RTLIL`] and read
    /// back (`design -reset; read_rtlil`), not as kept in memory: the same
    /// cells and wires, handed to ABC in another order. ABC's structural
    /// choices and its cut enumeration depend on that order; on the
    /// SPCImager top the same script has mapped the same design to LUT
    /// counts 12 % apart in the two orders (`hdl/RESOURCES.md`). Only the
    /// classic mapping can run so: `abc9` needs the black boxes' parameter
    /// declarations, which RTLIL does not keep.
    pub read_back: bool,
}

/// The prepared design in RTLIL, written once after [`PREPARE`] for the
/// mappings that [`Mapping::read_back`] (removed by [`yosys_resources`]
/// once measured: a whole top's is tens of MB).
pub const PREPARED_RTLIL: &str = "prepared.il";

/// yosys commands shared by every mapping: read the Verilog, count the
/// memory bits and multipliers of the flattened design (the analytic
/// floors), then `synth_xilinx -family xc6s -flatten` up to its LUT mapping,
/// saved as `prepared`.
pub const PREPARE: &str = "read_verilog top.v
hierarchy -top top
proc
flatten
stat
synth_xilinx -family xc6s -top top -flatten -run :map_luts
design -save prepared";

/// The depth-bounded mapping (quoted in its smaller order, see
/// [`ABC_D7_READ_BACK`]): `synth_xilinx`'s own `map_luts`,
/// `finalize` and `check` steps for the xc6s (6-input LUTs, MUXF7/8), with
/// one change, the ABC script: its default (`dch -f; if; mfs2`) with `if`
/// given a delay target of 7 LUT levels (`-D 7`: the LUT library's unit
/// delay) and more cuts and area-recovery rounds (`-C 24 -F 4 -A 6`). The
/// classic mapping's `if` recovers area only under the fewest levels it can
/// reach; one more level frees most of the LUTs that depth costs.
pub const ABC_D7: Mapping = Mapping {
    name: "abc-d7",
    about: "classic abc, at most 7 LUT levels, area recovered under that bound",
    commands: "opt_expr -mux_undef -noclkinv
abc -luts 2:2,3,6:5,10,20 -script +strash;&get,-n;&fraig,-x;&put;scorr;dc2;dretime;strash;dch,-f;if,-D,7,-C,24,-F,4,-A,6;mfs2
clean
techmap -map +/xilinx/ff_map.v
xilinx_srl -fixed -minlen 3
techmap -map +/xilinx/lut_map.v -map +/xilinx/cells_map.v -D LUT_WIDTH=6
xilinx_dffopt
opt_lut_ins -tech xilinx
clkbufmap -buf BUFG O:I
clean
hierarchy -check",
    read_back: false,
};

/// [`ABC_D7`]'s commands on the prepared design read back from
/// [`PREPARED_RTLIL`] ([`Mapping::read_back`]): a second order of the same
/// netlist, so that the report shows how far ABC's result moves with the
/// order alone, and the smaller of the two netlists can be used.
pub const ABC_D7_READ_BACK: Mapping = Mapping {
    name: "abc-d7-il",
    about: "abc-d7 on the prepared design as written to prepared.il and read back: the same cells in RTLIL's order",
    commands: ABC_D7.commands,
    read_back: true,
};

/// `synth_xilinx`'s own classic `abc` mapping: unit delay per LUT, each cone
/// between registers and carry chains mapped to its fewest levels, area
/// recovered only under that depth.
pub const ABC: Mapping = Mapping {
    name: "abc",
    about: "synth_xilinx's classic abc: the fewest LUT levels",
    commands: "synth_xilinx -family xc6s -top top -flatten -run map_luts:",
    read_back: false,
};

/// `synth_xilinx -abc9`: yosys' delay-driven flow (for the xc6s with the
/// xc7's timing model, as yosys warns). It maps for delay against the
/// design's critical *delay* (set by the long carry chains), then recovers
/// area on every path with slack, so its levels stretch up to that delay.
/// (`-abc9` changes `map_ffs`, the flip-flop mapping that precedes it.)
pub const ABC9: Mapping = Mapping {
    name: "abc9",
    about: "synth_xilinx -abc9: delay-driven, paths stretched up to the critical delay",
    commands: "techmap -map +/xilinx/ff_map.v
synth_xilinx -family xc6s -top top -flatten -abc9 -run map_luts:",
    read_back: false,
};

/// The mappings `yosys_resources` runs: the bounded-depth mapping in both
/// orders first, then the two of `synth_xilinx`.
pub const MAPPINGS: [Mapping; 4] = [ABC_D7, ABC_D7_READ_BACK, ABC, ABC9];

/// At most this many LUT levels between registers, in the netlist whose
/// LUTs are counted (issue #39: ≤ 80 % of the LX45's LUTs *and* ≤ 7 levels,
/// one netlist).
pub const LUT_LEVELS_TARGET: u32 = 7;

/// The whole yosys script of [`yosys_resources`], run as `yosys -s
/// synth.ys` in a folder holding `top.v`: [`PREPARE`] (and, if a mapping
/// reads it back, `write_rtlil prepared.il`), then for each mapping
/// `design -load prepared` (or `design -reset; read_rtlil prepared.il`),
/// its commands, its cell counts
/// (`stat-NAME.txt`), its netlist as JSON (`netlist-NAME.json`, measured in
/// LUT levels by [`crate::lut_levels`]) and yosys' own longest path through
/// the combinational cells, every cell counted (`ltp-NAME.txt`; flip-flops,
/// shift registers, block RAMs, DSP slices, buffers and the black boxes
/// deleted first, so that paths start and end at them).
pub fn yosys_script(mappings: &[Mapping]) -> String {
    let mut s = format!("{PREPARE}\n");
    if mappings.iter().any(|m| m.read_back) {
        s += &format!("write_rtlil {PREPARED_RTLIL}\n");
    }
    for m in mappings {
        let load = if m.read_back {
            format!("design -reset\nread_rtlil {PREPARED_RTLIL}")
        } else {
            "design -load prepared".to_string()
        };
        s += &format!(
            "# {name}: {about}\n{load}\n{commands}\n\
             tee -q -o stat-{name}.txt stat -tech xilinx\n\
             write_json netlist-{name}.json\n\
             delete t:FD* t:SRL* t:RAMB* t:DSP48* t:*BUF* t:ok* t:smartagg_mig\n\
             tee -q -o ltp-{name}.txt ltp\n",
            name = m.name,
            about = m.about,
            commands = m.commands
        );
    }
    s
}

/// Synthesises the Verilog for the Spartan-6 with yosys in `dir`: writes
/// `top.v` and the script ([`yosys_script`] of `mappings`) as `synth.ys`,
/// runs `yosys -s synth.ys` (log `yosys.log`), and measures every mapped
/// netlist (removed once measured: a whole top's is hundreds of MB). For
/// each mapping, the deepest path into every end deeper than 5 LUT levels
/// is written to `levels-paths-NAME.txt`: the pipelining work list.
pub fn yosys_resources(
    verilog: &str,
    dir: &Path,
    mappings: &[Mapping],
) -> Result<Synthesis, ToolError> {
    write_file(dir, "top.v", verilog)?;
    write_file(dir, "synth.ys", &yosys_script(mappings))?;
    let out = run(
        "yosys",
        Command::new("yosys")
            .current_dir(dir)
            .arg("-q")
            .arg("-l")
            .arg("yosys.log")
            .arg("-s")
            .arg("synth.ys"),
    )?;
    let read = |name: &str| {
        let path = dir.join(name);
        std::fs::read_to_string(&path).map_err(|error| ToolError::Io {
            action: "reading",
            path,
            error,
        })
    };
    let _ = std::fs::remove_file(dir.join(PREPARED_RTLIL));
    let log = read("yosys.log").unwrap_or(out);
    let (memory_bits, multipliers) = parse_floors(&log)?;
    let mut netlists = Vec::new();
    for m in mappings {
        let mut r = parse_cells(&read(&format!("stat-{}.txt", m.name))?)?;
        r.logic_depth = parse_ltp(&read(&format!("ltp-{}.txt", m.name))?);
        let json_name = format!("netlist-{}.json", m.name);
        let json = read(&json_name)?;
        let _ = std::fs::remove_file(dir.join(&json_name));
        let levels = crate::lut_levels::lut_levels(&json, "top")?;
        drop(json);
        let mut report = String::new();
        for (end, d) in levels.ends.iter().filter(|(_, d)| *d > 5) {
            if let Some((from, cells)) = levels.end_paths.get(end) {
                report += &format!("{d} {end} <- {from}: {}\n", cells.join(" > "));
            }
        }
        write_file(dir, &format!("levels-paths-{}.txt", m.name), &report)?;
        r.lut_levels = Some(levels);
        netlists.push(Netlist {
            mapping: *m,
            resources: r,
        });
    }
    Ok(Synthesis {
        memory_bits,
        multipliers,
        netlists,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_script_maps_the_prepared_design_once_per_mapping() {
        let s = yosys_script(&MAPPINGS);
        assert!(s.starts_with(PREPARE));
        let read_back = MAPPINGS.iter().filter(|m| m.read_back).count();
        assert_eq!(read_back, 1);
        assert_eq!(
            s.matches("design -load prepared").count(),
            MAPPINGS.len() - read_back
        );
        // The checkpoint is written once, before any mapping changes the
        // design, and each read-back mapping starts from it alone.
        let written = s.find("write_rtlil prepared.il").expect("checkpoint");
        assert!(written < s.find("# ").unwrap());
        assert_eq!(
            s.matches("design -reset\nread_rtlil prepared.il\n").count(),
            read_back
        );
        assert_eq!(ABC_D7_READ_BACK.commands, ABC_D7.commands);
        // Without a read-back mapping, no checkpoint.
        assert!(!yosys_script(&[ABC, ABC9]).contains("rtlil"));
        for m in MAPPINGS {
            for file in ["stat", "netlist", "ltp"] {
                assert!(
                    s.contains(&format!("{file}-{}.", m.name)),
                    "{file} {}",
                    m.name
                );
            }
        }
        // The bounded mapping asks ABC for the target depth.
        assert!(ABC_D7
            .commands
            .contains(&format!("if,-D,{LUT_LEVELS_TARGET},")));
        // No command line ends in `;` (yosys would split it there).
        assert!(s.lines().all(|l| !l.trim_end().ends_with(';')));
    }
}
