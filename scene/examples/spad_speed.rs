//! Quick look at SPAD simulator speed: `cargo run --release -p smartagg-scene --example spad_speed [planes] [emitters per um^2]`.
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
    let dens: f64 = std::env::args()
        .nth(2)
        .and_then(|a| a.parse().ok())
        .unwrap_or(50.0);
    let mut sc = Scene::smlm(&p);
    sc.layout = smartagg_scene::Layout::Random {
        density_per_um2: dens,
    };
    let b = bench_spad(cam, &sc, planes, 1).unwrap();
    println!(
        "{} planes: {:.0} planes/s ({:.0} per CPU-s), {:.0} Mpixel/s, ones {:.4}, on {:.1}, setup {:.3}s",
        b.planes,
        b.planes_per_s(),
        b.planes_per_cpu_s().unwrap_or(f64::NAN),
        b.mpixel_per_s(),
        b.ones_fraction,
        b.mean_on,
        b.setup_seconds
    );
}
