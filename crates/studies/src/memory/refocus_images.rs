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

use super::refocus::{RefocusStudy, optimal_tilt};
use super::render::slab_tracer;
use crate::StudyError;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_endpoints::{Pair, Sensor, Source};
use speckle_estimators::{
    CovarianceOptions, EstimatorError, FieldOptions, Progress, Scene, render_covariance,
    render_fields,
};
use speckle_medium::{DVec3, HomogeneousBox};
use speckle_phase::{Complex64, Phase};
use speckle_scene::SceneError;
use speckle_scene::validate::{invalid as bad, positive};
use speckle_stats::jackknife::jackknife;
use speckle_stats::rng::derive_seed;
use std::fmt::Write as _;
use std::time::Instant;

/// Most image pixels per side (`images.n_pixels`).
pub const MAX_IMAGE_PIXELS: usize = 63;
/// Most imaged displacements (`images.delta_um`).
pub const MAX_IMAGE_DISPLACEMENTS: usize = 8;
/// Most field realizations (`images.realizations`).
pub const MAX_IMAGE_REALIZATIONS: usize = 4096;
/// Most pairs (source, camera pixel) of the image scene.
pub const MAX_IMAGE_PAIRS: usize = 1 << 20;
/// Most fields held at once, `realizations x pairs` (16 bytes each).
pub const MAX_IMAGE_FIELDS: usize = 1 << 27;

/// Index of the field render's seed, `derive_seed(render.seed, FIELD_SEED_INDEX)`.
const FIELD_SEED_INDEX: u64 = 1 << 40;
/// Index of the first check group's seed: group `i` of case `c` renders with
/// `derive_seed(render.seed, CHECK_SEED_INDEX + c groups + i)`.
const CHECK_SEED_INDEX: u64 = 1 << 41;

/// `[images]` of a refocusing study file: the rendered refocused fields (Fig. 13 top).
///
/// ```toml
/// [images]
/// delta_um = [1.0, 2.0]   # imaged displacements (each shift only and shift + tilt; 0 is added)
/// half_width_um = 4.0     # the image: n_pixels focal points along x, +-half_width around the target
/// n_pixels = 21           # odd
/// n_rows = 1              # odd: rows along y at the same pitch (default 1, a line)
/// realizations = 64       # independent transmission matrices
/// paths = 20000           # sub-paths per realization
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefocusImagesFile {
    /// Imaged displacements, micrometres (positive, increasing, at most `delta_max_um`).
    pub delta_um: Vec<f64>,
    /// Half width of the image around the target, micrometres.
    pub half_width_um: f64,
    /// Pixels along x (odd; the middle one is the target).
    pub n_pixels: usize,
    /// Rows along y at the pixel pitch (odd, default 1: a line through the target).
    #[serde(default = "one")]
    pub n_rows: usize,
    /// Independent field realizations.
    pub realizations: usize,
    /// Sub-paths per realization.
    pub paths: u64,
}

fn one() -> usize {
    1
}

/// One refocusing attempt of the images.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageCase {
    /// Focus displacement `Delta = Delta_a`, micrometres.
    pub delta: f64,
    /// Tilt `theta`, radians (0: shift only).
    pub theta: f64,
    /// Shift of the pattern on face `b`, `Delta_b = Delta + L theta`, micrometres.
    pub delta_b: f64,
}

impl ImageCase {
    /// A short label.
    pub fn label(&self) -> String {
        if self.delta == 0.0 {
            "Delta = 0".into()
        } else if self.theta == 0.0 {
            format!("Delta = {} um, shift only", self.delta)
        } else {
            format!(
                "Delta = {} um, shift + tilt ({:.1} mrad)",
                self.delta,
                self.theta * 1e3
            )
        }
    }
}

/// The validated `[images]` of a study.
#[derive(Debug, Clone)]
pub struct ImagePlan {
    /// The section as parsed.
    pub file: RefocusImagesFile,
    /// The cases: `Delta = 0`, then shift only and shift and tilt for every imaged `Delta`.
    pub cases: Vec<ImageCase>,
    /// Pixel offsets from the target along x, micrometres (symmetric, middle 0).
    pub offsets: Vec<f64>,
    /// Row offsets along y, micrometres (the same pitch, middle 0).
    pub rows: Vec<f64>,
}

impl ImagePlan {
    /// Pixels per image.
    pub fn pixels(&self) -> usize {
        self.offsets.len() * self.rows.len()
    }

