//! The interior decorrelation of a path, as a [`PathFactor`], and the running sums that give
//! it at every time lag from one traced path.
//!
//! The contribution of vertex `x_b` of a path carries the product of the gammas of Eq. 14 over
//! its vertices `x_1 .. x_b`. The interior ones (`x_2 .. x_{b-1}`) do not depend on the pair
//! of endpoints; by the note's evaluation trick (`shared/notes/spatiotemporal-2023.md` Sec. 6)
//! they are kept as two sums along the path ([`MotionState`]),
//!
//! - `Y = sum_{m=2}^{b-1} D(x_m) |w_m - w_{m-1}|^2` (Brownian), and
//! - `Q = sum_{m=1}^{b-1} w_m . (U(x_m) - U(x_{m+1}))` (drift),
//!
//! and the interior factor at lag `t` is `exp(-k^2 |t| Y + i k t Q)`
//! ([`MotionState::interior`]), `O(1)` per lag. `Q` is the interior drift of the *hybrid
//! exact-drift* scheme (the note's Sec. 5.3, which the authors' code uses): the end vertices'
//! drift is applied exactly by connecting the two copies at `x -/+ t U(x) / 2`, and then the
//! sum of `q_m . U_m` over the interior and the shared parts of the end transfers telescopes to
//! `Q`; it vanishes when `U` is the same along the path.
//!
//! The end vertices' factors depend on the pair (the averaged endpoint directions,
//! [`crate::first_transfer`], [`crate::last_transfer`]): a [`PathFactor`]'s one value per
//! vertex cannot hold them, so [`MotionFactor`] as a path factor is the interior part at one
//! lag, and the spatio-temporal estimator (`speckle_estimators::render_correlation`) applies the
//! end factors per entry from the [`MotionState`] (the first direction, the motion at `x_1` and
//! at `x_b`), evaluating every lag from the same state.

use crate::Motion;
use crate::MotionModel;
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_paths::{PathFactor, Vertex};

/// The interior decorrelation factor of moving scatterers for a medium, its [`MotionModel`], a
/// wavenumber `k` and a time lag (the lag of its [`PathFactor`] value; [`MotionState`] gives
/// any other).
#[derive(Debug, Clone)]
pub struct MotionFactor<'a, M> {
    medium: &'a M,
    model: &'a MotionModel,
    k: f64,
    lag: f64,
}

/// The per-path state of a [`MotionFactor`]: what the end-vertex factors of the current
/// contribution need, and the running interior sums.
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
    /// The interior factor `exp(-k^2 |t| Y + i k t Q)` at lag `t` for wavenumber `k`.
    #[inline]
    pub fn interior(&self, k: f64, t: f64) -> Complex64 {
        Complex64::from_polar((-k * k * t.abs() * self.y).exp(), k * t * self.q)
    }
}

impl<'a, M: Medium> MotionFactor<'a, M> {
    /// The factor at the time lag `lag` (the caller validates the model against the medium and
    /// the lag, [`MotionModel::validated`], [`crate::check_lags`]).
    pub fn new(medium: &'a M, model: &'a MotionModel, k: f64, lag: f64) -> Self {
        Self {
            medium,
            model,
            k,
            lag,
        }
    }

    /// The time lag of the factor's value.
    pub fn lag(&self) -> f64 {
        self.lag
    }

    /// The wavenumber.
    pub fn wavenumber(&self) -> f64 {
        self.k
    }

    /// The motion model.
    pub fn model(&self) -> &'a MotionModel {
        self.model
    }

    /// The motion at `x`.
    #[inline]
    pub fn motion_at(&self, x: DVec3) -> Motion {
        *self.model.at(self.medium, x)
    }

    /// Starts a path at `x1`: resets `state`.
    #[inline]
    pub fn begin(&self, state: &mut MotionState, x1: DVec3) {
        let m = self.motion_at(x1);
        *state = MotionState {
            first: m,
            here: m,
            ..MotionState::default()
        };
    }

    /// The path has reached `v` (`v.index >= 2`): updates the sums of `state`.
    #[inline]
    pub fn advance(&self, state: &mut MotionState, v: &Vertex) {
        let here = self.motion_at(v.x);
        if v.index == 2 {
            state.w1 = v.w12;
        } else {
            // The vertex x_{b-1} is now interior: its transfer is w_in(x_b) - w_in(x_{b-1}).
            let q = crate::interior_transfer(state.w_in, v.w_in);
            state.y += state.here.diffusion * q.length_squared();
        }
        // The segment x_{b-1} -> x_b carries w . (U(x_{b-1}) - U(x_b)).
        state.q += v.w_in.dot(state.here.drift - here.drift);
        state.here = here;
        state.w_in = v.w_in;
    }
}

