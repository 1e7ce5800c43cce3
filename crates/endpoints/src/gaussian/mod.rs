//! The focused Gaussian-beam kind (Bar et al. 2020, Secs. 4-5, Eqs. 9-10 and 23-27; notes
//! Secs. 3.1 and 4.2): a lens of Gaussian (vMF) apodization focused at a point, as a source and,
//! by reciprocity, as a sensor. Here: validation, the beam's exact vacuum field and far-field
//! amplitude (what the exact wave solver needs), its weighted aperture at a medium point and
//! the exact scattering connection `Upsilon(x, w)` for a vMF-mixture amplitude (Eqs. 15-16,
//! `B >= 2`).
//!
//! **Definition** (source form, absolute units of `docs/conventions.md`). A beam focused at `f`
//! with unit optical axis `a` (the direction the light propagates through the focus) and
//! concentration `gamma` is the superposition of unit plane waves (Eqs. 9-10)
//!
//! `u(x) = int m(w) e^(i k w . (x - f)) dw`,   `m(w) = C(gamma) e^(gamma a . w)`,
//!
//! over the sphere (the circle in flatland), with the unit-integral mask `C_3(gamma) =
//! gamma / (4 pi sinh gamma)` (`C_2 = 1 / (2 pi I_0(gamma))` in flatland; notes Sec. 4.2, erratum
//! 12). So `u(f) = 1`, and the integral has the closed form `4 pi C_3 sinh(b) / b` (flatland
//! `2 pi C_2 I_0(b)`), `b = sqrt(mu . mu)`, `mu = gamma a + i k (x - f)` (Eq. 29), evaluated in
//! log form by `speckle-vmf`.
//!
//! **Limits.** As `gamma -> inf` the beam is the unit plane wave `e^(i k a . (x - f))` (error
//! of order `k^2 |x - f|^2 / gamma`). Far from the focus, `|x - f| = R`, it is an outgoing
//! spherical (cylindrical) wave from the focus with the angular weight of the mask, plus the
//! incoming wave converging on it from the opposite side: in 3D
//! `u ~ (2 pi / (i k)) [m(r) e^(i k R) - m(-r) e^(-i k R)] / R`, so its outgoing far-field
//! amplitude is `A(v) = (2 pi / (i k)) m(v) e^(-i k v . f)` (flatland:
//! `sqrt(2 pi / k) e^(-i pi / 4) m(v) e^(-i k v . f)` with `u ~ A e^(i k R) / sqrt(R)`). At
//! `gamma = 0` the beam is the isotropic standing wave `sin(k r) / (k r)` (`J_0(k r)`), whose
//! outgoing half is the point source `e^(i k r) / r` times `1 / (2 i k)`: a focused beam is an
//! isotropic point in the far zone, not near the focus.
//!
//! **As a sensor** focused at `v` looking along `a_v` (light travelling along `a_v` into it),
//! the reading of a field with outgoing far-field amplitude `A(w)` is `int m(w) e^(i k w . v)
//! A(w) dw` (Eq. 9 with the lens of Eq. 10); for a point scatterer at `o` (`A = f e^(-i k w.o)`)
//! that is `f` times the field at `o` of the beam focused at `v` with axis `-a_v` (its source
//! form, as for the other kinds).
//!
//! Unlike point endpoints, a focus may lie inside the medium (microscopy focuses there); the
//! beam's field is finite everywhere.

use crate::{EndpointError, check};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Dimension, Medium};
use speckle_vmf::{
    Aperture, CircleAperture, ComplexVmf, MAX_APERTURE_GAMMA, VmfMixture, gamma_from_na,
};
use std::f64::consts::{PI, TAU};

/// A focused Gaussian beam in source form: focus, unit optical axis (the propagation direction
/// through the focus) and the vMF concentration of its aperture (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussianBeam {
    /// The focal point.
    pub focus: DVec3,
    /// The unit optical axis: the direction light propagates through the focus (source form).
    pub axis: DVec3,
    /// The aperture's vMF concentration `gamma >= 0` (`0`: isotropic; `gamma = 4 / NA^2`).
    pub concentration: f64,
}

