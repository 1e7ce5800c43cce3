//! A complex amplitude tabulated at nodes of one variable, with `|s|^2` and the unwrapped phase
//! linear between nodes: the shared engine of [`crate::TabulatedAmplitude`] (nodes in
//! `cos theta` on the sphere) and [`crate::FlatTabulatedAmplitude`] (nodes in the angle on the
//! circle).
//!
//! A piecewise-linear density is normalised exactly (the trapezoid rule is exact for it) and
//! sampled exactly by inverting its piecewise-quadratic CDF.

use crate::{Complex64, PhaseError};
use std::f64::consts::{PI, TAU};

/// The table; `rho` is normalised so that `weight * int rho dx = 1`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LinearTable {
    pub(crate) x: Vec<f64>,
    pub(crate) rho: Vec<f64>,
    phase: Vec<f64>,
    /// CDF at the nodes, `cdf[0] = 0`, `cdf[n] = 1`.
    cdf: Vec<f64>,
    weight: f64,
    /// `weight * int |s_table|^2 dx` of the table as given.
    pub(crate) input_norm: f64,
    /// Spacing when the nodes are uniform (fast lookup), else `None`.
    uniform_step: Option<f64>,
}

impl LinearTable {
    /// A table on `[lo, hi]` from strictly increasing nodes `x` spanning it (ends within 1e-9)
    /// and amplitudes `s`; `what` names the node variable in errors ("cosine", "angle").
    pub(crate) fn new(
        x: Vec<f64>,
        s: &[Complex64],
        (lo, hi): (f64, f64),
        weight: f64,
        what: &str,
    ) -> Result<Self, PhaseError> {
        let bad = |m: String| Err(PhaseError::InvalidTable(m));
        if x.len() != s.len() {
            return bad(format!("{} {what}s but {} amplitudes", x.len(), s.len()));
        }
        if x.len() < 2 {
            return bad("at least two nodes are needed".into());
        }
        if let Some(i) = x.iter().position(|m| !m.is_finite()) {
            return bad(format!("{what} {i} is not finite"));
        }
        if let Some(i) = s
            .iter()
            .position(|v| !(v.re.is_finite() && v.im.is_finite()))
        {
            return bad(format!("amplitude {i} is not finite"));
        }
        let n = x.len();
        if (x[0] - lo).abs() > 1e-9 || (x[n - 1] - hi).abs() > 1e-9 {
            return bad(format!(
                "{what}s must span [{lo}, {hi}] (got [{}, {}])",
                x[0],
                x[n - 1]
            ));
        }
        if let Some(i) = x.windows(2).position(|w| w[1] <= w[0]) {
            return bad(format!(
                "{what}s must increase strictly (node {} to {})",
                i,
                i + 1
            ));
        }
        let mut x = x;
        x[0] = lo;
        x[n - 1] = hi;
        let rho_in: Vec<f64> = s.iter().map(|v| v.norm_sqr()).collect();
        // Unwrap the phase so that it interpolates along the shortest way between nodes.
        let mut phase: Vec<f64> = Vec::with_capacity(n);
        for (i, v) in s.iter().enumerate() {
            let p = v.arg();
            match i {
                0 => phase.push(p),
                _ => {
                    let prev = phase[i - 1];
                    phase.push(prev + (p - prev + PI).rem_euclid(TAU) - PI);
                }
            }
        }
        let mut cdf = vec![0.0; n];
        for i in 1..n {
            cdf[i] = cdf[i - 1] + weight * (x[i] - x[i - 1]) * 0.5 * (rho_in[i - 1] + rho_in[i]);
        }
        let total = cdf[n - 1];
        if !(total > 0.0 && total.is_finite()) {
            return bad("the amplitude is zero everywhere".into());
        }
        let rho = rho_in.iter().map(|r| r / total).collect();
        cdf.iter_mut().for_each(|c| *c /= total);
        cdf[n - 1] = 1.0;
        let step = (hi - lo) / (n - 1) as f64;
        let uniform = x
            .iter()
            .enumerate()
            .all(|(i, &m)| (m - (lo + step * i as f64)).abs() < 1e-12 * (1.0 + hi - lo));
        Ok(Self {
            x,
            rho,
            phase,
            cdf,
            weight,
            input_norm: total,
            uniform_step: uniform.then_some(step),
        })
    }