impl<M: Medium> PathFactor for MotionFactor<'_, M> {
    type State = MotionState;
    type Value = Complex64;

    fn start(&self, state: &mut MotionState, x1: DVec3, _ty: usize) -> Complex64 {
        self.begin(state, x1);
        Complex64::ONE
    }

    fn vertex(&self, state: &mut MotionState, v: &Vertex) -> Complex64 {
        self.advance(state, v);
        state.interior(self.k, self.lag)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{gamma, interior_transfer};
    use speckle_medium::{Aabb, Material, VoxelGrid};

    fn vertex(x: &[DVec3], w: &[DVec3], b: usize) -> Vertex {
        Vertex {
            index: b as u32,
            x1: x[0],
            w12: w[0],
            x: x[b - 1],
            w_in: w[b - 2],
            w_prev_out: w[b - 2],
            type1: 0,
            ty: 0,
            weight: 1.0,
            both_orders: 0.5,
            length: 0.0,
        }
    }

    /// Along a hand-made path through two materials, the interior factor is the product of
    /// the interior gammas of Eq. 14 (Brownian part) times the telescoped interior drift, at
    /// every lag (from the state, and as the path factor's value at its own lag), and the state
    /// holds the end-vertex data.
    #[test]
    fn interior_factor_is_the_product_of_interior_gammas() {
        let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 1.0, 1.0)).unwrap();
        let mats = vec![Material::single(1.0, 0.0), Material::single(1.0, 0.0)];
        let g = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
        let m0 = Motion::new(0.3, DVec3::new(0.2, 0.0, 0.1)).unwrap();
        let m1 = Motion::new(0.1, DVec3::new(-0.1, 0.3, 0.0)).unwrap();
        let model = MotionModel::per_material(vec![m0, m1]).unwrap();
        let k = 3.0;
        let lags = [0.0, 0.4, -0.7];
        let f = MotionFactor::new(&g, &model, k, 0.4);
        let x = [
            DVec3::new(0.2, 0.5, 0.5),
            DVec3::new(0.7, 0.3, 0.6),
            DVec3::new(1.4, 0.6, 0.2),
            DVec3::new(0.9, 0.2, 0.8),
            DVec3::new(1.8, 0.7, 0.4),
        ];
        let w: Vec<DVec3> = x.windows(2).map(|p| (p[1] - p[0]).normalize()).collect();
        let mut state = MotionState::default();
        assert_eq!(f.start(&mut state, x[0], 0), Complex64::ONE);
        for b in 2..=x.len() {
            let value = f.vertex(&mut state, &vertex(&x, &w, b));
            assert_eq!(state.w1, w[0]);
            assert_eq!(state.here, f.motion_at(x[b - 1]));
            assert_eq!(state.first, m0);
            assert_eq!(value, state.interior(k, 0.4));
            for &t in &lags {
                // Interior vertices x_2 .. x_{b-1} (indices 1..b-2): Brownian gammas.
                let mut want = Complex64::ONE;
                for m in 1..b - 1 {
                    let brownian = Motion::brownian(f.motion_at(x[m]).diffusion).unwrap();
                    want *= gamma(k, &brownian, interior_transfer(w[m - 1], w[m]), t);
                }
                // Drift: the sum over segments of w . (U_from - U_to).
                let q: f64 = (0..b - 1)
                    .map(|s| w[s].dot(f.motion_at(x[s]).drift - f.motion_at(x[s + 1]).drift))
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
        let uniform = MotionModel::uniform(Motion::new(0.0, DVec3::new(0.5, -0.2, 0.3)).unwrap());
        let f = MotionFactor::new(&g, &uniform, k, 0.4);
        f.start(&mut state, x[0], 0);
        for b in 2..=x.len() {
            assert_eq!(f.vertex(&mut state, &vertex(&x, &w, b)), Complex64::ONE);
        }
    }
}
