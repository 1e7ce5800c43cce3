//! `speckle g1`: temporal field correlations of moving scatterers (Bar et al. 2023), `C(t)`,
//! `g1`, `g2` and the speckle contrast `K(T)` of every pair at the lags of `[motion]`, every
//! lag from the same paths (`speckle::runs::temporal`), and a plot of `|g1(t)|`.

use super::covariance::Args;
use super::*;
use crate::error;
use speckle::runs::temporal::{self, Temporal};
use speckle::scene::npy::{encode_c16, encode_f8};
use speckle::studies::curves::{Curve, Figure, MAX_CURVES};

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    temporal::motion(&p).map_err(error::runs)?;
    let mut staged = plan(&p, estimate(&p, Command::G1), run)?;
    let (t, wall) = run.timed(&p, p.render.paths, "paths", error::runs, |pr| {
        temporal::temporal(&p, pr)
    })?;
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
    let svg_file = format!("{n}.g1.svg");
    staged.add(svg_file.clone(), figure(&p, &t).svg()?.into_bytes());
    files["svg"] = json!(svg_file);
    let max_rel = max_relative_error(
        t.correlation
            .iter()
            .zip(&t.correlation_stderr)
            .map(|(v, s)| (v.norm(), s.norm())),
    );
    let summary = json!({
        "lags": nl,
        "max_relative_stderr": max_rel,
    });
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
    finish(staged)
}

/// `|g1(t)|` of the first pairs (or `|C(t)|` when there is no zero lag), with error bars of
/// one standard error of `C(t)` scaled by `1 / C(0)` (the error of `C(0)` is not included).
fn figure(p: &Problem, t: &Temporal) -> Figure {
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
    let curves = (0..t.pairs.min(MAX_CURVES + 1))
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
    let more = t.pairs.saturating_sub(MAX_CURVES + 1);
    Figure {
        title: format!("{}: temporal field correlation (Bar et al. 2023)", p.name),
        subtitle: format!(
            "{} pairs, {} lags, {} paths; error bars: one standard error of C(t) / C(0){}",
            t.pairs,
            nl,
            t.paths,
            if more > 0 {
                format!("; {more} further pairs in the .npy files")
            } else {
                String::new()
            }
        ),
        x_label: "lag t (the scene's time unit)".into(),
        y_label: if t.g1.is_some() {
            "|g1(t)|".into()
        } else {
            "|C(t)|".into()
        },
        curves,
    }
}
