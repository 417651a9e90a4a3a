//! `smartagg hdl`: the gateware of a preset at an objective
//! (`smartagg_hdl::designs`).
//!
//! * `hdl generate` writes the design's Verilog (`top.v`, its hash in
//!   `top.v.hash`), its Verilator configuration (`top.vlt`: the waivers of
//!   rust-hdl's idioms, line by line, so that `verilator --lint-only -Wall
//!   --top-module top top.vlt top.v` is clean), the XEM6310 constraints (`xem6310.ucf`)
//!   and an ISE 14.7 project script (`build.tcl`, run with `xtclsh`) that
//!   adds them beside Opal Kelly's FrontPanel HDL and the MIG DDR2 core,
//!   which are proprietary and supplied by the user.
//! * `hdl resources` synthesises the same Verilog text with yosys
//!   `synth_xilinx -family xc6s -flatten`, maps the prepared design's LUTs
//!   four ways (`smartagg_hdl::synth::MAPPINGS`: one of them in two
//!   netlist orders) and reports, for each mapped netlist, LUT, FF, block
//!   RAM and DSP use against the XC6SLX45 and XC6SLX150 and its depth in
//!   LUT levels, the smallest netlist within the target depth, the
//!   analytic floors, the throughput arithmetic, and the yosys script that
//!   reproduces them.

use anyhow::{bail, Context};
use serde::Serialize;
use smartagg_hdl::designs::{text_hash, DelayLineKind, Design, TopKind};
use smartagg_hdl::device::DEVICES;
use smartagg_hdl::ise::build_tcl;
use smartagg_hdl::lint_waivers::{verilator_config, VLT_FILE};
use smartagg_hdl::synth::{
    yosys_resources, yosys_script, Netlist, Synthesis, ABC_D7, ABC_D7_READ_BACK, LUT_LEVELS_TARGET,
    MAPPINGS,
};
use smartagg_model::params::PresetName;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `smartagg hdl` subcommands.
#[derive(clap::Subcommand, Debug)]
pub enum Command {
    /// Write a design's Verilog, its Verilator lint waivers, its UCF and an ISE 14.7 (xtclsh) project script.
    Generate(GenerateArgs),
    /// Synthesise a design with yosys for the Spartan-6 and report its resources.
    Resources(ResourcesArgs),
}

/// Arguments of `smartagg hdl generate`.
#[derive(clap::Args, Debug)]
pub struct GenerateArgs {
    /// Camera preset: spcimager or spcimager-projected.
    #[arg(long)]
    pub preset: String,
    /// Objective magnification: 150 or 60.
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
}

/// Arguments of `smartagg hdl resources`.
#[derive(clap::Args, Debug)]
pub struct ResourcesArgs {
    /// Camera preset: spcimager or spcimager-projected.
    #[arg(long, required_unless_present = "verilog")]
    pub preset: Option<String>,
    /// Objective magnification: 150 or 60.
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
    /// Synthesise this Verilog file (top module `top`, e.g. one written by
    /// `hdl generate`) instead of generating the preset's design.
    #[arg(long, conflicts_with = "preset")]
    pub verilog: Option<PathBuf>,
    /// Directory for yosys's files (`top.v`, `synth.ys`, `yosys.log`, the deepest paths of each mapping; default: a temporary one, removed).
    #[arg(long)]
    pub work: Option<PathBuf>,
    /// Print JSON instead of the summary.
    #[arg(long)]
    pub json: bool,
}

/// Runs a `smartagg hdl` subcommand.
pub fn run(cmd: Command) -> anyhow::Result<()> {
    match cmd {
        Command::Generate(a) => generate(a),
        Command::Resources(a) => resources(a),
    }
}

fn design(preset: &str, objective: u32) -> anyhow::Result<Design> {
    let name = PresetName::parse(preset)?;
    Ok(Design::new(name, objective)?)
}

fn write(path: &Path, text: &str) -> anyhow::Result<()> {
    Ok(smartagg_io::output::write_atomic(path, text.as_bytes())?)
}

