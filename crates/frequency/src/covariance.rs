//! The 4D spectral covariance of a local light field and its operators along a path (Belcour et
//! al. 2014, Sec. 4, Fig. 3 and Eqs. 3-13; `shared/notes/frequency-2014.md` Sec. 2).
//!
//! Coordinates `(u, v, theta, phi)`: two transverse spatial ones in the plane perpendicular to
//! the central ray, two angular ones; the covariance is that of the power spectrum over the
//! frequencies `(Omega_u, Omega_v, Omega_theta, Omega_phi)`. The operators:
//!
//! - travel over `d` ([`SpectralCovariance::travel`]): `T_d^T S T_d`, the space-to-angle shear;
//! - rotation of the frame by `phi` ([`SpectralCovariance::rotate`]): `R^T S R`;
//! - scale / projection ([`SpectralCovariance::scale`]): `L S L`;
//! - occlusion and absorption ([`SpectralCovariance::occlude`], [`SpectralCovariance::absorb`]):
//!   `S + O` in the spatial block; for absorption (Eqs. 6-7) `O = dt |H_kappa| / (4 pi^2)`,
//!   `H_kappa` the transverse Hessian of the extinction. The paper prints the constant as
//!   `dt / 4 pi`; Eq. 2 (and the note) give `dt / (4 pi^2)`, which this follows;
//! - an angular filter ([`SpectralCovariance::angular_filter`]): `(S^-1 + B)^-1`,
//!   `B = diag(0, 0, b^-1)` (the BRDF operator);
//! - scattering by the angle `alpha` with a phase function of angular spectral covariance
//!   `sigma_rho` ([`SpectralCovariance::scatter`], Eqs. 11-12): `((V S V)^-1 + S_rho)^-1`,
//!   `V = diag(cos alpha, 1, 1, 1)`, `S_rho = diag(0, 0, sigma_rho^-1)`;
//! - merging ([`merge`]): the radiance-weighted average.
//!
//! `(S^-1 + P)^-1` is evaluated as `S (I + P S)^-1`, which needs no inverse of a degenerate `S`;
//! an infinite precision (a zero `sigma_rho` or `b` entry: an isotropic phase function removes
//! all angular bandwidth) conditions that coordinate to zero (`S - S e e^T S / (e^T S e)`), the
//! pseudo-inverse limit of the note.

use crate::matrix::{Mat, congruence, identity, inverse, mul};
use std::f64::consts::PI;

/// The spectral covariance of a local light field, a symmetric `4 x 4` matrix over
/// `(Omega_u, Omega_v, Omega_theta, Omega_phi)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpectralCovariance(pub Mat<4>);

impl SpectralCovariance {
    /// The zero covariance (a light field constant in space and angle).
    pub fn zero() -> Self {
        Self([[0.0; 4]; 4])
    }

    /// A diagonal covariance.
    pub fn diagonal(d: [f64; 4]) -> Self {
        let mut m = [[0.0; 4]; 4];
        for (i, v) in d.into_iter().enumerate() {
            m[i][i] = v;
        }
        Self(m)
    }

    /// Travel over the distance `d` along the ray: `T_d^T S T_d`,
    /// `T_d = [[1, 0, -d, 0], [0, 1, 0, -d], [0, 0, 1, 0], [0, 0, 0, 1]]`.
    pub fn travel(&self, d: f64) -> Self {
        Self(congruence(&travel_matrix(d), &self.0))
    }

    /// Rotation of the local frame about the ray by `phi`: `R^T S R`,
    /// `R = [[c, -s, 0, 0], [s, c, 0, 0], [0, 0, c, -s], [0, 0, s, c]]`.
    pub fn rotate(&self, phi: f64) -> Self {
        let (s, c) = phi.sin_cos();
        let r = [
            [c, -s, 0.0, 0.0],
            [s, c, 0.0, 0.0],
            [0.0, 0.0, c, -s],
            [0.0, 0.0, s, c],
        ];
        Self(congruence(&r, &self.0))
    }

