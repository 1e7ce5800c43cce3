//! Branch-free `f64` exponential and sine/cosine that the compiler vectorises.
//!
//! Every connection of a path vertex to an endpoint costs one attenuation `exp(-tau / 2)` and one
//! phase factor `exp(i k L)`. The standard library's `exp` and `sin_cos` are scalar calls, which
//! keep the connection loops of [`crate::Endpoints`] from being vectorised; the kernels here are
//! written with only arithmetic, comparisons and bit operations (no branches, no table look-ups,
//! no integer conversions), so that a loop over arrays of arguments compiles to packed SIMD
//! instructions on the portable `x86-64` baseline (SSE2, two lanes) and wider on targets with
//! AVX2 or AVX-512. The connection kernels built on them, [`crate::Endpoints`] (a list of sources
//! or sensors prepared for connecting many points) and its output [`crate::Legs`], are re-exported
//! here.
//!
//! - [`exp`]: `2^n * p(r)` with `n = round(x / ln 2)`, `r = x - n ln 2` (Cody-Waite, two-part
//!   `ln 2`), and `p` the degree-13 Taylor polynomial of `e^r` on `|r| <= ln 2 / 2` (truncation
//!   error below `5e-18`), evaluated as `1 + r q(r)` with `q` by Estrin's scheme (a short
//!   dependency chain: with Horner's 13 dependent steps the loop was latency-bound and slower
//!   than the library); the scale `2^n` is applied as two powers of two, so that results down
//!   to the subnormal range are right. Measured against `f64::exp` on 4 million arguments in
//!   `[-745, 709]`, `[-40, 0]`, `[-1, 1]` and the subnormal range: at most 1 ulp apart.
//! - [`sin_cos`]: `n = round(x * 2 / pi)`, `r = x - n pi / 2` with a three-part Cody-Waite
//!   `pi / 2` (the first two parts have 30 significant bits, so `n * P1` and `n * P2` are exact
//!   for `|n| < 2^23`), the minimax polynomials of fdlibm's `__kernel_sin` / `__kernel_cos` on
//!   `|r| <= pi / 4` (inner sums by Estrin's scheme), and the quadrant `n mod 4` applied by
//!   swapping and sign flips. Valid for `|x| <= SIN_COS_MAX` (`2^23`, about `8.4e6` rad);
//!   [`sin_cos`] and [`sin_cos_slice`] fall back to the standard library beyond it (and for NaN
//!   and infinities). Measured against `f64::sin_cos` on 6 million arguments (uniform on
//!   `|x| < pi`, `100`, `1e5`, `1e6`, `2^23` and log-uniform from `1e-300`): at most 2 ulp and
//!   `2.4e-16` relative apart where `|sin|`, `|cos| >= 1e-3`, and at most `1.2e-16` apart in
//!   absolute value everywhere (the phase factor `e^{i phi}` is exact to a rounding error).
//!   Next to multiples of `pi / 2` tiny results keep their relative accuracy (`sin(pi)`,
//!   `sin(1e5 pi)` to `1e-12` relative).
//!
//! Rounding to the nearest integer uses the `1.5 * 2^52` shifter: `(y + S) - S` rounds `y` to an
//! integer in the default rounding mode, and the low bits of `y + S` hold that integer in two's
//! complement, so the quadrant and the exponent come out with bit operations alone.
//!
//! ```
//! use speckle_endpoints::fastmath;
//! let (s, c) = fastmath::sin_cos(1.0e5);
//! assert!((s - 1.0e5f64.sin()).abs() < 1e-15 && (c - 1.0e5f64.cos()).abs() < 1e-15);
//! assert!((fastmath::exp(-3.5) / (-3.5f64).exp() - 1.0).abs() < 1e-15);
//! ```

/// `1.5 * 2^52`: adding and subtracting it rounds a double of magnitude below `2^51` to an
/// integer (round half to even).
const SHIFTER: f64 = 6_755_399_441_055_744.0;

/// The largest `|x|` for which the reduction of [`sin_cos`] is exact enough (`2^23`).
pub const SIN_COS_MAX: f64 = 8_388_608.0;

