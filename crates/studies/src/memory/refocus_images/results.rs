//! The results of the images: the measured and predicted statistics of the check pixels, their
//! deviations, and the output arrays, report and sidecar.

use super::plan::{ImageCase, ImagePlan};
use crate::memory::Array;
use crate::memory::refocus::RefocusStudy;
use serde_json::{Value, json};
use speckle_phase::Complex64;
use std::fmt::Write as _;

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
    pub fn arrays(&self, s: &RefocusStudy, plan: &ImagePlan) -> Vec<Array> {
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
            Array {
                key: "refocus_images",
                shape: vec![rr, nc, h, n, 2],
                data: self.amplitude.iter().flat_map(|a| [a.re, a.im]).collect(),
                content: "(realizations, cases, n_rows (y), n_pixels (x), 2): the refocused \
                          amplitude A(x) = sum_m u_x(s_m) conj(u_g(r_m)) exp(-i q tau_m) (real, \
                          imaginary), normalised by |E A(0)| of the check renders",
            },
            Array {
                key: "refocus_images_power",
                shape: vec![rr, nc, h, n],
                data: self.power(),
                content: "(realizations, cases, n_rows (y), n_pixels (x)): |A|^2 / |E A(0)|^2",
            },
            Array {
                key: "refocus_images_mean_power",
                shape: vec![nc, h, n],
                data: self.mean_power(plan),
                content: "(cases, n_rows (y), n_pixels (x)): the mean of |A|^2 / |E A(0)|^2 \
                          over the realizations",
            },
            Array {
                key: "refocus_images_offset_um",
                shape: vec![n],
                data: plan.offsets.clone(),
                content: "(n_pixels,): pixel offset from the target along x (columns), \
                          micrometres",
            },
            Array {
                key: "refocus_images_row_um",
                shape: vec![h],
                data: plan.rows.clone(),
                content: "(n_rows,): row offset from the target along y, micrometres",
            },
            Array {
                key: "refocus_images_delta_um",
                shape: vec![nc],
                data: case_col(|c| c.delta),
                content: "(cases,): focus displacement Delta of each case, micrometres",
            },
            Array {
                key: "refocus_images_theta_mrad",
                shape: vec![nc],
                data: case_col(|c| c.theta * 1e3),
                content: "(cases,): tilt theta of each case, milliradians (0: shift only)",
            },
            Array {
                key: "refocus_images_check_power",
                shape: vec![nc, nk, 2],
                data: flat(&|m, _| [m.power, m.power_se]),
                content: "(cases, check pixels, 2): mean |A|^2 / |E A(0)|^2 over the \
                          realizations and its SE; check pixels: target, +x, -x edges (and +y, -y with rows)",
            },
            Array {
                key: "refocus_images_check_var",
                shape: vec![nc, nk, 2],
                data: flat(&|m, _| [m.var, m.var_se]),
                content: "(cases, check pixels, 2): Var A / |E A(0)|^2 over the realizations \
                          and its SE",
            },
            Array {
                key: "refocus_images_predicted_power",
                shape: vec![nc, nk, 2],
                data: flat(&|_, p| [p.power.0, p.power.1]),
                content: "(cases, check pixels, 2): |E A|^2 + Var A (Isserlis) from the check's \
                          covariance renders, normalised, and its jackknife SE",
            },
            Array {
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
