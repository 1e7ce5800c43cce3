//! `speckle shaping`: dynamic wavefront shaping (Bar et al. 2023, Sec. 8.6, Fig. 10) on the
//! scene's sampled transmission-matrix sequences (`speckle::studies::shaping`): the sources are
//! the modulator's modes, a sensor the target; a phase-only mask is learned over the first
//! frames while the medium moves, then frozen, and the focus is followed against native speckle.

use super::field_sequence::{checked_motion, render};
use super::*;
use speckle::scene::SceneError;
use speckle::scene::npy::encode_f8;
use speckle::studies::curves::{Curve, Figure};
use speckle::studies::shaping::shape;

/// Arguments of `speckle shaping`.
#[derive(Debug, clap::Args)]
pub struct ShapingArgs {
    #[command(flatten)]
    fields: super::fields::Args,
    /// Frames (the first `[motion] lags`, as times) over which the mask is learned.
    #[arg(long, value_name = "L", default_value_t = 1)]
    learn: usize,
    /// The sensor whose field is focused.
    #[arg(long, value_name = "V", default_value_t = 0)]
    target: usize,
}

pub fn run(a: &ShapingArgs) -> anyhow::Result<()> {
    let (p, run) = a.fields.load()?;
    let motion = checked_motion(&p, &run, "shaping")?;
    if !p.all_pairs {
        return Err(p
            .in_document(SceneError::InvalidInput {
                field: "pairs".into(),
                reason: "`speckle shaping` needs every (source, sensor) pair (no `pairs` list): \
                         the sources are the modulator's modes"
                    .into(),
            })
            .into());
    }
    let (ns, nv) = (p.scene.sources().len(), p.scene.sensors().len());
    // Settings are checked before the render.
    let check = |field: &str, ok: bool, reason: String| -> anyhow::Result<()> {
        if ok {
            Ok(())
        } else {
            Err(p
                .in_document(SceneError::InvalidInput {
                    field: field.into(),
                    reason,
                })
                .into())
        }
    };
    check(
        "target",
        a.target < nv,
        format!("sensor {} does not exist ({nv} sensors)", a.target),
    )?;
    check(
        "learn",
        (1..=motion.lags.len()).contains(&a.learn),
        format!(
            "must be between 1 and the number of frames {} (got {})",
            motion.lags.len(),
            a.learn
        ),
    )?;
    check(
        "render.realizations",
        p.render.realizations >= 64,
        format!(
            "shaping needs at least 64 realizations for its standard errors (got {})",
            p.render.realizations
        ),
    )?;
    let mut staged = plan(&p, estimate(&p, Command::Fields), run)?;
    let (seq, wall) = render(&p, &run)?;
    let s = shape(&seq, ns, nv, a.target, a.learn, p.render.seed).map_err(|e| {
        p.in_document(SceneError::InvalidInput {
            field: e.field,
            reason: e.reason,
        })
    })?;
    let (r, nt) = (s.realizations, s.times.len());
    let n = &p.name;
    let mut files = json!({
        "shape": [r, nt],
        "layout": "(R, T): realization r at the recording time times[t] (from the frame where \
                   the mask is frozen, the last learning frame); curves: (T, 2) value and \
                   standard error",
        "content": "shaping_focus: |E_f(t)|^2 at the target with the learned phase-only mask; \
                    shaping_speckle: the same with a random phase mask (native speckle); \
                    shaping_enhancement: <I_f(t)> / <I_s>; shaping_focus_correlation, \
                    shaping_speckle_correlation: |<E(0) conj(E(t))>| / <|E(0)|^2> over \
                    realizations (jackknife errors over 32 groups)",
    });
    let pairs = |v: &[(f64, f64)]| -> Vec<f64> { v.iter().flat_map(|(a, b)| [*a, *b]).collect() };
    let arrays = [
        ("shaping_focus", encode_f8(&[r, nt], &s.focus)),
        ("shaping_speckle", encode_f8(&[r, nt], &s.speckle)),
        ("shaping_times", encode_f8(&[nt], &s.times)),
        (
            "shaping_enhancement",
            encode_f8(&[nt, 2], &pairs(&s.enhancement)),
        ),
        (
            "shaping_focus_correlation",
            encode_f8(&[nt, 2], &pairs(&s.focus_correlation)),
        ),
        (
            "shaping_speckle_correlation",
            encode_f8(&[nt, 2], &pairs(&s.speckle_correlation)),
        ),
    ];
    stage_arrays(&mut staged, &mut files, n, arrays);
    let curve = |label: &str, v: &[(f64, f64)]| Curve {
        label: label.into(),
        x: s.times.clone(),
        y: v.iter().map(|p| p.0).collect(),
        err: v.iter().map(|p| p.1).collect(),
    };
    let figure = Figure {
        title: format!("{n}: dynamic wavefront shaping (Bar et al. 2023, Fig. 10)"),
        subtitle: format!(
            "{} modes, mask learned over {} frames, {} realizations; error bars: one jackknife \
             standard error",
            s.modes, a.learn, r
        ),
        x_label: "time since the mask was frozen".into(),
        x_unit: Some(super::time_axis(&p)),
        x_log: false,
        y_label: "|<E(0) conj(E(t))>| / <|E(0)|^2>".into(),
        curves: vec![
            curve("focus after shaping", &s.focus_correlation),
            curve("native speckle", &s.speckle_correlation),
        ],
    };
    let svg = format!("{n}.shaping.svg");
    staged.add(svg.clone(), figure.svg()?.into_bytes());
    files["svg"] = json!(svg);
    let (eta, _) = s.enhancement[0];
    let summary = json!({
        "modes": s.modes,
        "learn_frames": a.learn,
        "target": a.target,
        "enhancement_at_freeze": eta,
        "focus_correlation_last": s.focus_correlation[nt - 1].0,
        "speckle_correlation_last": s.speckle_correlation[nt - 1].0,
    });
    let render = p.render.paths_json(threads(), wall);
    let meta = p.sidecar("shaping", render, files, summary);
    stage_sidecar(&mut staged, &p, "shaping", &meta)?;
    say!(
        "{n}: {} modes, {r} realizations in {wall:.2} s: enhancement {eta:.2} when the mask is \
         frozen; at t = {}: focus correlation {:.3}, native speckle {:.3}",
        s.modes,
        s.times[nt - 1],
        s.focus_correlation[nt - 1].0,
        s.speckle_correlation[nt - 1].0
    );
    finish(staged)
}
