//! The decorrelation factor of one vertex (Eq. 14) and the momentum transfers it is evaluated
//! at: interior vertices (Eq. 13) and the first and last vertices with the averaged endpoint
//! directions (derived below).
//!
//! Derivation: with the two copies of a path at `o - Delta/2` and
//! `o + Delta/2`, the difference of their path lengths is, to first order in `Delta`,
//! `-(G_1 + G_2) . Delta / 2`, `G_c` the gradient of copy `c`'s length with respect to the
//! vertex. The vertex's factor is the Gaussian average `E[exp(i k q . Delta)]` over
//! `Delta ~ N(t U, 2 D |t| I)`, with `q = -(G_1 + G_2) / 2`. Inside a path both copies have
//! `G = w_in - w_out` (the two segments at the vertex), so `q = w_out - w_in`. At the first
//! vertex `G_c = g_c - w1` (the copy's source leg, or for a reversed copy its sensor leg, plus
//! the shared segment to `x2`), so `q = w1 - (g_1 + g_2) / 2`; at the last vertex
//! `G_c = g_c + w_in`; at the only vertex of a single-scattering path `G_c = g_src + g_sens`.

use crate::Motion;
use glam::DVec3;
use num_complex::Complex64;

/// Eq. 14: the decorrelation of one vertex with momentum transfer `q` over the time lag `t` at
/// wavenumber `k`, `exp(-k^2 D |t| |q|^2 + i k t q . U)`.
///
/// ```
/// use speckle_motion::{Motion, gamma};
/// use speckle_motion::glam::DVec3;
/// // Back-scattering (|q|^2 = 4) of a diffusing scatterer: exp(-4 k^2 D t).
/// let m = Motion::brownian(0.015).unwrap();
/// let k = std::f64::consts::TAU;
/// let g = gamma(k, &m, DVec3::new(0.0, 2.0, 0.0), 2.0);
/// assert!((g.re - (-4.0 * k * k * 0.015 * 2.0f64).exp()).abs() < 1e-15 && g.im == 0.0);
/// ```
#[inline]
pub fn gamma(k: f64, motion: &Motion, q: DVec3, t: f64) -> Complex64 {
    let brownian = -k * k * motion.diffusion * t.abs() * q.length_squared();
    let drift = k * t * q.dot(motion.drift);
    Complex64::from_polar(brownian.exp(), drift)
}

/// The momentum transfer `w_out - w_in` of an interior vertex (Eq. 13), directions of
/// propagation before and after it.
#[inline]
pub fn interior_transfer(w_in: DVec3, w_out: DVec3) -> DVec3 {
    w_out - w_in
}

/// The leg gradient of a source leg whose propagation direction at the vertex is `dir` (see the
/// crate docs): `dir` itself.
#[inline]
pub fn source_gradient(dir: DVec3) -> DVec3 {
    dir
}

/// The leg gradient of a sensor leg leaving the vertex along `dir`: `-dir`.
#[inline]
pub fn sensor_gradient(dir: DVec3) -> DVec3 {
    -dir
}

/// The momentum transfer of the first vertex of a path of at least two vertices, whose two
/// copies have leg gradients `g1`, `g2` there and which leaves along `w1`:
/// `w1 - (g1 + g2) / 2` (`w1 - s` when both copies share their source).
#[inline]
pub fn first_transfer(w1: DVec3, g1: DVec3, g2: DVec3) -> DVec3 {
    w1 - 0.5 * (g1 + g2)
}

/// The momentum transfer of the last vertex of a path of at least two vertices, reached along
/// `w_in`, whose two copies have leg gradients `g1`, `g2` there: `-w_in - (g1 + g2) / 2`
/// (`e - w_in` for forward copies that share their sensor, `g = -e`).
#[inline]
pub fn last_transfer(w_in: DVec3, g1: DVec3, g2: DVec3) -> DVec3 {
    -w_in - 0.5 * (g1 + g2)
}

