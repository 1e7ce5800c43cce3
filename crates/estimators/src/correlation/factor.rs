//! The interior decorrelation of moving scatterers as a [`PathFactor`] of the path tracer:
//! [`speckle_motion::MotionState`] kept along each traced path, with the motion at each vertex
//! looked up in the medium's materials.

use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_motion::{Motion, MotionModel, MotionState};
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

impl<'a, M: Medium> MotionFactor<'a, M> {
    /// The factor at the time lag `lag` (the caller validates the model against the medium and
    /// the lag, [`MotionModel::validated`], [`speckle_motion::check_lags`]).
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
        *self.model.of_material(self.medium.material(x))
    }

    /// Starts a path at `x1`: resets `state`.
    #[inline]
    pub fn begin(&self, state: &mut MotionState, x1: DVec3) {
        *state = MotionState::start(self.motion_at(x1));
    }

    /// The path has reached `v` (`v.index >= 2`): updates the sums of `state` (the direction
    /// of arrival at `x2` is the first direction `w12`).
    #[inline]
    pub fn advance(&self, state: &mut MotionState, v: &Vertex) {
        state.advance(v.index, self.motion_at(v.x), v.w_in);
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
