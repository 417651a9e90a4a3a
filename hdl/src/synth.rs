//! Tool helpers: Verilator lint and a yosys `synth_xilinx -family xc6s`
//! resource report of generated Verilog.
//!
//! Both tools are required: a missing tool is an error that says how to
//! install it, never a skipped check.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use thiserror::Error;

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

/// Cell counts and depth of one mapped netlist.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Resources {
    /// Look-up tables: LUT1..LUT6 and the inverters ([`Resources::inverters`]).
    pub luts: u64,
    /// Inverters (`INV`) the mapping left, counted in [`Resources::luts`]:
    /// each takes a LUT (most drive a carry chain's select input, which on
    /// a Spartan-6 only its slice's LUT can drive).
    pub inverters: u64,
    /// Flip-flops (FD*).
    pub ffs: u64,
    /// 18-Kbit block RAMs.
    pub ramb16: u64,
    /// 9-Kbit block RAMs.
    pub ramb8: u64,
    /// DSP slices.
    pub dsp48a1: u64,
    /// LUTs used as distributed RAM or shift registers: each primitive
    /// counted by the LUTs of its slice it occupies ([`lut_ram_luts`]: a
    /// RAM32M or RAM64M takes four, an SRL16E one).
    pub lutram: u64,
    /// Carry chains (CARRY4).
    pub carry4: u64,
    /// Longest path between registers, memories, black boxes and ports in
    /// cells of the mapped netlist (LUTs, MUXF7/8, CARRY4, LUT-RAM reads and
    /// inverters each count 1): yosys `ltp` once the sequential cells, block
    /// RAMs, buffers and black boxes are deleted; a proxy for timing.
    pub logic_depth: Option<u64>,
    /// Longest register-to-register path in LUT levels (CARRY4 and MUXF7/8
    /// count 0, LUT-RAM reads 1), the longest carry chain, the worst
    /// path's cells and every path end's depth: [`crate::lut_levels`] on the
    /// mapped netlist.
    pub lut_levels: Option<crate::lut_levels::LutLevels>,
}

/// A mapping and the figures of its netlist.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Netlist {
    /// How its LUTs were mapped.
    pub mapping: Mapping,
    /// Its cells and depth.
    pub resources: Resources,
}

/// What [`yosys_resources`] measured: the Verilog's floors and one
/// [`Netlist`] per mapping, in [`MAPPINGS`]' order.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Synthesis {
    /// Bits of the design's memories before mapping (yosys `stat` after
    /// `proc; flatten`): with [`Synthesis::ramb16_floor`], the analytic floor.
    pub memory_bits: u64,
    /// Multipliers (`$mul` cells) before mapping: the floor of DSP slices
    /// (the spatial filter's multiplies that its configuration gives DSP
    /// slices; the others are shifts and adds).
    pub multipliers: u64,
    /// One mapped netlist per mapping.
    pub netlists: Vec<Netlist>,
}

impl Synthesis {
    /// 18-Kbit block RAMs needed at the least for [`Synthesis::memory_bits`].
    pub fn ramb16_floor(&self) -> u64 {
        self.memory_bits.div_ceil(18 * 1024)
    }

    /// The netlist of the mapping named `name`.
    pub fn netlist(&self, name: &str) -> Option<&Netlist> {
        self.netlists.iter().find(|n| n.mapping.name == name)
    }

    /// The netlist with the fewest LUTs (LUT RAM included) among those
    /// within [`LUT_LEVELS_TARGET`] LUT levels, the first of equals: the
    /// one to quote, since [`ABC_D7`] and [`ABC_D7_READ_BACK`] map one
    /// design in two orders and either may be the smaller.
    pub fn smallest_within_levels(&self) -> Option<&Netlist> {
        self.netlists
            .iter()
            .filter(|n| {
                n.resources
                    .lut_levels
                    .as_ref()
                    .is_some_and(|l| l.levels <= LUT_LEVELS_TARGET)
            })
            .min_by_key(|n| n.resources.luts + n.resources.lutram)
    }
}

/// LUTs of a Spartan-6 SLICEM that one distributed-RAM or shift-register
/// primitive occupies (UG384), or `None` for any other cell. The multi-port
/// RAM32M/RAM64M use all four LUTs of the slice, a dual-port RAMxX1D two.
pub fn lut_ram_luts(cell: &str) -> Option<u64> {
    Some(match cell {
        "RAM32M" | "RAM64M" | "RAM128X1D" | "RAM256X1S" => 4,
        "RAM32X1D" | "RAM64X1D" | "RAM128X1S" => 2,
        "RAM32X1S" | "RAM64X1S" | "SRL16E" | "SRLC16E" | "SRLC32E" => 1,
        _ => return None,
    })
}

