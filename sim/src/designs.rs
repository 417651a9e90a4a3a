//! The configurations co-simulated: the generated gateware top (rust-hdl
//! Verilog) inside a co-simulation wrapper (`cosim`) that adds the DDR2
//! model and, in debug builds, probe ports on every stage's output.
//!
//! Configurations follow `smartagg_hdl::pipeline`'s: SPCImager 150× (DDR2
//! delay line, N_max = 128, M = 32, 9×9 ROIs), SPCImager 60× (the same
//! design rules with the model's kernel for the 60× PSF) and the projected
//! SPCImager 150× (block-RAM delay line, N_max = 24), each on a reduced
//! 64×32 field, and SPCImager 150× on the full 320×240 field. rust-hdl
//! widths are type parameters, so each field size is its own type alias
//! below; [`DesignSpec::back`] computes the configuration and the block's
//! `new` checks that every width of the alias follows from it.

use crate::ddr2::{self, Ddr2Timing};
use crate::verilator::{BuildOptions, Dir, VerilatorError};
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig, GatewareError};
use smartagg_hdl::front_half::verilog;
use smartagg_hdl::pipeline::Pipeline;
use smartagg_hdl::xem6310::XemCore;
use smartagg_model::kernel::IntegerKernel;
use smartagg_model::params::{Preset, PresetName};
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
    /// No generated type for this field size.
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

/// The configurations with a generated gateware.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Config {
    /// SPCImager, 150× objective (DDR2 delay line).
    Spcimager150,
    /// SPCImager, 60× objective (DDR2 delay line).
    Spcimager60,
    /// Projected SPCImager, 150× objective (block-RAM delay line).
    Projected150,
}

impl Config {
    /// The configuration of a preset and objective.
    pub fn for_preset(name: PresetName, objective: u32) -> Result<Config, DesignError> {
        match (name, objective) {
            (PresetName::Spcimager, 150) => Ok(Config::Spcimager150),
            (PresetName::Spcimager, 60) => Ok(Config::Spcimager60),
            (PresetName::SpcimagerProjected, 150) => Ok(Config::Projected150),
            _ => Err(DesignError::Unsupported {
                what: format!("{name} at {objective}x"),
                why: "generated: spcimager 150/60, spcimager-projected 150".into(),
            }),
        }
    }

    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Config::Spcimager150 => "spcimager/150x",
            Config::Spcimager60 => "spcimager/60x",
            Config::Projected150 => "spcimager-projected/150x",
        }
    }

    /// The preset and objective (the inverse of [`Config::for_preset`]).
    fn preset_name(self) -> (PresetName, u32) {
        match self {
            Config::Spcimager150 => (PresetName::Spcimager, 150),
            Config::Spcimager60 => (PresetName::Spcimager, 60),
            Config::Projected150 => (PresetName::SpcimagerProjected, 150),
        }
    }

    fn preset(self) -> Result<Preset, DesignError> {
        let (n, o) = self.preset_name();
        Preset::new(n, o).map_err(|e| DesignError::Model(e.to_string()))
    }

    /// Largest N of the configuration's design on its full field
    /// ([`DesignSpec::n_max`] is the generated design's).
    fn n_max(self) -> u32 {
        match self {
            Config::Spcimager150 | Config::Spcimager60 => 128,
            Config::Projected150 => 24,
        }
    }

    /// The kernel k1 and its shift: the hdl's constants for 150× (so the
    /// design is the one `hdl` generates), the model's kernel for σ at 60×.
    pub fn kernel(self) -> Result<(Vec<u32>, u8), DesignError> {
        match self {
            Config::Spcimager150 | Config::Projected150 => {
                let f = smartagg_hdl::front_half::spcimager150_config();
                Ok((f.kernel, f.kernel_shift))
            }
            Config::Spcimager60 => {
                let sigma = self.preset()?.sigma_px();
                let k = IntegerKernel::default_for(sigma)
                    .map_err(|e| DesignError::Model(e.to_string()))?;
                Ok((k.weights, k.shift))
            }
        }
    }

    /// Whether the configuration's delay line is in DDR2 on its full field
    /// ([`DesignSpec::ddr`] is the generated design's).
    fn ddr(self) -> bool {
        !matches!(self, Config::Projected150)
    }

    /// The filter's DSP multiplies: every DSP slice of the device the
    /// configuration is generated for (as `smartagg_hdl::configs::Design`).
    fn dsp_multipliers(self) -> usize {
        smartagg_hdl::configs::device_for(self.preset_name().0).dsp48a1 as usize
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
}

