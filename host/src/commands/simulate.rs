//! `smartagg simulate`: blinking molecules seen by a camera preset.
//!
//! SPAD presets write a `.spad` bit-plane recording (or raw packed planes with
//! `--raw`), EMCCD/sCMOS presets a 16-bit multi-page TIFF stack; the ground
//! truth goes to `PATH.truth.csv` beside it. Everything is reproducible from
//! `--seed`.
//!
//! `--drift-nm A` (a smooth random trajectory reaching A nm from the start)
//! or `--drift-velocity-nm-s VX,VY` moves the stage during the acquisition:
//! every blink is imaged at its position plus the drift of its time, and the
//! truth gains the columns `drift_x_nm`, `drift_y_nm` (see
//! `smartagg_scene::truth`). Without them nothing changes.
//!
//! Every option is checked before anything touches the disk; both outputs
//! are written beside their targets and renamed into place only once both
//! are complete, so a failed run leaves any existing file as it was. The
//! output's extension must match what is written (`.spad` for a SPAD
//! recording, `.tif`/`.tiff` for a frame camera; raw planes may not be
//! named `.spad` or `.tif`), and a run that would write more than
//! `--max-out-gib` GiB (default [`DEFAULT_MAX_OUT_GIB`]) is refused before it
//! starts.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use smartagg_io::stack::StackWriter;
use smartagg_model::params::{
    check_non_negative, check_positive, check_range, fmt_num, Camera, Preset, PresetName,
    MAX_BACKGROUND_PER_UM2_HZ, MAX_FLUX_HZ, MAX_FRAME_PERIOD_S,
};
use smartagg_model::plane::BitPlane;
use smartagg_model::recording::{pack_plane, plane_bytes, BitOrder, RecordingWriter};
use smartagg_scene::{
    truth, Blinking, DriftTrajectory, EmccdSimulator, Frame, Layout, OnTime, Scene, ScmosSimulator,
    SpadSimulator,
};

use smartagg_io::output::AtomicFile;

/// Largest output `simulate` writes unless `--max-out-gib` says otherwise, GiB.
pub const DEFAULT_MAX_OUT_GIB: f64 = 64.0;
/// Shortest and longest blink durations and mean on-times, ms.
const ON_MS_RANGE: (f64, f64) = (0.01, 1e6);
/// Shortest and longest mean off-times, s.
const OFF_S_RANGE: (f64, f64) = (1e-3, 1e6);

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
// The preset is required here (no default). `mut_arg` moves the argument
// to the end of the list, which orders the usage line; moving `--out` after
// it keeps that line `--preset <PRESET> --out <OUT>`.
#[command(mut_arg("preset", |a| a.required(true).default_value(None::<&str>)))]
#[command(mut_arg("out", |a| a))]
#[command(mut_arg("objective", |a| a.help("Objective magnification (150 or 60)")))]
pub struct Args {
    #[command(flatten)]
    pub preset: crate::setup::PresetArgs,
    /// What the camera looks at.
    #[arg(long, value_enum, default_value = "single")]
    pub scene: SceneKind,
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
    /// Largest output to write, GiB (2^30 bytes); a longer run is refused before it starts.
    #[arg(long, default_value_t = DEFAULT_MAX_OUT_GIB, allow_negative_numbers = true)]
    pub max_out_gib: f64,
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
    /// Stage drift: a smooth random trajectory (seeded) whose largest distance
    /// from the start over the simulated time is this many nm; the truth
    /// gains the drift of every blink (`drift_x_nm`, `drift_y_nm`).
    #[arg(
        long,
        allow_negative_numbers = true,
        conflicts_with = "drift_velocity_nm_s"
    )]
    pub drift_nm: Option<f64>,
    /// Stage drift: a constant velocity VX,VY in nm/s (e.g. 0.1,-0.05).
    #[arg(long, value_parser = parse_velocity, allow_negative_numbers = true)]
    pub drift_velocity_nm_s: Option<(f64, f64)>,
}

fn parse_velocity(s: &str) -> Result<(f64, f64), String> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| format!("velocity `{s}` is not VX,VY in nm/s (e.g. 0.1,-0.05)"))?;
    let num = |v: &str| -> Result<f64, String> {
        v.trim()
            .parse::<f64>()
            .map_err(|_| format!("velocity component `{v}` is not a number"))
    };
    Ok((num(x)?, num(y)?))
}

