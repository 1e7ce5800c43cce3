//! The result's runtime table, summary and outputs.

use super::*;

/// One row of the runtime table.
#[derive(Debug, Clone, Serialize)]
pub struct TableRow {
    /// The method.
    pub method: String,
    /// Paths rendered.
    pub paths: u64,
    /// Wall time per path, microseconds.
    pub time_per_path_us: f64,
    /// The per-path variance summed over the diagonal.
    pub variance_per_path: f64,
    /// The standard error reached, root of the diagonal's summed squares over its number.
    pub stderr_reached: f64,
    /// Seconds to reach the brute force's standard error (`t v / se_far^2`).
    pub seconds_for_equal_stderr: f64,
    /// `(t v)_brute / (t v)` (1 for the brute force).
    pub speedup: f64,
}

impl BruteForce {
    /// The largest deviation over both near-field renders from the apodized brute force, in
    /// combined standard errors (with the Eq. 25 band).
    pub fn z_max(&self) -> f64 {
        self.near
            .iter()
            .map(|n| n.apodized.z_max())
            .fold(0.0, f64::max)
    }

    /// The largest deviation over both near-field renders from the biased reference, in
    /// combined standard errors (no band).
    pub fn z_max_biased(&self) -> f64 {
        self.near
            .iter()
            .map(|n| n.biased.z_max())
            .fold(0.0, f64::max)
    }

    /// The binary over the apodized brute force on diagonal entry `a`, from the paired
    /// difference (`1 + (binary - apodized) / apodized`, the same paths).
    pub fn binary_over_apodized(&self, a: usize) -> f64 {
        let e = a * J + a;
        1.0 + self.binary_minus_apodized.mean[e].re / self.brute.mean[e].re
    }

    /// Hermitian updates per vertex of the literal Eq. 11, `Q P (Q P + 1) / 2`.
    pub fn literal_updates(&self) -> f64 {
        let qp = (self.q * self.p) as f64;
        qp * (qp + 1.0) / 2.0
    }

    /// The runtime table: both near-field renders and the brute force, for the brute force's
    /// standard error.
    pub fn table(&self) -> Vec<TableRow> {
        let n = self.brute.paths as f64;
        let target = self.brute_variance / n;
        let far = self.brute_time_per_path * self.brute_variance;
        let mut rows: Vec<TableRow> = self
            .near
            .iter()
            .map(|r| TableRow {
                method: format!("near field, {}", r.label),
                paths: r.estimate.paths,
                time_per_path_us: r.time_per_path * 1e6,
                variance_per_path: r.variance,
                stderr_reached: (r.variance / r.estimate.paths as f64 / J as f64).sqrt(),
                seconds_for_equal_stderr: r.time_per_path * r.variance / target,
                speedup: far / (r.time_per_path * r.variance),
            })
            .collect();
        rows.push(TableRow {
            method: "brute force (Eqs. 9-11, per path)".into(),
            paths: self.brute.paths,
            time_per_path_us: self.brute_time_per_path * 1e6,
            variance_per_path: self.brute_variance,
            stderr_reached: (target / J as f64).sqrt(),
            seconds_for_equal_stderr: self.brute_time_per_path * n,
            speedup: 1.0,
        });
        rows
    }

