//! Bessel functions of order zero, `J0`, `Y0` and the Hankel function `H0^(1) = J0 + i Y0`,
//! for the flatland Green's function `G(r) = (i/4) H0^(1)(kr)`.
//!
//! Three regimes, each accurate to about `1e-15` absolute (relative to the envelope
//! `min(1, sqrt(2 / (pi x)))`) on its interval:
//!
//! - `0 < x <= 2`: the ascending series (Abramowitz & Stegun 9.1.12-13),
//!   `J0 = sum (-1)^m q^m / (m!)^2`, `q = x^2/4`, and
//!   `Y0 = (2/pi) [(ln(x/2) + gamma) J0 + sum_{m>=1} (-1)^{m+1} H_m q^m / (m!)^2]`
//!   with `H_m` the harmonic numbers. The largest term is at most `q <= 1`, so there is no
//!   cancellation. (Used alone up to `x = 12` the series loses four digits to cancellation: its
//!   terms grow to `I0(12) ~ 2e4`.)
//! - `2 < x < 20`: Miller's backward recurrence `J_{n-1} = (2n/x) J_n - J_{n+1}` from
//!   `n = N ~ x + 6 sqrt(x) + 20` with the normalisation `J0 + 2 sum_k J_{2k} = 1`
//!   (A&S 9.1.87), and `Y0` from Neumann's series
//!   `Y0 = (2/pi) (ln(x/2) + gamma) J0 - (4/pi) sum_{k>=1} (-1)^k J_{2k} / k` (A&S 9.1.88). The
//!   recurrence is stable for the minimal solution `J_n`, and the start order makes the error
//!   of starting from `J_{N+1} = 0` negligible (measured against mpmath: a few ulps of the
//!   envelope up to `x = 40`).
//! - `x >= 20`: Hankel's asymptotic expansion (A&S 9.2.5-9.2.10, 9.2.7 for `H^(1)`),
//!   `H0^(1)(x) = sqrt(2 / (pi x)) e^{i (x - pi/4)} sum_k i^k a_k / x^k`,
//!   `a_k = (-1)^k prod_{j<=k} (2j - 1)^2 / (k! 8^k)`, summed until a term is below `1e-17`.
//!   Its smallest term is about `e^{-2x}`, so at `x >= 20` the truncation error is below
//!   `1e-17`. (It would be only about `1e-11` at `x = 12`, hence the middle regime.)
//!
//! The phase `e^{i (x - pi/4)}` is formed from `sin x` and `cos x` of the exact argument, so no
//! rounding of `x - pi/4` enters at large `x`.

use num_complex::Complex64;
use std::f64::consts::{FRAC_1_SQRT_2, FRAC_2_PI, PI};

/// Euler-Mascheroni constant.
const EULER_GAMMA: f64 = 0.577_215_664_901_532_9;

/// Upper end of the ascending-series regime.
const SERIES_MAX: f64 = 2.0;

/// Lower end of the asymptotic regime.
const ASYMPTOTIC_MIN: f64 = 20.0;

/// Bessel function of the first kind of order zero, `J0(x)` (even in `x`).
///
/// ```
/// use speckle_wave::bessel::bessel_j0;
/// // Abramowitz & Stegun, Table 9.1.
/// assert!((bessel_j0(1.0) - 0.765_197_686_557_966_6).abs() < 1e-15);
/// ```
pub fn bessel_j0(x: f64) -> f64 {
    if x.is_nan() {
        return f64::NAN;
    }
    let x = x.abs();
    if x == 0.0 {
        return 1.0;
    }
    j0_y0(x).0
}

/// Bessel function of the second kind of order zero, `Y0(x)`, for `x > 0` (`-inf` at 0, NaN for
/// negative `x`).
///
/// ```
/// use speckle_wave::bessel::bessel_y0;
/// // Abramowitz & Stegun, Table 9.1.
/// assert!((bessel_y0(1.0) - 0.088_256_964_215_676_96).abs() < 1e-15);
/// ```
pub fn bessel_y0(x: f64) -> f64 {
    if x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return f64::NEG_INFINITY;
    }
    j0_y0(x).1
}