/// Parses the output of `stat -tech xilinx` (the last statistics table in
/// `text`) into cell counts ([`Resources::logic_depth`] and
/// [`Resources::lut_levels`] are left `None`).
pub fn parse_cells(text: &str) -> Result<Resources, ToolError> {
    let start = text
        .rfind("Number of cells:")
        .ok_or(ToolError::NoStatistics)?;
    let mut r = Resources::default();
    for line in text[start..].lines().skip(1) {
        let mut parts = line.split_whitespace();
        let (Some(name), Some(count), None) = (parts.next(), parts.next(), parts.next()) else {
            continue;
        };
        let Ok(n) = count.parse::<u64>() else {
            continue;
        };
        match name {
            n_ if n_.starts_with("LUT") => r.luts += n,
            "INV" => {
                r.luts += n;
                r.inverters += n;
            }
            n_ if n_.starts_with("FD") => r.ffs += n,
            "RAMB16BWER" => r.ramb16 += n,
            "RAMB8BWER" => r.ramb8 += n,
            "DSP48A1" => r.dsp48a1 += n,
            "CARRY4" => r.carry4 += n,
            other => r.lutram += n * lut_ram_luts(other).unwrap_or(0),
        }
    }
    Ok(r)
}

/// The length of yosys `ltp`'s longest path in `text`, if it has one.
pub fn parse_ltp(text: &str) -> Option<u64> {
    let i = text.rfind("Longest topological path in")?;
    let rest = &text[i..];
    let at = rest.find("length=")? + "length=".len();
    let digits: String = rest[at..]
        .chars()
        .take_while(|c| c.is_ascii_digit())
        .collect();
    digits.parse().ok()
}

/// The memory bits and multipliers of the first statistics table of a
/// yosys log ([`PREPARE`]'s `stat` of the flattened design).
pub fn parse_floors(log: &str) -> Result<(u64, u64), ToolError> {
    let first = log
        .find("Printing statistics")
        .ok_or(ToolError::NoStatistics)?;
    let end = log[first + 1..]
        .find("Printing statistics")
        .map_or(log.len(), |e| first + 1 + e);
    let (mut bits, mut muls) = (0, 0);
    for line in log[first..end].lines() {
        let line = line.trim();
        let number = |prefix: &str| {
            line.strip_prefix(prefix)
                .and_then(|rest| rest.trim().parse::<u64>().ok())
        };
        if let Some(n) = number("Number of memory bits:") {
            bits += n;
        }
        if let Some(n) = number("$mul") {
            muls += n;
        }
    }
    Ok((bits, muls))
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

    /// The shape of `stat`'s table after `proc; flatten` in a log.
    const LOG: &str = "\
Printing statistics.
   Number of memory bits:       4096
     $mul                          2
Printing statistics.
   Number of memory bits:       9999
";

    /// The shape of a `stat -tech xilinx` table and an `ltp` line.
    const STAT: &str = "\
   Number of cells:              100
     CARRY4                        3
     FDRE                         20
     INV                           4
     LUT2                         10
     LUT6                          5
     RAM32M                        2
     RAM64X1D                      1
     SRL16E                        3
     RAMB16BWER                    1
     RAMB8BWER                     2
   Estimated number of LCs:       19
Longest topological path in top (length=7):
";

    #[test]
    fn lut_ram_and_inverters_are_counted_in_the_luts_they_occupy() {
        let r = parse_cells(STAT).unwrap();
        assert_eq!(r.luts, 19);
        assert_eq!(r.inverters, 4);
        // 2 RAM32M × 4 + 1 RAM64X1D × 2 + 3 SRL16E × 1.
        assert_eq!(r.lutram, 13);
        assert_eq!((r.ffs, r.carry4, r.ramb16, r.ramb8), (20, 3, 1, 2));
        assert_eq!(parse_ltp(STAT), Some(7));
        assert_eq!(lut_ram_luts("LUT6"), None);
        assert!(parse_cells("no table").is_err());
    }

    #[test]
    fn the_smallest_netlist_is_chosen_among_the_shallow_ones() {
        let netlist = |mapping, luts, lutram, levels: Option<u32>| Netlist {
            mapping,
            resources: Resources {
                luts,
                lutram,
                lut_levels: levels.map(|levels| crate::lut_levels::LutLevels {
                    levels,
                    ..Default::default()
                }),
                ..Default::default()
            },
        };
        let mut s = Synthesis {
            memory_bits: 0,
            multipliers: 0,
            netlists: vec![
                netlist(ABC_D7, 125, 10, Some(7)),
                netlist(ABC_D7_READ_BACK, 100, 10, Some(7)),
                netlist(ABC, 130, 0, Some(6)),
                // Smaller, but too deep.
                netlist(ABC9, 90, 10, Some(12)),
            ],
        };
        let name = |s: &Synthesis| s.smallest_within_levels().map(|n| n.mapping.name);
        assert_eq!(name(&s), Some("abc-d7-il"));
        // LUT RAM counts: 100 + 40 is more than 130 + 0 (and 125 + 10).
        s.netlists[1].resources.lutram = 40;
        assert_eq!(name(&s), Some("abc"));
        // Unmeasured depth never qualifies; nothing shallow, no choice.
        s.netlists[2].resources.lut_levels = None;
        s.netlists[0].resources.lut_levels = None;
        s.netlists[1].resources.lut_levels = None;
        assert_eq!(name(&s), None);
    }

    #[test]
    fn the_floors_come_from_the_first_table() {
        assert_eq!(parse_floors(LOG).unwrap(), (4096, 2));
        assert!(parse_floors("").is_err());
    }

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
