//! `speckle`: the command-line renderer of speckle statistics.
//!
//! Reads a TOML scene (a homogeneous box of scatterers, a phase function, sources and sensors; in
//! 3D or in flatland), renders the speckle covariance, intensity, single-scattering covariance,
//! speckle mean or field realizations with the estimators of `speckle::estimators` (Bar et al.
//! 2019), or the exact reference of `speckle::wave` (Foldy-Lax, averaged over configurations),
//! and writes NumPy `.npy` arrays (complex128, float64 for intensities), a JSON sidecar and PNG
//! previews.
//!
//! Design decision: this binary owns argument parsing, scene-file validation and output; the
//! library crates never see a file or a terminal. Every bad input is reported with the path of
//! the offending field and exit code 2; a render interrupted with ctrl-c exits with 130 and
//! writes nothing, because outputs are staged in memory and renamed into place only after the
//! whole render has succeeded.
//!
//! Exit codes: 0 success, 1 runtime failure (for example I/O), 2 bad input, 130 interrupted.

#![forbid(unsafe_code)]

/// `println!` that ignores a closed stdout (`speckle check x.toml | head` must not panic).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// `eprintln!` that ignores a closed stderr.
macro_rules! tell {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr().lock(), $($arg)*);
    }};
}

mod commands;
mod examples;
mod fit;
mod image;
mod memory;
mod mie;
mod npy;
mod output;
mod progress;
mod scene;
mod spec;

use clap::{Args, Parser, Subcommand};
use commands::RunOptions;
use scene::{Loaded, Overrides};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Bad user input (exit code 2). The message names the offending field.
#[derive(Debug)]
pub struct InputError(pub String);

impl std::fmt::Display for InputError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for InputError {}

/// The render was interrupted (exit code 130); nothing was written.
#[derive(Debug)]
pub struct Cancelled;

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("interrupted; no output was written")
    }
}

impl std::error::Error for Cancelled {}

#[derive(Debug, Parser)]
#[command(
    name = "speckle",
    version,
    about = "Monte Carlo rendering of speckle statistics in scattering media (Bar et al. 2019)",
    after_help = "Start with `speckle demo`, or `speckle example NAME > scene.toml` and \
                  `speckle check scene.toml`. The scene format is described in README.md.\n\
                  Exit codes: 0 ok, 1 failure, 2 bad input, 130 interrupted."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render the speckle covariance of all pairs (Alg. 1) and the speckle mean.
    Covariance(CovarianceArgs),
    /// Render the speckle intensity of every pair alone (the covariance diagonal; O(J) per
    /// vertex, for many sensors).
    Intensity(CovarianceArgs),
    /// Render field realizations (Alg. 2), with PNG intensity images of sensor grids.
    Fields(FieldsArgs),
    /// Render the single-scattering covariance alone (Eq. 41; no path tracing).
    Single(SingleArgs),
    /// Compute the speckle mean of every pair (closed form).
    Mean(MeanArgs),
    /// Exact reference: solve the wave equation (Foldy-Lax) for random configurations of point
    /// scatterers; their fields, mean and covariance.
    ///
    /// Models resonant, lossless, isotropic point scatterers only (isotropic phase, sigma_a = 0),
    /// N = sigma_s |V| / c_s of them per configuration on average, at O(N^3) time and 16 N^2
    /// bytes per configuration. The outputs `<name>.wave_*.npy` have the pair order and layout
    /// of `speckle covariance`, for a direct comparison.
    Wave(WaveArgs),
    /// Lorenz-Mie quantities of a sphere: efficiencies, cross sections, asymmetry, bulk
    /// coefficients for a number density or volume fraction; with `--out`, the normalised
    /// amplitude table (CSV, loadable as a tabulated phase function) and S1, S2 (`.npy`).
    Mie(MieArgs),
    /// Fit a mixture of von Mises-Fisher lobes to an amplitude function (HG, Mie or a CSV
    /// table) by weighted EM, choosing the number of lobes to a tolerance and keeping the mean
    /// cosine; with `--out`, write a `[phase] type = "vmf"` table for scene files.
    FitPhase(FitArgs),
    /// The memory effect versus wavelength for Mie spheres in a slab (Bar et al. 2019, Fig. 11):
    /// C(theta) = |C_0theta|^2 / (C_00 C_thetatheta) per wavelength, against diffusion (Eq. 39).
    ///
    /// Reads a study file, a format of its own (`speckle example fig11a_memory_small` and
    /// `speckle example fig11b_memory_large` print the two panels of Fig. 11), and writes
    /// `<name>.memory*.npy`, a JSON sidecar with the Mie figures and an SVG plot.
    MemorySpectrum(memory::MemoryArgs),
    /// Parse and validate a scene and print a summary; renders nothing.
    Check(CheckArgs),
    /// Print an embedded example scene (TOML) to stdout.
    Example(ExampleArgs),
    /// Render the embedded default scene (covariance and fields) into `out/`.
    Demo(DemoArgs),
}

