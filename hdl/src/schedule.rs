//! Scheduling hints for Verilator on the generated Verilog.
//!
//! rust-hdl writes each block's logic as one `always @(*)` process.
//! Verilator orders combinational logic process by process, so a process
//! that reads a child's input-side signal and writes one of its
//! register-derived outputs looks like a loop when a parent closes it:
//! a FIFO's process reads `push`/`pop` and writes `count`, and the
//! packetiser computes its push from that count (likewise the tracker's
//! record push and the record queue's count, the delay line's prefetch FIFO,
//! the mask load and `mask_loadable`, the ROI aggregator's constant
//! multiplier; the ROI aggregator's row cover, lowest slot, view
//! multiplexer and ROI row; the blink tracker's item stage, compare stage,
//! association, record port, slots' flags and words and counters, which it
//! both drives and reads, the flags' on/off step, the compare stage's slot
//! compare and opening windows, and the walk memory, which the walk
//! pipeline drives and reads; the packetiser's bit packer, whose flags
//! choose the command the packetiser gives it). No signal
//! depends on itself — rust-hdl's `check_all` rules that out signal by
//! signal — but Verilator flags the processes `UNOPTFLAT` and re-runs them
//! until they settle, among them the blink tracker's and the packetiser's,
//! the two largest of the design: they ran up to three times a clock.
//!
//! [`isolate_false_loops`] marks the signals that cut those loops with
//! Verilator's `/*verilator isolate_assignments*/`, which moves their
//! assignments into processes of their own. It is a comment to every other
//! tool: yosys synthesises, and `smartagg hdl generate` writes, the same
//! logic, and the lint test runs without the `UNOPTFLAT` waiver.

/// Modules (known by a part of the port list rust-hdl writes: its end, or
/// ports found in that module only) and, in each, the signals to isolate:
/// outputs that are functions of the module's registers only, and the
/// locals they are computed from.
const MODULE_RULES: &[(&str, &[&str])] = &[
    // crate::fifo::Fifo.
    (
        "(clock,restart,push,push_data,pop,out_valid,out_data,room,count,overflow);",
        &["out_valid", "out_data", "room", "count", "overflow", "mem_count", "full"],
    ),
    // crate::blink_tracker::BlinkTracker: the inputs of its item stage,
    // compare stage, association and record port, whose outputs the
    // tracker reads back (the record port's `fb_pop` picks the walked
    // slot's bank; the item stage's `pop` is a function of `take`). The
    // walk pipeline's outputs are its W2 registers, and Verilator finds no
    // loop through the walk gate or the sequencer: their inputs need no
    // isolation.
    (
        "fb_pop,totals$blinks,totals$unconfirmed,totals$dropped,totals$bridged,totals$cuts,bank_error);",
        &[
            "items$*",
            "compare$*",
            "association$*",
            "port$*",
        ],
    ),
    // crate::blink_tracker::CompareStage: the inputs of its slot compare
    // and opening windows, whose outputs it registers, and the locals and
    // outputs they are computed from (functions of its registers and
    // inputs).
    (
        ",open_geo,open_win,open_view,open_bnd);",
        &[
            "slots$*",
            "opening$*",
            "take",
            "go",
            "candidate",
            "step",
            "end_item",
            "s_cx",
            "s_cy",
        ],
    ),
    // crate::roi_aggregator::RoiAggregator: the inputs of its row cover,
    // lowest slot, view multiplexer and ROI row, whose outputs it reads
    // back, and the locals they are computed from (functions of its
    // registers and inputs). Its port list ends with R counter lanes.
    (
        ",overrun,backlog,rd_req,rd_addr,rd_grant,",
        &[
            "row_cover$*",
            "pick$*",
            "views$*",
            "row$*",
            "go",
            "trig",
            "dplane",
            "par",
        ],
    ),
    // crate::packetiser::BitPacker: its flags and byte, functions of its
    // registers, which the packetiser reads to choose the packer's command.
    (
        "(clock,start,send,append,code,len,pad,full,empty,next_byte);",
        &["full", "empty", "next_byte", "shifted", "low", "pad_shift"],
    ),
    // crate::blink_tracker::SlotFlags: its outputs, functions of its
    // registers, which the tracker reads while it drives the inputs; and
    // the inputs of its on/off step, whose outputs it reads back, with the
    // plane's hits they are computed from.
    (
        ",opened,bridges,active_before,free_before);",
        &[
            "busy",
            "live",
            "dip",
            "pend",
            "opened",
            "bridges",
            "active_before",
            "free_before",
            "on_off$*",
            "on_v",
        ],
    ),
    // crate::blink_tracker::SlotWords: its outputs, the slots' words and ROI
    // view (functions of its registers), which the tracker reads while it
    // drives the inputs.
    (
        "(clock,restart,parity,walk_slot,end_of_plane,drain,finish,emit,",
        &["geo$", "win$", "bnd$", "sh$"],
    ),
    // crate::blink_tracker::TrackerCounters: its outputs, functions of its
    // registers (the plane's drops make the Dropped record), which the
    // tracker reads while it drives the events.
    (
        ",plane_drops,first_x,first_y,bank_error);",
        &[
            "totals$*",
            "plane_drops",
            "first_x",
            "first_y",
            "bank_error",
        ],
    ),
    // crate::blink_tracker::WalkMemory: its word, a function of its
    // registers and memories, which the walk pipeline reads while it drives the
    // read and write ports.
    (
        "(clock,restart,slot,slot_next,advance,word,write_enable,write_slot,write_data);",
        &["word"],
    ),
    // rust-hdl's AsynchronousFIFO (the sensor port): a wiring-only process.
    (
        "(read,data_out,empty,almost_empty,underflow,read_clock,read_fill,write,data_in,full,almost_full,overflow,write_clock,write_fill);",
        &[
            "data_out",
            "empty",
            "almost_empty",
            "underflow",
            "read_fill",
            "full",
            "almost_full",
            "overflow",
            "write_fill",
        ],
    ),
    // Its read side.
    (
        "(clock,read,data_out,empty,almost_empty,underflow,write_address_delayed,ram_read_address,ram_read_data,ram_read_clock,read_address_out,fill_level);",
        &[
            "empty",
            "almost_empty",
            "is_empty",
            "is_full",
            "fill_level",
            "underflow",
            "read_address_out",
        ],
    ),
    // Its write side.
    (
        "(write,data_in,full,almost_full,overflow,clock,ram_write_address,ram_write_clock,ram_write_data,ram_write_enable,read_address,write_address_delayed,fill_level);",
        &[
            "full",
            "almost_full",
            "is_empty",
            "is_full",
            "fill_level",
            "overflow",
            "write_address_delayed",
        ],
    ),
];

