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

mod background;
mod binomial;
mod lattice;
mod saddle_point;
mod tail;

pub use background::{false_blink_rate, l_min_for_target, BackgroundProcess};
pub use tail::{
    detection_probability, false_alarm_report, tail_probability, tail_probability_saddle_point,
};

use crate::kernel::{IntegerKernel, KernelError};
use serde::Serialize;
use std::collections::BTreeMap;
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

#[cfg(test)]
mod tests {
    use super::*;

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
}
