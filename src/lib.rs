//! # speckle
//!
//! Monte Carlo rendering of the statistics of coherent light in scattering media, after Bar,
//! Alterman, Gkioulekas and Levin, *A Monte Carlo framework for rendering speckle statistics in
//! scattering media*, ACM TOG 38(4), 2019.
//!
//! This facade only re-exports the workspace crates, one concept each (see `ARCHITECTURE.md`):
//!
//! - [`vmf`]: complex von Mises-Fisher algebra and vMF-mixture amplitudes;
//! - [`phase`]: phase and scattering-amplitude functions;
//! - [`medium`]: bulk media and their geometry;
//! - [`stats`]: random streams, batch-means accumulation and the deterministic batch driver;
//! - [`endpoints`]: sources and sensors, their connections to the medium and mean fields;
//! - [`paths`]: volumetric sub-path sampling;
//! - [`motion`]: moving scatterers: motion models, decorrelation factors, `g1`, `g2`, `K(T)`
//!   (Bar et al. 2023);
//! - [`scene`]: the problem description: the scene file format, its validation and builders,
//!   a validated scene;
//! - [`estimators`]: speckle mean, covariance and field estimators;
//! - [`frequency`]: frequency analysis of light transport (Belcour et al. 2014): spectral
//!   covariances along paths;
//! - [`wave`]: the exact multiple-scattering reference solver (Foldy-Lax equations for point
//!   scatterers, averaged over random configurations);
//! - [`runs`]: renders of a loaded problem, whole or as shards, shard files and their exact
//!   merge;
//! - [`studies`]: studies built on the renderers (the memory effect versus wavelength of
//!   Fig. 11), with their figures.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub use speckle_endpoints as endpoints;
pub use speckle_estimators as estimators;
pub use speckle_frequency as frequency;
pub use speckle_inverse as inverse;
pub use speckle_medium as medium;
pub use speckle_motion as motion;
pub use speckle_paths as paths;
pub use speckle_phase as phase;
pub use speckle_runs as runs;
pub use speckle_scene as scene;
pub use speckle_stats as stats;
pub use speckle_studies as studies;
pub use speckle_vmf as vmf;
pub use speckle_wave as wave;
