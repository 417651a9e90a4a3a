//! Quick look at SPAD simulator speed: `cargo run --release -p smartagg-scene --example spad_speed [planes]`.
//! The figures users quote come from `smartagg bench simulate`.
use smartagg_model::params::{Camera, Preset, PresetName};
use smartagg_scene::bench::bench_spad;
use smartagg_scene::Scene;

fn main() {
    let planes: u64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20_000);
    let p = Preset::new(PresetName::Spcimager, 150).unwrap();
    let Camera::Spad(cam) = &p.camera else {
        unreachable!()
    };
    let b = bench_spad(cam, &Scene::smlm(&p), planes, 1).unwrap();
    println!(
        "{} planes: {:.0} planes/s, {:.0} Mpixel/s, ones {:.4}, on {:.1}, setup {:.3}s",
        b.planes,
        b.planes_per_s(),
        b.mpixel_per_s(),
        b.ones_fraction,
        b.mean_on,
        b.setup_seconds
    );
}
