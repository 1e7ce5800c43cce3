//! `speckle example`: prints an embedded example scene or study.

use super::*;
use speckle::scene::examples;
use speckle::studies::examples as studies;

/// Arguments of `example`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which example (default: `default`).
    name: Option<String>,
    /// List the example names.
    #[arg(long)]
    list: bool,
}

pub fn run(a: &Args) -> anyhow::Result<()> {
    if a.list {
        for n in examples::names() {
            say!("{n}");
        }
        return Ok(());
    }
    let name = a.name.as_deref().unwrap_or("default");
    let text = examples::example(name)
        .or_else(|| studies::study(name))
        .ok_or_else(|| {
            input(format!(
                "no example called {name:?}; the examples are: {} (and the memory-spectrum \
                 studies {})",
                examples::names().join(", "),
                studies::names().join(", ")
            ))
        })?;
    use std::io::Write as _;
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
    Ok(())
}
