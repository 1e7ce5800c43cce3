//! `speckle tracking`: separating drift from diffusion by tracking (Bar et al. 2023, Eqs.
//! 38-39, Fig. 9): the temporal correlation of the scene's point source and point sensor in a
//! drifting medium without tracking, with both endpoints shifted by `tU` over each lag, and in
//! the same medium with the drift removed (`speckle::runs::temporal::tracking`); an SVG plot of
//! the three curves and the largest deviation of the tracked curve from the `U = 0` one.

use super::covariance::Args;
use super::*;
use crate::error;
use speckle::runs::temporal::{self, TRACKING_CURVES, Tracking};
use speckle::scene::npy::{encode_c16, encode_f8};
use speckle::studies::curves::{Curve, Figure};

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    temporal::tracking_check(&p).map_err(error::runs)?;
    run.whole_only(&p, "tracking")?;
    let mut staged = plan(&p, estimate(&p, Command::Tracking), run)?;
    let nl = p.motion.as_ref().map_or(0, |m| m.lags.len());
    let total = p.render.paths.saturating_mul(nl as u64 + 2);
    let (t, wall) = run.timed(&p, total, "paths", error::runs, |pr| {
        temporal::tracking(&p, pr)
    })?;
    let n = &p.name;
    let c0 = t.at(2, t.zero_lag()).0.re;
    let normalised = t.normalised();
    let mut files = json!({
        "shape": [3, nl],
        "layout": "(3, L), curve-major: row 0 no tracking, row 1 tracking, row 2 U = 0; \
                   [c, l] at motion.lags[l]; tracking_lags: float64 (L,)",
        "content": "tracking_correlation (complex128): row 0 C[(i, v), (i, v)](t) in the \
                    drifting medium (Eq. 38, bitwise the correlation of `speckle g1`), row 1 \
                    C[(i, v), (i + tU, v + tU)](t) in the drifting medium (Eq. 39), row 2 \
                    C[(i, v), (i, v)](t) with every drift set to 0 (same diffusion); \
                    tracking_correlation_stderr: their standard errors (real part: of Re, \
                    imaginary: of Im); tracking_normalised (float64): |C(t)| / Re C_2(t0), the \
                    U = 0 curve at the smallest lag t0 (0 when the lags include it)",
    });
    let arrays = [
        ("tracking_correlation", encode_c16(&[3, nl], &t.correlation)),
        (
            "tracking_correlation_stderr",
            encode_c16(&[3, nl], &t.correlation_stderr),
        ),
        ("tracking_normalised", encode_f8(&[3, nl], &normalised)),
        ("tracking_lags", encode_f8(&[nl], &t.lags)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let svg = format!("{n}.tracking.svg");
    staged.add(svg.clone(), figure(&p, &t, c0).svg()?.into_bytes());
    files["svg"] = json!(svg);
    let [untracked, tracked, _] = t.max_deviation;
    let summary = json!({
        "lags": nl,
        "drift": t.drift,
        "diffusion": p.motion.as_ref().map(|m| m.model.motions().iter().map(|m| m.diffusion).collect::<Vec<_>>()),
        "max_deviation_tracking_vs_u0_in_combined_se": tracked,
        "max_deviation_no_tracking_vs_u0_in_combined_se": untracked,
        "deviation": "max over lags and over real and imaginary parts of |a - b| / \
                      sqrt(se_a^2 + se_b^2); the renders are independent",
    });
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("tracking", render, files, summary);
    stage_sidecar(&mut staged, &p, "tracking", &meta)?;
    say!(
        "{n}: tracking at {nl} lags from {} paths in {wall:.2} s ({} threads): largest deviation \
         from U = 0 in combined standard errors: tracking {tracked:.2}, no tracking \
         {untracked:.2}",
        t.paths,
        threads(),
    );
    finish(staged)
}

/// `|C(t)| / C_2(t0)` of the three curves (`t0` the smallest lag), with error bars of one
/// standard error of `C(t)` on the same scale (the error of the normalisation not included).
fn figure(p: &Problem, t: &Tracking, c0: f64) -> Figure {
    let nl = t.lags.len();
    let curves = (0..3)
        .map(|c| Curve {
            label: TRACKING_CURVES[c].into(),
            x: t.lags.clone(),
            y: (0..nl).map(|l| t.at(c, l).0.norm() / c0).collect(),
            err: (0..nl).map(|l| t.at(c, l).1.norm() / c0).collect(),
        })
        .collect();
    let [untracked, tracked, _] = t.max_deviation;
    Figure {
        title: format!(
            "{}: tracking the flow (Bar et al. 2023, Eqs. 38-39, Fig. 9)",
            p.name
        ),
        subtitle: format!(
            "U = ({:.3e}, {:.3e}, {:.3e}); {} paths; largest deviation from U = 0: tracking \
             {tracked:.1} SE, no tracking {untracked:.1} SE; error bars: one SE",
            t.drift[0], t.drift[1], t.drift[2], t.paths
        ),
        x_label: "lag t".into(),
        x_unit: Some(super::time_axis(p)),
        x_log: true,
        y_label: "|C(t)| / C(0) at U = 0".into(),
        curves,
    }
}
