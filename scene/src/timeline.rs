//! The blink timeline: which molecule is on when, generated lazily in time
//! order so a recording of any length streams in constant memory (apart from
//! the ground-truth rows).

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use crate::drift::DriftTrajectory;
use crate::sampling::{
    exponential, poisson, rng_stream, unit_gamma, STREAM_BLINKING, STREAM_LAYOUT,
};
use crate::scene::{Blinking, ExplicitBlink, Layout, OnTime, Position, Scene};
use crate::truth::BlinkTruth;

/// An emitter's next switch-on time, ordered by time then emitter.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Event {
    t: f64,
    emitter: u32,
}

impl Eq for Event {}

impl PartialOrd for Event {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Event {
    fn cmp(&self, other: &Self) -> Ordering {
        self.t
            .total_cmp(&other.t)
            .then(self.emitter.cmp(&other.emitter))
    }
}

#[derive(Debug)]
enum Mode {
    OneAtATime {
        on: OnTime,
        gap_min: f64,
        gap_mean: f64,
        next_on: f64,
        /// Fresh uniform position per blink (random layout) rather than a
        /// member of the population.
        fresh: bool,
    },
    Independent {
        on: OnTime,
        mean_off: f64,
        heap: BinaryHeap<Reverse<Event>>,
    },
    Explicit {
        list: Vec<ExplicitBlink>,
        next: usize,
    },
}

/// Blinks generated so far and the ones still open.
#[derive(Debug)]
pub(crate) struct Timeline {
    field_w_nm: f64,
    field_h_nm: f64,
    margin_nm: f64,
    population: Vec<Position>,
    mode: Mode,
    rng: ChaCha8Rng,
    flux_hz: f64,
    intensity_cv: f64,
    /// Every blink started so far (the ground truth).
    pub(crate) blinks: Vec<BlinkTruth>,
    /// Indices of blinks that may still overlap a future window, ascending.
    open: Vec<usize>,
    /// Stage drift the blinks are imaged with.
    drift: DriftTrajectory,
}

fn sample_duration(rng: &mut ChaCha8Rng, on: OnTime) -> f64 {
    match on {
        OnTime::Fixed { seconds } => seconds,
        OnTime::Exponential { mean_s } => exponential(rng, mean_s),
    }
}

impl Timeline {
    /// Builds the layout and the initial state. `pixel_nm` converts the
    /// field and margin from pixels to nm.
    pub(crate) fn new(scene: &Scene, pixel_nm: f64, seed: u64) -> Timeline {
        let field_w_nm = scene.width as f64 * pixel_nm;
        let field_h_nm = scene.height as f64 * pixel_nm;
        let margin_nm = scene.margin_px * pixel_nm;
        let mut lrng = rng_stream(seed, STREAM_LAYOUT);
        let area_um2 = field_w_nm * field_h_nm * 1e-6;
        let uniform = |r: &mut ChaCha8Rng| Position {
            x_nm: margin_nm + r.gen::<f64>() * (field_w_nm - 2.0 * margin_nm),
            y_nm: margin_nm + r.gen::<f64>() * (field_h_nm - 2.0 * margin_nm),
        };
        let one_at_a_time = matches!(scene.blinking, Blinking::OneAtATime { .. });
        let population: Vec<Position> = match &scene.layout {
            Layout::Random { density_per_um2 } => {
                if one_at_a_time {
                    Vec::new()
                } else {
                    let n = poisson(&mut lrng, density_per_um2 * area_um2);
                    (0..n).map(|_| uniform(&mut lrng)).collect()
                }
            }
            Layout::Nanorulers {
                rulers_per_um2,
                spacing_nm,
                markers,
            } => {
                let n = poisson(&mut lrng, rulers_per_um2 * area_um2);
                let mut v = Vec::with_capacity((n * *markers as u64) as usize);
                for _ in 0..n {
                    let c = uniform(&mut lrng);
                    let theta = lrng.gen::<f64>() * std::f64::consts::PI;
                    let (s, co) = theta.sin_cos();
                    for m in 0..*markers {
                        let off = (m as f64 - (*markers as f64 - 1.0) / 2.0) * spacing_nm;
                        v.push(Position {
                            x_nm: c.x_nm + off * co,
                            y_nm: c.y_nm + off * s,
                        });
                    }
                }
                v
            }
            Layout::List(v) => v.clone(),
        };
        let mut rng = rng_stream(seed, STREAM_BLINKING);
        let mut blinks = Vec::new();
        let mode = match &scene.blinking {
            Blinking::OneAtATime {
                on,
                gap_min_s,
                gap_mean_s,
            } => {
                let fresh = matches!(scene.layout, Layout::Random { .. });
                let next_on = if fresh || !population.is_empty() {
                    gap_min_s + exponential(&mut rng, *gap_mean_s)
                } else {
                    f64::INFINITY
                };
                Mode::OneAtATime {
                    on: *on,
                    gap_min: *gap_min_s,
                    gap_mean: *gap_mean_s,
                    next_on,
                    fresh,
                }
            }
            Blinking::Independent { on, mean_off_s } => {
                let mean_on = on.mean_s();
                let p_on = mean_on / (mean_on + mean_off_s);
                let mut heap = BinaryHeap::with_capacity(population.len());
                let mut initial = Vec::new();
                for (e, pos) in population.iter().enumerate() {
                    let next = if rng.gen::<f64>() < p_on {
                        // Stationary renewal state: age and residual of the
                        // current blink (memoryless for exponential times,
                        // uniform split for a fixed duration).
                        let (age, residual) = match *on {
                            OnTime::Fixed { seconds } => {
                                let a = rng.gen::<f64>() * seconds;
                                (a, seconds - a)
                            }
                            OnTime::Exponential { mean_s } => {
                                (exponential(&mut rng, mean_s), exponential(&mut rng, mean_s))
                            }
                        };
                        let flux = scene.light.flux_hz * unit_gamma(&mut rng, scene.intensity_cv);
                        initial.push((-age, residual, e, *pos, flux));
                        residual + exponential(&mut rng, *mean_off_s)
                    } else {
                        exponential(&mut rng, *mean_off_s)
                    };
                    heap.push(Reverse(Event {
                        t: next,
                        emitter: e as u32,
                    }));
                }
                initial.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
                for (t_on, t_off, e, pos, flux) in initial {
                    blinks.push(BlinkTruth {
                        blink: blinks.len() as u64,
                        emitter: e as u64,
                        x_nm: pos.x_nm,
                        y_nm: pos.y_nm,
                        t_on_s: t_on,
                        t_off_s: t_off,
                        flux_hz: flux,
                        on_exposed_s: 0.0,
                        photons_emitted: 0,
                        photons_detected: 0,
                        drift_x_nm: 0.0,
                        drift_y_nm: 0.0,
                    });
                }
                Mode::Independent {
                    on: *on,
                    mean_off: *mean_off_s,
                    heap,
                }
            }
            Blinking::Explicit(list) => {
                let mut list = list.clone();
                list.sort_by(|a, b| a.t_on_s.total_cmp(&b.t_on_s));
                Mode::Explicit { list, next: 0 }
            }
        };
        let open = (0..blinks.len()).collect();
        Timeline {
            field_w_nm,
            field_h_nm,
            margin_nm,
            population,
            mode,
            rng,
            flux_hz: scene.light.flux_hz,
            intensity_cv: scene.intensity_cv,
            blinks,
            open,
            drift: DriftTrajectory::none(),
        }
    }

