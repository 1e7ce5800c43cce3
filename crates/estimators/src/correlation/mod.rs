//! The spatio-temporal covariance of moving scatterers (Bar et al. 2023, Eqs. 11-30):
//! `C[j, k](t) = E[u_j(t1) conj(u_k(t1 + t))] - m_j conj(m_k)` for entries `(j, k)` of the pair
//! list and a list of time lags `t`, every lag from the same traced paths.
//!
//! A path's contribution to the static covariance (Alg. 1 of the 2019 paper) is multiplied by
//! the decorrelation of each of its vertices (Eq. 14). The interior vertices give a factor that
//! does not depend on the pair, kept as two sums along the path by the state of
//! [`MotionFactor`] (a [`speckle_paths::PathFactor`]; its state gives the
//! interior factor at every lag, [`speckle_motion::MotionState::interior`]);
//! the first and last vertices give factors that depend on the endpoints of *both* copies of
//! the path (the averaged endpoint directions of `shared/notes/spatiotemporal-2023.md`
//! Sec. 5.3, [`speckle_motion::first_transfer`] and [`speckle_motion::last_transfer`]), so
//! they are evaluated entry by entry: a contribution to `C[j, k](t)` is
//!
//! `w h Y_t sum_{T1, T2} A_{j T1}(-t/2) conj(A_{k T2}(+t/2)) exp(-k^2 |t| X_{j T1, k T2})`,
//!
//! over the forward and (with coherent backscattering) reversed terms `T` of Eq. 38, `Y_t` the
//! interior factor, `X = D(x1) |q_1|^2 + D(x_b) |q_b|^2` the end vertices' Brownian exponents.
//! Drift is applied by the *hybrid exact-drift* scheme (the note's recommendation, and what the
//! authors' code does): copy 1 connects its end vertices to its endpoints from
//! `x - t U(x) / 2`, copy 2 from `x + t U(x) / 2` (`A(-/+t/2)`, exact lengths, attenuations and
//! amplitudes), the interior drift is the telescoped sum of [`MotionFactor`].
//! Both copies evaluate their Brownian end transfers with their own displaced directions, so
//! shifting the endpoints with the flow (`i + tU`, `v + tU`) reproduces the correlation of a
//! medium without drift path by path (up to attenuation and boundary effects).
//!
//! **Focused Gaussian beams** (Bar et al. 2020) are superpositions of plane waves, so a beam's
//! end vertex has no single leg direction for the averaged transfer: the Gaussian average over
//! its displacement couples the plane waves of both copies' apertures, `e^(-C |(p + p') / 2|^2)`
//! for the copies' momentum transfers `p = psi - w`, `p' = psi' - w` (`C = k^2 D |t|`; and a
//! beam's spread of directions decorrelates a forward-scattering end vertex that a single
//! direction would leave intact). Without drift that average is taken in closed form up to one
//! standard normal vector `u` per end vertex (`damped.rs`, `speckle_endpoints::Damping`): it is
//! each copy's own `e^(-C (1 - psi . w))`, a damping of the amplitude that keeps every beam
//! integral a closed-form vMF integral (each lobe `(gamma, l) -> (gamma + C, l - C)`), times the
//! coupling `e^(C |psi - psi'|^2 / 4) = E_u[e^(s u . psi) e^(-s u . psi')]`, `s = sqrt(C / 2)`,
//! a real tilt of each copy's aperture; both copies connect at the vertex itself (one set of
//! legs, apertures and attenuation fits for every lag), each lag costing one vMF integral per
//! beam, lobe and copy. Single scattering has no path direction there: its copies tilt both
//! beams' plane waves by the displacement's phase, `-/+ i k Delta / 2`, `Delta = sqrt(2 D |t|)
//! z_1`. Both take the draw and its opposite (antithetic). With drift, the end vertices'
//! displacements are *sampled* instead: per path, a standard normal vector `z_1` for the first
//! vertex and `z_b` for each later one (from a stream of their own, `BROWNIAN_KEY`), and at lag
//! `t` copy 1 connects from `x - Delta/2`, copy 2 from `x + Delta/2`, `Delta = t U + sqrt(2 D
//! |t|) z`, with the exact connections there (as drift is), times the shared segments'
//! first-order phase `exp(i k (w_1 . Delta_1 - w_in . Delta_b))` (Brownian parts only;
//! [`speckle_motion::EndDisplacement`] and [`speckle_motion::segment_phase`], the same in plain
//! data for an outside tracer). Its expectation over `z` is the exact Gaussian average at the
//! end vertices; interior vertices keep the closed form. `tests/motion_beams.rs` compares the
//! two. Lags are connected one by one (no powers).
//!
//! The medium's box stays where it is while its scatterers flow through it: a path whose
//! vertex `x_m` would lie outside the box at either time (`x_m -/+ t U(x_m) / 2`) goes through
//! a scatterer that is not in the medium then, and contributes nothing at that lag (the exact
//! solver, `speckle_wave::render_wave_motion`, solves the scatterers inside the box at each
//! time). The paper's derivation assumes an unbounded medium and has no such term; it matters
//! within `|t U|` of the faces. Brownian displacements are not tested against the box (their
//! spread `sqrt(2 D |t|)` is assumed small against it).
//!
//! A lag of exactly zero is accumulated as the static covariance is (the same connector, the
//! same Hermitian sums), so it is bitwise [`crate::render_covariance`] (all entries) or
//! [`crate::render_intensity`] (the diagonal). Other lags accumulate complex values entry by
//! entry ([`speckle_stats::Layout::GeneralDiagonal`]): `O(E L)` exponentials per vertex for
//! `E` entries and `L` lags, with the end-vertex products formed once per vertex and lag-free
//! when nothing drifts. Without drift the copies connect where the static connector does (its
//! legs serve both), and lags that are whole multiples of one step take their factors as powers
//! of one exponential per term ([`crate::lag_powers`]), summed per batch. With drift, plane
//! waves and far-field sensors in a homogeneous box connect along the copies' line as exact
//! exponentials, so each term is one complex exponential in the lag and takes powers too
//! (`linear.rs`, equal to the copy-by-copy connections to rounding).

