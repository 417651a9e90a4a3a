//! Small dense symmetric positive-definite solves (P ≤ 5), on the stack.
//!
//! LDLᵀ factorisation without square roots, with the reciprocal of each
//! pivot computed once: a fit solves one such system per iteration, and the
//! chain of square roots and divisions of a plain Cholesky factorisation is
//! a measurable part of a 9×9 fit. A pivot below 1e-13 of its diagonal entry
//! means the matrix is singular to working precision (this test does not
//! depend on the parameters' units).

/// Solves `A δ = b` for symmetric positive-definite `A`; `None` when `A` is
/// not (numerically) positive definite or anything is non-finite.
#[inline(always)]
pub fn solve_spd<const P: usize>(a: &[[f64; P]; P], b: &[f64; P]) -> Option<[f64; P]> {
    let (l, dinv) = ldl(a)?;
    let x = ldl_substitute(&l, &dinv, b);
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Inverse of a symmetric positive-definite matrix (the Cramér–Rao bound from
/// a Fisher information matrix); `None` when singular.
pub fn invert_spd<const P: usize>(a: &[[f64; P]; P]) -> Option<[[f64; P]; P]> {
    let (l, dinv) = ldl(a)?;
    let mut inv = [[0.0; P]; P];
    for c in 0..P {
        let mut e = [0.0; P];
        e[c] = 1.0;
        let z = ldl_substitute(&l, &dinv, &e);
        for r in 0..P {
            if !z[r].is_finite() {
                return None;
            }
            inv[r][c] = z[r];
        }
    }
    Some(inv)
}

/// Unit lower-triangular `L` and reciprocal pivots `1/D` with `A = L D Lᵀ`.
#[inline(always)]
#[allow(clippy::type_complexity)]
fn ldl<const P: usize>(a: &[[f64; P]; P]) -> Option<([[f64; P]; P], [f64; P])> {
    let mut l = [[0.0; P]; P];
    let mut d = [0.0; P];
    let mut dinv = [0.0; P];
    for j in 0..P {
        let ajj = a[j][j];
        if !(ajj > 0.0 && ajj.is_finite()) {
            return None;
        }
        let mut dj = ajj;
        for k in 0..j {
            dj -= l[j][k] * l[j][k] * d[k];
        }
        if !(dj > 1e-13 * ajj) {
            return None;
        }
        d[j] = dj;
        dinv[j] = 1.0 / dj;
        l[j][j] = 1.0;
        for i in j + 1..P {
            let mut s = a[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k] * d[k];
            }
            l[i][j] = s * dinv[j];
        }
    }
    Some((l, dinv))
}

#[inline(always)]
fn ldl_substitute<const P: usize>(l: &[[f64; P]; P], dinv: &[f64; P], b: &[f64; P]) -> [f64; P] {
    let mut y = [0.0; P];
    for i in 0..P {
        let mut sum = b[i];
        for k in 0..i {
            sum -= l[i][k] * y[k];
        }
        y[i] = sum;
    }
    let mut x = [0.0; P];
    for i in (0..P).rev() {
        let mut sum = y[i] * dinv[i];
        for k in i + 1..P {
            sum -= l[k][i] * x[k];
        }
        x[i] = sum;
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