    /// The pixels of the check: the target, then the middles of the edges (`+x, -x`, and `+y,
    /// -y` with more than one row), as (column, row) of the image (row `iy`, column `ix`, pixel
    /// `iy n_pixels + ix`).
    pub fn check_pixels(&self) -> Vec<(usize, usize)> {
        let (n, h) = (self.offsets.len(), self.rows.len());
        let (c, r) = (n / 2, h / 2);
        let mut v = vec![(c, r), (n - 1, r), (0, r)];
        if h > 1 {
            v.extend([(c, h - 1), (c, 0)]);
        }
        v
    }
}

/// Validates `[images]` against the study (`delta_max` and the slab's `width`, `thickness`).
pub(super) fn validate(
    f: &RefocusImagesFile,
    delta_max: f64,
    width: f64,
    thickness: f64,
    n_tau: usize,
) -> Result<ImagePlan, SceneError> {
    let d = &f.delta_um;
    if d.is_empty() || d.len() > MAX_IMAGE_DISPLACEMENTS {
        return Err(bad(
            "images.delta_um",
            format!(
                "must hold 1 to {MAX_IMAGE_DISPLACEMENTS} displacements (got {})",
                d.len()
            ),
        ));
    }
    for (j, &v) in d.iter().enumerate() {
        if !(v.is_finite() && v > 0.0 && v <= delta_max) {
            return Err(bad(
                "images.delta_um",
                format!("each must be in (0, delta_max_um = {delta_max}] (got {v})"),
            ));
        }
        if j > 0 && v <= d[j - 1] {
            return Err(bad(
                "images.delta_um",
                format!("must increase (got {} then {v})", d[j - 1]),
            ));
        }
    }
    let hw = positive("images.half_width_um", f.half_width_um)?;
    if delta_max / 2.0 + hw >= width / 2.0 {
        return Err(bad(
            "images.half_width_um",
            format!(
                "the image reaches {} um from the axis, outside the slab (width_um / 2 = {})",
                delta_max / 2.0 + hw,
                width / 2.0
            ),
        ));
    }
    let n = f.n_pixels;
    if n < 3 || n.is_multiple_of(2) || n > MAX_IMAGE_PIXELS {
        return Err(bad(
            "images.n_pixels",
            format!("must be odd and in 3..={MAX_IMAGE_PIXELS} (got {n})"),
        ));
    }
    let rows = f.n_rows;
    if rows.is_multiple_of(2) || rows > n {
        return Err(bad(
            "images.n_rows",
            format!("must be odd and at most n_pixels = {n} (got {rows})"),
        ));
    }
    if !(2..=MAX_IMAGE_REALIZATIONS).contains(&f.realizations) {
        return Err(bad(
            "images.realizations",
            format!(
                "must be in 2..={MAX_IMAGE_REALIZATIONS} (got {})",
                f.realizations
            ),
        ));
    }
    if f.paths == 0 {
        return Err(bad("images.paths", "must be positive (got 0)"));
    }
    let cases = 1 + 2 * d.len();
    let pairs = cases * (n * rows + 1) * n_tau;
    if pairs > MAX_IMAGE_PAIRS {
        return Err(bad(
            "images.n_pixels",
            format!(
                "gives {pairs} pairs (cases x (n_pixels n_rows + 1) x n_tau); at most \
                 {MAX_IMAGE_PAIRS}"
            ),
        ));
    }
    if pairs * f.realizations > MAX_IMAGE_FIELDS {
        return Err(bad(
            "images.realizations",
            format!(
                "gives {} fields (realizations x {pairs} pairs); at most {MAX_IMAGE_FIELDS}",
                pairs * f.realizations
            ),
        ));
    }
    let mut list = vec![ImageCase {
        delta: 0.0,
        theta: 0.0,
        delta_b: 0.0,
    }];
    for &v in d {
        let t = optimal_tilt(v, thickness);
        list.push(ImageCase {
            delta: v,
            theta: 0.0,
            delta_b: v,
        });
        list.push(ImageCase {
            delta: v,
            theta: t,
            delta_b: v + thickness * t,
        });
    }
    let h = (n / 2) as f64;
    let pitch = hw / h;
    let hr = (rows / 2) as f64;
    Ok(ImagePlan {
        file: f.clone(),
        cases: list,
        offsets: (0..n).map(|i| hw * (i as f64 - h) / h).collect(),
        rows: (0..rows).map(|i| pitch * (i as f64 - hr)).collect(),
    })
}

/// Where a case's fields sit among the pairs of a scene.
#[derive(Debug, Clone, Copy)]
struct CaseLayout {
    /// The first pair of the case: `n_tau` pairs `(g, r_m)`, then `n_tau` per pixel `(x, s_m)`.
    first: usize,
}

