//! Stage drift: the sample moves under the objective during a long
//! acquisition, so every emitter is imaged at its position plus the drift
//! `d(t) = (dx, dy)` of the moment.
//!
//! A [`DriftTrajectory`] is a linear term plus a few smooth low-frequency
//! terms, with `d(0) = 0`. [`DriftTrajectory::linear`] is a constant stage
//! velocity; [`DriftTrajectory::random`] is a smooth random curve (a random
//! linear term and three sinusoids of periods 2T, T and 2T/3 with random
//! amplitudes and phases, from the seed's drift stream) scaled so that the
//! largest distance from the starting point over `[0, T]` is the requested
//! amplitude — what "100 nm of drift over the acquisition" means here.
//!
//! The simulators sample the drift once per blink, at the middle of the part
//! of the blink after t = 0 (see [`DriftTrajectory::at_blink`]): 100 nm in
//! 10 minutes moves a 30 ms blink by 0.005 nm, far below any localisation
//! precision, and the truth then states exactly where each blink was imaged.

use rand::Rng;

use crate::sampling::{rng_stream, STREAM_DRIFT};
use smartagg_model::params::ParamError;

/// Largest drift amplitude or speed accepted (nm, nm/s): a millimetre is
/// far beyond any stage yet keeps every position finite.
pub const MAX_DRIFT_NM: f64 = 1e6;

/// Points per trajectory at which a random trajectory's amplitude is set.
const AMPLITUDE_SAMPLES: usize = 2001;

/// One smooth term: `(ax, ay) · (sin(2π f t + φ) − sin φ)`, zero at t = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Term {
    ax: f64,
    ay: f64,
    freq_hz: f64,
    phase: f64,
}

/// A stage-drift trajectory `d(t)`, nm, with `d(0) = 0`.
#[derive(Debug, Clone, PartialEq)]
pub struct DriftTrajectory {
    vx_nm_s: f64,
    vy_nm_s: f64,
    terms: Vec<Term>,
}

impl DriftTrajectory {
    /// No drift.
    pub fn none() -> DriftTrajectory {
        DriftTrajectory::linear(0.0, 0.0).expect("zero is valid")
    }

    /// A constant stage velocity, nm/s.
    pub fn linear(vx_nm_s: f64, vy_nm_s: f64) -> Result<DriftTrajectory, ParamError> {
        for (name, v) in [("drift vx (nm/s)", vx_nm_s), ("drift vy (nm/s)", vy_nm_s)] {
            if !(v.is_finite() && v.abs() <= MAX_DRIFT_NM) {
                return Err(ParamError::Invalid {
                    name,
                    value: v,
                    why: "must be a finite speed of at most 1e6 nm/s",
                });
            }
        }
        Ok(DriftTrajectory {
            vx_nm_s,
            vy_nm_s,
            terms: Vec::new(),
        })
    }

