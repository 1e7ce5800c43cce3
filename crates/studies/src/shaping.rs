//! Dynamic wavefront shaping (Bar et al. 2023, Sec. 8.6, Fig. 10; the observation of its ref. \[47\]) on
//! sampled transmission-matrix sequences ([`speckle_estimators::render_field_sequence`]).
//!
//! The scene's sources are the modes of a spatial light modulator, one of its sensors the
//! target pixel behind the medium; its pairs are every (source, sensor) combination, and the
//! field sequence gives, per realization `r`, the transmission row `u_m(t_l)` of every mode `m`
//! to the target at every frame time `t_l`.
//!
//! - **Learning**: the modulator's phase-only mask is fitted over the first `learn` frames, as
//!   an iterative algorithm that measures the modes' coefficients while the medium moves does:
//!   `a_m = exp(-i arg ubar_m) / sqrt(N)`, `ubar_m` the mean of `u_m` over the learning frames.
//!   With `learn = 1` this is phase conjugation at `t_0`.
//! - **Recording**: the mask is frozen at the last learning frame; the focus field is
//!   `E_f(t) = sum_m a_m u_m(t)` at that frame and every later one (times measured from it).
//! - **Native speckle**: the same with a random phase mask `b_m` (fixed per realization).
//!
//! Reported per recording time: the enhancement `<I_f(t)> / <I_s>` (the speckle intensity
//! averaged over realizations and recording frames) and the normalised field correlations
//! `|<E(0) conj(E(t))>| / <|E(0)|^2>` of focus and speckle, ensemble averages over realizations
//! (the paper's Eq. 40 averages over time within one record instead), with jackknife standard
//! errors over 32 groups of realizations. The paper's claim: after shaping, the focus decays more
//! slowly than native speckle when the medium has static and dynamic parts, because a mask
//! learned while the medium moves weighs the static paths.

use speckle_estimators::FieldSequence;
use speckle_phase::Complex64;
use speckle_stats::{PathRng, rng::derive_seed};
use std::f64::consts::TAU;

/// Groups of realizations for the jackknife.
const GROUPS: usize = 32;

/// A statistic of the realizations that a predicate keeps (for the jackknife).
type Statistic<'a> = &'a dyn Fn(&dyn Fn(usize) -> bool) -> f64;

/// The result of [`shape`]: tables are `R x T` (realization-major) over the recording frames.
#[derive(Debug, Clone, PartialEq)]
pub struct Shaping {
    /// Recording times, from the frame where the mask is frozen.
    pub times: Vec<f64>,
    /// Number of realizations `R`.
    pub realizations: usize,
    /// Number of modes `N`.
    pub modes: usize,
    /// Focus intensity `|E_f(t)|^2`.
    pub focus: Vec<f64>,
    /// Native speckle intensity `|E_s(t)|^2`.
    pub speckle: Vec<f64>,
    /// Per recording time: `<I_f(t)> / <I_s>` and its standard error.
    pub enhancement: Vec<(f64, f64)>,
    /// Per recording time: `|<E_f(0) conj(E_f(t))>| / <|E_f(0)|^2>` and its standard error.
    pub focus_correlation: Vec<(f64, f64)>,
    /// The same for native speckle.
    pub speckle_correlation: Vec<(f64, f64)>,
}

/// Errors of [`shape`], naming the setting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field}: {reason}")]
pub struct ShapingError {
    /// The offending setting.
    pub field: String,
    /// What is wrong with it.
    pub reason: String,
}

fn invalid(field: &str, reason: String) -> ShapingError {
    ShapingError {
        field: field.into(),
        reason,
    }
}

