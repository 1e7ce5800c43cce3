//! Fixed-axis weighted EM fit of a vMF mixture to a scattering amplitude (Bar et al. 2020,
//! Sec. 5.1, after Banerjee et al. 2005).

use crate::VmfError;
use crate::algebra::{inverse_mean_resultant_length, ln_vmf_normaliser};
use crate::mixture::{MAX_COMPONENTS, MAX_GAMMA, VmfMixture};
use speckle_rng::{GOLDEN_GAMMA, splitmix64};
use std::f64::consts::PI;

/// Options of [`fit_amplitude`] and [`fit_amplitude_fixed`]. Build with `Default` and struct
/// update syntax; the fit validates them and names the offending field.
#[derive(Debug, Clone, PartialEq)]
pub struct FitOptions {
    /// Target relative L2 residual of the amplitude, `||s_fit - |s|||_2 / |||s|||_2` over the
    /// sphere; finite and `> 0` (default `0.02`).
    pub tolerance: f64,
    /// Largest number of lobes [`fit_amplitude`] tries, in `1..=64` (default 13, the reference
    /// renderer's `MAX_DIM`).
    pub max_components: usize,
    /// EM iterations per fit, in `1..=10^8` (default `20_000`).
    pub max_iterations: u64,
    /// Quadrature nodes in the scattering angle: 8-point Gauss-Legendre on `angles / 8` equal
    /// panels of `[0, pi]`; a multiple of 8 in `[64, 2^22]` (default 1024: panels of `0.025` rad,
    /// which resolve lobes up to `|gamma| ~ 1e4` and HG up to `g ~ 0.99`; halving it changes the
    /// HG fits' residuals by less than `1e-4`). A target the grid does not resolve is rejected.
    pub angles: usize,
    /// EM stops when its weighted mean log-likelihood (nats) changes by less than this over 100
    /// iterations; finite and `>= 0` (default `1e-9`).
    pub em_tolerance: f64,
    /// Seed of the initial concentrations (a counter-based hash; the fit is deterministic).
    pub seed: u64,
}

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            tolerance: 0.02,
            max_components: 13,
            max_iterations: 20_000,
            angles: 1024,
            em_tolerance: 1e-9,
            seed: 0,
        }
    }
}

impl FitOptions {
    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), VmfError> {
        let bad =
            |field: &'static str, reason: String| Err(VmfError::InvalidOption { field, reason });
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return bad(
                "tolerance",
                format!("must be finite and > 0 (got {})", self.tolerance),
            );
        }
        if !(1..=MAX_COMPONENTS).contains(&self.max_components) {
            return bad(
                "max_components",
                format!(
                    "must be in 1..={MAX_COMPONENTS} (got {})",
                    self.max_components
                ),
            );
        }
        if !(1..=100_000_000).contains(&self.max_iterations) {
            return bad(
                "max_iterations",
                format!("must be in 1..=100000000 (got {})", self.max_iterations),
            );
        }
        if !(64..=1 << 22).contains(&self.angles) || !self.angles.is_multiple_of(8) {
            return bad(
                "angles",
                format!(
                    "must be a multiple of 8 in [64, 4194304] (got {})",
                    self.angles
                ),
            );
        }
        if !(self.em_tolerance.is_finite() && self.em_tolerance >= 0.0) {
            return bad(
                "em_tolerance",
                format!("must be finite and >= 0 (got {})", self.em_tolerance),
            );
        }
        Ok(())
    }
}

/// The result of a fit. `converged` is true only if the residual is at most the tolerance and
/// the mean cosine was matched to `1e-6`; otherwise the report is the best fit found, and says so.
#[derive(Debug, Clone, PartialEq)]
pub struct FitReport {
    /// The fitted mixture; its [`VmfMixture::raw_amplitude`] approximates the target's `|s|`
    /// (scaled so that `int s_fit dOmega = int |s| dOmega`), and its [`VmfMixture::amplitude`] is
    /// normalised.
    pub mixture: VmfMixture,
    /// Number of lobes (after pruning and merging; can be below the number requested).
    pub components: usize,
    /// Relative L2 residual of the amplitude over the sphere, `||s_fit - |s|||_2 / |||s|||_2`
    /// (`dOmega` measure, on the quadrature grid), after the mean-cosine correction.
    pub residual: f64,
    /// The target's mean cosine.
    pub g_target: f64,
    /// The fitted (normalised) mixture's mean cosine, [`VmfMixture::mean_cosine`].
    pub g_fit: f64,
    /// EM iterations spent on the returned fit.
    pub iterations: u64,
    /// Whether `residual <= tolerance` and `|g_fit - g_target| <= 1e-6`.
    pub converged: bool,
}

