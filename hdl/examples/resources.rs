//! Resource figures from yosys `synth_xilinx -family xc6s`, each of
//! [`MAPPINGS`] on the same prepared design (the script `synth.ys` in each
//! work folder), with the analytic floors (memory bits / 18 Kbit,
//! multipliers) and the logic depth between registers; and the throughput
//! arithmetic of the chosen P. Run one configuration at a time:
//! `cargo run -p smartagg-hdl --release --example resources -- NAME`
//! (all of them, in turn, when no name is given). The whole designs take
//! from minutes (test, pipe) to hours (xem150, proj150) of yosys time.
//!
//! Configurations: every generated design by its name (`spcimager-150x`,
//! `spcimager-60x`, `spcimager-projected-150x`, `spcimager-projected-60x`:
//! [`smartagg_hdl::designs::Design`], the same Verilog as `smartagg hdl
//! generate`), `lint` (Verilator `--lint-only -Wall` of all four), and:
//! * `test`: the small test front half (16×6, block-RAM delay line).
//! * `pipe`: the small test pipeline (16×6, M = 4, 3×3 ROIs).
//! * `spc150`: the SPCImager 150× front half (320×240, P = 16, N_max = 128,
//!   k = 9, a = 8) without its delay line (9.8 Mbit: DDR2).
//! * `filter150`: its spatial filter alone; `mask150`: its hot-pixel mask;
//!   `dl24`: a 24-plane block-RAM delay line; `ddr150`: its DDR2 delay
//!   line alone (N_max 128 planes behind the MCB port).
//! * `xem150`: the whole XEM6310 top for the SPCImager at 150×, DDR2 delay
//!   line, M = 32, 9×9 ROIs, for the LX45 (FrontPanel and MIG are black
//!   boxes: their own cost comes on top, see the report).
//! * `back150`, `tracker150`, `agg150`, `pkt150`: out-of-context synthesis
//!   of the SPCImager 150× back half and of its blink tracker, ROI
//!   aggregator and packetiser alone (ports left as ports: no constant
//!   propagation across the boundary), to iterate on one block in minutes.
//! * `proj150`: the projected SPCImager at 150× with its delay line of
//!   N_max = 24 planes in block RAM (the pipeline, without the XEM6310
//!   endpoints), for the LX150.
//!
//! The 150× kernel of `spc150` is the pixel-integrated Gaussian of the
//! preset's σ scaled to 2^8; `xem150` and `proj150` use
//! [`smartagg_hdl::front_half::spcimager150_config`].

use smartagg_hdl::back_half::BackHalf;
use smartagg_hdl::blink_tracker::BlinkTracker;
use smartagg_hdl::config::{BackHalfConfig, GatewareConfig, GatewareError};
use smartagg_hdl::delay_line::DelayLine;
use smartagg_hdl::delay_line_ddr::DelayLineDdr;
use smartagg_hdl::designs::{text_hash, Design};
use smartagg_hdl::designs::{Projected150Pipeline, Spcimager150Xem, TestPipeline};
use smartagg_hdl::device::DEVICES;
use smartagg_hdl::front_half::{test_config, verilog, Spcimager150FrontHalf, TestFrontHalf};
use smartagg_hdl::hot_pixel_mask::HotPixelMask;
use smartagg_hdl::packetiser::Packetiser;
use smartagg_hdl::pipeline::{
    projected150_back_config, spcimager150_back_config, test_back_config,
};
use smartagg_hdl::roi_aggregator::RoiAggregator;
use smartagg_hdl::spatial_filter::SpatialFilter;
use smartagg_hdl::synth::{verilator_lint, yosys_resources, Synthesis, MAPPINGS};
use smartagg_model::params::{Preset, PresetName};

/// Pixel-integrated Gaussian of width `sigma` over k pixels, scaled to 2^a.
fn kernel(sigma: f64, k: usize, a: u8) -> Vec<u32> {
    let c = (k / 2) as f64;
    let density = |x: f64| (-(x * x) / (2.0 * sigma * sigma)).exp();
    let integral = |lo: f64, hi: f64| {
        let n = 200;
        let h = (hi - lo) / n as f64;
        (0..n)
            .map(|i| density(lo + (i as f64 + 0.5) * h) * h)
            .sum::<f64>()
    };
    let g: Vec<f64> = (0..k)
        .map(|i| integral(i as f64 - c - 0.5, i as f64 - c + 0.5))
        .collect();
    let total: f64 = g.iter().sum();
    let scale = (1u32 << a) as f64 / total;
    let mut w: Vec<u32> = g.iter().map(|v| (v * scale).round() as u32).collect();
    let outer: u32 = w
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != k / 2)
        .map(|(_, v)| v)
        .sum();
    w[k / 2] = (1u32 << a) - outer;
    w
}

/// Verilog of one block of a back-half configuration.
type BlockVerilog = fn(&BackHalfConfig) -> Result<String, GatewareError>;

