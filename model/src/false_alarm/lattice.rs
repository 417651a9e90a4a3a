//! The exact lattice method: the law of a sum of scaled binomials carried
//! on `[0, T_int)`, convolved class after class, the mass that reaches
//! `T_int` added straight to the tail.

use super::binomial::Terms;
use super::{EXACT_MAX_STATES, EXACT_WORK_BUDGET, FIRST_PASS_CUTOFF, LATTICE_BLOCK, TERM_FLOOR};

/// A group of Bernoulli trials with a common weight and probability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Class {
    pub(super) weight: u64,
    pub(super) trials: u64,
    pub(super) p: f64,
}

pub(super) struct Lattice {
    /// `P(X = h)` for `h < T`.
    pub(super) below: Vec<f64>,
    /// `P(X ≥ T)`.
    pub(super) tail: f64,
    /// Mass skipped in the convolution (bound on the error of `tail`).
    pub(super) truncated: f64,
}

pub(super) struct Prepared {
    classes: Vec<(u64, Terms)>,
    threshold: u64,
    /// Largest value X can take.
    pub(super) max: u64,
}

impl Prepared {
    pub(super) fn new(classes: &[Class], threshold: u64) -> Prepared {
        let mut v: Vec<(u64, Terms)> = classes
            .iter()
            .filter(|c| c.weight > 0 && c.trials > 0 && c.p > 0.0)
            .map(|c| (c.weight, Terms::new(c.trials, c.p)))
            .collect();
        v.sort_by_key(|(w, _)| *w);
        let max = classes
            .iter()
            .filter(|c| c.p > 0.0)
            .map(|c| c.weight.saturating_mul(c.trials))
            .fold(0u64, |a, b| a.saturating_add(b));
        Prepared {
            classes: v,
            threshold,
            max,
        }
    }

    /// Upper bound on the multiply-adds of the convolution.
    fn work(&self) -> f64 {
        let t = self.threshold;
        let terms: f64 = self
            .classes
            .iter()
            .map(|(w, terms)| {
                let (lo, hi) = terms.significant(FIRST_PASS_CUTOFF);
                let below_t = (t.saturating_sub(1) / w + 1).saturating_sub(terms.first + lo as u64);
                (hi - lo + 1).min(below_t as usize) as f64
            })
            .sum();
        terms * t as f64
    }

    pub(super) fn exact_feasible(&self) -> bool {
        self.threshold <= EXACT_MAX_STATES && self.work() <= EXACT_WORK_BUDGET
    }

    pub(super) fn run(&self, cutoff: f64) -> Lattice {
        let t = self.threshold as usize;
        if t == 0 {
            return Lattice {
                below: Vec::new(),
                tail: 1.0,
                truncated: 0.0,
            };
        }
        let mut cur = vec![0.0f64; t];
        let mut next = vec![0.0f64; t];
        let mut taps: Vec<(usize, f64, usize)> = Vec::new();
        cur[0] = 1.0;
        let mut hi = 0usize; // highest index that may hold mass
        let mut tail = 0.0;
        let mut truncated = 0.0;
        for (w, terms) in &self.classes {
            let w = *w;
            let last_j = terms.first + terms.pmf.len() as u64 - 1;
            // Mass that this class carries to ≥ T.
            let reach = last_j.saturating_mul(w);
            let h_from = (t as u64).saturating_sub(reach) as usize;
            for (h, &m) in cur.iter().enumerate().take(hi + 1).skip(h_from) {
                if m != 0.0 {
                    let jmin = ((t - h) as u64).div_ceil(w);
                    tail += m * terms.sf(jmin);
                }
            }
            // Mass that stays below T.
            let (lo_i, hi_i) = terms.significant(cutoff);
            truncated += terms.pmf[..lo_i].iter().sum::<f64>()
                + terms.suffix.get(hi_i + 1).copied().unwrap_or(0.0);
            // The class's terms that land below T: (offset, probability,
            // length of the run of `cur` they move).
            taps.clear();
            for i in lo_i..=hi_i {
                let j = terms.first + i as u64;
                let off = match j.checked_mul(w) {
                    Some(o) if o < t as u64 => o as usize,
                    _ => break,
                };
                taps.push((off, terms.pmf[i], (hi + 1).min(t - off)));
            }
            // Never below `hi` (a class whose terms all reach T leaves no
            // mass below it, and cells up to `hi` must still be zeroed).
            let new_hi = taps
                .iter()
                .map(|&(off, _, len)| off + len - 1)
                .fold(hi, usize::max);
            // Cells above `hi` hold nothing: `next` held two classes ago's
            // lattice, whose mass lay at or below today's `hi`.
            next[..=new_hi].fill(0.0);
            // `next[off + h] += cur[h]·c` for every tap, a block of `next`
            // at a time so that it stays in the L1 cache while every tap
            // adds to it (a tap at a time, `next` went to memory and back
            // once per term). Each cell still adds the taps in their order:
            // the sums are the same to the bit.
            for b0 in (0..=new_hi).step_by(LATTICE_BLOCK) {
                let b1 = (b0 + LATTICE_BLOCK).min(new_hi + 1);
                for &(off, c, len) in &taps {
                    let (s, e) = (b0.max(off), b1.min(off + len));
                    if s < e {
                        for (d, x) in next[s..e].iter_mut().zip(&cur[s - off..e - off]) {
                            *d += x * c;
                        }
                    }
                }
            }
            hi = new_hi;
            std::mem::swap(&mut cur, &mut next);
        }
        Lattice {
            below: cur,
            tail,
            truncated,
        }
    }