/// Largest accepted `|g_fit - g_target|` after the mean-cosine correction.
pub const G_TOLERANCE: f64 = 1e-6;

/// Fits the modulus `|s(mu)|` of a normalised 3D scattering amplitude (`int |s|^2 dOmega = 1`)
/// whose mean cosine is `mean_cosine`, with the smallest number of vMF lobes `k = 1, 2, ...,
/// max_components` whose relative L2 residual is at most `options.tolerance`, and returns that
/// fit with `converged: true`; if no `k` reaches it, the fit with the smallest residual, with
/// `converged: false`.
///
/// `modulus` is called at the quadrature nodes only (`options.angles` times). For a phase
/// function of `speckle-phase`, `speckle_phase::fit_vmf(&phase, &options)` passes
/// `|s| = sqrt(rho)` and `g` for you. Each `k` is fitted by [`fit_amplitude_fixed`]; see there for
/// the method.
///
/// Errors: invalid options ([`VmfError::InvalidOption`]); a target whose modulus is not finite
/// and non-negative on the grid, that is not normalised or that the grid does not resolve, or
/// whose `mean_cosine` is not in `(-1, 1)` or disagrees with the quadrature of `|s|^2`
/// ([`VmfError::InvalidTarget`]).
///
/// ```
/// use speckle_vmf::{FitOptions, fit_amplitude};
/// use std::f64::consts::PI;
/// // Henyey-Greenstein: |s| = sqrt(rho), rho = (1 - g^2) / (4 pi (1 + g^2 - 2 g mu)^(3/2)).
/// let g = 0.9;
/// let rho = |mu: f64| (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
/// let modulus = |mu: f64| rho(mu).sqrt();
/// let fit = fit_amplitude(modulus, g, &FitOptions::default()).unwrap();
/// assert!(fit.converged && fit.residual <= 0.02);
/// assert!((fit.mixture.mean_cosine() - 0.9).abs() <= 1e-6);
/// // The fitted amplitude has the target's scale.
/// let (a, b) = (fit.mixture.raw_amplitude(0.5), modulus(0.5));
/// assert!((a - b).abs() < 0.1 * b);
/// ```
pub fn fit_amplitude(
    modulus: impl Fn(f64) -> f64,
    mean_cosine: f64,
    options: &FitOptions,
) -> Result<FitReport, VmfError> {
    options.validate()?;
    let problem = Problem::new(&modulus, mean_cosine, options)?;
    let mut best: Option<FitReport> = None;
    for k in 1..=options.max_components {
        let report = problem.fit(k, options)?;
        if report.converged {
            return Ok(report);
        }
        if best.as_ref().is_none_or(|b| report.residual < b.residual) {
            best = Some(report);
        }
    }
    Ok(best.expect("max_components >= 1"))
}

