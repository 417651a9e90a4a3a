//! The analysis a user does without the truth: density filter, principal
//! axis, 1-D k-means along it and the Gaussian mixture that refines it.

use crate::experiment::common::{quantile, TLoc};

/// Keeps localisations with at least `min` others within `r` nm.
pub fn density_filter(locs: &[TLoc], r: f64, min: usize) -> Vec<TLoc> {
    let cell = r;
    let key = |l: &TLoc| {
        (
            (l.x_nm / cell).floor() as i64,
            (l.y_nm / cell).floor() as i64,
        )
    };
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
    for (i, l) in locs.iter().enumerate() {
        grid.entry(key(l)).or_default().push(i);
    }
    locs.iter()
        .enumerate()
        .filter(|(i, l)| {
            let (cx, cy) = key(l);
            let mut n = 0;
            for gx in cx - 1..=cx + 1 {
                for gy in cy - 1..=cy + 1 {
                    for &j in grid.get(&(gx, gy)).map_or(&[][..], |v| &v[..]) {
                        if j != *i
                            && (locs[j].x_nm - l.x_nm).powi(2) + (locs[j].y_nm - l.y_nm).powi(2)
                                <= r * r
                        {
                            n += 1;
                        }
                    }
                }
            }
            n >= min
        })
        .map(|(_, l)| *l)
        .collect()
}

/// Principal axis (unit vector) and centroid of points.
pub fn principal_axis(p: &[(f64, f64)]) -> ((f64, f64), (f64, f64)) {
    let n = p.len().max(1) as f64;
    let (mx, my) = p
        .iter()
        .fold((0.0, 0.0), |a, q| (a.0 + q.0 / n, a.1 + q.1 / n));
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for q in p {
        let (dx, dy) = (q.0 - mx, q.1 - my);
        sxx += dx * dx;
        syy += dy * dy;
        sxy += dx * dy;
    }
    let theta = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    ((theta.cos(), theta.sin()), (mx, my))
}

/// 1-D k-means with 3 clusters, initialised at the 1/6, 1/2, 5/6
/// quantiles; returns each value's cluster (0..3, ordered along the axis).
pub fn kmeans3(v: &[f64]) -> Vec<usize> {
    let mut c = [1.0 / 6.0, 0.5, 5.0 / 6.0].map(|q| quantile(v, q).unwrap_or(0.0));
    let mut a = vec![0usize; v.len()];
    for _ in 0..50 {
        for (i, &x) in v.iter().enumerate() {
            a[i] = (0..3)
                .min_by(|&p, &q| (x - c[p]).abs().total_cmp(&(x - c[q]).abs()))
                .unwrap_or(0);
        }
        let mut nc = c;
        for (k, ck) in nc.iter_mut().enumerate() {
            let m: Vec<f64> = v
                .iter()
                .zip(&a)
                .filter(|(_, &ai)| ai == k)
                .map(|(x, _)| *x)
                .collect();
            if !m.is_empty() {
                *ck = m.iter().sum::<f64>() / m.len() as f64;
            }
        }
        if nc == c {
            break;
        }
        c = nc;
    }
    a
}

/// One isotropic 2-D Gaussian of a mixture.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// Mean x, nm.
    pub x: f64,
    /// Mean y, nm.
    pub y: f64,
    /// Per-axis standard deviation, nm.
    pub sigma: f64,
    /// Mixing weight.
    pub weight: f64,
}

/// A mixture of three isotropic 2-D Gaussians fitted to `pts` by EM,
/// started from the hard clusters `init` (0..3). Unlike the clusters'
/// plain centroids, the means are not pulled towards each other by the
/// tails that cross the cluster boundaries (markers 80 nm apart with a
/// 13 nm spread share about 1 % of their localisations each way).
pub fn gaussian_mixture(pts: &[(f64, f64)], init: &[usize]) -> Vec<Component> {
    let n = pts.len().max(1) as f64;
    let mut resp: Vec<[f64; 3]> = init
        .iter()
        .map(|&k| {
            let mut r = [0.0; 3];
            r[k.min(2)] = 1.0;
            r
        })
        .collect();
    let mut comps = [Component {
        x: 0.0,
        y: 0.0,
        sigma: 1.0,
        weight: 0.0,
    }; 3];
    for _ in 0..200 {
        // M step.
        for (k, c) in comps.iter_mut().enumerate() {
            let w: f64 = resp.iter().map(|r| r[k]).sum();
            if w <= 1e-9 {
                c.weight = 0.0;
                continue;
            }
            let (mut sx, mut sy) = (0.0, 0.0);
            for (p, r) in pts.iter().zip(&resp) {
                sx += r[k] * p.0;
                sy += r[k] * p.1;
            }
            c.x = sx / w;
            c.y = sy / w;
            let ss: f64 = pts
                .iter()
                .zip(&resp)
                .map(|(p, r)| r[k] * ((p.0 - c.x).powi(2) + (p.1 - c.y).powi(2)))
                .sum();
            c.sigma = (ss / (2.0 * w)).sqrt().max(0.5);
            c.weight = w / n;
        }
        // E step (log-sum-exp; a point far from every component goes to the nearest).
        let mut change = 0.0f64;
        for (p, r) in pts.iter().zip(resp.iter_mut()) {
            let mut l = [f64::NEG_INFINITY; 3];
            for (k, c) in comps.iter().enumerate() {
                if c.weight > 0.0 {
                    let d2 = (p.0 - c.x).powi(2) + (p.1 - c.y).powi(2);
                    l[k] = c.weight.ln() - 2.0 * c.sigma.ln() - d2 / (2.0 * c.sigma * c.sigma);
                }
            }
            let m = l.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let e: Vec<f64> = l.iter().map(|v| (v - m).exp()).collect();
            let t: f64 = e.iter().sum();
            for k in 0..3 {
                let v = e[k] / t;
                change = change.max((v - r[k]).abs());
                r[k] = v;
            }
        }
        if change < 1e-7 {
            break;
        }
    }
    comps.to_vec()
}
