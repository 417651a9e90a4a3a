//! Exact false-alarm statistics of the threshold, and the confirmation
//! length `L_min` (docs/DESIGN.md §4–5).
//!
//! The paper's 3σ rule treats H as Gaussian. With background only, H at a
//! pixel is `H = Σ_{mn} K_mn·S_mn` over the k×k neighbourhood, with
//! `S_mn ~ Binomial(N, p_off)` independent (N planes of independent
//! Bernoulli pixels) and `K` the integer kernel, so H is an integer in
//! units of `2^−(2a)`. Its upper tail is heavier than the Gaussian's; this
//! module computes it exactly.
//!
//! ## Exact tail: the lattice method ([`tail_probability`])
//!
//! Pixels with the same 2-D weight form a *class*; the sum of S over a class
//! of c pixels is `Binomial(c·N, p)`, so H is a sum of independent scaled
//! binomials `w_c·J_c`. The distribution of the partial sums is carried on
//! the integer lattice `[0, T_int)` only, convolving class after class (in
//! increasing weight). Weights are non-negative, so mass that reaches
//! `≥ T_int` never comes back: each class adds `Σ_h mass(h)·P(J_c ≥
//! ⌈(T_int−h)/w_c⌉)` straight to the tail (`P(J ≥ j)` summed from the top,
//! no cancellation). Every operation adds non-negative numbers, so the tail
//! is accurate to rounding even at 1e-30.
//!
//! Binomial terms are computed with Loader's saddle-point form (accurate
//! for any n) and recurrences outward from the mode, down to 1e-300. In the
//! convolution, the outermost terms whose combined mass on each side is
//! below a cut-off are skipped; the skipped mass bounds the error
//! ([`TailProbability::truncation_bound`]; the computed tail is low by at
//! most that much). The first pass skips up to 1e-30 per side per class; if
//! that is more than 1e-10 of the tail, it is repeated with a cut-off of
//! 1e-13 × tail (floored at 1e-300), so the tail is always good to ~1e-10
//! relative.
//!
//! The work is about `T_int × Σ_c (terms of class c)` multiply-adds. Above
//! [`EXACT_WORK_BUDGET`] (1e9, about a second) or [`EXACT_MAX_STATES`]
//! lattice states the tail falls back to the saddle-point approximation.
//!
//! ## Saddle point (Lugannani–Rice) fallback
//!
//! With the cumulant generating function
//! `K(s) = Σ_c n_c log(1 − p_c + p_c e^{s w_c})` (computed without overflow),
//! solve `K'(ŝ) = x̃` for `x̃ = T_int − δ/2` (δ = the lattice span, the gcd
//! of the weights: Daniels' second continuity correction), and
//! `P(H ≥ T_int) ≈ Q(r) + φ(r)(1/u − 1/r)` with
//! `r = sgn(ŝ)√(2(ŝx̃ − K(ŝ)))`, `u = (2/δ) sinh(ŝδ/2) √K''(ŝ)`.
//! Measured against the exact tail at thresholds giving tails from 1e-2 to
//! 1e-9 (`saddle_point_agrees_with_the_exact_tail` in `tests/statistics.rs`,
//! six kernels/windows including the SPCIMAGER 150× one): within 2.5 %
//! everywhere, within 1e-4 for the SPCIMAGER 150× case. For the presets
//! the exact method runs (T_int ≈ 1e5, tens of milliseconds).
//!
//! ## Confirmation length ([`false_blink_rate`], [`l_min_for_target`])
//!
//! A track stays on while H ≥ T_int, bridging single planes below; it ends
//! at `t_drop`, the first of two consecutive planes below, and its on-length
//! is `t_drop − t_cross`. A background-only excursion *starts* at plane t
//! only on an up-crossing `U_t = {H_{t−1} < T ≤ H_t}` (were `H_{t−1} ≥ T`,
//! plane t−1 would already be on and t would continue it). It lasts ≥ L
//! planes only if there are *no two consecutive planes below T among
//! t ..= t+L*, so for every c in `[t, t+L−1]` the event
//! `E(c) = {H_c ≥ T or H_{c+1} ≥ T}` holds. With `L − 1 = m(N+1) + r`,
//! `0 ≤ r ≤ N`, take `U_t ∩ E(t+r)` (planes `t−N ..= t+r+1`) and the m
//! events `E(t+r+j(N+1))`, `j = 1..m`: each of these depends on planes
//! `c−N+1 ..= c+1` only, disjoint from the others and from the first, so
//! they are independent and
//!
//! `P(start at t, on-length ≥ L) ≤ first(r) · P(E)^m`, with
//! `first(0) = P(U)`, `first(N) = P(U)·P(E)` (disjoint planes) and, for
//! `0 < r < N`, `first(r) ≤ min(P(U), P(H_t ≥ T, W_{t+r} ≥ T))`, where
//! `W_c` is the sum over the N+1 planes `c−N+1 ..= c+1`: the weights are
//! non-negative, so `H_c, H_{c+1} ≤ W_c` and `E(c) ⊂ {W_c ≥ T}`.
//!
//! All of these are exact. Two windows sharing planes split as
//! `X = A + C`, `Y = C + D` (C over the shared planes, A and D over the
//! private ones, all independent), so
//! `P(X ≥ T, Y ≥ T) = Σ_{c<T} P(C=c)·P(A ≥ T−c)·P(D ≥ T−c) + P(C ≥ T)`,
//! with the laws of C, A and D from the lattice. For `(H_t, W_{t+r})`:
//! `N − r` shared, r and r + 1 private planes. With `(H_t, H_{t+1})` (N − 1
//! shared, one private plane each),
//! `P(E) = Σ_{c<T} P(C=c)·(P(A ≥ x) + P(A < x)·P(D ≥ x)) + P(C ≥ T)` and
//! `P(U) = Σ_{c<T} P(C=c)·P(A < x)·P(D ≥ x)`, `x = T − c` (prefix and
//! suffix sums: no `1 − y` anywhere). [`BackgroundProcess::pair`] gives
//! `P2(r) = P(H_t ≥ T, H_{t+r} ≥ T)` the same way.
//! Since an excursion of length ≥ L' also has length ≥ L for L < L', the
//! bound for L may use any shorter L'. `first(r)` is evaluated on a grid of
//! at most [`FIRST_SEGMENT_GRID`]+1 values of r (always 0 and N) and replaced
//! by its running minimum `f̂(r)` over grid points ≤ r; the bound used is
//! `min(P(E)^m·f̂(r), P(E)^(m−1)·f̂(N))` (the second term for m ≥ 1 being the
//! end of the previous block), which is non-increasing in L.
//! If the lattice would exceed the budget, these fall back to the
//! always-valid `first(r) ≤ P`, `P(E) ≤ 2P`, `P(U) ≤ P`
//! ([`FalseBlinkBound::pair_terms_exact`]).
//!
//! Measured against a seeded simulation of 10^7 background-only planes
//! (SPCIMAGER 150×, `tests/statistics.rs`), the bound is tight at L = 1
//! (it is then the exact up-crossing rate) and loose by one to two orders of
//! magnitude for L of order N: between the independent checkpoints it knows
//! nothing of the planes in between.
//!
//! This counts every excursion at its start (a rate per pixel-plane).
//! Pixels at the field's edges see fewer neighbours (zero padding): H there
//! is stochastically smaller, so "rate × pixels" over-counts them, which
//! keeps the field figure an upper bound.
//!
//! **Tracker neighbourhood.** The tracker keeps a track on while the *max
//! of H over the 3×3 around its anchor* is ≥ T_int, which is on at least
//! as often as the anchor alone. [`Neighbourhood::Pixel`] bounds the
//! single-pixel process above (what the brief and the paper describe);
//! [`Neighbourhood::Max3x3`] is a valid bound for the tracker's rule: the
//! track opens on its anchor crossing (`first = P`: no up-crossing or window
//! refinement, since whether a neighbour's track already holds the anchor
//! and the pair terms across pixels are not computed) and the union over
//! the 9 pixels gives `P(E_max) ≤ 9·P(E)`, so `bound = P·min(1, 9P(E))^m`,
//! `m = ⌊(L−1)/(N+1)⌋`. It is much looser (a factor 9 per block).
//!
//! `L_min = 1` confirms every crossing: that is the paper's scheme, fine for
//! one molecule in a small field. Across a full 320×240 field at 10 kHz
//! (SPCIMAGER 150×) background alone holds H above the paper's T on about
//! 2.1 million pixel-planes per second, in about 280,000 separate
//! excursions per second; the bound then asks for `L_min` = 296 planes for
//! one false blink per second (551 with the 3×3 rule).