/// The stage drift the arguments ask for over `duration_s` of simulation.
fn build_drift(t: &Tuning, duration_s: f64, seed: u64) -> anyhow::Result<Option<DriftTrajectory>> {
    Ok(match (t.drift_nm, t.drift_velocity_nm_s) {
        (Some(a), _) => Some(
            DriftTrajectory::random(a, duration_s, seed)
                .map_err(|e| anyhow::anyhow!("--drift-nm: {e}"))?,
        ),
        (None, Some((vx, vy))) => Some(
            DriftTrajectory::linear(vx, vy)
                .map_err(|e| anyhow::anyhow!("--drift-velocity-nm-s: {e}"))?,
        ),
        (None, None) => None,
    })
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
            check_range(
                "--blink-ms (ms)",
                a.tuning.blink_ms,
                ON_MS_RANGE.0,
                ON_MS_RANGE.1,
            )?;
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
                mean_s: check_range("--mean-on-ms (ms)", m, ON_MS_RANGE.0, ON_MS_RANGE.1)? * 1e-3,
            };
        }
        if let Some(m) = a.tuning.mean_off_s {
            *mean_off_s = check_range("--mean-off-s (s)", m, OFF_S_RANGE.0, OFF_S_RANGE.1)?;
        }
    } else if a.tuning.mean_on_ms.is_some() || a.tuning.mean_off_s.is_some() {
        bail!("--mean-on-ms/--mean-off-s apply to the random and nanoruler scenes; the single scene uses --blink-ms");
    }
    if let Some(d) = a.tuning.density {
        check_non_negative("--density (per µm²)", d)?;
        match &mut sc.layout {
            Layout::Random { density_per_um2 } if a.scene == SceneKind::Random => {
                *density_per_um2 = d
            }
            Layout::Nanorulers { rulers_per_um2, .. } => *rulers_per_um2 = d,
            _ => bail!("--density applies to the random and nanoruler scenes"),
        }
    }
    if let Some(f) = a.tuning.flux {
        sc.light.flux_hz = check_range("--flux (photons/s)", f, 0.0, MAX_FLUX_HZ)?;
    }
    if let Some(b) = a.tuning.background {
        sc.light.background_per_um2_hz = check_range(
            "--background (photons/µm²/s)",
            b,
            0.0,
            MAX_BACKGROUND_PER_UM2_HZ,
        )?;
    }
    sc.intensity_cv = check_range("--intensity-cv", a.tuning.intensity_cv, 0.0, 10.0)?;
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
                        c.em_gain = check_range("--em-gain (×)", g, 1.0, 10000.0)?;
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
                check_positive("--frame-ms (ms)", f)?;
                *period = check_range("--frame-ms (ms)", f, 0.0, MAX_FRAME_PERIOD_S * 1e3)? * 1e-3;
                *exposure = *period;
            }
            if let Some(d) = a.tuning.dead_time_ms {
                let d = check_non_negative("--dead-time-ms (ms)", d)? * 1e-3;
                if d >= *period {
                    bail!(
                        "invalid parameter `--dead-time-ms` = {} ms: the dead time must be shorter than the frame period ({} ms)",
                        fmt_num(d * 1e3),
                        fmt_num(*period * 1e3)
                    );
                }
                *exposure = *period - d;
            }
        }
    }
    cam.validate()?;
    Ok(cam)
}

