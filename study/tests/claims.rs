//! The paper's claims (§4.2, Fig. 4 and Fig. 8), checked on `--quick`
//! configurations with 200 blinks per point — enough for ratio intervals of
//! about ±10 %. Where a claim does not hold, the test asserts what does,
//! and says why (the same explanation is in every summary's notes).
//!
//! All runs use the study defaults: smart aggregation is the field design
//! of each 32x32 study field, as `smartagg aggregate` defaults to (open
//! threshold for 1 false blink/s over the field, Eq. 7's threshold to hold,
//! r_assoc = round(2σ), L_min 1, end_trim ⌊N/2⌋), σ fitted,
//! ThunderSTORM-like frame detection at 1.5 std.

use smartagg_study::spec::{LMin, Plan, StudyName, StudyOptions};
use smartagg_study::stats::{summarise, Estimate, Summary};
use smartagg_study::{run, Shard};

const BLINKS: u32 = 200;

fn study(name: StudyName, points: Option<Vec<f64>>) -> (Plan, Summary) {
    let plan = Plan::new(
        name,
        StudyOptions {
            blinks_per_point: BLINKS,
            quick: true,
            points,
            ..Default::default()
        },
    )
    .unwrap();
    let items = run::run(&plan, Shard::ALL, &|_, _| {}).unwrap();
    let s = summarise(&plan, &items);
    (plan, s)
}

fn ratio<'a>(plan: &Plan, s: &'a Summary, label: &str, x: f64) -> &'a Estimate {
    let r = plan
        .ratios
        .iter()
        .position(|r| r.label == label)
        .unwrap_or_else(|| panic!("no ratio {label}"));
    let p = s.points.iter().find(|p| p.x == x).expect("point");
    &p.ratios[r]
}

fn scheme<'a>(
    plan: &Plan,
    s: &'a Summary,
    id: &str,
    x: f64,
) -> &'a smartagg_study::stats::SchemeStats {
    let i = plan.scheme(id).unwrap_or_else(|| panic!("no scheme {id}"));
    &s.points.iter().find(|p| p.x == x).expect("point").schemes[i]
}

fn lo(e: &Estimate) -> f64 {
    e.lo.expect("interval")
}
fn hi(e: &Estimate) -> f64 {
    e.hi.expect("interval")
}
fn val(e: &Estimate) -> f64 {
    e.value.expect("value")
}

#[test]
fn smart_vs_fixed_spcimager() {
    assert_eq!(StudyOptions::default().l_min, LMin::Design);
    let (plan, s) = study(StudyName::SmartVsFixed, None);
    // Smart aggregation beats fixed 500-plane frames for long blinks, with a
    // lower 95 % bound above the 1.3 at 100 ms...
    let r100 = ratio(&plan, &s, "fixed / smart", 100.0);
    assert!(lo(r100) > 1.25, "fixed/smart at 100 ms: {r100:?}");
    // ...but not by the paper's factor of about 2, and at 50 ms not by 1.3:
    // the frame detector (1.5 std of the first wavelet level) rejects the
    // faint partial-frame images that made fixed aggregation poor in the
    // paper, so fixed frames instead *miss* blinks, and the ones they keep
    // are well localised.
    let r50 = ratio(&plan, &s, "fixed / smart", 50.0);
    assert!(
        val(r50) > 1.0 && val(r50) < 1.3,
        "fixed/smart at 50 ms: {r50:?}"
    );
    // The field design (r_assoc = 2σ, tracks held at Eq. 7's threshold)
    // gives one record per blink.
    let s100 = scheme(&plan, &s, "spcimager-150x/smart", 100.0);
    assert!(
        (s100.matches as f64 / s100.detected as f64) < 1.1,
        "{s100:?}"
    );
    // Where smart aggregation wins without doubt is detection of short blinks.
    let f20 = scheme(&plan, &s, "spcimager-150x/fixed", 20.0);
    let s20 = scheme(&plan, &s, "spcimager-150x/smart", 20.0);
    assert!(f20.detection_rate() < 0.2, "{f20:?}");
    assert!(s20.detection_rate() > 0.9, "{s20:?}");
    // The paper's literal scheme (one threshold, L_min = 1, r_assoc = 1)
    // lets ~500 false blinks/s through in a 32x32 field; those whose ROI
    // holds the molecule add poor localisations, and its blinks split.
    let p = ratio(&plan, &s, "smart paper / smart", 100.0);
    assert!(lo(p) > 1.2, "{p:?}");
    assert!(scheme(&plan, &s, "spcimager-150x/smart-paper", 50.0).false_pos_rate() > 0.8);
    assert!(scheme(&plan, &s, "spcimager-150x/smart", 50.0).false_pos_rate() < 0.1);
    // Beyond the paper: within 1.3x of the Cramér–Rao bound for >= 50 ms, and
    // the SPAD binomial MLE equals the Poisson MLE here (no pile-up at the
    // SPCIMAGER's rates).
    for x in [50.0, 100.0] {
        let c = ratio(&plan, &s, "smart / CRLB", x);
        assert!(val(c) > 1.0 && val(c) < 1.3, "{x}: {c:?}");
        let m = ratio(&plan, &s, "smart / smart SPAD MLE", x);
        assert!((0.95..1.05).contains(&val(m)), "{x}: {m:?}");
    }
}