/// The Hankel function of the first kind of order zero, `H0^(1)(x) = J0(x) + i Y0(x)`, for
/// `x > 0`; asymptotically `sqrt(2 / (pi x)) e^{i (x - pi/4)}`, an outgoing cylindrical wave
/// for the time dependence `e^{-i omega t}`.
///
/// ```
/// use speckle_wave::bessel::hankel1_0;
/// let x = 500.0;
/// let h = hankel1_0(x);
/// let far = num_complex::Complex64::from_polar((2.0 / (std::f64::consts::PI * x)).sqrt(),
///     x - std::f64::consts::FRAC_PI_4);
/// assert!((h - far).norm() < 1e-3 * far.norm());
/// ```
pub fn hankel1_0(x: f64) -> Complex64 {
    if x.is_nan() || x <= 0.0 {
        return Complex64::new(bessel_j0(x), bessel_y0(x));
    }
    let (j, y) = j0_y0(x);
    Complex64::new(j, y)
}

/// `(J0(x), Y0(x))` for finite or infinite `x > 0`.
fn j0_y0(x: f64) -> (f64, f64) {
    debug_assert!(x > 0.0);
    if x == f64::INFINITY {
        (0.0, 0.0)
    } else if x <= SERIES_MAX {
        series(x)
    } else if x < ASYMPTOTIC_MIN {
        miller(x)
    } else {
        asymptotic(x)
    }
}

/// Ascending series (A&S 9.1.12, 9.1.13); accurate while `x^2 / 4` is at most a few.
fn series(x: f64) -> (f64, f64) {
    let q = 0.25 * x * x;
    let (mut term, mut harmonic) = (1.0, 0.0);
    let (mut j0, mut tail) = (1.0, 0.0);
    for m in 1..200 {
        let mf = f64::from(m);
        // term = (-1)^m q^m / (m!)^2
        term *= -q / (mf * mf);
        harmonic += 1.0 / mf;
        j0 += term;
        // sum_{m>=1} (-1)^{m+1} H_m q^m / (m!)^2
        tail -= harmonic * term;
        if (harmonic * term).abs() < 1e-18 * (1.0 + tail.abs()) {
            break;
        }
    }
    let y0 = FRAC_2_PI * (((0.5 * x).ln() + EULER_GAMMA) * j0 + tail);
    (j0, y0)
}

/// Miller's backward recurrence for `J0` (A&S 9.1.27 backwards, normalised with A&S 9.1.87)
/// and Neumann's series for `Y0` (A&S 9.1.88).
fn miller(x: f64) -> (f64, f64) {
    // Even start order N >= x + 6 sqrt(x) + 20: the error of starting from J_{N+1} = 0 is then
    // below rounding for 2 <= x <= 40 (with N = x + 30 it reaches 1e-13 near x = 40).
    let start = 2 * ((0.5 * (x + 6.0 * x.sqrt() + 20.0)).ceil() as usize);
    let (mut above, mut current) = (0.0f64, 1e-30f64); // unnormalised J_{n+1}, J_n at n = start
    let (mut norm, mut neumann) = (0.0, 0.0);
    for n in (1..=start).rev() {
        if n % 2 == 0 {
            let k = n / 2;
            norm += 2.0 * current;
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            neumann += sign * current / k as f64;
        }
        let below = (2.0 * n as f64 / x) * current - above;
        above = current;
        current = below;
        if current.abs() > 1e250 {
            // Never reached for x > 2 with this start order; kept so that no input overflows.
            above *= 1e-250;
            current *= 1e-250;
            norm *= 1e-250;
            neumann *= 1e-250;
        }
    }
    norm += current;
    let j0 = current / norm;
    let y0 = FRAC_2_PI * ((0.5 * x).ln() + EULER_GAMMA) * j0 - 2.0 * FRAC_2_PI * neumann / norm;
    (j0, y0)
}