/// In any module: the pipeline's `mask_loadable` (a function of the control
/// state, read back by the XEM6310 core to drive `load`); the ROI
/// aggregator's bank-base multiplier operand (a register's value), whose
/// product the aggregator's process reads. A name ending in `$` stands for
/// every element of that vector (`lane$0`, `lane$1`, …); one ending in
/// `$*` for every signal of that child but its clock (`items$take`, …: in
/// a parent the child's inputs are its `reg`s; a clock isolated in a
/// process of its own is no longer seen as the clock, and the child's
/// registers stop).
const ANY_MODULE_SIGNALS: &[&str] = &["mask_loadable", "bank_base$x"];

/// The signal `name` is one of `list`'s.
fn listed(list: &[&str], name: &str) -> bool {
    list.iter().any(|&l| {
        if let Some(child) = l.strip_suffix('*') {
            return name
                .strip_prefix(child)
                .is_some_and(|port| !port.is_empty() && port != "clock");
        }
        match l.strip_suffix('$') {
            Some(vector) => name
                .strip_prefix(vector)
                .and_then(|rest| rest.strip_prefix('$'))
                .is_some_and(|index| {
                    !index.is_empty() && index.bytes().all(|b| b.is_ascii_digit())
                }),
            None => l == name,
        }
    })
}

/// The metacomment.
pub const ISOLATE: &str = "/*verilator isolate_assignments*/";

/// The declared name of a `reg` declaration line (`output reg [15:0] count;`
/// or `reg  bank_base$x;`), if the line is one.
fn reg_name(line: &str) -> Option<&str> {
    let t = line.trim();
    let rest = t
        .strip_prefix("output reg")
        .or_else(|| t.strip_prefix("reg"))?;
    if !rest.starts_with(char::is_whitespace) {
        return None;
    }
    let decl = rest.trim().strip_suffix(';')?;
    decl.rsplit(char::is_whitespace).next()
}

