//! `speckle check`: parse and validate a scene and print a summary; renders nothing.

use super::*;

/// Arguments of `check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (TOML).
    scene: PathBuf,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let p = load_file(&a.scene, &Overrides::default())?;
    say!("{}", speckle::runs::summary(&p));
    Ok(())
}
