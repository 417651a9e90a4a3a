//! Logic depth in *LUT levels* of a netlist mapped by yosys `synth_xilinx`,
//! read from its `write_json` output.
//!
//! yosys `ltp` counts every cell on a path, so a 16-bit adder (four CARRY4)
//! or a wide multiplexer (MUXF7 + MUXF8) looks four or two levels deep when
//! on the chip it costs one LUT plus the dedicated carry or mux wiring. This
//! metric counts what limits the clock on a Spartan-6:
//! * LUT1–LUT6 and INV: **1** level each;
//! * CARRY4, MUXCY/XORCY, MUXF7, MUXF8 and buffers: **0** (dedicated
//!   wiring; the longest carry chain is reported beside);
//! * LUT RAM (RAM32M, RAM64M, RAM*X1*) and SRL16E/SRLC32E: the read from the
//!   address inputs to the data outputs is **1** level, and their outputs
//!   start a path at level 1 (the stored bits are registers); data, write
//!   enable and clock inputs end a path;
//! * flip-flops, block RAMs, DSP slices, black boxes and the module's ports
//!   begin and end paths.
//!
//! [`lut_levels`] returns the longest register-to-register path in those
//! units, the longest carry chain in CARRY4 cells, and the worst path's
//! cells by name.

use serde_json::Value;
use std::collections::HashMap;
use thiserror::Error;

/// Why a netlist could not be measured.
#[derive(Debug, Error)]
pub enum LevelsError {
    /// The text is not JSON.
    #[error("netlist JSON: {0}")]
    Json(#[from] serde_json::Error),
    /// The JSON has no such module, or not the shape `write_json` writes.
    #[error("netlist JSON: {0}")]
    Shape(String),
    /// A combinational loop (no register on it) through the named cell.
    #[error("combinational loop through cell {0}")]
    Loop(String),
}

/// The logic depth of a mapped netlist.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LutLevels {
    /// Longest path between registers (or ports, memories, black boxes) in
    /// LUT levels.
    pub levels: u32,
    /// Longest chain of CARRY4 cells (CO → CI) anywhere in the netlist.
    pub carry_chain: u32,
    /// The cells of the worst path, from its start to its end, as `(type,
    /// signal)`: the named signal (`name[bit]`) the cell drives on the path,
    /// or the cell's own name where yosys kept no signal name; only the
    /// cells that count or carry (LUTs, LUT RAM, CARRY4, MUXF7/8).
    pub path: Vec<(String, String)>,
    /// The register, memory or port bit where the worst path starts.
    pub start: String,
    /// Every group of path ends (a register, memory or port, named by its
    /// output signal without the bit index, or by the cell) with the
    /// deepest path into it, deepest first: the work list for pipelining.
    pub ends: Vec<(String, u32)>,
    /// For every group of path ends, where its deepest path starts and the
    /// named signals it passes (start first): what to register.
    pub end_paths: HashMap<String, (String, Vec<String>)>,
}

impl LutLevels {
    /// How many groups of path ends ([`LutLevels::ends`]) have their
    /// deepest path at each depth: element d counts those at d LUT levels,
    /// from 0 to [`LutLevels::levels`].
    pub fn ends_per_level(&self) -> Vec<usize> {
        let mut counts = vec![0; self.levels as usize + 1];
        for (_, d) in &self.ends {
            if let Some(c) = counts.get_mut(*d as usize) {
                *c += 1;
            }
        }
        counts
    }

    /// The path ends deeper than `levels`, deepest first, as
    /// `"name depth"`.
    pub fn ends_deeper_than(&self, levels: u32) -> Vec<String> {
        self.ends
            .iter()
            .filter(|(_, d)| *d > levels)
            .map(|(n, d)| format!("{n} {d}"))
            .collect()
    }
}

/// How a cell type takes part in paths.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// Combinational, one level.
    Lut,
    /// Combinational, no level (carry, wide mux, buffer).
    Free,
    /// Carry chain: bit i of CO/O depends on CI, CYINIT, DI[0..=i], S[0..=i].
    Carry,
    /// LUT RAM / SRL: address inputs to outputs is one level, outputs start at 1.
    LutRam,
    /// Sequential or unknown: begins and ends paths.
    Boundary,
}

