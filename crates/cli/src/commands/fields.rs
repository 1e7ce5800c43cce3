//! `speckle fields`: field realizations (Alg. 2), with intensity images of sensor grids.

use super::*;
use crate::error;
use speckle::estimators::{FieldEstimate, render_fields};
use speckle::scene::npy::encode_c16;

/// Arguments of `fields` and `field-sequence`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(flatten)]
    common: Common,
    /// Number of realizations (replaces `render.realizations`).
    #[arg(long, value_name = "R")]
    realizations: Option<usize>,
    /// Sub-paths per realization (replaces `render.paths_per_realization`).
    #[arg(long, value_name = "N")]
    paths_per_realization: Option<u64>,
    /// Forward paths only (`render.coherence = "forward_only"`).
    #[arg(long)]
    forward_only: bool,
    /// Do not add the speckle mean (`render.add_mean = false`).
    #[arg(long)]
    no_mean: bool,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
    /// PNGs (frames) for the first this many realizations (replaces
    /// `output.png_realizations`).
    #[arg(long, value_name = "K")]
    png_realizations: Option<usize>,
}

impl Args {
    /// The problem with these options applied (also `speckle field-sequence`'s).
    pub fn load(&self) -> anyhow::Result<(Problem, RunOptions)> {
        self.common.load(Overrides {
            realizations: self.realizations,
            paths_per_realization: self.paths_per_realization,
            forward_only: self.forward_only,
            no_mean: self.no_mean,
            no_png: self.no_png,
            png_realizations: self.png_realizations,
            ..Overrides::default()
        })
    }
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let (p, run) = a.load()?;
    render(&p, run)
}

/// Renders and writes field realizations of `p`.
pub fn render(p: &Problem, run: RunOptions) -> anyhow::Result<()> {
    p.field_rows_size(p.render.realizations, "render.realizations")
        .map_err(in_scene(p))?;
    let staged = plan_render(p, Kind::Fields, run)?;
    if let Some(s) = run.shard {
        return shard(p, Kind::Fields, s, run, staged);
    }
    let opts = speckle::runs::field_options(p);
    let (total, _) = work(p, Kind::Fields, None);
    let (est, wall) = run.timed(p, total, "paths", error::estimator, |pr| {
        render_fields(&p.scene, &opts, pr)
    })?;
    write(p, staged, &est, wall)
}

/// Writes the field realizations `est` of `p` (rendered, or merged from shards).
pub fn write(
    p: &Problem,
    mut staged: Staged,
    est: &FieldEstimate,
    wall: f64,
) -> anyhow::Result<()> {
    let r = &p.render;
    let (j, rr) = (p.pairs(), r.realizations);
    let n = &p.name;
    let (shape, layout) = layout(p, rr, "realization");
    let data = est.fields.as_slice();
    staged.add(format!("{n}.fields.npy"), encode_c16(&shape, data));
    if r.add_mean {
        staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &est.mean));
    }
    let naming = "<name>.r{realization}.s{source}.png";
    let images = FieldImages::new(p, data, n, naming, &mut staged)?;
    let mut summary = images.summary(p);
    summary["mean_coherent_intensity"] = json!(coherent_intensity(&est.mean));
    let mut files = json!({"fields": format!("{n}.fields.npy"), "shape": shape, "layout": layout});
    if r.add_mean {
        files["mean"] = json!(format!("{n}.mean.npy"));
    }
    if let Some(png) = images.png.clone() {
        files["png"] = png;
    }
    let render = json!({
        "realizations": rr,
        "paths_per_realization": r.paths_per_realization,
        "seed": r.seed,
        "coherence": speckle::scene::build::render::coherence_name(r.coherence),
        "add_mean": r.add_mean,
        "threads": threads(),
        "tracer": r.tracer_json(),
        "wall_time_s": wall,
    });
    let meta = p.sidecar("fields", render, files, summary);
    stage_sidecar(&mut staged, p, "fields", &meta)?;
    say!(
        "{n}: {rr} field realizations of J = {j} pairs ({} paths each) in {wall:.2} s ({} \
         threads); intensity contrast {}",
        r.paths_per_realization,
        threads(),
        images.contrasts()
    );
    finish(staged)
}

