//! Property tests of the complex vMF algebra (3D [`ComplexVmf`], flatland [`CircleVmf`]) against
//! brute-force quadrature, for random complex parameters: products, conjugates and rotations
//! integrated pointwise from their factors, and the closed-form sphere (circle) integrals, with
//! concentrations up to `1e5` and `mu . mu` near 0 (issue 11, "Must show", first item).
//!
//! The quadrature is independent of the closed forms: peak-centred Gauss-Legendre panels
//! (16 nodes each, built here by Newton's method) in `t = 1 - cos(theta)` about the axis of
//! `Re mu` (3D) or in the angle from that axis (flatland), graded geometrically from a width
//! `~0.05 / kappa` at the peak and split wherever the phase `Im mu . w` turns by more than 2 rad
//! within a panel; the azimuth (3D) by the trapezoid rule with `40 + 1.5 |Im mu_perp| sin(theta)`
//! nodes, spectrally accurate for this periodic entire integrand.
//!
//! Tolerance: `|closed - quadrature| <= 1e-10 int |h|`. The integral of `|h|` is the scale at
//! which any quadrature (and any floating-point evaluation) of `int h` is resolved, so this is the
//! strictest honest criterion: where the integral itself is much smaller (a cancelling
//! oscillation, `mu . mu ~ 0` with a large `mu`) it cannot be checked finer. The near-null cases
//! keep `|mu| <= 3`, so there `int |h| / |int h| <= e^3` and the check is tight. The quadrature
//! reaches about `1e-14` of `int |h|` on these cases. Run time: a few seconds in release.

use glam::{DMat3, DQuat, DVec2, DVec3};
use num_complex::Complex64;
use proptest::prelude::*;
use speckle_vmf::{Aperture, CircleVmf, ComplexVmf, VmfMixture};
use std::f64::consts::PI;

const TOL: f64 = 1e-10;

fn c(re: f64, im: f64) -> Complex64 {
    Complex64::new(re, im)
}

/// Gauss-Legendre nodes and weights on `[-1, 1]` by Newton's method on `P_n`.
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                // P_n(x) and P_n'(x) by the three-term recurrence.
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let k = k as f64;
                    let p2 = ((2.0 * k - 1.0) * x * p1 - (k - 1.0) * p0) / k;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

/// Panels on `[0, end]` graded geometrically (ratio 1.5) from `first`, each split so that a phase
/// of rate `rate(a, b)` (radians over the panel) turns by at most 2 rad.
fn panels(end: f64, first: f64, rate: impl Fn(f64, f64) -> f64) -> Vec<(f64, f64)> {
    let mut edges = vec![0.0];
    let mut e = first.min(end);
    while e < end {
        edges.push(e);
        e *= 1.5;
    }
    edges.push(end);
    let mut out = Vec::new();
    for w in edges.windows(2) {
        let parts = (rate(w[0], w[1]) / 2.0).ceil().max(1.0) as usize;
        for p in 0..parts {
            let a = w[0] + (w[1] - w[0]) * p as f64 / parts as f64;
            let b = w[0] + (w[1] - w[0]) * (p + 1) as f64 / parts as f64;
            out.push((a, b));
        }
    }
    out
}

/// `int_{S^2} f(w) dw` for `f` concentrated about `axis` with concentration about `kappa`, and
/// oscillating with the complex vector `im` (`f ~ e^(i im . w)`).
fn sphere_quadrature(
    axis: DVec3,
    kappa: f64,
    im: DVec3,
    f: impl Fn(DVec3) -> Complex64,
) -> Complex64 {
    sphere_quadrature_with(axis, kappa, im, 0.0, f)
}

