//! The configurations co-simulated: the generated gateware (rust-hdl
//! Verilog) inside a co-simulation wrapper (`cosim`) that adds the DDR2
//! model and, in debug builds, probe ports on every stage's output.
//!
//! Every configuration that `smartagg hdl generate` ships
//! ([`smartagg_hdl::designs::Design`]: the SPCImager and the projected
//! SPCImager, each at 150× and 60×) is co-simulated as its XEM6310 core
//! ([`smartagg_hdl::designs::Spcimager150Core`] and its siblings: the
//! FrontPanel endpoints and the sensor port, with the DDR2 behavioural model
//! on the MCB port of a DDR2 design, the MCB inputs parked as the top parks
//! them for a block-RAM one), on its full field or on **any smaller field**
//! of its sensor ([`DesignSpec::new`]): the same type, its memories' address
//! widths sized for the whole sensor ([`GatewareConfig::sized_for`]), with
//! the field's own constants. The demo's design ([`DesignSpec::demo`]) is
//! the one exception: a pipeline sized for its 48×48 field alone (block-RAM
//! delay line, M = 16), driven through its word port.

use crate::ddr2::{self, Ddr2Timing};
use crate::verilator::{BuildOptions, Dir, VerilatorError};
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig, GatewareError};
use smartagg_hdl::designs::{
    on_generation_stack, DelayLineKind, Design, Projected150Core, Projected60Core,
    Spcimager150Core, Spcimager60Core,
};
use smartagg_hdl::front_half::verilog;
use smartagg_hdl::pipeline::Pipeline;
use smartagg_model::params::PresetName;
use std::fmt::Write as _;

/// Errors naming a configuration problem.
#[derive(Debug, thiserror::Error)]
pub enum DesignError {
    /// The hdl configuration was refused.
    #[error("gateware configuration: {0}")]
    Gateware(#[from] GatewareError),
    /// The model configuration was refused.
    #[error("model: {0}")]
    Model(String),
    /// Verilator or the cache.
    #[error(transparent)]
    Verilator(#[from] VerilatorError),
    /// No design for this configuration or field.
    #[error("no co-simulation configuration for {what}: {why}")]
    Unsupported {
        /// What was asked.
        what: String,
        /// What exists.
        why: String,
    },
    /// The fault could not be injected (the Verilog changed shape).
    #[error("fault injection: {0}")]
    Fault(String),
}

/// The configurations `smartagg hdl generate` ships.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Config {
    /// SPCImager, 150× objective (DDR2 delay line).
    Spcimager150,
    /// SPCImager, 60× objective (DDR2 delay line).
    Spcimager60,
    /// Projected SPCImager, 150× objective (block-RAM delay line).
    Projected150,
    /// Projected SPCImager, 60× objective (block-RAM delay line).
    Projected60,
}

impl Config {
    /// Every shipped configuration, in `hdl generate`'s order.
    pub const ALL: [Config; 4] = [
        Config::Spcimager150,
        Config::Spcimager60,
        Config::Projected150,
        Config::Projected60,
    ];

    /// The configuration of a preset and objective.
    pub fn for_preset(name: PresetName, objective: u32) -> Result<Config, DesignError> {
        Config::ALL
            .into_iter()
            .find(|c| c.preset_name() == (name, objective))
            .ok_or_else(|| DesignError::Unsupported {
                what: format!("{name} at {objective}x"),
                why: "generated: spcimager and spcimager-projected, each at 150x and 60x".into(),
            })
    }

    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Config::Spcimager150 => "spcimager/150x",
            Config::Spcimager60 => "spcimager/60x",
            Config::Projected150 => "spcimager-projected/150x",
            Config::Projected60 => "spcimager-projected/60x",
        }
    }

    /// The preset and objective (the inverse of [`Config::for_preset`]).
    pub fn preset_name(self) -> (PresetName, u32) {
        match self {
            Config::Spcimager150 => (PresetName::Spcimager, 150),
            Config::Spcimager60 => (PresetName::Spcimager, 60),
            Config::Projected150 => (PresetName::SpcimagerProjected, 150),
            Config::Projected60 => (PresetName::SpcimagerProjected, 60),
        }
    }

    /// The shipped design, as `smartagg hdl generate` builds it.
    pub fn shipped(self) -> Result<Design, DesignError> {
        let (n, o) = self.preset_name();
        Ok(Design::new(n, o)?)
    }
}