    /// The emitters of the layout (empty for one-at-a-time random positions
    /// and explicit blinks); emitter `e` of the truth is `population[e]`.
    pub(crate) fn population(&self) -> &[Position] {
        &self.population
    }

    /// Images every blink, past and future, with `drift` (blinks already
    /// generated are updated).
    pub(crate) fn set_drift(&mut self, drift: DriftTrajectory) {
        for b in &mut self.blinks {
            (b.drift_x_nm, b.drift_y_nm) = drift.at_blink(b.t_on_s, b.t_off_s);
        }
        self.drift = drift;
    }

    fn push_blink(&mut self, emitter: u64, pos: Position, t_on: f64, t_off: f64, flux: f64) {
        let (drift_x_nm, drift_y_nm) = self.drift.at_blink(t_on, t_off);
        self.open.push(self.blinks.len());
        self.blinks.push(BlinkTruth {
            blink: self.blinks.len() as u64,
            emitter,
            x_nm: pos.x_nm,
            y_nm: pos.y_nm,
            t_on_s: t_on,
            t_off_s: t_off,
            flux_hz: flux,
            on_exposed_s: 0.0,
            photons_emitted: 0,
            photons_detected: 0,
            drift_x_nm,
            drift_y_nm,
        });
    }

    /// Generates every blink starting before `t1`, drops blinks that ended by
    /// `t0`, and returns the indices (ascending) of those that may overlap
    /// `[t0, t1)`. Windows must not go back in time.
    pub(crate) fn open_blinks(&mut self, t0: f64, t1: f64) -> &[usize] {
        loop {
            match &mut self.mode {
                Mode::OneAtATime {
                    on,
                    gap_min,
                    gap_mean,
                    next_on,
                    fresh,
                } => {
                    if *next_on >= t1 {
                        break;
                    }
                    let (on, gap_min, gap_mean, t_on, fresh) =
                        (*on, *gap_min, *gap_mean, *next_on, *fresh);
                    let (emitter, pos) = if fresh {
                        let pos = Position {
                            x_nm: self.margin_nm
                                + self.rng.gen::<f64>() * (self.field_w_nm - 2.0 * self.margin_nm),
                            y_nm: self.margin_nm
                                + self.rng.gen::<f64>() * (self.field_h_nm - 2.0 * self.margin_nm),
                        };
                        (self.blinks.len() as u64, pos)
                    } else {
                        let e = self.rng.gen_range(0..self.population.len());
                        (e as u64, self.population[e])
                    };
                    let d = sample_duration(&mut self.rng, on);
                    let flux = self.flux_hz * unit_gamma(&mut self.rng, self.intensity_cv);
                    let gap = gap_min + exponential(&mut self.rng, gap_mean);
                    if let Mode::OneAtATime { next_on, .. } = &mut self.mode {
                        *next_on = t_on + d + gap;
                    }
                    self.push_blink(emitter, pos, t_on, t_on + d, flux);
                }
                Mode::Independent { on, mean_off, heap } => {
                    let Some(&Reverse(ev)) = heap.peek() else {
                        break;
                    };
                    if ev.t >= t1 {
                        break;
                    }
                    heap.pop();
                    let (on, mean_off) = (*on, *mean_off);
                    let d = sample_duration(&mut self.rng, on);
                    let flux = self.flux_hz * unit_gamma(&mut self.rng, self.intensity_cv);
                    let next = ev.t + d + exponential(&mut self.rng, mean_off);
                    if let Mode::Independent { heap, .. } = &mut self.mode {
                        heap.push(Reverse(Event {
                            t: next,
                            emitter: ev.emitter,
                        }));
                    }
                    let pos = self.population[ev.emitter as usize];
                    self.push_blink(ev.emitter as u64, pos, ev.t, ev.t + d, flux);
                }
                Mode::Explicit { list, next } => {
                    if *next >= list.len() || list[*next].t_on_s >= t1 {
                        break;
                    }
                    let b = list[*next];
                    *next += 1;
                    let flux = self.flux_hz * b.flux_factor;
                    self.push_blink(b.emitter, b.position, b.t_on_s, b.t_off_s, flux);
                }
            }
        }
        let blinks = &self.blinks;
        self.open.retain(|&i| blinks[i].t_off_s > t0);
        &self.open
    }
}