/// The reduced field of every configuration.
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
/// multiple of 8 (`smartagg_hdl::configs::block_ram_n_max`, checked by a
/// test), as `smartagg_hdl::configs` sizes a block-RAM delay line
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
pub const P: usize = 16;

// The generated types. Parameters: those of `smartagg_hdl::pipeline::PipelineDdr`
// (P, PAW, CW, CAW, VW, HW, LAW, RAW, RCW, CAW2, BW, QAW, QW, PW, TW, TAW, OAW)
// and of `Pipeline` (DAW in place of PAW).

/// SPCImager 150× core on 64×32.
pub type Spcimager150Reduced =
    XemCore<16, 9, 8, 7, 16, 24, 2, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12>;
/// SPCImager 60× core on 64×32 (the model's kernel for the 60× PSF:
/// σ = 0.61 px, k = 5, a = 8; R = 5).
pub type Spcimager60Reduced = XemCore<16, 9, 8, 7, 16, 24, 2, 8, 17, 9, 7, 6, 233, 488, 53, 9, 12>;
/// Projected SPCImager 150× pipeline (block-RAM delay line) on 64×32.
pub type Projected150Reduced =
    Pipeline<16, 12, 5, 7, 13, 21, 2, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12>;
/// SPCImager 150× pipeline (block-RAM delay line, M = 16) on the demo's 48×48 field.
pub type Spcimager150Demo = Pipeline<16, 14, 7, 8, 15, 23, 2, 8, 17, 9, 6, 5, 232, 552, 53, 9, 12>;
/// SPCImager 150× core on the full 320×240 field.
pub type Spcimager150Full = XemCore<16, 9, 8, 13, 16, 24, 5, 8, 17, 10, 7, 6, 233, 552, 53, 9, 12>;