/// The measured statistics of one pixel over the realizations (normalised by the study's
/// `|E A(0)|^2` from the check renders).
#[derive(Debug, Clone, Copy, Default)]
pub struct PixelStats {
    /// Mean of `A`, real part, normalised by `|E A(0)|`.
    pub mean_re: f64,
    /// Mean of `A`, imaginary part, normalised by `|E A(0)|`.
    pub mean_im: f64,
    /// Standard error of the real part of the mean.
    pub mean_se: f64,
    /// Standard error of the imaginary part of the mean.
    pub mean_im_se: f64,
    /// Mean power `|A|^2`, normalised.
    pub power: f64,
    /// Its standard error over the realizations.
    pub power_se: f64,
    /// Sample variance `E|A - mean A|^2`, normalised.
    pub var: f64,
    /// Its standard error (of `|A - mean A|^2` over the realizations).
    pub var_se: f64,
}

/// The covariance prediction at one pixel (normalised as [`PixelStats`]; jackknife
/// bias-corrected values, jackknife standard errors).
#[derive(Debug, Clone, Copy, Default)]
pub struct PixelPrediction {
    /// `E A`, real part, normalised by `|E A(0)|`, and its jackknife SE.
    pub mean_re: (f64, f64),
    /// `E A`, imaginary part, and its jackknife SE.
    pub mean_im: (f64, f64),
    /// `|E A|^2 + Var A` (Isserlis), normalised, and its jackknife SE.
    pub power: (f64, f64),
    /// The focus term `|E A|^2`, normalised, and its jackknife SE.
    pub focus: (f64, f64),
    /// `Var A` (Isserlis), normalised, and its jackknife SE.
    pub var: (f64, f64),
}

/// The rendered refocused fields and their check.
#[derive(Debug, Clone)]
pub struct RefocusImages {
    /// The refocused amplitudes `A`, `(realizations, cases, n_rows, n_pixels)`, normalised by `|E A(0)|` of
    /// the check renders.
    pub amplitude: Vec<Complex64>,
    /// `|E A(0)|^2` of the check renders, in the covariance's units squared.
    pub norm: f64,
    /// Measured statistics at the check pixels, `[case][pixel]` (pixels of
    /// [`ImagePlan::check_pixels`]).
    pub measured: Vec<Vec<PixelStats>>,
    /// The covariance prediction at the same pixels.
    pub predicted: Vec<Vec<PixelPrediction>>,
    /// Wall time of the field render, seconds.
    pub fields_wall: f64,
    /// Wall time of the check renders, seconds.
    pub check_wall: f64,
}

impl RefocusStudy {
    /// The scene of the given cases with the given pixel offsets `(o_x, o_y)` per case (the
    /// same for all): per case, sources `g` then the pixels, sensors `r_m` then `s_m`, pairs
    /// `(g, r_m)` then `(x_p, s_m)` pixel after pixel.
    fn image_scene(
        &self,
        cases: &[ImageCase],
        pixels: &[(f64, f64)],
    ) -> Result<(Scene<HomogeneousBox, Phase>, Vec<CaseLayout>), EstimatorError> {
        let f = &self.file;
        let geo = &self.geometry;
        let l = f.thickness_um;
        let medium = geo.slab()?;
        let beam = |x: f64, y: f64, z: f64, tilt: f64| geo.beam(DVec3::new(x, y, z), tilt);
        let (mut sources, mut sensors, mut pairs, mut layout) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let nt = geo.tau.len();
        for c in cases {
            let da = geo.delta_a(c.delta_b, c.theta);
            layout.push(CaseLayout { first: pairs.len() });
            let g = sources.len();
            sources.push(Source::GaussianBeam(beam(
                -da / 2.0,
                0.0,
                -l / 2.0,
                -c.theta / 2.0,
            )?));
            let r0 = sensors.len();
            for s in [-1.0, 1.0] {
                for &t in &geo.tau {
                    sensors.push(Sensor::GaussianBeam(beam(
                        t + s * c.delta_b / 2.0,
                        0.0,
                        l / 2.0,
                        0.0,
                    )?));
                }
            }
            pairs.extend((0..nt).map(|m| Pair {
                source: g,
                sensor: r0 + m,
            }));
            for &(ox, oy) in pixels {
                let x = sources.len();
                sources.push(Source::GaussianBeam(beam(
                    da / 2.0 + ox,
                    oy,
                    -l / 2.0,
                    c.theta / 2.0,
                )?));
                pairs.extend((0..nt).map(|m| Pair {
                    source: x,
                    sensor: r0 + nt + m,
                }));
            }
        }
        let scene = Scene::new(
            medium,
            geo.phase()?,
            f.wavelength_um,
            sources,
            sensors,
            pairs,
        )?;
        Ok((scene, layout))
    }

