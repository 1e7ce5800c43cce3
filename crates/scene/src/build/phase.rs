//! Phase functions: `[phase]` (and each material's `phase`), the CSV amplitude tables that
//! `type = "tabulated"` reads, and the writer of that format.
//!
//! The CSV format: the first line that is neither blank nor a `#` comment is the header,
//! `theta_rad,re,im`, `theta_deg,re,im` or (3D only) `mu,re,im`, with `re_s` and `im_s`
//! accepted for `re` and `im`; then one row per node. Angles cover `[0, pi]` in 3D and the
//! signed scattering angle over `[0, 2 pi]` in flatland. Tables are normalised when read.

use crate::SceneError;
use crate::examples;
use crate::safe::{Files, MAX_TABLE_BYTES, excerpt, strip_bom};
use crate::schema::PhaseSpec;
use crate::validate::invalid;
use speckle_medium::Dimension;
use speckle_phase::{
    Complex64, FlatTabulatedAmplitude, HgMixture, Phase, PhaseError, TabulatedAmplitude, VmfMixture,
};
use std::fmt::Write as _;
use std::sync::Arc;

/// The prefix of `phase.file` that names a table embedded in the binary
/// ([`crate::examples::data`]).
pub const EMBEDDED: &str = "embedded:";

/// The phase function of `p`; `field` names the table (`phase`, `medium.materials[1].phase`),
/// files are read from `files`.
pub fn build_phase(
    p: &PhaseSpec,
    field: &str,
    files: Files<'_>,
    dim: Dimension,
) -> Result<Phase, SceneError> {
    let f = |k: &str| format!("{field}.{k}");
    match p {
        PhaseSpec::Isotropic {} => Ok(Phase::isotropic(dim)),
        PhaseSpec::Hg { g } => {
            if g.is_finite() && g.abs() < 1.0 {
                Phase::hg_in(dim, *g).map_err(|e| invalid(f("g"), e))
            } else {
                Err(invalid(
                    f("g"),
                    format!("must be finite with |g| < 1 (got {g})"),
                ))
            }
        }
        PhaseSpec::Tabulated { file } => {
            let embedded = file.to_str().and_then(|f| f.strip_prefix(EMBEDDED));
            let (text, shown) = match embedded {
                Some(name) => {
                    let text = examples::data(name).ok_or_else(|| {
                        invalid(
                            f("file"),
                            format!(
                                "no embedded table called {name:?}; the embedded tables are: {}",
                                examples::data_names().join(", ")
                            ),
                        )
                    })?;
                    (text.to_string(), file.display().to_string())
                }
                None => files.read_text(&f("file"), file, MAX_TABLE_BYTES)?,
            };
            read_table(&text, &shown, dim, &f("file"), files.access.quote_inputs)
        }
        PhaseSpec::HgMixture { weights, g } => {
            if dim == Dimension::Two {
                return Err(invalid(field, "hg_mixture is a 3D phase function"));
            }
            if weights.len() != g.len() {
                return Err(invalid(
                    f("g"),
                    format!(
                        "needs one g per weight ({} weights, {} g values)",
                        weights.len(),
                        g.len()
                    ),
                ));
            }
            let lobes: Vec<(f64, f64)> = weights.iter().copied().zip(g.iter().copied()).collect();
            let m = HgMixture::new(&lobes).map_err(|e| invalid(field, e))?;
            Ok(Phase::HgMixture(Arc::new(m)))
        }
        PhaseSpec::Vmf { gamma, alpha } => {
            if dim == Dimension::Two {
                return Err(invalid(field, "vmf is a 3D amplitude function"));
            }
            if gamma.len() != alpha.len() {
                return Err(invalid(
                    f("alpha"),
                    format!(
                        "needs one alpha per gamma ({} gamma, {} alpha values)",
                        gamma.len(),
                        alpha.len()
                    ),
                ));
            }
            let lobes = gamma.iter().copied().zip(alpha.iter().copied()).collect();
            let m = VmfMixture::new(lobes).map_err(|e| invalid(field, e))?;
            Ok(Phase::Vmf(Arc::new(m)))
        }
    }
}

/// Reads a CSV amplitude table (the format of the module documentation) into a phase
/// function; `shown` names the table in messages, `field` in the error. With `quote`, a message
/// may quote a short excerpt of the table ([`excerpt`]); without, it gives the line only (a
/// table that a shard file's scene names may be any file: see `crate::safe::Access`).
pub fn read_table(
    text: &str,
    shown: &str,
    dim: Dimension,
    field: &str,
    quote: bool,
) -> Result<Phase, SceneError> {
    parse_table(text, shown, dim, quote).map_err(|reason| invalid(field, reason))
}

