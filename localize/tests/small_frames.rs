//! Frames of any size (issue #37): a frame smaller than the fitting ROI is
//! fitted with the largest ROI that fits, spots on an edge or in a corner
//! are fitted from the pixels that exist, frames too small for any fit are
//! refused with an error, and a seeded stack of 9 × 9 frames is found and
//! fitted near the Cramér–Rao bound.

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use smartagg_io::stack::Frame;
use smartagg_localize::frames::{
    localize_batch, localize_frame, Conversion, FramePipeline, MIN_SIDE,
};
use smartagg_localize::stackbench::{score_stack, simulate_stack, StackScenario};
use smartagg_localize::synth::{expected_frame, poisson};
use smartagg_localize::{Estimator, FitOptions, LocalizeError, SigmaMode};

const PIXEL_NM: f64 = 100.0;

fn pipeline(roi: usize) -> FramePipeline {
    FramePipeline {
        conversion: Conversion::IDENTITY,
        roi_side: roi,
        threshold_factor: 1.5,
        estimator: Estimator::Mle,
        fit: FitOptions::new(SigmaMode::Fitted { initial: 1.5 }),
        pixel_nm: PIXEL_NM,
        read_var: None,
        hot: None,
        spad_planes: None,
    }
}

fn frame(rng: &mut StdRng, w: usize, h: usize, x: f64, y: f64, photons: f64) -> Vec<f64> {
    expected_frame(w, h, &[(x, y, photons)], 1.5, 5.9)
        .into_iter()
        .map(|m| poisson(rng, m))
        .collect()
}

#[test]
fn a_frame_smaller_than_the_roi_gets_the_largest_roi_that_fits() {
    let p = pipeline(11);
    assert_eq!(p.roi_for(9, 9), 9);
    assert_eq!(p.roi_for(8, 30), 7);
    assert_eq!(p.roi_for(64, 64), 11);
    assert_eq!(p.roi_for(3, 3), 3);
    let mut rng = StdRng::seed_from_u64(5);
    let img = frame(&mut rng, 9, 9, 4.3, 4.8, 1000.0);
    let r = localize_frame(&p, &img, 9, 9, 1).expect("a 9x9 frame is accepted");
    assert_eq!(r.localizations.len(), 1);
    let l = &r.localizations[0];
    assert!(l.status.is_ok(), "{:?}", l.status);
    let (dx, dy) = (l.x_nm / PIXEL_NM - 4.3, l.y_nm / PIXEL_NM - 4.8);
    let sd = l.uncertainty_nm / PIXEL_NM;
    assert!(dx.abs() < 5.0 * sd && dy.abs() < 5.0 * sd, "{dx} {dy} {sd}");
}

#[test]
fn frames_too_small_for_a_fit_are_refused_without_panic() {
    let p = pipeline(11);
    for (w, h) in [(1, 1), (2, 2), (2, 9), (9, 1)] {
        let img = vec![7.0; w * h];
        match localize_frame(&p, &img, w, h, 1) {
            Err(LocalizeError::FrameTooSmall { side, .. }) => assert_eq!(side, MIN_SIDE),
            other => panic!("{w}x{h}: {other:?}"),
        }
    }
    // 3x3 is the smallest frame: a spot there gives finite values or nothing.
    let mut rng = StdRng::seed_from_u64(2);
    let img = frame(&mut rng, 3, 3, 1.5, 1.5, 500.0);
    let r = localize_frame(&p, &img, 3, 3, 1).expect("3x3 is accepted");
    for l in &r.localizations {
        for v in [l.x_nm, l.y_nm, l.sigma_nm, l.intensity, l.uncertainty_nm] {
            assert!(v.is_finite());
        }
    }
}