    /// The phase ramp `a_m = exp(-i q tau_m)`, `q = 2 k sin(theta/2)`, of a case.
    fn ramp(&self, theta: f64) -> Vec<Complex64> {
        let q = self.geometry.k() * 2.0 * (theta / 2.0).sin();
        self.geometry
            .tau
            .iter()
            .map(|&t| Complex64::from_polar(1.0, -q * t))
            .collect()
    }

    /// The rough cost of the images on `threads` threads: seconds and bytes.
    pub fn images_estimate(&self, threads: usize) -> (f64, f64) {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
        let Some(p) = &self.images else {
            return (0.0, 0.0);
        };
        let f = &self.file;
        let t = 1.0 / f.mean_free_path_um;
        let taus = [t * f.width_um, t * f.width_um, t * f.thickness_um];
        let v = expected_vertices(&taus, 1.0, f.g, speckle_medium::Dimension::Three, u32::MAX);
        let nt = self.geometry.tau.len() as f64;
        let cases = p.cases.len() as f64;
        let pixels = p.pixels() as f64;
        let pairs = cases * (pixels + 1.0) * nt;
        // Every endpoint is a Gaussian beam of the single vMF lobe.
        let legs = gaussian_legs(cases * (pixels + 1.0 + 2.0 * nt), 1);
        let paths = p.file.realizations as f64 * p.file.paths as f64;
        let per_pair =
            covariance_seconds(paths, v, 0.0, 1.0) - covariance_seconds(paths, v, 0.0, 0.0);
        let fields = covariance_seconds(paths, v, legs, 0.0) + pairs * per_pair;
        let check_pairs = (1.0 + p.check_pixels().len() as f64) * nt;
        let check = cases
            * covariance_seconds(
                f.render.paths as f64,
                v,
                gaussian_legs(2.0 * nt + 6.0, 1),
                check_pairs,
            );
        let bytes = 16.0 * pairs * (p.file.realizations as f64 + 1.0)
            + 16.0 * p.file.realizations as f64 * cases * pixels;
        ((fields + check) / threads.max(1) as f64, bytes)
    }

    /// Renders the images of `[images]` (`None` without it): the fields of every case in one
    /// field render of `images.realizations` realizations of `images.paths` sub-paths (seed
    /// `derive_seed(render.seed, 2^40)`, `render.coherence` and the study's tracer), then the
    /// check: per case `render.groups` covariance renders of `render.paths` paths in all (group
    /// `i` of case `c` seeded with `derive_seed(render.seed, 2^41 + c groups + i)`).
    pub fn render_images(
        &self,
        progress: &dyn Progress,
    ) -> Result<Option<RefocusImages>, StudyError> {
        let Some(plan) = &self.images else {
            return Ok(None);
        };
        self.render_images_with(plan, false, progress).map(Some)
    }

