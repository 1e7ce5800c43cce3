//! `speckle wave` on a scene with `[motion]`: the exact solution with moving scatterers
//! (`speckle::wave::render_wave_motion`), each configuration moved along sampled trajectories and
//! solved at every lag, and the temporal correlation `C[j, j](t)` of each pair in the layout of
//! `speckle g1`'s `correlation.npy`, so the two compare entry by entry.

use super::*;
use crate::error;
use speckle::scene::npy::encode_c16;
use speckle::wave::{WaveScene, estimate_cost, render_wave_motion};

/// Renders the moving-scatterer solution of `p` (whose `[motion]` is given) and writes it.
pub fn run(p: &Problem, scene: &WaveScene, run: RunOptions) -> anyhow::Result<()> {
    let wave_error = |e| error::wave(e, &p.origin);
    let motion = p.motion.as_ref().expect("the scene has [motion]");
    run.whole_only(p, "wave` with `[motion]")?;
    let lags = &motion.lags;
    // The solver solves each configuration at every lag, from 0 on.
    if lags[0] != 0.0 || lags.windows(2).any(|w| w[1] <= w[0]) {
        return Err(in_scene(p)(speckle::scene::validate::invalid(
            "motion.lags",
            "the wave solver with moving scatterers needs lags that start at 0 and increase \
             strictly (it solves each configuration at every lag)",
        ))
        .into());
    }
    let rr = p.render.configurations;
    let (j, nl) = (p.pairs(), lags.len());
    let cost = estimate_cost(scene, rr, threads()).map_err(wave_error)?;
    let (rf, cols) = (rr as f64, (j * nl) as f64);
    let staged_bytes = 16.0 * (4.0 * (j * nl) as f64);
    let estimate = speckle::scene::cost::Estimate {
        bytes: cost.matrix_bytes + 16.0 * (2.0 * rf * cols + 2.0 * cols * cols) + staged_bytes,
        seconds: cost.seconds * nl as f64,
        ..cost.estimate(staged_bytes)
    };
    let seconds = estimate.seconds;
    let staged = plan(p, Ok(estimate), RunOptions { quiet: true, ..run })?;
    if !run.quiet {
        say!(
            "{}: wave solver with moving scatterers: {rr} configurations of about {:.1} \
             scatterers, each solved at {nl} lags; roughly {}",
            p.name,
            cost.scatterers,
            speckle::scene::cost::human_seconds(seconds)
        );
    }
    let opts = speckle::runs::wave_options(p);
    let (est, wall) = run.timed(p, rr as u64, "configurations", wave_error, |pr| {
        render_wave_motion(scene, &motion.model, lags, &opts, pr)
    })?;
    // C[j, j](t_l): pair j at time 0 against pair j at t_l.
    let mut c = Vec::with_capacity(j * nl);
    let mut se = Vec::with_capacity(j * nl);
    for e in 0..j {
        for l in 0..nl {
            let (v, s) = est.correlation(0, e, l, e);
            c.push(v);
            se.push(s);
        }
    }
    let g1: Vec<_> = (0..j * nl).map(|i| c[i] / c[i - i % nl].re).collect();
    let mut staged = staged;
    let n = &p.name;
    let mut files = json!({
        "layout": "wave_correlation, wave_correlation_stderr, wave_g1: complex128 (J, L), \
                   pair-major: [j, l] = pairs[j] at motion.lags[l], as speckle g1's \
                   correlation.npy; C[j, j](t) = E[u_j(0) conj(u_j(t))] - E[u_j] conj(E[u_j]) \
                   over configurations; stderr: re = standard error of Re C, im = of Im C; \
                   wave_g1 = C(t) / C(0)",
    });
    let arrays = [
        ("wave_correlation", encode_c16(&[j, nl], &c)),
        ("wave_correlation_stderr", encode_c16(&[j, nl], &se)),
        ("wave_g1", encode_c16(&[j, nl], &g1)),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let worst = (0..j)
        .map(|e| se[e * nl].re / c[e * nl].re.abs())
        .fold(0.0f64, f64::max);
    let summary = json!({
        "mean_scatterers": est.mean_scatterers,
        "expected_scatterers": est.expected_scatterers,
        "max_relative_stderr_c0": worst,
    });
    let render = json!({
        "solver": "speckle-wave with moving scatterers: each configuration (a Poisson set of \
                   resonant, lossless, isotropic point scatterers in the box grown by a margin) \
                   moved along trajectories sampled at the lags (drift plus Brownian \
                   increments) and solved exactly (Foldy-Lax, dense LU) at every lag with the \
                   scatterers then inside the box (scatterers that drift out are dropped, those \
                   that drift in are added: docs/conventions.md)",
        "configurations": rr,
        "seed": p.render.seed,
        "streams": "configuration r draws from the counter-based stream (seed, r)",
        "lags": lags,
        "threads": threads(),
        "wall_time_s": wall,
    });
    let meta = p.sidecar("wave", render, files, summary);
    stage_sidecar(&mut staged, p, "wave", &meta)?;
    say!(
        "{n}: exact wave temporal correlation of J = {j} pairs at {nl} lags from {rr} \
         configurations ({:.1} scatterers on average) in {wall:.2} s ({} threads); max relative \
         stderr of C(0) {:.2}%",
        est.mean_scatterers,
        threads(),
        100.0 * worst
    );
    finish(staged)
}