/// A configuration on a field of view.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DesignSpec {
    /// Which configuration.
    pub config: Config,
    /// Field width, pixels.
    pub width: usize,
    /// Field height, pixels.
    pub height: usize,
    /// DDR2 model timing.
    pub ddr: Ddr2Timing,
    /// Association radius r_assoc (a generation parameter of the tracker).
    pub r_assoc: u32,
    /// The front half's generation parameters on this field.
    front: GatewareConfig,
    /// Where the delay line lives.
    delay_line: DelayLineKind,
    /// The demo's pipeline ([`DesignSpec::demo`]) rather than the shipped core.
    demo: bool,
}

/// The reduced field of the randomised co-simulation cases.
pub const REDUCED: (usize, usize) = (64, 32);
/// The SPCImager's full field.
pub const FULL: (usize, usize) = (320, 240);
/// The field of `smartagg demo` (SPCImager 150×, 2.6 µm square). Its
/// design is sized for it (docs/DESIGN.md §7): 112 planes of 48×48 bits fit
/// block RAM, so the delay line is on chip ([`DEMO_N_MAX`]) and the
/// pipeline core is simulated, paced by its `ready` (a word every clock
/// while the back half has room); and the field's blinks need
/// [`DEMO_SLOTS`] slots.
pub const DEMO: (usize, usize) = (48, 48);

/// N_max of the demo's design: the SPCImager 150× window rounded up to a
/// multiple of 8 (`smartagg_hdl::designs::block_ram_n_max`, checked by a
/// test), as `smartagg_hdl::designs` sizes a block-RAM delay line
/// (0.26 Mbit: an eighth of the XC6SLX45's block RAM). A constant because
/// the design's types are generated from it.
pub const DEMO_N_MAX: u32 = 112;

/// Tracking slots M of the demo's design. The demo's 400,000 planes never
/// need more than 15 at once (measured on its scene at 64×64, 1.8 times
/// the area: 2 candidates dropped with 12 slots, none with 16, and the
/// same localisations as with the 32 of the full-field design); half the
/// slots halve the tracker, the largest part of the simulation's time per
/// clock.
pub const DEMO_SLOTS: usize = 16;

/// Pixels per clock of every configuration (see `smartagg_hdl`'s crate docs).
pub const P: usize = smartagg_hdl::designs::PIXELS_PER_CLOCK;

/// SPCImager 150× pipeline (block-RAM delay line, M = 16) on the demo's
/// 48×48 field. Parameters: those of `smartagg_hdl::pipeline::Pipeline`
/// (P, DAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW).
pub type Spcimager150Demo = Pipeline<16, 14, 7, 8, 15, 23, 2, 8, 17, 9, 6, 5, 232, 552, 53, 9, 12>;

impl DesignSpec {
    /// A shipped configuration on a field of its sensor: any `width` ×
    /// `height` up to the sensor's, the width a multiple of P = 16 and at
    /// least 2P, the height more than the ROI side (and, for a DDR2 design,
    /// a plane of whole 32-bit words). The error names these limits.
    pub fn new(config: Config, width: usize, height: usize) -> Result<DesignSpec, DesignError> {
        let shipped = config.shipped()?;
        let sensor = &shipped.config.front;
        let (sw, sh) = (sensor.width, sensor.height);
        let r = shipped.config.roi_size;
        let ddr = shipped.delay_line == DelayLineKind::Ddr2;
        let ok = width.is_multiple_of(P)
            && (2 * P..=sw).contains(&width)
            && (r + 1..=sh).contains(&height)
            && (!ddr || (width * height).is_multiple_of(32));
        if !ok {
            return Err(DesignError::Unsupported {
                what: format!("{} on {width}x{height}", config.name()),
                why: format!(
                    "its design is sized for the sensor's {sw}x{sh}: any field with a width that is a multiple of {P} from {} to {sw} and a height from {} to {sh}{}",
                    2 * P,
                    r + 1,
                    if ddr { " (width x height a multiple of 32: whole 32-bit DDR2 words)" } else { "" }
                ),
            });
        }
        let sized_for = ((width, height) != (sw, sh)).then_some((sw, sh));
        let front = GatewareConfig {
            width,
            height,
            sized_for,
            ..sensor.clone()
        };
        front.validate()?;
        Ok(DesignSpec {
            config,
            width,
            height,
            ddr: Ddr2Timing::default(),
            r_assoc: 1,
            front,
            delay_line: shipped.delay_line,
            demo: false,
        })
    }

