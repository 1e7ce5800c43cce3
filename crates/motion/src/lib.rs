//! Moving scatterers (Bar et al. 2023, "Monte Carlo spatio-temporal speckle", Eqs. 1-3, 13-14,
//! 35 and 41): how the scatterers of each material move, how that decorrelates the field of a
//! path, and the correlation functions an experiment measures.
//!
//! - [`Motion`]: Brownian diffusion `D` (length^2 per time unit) and a drift velocity `U`
//!   (length per time unit) of one material; a scatterer moves by
//!   `Delta_t = t U + w sqrt(2 D |t|)`, `w ~ N(0, I)` (Eq. 1) over a time `t`.
//! - [`MotionModel`]: the motion of every material of a medium (uniform, or one per material,
//!   by the index a medium gives each point: `speckle_medium::Medium::material`).
//! - [`gamma`]: the decorrelation factor of one vertex, Eq. 14,
//!   `gamma = exp(-k^2 D |t| |q|^2 + i k t q . U)`, with the momentum transfer `q` of the
//!   vertex: `w_out - w_in` inside a path ([`interior_transfer`]); at the first and last
//!   vertices, where the two copies of a path connect to different endpoints, the *averaged*
//!   endpoint directions (derived in the docs of [`gamma()`])
//!   ([`first_transfer`], [`last_transfer`], [`single_transfer`]).
//! - [`MotionState`]: the interior part of a path's decorrelation as two running sums (`Y^D` and
//!   `Q^U`) that any tracer keeps along its paths in plain data, so that
//!   every lag is evaluated from the same traced path (the project's tracer keeps it through
//!   `speckle_estimators::MotionFactor`).
//! - [`EndDisplacement`] and [`segment_phase`]: where the two copies of a path connect their
//!   end vertices at a lag (the exact drift of every endpoint, and the sampled Brownian
//!   displacements of endpoints with no single leg direction, focused Gaussian beams).
//! - [`correlation`]: `g1`, `g2 = 1 + beta |g1|^2` (Siegert) and the speckle contrast `K(T)`
//!   over an exposure `T`; [`diffusion`]: the correlation diffusion equation of Eq. 35.
//!
//! # Conventions (`docs/conventions.md`)
//!
//! The covariance at lag `t` is `C[j, k](t) = E[u_j(t1) conj(u_k(t1 + t))] - m_j conj(m_k)`: the
//! pair `j` is read at the earlier time when `t > 0`. By stationarity it is evaluated at
//! `(-t/2, t/2)` (Eq. 8): the first copy of a path at `o - Delta/2`, the second at
//! `o + Delta/2`. With fields `e^{+ikL}` this gives `gamma` of Eq. 14 with `+ i k t q . U`; a
//! single far-field scatterer drifting with `U` has `g1(t) = exp(i k t (v - i) . U)`.
//! `C[j, k](t) = conj(C[k, j](-t))` (Hermitian symmetry in time).
//!
//! # Which copy carries which endpoint direction
//!
//! A path's two copies share their interior vertices; at an end vertex each copy is connected
//! to its own endpoint. The *leg gradient* of a copy at an end vertex is the gradient of that
//! copy's endpoint leg length with respect to the vertex: for a source leg the propagation
//! direction into the vertex (`s = unit(x - i)`, or the plane wave's
//! direction), for a sensor leg minus the direction leaving the vertex (`-e`, `e = unit(v - x)`
//! or the far-field direction). A reversed path (coherent backscattering) connects its first
//! vertex to the sensor and its last to the source; its gradients follow the same rule.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

//!
//! # Dependencies
//!
//! Plain data only: [`glam`] vectors and [`num_complex`] numbers (both re-exported, so that an
//! embedder need not pin their versions) and `thiserror`; no other crate of the workspace.

pub mod correlation;
pub mod diffusion;
mod ends;
mod gamma;
mod state;

pub use ends::{EndDisplacement, segment_phase};
pub use gamma::{
    first_transfer, gamma, interior_transfer, last_transfer, sensor_gradient, single_transfer,
    source_gradient,
};
pub use glam;
pub use num_complex;
pub use state::MotionState;

use glam::DVec3;

/// Errors of motion models and correlation helpers; each names the offending field.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum MotionError {
    /// An input is invalid; `field` names it.
    #[error("{field}: {reason}")]
    InvalidInput {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
}

impl MotionError {
    /// The offending field and what is wrong with it (for callers that name fields their own
    /// way; the enum is `#[non_exhaustive]`).
    pub fn into_parts(self) -> (String, String) {
        match self {
            MotionError::InvalidInput { field, reason } => (field, reason),
        }
    }
}

