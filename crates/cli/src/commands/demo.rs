//! `speckle demo`: renders the embedded default scene (covariance, then fields) into `out/`.

use super::*;

/// Arguments of `demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory.
    #[arg(long, value_name = "DIR", default_value = "out")]
    out: PathBuf,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    set_threads(a.threads)?;
    install_interrupt_handler(true);
    let o = Overrides {
        out: Some(a.out),
        ..Overrides::default()
    };
    let p =
        speckle::scene::examples::load("default", &o).expect("the default example is embedded")?;
    let run = RunOptions {
        quiet: a.quiet,
        cancel_after: None,
        force: false,
        shard: None,
    };
    let start = Instant::now();
    covariance::render(&p, run)?;
    fields::render(&p, run)?;
    say!(
        "demo: done in {:.1} s; load the arrays with numpy.load (see README.md)",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