    /// `weight * int f(x) rho(x) dx` for `f` linear on each segment's sub-intervals, by
    /// `panels`-point Simpson per segment (exact when `f` is a polynomial of degree <= 2).
    pub(crate) fn moment(&self, f: impl Fn(f64) -> f64, panels: usize) -> f64 {
        let panels = 2 * panels.div_ceil(2);
        let mut total = 0.0;
        for i in 1..self.x.len() {
            let (a, b) = (self.x[i - 1], self.x[i]);
            let h = (b - a) / panels as f64;
            let mut acc = 0.0;
            for p in 0..=panels {
                let t = a + h * p as f64;
                let w = match p {
                    0 => 1.0,
                    _ if p == panels => 1.0,
                    _ if p % 2 == 1 => 4.0,
                    _ => 2.0,
                };
                acc += w * f(t) * self.density((t - a) / (b - a), i - 1);
            }
            total += acc * h / 3.0;
        }
        self.weight * total
    }

    #[inline]
    fn density(&self, t: f64, i: usize) -> f64 {
        self.rho[i] + t * (self.rho[i + 1] - self.rho[i])
    }

    /// Index `i` of the segment `[x_i, x_{i+1}]` containing `x` (clamped to the range), and the
    /// fraction along it.
    #[inline]
    fn locate(&self, x: f64) -> (usize, f64) {
        let n = self.x.len();
        let x = x.clamp(self.x[0], self.x[n - 1]);
        let i = match self.uniform_step {
            Some(h) => (((x - self.x[0]) / h) as usize).min(n - 2),
            None => self.x.partition_point(|&m| m <= x).clamp(1, n - 1) - 1,
        };
        let t = (x - self.x[i]) / (self.x[i + 1] - self.x[i]);
        (i, t.clamp(0.0, 1.0))
    }

    /// The interpolated amplitude at `x`.
    #[inline]
    pub(crate) fn amplitude(&self, x: f64) -> Complex64 {
        let (i, t) = self.locate(x);
        let phi = self.phase[i] + t * (self.phase[i + 1] - self.phase[i]);
        Complex64::from_polar(self.density(t, i).max(0.0).sqrt(), phi)
    }

    /// The interpolated (normalised) density at `x`.
    #[inline]
    pub(crate) fn value(&self, x: f64) -> f64 {
        let (i, t) = self.locate(x);
        self.density(t, i)
    }

    /// Samples `x` with density `weight * rho(x)` from one uniform variate in `[0, 1)`.
    pub(crate) fn sample(&self, u: f64) -> f64 {
        let n = self.x.len();
        let i = self.cdf.partition_point(|&c| c <= u).clamp(1, n - 1) - 1;
        let (a, b) = (self.x[i], self.x[i + 1]);
        let h = b - a;
        let (ra, rb) = (self.weight * self.rho[i], self.weight * self.rho[i + 1]);
        // Solve cdf_i + ra x + (rb - ra) x^2 / (2 h) = u for x in [0, h].
        let target = u - self.cdf[i];
        let slope = (rb - ra) / h;
        let x = if slope.abs() * h < 1e-12 * (ra + rb).max(f64::MIN_POSITIVE) {
            target / ra.max(f64::MIN_POSITIVE)
        } else {
            // Stable root of 0.5 slope x^2 + ra x - target = 0.
            let disc = (ra * ra + 2.0 * slope * target).max(0.0);
            2.0 * target / (ra + disc.sqrt()).max(f64::MIN_POSITIVE)
        };
        (a + x.clamp(0.0, h)).clamp(self.x[0], self.x[n - 1])
    }
}
