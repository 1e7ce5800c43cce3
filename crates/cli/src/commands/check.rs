//! `speckle check`: parse and validate a scene and print a summary; renders nothing.

use super::*;
use speckle::wave::expected_scatterers;

/// Arguments of `check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (TOML).
    scene: PathBuf,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let p = load_file(&a.scene, &Overrides::default())?;
    let wave = match p.box_scene().map(|s| expected_scatterers(&s)) {
        Ok(Ok(n)) => format!("{n:.1} scatterers per configuration on average"),
        Ok(Err(e)) => format!("not applicable ({e})"),
        Err(e) => format!("not applicable ({e})"),
    };
    say!("{}: ok", p.origin);
    say!("{}", p.summary(&wave).trim_end());
    Ok(())
}
