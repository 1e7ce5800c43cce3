//! Studies built on the renderers: a study reads a file of its own, derives one scene per point
//! of a sweep, renders them with the estimators and reduces the results to curves with error
//! bars and their theory, as plain data that a caller writes or plots.
//!
//! - [`memory`]: the memory effect versus wavelength for Mie spheres in a slab (Bar et al. 2019,
//!   Fig. 11), against diffusion theory (Eq. 39), and against the tilt for a sweep of `g` (Bar
//!   et al. 2023, Fig. 6, `memory::TiltStudy`), against the C1 term, and the tilt-shift memory
//!   effect of Gaussian beams (Bar et al. 2020, Fig. 12, `memory::TiltShiftStudy`), against
//!   Eq. 50 (Osnabrugge et al. 2017), and the power of a phase-conjugate focus through the slab
//!   against its displacement, shifted or shifted and tilted (Fig. 13, `memory::RefocusStudy`);
//! - [`nearfield`]: the near-field closed forms against the brute-force aperture integral of
//!   far-field paths (Bar et al. 2020, Fig. 7, Tables 1-2, `nearfield::BruteForceStudy`) and the
//!   gains of importance sampling around Gaussian beams (Figs. 9-10,
//!   `nearfield::SamplingStudy`);
//! - [`plot`]: its figure, an SVG drawn with `plotters`;
//! - [`curves`]: a generic figure of curves with error bars (the `speckle g1` plot);
//! - [`shaping`]: dynamic wavefront shaping on sampled transmission-matrix sequences (Bar et
//!   al. 2023, Fig. 10);
//! - [`seeing`]: seeing through scattering (Katz et al. 2014; Bar et al. 2019, Fig. 13):
//!   sampled speckle images of a hidden object, their autocorrelation and phase retrieval;
//! - [`permutations`]: the phase of path permutations and their integrals (Bar et al. 2019,
//!   Appendix A.3, Figs. 15-16): flatland throughputs of three-vertex paths, integrated by
//!   Monte Carlo;
//! - [`examples`]: the embedded study files of both panels of Fig. 11.
//!
//! Design decision: a study is a library, not a command: its schema, validation, band
//! preparation, render, statistics and figure live here, so that a binding reaches all of it;
//! the `speckle` binary only parses arguments, shows progress and writes files. Randomness comes
//! from the estimators' counter-based streams with seeds derived per sub-render
//! ([`speckle_stats::rng::derive_seed`]), so a study is bitwise reproducible for any thread
//! count; standard errors are jackknife estimates ([`speckle_stats::jackknife`]).

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod curves;
pub mod examples;
pub mod memory;
pub mod nearfield;
pub mod permutations;
pub mod plot;
pub mod seeing;
pub mod shaping;

/// Errors of a study.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StudyError {
    /// The study file, or a value derived from it, is invalid (the error names the field).
    #[error(transparent)]
    Input(#[from] speckle_scene::LoadError),
    /// A render failed or was cancelled.
    #[error(transparent)]
    Render(#[from] speckle_estimators::EstimatorError),
}
