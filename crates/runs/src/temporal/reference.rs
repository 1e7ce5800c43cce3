//! A reference curve `|g1(t)|` read from a CSV file and its comparison with a render
//! (`speckle g1 --reference`).

use super::*;

/// A reference curve `|g1(t)|` to compare a render with (`speckle g1 --reference`), read from
/// a CSV file: lines of comma-separated numbers, an optional header line first (a line whose
/// first field is not a number), `#` comments and blank lines ignored; the **first** column is
/// the lag (in the scene's time unit), the **last** the normalised `|g1|` (`g1(0) = 1`). The
/// authors' MCX curve `validation/data/mcx_dcs_validation/g1_mcx.csv` (`t_seconds,
/// mcx_correlation, g1_normalized`) is one.
#[derive(Debug, Clone, PartialEq)]
pub struct Reference {
    /// The file it was read from (for messages and sidecars).
    pub path: std::path::PathBuf,
    /// The name of its last column (from the header; `"g1"` without one).
    pub column: String,
    /// The lags of its rows.
    pub lags: Vec<f64>,
    /// `|g1|` at those lags.
    pub g1: Vec<f64>,
}

/// The comparison of the first pair's `|g1(t)|` with a [`Reference`] at the scene's lags.
#[derive(Debug, Clone, PartialEq)]
pub struct Comparison {
    /// The reference at each lag of `[motion]`.
    pub reference: Vec<f64>,
    /// The rendered `|g1(t)| = |C(t)| / Re C(0)` of the pooled renders.
    pub g1: Vec<f64>,
    /// Its standard error, the jackknife over the renders (0 at the zero lag, where `|g1| = 1`
    /// exactly).
    pub g1_stderr: Vec<f64>,
    /// `(|g1| - reference) / se` per lag (0 at the zero lag).
    pub deviation: Vec<f64>,
}

impl Comparison {
    /// The lag number of the largest `|deviation|` (the first of equals).
    pub fn worst(&self) -> usize {
        (0..self.deviation.len())
            .reduce(|a, b| {
                if self.deviation[b].abs() > self.deviation[a].abs() {
                    b
                } else {
                    a
                }
            })
            .unwrap_or(0)
    }

    /// The mean `|deviation|` over the lags.
    pub fn mean_abs_deviation(&self) -> f64 {
        self.deviation.iter().map(|d| d.abs()).sum::<f64>() / self.deviation.len().max(1) as f64
    }
}

/// The largest size of a reference file (bytes).
const MAX_REFERENCE_BYTES: u64 = speckle_scene::safe::MAX_TABLE_BYTES;

impl Reference {
    /// Reads a reference curve (a regular file of at most 64 MiB; errors name the file, the
    /// line and what is wrong).
    pub fn read(path: &std::path::Path) -> Result<Self, RunError> {
        let shown = speckle_scene::safe::shown_path(path);
        let text = speckle_scene::safe::read_text("reference", path, &shown, MAX_REFERENCE_BYTES)
            .map_err(|e| {
            let SceneError::InvalidInput { reason, .. } = e;
            RunError::File {
                path: path.into(),
                reason,
            }
        })?;
        Self::parse(&text, path)
    }