impl DesignSpec {
    /// A configuration on a field (one of [`REDUCED`] and, for SPCImager
    /// 150×, [`FULL`]).
    pub fn new(config: Config, width: usize, height: usize) -> Result<DesignSpec, DesignError> {
        let ok = (width, height) == REDUCED
            || (((width, height) == FULL || (width, height) == DEMO)
                && config == Config::Spcimager150);
        if !ok {
            return Err(DesignError::Unsupported {
                what: format!("{} on {width}x{height}", config.name()),
                why: format!(
                    "generated fields: {}x{} for every configuration, {}x{} and {}x{} for spcimager/150x",
                    REDUCED.0, REDUCED.1, FULL.0, FULL.1, DEMO.0, DEMO.1
                ),
            });
        }
        Ok(DesignSpec {
            config,
            width,
            height,
            ddr: Ddr2Timing::default(),
            r_assoc: 1,
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

    /// The front half's generation parameters.
    pub fn front(&self) -> Result<GatewareConfig, DesignError> {
        let (kernel, kernel_shift) = self.config.kernel()?;
        let g = GatewareConfig {
            width: self.width,
            height: self.height,
            pixels_per_clock: P,
            n_max: self.n_max(),
            kernel,
            kernel_shift,
            dsp_multipliers: self.config.dsp_multipliers(),
        };
        g.validate()?;
        Ok(g)
    }

    /// The back half's generation parameters, as `hdl`'s
    /// `spcimager150_back_config` derives them: M = 32, R = k, r_assoc (1
    /// unless [`DesignSpec::with_r_assoc`]), L_max,max = 65,535.
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
        Ok(BackHalfConfig::new(&cfg, front, 65_535)?)
    }

    /// Word-address bits of the DDR2 model: N_max slots of a plane's
    /// 32-bit words rounded up to a power of two (the delay line's layout).
    pub fn ddr_address_bits(&self) -> usize {
        let plane_words = (self.width * self.height / 32) as u64;
        let slot_bits = smartagg_hdl::config::bits_for(plane_words * 4 - 1);
        slot_bits - 2 + smartagg_hdl::config::bits_for(self.n_max() as u64 - 1)
    }

    /// Whether the delay line is in DDR2 and the XEM6310 core is simulated
    /// (the configuration's, except on the [`DEMO`] field, whose design keeps
    /// it in block RAM).
    pub fn ddr(&self) -> bool {
        self.config.ddr() && !self.is_demo()
    }

    /// Largest N the design supports.
    pub fn n_max(&self) -> u32 {
        if self.is_demo() {
            DEMO_N_MAX
        } else {
            self.config.n_max()
        }
    }

    /// Tracking slots M: 32, the model's default; [`DEMO_SLOTS`] on the demo's field.
    pub fn slots(&self) -> usize {
        if self.is_demo() {
            DEMO_SLOTS
        } else {
            32
        }
    }

    fn is_demo(&self) -> bool {
        (self.width, self.height) == DEMO && self.config == Config::Spcimager150
    }

    /// The Verilog of the generated top (module `top`), as `hdl` writes it.
    pub fn top_verilog(&self) -> Result<String, DesignError> {
        let b = self.back()?;
        let field = (self.width, self.height);
        Ok(match (self.config, field == FULL) {
            (Config::Spcimager150, _) if field == DEMO => verilog(Spcimager150Demo::new(&b)?),
            (Config::Spcimager150, false) => verilog(Spcimager150Reduced::new(&b)?),
            (Config::Spcimager150, true) => verilog(Spcimager150Full::new(&b)?),
            (Config::Spcimager60, _) => verilog(Spcimager60Reduced::new(&b)?),
            (Config::Projected150, _) => verilog(Projected150Reduced::new(&b)?),
        })
    }

    /// Prefix of the pipeline's instance path inside the wrapper.
    fn pipe_path(&self) -> &'static str {
        if self.ddr() {
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
        for (tag, inst) in [
            ("d", "delay"),
            ("c", "front.count"),
            ("f", "front.filter"),
            ("k", "front"),
        ] {
            v.push((format!("{tag}_valid"), 1, format!("{pp}{inst}.out_valid")));
            v.push((format!("{tag}_flush"), 1, format!("{pp}{inst}.out_flush")));
            v.push((format!("{tag}_x"), 16, format!("{pp}{inst}.out_x")));
            v.push((format!("{tag}_y"), 16, format!("{pp}{inst}.out_y")));
        }
        v.push(("d_live".into(), P, format!("{pp}delay.out_live")));
        v.push(("d_delayed".into(), P, format!("{pp}delay.out_delayed")));
        v.push(("c_counts".into(), P * cw, lanes("front.count", "counts")));
        v.push(("f_h".into(), P * hw, lanes("front.filter", "filtered")));
        v.push(("k_above".into(), P, lanes("front", "above")));
        v.push(("k_cand".into(), P, lanes("front", "candidate")));
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
        wrapper(
            top,
            self.ddr().then(|| self.ddr_address_bits()),
            &self.ddr,
            probes,
        )
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

/// MCB user-port signals of the top, connected to the DDR2 model.
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

/// The `cosim` wrapper around `top`: its ports (with `$` as `_`), the DDR2
/// model on the MCB port if `ddr_aw` is given, and probe outputs.
fn wrapper(
    top: &str,
    ddr_aw: Option<usize>,
    timing: &Ddr2Timing,
    probes: Vec<(String, usize, String)>,
) -> Result<String, DesignError> {
    let ports = top_ports(top)?;
    let mut names = Vec::new();
    let mut decls = String::new();
    let mut conns = Vec::new();
    let mut wires = String::new();
    for (name, dir, width) in &ports {
        let ext = name.replace('$', "_");
        if ddr_aw.is_some() && MCB.contains(&name.as_str()) {
            let range = if *width == 1 {
                String::new()
            } else {
                format!("[{}:0] ", width - 1)
            };
            let _ = writeln!(wires, "    wire {range}mcb_{ext};");
            conns.push(format!(".{name}(mcb_{ext})"));
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
    fn the_demo_design_generates_with_its_association_radius() {
        let spec = DesignSpec::new(Config::Spcimager150, DEMO.0, DEMO.1)
            .and_then(|s| s.with_r_assoc(3))
            .unwrap();
        let b = spec.back().unwrap();
        assert_eq!(b.r_assoc, 3);
        assert_eq!(b.slots, DEMO_SLOTS);
        assert_eq!(b.front.n_max, DEMO_N_MAX);
        assert!(!spec.ddr(), "the demo's delay line is in block RAM");
        // N_max follows smartagg_hdl::configs's rule for the SPCImager 150×
        // window, and fits block RAM as that rule sizes it: at most half of
        // the XC6SLX45's.
        let full = smartagg_hdl::configs::Design::new(PresetName::Spcimager, 150).unwrap();
        assert_eq!(
            DEMO_N_MAX,
            smartagg_hdl::configs::block_ram_n_max(full.n_window),
            "N = {}",
            full.n_window
        );
        let bits = (DEMO.0 * DEMO.1) as u64 * DEMO_N_MAX as u64;
        assert!(2 * bits <= smartagg_hdl::configs::XC6SLX45.block_ram_bits());
        let v = spec.top_verilog().unwrap();
        assert!(v.contains("module top"));
        assert!(DesignSpec::new(Config::Spcimager60, DEMO.0, DEMO.1).is_err());
        assert!(spec.with_r_assoc(17).is_err());
    }
}