/// `2 / pi`.
const TWO_OVER_PI: f64 = std::f64::consts::FRAC_2_PI;
/// `pi / 2 = P1 + P2 + P3 + O(5e-36)`; `P1`, `P2` have 30 significant bits
/// (`0x3ff921fb54800000`, `0xbe0de973dc800000`).
const PIO2_1: f64 = 1.570_796_327_665_448_2;
const PIO2_2: f64 = -8.705_515_692_000_731e-10;
const PIO2_3: f64 = -3.503_434_398_089_93e-19;

// fdlibm k_sin.c / k_cos.c minimax coefficients (|error| < 2^-58 on |r| <= pi/4).
const S1: f64 = -0.16666666666666632;
const S2: f64 = 0.00833333333332249;
const S3: f64 = -0.0001984126982985795;
const S4: f64 = 2.7557313707070068e-06;
const S5: f64 = -2.5050760253406863e-08;
const S6: f64 = 1.58969099521155e-10;
const C1: f64 = 0.0416666666666666;
const C2: f64 = -0.001388888888887411;
const C3: f64 = 2.480158728947673e-05;
const C4: f64 = -2.7557314351390663e-07;
const C5: f64 = 2.087572321298175e-09;
const C6: f64 = -1.1359647557788195e-11;

/// `1 / ln 2`.
const LOG2_E: f64 = std::f64::consts::LOG2_E;
/// `ln 2 = LN2_HI + LN2_LO + O(1.3e-27)`; `LN2_HI` has 29 significant bits
/// (`0x3fe62e42ff000000`), so `n * LN2_HI` is exact for `|n| < 2^24`.
const LN2_HI: f64 = 0.693_147_180_601_954_5;
const LN2_LO: f64 = -4.200_915_072_681_084_6e-11;
/// Below this `exp` underflows to zero, above the other bound it overflows; clamping the
/// argument keeps the exponent arithmetic in range.
const EXP_LO: f64 = -1080.0;
const EXP_HI: f64 = 710.0;

/// `e^x`, branch-free (see the module documentation for the method and its accuracy): at most
/// 1 ulp from the correctly rounded value, `0` below `-745.2`, `+inf` above `709.8`, NaN for NaN.
#[inline(always)]
pub fn exp(x: f64) -> f64 {
    // Comparisons written so that NaN passes through unchanged.
    let x = if x < EXP_LO { EXP_LO } else { x };
    let x = if x > EXP_HI { EXP_HI } else { x };
    let t = x * LOG2_E + SHIFTER;
    let n = t - SHIFTER;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // e^r = 1 + r q(r), q(r) = sum_{i=0}^{12} r^i / (i + 1)! (the Taylor polynomial of degree
    // 13), q by Estrin's scheme: a short dependency chain, so that the out-of-order core
    // overlaps many elements (Horner's 13 dependent steps made the loop latency-bound).
    let r2 = r * r;
    let r4 = r2 * r2;
    let r8 = r4 * r4;
    let a0 = 1.0 + r * 0.5;
    let a1 = 1.0 / 6.0 + r * (1.0 / 24.0);
    let a2 = 1.0 / 120.0 + r * (1.0 / 720.0);
    let a3 = 1.0 / 5_040.0 + r * (1.0 / 40_320.0);
    let a4 = 1.0 / 362_880.0 + r * (1.0 / 3_628_800.0);
    let a5 = 1.0 / 39_916_800.0 + r * (1.0 / 479_001_600.0);
    let a6 = 1.0 / 6_227_020_800.0;
    let b0 = a0 + a1 * r2;
    let b1 = a2 + a3 * r2;
    let b2 = a4 + a5 * r2;
    let c0 = b0 + b1 * r4;
    let c1 = b2 + a6 * r4;
    let q = c0 + c1 * r8;
    let p = 1.0 + r * q;
    // 2^n as 2^n1 * 2^n2 with n1 = round(n / 2): both stay normal for n in [-1559, 1025].
    let t1 = n * 0.5 + SHIFTER;
    let n1 = t1 - SHIFTER;
    let t2 = (n - n1) + SHIFTER;
    let bias = 1023u64.wrapping_sub(SHIFTER.to_bits());
    let s1 = f64::from_bits(t1.to_bits().wrapping_add(bias) << 52);
    let s2 = f64::from_bits(t2.to_bits().wrapping_add(bias) << 52);
    p * s1 * s2
}

