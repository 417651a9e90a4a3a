//! Resource figures of the generated front half from yosys
//! `synth_xilinx -family xc6s` (run: `cargo run -p smartagg-hdl --release
//! --example resources [test] [spc150] [mask150] [dl24]`, all by default), and
//! the throughput arithmetic of the chosen P. The SPCImager front half takes
//! minutes of yosys time.
//!
//! Configurations: the small test configuration (with its block-RAM delay
//! line) and the SPCImager at 150× (320×240, P = 16, N_max = 128, k = 9,
//! a = 8) without the delay line, which needs 128 planes × 76,800 bits =
//! 9.8 Mbit and goes to DDR2 in phase 2. The 150× kernel here is the
//! pixel-integrated Gaussian of the preset's σ, scaled to 2^8 (outer weights
//! rounded, centre = remainder): only the figures depend on it, weakly.

use smartagg_hdl::config::GatewareConfig;
use smartagg_hdl::delay_line::DelayLine;
use smartagg_hdl::front_half::{test_config, verilog, Spcimager150FrontHalf, TestFrontHalf};
use smartagg_hdl::hot_pixel_mask::HotPixelMask;
use smartagg_hdl::synth::{yosys_resources, Resources, YOSYS_SCRIPT};
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

fn print(name: &str, r: &Resources) {
    println!(
        "{name:<34} LUT {:>6}  FF {:>6}  RAMB16 {:>3}  RAMB8 {:>3}  DSP48A1 {:>2}  LUT-RAM {:>5}  CARRY4 {:>5}",
        r.luts, r.ffs, r.ramb16, r.ramb8, r.dsp48a1, r.lutram, r.carry4
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
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
    println!("yosys script: {YOSYS_SCRIPT}");
    let dir = std::env::temp_dir().join("smartagg-hdl-resources");
    let args: Vec<String> = std::env::args().skip(1).collect();
    let want = |name: &str| args.is_empty() || args.iter().any(|a| a == name);
    if want("test") {
        let small = test_config();
        let r = yosys_resources(&verilog(TestFrontHalf::new(&small)?), &dir.join("test"))?;
        print("test config (16x6, P 4, k 5, N_max 7)", &r);
    }
    if want("spc150") {
        let r = yosys_resources(
            &verilog(Spcimager150FrontHalf::new(&big)?),
            &dir.join("spc150"),
        )?;
        print("SPCImager 150x front half (no DL)", &r);
    }
    if want("mask150") {
        let r = yosys_resources(
            &verilog(HotPixelMask::<16, 13>::new(&big)?),
            &dir.join("mask150"),
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
        )?;
        print("BRAM delay line 320x240, N_max 24", &r);
    }
    Ok(())
}
