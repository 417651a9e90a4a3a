//! What yosys measured: the cell counts, depth and floors of a mapped
//! netlist ([`Resources`], [`Netlist`], [`Synthesis`]) and the parsers of
//! yosys's `stat` tables, `ltp` line and log that fill them.

use super::{Mapping, ToolError, LUT_LEVELS_TARGET};

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

/// What [`yosys_resources`](super::yosys_resources) measured: the
/// Verilog's floors and one [`Netlist`] per mapping, in
/// [`MAPPINGS`](super::MAPPINGS)' order.
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
    /// one to quote, since [`ABC_D7`](super::ABC_D7) and
    /// [`ABC_D7_READ_BACK`](super::ABC_D7_READ_BACK) map one design in two
    /// orders and either may be the smaller.
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
/// yosys log ([`PREPARE`](super::PREPARE)'s `stat` of the flattened design).
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{ABC, ABC9, ABC_D7, ABC_D7_READ_BACK};

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
}
