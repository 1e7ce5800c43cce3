//! Focusing through a scattering slab by phase conjugation, shifted or shifted and tilted (Bar et
//! al. 2020, Sec. 9.1, Fig. 13 bottom; Osnabrugge et al. 2017): the study of `speckle refocus`,
//! the expected power at the refocused spot against the displacement `Delta`.
//!
//! Procedure (`shared/notes/nearfield-2020.md` Sec. 7.8): a guide star `i` on face `a` of the
//! slab, its field `u_i(v)` measured by a camera on face `b`; sending the conjugate back focuses
//! on `i` (reciprocity: the field the pattern `P(v)` on `b` makes in the mode of a source `x` on
//! `a` is `sum_v u_x(v) P(v)`). To focus at `i + Delta` the pattern is shifted (Eq. 51) or
//! shifted and tilted (Eq. 52). The amplitude in the target mode is
//!
//! ```text
//! A(Delta) = sum_m u_{i2}(tau_m + Delta_b/2) conj(u_{i1}(tau_m - Delta_b/2)) exp(-i k 2 sin(theta/2) tau_m)
//! ```
//!
//! with the geometry of [`super::TiltShiftStudy`]: beams `i1, i2` focused on face `a` at `-+
//! Delta_a / 2`, tilted by `-+theta/2`, the camera a line of Gaussian-beam pixels on face `b`
//! (the ramp removes the tilt between the beams' fields on face `b`, `u_{i2} conj(u_{i1}) ~
//! exp(i k 2 sin(theta/2) x)` for plane waves `exp(i k d.x)`). The focus displacement is
//! `Delta_a = Delta`. Its mean is the complex conjugate of the tilt-shift correlation of Eq. 49,
//! `E A = conj(C(Delta_a, Delta_b, theta))`, a sum of covariance entries; the study works with
//! `C` (the same power). The rendered fields themselves (Fig. 13 top): `refocus_images/`.
//!
//! What is computed: the power of the focus, `|E A|^2`, normalised by its value at `Delta = 0`,
//! where `E A(0) = sum_m E|u_i(tau_m)|^2` is real and positive (the total mean intensity on the
//! camera, so the power there is its square). `E|A|^2 = |E A|^2 + Var A`: the variance is the
//! speckle background around the focus, which grows as the number `N` of independent speckle
//! grains the camera spans while the focus grows as `N^2`; the normalised power of the focus is
//! the paper's "expected power at focus points" in the limit of a large camera (the enhancement
//! of phase conjugation is of order `N`). The background (a fourth moment) is measured on the
//! rendered fields of the `[images]` section (`refocus_images/`), against its Gaussian value.
//!
//! The two variants, for every `Delta` (the shift `Delta_b` of the pattern on face `b` and the
//! tilt `theta` are tied by the Dirac delta of Eq. 50, `Delta_b = Delta_a + L theta`):
//! - shift only (Eq. 51): `theta = 0`, `Delta_b = Delta`;
//! - shift and tilt (Eq. 52): `theta` maximises Eq. 50 (in the derivation's form, see
//!   `tilt_shift.rs`, which the Monte Carlo of Fig. 12 confirmed) at fixed `Delta_a = Delta`:
//!   the exponent `theta^2/12 + (Delta/L + theta/2)^2` is least at `theta = -3 Delta / (2 L)`
//!   ([`optimal_tilt`]), so `Delta_b = -Delta / 2` (the two rays cross at depth `2L/3` from
//!   face `a`), and the exponent falls from `(Delta/L)^2` to `(Delta/L)^2 / 4`: Eq. 50 predicts
//!   twice the scan range.
//!
//! Eq. 52 as printed shifts the pattern by the same `Delta` as the focus; with the delta of Eq.
//! 50 a tilt then moves the focus to `Delta - L theta`. This study keeps the x axis the focus
//! displacement and places the pattern where Eq. 50 puts it.
//!
//! Estimator: as [`super::TiltShiftStudy`] (forward paths, jackknife over `render.groups`
//! independent renders of every point; `Delta = 0` is rendered once and shared by both
//! variants).

