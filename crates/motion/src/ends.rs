//! Where the two copies of a path connect their end vertices at a time lag, and the phase
//! their shared segments gain: the end-vertex factors for endpoints whose leg has no single
//! direction (focused Gaussian beams), and the exact-drift connections of every endpoint.
//!
//! At lag `t` copy 1 of a path is read at `-t/2` and copy 2 at `+t/2` (crate docs), so an end
//! vertex `x` moving by `Delta = t U + sqrt(2 D |t|) z` (Eq. 1, `z ~ N(0, I)`) lies at
//! `x - Delta / 2` for copy 1 and at `x + Delta / 2` for copy 2. Each copy connects to its own
//! endpoint from there, exactly (lengths, attenuation, amplitudes).
//!
//! - **Drift** (the *hybrid exact-drift* scheme, `docs/conventions.md`): the drift part `t U` is
//!   always applied this way; the interior drift telescopes in [`crate::MotionState`].
//! - **Brownian motion** at plane-wave, far-field and point endpoints is averaged in closed form
//!   ([`crate::gamma`] of [`crate::first_transfer`], [`crate::last_transfer`]): the
//!   displacement's Brownian part is then zero here ([`EndDisplacement::drift`]).
//! - At a **Gaussian beam**, a superposition of plane waves, the Gaussian average couples the
//!   plane-wave directions of both copies' apertures and has no closed form in the vMF algebra;
//!   the Brownian part is *sampled* instead ([`EndDisplacement::sampled`], one `z` per end vertex
//!   and path, shared by all lags), the copies connect from their displaced points, and the
//!   shared first and last segments of the path change by the first-order phase
//!   [`segment_phase`] (the Brownian parts only: their drift is in the interior sums). The
//!   expectation over `z` is the exact Gaussian average at the end vertex. A path that sampled
//!   its end displacements uses them at both ends (its first vertex's `z_1`, its last vertex's
//!   `z_b`; for single scattering one `z` for the one vertex, with no segment phase).

use crate::Motion;
use glam::DVec3;
use num_complex::Complex64;

/// The displacement of an end vertex between the two copies of a path at one lag: the drift
/// part `t U` and the Brownian part `sqrt(2 D |t|) z` (zero when averaged in closed form).
///
/// ```
/// use speckle_motion::{EndDisplacement, Motion};
/// use speckle_motion::glam::DVec3;
/// let m = Motion::new(0.01, DVec3::new(0.5, 0.0, 0.0)).unwrap();
/// let z = DVec3::new(1.0, -0.5, 0.25); // a standard normal draw of the embedder's own RNG
/// let d = EndDisplacement::sampled(&m, 2.0, z);
/// assert_eq!(d.drift, DVec3::new(1.0, 0.0, 0.0));
/// assert!((d.brownian - 0.2 * z).length() < 1e-15); // sqrt(2 D t) = 0.2
/// // Copy 1 (read at -t/2) connects from x - Delta/2, copy 2 from x + Delta/2.
/// let [a, b] = d.copies(DVec3::ZERO);
/// assert!((b - a - (d.drift + d.brownian)).length() < 1e-15);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EndDisplacement {
    /// The drift part `t U`.
    pub drift: DVec3,
    /// The Brownian part `sqrt(2 D |t|) z`.
    pub brownian: DVec3,
}

impl EndDisplacement {
    /// The drift part alone, `t U` (Brownian motion averaged in closed form): the exact-drift
    /// connections of plane-wave, far-field and point endpoints.
    #[inline]
    pub fn drift(motion: &Motion, t: f64) -> Self {
        Self::sampled(motion, t, DVec3::ZERO)
    }

    /// The displacement over the lag `t` of a vertex moving with `motion`, its Brownian part
    /// from the standard normal vector `z` (drawn once per end vertex and path; in flatland in
    /// the plane).
    #[inline]
    pub fn sampled(motion: &Motion, t: f64, z: DVec3) -> Self {
        Self {
            drift: t * motion.drift,
            brownian: (2.0 * motion.diffusion * t.abs()).sqrt() * z,
        }
    }

