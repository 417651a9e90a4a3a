//! What the fit knows per pixel (gain, offset, ignored) and per objective
//! (Poisson or least squares), and the starting values they give; shared
//! with the centroid, SPAD and Cramér–Rao code.

use crate::fastmath::{ln_and_recip, Arith};
use crate::roi::PixelMaps;

/// Per-pixel knowledge seen by the fit loop; the uniform version compiles to
/// constants.
pub(crate) trait PixelModel {
    /// Gain 1, no offset or shift, nothing ignored: lets the fit loop skip
    /// the per-pixel factors.
    const UNIFORM: bool;
    fn gain(&self, k: usize) -> f64;
    /// Added to μ (dark counts, sCMOS read variance).
    fn offset(&self, k: usize) -> f64;
    /// Added to the data (sCMOS read variance).
    fn shift(&self, k: usize) -> f64;
    fn ignored(&self, k: usize) -> bool;
}

pub(crate) struct Uniform;

impl PixelModel for Uniform {
    const UNIFORM: bool = true;
    #[inline(always)]
    fn gain(&self, _k: usize) -> f64 {
        1.0
    }
    #[inline(always)]
    fn offset(&self, _k: usize) -> f64 {
        0.0
    }
    #[inline(always)]
    fn shift(&self, _k: usize) -> f64 {
        0.0
    }
    #[inline(always)]
    fn ignored(&self, _k: usize) -> bool {
        false
    }
}

pub(crate) struct Mapped<'a> {
    pub maps: &'a PixelMaps,
    pub scmos: bool,
}

impl PixelModel for Mapped<'_> {
    const UNIFORM: bool = false;
    #[inline(always)]
    fn gain(&self, k: usize) -> f64 {
        self.maps.gain[k]
    }
    #[inline(always)]
    fn offset(&self, k: usize) -> f64 {
        if self.scmos {
            self.maps.dark[k] + self.maps.read_var[k]
        } else {
            self.maps.dark[k]
        }
    }
    #[inline(always)]
    fn shift(&self, k: usize) -> f64 {
        if self.scmos {
            self.maps.read_var[k]
        } else {
            0.0
        }
    }
    #[inline(always)]
    fn ignored(&self, k: usize) -> bool {
        self.maps.ignore[k]
    }
}

/// The objective's contribution of one pixel: (objective, residual factor r,
/// weight w) with gradient `Σ r ∂μ` and curvature `Σ w ∂μ∂μᵀ`.
pub(crate) trait Objective {
    fn pixel<A: Arith>(n: f64, mu: f64) -> (f64, f64, f64);
    /// Residual factor and weight only (no objective).
    fn pixel_grad<A: Arith>(n: f64, mu: f64) -> (f64, f64);
    /// Lowest background allowed.
    const B_MIN: f64;
    /// Whether the objective is a (negative half) sum of squares.
    const LEAST_SQUARES: bool;
}

pub(crate) struct PoissonObjective;

impl Objective for PoissonObjective {
    #[inline(always)]
    fn pixel<A: Arith>(n: f64, mu: f64) -> (f64, f64, f64) {
        // Negative data (sCMOS after offset subtraction) are clamped: a Poisson
        // variable cannot be negative.
        let n = n.max(0.0);
        let (ln, inv) = ln_and_recip::<A>(mu);
        (A::madd(n, ln, -mu), A::madd(n, inv, -1.0), inv)
    }
    #[inline(always)]
    fn pixel_grad<A: Arith>(n: f64, mu: f64) -> (f64, f64) {
        let inv = 1.0 / mu;
        (A::madd(n.max(0.0), inv, -1.0), inv)
    }
    const B_MIN: f64 = 0.0;
    const LEAST_SQUARES: bool = false;
}

pub(crate) struct LsqObjective;

impl Objective for LsqObjective {
    #[inline(always)]
    fn pixel<A: Arith>(n: f64, mu: f64) -> (f64, f64, f64) {
        let r = n - mu;
        (-0.5 * r * r, r, 1.0)
    }
    #[inline(always)]
    fn pixel_grad<A: Arith>(n: f64, mu: f64) -> (f64, f64) {
        (n - mu, 1.0)
    }
    const B_MIN: f64 = -1e12;
    const LEAST_SQUARES: bool = true;
}

/// Starting values `[x, y, N, b]`: background from the mean of the valid
/// border pixels, position from the centroid of the excess over it, photons
/// from the summed excess. `None` when the ROI holds no counts at all.
pub(crate) fn initial_guess<M: PixelModel>(data: &[f64], side: usize, m: &M) -> Option<[f64; 4]> {
    let mut border_sum = 0.0;
    let mut border_n = 0usize;
    let mut total = 0.0;
    let mut valid = 0usize;
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if m.ignored(k) {
                continue;
            }
            let v = (data[k] - m.offset(k) + m.shift(k)) / m.gain(k);
            total += data[k].max(0.0);
            valid += 1;
            if i == 0 || j == 0 || i + 1 == side || j + 1 == side {
                border_sum += v;
                border_n += 1;
            }
        }
    }
    if valid == 0 || total <= 0.0 {
        return None;
    }
    let b = if border_n > 0 {
        (border_sum / border_n as f64).max(0.0)
    } else {
        0.0
    };
    let (mut sx, mut sy, mut s, mut net) = (0.0, 0.0, 0.0, 0.0);
    for j in 0..side {
        for i in 0..side {
            let k = j * side + i;
            if m.ignored(k) {
                continue;
            }
            let v = (data[k] - m.offset(k) + m.shift(k)) / m.gain(k) - b;
            net += v;
            let w = v.max(0.0);
            s += w;
            sx += w * (i as f64 + 0.5);
            sy += w * (j as f64 + 0.5);
        }
    }
    let c = side as f64 / 2.0;
    let (x, y) = if s > 0.0 { (sx / s, sy / s) } else { (c, c) };
    let n = net.max(0.5 * s).max(1.0);
    Some([x, y, n, b])
}

/// True if any pixel that is not ignored holds a NaN or an infinity.
pub(crate) fn has_non_finite<M: PixelModel>(data: &[f64], m: &M) -> bool {
    data.iter()
        .enumerate()
        .any(|(k, v)| !v.is_finite() && !m.ignored(k))
}