    /// The output arrays (float64, C order); entries `a = 3 i + v` (source `i`, sensor `v`).
    pub fn arrays(&self) -> Vec<Array> {
        let nr = self.near.len();
        let flat = |m: &dyn Fn(usize) -> Complex64| -> Vec<f64> {
            (0..J * J).flat_map(|e| [m(e).re, m(e).im]).collect()
        };
        let near_part = |se: bool| -> Vec<f64> {
            self.near
                .iter()
                .flat_map(|r| {
                    flat(&|e| {
                        let (v, s) = r.estimate.total.get(e / J, e % J);
                        if se { s } else { v }
                    })
                })
                .collect()
        };
        let z = |c: fn(&NearRender) -> &Comparison| -> Vec<f64> {
            self.near.iter().flat_map(|r| c(r).z.clone()).collect()
        };
        let pair = |key: &'static str,
                    key_se: &'static str,
                    e: &Estimate,
                    content: &'static str|
         -> [Array; 2] {
            [
                Array {
                    key,
                    shape: vec![J, J, 2],
                    data: flat(&|i| e.mean[i]),
                    content,
                },
                Array {
                    key: key_se,
                    shape: vec![J, J, 2],
                    data: flat(&|i| e.se[i]),
                    content: "(6, 6, 2): its standard errors",
                },
            ]
        };
        let mut arrays = vec![
            Array {
                key: "bruteforce_near",
                shape: vec![nr, J, J, 2],
                data: near_part(false),
                content: "(render, 6, 6, 2): the near-field covariance (real, imaginary) of \
                          entries 3 i + v; render 0 with importance sampling around the beams, \
                          1 uniform",
            },
            Array {
                key: "bruteforce_near_stderr",
                shape: vec![nr, J, J, 2],
                data: near_part(true),
                content: "(render, 6, 6, 2): their standard errors",
            },
            Array {
                key: "bruteforce_z",
                shape: vec![nr, J, J],
                data: z(|r| &r.apodized),
                content: "(render, 6, 6): |near - brute| / (combined SE + Eq. 25 model error / \
                          4), the larger of the real and imaginary parts (real on the diagonal)",
            },
            Array {
                key: "bruteforce_z_binary",
                shape: vec![nr, J, J],
                data: z(|r| &r.binary),
                content: "(render, 6, 6): |near - binary brute force| / combined SE, the larger \
                          of the real and imaginary parts (real on the diagonal)",
            },
            Array {
                key: "bruteforce_z_biased",
                shape: vec![nr, J, J],
                data: z(|r| &r.biased),
                content: "(render, 6, 6): |near - biased reference| / combined SE, the larger \
                          of the real and imaginary parts (real on the diagonal)",
            },
        ];
        arrays.extend(pair(
            "bruteforce_far",
            "bruteforce_far_stderr",
            &self.brute,
            "(6, 6, 2): the brute-force aperture integral of far-field paths (Eqs. 9-11) with \
             apodized (vMF) apertures, same entries",
        ));
        arrays.extend(pair(
            "bruteforce_far_binary",
            "bruteforce_far_binary_stderr",
            &self.binary,
            "(6, 6, 2): the same brute force (the same paths) with binary apertures of matched \
             width",
        ));
        arrays.extend(pair(
            "bruteforce_far_biased",
            "bruteforce_far_biased_stderr",
            &self.biased,
            "(6, 6, 2): the biased reference: the apodized brute force with every plane wave \
             attenuated along its aperture's axis (Eq. 25), the first render.biased_paths paths",
        ));
        arrays.extend(pair(
            "bruteforce_binary_minus_apodized",
            "bruteforce_binary_minus_apodized_stderr",
            &self.binary_minus_apodized,
            "(6, 6, 2): binary minus apodized brute force, path by path (paired standard errors)",
        ));
        arrays.extend(pair(
            "bruteforce_biased_minus_apodized",
            "bruteforce_biased_minus_apodized_stderr",
            &self.biased_minus_apodized,
            "(6, 6, 2): biased reference minus apodized brute force, path by path over the \
             biased reference's paths (paired standard errors)",
        ));
        arrays
    }