fn kind(ty: &str) -> Kind {
    match ty {
        t if t.starts_with("LUT") => Kind::Lut,
        "INV" => Kind::Lut,
        "CARRY4" => Kind::Carry,
        // A bidirectional pad (the DDR2 data and strobes) is where paths
        // start and end, like a port: its pad pin is both its input and its
        // output, so walking through it would be a loop.
        t if t.starts_with("IOBUF") => Kind::Boundary,
        "MUXF7" | "MUXF8" | "MUXF5" | "MUXF6" | "MUXCY" | "XORCY" | "BUF" => Kind::Free,
        t if t.ends_with("BUF") || t == "BUFG" || t == "IBUFG" => Kind::Free,
        t if t.starts_with("RAM32")
            || t.starts_with("RAM64")
            || t.starts_with("RAM128")
            || t.starts_with("RAM16")
            || t.starts_with("SRL") =>
        {
            Kind::LutRam
        }
        _ => Kind::Boundary,
    }
}

/// Whether a LUT-RAM/SRL input is a read address (combinational to the outputs).
fn is_read_address(port: &str) -> bool {
    port.starts_with("ADDR") || port.starts_with("DPRA") || {
        // RAM64X1D / RAM32X1S: A0..A5; SRL16E: A0..A3, SRLC32E: A.
        let rest = port.strip_prefix('A');
        matches!(rest, Some(r) if r.is_empty() || r.chars().all(|c| c.is_ascii_digit()))
    }
}

struct Cell {
    name: String,
    ty: String,
    kind: Kind,
    /// Input ports: name and bit nets (None: a constant).
    inputs: Vec<(String, Vec<Option<u64>>)>,
}

fn nets(v: &Value) -> Result<Vec<Option<u64>>, LevelsError> {
    v.as_array()
        .ok_or_else(|| LevelsError::Shape("connection is not a bit list".into()))
        .map(|a| a.iter().map(Value::as_u64).collect())
}

