//! Random bit-plane scenes for co-simulation: Poisson-like background,
//! blinking emitters with a Gaussian spot (some on the field's edges, some
//! with one-plane dips), hot pixels. Not a physical simulation (that is
//! `smartagg-scene`): a generator of the situations the pipeline must get
//! right, cheap enough for tens of thousands of planes.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_model::plane::BitPlane;

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// Field width, pixels.
    pub width: usize,
    /// Field height, pixels.
    pub height: usize,
    /// Bit-planes.
    pub planes: usize,
    /// Probability of a background count per pixel and plane.
    pub background: f64,
    /// Emitters.
    pub emitters: usize,
    /// Probability of a count at an on emitter's centre pixel per plane.
    pub peak: f64,
    /// Mean on time, planes.
    pub mean_on: f64,
    /// Mean off time, planes.
    pub mean_off: f64,
    /// Fraction of emitters placed within 2 pixels of an edge.
    pub edge_fraction: f64,
    /// Probability that an on emitter goes dark for exactly one plane.
    pub dip: f64,
    /// Hot pixels (counting at `hot_rate`).
    pub hot: Vec<(usize, usize)>,
    /// Count probability of a hot pixel per plane.
    pub hot_rate: f64,
}

impl SceneSpec {
    /// `smartagg cosim`'s scene (and the profile-guided builds' training):
    /// sparse blinks over a faint background on a `width`×`height` field,
    /// one emitter per 150 pixels, a fifth of them on the edges, one-plane
    /// dips; no hot pixels.
    pub fn sparse(width: usize, height: usize, planes: usize) -> SceneSpec {
        SceneSpec {
            width,
            height,
            planes,
            background: 0.001,
            emitters: (width * height / 150).max(4),
            peak: 0.4,
            mean_on: 12.0,
            mean_off: 60.0,
            edge_fraction: 0.2,
            dip: 0.05,
            hot: Vec::new(),
            hot_rate: 0.0,
        }
    }
}

/// The bit-planes of a scene.
pub fn generate(spec: &SceneSpec, seed: u64) -> Vec<BitPlane> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (w, h) = (spec.width, spec.height);
    struct Emitter {
        x: f64,
        y: f64,
        on: bool,
        left: u32,
    }
    let geometric = |rng: &mut ChaCha8Rng, mean: f64| -> u32 {
        let p = (1.0 / mean.max(1.0)).clamp(1e-6, 1.0);
        let u: f64 = rng.gen_range(f64::MIN_POSITIVE..1.0);
        (u.ln() / (-p).ln_1p()).floor().max(0.0) as u32 + 1
    };
    let mut em: Vec<Emitter> = (0..spec.emitters)
        .map(|_| {
            let (x, y) = if rng.gen_bool(spec.edge_fraction.clamp(0.0, 1.0)) {
                // On an edge: a column or row within two pixels of the border.
                let side = rng.gen_range(0..4);
                let d = rng.gen_range(0.0..2.0);
                match side {
                    0 => (d, rng.gen_range(0.0..h as f64)),
                    1 => (w as f64 - 1.0 - d, rng.gen_range(0.0..h as f64)),
                    2 => (rng.gen_range(0.0..w as f64), d),
                    _ => (rng.gen_range(0.0..w as f64), h as f64 - 1.0 - d),
                }
            } else {
                (rng.gen_range(0.0..w as f64), rng.gen_range(0.0..h as f64))
            };
            let on = rng.gen_bool(0.3);
            let left = geometric(&mut rng, if on { spec.mean_on } else { spec.mean_off });
            Emitter { x, y, on, left }
        })
        .collect();
    let mut planes = Vec::with_capacity(spec.planes);
    for _ in 0..spec.planes {
        let mut bits = vec![false; w * h];
        if spec.background > 0.0 {
            // Geometric skips between background counts: cheap at low rates.
            let p = spec.background.clamp(1e-9, 1.0);
            let mut i = 0usize;
            loop {
                let u: f64 = rng.gen_range(f64::MIN_POSITIVE..1.0);
                let skip = if p >= 1.0 {
                    0
                } else {
                    (u.ln() / (-p).ln_1p()).floor() as usize
                };
                i = i.saturating_add(skip);
                if i >= bits.len() {
                    break;
                }
                bits[i] = true;
                i += 1;
            }
        }
        for &(x, y) in &spec.hot {
            if x < w && y < h && rng.gen_bool(spec.hot_rate.clamp(0.0, 1.0)) {
                bits[y * w + x] = true;
            }
        }
        for e in &mut em {
            let dark = e.on && rng.gen_bool(spec.dip.clamp(0.0, 1.0));
            if e.on && !dark {
                let (cx, cy) = (e.x.round() as i64, e.y.round() as i64);
                for dy in -2i64..=2 {
                    for dx in -2i64..=2 {
                        let (x, y) = (cx + dx, cy + dy);
                        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                            continue;
                        }
                        let d2 = (x as f64 - e.x).powi(2) + (y as f64 - e.y).powi(2);
                        let p = spec.peak * (-d2 / 2.0).exp();
                        if rng.gen_bool(p.clamp(0.0, 1.0)) {
                            bits[y as usize * w + x as usize] = true;
                        }
                    }
                }
            }
            e.left -= 1;
            if e.left == 0 {
                e.on = !e.on;
                e.left = geometric(&mut rng, if e.on { spec.mean_on } else { spec.mean_off });
            }
        }
        planes.push(BitPlane::from_fn(w, h, |x, y| bits[y * w + x]));
    }
    planes
}