    /// The demo's design: SPCImager 150× on its [`DEMO`] field, sized for
    /// that field alone ([`DEMO_N_MAX`] planes of block RAM, [`DEMO_SLOTS`]
    /// slots), the pipeline core driven through its word port.
    pub fn demo() -> Result<DesignSpec, DesignError> {
        let front = GatewareConfig {
            width: DEMO.0,
            height: DEMO.1,
            n_max: DEMO_N_MAX,
            sized_for: None,
            ..Config::Spcimager150.shipped()?.config.front
        };
        front.validate()?;
        Ok(DesignSpec {
            config: Config::Spcimager150,
            width: DEMO.0,
            height: DEMO.1,
            ddr: Ddr2Timing::default(),
            r_assoc: 1,
            front,
            delay_line: DelayLineKind::BlockRam,
            demo: true,
        })
    }

    /// The same configuration with association radius `r_assoc` (0..=16).
    pub fn with_r_assoc(mut self, r_assoc: u32) -> Result<DesignSpec, DesignError> {
        if r_assoc > 16 {
            return Err(DesignError::Unsupported {
                what: format!("r_assoc = {r_assoc}"),
                why: "0..=16 pixels".into(),
            });
        }
        self.r_assoc = r_assoc;
        Ok(self)
    }

    /// The front half's generation parameters: the shipped design's (kernel,
    /// N_max, DSP multiplies) on this field.
    pub fn front(&self) -> Result<GatewareConfig, DesignError> {
        Ok(self.front.clone())
    }

    /// The back half's generation parameters, as `hdl`'s
    /// [`Design`] derives them: M slots, R = k, r_assoc (1 unless
    /// [`DesignSpec::with_r_assoc`]), L_max,max = 65,535.
    pub fn back(&self) -> Result<BackHalfConfig, DesignError> {
        let front = self.front()?;
        let mut cfg = smartagg_model::config::PipelineConfig::new(
            front.width,
            front.height,
            front.n_max.min(18),
            front.kernel.clone(),
            front.kernel_shift,
            1,
        );
        cfg.slots = self.slots();
        cfg.roi_size = front.kernel.len();
        cfg.r_assoc = self.r_assoc;
        Ok(BackHalfConfig::new(
            &cfg,
            front,
            smartagg_hdl::designs::L_MAX_MAX,
        )?)
    }

    /// Word-address bits of the DDR2 model: N_max slots of a plane's
    /// 32-bit words rounded up to a power of two (the delay line's layout).
    pub fn ddr_address_bits(&self) -> usize {
        let plane_words = (self.width * self.height / 32) as u64;
        let slot_bits = smartagg_hdl::config::bits_for(plane_words * 4 - 1);
        slot_bits - 2 + smartagg_hdl::config::bits_for(self.n_max() as u64 - 1)
    }

    /// Whether the delay line is in DDR2 (the DDR2 model is verilated beside
    /// the core).
    pub fn ddr(&self) -> bool {
        self.delay_line == DelayLineKind::Ddr2
    }

    /// Whether the XEM6310 core is simulated (FrontPanel endpoints and the
    /// sensor port): every shipped design; not the demo's pipeline.
    pub fn xem(&self) -> bool {
        !self.demo
    }

    /// Largest N the design supports.
    pub fn n_max(&self) -> u32 {
        self.front.n_max
    }

    /// Tracking slots M: the shipped designs' 32; [`DEMO_SLOTS`] for the demo.
    pub fn slots(&self) -> usize {
        if self.demo {
            DEMO_SLOTS
        } else {
            smartagg_hdl::designs::SLOTS
        }
    }