/// Fits the modulus `|s(mu)|` of a normalised 3D scattering amplitude with mean cosine
/// `mean_cosine` (as for [`fit_amplitude`]) with (at most) `k` vMF lobes on the axis `+-i`, `k`
/// in `1..=64`.
///
/// Method (as the authors' reference code), with the differences stated:
///
/// 1. **Target.** The modulus `|s(mu)|` (for a phase function, `sqrt(rho(mu))`): any complex
///    phase of the amplitude (e.g. of Mie data) is discarded, as in the reference, and the fitted
///    `s` is real and positive.
/// 2. **Samples.** The lobes' axes are fixed to `+-i`, so only `mu = cos theta` matters and the
///    reference's random azimuths are integrated out exactly: samples are Gauss-Legendre nodes in
///    `theta` (`options.angles`) with weights `W_n = 2 pi w_n sin(theta_n) |s(cos theta_n)|`,
///    i.e. the reference's `sin theta` Jacobian times the amplitude.
/// 3. **Initialisation.** The first `k/2 + 1` lobes point along the dominant hemisphere
///    `sign(sum W_n mu_n)`, the rest the other way; `kappa_m = |N(0, 1)|` from a counter-based
///    hash of `(seed, k, m)`; `alpha_m = 1/k`; for `k > 1` lobe 0 is an isotropic "DC" lobe
///    pinned at `kappa = 0` until its weight falls below `alpha_min` and it is pruned.
/// 4. **E-step.** `log p_nm = ln alpha_m + ln C_3(kappa_m) + kappa_m (+-mu_n)`; responsibilities
///    times weights `r_nm = W_n p_nm / sum_m p_nm`.
/// 5. **M-step.** `alpha_m = sum_n r_nm / sum_n W_n`; the mean resultant along the fixed axis,
///    `rbar = sum_n r_nm (+-mu_n) / sum_n r_nm` (computed as `1 - rbar` from `1 -+ mu_n` to keep
///    the digits of sharp lobes); `kappa_m = A_3^{-1}(rbar)` by Banerjee's approximation
///    `(3 rbar - rbar^3) / (1 - rbar^2)` refined by Newton steps (to full precision rather than a
///    fixed 100 steps); `rbar <= 0` gives `kappa = 0`. Axes are not updated.
/// 6. **Pruning and merging.** Lobes with `alpha < 0.01 / k` are dropped (weights
///    renormalised); every 100 iterations lobes with `|gamma_a - gamma_b| < 1e-4` are merged.
/// 7. **Stopping.** Every 100 iterations: the weighted mean log-likelihood changed by less than
///    `options.em_tolerance` (the reference uses an absolute `1e-4` on an unweighted sum, which
///    depends on the sample count), or `options.max_iterations`.
/// 8. **Mean cosine.** The EM fit is a Kullback-Leibler fit of `|s|`, so the mean cosine of the
///    normalised `s_fit^2` misses the target's by up to about `1e-2`. It is corrected by scaling
///    the concentrations of all lobes on the side of `sign(g_target)` (for `g_target = 0`, the
///    side opposite to the EM fit's `g`) by one common factor `t`, found by bracketing and
///    bisection: as `t -> 0`
///    those lobes become isotropic and as `t -> inf` they become delta-like, so `g` sweeps from
///    below to above any reachable target, and the lobes' masses `alpha_m` (hence the scale
///    below) are unchanged. The factor stays close to 1 for good fits. If no bracket exists
///    (e.g. no lobe on that side), the fit is returned uncorrected and not `converged`.
/// 9. **Scale.** The masses are rescaled so that `int s_fit dOmega = int |s| dOmega` (the
///    reference's `hgMean / meanVals`), and the residual is computed on the quadrature grid.
///
/// Deterministic: the same target, `k` and options give bit-identical results.
///
/// ```
/// use speckle_vmf::{FitOptions, VmfMixture, fit_amplitude_fixed};
/// let truth = VmfMixture::new(vec![(0.0, 0.3), (20.0, 1.0), (-2.0, 0.2)]).unwrap();
/// let modulus = |mu| truth.amplitude(mu).re;
/// let fit = fit_amplitude_fixed(modulus, truth.mean_cosine(), 3, &FitOptions::default()).unwrap();
/// assert!(fit.residual < 1e-3, "{}", fit.residual);
/// assert!(fit.converged);
/// ```
pub fn fit_amplitude_fixed(
    modulus: impl Fn(f64) -> f64,
    mean_cosine: f64,
    k: usize,
    options: &FitOptions,
) -> Result<FitReport, VmfError> {
    options.validate()?;
    if !(1..=MAX_COMPONENTS).contains(&k) {
        return Err(VmfError::InvalidOption {
            field: "k",
            reason: format!("must be in 1..={MAX_COMPONENTS} (got {k})"),
        });
    }
    let problem = Problem::new(&modulus, mean_cosine, options)?;
    problem.fit(k, options)
}

/// The 8-point Gauss-Legendre rule on `[-1, 1]`: nodes and weights.
pub(crate) fn gauss_legendre_8() -> ([f64; 8], [f64; 8]) {
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    (
        [-X[3], -X[2], -X[1], -X[0], X[0], X[1], X[2], X[3]],
        [W[3], W[2], W[1], W[0], W[0], W[1], W[2], W[3]],
    )
}