use crate::kernel::{IntegerKernel, KernelError};
use crate::stats::{normal_sf, Detection};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::OnceLock;
use thiserror::Error;

/// Largest exact lattice computation, in multiply-adds (about a second).
pub const EXACT_WORK_BUDGET: f64 = 1e9;
/// Largest exact lattice, in states (T_int); two f64 arrays of this size.
pub const EXACT_MAX_STATES: u64 = 1 << 22;
/// Grid intervals on which `first(r)` of the false-blink bound is evaluated.
pub const FIRST_SEGMENT_GRID: u32 = 16;
/// Binomial terms below this are not computed at all.
const TERM_FLOOR: f64 = 1e-300;
/// First-pass cut-off on the skipped mass per side per class.
const FIRST_PASS_CUTOFF: f64 = 1e-30;
/// Lattice cells convolved at a time: 16 KB of f64, half an L1 data cache.
const LATTICE_BLOCK: usize = 2048;

/// Bad inputs to the false-alarm computations.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FalseAlarmError {
    /// The kernel breaks an invariant.
    #[error(transparent)]
    Kernel(#[from] KernelError),
    /// A parameter outside its range; the message names it.
    #[error("invalid parameter `{name}` = {value}: {why}")]
    Invalid {
        /// Parameter name.
        name: &'static str,
        /// Offending value.
        value: f64,
        /// What it must satisfy.
        why: &'static str,
    },
    /// No confirmation length brings the predicted rate below the target.
    #[error("no confirmation length reaches {target_per_s} false blinks/s: {why}")]
    TargetUnreachable {
        /// The requested rate, false blinks per second.
        target_per_s: f64,
        /// Why not.
        why: String,
    },
}

/// How a tail probability was computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// The exact lattice convolution.
    Exact,
    /// The Lugannani–Rice saddle-point approximation (lattice over budget).
    SaddlePoint,
}

/// `P(H ≥ T_int)` and how it was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TailProbability {
    /// The probability.
    pub p: f64,
    /// Exact or saddle point.
    pub method: Method,
    /// Exact method: the probability mass skipped in the convolution (the
    /// true value lies in `[p, p + truncation_bound]`); 0 for the saddle point.
    pub truncation_bound: f64,
}

/// Which on/off rule a false blink is bounded for (see the [module docs](self)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Neighbourhood {
    /// H at one pixel (the paper's rule).
    Pixel,
    /// The tracker's rule: max of H over the 3×3 around the anchor (union bound).
    Max3x3,
}

/// An upper bound on the rate of background-only excursions of on-length ≥ L.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FalseBlinkBound {
    /// L, planes.
    pub min_length: u32,
    /// The rule bounded.
    pub neighbourhood: Neighbourhood,
    /// Upper bound on excursions of on-length ≥ L starting per pixel-plane.
    pub per_pixel_plane: f64,
    /// m = number of independent blocks of N+1 planes in L−1.
    pub blocks: u32,
    /// r = (L−1) − m(N+1).
    pub remainder: u32,
    /// P = P(H ≥ T) per pixel-plane.
    pub single: f64,
    /// P(E) = P(H_t ≥ T or H_{t+1} ≥ T) (9× for [`Neighbourhood::Max3x3`]).
    pub either: f64,
    /// P(U) = P(H_{t−1} < T ≤ H_t), the up-crossing probability
    /// ([`Neighbourhood::Pixel`]; P for [`Neighbourhood::Max3x3`]).
    pub upcrossing: f64,
    /// The first-segment factor f̂(r) used.
    pub first_segment: f64,
    /// Whether the two-window terms (P(E), P(U), first(r)) came from the
    /// exact lattice (else the cruder bounds `first ≤ P`, `P(E) ≤ 2P`, `P(U) ≤ P`).
    pub pair_terms_exact: bool,
    /// How P was computed.
    pub method: Method,
}

