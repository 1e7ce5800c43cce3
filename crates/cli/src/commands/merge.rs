//! `speckle merge`: combines the shards of a run (`--shard i/n`), or the tiles of a covariance
//! band (`--band R --tile i/n`), into exactly the single run's outputs.

use super::*;
use crate::error;
use speckle::runs::{Outcome, is_tile_file, merge_files, merge_tiles};

/// Arguments of `merge`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The shard files (`<name>.<kind>.<i>-of-<n>.shard`), or the tile files of a covariance
    /// band (`<name>.cov_band.<i>-of-<n>.tile`), in any order.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output directory (replaces `output.dir` of the shards' scene).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    set_threads(a.threads)?;
    install_interrupt_handler(true);
    let o = Overrides {
        out: a.out.clone(),
        no_png: a.no_png,
        ..Overrides::default()
    };
    let start = Instant::now();
    let tiles = a.shards.iter().filter(|p| is_tile_file(p)).count();
    if tiles > 0 {
        if tiles < a.shards.len() {
            return Err(input(
                "merge: tile files (covariance --band --tile) and shard files cannot be merged \
                 together"
                    .into(),
            ));
        }
        let m = merge_tiles(&a.shards, &o).map_err(error::runs)?;
        let staged = prepare(m.problem.out_dir())?;
        say!(
            "{}: checked {} tiles of the covariance band in {:.2} s (their renders took {:.2} s \
             in all); writing the band",
            m.problem.name,
            m.tiles(),
            start.elapsed().as_secs_f64(),
            m.wall_time_s
        );
        return covariance::write_merged_band(m, staged);
    }
    let m = merge_files(&a.shards, &o).map_err(error::runs)?;
    say!(
        "{}: merged {} shards of the {} in {:.2} s (their renders took {:.2} s in all)",
        m.problem.name,
        m.shards,
        m.outcome.kind().command(),
        start.elapsed().as_secs_f64(),
        m.shard_wall_time_s
    );
    let (p, wall) = (&m.problem, m.shard_wall_time_s);
    let staged = prepare(p.out_dir())?;
    match &m.outcome {
        Outcome::Covariance(e, means) => covariance::write(p, staged, e, means, wall),
        Outcome::Intensity(e) => intensity::write(p, staged, e, wall),
        Outcome::Fields(e) => fields::write(p, staged, e, wall),
        Outcome::Wave(e) => wave::write(p, staged, e, wall),
    }
}
