//! What the demo measured against the truth (the study's truth-matching
//! rule; per-marker spread and ruler spacing from the localisations each
//! true marker collected) and the Markdown report.

use super::gateware::GatewareLeg;
use super::{Args, Timing, MATCH_NM, RULERS, SPACING_NM};
use smartagg_localize::table::Localization;
use smartagg_model::packet::LossStats;
use smartagg_model::record::BlinkRecord;
use smartagg_scene::scene::Position;
use smartagg_scene::truth::BlinkTruth;
use smartagg_study::matching::{assign, Loc, Truth};
use std::fmt::Write as _;

/// What the demo measured against the truth.
pub(super) struct Analysis {
    pub(super) matched: usize,
    false_positives: usize,
    blinks_true: usize,
    blinks_found: usize,
    rmse_nm: f64,
    markers: Vec<MarkerStats>,
    spacings_nm: Vec<f64>,
}

struct MarkerStats {
    ruler: usize,
    marker: usize,
    count: usize,
    spread_nm: f64,
    mean: (f64, f64),
}

pub(super) fn analyse(
    locs: &[Localization],
    records: &[BlinkRecord],
    (n_window, end_trim): (u32, u32),
    truth: &[BlinkTruth],
    rulers: &[[usize; 3]],
    emitters: &[Position],
    period_s: f64,
) -> Analysis {
    // The study's truth-matching rule: a localisation matches the nearest
    // true blink within MATCH_NM whose on-time overlaps the planes the
    // record summed.
    let mut per_emitter: Vec<Vec<(f64, f64)>> = vec![Vec::new(); emitters.len()];
    let mut found = vec![false; truth.len()];
    let (mut matched, mut sq) = (0usize, 0.0);
    let fitted: Vec<Loc> = locs
        .iter()
        .zip(records)
        .filter(|(loc, _)| loc.status.is_ok())
        .map(|(loc, rec)| {
            let summed =
                smartagg_model::record_check::summed_planes_by(rec, n_window, Some(end_trim));
            Loc {
                x_nm: loc.x_nm,
                y_nm: loc.y_nm,
                t0_s: summed.start as f64 * period_s,
                t1_s: summed.end as f64 * period_s,
                photons: loc.intensity,
            }
        })
        .collect();
    let blinks: Vec<Truth> = truth.iter().map(Truth::from).collect();
    for (loc, m) in fitted.iter().zip(assign(&blinks, &fitted, MATCH_NM)) {
        if let Some(i) = m {
            matched += 1;
            sq += (blinks[i].x_nm - loc.x_nm).powi(2) + (blinks[i].y_nm - loc.y_nm).powi(2);
            found[i] = true;
            if let Some(v) = per_emitter.get_mut(truth[i].emitter as usize) {
                v.push((loc.x_nm, loc.y_nm));
            }
        }
    }
    let mut markers = Vec::new();
    let mut spacings = Vec::new();
    for (r, ids) in rulers.iter().enumerate() {
        let mut means = Vec::new();
        for (m, &id) in ids.iter().enumerate() {
            let pts = &per_emitter[id];
            if pts.is_empty() {
                means.push(None);
                continue;
            }
            let n = pts.len() as f64;
            let mean = (
                pts.iter().map(|p| p.0).sum::<f64>() / n,
                pts.iter().map(|p| p.1).sum::<f64>() / n,
            );
            let spread = (pts
                .iter()
                .map(|p| (p.0 - mean.0).powi(2) + (p.1 - mean.1).powi(2))
                .sum::<f64>()
                / (2.0 * n))
                .sqrt();
            markers.push(MarkerStats {
                ruler: r,
                marker: m,
                count: pts.len(),
                spread_nm: spread,
                mean,
            });
            means.push(Some(mean));
        }
        for w in means.windows(2) {
            if let (Some(a), Some(b)) = (w[0], w[1]) {
                spacings.push(((a.0 - b.0).powi(2) + (a.1 - b.1).powi(2)).sqrt());
            }
        }
    }
    Analysis {
        matched,
        false_positives: locs.iter().filter(|l| l.status.is_ok()).count() - matched,
        blinks_true: truth.iter().filter(|b| b.on_exposed_s > 0.0).count(),
        blinks_found: found.iter().filter(|&&f| f).count(),
        rmse_nm: if matched > 0 {
            (sq / matched as f64).sqrt()
        } else {
            f64::NAN
        },
        markers,
        spacings_nm: spacings,
    }
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        (s[n / 2 - 1] + s[n / 2]) / 2.0
    }
}