pub(crate) fn invalid(field: impl Into<String>, reason: impl Into<String>) -> MotionError {
    MotionError::InvalidInput {
        field: field.into(),
        reason: reason.into(),
    }
}

/// The motion of the scatterers of one material: Brownian diffusion and a drift (Eq. 1),
/// `Delta_t = t U + w sqrt(2 D |t|)`, `w ~ N(0, I)`, so `E[Delta_t] = t U` and the variance per
/// axis is `2 D |t|`.
///
/// ```
/// use speckle_motion::Motion;
/// use speckle_motion::glam::DVec3;
/// let m = Motion::new(1e-6, DVec3::new(4.0, 0.0, 0.0)).unwrap();
/// assert!(m.is_moving() && m.has_drift());
/// assert!(Motion::new(-1.0, DVec3::ZERO).is_err());
/// assert!(!Motion::STATIC.is_moving());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// Diffusion coefficient `D >= 0` (length^2 per time unit).
    pub diffusion: f64,
    /// Drift velocity `U` (length per time unit).
    pub drift: DVec3,
}

impl Motion {
    /// Scatterers at rest.
    pub const STATIC: Self = Self {
        diffusion: 0.0,
        drift: DVec3::ZERO,
    };

    /// A motion; `diffusion` must be finite and `>= 0`, `drift` finite.
    pub fn new(diffusion: f64, drift: DVec3) -> Result<Self, MotionError> {
        Self { diffusion, drift }.validated("motion")
    }

    /// Pure Brownian motion of diffusion coefficient `diffusion`.
    pub fn brownian(diffusion: f64) -> Result<Self, MotionError> {
        Self::new(diffusion, DVec3::ZERO)
    }

    /// Checks the values, naming `field` (`field.diffusion`, `field.drift`).
    pub fn validated(self, field: &str) -> Result<Self, MotionError> {
        if !(self.diffusion.is_finite() && self.diffusion >= 0.0) {
            return Err(invalid(
                format!("{field}.diffusion"),
                format!("must be finite and >= 0 (got {})", self.diffusion),
            ));
        }
        if !self.drift.is_finite() {
            return Err(invalid(
                format!("{field}.drift"),
                format!("must be finite (got {})", self.drift),
            ));
        }
        Ok(self)
    }

    /// Whether the scatterers move at all.
    pub fn is_moving(&self) -> bool {
        self.diffusion > 0.0 || self.drift != DVec3::ZERO
    }

    /// Whether the drift is non-zero.
    pub fn has_drift(&self) -> bool {
        self.drift != DVec3::ZERO
    }
}

/// The motion of every material of a medium: one [`Motion`] for all, or one per material (by
/// the material index a medium gives each point), as the 2023 paper's heterogeneous scenes
/// (dynamic rods in a static cube, Fig. 5; static and dynamic layers, Fig. 10) need.
///
/// ```
/// use speckle_motion::{Motion, MotionModel};
/// // One material, three dimensions.
/// let m = MotionModel::uniform(Motion::brownian(0.1).unwrap()).validated(1, false).unwrap();
/// assert_eq!(m.of_material(0).diffusion, 0.1);
/// // A model of two materials does not fit a medium of one.
/// let two = MotionModel::per_material(vec![Motion::STATIC, Motion::brownian(1.0).unwrap()]).unwrap();
/// assert!(two.validated(1, false).is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MotionModel {
    materials: Vec<Motion>,
}

impl MotionModel {
    /// The same motion in every material.
    pub fn uniform(motion: Motion) -> Self {
        Self {
            materials: vec![motion],
        }
    }

    /// Scatterers at rest everywhere.
    pub fn at_rest() -> Self {
        Self::uniform(Motion::STATIC)
    }

    /// One motion per material, in the medium's material order; each is validated
    /// (`materials[i].diffusion`, `materials[i].drift`).
    pub fn per_material(materials: Vec<Motion>) -> Result<Self, MotionError> {
        if materials.is_empty() {
            return Err(invalid("materials", "needs at least one motion"));
        }
        let materials = materials
            .into_iter()
            .enumerate()
            .map(|(i, m)| m.validated(&format!("materials[{i}]")))
            .collect::<Result<_, _>>()?;
        Ok(Self { materials })
    }