/// The momentum transfer of a single-scattering path, whose copies have total leg gradients
/// `g1 = s_1 - e_1` and `g2 = s_2 - e_2`: `-(g1 + g2) / 2` (`e - s` for one pair).
#[inline]
pub fn single_transfer(g1: DVec3, g2: DVec3) -> DVec3 {
    -0.5 * (g1 + g2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use speckle_rng::PathRng;

    fn unit(v: [f64; 3]) -> DVec3 {
        DVec3::from_array(v).normalize()
    }

    proptest! {
        /// gamma is 1 at zero lag, bounded by 1, Hermitian in time (gamma(-t) = conj gamma(t)),
        /// and depends on D and t through D |t| only when U = 0.
        #[test]
        fn gamma_laws(d in 0.0f64..1.0, u in prop::array::uniform3(-1.0f64..1.0),
                      q in prop::array::uniform3(-2.0f64..2.0), t in -3.0f64..3.0) {
            let k = 2.7;
            let m = Motion::new(d, DVec3::from_array(u)).unwrap();
            let q = DVec3::from_array(q);
            prop_assert_eq!(gamma(k, &m, q, 0.0), Complex64::ONE);
            let g = gamma(k, &m, q, t);
            prop_assert!(g.norm() <= 1.0 + 1e-15);
            let h = gamma(k, &m, q, -t);
            prop_assert!((g - h.conj()).norm() < 1e-14);
            let b = Motion::brownian(d).unwrap();
            let scaled = Motion::brownian(2.0 * d).unwrap();
            prop_assert!((gamma(k, &b, q, t) - gamma(k, &scaled, q, t / 2.0)).norm() < 1e-14);
        }

        /// The endpoint transfers collapse to the interior one when both copies share their
        /// endpoint (the paper's collapse statement), and swapping the copies leaves them
        /// unchanged (Hermitian symmetry).
        #[test]
        fn endpoint_transfers_collapse(a in prop::array::uniform3(-1.0f64..1.0),
                                       b in prop::array::uniform3(-1.0f64..1.0),
                                       c in prop::array::uniform3(-1.0f64..1.0)) {
            prop_assume!(DVec3::from_array(a).length() > 0.1);
            prop_assume!(DVec3::from_array(b).length() > 0.1);
            prop_assume!(DVec3::from_array(c).length() > 0.1);
            let (s, w, e) = (unit(a), unit(b), unit(c));
            let g = source_gradient(s);
            prop_assert!((first_transfer(w, g, g) - interior_transfer(s, w)).length() < 1e-15);
            let g = sensor_gradient(e);
            prop_assert!((last_transfer(w, g, g) - interior_transfer(w, e)).length() < 1e-15);
            let g = source_gradient(s) + sensor_gradient(e);
            prop_assert!((single_transfer(g, g) - interior_transfer(s, e)).length() < 1e-15);
            prop_assert_eq!(first_transfer(w, s, e), first_transfer(w, e, s));
        }
    }

    /// The endpoint factors against brute force: the Gaussian average of the exact phase
    /// difference `k (L_1(x1 - Delta/2, x3 - Delta_3/2) - L_2(x1 + Delta/2, x3 + Delta_3/2))` of a
    /// three-vertex path whose copies connect to different point sources and sensors, over
    /// sampled displacements of all three vertices, equals the product of the three gammas of
    /// Eq. 14 with the averaged endpoint transfers, to the Monte Carlo error of the average
    /// (plus the second-order remainder `k |Delta|^2 / r`, here below 1e-3).
    #[test]
    fn endpoint_factors_match_brute_force_displacements() {
        let k = std::f64::consts::TAU;
        let m = Motion::new(0.01, DVec3::new(0.03, 0.02, 0.0)).unwrap();
        let t = 1.0;
        let (i1, i2) = (DVec3::new(-60.0, 0.0, -40.0), DVec3::new(-58.0, 3.0, -40.0));
        let (v1, v2) = (DVec3::new(70.0, 0.0, 50.0), DVec3::new(69.0, -2.0, 52.0));
        let x = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(3.0, 1.0, 2.0),
            DVec3::new(5.0, -1.0, 4.0),
        ];
        let len = |i: DVec3, p: [DVec3; 3], v: DVec3| {
            (p[0] - i).length()
                + (p[1] - p[0]).length()
                + (p[2] - p[1]).length()
                + (v - p[2]).length()
        };
        let n = 400_000u64;
        let sd = (2.0 * m.diffusion * t).sqrt();
        let mut acc = Complex64::ZERO;
        for s in 0..n {
            let mut rng = PathRng::new(77, s);
            let mut p1 = x;
            let mut p2 = x;
            for b in 0..3 {
                let g = DVec3::new(normal(&mut rng), normal(&mut rng), normal(&mut rng));
                let d = t * m.drift + sd * g;
                p1[b] -= 0.5 * d;
                p2[b] += 0.5 * d;
            }
            acc += Complex64::from_polar(1.0, k * (len(i1, p1, v1) - len(i2, p2, v2)));
        }
        let brute = acc / n as f64;
        let (w1, w2) = ((x[1] - x[0]).normalize(), (x[2] - x[1]).normalize());
        let s = |i: DVec3| (x[0] - i).normalize();
        let e = |v: DVec3| (v - x[2]).normalize();
        let q1 = first_transfer(w1, source_gradient(s(i1)), source_gradient(s(i2)));
        let q2 = interior_transfer(w1, w2);
        let q3 = last_transfer(w2, sensor_gradient(e(v1)), sensor_gradient(e(v2)));
        let static_phase = Complex64::from_polar(1.0, k * (len(i1, x, v1) - len(i2, x, v2)));
        let predicted =
            static_phase * gamma(k, &m, q1, t) * gamma(k, &m, q2, t) * gamma(k, &m, q3, t);
        // Standard error of the mean of unit phasors: at most 1/sqrt(n) per part.
        let tol = 4.0 / (n as f64).sqrt() + 1e-3;
        assert!(
            (brute - predicted).norm() < tol,
            "brute force {brute} against {predicted} (tolerance {tol})"
        );
        assert!(
            predicted.norm() < 0.9,
            "the test must decorrelate: {predicted}"
        );
    }

    /// A standard normal variate (Box-Muller on two uniforms of the stream).
    fn normal(rng: &mut PathRng) -> f64 {
        let [a, b] = rng.next_2();
        (-2.0 * (1.0 - a).ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}
