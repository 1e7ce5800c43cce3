//! Temporal field correlations of every pair (`speckle g1`, `speckle.g1` in Python): the
//! spatio-temporal estimator's diagonal `C[j, j](t)` at the lags of `[motion]`, and what
//! experiments read from it (`speckle_motion::correlation`): `g1`, `g2` (Siegert) and the
//! speckle contrast `K(T)` of an exposure `T`. One place, so that both front ends write the
//! same numbers.

use crate::RunError;
use num_complex::Complex64;
use speckle_estimators::{Entries, render_correlation};
use speckle_motion::correlation;
use speckle_scene::build::motion::MotionSettings;
use speckle_scene::cost::{self, Command, Estimate};
use speckle_scene::{Problem, SceneError};
use speckle_stats::Progress;

/// The temporal correlations of the `J` pairs of a problem at its `L` lags. Tables are `J x L`,
/// pair-major (`[j * L + l]` is pair `j` at `lags[l]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Temporal {
    /// The time lags, as given in `[motion]`.
    pub lags: Vec<f64>,
    /// Number `J` of pairs.
    pub pairs: usize,
    /// `C[j, j](t) = E[u_j(t1) conj(u_j(t1 + t))] - |E u_j|^2`.
    pub correlation: Vec<Complex64>,
    /// Standard errors of [`Self::correlation`] (real part: of the real part; imaginary: of
    /// the imaginary part).
    pub correlation_stderr: Vec<Complex64>,
    /// `g1(t) = C(t) / C(0)`, when a lag is 0 and every pair's `C(0)` is positive.
    pub g1: Option<Vec<Complex64>>,
    /// `g2(t) = 1 + |g1(t)|^2` (Siegert with coherence factor `beta = 1`; for a detector of
    /// factor `beta`, `g2 - 1` scales by `beta`), when `g1` is.
    pub g2: Option<Vec<f64>>,
    /// The speckle contrast `K(T)` of an exposure `T` equal to each lag (`beta = 1`; `K`
    /// scales by `sqrt(beta)`), when the lags start at 0 and increase; `K(0) = 1`.
    pub contrast: Option<Vec<f64>>,
    /// Number of sampled paths.
    pub paths: u64,
}

/// The problem's `[motion]` table, or an error naming `motion` when it has none.
pub fn motion(p: &Problem) -> Result<&MotionSettings, RunError> {
    p.motion.as_ref().ok_or_else(|| {
        RunError::Load(p.in_document(SceneError::InvalidInput {
            field: "motion".into(),
            reason: "temporal correlations need a [motion] table (diffusion, drift, lags)".into(),
        }))
    })
}

/// The cost estimate of a render of moving scatterers on `threads` threads (`command`:
/// [`Command::G1`] for [`temporal`] and [`map`], [`Command::Fields`] for [`field_sequence`]),
/// refused when it exceeds the machine unless `force` (errors name the field).
pub fn guard(
    p: &Problem,
    command: Command,
    threads: usize,
    force: bool,
) -> Result<Estimate, RunError> {
    motion(p)?;
    let in_doc = |e| RunError::Load(p.in_document(e));
    let e = p.estimate(command, threads).map_err(in_doc)?;
    cost::guard(&e, cost::machine_memory(), force).map_err(in_doc)?;
    Ok(e)
}

/// Renders the temporal correlation of every pair of `p` at the lags of its `[motion]` table
/// (an error naming `motion` when it has none) and derives `g1`, `g2` and `K(T)`.
pub fn temporal(p: &Problem, progress: &dyn Progress) -> Result<Temporal, RunError> {
    let motion = motion(p)?;
    let opts = crate::covariance_options(p);
    let est = render_correlation(
        &p.scene,
        &motion.model,
        &motion.lags,
        &Entries::Diagonal,
        &opts,
        progress,
    )?;
    let (j, nl) = (p.pairs(), motion.lags.len());
    let (mut c, mut se) = (Vec::with_capacity(j * nl), Vec::with_capacity(j * nl));
    for e in 0..j {
        let (v, s) = est.curve(e);
        c.extend(v);
        se.extend(s);
    }
    let g1 = motion.lags.iter().position(|t| *t == 0.0).and_then(|z| {
        let mut out = Vec::with_capacity(j * nl);
        for curve in c.chunks_exact(nl) {
            out.extend(correlation::normalise(curve, z).ok()?);
        }
        Some(out)
    });
    let g2 = g1
        .as_ref()
        .map(|g| g.iter().map(|g| 1.0 + g.norm_sqr()).collect::<Vec<f64>>());
    let contrast = g1.as_ref().and_then(|g| {
        let mut out = Vec::with_capacity(j * nl);
        for curve in g.chunks_exact(nl) {
            let sq: Vec<f64> = curve.iter().map(|g| g.norm_sqr()).collect();
            out.extend(correlation::contrast_curve(&motion.lags, &sq, 1.0).ok()?);
        }
        Some(out)
    });
    Ok(Temporal {
        lags: motion.lags.clone(),
        pairs: j,
        correlation: c,
        correlation_stderr: se,
        g1,
        g2,
        contrast,
        paths: est.paths,
    })
}

