//! Flatland (2D) phase functions: amplitudes normalised on the circle, `int |s|^2 dtheta = 1`.
//!
//! A flatland scatterer sees directions in the plane `z = 0`. Its amplitude is a function of the
//! signed scattering angle `theta` from the incoming to the outgoing propagation direction,
//! counter-clockwise positive, so tables need not be symmetric (`s(theta) != s(-theta)` is
//! allowed). The cosine-based methods of [`PhaseFunction`] refer to the counter-clockwise branch
//! `theta = acos(mu)` in `[0, pi]`; the estimators use [`PhaseFunction::amplitude_between`],
//! [`PhaseFunction::sample_direction`] and [`PhaseFunction::pdf_direction`], which use the signed
//! angle.

use crate::linear::LinearTable;
use crate::{Complex64, Dimension, PhaseError, PhaseFunction};
use glam::DVec3;
use std::f64::consts::{PI, TAU};

/// Signed angle from `a` to `b` in the plane, counter-clockwise positive, in `(-pi, pi]`.
#[inline]
pub fn signed_angle(a: DVec3, b: DVec3) -> f64 {
    (a.x * b.y - a.y * b.x).atan2(a.x * b.x + a.y * b.y)
}

/// `v` rotated counter-clockwise by `theta` in the plane (its `z` is dropped).
#[inline]
pub fn rotate_in_plane(v: DVec3, theta: f64) -> DVec3 {
    let (s, c) = theta.sin_cos();
    DVec3::new(c * v.x - s * v.y, s * v.x + c * v.y, 0.0)
}

/// A phase function on the circle, in terms of the signed angle; every flatland type
/// implements [`PhaseFunction`] through it.
pub(crate) trait Circular: Send + Sync {
    fn amplitude_at(&self, theta: f64) -> Complex64;
    fn density_at(&self, theta: f64) -> f64;
    /// Samples the signed angle with density `density_at` on `(-pi, pi]` (or `[0, 2 pi)`).
    fn sample_angle(&self, u: f64) -> f64;
    fn mean_cos(&self) -> f64;
}

impl<T: Circular> PhaseFunction for T {
    fn dimension(&self) -> Dimension {
        Dimension::Two
    }
    #[inline]
    fn amplitude(&self, mu: f64) -> Complex64 {
        self.amplitude_at(mu.clamp(-1.0, 1.0).acos())
    }
    #[inline]
    fn density(&self, mu: f64) -> f64 {
        self.density_at(mu.clamp(-1.0, 1.0).acos())
    }
    fn sample_cosine(&self, u: f64) -> f64 {
        self.sample_angle(u).cos()
    }
    fn mean_cosine(&self) -> f64 {
        self.mean_cos()
    }
    #[inline]
    fn amplitude_between(&self, incoming: DVec3, outgoing: DVec3) -> Complex64 {
        self.amplitude_at(signed_angle(incoming, outgoing))
    }
    fn sample_direction(&self, incoming: DVec3, u: [f64; 2]) -> DVec3 {
        rotate_in_plane(incoming, self.sample_angle(u[0]))
    }
    fn pdf_direction(&self, incoming: DVec3, outgoing: DVec3) -> f64 {
        self.density_at(signed_angle(incoming, outgoing))
    }
}

/// Isotropic flatland scattering: `s = 1 / sqrt(2 pi)`, `rho = 1 / (2 pi)` per radian.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FlatIsotropic;

impl Circular for FlatIsotropic {
    fn amplitude_at(&self, _theta: f64) -> Complex64 {
        Complex64::new((1.0 / TAU).sqrt(), 0.0)
    }
    fn density_at(&self, _theta: f64) -> f64 {
        1.0 / TAU
    }
    fn sample_angle(&self, u: f64) -> f64 {
        TAU * u - PI
    }
    fn mean_cos(&self) -> f64 {
        0.0
    }
}

/// The flatland Henyey-Greenstein function (the wrapped Cauchy distribution):
/// `rho(theta) = (1 - g^2) / (2 pi (1 + g^2 - 2 g cos theta))`, mean cosine `g`, amplitude
/// `sqrt(rho)`.
///
/// ```
/// use speckle_phase::{FlatHenyeyGreenstein, PhaseFunction};
/// let hg = FlatHenyeyGreenstein::new(0.5).unwrap();
/// assert_eq!(hg.mean_cosine(), 0.5);
/// assert!(FlatHenyeyGreenstein::new(-1.0).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatHenyeyGreenstein {
    g: f64,
}

impl FlatHenyeyGreenstein {
    /// Flatland HG with anisotropy `g`; rejects NaN and `|g| >= 1` (no clamping), as the 3D
    /// function does.
    pub fn new(g: f64) -> Result<Self, PhaseError> {
        Ok(Self {
            g: crate::HenyeyGreenstein::new(g)?.g(),
        })
    }

    /// The anisotropy parameter.
    pub fn g(&self) -> f64 {
        self.g
    }
}