    /// Where copy `copy` (`0`: read at `-t/2`; `1`: at `+t/2`) of the end vertex `x` connects
    /// from: `x -/+ (t U + sqrt(2 D |t|) z) / 2`.
    #[inline]
    pub fn copy(&self, x: DVec3, copy: usize) -> DVec3 {
        let sign = if copy == 0 { -0.5 } else { 0.5 };
        x + sign * self.drift + sign * self.brownian
    }

    /// Both copies' points, [`EndDisplacement::copy`] `0` and `1`.
    #[inline]
    pub fn copies(&self, x: DVec3) -> [DVec3; 2] {
        [self.copy(x, 0), self.copy(x, 1)]
    }
}

/// The first-order change `exp(i k (w1 . b_1 - w_in . b_b))` of a path's shared first and last
/// segments when its end vertices are displaced by sampled Brownian parts `b_1 = first.brownian`
/// and `b_b = last.brownian` between the copies (`w1` the direction leaving the first vertex,
/// `w_in` the direction reaching the last; paths of two or more vertices). Multiply the path's
/// interior factor ([`crate::MotionState::interior`]) and its copies' end connections by it.
///
/// ```
/// use speckle_motion::{EndDisplacement, segment_phase};
/// use speckle_motion::glam::DVec3;
/// let first = EndDisplacement { brownian: DVec3::new(0.0, 0.0, 0.1), ..Default::default() };
/// let last = EndDisplacement::default();
/// let p = segment_phase(std::f64::consts::TAU, DVec3::Z, &first, DVec3::X, &last);
/// assert!((p.arg() - 0.2 * std::f64::consts::PI).abs() < 1e-15);
/// ```
#[inline]
pub fn segment_phase(
    k: f64,
    w1: DVec3,
    first: &EndDisplacement,
    w_in: DVec3,
    last: &EndDisplacement,
) -> Complex64 {
    Complex64::from_polar(1.0, k * (w1.dot(first.brownian) - w_in.dot(last.brownian)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sampled phase of a vertex averages to the closed-form Brownian factor: for a last
    /// vertex reached along `w_in` and a far-field leg `v` connected from both copies,
    /// `E[e^{i k (v - w_in) . b}] = exp(-k^2 D |t| |v - w_in|^2)`, quadrature over `z`.
    #[test]
    fn sampled_displacements_average_to_the_closed_form() {
        let (k, t) = (std::f64::consts::TAU, 0.7);
        let m = Motion::brownian(0.01).unwrap();
        let (w_in, v) = (DVec3::new(0.6, 0.0, 0.8), DVec3::Z);
        let q = v - w_in;
        // Gauss-Hermite-free check: the average over z of a Gaussian along q's direction is
        // one-dimensional; trapezoid on a fine grid of the normal density.
        let u = q.normalize();
        let n = 4001;
        let (mut num, mut den) = (Complex64::ZERO, 0.0);
        for i in 0..n {
            let s = -8.0 + 16.0 * i as f64 / (n - 1) as f64;
            let p = (-0.5 * s * s).exp();
            let last = EndDisplacement::sampled(&m, t, s * u);
            let [a, b] = last.copies(DVec3::ZERO);
            // The far-field legs of the two copies, e^{-i k v . x}, and the segment's phase.
            let legs = Complex64::from_polar(1.0, -k * v.dot(a))
                * Complex64::from_polar(1.0, -k * v.dot(b)).conj();
            let f = legs * segment_phase(k, DVec3::Z, &EndDisplacement::default(), w_in, &last);
            num += p * f;
            den += p;
        }
        let expect = crate::gamma(k, &m, q, t);
        assert!(
            (num / den - expect).norm() < 1e-12,
            "{} vs {expect}",
            num / den
        );
    }

    #[test]
    fn drift_alone_has_no_brownian_part() {
        let m = Motion::new(0.3, DVec3::new(0.0, 2.0, 0.0)).unwrap();
        let d = EndDisplacement::drift(&m, -0.25);
        assert_eq!(d.brownian, DVec3::ZERO);
        assert_eq!(
            d.copies(DVec3::X),
            [DVec3::new(1.0, 0.25, 0.0), DVec3::new(1.0, -0.25, 0.0)]
        );
    }
}