/// Marks the loop-cutting signals (`MODULE_RULES` in the modules of those
/// port lists, `ANY_MODULE_SIGNALS` anywhere) with
/// [`ISOLATE`]. Returns the Verilog and the number of declarations marked.
pub fn isolate_false_loops(verilog: &str) -> (String, usize) {
    let mut out = String::with_capacity(verilog.len() + 4096);
    let mut rule: &[&str] = &[];
    let mut marked = 0;
    for line in verilog.split_inclusive('\n') {
        let body = line.trim_end_matches(['\n', '\r']);
        if body.starts_with("module ") {
            rule = MODULE_RULES
                .iter()
                .find(|(ports, _)| body.contains(ports))
                .map_or(&[], |(_, signals)| signals);
        }
        let mark = reg_name(body)
            .is_some_and(|name| listed(ANY_MODULE_SIGNALS, name) || listed(rule, name));
        if mark {
            let semi = body.len() - 1;
            out.push_str(&body[..semi]);
            out.push(' ');
            out.push_str(ISOLATE);
            out.push_str(&line[semi..]);
            marked += 1;
        } else {
            out.push_str(line);
        }
    }
    (out, marked)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_vector_entry_stands_for_its_elements_only() {
        assert!(listed(&["rsel$"], "rsel$0"));
        assert!(listed(&["rsel$"], "rsel$31"));
        assert!(!listed(&["rsel$"], "rsel"));
        assert!(!listed(&["rsel$"], "rsel$x"));
        assert!(!listed(&["rsel$"], "rsel_q$1"));
        assert!(listed(&["par"], "par"));
        assert!(!listed(&["par"], "par1"));
        assert!(listed(&["items$*"], "items$take"));
        assert!(!listed(&["items$*"], "items$clock"));
        assert!(!listed(&["items$*"], "items$"));
        assert!(!listed(&["items$*"], "items"));
        assert!(!listed(&["items$*"], "item$take"));
    }

    #[test]
    fn marks_fifo_outputs_and_named_signals_only() {
        let v = "module top$q(clock,restart,push,push_data,pop,out_valid,out_data,room,count,overflow);\n\
                 \x20   input wire  push;\n\
                 \x20   output reg  [15:0] count;\n\
                 \x20   output reg  room;\n\
                 \x20   reg  [15:0] mem_count;\n\
                 \x20   reg  [15:0] wr$d;\n\
                 endmodule\n\
                 module top$p(clock,count,mask_loadable);\n\
                 \x20   output reg  [15:0] count;\n\
                 \x20   output reg  mask_loadable;\n\
                 \x20   reg  [9:0] bank_base$x;\n\
                 \x20   wire  [9:0] bank_base$y;\n\
                 endmodule\n";
        let (out, n) = isolate_false_loops(v);
        assert_eq!(n, 5);
        let lines: Vec<&str> = out.lines().collect();
        assert!(lines[2].ends_with("count /*verilator isolate_assignments*/;"));
        assert!(lines[3].ends_with("room /*verilator isolate_assignments*/;"));
        assert!(lines[4].ends_with("mem_count /*verilator isolate_assignments*/;"));
        assert!(!lines[5].contains(ISOLATE), "a FIFO register is left alone");
        assert!(
            !lines[8].contains(ISOLATE),
            "count outside a FIFO is left alone"
        );
        assert!(lines[9].contains(ISOLATE));
        assert!(lines[10].contains(ISOLATE));
        assert!(!lines[11].contains(ISOLATE), "wires are not marked");
        assert_eq!(out.replace(&format!(" {ISOLATE}"), ""), v);
    }

    #[test]
    fn a_rule_known_by_ports_inside_the_list_applies_to_that_module_only() {
        let v = "module top$agg(clock,overrun,backlog,rd_req,rd_addr,rd_grant,rd_counts$0,rd_masked);\n\
                 \x20   reg  go;\n\
                 \x20   reg  [31:0] pick$slots;\n\
                 \x20   reg  ra;\n\
                 endmodule\n\
                 module top$pkt(clock,rd_req,rd_addr,rd_grant,rd_counts$0,rd_masked);\n\
                 \x20   reg  go;\n\
                 endmodule\n";
        let (out, n) = isolate_false_loops(v);
        assert_eq!(n, 2);
        let lines: Vec<&str> = out.lines().collect();
        assert!(lines[1].contains(ISOLATE) && lines[2].contains(ISOLATE));
        assert!(!lines[3].contains(ISOLATE));
        assert!(
            !lines[6].contains(ISOLATE),
            "the packetiser's `go` is left alone"
        );
    }
}