/// [`sphere_quadrature`] for an integrand that also varies (in modulus or phase) at up to the
/// rate `extra` per unit change of the direction, in any orientation.
fn sphere_quadrature_with(
    axis: DVec3,
    kappa: f64,
    im: DVec3,
    extra: f64,
    f: impl Fn(DVec3) -> Complex64,
) -> Complex64 {
    let (t1, t2) = axis.any_orthonormal_pair();
    let along = im.dot(axis).abs() + extra;
    let perp = (im - im.dot(axis) * axis).length() + extra;
    let s = |t: f64| (t * (2.0 - t)).max(0.0).sqrt();
    let gl = gauss_legendre(16);
    let mut sum = c(0.0, 0.0);
    let rate = |a: f64, b: f64| {
        let span = if a < 1.0 && b > 1.0 {
            (1.0 - s(a)) + (1.0 - s(b))
        } else {
            (s(b) - s(a)).abs()
        };
        along * (b - a) + perp * span
    };
    for (a, b) in panels(2.0, 0.05 / kappa.max(1.0), rate) {
        for &(x, wt) in &gl {
            let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
            let (ct, st) = (1.0 - t, s(t));
            let n_phi = 40 + (1.5 * perp * st).ceil() as usize;
            let mut ring = c(0.0, 0.0);
            for j in 0..n_phi {
                let (sp, cp) = (2.0 * PI * j as f64 / n_phi as f64).sin_cos();
                ring += f(ct * axis + st * cp * t1 + st * sp * t2);
            }
            sum += ring * (2.0 * PI / n_phi as f64) * (0.5 * (b - a) * wt);
        }
    }
    sum
}

/// `int_{S^1} f(w) dw` for `f` concentrated about the unit `axis` with concentration about
/// `kappa`, oscillating with the vector `im`.
fn circle_quadrature(
    axis: DVec2,
    kappa: f64,
    im: DVec2,
    f: impl Fn(DVec2) -> Complex64,
) -> Complex64 {
    let speed = im.length();
    let gl = gauss_legendre(16);
    let mut sum = c(0.0, 0.0);
    let first = 0.05 / kappa.max(1.0).sqrt();
    for (a, b) in panels(PI, first, |a, b| speed * (b - a)) {
        for &(x, wt) in &gl {
            let th = 0.5 * (a + b) + 0.5 * (b - a) * x;
            for sign in [1.0, -1.0] {
                let w = DVec2::from_angle(sign * th).rotate(axis);
                sum += f(w) * (0.5 * (b - a) * wt);
            }
        }
    }
    sum
}

fn re3(mu: &[Complex64; 3]) -> DVec3 {
    DVec3::new(mu[0].re, mu[1].re, mu[2].re)
}
fn im3(mu: &[Complex64; 3]) -> DVec3 {
    DVec3::new(mu[0].im, mu[1].im, mu[2].im)
}
fn re2(mu: &[Complex64; 2]) -> DVec2 {
    DVec2::new(mu[0].re, mu[1].re)
}
fn im2(mu: &[Complex64; 2]) -> DVec2 {
    DVec2::new(mu[0].im, mu[1].im)
}

/// Checks the closed-form `ln int h` of `h` against the quadrature of `pointwise` (which evaluates
/// `h` from its factors, scaled by `e^(-shift)`), relative to `int |h|`.
fn check_3d(
    h: &ComplexVmf,
    pointwise: impl Fn(DVec3) -> Complex64,
    shift: f64,
) -> Result<(), TestCaseError> {
    let re = re3(&h.mu);
    let kappa = re.length();
    let axis = if kappa > 0.0 { re / kappa } else { DVec3::Z };
    let quad = sphere_quadrature(axis, kappa, im3(&h.mu), pointwise);
    let closed = h.ln_sphere_integral();
    prop_assert!(closed.re.is_finite() || closed.re == f64::NEG_INFINITY);
    prop_assert!(closed.im.is_finite());
    let scale = (h.ln_modulus_integral() - shift).exp();
    let err = ((closed - shift).exp() - quad).norm();
    prop_assert!(
        err <= TOL * scale,
        "h={h:?}: closed {} quad {quad} err/scale {:e}",
        (closed - shift).exp(),
        err / scale
    );
    Ok(())
}

fn check_2d(
    h: &CircleVmf,
    pointwise: impl Fn(DVec2) -> Complex64,
    shift: f64,
) -> Result<(), TestCaseError> {
    let re = re2(&h.mu);
    let kappa = re.length();
    let axis = if kappa > 0.0 { re / kappa } else { DVec2::X };
    let quad = circle_quadrature(axis, kappa, im2(&h.mu), pointwise);
    let closed = h.ln_circle_integral();
    prop_assert!(closed.im.is_finite());
    let scale = (h.ln_modulus_integral() - shift).exp();
    let err = ((closed - shift).exp() - quad).norm();
    prop_assert!(
        err <= TOL * scale,
        "h={h:?}: closed {} quad {quad} err/scale {:e}",
        (closed - shift).exp(),
        err / scale
    );
    Ok(())
}

