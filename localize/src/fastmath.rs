//! Branch-free `exp`, `erfc` and `ln` for the fit loops.
//!
//! The fits evaluate these on every pixel edge and every pixel of every
//! iteration, four lanes at a time. Two things make them fast there: no
//! branches (so the lanes vectorise) and short dependency chains — the
//! polynomials use Estrin's scheme (depth ~log₂ degree) instead of Horner's
//! (depth = degree), since a fit is limited by latency, not throughput.
//! [`Arith`] selects fused multiply-add where the CPU has it.

/// Multiply-add: fused in the AVX2+FMA build, plain otherwise (`mul_add`
/// without hardware FMA is a slow library call).
pub(crate) trait Arith {
    fn madd(a: f64, b: f64, c: f64) -> f64;
}

/// `a · b + c`, two roundings.
pub(crate) struct Plain;

impl Arith for Plain {
    #[inline(always)]
    fn madd(a: f64, b: f64, c: f64) -> f64 {
        a * b + c
    }
}

/// Fused multiply-add (only used where the CPU has FMA).
#[cfg(target_arch = "x86_64")]
pub(crate) struct Fused;

#[cfg(target_arch = "x86_64")]
impl Arith for Fused {
    #[inline(always)]
    fn madd(a: f64, b: f64, c: f64) -> f64 {
        a.mul_add(b, c)
    }
}

/// Estrin evaluation of `Σ c_k x^k` for up to 17 ascending coefficients
/// (missing high coefficients are zero).
#[inline(always)]
fn estrin<A: Arith, const N: usize>(x: f64, c: &[f64; N]) -> f64 {
    assert!(N <= 17);
    let x2 = x * x;
    let x4 = x2 * x2;
    let x8 = x4 * x4;
    let q0 = A::madd(pair::<A, N>(c, 2, x), x2, pair::<A, N>(c, 0, x));
    if N <= 4 {
        return q0;
    }
    let q1 = A::madd(pair::<A, N>(c, 6, x), x2, pair::<A, N>(c, 4, x));
    let r0 = A::madd(q1, x4, q0);
    if N <= 8 {
        return r0;
    }
    let q2 = A::madd(pair::<A, N>(c, 10, x), x2, pair::<A, N>(c, 8, x));
    let q3 = A::madd(pair::<A, N>(c, 14, x), x2, pair::<A, N>(c, 12, x));
    let r1 = A::madd(q3, x4, q2);
    let s0 = A::madd(r1, x8, r0);
    if N <= 16 {
        return s0;
    }
    A::madd(coef(c, 16), x8 * x8, s0)
}

/// `c_k + c_{k+1} x`.
#[inline(always)]
fn pair<A: Arith, const N: usize>(c: &[f64; N], k: usize, x: f64) -> f64 {
    A::madd(coef(c, k + 1), x, coef(c, k))
}

/// `c_k`, or 0 past the end.
#[inline(always)]
fn coef<const N: usize>(c: &[f64; N], k: usize) -> f64 {
    if k < N {
        c[k]
    } else {
        0.0
    }
}

/// Coefficients of `erfcx(z)·(1 + 0.3 z)` as a polynomial in
/// `t = 1/(1 + 0.3 z)`, ascending (see [`crate::erf`]).
const ERFC_COEF: [f64; 17] = [
    0.169_256_875_063_838_46,
    0.169_256_875_346_349_26,
    0.161_640_288_750_579_6,
    0.146_408_210_811_118_35,
    0.124_565_768_776_707_79,
    0.098_470_014_727_201_88,
    0.068_353_149_291_893_04,
    0.053_563_803_166_146_51,
    -0.015_962_262_646_346_49,
    0.108_529_911_191_800_4,
    -0.206_032_079_053_492_77,
    0.281_454_777_188_790_3,
    -0.283_857_752_269_942_5,
    0.173_349_129_601_539_45,
    -0.056_811_064_231_253_61,
    0.007_850_146_353_275_057,
    -3.579_206_772_751_009_5e-5,
];

/// `erfc(z)` for `z ≥ 0` given `g = exp(−z²)`; relative error below 3e-12
/// (see [`crate::erf`]).
#[inline(always)]
pub(crate) fn erfc_nonneg<A: Arith>(z: f64, g: f64) -> f64 {
    let t = 1.0 / A::madd(0.3, z, 1.0);
    t * estrin::<A, 17>(t, &ERFC_COEF) * g
}

