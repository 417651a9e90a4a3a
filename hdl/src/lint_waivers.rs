//! The Verilator configuration file (`top.vlt`) that `smartagg hdl generate`
//! writes beside `top.v`: with it, `verilator --lint-only -Wall --top-module
//! top top.vlt top.v` reports nothing, and every waiver is narrowed to the
//! lines (or the exact message) of one rust-hdl idiom, never a rule for the
//! whole file.
//!
//! The waivers are derived from the Verilog text alone, by a scan in plain
//! Rust: the same text always gives the same file, and neither `hdl
//! generate` nor its user needs Verilator to get it. The tests lint every
//! generated design with its file and require no warning at all, so a
//! warning the scan does not expect (a width mismatch without a literal on
//! its line, a new unused signal) fails them.
//!
//! What is waived, and why it hides no design error:
//! * `WIDTH` on the lines that hold a sized literal (`32'h1`, `16'hffff`)
//!   or the bit-insert idiom `(v & ~(1 << (i)) | ((b) << (i)))`: rust-hdl
//!   writes every literal as 32 bits (`x = 32'h0`, `cur_x != 32'h0`,
//!   `wr + 32'h1`) and every cast as `((x) & N'hmask)`, so the operand widths
//!   on such a line differ by construction; the widths that matter are fixed
//!   by the Rust types, and the simulation tests check the values against
//!   the model. Also on the lines that index a vector or memory by a signal
//!   (`words[read_address]`, `x[(off)+:(16)]`): an index wider than the
//!   vector's address bits, which Verilator reports as `Bit extraction of
//!   ... requires 5 bit index, not 8 bits`, truncates no data.
//! * `UNUSEDSIGNAL` on the declaration lines of the signals in
//!   [`UNUSED_SIGNALS`] (each with its reason: outputs a parent does not
//!   read, the unused bits of wide shift registers and packed words) and on
//!   the lines of the `(* blackbox *)` stubs of the vendor cores, whose
//!   inputs no body reads.
//! * `UNUSEDPARAM` on the `localparam` lines whose name appears nowhere else
//!   in its module: rust-hdl declares the constants of a state enum in every
//!   module that holds a signal of that type.
//! * `DECLFILENAME` on the `module` lines of every module but `top`: one
//!   generated file holds every module.
//! * `PINCONNECTEMPTY` on the lines that leave a port unconnected (`.c3_clk0()`):
//!   outputs of the vendor black boxes that the top does not use.
//!
//! Line waivers of a configuration file apply to the files read after it:
//! give `top.vlt` first.

/// The name of the configuration file, beside `top.v`.
pub const VLT_FILE: &str = "top.vlt";

/// The file the waivers name (`-file "*top.v"`).
pub const VERILOG_FILE: &str = "top.v";