    /// Scaling of the light field `f(l_1 x_1, ..., l_4 x_4)` (projection onto a tilted plane):
    /// `L S L`, `L = diag(l)`.
    pub fn scale(&self, l: [f64; 4]) -> Self {
        let mut m = self.0;
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v *= l[i] * l[j];
            }
        }
        Self(m)
    }

    /// Occlusion by an occluder of spatial spectral covariance `o` (or absorption, Eq. 6): `S`
    /// plus `o` in the spatial block.
    pub fn occlude(&self, o: [[f64; 2]; 2]) -> Self {
        let mut m = self.0;
        for i in 0..2 {
            for j in 0..2 {
                m[i][j] += o[i][j];
            }
        }
        Self(m)
    }

    /// Absorption over a step `dt` in a medium whose extinction has the transverse Hessian
    /// `hessian` (Eq. 7; see the module docs for the constant): [`SpectralCovariance::occlude`]
    /// with `dt |hessian| / (4 pi^2)`.
    pub fn absorb(&self, dt: f64, hessian: [[f64; 2]; 2]) -> Self {
        let a = crate::matrix::abs_symmetric(hessian);
        let f = dt / (4.0 * PI * PI);
        self.occlude([[f * a[0][0], f * a[0][1]], [f * a[1][0], f * a[1][1]]])
    }

    /// The angular filter `(S^-1 + B)^-1`, `B = diag(0, 0, 1 / b_theta, 1 / b_phi)` (the BRDF
    /// operator of Fig. 3): a zero entry of `b` removes that angular bandwidth entirely.
    pub fn angular_filter(&self, b: [f64; 2]) -> Self {
        Self(add_precision(
            &self.0,
            [0.0, 0.0, inv_or_inf(b[0]), inv_or_inf(b[1])],
        ))
    }

    /// Scattering by the angle `alpha` between the incoming and outgoing rays (Eqs. 11-12),
    /// frames aligned so that the first angular axis lies in the plane of both, with a phase
    /// function of angular spectral covariance `sigma_rho` (diagonal; [`crate::hg_covariance`]
    /// for Henyey-Greenstein, [`crate::phase_covariance`] for any other):
    /// `((V S V)^-1 + S_rho)^-1`.
    pub fn scatter(&self, alpha: f64, sigma_rho: [f64; 2]) -> Self {
        let v = self.scale([alpha.cos(), 1.0, 1.0, 1.0]);
        v.angular_filter(sigma_rho)
    }

    /// The trace.
    pub fn trace(&self) -> f64 {
        (0..4).map(|i| self.0[i][i]).sum()
    }

    /// The `2 x 2` spatial block of `S^-1` (the primal-domain spatial precision the volumetric
    /// grid accumulates, Eq. 16), or `None` when `S` is singular.
    pub fn spatial_precision(&self) -> Option<[[f64; 2]; 2]> {
        let inv = inverse(&self.0)?;
        Some([[inv[0][0], inv[0][1]], [inv[1][0], inv[1][1]]])
    }
}

/// `1 / b`, infinite for `b = 0`.
fn inv_or_inf(b: f64) -> f64 {
    if b == 0.0 { f64::INFINITY } else { 1.0 / b }
}