use super::refocus_images::{ImagePlan, RefocusImagesFile, validate as validate_images};
use super::study::{StudyOutput, StudyOverrides, StudyRender, parse};
use super::tilt_shift::{TiltShiftFile, TiltShiftStudy, eq50, validate as validate_tilt_shift};
use crate::StudyError;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use speckle_estimators::{CovarianceOptions, EstimatorError, Progress, render_covariance};
use speckle_phase::Complex64;
use speckle_scene::validate::{invalid as bad, positive};
use speckle_scene::{LoadError, SceneError, load};
use speckle_stats::jackknife::jackknife;
use speckle_stats::rng::derive_seed;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// Most displacements `n_delta`.
pub const MAX_REFOCUS_POINTS: usize = 256;

/// A refocusing study file (TOML, unknown keys rejected). Lengths in micrometres.
///
/// ```toml
/// name = "fig13_refocus"          # output prefix (default: the file's stem)
/// wavelength_um = 0.5             # wavelength in the medium
/// mean_free_path_um = 23.0        # l = 1 / sigma_s (lossless)
/// g = 0.98                        # mean cosine of the single-lobe vMF amplitude
/// thickness_um = 20.0             # L
/// width_um = 30.0                 # lateral size of the slab (x and y)
/// numerical_aperture = 0.2        # of the guide star, the target mode and the camera pixels
/// delta_max_um = 2.0              # focus displacements: n_delta values from 0 to max
/// n_delta = 9
/// tau_max_um = 8.0                # camera line: n_tau pixels from -max to +max
/// n_tau = 33
///
/// [render]
/// paths = 20000                   # sub-paths per point, split over the groups
/// seed = 1
/// groups = 8
/// ```
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefocusFile {
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
    /// Largest focus displacement, micrometres.
    pub delta_max_um: f64,
    /// Number of displacements (at least 2; the first is 0).
    pub n_delta: usize,
    /// Half width of the camera line, micrometres.
    pub tau_max_um: f64,
    /// Camera pixels (at least 2).
    pub n_tau: usize,
    /// `[render]`: `paths` per point.
    #[serde(default)]
    pub render: StudyRender,
    /// `[output]`.
    #[serde(default)]
    pub output: StudyOutput,
    /// `[images]`: the rendered refocused fields (optional; see [`super::RefocusImagesFile`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub images: Option<RefocusImagesFile>,
}

/// A validated refocusing study.
#[derive(Debug, Clone)]
pub struct RefocusStudy {
    /// The document as parsed, with the command-line values filled in.
    pub file: RefocusFile,
    /// Output prefix.
    pub name: String,
    /// Where the study came from.
    pub origin: String,
    /// Focus displacements `Delta`, micrometres (the first 0).
    pub delta: Vec<f64>,
    /// The scenes' geometry: a tilt-shift study of the same slab, beams and camera (its own
    /// grids unused).
    pub geometry: TiltShiftStudy,
    /// The validated `[images]`, if any.
    pub images: Option<ImagePlan>,
}

/// The tilt of Eq. 52: the `theta` maximising Eq. 50 (derivation's form) at the focus
/// displacement `Delta_a = delta` on the delta `Delta_b = Delta_a + L theta`: `-3 delta / (2 L)`.
pub fn optimal_tilt(delta: f64, thickness: f64) -> f64 {
    -1.5 * delta / thickness
}

/// Loads and validates a refocusing study file.
pub fn load_refocus_file(
    path: &Path,
    overrides: &StudyOverrides,
) -> Result<RefocusStudy, LoadError> {
    let (text, stem) = load::read_input(path, "study")?;
    load_refocus_str(&text, &path.display().to_string(), &stem, overrides)
}

/// Loads and validates a refocusing study from its text (`origin` names it in errors,
/// `default_name` is the output prefix when the study sets none).
pub fn load_refocus_str(
    text: &str,
    origin: &str,
    default_name: &str,
    overrides: &StudyOverrides,
) -> Result<RefocusStudy, LoadError> {
    let mut file: RefocusFile = parse(text).map_err(|e| e.in_document(origin))?;
    overrides
        .apply(&mut file.render, &mut file.output)
        .map_err(|e| e.in_document(origin))?;
    validate(file, origin, default_name).map_err(|e| LoadError::from(e).in_document(origin))
}

