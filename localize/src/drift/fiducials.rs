//! Drift from fiducials: spots that persist through the acquisition.
//!
//! Candidates are the densest spots of the first segment: a localisation
//! with at least `fiducial_min` neighbours within `fiducial_radius_nm`
//! (itself included) and no denser neighbour within twice the radius; its
//! centre is the mean of those neighbours. Each candidate is then followed
//! segment by segment: its centre in the next segment is the mean of that
//! segment's localisations within the radius of its last centre (twice
//! recentred, so that a step of up to the radius is caught). A candidate
//! that finds fewer than `fiducial_min` localisations in some segment is
//! dropped. The drift of a segment is the mean displacement of the spots
//! kept, relative to their centres in the first segment.

use super::{segments_from, split, DriftError, DriftEstimate, DriftOptions, DriftPoint};

/// A uniform grid of cells of side `cell` over some points, for
/// neighbourhood queries in time proportional to the neighbours.
struct CellIndex<'a> {
    points: &'a [DriftPoint],
    cell: f64,
    map: std::collections::HashMap<(i64, i64), Vec<usize>>,
}

impl<'a> CellIndex<'a> {
    fn new(points: &'a [DriftPoint], cell: f64) -> CellIndex<'a> {
        let mut map: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
        for (n, p) in points.iter().enumerate() {
            map.entry(Self::key(p.x_nm, p.y_nm, cell))
                .or_default()
                .push(n);
        }
        CellIndex { points, cell, map }
    }

    fn key(x: f64, y: f64, cell: f64) -> (i64, i64) {
        // Saturating casts: a far-away point lands in an edge cell, never UB.
        ((x / cell).floor() as i64, (y / cell).floor() as i64)
    }

    /// Indices of the points within `r` (≤ the cell side) of `(x, y)`.
    fn within(&self, x: f64, y: f64, r: f64) -> impl Iterator<Item = usize> + '_ {
        let (cx, cy) = Self::key(x, y, self.cell);
        (-1..=1)
            .flat_map(move |dy| {
                (-1..=1).map(move |dx| (cx.saturating_add(dx), cy.saturating_add(dy)))
            })
            .filter_map(|k| self.map.get(&k))
            .flatten()
            .copied()
            .filter(move |&n| {
                let p = self.points[n];
                (p.x_nm - x).hypot(p.y_nm - y) <= r
            })
    }

    /// Mean position and count of the points within `r` of `(x, y)`.
    fn mean_within(&self, x: f64, y: f64, r: f64) -> (f64, f64, usize) {
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0usize);
        for i in self.within(x, y, r) {
            sx += self.points[i].x_nm;
            sy += self.points[i].y_nm;
            n += 1;
        }
        if n == 0 {
            (x, y, 0)
        } else {
            (sx / n as f64, sy / n as f64, n)
        }
    }
}

/// Estimates the drift from fiducials (see the module docs).
pub fn fiducials(points: &[DriftPoint], opts: &DriftOptions) -> Result<DriftEstimate, DriftError> {
    let (bounds, groups) = split(points, opts)?;
    let r = opts.fiducial_radius_nm;
    let min = opts.fiducial_min;
    let no_fiducial = DriftError::NoFiducial {
        min,
        radius_nm: r,
        segments: groups.len(),
    };
    // Candidates: local density maxima of the first segment.
    let first = CellIndex::new(&groups[0], 2.0 * r);
    let counts: Vec<usize> = groups[0]
        .iter()
        .map(|p| first.within(p.x_nm, p.y_nm, r).count())
        .collect();
    let mut candidates: Vec<(f64, f64)> = Vec::new();
    for (n, p) in groups[0].iter().enumerate() {
        let c = counts[n];
        if c < min {
            continue;
        }
        // The densest within 2r wins; ties go to the lowest index.
        let beaten = first
            .within(p.x_nm, p.y_nm, 2.0 * r)
            .any(|m| counts[m] > c || (counts[m] == c && m < n));
        if !beaten {
            let (x, y, _) = first.mean_within(p.x_nm, p.y_nm, r);
            candidates.push((x, y));
        }
    }
    let total = candidates.len();
    // Follow each candidate; `tracks[f][k]` is its centre in segment k.
    let mut tracks: Vec<Vec<(f64, f64)>> = candidates.iter().map(|&c| vec![c]).collect();
    for g in &groups[1..] {
        let index = CellIndex::new(g, 2.0 * r);
        tracks.retain_mut(|t| {
            let (mut x, mut y) = *t.last().expect("a track starts with its first centre");
            let mut n = 0;
            for _ in 0..2 {
                (x, y, n) = index.mean_within(x, y, r);
            }
            t.push((x, y));
            n >= min
        });
    }
    if tracks.is_empty() {
        return Err(no_fiducial);
    }
    let k = groups.len();
    let f = tracks.len() as f64;
    let drift: Vec<(f64, f64)> = (0..k)
        .map(|s| {
            let (sx, sy) = tracks.iter().fold((0.0, 0.0), |(ax, ay), t| {
                (ax + t[s].0 - t[0].0, ay + t[s].1 - t[0].1)
            });
            (sx / f, sy / f)
        })
        .collect();
    let mut sq = 0.0;
    for t in &tracks {
        for s in 0..k {
            let (ex, ey) = (t[s].0 - t[0].0 - drift[s].0, t[s].1 - t[0].1 - drift[s].1);
            sq += ex * ex + ey * ey;
        }
    }
    Ok(DriftEstimate {
        segments: segments_from(&bounds, &groups, &drift),
        bin_nm: 0.0,
        used: tracks.len(),
        total,
        residual_rms_nm: (sq / (f * k as f64)).sqrt(),
    })
}