/// `(sin x, cos x)` for `|x| <= SIN_COS_MAX`, branch-free; meaningless beyond (the callers
/// check the range with [`in_sin_cos_range`]). See the module documentation.
#[inline(always)]
pub(crate) fn sin_cos_reduced(x: f64) -> (f64, f64) {
    let t = x * TWO_OVER_PI + SHIFTER;
    let n = t - SHIFTER;
    let r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3;
    let z = r * r;
    // fdlibm __kernel_sin: r + r^3 (S1 + z (S2 + ... )), the inner sum by Estrin's scheme.
    let z2 = z * z;
    let ps = (S2 + z * S3) + z2 * ((S4 + z * S5) + z2 * S6);
    let s = r + (z * r) * (S1 + z * ps);
    // fdlibm __kernel_cos: 1 - z/2 + z^2 (C1 + ...), with the rounding of 1 - z/2 compensated.
    let pc = z * ((C1 + z * C2) + z2 * ((C3 + z * C4) + z2 * (C5 + z * C6)));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    let c = w + (((1.0 - w) - hz) + z * pc);
    // Quadrant q = n mod 4 (the low bits of t): sin(r + q pi/2), cos(r + q pi/2).
    let q = t.to_bits();
    let swap = 0u64.wrapping_sub(q & 1);
    let (sb, cb) = (s.to_bits(), c.to_bits());
    let sin_b = (sb & !swap) | (cb & swap);
    let cos_b = (cb & !swap) | (sb & swap);
    let sin = f64::from_bits(sin_b ^ ((q & 2) << 62));
    let cos = f64::from_bits(cos_b ^ ((q.wrapping_add(1) & 2) << 62));
    (sin, cos)
}

/// Whether [`sin_cos_reduced`] is accurate at `x` (false for NaN and infinities).
#[inline(always)]
pub(crate) fn in_sin_cos_range(x: f64) -> bool {
    x.abs() <= SIN_COS_MAX
}

/// `(sin x, cos x)`: the branch-free kernel for `|x| <= SIN_COS_MAX`, the standard library
/// beyond. Within 2 ulp of `f64::sin_cos` (where the result is not tiny; never more than
/// `1.2e-16` apart). For arrays use [`sin_cos_slice`], which keeps the kernel vectorised.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if in_sin_cos_range(x) {
        sin_cos_reduced(x)
    } else {
        x.sin_cos()
    }
}

/// `sin[i], cos[i] = sin_cos(x[i])` for every `i` (vectorised for the CPU's widest vector
/// instructions, chosen at run time; bitwise the same on every instruction set).
///
/// # Panics
/// If the three slices differ in length.
pub fn sin_cos_slice(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    assert!(x.len() == sin.len() && x.len() == cos.len());
    struct Op<'a>(&'a [f64], &'a mut [f64], &'a mut [f64]);
    impl pulp::WithSimd for Op<'_> {
        type Output = bool;
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) -> bool {
            let mut out_of_range = false;
            for ((x, s), c) in self.0.iter().zip(self.1.iter_mut()).zip(self.2.iter_mut()) {
                (*s, *c) = sin_cos_reduced(*x);
                out_of_range |= !in_sin_cos_range(*x);
            }
            out_of_range
        }
    }
    if pulp::Arch::new().dispatch(Op(x, sin, cos)) {
        fix_sin_cos(x, sin, cos);
    }
}

/// Recomputes with the standard library the entries whose argument is out of the kernel's
/// range (rare: called only when a vectorised loop saw one).
#[cold]
pub(crate) fn fix_sin_cos(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
    for ((x, s), c) in x.iter().zip(sin.iter_mut()).zip(cos.iter_mut()) {
        if !in_sin_cos_range(*x) {
            (*s, *c) = x.sin_cos();
        }
    }
}