fn generate(a: GenerateArgs) -> anyhow::Result<()> {
    let d = design(&a.preset, a.objective)?;
    let v = d.verilog()?;
    let hash = text_hash(&v);
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("creating the output directory {}", a.out.display()))?;
    write(&a.out.join("top.v"), &v)?;
    write(&a.out.join("top.v.hash"), &format!("{hash}  top.v\n"))?;
    write(&a.out.join(VLT_FILE), &verilator_config(&v))?;
    write(&a.out.join("xem6310.ucf"), d.ucf())?;
    write(&a.out.join("build.tcl"), &build_tcl(&d, &hash))?;
    println!(
        "{}: {} for the {} ({} delay line, N_max = {}, k = {}, M = {}, R = {})",
        d.name(),
        match d.top {
            TopKind::Xem6310 => "XEM6310 top",
            TopKind::Xem6310OnChip => "XEM6310 top (DDR2 parked)",
        },
        d.device.name,
        delay_line_name(d.delay_line),
        d.config.front.n_max,
        d.config.front.kernel.len(),
        d.config.slots,
        d.config.roi_size
    );
    println!(
        "wrote {} ({} bytes), top.v.hash, top.vlt, xem6310.ucf, build.tcl",
        a.out.join("top.v").display(),
        v.len()
    );
    println!("Verilog CRC-64/XZ {hash}");
    Ok(())
}

fn delay_line_name(k: DelayLineKind) -> &'static str {
    match k {
        DelayLineKind::BlockRam => "block-RAM",
        DelayLineKind::Ddr2 => "DDR2",
    }
}

#[derive(Serialize)]
struct DeviceUse {
    device: &'static str,
    lut_percent: f64,
    ff_percent: f64,
    block_ram_percent: f64,
    dsp_percent: f64,
    /// LUT ≤ 80 %, FF, block RAM and DSP ≤ 100 %.
    fits: bool,
    /// Fits, and at most `LUT_LEVELS_TARGET` LUT levels: both in this netlist.
    fits_within_levels: bool,
}

#[derive(Serialize)]
struct Throughput {
    pixels_per_clock: usize,
    clock_mhz: f64,
    words_per_plane: usize,
    planes_per_s: f64,
    busy_percent: f64,
    ddr2_refresh_percent: f64,
    headroom_percent: f64,
}

/// The figures of one mapped netlist: every count and depth of one row
/// comes from the same cells.
#[derive(Serialize)]
struct MappingReport {
    mapping: &'static str,
    about: &'static str,
    /// LUT1–LUT6 and inverters.
    luts: u64,
    inverters: u64,
    lut_ram: u64,
    ffs: u64,
    ramb16: u64,
    ramb8: u64,
    dsp48a1: u64,
    carry4: u64,
    logic_depth: Option<u64>,
    lut_levels: Option<u32>,
    carry_chain: Option<u32>,
    /// Groups of path ends whose deepest path has 0, 1, … LUT levels.
    ends_per_level: Vec<usize>,
    /// The worst path: its start, then its cells.
    worst_path: Vec<String>,
    /// Path ends deeper than the target, deepest first (at most 40).
    deep_ends: Vec<(String, u32)>,
    devices: Vec<DeviceUse>,
}

#[derive(Serialize)]
struct Report {
    design: String,
    verilog_crc64: String,
    verilog_bytes: usize,
    yosys_seconds: f64,
    /// The whole yosys script (`yosys -s synth.ys` beside `top.v`).
    yosys_script: String,
    lut_levels_target: u32,
    memory_bits: u64,
    ramb16_floor: u64,
    multipliers: u64,
    /// One entry per mapping of the same prepared design.
    mappings: Vec<MappingReport>,
    /// The mapping whose netlist has the fewest LUTs (LUT RAM included)
    /// among those within `lut_levels_target` levels, if any is.
    smallest_within_levels: Option<&'static str>,
    throughput: Option<Throughput>,
}

fn mapping_report(n: &Netlist) -> MappingReport {
    let r = &n.resources;
    let levels = r.lut_levels.as_ref();
    let ramb = r.ramb16 as f64 + r.ramb8 as f64 / 2.0;
    let shallow = levels.is_some_and(|l| l.levels <= LUT_LEVELS_TARGET);
    let devices = DEVICES
        .iter()
        .map(|dev| {
            let pct = |used: f64, cap: u64| 100.0 * used / cap as f64;
            let lut_percent = pct((r.luts + r.lutram) as f64, dev.luts);
            let ff_percent = pct(r.ffs as f64, dev.ffs);
            let block_ram_percent = pct(ramb, dev.ramb16);
            let dsp_percent = pct(r.dsp48a1 as f64, dev.dsp48a1);
            let fits = lut_percent <= 80.0
                && ff_percent <= 100.0
                && block_ram_percent <= 100.0
                && dsp_percent <= 100.0;
            DeviceUse {
                device: dev.name,
                lut_percent,
                ff_percent,
                block_ram_percent,
                dsp_percent,
                fits,
                fits_within_levels: fits && shallow,
            }
        })
        .collect();
    MappingReport {
        mapping: n.mapping.name,
        about: n.mapping.about,
        luts: r.luts,
        inverters: r.inverters,
        lut_ram: r.lutram,
        ffs: r.ffs,
        ramb16: r.ramb16,
        ramb8: r.ramb8,
        dsp48a1: r.dsp48a1,
        carry4: r.carry4,
        logic_depth: r.logic_depth,
        lut_levels: levels.map(|l| l.levels),
        carry_chain: levels.map(|l| l.carry_chain),
        ends_per_level: levels.map(|l| l.ends_per_level()).unwrap_or_default(),
        worst_path: levels
            .map(|l| {
                std::iter::once(l.start.clone())
                    .chain(l.path.iter().map(|(t, n)| format!("{t} {n}")))
                    .collect()
            })
            .unwrap_or_default(),
        deep_ends: levels
            .map(|l| {
                l.ends
                    .iter()
                    .filter(|(_, d)| *d > LUT_LEVELS_TARGET)
                    .take(40)
                    .cloned()
                    .collect()
            })
            .unwrap_or_default(),
        devices,
    }
}