/// `T_d`.
pub fn travel_matrix(d: f64) -> Mat<4> {
    [
        [1.0, 0.0, -d, 0.0],
        [0.0, 1.0, 0.0, -d],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

/// `(S^-1 + diag(p))^-1` for non-negative `p` (infinite entries condition that coordinate to
/// zero), without inverting `S`.
fn add_precision(s: &Mat<4>, p: [f64; 4]) -> Mat<4> {
    let mut s = *s;
    for (i, &pi) in p.iter().enumerate() {
        if pi.is_infinite() {
            let sii = s[i][i];
            if sii > 0.0 {
                let col: [f64; 4] = [s[0][i], s[1][i], s[2][i], s[3][i]];
                for a in 0..4 {
                    for b in 0..4 {
                        s[a][b] -= col[a] * col[b] / sii;
                    }
                }
            }
            for k in 0..4 {
                s[i][k] = 0.0;
                s[k][i] = 0.0;
            }
        }
    }
    let mut ips = identity::<4>();
    for (i, &pi) in p.iter().enumerate() {
        if pi.is_finite() {
            for k in 0..4 {
                ips[i][k] += pi * s[i][k];
            }
        }
    }
    let inv = inverse(&ips).expect("I + P S is invertible for P, S positive semi-definite");
    let mut out = mul(&s, &inv);
    // Symmetrize the rounding.
    for a in 0..4 {
        for b in a + 1..4 {
            let m = 0.5 * (out[a][b] + out[b][a]);
            out[a][b] = m;
            out[b][a] = m;
        }
    }
    out
}

/// The radiance-weighted average `sum I_i S_i / sum I_i` of the covariances of several rays
/// (exact for an additive combination); `None` for no weight.
pub fn merge(parts: &[(f64, SpectralCovariance)]) -> Option<SpectralCovariance> {
    let total: f64 = parts.iter().map(|p| p.0).sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let mut m = [[0.0; 4]; 4];
    for (w, s) in parts {
        for (i, row) in m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += w * s.0[i][j] / total;
            }
        }
    }
    Some(SpectralCovariance(m))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matrix::determinant;

    fn close(a: &Mat<4>, b: &Mat<4>, tol: f64) -> bool {
        a.iter()
            .flatten()
            .zip(b.iter().flatten())
            .all(|(x, y)| (x - y).abs() <= tol)
    }

    fn sample() -> SpectralCovariance {
        SpectralCovariance([
            [2.0, 0.3, 0.1, 0.0],
            [0.3, 1.5, 0.0, 0.2],
            [0.1, 0.0, 0.8, 0.1],
            [0.0, 0.2, 0.1, 0.6],
        ])
    }

    #[test]
    fn travel_composes_and_keeps_the_determinant() {
        let (d1, d2) = (0.7, -1.9);
        let a = mul(&travel_matrix(d1), &travel_matrix(d2));
        assert!(close(&a, &travel_matrix(d1 + d2), 1e-15));
        let s = sample();
        assert!(close(
            &s.travel(d1).travel(d2).0,
            &s.travel(d1 + d2).0,
            1e-12
        ));
        // det T_d = 1, so travel keeps the determinant of S, and it is undone by T_-d.
        assert!((determinant(&travel_matrix(d1)) - 1.0).abs() < 1e-15);
        assert!((determinant(&s.travel(d1).0) - determinant(&s.0)).abs() < 1e-12);
        assert!(close(&s.travel(d1).travel(-d1).0, &s.0, 1e-12));
    }

    #[test]
    fn rotations_keep_the_spectrum() {
        let s = sample();
        let r = s.rotate(0.4);
        assert!((r.trace() - s.trace()).abs() < 1e-14);
        // Frobenius norm (sum of squared eigenvalues) is kept.
        let f = |m: &Mat<4>| m.iter().flatten().map(|v| v * v).sum::<f64>();
        assert!((f(&r.0) - f(&s.0)).abs() < 1e-12);
        assert!(close(&r.rotate(-0.4).0, &s.0, 1e-14));
    }

    #[test]
    fn constant_or_linear_extinction_leaves_the_covariance() {
        let s = sample();
        assert_eq!(s.absorb(0.3, [[0.0, 0.0], [0.0, 0.0]]), s);
        let h = [[1.0, 2.0], [2.0, 1.0]];
        let a = s.absorb(4.0 * PI * PI, h);
        // |h| = [[2, 1], [1, 2]] added to the spatial block.
        assert!((a.0[0][0] - s.0[0][0] - 2.0).abs() < 1e-12);
        assert!((a.0[0][1] - s.0[0][1] - 1.0).abs() < 1e-12);
        assert_eq!(a.0[2], s.0[2]);
    }

    #[test]
    fn scattering_limits() {
        let s = sample();
        // alpha = pi/2 removes the u row and column (cos(pi/2) = 6e-17).
        let perp = s.scatter(0.5 * PI, [0.5, 0.5]);
        for k in 0..4 {
            assert!(perp.0[0][k].abs() < 1e-15 && perp.0[k][0].abs() < 1e-15);
        }
        // An isotropic phase function (sigma_rho = 0) removes all angular bandwidth.
        let iso = s.scatter(0.3, [0.0, 0.0]);
        for a in 2..4 {
            for k in 0..4 {
                assert_eq!(iso.0[a][k], 0.0);
            }
        }
        // ... and leaves the spatial block as the Gaussian conditioning on zero angles.
        let v = s.scale([0.3f64.cos(), 1.0, 1.0, 1.0]).0;
        let sa = [[v[2][2], v[2][3]], [v[3][2], v[3][3]]];
        let det = sa[0][0] * sa[1][1] - sa[0][1] * sa[1][0];
        let inv = [
            [sa[1][1] / det, -sa[0][1] / det],
            [-sa[1][0] / det, sa[0][0] / det],
        ];
        for i in 0..2 {
            for j in 0..2 {
                let mut c = v[i][j];
                for a in 0..2 {
                    for b in 0..2 {
                        c -= v[i][2 + a] * inv[a][b] * v[2 + b][j];
                    }
                }
                assert!((iso.0[i][j] - c).abs() < 1e-12, "{i}{j}");
            }
        }
        // A finite filter equals (S^-1 + B)^-1 computed directly.
        let f = s.angular_filter([0.4, 0.25]);
        let mut direct = inverse(&s.0).unwrap();
        direct[2][2] += 1.0 / 0.4;
        direct[3][3] += 1.0 / 0.25;
        assert!(close(&f.0, &inverse(&direct).unwrap(), 1e-12));
        // The zero covariance stays zero.
        assert_eq!(
            SpectralCovariance::zero().scatter(0.2, [0.3, 0.3]),
            SpectralCovariance::zero()
        );
    }

    #[test]
    fn merge_is_the_weighted_average() {
        let (a, b) = (sample(), sample().travel(1.0));
        let m = merge(&[(1.0, a), (3.0, b)]).unwrap();
        for i in 0..4 {
            for j in 0..4 {
                assert!((m.0[i][j] - 0.25 * a.0[i][j] - 0.75 * b.0[i][j]).abs() < 1e-15);
            }
        }
        assert!(merge(&[]).is_none());
    }
}
