//! The directional kind: a plane-wave source `exp(i k d . x)` and, its reciprocal, a far-field
//! sensor reading the scattering amplitude `A(v)` of `u(R v) = A(v) exp(i k R) / R` (Bar et al.
//! 2019, Eqs. 19, 24-25). Everything about this kind is here: validation, reciprocity, the
//! scalar leg, the vectorised kernel and its exact vacuum field for the wave solver.
//!
//! A directional endpoint in its source form has a propagation direction `d` (`d = i` for a
//! plane wave, `d = -v` for the far-field sensor `v`, which reads what a plane wave along `-v`
//! would illuminate): the leg to `x` has the phase `k d . x` and is attenuated along `-d` from
//! `x` to the boundary.

use crate::kernels::BoxMedium;
use crate::{EndpointError, Leg, Side, check, fastmath};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Medium, field_attenuation};

/// Validates a direction: finite, non-zero (normalised), in the plane `z = 0` in flatland.
pub(crate) fn validated<M: Medium>(
    field: &str,
    direction: DVec3,
    m: &M,
) -> Result<DVec3, EndpointError> {
    check::in_plane(field, direction, m.dimension())?;
    check::unit(field, direction)
}

/// The leg of the directional endpoint of propagation direction `d` (source form) at `x`:
/// `tau xi = exp(-sigma_t t / 2) exp(i k d . x)`, `t` the distance from `x` to the boundary
/// along `-d`.
#[inline]
pub(crate) fn leg<M: Medium>(m: &M, k: f64, d: DVec3, x: DVec3, side: Side) -> Leg {
    let att = field_attenuation(m.optical_depth_to_infinity(x, -d));
    Leg {
        amp: Complex64::from_polar(att, k * d.dot(x)),
        dir: side.direction(d),
    }
}

/// The exact vacuum field of the plane wave of propagation direction `d` at `x` (unit
/// amplitude).
#[inline]
pub(crate) fn incident(k: f64, d: DVec3, x: DVec3) -> Complex64 {
    Complex64::from_polar(1.0, k * d.dot(x))
}

/// Directional endpoints, structure of arrays: the phase is `kx x + ky y + kz z`, the
/// attenuation exponent `max_a (c_a q_a + r_a)` (see [`far_coefficients`]). Their leg
/// directions are constant: `Endpoints::legs` fills them in once.
#[derive(Debug, Clone, Default)]
pub(crate) struct Run {
    k: [Vec<f64>; 3],
    q: [Vec<f64>; 3],
    r: [Vec<f64>; 3],
}

impl Run {
    /// Appends the endpoint of propagation direction `d` (source form).
    pub(crate) fn push(&mut self, g: &BoxMedium, k: f64, d: DVec3) {
        let (exit, kappa) = (-d, k * d);
        for a in 0..3 {
            let (q, r) = far_coefficients(exit[a], g.half[a], g.half_sigma_t);
            self.k[a].push(kappa[a]);
            self.q[a].push(q);
            self.r[a].push(r);
        }
    }

    /// The kernel: `re + i im = exp(max_a(c_a q_a + r_a)) exp(i kappa . x)`. Returns false if a
    /// phase was out of the range of the vectorised `sin_cos`.
    /// Compiled for the CPU's widest vector instructions, chosen at run time (`pulp`); bitwise
    /// the same on every instruction set (no contraction into fused multiply-adds).
    #[inline(never)]
    pub(crate) fn connect(&self, g: &BoxMedium, x: DVec3, re: &mut [f64], im: &mut [f64]) -> bool {
        // A generic `WithSimd` (not a closure) is monomorphised inside each instruction set's
        // function, so the loop is inlined and vectorised there.
        struct Op<'a> {
            run: &'a Run,
            g: &'a BoxMedium,
            x: DVec3,
            re: &'a mut [f64],
            im: &'a mut [f64],
        }
        impl pulp::WithSimd for Op<'_> {
            type Output = bool;
            #[inline(always)]
            fn with_simd<S: pulp::Simd>(self, _: S) -> bool {
                self.run.connect_lanes(self.g, self.x, self.re, self.im)
            }
        }
        pulp::Arch::new().dispatch(Op {
            run: self,
            g,
            x,
            re,
            im,
        })
    }

    /// The loop of [`Run::connect`], inlined into each instruction set's version.
    #[inline(always)]
    pub(crate) fn connect_lanes(
        &self,
        g: &BoxMedium,
        x: DVec3,
        re: &mut [f64],
        im: &mut [f64],
    ) -> bool {
        let n = re.len();
        let c = g.center - x;
        let (kx, ky, kz) = (&self.k[0][..n], &self.k[1][..n], &self.k[2][..n]);
        let (qx, qy, qz) = (&self.q[0][..n], &self.q[1][..n], &self.q[2][..n]);
        let (rx, ry, rz) = (&self.r[0][..n], &self.r[1][..n], &self.r[2][..n]);
        let im = &mut im[..n];
        let mut in_range = true;
        for i in 0..n {
            // Attenuation exponent -sigma_t t / 2 (t: distance to the boundary, Eq. 24).
            let ex = c.x * qx[i] + rx[i];
            let ey = c.y * qy[i] + ry[i];
            let ez = c.z * qz[i] + rz[i];
            let e = if ex > ey { ex } else { ey };
            let e = if ez > e { ez } else { e };
            let e = if e > 0.0 { 0.0 } else { e };
            // Phase: k i.x for a plane wave, -k v.x for a far-field sensor (Eqs. 19, 25).
            let phase = kx[i] * x.x + ky[i] * x.y + kz[i] * x.z;
            let att = fastmath::exp(e);
            let (s, co) = fastmath::sin_cos_reduced(phase);
            in_range &= fastmath::in_sin_cos_range(phase);
            re[i] = att * co;
            im[i] = att * s;
        }
        in_range
    }
}