fn report(name: String, v: &str, s: &Synthesis, seconds: f64, d: Option<&Design>) -> Report {
    let throughput = d.map(|d| {
        let t = d.throughput();
        Throughput {
            pixels_per_clock: t.pixels_per_clock,
            clock_mhz: t.clock_hz * 1e-6,
            words_per_plane: t.words_per_plane,
            planes_per_s: t.planes_per_s,
            busy_percent: 100.0 * t.busy_fraction,
            ddr2_refresh_percent: 100.0 * t.refresh_fraction,
            headroom_percent: 100.0 * t.headroom(),
        }
    });
    Report {
        design: name,
        verilog_crc64: text_hash(v),
        verilog_bytes: v.len(),
        yosys_seconds: seconds,
        yosys_script: yosys_script(&MAPPINGS),
        lut_levels_target: LUT_LEVELS_TARGET,
        memory_bits: s.memory_bits,
        ramb16_floor: s.ramb16_floor(),
        multipliers: s.multipliers,
        mappings: s.netlists.iter().map(mapping_report).collect(),
        smallest_within_levels: s.smallest_within_levels().map(|n| n.mapping.name),
        throughput,
    }
}

fn resources(a: ResourcesArgs) -> anyhow::Result<()> {
    if let Some(w) = &a.work {
        if w.exists() && !w.is_dir() {
            bail!("--work {}: exists and is not a directory", w.display());
        }
    }
    let (name, v, d) = match (&a.preset, &a.verilog) {
        (_, Some(path)) => {
            let v = std::fs::read_to_string(path)
                .with_context(|| format!("reading the Verilog file {}", path.display()))?;
            if !v.contains("module top") {
                bail!(
                    "{} has no module named `top` (the top module yosys synthesises)",
                    path.display()
                );
            }
            (path.display().to_string(), v, None)
        }
        (Some(p), None) => {
            let d = design(p, a.objective)?;
            let v = d.verilog()?;
            (d.name(), v, Some(d))
        }
        (None, None) => bail!("give --preset NAME or --verilog FILE"),
    };
    let (dir, temporary) = match &a.work {
        Some(w) => (w.clone(), false),
        None => (
            std::env::temp_dir().join(format!("smartagg-hdl-resources-{}", std::process::id())),
            true,
        ),
    };
    if !a.json {
        println!(
            "{name}: Verilog CRC-64/XZ {} ({} bytes); yosys synth_xilinx -family xc6s -flatten, \
             then {} LUT mappings of the same prepared design, in {} ...",
            text_hash(&v),
            v.len(),
            MAPPINGS.len(),
            dir.display()
        );
    }
    let t0 = Instant::now();
    let result = yosys_resources(&v, &dir, &MAPPINGS);
    let seconds = t0.elapsed().as_secs_f64();
    if temporary {
        let _ = std::fs::remove_dir_all(&dir);
    }
    let s = result?;
    let rep = report(name, &v, &s, seconds, d.as_ref());
    if a.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
        return Ok(());
    }
    print_report(&rep, d.as_ref(), &dir, temporary);
    Ok(())
}

