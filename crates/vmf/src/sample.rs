//! Directions drawn from real von Mises-Fisher densities: on the sphere `C_3(kappa) e^(r . w)`
//! (`kappa = |r|`) and on the circle `e^(kappa cos(theta - theta_0)) / (2 pi I_0(kappa))`. The
//! focused beam's mask is one (Bar et al. 2020, Eq. 10), and so is each lobe of a vMF amplitude.

use glam::{DVec2, DVec3};
use std::f64::consts::{PI, TAU};

/// A direction from the real vMF density `C_3(|r|) e^(r . w)` on the sphere, from two uniform
/// variates in `[0, 1)`: the cosine about `r` by the exact, stable inverse CDF of `e^(kappa t)`
/// on `[-1, 1]`, the azimuth uniform. Uniform on the sphere for `|r| <= 1e-8`.
///
/// ```
/// use speckle_vmf::sample_sphere_vmf;
/// use glam::DVec3;
/// let w = sample_sphere_vmf(DVec3::new(0.0, 0.0, 50.0), [0.3, 0.7]);
/// assert!((w.length() - 1.0).abs() < 1e-12 && w.z > 0.9);
/// ```
pub fn sample_sphere_vmf(r: DVec3, u: [f64; 2]) -> DVec3 {
    let kappa = r.length();
    if kappa.is_nan() || kappa <= 1e-8 {
        let z = 1.0 - 2.0 * u[0];
        let s = (1.0 - z * z).max(0.0).sqrt();
        let (sn, cs) = (TAU * u[1]).sin_cos();
        return DVec3::new(s * cs, s * sn, z);
    }
    // Inverse CDF of e^(kappa t) on [-1, 1], stable for large kappa.
    let cos = (1.0 + ((1.0 - u[0]) * (-2.0 * kappa).exp_m1()).ln_1p() / kappa).clamp(-1.0, 1.0);
    let mean = r / kappa;
    let (a, b) = mean.any_orthonormal_pair();
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let (s, c) = (TAU * u[1]).sin_cos();
    cos * mean + sin * (c * a + s * b)
}

/// A direction from the von Mises density `e^(r . w) / (2 pi I_0(|r|))` on the unit circle, by
/// the rejection method of Best and Fisher (1979, "Efficient simulation of the von Mises
/// distribution", wrapped-Cauchy envelope; acceptance above 65% for every concentration), drawing
/// uniform variates in `[0, 1)` from `next` (three per trial). Uniform for `|r| <= 1e-8`.
///
/// ```
/// use speckle_vmf::sample_circle_vmf;
/// use glam::DVec2;
/// let mut u = [0.1, 0.8, 0.4, 0.6, 0.3, 0.2].into_iter().cycle();
/// let w = sample_circle_vmf(DVec2::new(40.0, 0.0), &mut || u.next().unwrap());
/// assert!((w.length() - 1.0).abs() < 1e-12 && w.x > 0.8);
/// ```
pub fn sample_circle_vmf(r: DVec2, next: &mut impl FnMut() -> f64) -> DVec2 {
    let kappa = r.length();
    if kappa.is_nan() || kappa <= 1e-8 {
        return DVec2::from_angle(TAU * next());
    }
    let tau = 1.0 + (1.0 + 4.0 * kappa * kappa).sqrt();
    let rho = (tau - (2.0 * tau).sqrt()) / (2.0 * kappa);
    let s = (1.0 + rho * rho) / (2.0 * rho);
    let f = loop {
        let (u1, u2) = (next(), next());
        let z = (PI * u1).cos();
        let f = (1.0 + s * z) / (s + z);
        let c = kappa * (s - f);
        if c * (2.0 - c) > u2 || (c / u2).ln() + 1.0 >= c {
            break f.clamp(-1.0, 1.0);
        }
    };
    let theta = f.acos().copysign(next() - 0.5);
    let mean = r / kappa;
    DVec2::from_angle(theta).rotate(mean)
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_rng::PathRng;

    /// Mean and standard error of `f` over `n` draws.
    fn mean_se(n: usize, mut f: impl FnMut() -> f64) -> (f64, f64) {
        let (mut a, mut a2) = (0.0, 0.0);
        for _ in 0..n {
            let y = f();
            a += y;
            a2 += y * y;
        }
        let m = a / n as f64;
        (m, ((a2 / n as f64 - m * m) / n as f64).sqrt())
    }

    /// The mean cosine about the mean direction and the mean of `cos(2 phi)` of the azimuth (or,
    /// on the circle, of the sine) against their closed forms: `coth(kappa) - 1 / kappa` and 0 on
    /// the sphere, `I_1(kappa) / I_0(kappa)` and 0 on the circle, within 5 standard errors.
    #[test]
    fn moments_match_the_closed_forms() {
        let mut rng = PathRng::new(5, 0);
        for kappa in [1e-9, 0.3, 4.0, 16.0, 400.0] {
            let dir = DVec3::new(0.3, -0.5, 0.8).normalize();
            let (m, se) = mean_se(200_000, || {
                sample_sphere_vmf(kappa * dir, rng.next_2()).dot(dir)
            });
            let want = if kappa < 1e-6 {
                0.0
            } else {
                1.0 / kappa.tanh() - 1.0 / kappa
            };
            assert!(
                (m - want).abs() < 5.0 * se + 1e-12,
                "3D {kappa}: {m} {want} {se}"
            );
            // E[t^2] = 1 - 2 E[t] / kappa.
            let (m2, se) = mean_se(200_000, || {
                let t = sample_sphere_vmf(kappa * dir, rng.next_2()).dot(dir);
                t * t
            });
            let want2 = if kappa < 1e-6 {
                1.0 / 3.0
            } else {
                1.0 - 2.0 * want / kappa
            };
            assert!(
                (m2 - want2).abs() < 5.0 * se,
                "3D t^2 {kappa}: {m2} {want2} {se}"
            );
            let (a, b) = dir.any_orthonormal_pair();
            let (m, se) = mean_se(200_000, || {
                let w = sample_sphere_vmf(kappa * dir, rng.next_2());
                let (x, y) = (w.dot(a), w.dot(b));
                (x * x - y * y) / (x * x + y * y).max(1e-300)
            });
            assert!(m.abs() < 5.0 * se, "3D azimuth {kappa}: {m} {se}");

            let mean = DVec2::new(-0.6, 0.8);
            let mut next = || rng.next_f64();
            let (m, se) = mean_se(200_000, || {
                sample_circle_vmf(kappa * mean, &mut next).dot(mean)
            });
            let ratio = crate::bessel_ratio_over_z(num_complex::Complex64::new(kappa, 0.0)).re;
            let want = ratio * kappa;
            assert!(
                (m - want).abs() < 5.0 * se + 1e-12,
                "2D {kappa}: {m} {want} {se}"
            );
            // E[cos 2 theta] = I_2 / I_0 = 1 - 2 I_1 / (kappa I_0).
            let (m, se) = mean_se(200_000, || {
                let c = sample_circle_vmf(kappa * mean, &mut next).dot(mean);
                2.0 * c * c - 1.0
            });
            let want = 1.0 - 2.0 * ratio;
            assert!(
                (m - want).abs() < 5.0 * se + 1e-12,
                "2D cos 2: {kappa}: {m} {want} {se}"
            );
            let (m, se) = mean_se(200_000, || {
                sample_circle_vmf(kappa * mean, &mut next).perp_dot(mean)
            });
            assert!(m.abs() < 5.0 * se + 1e-12, "2D sine {kappa}: {m} {se}");
        }
    }
}