/// `y[i] = exp(x[i])` for every `i` (vectorised for the CPU's widest vector instructions,
/// chosen at run time; bitwise the same on every instruction set).
///
/// # Panics
/// If the slices differ in length.
pub fn exp_slice(x: &[f64], y: &mut [f64]) {
    assert_eq!(x.len(), y.len());
    struct Op<'a>(&'a [f64], &'a mut [f64]);
    impl pulp::WithSimd for Op<'_> {
        type Output = ();
        #[inline(always)]
        fn with_simd<S: pulp::Simd>(self, _: S) {
            for (x, y) in self.0.iter().zip(self.1.iter_mut()) {
                *y = exp(*x);
            }
        }
    }
    pulp::Arch::new().dispatch(Op(x, y));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The dispatched slice kernels give bitwise the scalar functions' values.
    #[test]
    fn slices_are_bitwise_the_scalar_kernels() {
        let mut next = uniform(17);
        let x: Vec<f64> = (0..1000)
            .map(|i| (next() - 0.5) * 1e3 * (i % 7) as f64)
            .collect();
        let (mut s, mut c, mut e) = (vec![0.0; 1000], vec![0.0; 1000], vec![0.0; 1000]);
        sin_cos_slice(&x, &mut s, &mut c);
        let small: Vec<f64> = x.iter().map(|v| v * 1e-1).collect();
        exp_slice(&small, &mut e);
        for i in 0..1000 {
            let (si, ci) = sin_cos(x[i]);
            assert_eq!(
                (s[i].to_bits(), c[i].to_bits()),
                (si.to_bits(), ci.to_bits())
            );
            assert_eq!(e[i].to_bits(), exp(small[i]).to_bits());
        }
    }

    use speckle_stats::rng::uniform_stream as uniform;

    /// Distance in units in the last place between two finite doubles of the same sign.
    fn ulps(a: f64, b: f64) -> u64 {
        if a == b {
            return 0;
        }
        if a.signum() != b.signum() {
            return u64::MAX;
        }
        a.to_bits().abs_diff(b.to_bits())
    }

    /// Largest ulp distance and relative difference (where `|value| >= floor`) and largest
    /// absolute difference of `sin_cos_slice` from the standard library over `xs`.
    fn sin_cos_errors(xs: &[f64], floor: f64) -> (u64, f64, f64) {
        let (mut s, mut c) = (vec![0.0; xs.len()], vec![0.0; xs.len()]);
        sin_cos_slice(xs, &mut s, &mut c);
        let (mut ulp, mut rel, mut abs) = (0u64, 0.0f64, 0.0f64);
        for ((x, s), c) in xs.iter().zip(&s).zip(&c) {
            let (rs, rc) = x.sin_cos();
            abs = abs.max((s - rs).abs()).max((c - rc).abs());
            for (a, b) in [(*s, rs), (*c, rc)] {
                if b.abs() >= floor {
                    ulp = ulp.max(ulps(a, b));
                    rel = rel.max((a - b).abs() / b.abs());
                }
            }
        }
        (ulp, rel, abs)
    }

    #[test]
    fn sin_cos_matches_std_to_two_ulp() {
        let mut u = uniform(1);
        // 1 M arguments each on |x| < pi, < 100, < 1e5, < 1e6, < 2^23 and log-uniform over
        // 1e-300 .. 2^23, both signs.
        let mut report = vec![];
        for (name, gen_x) in [
            (
                "|x| < pi",
                Box::new(|u: f64| std::f64::consts::PI * (2.0 * u - 1.0))
                    as Box<dyn Fn(f64) -> f64>,
            ),
            ("|x| < 100", Box::new(|u: f64| 100.0 * (2.0 * u - 1.0))),
            ("|x| < 1e5", Box::new(|u: f64| 1e5 * (2.0 * u - 1.0))),
            ("|x| < 1e6", Box::new(|u: f64| 1e6 * (2.0 * u - 1.0))),
            (
                "|x| < 2^23",
                Box::new(|u: f64| SIN_COS_MAX * (2.0 * u - 1.0)),
            ),
            (
                "log-uniform",
                Box::new(|u: f64| {
                    let x = (u * (SIN_COS_MAX.ln() + 690.0) - 690.0).exp();
                    if u.to_bits() & 1 == 0 { x } else { -x }
                }),
            ),
        ] {
            let xs: Vec<f64> = (0..1_000_000).map(|_| gen_x(u())).collect();
            let (ulp, rel, abs) = sin_cos_errors(&xs, 1e-3);
            report.push(format!("{name}: {ulp} ulp, {rel:.2e} rel, {abs:.2e} abs"));
            assert!(ulp <= 2 && rel <= 2.5e-16, "{name}: {ulp} ulp, {rel:e} rel");
            assert!(abs <= 1.2e-16, "{name}: {abs:e}");
        }
        eprintln!("sin_cos vs std: {}", report.join("; "));
    }

    #[test]
    fn sin_cos_near_multiples_of_half_pi() {
        // Arguments next to n pi / 2 (the hardest for the reduction): the absolute error stays
        // at the rounding level, and tiny results keep their relative accuracy.
        let mut xs = vec![];
        for n in (0..2_000_000i64)
            .step_by(997)
            .chain([1, 2, 3, 4, 5_340_353])
        {
            let c = n as f64 * std::f64::consts::FRAC_PI_2;
            let mut x = c;
            for _ in 0..8 {
                xs.push(x);
                xs.push(-x);
                x = f64::from_bits(x.to_bits() + 1);
            }
        }
        let (_, _, abs) = sin_cos_errors(&xs, 1.0);
        assert!(abs <= 1.2e-16, "{abs:e}");
        let (s, c) = sin_cos(std::f64::consts::PI);
        assert!((s / std::f64::consts::PI.sin() - 1.0).abs() < 1e-12 && c == -1.0);
        let (s, _) = sin_cos(1e5 * std::f64::consts::PI);
        assert!(
            (s / (1e5 * std::f64::consts::PI).sin() - 1.0).abs() < 1e-9,
            "{s:e}"
        );
    }

    #[test]
    fn sin_cos_special_values() {
        for x in [0.0, -0.0, 1e-310, -1e-310, 1e-8] {
            let (s, c) = sin_cos(x);
            assert_eq!((s, c), (x, 1.0), "{x}");
        }
        for x in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let (s, c) = sin_cos(x);
            assert!(s.is_nan() && c.is_nan());
        }
        // Beyond the kernel's range the standard library answers (slice and scalar).
        let xs = [1e7, 1e9, -3e15, 1e300, f64::NAN, 0.5];
        let (mut s, mut c) = ([0.0; 6], [0.0; 6]);
        sin_cos_slice(&xs, &mut s, &mut c);
        for i in 0..6 {
            let (rs, rc) = xs[i].sin_cos();
            assert!(s[i].to_bits() == rs.to_bits() || i == 5 || (s[i].is_nan() && rs.is_nan()));
            assert!(c[i].to_bits() == rc.to_bits() || i == 5 || (c[i].is_nan() && rc.is_nan()));
            assert_eq!(sin_cos(xs[i]).0.to_bits(), s[i].to_bits());
        }
    }

    #[test]
    fn exp_matches_std_to_an_ulp() {
        let mut u = uniform(2);
        let mut report = vec![];
        for (name, lo, hi) in [
            ("[-745, 709]", -745.0, 709.0),
            ("[-40, 0]", -40.0, 0.0),
            ("[-1, 1]", -1.0, 1.0),
            ("[-708, -745] (subnormal)", -745.0, -708.0),
        ] {
            let xs: Vec<f64> = (0..1_000_000).map(|_| lo + (hi - lo) * u()).collect();
            let mut ys = vec![0.0; xs.len()];
            exp_slice(&xs, &mut ys);
            let mut worst = 0;
            for (x, y) in xs.iter().zip(&ys) {
                let r = x.exp();
                // Subnormal results have fewer bits: compare them on the absolute scale.
                let d = if r < f64::MIN_POSITIVE {
                    ((y - r).abs() / 4.9e-324) as u64
                } else {
                    ulps(*y, r)
                };
                worst = worst.max(d);
            }
            report.push(format!("{name}: {worst} ulp"));
            assert!(worst <= 1, "{name}: {worst} ulp");
        }
        eprintln!("exp vs std: {}", report.join("; "));
    }

    #[test]
    fn exp_special_values() {
        assert_eq!(exp(0.0), 1.0);
        assert_eq!(exp(-0.0), 1.0);
        assert_eq!(exp(-746.0), 0.0);
        assert_eq!(exp(f64::NEG_INFINITY), 0.0);
        assert_eq!(exp(710.0), f64::INFINITY);
        assert_eq!(exp(f64::INFINITY), f64::INFINITY);
        assert!(exp(f64::NAN).is_nan());
        assert!(ulps(exp(1.0), std::f64::consts::E) <= 1);
        // Near the smallest subnormal and the largest finite results.
        assert_eq!(exp(-745.1), (-745.1f64).exp());
        assert!(ulps(exp(709.7), 709.7f64.exp()) <= 1);
    }
}