fn print_report(rep: &Report, d: Option<&Design>, dir: &Path, temporary: bool) {
    println!(
        "yosys {:.0} s; floors: {} memory bits -> {} RAMB16; {} multipliers -> {} DSP48A1",
        rep.yosys_seconds, rep.memory_bits, rep.ramb16_floor, rep.multipliers, rep.multipliers
    );
    println!(
        "one row per netlist (its LUTs, RAM, DSP and depth all measured on the same cells; \
         LUT = LUT1-6 + INV; levels: CARRY4 and MUXF7/8 count 0):"
    );
    // The LUT share of the design's own device (the LX45 for a bare file).
    let device = d.map_or(DEVICES[0].name, |d| d.device.name);
    let share = |m: &MappingReport| {
        m.devices
            .iter()
            .find(|u| u.device == device)
            .map_or(f64::NAN, |u| u.lut_percent)
    };
    println!(
        "{:<9} {:>7} {:>5} {:>8} {:>7} {:>7} {:>4} {:>6} {:>6} {:>7}  ends per level (0, 1, ...)",
        "mapping",
        "LUT",
        "INV",
        "LUT RAM",
        format!("% {}", device.trim_start_matches("XC6S")),
        "FF",
        "DSP",
        "RAMB16",
        "CARRY4",
        "levels"
    );
    let unknown = |x: Option<u32>| x.map_or("?".into(), |x| x.to_string());
    for m in &rep.mappings {
        println!(
            "{:<9} {:>7} {:>5} {:>8} {:>6.1}% {:>7} {:>4} {:>6.1} {:>6} {:>7}  {}",
            m.mapping,
            m.luts,
            m.inverters,
            m.lut_ram,
            share(m),
            m.ffs,
            m.dsp48a1,
            m.ramb16 as f64 + m.ramb8 as f64 / 2.0,
            m.carry4,
            unknown(m.lut_levels),
            m.ends_per_level
                .iter()
                .map(|c| c.to_string())
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    match rep
        .smallest_within_levels
        .and_then(|b| rep.mappings.iter().find(|m| m.mapping == b))
    {
        Some(m) => println!(
            "smallest netlist within {} LUT levels: {} ({} LUT + {} LUT RAM = {:.1} % of the {device}); \
             {} and {} are one script on one design in two orders, \
             so their difference is ABC's sensitivity to the order alone",
            rep.lut_levels_target,
            m.mapping,
            m.luts,
            m.lut_ram,
            share(m),
            ABC_D7.name,
            ABC_D7_READ_BACK.name
        ),
        None => println!(
            "no netlist within {} LUT levels",
            rep.lut_levels_target
        ),
    }
    for m in &rep.mappings {
        println!("{}: {}", m.mapping, m.about);
        println!(
            "  longest carry chain {} CARRY4; yosys ltp {} cells; worst path: {}",
            unknown(m.carry_chain),
            m.logic_depth.map_or("?".into(), |x| x.to_string()),
            m.worst_path.join(" -> ")
        );
        if !m.deep_ends.is_empty() {
            let ends: Vec<String> = m
                .deep_ends
                .iter()
                .map(|(n, d)| format!("{n} {d}"))
                .collect();
            println!(
                "  path ends deeper than {}: {}",
                rep.lut_levels_target,
                ends.join(", ")
            );
        }
        for u in &m.devices {
            println!(
                "  {:<10} LUT {:5.1} %  FF {:5.1} %  block RAM {:5.1} %  DSP {:5.1} %  -> {}",
                u.device,
                u.lut_percent,
                u.ff_percent,
                u.block_ram_percent,
                u.dsp_percent,
                match (u.fits, u.fits_within_levels) {
                    (true, true) => format!(
                        "fits (LUT <= 80 %) within {} LUT levels",
                        rep.lut_levels_target
                    ),
                    (true, false) => format!(
                        "fits (LUT <= 80 %) but deeper than {} LUT levels",
                        rep.lut_levels_target
                    ),
                    _ => "does NOT fit (LUT <= 80 %, others <= 100 %)".into(),
                }
            );
        }
    }
    if let (Some(t), Some(d)) = (&rep.throughput, d) {
        println!(
            "throughput: P = {}, {:.1} MHz, {} words/plane: {:.0} planes/s keep the core {:.1} % busy; DDR2 refresh {:.1} %; headroom {:.1} % (target >= 25 %); design for the {}",
            t.pixels_per_clock,
            t.clock_mhz,
            t.words_per_plane,
            t.planes_per_s,
            t.busy_percent,
            t.ddr2_refresh_percent,
            t.headroom_percent,
            d.device.name
        );
    }
    if temporary {
        println!("yosys script (run `yosys -s synth.ys` in a folder holding top.v to reproduce every figure):");
        println!("{}", rep.yosys_script);
    } else {
        println!(
            "yosys script: {} (`yosys -s synth.ys` there reproduces every figure); per mapping, \
             the deepest paths in levels-paths-NAME.txt",
            dir.join("synth.ys").display()
        );
    }
}
