//! Speed of the SPAD simulator, measured (never asserted): used by
//! `smartagg bench simulate`.

use std::time::Instant;

use smartagg_model::params::SpadCamera;

use crate::scene::Scene;
use crate::spad::SpadSimulator;
use crate::SceneError;

/// Throughput of one run.
#[derive(Debug, Clone, PartialEq)]
pub struct SpadBench {
    /// Planes generated.
    pub planes: u64,
    /// Field width, pixels.
    pub width: u32,
    /// Field height, pixels.
    pub height: u32,
    /// Wall-clock seconds spent generating them (setup excluded).
    pub seconds: f64,
    /// CPU seconds this thread spent generating them, where the OS reports it
    /// (Linux): on a shared machine wall-clock figures understate the speed.
    pub cpu_seconds: Option<f64>,
    /// Fraction of pixel-planes that read 1.
    pub ones_fraction: f64,
    /// Mean number of blinks on per plane (truth).
    pub mean_on: f64,
    /// Seconds to build the simulator (maps, layout).
    pub setup_seconds: f64,
}

impl SpadBench {
    /// Bit-planes per second.
    pub fn planes_per_s(&self) -> f64 {
        self.planes as f64 / self.seconds
    }

    /// Bit-planes per second of this thread's CPU time, if known.
    pub fn planes_per_cpu_s(&self) -> Option<f64> {
        self.cpu_seconds.map(|c| self.planes as f64 / c.max(1e-9))
    }

    /// Million pixels per second.
    pub fn mpixel_per_s(&self) -> f64 {
        self.planes as f64 * self.width as f64 * self.height as f64 / self.seconds / 1e6
    }

    /// Bit-planes per second relative to the camera's own rate.
    pub fn realtime_factor(&self, camera: &SpadCamera) -> f64 {
        self.planes_per_s() * camera.plane_period_s
    }
}

/// CPU time of the calling thread, ns (Linux: first field of
/// `/proc/thread-self/schedstat`); `None` elsewhere.
pub fn thread_cpu_ns() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    s.split_whitespace().next()?.parse().ok()
}

/// Generates `planes` bit-planes of `scene` on one thread and times them.
pub fn bench_spad(
    camera: &SpadCamera,
    scene: &Scene,
    planes: u64,
    seed: u64,
) -> Result<SpadBench, SceneError> {
    let t = Instant::now();
    let mut sim = SpadSimulator::new(camera, scene, seed)?;
    let setup_seconds = t.elapsed().as_secs_f64();
    let n = scene.width as usize * scene.height as usize;
    let mut ones = 0u64;
    let cpu0 = thread_cpu_ns();
    let t = Instant::now();
    for _ in 0..planes {
        ones += sim.next_plane().count_ones() as u64;
    }
    let seconds = t.elapsed().as_secs_f64().max(1e-9);
    let cpu_seconds = match (cpu0, thread_cpu_ns()) {
        (Some(a), Some(b)) if b > a => Some((b - a) as f64 * 1e-9),
        _ => None,
    };
    let span = planes as f64 * camera.plane_period_s;
    let on_time: f64 = sim.truth().iter().map(|b| b.on_exposed_s).sum();
    Ok(SpadBench {
        planes,
        width: scene.width,
        height: scene.height,
        seconds,
        cpu_seconds,
        ones_fraction: ones as f64 / (planes as f64 * n as f64).max(1.0),
        mean_on: on_time / span.max(1e-300) * camera.plane_period_s / camera.exposure_s,
        setup_seconds,
    })
}
