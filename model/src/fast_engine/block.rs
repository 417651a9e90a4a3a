//! The fast front end's kernels on a few cells at a time: a footprint's
//! row of `±K` (stage 2), the compares of eight pixels with the two levels
//! and their neighbours (stages 3–4), the below-level test of a run of
//! pixels, and the appends of the pixels found. Each has a portable form
//! and, on x86-64, an AVX2 one that the AVX2 build of
//! [`FastFrontEnd`](super::FastFrontEnd) inlines (the AVX2 forms are
//! `#[inline]`: without it the front end, in another module, called them
//! and ran 3–5 % slower).

use super::above::AboveHold;
use super::AVX2;
use crate::candidates::Candidate;

/// `row += w` for one kernel row, as 8-, 4- and 1-lane pieces so that the
/// compiler emits whole vector adds.
#[inline(always)]
pub(super) fn add_row<const K: usize>(row: &mut [u32; K], w: &[u32; K]) {
    let mut i = 0;
    while i + 8 <= K {
        add_lanes::<8>(&mut row[i..], &w[i..]);
        i += 8;
    }
    while i + 4 <= K {
        add_lanes::<4>(&mut row[i..], &w[i..]);
        i += 4;
    }
    while i < K {
        add_lanes::<1>(&mut row[i..], &w[i..]);
        i += 1;
    }
}

/// `row[..L] += w[..L]`, loaded into registers before it is stored: after
/// inlining the compiler cannot tell that `row` and `w` do not overlap, and
/// would otherwise keep the adds scalar.
#[inline(always)]
fn add_lanes<const L: usize>(row: &mut [u32], w: &[u32]) {
    let mut r: [u32; L] = row[..L].try_into().expect("L lanes");
    let v: [u32; L] = w[..L].try_into().expect("L lanes");
    for l in 0..L {
        r[l] = r[l].wrapping_add(v[l]);
    }
    row[..L].copy_from_slice(&r);
}

/// Stages 3–4 for the eight pixels from `x0` of row `y` (`c0`: the row's
/// first cell in the haloed H, `w` the field's width, `s` the stride):
/// appends those at or above `thr` (hold) to `above`, and the local maxima
/// at or above `open` to `candidates`. A function, not a closure, so that it
/// is inlined into each instruction set's build with its compares.
#[inline(always)]
pub(super) fn scan_block<const ISA: u8>(
    f: &[u32],
    above: &mut AboveHold,
    candidates: &mut Vec<Candidate>,
    (y, w, s): (usize, usize, usize),
    c0: usize,
    x0: usize,
    (thr, open): (u32, u32),
) {
    #[cfg(target_arch = "x86_64")]
    let (ab, cands) = if ISA >= AVX2 {
        // SAFETY: ISA ≥ AVX2 only inside `push_words_avx2`, which runs
        // only when the CPU has AVX2.
        unsafe { block8_avx2(f, c0 + x0, s, (thr, open)) }
    } else {
        block8(f, c0 + x0, s, (thr, open))
    };
    #[cfg(not(target_arch = "x86_64"))]
    let (ab, cands) = block8(f, c0 + x0, s, (thr, open));
    #[cfg(target_arch = "x86_64")]
    if ISA >= AVX2 {
        // SAFETY: as above.
        unsafe { push_bits8_avx2(&mut above.pixels, ab, (y * w + x0) as u32) };
    } else {
        push_bits(&mut above.pixels, ab, y * w + x0, |i| i as u32);
    }
    #[cfg(not(target_arch = "x86_64"))]
    push_bits(&mut above.pixels, ab, y * w + x0, |i| i as u32);
    above.set_bits8(ab, y * w + x0);
    push_bits(candidates, cands, x0, |x| Candidate {
        x: x as u16,
        y: y as u16,
    });
}

