//! `speckle check`: parse and validate a scene and print a summary with the estimated cost of
//! each command; renders nothing.

use super::*;
use speckle::wave::estimate_cost;

/// Arguments of `check`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Let the scene read files outside its folder and write outside the current directory.
    #[arg(long)]
    allow_outside: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    let o = Overrides {
        allow_outside: a.allow_outside,
        ..Overrides::default()
    };
    let p = load_file(&a.scene, &o)?;
    // Paths that would never end are an error of the scene, whatever the command.
    p.check_path_length().map_err(in_scene(&p))?;
    say!("{}", speckle::runs::summary(&p));
    let t = threads();
    let mut commands = vec![
        ("covariance", Command::Covariance),
        ("intensity", Command::Intensity),
        ("single", Command::Single),
        ("fields", Command::Fields),
        ("mean", Command::Mean),
    ];
    if p.motion.is_some() {
        commands.push(("g1", Command::G1));
    }
    for (name, command) in commands {
        let text = match super::estimate(&p, command) {
            Ok(e) => e.describe(),
            Err(e) => format!("refused: {e}"),
        };
        say!("  {:<20} {text}", format!("cost of {name}"));
    }
    if let Ok(Ok(c)) = p
        .box_scene()
        .map(|s| estimate_cost(&s, p.render.configurations, t))
    {
        say!("  {:<20} {}", "cost of wave", c.estimate(0.0).describe());
    }
    Ok(())
}