    /// The figure: the real parts of the upper triangle's entries, near field (both renders)
    /// and the three brute forces with error bars, against the entry's number.
    pub fn figure(&self, s: &BruteForceStudy) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let entries: Vec<(usize, usize)> =
            (0..J).flat_map(|a| (a..J).map(move |b| (a, b))).collect();
        let x: Vec<f64> = (0..entries.len()).map(|i| i as f64).collect();
        let curve = |label: String, e: &Estimate| Curve {
            label,
            x: x.clone(),
            y: entries.iter().map(|&(a, b)| e.mean[a * J + b].re).collect(),
            err: entries.iter().map(|&(a, b)| e.se[a * J + b].re).collect(),
        };
        let mut curves = vec![
            curve("brute force, apodized (Eqs. 9-11)".into(), &self.brute),
            curve(
                format!(
                    "brute force, binary aperture (half-width {:.3} rad)",
                    self.binary_half_width
                ),
                &self.binary,
            ),
            curve(
                "brute force, axial attenuation (biased reference)".into(),
                &self.biased,
            ),
        ];
        for r in &self.near {
            curves.push(Curve {
                label: format!("near field, {}", r.label),
                x: x.clone(),
                y: entries
                    .iter()
                    .map(|&(a, b)| r.estimate.total.get(a, b).0.re)
                    .collect(),
                err: entries
                    .iter()
                    .map(|&(a, b)| r.estimate.total.get(a, b).1.re)
                    .collect(),
            });
        }
        let f = &s.file;
        Figure {
            title: format!(
                "{}: near field vs brute-force aperture integral (Bar et al. 2020, Fig. 7)",
                s.name
            ),
            subtitle: format!(
                "flatland {} x {}, mfp {}, gamma {}; Q = {}, P = {} plane waves; largest \
                 deviation {:.2} SE (apodized), {:.2} SE (biased reference); entries (a, b), \
                 a <= b, row-major",
                f.size[0],
                f.size[1],
                f.mean_free_path,
                f.concentration,
                self.q,
                self.p,
                self.z_max(),
                self.z_max_biased()
            ),
            x_label: "entry (a, b) of the upper triangle, a = 3 source + sensor".into(),
            x_unit: None,
            x_log: false,
            y_label: "Re C[a, b]".into(),
            curves,
        }
    }

    /// The terminal report: every entry, the table and the update counts.
    pub fn text(&self, s: &BruteForceStudy) -> String {
        let mut o = String::new();
        let (b, br, bi) = (&self.brute, &self.binary, &self.biased);
        let _ = writeln!(
            o,
            "{}: quadrature of the beam field off by {:.2e} (apodized), {:.2e} (binary, \
             half-width {:.4} rad, NA {:.4}); Q = {} source and P = {} sensor plane waves; {} \
             brute-force paths in {:.1} s, {} of them with axial attenuation in {:.1} s; {:.1} \
             s in all",
            s.name,
            self.quadrature_error.apodized,
            self.quadrature_error.binary,
            self.binary_half_width,
            self.binary_half_width.sin(),
            self.q,
            self.p,
            b.paths,
            self.brute_seconds,
            bi.paths,
            self.biased_seconds,
            self.wall
        );
        for r in &self.near {
            for a in 0..J {
                for c in 0..J {
                    let (vn, sn) = r.estimate.total.get(a, c);
                    let e = a * J + c;
                    let _ = writeln!(
                        o,
                        "  {}: C[{a}, {c}]: near {vn:.4e} +- {sn:.1e}, brute force {:.4e} +- \
                         {:.1e}, z {:.2}",
                        r.label, b.mean[e], b.se[e], r.apodized.z[e]
                    );
                }
            }
        }
        let (zb, zc) = (
            self.binary_minus_apodized.z(),
            self.biased_minus_apodized.z(),
        );
        for a in 0..J {
            for c in 0..J {
                let e = a * J + c;
                let d = &self.binary_minus_apodized;
                let _ = writeln!(
                    o,
                    "  C[{a}, {c}]: binary {:.4e} +- {:.1e} (binary - apodized {:.2e} +- {:.1e}, \
                     z {:.2}; near - binary z {:.2}, {:.2}); biased {:.4e} +- {:.1e} (z {:.2} \
                     from the apodized, paired; near - biased z {:.2}, {:.2})",
                    br.mean[e],
                    br.se[e],
                    d.mean[e],
                    d.se[e],
                    zb[e],
                    self.near[0].binary.z[e],
                    self.near[1].binary.z[e],
                    bi.mean[e],
                    bi.se[e],
                    zc[e],
                    self.near[0].biased.z[e],
                    self.near[1].biased.z[e],
                );
            }
        }
        for (a, ss) in self.single_scattering_ratio.iter().enumerate() {
            let _ = writeln!(
                o,
                "  C[{a}, {a}]: binary / apodized {:.3} (single scattering predicts {ss:.3})",
                self.binary_over_apodized(a)
            );
        }
        let _ = writeln!(
            o,
            "  {:<36} {:>8} {:>10} {:>11} {:>10} {:>12} {:>8}",
            "method", "paths", "us/path", "var/path", "SE", "s for eq. SE", "speed-up"
        );
        for t in self.table() {
            let _ = writeln!(
                o,
                "  {:<36} {:>8} {:>10.2} {:>11.3e} {:>10.3e} {:>12.3} {:>7.1}x",
                t.method,
                t.paths,
                t.time_per_path_us,
                t.variance_per_path,
                t.stderr_reached,
                t.seconds_for_equal_stderr,
                t.speedup
            );
        }
        let _ = writeln!(
            o,
            "  (the brute force's time per path is that of a render of many paths per \
             realization; as run here, one path per realization and contracted per path: {:.1} \
             us)",
            self.brute_seconds / b.paths as f64 * 1e6
        );
        let qp = (self.q * self.p) as f64;
        let _ = writeln!(
            o,
            "  updates per vertex: the literal Eq. 11 {:.3e} (Q P (Q P + 1) / 2), the per-path \
             quadrature here {qp} (Q P), the closed forms {} (J (J + 1) / 2): literal / \
             per-path {:.0}x",
            self.literal_updates(),
            J * (J + 1) / 2,
            self.literal_updates() / qp
        );
        let _ = writeln!(
            o,
            "  RMSE over the upper triangle, relative to the reference's mean intensity \
             (standard errors alone in brackets):"
        );
        for r in &self.near {
            for (what, c) in [
                ("apodized brute force", &r.apodized),
                ("biased reference", &r.biased),
                ("binary brute force", &r.binary),
            ] {
                let _ = writeln!(
                    o,
                    "    near field, {}, against the {what}: {:.2e} ({:.2e})",
                    r.label, c.rmse, c.rmse_expected
                );
            }
        }
        let scale = b.mean_intensity();
        for (what, d) in [
            ("binary - apodized brute force", &self.binary_minus_apodized),
            (
                "biased reference - apodized brute force",
                &self.biased_minus_apodized,
            ),
        ] {
            let (rmse, expected) = d.rmse(scale);
            let _ = writeln!(
                o,
                "    {what} (paired): {rmse:.2e} ({expected:.2e}), largest {:.2} paired SE",
                d.z().into_iter().fold(0.0, f64::max)
            );
        }
        let _ = writeln!(
            o,
            "  largest deviation {:.2} combined SE (apodized, with the Eq. 25 band), {:.2} \
             (biased reference, no band)",
            self.z_max(),
            self.z_max_biased()
        );
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &BruteForceStudy, files: Value, threads: usize) -> Value {
        let r = &s.file.render;
        let qp = (self.q * self.p) as f64;
        let scale = self.brute.mean_intensity();
        let paired = |d: &Estimate| {
            let (rmse, expected) = d.rmse(scale);
            json!({
                "rmse": rmse,
                "rmse_from_standard_errors": expected,
                "largest_deviation_paired_se": d.z().into_iter().fold(0.0, f64::max),
                "scale": "the apodized brute force's mean intensity",
            })
        };
        json!({
            "command": "bruteforce",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "geometry": {
                "dimension": 2,
                "phase": "isotropic",
                "sources": "Gaussian beams focused at (0, focus_depth) and (source_offset, \
                            focus_depth) along +y",
                "sensors": "Gaussian beams focused at (sensor_shift, focus_depth) and \
                            (sensor_shift + source_offset, focus_depth) along +y, and at \
                            (0, focus_depth) looking along -y (reflection)",
                "entries": "a = 3 source + sensor (all pairs, source-major)",
            },
            "quadrature_error": {
                "apodized": self.quadrature_error.apodized,
                "binary": self.quadrature_error.binary,
            },
            "binary_aperture": {
                "half_width_rad": self.binary_half_width,
                "numerical_aperture": self.binary_half_width.sin(),
                "rule": "the indicator of |t| <= a in the angle t from the axis, normalised \
                         to unit integral like the apodized mask (focal field 1 in free \
                         space), with the apodized mask's second moment of sin t",
            },
            "plane_waves": {"source": self.q, "sensor": self.p},
            "render": {
                "near_paths": r.near_paths,
                "near_seed": r.seed,
                "brute_force_paths": r.paths,
                "biased_reference_paths": self.biased.paths,
                "brute_force_chunk_seeds": format!(
                    "chunk c of {} realizations renders with {} + c",
                    r.chunk,
                    s.chunk_seed(0)
                ),
                "threads": threads,
                "wall_time_s": self.wall,
                "brute_force_time_s": self.brute_seconds,
                "biased_reference_time_s": self.biased_seconds,
                "brute_force_time_per_path_as_run_us":
                    self.brute_seconds / self.brute.paths as f64 * 1e6,
            },
            "largest_deviation_se": self.z_max(),
            "largest_deviation_from_biased_reference_se": self.z_max_biased(),
            "rmse_against_brute_force": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.apodized.rmse,
                "rmse_from_standard_errors": r.apodized.rmse_expected,
                "scale": "the brute force's mean intensity (mean of its diagonal)",
            })).collect::<Vec<_>>(),
            "rmse_against_biased_reference": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.biased.rmse,
                "rmse_from_standard_errors": r.biased.rmse_expected,
                "largest_deviation_se": r.biased.z_max(),
                "scale": "the biased reference's mean intensity",
            })).collect::<Vec<_>>(),
            "rmse_against_binary_brute_force": self.near.iter().map(|r| json!({
                "render": r.label,
                "rmse": r.binary.rmse,
                "rmse_from_standard_errors": r.binary.rmse_expected,
                "largest_deviation_se": r.binary.z_max(),
                "scale": "the binary brute force's mean intensity",
            })).collect::<Vec<_>>(),
            "binary_minus_apodized": paired(&self.binary_minus_apodized),
            "binary_over_apodized_diagonal": (0..J).map(|a| json!({
                "entry": a,
                "measured": self.binary_over_apodized(a),
                "single_scattering": self.single_scattering_ratio[a],
            })).collect::<Vec<_>>(),
            "biased_minus_apodized": paired(&self.biased_minus_apodized),
            "table": serde_json::to_value(self.table()).unwrap_or(Value::Null),
            "updates_per_vertex": {
                "literal_eq11": self.literal_updates(),
                "per_path_quadrature": qp,
                "closed_forms": J * (J + 1) / 2,
                "literal_over_per_path": self.literal_updates() / qp,
            },
            "files": files,
        })
    }
}