/// A spatio-temporal map (Bar et al. 2023, Eqs. 36-37, Fig. 7): the correlation of the first
/// pair with every pair `k` of the pair list, `c[k](t) = C[0, k](t) = E[u_0(t1) conj(u_k(t1 +
/// t))] - m_0 conj(m_k)`, at the lags of `[motion]`. With one source and a line of sensors
/// `v + dx_k` this is `c(dx, t)` of Eq. 36; with pairs that shift source and sensor together
/// (`pairs = [[0, 0], [1, 1], ...]`) it is the tracked map of Eq. 37 and Fig. 7b. Tables are
/// `K x L`, pair-major (`[k * L + l]` is pair `k` at `lags[l]`).
#[derive(Debug, Clone, PartialEq)]
pub struct Map {
    /// The time lags, as given in `[motion]`.
    pub lags: Vec<f64>,
    /// Number `K` of pairs (the map's columns).
    pub pairs: usize,
    /// `C[0, k](t)`.
    pub correlation: Vec<Complex64>,
    /// Standard errors of [`Self::correlation`] (real part: of the real part; imaginary: of
    /// the imaginary part).
    pub correlation_stderr: Vec<Complex64>,
    /// `|C[0, k](t)| / C[0, 0](0)`, when a lag is 0 and `C[0, 0](0)` is positive.
    pub normalised: Option<Vec<f64>>,
    /// Number of sampled paths.
    pub paths: u64,
}

/// Renders the spatio-temporal map [`Map`] of `p` at the lags of its `[motion]` table (an
/// error naming `motion` when it has none).
pub fn map(p: &Problem, progress: &dyn Progress) -> Result<Map, RunError> {
    let motion = motion(p)?;
    let opts = crate::covariance_options(p);
    let k = p.pairs();
    let entries = Entries::List((0..k).map(|j| (0, j)).collect());
    let est = render_correlation(
        &p.scene,
        &motion.model,
        &motion.lags,
        &entries,
        &opts,
        progress,
    )?;
    let nl = motion.lags.len();
    let (mut c, mut se) = (Vec::with_capacity(k * nl), Vec::with_capacity(k * nl));
    for e in 0..k {
        let (v, s) = est.curve(e);
        c.extend(v);
        se.extend(s);
    }
    let normalised = motion
        .lags
        .iter()
        .position(|t| *t == 0.0)
        .map(|z| c[z].re)
        .filter(|c0| *c0 > 0.0)
        .map(|c0| c.iter().map(|v| v.norm() / c0).collect());
    Ok(Map {
        lags: motion.lags.clone(),
        pairs: k,
        correlation: c,
        correlation_stderr: se,
        normalised,
        paths: est.paths,
    })
}

/// The `[motion]` table of a field-sequence render, checked: present (an error naming `motion`),
/// frame times `>= 0` (naming `motion.lags[i]`), and the fields of every realization at every
/// time within the size limit (naming `render.realizations`).
pub fn sequence_motion(p: &Problem) -> Result<&MotionSettings, RunError> {
    let motion = motion(p)?;
    let in_doc = |e| RunError::Load(p.in_document(e));
    if let Some((l, t)) = motion.lags.iter().enumerate().find(|(_, t)| **t < 0.0) {
        return Err(in_doc(SceneError::InvalidInput {
            field: format!("motion.lags[{l}]"),
            reason: format!("the frame times of a field sequence must be >= 0 (got {t})"),
        }));
    }
    let rows = p.render.realizations.saturating_mul(motion.lags.len());
    p.field_rows_size(rows, "render.realizations")
        .map_err(in_doc)?;
    Ok(motion)
}

/// Renders the field sequence of `p` (Bar et al. 2023, Sec. 5): field realizations of every
/// pair at the times of its `[motion]` table, checked by [`sequence_motion`].
pub fn field_sequence(
    p: &Problem,
    progress: &dyn Progress,
) -> Result<speckle_estimators::FieldSequence, RunError> {
    let motion = sequence_motion(p)?;
    let opts = crate::field_options(p);
    Ok(speckle_estimators::render_field_sequence(
        &p.scene,
        &motion.model,
        &motion.lags,
        &opts,
        progress,
    )?)
}
