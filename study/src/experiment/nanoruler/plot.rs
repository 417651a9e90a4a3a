//! nanoruler.png: Fig. 6 (one ruler rendered per scheme, its cross-section)
//! and Fig. 7 (spread per marker, neighbour distances).

use super::{NanorulerResult, SCHEMES, SPACING_NM};
use crate::error::StudyError;
use crate::experiment::common::{colour, median, plot_err, quantile, TLoc};
use plotters::prelude::*;
use std::path::Path;

pub(super) fn plot(path: &Path, r: &NanorulerResult) -> Result<(), StudyError> {
    let root = BitMapBackend::new(path, (1600, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| plot_err(path, e))?;
    let (top, bottom) = root.split_vertically(420);
    let imgs = top.split_evenly((1, 4));
    let panels = bottom.split_evenly((1, 3));
    // Fig. 6: one ruler per scheme, rendered (Gaussian of 8 nm per
    // localisation, 4 nm pixels), and its cross-section along the axis.
    let ruler = 0;
    let c = r.rulers[ruler][1];
    let half = 150.0;
    let px = 4.0;
    let n = (2.0 * half / px) as usize;
    let axis = {
        let a = r.rulers[ruler][0];
        let b = r.rulers[ruler][2];
        let l = ((b.x_nm - a.x_nm).powi(2) + (b.y_nm - a.y_nm).powi(2)).sqrt();
        ((b.x_nm - a.x_nm) / l, (b.y_nm - a.y_nm) / l)
    };
    let mut sections = Vec::new();
    for (s, area) in imgs.iter().enumerate() {
        let locs: Vec<TLoc> = r.schemes[s]
            .kept_locs
            .iter()
            .filter(|(ru, _)| *ru == ruler)
            .map(|x| x.1)
            .collect();
        let mut img = vec![0f64; n * n];
        let sg = 8.0;
        for l in &locs {
            for j in 0..n {
                let y = c.y_nm - half + (j as f64 + 0.5) * px;
                for i in 0..n {
                    let x = c.x_nm - half + (i as f64 + 0.5) * px;
                    let d2 = (x - l.x_nm).powi(2) + (y - l.y_nm).powi(2);
                    if d2 < 16.0 * sg * sg {
                        img[j * n + i] += (-d2 / (2.0 * sg * sg)).exp();
                    }
                }
            }
        }
        let max = img.iter().cloned().fold(0.0, f64::max).max(1e-9);
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{} — ruler {ruler} ({} locs)", SCHEMES[s], locs.len()),
                ("sans-serif", 18),
            )
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(-half..half, half..-half)
            .map_err(|e| plot_err(path, e))?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc("x − centre (nm)")
            .y_desc("y − centre (nm)")
            .draw()
            .map_err(|e| plot_err(path, e))?;
        chart
            .draw_series((0..n * n).map(|k| {
                let (i, j) = (k % n, k / n);
                let v = (img[k] / max).sqrt();
                let g = (255.0 * v) as u8;
                let x0 = -half + i as f64 * px;
                let y0 = -half + j as f64 * px;
                Rectangle::new(
                    [(x0, y0), (x0 + px, y0 + px)],
                    RGBColor(g, g, (g as f64 * 0.6) as u8).filled(),
                )
            }))
            .map_err(|e| plot_err(path, e))?;
        for t in &r.rulers[ruler] {
            chart
                .draw_series(std::iter::once(Cross::new(
                    (t.x_nm - c.x_nm, t.y_nm - c.y_nm),
                    5,
                    RED.stroke_width(1),
                )))
                .map_err(|e| plot_err(path, e))?;
        }
        // Cross-section: localisations within 40 nm of the axis, 5 nm bins.
        let bins = 60;
        let mut h = vec![0f64; bins];
        for l in &locs {
            let (dx, dy) = (l.x_nm - c.x_nm, l.y_nm - c.y_nm);
            let along = dx * axis.0 + dy * axis.1;
            let perp = -dx * axis.1 + dy * axis.0;
            if perp.abs() <= 40.0 && along.abs() < half {
                let b = ((along + half) / (2.0 * half) * bins as f64) as usize;
                h[b.min(bins - 1)] += 1.0;
            }
        }
        let tot: f64 = h.iter().sum::<f64>().max(1.0);
        sections.push(
            h.iter()
                .enumerate()
                .map(|(b, v)| (-half + (b as f64 + 0.5) * 2.0 * half / bins as f64, v / tot))
                .collect::<Vec<_>>(),
        );
    }
    let ymax = sections
        .iter()
        .flatten()
        .map(|p| p.1)
        .fold(0.0, f64::max)
        .max(0.01)
        * 1.15;
    let mut chart = ChartBuilder::on(&panels[0])
        .caption(
            "Cross-section of ruler 0 along its axis",
            ("sans-serif", 18),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(-half..half, 0.0..ymax)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("position along the ruler (nm)")
        .y_desc("fraction of localisations / 5 nm")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (s, sec) in sections.iter().enumerate() {
        let col = colour(s);
        chart
            .draw_series(LineSeries::new(sec.clone(), col.stroke_width(2)))
            .map_err(|e| plot_err(path, e))?
            .label(SCHEMES[s])
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], col.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    // Fig. 7 left: spread per marker.
    let smax = r
        .markers
        .iter()
        .map(|m| m.spread_nm)
        .fold(0.0, f64::max)
        .max(1.0)
        * 1.15;
    let nm = r.rulers.len() * 3;
    let mut chart = ChartBuilder::on(&panels[1])
        .caption("Localisation spread per marker", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(-0.5..(nm as f64 - 0.5), 0.0..smax)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_desc("marker (ruler × 3 + marker)")
        .y_desc("spread σ per axis (nm)")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    for (s, name) in SCHEMES.iter().enumerate() {
        let col = colour(s);
        chart
            .draw_series(r.markers.iter().filter(|m| m.scheme == s).map(|m| {
                Circle::new(
                    ((m.ruler * 3 + m.marker) as f64, m.spread_nm),
                    5,
                    col.filled(),
                )
            }))
            .map_err(|e| plot_err(path, e))?
            .label(*name)
            .legend(move |(x, y)| Circle::new((x + 10, y), 5, col.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| plot_err(path, e))?;
    // Fig. 7 right: box plot of neighbour distances.
    let all: Vec<f64> = r
        .schemes
        .iter()
        .flat_map(|s| s.distances.iter().map(|d| d.1))
        .collect();
    let lo = all.iter().cloned().fold(70.0, f64::min) - 5.0;
    let hi = all.iter().cloned().fold(90.0, f64::max) + 5.0;
    let mut chart = ChartBuilder::on(&panels[2])
        .caption("Neighbour distances (all rulers)", ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(-0.5..3.5, lo..hi)
        .map_err(|e| plot_err(path, e))?;
    chart
        .configure_mesh()
        .x_labels(4)
        .x_label_formatter(&|x: &f64| {
            let i = x.round() as i64;
            ["EMCCD", "fixed", "smart", "smart r3"]
                .get(i as usize)
                .filter(|_| (x - i as f64).abs() < 0.01)
                .map_or(String::new(), |s| s.to_string())
        })
        .y_desc("distance (nm)")
        .draw()
        .map_err(|e| plot_err(path, e))?;
    chart
        .draw_series(std::iter::once(PathElement::new(
            vec![(-0.5, SPACING_NM), (3.5, SPACING_NM)],
            BLACK.stroke_width(1),
        )))
        .map_err(|e| plot_err(path, e))?;
    for (s, sr) in r.schemes.iter().enumerate() {
        let d: Vec<f64> = sr.distances.iter().map(|x| x.1).collect();
        let (Some(q1), Some(q2), Some(q3)) = (quantile(&d, 0.25), median(&d), quantile(&d, 0.75))
        else {
            continue;
        };
        let x = s as f64;
        let col = colour(s);
        let (mn, mx) = d.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, &v| {
            (a.0.min(v), a.1.max(v))
        });
        let el = [
            PathElement::new(vec![(x, mn), (x, q1)], col.stroke_width(2)),
            PathElement::new(vec![(x, q3), (x, mx)], col.stroke_width(2)),
            PathElement::new(vec![(x - 0.25, q2), (x + 0.25, q2)], col.stroke_width(3)),
            PathElement::new(
                vec![
                    (x - 0.25, q1),
                    (x + 0.25, q1),
                    (x + 0.25, q3),
                    (x - 0.25, q3),
                    (x - 0.25, q1),
                ],
                col.stroke_width(2),
            ),
        ];
        chart.draw_series(el).map_err(|e| plot_err(path, e))?;
        chart
            .draw_series(
                d.iter()
                    .map(|&v| Circle::new((x + 0.32, v), 3, col.filled())),
            )
            .map_err(|e| plot_err(path, e))?;
    }
    root.present().map_err(|e| plot_err(path, e))?;
    Ok(())
}
