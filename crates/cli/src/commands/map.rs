//! `speckle map`: the spatio-temporal map of moving scatterers (Bar et al. 2023, Eqs. 36-37,
//! Fig. 7), the correlation `C[0, k](t)` of the first pair with every pair at the lags of
//! `[motion]` (`speckle::runs::temporal::map`), and a PNG of `|C[0, k](t)| / C[0, 0](0)`.

use super::covariance::Args;
use super::*;
use crate::error;
use speckle::runs::temporal;
use speckle::scene::npy::{encode_c16, encode_f8};

/// Smallest width or height of the PNG, in pixels (each map cell is a square of pixels).
const MIN_PNG_SIDE: usize = 256;

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    run.whole_only(&p, "map")?;
    temporal::motion(&p).map_err(error::runs)?;
    let mut staged = plan(&p, estimate(&p, Command::G1), run)?;
    let (m, wall) = run.timed(&p, p.render.paths, "paths", error::runs, |pr| {
        temporal::map(&p, pr)
    })?;
    let (k, nl) = (m.pairs, m.lags.len());
    let n = &p.name;
    let mut files = json!({
        "shape": [k, nl],
        "layout": "(K, L), pair-major: [k, l] = the first pair against pairs[k] at \
                   motion.lags[l]; lags: float64 (L,)",
        "content": "map (complex128): C[0, k](t) = E[u_0(t1) conj(u_k(t1 + t))] - m_0 conj(m_k) \
                    (Bar et al. 2023, Eq. 36 with a line of sensors, Eq. 37 with pairs that \
                    shift source and sensor together); map_stderr: its standard errors (real \
                    part: of Re, imaginary: of Im); map.png: |C[0, k](t)| / C[0, 0](0), one \
                    row per lag (top: the first), one column per pair, white = 1, written when \
                    a lag is 0",
    });
    let arrays = [
        ("map", encode_c16(&[k, nl], &m.correlation)),
        ("map_stderr", encode_c16(&[k, nl], &m.correlation_stderr)),
        ("lags", encode_f8(&[nl], &m.lags)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    if let Some(v) = &m.normalised {
        // Rows are lags, columns pairs: transpose the pair-major table.
        let rows: Vec<f64> = (0..nl)
            .flat_map(|l| (0..k).map(move |c| v[c * nl + l]))
            .collect();
        let scale = MIN_PNG_SIDE.div_ceil(k.min(nl).max(1)).clamp(1, 32);
        let png = format!("{n}.map.png");
        let image = Gray::from_values(k, nl, &rows, 1.0).upscaled(scale);
        staged.add(png.clone(), image.encode_png()?);
        files["png"] = json!(png);
    }
    let max_rel = max_relative_error(
        m.correlation
            .iter()
            .zip(&m.correlation_stderr)
            .take(nl)
            .map(|(v, s)| (v.norm(), s.norm())),
    );
    let summary = json!({
        "lags": nl,
        "pairs": k,
        "max_relative_stderr_first_pair": max_rel,
    });
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("map", render, files, summary);
    stage_sidecar(&mut staged, &p, "map", &meta)?;
    say!(
        "{n}: map of the first pair against K = {k} pairs at {nl} lags from {} paths in \
         {wall:.2} s ({} threads); max relative stderr of C[0, 0](t) {:.2}%",
        m.paths,
        threads(),
        100.0 * max_rel
    );
    finish(staged)
}
