//! The scalar kernels of the lag sums: `exp(-x)` without branches, whole powers, the first
//! eight powers and the chunks' multipliers, and a vector `s += a p`.

/// Powers below this are taken as zero (with the rest of a term's lags).
pub(super) const TINY: f64 = 1e-280;

/// `r^n` by repeated squaring (no fused multiply-adds: the same on every instruction set).
#[inline]
pub(super) fn whole_power(r: f64, mut n: usize) -> f64 {
    if n == 2 {
        // (The same product as below, without the loop: a multi-tau grid's levels.)
        return r * r;
    }
    let (mut acc, mut sq) = (1.0, r);
    while n > 0 {
        if n & 1 == 1 {
            acc *= sq;
        }
        sq *= sq;
        n >>= 1;
    }
    acc
}

/// The first eight powers `r, r^2, ..., r^8` (products at most three deep).
#[inline(always)]
pub(super) fn first_eight(r: f64) -> [f64; 8] {
    let r2 = r * r;
    let r4 = r2 * r2;
    [r, r2, r2 * r, r4, r4 * r, r4 * r2, r4 * r2 * r, r4 * r4]
}

/// Fills `ms` (whole blocks of eight) with the multipliers `r^(8 j)` of the chunks of eight
/// powers, `r^(64 b)` times one of `1, r^8, ..., r^56` (formed as [`first_eight`] of
/// `r8 = r^8`), so that successive chunks are one product apart from a power that changes once
/// per eight chunks; returns how many chunks do not underflow (whose leading power
/// `lead r^(8 j)`, `lead = r <= 1`, is at least [`TINY`]).
#[inline(always)]
pub(super) fn multipliers(ms: &mut [f64], lead: f64, r8: f64) -> usize {
    let e8 = first_eight(r8);
    let mut big = 1.0;
    let mut live = 0;
    for block in ms.chunks_exact_mut(8) {
        let mut b = [big; 8];
        for (m, x) in b[1..].iter_mut().zip(&e8) {
            *m = big * x;
        }
        block.copy_from_slice(&b);
        // Counted in registers (the multipliers decrease).
        live += b.iter().filter(|&&m| lead * m >= TINY).count();
        big *= e8[7];
    }
    live
}

/// `1 / k!`: the Taylor coefficients of [`exp_neg`] and of the slot sums' small factors.
pub(super) const INV_FACT: [f64; 14] = [
    1.0,
    1.0,
    1.0 / 2.0,
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

/// `exp(-x)` for `x >= 0` to about one ulp, or zero where it is below `exp(-700)` (far below
/// [`TINY`]): without branches or calls, so that a loop of them vectorises. The
/// reduction `-x = n ln 2 + f`, `|f| <= ln 2 / 2`, with `ln 2` in two parts (the first exact
/// times any `n` here), then `e^f` by its Taylor polynomial of degree 13 (remainder below
/// `5e-18`) and `2^n` from its exponent bits.
#[inline(always)]
pub(crate) fn exp_neg(x: f64) -> f64 {
    /// `1.5 2^52`: adding it rounds to a whole number, held in the low bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    /// `ln 2` in two parts: the first with 32 significant bits (so `n LN2_HI` is exact), the
    /// second the rest.
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let y = -x.min(700.0);
    let t = y * std::f64::consts::LOG2_E + ROUND;
    let n = t - ROUND;
    let f = (y - n * LN2_HI) - n * LN2_LO;
    let mut p = INV_FACT[13];
    for c in INV_FACT[..13].iter().rev() {
        p = p * f + c;
    }
    // `n >= -1010`: `2^n` is a normal number.
    let k = t.to_bits().wrapping_sub(ROUND.to_bits()) as i64;
    let scale = f64::from_bits(((k + 1023) as u64) << 52);
    if x > 700.0 { 0.0 } else { p * scale }
}

/// `s += a p`, element by element.
#[inline(always)]
pub(super) fn scale_add<S: pulp::Simd>(simd: S, s: &mut [f64], p: &[f64], a: f64) {
    let (sv, st) = S::as_mut_simd_f64s(s);
    let (pv, pt) = S::as_simd_f64s(p);
    let av = simd.splat_f64s(a);
    for (s, p) in sv.iter_mut().zip(pv) {
        *s = simd.add_f64s(*s, simd.mul_f64s(av, *p));
    }
    for (s, p) in st.iter_mut().zip(pt) {
        *s += a * p;
    }
}