#[derive(Debug, Args)]
struct Common {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Seed (replaces `render.seed`).
    #[arg(long, value_name = "S")]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// No progress bar (nor the cost estimate of `wave`).
    #[arg(long, short)]
    quiet: bool,
    /// Testing aid: behave as if ctrl-c was pressed once this many paths (configurations for
    /// `wave`) are done.
    #[arg(long, hide = true, value_name = "PATHS")]
    cancel_after_paths: Option<u64>,
}

#[derive(Debug, Args)]
struct CovarianceArgs {
    #[command(flatten)]
    common: Common,
    /// Number of sub-paths (replaces `render.paths`).
    #[arg(long, value_name = "N")]
    paths: Option<u64>,
    /// Forward paths only: no coherent backscattering (`render.coherence = "forward_only"`).
    #[arg(long)]
    forward_only: bool,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
}

#[derive(Debug, Args)]
struct SingleArgs {
    #[command(flatten)]
    common: Common,
    /// Number of first vertices (replaces `render.paths`).
    #[arg(long, value_name = "N")]
    paths: Option<u64>,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
}

#[derive(Debug, Args)]
struct WaveArgs {
    #[command(flatten)]
    common: Common,
    /// Number of scatterer configurations (replaces `render.configurations`).
    #[arg(long, value_name = "R")]
    configurations: Option<usize>,
    /// Write no PNG.
    #[arg(long)]
    no_png: bool,
}

#[derive(Debug, Args)]
struct FieldsArgs {
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
    /// PNGs for the first this many realizations (replaces `output.png_realizations`).
    #[arg(long, value_name = "K")]
    png_realizations: Option<usize>,
}

#[derive(Debug, Args)]
struct MeanArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output directory (replaces `output.dir`).
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Worker threads (default: all cores).
    #[arg(long, value_name = "T", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
}

#[derive(Debug, Args)]
struct MieArgs {
    /// Sphere radius (same length unit as the wavelength).
    #[arg(long, value_name = "R")]
    radius: f64,
    /// Real part of the sphere's refractive index relative to the host (n_sphere / n_host).
    #[arg(long, value_name = "M")]
    index: f64,
    /// Imaginary part of the relative index (absorption, >= 0).
    #[arg(
        long,
        value_name = "K",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    index_imag: f64,
    /// Refractive index of the host medium.
    #[arg(long, value_name = "N", default_value_t = 1.0)]
    host_index: f64,
    /// Vacuum wavelength.
    #[arg(long, value_name = "L")]
    wavelength: f64,
    /// Particles per unit volume, for sigma_s and sigma_a.
    #[arg(long, value_name = "N")]
    number_density: Option<f64>,
    /// Volume fraction of the particles, for sigma_s and sigma_a (Eq. 42).
    #[arg(long, value_name = "F")]
    volume_fraction: Option<f64>,
    /// Scattering angles of the written table (default: enough for the sphere's size).
    #[arg(long, value_name = "N")]
    angles: Option<usize>,
    /// Write the table, S1/S2 and a JSON sidecar into this directory.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Prefix of the written files.
    #[arg(long, value_name = "NAME", default_value = "mie")]
    name: String,
}