/// Eight pixels from cell `c` of the haloed H (row stride `s`): the bit
/// masks of those at or above `thr` (hold), and of the candidates: at or
/// above `thr` and `open`, strictly above their four earlier neighbours in
/// raster order and at least their four later ones. The neighbours are read
/// only if a pixel reaches both levels (in a crowded field most pixels at
/// the hold level are below the open level). Lane-wise, so that it compiles
/// to vector compares.
#[inline(always)]
fn block8(f: &[u32], c: usize, s: usize, (thr, open): (u32, u32)) -> (u32, u32) {
    let load = |at: usize| -> [u32; 8] { f[at..at + 8].try_into().expect("8 lanes") };
    let v = load(c);
    let (mut above, mut opened) = (0u32, 0u32);
    for (l, &x) in v.iter().enumerate() {
        above |= u32::from(x >= thr) << l;
        opened |= u32::from(x >= open) << l;
    }
    let opened = above & opened;
    if opened == 0 {
        return (above, 0);
    }
    let (ul, u, ur, le) = (load(c - s - 1), load(c - s), load(c - s + 1), load(c - 1));
    let (ri, dl, d, dr) = (load(c + 1), load(c + s - 1), load(c + s), load(c + s + 1));
    let mut max = 0u32;
    for l in 0..8 {
        let m = (v[l] > ul[l])
            & (v[l] > u[l])
            & (v[l] > ur[l])
            & (v[l] > le[l])
            & (v[l] >= ri[l])
            & (v[l] >= dl[l])
            & (v[l] >= d[l])
            & (v[l] >= dr[l]);
        max |= u32::from(m) << l;
    }
    (above, opened & max)
}

/// [`block8`] with AVX2 compares and move-masks (the compiler's own
/// vectorisation of the lane loops builds the masks lane by lane). Unsigned
/// order is signed order after flipping the sign bit. The neighbours are
/// compared whenever a pixel reaches the hold level: a branch on the open
/// level too was slower in the dense scene (mispredicted) than the compares
/// it saved.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn block8_avx2(f: &[u32], c: usize, s: usize, (thr, open): (u32, u32)) -> (u32, u32) {
    use std::arch::x86_64::*;
    #[target_feature(enable = "avx2")]
    fn load(f: &[u32], at: usize) -> __m256i {
        let lanes = &f[at..at + 8];
        // SAFETY: `lanes` is 8 u32 = 32 readable bytes; the load is unaligned.
        let v = unsafe { _mm256_loadu_si256(lanes.as_ptr().cast()) };
        _mm256_xor_si256(v, _mm256_set1_epi32(i32::MIN))
    }
    #[target_feature(enable = "avx2")]
    fn mask(v: __m256i) -> u32 {
        _mm256_movemask_ps(_mm256_castsi256_ps(v)) as u32
    }
    let v = load(f, c);
    let t = _mm256_set1_epi32((thr ^ 0x8000_0000) as i32);
    // v ≥ thr ⇔ not (thr > v).
    let above = !mask(_mm256_cmpgt_epi32(t, v)) & 0xff;
    if above == 0 {
        return (0, 0);
    }
    let o = _mm256_set1_epi32((open ^ 0x8000_0000) as i32);
    let opened = above & !mask(_mm256_cmpgt_epi32(o, v));
    let earlier = _mm256_and_si256(
        _mm256_and_si256(
            _mm256_cmpgt_epi32(v, load(f, c - s - 1)),
            _mm256_cmpgt_epi32(v, load(f, c - s)),
        ),
        _mm256_and_si256(
            _mm256_cmpgt_epi32(v, load(f, c - s + 1)),
            _mm256_cmpgt_epi32(v, load(f, c - 1)),
        ),
    );
    // A later neighbour breaks the maximum only if it is strictly greater.
    let later_greater = _mm256_or_si256(
        _mm256_or_si256(
            _mm256_cmpgt_epi32(load(f, c + 1), v),
            _mm256_cmpgt_epi32(load(f, c + s - 1), v),
        ),
        _mm256_or_si256(
            _mm256_cmpgt_epi32(load(f, c + s), v),
            _mm256_cmpgt_epi32(load(f, c + s + 1), v),
        ),
    );
    let max = mask(_mm256_andnot_si256(later_greater, earlier));
    (above, opened & max)
}