/// False alarms of one threshold, exact beside the paper's Gaussian.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FalseAlarmReport {
    /// Window N, planes.
    pub n_window: u32,
    /// Threshold in units of H.
    pub threshold_int: u64,
    /// P(H ≥ T_int) per background-only pixel-plane (exact or saddle point).
    pub per_pixel_plane: f64,
    /// How `per_pixel_plane` was computed.
    pub method: Method,
    /// The Gaussian approximation of the same probability (paper's 3σ rule).
    pub gaussian_per_pixel_plane: f64,
    /// per_pixel_plane / gaussian_per_pixel_plane (`None` if the latter is 0).
    pub ratio_to_gaussian: Option<f64>,
    /// Pixels in the field.
    pub field_pixels: u64,
    /// Bit-planes per second.
    pub plane_rate_hz: f64,
    /// Above-threshold pixel-planes per second over the field.
    pub per_second: f64,
    /// The Gaussian prediction of the same.
    pub gaussian_per_second: f64,
}

/// Detection probability of a molecule on for the whole window, exactly.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DetectionProbability {
    /// P(H ≥ T_int) with the molecule on for N planes, at its own pixel.
    pub detection: f64,
    /// P(H < T_int), computed directly (no cancellation when it is tiny).
    pub miss: f64,
    /// Exact or saddle point.
    pub method: Method,
}

fn invalid(name: &'static str, value: f64, why: &'static str) -> FalseAlarmError {
    FalseAlarmError::Invalid { name, value, why }
}

fn check_p(name: &'static str, p: f64) -> Result<f64, FalseAlarmError> {
    if !p.is_finite() || !(0.0..=1.0).contains(&p) {
        return Err(invalid(name, p, "must be a probability in [0, 1]"));
    }
    Ok(p)
}

fn check_window(n_window: u32) -> Result<(), FalseAlarmError> {
    if n_window == 0 {
        return Err(invalid("n_window", 0.0, "must be at least 1 plane"));
    }
    Ok(())
}

/// Weight → number of pixels with that 2-D weight (weight-0 pixels omitted).
fn pixel_classes(kernel: &IntegerKernel) -> Result<Vec<(u64, u64)>, FalseAlarmError> {
    kernel.validate()?;
    let mut map = BTreeMap::new();
    let k = kernel.size();
    for i in 0..k {
        for j in 0..k {
            let w = kernel.weight_2d(i, j);
            if w > 0 {
                *map.entry(w).or_insert(0u64) += 1;
            }
        }
    }
    Ok(map.into_iter().collect())
}

// ---------------------------------------------------------------------------
// Binomial terms

/// `lgamma(n+1) − [(n+½)ln n − n + ½ln 2π]`, Stirling's error term.
fn stirlerr(n: f64) -> f64 {
    const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;
    if n <= 15.0 {
        let mut f = 1.0f64;
        let mut i = 2.0;
        while i <= n {
            f *= i;
            i += 1.0;
        }
        f.ln() - (n + 0.5) * n.ln() + n - HALF_LN_2PI
    } else {
        let nn = n * n;
        const S0: f64 = 1.0 / 12.0;
        const S1: f64 = 1.0 / 360.0;
        const S2: f64 = 1.0 / 1260.0;
        const S3: f64 = 1.0 / 1680.0;
        const S4: f64 = 1.0 / 1188.0;
        (S0 - (S1 - (S2 - (S3 - S4 / nn) / nn) / nn) / nn) / n
    }
}

/// `x ln(x/m) + m − x`, accurate also when x ≈ m (series in (x−m)/(x+m)).
fn bd0(x: f64, m: f64) -> f64 {
    if (x - m).abs() < 0.1 * (x + m) {
        let v = (x - m) / (x + m);
        let v2 = v * v;
        let mut s = (x - m) * v;
        let mut ej = 2.0 * x * v;
        let mut j = 1.0;
        loop {
            ej *= v2;
            let s1 = s + ej / (2.0 * j + 1.0);
            if s1 == s {
                return s1;
            }
            s = s1;
            j += 1.0;
        }
    } else {
        x * (x / m).ln() + m - x
    }
}

/// ln P(J = x), J ~ Binomial(n, p), 0 < p < 1 (Loader 2000).
fn ln_binomial_pmf(x: u64, n: u64, p: f64) -> f64 {
    let q = 1.0 - p;
    if x == 0 {
        return n as f64 * (-p).ln_1p();
    }
    if x == n {
        return n as f64 * p.ln();
    }
    let (xf, nf) = (x as f64, n as f64);
    let lc =
        stirlerr(nf) - stirlerr(xf) - stirlerr(nf - xf) - bd0(xf, nf * p) - bd0(nf - xf, nf * q);
    let lf = (2.0 * std::f64::consts::PI).ln() + xf.ln() + (-xf / nf).ln_1p();
    lc - 0.5 * lf
}

/// The binomial terms ≥ [`TERM_FLOOR`] (a contiguous range around the mode).
#[derive(Debug, Clone)]
struct Terms {
    /// j of `pmf[0]`.
    first: u64,
    pmf: Vec<f64>,
    /// `suffix[i] = Σ_{l ≥ i} pmf[l]`, summed from the top.
    suffix: Vec<f64>,
}

impl Terms {
    fn new(n: u64, p: f64) -> Terms {
        let (first, pmf) = if n == 0 || p <= 0.0 {
            (0, vec![1.0])
        } else if p >= 1.0 {
            (n, vec![1.0])
        } else {
            let mode = (((n + 1) as f64 * p).floor() as u64).min(n);
            let top = ln_binomial_pmf(mode, n, p).exp();
            let odds = p / (1.0 - p);
            let mut up = Vec::new();
            let mut v = top;
            let mut j = mode;
            while j < n {
                v *= (n - j) as f64 / (j + 1) as f64 * odds;
                if v < TERM_FLOOR {
                    break;
                }
                up.push(v);
                j += 1;
            }
            let mut down = Vec::new();
            let mut v = top;
            let mut j = mode;
            while j > 0 {
                v *= j as f64 / (n - j + 1) as f64 / odds;
                if v < TERM_FLOOR {
                    break;
                }
                down.push(v);
                j -= 1;
            }
            let first = mode - down.len() as u64;
            let mut pmf: Vec<f64> = down.into_iter().rev().collect();
            pmf.push(top);
            pmf.extend(up);
            (first, pmf)
        };
        let mut suffix = vec![0.0; pmf.len()];
        let mut acc = 0.0;
        for i in (0..pmf.len()).rev() {
            acc += pmf[i];
            suffix[i] = acc;
        }
        Terms { first, pmf, suffix }
    }