fn validate(
    file: RefocusFile,
    origin: &str,
    default_name: &str,
) -> Result<RefocusStudy, SceneError> {
    let l = positive("thickness_um", file.thickness_um)?;
    let d_max = positive("delta_max_um", file.delta_max_um)?;
    if optimal_tilt(d_max, l).abs() > 1.0 {
        return Err(bad(
            "delta_max_um",
            format!(
                "gives a tilt 3 delta_max_um / (2 L) over 1 rad (got {d_max:.4e} um, L = {l:.4e} \
                 um)"
            ),
        ));
    }
    if !(2..=MAX_REFOCUS_POINTS).contains(&file.n_delta) {
        return Err(bad(
            "n_delta",
            format!("must be in 2..={MAX_REFOCUS_POINTS} (got {})", file.n_delta),
        ));
    }
    let tau_max = positive("tau_max_um", file.tau_max_um)?;
    positive("width_um", file.width_um)?;
    if tau_max + d_max / 2.0 >= file.width_um / 2.0 {
        return Err(bad(
            "width_um",
            format!(
                "must exceed twice the largest focus offset, {:.4} um (tau_max_um + \
                 delta_max_um / 2 on face b)",
                2.0 * tau_max + d_max
            ),
        ));
    }
    // The remaining checks (and the amplitude's concentration) are the tilt-shift study's, on a
    // 3 x 3 grid that needs no more width than the check above.
    let geometry = validate_tilt_shift(
        TiltShiftFile {
            name: Some(
                file.name
                    .clone()
                    .unwrap_or_else(|| default_name.to_string()),
            ),
            wavelength_um: file.wavelength_um,
            mean_free_path_um: file.mean_free_path_um,
            g: file.g,
            thickness_um: file.thickness_um,
            width_um: file.width_um,
            numerical_aperture: file.numerical_aperture,
            theta_max_mrad: 1e-3,
            n_theta: 3,
            delta_b_max_um: d_max,
            n_delta_b: 3,
            tau_max_um: tau_max,
            n_tau: file.n_tau,
            render: file.render.clone(),
            output: file.output.clone(),
        },
        origin,
        default_name,
    )?;
    let n = file.n_delta;
    let images = match &file.images {
        Some(im) => Some(validate_images(im, d_max, file.width_um, l, file.n_tau)?),
        None => None,
    };
    Ok(RefocusStudy {
        name: geometry.name.clone(),
        origin: origin.to_string(),
        delta: (0..n).map(|j| d_max * j as f64 / (n - 1) as f64).collect(),
        geometry,
        images,
        file,
    })
}

impl RefocusStudy {
    /// The tilts of Eq. 52 per displacement, radians.
    pub fn tilts(&self) -> Vec<f64> {
        let l = self.file.thickness_um;
        self.delta.iter().map(|&d| optimal_tilt(d, l)).collect()
    }

    /// Eq. 50's focus power `|C|^2` for both variants with the given tilts (one per
    /// displacement): `exp(-2 K (Delta/L)^2)` (shift only) and, at the tilts of
    /// [`Self::tilts`], `exp(-2 K (Delta/L)^2 / 4)` (shift and tilt), `K = k^2 L^3 / (2 l_tr)`.
    pub fn model(&self, tilts: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let g = &self.geometry;
        let (k, l, ltr) = (g.k(), self.file.thickness_um, g.transport_mfp());
        let shift = self
            .delta
            .iter()
            .map(|&d| eq50(k, l, ltr, d, 0.0).powi(2))
            .collect();
        let tilt = self
            .delta
            .iter()
            .zip(tilts)
            .map(|(&d, &t)| eq50(k, l, ltr, d + l * t, t).powi(2))
            .collect();
        (shift, tilt)
    }