impl GaussianBeam {
    /// A beam focused at `focus` along `axis` (normalised) with aperture concentration
    /// `concentration`. Errors name `<field>.axis` or `<field>.concentration`.
    pub fn new(
        field: &str,
        focus: DVec3,
        axis: DVec3,
        concentration: f64,
    ) -> Result<Self, EndpointError> {
        let axis = check::unit(&format!("{field}.axis"), axis)?;
        if !(concentration.is_finite() && (0.0..=MAX_APERTURE_GAMMA).contains(&concentration)) {
            return Err(check::invalid(
                format!("{field}.concentration"),
                format!("must be finite and in [0, {MAX_APERTURE_GAMMA}] (got {concentration})"),
            ));
        }
        Ok(Self {
            focus,
            axis,
            concentration,
        })
    }

    /// A beam whose concentration matches the numerical aperture `na` in `(0, 1]`
    /// (`gamma = 4 / na^2`, [`speckle_vmf::gamma_from_na`]). Errors name
    /// `<field>.numerical_aperture` or `<field>.axis`.
    pub fn with_numerical_aperture(
        field: &str,
        focus: DVec3,
        axis: DVec3,
        na: f64,
    ) -> Result<Self, EndpointError> {
        let gamma = gamma_from_na(na).map_err(|e| match e {
            speckle_vmf::VmfError::InvalidOption { reason, .. } => {
                check::invalid(format!("{field}.numerical_aperture"), reason)
            }
            other => check::invalid(format!("{field}.numerical_aperture"), other.to_string()),
        })?;
        Self::new(field, focus, axis, gamma)
    }

    /// Checks the beam against a medium: focus finite, axis unit and finite concentration (again,
    /// for values built directly), and in flatland focus and axis in the plane `z = 0`. Errors
    /// name `<field>.focus`, `<field>.axis` or `<field>.concentration`.
    pub fn validated<M: Medium>(self, field: &str, m: &M) -> Result<Self, EndpointError> {
        let focus_field = format!("{field}.focus");
        if !self.focus.is_finite() {
            return Err(check::invalid(
                focus_field,
                format!("{} must be finite", self.focus),
            ));
        }
        check::in_plane(&focus_field, self.focus, m.dimension())?;
        check::in_plane(&format!("{field}.axis"), self.axis, m.dimension())?;
        Self::new(field, self.focus, self.axis, self.concentration)
    }

    /// The beam seen from the other side (a sensor's source form and back): same focus and
    /// concentration, axis reversed.
    pub fn reversed(&self) -> Self {
        Self {
            axis: -self.axis,
            ..*self
        }
    }

    /// The 3D aperture.
    fn aperture(&self) -> Aperture {
        Aperture::new(self.concentration, self.axis).expect("validated beam")
    }

    /// The flatland aperture.
    fn circle_aperture(&self) -> CircleAperture {
        CircleAperture::new(self.concentration, self.axis.truncate()).expect("validated beam")
    }

    /// `ln u(x)`: the log of the beam's exact vacuum field at `x` (see the module docs), finite
    /// except at zeros of the field.
    pub fn ln_field(&self, dimension: Dimension, k: f64, x: DVec3) -> Complex64 {
        match dimension {
            Dimension::Three => self
                .aperture()
                .weighted(k, self.focus, x, 0.0)
                .ln_sphere_integral(),
            Dimension::Two => self
                .circle_aperture()
                .weighted(k, self.focus.truncate(), x.truncate(), 0.0)
                .ln_circle_integral(),
        }
    }

    /// The beam's exact vacuum field `u(x) = int m(w) e^(i k w . (x - f)) dw` (Eqs. 9-10).
    pub fn field(&self, dimension: Dimension, k: f64, x: DVec3) -> Complex64 {
        self.ln_field(dimension, k, x).exp()
    }

