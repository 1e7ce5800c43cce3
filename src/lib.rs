//! # speckle
//!
//! Monte Carlo rendering of the statistics of coherent light in scattering media, after Bar,
//! Alterman, Gkioulekas and Levin, *A Monte Carlo framework for rendering speckle statistics in
//! scattering media*, ACM TOG 38(4), 2019.
//!
//! This facade only re-exports the workspace crates, one concept each:
//!
//! - [`medium`]: bulk media and their geometry;
//! - [`phase`]: phase and scattering-amplitude functions;
//! - [`vmf`]: complex von Mises-Fisher algebra and vMF-mixture fits of amplitudes (below
//!   [`phase`], which renders a mixture as `Phase::Vmf` and fits any phase function with
//!   `phase::fit_vmf`);
//! - [`paths`]: counter-based random streams and volumetric sub-path sampling;
//! - [`estimators`]: speckle mean, covariance and field estimators;
//! - [`wave`]: the exact multiple-scattering reference solver (Foldy-Lax equations for point
//!   scatterers, averaged over random configurations).

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub use speckle_estimators as estimators;
pub use speckle_medium as medium;
pub use speckle_paths as paths;
pub use speckle_phase as phase;
pub use speckle_vmf as vmf;
pub use speckle_wave as wave;