    /// The rough cost on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        let mut e = self.geometry.estimate(threads);
        // The geometry's estimate is for its 3 x 3 grid; this study renders 2 n_delta - 1 points.
        e.seconds *= (2 * self.delta.len() - 1) as f64 / 9.0;
        e.time_field = "render.paths".into();
        e
    }

    /// Renders the points in `render.groups` independent groups: shift only at `Delta_j` is
    /// point `j`, shift and tilt at `Delta_j` (`j >= 1`) point `n_delta + j`; group `i` of point
    /// `p` renders with `derive_seed(seed, p groups + i)`.
    pub fn render(&self, progress: &dyn Progress) -> Result<Refocus, StudyError> {
        self.render_with_tilts(&self.tilts(), progress)
    }

    /// [`Self::render`] with the given tilts (radians, one per displacement) for the second
    /// variant, the pattern shifted by `Delta_b = Delta + L theta`.
    pub fn render_with_tilts(
        &self,
        tilts: &[f64],
        progress: &dyn Progress,
    ) -> Result<Refocus, StudyError> {
        if tilts.len() != self.delta.len() {
            return Err(EstimatorError::InvalidInput {
                field: "tilts".into(),
                reason: format!(
                    "{} tilts for {} displacements",
                    tilts.len(),
                    self.delta.len()
                ),
            }
            .into());
        }
        let start = Instant::now();
        let r = &self.file.render;
        let coherence = r.coherence.coherence();
        let g = r.groups as u64;
        let n = self.delta.len();
        let l = self.file.thickness_um;
        let geo = &self.geometry;
        // sums[i][p]: group i's E A at point p (shift: 0..n, tilt: n..2n).
        let mut sums = vec![vec![Complex64::new(0.0, 0.0); 2 * n]; r.groups];
        let mut weights = vec![0.0; r.groups];
        for p in 0..2 * n {
            if p == n {
                continue; // Delta = 0 of the tilt variant is the shift variant's point 0
            }
            let (theta, delta_b) = if p < n {
                (0.0, self.delta[p])
            } else {
                let t = tilts[p - n];
                (t, self.delta[p - n] + l * t)
            };
            let scene = geo.scene(theta, delta_b)?;
            for i in 0..g {
                let paths = r.paths / g + u64::from(i < r.paths % g);
                let opts = CovarianceOptions {
                    paths,
                    seed: derive_seed(r.seed, p as u64 * g + i),
                    coherence,
                    sampling: super::render::slab_tracer(coherence),
                };
                let est = render_covariance(&scene, &opts, progress)?;
                let v = &est.total.value;
                sums[i as usize][p] = geo.eq49(theta, |a, b| v.get(a, b));
                weights[i as usize] = paths as f64;
            }
        }
        for s in &mut sums {
            s[n] = s[0];
        }
        let mean = |skip: Option<usize>| -> Vec<Complex64> {
            let mut m = vec![Complex64::new(0.0, 0.0); 2 * n];
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
        // The statistic: P_shift (n), P_tilt (n), P_tilt - P_shift (n), Im A(0) / Re A(0).
        let stat = |skip: Option<usize>| -> Vec<f64> {
            let m = mean(skip);
            let norm = m[0].norm_sqr();
            let p: Vec<f64> = m.iter().map(|a| a.norm_sqr() / norm).collect();
            let mut out = p.clone();
            out.extend((0..n).map(|j| p[n + j] - p[j]));
            out.push(m[0].im / m[0].re);
            out
        };
        let (c, se) = jackknife(r.groups, stat);
        let (model_shift, model_tilt) = self.model(tilts);
        Ok(Refocus {
            complex: mean(None),
            shift: c[..n].to_vec(),
            shift_se: se[..n].to_vec(),
            tilt: c[n..2 * n].to_vec(),
            tilt_se: se[n..2 * n].to_vec(),
            gain: c[2 * n..3 * n].to_vec(),
            gain_se: se[2 * n..3 * n].to_vec(),
            im_ratio: c[3 * n],
            im_ratio_se: se[3 * n],
            tilts: tilts.to_vec(),
            model_shift,
            model_tilt,
            wall: start.elapsed().as_secs_f64(),
        })
    }
}