    /// A smooth random trajectory whose largest distance from the start over
    /// `[0, duration_s]` is `amplitude_nm` (see the module docs); the same
    /// seed gives the same trajectory, independent of every other stream.
    pub fn random(
        amplitude_nm: f64,
        duration_s: f64,
        seed: u64,
    ) -> Result<DriftTrajectory, ParamError> {
        if !(amplitude_nm.is_finite() && (0.0..=MAX_DRIFT_NM).contains(&amplitude_nm)) {
            return Err(ParamError::Invalid {
                name: "drift amplitude (nm)",
                value: amplitude_nm,
                why: "must be between 0 and 1e6 nm",
            });
        }
        if !(duration_s.is_finite() && duration_s > 0.0) {
            return Err(ParamError::Invalid {
                name: "drift duration (s)",
                value: duration_s,
                why: "must be a positive number of seconds",
            });
        }
        let mut rng = rng_stream(seed, STREAM_DRIFT);
        // Standard normal by Box–Muller: two uniforms, no extra dependency.
        let mut normal = || {
            let u: f64 = 1.0 - rng.gen::<f64>();
            let v: f64 = rng.gen::<f64>();
            (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
        };
        let (vx, vy) = (normal(), normal());
        let mut terms = Vec::new();
        for k in 1..=3 {
            // Amplitudes fall with frequency: a smooth curve, mostly slow.
            let scale = 0.6 / k as f64;
            let (ax, ay) = (scale * normal(), scale * normal());
            let phase = 2.0 * std::f64::consts::PI * normal().abs().fract();
            terms.push(Term {
                ax,
                ay,
                freq_hz: k as f64 / (2.0 * duration_s),
                phase,
            });
        }
        let mut d = DriftTrajectory {
            vx_nm_s: vx / duration_s,
            vy_nm_s: vy / duration_s,
            terms,
        };
        let largest = (0..AMPLITUDE_SAMPLES)
            .map(|i| {
                let (x, y) = d.at(duration_s * i as f64 / (AMPLITUDE_SAMPLES - 1) as f64);
                x.hypot(y)
            })
            .fold(0.0, f64::max);
        let s = if largest > 0.0 {
            amplitude_nm / largest
        } else {
            0.0
        };
        d.vx_nm_s *= s;
        d.vy_nm_s *= s;
        for t in &mut d.terms {
            t.ax *= s;
            t.ay *= s;
        }
        Ok(d)
    }

    /// Whether this is no drift at all.
    pub fn is_none(&self) -> bool {
        self.vx_nm_s == 0.0
            && self.vy_nm_s == 0.0
            && self.terms.iter().all(|t| t.ax == 0.0 && t.ay == 0.0)
    }

    /// The drift at time `t_s`, nm.
    pub fn at(&self, t_s: f64) -> (f64, f64) {
        let (mut x, mut y) = (self.vx_nm_s * t_s, self.vy_nm_s * t_s);
        for term in &self.terms {
            let w = (2.0 * std::f64::consts::PI * term.freq_hz * t_s + term.phase).sin()
                - term.phase.sin();
            x += term.ax * w;
            y += term.ay * w;
        }
        (x, y)
    }

    /// The drift a blink on `[t_on_s, t_off_s)` is imaged with: the drift at
    /// the middle of the part of the blink after t = 0.
    pub fn at_blink(&self, t_on_s: f64, t_off_s: f64) -> (f64, f64) {
        if self.is_none() {
            return (0.0, 0.0);
        }
        let t0 = t_on_s.max(0.0);
        let t1 = t_off_s.max(t0);
        self.at(0.5 * (t0 + t1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_trajectories_reach_their_amplitude_and_start_at_zero() {
        for seed in 0..20 {
            let d = DriftTrajectory::random(100.0, 600.0, seed).unwrap();
            assert_eq!(d.at(0.0), (0.0, 0.0));
            let largest = (0..=6000)
                .map(|i| {
                    let (x, y) = d.at(i as f64 * 0.1);
                    x.hypot(y)
                })
                .fold(0.0, f64::max);
            assert!((largest - 100.0).abs() < 0.5, "seed {seed}: {largest}");
            // Smooth: no more than a few nm per second at 100 nm per 10 min.
            for i in 0..600 {
                let (a, b) = (d.at(i as f64), d.at(i as f64 + 1.0));
                assert!((a.0 - b.0).hypot(a.1 - b.1) < 3.0, "seed {seed} at {i} s");
            }
        }
        assert_ne!(
            DriftTrajectory::random(100.0, 600.0, 1).unwrap(),
            DriftTrajectory::random(100.0, 600.0, 2).unwrap()
        );
    }

    #[test]
    fn linear_drift_and_bad_values() {
        let d = DriftTrajectory::linear(0.5, -0.25).unwrap();
        assert_eq!(d.at(10.0), (5.0, -2.5));
        assert_eq!(d.at_blink(-1.0, 2.0), (0.5, -0.25));
        assert!(DriftTrajectory::none().is_none());
        assert!(DriftTrajectory::linear(f64::NAN, 0.0).is_err());
        assert!(DriftTrajectory::linear(0.0, 2e6).is_err());
        assert!(DriftTrajectory::random(-1.0, 1.0, 1).is_err());
        assert!(DriftTrajectory::random(1.0, 0.0, 1).is_err());
        assert!(DriftTrajectory::random(f64::INFINITY, 1.0, 1).is_err());
        assert!(DriftTrajectory::random(0.0, 1.0, 1).unwrap().is_none());
    }
}