mod damped;
mod diagonal;
mod factor;
mod legs;
mod linear;
mod sink;

pub use factor::MotionFactor;

use crate::connect::{Connector, Ends};
use crate::lag_powers::{DriftSums, PowerSums, Powers, SlotSums};
use crate::{
    Coherence, CovarianceEstimate, CovarianceOptions, EstimatorError, MatrixEstimate, Scene,
};
use damped::DampedScratch;
use glam::DVec3;
use num_complex::Complex64;
use sink::*;
use speckle_medium::Medium;
use speckle_motion::{EndDisplacement, Motion, MotionModel, MotionState, segment_phase};
use speckle_paths::{PathRng, Vertex, VertexSink};
use speckle_phase::PhaseFunction;
use speckle_stats::rng::derive_seed;
use speckle_stats::{BatchSum, CMatrix, Layout, PartGroups, Poll, Progress, batch_moments_grouped};

/// The index given to [`derive_seed`] for the key of the end vertices' normal vectors (scenes
/// with Gaussian beams: the sampled Brownian displacements with drift, the tilts of the closed
/// form without): path `n` draws them from stream `n` of `derive_seed(seed, BROWNIAN_KEY)`, so
/// its path is the static one.
pub const BROWNIAN_KEY: u64 = 0x0042_726f_776e; // "Brown"

/// Which entries `C[j, k](t)` of the pair list a correlation render estimates.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Entries {
    /// The temporal correlation of every pair with itself, `C[j, j](t)` (`g1` curves, DCS):
    /// `O(J)` per vertex and lag.
    Diagonal,
    /// Every entry: `J x J` matrices per lag (`O(J^2)` per vertex and lag).
    Full,
    /// The listed entries `(j, k)` (spatio-temporal maps such as `C[(i, v), (i, v + dx)](t)`).
    List(Vec<(usize, usize)>),
}

/// A spatio-temporal covariance estimate: one [`CovarianceEstimate`] per time lag.
#[derive(Debug, Clone, PartialEq)]
pub struct CorrelationEstimate {
    /// The time lags `t`, in the order given.
    pub lags: Vec<f64>,
    /// The estimated entries `(j, k)`, in the order of the estimate's vectors.
    pub entries: Vec<(usize, usize)>,
    /// Per lag: the single-, multiple-scattering and total estimates. [`Entries::Full`] gives
    /// `J x J` matrices, the others `E x 1` columns in the order of `entries`.
    pub per_lag: Vec<CovarianceEstimate>,
    /// Number of sampled sub-paths.
    pub paths: u64,
}

impl CorrelationEstimate {
    /// The total estimate of entry number `e` (in the order of `entries`) at lag number `l`,
    /// with its standard error.
    pub fn total(&self, l: usize, e: usize) -> (Complex64, Complex64) {
        let m = &self.per_lag[l].total;
        if m.value.cols() == 1 {
            (m.value.get(e, 0), m.std_error.get(e, 0))
        } else {
            let j = m.value.cols();
            (m.value.get(e / j, e % j), m.std_error.get(e / j, e % j))
        }
    }

