//! `speckle g1`: temporal field correlations of moving scatterers (Bar et al. 2023), `C(t)` and
//! `g1(t) = C(t) / C(0)` of every pair at the lags of `[motion]`, every lag from the same paths.

use super::covariance::{Args, options};
use super::*;
use crate::error;
use speckle::estimators::{Entries, render_correlation};
use speckle::scene::SceneError;
use speckle::scene::npy::{encode_c16, encode_f8};

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    let Some(motion) = p.motion.clone() else {
        return Err(p
            .in_document(SceneError::InvalidInput {
                field: "motion".into(),
                reason: "`speckle g1` needs a [motion] table (diffusion, drift, lags)".into(),
            })
            .into());
    };
    let mut staged = plan(&p, estimate(&p, Command::G1), run)?;
    let opts = options(&p);
    let (est, wall) = run.timed(&p, opts.paths, "paths", error::estimator, |pr| {
        render_correlation(
            &p.scene,
            &motion.model,
            &motion.lags,
            &Entries::Diagonal,
            &opts,
            pr,
        )
    })?;
    let (j, nl) = (p.pairs(), motion.lags.len());
    // (J, L) arrays, pair-major.
    let mut c = vec![Complex64::new(0.0, 0.0); j * nl];
    let mut se = c.clone();
    for e in 0..j {
        for l in 0..nl {
            let (v, s) = est.total(l, e);
            c[e * nl + l] = v;
            se[e * nl + l] = s;
        }
    }
    let n = &p.name;
    let mut files = json!({
        "shape": [j, nl],
        "layout": "complex128 (J, L): [j, l] = pairs[j] at motion.lags[l]; lags: float64 (L,)",
        "content": "correlation: C[j, j](t) = E[u_j(t1) conj(u_j(t1 + t))] - |E u_j|^2; \
                    correlation_stderr: its standard errors (real part: of Re, imaginary: of \
                    Im; batch means over 128 batches); g1: C(t) / C(0), written when a lag is \
                    0; g2 = 1 + beta |g1|^2 (Siegert)",
    });
    let arrays = [
        ("correlation", encode_c16(&[j, nl], &c)),
        ("correlation_stderr", encode_c16(&[j, nl], &se)),
        ("lags", encode_f8(&[nl], &motion.lags)),
    ];
    // g1 = C(t) / C(0) when the zero lag is rendered and C(0) > 0 for every pair.
    if let Some(z) = motion.lags.iter().position(|t| *t == 0.0)
        && (0..j).all(|e| c[e * nl + z].re > 0.0)
    {
        let g1: Vec<Complex64> = (0..j * nl)
            .map(|i| c[i] / c[(i / nl) * nl + z].re)
            .collect();
        stage_arrays(
            &mut staged,
            &mut files,
            n,
            [("g1", encode_c16(&[j, nl], &g1))],
        );
    }
    stage_arrays(&mut staged, &mut files, n, arrays);
    let max_rel = max_relative_error(c.iter().zip(&se).map(|(v, s)| (v.norm(), s.norm())));
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
        opts.paths,
        threads(),
        100.0 * max_rel
    );
    finish(staged)
}