/// Hankel's asymptotic expansion of `H0^(1)` (A&S 9.2.7 with the coefficients of 9.2.9-9.2.10).
fn asymptotic(x: f64) -> (f64, f64) {
    // c_k = i^k a_k / x^k, c_k = c_{k-1} (-i) (2k - 1)^2 / (8 k x): P0 + i Q0 = sum_k c_k.
    let mut c = Complex64::new(1.0, 0.0);
    let mut sum = c;
    let mut last = f64::INFINITY;
    for k in 1..200 {
        let kf = f64::from(k);
        c *= Complex64::new(0.0, -(2.0 * kf - 1.0).powi(2) / (8.0 * kf * x));
        let size = c.norm();
        if size >= last {
            // The series is asymptotic: stop before its terms grow again (not reached for
            // x >= 20, where terms fall below 1e-17 first).
            break;
        }
        sum += c;
        last = size;
        if size < 1e-17 {
            break;
        }
    }
    let (s, co) = x.sin_cos();
    // e^{i (x - pi/4)} = ((cos x + sin x) + i (sin x - cos x)) / sqrt(2)
    let phase = Complex64::new((co + s) * FRAC_1_SQRT_2, (s - co) * FRAC_1_SQRT_2);
    let h = sum * phase * (2.0 / (PI * x)).sqrt();
    (h.re, h.im)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `(x, J0(x), Y0(x))` from mpmath 1.3.0 (`besselj(0, x)`, `bessely(0, x)` at 40 digits,
    /// rounded to 17) at the exact binary value of each `x` (for `x = 12345.678` the decimal
    /// and the binary argument differ by `1.2e-13`, which changes `J0` by `8e-16`, `1e-13` of
    /// its envelope). The values at 1 and 10 agree with Abramowitz & Stegun, Table 9.1. The
    /// digits are kept as printed; the compiler rounds them to `f64`.
    #[allow(clippy::excessive_precision)]
    const REFERENCE: [(f64, f64, f64); 21] = [
        (1e-8, 0.999_999_999_999_999_97, -11.800_773_877_179_531),
        (0.001, 0.999_999_750_000_015_62, -4.471_416_611_375_923_3),
        (0.5, 0.938_469_807_240_812_9, -0.444_518_733_506_706_56),
        (1.0, 0.765_197_686_557_966_55, 0.088_256_964_215_676_958),
        (1.9, 0.281_818_559_374_385_52, 0.496_819_971_283_820_19),
        (2.0, 0.223_890_779_141_235_67, 0.510_375_672_649_745_12),
        (2.1, 0.166_606_980_331_990_28, 0.518_293_737_513_760_73),
        (3.0, -0.260_051_954_901_933_44, 0.376_850_010_012_790_38),
        (5.0, -0.177_596_771_314_338_3, -0.308_517_625_249_033_78),
        (8.0, 0.171_650_807_137_553_91, 0.223_521_489_387_566_22),
        (10.0, -0.245_935_764_451_348_34, 0.055_671_167_283_599_391),
        (12.0, 0.047_689_310_796_833_537, -0.225_237_312_634_361_43),
        (15.0, -0.014_224_472_826_780_773, 0.205_464_296_038_918_26),
        (19.9, 0.172_877_756_392_618_46, 0.045_762_094_159_385_479),
        (20.0, 0.167_024_664_340_583_15, 0.062_640_596_809_383_831),
        (20.1, 0.159_536_067_937_297_09, 0.078_810_592_428_750_293),
        (25.0, 0.096_266_783_275_958_116, -0.127_249_432_268_006_14),
        (40.0, 0.007_366_890_584_237_289_6, 0.125_936_417_058_260_93),
        (100.0, 0.019_985_850_304_223_122, -0.077_244_313_365_083_152),
        (
            1000.0,
            0.024_786_686_152_420_175,
            0.004_715_917_977_622_813_4,
        ),
        (
            12345.678,
            0.000_030_586_713_322_758_247,
            -0.007_180_896_197_612_129_1,
        ),
    ];

    /// The envelope of `|H0(x)|` (1 near the origin, `sqrt(2 / (pi x))` far out), the scale
    /// absolute errors are measured against.
    fn envelope(x: f64) -> f64 {
        (2.0 / (PI * x)).sqrt().min(1.0)
    }

    #[test]
    fn matches_reference_values() {
        let mut worst: f64 = 0.0;
        for &(x, j, y) in &REFERENCE {
            let (gj, gy) = (bessel_j0(x), bessel_y0(x));
            let ej = (gj - j).abs() / envelope(x);
            // Y0 diverges logarithmically at the origin: relative error there.
            let ey = (gy - y).abs() / envelope(x).max(y.abs());
            worst = worst.max(ej).max(ey);
            assert!(
                ej < 2e-15 && ey < 2e-15,
                "x = {x}: J0 {gj} vs {j}, Y0 {gy} vs {y}"
            );
        }
        eprintln!("worst error against mpmath, relative to the envelope: {worst:.1e}");
    }

    #[test]
    fn regimes_agree_where_they_overlap() {
        // Against mpmath on a fine grid, relative to the envelope: the series is within 3 ulps
        // up to x = 4 (its terms stay below I0(4) ~ 11), Miller within 6 ulps on [1, 20] (8 up
        // to 40), the asymptotic expansion within 2 ulps from x = 17 (smallest term
        // ~ e^{-2x}). Compare each pair on a stretch around its switch.
        let mut worst: f64 = 0.0;
        for i in 0..=200 {
            let x = 1.0 + 2.0 * f64::from(i) / 200.0;
            let (a, b) = (series(x), miller(x));
            let e = (a.0 - b.0).abs().max((a.1 - b.1).abs());
            worst = worst.max(e);
            assert!(e < 3e-15, "x = {x}: series {a:?} vs Miller {b:?}");
        }
        for i in 0..=400 {
            let x = 17.0 + 6.0 * f64::from(i) / 400.0;
            let (a, b) = (miller(x), asymptotic(x));
            let e = ((a.0 - b.0).abs().max((a.1 - b.1).abs())) / envelope(x);
            worst = worst.max(e);
            assert!(e < 3e-15, "x = {x}: Miller {a:?} vs asymptotic {b:?}");
        }
        eprintln!("worst disagreement between regimes: {worst:.1e}");
    }

    #[test]
    fn continuous_across_the_switches() {
        for s in [SERIES_MAX, ASYMPTOTIC_MIN] {
            let below = j0_y0(s * (1.0 - 1e-15));
            let at = j0_y0(s);
            let above = j0_y0(s * (1.0 + 1e-15));
            for (a, b) in [(below, at), (at, above)] {
                assert!(
                    (a.0 - b.0).abs() < 1e-14 && (a.1 - b.1).abs() < 1e-14,
                    "jump at {s}: {a:?} vs {b:?}"
                );
            }
        }
    }

    #[test]
    fn satisfies_the_wronskian_of_the_hankel_pair() {
        // J0' = -J1 and the Wronskian J1 Y0 - J0 Y1 = 2 / (pi x) give
        // J0 Y0' - J0' Y0 = 2 / (pi x); the derivatives by a fourth-order central difference.
        for x in [0.7f64, 1.5, 2.5, 6.0, 13.0, 19.0, 21.0, 60.0, 300.0] {
            let h = 1e-3 * x.min(1.0);
            let d = |f: fn(f64) -> f64| {
                (8.0 * (f(x + h) - f(x - h)) - (f(x + 2.0 * h) - f(x - 2.0 * h))) / (12.0 * h)
            };
            let w = bessel_j0(x) * d(bessel_y0) - d(bessel_j0) * bessel_y0(x);
            let expect = 2.0 / (PI * x);
            assert!(
                (w - expect).abs() < 1e-9 * expect,
                "x = {x}: {w} vs {expect}"
            );
        }
    }

    #[test]
    fn special_arguments() {
        assert_eq!(bessel_j0(0.0), 1.0);
        assert_eq!(bessel_y0(0.0), f64::NEG_INFINITY);
        assert_eq!(bessel_j0(-3.0), bessel_j0(3.0));
        assert!(bessel_y0(-1.0).is_nan() && bessel_j0(f64::NAN).is_nan());
        assert_eq!(hankel1_0(f64::INFINITY), Complex64::new(0.0, 0.0));
        assert!(hankel1_0(1e-300).im < -400.0);
    }
}