    /// The Verilog of the generated core (module `top`), as `hdl` writes
    /// it: the shipped design's XEM6310 core type, or the demo's pipeline.
    /// Built on a thread of its own ([`on_generation_stack`]): a core is
    /// too large a value for a test thread's stack.
    pub fn top_verilog(&self) -> Result<String, DesignError> {
        let b = self.back()?;
        on_generation_stack(|| {
            Ok(match self.config {
                _ if self.demo => verilog(Spcimager150Demo::new(&b)?),
                Config::Spcimager150 => verilog(Spcimager150Core::new(&b)?),
                Config::Spcimager60 => verilog(Spcimager60Core::new(&b)?),
                Config::Projected150 => verilog(Projected150Core::new(&b)?),
                Config::Projected60 => verilog(Projected60Core::new(&b)?),
            })
        })
    }

    /// Prefix of the pipeline's instance path inside the wrapper.
    fn pipe_path(&self) -> &'static str {
        if self.xem() {
            "core.pipe."
        } else {
            "core."
        }
    }

    /// Stage probes of a debug build: (port name, width, expression).
    fn probes(&self) -> Result<Vec<(String, usize, String)>, DesignError> {
        let f = self.front()?;
        let pp = self.pipe_path();
        let cw = f.count_bits();
        let hw = f.filtered_bits();
        let mut v = Vec::new();
        let lanes = |inst: &str, name: &str| -> String {
            let parts: Vec<String> = (0..P)
                .rev()
                .map(|i| format!("{pp}{inst}.{name}${i}"))
                .collect();
            format!("{{{}}}", parts.join(", "))
        };
        // The delay line's and the front half's words are bundles
        // (`out$field`); the front half's inner stages have `out_field`.
        for (tag, port) in [
            ("d", "delay.out$"),
            ("c", "front.count.out_"),
            ("f", "front.filter.out_"),
            ("k", "front.out$"),
        ] {
            v.push((format!("{tag}_valid"), 1, format!("{pp}{port}valid")));
            v.push((format!("{tag}_flush"), 1, format!("{pp}{port}flush")));
            v.push((format!("{tag}_x"), 16, format!("{pp}{port}x")));
            v.push((format!("{tag}_y"), 16, format!("{pp}{port}y")));
        }
        v.push(("d_live".into(), P, format!("{pp}delay.out$live")));
        v.push(("d_delayed".into(), P, format!("{pp}delay.out$delayed")));
        v.push(("c_counts".into(), P * cw, lanes("front.count", "counts")));
        v.push(("f_h".into(), P * hw, lanes("front.filter", "filtered")));
        v.push(("k_above".into(), P, format!("{pp}front.out$above")));
        v.push(("k_cand".into(), P, format!("{pp}front.out$candidate")));
        Ok(v)
    }

    /// The complete Verilog verilated: the top, the DDR2 model (DDR2
    /// configurations) and the `cosim` wrapper; `debug` adds the probes.
    pub fn cosim_verilog(&self, top: &str, debug: bool) -> Result<String, DesignError> {
        let top = clock_wires(top);
        let top = top.as_str();
        let pp = self.pipe_path();
        // Which sticky fault flag rose: always exposed (three bits, no cost).
        let mut probes = vec![("fault_back".to_string(), 1, format!("{pp}back.fault"))];
        // The back half's five sticky sources, so that a FAULT names its buffer.
        for (port, inst) in [
            ("fault_tracker_fifo", "tfifo.overflow"),
            ("fault_roi_ring", "agg.overrun"),
            ("fault_bank", "tracker.bank_error"),
            ("fault_record_queue", "queue.overflow"),
            ("fault_output_fifo", "ofifo.overflow"),
        ] {
            probes.push((port.to_string(), 1, format!("{pp}back.{inst}")));
        }
        if self.ddr() {
            probes.push(("fault_underrun".into(), 1, format!("{pp}delay.underrun")));
            probes.push(("fault_write".into(), 1, format!("{pp}delay.write_error")));
        }
        if debug {
            probes.extend(self.probes()?);
        }
        let mcb = if self.ddr() {
            McbPort::Ddr2(self.ddr_address_bits())
        } else if self.xem() {
            McbPort::Parked
        } else {
            McbPort::Absent
        };
        wrapper(top, mcb, &self.ddr, probes)
    }

    /// Verilator build options for the wrapper.
    pub fn build_options(debug: bool) -> BuildOptions {
        BuildOptions {
            trace: debug,
            top: "cosim".into(),
            clock: "clock".into(),
            // The fast build is profile-guided (trained by the harness); the
            // debug build only runs to locate a mismatch.
            profile: !debug,
        }
    }
}

