//! The blinks of one work item and the seeds everything is drawn from.
//!
//! Every configuration of a work item sees the same blinks: the same start
//! and end times, and the same *relative* position `(u, v) ∈ [0, 1)²` in its
//! field less a margin of 3σ (as [`smartagg_scene::Scene::study`] does). For
//! the SPAD, EMCCD and sCMOS fields of the study (≈ 1.7 µm wide at 150×) this
//! is the same position in the sample to within 13 nm. The blinks are given
//! to the scene simulators as [`smartagg_scene::Blinking::Explicit`], so
//! the comparison of schemes and cameras is paired, blink by blink.
//!
//! The timeline follows the paper (and `Scene::study`): one molecule on at a
//! time, every blink of exactly the point's duration, separated by 10 ms plus
//! an exponential gap of mean 40 ms.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Shortest gap between blinks, s (as `Scene::study`).
pub const GAP_MIN_S: f64 = 0.010;
/// Mean of the exponential part of the gap, s (as `Scene::study`).
pub const GAP_MEAN_S: f64 = 0.040;
/// Recordings run at least this long after the last blink ends, s (the
/// pipeline needs about N/2 planes to close a track), rounded up to whole
/// 50 ms frames.
pub const TAIL_S: f64 = 0.030;
/// Frame period of the fixed SPAD frames and of the EMCCD/sCMOS, s.
pub const FRAME_S: f64 = 0.050;

/// SplitMix64 finaliser: a well-mixed 64-bit hash of a 64-bit value.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Combines seeds and keys into one seed (order matters).
pub fn derive_seed(parts: &[u64]) -> u64 {
    parts
        .iter()
        .fold(0x5EED_0F5A_u64, |acc, &p| mix64(acc ^ mix64(p)))
}

/// FNV-1a of a string, to turn configuration keys into seed parts.
pub fn key_hash(s: &str) -> u64 {
    s.bytes().fold(0xCBF2_9CE4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01B3)
    })
}

/// One blink of a work item.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthBlink {
    /// Relative horizontal position in the field less margins, [0, 1).
    pub u: f64,
    /// Relative vertical position, [0, 1).
    pub v: f64,
    /// Start, s.
    pub t_on_s: f64,
    /// End, s.
    pub t_off_s: f64,
}

/// The blinks of one work item and the length of its recordings.
#[derive(Debug, Clone, PartialEq)]
pub struct Timeline {
    /// Blinks in time order, never overlapping.
    pub blinks: Vec<TruthBlink>,
    /// Length of every recording of the item, s: a whole number of 50 ms frames.
    pub end_s: f64,
}

impl Timeline {
    /// One molecule at a time, `n` blinks of `duration_s`, gaps of
    /// 10 ms + Exp(40 ms) before each, drawn from `seed`.
    pub fn one_at_a_time(seed: u64, n: usize, duration_s: f64) -> Timeline {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut t = 0.0;
        let mut blinks = Vec::with_capacity(n);
        for _ in 0..n {
            let gap = GAP_MIN_S - GAP_MEAN_S * (1.0 - rng.gen::<f64>()).ln();
            let t_on = t + gap;
            let (u, v) = (rng.gen::<f64>(), rng.gen::<f64>());
            blinks.push(TruthBlink {
                u,
                v,
                t_on_s: t_on,
                t_off_s: t_on + duration_s,
            });
            t = t_on + duration_s;
        }
        let end_s = whole_frames(t + TAIL_S);
        Timeline { blinks, end_s }
    }

    /// `n` blinks each exactly filling one 50 ms frame, back to back (the
    /// hot-pixel study: "50 ms total exposure with the molecule on throughout").
    pub fn frame_aligned(seed: u64, n: usize) -> Timeline {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let blinks = (0..n)
            .map(|k| TruthBlink {
                u: rng.gen::<f64>(),
                v: rng.gen::<f64>(),
                t_on_s: k as f64 * FRAME_S,
                t_off_s: (k + 1) as f64 * FRAME_S,
            })
            .collect();
        Timeline {
            blinks,
            end_s: n as f64 * FRAME_S,
        }
    }
}

/// `t` rounded up to a whole number of 50 ms frames (at least one).
pub fn whole_frames(t: f64) -> f64 {
    ((t / FRAME_S).ceil().max(1.0)) * FRAME_S
}

/// A blink's place in one configuration's field.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BlinkNm {
    /// x, nm from the field's left edge.
    pub x_nm: f64,
    /// y, nm from the field's top edge.
    pub y_nm: f64,
    /// Start, s.
    pub t_on_s: f64,
    /// End, s.
    pub t_off_s: f64,
}

/// The blinks placed in a field of `field_nm` with margins `margin_nm`.
pub fn place(blinks: &[TruthBlink], field_nm: f64, margin_nm: f64) -> Vec<BlinkNm> {
    let span = field_nm - 2.0 * margin_nm;
    blinks
        .iter()
        .map(|b| BlinkNm {
            x_nm: margin_nm + b.u * span,
            y_nm: margin_nm + b.v * span,
            t_on_s: b.t_on_s,
            t_off_s: b.t_off_s,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_at_a_time_blinks_never_overlap_and_fit_the_recording() {
        let t = Timeline::one_at_a_time(7, 200, 0.03);
        assert_eq!(t.blinks.len(), 200);
        for w in t.blinks.windows(2) {
            assert!(w[1].t_on_s >= w[0].t_off_s + GAP_MIN_S - 1e-12);
        }
        let last = t.blinks.last().unwrap();
        assert!(t.end_s >= last.t_off_s + TAIL_S);
        assert!((t.end_s / FRAME_S - (t.end_s / FRAME_S).round()).abs() < 1e-9);
        // Mean gap 50 ms: 200 blinks of 30 ms take about 16 s.
        assert!((12.0..20.0).contains(&t.end_s), "{}", t.end_s);
        assert_eq!(t, Timeline::one_at_a_time(7, 200, 0.03));
        assert_ne!(t, Timeline::one_at_a_time(8, 200, 0.03));
    }

    #[test]
    fn seeds_depend_on_every_part() {
        let a = derive_seed(&[1, 2, 3]);
        assert_ne!(a, derive_seed(&[1, 2, 4]));
        assert_ne!(a, derive_seed(&[2, 1, 3]));
        assert_ne!(key_hash("spcimager-150x"), key_hash("spcimager-60x"));
    }
}
