//! The demo's gateware leg: the pipeline generated for the demo's field,
//! verilated, on the first planes of the recording, every packet checked
//! against the golden model.

use anyhow::Context;
use smartagg_scene::scene::Scene;
use smartagg_scene::spad::SpadSimulator;
use std::time::Instant;

/// What the gateware leg measured.
pub(super) struct GatewareLeg {
    /// Bit-planes co-simulated.
    pub(super) planes: usize,
    /// Bit-planes of the recording.
    pub(super) of: u64,
    /// Packets compared.
    pub(super) packets: u64,
    /// Clocks from START to the stream's end, per plane.
    pub(super) clocks_per_plane: f64,
    /// Simulated clock cycles per second, millions.
    pub(super) mcycles_per_s: f64,
    /// Verilating and compiling (or loading the cached build), s.
    pub(super) build_s: f64,
}

/// What the gateware leg needs, owned: it runs on its own thread.
pub(super) struct GatewareJob {
    pub(super) field: usize,
    pub(super) seed: u64,
    /// Bit-planes to co-simulate (the first of the recording).
    pub(super) planes: u64,
    /// Bit-planes of the recording.
    pub(super) recording_planes: u64,
    pub(super) cfg: smartagg_model::config::PipelineConfig,
    pub(super) scene: Scene,
    pub(super) cam: smartagg_model::params::SpadCamera,
}

/// Streams the first `planes` planes of the recording (the same seed gives
/// the same planes) through the gateware generated for this scene, checking
/// every packet against the golden model on those planes.
pub(super) fn gateware_leg(job: GatewareJob) -> anyhow::Result<GatewareLeg> {
    let GatewareJob {
        field,
        seed,
        planes,
        recording_planes,
        cfg,
        scene,
        cam,
    } = job;
    use smartagg_sim::designs::{DesignSpec, DEMO};
    use smartagg_sim::harness::{Case, Cosim};
    let t = Instant::now();
    anyhow::ensure!(
        (field, field) == DEMO,
        "the demo's gateware is generated for {}x{} pixels, not {field}x{field}",
        DEMO.0,
        DEMO.1
    );
    let spec = DesignSpec::demo()
        .and_then(|s| s.with_r_assoc(cfg.r_assoc))
        .context("the demo's gateware")?;
    let mut cosim = Cosim::new(spec).context("building the demo's gateware")?;
    let build_s = t.elapsed().as_secs_f64();
    let n = usize::try_from(planes)?;
    let mut sim = SpadSimulator::new(&cam, &scene, seed)?;
    let case = Case {
        seed,
        threshold_hold: Some(cfg.threshold_hold),
        end_trim: cfg.end_trim,
        ..Case::replay(
            cfg.n_window,
            cfg.threshold_int,
            cfg.l_min,
            cfg.l_max,
            (0..n).map(|_| sim.next_plane()).collect(),
        )
    };
    // The gateware's generation parameters must be the demo's.
    let g = cosim.model_config(&case)?;
    anyhow::ensure!(
        (&g.kernel, g.kernel_shift, g.slots, g.roi_size, g.r_assoc)
            == (&cfg.kernel, cfg.kernel_shift, cfg.slots, cfg.roi_size, cfg.r_assoc),
        "the generated gateware (kernel {:?} >> {}, {} slots, ROI {}, r_assoc {}) is not the demo's pipeline (kernel {:?} >> {}, {} slots, ROI {}, r_assoc {})",
        g.kernel, g.kernel_shift, g.slots, g.roi_size, g.r_assoc,
        cfg.kernel, cfg.kernel_shift, cfg.slots, cfg.roi_size, cfg.r_assoc
    );
    match cosim.check(&case)? {
        Ok(cov) => Ok(GatewareLeg {
            planes: n,
            of: recording_planes,
            packets: cov.packets,
            clocks_per_plane: cov.clocks_per_plane(),
            mcycles_per_s: cov.mcycles_per_second(),
            build_s,
        }),
        Err(m) => anyhow::bail!("the gateware differs from the golden model: {m}"),
    }
}

impl GatewareLeg {
    /// "all 400000 bit-planes" or "the first 1500 of 400000 bit-planes".
    pub(super) fn which_planes(&self) -> String {
        if self.planes as u64 == self.of {
            format!("all {} bit-planes", self.planes)
        } else {
            format!("the first {} of {} bit-planes", self.planes, self.of)
        }
    }
}