/// The number of planes or frames, checked against the output limit:
/// `bytes_each` is what one plane or frame adds to the output, `what` names
/// it ("bit-plane", "frame").
fn count(a: &Args, period_s: f64, bytes_each: u64, what: &str) -> anyhow::Result<u64> {
    let max_gib = check_range("--max-out-gib (GiB)", a.max_out_gib, 1e-6, 1e6)?;
    let max_bytes = max_gib * (1u64 << 30) as f64;
    let most = (max_bytes / bytes_each.max(1) as f64).floor().max(0.0);
    if let Some(n) = a.planes {
        if n == 0 {
            bail!("invalid parameter `--planes` = 0: simulate at least one {what} (1 ..= {} {what}s fit in --max-out-gib {} GiB)", fmt_num(most), fmt_num(max_gib));
        }
        if n as f64 > most {
            bail!(
                "invalid parameter `--planes` = {n}: {n} {what}s of {bytes_each} bytes would write {} GiB, more than --max-out-gib {} GiB (at most {} {what}s; raise --max-out-gib to write more)",
                fmt_num(n as f64 * bytes_each as f64 / (1u64 << 30) as f64),
                fmt_num(max_gib),
                fmt_num(most)
            );
        }
        return Ok(n);
    }
    let s = check_positive("--seconds (s)", a.seconds.unwrap_or(1.0))?;
    let n = (s / period_s).ceil();
    if n > most {
        bail!(
            "invalid parameter `--seconds` = {} s: {} {what}s of {} s and {bytes_each} bytes each would write {} GiB, more than --max-out-gib {} GiB (at most {} s; raise --max-out-gib to write more)",
            fmt_num(s),
            fmt_num(n),
            fmt_num(period_s),
            fmt_num(n * bytes_each as f64 / (1u64 << 30) as f64),
            fmt_num(max_gib),
            fmt_num(most * period_s)
        );
    }
    Ok((n as u64).max(1))
}

/// Refuses an output name whose extension says another format than the one
/// written.
fn check_extension(out: &Path, cam: &Camera, raw: bool) -> anyhow::Result<()> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let is_tif = ext == "tif" || ext == "tiff";
    match cam {
        Camera::Spad(_) if raw => {
            if ext == "spad" || is_tif {
                bail!(
                    "--out {}: --raw writes headerless packed bit-planes, not a .{ext} file; name it e.g. .bin or .raw",
                    out.display()
                );
            }
        }
        Camera::Spad(_) => {
            if ext != "spad" {
                bail!(
                    "--out {}: a SPAD preset writes a .spad bit-plane recording; name the output .spad (or add --raw for headerless planes)",
                    out.display()
                );
            }
        }
        Camera::Emccd(_) | Camera::Scmos(_) => {
            if !is_tif {
                bail!(
                    "--out {}: the emccd and scmos presets write a 16-bit TIFF stack; name the output .tif or .tiff",
                    out.display()
                );
            }
        }
    }
    Ok(())
}

fn truth_path(out: &std::path::Path) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".truth.csv");
    PathBuf::from(s)
}