fn print(name: &str, s: &Synthesis) {
    println!(
        "{name:<34} memory {} bits -> floor {} RAMB16; multipliers {} -> floor {} DSP48A1",
        s.memory_bits,
        s.ramb16_floor(),
        s.multipliers,
        s.multipliers
    );
    for n in &s.netlists {
        let r = &n.resources;
        // A RAMB8 is half a RAMB16.
        let ramb = r.ramb16 as f64 + r.ramb8 as f64 / 2.0;
        println!(
            "{:<34} {:<6} LUT {:>6} (INV {})  FF {:>6}  RAMB16 {:.1}  DSP48A1 {:>2}  LUT-RAM {:>5}  CARRY4 {:>5}  ltp {}",
            "",
            n.mapping.name,
            r.luts,
            r.inverters,
            r.ffs,
            ramb,
            r.dsp48a1,
            r.lutram,
            r.carry4,
            r.logic_depth.map_or("?".to_string(), |d| d.to_string())
        );
        if let Some(l) = &r.lut_levels {
            let path: Vec<String> = l.path.iter().map(|(t, n)| format!("{t} {n}")).collect();
            println!(
                "{:<34} {:<6} LUT levels {} (ends per level {:?}); longest carry chain {} CARRY4; worst path: {} -> {}",
                "",
                "",
                l.levels,
                l.ends_per_level(),
                l.carry_chain,
                l.start,
                path.join(" -> ")
            );
            let deep = l.ends_deeper_than(6);
            if !deep.is_empty() {
                println!(
                    "{:<34} {:<6} ends deeper than 6: {}",
                    "",
                    "",
                    deep.join(", ")
                );
            }
        }
        for dev in DEVICES {
            println!(
                "{:<34} {:<6} {}: LUT {:.1} %  FF {:.1} %  RAMB16 {:.1} %  DSP {:.1} %",
                "",
                "",
                dev.name,
                100.0 * (r.luts + r.lutram) as f64 / dev.luts as f64,
                100.0 * r.ffs as f64 / dev.ffs as f64,
                100.0 * ramb / dev.ramb16 as f64,
                100.0 * r.dsp48a1 as f64 / dev.dsp48a1 as f64
            );
        }
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    // `levels NETLIST.json`: the LUT levels of a netlist mapped by any
    // script (e.g. classic `abc`, which maps each cone level-optimally).
    let argv: Vec<String> = std::env::args().collect();
    if argv.len() == 3 && argv[1] == "levels" {
        let l = smartagg_hdl::lut_levels::lut_levels(&std::fs::read_to_string(&argv[2])?, "top")?;
        println!("LUT levels {}; start {}", l.levels, l.start);
        for e in l.ends_deeper_than(6) {
            println!("  {e}");
        }
        return Ok(());
    }
    let preset = Preset::new(PresetName::Spcimager, 150)?;
    let sigma = preset.sigma_px();
    let k = 2 * (2.0 * sigma).ceil() as usize + 1;
    let k1 = kernel(sigma, k, 8);
    let big = GatewareConfig {
        width: 320,
        height: 240,
        pixels_per_clock: 16,
        n_max: 128,
        kernel: k1.clone(),
        kernel_shift: 8,
        dsp_multipliers: smartagg_hdl::device::XC6SLX45.dsp48a1 as usize,
        sized_for: None,
    };
    big.validate()?;
    println!("SPCImager 150x: sigma = {sigma:.3} px, k = {k}, k1 = {k1:?} (sum 256)");
    let clock_hz = 100.8e6;
    let words = big.words_per_plane() as f64;
    let busy = words * 10_000.0 / clock_hz;
    println!(
        "throughput: {} words/plane at P = {}; 10,000 planes/s need {:.1} Mword/s = {:.1} % of {:.1} MHz ({:.1} % headroom before DDR2 refresh and host stalls)",
        words,
        big.pixels_per_clock,
        words * 1e-2,
        100.0 * busy,
        clock_hz * 1e-6,
        100.0 * (1.0 - busy)
    );
    println!(
        "yosys: synth_xilinx -family xc6s -flatten, LUT mappings {}; each work folder under {} keeps its synth.ys",
        MAPPINGS.map(|m| m.name).join(", "),
        std::env::temp_dir().join("smartagg-hdl-resources").display()
    );
    let dir = std::env::temp_dir().join("smartagg-hdl-resources");
    let args: Vec<String> = std::env::args().skip(1).collect();
    let want = |name: &str| args.is_empty() || args.iter().any(|a| a == name);
    let designs = Design::all()?;
    let names: Vec<String> = designs.iter().map(|d| d.name()).collect();
    for d in designs {
        let name = d.name();
        let explicit = args.contains(&name);
        if !(explicit || want("lint")) {
            continue;
        }
        let v = d.verilog()?;
        println!(
            "{name}: {} bytes of Verilog, CRC-64/XZ {}, {}",
            v.len(),
            text_hash(&v),
            d.device.name
        );
        if want("lint") && !explicit {
            let t0 = std::time::Instant::now();
            verilator_lint(&v, &dir.join(format!("lint-{name}")))?;
            println!(
                "{name}: verilator --lint-only -Wall clean ({:.0} s)",
                t0.elapsed().as_secs_f64()
            );
            continue;
        }
        let t0 = std::time::Instant::now();
        let r = yosys_resources(&v, &dir.join(&name), &MAPPINGS)?;
        println!("{name}: yosys {:.0} s", t0.elapsed().as_secs_f64());
        print(&name, &r);
    }
    if !args.is_empty() && args.iter().all(|a| a == "lint" || names.contains(a)) {
        return Ok(());
    }
    if want("test") {
        let small = test_config();
        let r = yosys_resources(
            &verilog(TestFrontHalf::new(&small)?),
            &dir.join("test"),
            &MAPPINGS,
        )?;
        print("test config (16x6, P 4, k 5, N_max 7)", &r);
    }
    if want("pipe") {
        let cfg = test_back_config(4, 3, 1)?;
        let r = yosys_resources(
            &verilog(TestPipeline::new(&cfg)?),
            &dir.join("pipe"),
            &MAPPINGS,
        )?;
        print("test pipeline (16x6, M 4, R 3)", &r);
    }
    if want("back150") || want("tracker150") || want("agg150") || want("pkt150") {
        let cfg = spcimager150_back_config()?;
        let blocks: [(&str, &str, BlockVerilog); 4] = [
            ("back150", "SPCImager 150x back half", |c| {
                Ok(verilog(BackHalf::<
                    16,
                    8,
                    8,
                    17,
                    10,
                    7,
                    6,
                    233,
                    552,
                    53,
                    9,
                    12,
                >::new(c)?))
            }),
            ("tracker150", "SPCImager 150x blink tracker", |c| {
                Ok(verilog(BlinkTracker::<16, 8, 7>::new(c)?))
            }),
            ("agg150", "SPCImager 150x ROI aggregator", |c| {
                Ok(verilog(RoiAggregator::<16, 8, 17, 10, 7>::new(c)?))
            }),
            ("pkt150", "SPCImager 150x packetiser", |c| {
                Ok(verilog(Packetiser::<17, 10, 7, 8, 552>::new(c)?))
            }),
        ];
        for (key, title, gen) in blocks {
            if args.iter().any(|a| a == key) {
                let v = gen(&cfg)?;
                let t0 = std::time::Instant::now();
                let r = yosys_resources(&v, &dir.join(key), &MAPPINGS)?;
                println!("{key}: yosys {:.0} s", t0.elapsed().as_secs_f64());
                print(title, &r);
            }
        }
    }
    if want("spc150") {
        let r = yosys_resources(
            &verilog(Spcimager150FrontHalf::new(&big)?),
            &dir.join("spc150"),
            &MAPPINGS,
        )?;
        print("SPCImager 150x front half (no DL)", &r);
    }
    if want("filter150") {
        let r = yosys_resources(
            &verilog(SpatialFilter::<8, 16, 24, 5>::new(&big)?),
            &dir.join("filter150"),
            &MAPPINGS,
        )?;
        print("SPCImager 150x spatial filter", &r);
    }
    if want("mask150") {
        let r = yosys_resources(
            &verilog(HotPixelMask::<16, 13>::new(&big)?),
            &dir.join("mask150"),
            &MAPPINGS,
        )?;
        print("SPCImager 150x hot-pixel mask", &r);
    }
    if want("dl24") {
        // The largest block-RAM delay line of 320x240 planes an LX45 can
        // hold: 24 planes x 76,800 bits = 1.84 Mbit (the projected
        // SPCImager's N is about 18).
        let dl = GatewareConfig {
            n_max: 24,
            ..big.clone()
        };
        println!(
            "delay line N_max 24: {} bits of block RAM",
            dl.delay_line_bits()
        );
        let r = yosys_resources(
            &verilog(DelayLine::<16, 17, 5>::new(&dl)?),
            &dir.join("dl24"),
            &MAPPINGS,
        )?;
        print("BRAM delay line 320x240, N_max 24", &r);
    }
    if want("ddr150") {
        let cfg = spcimager150_back_config()?;
        let r = yosys_resources(
            &verilog(DelayLineDdr::<16, 8, 9>::new(&cfg.front)?),
            &dir.join("ddr150"),
            &MAPPINGS,
        )?;
        print("SPCImager 150x DDR2 delay line", &r);
    }
    if want("xem150") {
        let cfg = spcimager150_back_config()?;
        let r = yosys_resources(
            &verilog(Spcimager150Xem::new(&cfg)?),
            &dir.join("xem150"),
            &MAPPINGS,
        )?;
        print("XEM6310 top, SPCImager 150x, DDR2", &r);
    }
    if want("proj150") {
        let cfg = projected150_back_config()?;
        let r = yosys_resources(
            &verilog(Projected150Pipeline::new(&cfg)?),
            &dir.join("proj150"),
            &MAPPINGS,
        )?;
        print("pipeline, projected 150x, BRAM DL 24", &r);
    }
    Ok(())
}
