//! `smartagg simulate`: blinking molecules seen by a camera preset.
//!
//! SPAD presets write a `.spad` bit-plane recording (or raw packed planes with
//! `--raw`), EMCCD/sCMOS presets a 16-bit multi-page TIFF stack; the ground
//! truth goes to `PATH.truth.csv` beside it. Everything is reproducible from
//! `--seed`.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, Context};
use smartagg_model::params::{
    check_non_negative, check_positive, check_range, Camera, Preset, PresetName,
};
use smartagg_model::plane::BitPlane;
use smartagg_model::recording::{pack_plane, BitOrder, RecordingWriter};
use smartagg_scene::tiff::TiffStackWriter;
use smartagg_scene::{
    truth, Blinking, EmccdSimulator, Frame, Layout, OnTime, Scene, ScmosSimulator, SpadSimulator,
};

/// Which molecules to simulate.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneKind {
    /// The paper's study: one molecule on at a time at random positions, fixed blink duration.
    Single,
    /// dSTORM field: random emitters at SMLM density, independent on/off kinetics.
    Random,
    /// GATTA-PAINT 80G nanorulers (three markers 80 nm apart), independent kinetics.
    Nanoruler,
}

/// Pixel order within a byte of the bit-plane output.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Pixel i at bit i % 8 (least significant first).
    Lsb,
    /// Pixel i at bit 7 − i % 8 (most significant first).
    Msb,
}

/// Arguments.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Camera preset: spcimager, spcimager-projected, emccd, scmos.
    #[arg(long)]
    pub preset: String,
    /// What the camera looks at.
    #[arg(long, value_enum, default_value = "single")]
    pub scene: SceneKind,
    /// Objective magnification (150 or 60).
    #[arg(long, default_value_t = 150)]
    pub objective: u32,
    /// Number of bit-planes (SPAD) or frames (EMCCD/sCMOS).
    #[arg(long, conflicts_with = "seconds")]
    pub planes: Option<u64>,
    /// Duration to simulate, s (default 1 s).
    #[arg(long, allow_negative_numbers = true)]
    pub seconds: Option<f64>,
    /// Random seed: the same seed gives bit-identical output.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output file (.spad or .tif); the ground truth goes to PATH.truth.csv.
    #[arg(long)]
    pub out: PathBuf,
    /// Field (ROI) size WxH in pixels [default: the study field for `single`, the whole sensor otherwise].
    #[arg(long, value_parser = parse_field)]
    pub field: Option<(u32, u32)>,
    /// Scene and camera adjustments.
    #[command(flatten)]
    pub tuning: Box<Tuning>,
}

/// Scene and camera adjustments of `smartagg simulate` (boxed: keeps the
/// command enum small).
#[derive(clap::Args, Debug)]
pub struct Tuning {
    /// Blink duration of the `single` scene, ms.
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    pub blink_ms: f64,
    /// Mean on-time of the `random`/`nanoruler` kinetics, ms [default: 30].
    #[arg(long, allow_negative_numbers = true)]
    pub mean_on_ms: Option<f64>,
    /// Mean off-time of the `random`/`nanoruler` kinetics, s [default: 30 random, 3 nanoruler].
    #[arg(long, allow_negative_numbers = true)]
    pub mean_off_s: Option<f64>,
    /// Emitters (random) or rulers (nanoruler) per µm² [default: 50 / 0.5].
    #[arg(long, allow_negative_numbers = true)]
    pub density: Option<f64>,
    /// Molecule flux, photons/s reaching the sensor [default: 50,000].
    #[arg(long, allow_negative_numbers = true)]
    pub flux: Option<f64>,
    /// Background, photons per µm² of sample per second [default: 70,000].
    #[arg(long, allow_negative_numbers = true)]
    pub background: Option<f64>,
    /// Relative spread of the intensity per blink (0 = none).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub intensity_cv: f64,
    /// Frame cameras: read-out dead time per frame, ms (exposure = period − dead time).
    #[arg(long, allow_negative_numbers = true)]
    pub dead_time_ms: Option<f64>,
    /// Frame cameras: frame period, ms [default: the preset's 50 ms].
    #[arg(long, allow_negative_numbers = true)]
    pub frame_ms: Option<f64>,
    /// EMCCD electron-multiplication gain [default: the preset's 300].
    #[arg(long, allow_negative_numbers = true)]
    pub em_gain: Option<f64>,
    /// SPAD: fraction of hot pixels [default: the preset's 0].
    #[arg(long, allow_negative_numbers = true)]
    pub hot_pixels: Option<f64>,
    /// SPAD: pixel order within bytes.
    #[arg(long, value_enum, default_value = "lsb")]
    pub bit_order: Order,
    /// SPAD: write headerless packed planes instead of a .spad container.
    #[arg(long)]
    pub raw: bool,
}

