//! The outputs of a sampling study: the arrays, the figure per case, the terminal report and
//! the JSON sidecar of a [`SamplingGain`].

use super::render::{CaseResult, SamplingGain};
use super::study::{SamplingStudy, strategy_name};
use crate::memory::Array;
use serde_json::{Value, json};
use std::fmt::Write as _;

impl SamplingGain {
    /// The output arrays (float64, C order).
    pub fn arrays(&self, s: &SamplingStudy) -> Vec<Array> {
        let shape = vec![s.cases.len(), s.strategies.len(), s.paths.len()];
        let grid = |f: &dyn Fn(&CaseResult) -> &Vec<Vec<f64>>| -> Vec<f64> {
            self.cases
                .iter()
                .flat_map(|c| f(c).iter().flatten().copied().collect::<Vec<_>>())
                .collect()
        };
        vec![
            Array {
                key: "sampling_paths",
                shape: vec![s.paths.len()],
                data: s.paths.iter().map(|&p| p as f64).collect(),
                content: "(steps,): the path counts of the sweep",
            },
            Array {
                key: "sampling_seconds",
                shape: shape.clone(),
                data: grid(&|c| &c.seconds),
                content: "(case, strategy, step): wall time of the render, seconds",
            },
            Array {
                key: "sampling_rmse",
                shape: shape.clone(),
                data: grid(&|c| &c.rmse),
                content: "(case, strategy, step): sqrt(mean |C - R|^2) over the upper triangle \
                          against the case's reference R, over the mean of R's diagonal",
            },
            Array {
                key: "sampling_stderr",
                shape: shape.clone(),
                data: grid(&|c| &c.stderr),
                content: "(case, strategy, step): sqrt(mean(se_re^2 + se_im^2)) over the upper \
                          triangle, on the same scale",
            },
            Array {
                key: "sampling_median_relative_stderr",
                shape,
                data: grid(&|c| &c.median_relative_se),
                content: "(case, strategy, step): the median relative standard error of the \
                          diagonal",
            },
            Array {
                key: "sampling_gain",
                shape: vec![s.cases.len(), s.strategies.len(), 2],
                data: self
                    .cases
                    .iter()
                    .flat_map(|c| c.gains.iter().flat_map(|g| [g.0, g.1]))
                    .collect(),
                content: "(case, strategy, 2): variance x time gain over the first strategy at \
                          the largest path count, (smallest, median) over the diagonal",
            },
        ]
    }

    /// The figure of case `c`: `log10` of the relative RMSE and of the standard error against
    /// `log10` of the time, per strategy.
    pub fn figure(&self, s: &SamplingStudy, c: usize) -> crate::curves::Figure {
        use crate::curves::{Curve, Figure};
        let r = &self.cases[c];
        let mut curves = Vec::new();
        for (what, data) in [("RMSE", &r.rmse), ("SE", &r.stderr)] {
            for (i, &b) in s.strategies.iter().enumerate() {
                curves.push(Curve {
                    label: format!("{} {what}", strategy_name(b)),
                    x: r.seconds[i].iter().map(|t| t.log10()).collect(),
                    y: data[i].iter().map(|e| e.log10()).collect(),
                    err: vec![],
                });
            }
        }
        Figure {
            title: format!(
                "{}: {} (Bar et al. 2020, Figs. 9-10)",
                s.name, s.cases[c].name
            ),
            subtitle: format!(
                "error relative to the mean intensity against a reference of {} paths (its own \
                 SE {:.1e}); paths {:?}",
                s.file.render.reference_paths, r.reference_stderr, s.paths
            ),
            x_label: "log10 wall time (s)".into(),
            x_unit: None,
            x_log: false,
            y_label: "log10 relative error".into(),
            curves,
        }
    }

    /// The terminal report.
    pub fn text(&self, s: &SamplingStudy) -> String {
        let mut o = String::new();
        let _ = writeln!(o, "{}: {:.1} s", s.name, self.wall);
        for (c, r) in self.cases.iter().enumerate() {
            let _ = writeln!(
                o,
                "  {}: reference {} paths ({:.2} s), its SE {:.2e} of the mean intensity",
                s.cases[c].name,
                r.reference.estimate.paths,
                r.reference.seconds,
                r.reference_stderr
            );
            let _ = writeln!(
                o,
                "    {:<24} {:>8} {:>9} {:>10} {:>10} {:>10}",
                "strategy", "paths", "time (s)", "rel. RMSE", "rel. SE", "median SE"
            );
            for (i, &b) in s.strategies.iter().enumerate() {
                for (k, &p) in s.paths.iter().enumerate() {
                    let _ = writeln!(
                        o,
                        "    {:<24} {:>8} {:>9.3} {:>10.3e} {:>10.3e} {:>10.3e}",
                        strategy_name(b),
                        p,
                        r.seconds[i][k],
                        r.rmse[i][k],
                        r.stderr[i][k],
                        r.median_relative_se[i][k]
                    );
                }
            }
            for (i, &b) in s.strategies.iter().enumerate() {
                let _ = writeln!(
                    o,
                    "    {}: variance x time gain over {}: {:.2} (median {:.2}); largest z \
                     against the reference {:.2}",
                    strategy_name(b),
                    strategy_name(s.strategies[0]),
                    r.gains[i].0,
                    r.gains[i].1,
                    r.z[i]
                );
            }
        }
        o
    }

    /// The JSON sidecar.
    pub fn describe(&self, s: &SamplingStudy, files: Value, threads: usize) -> Value {
        let names: Vec<&str> = s.strategies.iter().map(|b| strategy_name(*b)).collect();
        let cases: Vec<Value> = self
            .cases
            .iter()
            .enumerate()
            .map(|(c, r)| {
                json!({
                    "name": s.cases[c].name,
                    "reference_paths": r.reference.estimate.paths,
                    "reference_seconds": r.reference.seconds,
                    "reference_stderr": r.reference_stderr,
                    "mean_intensity": r.scale,
                    "gain_over_first": names.iter().zip(&r.gains).map(|(n, g)| json!({
                        "strategy": n, "smallest": g.0, "median": g.1,
                    })).collect::<Vec<_>>(),
                    "largest_z_against_reference": r.z,
                })
            })
            .collect();
        json!({
            "command": "sampling-gain",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "strategies": names,
            "paths": s.paths,
            "geometry": "per case: sources focused on the entry face at lateral 0 and 1, sensors \
                         on the exit face at 0 and 1, with reflection one on the entry face at 0 \
                         looking back; all pairs, forward and reversed paths",
            "render": {
                "seed": s.file.render.seed,
                "seeds": "render k of strategy s of case c: derive_seed(seed, c (S K + 1) + s K \
                          + k); the case's reference: derive_seed(seed, c (S K + 1) + S K)",
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "cases": cases,
            "files": files,
        })
    }
}
