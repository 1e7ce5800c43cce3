//! Importance sampling around focused Gaussian beams (Bar et al. 2020, Sec. 6, Figs. 9-10): the
//! study of `speckle sampling-gain` and of `tests/nearfield_sampling.rs`.
//!
//! A case is a box of one homogeneous medium with two sources focused on its entry face, two
//! sensors focused on its exit face (transmission) and optionally one on the entry face looking
//! back (reflection), all Gaussian beams of one concentration ([`SamplingCase::scene`]). Each is
//! rendered (covariance of all pairs, forward and reversed paths) with each strategy of
//! `render.beams`: `off` (uniform first vertices and directions, the estimator of Bar et al.
//! 2019), `position` (first vertices from the beams' Gaussian structure, Eqs. 33-36) and
//! `position_and_direction` (also first directions from the vMF pair mixture of `|Upsilon|^2`,
//! Eq. 41; 3D only), at a sweep of path counts.
//!
//! The error of a render (Fig. 10's `log RMSE`): against a reference render of the case (the
//! default strategy at `render.reference_paths`, its own seed), over the upper triangle of the
//! covariance, `sqrt(mean |C_ab - R_ab|^2) / mean_a R_aa`, the root-mean-square error relative to
//! the mean intensity; beside it the render's own standard error on the same scale
//! (`sqrt(mean(se_re^2 + se_im^2)) / mean_a R_aa`). Where a strategy is unbiased the two agree
//! until the RMSE reaches the reference's own standard error (printed); a uniform render of a
//! wide slab shows an RMSE well above its standard error (its rare large contributions are
//! missing from both its mean and its error).
//!
//! The gain of a strategy over the first listed (`off` by default), at the largest path count:
//! `(se_first^2 t_first) / (se^2 t)` per diagonal entry, the smallest and the median ([`gain`],
//! as `tests/nearfield_sampling.rs` prints it): how many times less time the strategy needs for
//! the same standard error.
//!
//! The module's parts: a case's box and beams (`case.rs`); the study file, its loading and
//! validation (`study.rs`); the renders, their errors and gains (`render.rs`); the output
//! arrays, figure, report and sidecar (`report.rs`).

mod case;
mod render;
mod report;
mod study;
#[cfg(test)]
mod tests;

pub use case::SamplingCase;
pub use render::{
    CaseResult, SamplingGain, StrategyRender, gain, max_z, relative_ses, render_strategy,
};
pub use study::{
    CaseFile, MAX_CASES, MAX_STEPS, SamplingFile, SamplingRender, SamplingStudy,
    load_sampling_file, load_sampling_str, strategy_name,
};
