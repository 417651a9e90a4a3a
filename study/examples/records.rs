use smartagg_study::timeline::*;
use smartagg_study::*;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let d: f64 = args[1].parse().unwrap();
    let n: usize = args[2].parse().unwrap();
    let setup = sim::Setup::new(smartagg_model::params::PresetName::Spcimager, 150).unwrap();
    let t = Timeline::one_at_a_time(5, n, d / 1000.0);
    let blinks = place(&t.blinks, setup.field_nm(), setup.margin_nm);
    let data = sim::record_spad(&setup, &blinks, t.end_s, 9, true, false, None).unwrap();
    println!("records {}", data.records.len());
    let mut hist = std::collections::BTreeMap::new();
    for r in &data.records {
        *hist
            .entry((r.t_drop - r.t_cross).min(200) / 10 * 10)
            .or_insert(0) += 1;
    }
    println!("live length hist (planes, /10): {:?}", hist);
    for (i, b) in blinks.iter().enumerate() {
        println!(
            "blink {i}: x {:.0} y {:.0} px ({:.1},{:.1}) on {:.4}-{:.4} (planes {:.0}-{:.0})",
            b.x_nm,
            b.y_nm,
            b.x_nm / setup.pixel_nm,
            b.y_nm / setup.pixel_nm,
            b.t_on_s,
            b.t_off_s,
            b.t_on_s / 1e-4,
            b.t_off_s / 1e-4
        );
        for r in &data.records {
            let first = r.t_drop + 1 - r.planes_summed as u64;
            let (f, l) = (first as f64 * 1e-4, (r.t_drop + 1) as f64 * 1e-4);
            if f < b.t_off_s && l > b.t_on_s {
                let dx = r.anchor_x as f64 + 0.5 - b.x_nm / setup.pixel_nm;
                let dy = r.anchor_y as f64 + 0.5 - b.y_nm / setup.pixel_nm;
                if dx.abs() < 5.0 && dy.abs() < 5.0 {
                    let data: Vec<f64> = r.counts.iter().map(|&c| c as f64).collect();
                    let roi = smartagg_localize::RoiView::new(9, &data, None).unwrap();
                    let fit = smartagg_localize::fit_roi(
                        smartagg_localize::Estimator::Mle,
                        &roi,
                        &frames::fit_options(
                            setup.sigma_px,
                            true,
                            smartagg_localize::NoiseModel::Poisson,
                        ),
                    );
                    let fitx = smartagg_localize::fit_roi(
                        smartagg_localize::Estimator::Mle,
                        &roi,
                        &frames::fit_options(
                            setup.sigma_px,
                            false,
                            smartagg_localize::NoiseModel::Poisson,
                        ),
                    );
                    let ex = (r.roi_x0() as f64 + fit.x) * setup.pixel_nm - b.x_nm;
                    let ey = (r.roi_y0() as f64 + fit.y) * setup.pixel_nm - b.y_nm;
                    let fx = (r.roi_x0() as f64 + fitx.x) * setup.pixel_nm - b.x_nm;
                    let fy = (r.roi_y0() as f64 + fitx.y) * setup.pixel_nm - b.y_nm;
                    println!("   err fitted-sigma ({ex:.1},{ey:.1}) |{:.1}| sigma {:.2} N {:.0} bg {:.1} {:?} ; fixed-sigma |{:.1}|", (ex*ex+ey*ey).sqrt(), fit.sigma, fit.photons, fit.background, fit.status, (fx*fx+fy*fy).sqrt());
                    println!(
                        "   rec anchor ({},{}) d=({:.1},{:.1}) cross {} drop {} summed {} flags {}",
                        r.anchor_x,
                        r.anchor_y,
                        dx,
                        dy,
                        r.t_cross,
                        r.t_drop,
                        r.planes_summed,
                        r.flags
                    );
                }
            }
        }
    }
}
