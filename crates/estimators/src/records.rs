//! Path records of a detector render ([`crate::render_detector_records`]): what each
//! registered contribution depends on, so that the readings and temporal correlations can be
//! evaluated again at other motions, and in a homogeneous medium at other coefficients, without
//! tracing again (`docs/fitting.md`).
//!
//! # What a contribution depends on
//!
//! A contribution of [`crate::DetectorEstimate`] to pair `j` at lag `t` is
//! `W exp(-k^2 |t| sum_m D_m Y_m + i k t sum_m U_m . Q_m)`, `Y_m = sum |q|^2` and
//! `Q_m = sum q` over the path's vertices in material `m` (Eq. 14 of the 2023 paper with one
//! motion per material), `W` its weight. A record keeps `W`, `Y_m`, `Q_m`, the number `b` of
//! vertices and the length `L` of the path inside the medium (from where it enters to where it
//! leaves or connects to the disc). Then, exactly:
//!
//! - other motions `D_m`, `U_m`: the same formula (the paths' distribution does not depend on
//!   the motion, so this is what a render at those motions would compute from the same paths);
//! - in a homogeneous medium, other `sigma_s` and `sigma_a` (same phase function, same
//!   refractive indices): the path's throughput has a factor `sigma_s e^{-sigma_t l}` per
//!   vertex and flight and `e^{-sigma_t l}` on the last flight, so the contribution is
//!   multiplied by `(sigma_s' / sigma_s)^b e^{-(sigma_t' - sigma_t) L}` (perturbation Monte
//!   Carlo: an importance re-weighting of the same paths, unbiased, whose variance grows with
//!   the change; [`Replayed::effective_fraction`] measures it).
//!
//! Anything else (the phase function, `g`, the geometry, the indices, the coefficients of one
//! layer of a layered medium) needs a new render.

use crate::CMatrix;
use glam::DVec3;
use num_complex::Complex64;
use rayon::prelude::*;
use speckle_motion::Motion;

/// One registered contribution: the path it came from, its pair, vertex count, weight and
/// length inside the medium (its transfers are kept beside it, [`PathRecords`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Record {
    /// The global index of the path (the copies of a split path share it).
    pub path: u64,
    /// The (source, detector) pair.
    pub pair: u32,
    /// Number `b` of scattering vertices.
    pub vertices: u32,
    /// The contribution's weight at the rendered parameters, lag 0 (the path weight, the
    /// detector's reading and the technique's weight).
    pub weight: f64,
    /// Length of the path's flights inside the medium.
    pub length: f64,
}

/// The parameters a render's records can be evaluated at.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameters {
    /// One motion per material.
    pub motions: Vec<Motion>,
    /// The scattering and absorption coefficients of a homogeneous medium (`None` in a medium
    /// of several materials or varying coefficients: they cannot change).
    pub coefficients: Option<(f64, f64)>,
}

/// A parameter a replay differentiates by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Derivative {
    /// The diffusion coefficient of one material.
    Diffusion(usize),
    /// The scattering coefficient of the homogeneous medium.
    SigmaS,
    /// The absorption coefficient of the homogeneous medium.
    SigmaA,
}

/// The records of a detector render: every contribution, in path order.
#[derive(Debug, Clone, PartialEq)]
pub struct PathRecords {
    /// Number `J` of (source, detector) pairs.
    pub pairs: usize,
    /// Number `M` of materials.
    pub materials: usize,
    /// The wavenumber in the medium.
    pub wavenumber: f64,
    /// Number of sampled paths (the estimates are means over them).
    pub paths: u64,
    /// The parameters of the render.
    pub rendered: Parameters,
    /// Per pair, whether its contributions were recorded (a replay of another pair is 0).
    recorded: Vec<bool>,
    records: Vec<Record>,
    /// Per record, per material: `|q|^2` summed, then the three components of `q` summed.
    transfers: Vec<f64>,
}

/// Values per material a record keeps.
pub(crate) const PER_MATERIAL: usize = 4;

impl PathRecords {
    /// Records from their parts (sorted by path already: [`crate::render_detector_records`]);
    /// `recorded` has one entry per pair.
    pub(crate) fn new(
        materials: usize,
        wavenumber: f64,
        paths: u64,
        rendered: Parameters,
        recorded: Vec<bool>,
        records: Vec<Record>,
        transfers: Vec<f64>,
    ) -> Self {
        debug_assert_eq!(transfers.len(), records.len() * materials * PER_MATERIAL);
        Self {
            pairs: recorded.len(),
            materials,
            wavenumber,
            paths,
            rendered,
            recorded,
            records,
            transfers,
        }
    }

    /// Whether pair `j`'s contributions were recorded (those of other pairs replay to 0).
    pub fn recorded(&self, j: usize) -> bool {
        self.recorded.get(j).copied().unwrap_or(false)
    }

    /// The records, in path order.
    pub fn records(&self) -> &[Record] {
        &self.records
    }

