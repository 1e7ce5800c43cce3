//! The near-field estimator against its alternatives (Bar et al. 2020, Sec. 8): the studies of
//! `speckle bruteforce` and `speckle sampling-gain`, shared with `tests/nearfield_bruteforce.rs`
//! and `tests/nearfield_sampling.rs` (the tests call these functions and keep the assertions).
//!
//! - [`bruteforce`]: the closed-form aperture connections (Eqs. 13-18) against the brute-force
//!   aperture integral of far-field per-path fields (Eqs. 9-11) in flatland, entry by entry, and
//!   the runtime table for the same standard error (Fig. 7, Tables 1-2);
//! - [`sampling`]: importance sampling around focused Gaussian beams (Sec. 6, `render.beams`
//!   `off`, `position`, `position_and_direction`): the error against path count and time per
//!   strategy, and the variance x time gains (Figs. 9-10).
//!
//! Design decision: each study has a small TOML file of its own (loaded and validated here,
//! errors naming the field, `[render]` seeds and paths replaced by the command line through
//! [`crate::memory::StudyOverrides::apply_to`]); its result is plain data with `arrays`,
//! `figure`, `text` and `describe` for the caller to write.

pub mod bruteforce;
pub mod sampling;

pub use bruteforce::{
    BruteForce, BruteForceFile, BruteForceRender, BruteForceStudy, MAX_CHUNK_BYTES, MAX_NODES,
    load_bruteforce_file, load_bruteforce_str,
};
pub use sampling::{
    CaseFile, MAX_CASES, MAX_STEPS, SamplingCase, SamplingFile, SamplingGain, SamplingRender,
    SamplingStudy, StrategyRender, gain, load_sampling_file, load_sampling_str, max_z,
    relative_ses, render_strategy, strategy_name,
};

/// Most paths of one render of these studies (so that their sums cannot overflow; the cost
/// guard refuses far fewer on any machine).
pub const MAX_PATHS: u64 = 1_000_000_000_000;

/// Checks a path count: at least 8, at most [`MAX_PATHS`].
pub(crate) fn check_paths(field: &str, v: u64) -> Result<(), speckle_scene::SceneError> {
    if !(8..=MAX_PATHS).contains(&v) {
        return Err(speckle_scene::validate::invalid(
            field,
            format!("must be in 8..={MAX_PATHS} (got {v})"),
        ));
    }
    Ok(())
}

/// Gauss-Legendre nodes and weights on [-1, 1] (Newton on the three-term recurrence).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut t = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 1.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, t);
                for k in 2..=n {
                    let k = k as f64;
                    (p0, p1) = (p1, ((2.0 * k - 1.0) * t * p1 - (k - 1.0) * p0) / k);
                }
                dp = n as f64 * (t * p1 - p0) / (t * t - 1.0);
                let step = p1 / dp;
                t -= step;
                if step.abs() < 1e-15 {
                    break;
                }
            }
            (t, 2.0 / ((1.0 - t * t) * dp * dp))
        })
        .collect()
}