#[test]
fn projected_spad_roughly_halves_the_error() {
    let (plan, s) = study(StudyName::FutureSpad, None);
    let label = "current / projected (smart)";
    // About 2x or more at every duration, as the paper says.
    for x in [20.0, 50.0, 100.0] {
        let r = ratio(&plan, &s, label, x);
        assert!(lo(r) > 1.6, "{x}: {r:?}");
        assert!((1.8..3.0).contains(&val(r)), "{x}: {r:?}");
    }
    // The projected SPAD's short window (N = 18) no longer splits its blinks:
    // one record per blink, close to its Cramér–Rao bound at 100 ms.
    let p = scheme(&plan, &s, "projected-150x/smart", 100.0);
    assert!((p.matches as f64 / p.detected as f64) < 1.1, "{p:?}");
    let bound = scheme(&plan, &s, "projected-150x/smart-crlb", 100.0);
    assert!(val(&p.rms) < 1.2 * val(&bound.rms), "{p:?} vs {bound:?}");
    // Fixed frames improve too, less.
    assert!(lo(ratio(&plan, &s, "current / projected (fixed)", 100.0)) > 1.2);
}

#[test]
fn projected_spad_against_emccd_and_scmos() {
    let (plan, s) = study(StudyName::Cameras, None);
    for x in [20.0, 50.0, 100.0] {
        // Better than the EMCCD's unmerged 50 ms frames at every duration...
        let e = ratio(&plan, &s, "EMCCD / projected smart", x);
        assert!(lo(e) > 1.0, "{x}: {e:?}");
        // ...and comparable to its merged frames.
        let em = ratio(&plan, &s, "EMCCD merged / projected smart", x);
        assert!((0.8..1.4).contains(&val(em)), "{x}: {em:?}");
        // The sCMOS's merged frames are at least as good: its 80 % QE
        // collects ~3x the photons of the projected SPAD's 35 % PDE x 78 %
        // fill.
        let sm = ratio(&plan, &s, "sCMOS merged / projected smart", x);
        assert!(val(sm) < 1.0, "{x}: {sm:?}");
    }
    let sm = ratio(&plan, &s, "sCMOS merged / projected smart", 50.0);
    assert!(hi(sm) < 0.8, "{sm:?}");
}

#[test]
fn sixty_x_helps_the_current_spad_only() {
    let (plan, s) = study(StudyName::Objective, Some(vec![50.0, 100.0]));
    for x in [50.0, 100.0] {
        // Paper: about 20 % better at 60x for the current SPAD (DCR matters)...
        let c = ratio(&plan, &s, "SPCIMAGER 150x / 60x", x);
        assert!(val(c) > 1.0, "{x}: {c:?}");
        // ...and no gain for the projected one (background dominates).
        let p = ratio(&plan, &s, "projected 150x / 60x", x);
        assert!(val(p) < 1.1, "{x}: {p:?}");
    }
    let c = ratio(&plan, &s, "SPCIMAGER 150x / 60x", 50.0);
    assert!(lo(c) > 1.05, "{c:?}");
}

#[test]
fn few_hot_pixels_barely_matter_and_ignoring_beats_interpolating() {
    let (plan, s) = study(StudyName::HotPixels, None);
    for obj in ["150x", "60x"] {
        for x in [5.0, 10.0] {
            let r = ratio(&plan, &s, &format!("{obj} ignore / 0 % hot"), x);
            assert!(val(r) < 1.2, "{obj} {x}: {r:?}");
        }
        // 20 % does matter.
        let r = ratio(&plan, &s, &format!("{obj} ignore / 0 % hot"), 20.0);
        assert!(lo(r) > 1.05, "{obj}: {r:?}");
    }
    for x in [5.0, 10.0, 20.0] {
        // At 60x (sigma 0.6 px) interpolating a hot pixel under the PSF is
        // clearly worse than leaving it out...
        let r = ratio(&plan, &s, "60x interpolate / ignore", x);
        assert!(lo(r) > 1.0, "{x}: {r:?}");
        // ...at 150x (sigma 1.5 px) the 4-neighbour mean is a good estimate
        // of the missing pixel and the two are indistinguishable.
        let r = ratio(&plan, &s, "150x interpolate / ignore", x);
        assert!((0.95..1.05).contains(&val(r)), "{x}: {r:?}");
    }
}

#[test]
fn every_localiser_on_the_same_rois() {
    let (plan, s) = study(StudyName::Localizers, Some(vec![50.0]));
    let r = |e: &str| val(ratio(&plan, &s, &format!("{e} / CRLB"), 50.0));
    // Nothing beats the bound; the MLEs come within 30 % of it; the centroid
    // (biased to the ROI centre by the background) is far off.
    for e in [
        "lsq",
        "mle",
        "mle-fixed-sigma",
        "spad-mle",
        "spad-mle-fixed-sigma",
    ] {
        assert!(r(e) > 1.0 && r(e) < 1.35, "{e}: {}", r(e));
    }
    assert!(r("centroid") > 1.6, "{}", r("centroid"));
    // Fixing sigma helps a little, never hurts.
    assert!(r("mle-fixed-sigma") <= r("mle") * 1.01);
    // Every estimator saw the same ROIs: same detections.
    let d: Vec<u64> = plan
        .schemes
        .iter()
        .filter(|sc| !sc.method.is_reference())
        .map(|sc| scheme(&plan, &s, &sc.id, 50.0).detections)
        .collect();
    assert!(d.windows(2).all(|w| w[0] == w[1]), "{d:?}");
}