    /// [`Self::render_images`] of `plan`; with `unconjugated` the pattern is `u_g(r_m) exp(-i q
    /// tau_m)` without the complex conjugate (a check that the conjugation is what focuses).
    pub fn render_images_with(
        &self,
        plan: &ImagePlan,
        unconjugated: bool,
        progress: &dyn Progress,
    ) -> Result<RefocusImages, StudyError> {
        let r = &self.file.render;
        let coherence = r.coherence.coherence();
        let nt = self.geometry.tau.len();
        let n = plan.offsets.len();
        let np = plan.pixels();
        let nc = plan.cases.len();
        // The check first: its |E A(0)| normalises everything.
        let start = Instant::now();
        let cp = plan.check_pixels();
        let check_offsets: Vec<(f64, f64)> = cp
            .iter()
            .map(|&(ix, iy)| (plan.offsets[ix], plan.rows[iy]))
            .collect();
        let nk = cp.len();
        let g = r.groups as u64;
        // blocks[c][i]: group i's covariance blocks of case c.
        let mut blocks: Vec<Vec<Blocks>> = Vec::with_capacity(nc);
        let mut weights = vec![0.0; r.groups];
        for (c, case) in plan.cases.iter().enumerate() {
            let (scene, _) = self.image_scene(std::slice::from_ref(case), &check_offsets)?;
            let mut per_group = Vec::with_capacity(r.groups);
            for i in 0..g {
                let paths = r.paths / g + u64::from(i < r.paths % g);
                let opts = CovarianceOptions {
                    paths,
                    seed: derive_seed(r.seed, CHECK_SEED_INDEX + c as u64 * g + i),
                    coherence,
                    sampling: slab_tracer(coherence),
                };
                let est = render_covariance(&scene, &opts, progress)?;
                let v = &est.total.value;
                per_group.push(Blocks::from_fn(nt, nk, |a, b| v.get(a, b)));
                weights[i as usize] = paths as f64;
            }
            blocks.push(per_group);
        }
        let ramps: Vec<Vec<Complex64>> = plan.cases.iter().map(|c| self.ramp(c.theta)).collect();
        // The statistic: |E A(0)|^2 (target of case 0), then per case and check pixel: Re E A,
        // Im E A (by |E A(0)|), |E A|^2 + Var A, Var A and |E A|^2 (by |E A(0)|^2), from the covariances
        // pooled over the groups kept.
        let stat = |skip: Option<usize>| -> Vec<f64> {
            let kept: Vec<usize> = (0..r.groups).filter(|&i| Some(i) != skip).collect();
            let w: f64 = kept.iter().map(|&i| weights[i]).sum();
            let pooled: Vec<Blocks> = blocks
                .iter()
                .map(|b| Blocks::pool(kept.iter().map(|&i| (&b[i], weights[i] / w))))
                .collect();
            let moments: Vec<Vec<(Complex64, f64)>> = pooled
                .iter()
                .zip(&ramps)
                .map(|(b, a)| (0..nk).map(|k| b.moments(k, a)).collect())
                .collect();
            let norm = moments[0][0].0.norm_sqr();
            let mut out = vec![norm];
            for m in &moments {
                for &(mean, var) in m {
                    out.extend([
                        mean.re / norm.sqrt(),
                        mean.im / norm.sqrt(),
                        (mean.norm_sqr() + var) / norm,
                        var / norm,
                        mean.norm_sqr() / norm,
                    ]);
                }
            }
            out
        };
        // Jackknife standard errors, and the jackknife's bias correction `G v - (G - 1) mean(v_i)`
        // of the values: `|E A|^2` and the products of covariances in `Var A` carry an upward
        // bias of the order of the squared standard errors of their entries (many near zero).
        let (raw, se) = jackknife(r.groups, stat);
        let gf = r.groups as f64;
        let loo: Vec<Vec<f64>> = (0..r.groups).map(|i| stat(Some(i))).collect();
        let value: Vec<f64> = (0..raw.len())
            .map(|j| gf * raw[j] - (gf - 1.0) * loo.iter().map(|l| l[j]).sum::<f64>() / gf)
            .collect();
        let norm = value[0];
        let predicted = (0..nc)
            .map(|c| {
                (0..nk)
                    .map(|k| {
                        let j = 1 + 5 * (nk * c + k);
                        PixelPrediction {
                            mean_re: (value[j], se[j]),
                            mean_im: (value[j + 1], se[j + 1]),
                            power: (value[j + 2], se[j + 2]),
                            var: (value[j + 3], se[j + 3]),
                            focus: (value[j + 4], se[j + 4]),
                        }
                    })
                    .collect()
            })
            .collect();
        let check_wall = start.elapsed().as_secs_f64();

        // The fields: every case in one scene, one realization one medium.
        let start = Instant::now();
        let pixels: Vec<(f64, f64)> = (0..np)
            .map(|p| (plan.offsets[p % n], plan.rows[p / n]))
            .collect();
        let (scene, layout) = self.image_scene(&plan.cases, &pixels)?;
        let opts = FieldOptions {
            realizations: plan.file.realizations,
            paths_per_realization: plan.file.paths,
            seed: derive_seed(r.seed, FIELD_SEED_INDEX),
            coherence,
            add_mean: false,
            sampling: slab_tracer(coherence),
        };
        let est = render_fields(&scene, &opts, progress)?;
        let rr = plan.file.realizations;
        let scale = 1.0 / norm.sqrt();
        let mut amplitude = vec![Complex64::new(0.0, 0.0); rr * nc * np];
        for q in 0..rr {
            let u = |j: usize| est.fields.get(q, j);
            for (c, lay) in layout.iter().enumerate() {
                let pattern: Vec<Complex64> = (0..nt)
                    .map(|m| {
                        let ug = u(lay.first + m);
                        (if unconjugated { ug } else { ug.conj() }) * ramps[c][m]
                    })
                    .collect();
                for p in 0..np {
                    let x0 = lay.first + nt * (1 + p);
                    let a: Complex64 = (0..nt).map(|m| u(x0 + m) * pattern[m]).sum();
                    amplitude[(q * nc + c) * np + p] = a * scale;
                }
            }
        }
        let measured = (0..nc)
            .map(|c| {
                cp.iter()
                    .map(|&(ix, iy)| {
                        let p = iy * n + ix;
                        let a: Vec<Complex64> =
                            (0..rr).map(|q| amplitude[(q * nc + c) * np + p]).collect();
                        pixel_stats(&a)
                    })
                    .collect()
            })
            .collect();
        Ok(RefocusImages {
            amplitude,
            norm,
            measured,
            predicted,
            fields_wall: start.elapsed().as_secs_f64(),
            check_wall,
        })
    }
}