/// The fields of the top's MCB user port (`mcb$…`), connected to the DDR2
/// model.
const MCB: [&str; 13] = [
    "calib_done",
    "cmd_en",
    "cmd_instr",
    "cmd_bl",
    "cmd_addr",
    "cmd_full",
    "wr_en",
    "wr_mask",
    "wr_data",
    "wr_full",
    "rd_en",
    "rd_data",
    "rd_empty",
];

/// The top's ports allowing rust-hdl's `$` (vector elements).
fn top_ports(verilog: &str) -> Result<Vec<(String, Dir, usize)>, DesignError> {
    Ok(crate::verilator::declared_ports(verilog, "top")?
        .into_iter()
        .map(|p| (p.name, p.dir, p.width))
        .collect())
}

fn decl(dir: &str, width: usize, name: &str) -> String {
    if width == 1 {
        format!("    {dir} wire {name};\n")
    } else {
        format!("    {dir} wire [{}:0] {name};\n", width - 1)
    }
}

/// What the wrapper connects to the core's MCB user port.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum McbPort {
    /// The DDR2 behavioural model, with this many word-address bits.
    Ddr2(usize),
    /// Parked as `Xem6310TopOnChip` parks it (calibrated, never full,
    /// never a read word): a block-RAM design's core.
    Parked,
    /// No MCB port (the demo's pipeline).
    Absent,
}

/// The MCB inputs of a parked port and their values, as the on-chip top
/// ties them.
const MCB_PARKED: [(&str, &str); 5] = [
    ("calib_done", "1'b1"),
    ("cmd_full", "1'b0"),
    ("wr_full", "1'b0"),
    ("rd_data", "32'h0"),
    ("rd_empty", "1'b1"),
];

/// The `cosim` wrapper around `top`: its ports (with `$` as `_`), the DDR2
/// model or the parking of the MCB port, and probe outputs.
fn wrapper(
    top: &str,
    mcb: McbPort,
    timing: &Ddr2Timing,
    probes: Vec<(String, usize, String)>,
) -> Result<String, DesignError> {
    let ddr_aw = match mcb {
        McbPort::Ddr2(aw) => Some(aw),
        _ => None,
    };
    let ports = top_ports(top)?;
    let mut names = Vec::new();
    let mut decls = String::new();
    let mut conns = Vec::new();
    let mut wires = String::new();
    for (name, dir, width) in &ports {
        let ext = name.replace('$', "_");
        let field = name
            .strip_prefix("mcb$")
            .filter(|f| MCB.contains(f) && mcb != McbPort::Absent);
        if let (McbPort::Parked, Some(field)) = (mcb, field) {
            if let Some((_, v)) = MCB_PARKED.iter().find(|(n, _)| *n == field) {
                conns.push(format!(".{name}({v})"));
            } else {
                conns.push(format!(".{name}()"));
            }
            continue;
        }
        if let (Some(_), Some(field)) = (ddr_aw, field) {
            let range = if *width == 1 {
                String::new()
            } else {
                format!("[{}:0] ", width - 1)
            };
            let _ = writeln!(wires, "    wire {range}mcb_{field};");
            conns.push(format!(".{name}(mcb_{field})"));
            continue;
        }
        let d = if *dir == Dir::In { "input" } else { "output" };
        decls.push_str(&decl(d, *width, &ext));
        names.push(ext.clone());
        conns.push(format!(".{name}({ext})"));
    }
    let mut body = String::new();
    if ddr_aw.is_some() {
        for n in ["ddr_error", "ddr_refresh_collisions", "ddr_refreshes"] {
            names.push(n.into());
        }
        decls.push_str(&decl("output", 1, "ddr_error"));
        decls.push_str(&decl("output", 32, "ddr_refresh_collisions"));
        decls.push_str(&decl("output", 32, "ddr_refreshes"));
        let mc: Vec<String> = MCB.iter().map(|m| format!(".{m}(mcb_{m})")).collect();
        let _ = writeln!(
            body,
            "    cosim_ddr2 ddr(.clock(clock), {}, .error(ddr_error), \
             .refresh_collisions(ddr_refresh_collisions), .refreshes(ddr_refreshes));",
            mc.join(", ")
        );
    }
    for (name, width, expr) in &probes {
        names.push(name.clone());
        decls.push_str(&decl("output", *width, name));
        let _ = writeln!(body, "    assign {name} = {expr};");
    }
    let mut v = String::new();
    v.push_str(top);
    if let Some(aw) = ddr_aw {
        v.push_str(&ddr2::verilog(aw, timing));
    }
    let _ = write!(
        v,
        "\n// Co-simulation wrapper (smartagg-sim).\nmodule cosim({});\n{decls}{wires}    top core({});\n{body}endmodule\n",
        names.join(", "),
        conns.join(", ")
    );
    Ok(v)
}