    /// The outgoing far-field amplitude `A(v)` of the beam in the unit direction `v`:
    /// `(2 pi / (i k)) m(v) e^(-i k v . f)` in 3D, `sqrt(2 pi / k) e^(-i pi/4) m(v) e^(-i k v . f)`
    /// in flatland (the stationary-phase limit of the superposition; module docs).
    pub fn far_amplitude(&self, dimension: Dimension, k: f64, v: DVec3) -> Complex64 {
        let phase = -k * v.dot(self.focus);
        match dimension {
            Dimension::Three => {
                let m = self.aperture().mask().ln_eval(v).re;
                Complex64::from_polar(((TAU / k).ln() + m).exp(), phase - 0.5 * PI)
            }
            Dimension::Two => {
                let m = self.circle_aperture().mask().ln_eval(v.truncate()).re;
                Complex64::from_polar((0.5 * (TAU / k).ln() + m).exp(), phase - 0.25 * PI)
            }
        }
    }

    /// What this beam, as the source form of a Gaussian sensor, reads of the vacuum field of the
    /// beam `source`: `int m_v(w) e^(i k w . v) A(w) dw` with the source's far-field amplitude
    /// `A(w) = (2 pi / (i k)) m_s(w) e^(-i k w . f_s)` (flatland: `sqrt(2 pi / k) e^(-i pi/4)`
    /// in place of `2 pi / (i k)`) and the sensor's mask `m_v(w) = m(-w)` of this source form:
    /// the closed-form integral of the product of the two masks and the phase.
    pub fn read_beam(&self, dimension: Dimension, k: f64, source: &GaussianBeam) -> Complex64 {
        // mu = gamma_s a_s + gamma_v a_v + i k (v - f_s), with a_v = -self.axis.
        let d = k * (self.focus - source.focus);
        match dimension {
            Dimension::Three => {
                let (ms, mv) = (source.aperture().mask(), self.reversed().aperture().mask());
                let wave = ComplexVmf::new(
                    Complex64::new(0.0, 0.0),
                    [d.x, d.y, d.z].map(|v| Complex64::new(0.0, v)),
                );
                let l = ms.mul(&mv).mul(&wave).ln_sphere_integral();
                Complex64::from_polar(((TAU / k).ln() + l.re).exp(), l.im - 0.5 * PI)
            }
            Dimension::Two => {
                let (ms, mv) = (
                    source.circle_aperture().mask(),
                    self.reversed().circle_aperture().mask(),
                );
                let wave = speckle_vmf::CircleVmf::new(
                    Complex64::new(0.0, 0.0),
                    [Complex64::new(0.0, d.x), Complex64::new(0.0, d.y)],
                );
                let l = ms.mul(&mv).mul(&wave).ln_circle_integral();
                Complex64::from_polar((0.5 * (TAU / k).ln() + l.re).exp(), l.im - 0.25 * PI)
            }
        }
    }

    /// The 3D weighted aperture at the medium point `o` (Eqs. 26-27): a complex vMF of the
    /// plane-wave direction, attenuated by `e^(-tau)`, `tau = sigma_t d / 2` along the axis
    /// (the constant-attenuation approximation of Eq. 25).
    pub fn weighted(&self, k: f64, o: DVec3, tau: f64) -> ComplexVmf {
        self.aperture().weighted(k, self.focus, o, tau)
    }

    /// The exact connection `Upsilon(o, w_out) = int a~(w; o) s(w . w_out) dw` (Eqs. 15-16,
    /// notes Sec. 4.5) for the normalised amplitude of `mixture` (Eq. 28), in log form; 3D.
    /// `w_out` is the propagation direction leaving `o` in source form (for a sensor, minus the
    /// direction arriving at `o`).
    pub fn ln_upsilon(
        &self,
        k: f64,
        o: DVec3,
        tau: f64,
        mixture: &VmfMixture,
        w_out: DVec3,
    ) -> Complex64 {
        Aperture::ln_upsilon(&self.weighted(k, o, tau), mixture, w_out)
    }
}

