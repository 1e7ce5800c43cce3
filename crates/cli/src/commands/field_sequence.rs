//! `speckle field-sequence`: field realizations of moving scatterers at the times of `[motion]`
//! (Bar et al. 2023, Sec. 5): spatio-temporal transmission matrices (or speckle image sequences)
//! whose covariance is the spatio-temporal covariance of `speckle g1`.

use super::fields::Args;
use super::*;
use crate::error;
use speckle::runs::temporal;
use speckle::scene::SceneError;
use speckle::scene::build::motion::MotionSettings;
use speckle::scene::npy::{encode_c16, encode_f8};

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    let motion = checked_motion(&p, &run, "field-sequence")?;
    let (r, nt) = (p.render.realizations, motion.lags.len());
    // One PNG frame per time of each image that `speckle fields` would write.
    let (images, _) = p.pngs(Command::Fields, r).map_err(in_scene(&p))?;
    let frames = images.saturating_mul(nt);
    if frames > speckle::scene::cost::MAX_PNG_FILES {
        return Err(p
            .in_document(SceneError::InvalidInput {
                field: "output.png_realizations".into(),
                reason: format!(
                    "this would write {frames} PNG frames, more than the limit of {}",
                    speckle::scene::cost::MAX_PNG_FILES
                ),
            })
            .into());
    }
    let staged = plan(&p, estimate(&p, Command::Fields), run)?;
    let (est, wall) = render(&p, &run)?;
    write(&p, staged, &est, &motion.lags, wall)
}

/// The `[motion]` table of a command that renders field sequences (`command` names it in
/// messages), checked by `speckle::runs::temporal::sequence_motion`, and no `--shard`.
pub fn checked_motion(
    p: &Problem,
    run: &RunOptions,
    command: &str,
) -> anyhow::Result<MotionSettings> {
    let motion = temporal::sequence_motion(p).map_err(error::runs)?;
    run.whole_only(p, command)?;
    Ok(motion.clone())
}

/// Renders the field sequence of `p` with progress; returns it and the wall time.
pub fn render(
    p: &Problem,
    run: &RunOptions,
) -> anyhow::Result<(speckle::estimators::FieldSequence, f64)> {
    let total = (p.render.realizations as u64).saturating_mul(p.render.paths_per_realization);
    run.timed(p, total, "paths", error::runs, |pr| {
        temporal::field_sequence(p, pr)
    })
}

fn write(
    p: &Problem,
    mut staged: Staged,
    est: &speckle::estimators::FieldSequence,
    times: &[f64],
    wall: f64,
) -> anyhow::Result<()> {
    let rd = &p.render;
    let (j, rr, nt) = (p.pairs(), rd.realizations, times.len());
    let n = &p.name;
    let shape = [vec![rr, nt], p.pair_shape()].concat();
    let layout = if p.all_pairs {
        "complex128 (R, T, n_sources, n_sensors): [r, l, s, d] = realization r at time \
         motion.lags[l] of pair (source s, sensor d); for a sensor grid, reshape the last axis \
         to (ny, nx)"
    } else {
        "complex128 (R, T, J): [r, l, j] = realization r at time motion.lags[l] of pairs[j]"
    };
    let mut files = json!({
        "field_sequence": format!("{n}.field_sequence.npy"),
        "times": format!("{n}.times.npy"),
        "shape": shape,
        "layout": layout,
        "content": "field sequences of moving scatterers (Bar et al. 2023, Sec. 5): \
                    E[(u_j(t_a) - m_j) conj(u_k(t_b) - m_k)] = C[j, k](t_b - t_a) of `speckle \
                    g1`; frame 0 at time 0 is bitwise `speckle fields` with the same settings",
    });
    staged.add(
        format!("{n}.field_sequence.npy"),
        encode_c16(&shape, est.fields.as_slice()),
    );
    staged.add(format!("{n}.times.npy"), encode_f8(&[nt], times));
    if rd.add_mean {
        staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &est.mean));
        files["mean"] = json!(format!("{n}.mean.npy"));
    }
    // The mean intensity of every frame, over realizations and pairs.
    let frame_intensity: Vec<f64> = (0..nt)
        .map(|l| {
            let s: f64 = (0..rr)
                .flat_map(|q| est.frame(q, l).iter().map(|u| u.norm_sqr()))
                .sum();
            s / (rr * j).max(1) as f64
        })
        .collect();
    if let Some(png) = frames(p, &mut staged, est, nt)? {
        files["png"] = png;
    }
    let render = json!({
        "realizations": rr,
        "paths_per_realization": rd.paths_per_realization,
        "seed": rd.seed,
        "coherence": speckle::scene::build::render::coherence_name(rd.coherence),
        "add_mean": rd.add_mean,
        "threads": threads(),
        "tracer": rd.tracer_json(),
        "wall_time_s": wall,
    });
    let summary = json!({ "frame_mean_intensity": frame_intensity });
    let meta = p.sidecar("field_sequence", render, files, summary);
    stage_sidecar(&mut staged, p, "field_sequence", &meta)?;
    say!(
        "{n}: {rr} field sequences of {nt} times of J = {j} pairs ({} paths each) in {wall:.2} \
         s ({} threads)",
        rd.paths_per_realization,
        threads(),
    );
    finish(staged)
}

/// Stages the intensity frames of the first `output.png_realizations` realizations, when the
/// sensors form an image: `{name}.field_sequence.r{r}.s{s}.t{l}.png`, all times of one
/// (realization, source) on one gray scale (3 times their mean intensity), so that the
/// decorrelation shows. Returns the sidecar's entry.
fn frames(
    p: &Problem,
    staged: &mut Staged,
    est: &speckle::estimators::FieldSequence,
    nt: usize,
) -> anyhow::Result<Option<Value>> {
    let Some(g) = p.png_grid() else {
        return Ok(None);
    };
    let (n, ns, nd) = (&p.name, p.n_sources(), p.n_sensors());
    let mut files = Vec::new();
    for q in 0..p.render.realizations.min(p.output.png_realizations) {
        for s in 0..ns {
            let frame = |l: usize| -> Vec<f64> {
                est.frame(q, l)[s * nd..(s + 1) * nd]
                    .iter()
                    .map(|u| u.norm_sqr())
                    .collect()
            };
            let all: Vec<Vec<f64>> = (0..nt).map(frame).collect();
            let mean = all.iter().flatten().sum::<f64>() / (nt * nd).max(1) as f64;
            for (l, values) in all.iter().enumerate() {
                let name = format!("{n}.field_sequence.r{q}.s{s}.t{l}.png");
                staged.add(name.clone(), grid_png(p, g, values, 3.0 * mean)?);
                files.push(name);
            }
        }
    }
    Ok(Some(json!({
        "files": files,
        "naming": "<name>.field_sequence.r{realization}.s{source}.t{time index}.png, row 0 = \
                   iy 0 (top), column = ix",
        "scale": "gray = min(255, round(255 I / (3 <I>))), I = |u|^2, <I> = mean intensity of \
                  that realization and source over all its times and sensors; pixel replication",
    })))
}