/// The covariance blocks of a check scene (pairs `(g, r_m)`, then `(x_k, s_m)` for the check
/// pixels): `C[(x_k, s_m), (g, r_m)]`, `C[(x_k, s_m), (x_k, s_m')]` and `C[(g, r_m'), (g,
/// r_m)]`.
#[derive(Debug, Clone)]
struct Blocks {
    nt: usize,
    /// `cross[k nt + m]`.
    cross: Vec<Complex64>,
    /// `xx[(k nt + m) nt + m']`.
    xx: Vec<Complex64>,
    /// `gg[m' nt + m] = C[(g, r_m'), (g, r_m)]`.
    gg: Vec<Complex64>,
}

impl Blocks {
    fn from_fn(nt: usize, nk: usize, c: impl Fn(usize, usize) -> Complex64) -> Self {
        let x = |k: usize| nt * (1 + k);
        Self {
            nt,
            cross: (0..nk * nt)
                .map(|j| c(x(j / nt) + j % nt, j % nt))
                .collect(),
            xx: (0..nk * nt * nt)
                .map(|j| {
                    let (k, m, mp) = (j / (nt * nt), (j / nt) % nt, j % nt);
                    c(x(k) + m, x(k) + mp)
                })
                .collect(),
            gg: (0..nt * nt).map(|j| c(j / nt, j % nt)).collect(),
        }
    }

    /// The weighted sum of blocks.
    fn pool<'a>(parts: impl Iterator<Item = (&'a Blocks, f64)>) -> Self {
        let mut out: Option<Blocks> = None;
        for (b, w) in parts {
            let o = out.get_or_insert_with(|| Blocks {
                nt: b.nt,
                cross: vec![Complex64::new(0.0, 0.0); b.cross.len()],
                xx: vec![Complex64::new(0.0, 0.0); b.xx.len()],
                gg: vec![Complex64::new(0.0, 0.0); b.gg.len()],
            });
            for (d, s) in [
                (&mut o.cross, &b.cross),
                (&mut o.xx, &b.xx),
                (&mut o.gg, &b.gg),
            ] {
                for (x, y) in d.iter_mut().zip(s) {
                    *x += y * w;
                }
            }
        }
        out.expect("at least one group")
    }

    /// `E A` and the Isserlis `Var A` of check pixel `k` with the ramp `a`.
    fn moments(&self, k: usize, a: &[Complex64]) -> (Complex64, f64) {
        let nt = self.nt;
        let mean = (0..nt).map(|m| self.cross[k * nt + m] * a[m]).sum();
        let mut var = Complex64::new(0.0, 0.0);
        for m in 0..nt {
            for mp in 0..nt {
                var += a[m] * a[mp].conj() * self.xx[(k * nt + m) * nt + mp] * self.gg[mp * nt + m];
            }
        }
        (mean, var.re)
    }
}

/// Mean, power and variance of samples of `A`, with their standard errors.
fn pixel_stats(a: &[Complex64]) -> PixelStats {
    let r = a.len() as f64;
    let mean: Complex64 = a.iter().sum::<Complex64>() / r;
    let p: Vec<f64> = a.iter().map(|z| z.norm_sqr()).collect();
    let d: Vec<f64> = a.iter().map(|z| (z - mean).norm_sqr()).collect();
    let mean_sd = |x: &[f64]| {
        let m = x.iter().sum::<f64>() / r;
        let v = x.iter().map(|y| (y - m).powi(2)).sum::<f64>() / (r - 1.0);
        (m, (v / r).sqrt())
    };
    let (power, power_se) = mean_sd(&p);
    let (var_biased, var_se) = mean_sd(&d);
    let var = var_biased * r / (r - 1.0);
    PixelStats {
        mean_re: mean.re,
        mean_im: mean.im,
        mean_se: mean_sd(&a.iter().map(|z| z.re).collect::<Vec<_>>()).1,
        mean_im_se: mean_sd(&a.iter().map(|z| z.im).collect::<Vec<_>>()).1,
        power,
        power_se,
        var,
        var_se,
    }
}

/// Names of the check pixels.
pub const CHECK_PIXEL_NAMES: [&str; 5] = ["target", "+x edge", "-x edge", "+y edge", "-y edge"];

