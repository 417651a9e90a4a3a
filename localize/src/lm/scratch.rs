//! The per-thread work space of a fit: its layout, borrowing it, and
//! filling its input arrays from the ROI once per fit.

use super::lanes::LANES;
use super::model::PixelModel;
use crate::fit::FitStatus;
use crate::psf::AxisTerms;

/// A thread's work space: the pixel arrays and the 1-D terms of both axes,
/// allocated once per thread and reused by every fit (nothing is allocated
/// or cleared per fit).
pub(super) struct Scratch {
    pub(super) buf: Vec<f64>,
    pub(super) ax: AxisTerms,
    pub(super) ay: AxisTerms,
}

thread_local! {
    static SCRATCH: std::cell::Cell<Option<Box<Scratch>>> = const { std::cell::Cell::new(None) };
}

/// Layout of the pixel arrays: the ROI's pixels row-major and flat, padded
/// to a whole number of blocks; padding lanes are masked out.
#[derive(Clone, Copy)]
pub(super) struct Layout {
    pub(super) side: usize,
    /// Entries visited, `side²` rounded up to a multiple of [`LANES`].
    pub(super) nb: usize,
    /// Entries per array: `nb` plus one block of slack, so that rows of
    /// tiles can be written in whole blocks (a row's last block spills into
    /// the next row, which is written after it, or into the slack).
    pub(super) np: usize,
}

impl Layout {
    #[inline(always)]
    pub(super) fn new(side: usize) -> Layout {
        let nb = (side * side).div_ceil(LANES) * LANES;
        Layout {
            side,
            nb,
            np: nb + LANES,
        }
    }
}

/// Number of input arrays: data (+ shift), gain, offset, use.
pub(super) const INPUTS: usize = 4;
/// Number of per-iteration arrays of the separable model: the column terms
/// `Ex, ∂Ex/∂x, ∂Ex/∂σ` and row terms `Ey, ∂Ey/∂y, ∂Ey/∂σ` of every pixel.
pub(super) const TILES: usize = 6;

/// Borrows this thread's scratch, with room for the input arrays, tiles and
/// the `1 + params` output arrays (weights, derivatives) of [`Layout`]. Give
/// it back with [`return_scratch`]. (No closure runs the fit: closures would
/// not inherit the AVX2 build.)
#[inline(always)]
pub(super) fn take_scratch(lay: Layout, params: usize) -> Box<Scratch> {
    let mut s = SCRATCH.with(|c| c.take()).unwrap_or_else(|| {
        Box::new(Scratch {
            buf: Vec::new(),
            ax: AxisTerms::default(),
            ay: AxisTerms::default(),
        })
    });
    let need = lay.np * (INPUTS + TILES + 1 + params);
    if s.buf.len() < need {
        s.buf.resize(need, 0.0);
    }
    s
}

#[inline(always)]
pub(super) fn return_scratch(s: Box<Scratch>) {
    SCRATCH.with(|c| c.set(Some(s)));
}

/// Copies the ROI into the input arrays once per fit — data plus shift (0
/// where ignored: NaN in an ignored pixel never reaches a sum), gain,
/// offset, and use (1 or 0); padding lanes get use 0 and a harmless μ > 0,
/// and the padding of the tile arrays is zeroed — and computes the starting
/// values of [`initial_guess`] on the way. Errors: a non-finite pixel that
/// is not ignored, or no counts at all.
///
/// [`initial_guess`]: super::model::initial_guess
#[inline(always)]
pub(super) fn prepare<M: PixelModel>(
    data: &[f64],
    m: &M,
    lay: Layout,
    scratch: &mut [f64],
) -> Result<[f64; 4], FitStatus> {
    let np = lay.np;
    let side = lay.side;
    let n = side * side;
    let (dp, rest) = scratch[..(INPUTS + TILES) * np].split_at_mut(np);
    let (gp, rest) = rest.split_at_mut(np);
    let (op, rest) = rest.split_at_mut(np);
    let (up, tiles) = rest.split_at_mut(np);
    let data = &data[..n];
    let (mut border_sum, mut border_n, mut total, mut valid) = (0.0, 0usize, 0.0, 0usize);
    let mut finite = true;
    for j in 0..side {
        let edge_row = j == 0 || j + 1 == side;
        for i in 0..side {
            let k = j * side + i;
            let used = !m.ignored(k);
            let v = data[k];
            finite &= !used || v.is_finite();
            dp[k] = if used { v + m.shift(k) } else { 0.0 };
            gp[k] = m.gain(k);
            op[k] = m.offset(k);
            up[k] = if used { 1.0 } else { 0.0 };
            if used {
                total += v.max(0.0);
                valid += 1;
                if edge_row || i == 0 || i + 1 == side {
                    border_sum += (dp[k] - op[k]) / gp[k];
                    border_n += 1;
                }
            }
        }
    }
    if !finite {
        return Err(FitStatus::NonFiniteInput);
    }
    if valid == 0 || !(total > 0.0) {
        return Err(FitStatus::NoSignal);
    }
    dp[n..].fill(0.0);
    gp[n..].fill(1.0);
    op[n..].fill(1.0);
    up[n..].fill(0.0);
    for t in 0..TILES {
        tiles[t * np + n..(t + 1) * np].fill(0.0);
    }
    let b = if border_n > 0 {
        (border_sum / border_n as f64).max(0.0)
    } else {
        0.0
    };
    let (mut sx, mut sy, mut s, mut net) = (0.0, 0.0, 0.0, 0.0);
    for j in 0..side {
        let mut row = 0.0;
        for i in 0..side {
            let k = j * side + i;
            let v = if M::UNIFORM {
                dp[k] - b
            } else {
                ((dp[k] - op[k]) / gp[k] - b) * up[k]
            };
            net += v;
            let w = v.max(0.0);
            row += w;
            sx += w * (i as f64 + 0.5);
        }
        s += row;
        sy += row * (j as f64 + 0.5);
    }
    let c = side as f64 / 2.0;
    let (x, y) = if s > 0.0 { (sx / s, sy / s) } else { (c, c) };
    Ok([x, y, net.max(0.5 * s).max(1.0), b])
}