/// The near-field Monte Carlo connections of a Gaussian endpoint (Bar et al. 2020, Eqs. 14-18;
/// notes Secs. 3.4, 4.4-4.5), for a scattering amplitude given as vMF lobes
/// `s(mu) = sum_m e^(l_m + gamma_m mu)` (`PhaseFunction::amplitude_lobes`), in 3D and flatland.
/// Everything is in source form (a sensor is the beam with its axis reversed, see the module
/// docs) and in log form until the last exponential.
pub(crate) mod near {
    use super::GaussianBeam;
    pub(crate) use super::batch::{Batch, integral};
    use glam::DVec3;
    use num_complex::Complex64;
    use speckle_vmf::{Aperture, CircleAperture, CircleVmf, ComplexVmf};
    use std::f64::consts::{PI, TAU};

    /// A beam's aperture in the medium's dimension (its mask's normaliser computed once).
    #[derive(Debug, Clone, Copy)]
    pub(crate) enum Lens {
        Sphere(Aperture),
        Circle(CircleAperture),
    }

    impl Lens {
        /// The lens of `beam` in 3D (`three`) or flatland.
        pub(crate) fn of(beam: &GaussianBeam, three: bool) -> Self {
            if three {
                Self::Sphere(beam.aperture())
            } else {
                Self::Circle(beam.circle_aperture())
            }
        }

        /// The weighted aperture `a~(w; x)` of `beam` (this lens's beam) at the medium point
        /// `x` (Eqs. 26-27) with the field attenuation `e^(-tau)` along the axis (the
        /// constant-attenuation approximation of Eq. 25), with the dimension's unit-integral
        /// mask; a flatland aperture is stored as a 3D one with `mu_z = 0` (integrated over the
        /// circle by [`ln_integral`]).
        pub(crate) fn at(&self, beam: &GaussianBeam, k: f64, x: DVec3, tau: f64) -> ComplexVmf {
            match self {
                Self::Sphere(a) => a.weighted(k, beam.focus, x, tau),
                Self::Circle(a) => {
                    let c = a.weighted(k, beam.focus.truncate(), x.truncate(), tau);
                    ComplexVmf::new(c.log_scale, [c.mu[0], c.mu[1], Complex64::new(0.0, 0.0)])
                }
            }
        }
    }

    /// The weighted aperture of `beam` at `x` ([`Lens::at`]; the tests' shorthand).
    #[cfg(test)]
    pub(crate) fn aperture_at(
        beam: &GaussianBeam,
        three: bool,
        k: f64,
        x: DVec3,
        tau: f64,
    ) -> ComplexVmf {
        Lens::of(beam, three).at(beam, k, x, tau)
    }

    /// `ln int h(w) dw` over the sphere (Eq. 29) or, in flatland, the circle (`2 pi I_0`).
    #[inline]
    pub(crate) fn ln_integral(h: &ComplexVmf, three: bool) -> Complex64 {
        if three {
            h.ln_sphere_integral()
        } else {
            CircleVmf::new(h.log_scale, [h.mu[0], h.mu[1]]).ln_circle_integral()
        }
    }