impl RefocusImages {
    /// Measured against predicted in standard errors (the two SEs in quadrature) for every case
    /// and check pixel: `[Re E A, Im E A, E|A|^2, Var A]`.
    pub fn deviations(&self) -> Vec<Vec<[f64; 4]>> {
        self.measured
            .iter()
            .zip(&self.predicted)
            .map(|(m, p)| {
                m.iter()
                    .zip(p)
                    .map(|(m, p)| {
                        // A part that is zero in both up to rounding (Im A at the Delta = 0 target,
                        // the guide star's own intensities) deviates by 0.
                        let z = |x: f64, sx: f64, (y, sy): (f64, f64)| {
                            let (d, s) = (x - y, sx.hypot(sy));
                            if s < 1e-9 && d.abs() < 1e-9 {
                                0.0
                            } else {
                                d / s
                            }
                        };
                        [
                            z(m.mean_re, m.mean_se, p.mean_re),
                            z(m.mean_im, m.mean_im_se, p.mean_im),
                            z(m.power, m.power_se, p.power),
                            z(m.var, m.var_se, p.var),
                        ]
                    })
                    .collect()
            })
            .collect()
    }

    /// The power `|A|^2` of every realization, case and pixel, `(R, cases, n_rows, n_pixels)`.
    pub fn power(&self) -> Vec<f64> {
        self.amplitude.iter().map(|a| a.norm_sqr()).collect()
    }

    /// The mean power over the realizations, `(cases, n_rows, n_pixels)`.
    pub fn mean_power(&self, plan: &ImagePlan) -> Vec<f64> {
        let np = plan.pixels() * plan.cases.len();
        let rr = plan.file.realizations;
        let mut m = vec![0.0; np];
        for q in 0..rr {
            for (j, v) in m.iter_mut().enumerate() {
                *v += self.amplitude[q * np + j].norm_sqr() / rr as f64;
            }
        }
        m
    }

    /// The output arrays (float64, C order).
    pub fn arrays(&self, s: &RefocusStudy, plan: &ImagePlan) -> Vec<super::Array> {
        let (rr, nc, n, h) = (
            plan.file.realizations,
            plan.cases.len(),
            plan.offsets.len(),
            plan.rows.len(),
        );
        let nk = plan.check_pixels().len();
        let case_col = |f: fn(&ImageCase) -> f64| plan.cases.iter().map(f).collect::<Vec<_>>();
        let flat = |x: &dyn Fn(&PixelStats, &PixelPrediction) -> [f64; 2]| -> Vec<f64> {
            self.measured
                .iter()
                .zip(&self.predicted)
                .flat_map(|(m, p)| m.iter().zip(p).flat_map(|(m, p)| x(m, p)))
                .collect()
        };
        let _ = s;
        vec![
            super::Array {
                key: "refocus_images",
                shape: vec![rr, nc, h, n, 2],
                data: self.amplitude.iter().flat_map(|a| [a.re, a.im]).collect(),
                content: "(realizations, cases, n_rows (y), n_pixels (x), 2): the refocused \
                          amplitude A(x) = sum_m u_x(s_m) conj(u_g(r_m)) exp(-i q tau_m) (real, \
                          imaginary), normalised by |E A(0)| of the check renders",
            },
            super::Array {
                key: "refocus_images_power",
                shape: vec![rr, nc, h, n],
                data: self.power(),
                content: "(realizations, cases, n_rows (y), n_pixels (x)): |A|^2 / |E A(0)|^2",
            },
            super::Array {
                key: "refocus_images_mean_power",
                shape: vec![nc, h, n],
                data: self.mean_power(plan),
                content: "(cases, n_rows (y), n_pixels (x)): the mean of |A|^2 / |E A(0)|^2 \
                          over the realizations",
            },
            super::Array {
                key: "refocus_images_offset_um",
                shape: vec![n],
                data: plan.offsets.clone(),
                content: "(n_pixels,): pixel offset from the target along x (columns), \
                          micrometres",
            },
            super::Array {
                key: "refocus_images_row_um",
                shape: vec![h],
                data: plan.rows.clone(),
                content: "(n_rows,): row offset from the target along y, micrometres",
            },
            super::Array {
                key: "refocus_images_delta_um",
                shape: vec![nc],
                data: case_col(|c| c.delta),
                content: "(cases,): focus displacement Delta of each case, micrometres",
            },
            super::Array {
                key: "refocus_images_theta_mrad",
                shape: vec![nc],
                data: case_col(|c| c.theta * 1e3),
                content: "(cases,): tilt theta of each case, milliradians (0: shift only)",
            },
            super::Array {
                key: "refocus_images_check_power",
                shape: vec![nc, nk, 2],
                data: flat(&|m, _| [m.power, m.power_se]),
                content: "(cases, check pixels, 2): mean |A|^2 / |E A(0)|^2 over the \
                          realizations and its SE; check pixels: target, +x, -x edges (and +y, -y with rows)",
            },
            super::Array {
                key: "refocus_images_check_var",
                shape: vec![nc, nk, 2],
                data: flat(&|m, _| [m.var, m.var_se]),
                content: "(cases, check pixels, 2): Var A / |E A(0)|^2 over the realizations \
                          and its SE",
            },
            super::Array {
                key: "refocus_images_predicted_power",
                shape: vec![nc, nk, 2],
                data: flat(&|_, p| [p.power.0, p.power.1]),
                content: "(cases, check pixels, 2): |E A|^2 + Var A (Isserlis) from the check's \
                          covariance renders, normalised, and its jackknife SE",
            },
            super::Array {
                key: "refocus_images_predicted_var",
                shape: vec![nc, nk, 2],
                data: flat(&|_, p| [p.var.0, p.var.1]),
                content: "(cases, check pixels, 2): Var A (Isserlis) from the check's covariance \
                          renders, normalised, and its jackknife SE",
            },
        ]
    }

