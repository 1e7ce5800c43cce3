//! `speckle mean`: the speckle mean of every pair (closed form).

use super::*;
use crate::error;
use speckle::scene::npy::encode_c16;

/// Arguments of `mean`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No cost estimate.
    #[arg(long, short)]
    quiet: bool,
    /// Run even when the estimated memory exceeds the machine's or the rough time a day.
    #[arg(long)]
    force: bool,
    /// Let the scene read files outside its folder and write outside the current directory.
    #[arg(long)]
    allow_outside: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = Overrides {
        out: a.out.clone(),
        allow_outside: a.allow_outside,
        ..Overrides::default()
    };
    let p = load_file(&a.scene, &o)?;
    set_threads(a.threads)?;
    install_interrupt_handler(true);
    let run = RunOptions {
        quiet: a.quiet,
        cancel_after: None,
        force: a.force,
        shard: None,
    };
    let mut staged = plan(&p, estimate(&p, Command::Mean), run)?;
    let start = Instant::now();
    let progress = CliProgress::new(0, "pairs", &p.name, true, None);
    let mean = means(&p, &progress).map_err(error::estimator)?;
    let wall = start.elapsed().as_secs_f64();
    let n = &p.name;
    let j = p.pairs();
    staged.add(format!("{n}.mean.npy"), encode_c16(&[j], &mean));
    let files = json!({
        "mean": format!("{n}.mean.npy"),
        "layout": "complex128 (J,): the speckle mean E[u_j] of each pair (closed form)",
    });
    let render = json!({"threads": threads(), "wall_time_s": wall});
    let summary = json!({"mean_coherent_intensity": coherent_intensity(&mean)});
    let meta = p.sidecar("mean", render, files, summary);
    stage_sidecar(&mut staged, &p, "mean", &meta)?;
    say!("{n}: speckle mean of J = {j} pairs in {wall:.2} s");
    for (k, (m, pair)) in mean.iter().zip(p.scene.pairs()).enumerate().take(8) {
        say!(
            "  pair {k} (source {}, sensor {}): {:+.6e} {:+.6e}i  |m|^2 = {:.6e}",
            pair.source,
            pair.sensor,
            m.re,
            m.im,
            m.norm_sqr()
        );
    }
    if j > 8 {
        say!("  ... ({} more in {n}.mean.npy)", j - 8);
    }
    finish(staged)
}
