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
    #[error("`{tool}` is not installed or not on PATH ({source}); install it, e.g. `apt-get install -y verilator yosys`")]
    Missing {
        /// Tool name.
        tool: &'static str,
        /// The spawn error.
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error("writing {path}: {source}")]
    Io {
        /// The path.
        path: PathBuf,
        /// The error.
        source: std::io::Error,
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
    std::fs::create_dir_all(dir).map_err(|source| ToolError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let path = dir.join(name);
    let mut f = std::fs::File::create(&path).map_err(|source| ToolError::Io {
        path: path.clone(),
        source,
    })?;
    f.write_all(text.as_bytes())
        .map_err(|source| ToolError::Io {
            path: path.clone(),
            source,
        })?;
    Ok(path)
}

fn run(tool: &'static str, cmd: &mut Command) -> Result<String, ToolError> {
    let out = cmd
        .output()
        .map_err(|source| ToolError::Missing { tool, source })?;
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

/// Cell counts of a yosys `synth_xilinx -family xc6s` run.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Resources {
    /// Look-up tables (LUT1..LUT6).
    pub luts: u64,
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
    /// Bits of the design's memories before mapping (yosys `stat` after
    /// `proc; flatten`): with [`Resources::ramb16_floor`], the analytic floor.
    pub memory_bits: u64,
    /// Multipliers (`$mul` cells) before mapping: the floor of DSP slices
    /// (the spatial filter's multiplies that its configuration gives DSP
    /// slices; the others are shifts and adds).
    pub multipliers: u64,
    /// Longest path between registers, memories, black boxes and ports in
    /// cells of the mapped netlist (LUTs, MUXF7/8, CARRY4, LUT-RAM reads and
    /// inverters each count 1): yosys `ltp` once the sequential cells, block
    /// RAMs, buffers and black boxes are deleted; a proxy for timing.
    pub logic_depth: Option<u64>,
    /// Longest register-to-register path in LUT levels (CARRY4 and MUXF7/8
    /// count 0, LUT-RAM reads 1), the longest carry chain and the worst
    /// path's cells: [`crate::lut_levels`] on the mapped netlist.
    pub lut_levels: Option<crate::lut_levels::LutLevels>,
    /// The same, on the same Verilog mapped by the classic `abc`
    /// ([`LEVELS_SCRIPT`]): unit delay per LUT, each cone between registers
    /// and carry chains mapped to its fewest levels. `abc9` instead stretches
    /// every path with slack against its critical *delay* (set by the long
    /// carry chains) into chains of small LUTs, so its levels say what it
    /// allowed, not what the logic needs; the ≤ 6 target is read here.
    pub unit_levels: Option<crate::lut_levels::LutLevels>,
}

impl Resources {
    /// 18-Kbit block RAMs needed at the least for [`Resources::memory_bits`].
    pub fn ramb16_floor(&self) -> u64 {
        self.memory_bits.div_ceil(18 * 1024)
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

/// Parses a log of [`YOSYS_SCRIPT`]: the cells of the last `stat` table, the
/// memory bits and multipliers of the first, the `ltp` path length.
pub fn parse_yosys_stat(log: &str) -> Result<Resources, ToolError> {
    let start = log
        .rfind("Printing statistics")
        .ok_or(ToolError::NoStatistics)?;
    let mut r = Resources::default();
    let first = log.find("Printing statistics").unwrap_or(start);
    if first < start {
        for line in log[first..start].lines() {
            let line = line.trim();
            let number = |prefix: &str| {
                line.strip_prefix(prefix)
                    .and_then(|rest| rest.trim().parse::<u64>().ok())
            };
            if let Some(n) = number("Number of memory bits:") {
                r.memory_bits += n;
            }
            if let Some(n) = number("$mul") {
                r.multipliers += n;
            }
        }
    }
    r.logic_depth = log.rfind("Longest topological path in").and_then(|i| {
        let rest = &log[i..];
        let at = rest.find("length=")? + "length=".len();
        let digits: String = rest[at..]
            .chars()
            .take_while(|c| c.is_ascii_digit())
            .collect();
        digits.parse().ok()
    });
    let end = log[start..]
        .find("Longest topological path")
        .map_or(log.len(), |e| start + e);
    for line in log[start..end].lines() {
        let mut parts = line.split_whitespace();
        let (Some(name), Some(count)) = (parts.next(), parts.next()) else {
            continue;
        };
        let Ok(n) = count.parse::<u64>() else {
            continue;
        };
        match name {
            n_ if n_.starts_with("LUT") => r.luts += n,
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

/// The yosys command used for the resource figures: memory bits and
/// multipliers of the flattened design, Spartan-6 synthesis, cell counts,
/// the mapped netlist as JSON (`netlist.json`, measured in LUT levels by
/// [`crate::lut_levels`]), then yosys' own longest path through the
/// combinational cells, every cell counted (flip-flops, shift registers,
/// block RAMs, buffers and the black boxes deleted first, so that paths
/// start and end at them).
///
/// LUT mapping by `abc9` (yosys' delay-driven flow) rather than the
/// classic `abc`: fewer LUTs on the same Verilog; its levels stretch up to
/// its critical delay, so the depth is also read from [`LEVELS_SCRIPT`]'s
/// mapping ([`Resources::unit_levels`]). Neither maps
/// the one flat netlist of a whole top steadily: a rewrite that changes no
/// logic can move the count by ±7 % (figures in `hdl/RESOURCES.md`).
pub const YOSYS_SCRIPT: &str = "read_verilog top.v; hierarchy -top top; proc; flatten; stat; \
     synth_xilinx -family xc6s -top top -flatten -abc9; stat; write_json netlist.json; \
     delete t:FD* t:SRL* t:RAMB* t:DSP48* t:*BUF* t:ok* t:smartagg_mig; ltp";

/// The yosys command whose mapping [`Resources::unit_levels`] measures:
/// Spartan-6 synthesis with the classic `abc` LUT mapping, the netlist as
/// JSON (`levels.json`).
pub const LEVELS_SCRIPT: &str = "read_verilog top.v; hierarchy -top top; proc; flatten; \
     synth_xilinx -family xc6s -top top -flatten; write_json levels.json";

/// Synthesises the Verilog for the Spartan-6 with yosys in `dir` and returns
/// the cell counts (the log is left in `dir/yosys.log`), and the LUT levels
/// of both mappings: [`YOSYS_SCRIPT`] and, in a second yosys run beside it,
/// [`LEVELS_SCRIPT`] (log `dir/levels.log`; the deepest path into every
/// end deeper than 5 levels of that mapping in `dir/levels-paths.txt`).
pub fn yosys_resources(verilog: &str, dir: &Path) -> Result<Resources, ToolError> {
    write_file(dir, "top.v", verilog)?;
    let yosys = |log: &str, script: &str| {
        run(
            "yosys",
            Command::new("yosys")
                .current_dir(dir)
                .arg("-q")
                .arg("-l")
                .arg(log)
                .arg("-p")
                .arg(script),
        )
    };
    let (main, unit) = std::thread::scope(|s| {
        let unit = s.spawn(|| yosys("levels.log", LEVELS_SCRIPT));
        let main = yosys("yosys.log", YOSYS_SCRIPT);
        (main, unit.join())
    });
    let log = main?;
    unit.unwrap_or_else(|p| std::panic::resume_unwind(p))?;
    let full = std::fs::read_to_string(dir.join("yosys.log")).unwrap_or(log);
    let mut r = parse_yosys_stat(&full)?;
    // The netlist of a whole design is hundreds of MB; the figures are kept.
    let levels = |name: &str| -> Result<crate::lut_levels::LutLevels, ToolError> {
        let netlist = dir.join(name);
        let json = std::fs::read_to_string(&netlist).map_err(|source| ToolError::Io {
            path: netlist.clone(),
            source,
        })?;
        let _ = std::fs::remove_file(&netlist);
        Ok(crate::lut_levels::lut_levels(&json, "top")?)
    };
    r.lut_levels = Some(levels("netlist.json")?);
    let unit = levels("levels.json")?;
    // Where each deep end's path comes from, for the pipelining work list.
    let mut report = String::new();
    for (end, d) in unit.ends.iter().filter(|(_, d)| *d > 5) {
        if let Some((from, cells)) = unit.end_paths.get(end) {
            report += &format!("{d} {end} <- {from}: {}\n", cells.join(" > "));
        }
    }
    write_file(dir, "levels-paths.txt", &report)?;
    r.unit_levels = Some(unit);
    Ok(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shape of the two `stat` tables and the `ltp` line of a yosys log.
    const LOG: &str = "\
Printing statistics.
   Number of memory bits:       4096
     $mul                          2
Printing statistics.
   Number of cells:              100
     CARRY4                        3
     FDRE                         20
     LUT2                         10
     LUT6                          5
     RAM32M                        2
     RAM64X1D                      1
     SRL16E                        3
     RAMB16BWER                    1
     RAMB8BWER                     2
Longest topological path in top (length=7):
";

    #[test]
    fn lut_ram_is_counted_in_the_luts_it_occupies() {
        let r = parse_yosys_stat(LOG).unwrap();
        assert_eq!(r.luts, 15);
        // 2 RAM32M × 4 + 1 RAM64X1D × 2 + 3 SRL16E × 1.
        assert_eq!(r.lutram, 13);
        assert_eq!((r.ffs, r.carry4, r.ramb16, r.ramb8), (20, 3, 1, 2));
        assert_eq!((r.memory_bits, r.multipliers), (4096, 2));
        assert_eq!(r.logic_depth, Some(7));
        assert_eq!(lut_ram_luts("LUT6"), None);
    }
}
