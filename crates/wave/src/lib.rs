//! Exact multiple-scattering reference solver: Foldy-Lax equations for point scatterers
//! (coupled dipoles), averaged over random configurations.
//!
//! The Monte Carlo estimators of `speckle-estimators` predict speckle means and covariances
//! from bulk parameters alone. This crate computes the same quantities the slow, exact way:
//! it draws explicit scatterer positions, solves the wave equation for each configuration with
//! all orders of scattering (and all dependent-scattering effects), and averages. It is the
//! reference the Monte Carlo is checked against, in the absolute units of
//! `docs/conventions.md`.
//!
//! # Physics
//!
//! Scalar monochromatic waves (time dependence `e^{-i omega t}`), wavenumber `k = 2 pi /
//! lambda`, in 3D or in flatland (the plane `z = 0`).
//!
//! **Green's function** of `(nabla^2 + k^2) G = -delta`, outgoing ([`Kernel::green`]):
//! `G(r) = e^{ikr} / (4 pi r)` in 3D, `G(r) = (i/4) H0^(1)(kr)` in flatland, with
//! `H0^(1) = J0 + i Y0` computed by [`bessel`]. `Im G` is finite at the origin:
//! `Im G(0) = k / (4 pi)` in 3D (`sin(kr) / (4 pi r)`), `1/4` in flatland (`J0(0) / 4`).
//!
//! **Point scatterer.** A scatterer at `o` excited by the field `psi(o)` radiates
//! `tau G(x - o) psi(o)`, `tau` its t-matrix. Far away, `G(R v - o) ~ g e^{-ik v.o} e^{ikR} /
//! R^{(d-1)/2}` with `g = 1/(4 pi)` in 3D and, from `H0^(1)(x) ~ sqrt(2/(pi x)) e^{i(x - pi/4)}`,
//! `g = e^{i pi/4} / sqrt(8 pi k)` in flatland; the scattering amplitude is `f = tau g`. Energy
//! conservation (the optical theorem, extinction = scattering) holds exactly when
//! `Im(1/tau) = -Im G(0)`. We take the *resonant* lossless scatterer, `Re(1/tau) = 0`:
//!
//! - 3D: `tau = i / Im G(0) = 4 pi i / k`, `f = i / k`, cross-section
//!   `c_s = 4 pi |f|^2 = 4 pi / k^2 = (4 pi / k) Im f`;
//! - flatland: `tau = 4 i`, `f = 4 i e^{i pi/4} / sqrt(8 pi k)`, cross-width
//!   `c_s = 2 pi |f|^2 = 4 / k = sqrt(8 pi / k) Im(f e^{-i pi/4})`.
//!
//! In both, `tau = i k c_s`. The forward amplitude is purely imaginary, so the scatterers
//! change no refractive index: in Foldy's effective medium (`<psi> ~ <u>`, number density `n`)
//! the mean field obeys `(nabla^2 + k^2 + n tau) <u> = 0`, so
//! `k_eff = sqrt(k^2 + n tau) ~ k + n tau / (2k) = k + i n c_s / 2 = k + i sigma_s / 2`:
//! the mean field decays exactly as the Monte Carlo's `e^{-sigma_t d / 2}` (`sigma_a = 0`),
//! up to dependent-scattering corrections of relative order `1 / (k l)`, `l` the mean free
//! path (recurrent scattering; Poisson positions have no pair correlations).
//!
//! **Foldy-Lax equations.** For scatterers `o_1..o_N`, the exciting fields satisfy
//! `psi_n = u_inc(o_n) + sum_{m != n} tau G(o_n - o_m) psi_m`, i.e.
//! `(I - tau G_offdiag) psi = u_inc`: one dense complex LU per configuration ([`lu`]: blocked,
//! cancellable, on faer's kernels; partial
//! pivoting, sequential), reused for every source as a right-hand side. The total field is
//! `u(x) = u_inc(x) + sum_n tau G(x - o_n) psi_n`. `G_offdiag` is symmetric, which makes the
//! solution reciprocal.
//!
//! **Bulk parameters.** From the scene's medium (a [`speckle_medium::HomogeneousBox`] with
//! `sigma_a = 0`) and its isotropic phase function: `n = sigma_s / c_s`; the number of
//! scatterers is Poisson with mean `n |V|` (volume in 3D, area in flatland), positions uniform
//! in the box ([`sample_scatterers`]).
//!
//! **Sources** (`speckle_endpoints::Source`): a plane wave `e^{ik d.x}`; a point source
//! `e^{ikr} / r` in 3D and `sqrt(pi k / 2) e^{i pi/4} H0^(1)(kr)` in flatland, which tends to
//! `e^{ikr} / sqrt(r)` (the Monte Carlo's flatland point source).
//!
//! **Sensors** (`speckle_endpoints::Sensor`):
//! - far field `v`: the amplitude `A(v)` of `u(R v) = A e^{ikR} / R` (3D) or
//!   `A e^{ikR} / sqrt(R)` (flatland): `A = sum_n f e^{-ik v.o_n} psi_n`, plus `e^{-ik v.p}`
//!   for a point source at `p` (its own far field; a plane wave has none in a direction `v`);
//! - point `q`: the total field `u_inc(q) + sum_n tau G(q - o_n) psi_n`.
//!
//! These are what the Monte Carlo mean and covariance estimate (the mean of
//! `speckle_scene::Scene::mean` includes the attenuated incident field).
//!
//! **Multi-slice beam propagation** ([`render_multislice`], [`multislice`]): a second,
//! approximate reference through the same configurations: the plane wave carried slice by
//! slice with the exact angular-spectrum propagator, each slice's scatterers a thin screen,
//! forward scattering only (Bar et al. 2020, Fig. 11 right); no dense matrix, so it runs on slabs
//! far beyond the Foldy-Lax limit, and its departures from the exact solution (no backward
//! light, so less transmitted power) are measured in `tests/multislice.rs`.
//!
//! **Moving scatterers** ([`render_wave_motion`]): each configuration is moved along sampled
//! trajectories (Brownian diffusion and drift, Bar et al. 2023, Eq. 1) and solved at every
//! requested time, for the spatio-temporal covariance of the 2023 paper.
//!
//! # Cost
//! Assembly `O(N^2)` Green's functions, LU `(8/3) N^3` real flops, solves `O(N^2 S)` for `S`
//! sources, sensors `O(N (sensors + pairs))`; memory `16 N^2` bytes. The expected `N` is
//! limited to [`MAX_EXPECTED_SCATTERERS`].
//!
//! ```
//! use speckle_endpoints::{Pair, Sensor, Source};
//! use speckle_scene::Scene;
//! use speckle_stats::NoProgress;
//! use speckle_medium::{Aabb, DVec3, HomogeneousBox};
//! use speckle_phase::Phase;
//! use speckle_wave::{WaveOptions, render_wave};
//! // 4 x 4 x 2 wavelengths, mean free path 4: about 40 scatterers per configuration.
//! let b = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
//! let m = HomogeneousBox::from_mean_free_path(b, 4.0, 1.0).unwrap();
//! let sensors = vec![Sensor::far_field(DVec3::new(0.3, 0.0, 1.0)).unwrap()];
//! let scene = Scene::new(m, Phase::Isotropic, 1.0, vec![Source::plane_wave(DVec3::Z).unwrap()],
//!     sensors, Pair::all(1, 1)).unwrap();
//! let w = render_wave(&scene, &WaveOptions { configurations: 20, seed: 7 }, &NoProgress).unwrap();
//! assert!((w.mean_scatterers - w.expected_scatterers).abs() < 0.5 * w.expected_scatterers);
//! let (c, se) = w.covariance.get(0, 0);
//! assert!(c.re > 0.0 && se.re > 0.0);
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod bessel;
mod cost;
mod kernel;
pub mod lu;
mod motion;
pub mod multislice;
mod render;
mod solve;