    /// The curve of entry number `e` over the lags: values and standard errors.
    pub fn curve(&self, e: usize) -> (Vec<Complex64>, Vec<Complex64>) {
        (0..self.lags.len()).map(|l| self.total(l, e)).unzip()
    }
}

/// The most entries (lags times estimated entries) one correlation render holds (about 2 GB
/// of estimates).
pub const MAX_STORED_ENTRIES: usize = 1 << 24;

/// Renders the spatio-temporal covariance `C[j, k](t)` of the `entries` of `scene`'s pair list
/// for scatterers moving as `model` says, at every lag of `lags` (see the module docs for the
/// estimator, `docs/conventions.md` for the time convention).
///
/// Deterministic: the same seed gives bitwise the same result for any number of threads; a
/// lag of exactly zero is bitwise [`crate::render_covariance`] ([`Entries::Full`]) or the
/// diagonal of [`crate::render_intensity`] ([`Entries::Diagonal`]) with the same options.
///
/// Errors name the field: `lags` (empty, not finite), `entries[e]` (an index beyond the pair
/// list), `motion.materials` (a model that does not fit the medium), `paths`.
///
/// ```
/// use speckle_estimators::*;
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// use speckle_motion::{Motion, MotionModel};
/// use speckle_phase::Phase;
/// let slab = Aabb::centered(DVec3::ZERO, DVec3::new(20.0, 20.0, 5.0)).unwrap();
/// let m = HomogeneousBox::from_mean_free_path(slab, 5.0, 1.0).unwrap();
/// let scene = Scene::new(m, Phase::Isotropic, 1.0, vec![Source::plane_wave(DVec3::Z).unwrap()],
///     vec![Sensor::far_field(DVec3::new(0.2, 0.0, 1.0)).unwrap()], Pair::all(1, 1)).unwrap();
/// let model = MotionModel::uniform(Motion::brownian(1e-3).unwrap());
/// let opts = CovarianceOptions { paths: 2000, seed: 1, ..Default::default() };
/// let c = render_correlation(&scene, &model, &[0.0, 1.0, 4.0], &Entries::Diagonal, &opts,
///     &NoProgress).unwrap();
/// let g: Vec<f64> = (0..3).map(|l| c.total(l, 0).0.re).collect();
/// assert!(g[0] > g[1] && g[1] > g[2] && g[2] > 0.0);
/// ```
pub fn render_correlation<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    model: &MotionModel,
    lags: &[f64],
    entries: &Entries,
    options: &CovarianceOptions,
    progress: &dyn Progress,
) -> Result<CorrelationEstimate, EstimatorError> {
    if options.paths < 2 {
        return Err(EstimatorError::InvalidInput {
            field: "paths".into(),
            reason: format!(
                "at least 2 paths are needed for a standard error (got {})",
                options.paths
            ),
        });
    }
    speckle_endpoints::check_near_field(scene.sources(), scene.sensors(), scene.phases())?;
    speckle_motion::check_lags("lags", lags).map_err(motion_error)?;
    let model = scene
        .motion_fits(model)
        .map_err(|e| match motion_error(e) {
            EstimatorError::InvalidInput { field, reason } => EstimatorError::InvalidInput {
                field: format!("motion.{field}"),
                reason,
            },
            e => e,
        })?;
    let j = scene.len();
    // Refuse what cannot be held before building the entry list: every lag keeps three
    // estimates (single, multiple, total) of every entry, 32 bytes each, plus batch sums.
    let per_lag = match entries {
        Entries::Diagonal => j,
        Entries::Full => j.saturating_mul(j),
        Entries::List(v) => v.len(),
    };
    if per_lag.saturating_mul(lags.len()) > MAX_STORED_ENTRIES {
        return Err(EstimatorError::InvalidInput {
            field: "lags".into(),
            reason: format!(
                "{} lags of {per_lag} entries each exceed the {MAX_STORED_ENTRIES} entries a \
                 correlation render holds; render fewer lags or entries at a time",
                lags.len()
            ),
        });
    }
    let (mode, list) = match entries {
        Entries::Diagonal => (Mode::Diagonal, (0..j).map(|i| (i, i)).collect()),
        Entries::Full => (
            Mode::Full,
            (0..j).flat_map(|r| (0..j).map(move |c| (r, c))).collect(),
        ),
        Entries::List(v) => {
            if v.is_empty() {
                return Err(EstimatorError::InvalidInput {
                    field: "entries".into(),
                    reason: "needs at least one (j, k) entry".into(),
                });
            }
            if let Some((e, p)) = v.iter().enumerate().find(|(_, p)| p.0 >= j || p.1 >= j) {
                return Err(EstimatorError::InvalidInput {
                    field: format!("entries[{e}]"),
                    reason: format!("({}, {}) is beyond the {j} pairs of the scene", p.0, p.1),
                });
            }
            (Mode::List, v.clone())
        }
    };
    let e_len: usize = list.len();
    // Diagonal entries without drift: the forward, crossed and reversed terms.
    let slots_per_entry = if options.coherence == Coherence::ForwardAndReversed {
        3
    } else {
        1
    };
    let beams = scene.has_beams();
    let factor = MotionFactor::new(scene.medium(), &model, scene.wavenumber(), lags[0]);
    let tracer = scene.tracer_with(
        options.sampling,
        options.coherence,
        &drift_midpoints(scene, &factor, lags, &list),
    )?;
    let probe = Connector::new(scene);
    let local: Vec<Entry> = list
        .iter()
        .map(|&(a, b)| {
            let (s1, v1) = probe.pair_ends(a);
            let (s2, v2) = probe.pair_ends(b);
            Entry { s1, v1, s2, v2 }
        })
        .collect();
    let mut plan = Plan {
        lags: lags.to_vec(),
        zero: lags.iter().map(|t| *t == 0.0).collect(),
        any_zero: lags.contains(&0.0),
        zero_lags: (0..lags.len()).filter(|&l| lags[l] == 0.0).collect(),
        entries: list,
        local,
        mode,
        sampled: beams && model.has_drift(),
        damped: beams && !model.has_drift(),
        displaced: model.has_drift(),
        key: derive_seed(options.seed, BROWNIAN_KEY),
        flat: scene.medium().dimension() == speckle_medium::Dimension::Two,
        combos: match options.coherence {
            Coherence::ForwardAndReversed => 4,
            Coherence::ForwardOnly => 1,
        },
        k: scene.wavenumber(),
        powers: if model.has_drift() || beams {
            None
        } else {
            Powers::of(lags)
        },
        linear: None,
        times: Vec::new(),
    };
    if model.has_drift()
        && !beams
        && lags.iter().all(|t| *t >= 0.0)
        && linear::exponential(probe.sources(), probe.sensors())
    {
        plan.linear = Powers::of(lags).filter(|p| p.eta == 0.0);
        if let Some(p) = &plan.linear {
            plan.times = p.order.iter().map(|&(l, _)| lags[l]).collect();
        }
    }
    drop(probe);
    let parts: Vec<(Layout, usize)> = plan
        .zero
        .iter()
        .flat_map(|&z| {
            let part = match (z, mode) {
                (true, Mode::Diagonal) => (Layout::HermitianDiagonal, j),
                (true, Mode::Full) => (Layout::Hermitian, j),
                _ => (Layout::GeneralDiagonal, e_len),
            };
            [part, part]
        })
        .collect();
    // (The exponential drift connects no copies, `linear.rs`.)
    let sets = if plan.displaced && plan.linear.is_none() {
        2 * lags.len()
    } else {
        0
    };
    let init = || {
        let conn = Connector::new(scene);
        let conn_len = (conn.sources().len(), conn.sensors().len());
        let ends = (0..sets)
            .map(|_| Ends::new(conn.sources(), conn.sensors()))
            .collect();
        Scratch {
            conn,
            state: MotionState::default(),
            ends,
            xs: Vec::with_capacity(sets),
            prod: vec![Complex64::ZERO; e_len * plan.combos],
            expo: vec![0.0; e_len * plan.combos],
            buf: vec![Complex64::ZERO; e_len],
            table: plan
                .powers
                .as_ref()
                .map(|p| [PowerSums::new(p, e_len), PowerSums::new(p, e_len)]),
            slots: plan
                .powers
                .as_ref()
                .filter(|_| plan.mode == Mode::Diagonal && !plan.sampled)
                .map(|p| SlotSums::new(p, e_len, slots_per_entry)),
            terms: Vec::with_capacity(4 * e_len),
            first_fwd: Vec::new(),
            first_rev: Vec::new(),
            first_cross: Vec::new(),
            inside: vec![true; lags.len()],
            inside_saved: Vec::with_capacity(lags.len()),
            brown: PathRng::new(plan.key, 0),
            z1: DVec3::ZERO,
            zb: DVec3::ZERO,
            drift: plan.linear.as_ref().map(|p| {
                [
                    DriftSums::new(p, e_len, 1),
                    DriftSums::new(p, e_len, plan.combos),
                ]
            }),
            legs: Default::default(),
            count: 0,
            damped: plan
                .damped
                .then(|| DampedScratch::new(lags.len(), conn_len.0, conn_len.1)),
            shares: Default::default(),
        }
    };
    let path = |s: &mut Scratch<M, P>, n: u64, sums: &mut [BatchSum], poll: &mut Poll| {
        let mut sink = CorrelationSink {
            scene,
            plan: &plan,
            factor: &factor,
            s,
            sums,
            coherence: options.coherence,
            type1: 0,
            poll,
        };
        if plan.sampled || plan.damped {
            sink.s.brown = PathRng::new(plan.key, n);
        }
        tracer.trace(&mut PathRng::new(options.seed, n), &mut sink);
    };
    let groups = PartGroups { parts, group: 2 };
    // The sums of the lags taken by powers are added to the batch's once, at its end.
    let end = |s: &mut Scratch<M, P>, sums: &mut [BatchSum]| {
        if let Some(tables) = &mut s.table {
            for (half, t) in tables.iter_mut().enumerate() {
                t.flush(sums, |l| 2 * l + half, &mut s.buf);
            }
        }
        if let Some(t) = &mut s.slots {
            t.flush(sums, |l| 2 * l + 1, &mut s.buf);
        }
        if let Some(d) = &mut s.drift {
            for (half, t) in d.iter_mut().enumerate() {
                t.flush(sums, |l| 2 * l + half, &mut s.buf);
            }
        }
    };
    let estimates = batch_moments_grouped(options.paths, &groups, init, path, end, progress)
        .ok_or(EstimatorError::Cancelled)?;
    let per_lag = estimates
        .into_iter()
        .zip(&plan.zero)
        .map(|((parts, total), &zero)| {
            let shape = |m: MatrixEstimate| {
                if mode == Mode::Full && !zero {
                    MatrixEstimate {
                        value: CMatrix::from_vec(j, j, m.value.as_slice().to_vec()),
                        std_error: CMatrix::from_vec(j, j, m.std_error.as_slice().to_vec()),
                        samples: m.samples,
                    }
                } else {
                    m
                }
            };
            let [single, multiple]: [MatrixEstimate; 2] =
                parts.try_into().expect("two parts were estimated");
            CovarianceEstimate {
                single: shape(single),
                multiple: shape(multiple),
                total: shape(total.expect("the total was estimated")),
                paths: options.paths,
            }
        })
        .collect();
    Ok(CorrelationEstimate {
        lags: lags.to_vec(),
        entries: plan.entries,
        per_lag,
        paths: options.paths,
    })
}