#[derive(Debug, Args)]
struct FitArgs {
    /// Fit Henyey-Greenstein with this g.
    #[arg(long, value_name = "G", allow_negative_numbers = true)]
    hg: Option<f64>,
    /// Fit the amplitude of a Mie sphere of this radius (with --index, --wavelength).
    #[arg(long, value_name = "R")]
    mie_radius: Option<f64>,
    /// Mie: real part of the relative refractive index.
    #[arg(long, value_name = "M")]
    index: Option<f64>,
    /// Mie: imaginary part of the relative refractive index.
    #[arg(
        long,
        value_name = "K",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    index_imag: f64,
    /// Mie: host refractive index.
    #[arg(long, value_name = "N", default_value_t = 1.0)]
    host_index: f64,
    /// Mie: vacuum wavelength.
    #[arg(long, value_name = "L")]
    wavelength: Option<f64>,
    /// Fit a CSV amplitude table (`theta_rad,re,im`, `theta_deg,re,im` or `mu,re,im`).
    #[arg(long, value_name = "FILE")]
    table: Option<PathBuf>,
    /// Relative L2 residual of the amplitude to reach.
    #[arg(long, value_name = "TOL", default_value_t = 0.02)]
    tolerance: f64,
    /// Most lobes tried by the automatic choice.
    #[arg(long, value_name = "K", default_value_t = 13)]
    max_components: usize,
    /// Fit exactly this many lobes.
    #[arg(long, value_name = "K")]
    components: Option<usize>,
    /// Write the fit into this directory.
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Prefix of the written files.
    #[arg(long, value_name = "NAME", default_value = "fit")]
    name: String,
}

impl FitArgs {
    fn request(self) -> Result<fit::FitRequest, InputError> {
        let target = match (self.hg, self.mie_radius, self.table) {
            (Some(g), None, None) => fit::Target::Hg(g),
            (None, Some(radius), None) => fit::Target::Mie {
                radius,
                index: speckle::phase::Complex64::new(
                    self.index
                        .ok_or_else(|| InputError("--index: needed with --mie-radius".into()))?,
                    self.index_imag,
                ),
                host_index: self.host_index,
                wavelength: self
                    .wavelength
                    .ok_or_else(|| InputError("--wavelength: needed with --mie-radius".into()))?,
            },
            (None, None, Some(t)) => fit::Target::Table(t),
            _ => {
                return Err(InputError(
                    "--hg/--mie-radius/--table: give exactly one target".into(),
                ));
            }
        };
        Ok(fit::FitRequest {
            target,
            tolerance: self.tolerance,
            max_components: self.max_components,
            components: self.components,
            out: self.out,
            name: self.name,
        })
    }
}

#[derive(Debug, Args)]
struct CheckArgs {
    /// The scene file (TOML).
    scene: PathBuf,
}

#[derive(Debug, Args)]
struct ExampleArgs {
    /// Which example (default: `default`).
    name: Option<String>,
    /// List the example names.
    #[arg(long)]
    list: bool,
}

#[derive(Debug, Args)]
struct DemoArgs {
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

fn set_threads(threads: Option<u16>) -> anyhow::Result<()> {
    if let Some(t) = threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t as usize)
            .build_global()?;
    }
    Ok(())
}

fn load(path: &Path, overrides: &Overrides) -> anyhow::Result<Loaded> {
    Ok(scene::load_file(path, overrides)?)
}

impl CovarianceArgs {
    /// Loads the scene with the command-line values of `covariance` and `intensity`.
    fn load(&self) -> anyhow::Result<Loaded> {
        let o = Overrides {
            paths: self.paths,
            forward_only: self.forward_only,
            no_png: self.no_png,
            ..self.common.overrides()
        };
        load(&self.common.scene, &o)
    }
}

impl Common {
    fn overrides(&self) -> Overrides {
        Overrides {
            seed: self.seed,
            out: self.out.clone(),
            ..Default::default()
        }
    }