    /// The exact lattice with the adaptive cut-off of the module docs.
    pub(super) fn exact(&self) -> Lattice {
        let first = self.run(FIRST_PASS_CUTOFF);
        if first.truncated <= 1e-10 * first.tail || first.truncated == 0.0 {
            return first;
        }
        let cutoff = (1e-13 * first.tail).max(TERM_FLOOR);
        self.run(cutoff)
    }
}

/// The classes of H summed over `planes` background-only planes.
pub(super) fn background_classes(pixels: &[(u64, u64)], planes: u64, p: f64) -> Vec<Class> {
    pixels
        .iter()
        .map(|&(w, c)| Class {
            weight: w,
            trials: c * planes,
            p,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::pixel_classes;
    use super::*;

    /// [`Prepared::run`]'s lattice below T, convolved one term at a time
    /// over the whole lattice (the order of the sums before it was blocked).
    fn lattice_term_by_term(prepared: &Prepared, cutoff: f64) -> Vec<f64> {
        let t = prepared.threshold as usize;
        let (mut cur, mut hi) = (vec![0.0f64; t], 0usize);
        cur[0] = 1.0;
        for (w, terms) in &prepared.classes {
            let (lo_i, hi_i) = terms.significant(cutoff);
            let mut next = vec![0.0f64; t];
            let mut new_hi = 0;
            for i in lo_i..=hi_i {
                let off = (terms.first + i as u64) * w;
                if off >= t as u64 {
                    break;
                }
                let (off, c) = (off as usize, terms.pmf[i]);
                let len = (hi + 1).min(t - off);
                for (d, s) in next[off..off + len].iter_mut().zip(&cur[..len]) {
                    *d += s * c;
                }
                new_hi = new_hi.max(off + len - 1);
            }
            (cur, hi) = (next, new_hi);
        }
        cur
    }

    #[test]
    fn the_blocked_lattice_sums_in_the_same_order() {
        let kernel = crate::kernel::IntegerKernel::gaussian(1.3, 9, 8).unwrap();
        let pixels = pixel_classes(&kernel).unwrap();
        for (planes, p, threshold) in [(109, 0.0117, 175_760), (1, 0.3, 9_000), (30, 0.05, 60_000)]
        {
            let prepared = Prepared::new(&background_classes(&pixels, planes, p), threshold);
            for cutoff in [FIRST_PASS_CUTOFF, 1e-200] {
                let blocked = prepared.run(cutoff).below;
                let reference = lattice_term_by_term(&prepared, cutoff);
                assert!(reference.len() > 4 * LATTICE_BLOCK);
                assert!(reference.iter().filter(|&&m| m > 0.0).count() > LATTICE_BLOCK);
                let same = blocked
                    .iter()
                    .zip(&reference)
                    .all(|(a, b)| a.to_bits() == b.to_bits());
                assert!(
                    same && blocked.len() == reference.len(),
                    "{planes} planes, p {p}"
                );
            }
        }
    }

    #[test]
    fn a_class_beyond_the_threshold_leaves_no_mass_below_it() {
        // The second class's every significant term reaches T: all mass goes
        // to the tail, and the lattice below T is zero for good.
        let classes = [
            Class {
                weight: 1,
                trials: 3_000,
                p: 0.5,
            },
            Class {
                weight: 1_000,
                trials: 40,
                p: 0.999,
            },
            Class {
                weight: 1_001,
                trials: 1,
                p: 0.01,
            },
        ];
        let prepared = Prepared::new(&classes, 1_800);
        let lattice = prepared.run(FIRST_PASS_CUTOFF);
        assert!(lattice.below.iter().all(|&m| m == 0.0));
        assert!((lattice.tail - 1.0).abs() < 1e-9, "{}", lattice.tail);
        let reference = lattice_term_by_term(&prepared, FIRST_PASS_CUTOFF);
        assert!(reference.iter().all(|&m| m == 0.0));
    }
}