impl Circular for FlatHenyeyGreenstein {
    fn amplitude_at(&self, theta: f64) -> Complex64 {
        Complex64::new(self.density_at(theta).sqrt(), 0.0)
    }
    fn density_at(&self, theta: f64) -> f64 {
        let g = self.g;
        (1.0 - g * g) / (TAU * (1.0 + g * g - 2.0 * g * theta.cos()))
    }
    fn sample_angle(&self, u: f64) -> f64 {
        // With t = tan(theta / 2) the density becomes a Cauchy law of scale (1 - g) / (1 + g).
        let g = self.g;
        2.0 * ((1.0 - g) / (1.0 + g) * (PI * (u - 0.5)).tan()).atan()
    }
    fn mean_cos(&self) -> f64 {
        self.g
    }
}

/// A flatland complex amplitude tabulated over the signed scattering angle in `[0, 2 pi]`
/// (`theta` and `theta + 2 pi` are the same direction). Between nodes `|s|^2` and the unwrapped
/// phase are linear in the angle, so the table is normalised and sampled exactly, as
/// [`crate::TabulatedAmplitude`] is in 3D.
///
/// The table is scaled so that `int |s|^2 dtheta = 1`; the integral of the table as given is
/// [`FlatTabulatedAmplitude::input_norm`].
///
/// ```
/// use speckle_phase::{Complex64, FlatTabulatedAmplitude, PhaseFunction};
/// use std::f64::consts::TAU;
/// let theta: Vec<f64> = (0..=360).map(|d| (d as f64).to_radians()).collect();
/// let s: Vec<Complex64> = theta.iter().map(|t| Complex64::new(2.0 + t.cos(), t.sin())).collect();
/// let t = FlatTabulatedAmplitude::new(theta, s).unwrap();
/// assert!(t.mean_cosine() > 0.0);
/// assert!((t.input_norm() - TAU * 5.0).abs() < 1e-3);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FlatTabulatedAmplitude {
    table: LinearTable,
    mean_cosine: f64,
}

impl FlatTabulatedAmplitude {
    /// A table from strictly increasing angles starting at 0 and the amplitude at each. If the
    /// last angle is below `2 pi`, the table is closed periodically with `s(2 pi) = s(0)`.
    pub fn new(theta: Vec<f64>, s: Vec<Complex64>) -> Result<Self, PhaseError> {
        let (mut theta, mut s) = (theta, s);
        if let (Some(&last), Some(&first)) = (theta.last(), s.first())
            && last.is_finite()
            && last < TAU - 1e-9
            && theta.len() == s.len()
            && theta.len() >= 2
        {
            theta.push(TAU);
            s.push(first);
        }
        let table = LinearTable::new(theta, &s, (0.0, TAU), 1.0, "angle")?;
        let mean_cosine = table.moment(f64::cos, 4);
        Ok(Self { table, mean_cosine })
    }

    /// `int |s_table|^2 dtheta` of the table as given, before normalisation.
    pub fn input_norm(&self) -> f64 {
        self.table.input_norm
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.table.x.len()
    }

    /// Whether the table is empty (never true for a constructed table).
    pub fn is_empty(&self) -> bool {
        self.table.x.is_empty()
    }
}