    /// Parses the text of a reference file (`path` for messages).
    pub fn parse(text: &str, path: &std::path::Path) -> Result<Self, RunError> {
        use speckle_scene::safe::{excerpt, strip_bom};
        let bad = |line: usize, reason: String| RunError::File {
            path: path.into(),
            reason: format!("reference: line {line}: {reason}"),
        };
        let (mut column, mut width) = (None, None);
        let (mut lags, mut g1) = (Vec::new(), Vec::new());
        for (n, line) in strip_bom(text).lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let first_row = column.is_none() && lags.is_empty();
            if first_row && fields[0].parse::<f64>().is_err() {
                column = Some(fields[fields.len() - 1].to_string());
                continue;
            }
            if fields.len() < 2 {
                return Err(bad(
                    n + 1,
                    format!(
                        "expected the lag and |g1| separated by commas (got `{}`)",
                        excerpt(line)
                    ),
                ));
            }
            if *width.get_or_insert(fields.len()) != fields.len() {
                return Err(bad(
                    n + 1,
                    format!(
                        "{} columns where the first row has {}",
                        fields.len(),
                        width.unwrap_or(0)
                    ),
                ));
            }
            let number = |f: &str| -> Result<f64, RunError> {
                match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    _ => Err(bad(n + 1, format!("not a finite number: `{}`", excerpt(f)))),
                }
            };
            lags.push(number(fields[0])?);
            g1.push(number(fields[fields.len() - 1])?);
        }
        if lags.is_empty() {
            return Err(RunError::File {
                path: path.into(),
                reason: "reference: no rows of numbers".into(),
            });
        }
        Ok(Reference {
            path: path.into(),
            column: column.unwrap_or_else(|| "g1".into()),
            lags,
            g1,
        })
    }

    /// The row of each lag of `p`'s `[motion]` table, checked before any render: one pair (the
    /// curve is compared with it), a zero lag (`g1` needs it), a row at every lag (equal within
    /// `1e-9` of the largest lag) and a normalised reference (`|g1(0)| = 1` within `1e-6`).
    /// Errors name the field or the file.
    pub fn rows(&self, p: &Problem) -> Result<Vec<usize>, RunError> {
        let motion = motion(p)?;
        let bad = |reason: String| RunError::File {
            path: self.path.clone(),
            reason: format!("reference: {reason}"),
        };
        if p.pairs() != 1 {
            return Err(bad(format!(
                "a reference curve is compared with one pair; the scene has {} (choose one \
                 with `pairs`)",
                p.pairs()
            )));
        }
        if !motion.lags.contains(&0.0) {
            return Err(bad(
                "the scene's motion.lags have no 0, so there is no g1 to compare".into(),
            ));
        }
        let scale = motion
            .lags
            .iter()
            .chain(&self.lags)
            .fold(0.0f64, |m, t| m.max(t.abs()));
        let rows = motion
            .lags
            .iter()
            .enumerate()
            .map(|(l, t)| {
                self.lags
                    .iter()
                    .position(|r| (r - t).abs() <= 1e-9 * scale)
                    .ok_or_else(|| {
                        bad(format!(
                            "no row at motion.lags[{l}] = {t} (the reference has {} rows from \
                             {} to {})",
                            self.lags.len(),
                            self.lags[0],
                            self.lags[self.lags.len() - 1]
                        ))
                    })
            })
            .collect::<Result<Vec<usize>, _>>()?;
        let zero = rows[motion.lags.iter().position(|t| *t == 0.0).unwrap_or(0)];
        if (self.g1[zero] - 1.0).abs() > 1e-6 {
            return Err(bad(format!(
                "its last column ({}) is {} at lag 0: it must be the normalised |g1| (1 at \
                 lag 0)",
                speckle_scene::safe::excerpt(&self.column),
                self.g1[zero]
            )));
        }
        Ok(rows)
    }

    /// Compares the renders `r` of `p` with this curve ([`Reference::rows`] says what is
    /// checked): at least 2 renders (an error naming `groups`), `C(0)` of every render and of
    /// their pool positive.
    pub fn compare(&self, p: &Problem, r: &Renders) -> Result<Comparison, RunError> {
        let rows = self.rows(p)?;
        let bad = |reason: String| RunError::File {
            path: self.path.clone(),
            reason: format!("reference: {reason}"),
        };
        let groups = r.renders.len();
        if groups < 2 {
            return Err(RunError::Load(p.in_document(SceneError::InvalidInput {
                field: "groups".into(),
                reason: format!(
                    "the standard error of |g1| needs at least 2 independent renders (got \
                     {groups})"
                ),
            })));
        }
        let t = &r.pooled;
        let nl = t.lags.len();
        let z = t.lags.iter().position(|x| *x == 0.0).unwrap_or(0);
        // Sums over the renders (all of them, or all but one), pair 0.
        let sum = |skip: Option<usize>| -> Vec<Complex64> {
            (0..nl)
                .map(|l| {
                    (0..groups)
                        .filter(|g| Some(*g) != skip)
                        .map(|g| r.renders[g].correlation[l])
                        .sum()
                })
                .collect()
        };
        for skip in std::iter::once(None).chain((0..groups).map(Some)) {
            let c0 = sum(skip)[z].re;
            if c0.is_nan() || c0 <= 0.0 {
                return Err(bad(format!("the render's C(0) = {c0} is not positive")));
            }
        }
        let (g1, se) = speckle_stats::jackknife::jackknife(groups, |skip| {
            let c = sum(skip);
            c.iter().map(|v| v.norm() / c[z].re).collect()
        });
        let reference: Vec<f64> = rows.iter().map(|&row| self.g1[row]).collect();
        let deviation = (0..nl)
            .map(|l| {
                let d = g1[l] - reference[l];
                // At the zero lag both are 1 (the reference within 1e-6, checked by `rows`).
                if l == z || d == 0.0 { 0.0 } else { d / se[l] }
            })
            .collect();
        Ok(Comparison {
            reference,
            g1,
            g1_stderr: se,
            deviation,
        })
    }
}
