//! `speckle`: the command-line renderer of speckle statistics.
//!
//! Reads a TOML scene (`speckle::scene`, which parses and validates it), renders the speckle
//! covariance, intensity, single-scattering covariance, speckle mean or field realizations with
//! `speckle::estimators` (Bar et al. 2019), or the exact reference of `speckle::wave`, or runs a
//! study of `speckle::studies`, and writes NumPy `.npy` arrays, JSON sidecars and PNG or SVG
//! previews.
//!
//! Design decision: this binary owns argument parsing, progress and cancellation, and output
//! files; it checks no value and computes no physics (the libraries do, and name the offending
//! field). It maps their errors to exit codes: 0 success, 1 runtime failure (for example I/O),
//! 2 bad input, 130 interrupted. Before any work it estimates the cost and checks the output
//! directory; a render's files appear all together or not at all (`speckle_output`), so an
//! interrupted or failed render leaves the previous files as they were.

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
mod error;
mod image;
mod progress;

use clap::{Parser, Subcommand};
use commands::*;
use std::process::ExitCode;

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
    Covariance(covariance::Args),
    /// Render the speckle intensity of every pair alone (the covariance diagonal; O(J) per
    /// vertex, for many sensors).
    Intensity(covariance::Args),
    /// Temporal field correlations of moving scatterers (Bar et al. 2023): C(t) and
    /// g1(t) = C(t) / C(0) of every pair at the scene's `[motion]` lags; with `--reference`,
    /// compared with a reference curve (the authors' MCX curve of Fig. 5, for one).
    G1(g1::G1Args),
    /// Fit the scene's `[fit]` parameters (blood-flow index per material, beta, sigma_a,
    /// sigma_s, a calibration scale) to a measured g2 or g1 curve or to detector intensities:
    /// one render keeps its path records, replayed at other parameters (docs/fitting.md);
    /// estimates with intervals that include the Monte Carlo's uncertainty, residuals, and a
    /// plot of the data against the fitted curve.
    Fit(fit::FitArgs),
    /// Spatio-temporal map of moving scatterers (Bar et al. 2023, Eqs. 36-37, Fig. 7): the
    /// correlation `C[0, k](t)` of the first pair with every pair `k` at the scene's `[motion]`
    /// lags (a line of sensors gives c(dx, t); pairs shifting source and sensor together, the
    /// tracked map), and a PNG of `|C[0, k](t)| / C[0, 0](0)`.
    Map(covariance::Args),
    /// Tracking (Bar et al. 2023, Eqs. 38-39, Fig. 9): the temporal correlation of the scene's
    /// point source and point sensor in a medium drifting with U, without tracking, with both
    /// shifted by t U over each lag, and with the drift removed (same diffusion); an SVG plot
    /// and the largest deviation of the tracked curve from U = 0 in standard errors.
    Tracking(covariance::Args),
    /// Render field realizations (Alg. 2), with PNG intensity images of sensor grids.
    Fields(fields::Args),
    /// Field sequences of moving scatterers (Bar et al. 2023): field realizations at the
    /// scene's `[motion]` lags as frame times (>= 0), whose covariance is that of `speckle g1`.
    FieldSequence(fields::Args),
    /// Dynamic wavefront shaping (Bar et al. 2023, Fig. 10): a phase-only mask over the scene's
    /// sources (modulator modes) learned over the first `--learn` frames of a field sequence
    /// while the medium moves, then frozen; the focus at sensor `--target` against native
    /// speckle (enhancement, field correlations, an SVG plot).
    Shaping(shaping::ShapingArgs),
    /// Render the single-scattering covariance alone (Eq. 41; no path tracing).
    Single(single::Args),
    /// Compute the speckle mean of every pair (closed form).
    Mean(mean::Args),
    /// Exact reference: solve the wave equation (Foldy-Lax) for random configurations of point
    /// scatterers; their fields, mean and covariance.
    ///
    /// Models resonant, lossless, isotropic point scatterers only (isotropic phase, sigma_a = 0),
    /// N = sigma_s |V| / c_s of them per configuration on average, at O(N^3) time and 16 N^2
    /// bytes per configuration. The outputs `<name>.wave_*.npy` have the pair order and layout
    /// of `speckle covariance`, for a direct comparison.
    Wave(wave::Args),
    /// Lorenz-Mie quantities of a sphere: efficiencies, cross sections, asymmetry, bulk
    /// coefficients for a number density or volume fraction; with `--out`, the normalised
    /// amplitude table (CSV, loadable as a tabulated phase function) and S1, S2 (`.npy`).
    Mie(mie::Args),
    /// Fit a mixture of von Mises-Fisher lobes to an amplitude function (HG, Mie or a CSV
    /// table) by weighted EM, choosing the number of lobes to a tolerance and keeping the mean
    /// cosine; with `--out`, write a `[phase] type = "vmf"` table for scene files.
    FitPhase(fit_phase::Args),
    /// The memory effect versus wavelength for Mie spheres in a slab (Bar et al. 2019, Fig. 11):
    /// C(theta) = |C_0theta|^2 / (C_00 C_thetatheta) per wavelength, against diffusion (Eq. 39).
    ///
    /// Reads a study file, a format of its own (`speckle example fig11a_memory_small` and
    /// `speckle example fig11b_memory_large` print the two panels of Fig. 11), and writes
    /// `<name>.memory*.npy`, a JSON sidecar with the Mie figures and an SVG plot.
    MemorySpectrum(memory_spectrum::Args),
    /// The memory effect against the tilt for several anisotropies g at a fixed mean free path
    /// (Bar et al. 2023, Fig. 6): C(theta) = |C_0theta|^2 / (C_00 C_thetatheta) per g, against
    /// the C1 term (k theta L)^2 / sinh^2(k theta L); reads a study file of its own
    /// (`scenes/fig6a_memory_tilt.toml`) and writes `<name>.memory_tilt*.npy`, a JSON sidecar
    /// and an SVG plot.
    MemoryTilt(memory_tilt::Args),
    /// Speckle images under a few illumination tilts and their shift (Bar et al. 2019, Fig. 1):
    /// for each g, images of a slab under tilts n Delta, each with its cross-correlation with
    /// the untilted image, which peaks at the memory-effect shift and decays with the tilt;
    /// reads a study file of its own (`scenes/fig1_memory_images.toml`) and writes
    /// `<name>.*.npy`, a JSON sidecar and a labelled PNG of the images with their insets.
    MemoryImages(memory_images::Args),
    /// The tilt-shift memory effect (Bar et al. 2020, Fig. 12): the near-field correlation of
    /// Eq. 49 over a grid of output shifts and tilts of two Gaussian beams focused on one face
    /// of a slab, seen by a camera focused on the other, against the model of Osnabrugge et al.
    /// 2017 (Eq. 50); reads a study file of its own (`scenes/fig12_tilt_shift.toml`) and writes
    /// `<name>.tilt_shift*.npy`, a JSON sidecar and an SVG plot.
    TiltShift(tilt_shift::Args),
    /// Focusing through a slab by phase conjugation (Bar et al. 2020, Fig. 13 bottom): the
    /// expected power of the focus against its displacement, the conjugate field shifted (Eq. 51)
    /// or shifted and tilted (Eq. 52, the tilt from Eq. 50), from the covariances of Gaussian
    /// beams; reads a study file of its own (`scenes/fig13_refocus.toml`) and writes
    /// `<name>.refocus*.npy`, a JSON sidecar and an SVG plot.
    Refocus(refocus::Args),
    /// Seeing through scattering (Katz et al. 2014; Bar et al. 2019, Fig. 13): speckle images
    /// of an object of incoherent illuminators behind a slab, their autocorrelation against the
    /// object's, and the object recovered by phase retrieval (HIO and error reduction); reads a
    /// study file of its own (`scenes/fig13_seeing_through.toml`) and writes
    /// `<name>.*.npy`, a JSON sidecar and a PNG mosaic.
    SeeingThrough(seeing_through::Args),
    /// The phase of path permutations (Bar et al. 2019, Appendix A.3, Figs. 15-16): for three
    /// vertices between a plane wave and a far-field sensor in flatland, the phase of
    /// mu(x) mu(x_P)^* over one vertex for the six vertex orders P (constant for the forward
    /// order, and for the reversed one at backscattering), and the integrals over two vertices
    /// relative to the forward one; reads a study file of its own
    /// (`scenes/fig15_permutations.toml`) and writes `<name>.*.npy`, a PNG of the phase maps,
    /// an SVG bar chart and a JSON sidecar.
    Permutations(permutations::Args),
    /// The near field against the brute force (Bar et al. 2020, Fig. 7, Tables 1-2): the
    /// closed-form aperture connections of Gaussian beams against the aperture integral of
    /// far-field per-path fields (Eqs. 9-11) in flatland, entry by entry, and the time for the
    /// same standard error; reads a study file of its own (`scenes/fig7_bruteforce.toml`) and
    /// writes `<name>.bruteforce*.npy`, a JSON sidecar with the runtime table and an SVG plot.
    Bruteforce(bruteforce::Args),
    /// Importance sampling around Gaussian beams (Bar et al. 2020, Figs. 9-10): the error of
    /// covariance renders against path count and time with `render.beams` = off, position and
    /// position_and_direction, and the variance x time gains; reads a study file of its own
    /// (`scenes/fig9_sampling_gain.toml`) and writes `<name>.sampling*.npy`, a JSON sidecar and
    /// one SVG plot per case.
    SamplingGain(sampling_gain::Args),
    /// Electric-field Monte Carlo (Xu 2004, Sawicki et al. 2008), the baseline of Bar et al.
    /// 2019 (Figs. 9 and 12): light tracing with the path length as phase, each photon scored by
    /// the far-field sensors around its exit direction; intensities (with coherent
    /// backscattering) and field realizations without spatial correlation. Plane-wave sources
    /// and far-field sensors, 3D.
    Emc(emc::Args),
    /// Predictions before rendering, from a pilot of one pair (a plane-wave source and a
    /// far-field sensor): its intensity and the paths a target error needs, the memory-effect
    /// range and the speckle grain (Gaussian from where paths enter and leave, and the pilot's
    /// own correlation curves), and the sensor spacing and tilts they suggest. Writes nothing.
    Plan(plan::Args),
    /// Merge the shards of a run (`--shard I/N`) into exactly the single run's outputs.
    Merge(merge::Args),
    /// Parse and validate a scene and print a summary; renders nothing.
    Check(check::Args),
    /// Print an embedded example scene (TOML) to stdout.
    Example(example::Args),
    /// Render the embedded default scene (covariance and fields) into `out/`.
    Demo(demo::Args),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Covariance(a) => covariance::run(&a),
        Command::Intensity(a) => intensity::run(&a),
        Command::G1(a) => g1::run(&a),
        Command::Fit(a) => fit::run(&a),
        Command::Map(a) => map::run(&a),
        Command::Tracking(a) => tracking::run(&a),
        Command::Fields(a) => fields::run(&a),
        Command::FieldSequence(a) => field_sequence::run(&a),
        Command::Shaping(a) => shaping::run(&a),
        Command::Single(a) => single::run(&a),
        Command::Mean(a) => mean::run(&a),
        Command::Wave(a) => wave::run(&a),
        Command::Mie(a) => mie::run(a),
        Command::FitPhase(a) => fit_phase::run(a),
        Command::MemorySpectrum(a) => memory_spectrum::run(&a),
        Command::MemoryTilt(a) => memory_tilt::run(&a),
        Command::MemoryImages(a) => memory_images::run(&a),
        Command::TiltShift(a) => tilt_shift::run(&a),
        Command::Refocus(a) => refocus::run(&a),
        Command::SeeingThrough(a) => seeing_through::run(&a),
        Command::Permutations(a) => permutations::run(&a),
        Command::Bruteforce(a) => bruteforce::run(&a),
        Command::SamplingGain(a) => sampling_gain::run(&a),
        Command::Emc(a) => emc::run(&a),
        Command::Plan(a) => plan::run(&a),
        Command::Merge(a) => merge::run(&a),
        Command::Check(a) => check::run(&a),
        Command::Example(a) => example::run(&a),
        Command::Demo(a) => demo::run(a),
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => error::report(&e),
    }
}