impl Circular for FlatTabulatedAmplitude {
    fn amplitude_at(&self, theta: f64) -> Complex64 {
        self.table.amplitude(theta.rem_euclid(TAU))
    }
    fn density_at(&self, theta: f64) -> f64 {
        self.table.value(theta.rem_euclid(TAU))
    }
    fn sample_angle(&self, u: f64) -> f64 {
        self.table.sample(u)
    }
    fn mean_cos(&self) -> f64 {
        self.mean_cosine
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Phase;
    use crate::testing::{ks_distance, uniform_stream};
    use std::sync::Arc;

    /// `int rho dtheta` and `int cos(theta) rho dtheta` by the midpoint rule with `n` panels.
    fn moments(p: &dyn Circular, n: usize) -> (f64, f64) {
        let h = TAU / n as f64;
        (0..n)
            .map(|i| {
                let t = -PI + h * (i as f64 + 0.5);
                let r = p.density_at(t);
                (h * r, h * r * t.cos())
            })
            .fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1))
    }

    /// `sqrt(n) * D` of `n` sampled directions' signed angles in `(-pi, pi]` against the CDF of
    /// the density (midpoint rule on a fine grid).
    fn ks_statistic(p: &Phase, n: usize) -> f64 {
        let mut next = uniform_stream(0x2545_F491_4F6C_DD1D);
        let inc = DVec3::new(0.6, -0.8, 0.0);
        let xs: Vec<f64> = (0..n)
            .map(|_| signed_angle(inc, p.sample_direction(inc, [next(), next()])))
            .collect();
        let m = 400_000;
        let h = TAU / m as f64;
        let mut cdf = vec![0.0; m + 1];
        for i in 1..=m {
            let t = -PI + h * (i as f64 - 0.5);
            cdf[i] = cdf[i - 1] + h * p.pdf_direction(inc, rotate_in_plane(inc, t));
        }
        let total = cdf[m];
        ks_distance(xs, |x: f64| {
            let t = ((x + PI) / h).clamp(0.0, m as f64 - 1e-9);
            let (i, a) = (t as usize, t.fract());
            (cdf[i] * (1.0 - a) + cdf[i + 1] * a) / total
        })
    }

    fn skewed_table() -> FlatTabulatedAmplitude {
        // Asymmetric: more light to positive angles, with an angle-dependent phase.
        let theta: Vec<f64> = (0..720).map(|i| i as f64 * TAU / 720.0).collect();
        let s = theta
            .iter()
            .map(|&t| Complex64::from_polar(1.2 + t.cos() + 0.5 * t.sin(), 2.0 * t.sin()))
            .collect();
        FlatTabulatedAmplitude::new(theta, s).unwrap()
    }

    #[test]
    fn flat_functions_are_normalised_with_their_mean_cosine() {
        let hg = FlatHenyeyGreenstein::new(0.7).unwrap();
        let t = skewed_table();
        let cases: [(&dyn Circular, f64); 4] = [
            (&FlatIsotropic, 0.0),
            (&hg, 0.7),
            (&FlatHenyeyGreenstein::new(-0.4).unwrap(), -0.4),
            (&t, t.mean_cosine()),
        ];
        for (p, g) in cases {
            let (m0, m1) = moments(p, 200_000);
            assert!((m0 - 1.0).abs() < 1e-6, "norm {m0}");
            assert!((m1 - g).abs() < 1e-6, "mean cosine {m1} vs {g}");
            let a = p.amplitude_at(0.3);
            assert!((a.norm_sqr() - p.density_at(0.3)).abs() < 1e-14);
        }
        // The table's mean cosine is that of the interpolated function, and it is forward.
        assert!(t.mean_cosine() > 0.3);
    }

    #[test]
    fn flat_samplers_pass_ks() {
        for p in [
            Phase::FlatIsotropic,
            Phase::flat_hg(0.8).unwrap(),
            Phase::flat_hg(-0.3).unwrap(),
            Phase::FlatTabulated(Arc::new(skewed_table())),
        ] {
            let s = ks_statistic(&p, 20_000);
            assert!(s < crate::testing::KS_CRITICAL_0_001, "{p:?}: KS {s}");
        }
    }

    #[test]
    fn a_wrong_density_fails_ks() {
        // The check has power: HG 0.5 samples judged against HG 0.4.
        let s = {
            let good = FlatHenyeyGreenstein::new(0.5).unwrap();
            let bad = FlatHenyeyGreenstein::new(0.4).unwrap();
            let mut xs: Vec<f64> = (0..20_000)
                .map(|i| good.sample_angle((i as f64 + 0.5) / 20_000.0))
                .collect();
            xs.sort_by(f64::total_cmp);
            // Exact CDF of `bad` by fine midpoint sums.
            let cdf = |x: f64| {
                let n = 4000;
                let h = (x + PI) / n as f64;
                (0..n)
                    .map(|i| h * bad.density_at(-PI + h * (i as f64 + 0.5)))
                    .sum::<f64>()
            };
            let d = xs
                .iter()
                .enumerate()
                .step_by(50)
                .map(|(i, &x)| (cdf(x) - (i as f64 + 0.5) / 20_000.0).abs())
                .fold(0.0, f64::max);
            (20_000f64).sqrt() * d
        };
        assert!(s > 2.0 * crate::testing::KS_CRITICAL_0_001, "KS {s}");
    }

    #[test]
    fn asymmetric_table_uses_the_signed_angle() {
        let t = skewed_table();
        let inc = DVec3::X;
        let up = rotate_in_plane(inc, 1.0);
        let down = rotate_in_plane(inc, -1.0);
        assert!((t.amplitude_between(inc, up) - t.amplitude_at(1.0)).norm() < 1e-15);
        assert!((t.amplitude_between(inc, down) - t.amplitude_at(TAU - 1.0)).norm() < 1e-15);
        assert!(t.density_at(1.0) > t.density_at(-1.0));
        assert!((signed_angle(inc, down) + 1.0).abs() < 1e-15);
    }

    #[test]
    fn table_closes_periodically_and_rejects_bad_input() {
        let c = |v: f64| Complex64::new(v, 0.0);
        let open = FlatTabulatedAmplitude::new(vec![0.0, PI], vec![c(1.0), c(2.0)]).unwrap();
        assert_eq!(open.len(), 3);
        assert!((open.amplitude_at(TAU - 1e-12) - open.amplitude_at(0.0)).norm() < 1e-9);
        assert!(FlatTabulatedAmplitude::new(vec![0.5, PI], vec![c(1.0), c(1.0)]).is_err());
        assert!(FlatTabulatedAmplitude::new(vec![0.0, 1.0, 1.0], vec![c(1.0); 3]).is_err());
        assert!(FlatTabulatedAmplitude::new(vec![0.0, f64::NAN], vec![c(1.0); 2]).is_err());
        assert!(FlatTabulatedAmplitude::new(vec![0.0, 1.0], vec![c(0.0); 2]).is_err());
        assert!(FlatTabulatedAmplitude::new(vec![0.0], vec![c(1.0)]).is_err());
    }
}