/// Shapes the wavefront towards sensor `target` of every realization of `seq`, a field sequence
/// of `sources x sensors` pairs in source-major order (`Pair::all`), learning over the first
/// `learn` frames; the random masks of native speckle draw from `seed`.
pub fn shape(
    seq: &FieldSequence,
    sources: usize,
    sensors: usize,
    target: usize,
    learn: usize,
    seed: u64,
) -> Result<Shaping, ShapingError> {
    let nt = seq.times.len();
    let r = seq.fields.rows();
    if seq.pairs() != sources * sensors {
        return Err(invalid(
            "pairs",
            format!(
                "shaping needs every (source, sensor) pair in source-major order ({} x {}), \
                 got {} pairs",
                sources,
                sensors,
                seq.pairs()
            ),
        ));
    }
    if target >= sensors {
        return Err(invalid(
            "target",
            format!("sensor {target} does not exist ({sensors} sensors)"),
        ));
    }
    if learn == 0 || learn > nt {
        return Err(invalid(
            "learn",
            format!("must be between 1 and the number of frames {nt} (got {learn})"),
        ));
    }
    if r < 2 * GROUPS {
        return Err(invalid(
            "realizations",
            format!(
                "at least {} are needed for standard errors (got {r})",
                2 * GROUPS
            ),
        ));
    }
    let n = sources;
    let norm = 1.0 / (n as f64).sqrt();
    let first = learn - 1;
    let times: Vec<f64> = seq.times[first..]
        .iter()
        .map(|t| t - seq.times[first])
        .collect();
    let nr = times.len();
    let (mut ef, mut es) = (vec![Complex64::ZERO; r * nr], vec![Complex64::ZERO; r * nr]);
    let key = derive_seed(seed, 0x5348_4150_4549);
    for i in 0..r {
        let u = |l: usize, m: usize| seq.get(i, l, m * sensors + target);
        let mut rng = PathRng::new(key, i as u64);
        let a: Vec<Complex64> = (0..n)
            .map(|m| {
                let mean: Complex64 = (0..learn).map(|l| u(l, m)).sum();
                if mean == Complex64::ZERO {
                    Complex64::new(norm, 0.0)
                } else {
                    Complex64::from_polar(norm, -mean.arg())
                }
            })
            .collect();
        let b: Vec<Complex64> = (0..n)
            .map(|_| Complex64::from_polar(norm, TAU * rng.next_f64()))
            .collect();
        for (k, l) in (first..nt).enumerate() {
            ef[i * nr + k] = (0..n).map(|m| a[m] * u(l, m)).sum();
            es[i * nr + k] = (0..n).map(|m| b[m] * u(l, m)).sum();
        }
    }
    let focus: Vec<f64> = ef.iter().map(|e| e.norm_sqr()).collect();
    let speckle: Vec<f64> = es.iter().map(|e| e.norm_sqr()).collect();
    // Jackknife over groups of realizations of a statistic of the realizations' sums.
    let groups: Vec<std::ops::Range<usize>> = (0..GROUPS)
        .map(|g| g * r / GROUPS..(g + 1) * r / GROUPS)
        .collect();
    let jackknife = |stat: Statistic| -> (f64, f64) {
        let all = stat(&|_| true);
        let loo: Vec<f64> = groups.iter().map(|g| stat(&|i| !g.contains(&i))).collect();
        let k = GROUPS as f64;
        let mean = loo.iter().sum::<f64>() / k;
        let var = (k - 1.0) / k * loo.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
        (all, var.sqrt())
    };
    let enhancement = (0..nr)
        .map(|k| {
            jackknife(&|keep| {
                let (mut f, mut s, mut c) = (0.0, 0.0, 0.0);
                for i in (0..r).filter(|i| keep(*i)) {
                    f += focus[i * nr + k];
                    s += speckle[i * nr..(i + 1) * nr].iter().sum::<f64>() / nr as f64;
                    c += 1.0;
                }
                (f / c) / (s / c)
            })
        })
        .collect();
    let correlation = |e: &[Complex64]| -> Vec<(f64, f64)> {
        (0..nr)
            .map(|k| {
                jackknife(&|keep| {
                    let (mut p, mut q) = (Complex64::ZERO, 0.0);
                    for i in (0..r).filter(|i| keep(*i)) {
                        p += e[i * nr] * e[i * nr + k].conj();
                        q += e[i * nr].norm_sqr();
                    }
                    p.norm() / q
                })
            })
            .collect()
    };
    Ok(Shaping {
        focus_correlation: correlation(&ef),
        speckle_correlation: correlation(&es),
        times,
        realizations: r,
        modes: n,
        focus,
        speckle,
        enhancement,
    })
}

/// The phase-only enhancement expected at the frame where the mask was learned (`learn = 1`)
/// for independent circular Gaussian transmission entries of mean intensities `s2[m]`:
/// `1 + (pi / 4) ((sum sigma_m)^2 - sum sigma_m^2) / sum sigma_m^2`, `sigma_m = sqrt(s2[m])`
/// (`1 + (pi / 4) (N - 1)` for equal intensities; Vellekoop and Mosk 2007).
pub fn phase_only_enhancement(s2: &[f64]) -> f64 {
    let sum: f64 = s2.iter().map(|v| v.sqrt()).sum();
    let sq: f64 = s2.iter().sum();
    1.0 + std::f64::consts::FRAC_PI_4 * (sum * sum - sq) / sq
}