    /// `P(J ≥ j)`.
    fn sf(&self, j: u64) -> f64 {
        if j <= self.first {
            self.suffix[0]
        } else {
            let i = (j - self.first) as usize;
            self.suffix.get(i).copied().unwrap_or(0.0)
        }
    }

    /// Index range `[lo, hi]` keeping all but ≤ `cutoff` mass on each side.
    fn significant(&self, cutoff: f64) -> (usize, usize) {
        let mut lo = 0;
        let mut below = 0.0;
        while lo + 1 < self.pmf.len() && below + self.pmf[lo] <= cutoff {
            below += self.pmf[lo];
            lo += 1;
        }
        let mut hi = self.pmf.len() - 1;
        while hi > lo && self.suffix[hi] <= cutoff {
            hi -= 1;
        }
        (lo, hi)
    }
}

// ---------------------------------------------------------------------------
// The lattice

/// A group of Bernoulli trials with a common weight and probability.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Class {
    weight: u64,
    trials: u64,
    p: f64,
}

struct Lattice {
    /// `P(X = h)` for `h < T`.
    below: Vec<f64>,
    /// `P(X ≥ T)`.
    tail: f64,
    /// Mass skipped in the convolution (bound on the error of `tail`).
    truncated: f64,
}

struct Prepared {
    classes: Vec<(u64, Terms)>,
    threshold: u64,
    /// Largest value X can take.
    max: u64,
}