/// The result of a refocusing study; curves are over the displacements.
#[derive(Debug, Clone)]
pub struct Refocus {
    /// `E A` (Eq. 49), shift only then shift and tilt (`2 n_delta`), in the covariance's units.
    pub complex: Vec<Complex64>,
    /// Shift only: `|E A(Delta)|^2 / |E A(0)|^2`, Monte Carlo.
    pub shift: Vec<f64>,
    /// Its jackknife standard error.
    pub shift_se: Vec<f64>,
    /// Shift and tilt, the same normalisation.
    pub tilt: Vec<f64>,
    /// Its jackknife standard error.
    pub tilt_se: Vec<f64>,
    /// `tilt - shift`.
    pub gain: Vec<f64>,
    /// Its jackknife standard error (the variants share the normalisation).
    pub gain_se: Vec<f64>,
    /// `Im E A(0) / Re E A(0)`: zero in expectation (`E A(0)` is a sum of mean intensities).
    pub im_ratio: f64,
    /// Its jackknife standard error.
    pub im_ratio_se: f64,
    /// The tilts of the second variant, radians.
    pub tilts: Vec<f64>,
    /// Eq. 50's shift-only power.
    pub model_shift: Vec<f64>,
    /// Eq. 50's shift-and-tilt power.
    pub model_tilt: Vec<f64>,
    /// Wall time, seconds.
    pub wall: f64,
}

impl Refocus {
    /// The output arrays (float64, C order).
    pub fn arrays(&self, s: &RefocusStudy) -> Vec<super::Array> {
        let n = vec![s.delta.len()];
        let arr = |key, data: &Vec<f64>, content| super::Array {
            key,
            shape: n.clone(),
            data: data.clone(),
            content,
        };
        vec![
            arr(
                "refocus_delta_um",
                &s.delta,
                "(n_delta,): focus displacement Delta = Delta_a on face a, micrometres",
            ),
            arr(
                "refocus_shift",
                &self.shift,
                "(n_delta,): shift only (Eq. 51): focus power |E A(Delta)|^2 / |E A(0)|^2, \
                 Monte Carlo",
            ),
            arr(
                "refocus_shift_stderr",
                &self.shift_se,
                "(n_delta,): its jackknife standard error over render.groups",
            ),
            arr(
                "refocus_tilt",
                &self.tilt,
                "(n_delta,): shift and tilt (Eq. 52, theta = -3 Delta / (2 L), pattern shift \
                 Delta_b = -Delta / 2): focus power, the same normalisation",
            ),
            arr(
                "refocus_tilt_stderr",
                &self.tilt_se,
                "(n_delta,): its jackknife standard error over render.groups",
            ),
            arr(
                "refocus_theta_mrad",
                &self.tilts.iter().map(|t| t * 1e3).collect(),
                "(n_delta,): the tilt of the shift-and-tilt variant, milliradians",
            ),
            arr(
                "refocus_model_shift",
                &self.model_shift,
                "(n_delta,): Eq. 50 squared, shift only: exp(-2 K (Delta/L)^2), K = k^2 L^3 / \
                 (2 l_tr)",
            ),
            arr(
                "refocus_model_tilt",
                &self.model_tilt,
                "(n_delta,): Eq. 50 squared at the optimal tilt: exp(-2 K (Delta/L)^2 / 4)",
            ),
        ]
    }