/// Spots 1 px from an edge and in the corners of 16 × 16 frames (ROI 7):
/// every one is detected and fitted from the pixels inside the frame, the
/// errors within 4 reported standard deviations (the Cramér–Rao bound of
/// the fitted model) and their RMS near that bound.
#[test]
fn spots_on_edges_and_in_corners_are_fitted() {
    let p = pipeline(7);
    let (w, h) = (16, 16);
    let mut rng = StdRng::seed_from_u64(37);
    let (mut z2, mut n) = (0.0, 0usize);
    for case in 0..6 {
        for _ in 0..25 {
            let u = rng.gen_range(0.8..1.2);
            let v = rng.gen_range(4.0..12.0);
            let (x, y) = match case {
                0 => (u, v),                                   // left edge
                1 => (w as f64 - u, v),                        // right edge
                2 => (v, u),                                   // top edge
                3 => (v, h as f64 - u),                        // bottom edge
                4 => (u + 0.2, u + 0.2),                       // top-left corner
                _ => (w as f64 - u - 0.2, h as f64 - u - 0.2), // bottom-right
            };
            let img = frame(&mut rng, w, h, x, y, 1000.0);
            let r = localize_frame(&p, &img, w, h, 1).unwrap();
            let best = r
                .localizations
                .iter()
                .filter(|l| l.status.is_ok())
                .min_by(|a, b| {
                    let d = |l: &&smartagg_localize::Localization| {
                        (l.x_nm / PIXEL_NM - x).hypot(l.y_nm / PIXEL_NM - y)
                    };
                    d(a).total_cmp(&d(b))
                })
                .unwrap_or_else(|| panic!("case {case}: spot at ({x:.2}, {y:.2}) dropped"));
            let sd = best.uncertainty_nm / PIXEL_NM;
            let (dx, dy) = (best.x_nm / PIXEL_NM - x, best.y_nm / PIXEL_NM - y);
            assert!(
                dx.abs() < 4.0 * sd && dy.abs() < 4.0 * sd,
                "case {case}: ({x:.2}, {y:.2}) error ({dx:.3}, {dy:.3}), sd {sd:.3}"
            );
            z2 += (dx * dx + dy * dy) / (2.0 * sd * sd);
            n += 1;
        }
    }
    let z = (z2 / n as f64).sqrt();
    assert!(z > 0.7 && z < 1.3, "RMS error / bound {z}");
}

/// Issue #37's stack, small and seeded: one spot per 9 × 9 frame within
/// ±1.5 px of the centre, the default ROI (11) adapted to the frame.
#[test]
fn a_stack_of_small_frames_is_found_near_the_bound() {
    let sc = StackScenario::issue37(600, 11);
    let (pages, truth) = simulate_stack(&sc);
    let frames: Vec<(u64, Frame)> = pages
        .into_iter()
        .enumerate()
        .map(|(i, p)| {
            (
                i as u64 + 1,
                Frame {
                    width: 9,
                    height: 9,
                    data: p.into_iter().map(f64::from).collect(),
                },
            )
        })
        .collect();
    let mut rows = Vec::new();
    let cands = localize_batch(&pipeline(11), &frames, &mut rows).unwrap();
    assert_eq!(cands, rows.len());
    let s = score_stack(&rows, &truth, 9, 9, PIXEL_NM, 2.0);
    assert!(s.recall() > 0.97, "found {} of {}", s.found, s.spots);
    assert!(s.spurious < 6, "{} spurious", s.spurious);
    // 600 spots: the ratio's own scatter is about 3 %.
    assert!(s.ratio() < 1.12, "RMSE/CRLB {}", s.ratio());
}

/// The TIFF reader's seekable buffer returns what the file holds after any
/// mix of seeks (inside and outside its buffer) and reads.
#[test]
fn the_seekable_buffer_reads_what_the_file_holds() {
    use smartagg_io::stack::SeekBufReader;
    use std::io::{Cursor, Read, Seek, SeekFrom};
    let data: Vec<u8> = (0..700_000u64).map(|i| (i * 7919 % 251) as u8).collect();
    let mut r = SeekBufReader::new(Cursor::new(data.clone()));
    let mut rng = StdRng::seed_from_u64(9);
    let mut here = 0u64;
    for _ in 0..2000 {
        match rng.gen_range(0..4) {
            0 => here = r.seek(SeekFrom::Start(rng.gen_range(0..700_000))).unwrap(),
            1 => {
                let d = rng.gen_range(-5000i64..5000).max(-(here as i64));
                here = r.seek(SeekFrom::Current(d)).unwrap();
            }
            _ => {
                let n = if rng.gen_bool(0.01) {
                    300_000
                } else {
                    rng.gen_range(0..600)
                };
                let mut buf = vec![0u8; n];
                let got = r.read(&mut buf).unwrap();
                // A seek may go past the end (as with a file): reads give 0.
                let start = (here as usize).min(data.len());
                let end = (start + got).min(data.len());
                assert_eq!(&buf[..got], &data[start..end]);
                assert!(got > 0 || n == 0 || here as usize >= data.len());
                here += got as u64;
            }
        }
        assert_eq!(r.stream_position().unwrap(), here);
    }
    assert!(r.seek(SeekFrom::Current(-(here as i64) - 1)).is_err());
}