impl Prepared {
    fn new(classes: &[Class], threshold: u64) -> Prepared {
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

    fn exact_feasible(&self) -> bool {
        self.threshold <= EXACT_MAX_STATES && self.work() <= EXACT_WORK_BUDGET
    }

    fn run(&self, cutoff: f64) -> Lattice {
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
    fn exact(&self) -> Lattice {
        let first = self.run(FIRST_PASS_CUTOFF);
        if first.truncated <= 1e-10 * first.tail || first.truncated == 0.0 {
            return first;
        }
        let cutoff = (1e-13 * first.tail).max(TERM_FLOOR);
        self.run(cutoff)
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Per class: `(log MGF, tilted mean q, q(1−q))` at s, without overflow.
fn tilted(w: f64, p: f64, s: f64) -> (f64, f64, f64) {
    let sw = s * w;
    if p >= 1.0 {
        return (sw, 1.0, 0.0);
    }
    if sw > 0.0 {
        let e = (-sw).exp();
        let d = p + (1.0 - p) * e;
        let q = p / d;
        let one_minus_q = (1.0 - p) * e / d;
        (sw + d.ln(), q, q * one_minus_q)
    } else {
        let e = sw.exp();
        let d = 1.0 + p * sw.exp_m1();
        let q = p * e / d;
        let one_minus_q = (1.0 - p) / d;
        (d.ln(), q, q * one_minus_q)
    }
}

/// Lugannani–Rice with the second continuity correction (module docs).
fn saddle_point_tail(classes: &[Class], x: u64) -> f64 {
    let cls: Vec<Class> = classes
        .iter()
        .copied()
        .filter(|c| c.weight > 0 && c.trials > 0 && c.p > 0.0)
        .collect();
    let hmin: f64 = cls
        .iter()
        .filter(|c| c.p >= 1.0)
        .map(|c| c.weight as f64 * c.trials as f64)
        .sum();
    let hmax: f64 = cls.iter().map(|c| c.weight as f64 * c.trials as f64).sum();
    let xf = x as f64;
    if xf <= hmin {
        return 1.0;
    }
    if xf > hmax {
        return 0.0;
    }
    if xf == hmax {
        return cls
            .iter()
            .map(|c| c.trials as f64 * c.p.ln())
            .sum::<f64>()
            .exp();
    }
    let delta = cls
        .iter()
        .filter(|c| c.p < 1.0)
        .fold(0u64, |g, c| gcd(g, c.weight))
        .max(1) as f64;
    let xt = xf - delta / 2.0;
    if xt <= hmin {
        return 1.0;
    }
    let cgf = |s: f64| {
        let (mut k0, mut k1, mut k2) = (0.0, 0.0, 0.0);
        for c in &cls {
            let (w, n) = (c.weight as f64, c.trials as f64);
            let (l, q, v) = tilted(w, c.p, s);
            k0 += n * l;
            k1 += n * w * q;
            k2 += n * w * w * v;
        }
        (k0, k1, k2)
    };
    let wmax = cls.iter().map(|c| c.weight).max().unwrap_or(1) as f64;
    let (_, mean, _) = cgf(0.0);
    let (mut lo, mut hi) = if mean < xt {
        let mut hi = 1.0 / wmax;
        while cgf(hi).1 < xt && hi < 1e6 {
            hi *= 2.0;
        }
        (0.0, hi)
    } else {
        let mut lo = -1.0 / wmax;
        while cgf(lo).1 > xt && lo > -1e6 {
            lo *= 2.0;
        }
        (lo, 0.0)
    };
    let mut s = 0.5 * (lo + hi);
    for _ in 0..200 {
        let (_, k1, k2) = cgf(s);
        if k1 < xt {
            lo = s;
        } else {
            hi = s;
        }
        let newton = if k2 > 0.0 {
            s - (k1 - xt) / k2
        } else {
            f64::NAN
        };
        let next = if newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - s).abs() <= 1e-15 * s.abs().max(1e-300) {
            s = next;
            break;
        }
        s = next;
    }
    let (k0, _, k2) = cgf(s);
    if k2.is_nan() || k2 <= 0.0 {
        return if xt > mean { 0.0 } else { 1.0 };
    }
    let r = s.signum() * (2.0 * (s * xt - k0).max(0.0)).sqrt();
    if r.abs() < 1e-6 {
        // Centre of the distribution: the limit 1/2 − κ3/(6√(2π)κ2^{3/2}).
        let k3: f64 = cls
            .iter()
            .map(|c| {
                let (w, n) = (c.weight as f64, c.trials as f64);
                n * w * w * w * c.p * (1.0 - c.p) * (1.0 - 2.0 * c.p)
            })
            .sum();
        let v = 0.5 - k3 / (6.0 * (2.0 * std::f64::consts::PI).sqrt() * k2.powf(1.5));
        return v.clamp(0.0, 1.0);
    }
    let u = 2.0 / delta * (s * delta / 2.0).sinh() * k2.sqrt();
    let phi = (-0.5 * r * r).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let p = normal_sf(r) + phi * (1.0 / u - 1.0 / r);
    if p.is_finite() {
        p.clamp(0.0, 1.0)
    } else {
        normal_sf(r)
    }
}

/// `P(X ≥ threshold)` for a sum of scaled binomials, exact when affordable.
fn class_tail(classes: &[Class], threshold: u64) -> TailProbability {
    let prep = Prepared::new(classes, threshold);
    if threshold == 0 {
        return TailProbability {
            p: 1.0,
            method: Method::Exact,
            truncation_bound: 0.0,
        };
    }
    if threshold > prep.max {
        return TailProbability {
            p: 0.0,
            method: Method::Exact,
            truncation_bound: 0.0,
        };
    }
    if prep.exact_feasible() {
        let l = prep.exact();
        TailProbability {
            p: l.tail,
            method: Method::Exact,
            truncation_bound: l.truncated,
        }
    } else {
        TailProbability {
            p: saddle_point_tail(classes, threshold),
            method: Method::SaddlePoint,
            truncation_bound: 0.0,
        }
    }
}

/// The classes of H summed over `planes` background-only planes.
fn background_classes(pixels: &[(u64, u64)], planes: u64, p: f64) -> Vec<Class> {
    pixels
        .iter()
        .map(|&(w, c)| Class {
            weight: w,
            trials: c * planes,
            p,
        })
        .collect()
}

// ---------------------------------------------------------------------------
// Public API

/// `P(H ≥ T_int)` per background-only pixel-plane: H summed over
/// `n_window` planes with the integer kernel, every pixel Bernoulli(`p_off`)
/// per plane. Exact lattice method, or the saddle point over budget.
pub fn tail_probability(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
) -> Result<TailProbability, FalseAlarmError> {
    check_window(n_window)?;
    check_p("p_off", p_off)?;
    let pixels = pixel_classes(kernel)?;
    Ok(class_tail(
        &background_classes(&pixels, n_window as u64, p_off),
        threshold_int,
    ))
}

/// The Lugannani–Rice approximation of [`tail_probability`], whatever the
/// budget (for comparisons).
pub fn tail_probability_saddle_point(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
) -> Result<f64, FalseAlarmError> {
    check_window(n_window)?;
    check_p("p_off", p_off)?;
    let pixels = pixel_classes(kernel)?;
    Ok(saddle_point_tail(
        &background_classes(&pixels, n_window as u64, p_off),
        threshold_int,
    ))
}

/// Exact detection probability of a molecule on for the whole window: H at
/// the molecule's pixel with each pixel Bernoulli(`E(B_on)`) from
/// [`Detection::e_b_on`], at `T_int`.
pub fn detection_probability(det: &Detection) -> Result<DetectionProbability, FalseAlarmError> {
    let kernel = det.kernel();
    kernel.validate()?;
    check_window(det.n_window)?;
    let k = kernel.size();
    if det.e_b_on.len() != k * k {
        return Err(invalid(
            "e_b_on",
            det.e_b_on.len() as f64,
            "must hold k×k probabilities",
        ));
    }
    let mut map: BTreeMap<(u64, u64), u64> = BTreeMap::new();
    for i in 0..k {
        for j in 0..k {
            let p = check_p("e_b_on", det.e_b_on[i * k + j])?;
            *map.entry((kernel.weight_2d(i, j), p.to_bits()))
                .or_insert(0) += 1;
        }
    }
    let classes: Vec<Class> = map
        .into_iter()
        .map(|((w, pb), c)| Class {
            weight: w,
            trials: c * det.n_window as u64,
            p: f64::from_bits(pb),
        })
        .collect();
    let prep = Prepared::new(&classes, det.threshold_int);
    if prep.exact_feasible() && det.threshold_int <= prep.max {
        let l = prep.exact();
        let miss: f64 = l.below.iter().sum();
        Ok(DetectionProbability {
            detection: l.tail,
            miss,
            method: Method::Exact,
        })
    } else {
        let t = class_tail(&classes, det.threshold_int);
        Ok(DetectionProbability {
            detection: t.p,
            miss: 1.0 - t.p,
            method: t.method,
        })
    }
}

/// Per pixel-plane and per second false alarms of a derived threshold, beside
/// the Gaussian prediction, for a `width × height` field at `plane_rate_hz`.
pub fn false_alarm_report(
    det: &Detection,
    width: u32,
    height: u32,
    plane_rate_hz: f64,
) -> Result<FalseAlarmReport, FalseAlarmError> {
    if !plane_rate_hz.is_finite() || plane_rate_hz <= 0.0 {
        return Err(invalid(
            "plane_rate_hz",
            plane_rate_hz,
            "must be finite and > 0",
        ));
    }
    let tail = tail_probability(&det.kernel(), det.n_window, det.p_off, det.threshold_int)?;
    let field_pixels = width as u64 * height as u64;
    let g = det.gaussian_false_alarm_probability;
    Ok(FalseAlarmReport {
        n_window: det.n_window,
        threshold_int: det.threshold_int,
        per_pixel_plane: tail.p,
        method: tail.method,
        gaussian_per_pixel_plane: g,
        ratio_to_gaussian: (g > 0.0).then(|| tail.p / g),
        field_pixels,
        plane_rate_hz,
        per_second: tail.p * field_pixels as f64 * plane_rate_hz,
        gaussian_per_second: g * field_pixels as f64 * plane_rate_hz,
    })
}

/// The background-only H process at one pixel: caches P, P(E) and the
/// first-segment table of the false-blink bound.
#[derive(Debug)]
pub struct BackgroundProcess {
    pixels: Vec<(u64, u64)>,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
    single: TailProbability,
    pairs_exact: bool,
    /// `(P(E), P(U))`.
    lag_one: OnceLock<(f64, f64)>,
    /// `(r, f̂(r))` on the grid, ascending r, running minimum.
    first_table: OnceLock<Vec<(u32, f64)>>,
}

impl BackgroundProcess {
    /// Sets up the process; computes `P = P(H ≥ T_int)`.
    pub fn new(
        kernel: &IntegerKernel,
        n_window: u32,
        p_off: f64,
        threshold_int: u64,
    ) -> Result<Self, FalseAlarmError> {
        check_window(n_window)?;
        check_p("p_off", p_off)?;
        let pixels = pixel_classes(kernel)?;
        let classes = background_classes(&pixels, n_window as u64, p_off);
        let single = class_tail(&classes, threshold_int);
        let pairs_exact = Prepared::new(&classes, threshold_int).exact_feasible();
        Ok(BackgroundProcess {
            pixels,
            n_window,
            p_off,
            threshold_int,
            single,
            pairs_exact,
            lag_one: OnceLock::new(),
            first_table: OnceLock::new(),
        })
    }

    /// The process of a derived [`Detection`].
    pub fn from_detection(det: &Detection) -> Result<Self, FalseAlarmError> {
        Self::new(&det.kernel(), det.n_window, det.p_off, det.threshold_int)
    }

    /// `P(H ≥ T_int)` per pixel-plane.
    pub fn single(&self) -> TailProbability {
        self.single
    }

    /// `(P(X ≥ x), P(X < x))` for x in `0..=T`, X the sum over `planes`
    /// background planes (exact lattice; suffix and prefix sums, so neither
    /// is a `1 − y`).
    fn sf_cdf(&self, planes: u64, cutoff: f64) -> (Vec<f64>, Vec<f64>) {
        let t = self.threshold_int as usize;
        let l = Prepared::new(
            &background_classes(&self.pixels, planes, self.p_off),
            t as u64,
        )
        .run(cutoff);
        let mut sf = vec![0.0; t + 1];
        sf[t] = l.tail;
        for x in (0..t).rev() {
            sf[x] = sf[x + 1] + l.below[x];
        }
        let mut cdf = vec![0.0; t + 1];
        for x in 0..t {
            cdf[x + 1] = cdf[x] + l.below[x];
        }
        (sf, cdf)
    }

    /// Two windows sharing `shared` planes, with `a` and `d` private planes:
    /// `X = A + C`, `Y = C + D`. For each `g`, returns
    /// `Σ_{c<T} P(C=c)·g(P(A ≥ T−c), P(A < T−c), P(D ≥ T−c), P(D < T−c))
    ///  + P(C ≥ T)·g(1, 0, 1, 0)`; `g` encodes the event on (X, Y).
    fn joint(
        &self,
        shared: u64,
        a: u64,
        d: u64,
        gs: &[&dyn Fn(f64, f64, f64, f64) -> f64],
    ) -> Vec<f64> {
        let t = self.threshold_int as usize;
        if t == 0 {
            return gs.iter().map(|g| g(1.0, 0.0, 1.0, 0.0)).collect();
        }
        // Every event used here has probability ≥ P² (increasing events of
        // independent pixels are positively associated) or is compared with
        // such, so skipping 1e-13·P² of mass per class side keeps ~1e-11
        // relative accuracy while sparing most of the far terms.
        let p = self.single.p;
        let cutoff = (1e-13 * p * p).clamp(TERM_FLOOR, 1e-16);
        let c = Prepared::new(
            &background_classes(&self.pixels, shared, self.p_off),
            t as u64,
        )
        .run(cutoff);
        let (sf_a, cdf_a) = self.sf_cdf(a, cutoff);
        let (sf_d, cdf_d) = if d == a {
            (sf_a.clone(), cdf_a.clone())
        } else {
            self.sf_cdf(d, cutoff)
        };
        gs.iter()
            .map(|g| {
                let mut sum = c.tail * g(1.0, 0.0, 1.0, 0.0);
                for (cv, &m) in c.below.iter().enumerate() {
                    if m != 0.0 {
                        let x = t - cv;
                        sum += m * g(sf_a[x], cdf_a[x], sf_d[x], cdf_d[x]);
                    }
                }
                sum.min(1.0)
            })
            .collect()
    }

    /// `P2(r) = P(H_t ≥ T, H_{t+r} ≥ T)`: exact when the lattice is within
    /// budget, else `None`.
    pub fn pair(&self, r: u32) -> Option<f64> {
        let p = self.single.p;
        if r == 0 {
            return Some(p);
        }
        if r >= self.n_window {
            return Some(p * p);
        }
        if !self.pairs_exact {
            return None;
        }
        let n = self.n_window as u64;
        Some(self.joint(n - r as u64, r as u64, r as u64, &[&|sa, _, sd, _| sa * sd])[0])
    }

    /// `(P(E), P(U))` with `E = {H_t ≥ T or H_{t+1} ≥ T}` and the up-crossing
    /// `U = {H_{t−1} < T ≤ H_t}`; over budget, the bounds `2P` and `P`.
    fn lag_one(&self) -> (f64, f64) {
        *self.lag_one.get_or_init(|| {
            let p = self.single.p;
            if self.n_window == 1 {
                // Windows of one plane at consecutive planes are independent.
                return (1.0 - (1.0 - p) * (1.0 - p), (1.0 - p) * p);
            }
            if !self.pairs_exact {
                return ((2.0 * p).min(1.0), p);
            }
            // H_t = A + C, H_{t+1} = C + D: E ⇔ not both below, i.e.
            // 1 − P(A < x)·P(D < x) = sf_a + cdf_a·sf_d; U (the same law one
            // plane earlier) ⇔ A < x ≤ D: cdf_a·sf_d.
            let n = self.n_window as u64;
            let v = self.joint(
                n - 1,
                1,
                1,
                &[&|sa, ca, sd, _| sa + ca * sd, &|_, ca, sd, _| ca * sd],
            );
            (v[0], v[1])
        })
    }

    /// `P(E) = P(H_t ≥ T or H_{t+1} ≥ T)` (exact, or the bound 2P over budget).
    pub fn either(&self) -> f64 {
        self.lag_one().0
    }

    /// `P(U) = P(H_{t−1} < T ≤ H_t)`, the up-crossing probability per
    /// pixel-plane: an excursion can only start at an up-crossing (exact, or
    /// the bound P over budget).
    pub fn upcrossing(&self) -> f64 {
        self.lag_one().1
    }

    /// `P(H_t ≥ T, W ≥ T)` with W the sum over the N+1 planes
    /// `t+r−N+1 ..= t+r+1`, for `0 < r < N`: since weights are non-negative,
    /// `H_{t+r}, H_{t+r+1} ≤ W`, so `E(t+r) ⊂ {W ≥ T}`. Shared planes `N − r`,
    /// private r (H_t) and r + 1 (W). `None` over budget or outside `0 < r < N`.
    pub fn pair_with_wide_window(&self, r: u32) -> Option<f64> {
        if !self.pairs_exact || r == 0 || r >= self.n_window {
            return None;
        }
        let n = self.n_window as u64;
        let r = r as u64;
        Some(self.joint(n - r, r, r + 1, &[&|sa, _, sd, _| sa * sd])[0])
    }

    fn first_table(&self) -> &[(u32, f64)] {
        self.first_table.get_or_init(|| {
            let n = self.n_window;
            let p = self.single.p;
            let g = FIRST_SEGMENT_GRID.min(n);
            let mut rs: Vec<u32> = (0..=g)
                .map(|i| ((i as u64 * n as u64 + g as u64 / 2) / g as u64) as u32)
                .collect();
            rs.dedup();
            let u = self.upcrossing().min(p);
            let mut table = Vec::with_capacity(rs.len());
            let mut best = f64::INFINITY;
            for r in rs {
                let f = if r == 0 {
                    u
                } else if r >= n {
                    u * self.either()
                } else {
                    self.pair_with_wide_window(r).map_or(u, |v| v.min(u))
                };
                best = best.min(f);
                table.push((r, best));
            }
            table
        })
    }

    /// The false-blink bound for on-length ≥ `min_length` (module docs).
    pub fn false_blink_bound(
        &self,
        min_length: u32,
        neighbourhood: Neighbourhood,
    ) -> Result<FalseBlinkBound, FalseAlarmError> {
        if min_length == 0 {
            return Err(invalid("min_length", 0.0, "must be at least 1 plane"));
        }
        let n1 = self.n_window as u64 + 1;
        let blocks = ((min_length as u64 - 1) / n1) as u32;
        let remainder = ((min_length as u64 - 1) % n1) as u32;
        let p = self.single.p;
        let base = FalseBlinkBound {
            min_length,
            neighbourhood,
            per_pixel_plane: p,
            blocks,
            remainder,
            single: p,
            either: p,
            upcrossing: p,
            first_segment: p,
            pair_terms_exact: self.pairs_exact,
            method: self.single.method,
        };
        if p == 0.0 {
            return Ok(FalseBlinkBound {
                per_pixel_plane: 0.0,
                either: 0.0,
                upcrossing: 0.0,
                first_segment: 0.0,
                ..base
            });
        }
        match neighbourhood {
            Neighbourhood::Pixel => {
                let e = self.either();
                let u = self.upcrossing().min(p);
                // L = 1 needs only f̂(0) = P(U); spare the grid.
                let (f_r, f_n) = if min_length == 1 {
                    (u, u)
                } else {
                    let table = self.first_table();
                    let f_r = table
                        .iter()
                        .rev()
                        .find(|(r, _)| *r <= remainder)
                        .map_or(u, |x| x.1);
                    (f_r, table.last().map_or(u, |x| x.1))
                };
                let mut bound = e.powf(blocks as f64) * f_r;
                if blocks >= 1 {
                    bound = bound.min(e.powf(blocks as f64 - 1.0) * f_n);
                }
                Ok(FalseBlinkBound {
                    per_pixel_plane: bound,
                    either: e,
                    upcrossing: u,
                    first_segment: f_r,
                    ..base
                })
            }
            Neighbourhood::Max3x3 => {
                let e = if min_length == 1 {
                    p
                } else {
                    (9.0 * self.either()).min(1.0)
                };
                Ok(FalseBlinkBound {
                    per_pixel_plane: p * if blocks == 0 {
                        1.0
                    } else {
                        e.powf(blocks as f64)
                    },
                    either: e,
                    first_segment: p,
                    ..base
                })
            }
        }
    }

    /// The smallest L whose bounded false-blink rate over `field_pixels`
    /// pixels at `plane_rate_hz` planes/s is ≤ `target_per_s`.
    pub fn l_min_for_target(
        &self,
        neighbourhood: Neighbourhood,
        field_pixels: u64,
        plane_rate_hz: f64,
        target_per_s: f64,
    ) -> Result<u32, FalseAlarmError> {
        if field_pixels == 0 {
            return Err(invalid("field_pixels", 0.0, "must be at least 1"));
        }
        if !plane_rate_hz.is_finite() || plane_rate_hz <= 0.0 {
            return Err(invalid(
                "plane_rate_hz",
                plane_rate_hz,
                "must be finite and > 0",
            ));
        }
        if !target_per_s.is_finite() || target_per_s <= 0.0 {
            return Err(invalid(
                "target_false_blinks_per_s",
                target_per_s,
                "must be finite and > 0",
            ));
        }
        let scale = field_pixels as f64 * plane_rate_hz;
        let ok = |b: f64| b * scale <= target_per_s;
        let p = self.single.p;
        if ok(self.false_blink_bound(1, neighbourhood)?.per_pixel_plane) {
            return Ok(1);
        }
        let n1 = self.n_window as u64 + 1;
        let e = match neighbourhood {
            Neighbourhood::Pixel => self.either(),
            Neighbourhood::Max3x3 => (9.0 * self.either()).min(1.0),
        };
        // End-of-block value: f̂(N)·e^m (Pixel) or P·e^(m+1) (Max3x3).
        let end = match neighbourhood {
            Neighbourhood::Pixel => self.first_table().last().map(|x| x.1).unwrap_or(p),
            Neighbourhood::Max3x3 => p * e,
        };
        if e >= 1.0 && !ok(end) {
            return Err(FalseAlarmError::TargetUnreachable {
                target_per_s,
                why: format!("background alone keeps H above T_int too often (P(E) = {e})"),
            });
        }
        // Smallest block m whose end reaches the target.
        let mut m: u64 = if ok(end) {
            0
        } else {
            ((target_per_s / (end * scale)).ln() / e.ln())
                .ceil()
                .max(0.0) as u64
        };
        while m > 0 && ok(end * e.powf(m as f64 - 1.0)) {
            m -= 1;
        }
        while !ok(end * e.powf(m as f64)) {
            m += 1;
        }
        let length = match neighbourhood {
            Neighbourhood::Max3x3 => 1 + (m + 1) * n1,
            Neighbourhood::Pixel => {
                let table = self.first_table();
                let r = table
                    .iter()
                    .find(|(_, f)| ok(f * e.powf(m as f64)))
                    .map(|x| x.0)
                    .unwrap_or(self.n_window);
                1 + m * n1 + r as u64
            }
        };
        u32::try_from(length).map_err(|_| FalseAlarmError::TargetUnreachable {
            target_per_s,
            why: format!("it needs {length} planes, beyond u32"),
        })
    }
}

/// Upper bound on background-only excursions of on-length ≥ `min_length`
/// per pixel-plane (see the [module docs](self) for the derivation).
pub fn false_blink_rate(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
    min_length: u32,
    neighbourhood: Neighbourhood,
) -> Result<FalseBlinkBound, FalseAlarmError> {
    BackgroundProcess::new(kernel, n_window, p_off, threshold_int)?
        .false_blink_bound(min_length, neighbourhood)
}

/// The smallest confirmation length `L_min` whose bounded single-pixel
/// ([`Neighbourhood::Pixel`]) false-blink rate over `field_pixels` pixels at
/// `plane_rate_hz` is ≤ `target_false_blinks_per_s`
/// ([`BackgroundProcess::l_min_for_target`] offers the 3×3 rule too).
/// `L_min = 1` is the paper's scheme (every crossing is a blink), right for
/// one molecule in a small field.
pub fn l_min_for_target(
    kernel: &IntegerKernel,
    n_window: u32,
    p_off: f64,
    threshold_int: u64,
    field_pixels: u64,
    plane_rate_hz: f64,
    target_false_blinks_per_s: f64,
) -> Result<u32, FalseAlarmError> {
    BackgroundProcess::new(kernel, n_window, p_off, threshold_int)?.l_min_for_target(
        Neighbourhood::Pixel,
        field_pixels,
        plane_rate_hz,
        target_false_blinks_per_s,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn direct_pmf(j: u64, n: u64, p: f64) -> f64 {
        let mut c = 1.0f64;
        for i in 0..j {
            c = c * (n - i) as f64 / (i + 1) as f64;
        }
        c * p.powi(j as i32) * (1.0 - p).powi((n - j) as i32)
    }

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

    #[test]
    fn binomial_terms_match_direct_products() {
        for &(n, p) in &[(1u64, 0.3), (7, 0.5), (40, 0.01), (109, 0.0117), (300, 0.9)] {
            let t = Terms::new(n, p);
            let total: f64 = t.pmf.iter().sum();
            assert!((total - 1.0).abs() < 1e-13, "n {n} p {p}: {total}");
            for (i, &v) in t.pmf.iter().enumerate() {
                let j = t.first + i as u64;
                let d = direct_pmf(j, n, p);
                if d > 1e-250 {
                    assert!(((v - d) / d).abs() < 1e-11, "n {n} p {p} j {j}: {v} vs {d}");
                }
            }
            assert!((t.sf(0) - 1.0).abs() < 1e-13);
        }
        // Huge n: still normalised and centred (naive (1-p)^n underflows here).
        let t = Terms::new(80_000_000, 0.3);
        let total: f64 = t.pmf.iter().sum();
        assert!((total - 1.0).abs() < 1e-9, "{total}");
        assert!(t.first < 24_000_000 && t.first + (t.pmf.len() as u64) > 24_000_000);
        assert_eq!(Terms::new(10, 0.0).pmf, vec![1.0]);
        assert_eq!(Terms::new(10, 1.0).first, 10);
    }

    #[test]
    fn degenerate_tails() {
        let k = IntegerKernel::gaussian(1.0, 3, 4).unwrap();
        // p = 0: H = 0 always.
        let t = tail_probability(&k, 10, 0.0, 1).unwrap();
        assert_eq!(t.p, 0.0);
        // Threshold 0 is always reached; a threshold above the maximum never.
        assert_eq!(tail_probability(&k, 10, 0.1, 0).unwrap().p, 1.0);
        assert_eq!(tail_probability(&k, 10, 0.1, 256 * 10 + 1).unwrap().p, 0.0);
        // The maximum: every pixel fires in every plane.
        let t = tail_probability(&k, 2, 0.5, 256 * 2).unwrap();
        assert!((t.p - 0.5f64.powi(18)).abs() < 1e-18, "{}", t.p);
        // p = 1: H is the maximum.
        assert_eq!(tail_probability(&k, 3, 1.0, 768).unwrap().p, 1.0);
        assert!(
            (saddle_point_tail(
                &background_classes(&pixel_classes(&k).unwrap(), 2, 0.5),
                512
            ) - 0.5f64.powi(18))
            .abs()
                < 1e-18
        );
    }

    #[test]
    fn bad_inputs_are_named() {
        let k = IntegerKernel::gaussian(1.0, 3, 4).unwrap();
        let e = tail_probability(&k, 0, 0.1, 5).unwrap_err().to_string();
        assert!(e.contains("n_window"), "{e}");
        let e = tail_probability(&k, 4, 1.5, 5).unwrap_err().to_string();
        assert!(e.contains("p_off"), "{e}");
        let bad = IntegerKernel {
            weights: vec![1, 2],
            ..k.clone()
        };
        assert!(tail_probability(&bad, 4, 0.1, 5).is_err());
        let bp = BackgroundProcess::new(&k, 4, 0.1, 50).unwrap();
        assert!(bp.false_blink_bound(0, Neighbourhood::Pixel).is_err());
        let e = bp
            .l_min_for_target(Neighbourhood::Pixel, 100, 1e4, 0.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("target_false_blinks_per_s"), "{e}");
    }

    #[test]
    fn bound_is_non_increasing_in_length() {
        let k = IntegerKernel::gaussian(1.2, 5, 6).unwrap();
        let bp = BackgroundProcess::new(&k, 12, 0.02, 700).unwrap();
        for nb in [Neighbourhood::Pixel, Neighbourhood::Max3x3] {
            let mut last = 1.0;
            for l in 1..60 {
                let b = bp.false_blink_bound(l, nb).unwrap().per_pixel_plane;
                assert!(b <= last && b >= 0.0, "{nb:?} L {l}: {b} > {last}");
                last = b;
            }
        }
        // l_min agrees with the bound it is defined from.
        let (pixels, rate) = (10_000u64, 1e4);
        for target in [1e3, 1.0, 1e-3] {
            let l = bp
                .l_min_for_target(Neighbourhood::Pixel, pixels, rate, target)
                .unwrap();
            let at = bp
                .false_blink_bound(l, Neighbourhood::Pixel)
                .unwrap()
                .per_pixel_plane;
            assert!(at * pixels as f64 * rate <= target, "L {l}");
            if l > 1 {
                let before = bp
                    .false_blink_bound(l - 1, Neighbourhood::Pixel)
                    .unwrap()
                    .per_pixel_plane;
                assert!(before * pixels as f64 * rate > target, "L {l} not minimal");
            }
        }
    }
}
