//! The rendered refocused fields of Fig. 13 top (Bar et al. 2020, Sec. 9.1): the `[images]`
//! section of a refocusing study (`speckle refocus`).
//!
//! Where [`super::RefocusStudy`] sums covariances into the mean focus amplitude `E A`, this
//! samples transmission matrices with the near-field field sampler (Sec. 7,
//! [`speckle_estimators::render_fields`]: every field of a realization from the same sub-paths,
//! so the memory-effect correlations are present) and forms the focus of every realization.
//!
//! Geometry of a case `(Delta, theta, Delta_b)` (the scene of [`super::TiltShiftStudy::scene`]
//! at `Delta_a = Delta_b - L theta = Delta`): the guide star `g`, a Gaussian beam focused at
//! `(-Delta/2, 0, -L/2)` tilted by `-theta/2`; its field `u_g(r_m)` on the camera line `r_m =
//! tau_m - Delta_b/2` on face `b`; an image of `n_pixels` (along x) by `n_rows` (along y)
//! focal points `x = (Delta/2 + o_x, o_y, -L/2)` on face `a` (Gaussian beams tilted by
//! `+theta/2`, the target mode of the study at the centre `o = 0`), and the camera line `s_m =
//! tau_m + Delta_b/2` where the conjugate pattern is displayed. By reciprocity the field the pattern `P(s_m) =
//! conj(u_g(r_m)) exp(-i q tau_m)`, `q = 2 k sin(theta/2)`, makes in the mode of `x` is
//!
//! ```text
//! A(x) = sum_m u_x(s_m) conj(u_g(r_m)) exp(-i q tau_m).
//! ```
//!
//! The ramp removes the tilt between the two beams' fields on face `b` (`u_x ~ exp(i k
//! sin(theta/2) x)`, `u_g ~ exp(-i k sin(theta/2) x)` for plane waves `exp(i k d.x)`,
//! `docs/conventions.md`), so `E A(target) = sum_m C[(t, s_m), (g, r_m)] exp(-i q tau_m)` is the
//! complex conjugate of the study's Eq. 49 sum: the same power. The cases: `Delta = 0` once, then
//! for every imaged `Delta` shift only (`theta = 0`, `Delta_b = Delta`) and shift and tilt (the
//! tilt of [`super::optimal_tilt`], `Delta_b = Delta + L theta`). One scene holds every case, so
//! a realization is one medium seen by every refocusing attempt.
//!
//! The fields are the scattered fields (no speckle mean added), as the covariances of the study:
//! the ballistic part of the guide star's field is not conjugated.
//!
//! The check (an independent estimator, the covariance render, on the same geometry): for the
//! target and the pixels away from it at the middles of the image's edges, `render.groups`
//! covariance renders of `render.paths` paths give `E A` and, for circular complex Gaussian
//! fields (Isserlis), the background
//!
//! ```text
//! Var A(x) = sum_{m, m'} a_m conj(a_m') C[(x, s_m), (x, s_m')] C[(g, r_m'), (g, r_m)],  a_m = exp(-i q tau_m),
//! ```
//!
//! a sum of products of second moments; `E|A|^2 = |E A|^2 + Var A`. The sampler's fields are
//! circular (a uniform phase per sub-path) and Gaussian as the number of sub-paths per
//! realization grows (their fourth moments differ from Isserlis' by `O(1 / images.paths)`).
//! Standard errors: over the realizations for the images (independent), jackknife over the
//! groups for the covariances.
//!
//! The module's parts: the `[images]` section, its limits and its validated plan
//! (`plan.rs`); the image scenes and the field and check renders (`fields.rs`); the measured
//! and predicted statistics and the outputs (`results.rs`).

mod fields;
mod plan;
mod results;

pub(super) use plan::validate;
pub use plan::{
    ImageCase, ImagePlan, MAX_IMAGE_DISPLACEMENTS, MAX_IMAGE_FIELDS, MAX_IMAGE_PAIRS,
    MAX_IMAGE_PIXELS, MAX_IMAGE_REALIZATIONS, RefocusImagesFile,
};
pub use results::{CHECK_PIXEL_NAMES, PixelPrediction, PixelStats, RefocusImages};