/// Taylor coefficients of `e^r`, ascending, to degree 13.
const EXP_COEF: [f64; 14] = [
    1.0,
    1.0,
    0.5,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5_040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
];

/// `e^x` for `x ∈ [−700, 0]` (clamped): `x = k ln 2 + r` with `|r| ≤ ln2/2`,
/// a degree-13 Taylor polynomial for `e^r` (relative error below 1e-15) and
/// `2^k` built in the exponent bits.
#[inline(always)]
pub(crate) fn exp_nonpositive<A: Arith>(x: f64) -> f64 {
    // 1.5·2^52: adding it rounds to an integer held in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let x = x.clamp(-700.0, 0.0);
    let t = A::madd(x, std::f64::consts::LOG2_E, SHIFT);
    let k = t - SHIFT;
    let r = A::madd(-k, LN2_LO, A::madd(-k, LN2_HI, x));
    // Low 12 bits of (mantissa + 1023) are the biased exponent of 2^k.
    let scale = f64::from_bits(t.to_bits().wrapping_add(1023) << 52);
    estrin::<A, 14>(r, &EXP_COEF) * scale
}

/// Series coefficients of `atanh(s)/s` in `z = s²`, ascending, to `z⁶`.
const LN_COEF: [f64; 7] = [
    1.0,
    1.0 / 3.0,
    1.0 / 5.0,
    1.0 / 7.0,
    1.0 / 9.0,
    1.0 / 11.0,
    1.0 / 13.0,
];

/// `ln x` and `1/x` for a positive, finite, normal `x` with one division:
/// `x = m·2^e`, `m ∈ [√½, √2)`, `ln m = 2 atanh(s)`, `s = (m−1)/(m+1)`,
/// series to `s¹³` (relative error below 2e-12, ample for comparing
/// log-likelihoods); `1/x` to full precision.
#[inline(always)]
pub(crate) fn ln_and_recip<A: Arith>(x: f64) -> (f64, f64) {
    const MANT: u64 = 0x000f_ffff_ffff_ffff;
    const ONE: u64 = 0x3ff0_0000_0000_0000;
    // 2^52 as a bit pattern: OR-ing a small integer into its mantissa and
    // subtracting 2^52 converts it to f64 without an int→float instruction.
    const MAGIC: u64 = 0x4330_0000_0000_0000;
    let bits = x.to_bits();
    let m = f64::from_bits((bits & MANT) | ONE);
    let e = f64::from_bits(MAGIC | (bits >> 52)) - 4_503_599_627_370_496.0 - 1023.0;
    let big = m > std::f64::consts::SQRT_2;
    let m = if big { 0.5 * m } else { m };
    let e = if big { e + 1.0 } else { e };
    let f = m - 1.0;
    let den = 2.0 + f;
    // One division for both: q = 1/(x·den), so 1/x = q·den and 1/den = q·x.
    let q = 1.0 / (x * den);
    let s = f * (q * x);
    let z = s * s;
    let ln = A::madd(
        e,
        std::f64::consts::LN_2,
        2.0 * s * estrin::<A, 7>(z, &LN_COEF),
    );
    (ln, q * den)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_matches_std() {
        let mut worst = 0.0f64;
        for k in 0..=70_000 {
            let x = -(k as f64) * 0.01;
            worst = worst.max((exp_nonpositive::<Plain>(x) / x.exp() - 1.0).abs());
        }
        assert!(worst < 1e-15, "{worst}");
        assert_eq!(exp_nonpositive::<Plain>(0.0), 1.0);
    }

    #[test]
    fn erfc_matches_horner_version() {
        for k in 0..=2600 {
            let z = k as f64 * 0.01;
            let g = (-z * z).exp();
            let a = erfc_nonneg::<Plain>(z, g);
            let b = crate::erf::erfc_nonneg_with_gauss(z, g);
            assert!((a / b - 1.0).abs() < 1e-13 || b == 0.0, "z={z}: {a} vs {b}");
        }
    }

    #[test]
    fn ln_and_reciprocal() {
        let mut worst = 0.0f64;
        let mut x = 1e-12;
        while x < 1e12 {
            let (l, r) = ln_and_recip::<Plain>(x);
            worst = worst.max((l - x.ln()).abs() / x.ln().abs().max(1.0));
            assert!((r * x - 1.0).abs() < 1e-15);
            x *= 1.0137;
        }
        assert!(worst < 2e-12, "{worst}");
        assert_eq!(ln_and_recip::<Plain>(1.0).0, 0.0);
    }
}