/// Runs the command.
pub fn run(a: Args) -> anyhow::Result<()> {
    let name = PresetName::parse(&a.preset.name)?;
    let preset = Preset::new(name, a.preset.objective)?;
    let cam = build_camera(&a, &preset)?;
    let scene = build_scene(&a, &preset)?;
    scene.validate(&cam)?;
    check_extension(&a.out, &cam, a.tuning.raw)?;
    let frame_bytes = scene.width as u64 * scene.height as u64 * 2;
    let n = match &cam {
        Camera::Spad(c) => count(
            &a,
            c.plane_period_s,
            plane_bytes(scene.width, scene.height) as u64,
            "bit-plane",
        )?,
        Camera::Emccd(c) => count(&a, c.frame_period_s, frame_bytes, "frame")?,
        Camera::Scmos(c) => count(&a, c.frame_period_s, frame_bytes, "frame")?,
    };
    let period_s = match &cam {
        Camera::Spad(c) => c.plane_period_s,
        Camera::Emccd(c) => c.frame_period_s,
        Camera::Scmos(c) => c.frame_period_s,
    };
    let drift = build_drift(&a.tuning, n as f64 * period_s, a.seed)?;
    let tp = truth_path(&a.out);
    // Nothing is written to the targets until both files are complete.
    let out_file = AtomicFile::create(&a.out)?;
    let truth_file = AtomicFile::create(&tp)?;
    let out = BufWriter::with_capacity(1 << 20, out_file);
    let t = Instant::now();
    println!(
        "preset {name} ({}x), field {}x{} px of {:.2} nm, PSF sigma {:.3} px, seed {}",
        a.preset.objective,
        scene.width,
        scene.height,
        scene.pixel_nm(&cam),
        scene.sigma_px(&cam),
        a.seed
    );
    if let Some(on) = scene.expected_on(&cam) {
        println!("expected molecules on at a time: {on:.2}");
    }
    if let Some(d) = &drift {
        let (x, y) = d.at(n as f64 * period_s);
        println!("stage drift: {x:.1}, {y:.1} nm at the end (drift_x_nm, drift_y_nm in the truth)");
    }
    let (truth_rows, out) = match &cam {
        Camera::Spad(c) => {
            let mut sim = SpadSimulator::new(c, &scene, a.seed)?;
            if let Some(d) = &drift {
                sim.set_drift(d.clone());
            }
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
            let out = if a.tuning.raw {
                let mut w = out;
                let mut buf = Vec::new();
                for _ in 0..n {
                    buf.clear();
                    pack_plane(&next(&mut sim), order, &mut buf);
                    w.write_all(&buf)
                        .with_context(|| format!("writing {}", a.out.display()))?;
                }
                w
            } else {
                let mut w = RecordingWriter::new(out, sim.recording_header(n, order))?;
                for _ in 0..n {
                    w.write_plane(&next(&mut sim))
                        .with_context(|| format!("writing {}", a.out.display()))?;
                }
                w.finish()
                    .with_context(|| format!("writing {}", a.out.display()))?
            };
            let el = t.elapsed().as_secs_f64();
            println!(
                "{n} bit-planes ({:.3} s of camera time) in {el:.2} s ({:.0} planes/s); {:.4} % of pixel-planes read 1; {} hot pixels",
                n as f64 * c.plane_period_s,
                n as f64 / el.max(1e-9),
                100.0 * ones as f64 / (n as f64 * sim.width() as f64 * sim.height() as f64),
                sim.maps().hot_pixels()
            );
            (sim.truth().to_vec(), out)
        }
        Camera::Emccd(c) => {
            let mut sim = EmccdSimulator::new(c, &scene, a.seed)?;
            if let Some(d) = &drift {
                sim.set_drift(d.clone());
            }
            let (clipped, out) = write_frames(out, &scene, n, || sim.next_frame())
                .with_context(|| format!("writing {}", a.out.display()))?;
            report_frames(n, c.frame_period_s, c.exposure_s, clipped, t);
            (sim.truth().to_vec(), out)
        }
        Camera::Scmos(c) => {
            let mut sim = ScmosSimulator::new(c, &scene, a.seed)?;
            if let Some(d) = &drift {
                sim.set_drift(d.clone());
            }
            let (clipped, out) = write_frames(out, &scene, n, || sim.next_frame())
                .with_context(|| format!("writing {}", a.out.display()))?;
            report_frames(n, c.frame_period_s, c.exposure_s, clipped, t);
            (sim.truth().to_vec(), out)
        }
    };
    let out = out
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", a.out.display()))?;
    let mut tw = BufWriter::new(truth_file);
    truth::write_csv(&mut tw, &truth_rows).with_context(|| format!("writing {}", tp.display()))?;
    let truth_file = tw
        .into_inner()
        .map_err(|e| e.into_error())
        .with_context(|| format!("writing {}", tp.display()))?;
    out.commit()?;
    truth_file.commit()?;
    let detected: u64 = truth_rows.iter().map(|b| b.photons_detected).sum();
    println!(
        "{} blinks, {detected} molecule photons detected; wrote {} and {}",
        truth_rows.len(),
        a.out.display(),
        tp.display()
    );
    Ok(())
}

/// Writes `n` frames as a TIFF stack; returns the number of clipped pixel
/// values and the writer.
fn write_frames<W: Write + std::io::Seek>(
    mut out: W,
    scene: &Scene,
    n: u64,
    mut next: impl FnMut() -> Frame,
) -> anyhow::Result<(u64, W)> {
    let mut clipped = 0u64;
    {
        // Borrow the buffer so that it can be flushed (and errors seen) afterwards.
        let mut w = StackWriter::create(&mut out, scene.width, scene.height, n)?;
        for _ in 0..n {
            let f = next();
            clipped += f.clipped as u64;
            w.write_frame(&f.adu)?;
        }
    }
    out.flush()?;
    Ok((clipped, out))
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