/// The discretised target: quadrature nodes in `theta` and the target amplitude at them.
struct Problem {
    /// `mu_n = cos theta_n`.
    mu: Vec<f64>,
    /// `1 - mu_n` and `1 + mu_n`, exact from half angles.
    one_minus: Vec<f64>,
    one_plus: Vec<f64>,
    /// Solid-angle quadrature weights: `sum_n dw_n f(mu_n) ~ int f dOmega`.
    dw: Vec<f64>,
    /// Target `|s(mu_n)|`.
    amplitude: Vec<f64>,
    /// EM sample weights `W_n = dw_n |s(mu_n)|`.
    weight: Vec<f64>,
    /// `sum_n W_n ~ int |s| dOmega`.
    total: f64,
    /// `sum_n dw_n |s|^2 ~ int |s|^2 dOmega`.
    norm2: f64,
    g_target: f64,
}

impl Problem {
    fn new(
        modulus: &dyn Fn(f64) -> f64,
        g_target: f64,
        options: &FitOptions,
    ) -> Result<Self, VmfError> {
        if !(g_target.is_finite() && g_target.abs() < 1.0) {
            return Err(VmfError::InvalidTarget(format!(
                "mean cosine {g_target} is not in (-1, 1)"
            )));
        }
        let (x, w) = gauss_legendre_8();
        let panels = options.angles / 8;
        let h = PI / panels as f64;
        let n = options.angles;
        let mut p = Problem {
            mu: Vec::with_capacity(n),
            one_minus: Vec::with_capacity(n),
            one_plus: Vec::with_capacity(n),
            dw: Vec::with_capacity(n),
            amplitude: Vec::with_capacity(n),
            weight: Vec::with_capacity(n),
            total: 0.0,
            norm2: 0.0,
            g_target,
        };
        // int mu |s|^2 dOmega on the grid, to check the given mean cosine.
        let mut first_moment = 0.0;
        for panel in 0..panels {
            let centre = (panel as f64 + 0.5) * h;
            for (xi, wi) in x.iter().zip(w.iter()) {
                let theta = centre + 0.5 * h * xi;
                let (s2, c2) = (0.5 * theta).sin_cos();
                let mu = theta.cos();
                let a = modulus(mu);
                if !(a.is_finite() && a >= 0.0) {
                    return Err(VmfError::InvalidTarget(format!(
                        "|s({mu})| = {a} is not finite and non-negative"
                    )));
                }
                // dOmega = 2 pi sin(theta) dtheta
                let dw = 2.0 * PI * 0.5 * h * wi * theta.sin();
                let rho = a * a;
                p.mu.push(mu);
                p.one_minus.push(2.0 * s2 * s2);
                p.one_plus.push(2.0 * c2 * c2);
                p.dw.push(dw);
                p.amplitude.push(a);
                p.weight.push(dw * a);
                p.total += dw * a;
                p.norm2 += dw * rho;
                first_moment += dw * rho * mu;
            }
        }
        // The target is normalised (int |s|^2 dOmega = 1): a quadrature far from 1 means the grid
        // misses its features.
        if p.norm2.is_nan() || (p.norm2 - 1.0).abs() > 1e-3 {
            return Err(VmfError::InvalidTarget(format!(
                "the quadrature of |s|^2 on {n} angles is {} instead of 1 (a feature \
                 narrower than the grid, or an unnormalised amplitude): increase FitOptions::angles",
                p.norm2
            )));
        }
        // The mean cosine is given separately from |s|: to the same accuracy, they must agree.
        let g_grid = first_moment / p.norm2;
        if (g_grid - g_target).abs() > 1e-3 {
            return Err(VmfError::InvalidTarget(format!(
                "mean cosine {g_target} disagrees with the quadrature of |s|^2 on {n} angles \
                 ({g_grid})"
            )));
        }
        Ok(p)
    }

