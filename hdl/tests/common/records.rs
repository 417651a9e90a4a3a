//! Random records of every kind, valid for the model's encoder, for the
//! packetiser's tests.

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use smartagg_model::record::{BlinkRecord, DroppedRecord, StreamEnd, MAX_PLANE};

/// A random Blink of side `r`: counts of one of several shapes (flat, PSF
/// bump, sparse, huge with escapes), anywhere on the sensor.
pub fn random_blink(rng: &mut ChaCha8Rng, r: usize) -> BlinkRecord {
    let n = r * r;
    let shape = rng.gen_range(0..5);
    let base: u32 = match shape {
        3 => rng.gen_range(0..u32::MAX / 2),
        _ => rng.gen_range(0..20),
    };
    let mut counts: Vec<u32> = (0..n)
        .map(|i| match shape {
            0 => base,
            1 => base + rng.gen_range(0..4) + if i == n / 2 { 60 } else { 0 },
            2 => {
                if rng.gen_bool(0.1) {
                    rng.gen_range(0..1000)
                } else {
                    0
                }
            }
            3 => {
                base + if rng.gen_bool(0.2) {
                    rng.gen_range(0..u32::MAX / 2)
                } else {
                    rng.gen_range(0..3)
                }
            }
            _ => rng.gen_range(0..200),
        })
        .collect();
    let (ax, ay) = (rng.gen_range(0..320u16), rng.gen_range(0..240u16));
    let h = (r / 2) as i64;
    for dy in 0..r {
        for dx in 0..r {
            let (x, y) = (ax as i64 - h + dx as i64, ay as i64 - h + dy as i64);
            if !(0..320).contains(&x) || !(0..240).contains(&y) {
                counts[dy * r + dx] = 0;
            }
        }
    }
    let t_cross = rng.gen_range(0..MAX_PLANE);
    BlinkRecord {
        slot: rng.gen_range(0..32),
        flags: rng.gen::<u8>() & 0x3F,
        anchor_x: ax,
        anchor_y: ay,
        t_cross,
        t_drop: rng.gen_range(t_cross..=MAX_PLANE),
        t_s: rng.gen_range(-(1i64 << 47)..(1i64 << 47)),
        t_e: rng.gen_range(-(1i64 << 47)..(1i64 << 47)),
        planes_summed: rng.gen(),
        roi_size: r as u8,
        counts,
    }
}

/// A random Dropped record.
pub fn random_dropped(rng: &mut ChaCha8Rng) -> DroppedRecord {
    DroppedRecord {
        plane: rng.gen_range(0..=MAX_PLANE),
        count: rng.gen(),
        first_x: rng.gen(),
        first_y: rng.gen(),
    }
}

/// A random StreamEnd.
pub fn random_end(rng: &mut ChaCha8Rng) -> StreamEnd {
    StreamEnd {
        planes: rng.gen(),
        blinks: rng.gen(),
        unconfirmed: rng.gen(),
        dropped_candidates: rng.gen(),
        bridged_dips: rng.gen(),
        cut_segments: rng.gen(),
    }
}
