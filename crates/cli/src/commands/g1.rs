//! `speckle g1`: temporal field correlations of moving scatterers (Bar et al. 2023), `C(t)`,
//! `g1`, `g2` and the speckle contrast `K(T)` of every pair at the lags of `[motion]`, every
//! lag from the same paths (`speckle::runs::temporal`), and a plot of `|g1(t)|`; with
//! `--reference`, the comparison of the one pair's `|g1(t)|` with a reference curve
//! (`speckle::runs::temporal::Reference`).

use super::*;
use crate::error;
use speckle::runs::temporal::{self, Comparison, Reference, Temporal};
use speckle::scene::npy::{encode_c16, encode_f8};
use speckle::studies::curves::{Curve, Figure, MAX_CURVES};

/// Arguments of `g1`.
#[derive(Debug, clap::Args)]
pub struct G1Args {
    #[command(flatten)]
    pub render: covariance::Args,
    /// A reference curve |g1(t)| to compare the scene's one pair with: a CSV file whose first
    /// column is the lag and last column the normalised |g1| (an optional header line; e.g.
    /// validation/data/mcx_dcs_validation/g1_mcx.csv), with a row at every lag of the scene.
    /// The paths are then shared by `--groups` independent renders, pooled, whose jackknife
    /// gives the standard error of |g1|. Writes `<name>.g1_reference.npy`,
    /// `.g1_abs_stderr.npy` and `.g1_deviation.npy` and draws the curve in the plot.
    #[arg(long, value_name = "CSV")]
    pub reference: Option<PathBuf>,
    /// Independent renders (>= 2) for `--reference`, render g from the seed
    /// `derive_seed(seed, g)`.
    #[arg(long, value_name = "G", default_value_t = 16, requires = "reference",
          value_parser = clap::value_parser!(u16).range(2..))]
    pub groups: u16,
}