pub use cost::{WaveCost, estimate_cost};
pub use kernel::Kernel;
pub use motion::{MAX_FIELD_ENTRIES, WaveMotionEstimate, render_wave_motion};
pub use multislice::{
    APERTURE_ROLLOFF, EMISSION_DEPTH, ExitField, GridInfo, MAX_GRID_POINTS,
    MAX_MULTISLICE_SCATTERERS, MAX_MULTISLICE_WORK, MultisliceOptions, Propagation, WINDOW_ROLLOFF,
    estimate_multislice_cost, multislice_grids, multislice_propagate, multislice_solve,
    render_multislice,
};
pub use render::{WaveEstimate, WaveOptions, WaveShard, render_wave, render_wave_shard};
pub use solve::{
    MAX_EXPECTED_SCATTERERS, MAX_SCATTERERS, WaveScene, check_scene, expected_scatterers,
    number_density, sample_scatterers, solve,
};

/// Errors of the wave solver.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WaveError {
    /// An input is invalid; `field` names it.
    #[error("{field}: {reason}")]
    InvalidInput {
        /// The offending field.
        field: String,
        /// What is wrong with it.
        reason: String,
    },

    /// The render was cancelled through `Progress::cancelled`.
    #[error("the wave render was cancelled")]
    Cancelled,

    /// Shards cannot be merged: missing, overlapping, or of different renders.
    #[error(transparent)]
    Shard(#[from] speckle_stats::ShardError),
}

impl WaveError {
    /// The name of the offending input, if the error is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::InvalidInput { field, .. } => Some(field),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests;

impl From<speckle_stats::StatsError> for WaveError {
    fn from(e: speckle_stats::StatsError) -> Self {
        let speckle_stats::StatsError::InvalidInput { field, reason } = e;
        Self::InvalidInput { field, reason }
    }
}