/// The points where both drifting copies of a path are singular at once: copy 1 connects from
/// `x - t U / 2`, so its leg to a point endpoint `p1` is singular at `x = p1 + t U(p1) / 2`, and
/// copy 2's leg to `p2` at `p2 - t U(p2) / 2`. For an entry that tracks the flow
/// (`p2 = p1 + t U`, Eq. 39) the two coincide, the product of the two `1/r` legs is `1/r^2`
/// there, and without first vertices sampled around that point the estimator has infinite
/// variance (a point in or on the medium). Returns those points (sources and sensors of every
/// entry and lag, coinciding to 1e-9 relative), once each.
fn drift_midpoints<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    factor: &MotionFactor<'_, M>,
    lags: &[f64],
    entries: &[(usize, usize)],
) -> Vec<DVec3> {
    if !factor.model().has_drift() {
        return Vec::new();
    }
    let pairs = scene.pairs();
    let mut out: Vec<DVec3> = Vec::new();
    for &(j, k) in entries {
        let (a, b) = (pairs[j], pairs[k]);
        let ends = [
            (
                scene.sources()[a.source].point_position(),
                scene.sources()[b.source].point_position(),
            ),
            (
                scene.sensors()[a.sensor].point_position(),
                scene.sensors()[b.sensor].point_position(),
            ),
        ];
        for (p1, p2) in ends {
            let (Some(p1), Some(p2)) = (p1, p2) else {
                continue;
            };
            let (u1, u2) = (factor.motion_at(p1).drift, factor.motion_at(p2).drift);
            for &t in lags.iter().filter(|t| **t != 0.0) {
                let (s1, s2) = (p1 + 0.5 * t * u1, p2 - 0.5 * t * u2);
                let scale = 1.0 + p1.abs().max_element().max(p2.abs().max_element());
                if (s1 - s2).length() <= 1e-9 * scale && !out.contains(&s1) {
                    out.push(s1);
                }
            }
        }
    }
    out
}

fn motion_error(e: speckle_motion::MotionError) -> EstimatorError {
    let (field, reason) = e.into_parts();
    EstimatorError::InvalidInput { field, reason }
}