pub fn run(a: &G1Args) -> anyhow::Result<()> {
    let (p, run) = a.render.load()?;
    run.whole_only(&p, "g1")?;
    temporal::motion(&p).map_err(error::runs)?;
    // The reference is read and checked against the scene before any work.
    let reference = match &a.reference {
        Some(path) => {
            let r = Reference::read(path).map_err(error::runs)?;
            r.rows(&p).map_err(error::runs)?;
            Some(r)
        }
        None => None,
    };
    let groups = if reference.is_some() {
        usize::from(a.groups)
    } else {
        1
    };
    let mut staged = plan(&p, estimate(&p, Command::G1), run)?;
    let (renders, wall) = run.timed(&p, p.render.paths, "paths", error::runs, |pr| {
        temporal::temporal_renders(&p, groups, pr)
    })?;
    let t = &renders.pooled;
    let (j, nl) = (t.pairs, t.lags.len());
    let n = &p.name;
    let mut files = json!({
        "shape": [j, nl],
        "layout": "(J, L), pair-major: [j, l] = pairs[j] at motion.lags[l]; lags: float64 (L,)",
        "content": "correlation (complex128): C[j, j](t) = E[u_j(t1) conj(u_j(t1 + t))] - \
                    |E u_j|^2; correlation_stderr: its standard errors (real part: of Re, \
                    imaginary: of Im; batch means over 128 batches); g1 (complex128): C(t) / \
                    C(0), written when a lag is 0; g2 (float64): 1 + |g1|^2 (Siegert, beta = 1; \
                    g2 - 1 scales with a detector's beta); contrast (float64): the speckle \
                    contrast K(T) of an exposure T equal to each lag (beta = 1, K scales with \
                    sqrt(beta); |g1|^2 interpolated linearly), written when the lags start at \
                    0 and increase",
    });
    let arrays = [
        ("correlation", encode_c16(&[j, nl], &t.correlation)),
        (
            "correlation_stderr",
            encode_c16(&[j, nl], &t.correlation_stderr),
        ),
        ("lags", encode_f8(&[nl], &t.lags)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    if let Some(g1) = &t.g1 {
        stage_arrays(
            &mut staged,
            &mut files,
            n,
            [("g1", encode_c16(&[j, nl], g1))],
        );
    }
    if let Some(g2) = &t.g2 {
        stage_arrays(
            &mut staged,
            &mut files,
            n,
            [("g2", encode_f8(&[j, nl], g2))],
        );
    }
    if let Some(k) = &t.contrast {
        stage_arrays(
            &mut staged,
            &mut files,
            n,
            [("contrast", encode_f8(&[j, nl], k))],
        );
    }
    if let Some(d) = &t.decay_shares {
        let m = d.materials;
        files["decay_share_content"] = json!(
            "detectors: decay_share (float64, (J, M)): material m's share of pair j's initial \
             Brownian decay rate of g1 (the sensitivity to the flow in each layer or material; \
             NaN where nothing decays); decay_share_stderr: its standard error"
        );
        let arrays = [
            ("decay_share", encode_f8(&[j, m], &d.share)),
            ("decay_share_stderr", encode_f8(&[j, m], &d.stderr)),
        ];
        stage_arrays(&mut staged, &mut files, n, arrays);
    }
    let comparison = match &reference {
        Some(r) => Some(r.compare(&p, &renders).map_err(error::runs)?),
        None => None,
    };
    if let Some(c) = &comparison {
        files["reference_content"] = json!(format!(
            "every array is pooled over {groups} independent renders sharing the paths (render \
             g from the seed derive_seed(seed, g)); g1_reference (float64, (L,)): the \
             reference's last column at each lag; g1_abs_stderr (float64, (L,)): the standard \
             error of |g1| = |C(t)| / C(0), the jackknife over the renders (C(t) and C(0) come \
             from the same paths); g1_deviation (float64, (L,)): (|g1| - reference) / \
             g1_abs_stderr (0 at the zero lag)"
        ));
        let arrays = [
            ("g1_reference", encode_f8(&[nl], &c.reference)),
            ("g1_abs_stderr", encode_f8(&[nl], &c.g1_stderr)),
            ("g1_deviation", encode_f8(&[nl], &c.deviation)),
        ];
        stage_arrays(&mut staged, &mut files, n, arrays);
    }
    let svg_file = format!("{n}.g1.svg");
    let plot = figure(&p, t, reference.as_ref().zip(comparison.as_ref()));
    staged.add(svg_file.clone(), plot.svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    if let Some(plot) = g2_figure(&p, t) {
        let g2_file = format!("{n}.g2.svg");
        staged.add(g2_file.clone(), plot.svg()?.into_bytes());
        files["g2_svg"] = json!(g2_file);
    }
    let max_rel = max_relative_error(
        t.correlation
            .iter()
            .zip(&t.correlation_stderr)
            .map(|(v, s)| (v.norm(), s.norm())),
    );
    let mut summary = json!({
        "lags": nl,
        "max_relative_stderr": max_rel,
    });
    if let (Some(r), Some(c)) = (&reference, &comparison) {
        let w = c.worst();
        summary["reference"] = json!({
            "file": r.path.display().to_string(),
            "column": r.column,
            "max_abs_deviation_in_se": c.deviation[w].abs(),
            "max_deviation": c.g1[w] - c.reference[w],
            "max_deviation_stderr": c.g1_stderr[w],
            "max_deviation_lag": t.lags[w],
            "mean_abs_deviation_in_se": c.mean_abs_deviation(),
            "groups": groups,
            "stderr": "jackknife over the independent renders",
        });
    }
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("g1", render, files, summary);
    stage_sidecar(&mut staged, &p, "g1", &meta)?;
    say!(
        "{n}: g1 of J = {j} pairs at {nl} lags from {} paths in {wall:.2} s ({} threads); max \
         relative stderr {:.2}%",
        t.paths,
        threads(),
        100.0 * max_rel
    );
    if let Some(d) = &t.decay_shares {
        let m = d.materials;
        for pair in 0..j {
            let shares: Vec<String> = (0..m)
                .map(|k| {
                    let e = pair * m + k;
                    format!("{:.3} +- {:.3}", d.share[e], d.stderr[e])
                })
                .collect();
            say!(
                "{n}: pair {pair}: share of the initial decay by material: {}",
                shares.join(", ")
            );
        }
    }
    if let Some(c) = &comparison {
        let w = c.worst();
        say!(
            "{n}: against the reference ({groups} renders, jackknife): largest deviation of \
             |g1| {:+.4} (+- {:.4}, {:+.2} standard errors) at t = {:.4e}; mean |deviation| \
             {:.2} standard errors",
            c.g1[w] - c.reference[w],
            c.g1_stderr[w],
            c.deviation[w],
            t.lags[w],
            c.mean_abs_deviation()
        );
    }
    finish(staged)
}

/// `g2(t) = 1 + beta |g1(t)|^2` of the first pairs as DCS users read it (Siegert, `beta = 1`:
/// an instrument's `beta` scales `g2 - 1`), with error bars `2 |g1| se(|g1|)` from those of
/// the `g1` figure; `None` without a zero lag (no `g1`).
fn g2_figure(p: &Problem, t: &Temporal) -> Option<Figure> {
    let g1 = t.g1.as_ref()?;
    let nl = t.lags.len();
    let z = t.lags.iter().position(|x| *x == 0.0)?;
    let curves = (0..t.pairs.min(MAX_CURVES))
        .map(|e| {
            let c0 = t.correlation[e * nl + z].re;
            let g = &g1[e * nl..(e + 1) * nl];
            let se = &t.correlation_stderr[e * nl..(e + 1) * nl];
            Curve {
                label: format!("pair {e}"),
                x: t.lags.clone(),
                y: g.iter().map(|v| 1.0 + v.norm_sqr()).collect(),
                err: g
                    .iter()
                    .zip(se)
                    .map(|(v, s)| 2.0 * v.norm() * s.norm() / c0)
                    .collect(),
            }
        })
        .collect();
    Some(Figure {
        title: format!("{}: intensity correlation g2 (Siegert)", p.name),
        subtitle: format!(
            "g2(t) = 1 + beta |g1(t)|^2 with beta = 1 (a detector's beta scales g2 - 1); {} \
             paths; error bars: 2 |g1| times one standard error of C(t) / C(0)",
            t.paths
        ),
        x_label: "lag t".into(),
        x_unit: Some(super::time_axis(p)),
        x_log: true,
        y_label: "g2(t)".into(),
        curves,
    })
}

/// `|g1(t)|` of the first pairs (or `|C(t)|` when there is no zero lag), with error bars of
/// one standard error of `C(t)` scaled by `1 / C(0)` (the error of `C(0)` is not included);
/// with a reference, the one pair's error bars are the jackknife standard errors of `|g1|`
/// and the reference curve is drawn.
fn figure(p: &Problem, t: &Temporal, reference: Option<(&Reference, &Comparison)>) -> Figure {
    let nl = t.lags.len();
    let zero = t.lags.iter().position(|x| *x == 0.0);
    let (values, scale): (&[Complex64], Vec<f64>) = match (&t.g1, zero) {
        (Some(g), Some(z)) => (
            g,
            t.correlation
                .chunks_exact(nl)
                .map(|c| 1.0 / c[z].re)
                .collect(),
        ),
        _ => (&t.correlation, vec![1.0; t.pairs]),
    };
    let mut curves: Vec<Curve> = (0..t.pairs.min(MAX_CURVES + 1))
        .map(|e| Curve {
            label: format!("pair {e}"),
            x: t.lags.clone(),
            y: values[e * nl..(e + 1) * nl]
                .iter()
                .map(|v| v.norm())
                .collect(),
            err: t.correlation_stderr[e * nl..(e + 1) * nl]
                .iter()
                .map(|s| s.norm() * scale[e])
                .collect(),
        })
        .collect();
    let mut compared = String::new();
    let mut bars = "one standard error of C(t) / C(0)";
    if let Some((r, c)) = reference {
        curves[0].err = c.g1_stderr.clone();
        bars = "one standard error of |g1| (jackknife over the renders)";
        let file = r.path.file_name().map_or_else(
            || r.path.display().to_string(),
            |f| f.to_string_lossy().into(),
        );
        curves.push(Curve {
            label: format!("reference ({file})"),
            x: t.lags.clone(),
            y: c.reference.clone(),
            err: vec![],
        });
        let w = c.worst();
        compared = format!(
            "; largest deviation from the reference {:+.4} ({:+.1} SE)",
            c.g1[w] - c.reference[w],
            c.deviation[w]
        );
    }
    let more = t.pairs.saturating_sub(MAX_CURVES + 1);
    Figure {
        title: format!("{}: temporal field correlation (Bar et al. 2023)", p.name),
        subtitle: format!(
            "{} pairs, {} lags, {} paths; error bars: {bars}{}{}",
            t.pairs,
            nl,
            t.paths,
            if more > 0 {
                format!("; {more} further pairs in the .npy files")
            } else {
                String::new()
            },
            compared
        ),
        x_label: "lag t".into(),
        x_unit: Some(super::time_axis(p)),
        x_log: true,
        y_label: if t.g1.is_some() {
            "|g1(t)|".into()
        } else {
            "|C(t)|".into()
        },
        curves,
    }
}