    /// Record `r`'s `Y_m = sum |q|^2` over its vertices in material `m`.
    pub fn momentum(&self, r: usize, m: usize) -> f64 {
        self.transfers[(r * self.materials + m) * PER_MATERIAL]
    }

    /// Record `r`'s `Q_m = sum q` over its vertices in material `m`.
    pub fn transfer(&self, r: usize, m: usize) -> DVec3 {
        let o = (r * self.materials + m) * PER_MATERIAL;
        DVec3::new(
            self.transfers[o + 1],
            self.transfers[o + 2],
            self.transfers[o + 3],
        )
    }

    /// Checks that `p` is a set of parameters these records can be evaluated at: one motion
    /// per material, finite; coefficients only in a homogeneous medium, positive and finite.
    pub fn check(&self, p: &Parameters) -> Result<(), String> {
        if p.motions.len() != self.materials {
            return Err(format!(
                "{} motions given for {} materials",
                p.motions.len(),
                self.materials
            ));
        }
        for (m, motion) in p.motions.iter().enumerate() {
            let finite =
                motion.diffusion >= 0.0 && motion.diffusion.is_finite() && motion.drift.is_finite();
            if !finite {
                return Err(format!("material {m}: motion {motion:?} is not finite"));
            }
        }
        match (p.coefficients, self.rendered.coefficients) {
            (None, _) => Ok(()),
            (Some(_), None) => Err(
                "the medium's coefficients can change only in a homogeneous \
                                    medium (the records keep one length per path)"
                    .into(),
            ),
            (Some((s, a)), Some(_)) => {
                if s > 0.0 && s.is_finite() && a >= 0.0 && a.is_finite() {
                    Ok(())
                } else {
                    Err(format!(
                        "sigma_s = {s} and sigma_a = {a}: need sigma_s > 0, sigma_a >= 0, finite"
                    ))
                }
            }
        }
    }

    /// The group (of `groups`, contiguous ranges of path indices) of path `n`.
    fn group(&self, n: u64, groups: usize) -> usize {
        ((u128::from(n) * groups as u128) / u128::from(self.paths)) as usize
    }

    /// Paths in group `g` of `groups`.
    fn group_paths(&self, g: usize, groups: usize) -> u64 {
        let start = |g: usize| -> u64 {
            // The first n with n * groups >= g * paths.
            (u128::from(self.paths) * g as u128).div_ceil(groups as u128) as u64
        };
        start(g + 1) - start(g)
    }

    /// Evaluates every pair at every lag at `p` (checked with [`PathRecords::check`]), with the
    /// derivatives `derivatives`, summed over each of `groups` groups of paths (contiguous
    /// ranges of path indices, for jackknife estimates). Deterministic whatever the thread
    /// count (each group is summed in record order).
    ///
    /// # Panics
    /// If `groups` is 0 or above the number of paths, or `p` fails [`PathRecords::check`].
    pub fn replay(
        &self,
        p: &Parameters,
        lags: &[f64],
        groups: usize,
        derivatives: &[Derivative],
    ) -> Replayed {
        assert!(
            groups > 0 && groups as u64 <= self.paths,
            "groups out of range"
        );
        if let Err(e) = self.check(p) {
            panic!("replay at invalid parameters: {e}");
        }
        let (j, nl, nd, nm) = (self.pairs, lags.len(), derivatives.len(), self.materials);
        let k = self.wavenumber;
        let k2 = k * k;
        let per_group = j * nl * (1 + nd);
        // The factor of the coefficients' change on a record: ratio^b e^{-delta L}, and its
        // derivatives' factors (b / sigma_s - L and -L).
        let (ratio, delta, sigma_s) = match (p.coefficients, self.rendered.coefficients) {
            (Some((s1, a1)), Some((s0, a0))) => (s1 / s0, (s1 + a1) - (s0 + a0), s1),
            _ => (1.0, 0.0, 1.0),
        };
        // Where each group's records start (records are in path order).
        let mut bounds = vec![0usize; groups + 1];
        for (i, r) in self.records.iter().enumerate() {
            bounds[self.group(r.path, groups) + 1] = i + 1;
        }
        for g in 1..=groups {
            bounds[g] = bounds[g].max(bounds[g - 1]);
        }
        let sums: Vec<(Vec<Complex64>, Vec<f64>)> = (0..groups)
            .into_par_iter()
            .map(|g| {
                let mut out = vec![Complex64::ZERO; per_group];
                // Per pair: sum and sum of squares of the lag-0 contributions.
                let mut ess = vec![[0.0f64; 2]; j];
                for r in bounds[g]..bounds[g + 1] {
                    let rec = &self.records[r];
                    let scale = if ratio == 1.0 && delta == 0.0 {
                        1.0
                    } else {
                        ratio.powi(rec.vertices as i32) * (-delta * rec.length).exp()
                    };
                    let w = rec.weight * scale;
                    let pair = rec.pair as usize;
                    ess[pair][0] += w;
                    ess[pair][1] += w * w;
                    let (mut y, mut q) = (0.0, 0.0);
                    for (m, motion) in p.motions.iter().enumerate() {
                        y += motion.diffusion * self.momentum(r, m);
                        q += motion.drift.dot(self.transfer(r, m));
                    }
                    for (l, &t) in lags.iter().enumerate() {
                        let c = w * Complex64::from_polar((-k2 * t.abs() * y).exp(), k * t * q);
                        let base = pair * nl + l;
                        out[base] += c;
                        for (d, der) in derivatives.iter().enumerate() {
                            let f = match *der {
                                Derivative::Diffusion(m) if m < nm => {
                                    -k2 * t.abs() * self.momentum(r, m)
                                }
                                Derivative::Diffusion(_) => 0.0,
                                Derivative::SigmaS => {
                                    f64::from(rec.vertices) / sigma_s - rec.length
                                }
                                Derivative::SigmaA => -rec.length,
                            };
                            out[(1 + d) * j * nl + base] += c * f;
                        }
                    }
                }
                (out, ess.into_iter().flatten().collect())
            })
            .collect();
        let mut values = Vec::with_capacity(groups * per_group);
        let mut ess = Vec::with_capacity(groups * 2 * j);
        for (v, e) in sums {
            values.extend(v);
            ess.extend::<Vec<f64>>(e);
        }
        Replayed {
            pairs: j,
            lags: nl,
            derivatives: nd,
            groups,
            paths: (0..groups).map(|g| self.group_paths(g, groups)).collect(),
            values,
            ess,
        }
    }
}