/// [`below`] in `ISA`'s build.
#[inline(always)]
pub(super) fn below_run<const ISA: u8, const B: usize>(f: &[u32], c: usize, thr: u32) -> bool {
    #[cfg(target_arch = "x86_64")]
    if ISA >= AVX2 {
        // SAFETY: ISA ≥ AVX2 only inside `push_words_avx2`, which runs only
        // when the CPU has AVX2.
        return unsafe { below_avx2::<B>(f, c, thr) };
    }
    below::<B>(f, c, thr)
}

/// The set bits of every byte, ascending, then zeros: `PACKED[m][..k]` are
/// the k bits of `m`.
const PACKED: [[u32; 8]; 256] = {
    let mut t = [[0u32; 8]; 256];
    let mut m = 0;
    while m < 256 {
        let (mut k, mut b) = (0, 0);
        while b < 8 {
            if m & (1 << b) != 0 {
                t[m][k] = b as u32;
                k += 1;
            }
            b += 1;
        }
        m += 1;
    }
    t
};

/// [`push_bits`] of the eight low bits of `bits` as `offset + i`, with one
/// 8-lane store and a length step: in a crowded field most blocks have
/// several pixels at the hold level, and a push per pixel cost more than
/// the compares that found them.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn push_bits8_avx2(out: &mut Vec<u32>, bits: u32, offset: u32) {
    use std::arch::x86_64::*;
    let bits = bits & 0xff;
    if bits == 0 {
        return;
    }
    out.reserve(8);
    let len = out.len();
    let lanes = &PACKED[bits as usize];
    // SAFETY: `lanes` is 8 u32 = one unaligned 32-byte load; `reserve(8)`
    // made room for 8 u32 from `len`, of which the first `popcount` are
    // written values and become part of the vector.
    unsafe {
        let v = _mm256_add_epi32(
            _mm256_loadu_si256(lanes.as_ptr().cast()),
            _mm256_set1_epi32(offset as i32),
        );
        _mm256_storeu_si256(out.as_mut_ptr().add(len).cast(), v);
        out.set_len(len + bits.count_ones() as usize);
    }
}

/// Pushes `make(offset + i)` for every set bit i of `bits`, ascending.
#[inline(always)]
fn push_bits<T>(out: &mut Vec<T>, mut bits: u32, offset: usize, make: impl Fn(usize) -> T) {
    while bits != 0 {
        out.push(make(offset + bits.trailing_zeros() as usize));
        bits &= bits - 1;
    }
}

/// Whether all `B` cells from `c` are below `thr` (`B` a multiple of 8):
/// lane-wise maxima, reduced once.
#[inline(always)]
fn below<const B: usize>(f: &[u32], c: usize, thr: u32) -> bool {
    let g: &[u32; B] = f[c..c + B].try_into().expect("B cells");
    let mut m = [0u32; 8];
    for group in g.chunks_exact(8) {
        for l in 0..8 {
            m[l] = m[l].max(group[l]);
        }
    }
    m.iter().fold(0, |a, &v| a.max(v)) < thr
}

/// [`below`] with AVX2 unsigned maxima and one compare.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn below_avx2<const B: usize>(f: &[u32], c: usize, thr: u32) -> bool {
    use std::arch::x86_64::*;
    let g: &[u32; B] = f[c..c + B].try_into().expect("B cells");
    if thr == 0 {
        return false;
    }
    let p = g.as_ptr().cast::<__m256i>();
    // SAFETY: `g` is B u32 = B / 8 unaligned 32-byte loads.
    let mut m = unsafe { _mm256_loadu_si256(p) };
    for i in 1..B / 8 {
        m = _mm256_max_epu32(m, unsafe { _mm256_loadu_si256(p.add(i)) });
    }
    // Every lane < thr ⇔ max(lane, thr − 1) = thr − 1.
    let t = _mm256_set1_epi32((thr - 1) as i32);
    _mm256_movemask_epi8(_mm256_cmpeq_epi32(_mm256_max_epu32(m, t), t)) == -1
}
