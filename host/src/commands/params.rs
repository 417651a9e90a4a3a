//! `smartagg params`: the paper's statistics (Eq. 1–7) for a camera and a
//! molecule — window N, threshold T and T_int, the integer kernel — with the
//! predicted false alarms, and the field design that `smartagg aggregate`
//! runs by default (open and hold thresholds for a false-blink budget over
//! the field, with the recall it predicts against blink duration).

use crate::setup;
use serde::Serialize;
use smartagg_model::false_alarm::{self, DetectionProbability, FalseAlarmReport};
use smartagg_model::field_design::{self, FieldDesign};
use smartagg_model::params::Camera;
use smartagg_model::stats::Detection;

/// Arguments of `smartagg params`.
#[derive(clap::Args, Debug)]
#[command(mut_arg("preset", |a| a.help("Camera preset: spcimager, spcimager-projected or spad512s (bit-plane cameras)")))]
pub struct Args {
    #[command(flatten)]
    pub preset: crate::setup::PresetArgs,
    /// Molecule flux, photons/s reaching the sensor (default: 50,000).
    #[arg(long)]
    pub flux: Option<f64>,
    /// Field for the false-alarm figures, pixels (default: the whole sensor).
    #[arg(long)]
    pub width: Option<u32>,
    /// Field height, pixels (default: the whole sensor).
    #[arg(long)]
    pub height: Option<u32>,
    /// Tolerated false blinks per second over the field: the field design's
    /// budget (and the paper scheme's suggested L_min).
    #[arg(long, default_value_t = smartagg_model::field_design::DEFAULT_FALSE_BLINKS_PER_S)]
    pub false_blinks_per_s: f64,
    /// Print JSON (all fields) instead of the summary.
    #[arg(long)]
    pub json: bool,
}

#[derive(Serialize)]
struct Output<'a> {
    preset: &'a str,
    objective: u32,
    #[serde(flatten)]
    detection: &'a Detection,
    detection_probability: Option<DetectionProbability>,
    false_alarms: Option<FalseAlarmReport>,
    false_blinks_per_s_target: f64,
    l_min_suggested: Option<u32>,
    field_design: Option<FieldDesign>,
    /// (blink duration ms, predicted recall) of the field design.
    recall_by_duration_ms: Vec<(f64, f64)>,
    notes: Vec<String>,
}

/// Blink durations at which the predicted recall is printed, ms.
const RECALL_DURATIONS_MS: [f64; 8] = [5.0, 10.0, 15.0, 20.0, 30.0, 50.0, 70.0, 100.0];