    /// EM with `k` lobes, then the mean-cosine correction and the scale.
    fn fit(&self, k: usize, options: &FitOptions) -> Result<FitReport, VmfError> {
        let (lobes, iterations) = self.em(k, options);
        let total = self.total;
        // Lobes with gamma on `side` scaled by t; masses scaled to int s_fit dOmega = int |s| dOmega.
        let build = |t: f64, side: f64| {
            VmfMixture::new(
                lobes
                    .iter()
                    .map(|&(gamma, alpha)| {
                        let g = if gamma * side > 0.0 {
                            (gamma * t).clamp(-MAX_GAMMA, MAX_GAMMA)
                        } else {
                            gamma
                        };
                        (g, alpha * total)
                    })
                    .collect(),
            )
            .map_err(|e| {
                VmfError::InvalidTarget(format!("the EM produced an invalid mixture: {e}"))
            })
        };
        let mut mixture = build(1.0, 1.0)?;
        let g0 = mixture.mean_cosine();
        if (g0 - self.g_target).abs() > 0.1 * G_TOLERANCE {
            let side = if self.g_target > 0.0 || (self.g_target == 0.0 && g0 < 0.0) {
                1.0
            } else {
                -1.0
            };
            let g = |t: f64| build(t, side).map_or(f64::NAN, |m| m.mean_cosine());
            if let Some(t) = self.match_mean_cosine(g, side) {
                mixture = build(t, side)?;
            }
        }
        let residual = self.residual(&mixture);
        let g_fit = mixture.mean_cosine();
        Ok(FitReport {
            components: mixture.len(),
            converged: residual <= options.tolerance
                && (g_fit - self.g_target).abs() <= G_TOLERANCE,
            mixture,
            residual,
            g_target: self.g_target,
            g_fit,
            iterations,
        })
    }

    /// The factor `t` with `g(t) = g_target`, where `g` moves towards `side` as `t` grows; `None`
    /// without a bracket.
    fn match_mean_cosine(&self, g: impl Fn(f64) -> f64, side: f64) -> Option<f64> {
        // f(t) = side (g(t) - g_target) grows with t (where the bracket holds).
        let f = |t: f64| side * (g(t) - self.g_target);
        let (mut lo, mut hi) = (1.0, 1.0);
        let f1 = f(1.0);
        if f1 < 0.0 {
            while f(hi) < 0.0 {
                hi *= 2.0;
                if hi > 1e8 {
                    return None;
                }
            }
        } else {
            while f(lo) > 0.0 {
                lo *= 0.5;
                if lo < 1e-8 {
                    return None;
                }
            }
        }
        // Bisection to the resolution of t (g is smooth in t, about 55 steps).
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            let fm = f(mid);
            if fm == 0.0 {
                return Some(mid);
            }
            if fm < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        // The end with the smaller mismatch.
        Some(if f(lo).abs() <= f(hi).abs() { lo } else { hi })
    }

    /// `||s_fit - |s|||_2 / |||s|||_2` on the grid.
    fn residual(&self, mixture: &VmfMixture) -> f64 {
        let mut err = 0.0;
        for ((&mu, &dw), &a) in self.mu.iter().zip(&self.dw).zip(&self.amplitude) {
            let d = mixture.raw_amplitude(mu) - a;
            err += dw * d * d;
        }
        (err / self.norm2).sqrt()
    }