#[allow(clippy::too_many_arguments)]
pub(super) fn report(
    args: &Args,
    cfg: &smartagg_model::config::PipelineConfig,
    planes: u64,
    raw_bytes: u64,
    packet_bytes: u64,
    identical: Option<bool>,
    losses: &LossStats,
    end: Option<smartagg_model::record::StreamEnd>,
    a: &Analysis,
    timing: &Timing,
    failed: usize,
    gateware: Option<&GatewareLeg>,
) -> String {
    let mut s = String::new();
    let fmt_nm = |v: f64| {
        if v.is_finite() {
            format!("{v:.1} nm")
        } else {
            "n/a".into()
        }
    };
    let _ = writeln!(
        s,
        "# smartagg demo: GATTA-PAINT 80G nanorulers, SPCImager 150x\n"
    );
    let _ = writeln!(
        s,
        "{} rulers (three markers {SPACING_NM} nm apart), {}x{} pixels of 53.3 nm, {:.0} s of bit-planes ({planes} planes), seed {}.\n",
        RULERS.len(),
        args.field,
        args.field,
        args.seconds,
        args.seed
    );
    let _ = writeln!(
        s,
        "Pipeline (the field design, `smartagg aggregate`'s defaults): window N = {} planes, a track opens at T_int = {} and holds down to T_hold = {}, a blink sums the bit-planes [t_cross − N, t_drop − {}] (to its estimated end), r_assoc = {}, kernel {:?}, L_min = {}, ROI {}x{}.\n",
        cfg.n_window,
        cfg.threshold_int,
        cfg.threshold_hold,
        cfg.end_trim,
        cfg.r_assoc,
        cfg.kernel,
        cfg.l_min,
        cfg.roi_size,
        cfg.roi_size
    );
    let _ = writeln!(s, "## Result\n");
    let _ = writeln!(s, "| quantity | value |\n|---|---|");
    let _ = writeln!(
        s,
        "| localisation error (RMS vs truth, matched within {MATCH_NM} nm) | {} |",
        fmt_nm(a.rmse_nm)
    );
    let _ = writeln!(
        s,
        "| localisations matched / false | {} / {} ({failed} fits failed) |",
        a.matched, a.false_positives
    );
    let _ = writeln!(
        s,
        "| recall: true blinks found | {} of {} ({:.1} %) |",
        a.blinks_found,
        a.blinks_true,
        100.0 * a.blinks_found as f64 / a.blinks_true.max(1) as f64
    );
    let _ = writeln!(
        s,
        "| median ruler spacing | {} (true {SPACING_NM} nm; {} neighbour pairs) |",
        fmt_nm(median(&a.spacings_nm)),
        a.spacings_nm.len()
    );
    let _ = writeln!(
        s,
        "| packets vs raw bit-planes | {} bytes vs {} bytes ({:.0}x smaller) |",
        packet_bytes,
        raw_bytes,
        raw_bytes as f64 / packet_bytes.max(1) as f64
    );
    let _ = writeln!(
        s,
        "| golden model and fast engine | {} |",
        match identical {
            Some(true) => "byte-identical packet streams",
            Some(false) => "DIFFER",
            None => "golden model skipped",
        }
    );
    let _ = writeln!(
        s,
        "| gateware (Verilated pipeline core) vs golden model | {} |",
        match gateware {
            Some(g) => format!(
                "byte-identical on {} ({} packets; {:.0} clocks per plane at 16 pixels per clock)",
                g.which_planes(),
                g.packets,
                g.clocks_per_plane
            ),
            None => "not run (--gateware-planes 0)".into(),
        }
    );
    let _ = writeln!(
        s,
        "| losses in the packet stream | {} |",
        if losses.any_loss() {
            losses.to_string()
        } else {
            "none".into()
        }
    );
    if let Some(e) = end {
        let _ = writeln!(
            s,
            "| tracks unconfirmed / candidates dropped / dips bridged | {} / {} / {} |",
            e.unconfirmed, e.dropped_candidates, e.bridged_dips
        );
    }
    let _ = writeln!(s, "\n## Markers\n\n| ruler | marker | localisations | spread (RMS per axis) | mean x, y (nm) |\n|---|---|---|---|---|");
    for m in &a.markers {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1}, {:.1} |",
            m.ruler + 1,
            m.marker + 1,
            m.count,
            fmt_nm(m.spread_nm),
            m.mean.0,
            m.mean.1
        );
    }
    let _ = writeln!(
        s,
        "\nNeighbour spacings: {}",
        a.spacings_nm
            .iter()
            .map(|d| format!("{d:.1}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        s,
        "\n## Time per stage\n\n| stage | seconds | |\n|---|---|---|"
    );
    for (stage, secs, what) in &timing.rows {
        let _ = writeln!(s, "| {stage} | {secs:.2} | {what} |");
    }
    s
}