/// The table's messages quote its contents only through [`excerpt`], and only with `quote`.
fn parse_table(text: &str, shown: &str, dim: Dimension, quote: bool) -> Result<Phase, String> {
    let excerpt = |t: &str| {
        if quote {
            excerpt(t)
        } else {
            "(contents not shown)".to_string()
        }
    };
    let mut lines = strip_bom(text)
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hl, header) = lines
        .next()
        .ok_or_else(|| format!("{shown} has no header line"))?;
    let cols: Vec<String> = header
        .split(',')
        .map(|c| c.trim().to_ascii_lowercase())
        .collect();
    let abscissa = match cols.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        [
            a @ ("theta_rad" | "theta_deg" | "mu"),
            "re" | "re_s",
            "im" | "im_s",
        ] => a.to_string(),
        _ => {
            let allowed = match dim {
                Dimension::Three => "`theta_rad,re,im`, `theta_deg,re,im` or `mu,re,im`",
                Dimension::Two => "`theta_rad,re,im` or `theta_deg,re,im`",
            };
            return Err(format!(
                "{shown} line {hl}: the header must be {allowed} (`re_s`, `im_s` are accepted \
                 for `re`, `im`; got `{}`)",
                excerpt(header)
            ));
        }
    };
    if dim == Dimension::Two && abscissa == "mu" {
        return Err(format!(
            "{shown} line {hl}: a `mu` column cannot describe a flatland amplitude, which depends \
             on the signed scattering angle (mu = cos theta loses the sign); tabulate \
             `theta_rad` over [0, 2 pi] or `theta_deg` over [0, 360] instead"
        ));
    }
    let (mut x, mut s) = (Vec::new(), Vec::new());
    for (n, line) in lines {
        let v: Vec<&str> = line.split(',').map(str::trim).collect();
        if v.len() != 3 {
            return Err(format!(
                "{shown} line {n}: expected 3 comma-separated numbers (got `{}`)",
                excerpt(line)
            ));
        }
        let mut num = [0.0; 3];
        for (k, t) in v.iter().enumerate() {
            num[k] = t
                .parse::<f64>()
                .ok()
                .filter(|f| f.is_finite())
                .ok_or_else(|| {
                    format!(
                        "{shown} line {n}: `{}` in column {} is not a finite number",
                        excerpt(t),
                        k + 1
                    )
                })?;
        }
        x.push(num[0]);
        s.push(Complex64::new(num[1], num[2]));
    }
    if x.len() < 2 {
        return Err(format!("{shown}: at least two rows are needed"));
    }
    // Tables are normalised, so their scale is free: bring the largest modulus near 1 by a
    // power of two (exact, so the normalised table is bitwise the same), so that |s|^2 of
    // values near the limits of f64 (1e200, 1e-200) neither overflows nor underflows.
    let largest = s
        .iter()
        .map(|c| c.re.abs().max(c.im.abs()))
        .fold(0.0, f64::max);
    if largest > 0.0 && !(1e-100..=1e100).contains(&largest) {
        let scale = (-largest.log2().round()).exp2();
        for c in &mut s {
            *c = Complex64::new(c.re * scale, c.im * scale);
        }
    }
    let wrap = |e: PhaseError| format!("{shown}: {e}");
    if abscissa == "mu" {
        let table = TabulatedAmplitude::new(x, s).map_err(wrap)?;
        return Ok(Phase::Tabulated(Arc::new(table)));
    }
    let scale = if abscissa == "theta_deg" {
        std::f64::consts::PI / 180.0
    } else {
        1.0
    };
    let (max, range) = match dim {
        Dimension::Three => (std::f64::consts::PI, "[0, pi]"),
        Dimension::Two => (std::f64::consts::TAU, "[0, 2 pi]"),
    };
    let theta: Vec<f64> = x.iter().map(|t| t * scale).collect();
    if let Some(i) = theta.iter().position(|t| !(-1e-9..=max + 1e-9).contains(t)) {
        return Err(format!(
            "{shown}: row {} has an angle outside {range} ({} {abscissa})",
            i + 1,
            x[i]
        ));
    }
    Ok(match dim {
        Dimension::Three => Phase::Tabulated(Arc::new(
            TabulatedAmplitude::from_angles(&theta, &s).map_err(wrap)?,
        )),
        Dimension::Two => {
            // Rounding (360 degrees, 2 pi printed to 16 digits) may step just outside the range.
            let theta = theta.iter().map(|t| t.clamp(0.0, max)).collect();
            let table = FlatTabulatedAmplitude::new(theta, s).map_err(wrap)?;
            Phase::FlatTabulated(Arc::new(table))
        }
    })
}

/// Writes `(theta in radians, amplitude)` rows as a CSV table that [`read_table`] reads back
/// exactly (17 significant digits).
pub fn write_table(rows: impl IntoIterator<Item = (f64, Complex64)>) -> String {
    let mut csv = String::from("theta_rad,re,im\n");
    for (t, s) in rows {
        let _ = writeln!(csv, "{t:.17e},{:.17e},{:.17e}", s.re, s.im);
    }
    csv
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_phase::PhaseFunction;

    #[test]
    fn a_written_table_reads_back() {
        let rows: Vec<(f64, Complex64)> = (0..5)
            .map(|j| {
                let t = std::f64::consts::PI * j as f64 / 4.0;
                (t, Complex64::new(1.0 + t.cos(), 0.1 * t))
            })
            .collect();
        let text = write_table(rows);
        assert!(text.starts_with("theta_rad,re,im\n"));
        let p = read_table(&text, "t.csv", Dimension::Three, "phase.file", true).unwrap();
        assert!(p.mean_cosine() > 0.0);
        let e = read_table("x,y\n", "t.csv", Dimension::Three, "phase.file", true).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("phase.file: t.csv line 1: the header"),
            "{e}"
        );
    }
}
