//! Shared helpers of the block tests: random planes, words of P pixels.
#![allow(dead_code)]

pub mod records;
pub mod walk;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use smartagg_model::plane::BitPlane;

/// A seeded generator.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// A slot command's one-hot slot of `m` (past M included, up to M + 1),
/// or, one time in ten, any 32 bits.
pub fn slot_bits(rng: &mut ChaCha8Rng, m: usize) -> u64 {
    if rng.gen_bool(0.1) {
        rng.gen::<u32>() as u64
    } else {
        1 << rng.gen_range(0..32.min(m + 2))
    }
}

/// Random planes with a bright blob so that counts and candidates vary.
pub fn random_planes(
    rng: &mut ChaCha8Rng,
    w: usize,
    h: usize,
    n: usize,
    p_one: f64,
) -> Vec<BitPlane> {
    let (cx, cy) = (rng.gen_range(0..w) as f64, rng.gen_range(0..h) as f64);
    (0..n)
        .map(|_| {
            BitPlane::from_fn(w, h, |x, y| {
                let d2 = (x as f64 - cx).powi(2) + (y as f64 - cy).powi(2);
                let p = p_one + 0.6 * (-d2 / 4.0).exp();
                rng.gen_bool(p.min(1.0))
            })
        })
        .collect()
}
