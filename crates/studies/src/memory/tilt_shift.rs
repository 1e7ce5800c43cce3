//! The tilt-shift memory effect (Bar et al. 2020, Sec. 9, Fig. 12; Osnabrugge et al. 2017), the
//! study of `speckle tilt-shift`: the near-field correlation of Eq. 49 over a grid of output
//! shifts `Delta_b` and tilts `theta`, against the analytic model of Eq. 50.
//!
//! Geometry (`shared/notes/nearfield-2020.md` Sec. 7.7, reconstruction of App. A.7): a lossless
//! slab `L` thick along z (faces `a` at `z = -L/2` and `b` at `z = +L/2`), `width` wide, of a
//! single-lobe vMF scattering amplitude of mean cosine `g` (the closed-form connections of
//! Gaussian beams need a vMF amplitude). Two Gaussian beams focused on face `a`,
//! `i1 = (-Delta_a / 2, 0, -L/2)` propagating along `+z` tilted by `-theta/2` about +y and
//! `i2 = (+Delta_a / 2, 0, -L/2)` tilted by `+theta/2` (directions `(sin(+-theta/2), 0,
//! cos(+-theta/2))`), and a camera of Gaussian-beam pixels focused on face `b` viewing along
//! +z, at `tau_m -+ Delta_b / 2` on the x axis. The input shift follows the Dirac delta of
//! Eq. 50, `Delta_a = Delta_b - L theta`: a ray entering at `+-Delta_a/2` along its beam's axis
//! leaves at `+-Delta_b/2`. For every `(theta, Delta_b)` the study renders the covariance of the
//! pairs `(i1, v1_m)`, `(i2, v2_m)` and sums (Eq. 49, the camera a line of `n_tau` pixels `h`
//! apart)
//!
//! ```text
//! C(Delta_b, theta) = sum_m C[(i1, v1_m), (i2, v2_m)] exp(i k 2 sin(theta/2) tau_m)
//! ```
//!
//! (`C[(i1,v1),(i2,v2)] = E[u1 conj(u2)]`, `docs/conventions.md`; the two beams' fields at face
//! `b` differ by the tilt `exp(i k 2 sin(theta/2) x)`, which the factor removes). The output is
//! `|C| / C(0, 0)`.
//!
//! The model (Eq. 50). The paper prints the exponent `-(L^3 k^2 / (2 l_tr)) (theta^2/12 +
//! (theta/2 + Delta_b/L)^2)` beside the delta `Delta_b = Delta_a + L theta`. With the delta's
//! convention (which fixes the sign of `theta`) that exponent is largest at `Delta_b = -L
//! theta / 2`, `Delta_a = -3 L theta / 2`: beams whose axes cross outside the slab. Osnabrugge's
//! derivation (a thin-screen phase decorrelating as `k^2 delta(z)^2 / l_tr` per unit depth, for
//! two rays `delta(z) = Delta_a + theta z` apart at depth `z`, integrated over `0 < z < L`)
//! gives `int_0^L (Delta_a + theta z)^2 dz = L^3 (theta^2/12 + (theta/2 + Delta_a/L)^2)`: the
//! printed exponent with `Delta_a` in place of `Delta_b`, largest where the beams cross at
//! mid-depth (`Delta_b = +L theta / 2`). This study follows the derivation (`model`) and also
//! writes the printed form (`model_printed`); the Monte Carlo decides between them (the
//! centroid slopes `d<Delta_b>/d theta` the report prints; `tests/tilt_shift.rs`).
//!
//! Estimator: forward paths only, the first vertex exponential in depth from face `a` and the
//! first direction from the phase function around +z (as `speckle memory-tilt`); standard errors
//! are jackknife estimates over `render.groups` independent renders of every grid point.