fn unit3() -> impl Strategy<Value = DVec3> {
    (-1.0..1.0f64, 0.0..(2.0 * PI)).prop_map(|(z, phi)| {
        let r = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    })
}

fn rotation() -> impl Strategy<Value = DMat3> {
    (unit3(), 0.0..(2.0 * PI))
        .prop_map(|(axis, angle)| DMat3::from_quat(DQuat::from_axis_angle(axis, angle).normalize()))
}

/// Moderate parameters: components of `mu` up to 40, random complex scale.
fn general3() -> impl Strategy<Value = ComplexVmf> {
    (
        -5.0..5.0f64,
        -3.0..3.0f64,
        prop::array::uniform3((-40.0..40.0f64, -40.0..40.0f64)),
    )
        .prop_map(|(a, b, m)| ComplexVmf::new(c(a, b), m.map(|(re, im)| c(re, im))))
}

/// Sharp lobes: `|Re mu| = 10^u` up to `1e5` about a random axis, `|Im mu| <= 100` (an aperture
/// `gamma_a` plus `k` times a few wavelengths).
fn sharp3() -> impl Strategy<Value = ComplexVmf> {
    (0.0..5.0f64, unit3(), unit3(), 0.0..100.0f64, -3.0..3.0f64).prop_map(
        |(u, axis, dir, im, phase)| {
            let re = 10f64.powf(u) * axis;
            let im = im * dir;
            ComplexVmf::new(
                c(-re.length(), phase),
                [c(re.x, im.x), c(re.y, im.y), c(re.z, im.z)],
            )
        },
    )
}

/// `mu . mu` near 0: `mu = a (e1 + i e2) + delta` with `e1 _|_ e2` unit, `a <= 3`,
/// `|delta| = 10^u`, `u in [-12, -1]` (the closed form's series branch and its edge).
fn near_null3() -> impl Strategy<Value = ComplexVmf> {
    (
        0.01..3.0f64,
        rotation(),
        -12.0..-1.0f64,
        prop::array::uniform3((-1.0..1.0f64, -1.0..1.0f64)),
    )
        .prop_map(|(a, r, u, d)| {
            let e1 = r * DVec3::X;
            let e2 = r * DVec3::Y;
            let size = 10f64.powf(u);
            ComplexVmf::new(
                c(0.0, 0.0),
                std::array::from_fn(|j| c(a * e1[j] + size * d[j].0, a * e2[j] + size * d[j].1)),
            )
        })
}

fn general2() -> impl Strategy<Value = CircleVmf> {
    (
        -5.0..5.0f64,
        -3.0..3.0f64,
        prop::array::uniform2((-40.0..40.0f64, -40.0..40.0f64)),
    )
        .prop_map(|(a, b, m)| CircleVmf::new(c(a, b), m.map(|(re, im)| c(re, im))))
}

fn sharp2() -> impl Strategy<Value = CircleVmf> {
    (
        0.0..5.0f64,
        0.0..(2.0 * PI),
        0.0..(2.0 * PI),
        0.0..100.0f64,
        -3.0..3.0f64,
    )
        .prop_map(|(u, t, s, im, phase)| {
            let re = 10f64.powf(u) * DVec2::from_angle(t);
            let im = im * DVec2::from_angle(s);
            CircleVmf::new(c(-re.length(), phase), [c(re.x, im.x), c(re.y, im.y)])
        })
}

