//! `smartagg demo`: the whole chain on an embedded default scene.
//!
//! GATTA-PAINT 80G nanorulers (three markers 80 nm apart) seen by the
//! SPCImager at 150× on a 48×48-pixel field: simulate the bit-planes, run them
//! through the gateware (the pipeline generated for this field, verilated),
//! the golden model and the fast engine (all three must give the same
//! bytes), stream the packets through the host decoder in USB-sized chunks as
//! they would arrive from the board, localise every blink, and write the
//! packet stream, a ThunderSTORM CSV, a rendered super-resolution image and a
//! Markdown report with error against ground truth beside the time of each
//! stage, the recovered ruler spacing, and bytes of packets against bytes of
//! raw bit-planes.

use crate::setup::{self, PipelineArgs};
use anyhow::Context;
use smartagg_localize::render::{self, Point, RenderOptions};
use smartagg_localize::table::{LocTable, Localization};
use smartagg_localize::{fit_binomial, FitOptions, SigmaMode, SpadRoi};
use smartagg_model::fast_engine::fast_pipeline;
use smartagg_model::packet::{Decoder, Event, LossStats};
use smartagg_model::packetiser::Packetiser;
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_model::pipeline::Pipeline;
use smartagg_model::record::{BlinkRecord, Record};
use smartagg_scene::scene::{Blinking, Layout, OnTime, Position, Scene};
use smartagg_scene::spad::SpadSimulator;
use smartagg_scene::truth::BlinkTruth;
use std::path::PathBuf;
use std::time::Instant;

mod analysis;
mod gateware;

use analysis::{analyse, report};
use gateware::{gateware_leg, GatewareJob};

/// Arguments of `smartagg demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output folder (created).
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Simulated acquisition, seconds of bit-planes (10,000 planes per second).
    #[arg(long, default_value_t = 40.0)]
    pub seconds: f64,
    /// Field side, pixels (53.3 nm each at 150x). The gateware is generated
    /// for the default, 48; other fields need `--gateware-planes 0`.
    #[arg(long, default_value_t = smartagg_sim::designs::DEMO.0 as u32)]
    pub field: u32,
    /// Random seed of the scene and the photons.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Mean time a marker stays off between blinks, s.
    #[arg(long, default_value_t = 1.5)]
    pub mean_off_s: f64,
    /// Confirmation length L_min, planes (default: the field design's, 1).
    #[arg(long)]
    pub l_min: Option<u32>,
    /// Association radius (Chebyshev, pixels): a candidate this close to a
    /// live track's anchor belongs to that track (default: the field
    /// design's, about 2σ of the PSF).
    #[arg(long)]
    pub r_assoc: Option<u32>,
    /// Skip the golden model (it is the slowest stage); the fast engine alone.
    #[arg(long)]
    pub skip_golden: bool,
    /// Bit-planes (from the first) streamed through the gateware: the
    /// pipeline generated for this field (block-RAM delay line, M = 16),
    /// verilated, a word on every clock it is ready, checked byte for byte
    /// against the golden model on the same planes. Default: the whole
    /// recording; 0 skips it. It runs at about 3·10^5 clocks/s, 2,000
    /// bit-planes per second of this field, on its own thread beside the
    /// model and the fast engine.
    #[arg(long)]
    pub gateware_planes: Option<u64>,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// Ruler centres and orientations of the embedded scene, as fractions of the field.
const RULERS: [(f64, f64, f64); 6] = [
    (0.25, 0.25, 0.0),
    (0.72, 0.27, 60.0),
    (0.27, 0.73, 120.0),
    (0.70, 0.70, 30.0),
    (0.50, 0.48, 95.0),
    (0.85, 0.50, 150.0),
];

/// Marker spacing of GATTA-PAINT 80G, nm.
const SPACING_NM: f64 = 80.0;

/// Localisations further than this from the truth are false (one pixel at
/// 150x): the study's match radius, 53.3 nm.
const MATCH_NM: f64 = smartagg_study::spec::DEFAULT_MATCH_RADIUS_NM;

