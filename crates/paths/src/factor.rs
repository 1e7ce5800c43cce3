//! Per-vertex path factors: a weight on every path contribution that may change at every vertex.
//!
//! The static estimators weight the contribution of vertex `x_b` by the constant
//! `sigma_s(x1) / (q_o(x1) p(w1))` ([`crate::Vertex::weight`]). Moving scatterers (Bar et al.
//! 2023, Eqs. 12-14, 26-30) multiply it by a product over the interior vertices `x_2 ..
//! x_{b-1}` of decorrelation factors `gamma(x_m, w_{m-1}, w_m)`, each known once the path has
//! left `x_m`; other uses are per-vertex filters or weights (a depth window, a material tag). A
//! [`PathFactor`] carries such a product along a path in its own state: [`PathFactor::start`]
//! at `x1`, then [`PathFactor::vertex`] at every `x_b`, which sees the vertex (position,
//! incoming direction, particle type) and can keep the previous vertex to form the factor of
//! `x_{b-1}` (whose outgoing direction is `x_b`'s incoming one).
//!
//! Its value is real ([`f64`]: the estimators keep the Hermitian accumulation `w a a^H`) or
//! complex (`Complex64`, a drift's Doppler phase: general accumulation `w a b^H`), see
//! [`FactorValue`]. [`NoFactor`] is the constant 1; the estimators without a factor are exactly
//! the estimators with it (bitwise: `x * 1.0 == x`).

use crate::Vertex;
use glam::DVec3;
use num_complex::Complex64;

/// A factor on every path contribution, updated at every vertex (see the module docs).
pub trait PathFactor: Sync {
    /// Per-path state (a running product, accumulated momentum transfer, the previous vertex);
    /// cloned to evaluate a branch off the path ([`crate::VertexSink::branch`]).
    type State: Default + Clone;
    /// The factor's value: [`f64`] or `Complex64`.
    type Value: FactorValue;
    /// Starts a path at `x1` (particle type `ty`): resets `state` and returns the factor of the
    /// single-scattering contribution of `x1`.
    fn start(&self, state: &mut Self::State, x1: DVec3, ty: usize) -> Self::Value;
    /// The path has reached `v` (`v.index >= 2`): updates `state` and returns the factor of the
    /// contribution of `v`.
    fn vertex(&self, state: &mut Self::State, v: &Vertex) -> Self::Value;
}

/// The value of a [`PathFactor`]: real (Hermitian accumulation) or complex (general).
pub trait FactorValue: Copy + Send + Sync {
    /// Whether every value is real, so contributions `w a a^H` stay Hermitian.
    const REAL: bool;
    /// The value as a real number (only called when [`FactorValue::REAL`]).
    fn real(self) -> f64;
    /// The value as a complex number.
    fn complex(self) -> Complex64;
}

impl FactorValue for f64 {
    const REAL: bool = true;
    #[inline]
    fn real(self) -> f64 {
        self
    }
    #[inline]
    fn complex(self) -> Complex64 {
        Complex64::new(self, 0.0)
    }
}

impl FactorValue for Complex64 {
    const REAL: bool = false;
    #[inline]
    fn real(self) -> f64 {
        self.re
    }
    #[inline]
    fn complex(self) -> Complex64 {
        self
    }
}

/// The constant factor 1 (the static estimators).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NoFactor;

impl PathFactor for NoFactor {
    type State = ();
    type Value = f64;
    #[inline]
    fn start(&self, _: &mut (), _: DVec3, _: usize) -> f64 {
        1.0
    }
    #[inline]
    fn vertex(&self, _: &mut (), _: &Vertex) -> f64 {
        1.0
    }
}
