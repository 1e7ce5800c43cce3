//! Results checked finite before they are returned: a scene whose values lie where the
//! estimators' formulas overflow (a diffusion coefficient of 1e40 with a focused beam) or
//! underflow (lags of 5e-324) would otherwise give NaN or infinite arrays that a command writes
//! with exit code 0. The error is an input error naming the scene's field that produced them
//! (or, for a merge, saying that the shards hold numbers no render gives).

use crate::RunError;
use crate::temporal::{Map, Temporal};
use num_complex::Complex64;
use speckle_scene::{Problem, SceneError};

fn finite(z: &Complex64) -> bool {
    z.re.is_finite() && z.im.is_finite()
}

fn refuse(p: &Problem, field: String, reason: String) -> RunError {
    RunError::Load(p.in_document(SceneError::InvalidInput { field, reason }))
}

/// The first (pair, lag) of a `pairs x lags` table, pair-major, where `ok` fails.
fn first_bad<T>(v: &[T], lags: usize, ok: impl Fn(&T) -> bool) -> Option<(usize, usize)> {
    let i = v.iter().position(|x| !ok(x))?;
    Some((i / lags.max(1), i % lags.max(1)))
}

/// Refuses temporal correlations (of `speckle g1`, `map`) that are not finite at some lag,
/// naming `motion` (the decorrelation of its motions overflows there).
fn correlation(
    p: &Problem,
    lags: &[f64],
    what: &str,
    at: Option<(usize, usize)>,
) -> Result<(), RunError> {
    let Some((j, l)) = at else { return Ok(()) };
    Err(refuse(
        p,
        "motion".into(),
        format!(
            "{what} of pair {j} at lag {:e} is not finite (NaN or infinite): the decorrelation \
             of the scene's motions overflows there (a diffusion coefficient or a drift far too \
             large for the wavelength and the endpoints, such as motion.diffusion = 1e40); \
             choose smaller motions or lags",
            lags[l]
        ),
    ))
}

/// Refuses a [`Temporal`] whose correlations, `g1`, `g2` or contrast are not finite (each
/// pair's decay shares of detectors are NaN where it does not decay, by definition, and are
/// not checked).
pub(crate) fn temporal(p: &Problem, t: &Temporal) -> Result<(), RunError> {
    let nl = t.lags.len();
    correlation(
        p,
        &t.lags,
        "the correlation",
        first_bad(&t.correlation, nl, finite),
    )?;
    correlation(
        p,
        &t.lags,
        "the standard error of the correlation",
        first_bad(&t.correlation_stderr, nl, finite),
    )?;
    if let Some(g1) = &t.g1 {
        correlation(p, &t.lags, "g1", first_bad(g1, nl, finite))?;
    }
    if let Some(g2) = &t.g2 {
        correlation(p, &t.lags, "g2", first_bad(g2, nl, |x| x.is_finite()))?;
    }
    if let Some((j, l)) = t
        .contrast
        .as_ref()
        .and_then(|k| first_bad(k, nl, |x| x.is_finite()))
    {
        return Err(refuse(
            p,
            format!("motion.lags[{l}]"),
            format!(
                "the speckle contrast K(T) of pair {j} for an exposure of {:e} is not finite \
                 (NaN or infinite): K(T) divides by the exposure, and 1 / T overflows for lags \
                 this close to 0 (below about 1e-308); choose larger lags",
                t.lags[l]
            ),
        ));
    }
    Ok(())
}

/// Refuses a [`Map`] whose correlations are not finite.
pub(crate) fn map(p: &Problem, m: &Map) -> Result<(), RunError> {
    let nl = m.lags.len();
    correlation(
        p,
        &m.lags,
        "the correlation",
        first_bad(&m.correlation, nl, finite),
    )?;
    correlation(
        p,
        &m.lags,
        "the standard error of the correlation",
        first_bad(&m.correlation_stderr, nl, finite),
    )?;
    if let Some(n) = &m.normalised {
        correlation(
            p,
            &m.lags,
            "|C| / C(0)",
            first_bad(n, nl, |x| x.is_finite()),
        )?;
    }
    Ok(())
}

/// Refuses a merge whose estimate is not finite: every shard's numbers are finite, but numbers
/// too large to come from a render (1e308) overflow in the sums of the merge. The speckle means
/// of a covariance may be NaN with the warning that explains them, as a single run's.
pub(crate) fn merged(o: &crate::Outcome) -> Result<(), RunError> {
    use crate::Outcome;
    let all = |v: &[Complex64]| v.iter().all(finite);
    let est = |e: &speckle_estimators::CovarianceEstimate| {
        [&e.total, &e.single, &e.multiple]
            .iter()
            .all(|m| all(m.value.as_slice()) && all(m.std_error.as_slice()))
    };
    let ok = match o {
        Outcome::Covariance(e, means) => est(e) && (means.warning.is_some() || all(&means.values)),
        Outcome::Intensity(e) => est(e),
        Outcome::Fields(f) => all(f.fields.as_slice()) && all(&f.mean),
        Outcome::Wave(w) => {
            all(w.fields.as_slice())
                && all(&w.mean)
                && all(&w.mean_std_error)
                && all(w.covariance.value.as_slice())
                && all(w.covariance.std_error.as_slice())
                && w.mean_scatterers.is_finite()
        }
    };
    if ok {
        return Ok(());
    }
    Err(RunError::Shard(speckle_stats::ShardError::Mismatch(
        format!(
            "the merged {} is not finite (NaN or infinite): the shards hold numbers too large to \
         come from a render (the files are damaged or not speckle's)",
            o.kind().command()
        ),
    )))
}
