//! The running sums of a path's interior decorrelation ([`MotionState`]), which give it at every
//! time lag from one traced path, in plain data (directions and motions): any tracer can keep
//! them.
//!
//! The contribution of vertex `x_b` of a path carries the product of the gammas of Eq. 14 over
//! its vertices `x_1 .. x_b`. The interior ones (`x_2 .. x_{b-1}`) do not depend on the pair
//! of endpoints, so they are kept as two sums along the path ([`MotionState`]),
//!
//! - `Y = sum_{m=2}^{b-1} D(x_m) |w_m - w_{m-1}|^2` (Brownian), and
//! - `Q = sum_{m=1}^{b-1} w_m . (U(x_m) - U(x_{m+1}))` (drift),
//!
//! and the interior factor at lag `t` is `exp(-k^2 |t| Y + i k t Q)`
//! ([`MotionState::interior`]), `O(1)` per lag. `Q` is the interior drift of the *hybrid
//! exact-drift* scheme (which the authors' code uses): the end vertices'
//! drift is applied exactly by connecting the two copies at `x -/+ t U(x) / 2`, and then the
//! sum of `q_m . U_m` over the interior and the shared parts of the end transfers telescopes to
//! `Q`; it vanishes when `U` is the same along the path.
//!
//! The end vertices' factors depend on the pair (the averaged endpoint directions,
//! [`crate::first_transfer`], [`crate::last_transfer`]): a tracer applies them per pair from
//! the state (the first direction, the motion at `x_1` and at `x_b`), evaluating every lag from
//! the same state, as the spatio-temporal estimator (`speckle_estimators::render_correlation`,
//! whose path factor `speckle_estimators::MotionFactor` keeps this state along its paths) does.
//!
//! # A path's factor at lag `t`, in your own tracer
//!
//! For a contribution ending at `x_b` (`b >= 2`) of a pair whose copies have leg gradients
//! `g_s1, g_s2` at `x_1` and `g_v1, g_v2` at `x_b` ([`crate::source_gradient`],
//! [`crate::sensor_gradient`]: for point and far-field endpoints the leg direction; equal for a
//! diagonal entry):
//!
//! - without drift: `gamma(k, m_1, first_transfer(w1, g_s1, g_s2), t) * interior(k, t) *
//!   gamma(k, m_b, last_transfer(w_in, g_v1, g_v2), t)` (`m_1`, `m_b`: [`MotionState::first`]
//!   and [`MotionState::here`]);
//! - with drift: connect copy 1 (read at `-t/2`) from `x - t U(x) / 2` and copy 2 from
//!   `x + t U(x) / 2` at both end vertices with your own exact legs (lengths, attenuations,
//!   amplitudes), multiply `A_1 conj(A_2)` by `interior(k, t)` (whose drift sum telescopes the
//!   interior) and by the end gammas of the Brownian parts alone (`Motion::brownian(D)`); a path
//!   whose vertex lies outside the medium at either time contributes nothing at that lag. This is
//!   what `render_correlation` does; `crates/motion/examples/own_tracer.rs` does it for a plane
//!   wave and a far-field sensor, checked against `render_correlation` (real and imaginary
//!   parts of `g1`) by the workspace's `tests/embed_g1.rs`.

use crate::Motion;
use glam::DVec3;
use num_complex::Complex64;

/// The per-path state of the decorrelation of moving scatterers: what the end-vertex factors of
/// the current contribution need, and the running interior sums (see the module docs). A tracer
/// keeps one per path: [`MotionState::start`] at the first vertex, [`MotionState::advance`] at
/// each next one, and [`MotionState::interior`] for the interior factor at any lag.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MotionState {
    /// The motion at the first vertex `x1`.
    pub first: Motion,
    /// The motion at the current vertex `x_b`.
    pub here: Motion,
    /// The first direction `w1` (from `x1` to `x2`; zero before `x2`).
    pub w1: DVec3,
    /// The direction of arrival at the current vertex `x_b`.
    pub w_in: DVec3,
    /// `Y`, the Brownian interior sum over `x_2 .. x_{b-1}` (see the module docs).
    pub y: f64,
    /// `Q`, the interior drift sum over the segments `x_1 -> .. -> x_b`.
    pub q: f64,
}

impl MotionState {
    /// The state of a path at its first vertex `x1`, where the scatterers move with `first`.
    #[inline]
    pub fn start(first: Motion) -> Self {
        Self {
            first,
            here: first,
            ..Self::default()
        }
    }

