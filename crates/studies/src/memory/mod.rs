//! The memory effect of a slab of Mie spheres versus wavelength (Bar et al. 2019, Sec. 6.2,
//! Fig. 11; diffusion theory, Eq. 39), the study of `speckle memory-spectrum`.
//!
//! For every vacuum wavelength `lambda` of a study, Lorenz-Mie theory
//! (`speckle_phase::MieSphere`) gives one sphere's cross sections `c_sca`, `c_abs`, its asymmetry
//! `g` and its tabulated scalar amplitude function; with the number density `N` the slab has
//! `sigma_s = N c_sca` and `sigma_a = N c_abs` (`docs/conventions.md`). The slab, `L` thick
//! along z and `lateral_factor L` wide in x and y, is lit by plane waves `i_n` tilted by
//! `theta_n` from +z about +y and seen in transmission by far-field sensors `v_n = i_n`; the
//! covariance of the pairs `(i_n, v_n)` (Alg. 1) gives the normalised intensity correlation
//! (Siegert) `C(theta_n) = |C_0n|^2 / (C_00 C_nn)`, which diffusion theory predicts to be
//! `(k theta L)^2 / sinh^2(k theta L)` with `k = 2 pi n_host / lambda` (Eq. 39).
//!
//! Design decisions:
//! - A study has a small file format of its own, not a scene: its medium coefficients and phase
//!   function are derived per wavelength, and its sources, sensors and pairs follow from the
//!   list of angles. The format is documented on [`StudyFile`].
//! - Estimator (`render.coherence = "forward_only"`, the default): forward paths only, the first
//!   vertex exponential in depth from the lit face (at the extinction rate) and the first
//!   direction drawn from the phase function around +z. In transmission the reversed paths have
//!   the expectation of the forward ones (reciprocity) plus cross terms that oscillate as
//!   `exp(2 i k (z_1 - z_B))` and average out over a slab many wavelengths thick; forward-only
//!   with an exponential first vertex has a far smaller variance (tests/memory_effect.rs
//!   checks the agreement of the two at optical depth 10). The phase-sampled first direction
//!   keeps the forward diffraction peak of a large sphere (`rho(1)` up to `~x^2` times the
//!   isotropic value) out of the weights: on the study of Fig. 11b (48 k paths) it gave 2 to 5
//!   times smaller standard errors than a uniform first direction, for 1.7 times the time per
//!   path. `"forward_and_reversed"` renders the library's default estimator instead (uniform
//!   first vertex and direction), as a check; it is far noisier for large spheres.
//! - Standard errors are jackknife estimates over `render.groups` independent renders of each
//!   wavelength (delete one group, `speckle_stats::jackknife`; group `g` of wavelength `w` is
//!   seeded with `speckle_stats::rng::derive_seed(seed, w groups + g)`), so they include the
//!   correlation between the numerator and the denominator of `C` (both fluctuate with the same
//!   rare long paths), which propagating the library's per-entry standard errors would ignore.
//! - The slab is finite: a tilted plane wave also enters through the side faces, into a strip of
//!   relative width `theta L / W = k theta L / (k W)` where deep first vertices carry weights up
//!   to `e^OD`. With `lateral_factor = 100` and `k L >= 10^4` (a slab of a millimetre in the
//!   visible) neither it nor the leakage through the side faces (which biases `C` upwards by
//!   `O(L / W)`, tests/memory_effect.rs) is visible; at `k L = 420` it raised the standard
//!   errors six-fold. The cost of a study does not depend on `k L`, only on the optical depths.
//! - The result is plain data ([`MemorySpectrum`]); [`crate::plot`] draws it. Writing files is
//!   the caller's business.

mod images;
mod refocus;
mod refocus_images;
mod render;
pub(crate) mod study;
mod tilt;
mod tilt_fit;
mod tilt_material;
mod tilt_shift;

pub use images::{
    MAX_IMAGE_TILTS, MemoryImages, MemoryImagesFile, MemoryImagesRow, MemoryImagesStudy,
    load_memory_images_file, load_memory_images_str,
};
pub use refocus::{
    MAX_REFOCUS_POINTS, Refocus, RefocusFile, RefocusStudy, load_refocus_file, load_refocus_str,
    optimal_tilt,
};
pub use refocus_images::{
    CHECK_PIXEL_NAMES, ImageCase, ImagePlan, MAX_IMAGE_DISPLACEMENTS, MAX_IMAGE_FIELDS,
    MAX_IMAGE_PAIRS, MAX_IMAGE_PIXELS, MAX_IMAGE_REALIZATIONS, PixelPrediction, PixelStats,
    RefocusImages, RefocusImagesFile,
};
pub use render::{
    Array, Band, Curve, DENSE_VOLUME_FRACTION, LAYOUT, MAX_OPTICAL_DEPTH, MILNE_ZE, MemorySpectrum,
    Wavelength, check_finite, eq39,
};
pub(crate) use render::{slab_tracer, slab_tracer_json};
pub use study::{
    Density, MAX_ANGLES, MAX_WAVELENGTHS, Study, StudyFile, StudyOutput, StudyOverrides,
    StudyRender, load_file, load_str,
};
pub use tilt::{
    MAX_G, MAX_TILT_OPTICAL_DEPTH, MemoryTilt, TiltFile, TiltRow, TiltStudy, load_tilt_file,
    load_tilt_str,
};
pub use tilt_fit::{TiltFit, TiltFitSpec, TiltFitted};
pub use tilt_material::{Material, MaterialG, MaterialSpec, TiltGeometry};
pub use tilt_shift::{
    MAX_GRID, MAX_TAU, MAX_TILT_SHIFT_OPTICAL_DEPTH, TiltShift, TiltShiftFile, TiltShiftStudy,
    centroid_slope, eq50, eq50_printed, load_tilt_shift_file, load_tilt_shift_str,
};