fn scene(preset: &Preset, field: u32, mean_off_s: f64) -> (Scene, Vec<[usize; 3]>) {
    let px = preset.pixel_nm();
    let side = field as f64 * px;
    let mut positions = Vec::new();
    let mut rulers = Vec::new();
    for (i, &(fx, fy, deg)) in RULERS.iter().enumerate() {
        let (cx, cy) = (fx * side, fy * side);
        let (dx, dy) = (
            deg.to_radians().cos() * SPACING_NM,
            deg.to_radians().sin() * SPACING_NM,
        );
        for m in -1..=1 {
            positions.push(Position {
                x_nm: cx + m as f64 * dx,
                y_nm: cy + m as f64 * dy,
            });
        }
        rulers.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let s = Scene {
        layout: Layout::List(positions),
        blinking: Blinking::Independent {
            on: OnTime::Exponential { mean_s: 0.030 },
            mean_off_s,
        },
        ..Scene::nanorulers(preset).with_field(field, field)
    };
    (s, rulers)
}

struct Timing {
    rows: Vec<(String, f64, String)>,
}

impl Timing {
    fn add(&mut self, stage: &str, since: Instant, what: String) {
        self.add_seconds(stage, since.elapsed().as_secs_f64(), what);
    }

    fn add_seconds(&mut self, stage: &str, s: f64, what: String) {
        eprintln!("  {stage}: {s:.2} s — {what}");
        self.rows.push((stage.to_string(), s, what));
    }
}

/// Runs the demo.
pub fn run(args: Args) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let preset = Preset::new(PresetName::Spcimager, 150)?;
    let Camera::Spad(cam) = &preset.camera else {
        unreachable!("the SPCImager preset is a SPAD camera")
    };
    let planes = (args.seconds / cam.plane_period_s).round() as u64;
    anyhow::ensure!(planes >= 1, "--seconds must cover at least one bit-plane");
    let gateware_planes = args.gateware_planes.unwrap_or(planes).min(planes);
    let demo_field = smartagg_sim::designs::DEMO;
    anyhow::ensure!(
        gateware_planes == 0 || (args.field as usize, args.field as usize) == demo_field,
        "--field {}: the demo's gateware is generated for {}x{} pixels; add --gateware-planes 0 to run the model alone on another field",
        args.field,
        demo_field.0,
        demo_field.1
    );
    let (scene, rulers) = scene(&preset, args.field, args.mean_off_s);
    let pipeline_args = PipelineArgs {
        l_min: args.l_min,
        r_assoc: args.r_assoc,
        // The slots of the demo's gateware, which the model must share.
        slots: smartagg_sim::designs::DEMO_SLOTS,
        ..PipelineArgs::default()
    };
    let cfg = setup::pipeline_config(&pipeline_args, args.field, args.field, 100_000)?;
    eprintln!(
        "smartagg demo: {} GATTA-PAINT 80G rulers, SPCImager 150x, {}x{} pixels, {:.0} s = {} bit-planes",
        rulers.len(),
        args.field,
        args.field,
        args.seconds,
        planes
    );
    eprintln!("{}", setup::describe(&cfg));
    let mut timing = Timing { rows: Vec::new() };

    // The gateware leg, the slowest stage, runs on its own thread beside the
    // model and the fast engine (two cores): it shares only the seed.
    let gateware_job = (gateware_planes > 0).then(|| {
        let job = GatewareJob {
            field: args.field as usize,
            seed: args.seed,
            planes: gateware_planes,
            recording_planes: planes,
            cfg: cfg.clone(),
            scene: scene.clone(),
            cam: cam.clone(),
        };
        let t = Instant::now();
        std::thread::spawn(move || (gateware_leg(job), t.elapsed().as_secs_f64()))
    });

    // 1+2. Simulate and aggregate, plane by plane (nothing of the recording is kept).
    let mut sim = SpadSimulator::new(cam, &scene, args.seed)?;
    let mut golden = (!args.skip_golden)
        .then(|| Pipeline::new(cfg.clone()))
        .transpose()?;
    let mut fast = fast_pipeline(cfg.clone())?;
    let mut golden_bytes = Vec::new();
    let mut fast_bytes = Vec::new();
    let (mut pg, mut pf) = (Packetiser::new(), Packetiser::new());
    if let Some(g) = &golden {
        pg.push(&g.start_record(), &mut golden_bytes)?;
    }
    pf.push(&fast.start_record(), &mut fast_bytes)?;
    let progress = setup::progress(Some(planes), args.quiet);
    let (mut t_sim, mut t_golden, mut t_fast) = (0.0, 0.0, 0.0);
    for _ in 0..planes {
        let t = Instant::now();
        let plane = sim.next_plane();
        t_sim += t.elapsed().as_secs_f64();
        if let Some(g) = &mut golden {
            let t = Instant::now();
            for r in g.push_plane(&plane)? {
                pg.push(&r, &mut golden_bytes)?;
            }
            t_golden += t.elapsed().as_secs_f64();
        }
        let t = Instant::now();
        for r in fast.push_plane(&plane)? {
            pf.push(&r, &mut fast_bytes)?;
        }
        t_fast += t.elapsed().as_secs_f64();
        progress.inc(1);
    }
    progress.finish_and_clear();
    if let Some(g) = &mut golden {
        for r in g.finish() {
            pg.push(&r, &mut golden_bytes)?;
        }
    }
    for r in fast.finish() {
        pf.push(&r, &mut fast_bytes)?;
    }
    let truth: Vec<BlinkTruth> = sim.truth().to_vec();
    let rate = |s: f64| planes as f64 / s.max(1e-9);
    timing.rows.push((
        "simulate bit-planes".into(),
        t_sim,
        format!("{planes} planes, {:.0} planes/s", rate(t_sim)),
    ));
    let identical = if golden.is_some() {
        timing.rows.push((
            "golden model".into(),
            t_golden,
            format!(
                "{:.0} planes/s, {} bytes of packets",
                rate(t_golden),
                golden_bytes.len()
            ),
        ));
        Some(golden_bytes == fast_bytes)
    } else {
        None
    };
    timing.rows.push((
        "fast engine".into(),
        t_fast,
        format!(
            "{:.0} planes/s, {} bytes of packets",
            rate(t_fast),
            fast_bytes.len()
        ),
    ));
    if identical == Some(false) {
        anyhow::bail!("the fast engine's packets differ from the golden model's: this is a bug, please report it");
    }

    // 2b. The gateware, co-simulated on the same recording (the first
    //     --gateware-planes of it).
    let gateware = match gateware_job {
        Some(job) => {
            if !args.quiet {
                eprintln!(
                    "  waiting for the gateware co-simulation (started with the simulation) ..."
                );
            }
            let (leg, seconds) = job
                .join()
                .map_err(|_| anyhow::anyhow!("the gateware co-simulation thread panicked"))?;
            let leg = leg?;
            let what = format!(
                "{}: byte-identical to the golden model ({} packets), {:.0} clocks per plane, {:.3} M cycles/s (build {:.1} s); on its own thread, beside the stages above",
                leg.which_planes(),
                leg.packets,
                leg.clocks_per_plane,
                leg.mcycles_per_s,
                leg.build_s
            );
            timing.add_seconds("gateware co-simulation", seconds, what);
            Some(leg)
        }
        None => None,
    };

    // 3. The host side: bytes arrive in USB-sized chunks, are written to disk
    //    as they come, and are decoded incrementally.
    let t = Instant::now();
    let rois_path = args.out.join("blinks.rois");
    let mut decoder = Decoder::new();
    let mut received = Vec::with_capacity(fast_bytes.len());
    let mut records: Vec<BlinkRecord> = Vec::new();
    let mut end = None;
    for chunk in fast_bytes.chunks(16 * 1024) {
        received.extend_from_slice(chunk);
        decoder.feed(chunk);
        while let Some(ev) = decoder.next_event() {
            take(ev, &mut records, &mut end);
        }
    }
    for ev in decoder.finish() {
        take(ev, &mut records, &mut end);
    }
    smartagg_io::output::write_atomic(&rois_path, &received)?;
    // `smartagg localize demo-out/blinks.rois` needs no camera flags.
    crate::stream_info::StreamInfo::new(&preset, args.field, args.field, "demo")
        .write_beside(&rois_path)?;
    let losses: LossStats = decoder.stats().clone();
    timing.add(
        "host decoder",
        t,
        format!(
            "{} packets, {} blinks, losses: {}",
            losses.packets_ok,
            records.len(),
            if losses.any_loss() { "YES" } else { "none" }
        ),
    );

    // 4. Localise every blink (SPAD binomial MLE with the record's on/off split).
    let t = Instant::now();
    let pixel_nm = preset.pixel_nm();
    let opts = FitOptions::new(SigmaMode::Fitted {
        initial: preset.sigma_px(),
    });
    let mut locs: Vec<Localization> = Vec::new();
    let mut failed = 0;
    for (i, rec) in records.iter().enumerate() {
        let roi = SpadRoi::from_record(rec, None)?;
        let fit = fit_binomial(&roi, &opts);
        if !fit.status.is_ok() {
            failed += 1;
        }
        let mut loc = Localization::from_fit(
            &fit,
            rec.roi_x0() as f64,
            rec.roi_y0() as f64,
            pixel_nm,
            i as u64 + 1,
        );
        loc.extra = vec![rec.t_s as f64, rec.t_e as f64, rec.planes_summed as f64];
        locs.push(loc);
    }
    timing.add(
        "localise",
        t,
        format!(
            "{} localisations ({failed} fits failed, flagged), {:.0} fits/s",
            locs.len(),
            locs.len() as f64 / t.elapsed().as_secs_f64().max(1e-9)
        ),
    );

    // 5. Compare with the truth, measure the rulers.
    let t = Instant::now();
    let period = cam.plane_period_s;
    let analysis = analyse(
        &locs,
        &records,
        (cfg.n_window, cfg.end_trim),
        &truth,
        &rulers,
        sim.emitters(),
        period,
    );
    timing.add("analysis", t, format!("{} matched", analysis.matched));

    // 6. Outputs.
    let t = Instant::now();
    let csv = args.out.join("localisations.csv");
    let table = LocTable {
        extra_columns: vec![
            "t_s [plane]".into(),
            "t_e [plane]".into(),
            "planes summed".into(),
        ],
        merged: false,
        rows: locs.clone(),
    };
    let mut table_bytes = Vec::new();
    table.write_csv(&mut table_bytes)?;
    smartagg_io::output::write_atomic(&csv, &table_bytes)?;
    let png = args.out.join("render.png");
    let points: Vec<Point> = locs
        .iter()
        .filter(|l| l.status.is_ok())
        .map(|l| Point {
            x_nm: l.x_nm,
            y_nm: l.y_nm,
            sigma_nm: l.uncertainty_nm,
        })
        .collect();
    let mut ropts = RenderOptions::covering(&points, 2.0, 3.0)?;
    // Render the whole field, not only the area the localisations cover.
    let side = args.field as f64 * pixel_nm;
    ropts.origin_x_nm = 0.0;
    ropts.origin_y_nm = 0.0;
    ropts.width = (side / ropts.pixel_nm).ceil() as usize;
    ropts.height = ropts.width;
    let (image, _) = render::render(&points, &ropts)?;
    let (png_bytes, _) = smartagg_localize::figure::figure_png(
        &image,
        &smartagg_localize::figure::FigureOptions {
            colormap: smartagg_localize::figure::Colormap::Gray,
            saturate: 0.5,
            scale_bar: true,
        },
    )?;
    smartagg_io::output::write_atomic(&png, &png_bytes)?;
    timing.add(
        "write outputs",
        t,
        format!("{}, {}", csv.display(), png.display()),
    );

    let raw_bytes = planes * smartagg_model::recording::plane_bytes(args.field, args.field) as u64;
    let report = report(
        &args,
        &cfg,
        planes,
        raw_bytes,
        fast_bytes.len() as u64,
        identical,
        &losses,
        end,
        &analysis,
        &timing,
        failed,
        gateware.as_ref(),
    );
    let md = args.out.join("report.md");
    smartagg_io::output::write_atomic(&md, report.as_bytes())?;
    println!("{report}");
    println!(
        "written: {}, {}, {}, {}",
        rois_path.display(),
        csv.display(),
        png.display(),
        md.display()
    );
    Ok(())
}

fn take(
    ev: Event,
    records: &mut Vec<BlinkRecord>,
    end: &mut Option<smartagg_model::record::StreamEnd>,
) {
    if let Event::Packet(p) = ev {
        match p.record {
            Record::Blink(b) => records.push(b),
            Record::End(e) => *end = Some(e),
            _ => {}
        }
    }
}