    fn run(&self) -> anyhow::Result<RunOptions> {
        set_threads(self.threads)?;
        progress::install_interrupt_handler();
        Ok(RunOptions {
            quiet: self.quiet,
            cancel_after: self.cancel_after_paths,
        })
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Covariance(a) => {
            commands::covariance(&a.load()?, a.common.run()?)?;
        }
        Command::Intensity(a) => {
            commands::intensity(&a.load()?, a.common.run()?)?;
        }
        Command::Single(a) => {
            let o = Overrides {
                paths: a.paths,
                no_png: a.no_png,
                ..a.common.overrides()
            };
            let l = load(&a.common.scene, &o)?;
            commands::single(&l, a.common.run()?)?;
        }
        Command::Wave(a) => {
            let o = Overrides {
                configurations: a.configurations,
                no_png: a.no_png,
                ..a.common.overrides()
            };
            let l = load(&a.common.scene, &o)?;
            commands::wave(&l, a.common.run()?)?;
        }
        Command::Fields(a) => {
            let o = Overrides {
                realizations: a.realizations,
                paths_per_realization: a.paths_per_realization,
                forward_only: a.forward_only,
                no_mean: a.no_mean,
                no_png: a.no_png,
                png_realizations: a.png_realizations,
                ..a.common.overrides()
            };
            let l = load(&a.common.scene, &o)?;
            commands::fields(&l, a.common.run()?)?;
        }
        Command::Mean(a) => {
            let o = Overrides {
                out: a.out,
                ..Default::default()
            };
            let l = load(&a.scene, &o)?;
            set_threads(a.threads)?;
            commands::mean(&l)?;
        }
        Command::Mie(a) => mie::run(&mie::MieRequest {
            radius: a.radius,
            index: a.index,
            index_imag: a.index_imag,
            host_index: a.host_index,
            wavelength: a.wavelength,
            number_density: a.number_density,
            volume_fraction: a.volume_fraction,
            angles: a.angles,
            out: a.out,
            name: a.name,
        })?,
        Command::FitPhase(a) => fit::run(&a.request()?)?,
        Command::MemorySpectrum(a) => {
            memory::run(&a)?;
        }
        Command::Check(a) => {
            let l = load(&a.scene, &Overrides::default())?;
            commands::check(&l);
        }
        Command::Example(a) => {
            if a.list {
                for n in examples::names() {
                    say!("{n}");
                }
                return Ok(());
            }
            let name = a.name.as_deref().unwrap_or("default");
            let text = examples::example(name).ok_or_else(|| {
                InputError(format!(
                    "no example called {name:?}; the examples are: {} (and the \
                     memory-spectrum studies {})",
                    examples::names().join(", "),
                    examples::study_names().join(", ")
                ))
            })?;
            use std::io::Write as _;
            let _ = std::io::stdout().lock().write_all(text.as_bytes());
        }
        Command::Demo(a) => demo(a)?,
    }
    Ok(())
}

/// Renders the embedded default scene: covariance, then fields.
fn demo(a: DemoArgs) -> anyhow::Result<()> {
    set_threads(a.threads)?;
    progress::install_interrupt_handler();
    let o = Overrides {
        out: Some(a.out),
        ..Default::default()
    };
    let text = examples::example("default").expect("the default example is embedded");
    let cwd = std::env::current_dir().unwrap_or_default();
    let l = scene::load_str(text, "<embedded default.toml>", &cwd, "default", &o)?;
    let run = RunOptions {
        quiet: a.quiet,
        cancel_after: None,
    };
    let start = Instant::now();
    commands::covariance(&l, run)?;
    commands::fields(&l, run)?;
    say!(
        "demo: done in {:.1} s; load the arrays with numpy.load (see README.md)",
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if e.downcast_ref::<Cancelled>().is_some() {
                tell!("speckle: {e}");
                ExitCode::from(130)
            } else if let Some(input) = e.downcast_ref::<InputError>() {
                tell!("error: {input}");
                ExitCode::from(2)
            } else {
                tell!("error: {e:#}");
                ExitCode::from(1)
            }
        }
    }
}