    /// The figure: both variants with error bars, and Eq. 50.
    pub fn figure(&self, s: &RefocusStudy) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let f = &s.file;
        let curve = |label: &str, y: &[f64], err: &[f64]| Curve {
            label: label.into(),
            x: s.delta.clone(),
            y: y.to_vec(),
            err: err.to_vec(),
        };
        Figure {
            title: format!(
                "{}: refocusing by phase conjugation (Bar et al. 2020, Fig. 13)",
                s.name
            ),
            subtitle: format!(
                "L = {} um, l = {} um, g = {}, lambda = {} um, NA {}; {} paths per point",
                f.thickness_um,
                f.mean_free_path_um,
                f.g,
                f.wavelength_um,
                f.numerical_aperture,
                f.render.paths
            ),
            x_label: "focus displacement Delta (um)".into(),
            x_unit: None,
            x_log: false,
            y_label: "focus power |E A(Delta)|^2 / |E A(0)|^2".into(),
            curves: vec![
                curve("MC, shift only (Eq. 51)", &self.shift, &self.shift_se),
                curve("MC, shift + tilt (Eq. 52)", &self.tilt, &self.tilt_se),
                curve("Eq. 50, shift only", &self.model_shift, &[]),
                curve("Eq. 50, shift + tilt", &self.model_tilt, &[]),
            ],
        }
    }

    /// The terminal report.
    pub fn text(&self, s: &RefocusStudy) -> String {
        let mut o = String::new();
        let f = &s.file;
        let g = &s.geometry;
        let k = g.k();
        let _ = writeln!(
            o,
            "{}: L = {} um, l = {} um (L / l = {:.3}), g = {}, l_tr = {:.1} um, K = k^2 L^3 / (2 \
             l_tr) = {:.2}; {:.1} s; Im A(0) / Re A(0) = {:.2e} +- {:.2e}",
            s.name,
            f.thickness_um,
            f.mean_free_path_um,
            f.thickness_um / f.mean_free_path_um,
            f.g,
            g.transport_mfp(),
            k * k * f.thickness_um.powi(3) / (2.0 * g.transport_mfp()),
            self.wall,
            self.im_ratio,
            self.im_ratio_se
        );
        let _ = writeln!(
            o,
            "  {:>10}  {:>12}  {:>18}  {:>10}  {:>18}  {:>10}",
            "Delta (um)", "theta (mrad)", "shift only MC", "Eq. 50", "shift+tilt MC", "Eq. 50"
        );
        for (j, &d) in s.delta.iter().enumerate() {
            let _ = writeln!(
                o,
                "  {:>10.3}  {:>12.1}  {:>9.4} +- {:<6.4}  {:>10.4}  {:>9.4} +- {:<6.4}  {:>10.4}",
                d,
                self.tilts[j] * 1e3,
                self.shift[j],
                self.shift_se[j],
                self.model_shift[j],
                self.tilt[j],
                self.tilt_se[j],
                self.model_tilt[j]
            );
        }
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &RefocusStudy, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        let coherence = r.coherence.coherence();
        json!({
            "command": "refocus",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "slab_um": [s.file.width_um, s.file.width_um, s.file.thickness_um],
                "phase": format!("single vMF amplitude lobe, gamma = {} (g = A3(2 gamma))",
                                 s.geometry.amplitude_gamma),
                "guide_star_and_target": "Gaussian beams focused at (-+Delta/2, 0, -L/2), axes \
                                          tilted by -+theta/2 from +z towards +x",
                "camera": "Gaussian-beam pixels focused at (tau_m -+ Delta_b/2, 0, L/2) viewing \
                           along +z",
                "focus_amplitude": "E A = sum_m C[(i1, v1_m), (i2, v2_m)] exp(i k 2 \
                                    sin(theta/2) tau_m) (Eq. 49)",
                "power": "|E A(Delta)|^2 / |E A(0)|^2: the focus term; the speckle background \
                          Var A is not rendered",
                "shift_only": "theta = 0, Delta_b = Delta (Eq. 51)",
                "shift_and_tilt": "theta = -3 Delta / (2 L), Delta_b = Delta + L theta = \
                                   -Delta / 2: the maximum of Eq. 50 at fixed Delta_a = Delta \
                                   (Eq. 52)",
            },
            "render": {
                "paths_per_point": r.paths,
                "groups": r.groups,
                "seed": r.seed,
                "group_seeds": "group i of point p (shift only at Delta_j: p = j; shift and tilt: \
                                p = n_delta + j, j >= 1; Delta = 0 shared) renders with \
                                derive_seed(render.seed, p groups + i)",
                "tracer": super::render::slab_tracer_json(coherence),
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "im_over_re_at_zero": [self.im_ratio, self.im_ratio_se],
            "files": files,
        })
    }
}