/// A deliberate fault in the spatial filter: the vertical pass's symmetric
/// tap pair nearest the centre adds the centre line instead of the line
/// beside it (an off-by-one in the line-buffer index).
pub fn inject_filter_fault(verilog: &str) -> Result<String, DesignError> {
    let start = verilog
        .find("module top$pipe$front$filter(")
        .or_else(|| verilog.find("module top$front$filter("))
        .ok_or_else(|| DesignError::Fault("no spatial filter module".into()))?;
    let end = start
        + verilog[start..]
            .find("endmodule")
            .ok_or_else(|| DesignError::Fault("unterminated filter module".into()))?;
    // Lane 0's pairs `vpair$d$i = tap$a + tap$b;` come first; the one with
    // the smallest b − a is next to the centre.
    let mut best: Option<(usize, usize, usize)> = None; // (gap, position of b, length of b)
    let mut at = start;
    while let Some(off) = verilog[at..end].find("vpair$") {
        let line_start = at + off;
        let line_end = line_start + verilog[line_start..end].find(';').unwrap_or(0);
        let line = &verilog[line_start..line_end];
        at = line_end.max(line_start + 1);
        let Some((_, rhs)) = line
            .split_once("$d$")
            .and_then(|(_, r)| r.split_once(" = tap$"))
        else {
            continue;
        };
        let Some((a, b)) = rhs.split_once(" + tap$") else {
            continue;
        };
        let (Ok(a), Ok(b)) = (a.trim().parse::<usize>(), b.trim().parse::<usize>()) else {
            continue;
        };
        if a == 0 && best.is_some() {
            break;
        }
        if b > a + 1 && best.is_none_or(|(g, _, _)| b - a < g) {
            let bpos = line_start + line.rfind("tap$").unwrap_or(0) + 4;
            best = Some((b - a, bpos, b.to_string().len()));
        }
        if b.saturating_sub(a) <= 2 {
            break;
        }
    }
    let (_, bpos, blen) =
        best.ok_or_else(|| DesignError::Fault("no vertical tap pair in the filter".into()))?;
    let b: usize = verilog[bpos..bpos + blen]
        .parse()
        .map_err(|_| DesignError::Fault("tap index".into()))?;
    Ok(format!(
        "{}{}{}",
        &verilog[..bpos],
        b - 1,
        &verilog[bpos + blen..]
    ))
}
/// rust-hdl distributes the clock through combinational `always @(*)`
/// blocks (`child$clock = clock;`), which makes Verilator re-evaluate those
/// whole blocks on every clock edge and treat every child clock as a
/// derived clock. The same netlist with the clock distributed by wires
/// (`wire child$clock = clock;`) is equivalent and several times faster to
/// simulate: this rewrites exactly those declarations and assignments.
pub fn clock_wires(verilog: &str) -> String {
    let mut out = String::with_capacity(verilog.len());
    for line in verilog.lines() {
        let t = line.trim();
        if let Some(name) = t
            .strip_prefix("reg  ")
            .and_then(|r| r.strip_suffix(';'))
            .filter(|n| n.ends_with("$clock") && !n.contains(' '))
        {
            out.push_str(&format!("    wire {name} = clock;\n"));
            continue;
        }
        if let Some(name) = t.strip_suffix(" = clock;") {
            if name.ends_with("$clock") && !name.contains(' ') {
                continue;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shipped_design_is_a_configuration_and_its_full_field_is_the_shipped_generation() {
        let shipped = Design::all().unwrap();
        assert_eq!(shipped.len(), Config::ALL.len());
        for d in shipped {
            let c = Config::for_preset(d.preset, d.objective).unwrap();
            let (w, h) = (d.config.front.width, d.config.front.height);
            let spec = DesignSpec::new(c, w, h)
                .and_then(|s| s.with_r_assoc(d.config.r_assoc))
                .unwrap();
            assert_eq!(spec.back().unwrap(), d.config, "{}", c.name());
            assert_eq!(spec.ddr(), d.delay_line == DelayLineKind::Ddr2);
            assert!(spec.xem());
        }
        assert!(Config::for_preset(PresetName::Spcimager, 100).is_err());
    }

    #[test]
    fn any_field_of_the_sensor_is_a_design_sized_for_the_sensor() {
        for (c, w, h) in [
            (Config::Spcimager150, 96, 72),
            (Config::Spcimager60, 48, 48),
            (Config::Projected150, 64, 48),
            (Config::Projected60, 320, 16),
        ] {
            let spec = DesignSpec::new(c, w, h).unwrap();
            let f = spec.front().unwrap();
            assert_eq!((f.width, f.height), (w, h));
            assert_eq!(f.address_field(), FULL, "{}", c.name());
            // The address widths are the sensor's, so the shipped type fits.
            let full = DesignSpec::new(c, FULL.0, FULL.1).unwrap().front().unwrap();
            assert_eq!(full.sized_for, None);
            assert_eq!(f.count_addr_bits(), full.count_addr_bits());
            assert_eq!(f.line_addr_bits(), full.line_addr_bits());
            assert_eq!(f.delay_addr_bits(), full.delay_addr_bits());
            assert!(f.words_per_plane() < full.words_per_plane());
        }
        for (c, w, h) in [
            (Config::Spcimager150, 336, 240),
            (Config::Spcimager150, 320, 241),
            (Config::Spcimager150, 100, 72),
            (Config::Spcimager150, 16, 72),
            (Config::Spcimager150, 64, 9),
            // 3 words of 16 pixels × 7 rows: not whole 32-bit DDR2 words.
            (Config::Spcimager60, 48, 7),
        ] {
            let e = DesignSpec::new(c, w, h).unwrap_err().to_string();
            assert!(
                e.contains("320x240") && e.contains("multiple of 16"),
                "{w}x{h}: {e}"
            );
        }
        // A block-RAM design takes a plane of any whole number of P-pixel words.
        assert!(DesignSpec::new(Config::Projected60, 48, 7).is_ok());
    }

    #[test]
    fn the_demo_design_generates_with_its_association_radius() {
        let spec = DesignSpec::demo().and_then(|s| s.with_r_assoc(3)).unwrap();
        let b = spec.back().unwrap();
        assert_eq!(b.r_assoc, 3);
        assert_eq!(b.slots, DEMO_SLOTS);
        assert_eq!(b.front.n_max, DEMO_N_MAX);
        assert!(!spec.ddr(), "the demo's delay line is in block RAM");
        // N_max follows smartagg_hdl::designs's rule for the SPCImager 150×
        // window, and fits block RAM as that rule sizes it: at most half of
        // the XC6SLX45's.
        let full = smartagg_hdl::designs::Design::new(PresetName::Spcimager, 150).unwrap();
        assert_eq!(
            DEMO_N_MAX,
            smartagg_hdl::designs::block_ram_n_max(full.n_window),
            "N = {}",
            full.n_window
        );
        let bits = (DEMO.0 * DEMO.1) as u64 * DEMO_N_MAX as u64;
        assert!(2 * bits <= smartagg_hdl::device::XC6SLX45.block_ram_bits());
        let v = spec.top_verilog().unwrap();
        assert!(v.contains("module top"));
        assert!(!spec.xem() && spec.slots() == DEMO_SLOTS);
        assert!(spec.with_r_assoc(17).is_err());
    }
}
