//! Arbitrary (valid) parameters, including extreme rates, never panic and
//! never put a non-finite number or an impossible count into the output.

use proptest::prelude::*;
use smartagg_model::params::{spcimager, Optics, SceneLight, SpadCamera};
use smartagg_scene::{Blinking, ExplicitBlink, Layout, OnTime, Position, Scene, SpadSimulator};

fn log_uniform(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (0.0f64..=1.0).prop_map(move |u| {
        if u == 0.0 {
            0.0
        } else {
            lo * (hi / lo).powf(u)
        }
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    #[test]
    fn extreme_spad_scenes_stay_finite(
        w in 1u32..24,
        h in 1u32..24,
        flux in log_uniform(1.0, 1e9),
        bg in log_uniform(1e-3, 1e9),
        dcr in log_uniform(1e-300, 1e7),
        prnu in 0.0f64..1.0,
        drnu in 0.0f64..10.0,
        hot in 0.0f64..1.0,
        x in -5.0f64..30.0,
        y in -5.0f64..30.0,
        t_on in -1e-3f64..2e-3,
        len in 0.0f64..2e-3,
        independent: bool,
        seed: u64,
    ) {
        let cam = SpadCamera { dcr_median_hz: dcr, prnu, drnu, hot_pixel_fraction: hot, ..spcimager() };
        let optics = Optics::objective(150).unwrap();
        let p = optics.pixel_nm(cam.pixel_pitch_um);
        let blinking = if independent {
            Blinking::Independent { on: OnTime::Exponential { mean_s: 2e-4 }, mean_off_s: 3e-4 }
        } else {
            Blinking::Explicit(vec![ExplicitBlink {
                emitter: 0,
                position: Position { x_nm: x * p, y_nm: y * p },
                t_on_s: t_on,
                t_off_s: t_on + len,
                flux_factor: 1.0,
            }])
        };
        let scene = Scene {
            width: w,
            height: h,
            optics,
            light: SceneLight { flux_hz: flux, background_per_um2_hz: bg },
            layout: Layout::List(vec![Position { x_nm: x * p, y_nm: y * p }]),
            blinking,
            intensity_cv: 0.5,
            margin_px: 0.0,
        };
        let mut sim = SpadSimulator::new(&cam, &scene, seed).unwrap();
        let planes = 20u64;
        for _ in 0..planes {
            let plane = sim.next_plane();
            prop_assert_eq!(plane.width(), w as usize);
            prop_assert_eq!(plane.height(), h as usize);
        }
        prop_assert!(sim.background_rate_hz().iter().all(|r| r.is_finite() && *r >= 0.0));
        for b in sim.truth() {
            prop_assert!(b.on_exposed_s.is_finite() && b.on_exposed_s >= 0.0);
            prop_assert!(b.on_exposed_s <= planes as f64 * cam.exposure_s + 1e-12);
            prop_assert!(b.flux_hz.is_finite() && b.flux_hz >= 0.0);
            prop_assert!(b.photons_detected <= b.photons_emitted);
        }
    }
}
