//! Small dense symmetric positive-definite solves (P ≤ 5), on the stack.
//!
//! Fit parameters have very different scales (photons ~ 10³, positions ~ 1),
//! so every solve first applies the Jacobi scaling `D^-½ A D^-½`, which makes
//! the Cholesky factorisation insensitive to units.

/// Solves `A δ = b` for symmetric positive-definite `A`; `None` when `A` is
/// not (numerically) positive definite or anything is non-finite.
#[inline(always)]
pub fn solve_spd<const P: usize>(a: &[[f64; P]; P], b: &[f64; P]) -> Option<[f64; P]> {
    let (l, s) = scaled_cholesky(a)?;
    let mut y = [0.0; P];
    for i in 0..P {
        y[i] = b[i] * s[i];
    }
    let z = cholesky_substitute(&l, &y);
    let mut out = [0.0; P];
    for i in 0..P {
        out[i] = z[i] * s[i];
        if !out[i].is_finite() {
            return None;
        }
    }
    Some(out)
}

/// Inverse of a symmetric positive-definite matrix (the Cramér–Rao bound from
/// a Fisher information matrix); `None` when singular.
pub fn invert_spd<const P: usize>(a: &[[f64; P]; P]) -> Option<[[f64; P]; P]> {
    let (l, s) = scaled_cholesky(a)?;
    let mut inv = [[0.0; P]; P];
    for c in 0..P {
        let mut e = [0.0; P];
        e[c] = 1.0;
        let z = cholesky_substitute(&l, &e);
        for r in 0..P {
            inv[r][c] = z[r] * s[r] * s[c];
            if !inv[r][c].is_finite() {
                return None;
            }
        }
    }
    Some(inv)
}

/// Cholesky factor of the Jacobi-scaled matrix, and the scale `1/√A_ii`.
#[inline(always)]
fn scaled_cholesky<const P: usize>(a: &[[f64; P]; P]) -> Option<([[f64; P]; P], [f64; P])> {
    let mut s = [0.0; P];
    for i in 0..P {
        let d = a[i][i];
        if !(d > 0.0 && d.is_finite()) {
            return None;
        }
        s[i] = 1.0 / d.sqrt();
    }
    let mut l = [[0.0; P]; P];
    for i in 0..P {
        for j in 0..=i {
            let mut sum = a[i][j] * s[i] * s[j];
            for k in 0..j {
                sum -= l[i][k] * l[j][k];
            }
            if i == j {
                // Relative pivot floor: a pivot this small means the scaled
                // matrix is singular to working precision.
                if !(sum > 1e-13) {
                    return None;
                }
                l[i][i] = sum.sqrt();
            } else {
                l[i][j] = sum / l[j][j];
            }
        }
    }
    Some((l, s))
}

#[inline(always)]
fn cholesky_substitute<const P: usize>(l: &[[f64; P]; P], b: &[f64; P]) -> [f64; P] {
    let mut y = [0.0; P];
    for i in 0..P {
        let mut sum = b[i];
        for k in 0..i {
            sum -= l[i][k] * y[k];
        }
        y[i] = sum / l[i][i];
    }
    let mut x = [0.0; P];
    for i in (0..P).rev() {
        let mut sum = y[i];
        for k in i + 1..P {
            sum -= l[k][i] * x[k];
        }
        x[i] = sum / l[i][i];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_and_inverts_badly_scaled_matrices() {
        let a = [
            [4.0, 1e3 * 0.5, 0.2],
            [1e3 * 0.5, 1e6 * 3.0, 1e3 * 0.1],
            [0.2, 1e3 * 0.1, 2.0],
        ];
        let b = [1.0, 2.0e3, -0.5];
        let x = solve_spd(&a, &b).unwrap();
        for i in 0..3 {
            let r: f64 = (0..3).map(|k| a[i][k] * x[k]).sum::<f64>() - b[i];
            assert!(r.abs() < 1e-9 * b[i].abs().max(1.0));
        }
        let inv = invert_spd(&a).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| a[i][k] * inv[k][j]).sum();
                assert!((p - if i == j { 1.0 } else { 0.0 }).abs() < 1e-9);
            }
        }
        assert!(invert_spd(&[[1.0, 1.0], [1.0, 1.0]]).is_none());
        assert!(invert_spd(&[[0.0, 0.0], [0.0, 1.0]]).is_none());
        assert!(solve_spd(&[[f64::NAN]], &[1.0]).is_none());
    }
}
