//! Stage 4 — candidates: above-threshold pixels that are maxima of their 3×3
//! neighbourhood.
//!
//! Tie rule (decided as pixels stream in raster order, so that two candidates
//! are never 3×3 neighbours): a pixel must be strictly greater than its four
//! *earlier* neighbours in raster order — (x−1,y−1), (x,y−1), (x+1,y−1),
//! (x−1,y) — and greater than or equal to its four *later* ones — (x+1,y),
//! (x−1,y+1), (x,y+1), (x+1,y+1). Neighbours outside the sensor are ignored
//! (equivalently H = 0 there, which an above-threshold pixel always beats).
//!
//! A connected plateau of equal values can yield more than one candidate
//! (never two neighbours): on a 3×2 sensor with rows `0 0 5` and `5 5 0`,
//! (2,0) and (0,1) each beat their earlier neighbours (all 0) and tie their
//! later neighbour (1,1) = 5, which loses to its earlier neighbour (2,0); so
//! both are candidates although the three 5s are connected. A 2×2 plateau
//! yields its first pixel in raster order.

/// A candidate pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Candidate {
    /// Column.
    pub x: u16,
    /// Row.
    pub y: u16,
}

/// Candidates of one plane, in raster order.
pub fn find(filtered: &[u32], width: usize, height: usize, threshold_int: u32) -> Vec<Candidate> {
    let at = |x: i64, y: i64| -> Option<u32> {
        (x >= 0 && y >= 0 && x < width as i64 && y < height as i64)
            .then(|| filtered[y as usize * width + x as usize])
    };
    let mut out = Vec::new();
    for y in 0..height as i64 {
        for x in 0..width as i64 {
            let h = filtered[y as usize * width + x as usize];
            if h < threshold_int {
                continue;
            }
            let earlier = [(-1, -1), (0, -1), (1, -1), (-1, 0)];
            let later = [(1, 0), (-1, 1), (0, 1), (1, 1)];
            let beats_earlier = earlier
                .iter()
                .all(|&(dx, dy)| at(x + dx, y + dy).is_none_or(|n| h > n));
            let holds_later = later
                .iter()
                .all(|&(dx, dy)| at(x + dx, y + dy).is_none_or(|n| h >= n));
            if beats_earlier && holds_later {
                out.push(Candidate {
                    x: x as u16,
                    y: y as u16,
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn single_peak_and_plateau() {
        #[rustfmt::skip]
        let h = [
            0, 1, 0, 0,
            1, 5, 1, 0,
            0, 1, 0, 7,
        ];
        assert_eq!(
            find(&h, 4, 3, 2),
            vec![Candidate { x: 1, y: 1 }, Candidate { x: 3, y: 2 }]
        );
        // A 2x2 plateau gives exactly its first pixel in raster order.
        let p = [0, 0, 0, 0, 3, 3, 0, 3, 3];
        assert_eq!(find(&p, 3, 3, 1), vec![Candidate { x: 1, y: 1 }]);
        // Below threshold: nothing.
        assert!(find(&p, 3, 3, 4).is_empty());
    }

    /// The tie rule does not make a plateau yield one candidate: this
    /// connected plateau of three 5s yields two, (2,0) and (0,1), which are
    /// not neighbours (the claim the module docs make instead).
    #[test]
    fn a_connected_plateau_can_yield_two_candidates() {
        #[rustfmt::skip]
        let h = [
            0, 0, 5,
            5, 5, 0,
        ];
        assert_eq!(
            find(&h, 3, 2, 1),
            vec![Candidate { x: 2, y: 0 }, Candidate { x: 0, y: 1 }]
        );
    }

    proptest! {
        /// Every candidate is a 3x3 maximum above threshold, and no two
        /// candidates are 3x3 neighbours (a plateau may still yield several,
        /// see `a_connected_plateau_can_yield_two_candidates`).
        #[test]
        fn candidates_are_maxima_and_never_neighbours(w in 1usize..9, h in 1usize..9, vals in proptest::collection::vec(0u32..4, 81)) {
            let img: Vec<u32> = vals[..w * h].to_vec();
            let c = find(&img, w, h, 1);
            for a in &c {
                let v = img[a.y as usize * w + a.x as usize];
                prop_assert!(v >= 1);
                for dy in -1i64..=1 { for dx in -1i64..=1 {
                    let (x, y) = (a.x as i64 + dx, a.y as i64 + dy);
                    if x >= 0 && y >= 0 && x < w as i64 && y < h as i64 {
                        prop_assert!(img[y as usize * w + x as usize] <= v);
                    }
                }}
                for b in &c {
                    if a != b {
                        prop_assert!((a.x as i64 - b.x as i64).abs() > 1 || (a.y as i64 - b.y as i64).abs() > 1);
                    }
                }
            }
        }
    }
}