/// Measures module `top` of a yosys `write_json` netlist.
pub fn lut_levels(json: &str, top: &str) -> Result<LutLevels, LevelsError> {
    let doc: Value = serde_json::from_str(json)?;
    let module = doc
        .get("modules")
        .and_then(|m| m.get(top))
        .ok_or_else(|| LevelsError::Shape(format!("no module `{top}`")))?;
    let empty = serde_json::Map::new();
    let cells_json = module
        .get("cells")
        .and_then(Value::as_object)
        .unwrap_or(&empty);

    let mut cells = Vec::with_capacity(cells_json.len());
    // Net → (driving cell, output port, bit index).
    let mut driver: HashMap<u64, (usize, String, usize)> = HashMap::new();
    for (name, c) in cells_json {
        let ty = c
            .get("type")
            .and_then(Value::as_str)
            .ok_or_else(|| LevelsError::Shape(format!("cell {name} has no type")))?;
        let dirs = c.get("port_directions").and_then(Value::as_object);
        let conns = c
            .get("connections")
            .and_then(Value::as_object)
            .ok_or_else(|| LevelsError::Shape(format!("cell {name} has no connections")))?;
        let idx = cells.len();
        let mut inputs = Vec::new();
        for (port, bits) in conns {
            let bits = nets(bits)?;
            let dir = dirs
                .and_then(|d| d.get(port))
                .and_then(Value::as_str)
                .unwrap_or("input");
            if dir == "output" || dir == "inout" {
                for (i, b) in bits.iter().enumerate() {
                    if let Some(n) = b {
                        driver.insert(*n, (idx, port.clone(), i));
                    }
                }
            }
            if dir == "input" || dir == "inout" {
                inputs.push((port.clone(), bits));
            }
        }
        cells.push(Cell {
            name: name.clone(),
            ty: ty.to_string(),
            kind: kind(ty),
            inputs,
        });
    }

    // Readable names of nets: user signals before yosys' `$` names.
    let mut net_name: HashMap<u64, (bool, String)> = HashMap::new();
    if let Some(names) = module.get("netnames").and_then(Value::as_object) {
        for (name, n) in names {
            let hidden =
                n.get("hide_name").and_then(Value::as_u64) == Some(1) || name.starts_with('$');
            let Some(bits) = n.get("bits").and_then(Value::as_array) else {
                continue;
            };
            for (i, b) in bits.iter().enumerate() {
                let Some(b) = b.as_u64() else { continue };
                let label = if bits.len() == 1 {
                    name.clone()
                } else {
                    format!("{name}[{i}]")
                };
                let better = match net_name.get(&b) {
                    None => true,
                    Some((h, old)) => (*h && !hidden) || (*h == hidden && label.len() < old.len()),
                };
                if better {
                    net_name.insert(b, (hidden, label));
                }
            }
        }
    }

    // The input nets a driven net depends on and the level its driver adds.
    let deps = |net: u64| -> (u32, Vec<u64>) {
        let Some((c, _port, bit)) = driver.get(&net) else {
            return (0, Vec::new()); // a module input or undriven
        };
        let cell = &cells[*c];
        let all = |filter: &dyn Fn(&str, usize) -> bool| -> Vec<u64> {
            cell.inputs
                .iter()
                .flat_map(|(p, bits)| {
                    bits.iter()
                        .enumerate()
                        .filter(move |(i, _)| filter(p, *i))
                        .filter_map(|(_, b)| *b)
                })
                .collect()
        };
        match cell.kind {
            Kind::Lut => (1, all(&|_, _| true)),
            Kind::Free => (0, all(&|_, _| true)),
            // CO[i] and O[i] of `port` see the carry in and bits 0..=i.
            Kind::Carry => (
                0,
                all(&|p, i| p == "CI" || p == "CYINIT" || ((p == "DI" || p == "S") && i <= *bit)),
            ),
            Kind::LutRam => (1, all(&|p, _| is_read_address(p))),
            Kind::Boundary => (0, Vec::new()),
        }
    };

    // Longest depth of every net, iteratively (paths can be long).
    let mut depth: HashMap<u64, (u32, Option<u64>)> = HashMap::new();
    let mut on_stack: HashMap<u64, bool> = HashMap::new();
    let all_nets: Vec<u64> = driver.keys().copied().collect();
    for &root in &all_nets {
        if depth.contains_key(&root) {
            continue;
        }
        let mut stack = vec![(root, false)];
        while let Some((n, expanded)) = stack.pop() {
            if depth.contains_key(&n) {
                continue;
            }
            let (w, ins) = deps(n);
            if expanded {
                let mut best = (0u32, None);
                for i in &ins {
                    let d = depth.get(i).map_or(0, |d| d.0);
                    if best.1.is_none() || d > best.0 {
                        best = (d, Some(*i));
                    }
                }
                depth.insert(n, (w + best.0, best.1));
                on_stack.remove(&n);
                continue;
            }
            if on_stack.insert(n, true).is_some() {
                let (c, _, _) = &driver[&n];
                return Err(LevelsError::Loop(cells[*c].name.clone()));
            }
            stack.push((n, true));
            for i in ins {
                if !depth.contains_key(&i) {
                    if on_stack.contains_key(&i) {
                        let (c, _, _) = &driver[&i];
                        return Err(LevelsError::Loop(cells[*c].name.clone()));
                    }
                    stack.push((i, false));
                }
            }
        }
    }

    // The cells of the deepest path into `n` (start first) and its start.
    let trace = |mut n: u64| -> (Vec<(String, String)>, String) {
        let mut path = Vec::new();
        let mut last_cell = None;
        loop {
            if let Some((c, _, _)) = driver.get(&n) {
                let cell = &cells[*c];
                if cell.kind != Kind::Boundary
                    && !(cell.kind == Kind::Free && cell.ty.contains("BUF"))
                    && last_cell != Some(*c)
                {
                    let label = match net_name.get(&n) {
                        Some((false, name)) => name.clone(),
                        _ => cell.name.clone(),
                    };
                    path.push((cell.ty.clone(), label));
                    last_cell = Some(*c);
                }
            }
            match depth.get(&n).and_then(|d| d.1) {
                Some(prev) => n = prev,
                None => {
                    let start = match (net_name.get(&n), driver.get(&n)) {
                        (Some((false, name)), _) => name.clone(),
                        (_, Some((c, port, bit))) => format!("{}.{port}[{bit}]", cells[*c].name),
                        _ => format!("net {n}"),
                    };
                    path.reverse();
                    return (path, start);
                }
            }
        }
    };
    let worst = depth
        .iter()
        .max_by_key(|(n, d)| (d.0, std::cmp::Reverse(**n)))
        .map(|(n, d)| (*n, d.0));
    let (mut path, mut levels, mut start) = (Vec::new(), 0, String::new());
    if let Some((n, l)) = worst {
        levels = l;
        (path, start) = trace(n);
    }

    // Path ends: the inputs of the cells that begin and end paths (and the
    // written side of LUT RAM), grouped by what the cell drives.
    let mut out_name: HashMap<usize, String> = HashMap::new();
    for (net, (c, _, _)) in &driver {
        if let Some((false, name)) = net_name.get(net) {
            let base = name.split('[').next().unwrap_or(name).to_string();
            let e = out_name.entry(*c).or_insert_with(|| base.clone());
            if base < *e {
                *e = base;
            }
        }
    }
    let mut end_depth: HashMap<String, (u32, Option<u64>)> = HashMap::new();
    let mut deeper = |label: String, d: Option<(u32, u64)>| {
        if let Some((d, n)) = d {
            let e = end_depth.entry(label).or_insert((0, None));
            if e.1.is_none() || d > e.0 {
                *e = (d, Some(n));
            }
        }
    };
    for (i, cell) in cells.iter().enumerate() {
        let ends_here = |p: &str| match cell.kind {
            Kind::Boundary => true,
            Kind::LutRam => !is_read_address(p),
            _ => false,
        };
        let d = cell
            .inputs
            .iter()
            .filter(|(p, _)| ends_here(p))
            .flat_map(|(_, bits)| bits.iter().flatten())
            .map(|n| (depth.get(n).map_or(0, |d| d.0), *n))
            .max_by_key(|(d, n)| (*d, std::cmp::Reverse(*n)));
        let label = out_name
            .get(&i)
            .cloned()
            .unwrap_or_else(|| cell.name.clone());
        deeper(label, d);
    }
    // The module's outputs end paths too.
    if let Some(ports) = module.get("ports").and_then(Value::as_object) {
        for (name, p) in ports {
            if p.get("direction").and_then(Value::as_str) == Some("input") {
                continue;
            }
            let d = p
                .get("bits")
                .map(nets)
                .transpose()?
                .unwrap_or_default()
                .iter()
                .flatten()
                .map(|n| (depth.get(n).map_or(0, |d| d.0), *n))
                .max_by_key(|(d, n)| (*d, std::cmp::Reverse(*n)));
            deeper(name.clone(), d);
        }
    }
    let mut end_paths = HashMap::new();
    let mut ends: Vec<(String, u32)> = Vec::with_capacity(end_depth.len());
    for (label, (d, n)) in end_depth {
        if let Some(n) = n {
            let (cells_on, from) = trace(n);
            end_paths.insert(
                label.clone(),
                (from, cells_on.into_iter().map(|c| c.1).collect()),
            );
        }
        ends.push((label, d));
    }
    ends.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(&b.0)));

    // Carry chains: CARRY4 whose CI comes from another CARRY4.
    let carry_pred = |c: usize| -> Option<usize> {
        let ci = cells[c]
            .inputs
            .iter()
            .find(|(p, _)| p == "CI")
            .and_then(|(_, b)| b.first().copied().flatten())?;
        let (d, _, _) = driver.get(&ci)?;
        (cells[*d].kind == Kind::Carry).then_some(*d)
    };
    let mut chain: HashMap<usize, u32> = HashMap::new();
    let mut carry_chain = 0;
    for start in 0..cells.len() {
        if cells[start].kind != Kind::Carry || chain.contains_key(&start) {
            continue;
        }
        // Down to the chain's head (or a cell already numbered), then up.
        let mut walk = vec![start];
        while let Some(d) = carry_pred(*walk.last().unwrap()) {
            if chain.contains_key(&d) || walk.len() > cells.len() {
                break;
            }
            walk.push(d);
        }
        let mut below = carry_pred(*walk.last().unwrap())
            .and_then(|d| chain.get(&d).copied())
            .unwrap_or(0);
        for c in walk.into_iter().rev() {
            below += 1;
            chain.insert(c, below);
            carry_chain = carry_chain.max(below);
        }
    }

    Ok(LutLevels {
        levels,
        carry_chain,
        path,
        start,
        ends,
        end_paths,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand-written netlist: FF q → LUT a → CARRY4 c0 → CARRY4 c1 → MUXF7
    /// m → LUT b → FF d; and a LUT-RAM read r from FF q's net to FF e via
    /// LUT f; m and b drive the named signal `sum`. Expected: a, b count (2 levels); the carry and mux count 0;
    /// the chain is 2 CARRY4 long; the RAM path is RAM (1) + LUT f (1) = 2.
    fn netlist(extra_lut: bool) -> String {
        let b_in = if extra_lut { 30 } else { 20 };
        let extra = if extra_lut {
            r#","g": {"type": "LUT1", "port_directions": {"I0": "input", "O": "output"},
                  "connections": {"I0": [20], "O": [30]}}"#
        } else {
            ""
        };
        format!(
            r#"{{"modules": {{"top": {{"ports": {{"clk": {{"direction": "input", "bits": [1]}}}},
            "netnames": {{"sum": {{"hide_name": 0, "bits": [20, 21]}},
                          "$auto$x": {{"hide_name": 1, "bits": [3]}}}},
            "cells": {{
              "q": {{"type": "FDRE", "port_directions": {{"C": "input", "D": "input", "Q": "output"}},
                    "connections": {{"C": [1], "D": [40], "Q": [2]}}}},
              "a": {{"type": "LUT2", "port_directions": {{"I0": "input", "I1": "input", "O": "output"}},
                    "connections": {{"I0": [2], "I1": [2], "O": [3]}}}},
              "c0": {{"type": "CARRY4", "port_directions": {{"CI": "input", "CYINIT": "input", "DI": "input", "S": "input", "CO": "output", "O": "output"}},
                    "connections": {{"CI": ["0"], "CYINIT": ["0"], "DI": ["0", "0", "0", "0"], "S": [3, "0", "0", "0"], "CO": [4, 5, 6, 7], "O": [8, 9, 10, 11]}}}},
              "c1": {{"type": "CARRY4", "port_directions": {{"CI": "input", "CYINIT": "input", "DI": "input", "S": "input", "CO": "output", "O": "output"}},
                    "connections": {{"CI": [7], "CYINIT": ["0"], "DI": ["0", "0", "0", "0"], "S": ["0", "0", "0", "0"], "CO": [12, 13, 14, 15], "O": [16, 17, 18, 19]}}}},
              "m": {{"type": "MUXF7", "port_directions": {{"I0": "input", "I1": "input", "S": "input", "O": "output"}},
                    "connections": {{"I0": [19], "I1": [2], "S": [2], "O": [20]}}}},
              "b": {{"type": "LUT1", "port_directions": {{"I0": "input", "O": "output"}},
                    "connections": {{"I0": [{b_in}], "O": [21]}}}},
              "d": {{"type": "FDRE", "port_directions": {{"C": "input", "D": "input", "Q": "output"}},
                    "connections": {{"C": [1], "D": [21], "Q": [40]}}}},
              "r": {{"type": "RAM64X1D", "port_directions": {{"A0": "input", "DPRA0": "input", "D": "input", "WE": "input", "WCLK": "input", "SPO": "output", "DPO": "output"}},
                    "connections": {{"A0": [2], "DPRA0": [2], "D": [21], "WE": ["1"], "WCLK": [1], "SPO": [22], "DPO": [23]}}}},
              "f": {{"type": "LUT2", "port_directions": {{"I0": "input", "I1": "input", "O": "output"}},
                    "connections": {{"I0": [22], "I1": [23], "O": [24]}}}},
              "e": {{"type": "FDRE", "port_directions": {{"C": "input", "D": "input", "Q": "output"}},
                    "connections": {{"C": [1], "D": [24], "Q": [25]}}}}
              {extra}
            }}}}}}}}"#
        )
    }

    #[test]
    fn counts_luts_not_carries_or_wide_muxes() {
        let r = lut_levels(&netlist(false), "top").unwrap();
        assert_eq!(r.levels, 2);
        assert_eq!(r.carry_chain, 2);
        let names: Vec<&str> = r.path.iter().map(|(_, n)| n.as_str()).collect();
        assert!(
            names == ["a", "c0", "c1", "sum[0]", "sum[1]"] || names == ["r", "f"],
            "{names:?}"
        );
    }

    #[test]
    fn one_more_lut_is_one_more_level() {
        let r = lut_levels(&netlist(true), "top").unwrap();
        assert_eq!(r.levels, 3);
        let names: Vec<&str> = r.path.iter().map(|(_, n)| n.as_str()).collect();
        // Cells are named by the user signal they drive where there is one.
        assert_eq!(names, ["a", "c0", "c1", "sum[0]", "g", "sum[1]"]);
        assert_eq!(r.path[4].0, "LUT1");
        // Unnamed nets are named by the cell and port that drive them.
        assert_eq!(r.start, "q.Q[0]");
        // Every end with its deepest path: the FF d and the LUT RAM's
        // written data both 3, the FF e behind the RAM's read 2.
        assert_eq!(
            r.ends[..3],
            [("d".into(), 3), ("r".into(), 3), ("e".into(), 2)]
        );
        assert_eq!(r.ends_deeper_than(2), ["d 3", "r 3"]);
        // Ends per depth 0..=3: e at 2, d and r at 3, and whatever else ends.
        let per = r.ends_per_level();
        assert_eq!(per.len(), 4);
        assert_eq!(per.iter().sum::<usize>(), r.ends.len());
        assert_eq!((per[2] >= 1, per[3]), (true, 2));
        // And where each end's deepest path comes from.
        let path = |end: &str| {
            let (from, cells) = &r.end_paths[end];
            (
                from.as_str(),
                cells.iter().map(String::as_str).collect::<Vec<_>>(),
            )
        };
        assert_eq!(path("e"), ("q.Q[0]", vec!["r", "f"]));
        assert_eq!(path("d"), ("q.Q[0]", names));
    }

    #[test]
    fn a_bidirectional_pad_bounds_paths() {
        // LUT -> IOBUF.I, pad IO (inout, the top's port), IOBUF.O -> LUT.
        let pad = r#"{"modules": {"top": {"ports": {"dq": {"direction": "inout", "bits": [5]}},
          "cells": {
            "a": {"type": "LUT1", "port_directions": {"I0": "input", "O": "output"},
                  "connections": {"I0": [2], "O": [3]}},
            "p": {"type": "IOBUF", "port_directions": {"I": "input", "T": "input", "O": "output", "IO": "inout"},
                  "connections": {"I": [3], "T": ["0"], "O": [4], "IO": [5]}},
            "b": {"type": "LUT1", "port_directions": {"I0": "input", "O": "output"},
                  "connections": {"I0": [4], "O": [2]}}}}}}"#;
        let l = lut_levels(pad, "top").unwrap();
        assert_eq!(l.levels, 2, "pad O -> b -> a -> pad I");
        assert_eq!(kind("IOBUFDS"), Kind::Boundary);
        assert_eq!(kind("OBUF"), Kind::Free);
    }

    #[test]
    fn loops_and_bad_input_are_errors() {
        let looped = r#"{"modules": {"top": {"cells": {
            "a": {"type": "LUT1", "port_directions": {"I0": "input", "O": "output"},
                  "connections": {"I0": [2], "O": [3]}},
            "b": {"type": "LUT1", "port_directions": {"I0": "input", "O": "output"},
                  "connections": {"I0": [3], "O": [2]}}}}}}"#;
        assert!(matches!(
            lut_levels(looped, "top"),
            Err(LevelsError::Loop(_))
        ));
        assert!(matches!(
            lut_levels(looped, "other"),
            Err(LevelsError::Shape(_))
        ));
        assert!(matches!(
            lut_levels("not json", "top"),
            Err(LevelsError::Json(_))
        ));
    }
}