use super::render::{slab_tracer, slab_tracer_json};
use super::study::{StudyOutput, StudyOverrides, StudyRender, check_render, parse};
use crate::StudyError;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_endpoints::{GaussianBeam, Pair, Sensor, Source};
use speckle_estimators::{CovarianceOptions, EstimatorError, Progress, Scene, render_covariance};
use speckle_medium::{Aabb, DVec3, HomogeneousBox};
use speckle_phase::{Complex64, Phase, VmfMixture};
use speckle_scene::validate::{invalid as bad, number, positive};
use speckle_scene::{LoadError, SceneError, load};
use speckle_stats::jackknife::jackknife;
use speckle_stats::rng::derive_seed;
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Most grid points `n_theta n_delta_b` a study may render.
pub const MAX_GRID: usize = 4096;
/// Most camera pixels `n_tau`.
pub const MAX_TAU: usize = 512;
/// Largest optical depth `L / l`.
pub const MAX_TILT_SHIFT_OPTICAL_DEPTH: f64 = 20.0;

/// A tilt-shift study file (TOML, unknown keys rejected). Lengths in micrometres.
///
/// ```toml
/// name = "fig12_tilt_shift"       # output prefix (default: the file's stem)
/// wavelength_um = 0.5             # wavelength in the medium
/// mean_free_path_um = 23.0        # l = 1 / sigma_s (lossless)
/// g = 0.98                        # mean cosine of the single-lobe vMF amplitude
/// thickness_um = 20.0             # L
/// width_um = 60.0                 # lateral size of the slab (x and y)
/// numerical_aperture = 0.5        # of both beams and of the camera's pixels
/// theta_max_mrad = 150.0          # tilts: n_theta values from -max to +max (n_theta odd)
/// n_theta = 7
/// delta_b_max_um = 3.0            # output shifts: n_delta_b values from -max to +max (odd)
/// n_delta_b = 13
/// tau_max_um = 15.0               # camera line: n_tau pixels from -max to +max
/// n_tau = 61
///
/// [render]
/// paths = 20000                   # sub-paths per grid point, split over the groups
/// seed = 1
/// groups = 8
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TiltShiftFile {
    /// Output prefix (default: the stem of the file name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Wavelength in the medium, micrometres.
    pub wavelength_um: f64,
    /// Mean free path `l = 1 / sigma_s`, micrometres.
    pub mean_free_path_um: f64,
    /// Mean cosine of the vMF amplitude.
    pub g: f64,
    /// Slab thickness `L`, micrometres.
    pub thickness_um: f64,
    /// Slab width, micrometres.
    pub width_um: f64,
    /// Numerical aperture of the beams and the camera pixels.
    pub numerical_aperture: f64,
    /// Largest tilt, milliradians.
    pub theta_max_mrad: f64,
    /// Number of tilts (odd, at least 3).
    pub n_theta: usize,
    /// Largest output shift, micrometres.
    pub delta_b_max_um: f64,
    /// Number of output shifts (odd, at least 3).
    pub n_delta_b: usize,
    /// Half width of the camera line, micrometres.
    pub tau_max_um: f64,
    /// Camera pixels (at least 2).
    pub n_tau: usize,
    /// `[render]`: `paths` per grid point.
    #[serde(default)]
    pub render: StudyRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
}

/// A validated tilt-shift study.
#[derive(Debug, Clone)]
pub struct TiltShiftStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: TiltShiftFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// Tilts, radians (symmetric, the middle one 0).
    pub theta: Vec<f64>,
    /// Output shifts, micrometres (symmetric, the middle one 0).
    pub delta_b: Vec<f64>,
    /// Camera pixel positions, micrometres.
    pub tau: Vec<f64>,
    /// The vMF concentration of the single-lobe amplitude (`g = A_3(2 gamma)`).
    pub amplitude_gamma: f64,
}