/// Signals that are unused by design, as `(pattern, reason)`: `*` matches
/// any run of characters, `?` one (no character classes). Only their declaration lines are waived
/// (for `UNUSEDSIGNAL` alone).
pub const UNUSED_SIGNALS: &[(&str, &str)] = &[
    // FrontPanel endpoints.
    (
        "wi?$ok_eh",
        "the wire-in's FrontPanel bus, which a wire-in never drives",
    ),
    ("wi?$ep_strobe", "wire-in strobes the registers do not need"),
    (
        "wo?$ep_strobe",
        "wire-out strobes the registers do not need",
    ),
    ("wo?$ep_dataout", "wire-out endpoints only drive the host"),
    ("ti40$ok_eh", "the trigger's FrontPanel bus"),
    ("ti40$ep_strobe", "trigger strobe not needed"),
    ("poa0$ep_dataout", "the pipe-out's data is read by the host"),
    ("okEH*", "the FrontPanel bus into the host interface"),
    ("okHE", "the FrontPanel bus where an endpoint ignores it"),
    ("okUH", "host-interface pins read by okHost"),
    ("ep_*", "endpoint ports of the FrontPanel stubs"),
    (
        "wire_in$*",
        "wire-in registers of which only the low bits are fields",
    ),
    (
        "trigger",
        "trigger-in word of which only the low bits are triggers",
    ),
    // The DDR2 controller (MIG) and its parked stand-in.
    ("c3_*", "MIG user-port signals the design does not use"),
    (
        "sys_clk_?",
        "the MIG's system clock, used by the vendor core only",
    ),
    ("sys_rst", "the MIG's reset, used by the vendor core only"),
    (
        "mcb$calib_done",
        "MCB calibration flag, idle with the block-RAM delay line",
    ),
    ("mcb$cmd_*", "MCB command port of the parked DDR2"),
    ("mcb$wr_*", "MCB write port of the parked DDR2"),
    (
        "mcb$rd_*",
        "MCB read port of the parked DDR2 or the idle pipeline",
    ),
    ("port_clk", "MIG port clock of the parked DDR2"),
    // FIFO and block status outputs a parent does not read.
    ("*$room", "FIFO fill level a parent does not read"),
    ("*$overflow", "FIFO overflow flag a parent does not read"),
    ("*$underflow", "FIFO underflow flag a parent does not read"),
    ("*$count", "FIFO count a parent does not read"),
    ("*$almost_empty", "FIFO flag a parent does not read"),
    ("*$almost_full", "FIFO flag a parent does not read"),
    ("*$read_fill", "FIFO fill level a parent does not read"),
    ("*$write_fill", "FIFO fill level a parent does not read"),
    (
        "*_to_*$update",
        "clock-crossing strobe a parent does not read",
    ),
    (
        "owords$out_valid",
        "the packetiser's word FIFO is drained by count",
    ),
    ("pos$x", "position outputs of the last stage"),
    ("pos$y", "position outputs of the last stage"),
    (
        "t?$out_origin",
        "tracker stage outputs carried only by the first stage",
    ),
    (
        "wbot$out_*",
        "the bottom candidate window's tags duplicate the middle one's",
    ),
    (
        "sel_tree$*",
        "levels of a selection tree of which the root is read",
    ),
    (
        "word$drain",
        "a field of the delay line's word that the front half does not read (the back half's)",
    ),
    (
        "word$side",
        "a field of the delay line's word that the front half does not read (the back half's)",
    ),
    (
        "raw$y",
        "a field of the delay line's word that the back half does not read (the front half's)",
    ),
    (
        "raw$idx",
        "a field of the delay line's word that the back half does not read (the front half's)",
    ),
    (
        "raw$live",
        "a field of the delay line's word that the back half does not read (the front half's)",
    ),
    // Unused bits of wide temporaries and inputs.
    ("rshift", "shift temporaries wider than the value kept"),
    ("mshift", "shift temporaries wider than the value kept"),
    ("shifted", "shift temporaries wider than the value kept"),
    (
        "pk_shift",
        "packing shift registers of which a byte is read",
    ),
    (
        "pad_shift",
        "packing shift registers of which a byte is read",
    ),
    ("crc_shift", "CRC shift register of which a byte is read"),
    ("len$*", "length registers wider than the length kept"),
    ("tr_plane", "plane counter of which the low bits are read"),
    ("row$delayed", "ROI row bits beyond the ROI side"),
    (
        "walk_slot",
        "the walked slot's one-hot, of which the flags read their M slots' bits",
    ),
    (
        "open_slot",
        "the opened slot's one-hot, of which the flags read their M slots' bits",
    ),
    (
        "slot_geo$*",
        "a slot's packed word, of which the tracker's compare stage reads the fields it compares",
    ),
    (
        "slot_win$*",
        "a slot's lane masks, of which the tracker's compare stage reads the P bits of each",
    ),
    (
        "slot_bnd$*",
        "a slot's association window, of which the tracker's compare stage reads the four bounds",
    ),
    ("read_address", "block-RAM addresses wider than the memory"),
    ("write_address", "block-RAM addresses wider than the memory"),
    (
        "x",
        "inputs of the saturating casts wider than the value kept",
    ),
];

/// `*`/`?` pattern match (no escapes).
fn glob(pattern: &str, text: &str) -> bool {
    let (p, t): (Vec<char>, Vec<char>) = (pattern.chars().collect(), text.chars().collect());
    let (mut pi, mut ti) = (0, 0);
    let (mut star, mut mark) = (None, 0);
    while ti < t.len() {
        if pi < p.len() && (p[pi] == '?' || p[pi] == t[ti]) {
            pi += 1;
            ti += 1;
        } else if pi < p.len() && p[pi] == '*' {
            star = Some(pi);
            mark = ti;
            pi += 1;
        } else if let Some(s) = star {
            pi = s + 1;
            mark += 1;
            ti = mark;
        } else {
            return false;
        }
    }
    p[pi..].iter().all(|&c| c == '*')
}

fn ident_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_' || c == '$'
}