    /// Checks the model against a medium of `n` materials (`flatland`: a 2D medium): a uniform
    /// model fits any medium, a per-material one needs one motion per material; drifts of a
    /// flatland medium lie in the plane `z = 0`.
    pub fn validated(self, n: usize, flatland: bool) -> Result<Self, MotionError> {
        if self.materials.len() != 1 && self.materials.len() != n {
            return Err(invalid(
                "materials",
                format!(
                    "the medium has {n} materials but {} motions were given (give one for all, or \
                     one per material)",
                    self.materials.len()
                ),
            ));
        }
        for (i, m) in self.materials.iter().enumerate() {
            m.validated(&format!("materials[{i}]"))?;
            if flatland && m.drift.z != 0.0 {
                return Err(invalid(
                    format!("materials[{i}].drift"),
                    format!("must have z = 0 in a flatland medium (got {})", m.drift),
                ));
            }
        }
        Ok(self)
    }

    /// The motions, one per material (one for all when uniform).
    pub fn motions(&self) -> &[Motion] {
        &self.materials
    }

    /// The motion of the material with index `material`.
    #[inline]
    pub fn of_material(&self, material: usize) -> &Motion {
        if self.materials.len() == 1 {
            &self.materials[0]
        } else {
            &self.materials[material]
        }
    }

    /// Whether any material drifts.
    pub fn has_drift(&self) -> bool {
        self.materials.iter().any(Motion::has_drift)
    }

    /// Whether any material moves.
    pub fn is_moving(&self) -> bool {
        self.materials.iter().any(Motion::is_moving)
    }

    /// The largest drift speed `|U|` over materials.
    pub fn max_speed(&self) -> f64 {
        self.materials
            .iter()
            .map(|m| m.drift.length())
            .fold(0.0, f64::max)
    }

    /// The largest diffusion coefficient over materials.
    pub fn max_diffusion(&self) -> f64 {
        self.materials
            .iter()
            .map(|m| m.diffusion)
            .fold(0.0, f64::max)
    }
}

/// Checks a list of time lags: non-empty, finite (`field[i]` names a bad one).
pub fn check_lags(field: &str, lags: &[f64]) -> Result<(), MotionError> {
    if lags.is_empty() {
        return Err(invalid(field, "needs at least one time lag"));
    }
    if let Some((i, t)) = lags.iter().enumerate().find(|(_, t)| !t.is_finite()) {
        return Err(invalid(
            format!("{field}[{i}]"),
            format!("must be finite (got {t})"),
        ));
    }
    Ok(())
}

/// The examples of the crate's README.md, compiled and run as doctests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn models_give_each_material_its_motion() {
        let fast = Motion::new(2.0, DVec3::X).unwrap();
        let m = MotionModel::per_material(vec![Motion::STATIC, fast])
            .unwrap()
            .validated(2, false)
            .unwrap();
        assert_eq!(*m.of_material(0), Motion::STATIC);
        assert_eq!(*m.of_material(1), fast);
        assert!(m.has_drift() && m.is_moving());
        assert_eq!(m.max_speed(), 1.0);
        // A uniform model serves every material.
        let u = MotionModel::uniform(fast).validated(5, false).unwrap();
        assert_eq!(*u.of_material(3), fast);
        // Three motions for two materials are refused, naming the field.
        let e = MotionModel::per_material(vec![Motion::STATIC; 3])
            .unwrap()
            .validated(2, false)
            .unwrap_err();
        assert!(e.to_string().starts_with("materials:"), "{e}");
    }

    #[test]
    fn bad_values_are_refused_with_their_field() {
        let e = Motion::new(f64::NAN, DVec3::ZERO).unwrap_err();
        assert!(e.to_string().starts_with("motion.diffusion"), "{e}");
        let e = Motion::new(0.0, DVec3::new(f64::INFINITY, 0.0, 0.0)).unwrap_err();
        assert!(e.to_string().starts_with("motion.drift"), "{e}");
        let e = MotionModel::per_material(vec![
            Motion::STATIC,
            Motion {
                diffusion: -1.0,
                drift: DVec3::ZERO,
            },
        ])
        .unwrap_err();
        assert!(e.to_string().starts_with("materials[1].diffusion"), "{e}");
        assert!(MotionModel::per_material(vec![]).is_err());
        // A flatland drift must lie in the plane.
        let e = MotionModel::uniform(Motion::new(0.0, DVec3::Z).unwrap())
            .validated(1, true)
            .unwrap_err();
        assert!(e.to_string().starts_with("materials[0].drift"), "{e}");
        assert!(check_lags("lags", &[]).is_err());
        let e = check_lags("lags", &[0.0, f64::NAN]).unwrap_err();
        assert!(e.to_string().starts_with("lags[1]"), "{e}");
    }
}
