//! Merging localisations of the same blink in consecutive frames.
//!
//! The paper merges EMCCD/sCMOS localisations "within 40 nm from one
//! another on subsequent frames" (as ThunderSTORM's merging post-processing
//! does). A localisation in frame `f` joins the track whose last member is
//! in frame `f − 1 − gap … f − 1` and lies within `max_dist_nm` of it; pairs
//! are matched closest first, each track and localisation at most once.
//! A track becomes one localisation: position and σ weighted by the inverse
//! variance `1/u²`, uncertainty `sqrt(1/Σ 1/u²)`, intensities summed, offset
//! and bkgstd averaged, frame of the first member, `detections` = members.
//! Failed fits are never merged; they pass through unchanged.

use crate::table::Localization;
use std::collections::HashMap;

/// Merging counts, for the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MergeStats {
    /// Localisations in.
    pub input: usize,
    /// Localisations out.
    pub output: usize,
    /// Tracks of two or more detections.
    pub merged_tracks: usize,
    /// Failed fits passed through unmerged.
    pub passed_failed: usize,
}

struct Track {
    members: Vec<usize>,
    last_frame: u64,
    last: (f64, f64),
}

/// Merges localisations of consecutive frames (`max_gap` frames may be
/// skipped; 0 means strictly consecutive) within `max_dist_nm`. The output
/// is sorted by frame.
pub fn merge_consecutive(
    locs: &[Localization],
    max_dist_nm: f64,
    max_gap: u64,
) -> (Vec<Localization>, MergeStats) {
    let mut order: Vec<usize> = (0..locs.len()).collect();
    order.sort_by_key(|&i| locs[i].frame);
    let cell = max_dist_nm.max(1e-9);
    let key = |x: f64, y: f64| ((x / cell).floor() as i64, (y / cell).floor() as i64);
    let mut open: Vec<Track> = Vec::new();
    let mut closed: Vec<Track> = Vec::new();
    let mut passed = Vec::new();
    let mut start = 0;
    while start < order.len() {
        let frame = locs[order[start]].frame;
        let mut end = start;
        while end < order.len() && locs[order[end]].frame == frame {
            end += 1;
        }
        // Close tracks that can no longer continue.
        let (keep, done): (Vec<Track>, Vec<Track>) = open
            .into_iter()
            .partition(|t| t.last_frame + 1 + max_gap >= frame && t.last_frame < frame);
        closed.extend(done);
        open = keep;
        let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
        for (ti, t) in open.iter().enumerate() {
            grid.entry(key(t.last.0, t.last.1)).or_default().push(ti);
        }
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for &li in &order[start..end] {
            let l = &locs[li];
            if !l.status.is_ok() {
                continue;
            }
            let (cx, cy) = key(l.x_nm, l.y_nm);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    if let Some(ts) = grid.get(&(cx + dx, cy + dy)) {
                        for &ti in ts {
                            let t = &open[ti];
                            let d =
                                ((l.x_nm - t.last.0).powi(2) + (l.y_nm - t.last.1).powi(2)).sqrt();
                            if d <= max_dist_nm {
                                pairs.push((d, ti, li));
                            }
                        }
                    }
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let mut track_used = vec![false; open.len()];
        let mut loc_used: HashMap<usize, ()> = HashMap::new();
        for (_, ti, li) in pairs {
            if track_used[ti] || loc_used.contains_key(&li) {
                continue;
            }
            track_used[ti] = true;
            loc_used.insert(li, ());
            let t = &mut open[ti];
            t.members.push(li);
            t.last_frame = frame;
            t.last = (locs[li].x_nm, locs[li].y_nm);
        }
        for &li in &order[start..end] {
            if loc_used.contains_key(&li) {
                continue;
            }
            if locs[li].status.is_ok() {
                open.push(Track {
                    members: vec![li],
                    last_frame: frame,
                    last: (locs[li].x_nm, locs[li].y_nm),
                });
            } else {
                passed.push(li);
            }
        }
        start = end;
    }
    closed.extend(open);
    let mut out: Vec<Localization> = closed.iter().map(|t| combine(locs, &t.members)).collect();
    let stats = MergeStats {
        input: locs.len(),
        output: closed.len() + passed.len(),
        merged_tracks: closed.iter().filter(|t| t.members.len() > 1).count(),
        passed_failed: passed.len(),
    };
    out.extend(passed.iter().map(|&i| locs[i].clone()));
    out.sort_by(|a, b| a.frame.cmp(&b.frame).then(a.x_nm.total_cmp(&b.x_nm)));
    (out, stats)
}

/// One localisation from the members of a track.
fn combine(locs: &[Localization], members: &[usize]) -> Localization {
    let first = &locs[members[0]];
    if members.len() == 1 {
        return first.clone();
    }
    let (mut sw, mut sx, mut sy, mut ss) = (0.0, 0.0, 0.0, 0.0);
    let (mut inten, mut off, mut bkg, mut det) = (0.0, 0.0, 0.0, 0u32);
    for &i in members {
        let l = &locs[i];
        // Inverse-variance weights; a zero uncertainty would dominate, so it
        // is floored at 1e-3 nm.
        let w = 1.0 / l.uncertainty_nm.max(1e-3).powi(2);
        sw += w;
        sx += w * l.x_nm;
        sy += w * l.y_nm;
        ss += w * l.sigma_nm;
        inten += l.intensity;
        off += l.offset;
        bkg += l.bkgstd;
        det += l.detections;
    }
    let n = members.len() as f64;
    Localization {
        frame: first.frame,
        x_nm: sx / sw,
        y_nm: sy / sw,
        sigma_nm: ss / sw,
        intensity: inten,
        offset: off / n,
        bkgstd: bkg / n,
        uncertainty_nm: (1.0 / sw).sqrt(),
        status: first.status,
        detections: det,
        extra: first.extra.clone(),
    }
}