    /// The path has reached its vertex `x_b` (`b >= 2`), arriving along the unit `w_in`, where
    /// the scatterers move with `here`. At `b = 2`, `w_in` is also the first direction `w1`.
    /// Updates the sums: the vertex `x_{b-1}` becomes interior (its transfer is
    /// `w_in(x_b) - w_in(x_{b-1})`), and the segment `x_{b-1} -> x_b` adds
    /// `w_in . (U(x_{b-1}) - U(x_b))` to the drift sum.
    #[inline]
    pub fn advance(&mut self, b: u32, here: Motion, w_in: DVec3) {
        if b == 2 {
            self.w1 = w_in;
        } else {
            let q = crate::interior_transfer(self.w_in, w_in);
            self.y += self.here.diffusion * q.length_squared();
        }
        self.q += w_in.dot(self.here.drift - here.drift);
        self.here = here;
        self.w_in = w_in;
    }

    /// The interior factor `exp(-k^2 |t| Y + i k t Q)` at lag `t` for wavenumber `k`.
    #[inline]
    pub fn interior(&self, k: f64, t: f64) -> Complex64 {
        Complex64::from_polar(self.interior_decay(k, t), k * t * self.q)
    }

    /// Its magnitude `exp(-k^2 |t| Y)`: the whole factor where nothing drifts (`Q = 0`; then
    /// equal to [`MotionState::interior`]'s real part bitwise, without its sine and cosine).
    #[inline]
    pub fn interior_decay(&self, k: f64, t: f64) -> f64 {
        (-k * k * t.abs() * self.y).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{gamma, interior_transfer};

    /// Along a hand-made path whose vertices move in two ways, the interior factor is the
    /// product of the interior gammas of Eq. 14 (Brownian part) times the telescoped interior
    /// drift, at every lag, and the state holds the end-vertex data.
    #[test]
    fn interior_factor_is_the_product_of_interior_gammas() {
        let m0 = Motion::new(0.3, DVec3::new(0.2, 0.0, 0.1)).unwrap();
        let m1 = Motion::new(0.1, DVec3::new(-0.1, 0.3, 0.0)).unwrap();
        // The motion of each vertex (x < 1: m0, else m1).
        let x = [
            DVec3::new(0.2, 0.5, 0.5),
            DVec3::new(0.7, 0.3, 0.6),
            DVec3::new(1.4, 0.6, 0.2),
            DVec3::new(0.9, 0.2, 0.8),
            DVec3::new(1.8, 0.7, 0.4),
        ];
        let motion = |p: DVec3| if p.x < 1.0 { m0 } else { m1 };
        let k = 3.0;
        let lags = [0.0, 0.4, -0.7];
        let w: Vec<DVec3> = x.windows(2).map(|p| (p[1] - p[0]).normalize()).collect();
        let mut state = MotionState::start(motion(x[0]));
        for b in 2..=x.len() {
            state.advance(b as u32, motion(x[b - 1]), w[b - 2]);
            assert_eq!(state.w1, w[0]);
            assert_eq!(state.here, motion(x[b - 1]));
            assert_eq!(state.first, m0);
            for &t in &lags {
                // Interior vertices x_2 .. x_{b-1} (indices 1..b-2): Brownian gammas.
                let mut want = Complex64::ONE;
                for m in 1..b - 1 {
                    let brownian = Motion::brownian(motion(x[m]).diffusion).unwrap();
                    want *= gamma(k, &brownian, interior_transfer(w[m - 1], w[m]), t);
                }
                // Drift: the sum over segments of w . (U_from - U_to).
                let q: f64 = (0..b - 1)
                    .map(|s| w[s].dot(motion(x[s]).drift - motion(x[s + 1]).drift))
                    .sum();
                want *= Complex64::from_polar(1.0, k * t * q);
                let got = state.interior(k, t);
                assert!((got - want).norm() < 1e-14, "b = {b}, t = {t}");
                if t == 0.0 {
                    assert_eq!(got, Complex64::ONE);
                }
            }
        }
        // Uniform drift telescopes to no interior drift phase.
        let uniform = Motion::new(0.0, DVec3::new(0.5, -0.2, 0.3)).unwrap();
        let mut state = MotionState::start(uniform);
        for b in 2..=x.len() {
            state.advance(b as u32, uniform, w[b - 2]);
            assert_eq!(state.interior(k, 0.4), Complex64::ONE);
        }
    }
}
