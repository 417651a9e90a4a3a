//! Exchange formats and the frame pipeline: ThunderSTORM CSV, merging,
//! rendering to PNG, ROI export, detection in frames (TIFF stacks are
//! `smartagg-io`'s, tested there).

use rand::SeedableRng;
use smartagg_localize::export::{roi_pages, RoiLayout, RoiPage};
use smartagg_localize::frames::{localize_frame, Conversion, FramePipeline};
use smartagg_localize::merge::merge_consecutive;
use smartagg_localize::render::{render, Point, RenderOptions};
use smartagg_localize::table::{CsvTable, LocTable, Localization};
use smartagg_localize::{synth, Estimator, FitOptions, FitStatus, SigmaMode};

fn loc(frame: u64, x: f64, y: f64, u: f64) -> Localization {
    Localization {
        frame,
        x_nm: x,
        y_nm: y,
        sigma_nm: 80.0,
        intensity: 100.0,
        offset: 5.0,
        bkgstd: 2.0,
        uncertainty_nm: u,
        status: FitStatus::Ok,
        detections: 1,
        extra: vec![],
    }
}

#[test]
fn csv_header_is_thunderstorm_exactly() {
    let t = LocTable {
        extra_columns: vec![],
        merged: false,
        rows: vec![loc(3, 1234.5, 987.25, 12.0)],
    };
    let mut buf = Vec::new();
    t.write_csv(&mut buf).unwrap();
    let text = String::from_utf8(buf).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        r#""id","frame","x [nm]","y [nm]","sigma [nm]","intensity [photon]","offset [photon]","bkgstd [photon]","uncertainty [nm]","fit_status""#
    );
    assert_eq!(lines.next().unwrap(), "1,3,1234.5,987.25,80,100,5,2,12,0");
    // Merged tables add ThunderSTORM's detections column, then the extras.
    let t = LocTable {
        extra_columns: vec!["t_start [plane]".into()],
        merged: true,
        rows: vec![Localization {
            detections: 3,
            extra: vec![42.0],
            ..loc(1, 1.0, 2.0, 3.0)
        }],
    };
    let mut buf = Vec::new();
    t.write_csv(&mut buf).unwrap();
    let text = String::from_utf8(buf).unwrap();
    assert!(text.starts_with(r#""id","frame","x [nm]","y [nm]","sigma [nm]","intensity [photon]","offset [photon]","bkgstd [photon]","uncertainty [nm]","fit_status","detections","t_start [plane]""#));
    assert!(text.lines().nth(1).unwrap().ends_with(",0,3,42"));
    // Reading back.
    let back = CsvTable::read(text.as_bytes()).unwrap();
    assert_eq!(back.column(&["x [nm]"]), Some(2));
    assert_eq!(back.rows[0][back.column(&["detections"]).unwrap()], 3.0);
}

#[test]
fn csv_errors_name_the_line() {
    let e = CsvTable::read("\"id\",\"x [nm]\"\n1,2\n2,abc\n".as_bytes())
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 3") && e.contains("abc"), "{e}");
    let e = CsvTable::read("a,b\n1,2,3\n".as_bytes())
        .unwrap_err()
        .to_string();
    assert!(e.contains("line 2"), "{e}");
    assert!(CsvTable::read("".as_bytes()).is_err());
    // ThunderSTORM 1.3 names the uncertainty column differently.
    let t = CsvTable::read(
        "\"id\",\"x [nm]\",\"y [nm]\",\"uncertainty_xy [nm]\"\n1,5,6,7\n".as_bytes(),
    )
    .unwrap();
    assert_eq!(
        t.column(&["uncertainty [nm]", "uncertainty_xy [nm]"]),
        Some(3)
    );
}

#[test]
fn merging_consecutive_frames_within_40_nm() {
    let mut failed = loc(2, 1010.0, 1000.0, 10.0);
    failed.status = FitStatus::NotConverged;
    let locs = vec![
        loc(1, 1000.0, 1000.0, 10.0),
        loc(2, 1020.0, 1005.0, 20.0),
        loc(3, 1010.0, 990.0, 10.0),
        loc(2, 2000.0, 2000.0, 15.0), // another molecule
        loc(4, 1060.0, 990.0, 10.0),  // 50 nm from frame 3's: new track
        loc(6, 1010.0, 990.0, 10.0),  // after a gap: new track
        failed,                       // never merged
    ];
    let (out, stats) = merge_consecutive(&locs, 40.0, 0);
    assert_eq!(stats.input, 7);
    assert_eq!(stats.output, 5);
    assert_eq!(stats.merged_tracks, 1);
    assert_eq!(stats.passed_failed, 1);
    let m = out
        .iter()
        .find(|l| l.detections == 3)
        .expect("a 3-detection track");
    assert_eq!(m.frame, 1);
    // Inverse-variance weights 1/100, 1/400, 1/100.
    let w = [0.01, 0.0025, 0.01];
    let sw: f64 = w.iter().sum();
    assert!((m.x_nm - (1000.0 * w[0] + 1020.0 * w[1] + 1010.0 * w[2]) / sw).abs() < 1e-9);
    assert!((m.uncertainty_nm - (1.0 / sw).sqrt()).abs() < 1e-9);
    assert_eq!(m.intensity, 300.0);
    assert!(out.iter().any(|l| l.status == FitStatus::NotConverged));
    // Allowing two missing frames, frame 6 continues the frame-1–3 track
    // (the frame-4 localisation is 50 nm away from both).
    let (out, stats) = merge_consecutive(&locs, 40.0, 2);
    assert_eq!(stats.merged_tracks, 1);
    assert!(out.iter().any(|l| l.detections == 4));
}

#[test]
fn rendering_a_tiny_table() {
    let pts = [
        Point {
            x_nm: 200.0,
            y_nm: 150.0,
            sigma_nm: 8.0,
        },
        Point {
            x_nm: 280.0,
            y_nm: 150.0,
            sigma_nm: 8.0,
        },
    ];
    let o = RenderOptions::covering(&pts, 5.0, 2.0).unwrap();
    let (img, skipped) = render(&pts, &o).unwrap();
    assert_eq!(skipped, 0);
    let at = |x: f64, y: f64| {
        img.at(
            ((x - img.origin_x_nm) / img.pixel_nm) as usize,
            ((y - img.origin_y_nm) / img.pixel_nm) as usize,
        )
    };
    // Peak of a normalised Gaussian of σ = 1.6 px: ≈ 1/(2π·1.6²) per pixel.
    assert!(at(200.0, 150.0) > 0.04, "{}", at(200.0, 150.0));
    assert!(
        at(240.0, 150.0) < 1e-6,
        "between the two: {}",
        at(240.0, 150.0)
    );
    // Too large an image is refused with a clear error.
    let far = [
        pts[0],
        Point {
            x_nm: 1e9,
            ..pts[0]
        },
    ];
    assert!(RenderOptions::covering(&far, 1.0, 2.0).is_err());
}

#[test]
fn roi_export_layouts() {
    let a: Vec<u32> = (1..=9).collect();
    let b: Vec<u32> = (1..=25).collect();
    let rois = [
        RoiPage {
            x0: -1,
            y0: 2,
            side: 3,
            counts: &a,
        },
        RoiPage {
            x0: 5,
            y0: 5,
            side: 5,
            counts: &b,
        },
    ];
    let (w, h, pages) = roi_pages(&rois, RoiLayout::Compact);
    assert_eq!((w, h), (5, 5));
    assert_eq!(pages[0][5..8], [4, 5, 6]);
    assert_eq!(pages[0][3], 0);
    let (w, h, pages) = roi_pages(
        &rois,
        RoiLayout::Sensor {
            width: 8,
            height: 8,
        },
    );
    assert_eq!((w, h), (8, 8));
    // Column −1 is off the sensor: counts 1, 4, 7 dropped.
    assert_eq!(pages[0][2 * 8], 2);
    assert_eq!(pages[1][5 * 8 + 5], 1);
    assert_eq!(pages[1][7 * 8 + 7], 13);
}

#[test]
fn frame_pipeline_finds_and_fits_molecules() {
    let (w, h) = (48, 40);
    let truth = [
        (10.3, 12.7, 1500.0),
        (30.8, 9.4, 1500.0),
        (25.5, 30.2, 1500.0),
    ];
    let mu = synth::expected_frame(w, h, &truth, 1.4, 10.0);
    let mut rng = rand::rngs::StdRng::seed_from_u64(9);
    // In ADU: offset 100, 2 e⁻ per ADU.
    let raw: Vec<f64> = mu
        .iter()
        .map(|&m| synth::poisson(&mut rng, m) / 2.0 + 100.0)
        .collect();
    let p = FramePipeline {
        conversion: Conversion {
            offset_adu: 100.0,
            e_per_adu: 2.0,
            em_gain: 1.0,
        },
        roi_side: 9,
        threshold_factor: 1.5,
        estimator: Estimator::Mle,
        fit: FitOptions::new(SigmaMode::Fitted { initial: 1.3 }),
        pixel_nm: 100.0,
        read_var: None,
        hot: None,
        spad_planes: None,
    };
    let r = localize_frame(&p, &raw, w, h, 1).unwrap();
    let ok: Vec<_> = r
        .localizations
        .iter()
        .filter(|l| l.status.is_ok())
        .collect();
    for &(x, y, _) in &truth {
        let best = ok
            .iter()
            .map(|l| ((l.x_nm - x * 100.0).powi(2) + (l.y_nm - y * 100.0).powi(2)).sqrt())
            .fold(f64::INFINITY, f64::min);
        assert!(
            best < 15.0,
            "molecule at ({x}, {y}) missed: nearest {best} nm"
        );
    }
    // Few false positives on a flat background.
    assert!(ok.len() <= 6, "{} localisations", ok.len());
    for l in &ok {
        assert!(l.intensity > 0.0 && l.uncertainty_nm > 0.0);
    }
    // A frame smaller than the ROI is fitted with a smaller ROI; one under
    // 3x3 pixels, the smallest ROI, is refused with a clear error.
    assert!(localize_frame(&p, &raw[..64], 8, 8, 1).is_ok());
    let e = localize_frame(&p, &raw[..4], 2, 2, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("frame 2x2 is smaller than 3x3"), "{e}");
}
