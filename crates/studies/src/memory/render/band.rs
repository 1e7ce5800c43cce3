//! One wavelength's band (the Mie sphere and the slab's coefficients), the limits on a study's
//! density and Eq. 39 of diffusion theory.

use speckle_phase::{MieSphere, Phase};

/// Milne extrapolation length of isotropic scattering in transport mean free paths: diffusion
/// theory puts the absorbing boundaries `z_e = 0.7104 l*` outside each face (as in
/// tests/memory_effect.rs).
pub const MILNE_ZE: f64 = 0.7104;

/// Largest extinction optical depth rendered, a guard against a density in the wrong unit: the
/// cost per path grows with the optical depth, as its square for the paths that cross the slab.
pub const MAX_OPTICAL_DEPTH: f64 = 500.0;

/// Volume fraction above which a study is noted as dense.
pub const DENSE_VOLUME_FRACTION: f64 = 0.3;

/// Eq. 39: the diffusion-theory intensity correlation `x^2 / sinh^2 x`, `x = k theta L`.
pub fn eq39(x: f64) -> f64 {
    let x = x.abs();
    if x < 1e-4 {
        // x / sinh x = 1 - x^2 / 6 + ..., squared: 1 - x^2 / 3.
        1.0 - x * x / 3.0
    } else {
        // x / sinh x underflows to 0 (sinh overflows to inf) for x > 710: the right limit.
        (x / x.sinh()).powi(2)
    }
}

/// One wavelength: the sphere and the slab's coefficients.
#[derive(Debug, Clone)]
pub struct Band {
    /// Vacuum wavelength, micrometres.
    pub lambda: f64,
    /// The sphere at this wavelength.
    pub mie: MieSphere,
    /// Its tabulated amplitude function.
    pub phase: Phase,
    /// Nodes of the table.
    pub table_nodes: usize,
    /// Mean cosine of the table.
    pub table_mean_cosine: f64,
    /// Particles per cubic micrometre.
    pub density: f64,
    /// Scattering coefficient, per micrometre.
    pub sigma_s: f64,
    /// Absorption coefficient, per micrometre.
    pub sigma_a: f64,
}

impl Band {
    /// Extinction coefficient, per micrometre.
    pub fn sigma_t(&self) -> f64 {
        self.sigma_s + self.sigma_a
    }

    /// Transport mean free path `1 / (sigma_s (1 - g) + sigma_a)`.
    pub fn transport_mfp(&self) -> f64 {
        1.0 / (self.sigma_s * (1.0 - self.mie.asymmetry()) + self.sigma_a)
    }

    /// Host wavenumber `2 pi n_host / lambda`, per micrometre.
    pub fn k(&self) -> f64 {
        self.mie.wavenumber()
    }
}