/// The sums of a replay ([`PathRecords::replay`]) per group of paths: every pair at every lag
/// and the derivatives.
#[derive(Debug, Clone, PartialEq)]
pub struct Replayed {
    pairs: usize,
    lags: usize,
    derivatives: usize,
    groups: usize,
    /// Paths per group.
    paths: Vec<u64>,
    /// Per group: `(1 + derivatives) x J x L` sums.
    values: Vec<Complex64>,
    /// Per group, per pair: the sum and the sum of squares of the lag-0 contributions.
    ess: Vec<f64>,
}

impl Replayed {
    /// Number of groups.
    pub fn groups(&self) -> usize {
        self.groups
    }

    /// The estimate of pair `j` at lag `l` (`d = 0`) or its derivative `d - 1`, over every
    /// group but `left_out` (`None`: every group): the group sums over their paths.
    pub fn value(&self, j: usize, l: usize, d: usize, left_out: Option<usize>) -> Complex64 {
        let per_group = self.pairs * self.lags * (1 + self.derivatives);
        let e = (d * self.pairs + j) * self.lags + l;
        let mut sum = Complex64::ZERO;
        let mut paths = 0u64;
        for g in 0..self.groups {
            if Some(g) != left_out {
                sum += self.values[g * per_group + e];
                paths += self.paths[g];
            }
        }
        sum / paths as f64
    }

    /// The estimates of pair `j` at every lag as a column, with jackknife standard errors over
    /// the groups (at least 2).
    pub fn curve(&self, j: usize) -> (CMatrix, CMatrix) {
        let k = self.groups as f64;
        let (mut v, mut s) = (vec![], vec![]);
        for l in 0..self.lags {
            let all = self.value(j, l, 0, None);
            let loo: Vec<Complex64> = (0..self.groups)
                .map(|g| self.value(j, l, 0, Some(g)))
                .collect();
            let mean = loo.iter().sum::<Complex64>() / k;
            let (re, im) = loo.iter().fold((0.0, 0.0), |(a, b), c| {
                (a + (c.re - mean.re).powi(2), b + (c.im - mean.im).powi(2))
            });
            v.push(all);
            s.push(Complex64::new(
                ((k - 1.0) / k * re).sqrt(),
                ((k - 1.0) / k * im).sqrt(),
            ));
        }
        (
            CMatrix::from_vec(self.lags, 1, v),
            CMatrix::from_vec(self.lags, 1, s),
        )
    }

    /// The effective number of pair `j`'s contributions (Kish: `(sum w)^2 / sum w^2` of the
    /// lag-0 contributions, all groups).
    pub fn effective_records(&self, j: usize) -> f64 {
        let (mut s, mut s2) = (0.0, 0.0);
        for g in 0..self.groups {
            let o = (g * self.pairs + j) * 2;
            s += self.ess[o];
            s2 += self.ess[o + 1];
        }
        if s2 > 0.0 { s * s / s2 } else { 0.0 }
    }

    /// The effective number of pair `j`'s contributions here over that of `reference` (the
    /// replay at the rendered parameters): 1 without re-weighting, smaller as the weights of
    /// a change of coefficients spread.
    pub fn effective_fraction(&self, reference: &Replayed, j: usize) -> f64 {
        let r = reference.effective_records(j);
        if r > 0.0 {
            self.effective_records(j) / r
        } else {
            0.0
        }
    }
}