/// Runs the command.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (preset, det) = setup::detection(&args.preset.name, args.preset.objective, args.flux)?;
    let Camera::Spad(cam) = &preset.camera else {
        anyhow::bail!("params applies to bit-plane (SPAD) presets");
    };
    let (w, h) = (
        args.width.unwrap_or(cam.width),
        args.height.unwrap_or(cam.height),
    );
    let rate = 1.0 / cam.plane_period_s;
    let mut notes = Vec::new();
    let pd = false_alarm::detection_probability(&det)
        .map_err(|e| notes.push(format!("detection probability not computed: {e}")))
        .ok();
    let fa = false_alarm::false_alarm_report(&det, w, h, rate)
        .map_err(|e| notes.push(format!("false alarms not computed: {e}")))
        .ok();
    let l_min = false_alarm::l_min_for_target(
        &det.kernel(),
        det.n_window,
        det.p_off,
        det.threshold_int,
        w as u64 * h as u64,
        rate,
        args.false_blinks_per_s,
    )
    .map_err(|e| notes.push(format!("L_min not computed: {e}")))
    .ok();
    let fd = field_design::design(&det, w, h, rate, args.false_blinks_per_s)
        .map_err(|e| notes.push(format!("field design not made: {e}")))
        .ok();
    let recall: Vec<(f64, f64)> = fd.as_ref().map_or(Vec::new(), |d| {
        RECALL_DURATIONS_MS
            .iter()
            .map(|&ms| (ms, d.recall((ms * 1e-3 * rate).round() as u32)))
            .collect()
    });
    if args.json {
        let out = Output {
            preset: &args.preset.name,
            objective: args.preset.objective,
            detection: &det,
            detection_probability: pd,
            false_alarms: fa,
            false_blinks_per_s_target: args.false_blinks_per_s,
            l_min_suggested: l_min,
            field_design: fd,
            recall_by_duration_ms: recall,
            notes,
        };
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(());
    }
    println!(
        "{} at {}x: eta = {:.4}, background b = {:.2} Hz/pixel, molecule I = {:.0} photons/s, tau = {:.0} us, PSF sigma = {:.3} px",
        args.preset.name,
        args.preset.objective,
        det.eta,
        det.background_rate_hz,
        det.flux_hz,
        det.tau_s * 1e6,
        det.sigma_px
    );
    println!(
        "kernel: {} taps {:?}, sum 2^{} (max 2-D weight error {:.2e}, sum K^2 error {:+.2e} relative)",
        det.kernel_size,
        det.kernel_weights,
        det.kernel_shift,
        det.kernel_quantisation.max_abs_error_2d,
        det.kernel_quantisation.sum_sq_rel_error
    );
    println!(
        "window N = {} bit-planes (Eq. 6 gives {:.2}; {:.1} ms)",
        det.n_window,
        det.n_window_real,
        det.n_window as f64 * det.tau_s * 1e3
    );
    println!(
        "threshold T = {:.5} (Eq. 7), T_int = {} in units of 2^-{} (quantisation {:.2e})",
        det.threshold,
        det.threshold_int,
        2 * det.kernel_shift as u32,
        det.threshold_quantisation_abs
    );
    println!(
        "H off: {:.4} ± {:.4}; H on: {:.4} ± {:.4} (normalised units)",
        det.e_h_off, det.sd_h_off, det.e_h_on, det.sd_h_on
    );
    if let Some(pd) = &pd {
        println!(
            "detection probability of a molecule on for the whole window: {:.4} exact ({:.4} Gaussian)",
            pd.detection, det.gaussian_detection_probability
        );
    }
    if let Some(fa) = &fa {
        println!(
            "false alarms: {:.3e} per pixel-plane exact vs {:.3e} Gaussian ({}); {:.0}/s over {}x{} pixels at {:.0} planes/s",
            fa.per_pixel_plane,
            fa.gaussian_per_pixel_plane,
            fa.ratio_to_gaussian.map_or("-".into(), |r| format!("{r:.2}x")),
            fa.per_second,
            w,
            h,
            rate
        );
    }
    if let Some(l) = l_min {
        println!(
            "paper scheme (--detection paper): L_min = {l} planes would be needed for <= {} false blinks/s over the field (bound), losing every blink shorter than about {:.0} ms",
            args.false_blinks_per_s,
            l as f64 / rate * 1e3
        );
    }
    if let Some(d) = &fd {
        println!("field design (the default of `smartagg aggregate`, --detection field):");
        println!(
            "  a track opens where H reaches T_int = {} ({:.2} sd above the background's mean): background alone then opens at most {:.3} tracks/s over the {}x{} field (budget {}/s; exact up-crossing bound)",
            d.threshold_open, d.open_sigmas, d.predicted_false_blinks_per_s, w, h, d.budget_per_s
        );
        println!(
            "  it stays on while H near its anchor is >= T_hold = {} (the paper's {:.2}-sd threshold), so one blink gives one record spanning the blink; candidates within r_assoc = {} px (2 sigma) of a live track belong to it; L_min = {}",
            d.threshold_hold, d.hold_sigmas, d.r_assoc, d.l_min
        );
        println!(
            "  each blink's image sums the bit-planes from N before the crossing to its estimated end, t_drop - {} (--end-trim; the paper sums to t_drop, {:.1} ms more, after the blink has ended: background, which at this light limits the localisation of short blinks)",
            d.end_trim,
            d.end_trim as f64 / rate * 1e3
        );
        let row: Vec<String> = recall
            .iter()
            .map(|(ms, r)| format!("{ms:.0} ms {r:.2}"))
            .collect();
        println!("  predicted recall by blink duration: {}", row.join(", "));
        match d.shortest_blink_planes {
            Some(p) => println!(
                "  blinks of {:.1} ms or longer are detected with >= 90 % probability",
                p as f64 / rate * 1e3
            ),
            None => println!(
                "  warning: no blink reaches 90 % detection at this budget: the light is too weak for it; raise --false-blinks-per-s"
            ),
        }
    }
    for n in notes {
        println!("note: {n}");
    }
    Ok(())
}