    /// The terminal report.
    pub fn text(&self, plan: &ImagePlan) -> String {
        let mut o = String::new();
        let dev = self.deviations();
        let _ = writeln!(
            o,
            "images: {} realizations of {} paths, {} cases, {} x {} pixels (x, y); fields {:.1} s, \
             check {:.1} s. Normalised by |E A(0)|^2; measured (realizations) / predicted \
             (covariance, Isserlis), deviation in SE:",
            plan.file.realizations,
            plan.file.paths,
            plan.cases.len(),
            plan.offsets.len(),
            plan.rows.len(),
            self.fields_wall,
            self.check_wall
        );
        for (c, case) in plan.cases.iter().enumerate() {
            let _ = writeln!(o, "  {}", case.label());
            for k in 0..self.measured[c].len() {
                let (m, p, d) = (self.measured[c][k], self.predicted[c][k], dev[c][k]);
                let _ = writeln!(
                    o,
                    "    {:>8}: E A {:>7.4}{:+.4}i / {:>7.4}{:+.4}i ({:+.1}, {:+.1}); E|A|^2 \
                     {:>7.4} +- {:.4} / {:>7.4} ({:+.1}); Var A {:>7.4} +- {:.4} / {:>7.4} \
                     ({:+.1})",
                    CHECK_PIXEL_NAMES[k],
                    m.mean_re,
                    m.mean_im,
                    p.mean_re.0,
                    p.mean_im.0,
                    d[0],
                    d[1],
                    m.power,
                    m.power_se,
                    p.power.0,
                    d[2],
                    m.var,
                    m.var_se,
                    p.var.0,
                    d[3]
                );
            }
        }
        o
    }

    /// The sidecar's part.
    pub fn describe(&self, plan: &ImagePlan) -> Value {
        let dev = self.deviations();
        let worst = dev
            .iter()
            .flat_map(|c| c.iter().flat_map(|p| p.iter().map(|d| d.abs())))
            .fold(0.0, f64::max);
        json!({
            "section": serde_json::to_value(&plan.file).unwrap_or(Value::Null),
            "cases": plan.cases.iter().map(|c| json!({
                "delta_um": c.delta, "theta_mrad": c.theta * 1e3, "delta_b_um": c.delta_b,
                "label": c.label(),
            })).collect::<Vec<_>>(),
            "amplitude": "A(x) = sum_m u_x(s_m) conj(u_g(r_m)) exp(-i q tau_m), q = 2 k \
                          sin(theta/2): guide star g at (-Delta/2, 0, -L/2) tilted by -theta/2, \
                          its field on r_m = tau_m - Delta_b/2; image pixels x at (Delta/2 + o_x, \
                          o_y, -L/2) tilted by +theta/2, their fields on s_m = tau_m + Delta_b/2; \
                          scattered fields only (no mean)",
            "normalisation": "|E A(0)|^2 of the check renders",
            "norm": self.norm,
            "field_seed": "derive_seed(render.seed, 2^40)",
            "check": "per case, render.groups covariance renders of render.paths paths (group i \
                      of case c: derive_seed(render.seed, 2^41 + c groups + i)) of the guide \
                      star and the check pixels (the target, the middles of the edges: +x, \
                      -x, then +y, -y with rows): E A and Var A = sum a_m conj(a_m') \
                      C[(x,s_m),(x,s_m')] C[(g,r_m'),(g,r_m)] (Isserlis, circular Gaussian \
                      fields)",
            "largest_deviation_in_se": worst,
            "fields_wall_time_s": self.fields_wall,
            "check_wall_time_s": self.check_wall,
        })
    }
}