    /// Queues on `batch` for `owner` the lobes of the exact connection `factor Upsilon(x, w)`,
    /// `Upsilon(x, w) = int a~(psi; x) s(psi . w) dpsi = sum_m e^(l_m) int a~(psi)
    /// e^(gamma_m w . psi) dpsi` (Eqs. 15-16, exact for a known outgoing source-form direction
    /// `w`: every `B >= 2` vertex and single scattering towards a non-Gaussian endpoint).
    /// `aperture` comes from [`aperture_at`]. With a [`Damping`](crate::Damping) other than
    /// none, the integrand is multiplied by `e^(-c (1 - psi . w)) e^(tilt . (psi - w))` (every
    /// lobe `(gamma + c, l - c - tilt . w)` and the parameter shifted by `tilt`); none is the
    /// plain connection, bitwise.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn push_upsilon(
        batch: &mut Batch,
        owner: usize,
        factor: Complex64,
        aperture: &ComplexVmf,
        lobes: &[(f64, f64)],
        damping: &crate::Damping,
        w: DVec3,
        sink: &mut impl FnMut(usize, Complex64),
    ) {
        let a = damping.tilted(aperture);
        for &(gamma, l) in lobes {
            let (gamma, l) = if *damping == crate::Damping::NONE {
                (gamma, l)
            } else {
                (gamma + damping.c, l - damping.c - damping.tilt.dot(w))
            };
            let mut mu = a.mu;
            for (m, d) in mu.iter_mut().zip(w.to_array()) {
                m.re += gamma * d;
            }
            batch.push(owner, factor, a.log_scale + l, mu, sink);
        }
    }

    /// `ln int a(psi) e^(gamma w . psi) dpsi` as a complex vMF of `w` (Eqs. 31-32), linearised
    /// about `w_o` and exact there: in 3D [`ComplexVmf::convolve_approx`]; in flatland the same
    /// construction with the circle integral, `mu' = (gamma / beta_o) mu`, scale
    /// `ln int a(psi) e^(gamma w_o . psi) dpsi - mu' . w_o`. `None` at the branch point
    /// `beta_o ~ 0`.
    fn convolve(
        a: &ComplexVmf,
        three: bool,
        gamma: f64,
        w_o: DVec3,
    ) -> Option<Result<ComplexVmf, Complex64>> {
        let c = linearised(a, three, gamma, w_o)?;
        // Near the branch point (`beta_o` small next to `|mu|`: for a point about
        // `(gamma_a + gamma) / k` off the focus, where the beam is weak) the linearised parameter
        // `(gamma / beta_o) mu` grows without bound and the approximation with it, by up to
        // hundreds of orders of magnitude. The exact convolution never exceeds
        // `|eta| int e^((Re mu + gamma w) . psi) dpsi <= |eta| 4 pi e^(|Re mu| + |gamma|)` (2 pi
        // in flatland), so an approximation whose largest value exceeds that bound is refused
        // (frozen at `w_o` by the caller).
        let re_norm = |v: &ComplexVmf| v.mu.iter().map(|m| m.re * m.re).sum::<f64>().sqrt();
        let measure = if three { 4.0 * PI } else { TAU };
        let bound = a.log_scale.re + measure.ln() + re_norm(a) + gamma.abs();
        // Refused: the exact value at `w_o`, where the linearisation is exact.
        Some(if c.log_scale.re + re_norm(&c) <= bound {
            Ok(c)
        } else {
            Err(c.ln_eval(w_o))
        })
    }

    /// The linearisation of [`convolve`] (Eqs. 31-32), without its bound.
    fn linearised(a: &ComplexVmf, three: bool, gamma: f64, w_o: DVec3) -> Option<ComplexVmf> {
        if three {
            return a.convolve_approx(gamma, w_o);
        }
        let shifted = a.mul(&ComplexVmf::real(0.0, gamma, w_o));
        let beta = shifted.beta();
        let size = a.mu.iter().map(|m| m.norm()).sum::<f64>() + gamma.abs();
        let scale = beta.norm();
        if scale.is_nan() || scale <= 1e-8 * size {
            return None;
        }
        let ratio = gamma / beta;
        let mu = a.mu.map(|m| ratio * m);
        let at = mu[0] * w_o.x + mu[1] * w_o.y + mu[2] * w_o.z;
        Some(ComplexVmf::new(ln_integral(&shifted, false) - at, mu))
    }

    /// The source's side of one lobe of single scattering between two Gaussian beams
    /// ([`push_single_both`]): the convolution of the source's aperture with the lobe, as a
    /// complex vMF of the sensor's plane-wave direction, or frozen at its value at the viewing
    /// axis (log form).
    #[derive(Debug, Clone, Copy)]
    pub(crate) enum Convolved {
        /// `int a~_s(psi) e^(-gamma psi . w') dpsi` as a complex vMF of `w'`.
        Vmf(ComplexVmf),
        /// Its log at the viewing axis, used for every `w'`.
        Frozen(Complex64),
    }

    /// The source side of lobe `gamma != 0` for the source aperture `a_s` and viewing axis
    /// `view` (see [`push_single_both`]).
    pub(crate) fn convolved(a_s: &ComplexVmf, three: bool, gamma: f64, view: DVec3) -> Convolved {
        match convolve(a_s, three, gamma, view) {
            // c is a vMF of v^ = -w': negate its parameter.
            Some(Ok(c)) => Convolved::Vmf(ComplexVmf::new(c.log_scale, c.mu.map(|m| -m))),
            Some(Err(at)) => Convolved::Frozen(at),
            None => Convolved::Frozen(ln_integral(
                &a_s.mul(&ComplexVmf::real(0.0, gamma, view)),
                three,
            )),
        }
    }

    /// Queues on `batch` for `owner` the lobes of single scattering between a Gaussian source
    /// and a Gaussian sensor (Eq. 18, notes Sec. 4.5): `sum_m e^(l_m) int a~_v(w') [int a~_s(psi)
    /// e^(-gamma_m psi . w') dpsi] dw'` for the source's aperture `a_s` and the sensor's
    /// source-form aperture `a_v` (its plane-wave direction `w'` is minus the viewing direction
    /// `v^`, so the lobe `e^(gamma_m psi . v^)` reads `e^(-gamma_m psi . w')`). An isotropic
    /// lobe (`gamma_m = 0`) is exact, `e^(l_m)` (`scale(m)`) times the product of the two
    /// fields (`fields()`: the integrals of `a_s` and `a_v`); any other lobe takes the convolution approximation of
    /// Eqs. 31-32 about the viewing axis (the paper's choice, the centre of the viewing
    /// aperture), exact there, given by `source(m)` ([`convolved`] of lobe `m`; callers cache
    /// it per source, lobe and viewing axis). Near its branch point (`beta_o` small next to
    /// `|mu|`), where the linearised convolution would exceed the bound that the exact one
    /// obeys, the convolution is frozen at its exact value at the viewing axis.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(crate) fn push_single_both(
        batch: &mut Batch,
        owner: usize,
        a_v: &ComplexVmf,
        lobes: &[(f64, f64)],
        scale: impl Fn(usize) -> f64,
        mut source: impl FnMut(usize) -> Convolved,
        mut fields: impl FnMut() -> (Complex64, Complex64),
        sink: &mut impl FnMut(usize, Complex64),
    ) {
        let one = Complex64::new(1.0, 0.0);
        for (m, &(gamma, l)) in lobes.iter().enumerate() {
            if gamma == 0.0 {
                let (field_s, field_v) = fields();
                batch.push_value(owner, scale(m) * field_s * field_v, sink);
                continue;
            }
            match source(m) {
                Convolved::Vmf(c) => {
                    let mu = std::array::from_fn(|j| a_v.mu[j] + c.mu[j]);
                    batch.push(owner, one, a_v.log_scale + c.log_scale + l, mu, sink);
                }
                Convolved::Frozen(at) => batch.push_value(owner, (l + at).exp() * fields().1, sink),
            }
        }
    }

    /// Single scattering between a Gaussian source and a Gaussian sensor viewing along `view`
    /// ([`push_single_both`]) alone (the tests' reference).
    #[cfg(test)]
    pub(crate) fn single_both(
        a_s: &ComplexVmf,
        a_v: &ComplexVmf,
        three: bool,
        lobes: &[(f64, f64)],
        view: DVec3,
    ) -> Complex64 {
        let mut sum = Complex64::new(0.0, 0.0);
        let sink = &mut |_, v| sum += v;
        let mut batch = Batch::new(three);
        push_single_both(
            &mut batch,
            0,
            a_v,
            lobes,
            |m| lobes[m].1.exp(),
            |m| convolved(a_s, three, lobes[m].0, view),
            || (integral(a_s, three), integral(a_v, three)),
            sink,
        );
        batch.flush(sink);
        sum
    }
}

mod batch;

#[cfg(test)]
pub(crate) mod tests;