impl Run {
    /// The attenuation exponent `max_a (c_a q_a + r_a)` (`c = center - y`) of endpoint `i` at
    /// `y`, and the face `a` that attains it.
    #[inline]
    fn exponent(&self, i: usize, g: &BoxMedium, y: DVec3) -> (usize, f64) {
        let c = g.center - y;
        let mut best = (0, f64::NEG_INFINITY);
        for a in 0..3 {
            let e = c[a] * self.q[a][i] + self.r[a][i];
            if e > best.1 {
                best = (a, e);
            }
        }
        best
    }

    /// The rate `beta = d/ds ln leg_i(x + s u)` of endpoint `i` of the run along the line
    /// `x + s u`, `|s| <= reach`: `i kappa . u` from the phase and `-u_a q_a` from the
    /// attenuation exponent `max_a (c_a q_a + r_a)` (`c = center - x`) of the face `a` the leg
    /// leaves through. The exponent is a maximum of linear functions of `s`, so when the same
    /// face attains it at both ends of the segment it does all along (a convex function below its
    /// chord is the chord), and `leg_i(x + s u) = leg_i(x) exp(beta s)` exactly there. `None`
    /// when the face changes along the segment or an end lies outside the box.
    pub(crate) fn rate(
        &self,
        i: usize,
        g: &BoxMedium,
        x: DVec3,
        u: DVec3,
        reach: f64,
    ) -> Option<Complex64> {
        let (lo, hi) = (
            self.exponent(i, g, x - reach * u),
            self.exponent(i, g, x + reach * u),
        );
        if lo.0 != hi.0 || lo.1 > 0.0 || hi.1 > 0.0 || !lo.1.is_finite() {
            return None;
        }
        let a = lo.0;
        Some(Complex64::new(-u[a] * self.q[a][i], self.phase_rate(i, u)))
    }

    /// `kappa_i . u`, the rate of the phase of endpoint `i` along `u`.
    #[inline]
    fn phase_rate(&self, i: usize, u: DVec3) -> f64 {
        self.k[0][i] * u.x + self.k[1][i] * u.y + self.k[2][i] * u.z
    }

    /// `ln(leg_i(x + s u) / leg_i(x))` of endpoint `i` (both points in the box): the change of
    /// the attenuation exponent and `i s kappa . u`.
    pub(crate) fn log_ratio(
        &self,
        i: usize,
        g: &BoxMedium,
        x: DVec3,
        u: DVec3,
        s: f64,
    ) -> Complex64 {
        let (e0, e1) = (self.exponent(i, g, x).1, self.exponent(i, g, x + s * u).1);
        Complex64::new(e1.min(0.0) - e0.min(0.0), s * self.phase_rate(i, u))
    }
}

/// Coefficients `(q, r)` of one axis of the far-field attenuation exponent: for a unit exit
/// direction with component `e`, the distance from `x` to the face it heads for is
/// `t = (c + h sgn e) / e` (`c = center - x`, `h` the half size), so `-sigma_t t / 2 = c q + r`
/// with `q = -sigma_t / (2 e)` and `r = -sigma_t h / (2 |e|)`; an axis with `e = 0` never exits:
/// `q = 0`, `r = -inf`.
pub(crate) fn far_coefficients(e: f64, h: f64, half_sigma_t: f64) -> (f64, f64) {
    if e == 0.0 {
        (0.0, f64::NEG_INFINITY)
    } else {
        (-half_sigma_t / e, -half_sigma_t * h / e.abs())
    }
}
