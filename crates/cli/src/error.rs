//! Library errors to exit codes: bad input 2 (the message names the field), interrupted 130,
//! anything else 1.

use speckle::estimators::EstimatorError;
use speckle::runs::RunError;
use speckle::scene::safe::printable;
use speckle::scene::tools::fit::FitError;
use speckle::scene::{LoadError, SceneError};
use speckle::studies::StudyError;
use speckle::wave::WaveError;
use speckle_output::OutputError;
use std::process::ExitCode;

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

/// An estimator's error: cancelled, bad input, or a failed render.
pub fn estimator(e: EstimatorError) -> anyhow::Error {
    match e {
        EstimatorError::Cancelled => Cancelled.into(),
        EstimatorError::InvalidInput { field, reason } => {
            InputError(format!("{field}: {reason}")).into()
        }
        other => anyhow::Error::new(other).context("render failed"),
    }
}

/// The wave solver's error, in the scene file `origin` (its option `configurations` is
/// `render.configurations` there).
pub fn wave(e: WaveError, origin: &str) -> anyhow::Error {
    match e {
        WaveError::Cancelled => Cancelled.into(),
        WaveError::InvalidInput { field, reason } => {
            let field = match field.as_str() {
                "configurations" => "render.configurations".to_string(),
                _ => field,
            };
            InputError(format!("{origin}: {field}: {reason}")).into()
        }
        WaveError::Shard(e) => InputError(e.to_string()).into(),
    }
}

/// A sharded render's or a merge's error: shards missing, overlapping, of other runs, or
/// unreadable are bad input.
pub fn runs(e: RunError) -> anyhow::Error {
    match e {
        RunError::Estimator(e) => estimator(e),
        e if e.is_cancelled() => Cancelled.into(),
        RunError::Load(e) => e.into(),
        e => InputError(e.to_string()).into(),
    }
}

/// An output error: cancelled (130), a directory or name that cannot take the files (bad
/// input, named `output.dir`), or a failed write (1; the previous files are unchanged).
pub fn output(e: OutputError) -> anyhow::Error {
    match e {
        OutputError::Cancelled => Cancelled.into(),
        e @ (OutputError::Directory { .. } | OutputError::Name { .. }) => {
            InputError(format!("output.dir: {e}")).into()
        }
        e @ OutputError::Io { .. } => anyhow::Error::new(e),
    }
}

/// A study's error.
pub fn study(e: StudyError) -> anyhow::Error {
    match e {
        StudyError::Input(e) => e.into(),
        StudyError::Render(e) => estimator(e),
    }
}

/// A tool's error naming an option by its field name (`host_index`, `index/index_imag`), with
/// the option's flags (`--host-index`, `--index/--index-imag`).
pub fn flags(e: SceneError) -> anyhow::Error {
    let SceneError::InvalidInput { field, reason } = e;
    let names: Vec<String> = field
        .split('/')
        .map(|f| format!("--{}", f.replace('_', "-")))
        .collect();
    InputError(format!("{}: {reason}", names.join("/"))).into()
}

/// A fit's error: a bad option, or a fit that failed (bad input too).
pub fn fit(e: FitError) -> anyhow::Error {
    match e {
        FitError::Invalid(e) => flags(e),
        FitError::Fit(e) => InputError(e.to_string()).into(),
    }
}

/// Prints `e` (never a terminal escape sequence: see `printable`) and returns its exit code.
pub fn report(e: &anyhow::Error) -> ExitCode {
    if e.is::<Cancelled>() {
        tell!("speckle: {}", printable(&e.to_string()));
        ExitCode::from(130)
    } else if e.is::<InputError>() || e.is::<LoadError>() || e.is::<SceneError>() {
        tell!("error: {}", printable(&e.to_string()));
        ExitCode::from(2)
    } else {
        tell!("error: {}", printable(&format!("{e:#}")));
        ExitCode::from(1)
    }
}