fn near_null2() -> impl Strategy<Value = CircleVmf> {
    (
        0.01..3.0f64,
        0.0..(2.0 * PI),
        prop::bool::ANY,
        -12.0..-1.0f64,
        prop::array::uniform2((-1.0..1.0f64, -1.0..1.0f64)),
    )
        .prop_map(|(a, t, flip, u, d)| {
            let e1 = DVec2::from_angle(t);
            let e2 = if flip { -e1.perp() } else { e1.perp() };
            let size = 10f64.powf(u);
            CircleVmf::new(
                c(0.0, 0.0),
                std::array::from_fn(|j| c(a * e1[j] + size * d[j].0, a * e2[j] + size * d[j].1)),
            )
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Eq. 29 against quadrature of `h` itself.
    #[test]
    fn sphere_integral(h in prop_oneof![general3(), sharp3(), near_null3()]) {
        let shift = h.log_scale.re + re3(&h.mu).length();
        check_3d(&h, |w| (h.ln_eval(w) - shift).exp(), shift)?;
    }

    /// `int h1 h2^*` in closed form (product and conjugate closure) against quadrature of the
    /// pointwise product of the two factors, one of them sharp.
    #[test]
    fn product_and_conjugate(h1 in prop_oneof![general3(), near_null3()], h2 in sharp3()) {
        let p = h1.mul_conj(&h2);
        let shift = p.log_scale.re + re3(&p.mu).length();
        check_3d(&p, |w| (h1.ln_eval(w) + h2.ln_eval(w).conj() - shift).exp(), shift)?;
        let q = h1.mul(&h2);
        let shift = q.log_scale.re + re3(&q.mu).length();
        check_3d(&q, |w| (h1.ln_eval(w) + h2.ln_eval(w) - shift).exp(), shift)?;
    }

    /// A rotated function integrated by quadrature of the original at rotated directions; the
    /// pointwise identity `h'(R w) = h(w)`.
    #[test]
    fn rotation_invariance(h in prop_oneof![general3(), sharp3(), near_null3()], r in rotation(), w in unit3()) {
        let g = h.rotated(r);
        let a = h.ln_eval(w);
        let b = g.ln_eval(r * w);
        prop_assert!((a - b).norm() <= 1e-12 * (1.0 + a.norm()));
        let shift = g.log_scale.re + re3(&g.mu).length();
        check_3d(&g, |v| (h.ln_eval(r.transpose() * v) - shift).exp(), shift)?;
    }

    /// The circle integral `2 pi eta I_0(beta)` against quadrature.
    #[test]
    fn circle_integral(h in prop_oneof![general2(), sharp2(), near_null2()]) {
        let shift = h.log_scale.re + re2(&h.mu).length();
        check_2d(&h, |w| (h.ln_eval(w) - shift).exp(), shift)?;
    }

    /// Flatland products, conjugates and rotations against quadrature of the factors.
    #[test]
    fn circle_product_conjugate_rotation(
        h1 in prop_oneof![general2(), near_null2()],
        h2 in sharp2(),
        angle in 0.0..(2.0 * PI),
    ) {
        let p = h1.mul_conj(&h2);
        let shift = p.log_scale.re + re2(&p.mu).length();
        check_2d(&p, |w| (h1.ln_eval(w) + h2.ln_eval(w).conj() - shift).exp(), shift)?;
        let g = h2.rotated(angle);
        let rot = DVec2::from_angle(angle);
        let back = DVec2::from_angle(-angle);
        let w = DVec2::from_angle(0.3 * angle + 1.0);
        prop_assert!((h2.ln_eval(w) - g.ln_eval(rot.rotate(w))).norm() <= 1e-12 * (1.0 + h2.ln_eval(w).norm()));
        let shift = g.log_scale.re + re2(&g.mu).length();
        check_2d(&g, |v| (h2.ln_eval(back.rotate(v)) - shift).exp(), shift)?;
    }
}

/// The quadrature itself resolves known values to far below the tolerance: `4 pi sinh(k)/k`
/// for real `k` up to `1e5` (scaled), the null vector `(1, i, 0)` (exactly `4 pi`), and
/// `2 pi I_0(i y) = 2 pi J_0(y)` at `y = 40`. At `k = 1e5` the integrand itself, evaluated at
/// unit vectors whose components are rounded to `eps = 1.1e-16`, is only good to `k eps = 1.1e-11`
/// relative (this, not the rule, limits every evaluation at such concentrations); the bound is
/// `3 k eps`.
#[test]
fn quadrature_is_accurate() {
    for k in [1.0, 1e3, 1e5] {
        let q = sphere_quadrature(DVec3::Z, k, DVec3::ZERO, |w| c(k * (w.z - 1.0), 0.0).exp());
        let exact = 2.0 * PI / k * (-(-2.0 * k).exp_m1());
        let tol = 1e-14 + 3.0 * k * f64::EPSILON;
        assert!(
            (q.re - exact).abs() < tol * exact && q.im == 0.0,
            "{q} {exact}"
        );
    }
    let q = sphere_quadrature(DVec3::X, 1.0, DVec3::Y, |w| c(w.x - 1.0, w.y).exp());
    assert!((q * 1f64.exp() - 4.0 * PI).norm() < 1e-13, "{q}");
    // J_0(40) = 0.0073668905842372896 (mpmath, 30 digits)
    let q = circle_quadrature(DVec2::X, 0.0, DVec2::new(40.0, 0.0), |w| {
        c(0.0, 40.0 * w.x).exp()
    });
    assert!(
        (q - 2.0 * PI * 0.007_366_890_584_237_29).norm() < 1e-14,
        "{q}"
    );
}

/// Log-domain numerics at the extremes: concentration `1e5` with a large phase, and exactly
/// null `mu . mu` with `|mu| = 1e5`, neither overflow nor lose the phase.
#[test]
fn extremes_do_not_overflow() {
    let k = 2.0 * PI;
    // A sharp lobe times a focus 50 wavelengths away: the phase is k * 50 along the axis.
    let h = ComplexVmf::new(c(0.0, 0.0), [c(0.0, 0.0), c(0.0, 0.0), c(1e5, 50.0 * k)]);
    let l = h.ln_sphere_integral();
    // beta = sqrt((1e5 + 100 pi i)^2) = 1e5 + 100 pi i: ln int = beta - ln(2 beta / (2 pi))...
    let beta = c(1e5, 50.0 * k);
    let expected = beta + (2.0 * PI).ln() - beta.ln();
    // The log is ~1e5: its rounding (1.5e-11 absolute) is the relative error of the value.
    let d = ((l - expected).exp() - 1.0).norm();
    assert!(d < 4.0 * 1e5 * f64::EPSILON, "{l} vs {expected}");
    let null = ComplexVmf::new(c(0.0, 0.0), [c(1e5, 0.0), c(0.0, 1e5), c(0.0, 0.0)]);
    assert!((null.sphere_integral() - 4.0 * PI).norm() < 1e-12);
    let null2 = CircleVmf::new(c(0.0, 0.0), [c(1e5, 0.0), c(0.0, 1e5)]);
    assert!((null2.circle_integral() - 2.0 * PI).norm() < 1e-12);
    let sharp2 = CircleVmf::new(c(0.0, 0.0), [c(1e5, 30.0), c(0.0, 0.0)]);
    assert!(sharp2.ln_circle_integral().re.is_finite());
}

/// Mixtures for the connection test: a back lobe with an isotropic floor, and sharp forward
/// lobes up to `gamma = 3000` (as fitted to HG `g = 0.98`).
fn mixtures() -> Vec<VmfMixture> {
    vec![
        VmfMixture::new(vec![(0.0, 0.3), (8.0, 1.0), (-4.0, 0.4)]).unwrap(),
        VmfMixture::new(vec![(3000.0, 0.2), (40.0, 0.5), (0.5, 0.3)]).unwrap(),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// The exact connection `Upsilon(w_out; o)` of Eqs. 15-16 (weighted aperture of Eqs. 26-27
    /// times the mixture amplitude of Eq. 28, integrated in closed form lobe by lobe) against
    /// quadrature of the pointwise product `a~(w; o) s(w . w_out)`, with `s` the mixture's
    /// normalised amplitude evaluated as a function of the cosine, centred on the sharp lobes
    /// about `w_out`. Apertures up to `gamma_a = 50`, points up to 3 wavelengths from the focus.
    #[test]
    fn upsilon_matches_quadrature(
        log_gamma in -1.0..1.7f64,
        axis in unit3(),
        offset in unit3(),
        r in 0.0..3.0f64,
        w_out in unit3(),
        which in 0usize..2,
        tau in 0.0..2.0f64,
    ) {
        let k = 2.0 * PI;
        let gamma = 10f64.powf(log_gamma);
        let a = Aperture::new(gamma, axis).unwrap();
        let focus = DVec3::new(0.3, -0.1, 0.2);
        let o = focus + r * offset;
        let weighted = a.weighted(k, focus, o, tau);
        let mix = &mixtures()[which];
        let closed = Aperture::ln_upsilon(&weighted, mix, w_out).exp();
        let kappa = mix.components().iter().map(|l| l.gamma.abs()).fold(0.0, f64::max);
        let im = k * (o - focus);
        let f = |w: DVec3| weighted.eval(w) * mix.amplitude(w.dot(w_out));
        let quad = sphere_quadrature_with(w_out, kappa, im, gamma, f);
        let scale = sphere_quadrature_with(w_out, kappa, im, gamma, |w| c(f(w).norm(), 0.0)).re;
        let err = (closed - quad).norm();
        prop_assert!(err <= TOL * scale, "closed {closed} quad {quad} err/scale {:e}", err / scale);
    }
}

/// `|s|` of Henyey-Greenstein, normalised (`int |s|^2 = 1`).
fn hg(g: f64) -> impl Fn(f64) -> f64 {
    move |mu| ((1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5))).sqrt()
}

/// The connection with the mixture of Eq. 28 fitted by the existing EM (`fit_amplitude`) to HG
/// amplitudes, against quadrature with the true HG amplitude. The difference is the fit's error,
/// bounded by Cauchy-Schwarz: `|Upsilon_fit - Upsilon_HG| <= ||a~||_2 ||s_fit - s_HG||_2`, with
/// `||a~||_2^2 = int a~ a~^*` in closed form and the amplitude error by 1-D quadrature in the
/// cosine; the bound is asserted (plus the quadrature tolerance), and the actual relative errors are
/// printed (run with `--nocapture`).
#[test]
fn upsilon_with_fitted_hg_mixture() {
    let k = 2.0 * PI;
    let gl = gauss_legendre(16);
    for g in [0.5, 0.9] {
        let fit =
            speckle_vmf::fit_amplitude(hg(g), g, &speckle_vmf::FitOptions::default()).expect("fit");
        let mix = &fit.mixture;
        // ||s_fit - s_HG||_2 over the sphere: 2 pi int_{-1}^{1} (s_fit - s)^2 dmu, panels graded
        // towards mu = 1 where HG peaks.
        let mut l2 = 0.0;
        for (a, b) in panels(2.0, 1e-4, |_, _| 0.0) {
            for &(x, wt) in &gl {
                let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
                let mu = 1.0 - t;
                let d = mix.amplitude(mu).re - hg(g)(mu);
                l2 += 2.0 * PI * d * d * 0.5 * (b - a) * wt;
            }
        }
        let l2 = l2.sqrt();
        for (gamma, r) in [(2.78, 0.0), (16.0, 1.0), (16.0, 2.5), (50.0, 0.5)] {
            let a = Aperture::new(gamma, DVec3::Z).unwrap();
            let focus = DVec3::ZERO;
            let o = DVec3::new(0.6 * r, 0.0, 0.8 * r);
            let weighted = a.weighted(k, focus, o, 0.3);
            let w_out = DVec3::new(0.3, -0.2, 0.9).normalize();
            let closed = Aperture::ln_upsilon(&weighted, mix, w_out).exp();
            let f = |w: DVec3| weighted.eval(w) * hg(g)(w.dot(w_out));
            let quad = sphere_quadrature_with(w_out, 100.0, k * (o - focus), gamma, f);
            let scale = sphere_quadrature_with(w_out, 100.0, k * (o - focus), gamma, |w| {
                c(f(w).norm(), 0.0)
            })
            .re;
            let norm_a = weighted.mul_conj(&weighted).sphere_integral().re.sqrt();
            let err = (closed - quad).norm();
            println!(
                "HG g={g} ({} lobes, residual {:.3}): gamma_a={gamma} r={r}: |Upsilon|={:.4e} \
                 relative error {:.2e}, bound {:.2e}",
                fit.components,
                fit.residual,
                quad.norm(),
                err / quad.norm(),
                norm_a * l2 / quad.norm()
            );
            assert!(
                err <= norm_a * l2 + TOL * scale,
                "g={g} gamma={gamma} r={r}"
            );
        }
    }
}

/// The convolution approximation of Eqs. 31-32: exact at the expansion direction, variances add
/// for a real lobe on the axis, and the single-scattering (`B = 1`) quantity of Eq. 18,
/// `int a~_v(w) conv(w) dw` with the illumination's weighted aperture convolved with the lobe,
/// against quadrature of the exact per-direction convolution, for the paper's `sigma_a = 0.25`
/// (`gamma_a = 16`), lobes `gamma_s in {2, 20, 100}`, foci on the plane `z = 0` and first
/// vertices within 2 wavelengths (transmission: both axes `+z`, `w_o` the viewing axis).
/// Measured (release, `--nocapture`): median 0.5%, worst 2.46% at `gamma_s = 2`,
/// `o = (0.3, 1.1, 0.2)`, 1.7 beam waists off the axis; the notes (Sec. 4.4f, I6) report below
/// 1-2% nearer the axis. This is the documented error of the approximation where it is made
/// (`B = 1` only); the test pins it below 3% on these points, so a change that degrades it fails.
#[test]
fn convolution_approximation() {
    let k = 2.0 * PI;
    // Exact at w_o, and variances add on the axis.
    let h = ComplexVmf::new(c(0.3, -0.2), [c(1.0, 2.0), c(-0.5, 0.7), c(16.0, -3.0)]);
    let w_o = DVec3::new(0.1, -0.2, 0.97).normalize();
    for gamma in [0.5, 20.0, 3000.0] {
        let a = h.convolve_approx(gamma, w_o).unwrap();
        let d = ((a.ln_eval(w_o) - h.ln_convolve_at(gamma, w_o)).exp() - 1.0).norm();
        assert!(d < 1e-12, "gamma={gamma}: {d:e}");
    }
    let axis = ComplexVmf::real(0.0, 16.0, DVec3::Z)
        .convolve_approx(100.0, DVec3::Z)
        .unwrap();
    let expect = 16.0 * 100.0 / 116.0;
    assert!((axis.mu[2].re - expect).abs() < 1e-12 && axis.mu[0].norm() == 0.0);
    // Branch point: (mu + gamma w_o)^2 = 0 exactly.
    let null = ComplexVmf::new(c(0.0, 0.0), [c(1.0, 0.0), c(0.0, 1.0), c(-2.0, 0.0)]);
    assert!(null.convolve_approx(2.0, DVec3::Z).is_none());

    let gamma_a = 16.0;
    let illum = Aperture::new(gamma_a, DVec3::Z).unwrap();
    let view = Aperture::new(gamma_a, -DVec3::Z).unwrap(); // source form of a sensor along +z
    let (f_i, f_v) = (DVec3::ZERO, DVec3::new(0.4, -0.2, 0.0));
    let mut worst: f64 = 0.0;
    for gamma_s in [2.0, 20.0, 100.0] {
        for o in [
            DVec3::new(0.0, 0.0, 0.5),
            DVec3::new(0.7, -0.3, 1.2),
            DVec3::new(-1.0, 0.5, 2.0),
            DVec3::new(0.3, 1.1, 0.2),
        ] {
            let a_i = illum.weighted(k, f_i, o, 0.0);
            // The viewing aperture over the viewing direction v^: source form over w = -v^.
            let a_v = view.weighted(k, f_v, o, 0.0);
            let a_v_of = |v_hat: DVec3| a_v.ln_eval(-v_hat);
            let approx = a_i.convolve_approx(gamma_s, DVec3::Z).unwrap();
            let a_v_user = ComplexVmf::new(a_v.log_scale, a_v.mu.map(|m| -m));
            let closed = a_v_user.mul(&approx).sphere_integral();
            let im = k * (o - f_i).length() + k * (o - f_v).length();
            let quad =
                sphere_quadrature_with(DVec3::Z, gamma_a, DVec3::new(im, 0.0, 0.0), gamma_s, |w| {
                    (a_v_of(w) + a_i.ln_convolve_at(gamma_s, w)).exp()
                });
            let rel = (closed - quad).norm() / quad.norm();
            println!("gamma_s={gamma_s} o={o}: B = 1 relative error {rel:.2e}");
            worst = worst.max(rel);
        }
    }
    assert!(worst < 0.03, "worst relative error {worst}");
}