fn parse_field(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("field `{s}` is not WxH (e.g. 64x64)"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("field width `{w}` is not a number"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("field height `{h}` is not a number"))?;
    Ok((w, h))
}

/// Builds the scene the arguments describe.
fn build_scene(a: &Args, p: &Preset) -> anyhow::Result<Scene> {
    let mut sc = match a.scene {
        SceneKind::Single => {
            check_positive("--blink-ms", a.tuning.blink_ms)?;
            Scene::study(p, a.tuning.blink_ms * 1e-3)
        }
        SceneKind::Random => Scene::smlm(p),
        SceneKind::Nanoruler => Scene::nanorulers(p),
    };
    if let Some((w, h)) = a.field {
        sc = sc.with_field(w, h);
        if a.scene == SceneKind::Single {
            sc.margin_px = sc.margin_px.min(w.min(h) as f64 / 4.0);
        }
    }
    if let Blinking::Independent { on, mean_off_s } = &mut sc.blinking {
        if let Some(m) = a.tuning.mean_on_ms {
            *on = OnTime::Exponential {
                mean_s: check_positive("--mean-on-ms", m)? * 1e-3,
            };
        }
        if let Some(m) = a.tuning.mean_off_s {
            *mean_off_s = check_positive("--mean-off-s", m)?;
        }
    } else if a.tuning.mean_on_ms.is_some() || a.tuning.mean_off_s.is_some() {
        bail!("--mean-on-ms/--mean-off-s apply to the random and nanoruler scenes; the single scene uses --blink-ms");
    }
    if let Some(d) = a.tuning.density {
        check_non_negative("--density", d)?;
        match &mut sc.layout {
            Layout::Random { density_per_um2 } if a.scene == SceneKind::Random => {
                *density_per_um2 = d
            }
            Layout::Nanorulers { rulers_per_um2, .. } => *rulers_per_um2 = d,
            _ => bail!("--density applies to the random and nanoruler scenes"),
        }
    }
    if let Some(f) = a.tuning.flux {
        sc.light.flux_hz = check_non_negative("--flux", f)?;
    }
    if let Some(b) = a.tuning.background {
        sc.light.background_per_um2_hz = check_non_negative("--background", b)?;
    }
    sc.intensity_cv = check_non_negative("--intensity-cv", a.tuning.intensity_cv)?;
    Ok(sc)
}

/// Applies the camera options to the preset's camera.
fn build_camera(a: &Args, p: &Preset) -> anyhow::Result<Camera> {
    let mut cam = p.camera.clone();
    let frame_opts = a.tuning.dead_time_ms.is_some() || a.tuning.frame_ms.is_some();
    match &mut cam {
        Camera::Spad(c) => {
            if frame_opts || a.tuning.em_gain.is_some() {
                bail!(
                    "--dead-time-ms, --frame-ms and --em-gain apply to the emccd and scmos presets"
                );
            }
            if let Some(h) = a.tuning.hot_pixels {
                c.hot_pixel_fraction = check_range("--hot-pixels", h, 0.0, 1.0)?;
            }
        }
        Camera::Emccd(_) | Camera::Scmos(_) => {
            if a.tuning.hot_pixels.is_some() || a.tuning.raw || a.tuning.bit_order != Order::Lsb {
                bail!("--hot-pixels, --raw and --bit-order apply to the SPAD presets");
            }
            let (period, exposure) = match &mut cam {
                Camera::Emccd(c) => {
                    if let Some(g) = a.tuning.em_gain {
                        c.em_gain = check_range("--em-gain", g, 1.0, 10000.0)?;
                    }
                    (&mut c.frame_period_s, &mut c.exposure_s)
                }
                Camera::Scmos(c) => {
                    if a.tuning.em_gain.is_some() {
                        bail!("--em-gain applies to the emccd preset");
                    }
                    (&mut c.frame_period_s, &mut c.exposure_s)
                }
                Camera::Spad(_) => unreachable!(),
            };
            if let Some(f) = a.tuning.frame_ms {
                *period = check_positive("--frame-ms", f)? * 1e-3;
                *exposure = *period;
            }
            if let Some(d) = a.tuning.dead_time_ms {
                let d = check_non_negative("--dead-time-ms", d)? * 1e-3;
                if d >= *period {
                    bail!(
                        "invalid parameter `--dead-time-ms` = {}: the dead time must be shorter than the frame period ({} ms)",
                        d * 1e3,
                        *period * 1e3
                    );
                }
                *exposure = *period - d;
            }
        }
    }
    cam.validate()?;
    Ok(cam)
}

fn count(a: &Args, period_s: f64) -> anyhow::Result<u64> {
    if let Some(n) = a.planes {
        if n == 0 {
            bail!("invalid parameter `--planes` = 0: simulate at least one plane or frame");
        }
        return Ok(n);
    }
    let s = check_positive("--seconds", a.seconds.unwrap_or(1.0))?;
    let n = (s / period_s).ceil();
    if n > 1e15 {
        bail!("invalid parameter `--seconds` = {s}: too long");
    }
    Ok(n as u64)
}

fn truth_path(out: &std::path::Path) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".truth.csv");
    PathBuf::from(s)
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let name = PresetName::parse(&a.preset)?;
    let preset = Preset::new(name, a.objective)?;
    let cam = build_camera(&a, &preset)?;
    let scene = build_scene(&a, &preset)?;
    scene.validate(&cam)?;
    let out = File::create(&a.out).with_context(|| format!("cannot create {}", a.out.display()))?;
    let out = BufWriter::with_capacity(1 << 20, out);
    let t = Instant::now();
    println!(
        "preset {name} ({}x), field {}x{} px of {:.2} nm, PSF sigma {:.3} px, seed {}",
        a.objective,
        scene.width,
        scene.height,
        scene.pixel_nm(&cam),
        scene.sigma_px(&cam),
        a.seed
    );
    if let Some(on) = scene.expected_on(&cam) {
        println!("expected molecules on at a time: {on:.2}");
    }
    let truth_rows = match &cam {
        Camera::Spad(c) => {
            let n = count(&a, c.plane_period_s)?;
            let mut sim = SpadSimulator::new(c, &scene, a.seed)?;
            let order = match a.tuning.bit_order {
                Order::Lsb => BitOrder::LsbFirst,
                Order::Msb => BitOrder::MsbFirst,
            };
            let mut ones = 0u64;
            let mut next = |sim: &mut SpadSimulator| -> BitPlane {
                let p = sim.next_plane();
                ones += p.count_ones() as u64;
                p
            };
            if a.tuning.raw {
                let mut w = out;
                let mut buf = Vec::new();
                for _ in 0..n {
                    buf.clear();
                    pack_plane(&next(&mut sim), order, &mut buf);
                    w.write_all(&buf)?;
                }
                w.flush()?;
            } else {
                let mut w = RecordingWriter::new(out, sim.recording_header(n, order))?;
                for _ in 0..n {
                    w.write_plane(&next(&mut sim))?;
                }
                w.finish()?.flush()?;
            }
            let el = t.elapsed().as_secs_f64();
            println!(
                "{n} bit-planes ({:.3} s of camera time) in {el:.2} s ({:.0} planes/s); {:.4} % of pixel-planes read 1; {} hot pixels",
                n as f64 * c.plane_period_s,
                n as f64 / el.max(1e-9),
                100.0 * ones as f64 / (n as f64 * sim.width() as f64 * sim.height() as f64),
                sim.maps().hot_pixels()
            );
            sim.truth().to_vec()
        }
        Camera::Emccd(c) => {
            let n = count(&a, c.frame_period_s)?;
            let mut sim = EmccdSimulator::new(c, &scene, a.seed)?;
            let clipped = write_frames(out, &scene, n, || sim.next_frame())?;
            report_frames(n, c.frame_period_s, c.exposure_s, clipped, t);
            sim.truth().to_vec()
        }
        Camera::Scmos(c) => {
            let n = count(&a, c.frame_period_s)?;
            let mut sim = ScmosSimulator::new(c, &scene, a.seed)?;
            let clipped = write_frames(out, &scene, n, || sim.next_frame())?;
            report_frames(n, c.frame_period_s, c.exposure_s, clipped, t);
            sim.truth().to_vec()
        }
    };
    let tp = truth_path(&a.out);
    let f = File::create(&tp).with_context(|| format!("cannot create {}", tp.display()))?;
    truth::write_csv(BufWriter::new(f), &truth_rows)?;
    let detected: u64 = truth_rows.iter().map(|b| b.photons_detected).sum();
    println!(
        "{} blinks, {detected} molecule photons detected; wrote {} and {}",
        truth_rows.len(),
        a.out.display(),
        tp.display()
    );
    Ok(())
}

/// Writes `n` frames as a TIFF stack; returns the number of clipped pixel values.
fn write_frames(
    mut out: BufWriter<File>,
    scene: &Scene,
    n: u64,
    mut next: impl FnMut() -> Frame,
) -> anyhow::Result<u64> {
    let mut clipped = 0u64;
    {
        // Borrow the buffer so that it can be flushed (and errors seen) afterwards.
        let mut w = TiffStackWriter::create(&mut out, scene.width, scene.height, n)?;
        for _ in 0..n {
            let f = next();
            clipped += f.clipped as u64;
            w.write_frame(&f.adu)?;
        }
    }
    out.flush()?;
    Ok(clipped)
}

fn report_frames(n: u64, period: f64, exposure: f64, clipped: u64, t: Instant) {
    println!(
        "{n} frames of {:.1} ms ({:.1} ms exposed) in {:.2} s; {clipped} pixel values clipped to 0 or 65535",
        period * 1e3,
        exposure * 1e3,
        t.elapsed().as_secs_f64()
    );
    if clipped > 0 {
        eprintln!("smartagg: warning: {clipped} pixel values were clipped to the 16-bit range");
    }
}