/// Loads and validates a tilt-shift study file.
pub fn load_tilt_shift_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<TiltShiftStudy, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_tilt_shift_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a tilt-shift study from its text (`origin` names it in errors,
/// `default_name` is the output prefix when the study sets none).
pub fn load_tilt_shift_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<TiltShiftStudy, LoadError> {
    let mut file: TiltShiftFile = parse(text).map_err(|e| e.in_document(origin))?;
    overrides
        .apply(&mut file.render, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

/// `n` values from `-max` to `max`, the middle one exactly 0.
fn symmetric(max: f64, n: usize) -> Vec<f64> {
    let h = (n / 2) as f64;
    (0..n).map(|i| max * (i as f64 - h) / h).collect()
}

/// `A_3(x) = coth x - 1/x`, the mean cosine of a vMF density of concentration `x`.
fn a3(x: f64) -> f64 {
    if x < 1e-4 {
        x / 3.0
    } else {
        1.0 / x.tanh() - 1.0 / x
    }
}

fn odd_count(field: &str, n: usize, max: usize) -> Result<(), SceneError> {
    if n < 3 || n.is_multiple_of(2) || n > max {
        return Err(bad(
            field,
            format!("must be odd and in 3..={max} (got {n})"),
        ));
    }
    Ok(())
}

pub(super) fn validate(
    file: TiltShiftFile,
    origin: &str,
    default_name: &str,
) -> Result<TiltShiftStudy, SceneError> {
    let name = file
        .name
        .clone()
        .unwrap_or_else(|| default_name.to_string());
    speckle_scene::validate::name(&name)?;
    positive("wavelength_um", file.wavelength_um)?;
    let mfp = positive("mean_free_path_um", file.mean_free_path_um)?;
    let l = positive("thickness_um", file.thickness_um)?;
    positive("width_um", file.width_um)?;
    if l / mfp > MAX_TILT_SHIFT_OPTICAL_DEPTH {
        return Err(bad(
            "thickness_um",
            format!(
                "gives an optical depth L / l of {:.4e}; at most {MAX_TILT_SHIFT_OPTICAL_DEPTH} \
                 (the model of Eq. 50 is for thin slabs)",
                l / mfp
            ),
        ));
    }
    let g = file.g;
    if !(g.is_finite() && (0.0..0.999).contains(&g)) {
        return Err(bad(
            "g",
            format!("must be in [0, 0.999) (got {})", number(g)),
        ));
    }
    let na = file.numerical_aperture;
    if !(na.is_finite() && na > 0.0 && na <= 1.0) {
        return Err(bad(
            "numerical_aperture",
            format!("must be in (0, 1] (got {})", number(na)),
        ));
    }
    let theta_max = positive("theta_max_mrad", file.theta_max_mrad)? * 1e-3;
    if theta_max > 1.0 {
        return Err(bad(
            "theta_max_mrad",
            format!("must be at most 1000 (got {})", file.theta_max_mrad),
        ));
    }
    let db_max = positive("delta_b_max_um", file.delta_b_max_um)?;
    let tau_max = positive("tau_max_um", file.tau_max_um)?;
    odd_count("n_theta", file.n_theta, MAX_GRID)?;
    odd_count("n_delta_b", file.n_delta_b, MAX_GRID)?;
    if file.n_theta * file.n_delta_b > MAX_GRID {
        return Err(bad(
            "n_delta_b",
            format!(
                "n_theta n_delta_b = {} grid points; at most {MAX_GRID}",
                file.n_theta * file.n_delta_b
            ),
        ));
    }
    if !(2..=MAX_TAU).contains(&file.n_tau) {
        return Err(bad(
            "n_tau",
            format!("must be in 2..={MAX_TAU} (got {})", file.n_tau),
        ));
    }
    let half = file.width_um / 2.0;
    let reach = tau_max + db_max / 2.0;
    let input = (db_max + l * theta_max) / 2.0;
    if reach >= half || input >= half {
        return Err(bad(
            "width_um",
            format!(
                "must exceed twice the largest focus offset, {:.4} um (tau_max_um + \
                 delta_b_max_um / 2 on face b, (delta_b_max_um + L theta_max) / 2 on face a)",
                2.0 * reach.max(input)
            ),
        ));
    }
    check_render(&file.render)?;
    // g = A_3(2 gamma) for the amplitude exp(gamma mu): bisection on 2 gamma.
    let (mut lo, mut hi) = (0.0_f64, 2000.0_f64);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if a3(mid) < g {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(TiltShiftStudy {
        name,
        origin: origin.to_string(),
        theta: symmetric(theta_max, file.n_theta),
        delta_b: symmetric(db_max, file.n_delta_b),
        tau: (0..file.n_tau)
            .map(|m| -tau_max + 2.0 * tau_max * m as f64 / (file.n_tau - 1) as f64)
            .collect(),
        amplitude_gamma: 0.5 * (lo + hi) / 2.0,
        file,
    })
}

/// The correlation of Eq. 50 with the derivation's exponent (see the module documentation):
/// `exp(-(L^3 k^2 / (2 l_tr)) (theta^2/12 + (Delta_b/L - theta/2)^2))`.
pub fn eq50(k: f64, l: f64, l_tr: f64, delta_b: f64, theta: f64) -> f64 {
    let a = delta_b / l - theta / 2.0;
    (-(l.powi(3) * k * k / (2.0 * l_tr)) * (theta * theta / 12.0 + a * a)).exp()
}

/// Eq. 50's exponent as the paper prints it, `(theta/2 + Delta_b/L)^2` in place of
/// `(Delta_b/L - theta/2)^2`.
pub fn eq50_printed(k: f64, l: f64, l_tr: f64, delta_b: f64, theta: f64) -> f64 {
    eq50(k, l, l_tr, delta_b, -theta)
}

/// The centroid `sum Delta_b c^2 / sum c^2` of each row of `c` (`(n_theta, n_delta_b)`), and
/// the least-squares slope through the origin of the centroids against `theta`.
pub fn centroid_slope(theta: &[f64], delta_b: &[f64], c: &[f64]) -> (Vec<f64>, f64) {
    let nd = delta_b.len();
    let centroids: Vec<f64> = (0..theta.len())
        .map(|t| {
            let row = &c[t * nd..(t + 1) * nd];
            let w: f64 = row.iter().map(|v| v * v).sum();
            row.iter().zip(delta_b).map(|(v, d)| v * v * d).sum::<f64>() / w
        })
        .collect();
    let num: f64 = theta.iter().zip(&centroids).map(|(t, c)| t * c).sum();
    let den: f64 = theta.iter().map(|t| t * t).sum();
    (centroids, num / den)
}

impl TiltShiftStudy {
    /// Wavenumber `k = 2 pi / lambda`, per micrometre.
    pub fn k(&self) -> f64 {
        TAU / self.file.wavelength_um
    }

    /// The transport mean free path `l / (1 - g)`, micrometres.
    pub fn transport_mfp(&self) -> f64 {
        self.file.mean_free_path_um / (1.0 - self.file.g)
    }

    /// The phase: a single vMF lobe.
    pub fn phase(&self) -> Result<Phase, EstimatorError> {
        let m = VmfMixture::new(vec![(self.amplitude_gamma, 1.0)]).map_err(|e| {
            EstimatorError::InvalidInput {
                field: "g".into(),
                reason: e.to_string(),
            }
        })?;
        Ok(Phase::Vmf(Arc::new(m)))
    }

    /// The slab: `width_um x width_um x thickness_um` centred on the origin (faces `a` and `b`
    /// at `z = -+L/2`), lossless, of mean free path `mean_free_path_um`.
    pub fn slab(&self) -> Result<HomogeneousBox, EstimatorError> {
        let f = &self.file;
        let medium_error = |e: speckle_medium::MediumError| EstimatorError::InvalidInput {
            field: "width_um".into(),
            reason: e.to_string(),
        };
        let slab = Aabb::centered(
            DVec3::ZERO,
            DVec3::new(f.width_um, f.width_um, f.thickness_um),
        )
        .map_err(medium_error)?;
        HomogeneousBox::new(slab, 1.0 / f.mean_free_path_um, 0.0).map_err(medium_error)
    }

    /// A Gaussian beam of the study's numerical aperture focused at `focus`, its axis tilted by
    /// `tilt` (radians) from +z towards +x.
    pub fn beam(&self, focus: DVec3, tilt: f64) -> Result<GaussianBeam, EstimatorError> {
        Ok(GaussianBeam::with_numerical_aperture(
            "numerical_aperture",
            focus,
            DVec3::new(tilt.sin(), 0.0, tilt.cos()),
            self.file.numerical_aperture,
        )?)
    }

    /// The input shift `Delta_a = Delta_b - L theta` (the Dirac delta of Eq. 50).
    pub fn delta_a(&self, delta_b: f64, theta: f64) -> f64 {
        delta_b - self.file.thickness_um * theta
    }

    /// The scene of one grid point: sources `i1, i2`, sensors `v1_m` (`0..n_tau`) then `v2_m`,
    /// pairs `(i1, v1_m)` then `(i2, v2_m)`.
    pub fn scene(
        &self,
        theta: f64,
        delta_b: f64,
    ) -> Result<Scene<HomogeneousBox, Phase>, EstimatorError> {
        let f = &self.file;
        let l = f.thickness_um;
        let medium = self.slab()?;
        let da = self.delta_a(delta_b, theta);
        let beam = |s: f64| self.beam(DVec3::new(s * da / 2.0, 0.0, -l / 2.0), s * theta / 2.0);
        let sources = vec![
            Source::GaussianBeam(beam(-1.0)?),
            Source::GaussianBeam(beam(1.0)?),
        ];
        let mut sensors = Vec::with_capacity(2 * self.tau.len());
        for s in [-1.0, 1.0] {
            for &t in &self.tau {
                let focus = DVec3::new(t + s * delta_b / 2.0, 0.0, l / 2.0);
                sensors.push(Sensor::GaussianBeam(self.beam(focus, 0.0)?));
            }
        }
        let n = self.tau.len();
        let pairs = (0..2 * n)
            .map(|j| Pair {
                source: j / n,
                sensor: j,
            })
            .collect();
        Ok(Scene::new(
            medium,
            self.phase()?,
            f.wavelength_um,
            sources,
            sensors,
            pairs,
        )?)
    }

    /// Eq. 49 from a covariance matrix of [`Self::scene`]'s pairs.
    pub fn eq49(&self, theta: f64, c: impl Fn(usize, usize) -> Complex64) -> Complex64 {
        let n = self.tau.len();
        let q = self.k() * 2.0 * (theta / 2.0).sin();
        self.tau
            .iter()
            .enumerate()
            .map(|(m, &t)| c(m, n + m) * Complex64::from_polar(1.0, q * t))
            .sum()
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        use speckle_scene::cost::{covariance_seconds, expected_vertices, gaussian_legs};
        let f = &self.file;
        let t = 1.0 / f.mean_free_path_um;
        let taus = [t * f.width_um, t * f.width_um, t * f.thickness_um];
        let v = expected_vertices(&taus, 1.0, f.g, speckle_medium::Dimension::Three, u32::MAX);
        let pairs = 2.0 * self.tau.len() as f64;
        let points = (self.theta.len() * self.delta_b.len()) as f64;
        // Every endpoint is a Gaussian beam of the single vMF lobe.
        let legs = gaussian_legs(pairs + 2.0, 1);
        let seconds = points * covariance_seconds(f.render.paths as f64, v, legs, pairs);
        speckle_scene::cost::Estimate {
            bytes: 16.0 * pairs * pairs * (8.0 + 4.0 * threads as f64) + 1e6,
            memory_field: "n_tau".into(),
            seconds: seconds / threads.max(1) as f64,
            time_field: "render.paths".into(),
            vertices_per_path: 0.0,
        }
    }

    /// Renders every grid point in `render.groups` independent groups (group `i` of point `p`,
    /// row-major over `(theta, Delta_b)`, seeded with `derive_seed(seed, p groups + i)`).
    pub fn render(&self, progress: &dyn Progress) -> Result<TiltShift, StudyError> {
        let start = Instant::now();
        let r = &self.file.render;
        let coherence = r.coherence.coherence();
        let g = r.groups as u64;
        let (nt, nd) = (self.theta.len(), self.delta_b.len());
        // sums[i][p]: group i's estimate at point p, and its paths.
        let mut sums = vec![vec![Complex64::new(0.0, 0.0); nt * nd]; r.groups];
        let mut weights = vec![0.0; r.groups];
        for (t, &theta) in self.theta.iter().enumerate() {
            for (d, &db) in self.delta_b.iter().enumerate() {
                let p = t * nd + d;
                let scene = self.scene(theta, db)?;
                for i in 0..g {
                    let paths = r.paths / g + u64::from(i < r.paths % g);
                    let opts = CovarianceOptions {
                        paths,
                        seed: derive_seed(r.seed, p as u64 * g + i),
                        coherence,
                        sampling: slab_tracer(coherence),
                    };
                    let est = render_covariance(&scene, &opts, progress)?;
                    let v = &est.total.value;
                    sums[i as usize][p] = self.eq49(theta, |a, b| v.get(a, b));
                    weights[i as usize] = paths as f64;
                }
            }
        }
        let origin = (nt / 2) * nd + nd / 2;
        let mean = |skip: Option<usize>| -> Vec<Complex64> {
            let mut m = vec![Complex64::new(0.0, 0.0); nt * nd];
            let mut w = 0.0;
            for (i, s) in sums.iter().enumerate() {
                if Some(i) == skip {
                    continue;
                }
                w += weights[i];
                for (a, b) in m.iter_mut().zip(s) {
                    *a += b * weights[i];
                }
            }
            m.iter().map(|a| a / w).collect()
        };
        // The statistic: |C| / C(0, 0) at every point, then the centroid slope.
        let stat = |skip: Option<usize>| -> Vec<f64> {
            let m = mean(skip);
            let norm = m[origin].re;
            let mut c: Vec<f64> = m.iter().map(|a| a.norm() / norm).collect();
            let (_, slope) = centroid_slope(&self.theta, &self.delta_b, &c);
            c.push(slope);
            c
        };
        let (mut c, mut se) = jackknife(r.groups, stat);
        let slope = c.pop().unwrap_or(f64::NAN);
        let slope_se = se.pop().unwrap_or(f64::NAN);
        let (k, l, ltr) = (self.k(), self.file.thickness_um, self.transport_mfp());
        let grid = |f: fn(f64, f64, f64, f64, f64) -> f64| -> Vec<f64> {
            self.theta
                .iter()
                .flat_map(|&t| self.delta_b.iter().map(move |&d| f(k, l, ltr, d, t)))
                .collect()
        };
        let model = grid(eq50);
        let printed = grid(eq50_printed);
        let (centroids, _) = centroid_slope(&self.theta, &self.delta_b, &c);
        let (model_centroids, model_slope) = centroid_slope(&self.theta, &self.delta_b, &model);
        let (_, printed_slope) = centroid_slope(&self.theta, &self.delta_b, &printed);
        Ok(TiltShift {
            complex: mean(None),
            c,
            se,
            model,
            printed,
            centroids,
            model_centroids,
            slope,
            slope_se,
            model_slope,
            printed_slope,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}

/// The result of a tilt-shift study; grids are `(n_theta, n_delta_b)`, row-major.
#[derive(Debug, Clone)]
pub struct TiltShift {
    /// Eq. 49, the mean over the groups, in the covariance's units.
    pub complex: Vec<Complex64>,
    /// `|C| / C(0, 0)`, Monte Carlo.
    pub c: Vec<f64>,
    /// Its jackknife standard error.
    pub se: Vec<f64>,
    /// Eq. 50 (the derivation's exponent).
    pub model: Vec<f64>,
    /// Eq. 50 as printed.
    pub printed: Vec<f64>,
    /// The Monte Carlo centroid `<Delta_b>` of `|C|^2` per tilt, micrometres.
    pub centroids: Vec<f64>,
    /// The model's centroid per tilt.
    pub model_centroids: Vec<f64>,
    /// `d<Delta_b>/d theta` of the Monte Carlo, micrometres per radian.
    pub slope: f64,
    /// Its jackknife standard error.
    pub slope_se: f64,
    /// The model's slope on the same grid.
    pub model_slope: f64,
    /// The printed model's slope on the same grid.
    pub printed_slope: f64,
    /// Wall time, seconds.
    pub wall: f64,
}

impl TiltShift {
    /// The output arrays (float64, C order).
    pub fn arrays(&self, s: &TiltShiftStudy) -> Vec<super::Array> {
        let shape = vec![s.theta.len(), s.delta_b.len()];
        vec![
            super::Array {
                key: "tilt_shift",
                shape: shape.clone(),
                data: self.c.clone(),
                content: "(n_theta, n_delta_b): |C(Delta_b, theta)| / C(0, 0), Eq. 49, Monte \
                          Carlo",
            },
            super::Array {
                key: "tilt_shift_stderr",
                shape: shape.clone(),
                data: self.se.clone(),
                content: "(n_theta, n_delta_b): its jackknife standard error over render.groups",
            },
            super::Array {
                key: "tilt_shift_complex",
                shape: vec![s.theta.len(), s.delta_b.len(), 2],
                data: self.complex.iter().flat_map(|c| [c.re, c.im]).collect(),
                content: "(n_theta, n_delta_b, 2): Eq. 49 (real, imaginary), the covariance \
                          summed over the camera line",
            },
            super::Array {
                key: "tilt_shift_model",
                shape: shape.clone(),
                data: self.model.clone(),
                content: "(n_theta, n_delta_b): Eq. 50 (Osnabrugge et al. 2017), exp(-(L^3 k^2 \
                          / (2 l_tr)) (theta^2/12 + (Delta_b/L - theta/2)^2))",
            },
            super::Array {
                key: "tilt_shift_model_printed",
                shape,
                data: self.printed.clone(),
                content: "(n_theta, n_delta_b): Eq. 50 as the paper prints it, (theta/2 + \
                          Delta_b/L)^2 in the exponent",
            },
            super::Array {
                key: "tilt_shift_theta_mrad",
                shape: vec![s.theta.len()],
                data: s.theta.iter().map(|t| t * 1e3).collect(),
                content: "(n_theta,): theta, milliradians; beam 2 tilted by +theta/2 towards +x",
            },
            super::Array {
                key: "tilt_shift_delta_b_um",
                shape: vec![s.delta_b.len()],
                data: s.delta_b.clone(),
                content: "(n_delta_b,): Delta_b, micrometres; Delta_a = Delta_b - L theta",
            },
        ]
    }

    /// The figure: `|C|` against `Delta_b` for up to four tilts (0 and positive ones), Monte
    /// Carlo with error bars and Eq. 50.
    pub fn figure(&self, s: &TiltShiftStudy) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let nd = s.delta_b.len();
        let half = s.theta.len() / 2;
        let step = half.div_ceil(3).max(1);
        let rows: Vec<usize> = (half..s.theta.len()).step_by(step).take(4).collect();
        let mut curves = Vec::new();
        for &t in &rows {
            let r = t * nd..(t + 1) * nd;
            curves.push(Curve {
                label: format!("MC, theta = {:.0} mrad", s.theta[t] * 1e3),
                x: s.delta_b.clone(),
                y: self.c[r.clone()].to_vec(),
                err: self.se[r].to_vec(),
            });
        }
        for &t in &rows {
            curves.push(Curve {
                label: format!("Eq. 50, theta = {:.0} mrad", s.theta[t] * 1e3),
                x: s.delta_b.clone(),
                y: self.model[t * nd..(t + 1) * nd].to_vec(),
                err: vec![],
            });
        }
        let f = &s.file;
        Figure {
            title: format!(
                "{}: tilt-shift memory effect (Bar et al. 2020, Fig. 12)",
                s.name
            ),
            subtitle: format!(
                "L = {} um, l = {} um, g = {}, lambda = {} um, NA {}; {} paths per point; slope \
                 d<Delta_b>/d theta: MC {:.2} +- {:.2}, Eq. 50 {:.2} um/rad",
                f.thickness_um,
                f.mean_free_path_um,
                f.g,
                f.wavelength_um,
                f.numerical_aperture,
                f.render.paths,
                self.slope,
                self.slope_se,
                self.model_slope
            ),
            x_label: "output shift Delta_b (um), Delta_a = Delta_b - L theta".into(),
            x_unit: None,
            x_log: false,
            y_label: "|C(Delta_b, theta)| / C(0, 0)".into(),
            curves,
        }
    }

    /// The terminal report.
    pub fn text(&self, s: &TiltShiftStudy) -> String {
        let mut o = String::new();
        let f = &s.file;
        let k = s.k();
        let _ = writeln!(
            o,
            "{}: L = {} um, l = {} um (L / l = {:.3}), g = {}, l_tr = {:.1} um, k^2 L^3 / (2 \
             l_tr) = {:.2}; {:.1} s",
            s.name,
            f.thickness_um,
            f.mean_free_path_um,
            f.thickness_um / f.mean_free_path_um,
            f.g,
            s.transport_mfp(),
            k * k * f.thickness_um.powi(3) / (2.0 * s.transport_mfp()),
            self.wall
        );
        let nd = s.delta_b.len();
        let _ = writeln!(
            o,
            "  {:>12}  {:>14}  {:>14}  {:>12}",
            "theta (mrad)", "<Db> MC (um)", "<Db> Eq.50", "max |C| MC"
        );
        for (t, &theta) in s.theta.iter().enumerate() {
            let row = &self.c[t * nd..(t + 1) * nd];
            let max = row.iter().copied().fold(0.0, f64::max);
            let _ = writeln!(
                o,
                "  {:>12.1}  {:>14.4}  {:>14.4}  {:>12.4}",
                theta * 1e3,
                self.centroids[t],
                self.model_centroids[t],
                max
            );
        }
        let _ = writeln!(
            o,
            "  slope d<Delta_b>/d theta (um/rad): Monte Carlo {:.3} +- {:.3}; Eq. 50 {:.3} \
             (derivation, L/2 = {:.3} on an unbounded grid); Eq. 50 as printed {:.3}",
            self.slope,
            self.slope_se,
            self.model_slope,
            f.thickness_um / 2.0,
            self.printed_slope
        );
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &TiltShiftStudy, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        let coherence = r.coherence.coherence();
        json!({
            "command": "tilt-shift",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "slab_um": [s.file.width_um, s.file.width_um, s.file.thickness_um],
                "phase": format!("single vMF amplitude lobe, gamma = {} (g = A3(2 gamma))",
                                 s.amplitude_gamma),
                "sources": "Gaussian beams focused at (-+Delta_a/2, 0, -L/2), axes tilted by \
                            -+theta/2 from +z towards +x",
                "sensors": "Gaussian-beam pixels focused at (tau_m -+ Delta_b/2, 0, L/2) \
                            viewing along +z",
                "correlation": "sum_m C[(i1, v1_m), (i2, v2_m)] exp(i k 2 sin(theta/2) tau_m)",
                "delta_a": "Delta_b - L theta",
            },
            "render": {
                "paths_per_point": r.paths,
                "groups": r.groups,
                "seed": r.seed,
                "group_seeds": "group i of point p (row-major over theta, Delta_b) renders \
                                with derive_seed(render.seed, p groups + i)",
                "tracer": slab_tracer_json(coherence),
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "slope_um_per_rad": {
                "monte_carlo": self.slope,
                "monte_carlo_stderr": self.slope_se,
                "eq50": self.model_slope,
                "eq50_printed": self.printed_slope,
            },
            "centroids_um": self.centroids,
            "model_centroids_um": self.model_centroids,
            "files": files,
        })
    }
}