    /// Fixed-axis weighted EM with `k` lobes; returns `(gamma, alpha)` per lobe (`sum alpha =
    /// 1`) and the iteration count.
    fn em(&self, k: usize, options: &FitOptions) -> (Vec<(f64, f64)>, u64) {
        #[derive(Clone, Copy)]
        struct Lobe {
            sign: f64,
            kappa: f64,
            alpha: f64,
        }
        let dominant = if self
            .weight
            .iter()
            .zip(&self.mu)
            .map(|(w, m)| w * m)
            .sum::<f64>()
            >= 0.0
        {
            1.0
        } else {
            -1.0
        };
        let forward = k / 2 + 1;
        let mut lobes: Vec<Lobe> = (0..k)
            .map(|m| Lobe {
                sign: if m < forward { dominant } else { -dominant },
                kappa: if k > 1 && m == 0 {
                    0.0
                } else {
                    half_normal(options.seed, k as u64, m as u64)
                },
                alpha: 1.0 / k as f64,
            })
            .collect();
        let mut dc = k > 1;
        let alpha_min = 0.01 / k as f64;
        let n = self.mu.len();
        let mut log_p = vec![0.0; k];
        let mut resp = vec![0.0; k];
        let mut spread = vec![0.0; k];
        let mut previous = f64::NEG_INFINITY;
        let mut iterations = 0;
        while iterations < options.max_iterations {
            iterations += 1;
            let kk = lobes.len();
            // E-step: log p_nm = ln alpha_m + ln C_3(kappa_m) + kappa_m (+-mu_n).
            let offset: Vec<f64> = lobes
                .iter()
                .map(|l| l.alpha.ln() + ln_vmf_normaliser(l.kappa))
                .collect();
            let slope: Vec<f64> = lobes.iter().map(|l| l.sign * l.kappa).collect();
            resp[..kk].fill(0.0);
            spread[..kk].fill(0.0);
            let mut loglik = 0.0;
            for i in 0..n {
                let mu = self.mu[i];
                let mut top = f64::NEG_INFINITY;
                for m in 0..kk {
                    log_p[m] = offset[m] + slope[m] * mu;
                    top = top.max(log_p[m]);
                }
                let mut sum = 0.0;
                for lp in &mut log_p[..kk] {
                    *lp = (*lp - top).exp();
                    sum += *lp;
                }
                let w = self.weight[i];
                if w == 0.0 {
                    continue;
                }
                loglik += w * (top + sum.ln());
                let scale = w / sum;
                let (om, op) = (self.one_minus[i], self.one_plus[i]);
                for m in 0..kk {
                    let r = log_p[m] * scale;
                    resp[m] += r;
                    // r (1 - (+-mu)): the distance of the sample from the lobe's axis.
                    spread[m] += r * if lobes[m].sign > 0.0 { om } else { op };
                }
            }
            loglik /= self.total;
            // M-step.
            for (m, l) in lobes.iter_mut().enumerate() {
                l.alpha = resp[m] / self.total;
                if !(dc && m == 0) && resp[m] > 0.0 {
                    // A_3(kappa) = rbar, 1 - rbar = spread / resp.
                    l.kappa = inverse_mean_resultant_length(spread[m] / resp[m], MAX_GAMMA);
                }
            }
            // Pruning.
            if lobes.iter().any(|l| l.alpha < alpha_min) {
                if dc && lobes[0].alpha < alpha_min {
                    dc = false;
                }
                lobes.retain(|l| l.alpha >= alpha_min);
                let sum: f64 = lobes.iter().map(|l| l.alpha).sum();
                lobes.iter_mut().for_each(|l| l.alpha /= sum);
                previous = f64::NEG_INFINITY;
            }
            if iterations % 100 == 0 {
                // Merging.
                // Merging (the DC lobe, first, stays first and absorbs lobes with gamma ~ 0).
                let mut merged: Vec<Lobe> = Vec::with_capacity(lobes.len());
                for l in &lobes {
                    let gamma = l.sign * l.kappa;
                    if let Some(j) = merged
                        .iter()
                        .position(|q| (q.sign * q.kappa - gamma).abs() < 1e-4)
                    {
                        merged[j].alpha += l.alpha;
                    } else {
                        merged.push(*l);
                    }
                }
                if merged.len() < lobes.len() {
                    previous = f64::NEG_INFINITY;
                }
                lobes = merged;
                // Stopping.
                if (loglik - previous).abs() < options.em_tolerance {
                    break;
                }
                previous = loglik;
            }
        }
        // (+ 0.0 turns a DC lobe's -0.0 into 0.0.)
        let mut out: Vec<(f64, f64)> = lobes
            .iter()
            .map(|l| (l.sign * l.kappa + 0.0, l.alpha))
            .collect();
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        (out, iterations)
    }
}

/// `|N(0, 1)|` from a counter-based hash of `(seed, k, m)` (SplitMix64 finaliser, Box-Muller).
fn half_normal(seed: u64, k: u64, m: u64) -> f64 {
    let mix = |z: u64| splitmix64(z.wrapping_add(GOLDEN_GAMMA));
    let base = mix(seed ^ mix(k.wrapping_mul(0x1000_0000_01B3) ^ mix(m)));
    let unit = |z: u64| ((z >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64);
    let (u1, u2) = (unit(mix(base)), unit(mix(base ^ 0xD6E8_FEB8_6659_FD93)));
    ((-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()).abs()
}