/// The shape of `rows` field vectors: `(rows, n_sources, n_sensors)` with all pairs, else
/// `(rows, J)`; and its description for the sidecar.
pub fn layout(p: &Problem, rows: usize, what: &str) -> (Vec<usize>, String) {
    let shape = [vec![rows], p.pair_shape()].concat();
    let layout = if p.all_pairs {
        format!(
            "complex128 (R, n_sources, n_sensors): [r, s, d] = {what} r of pair (source s, sensor \
             d); for a sensor grid, reshape the last axis to (ny, nx)"
        )
    } else {
        format!("complex128 (R, J): [r, j] = {what} r of pairs[j]")
    };
    (shape, layout)
}

/// Intensity statistics and images of field vectors: `R` rows of all pairs.
pub struct FieldImages {
    /// `(mean intensity, contrast std / mean)` per source (all pairs), else of everything.
    per_source: Vec<(f64, f64)>,
    /// The sidecar's entry for the PNGs, when there are any.
    pub png: Option<Value>,
}

impl FieldImages {
    /// Computes the statistics of `data` (`R x J`, pairs in scene order) and, when the sensors
    /// form an image, stages the intensity PNGs of the first `output.png_realizations` rows as
    /// `{stem}.r{row}.s{source}.png`; `naming` describes those names for the sidecar.
    pub fn new(
        p: &Problem,
        data: &[Complex64],
        stem: &str,
        naming: &str,
        staged: &mut Staged,
    ) -> anyhow::Result<Self> {
        let (ns, nd) = (p.n_sources(), p.n_sensors());
        let rows = data.len() / p.pairs().max(1);
        let intensity: Vec<f64> = data.iter().map(|u| u.norm_sqr()).collect();
        let stats = |vals: &mut dyn Iterator<Item = f64>| {
            let (mut s1, mut s2, mut k) = (0.0, 0.0, 0usize);
            for v in vals {
                s1 += v;
                s2 += v * v;
                k += 1;
            }
            let m = s1 / k.max(1) as f64;
            let var = (s2 / k.max(1) as f64 - m * m).max(0.0);
            (m, if m > 0.0 { var.sqrt() / m } else { 0.0 })
        };
        // The intensities of row q, source s (all pairs: source-major rows of n_sensors).
        let block = |q: usize, s: usize| &intensity[(q * ns + s) * nd..(q * ns + s + 1) * nd];
        let per_source: Vec<(f64, f64)> = if p.all_pairs {
            (0..ns)
                .map(|s| stats(&mut (0..rows).flat_map(|q| block(q, s).iter().copied())))
                .collect()
        } else {
            vec![stats(&mut intensity.iter().copied())]
        };
        let mut png = None;
        if let Some(g) = p.png_grid() {
            let mut files = Vec::new();
            for q in 0..rows.min(p.output.png_realizations) {
                for (s, &(mean_i, _)) in per_source.iter().enumerate() {
                    let name = format!("{stem}.r{q}.s{s}.png");
                    staged.add(name.clone(), grid_png(p, g, block(q, s), 3.0 * mean_i)?);
                    files.push(name);
                }
            }
            png = Some(json!({
                "files": files,
                "naming": format!("{naming}, row 0 = iy 0 (top), column = ix"),
                "scale": "gray = min(255, round(255 I / (3 <I>))), I = |u|^2, <I> = mean \
                          intensity of that source over all rows and sensors; pixel replication",
            }));
        }
        Ok(Self { per_source, png })
    }

    /// The sidecar's summary entries.
    pub fn summary(&self, p: &Problem) -> Value {
        json!({
            "mean_intensity": self.per_source.iter().map(|s| s.0).collect::<Vec<_>>(),
            "intensity_contrast": self.per_source.iter().map(|s| s.1).collect::<Vec<_>>(),
            "per": if p.all_pairs { "source" } else { "all pairs" },
        })
    }

    /// The contrasts, for the terminal.
    pub fn contrasts(&self) -> String {
        let c: Vec<String> = self
            .per_source
            .iter()
            .map(|s| format!("{:.3}", s.1))
            .collect();
        c.join(", ")
    }
}