/// The identifiers of a line (letters, digits, `_`, `$`; not starting with
/// a digit or `$`).
fn identifiers(line: &str) -> impl Iterator<Item = &str> {
    line.split(|c: char| !ident_char(c))
        .filter(|w| w.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_'))
}

/// A sized literal (`32'h0`, `8'd3`, `1'b1`) on the line.
fn has_sized_literal(line: &str) -> bool {
    let b = line.as_bytes();
    (1..b.len().saturating_sub(1)).any(|i| {
        b[i] == b'\''
            && b[i - 1].is_ascii_digit()
            && matches!(b[i + 1].to_ascii_lowercase(), b'h' | b'd' | b'b' | b'o')
    })
}

/// A vector or memory indexed by a signal: `[name]` or `[(name)+:`.
fn has_signal_index(line: &str) -> bool {
    line.match_indices('[').any(|(i, _)| {
        let rest = line[i + 1..].trim_start_matches('(');
        rest.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
    })
}

/// The name a declaration line declares (`reg [7:0] x;`, `input wire y;`),
/// if the line is one.
fn declared_name(line: &str) -> Option<&str> {
    let t = line.trim();
    let body = ["input ", "output ", "inout ", "wire ", "reg "]
        .iter()
        .find_map(|k| t.strip_prefix(k))?;
    let body = body.strip_suffix(';')?;
    // A signal isolated for Verilator's scheduling (`crate::schedule`)
    // carries the metacomment after its name.
    let body = body
        .trim_end()
        .strip_suffix(crate::schedule::ISOLATE)
        .unwrap_or(body);
    if body.contains('=') || body.contains(',') || body.contains('(') {
        return None;
    }
    body.split_whitespace().last()
}

/// One waiver: a rule on a set of lines.
struct Lines {
    rule: &'static str,
    why: &'static str,
    lines: Vec<usize>,
}

impl Lines {
    fn new(rule: &'static str, why: &'static str) -> Self {
        Lines {
            rule,
            why,
            lines: Vec::new(),
        }
    }

    /// `lint_off` lines, consecutive lines joined into ranges.
    fn write(&self, out: &mut String) {
        if self.lines.is_empty() {
            return;
        }
        out.push_str(&format!("// {}: {}\n", self.rule, self.why));
        let mut lines = self.lines.clone();
        lines.sort_unstable();
        lines.dedup();
        let mut i = 0;
        while i < lines.len() {
            let mut j = i;
            while j + 1 < lines.len() && lines[j + 1] == lines[j] + 1 {
                j += 1;
            }
            let range = if i == j {
                lines[i].to_string()
            } else {
                format!("{}-{}", lines[i], lines[j])
            };
            out.push_str(&format!(
                "lint_off -rule {} -file \"*{VERILOG_FILE}\" -lines {range}\n",
                self.rule
            ));
            i = j + 1;
        }
    }
}

/// The Verilator configuration file for the generated Verilog `verilog`
/// (written as `top.v`): every waiver on the lines of one rust-hdl idiom.
pub fn verilator_config(verilog: &str) -> String {
    let mut width = Lines::new(
        "WIDTH",
        "rust-hdl's 32-bit literals, casts `((x) & N'hmask)`, bit inserts and signal indices",
    );
    let mut unused = Lines::new(
        "UNUSEDSIGNAL",
        "signals unused by design (lint_waivers::UNUSED_SIGNALS) and the vendor black-box stubs",
    );
    let mut param = Lines::new(
        "UNUSEDPARAM",
        "state-enum constants rust-hdl declares in every module holding the type",
    );
    let mut decl = Lines::new("DECLFILENAME", "one generated file holds every module");
    let mut pins = Lines::new(
        "PINCONNECTEMPTY",
        "vendor black-box outputs the top leaves unconnected",
    );
    let lines: Vec<&str> = verilog.lines().collect();
    let mut start = 0;
    while start < lines.len() {
        // One module: `module` .. `endmodule`, with the black-box attribute
        // on the line before it.
        let Some(m) = (start..lines.len()).find(|&i| lines[i].trim_start().starts_with("module "))
        else {
            break;
        };
        let end = (m..lines.len())
            .find(|&i| lines[i].trim_start().starts_with("endmodule"))
            .unwrap_or(lines.len() - 1);
        let name = identifiers(&lines[m].trim_start()["module ".len()..])
            .next()
            .unwrap_or("");
        if name != "top" {
            decl.lines.push(m + 1);
        }
        let blackbox = m > 0 && lines[m - 1].contains("(* blackbox *)");
        if blackbox {
            unused.lines.extend(m + 1..=end + 1);
        }
        // How often each identifier appears in the module.
        let mut uses: std::collections::HashMap<&str, usize> = Default::default();
        for line in &lines[m..=end] {
            for id in identifiers(line) {
                *uses.entry(id).or_default() += 1;
            }
        }
        for (i, line) in lines.iter().enumerate().take(end + 1).skip(m) {
            let n = i + 1;
            let t = line.trim();
            if let Some(p) = t.strip_prefix("localparam ") {
                if identifiers(p)
                    .next()
                    .is_some_and(|id| uses.get(id) == Some(&1))
                {
                    param.lines.push(n);
                }
            }
            if let Some(s) = declared_name(t) {
                if UNUSED_SIGNALS.iter().any(|(p, _)| glob(p, s)) {
                    unused.lines.push(n);
                }
            }
            if has_sized_literal(t) || t.contains("~(1 << (") || has_signal_index(t) {
                width.lines.push(n);
            }
            if t.match_indices("()").any(|(k, _)| {
                let before = t[..k].trim_end_matches(ident_char);
                before.ends_with('.') && before.len() < k
            }) {
                pins.lines.push(n);
            }
        }
        start = end + 1;
    }
    let mut out = String::from(
        "`verilator_config\n\
         // Waivers for the generated top.v, each on the lines of one rust-hdl idiom\n\
         // (smartagg_hdl::lint_waivers). Give this file first, as in\n\
         // `verilator --lint-only -Wall --top-module top top.vlt top.v`.\n",
    );
    for w in [&decl, &pins, &param, &unused, &width] {
        w.write(&mut out);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glob_matches_stars_and_single_characters() {
        assert!(glob("wi?$ok_eh", "wi3$ok_eh"));
        assert!(!glob("wi?$ok_eh", "wi13$ok_eh"));
        assert!(glob("*$room", "tfifo$room"));
        assert!(glob("c3_*", "c3_p0_rd_en"));
        assert!(!glob("x", "xx"));
    }

    #[test]
    fn waivers_name_the_lines_of_each_idiom() {
        let v = "\
(* blackbox *)
module okHost(input wire [4:0] okUH);
endmodule
module top$core(clock, a);
input wire clock;
reg [31:0] rshift;
reg [7:0] kept;
localparam s$idle = 32'h0;
localparam s$busy = 32'h1;
always @(*) begin
  kept = s$busy;
  kept = kept + rshift;
end
okHost h(.okUH(), .x(kept));
endmodule
module top(clock);
endmodule
";
        let c = verilator_config(v);
        assert!(c.starts_with("`verilator_config\n"), "{c}");
        let has = |s: &str| c.lines().any(|l| l == s);
        for want in [
            r#"lint_off -rule DECLFILENAME -file "*top.v" -lines 2"#,
            r#"lint_off -rule DECLFILENAME -file "*top.v" -lines 4"#,
            r#"lint_off -rule UNUSEDSIGNAL -file "*top.v" -lines 2-3"#,
            r#"lint_off -rule UNUSEDSIGNAL -file "*top.v" -lines 6"#,
            r#"lint_off -rule UNUSEDPARAM -file "*top.v" -lines 8"#,
            r#"lint_off -rule WIDTH -file "*top.v" -lines 8-9"#,
            r#"lint_off -rule PINCONNECTEMPTY -file "*top.v" -lines 14"#,
        ] {
            assert!(has(want), "no `{want}` in\n{c}");
        }
        // A width mismatch without a literal is not waived; nothing is
        // waived for a whole file.
        assert!(!c.contains("-lines 12"), "{c}");
        assert!(c
            .lines()
            .filter(|l| l.starts_with("lint_off"))
            .all(|l| l.contains("-lines ")));
        assert_eq!(c, verilator_config(v));
    }

    #[test]
    fn an_isolated_declaration_keeps_its_name() {
        let isolated = format!("    reg  [71:0] shifted {};", crate::schedule::ISOLATE);
        assert_eq!(declared_name(&isolated), Some("shifted"));
        assert_eq!(declared_name("    reg  [71:0] shifted;"), Some("shifted"));
        assert_eq!(declared_name("    output reg  full;"), Some("full"));
        assert_eq!(declared_name("    wire  x = y;"), None);
    }
}
