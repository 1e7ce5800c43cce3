//! Connections averaged over a Gaussian displacement of the connected point, for the two
//! copies of a path in the spatio-temporal estimator (moving scatterers; Bar et al. 2023,
//! Eqs. 17-20, with focused Gaussian beams).
//!
//! Copy 1 of a path connects its end vertex from `x - Delta / 2`, copy 2 from `x + Delta / 2`,
//! `Delta ~ N(0, sigma^2 I)`. To first order in `Delta` a copy's phase changes by
//! `-k p . Delta / 2` (copy 2: `+k p' . Delta / 2`), `p = psi - w` its momentum transfer there
//! (`psi` the plane wave of its endpoint in source form, `w` the path direction in source
//! form), so the pair's Gaussian average is `e^(-C |(p + p') / 2|^2)`, `C = k^2 sigma^2 / 2`
//! (`k^2 D |t|` for Brownian motion). With `|(p + p') / 2|^2 = |p|^2 / 2 + |p'|^2 / 2 -
//! |p - p'|^2 / 4` it factors into each copy's own `e^(-C |p|^2 / 2) = e^(-C (1 - psi . w))`
//! (the damping `c = C` of the amplitude: every vMF lobe `e^(l + gamma mu)` of a beam's
//! integral becomes `e^(l - c + (gamma + c) mu)`, still closed form) and a coupling
//! `e^(C |p - p'|^2 / 4)`, which is the average over a standard normal vector `u` of
//! `e^(s u . p) e^(-s u . p')`, `s = sqrt(C / 2)` (the Gaussian's moment generating function).
//! The directions `w` cancel between the copies (`p - p' = psi - psi'`), so copy 1 takes
//! [`Damping`] `(C, s u)` and copy 2 `(C, -s u)` for one `u` drawn per end vertex: the product of
//! copy 1 and the conjugate of copy 2, averaged over `u`, is the Gaussian average exactly, while
//! every connection stays one closed-form vMF integral per lobe (the plane waves' weight
//! `e^(tilt . (psi - w))` shifts the aperture's real parameter and its scale; keeping `w` in it
//! bounds each copy at any lag, see [`Damping`]).

use super::{Endpoints, Legs, lobes};
use crate::gaussian::near::{self, Batch};
use crate::{Kind, Side};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_phase::PhaseFunction;
use speckle_vmf::ComplexVmf;

/// The weight of each plane wave `psi` (source form) of a connection averaged over a Gaussian
/// displacement of its point (module docs): `e^(-c (1 - psi . w)) e^(tilt . (psi - w))`, `w` the
/// path direction in source form. (The factor `e^(-tilt . w)` cancels between the two copies of
/// a [`Damping::pair`]; with it each copy's weight is at most `e^(|tilt|^2 / (2 c))`, `e^(|u|^2 /
/// 4)` for a pair, at any lag, where `e^(tilt . psi)` alone would overflow at large `c`.)
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Damping {
    /// `c >= 0`: the amplitude damped by `e^(-c (1 - mu))`.
    pub c: f64,
    /// The plane waves weighted by `e^(tilt . (psi - w))`.
    pub tilt: DVec3,
}

impl Damping {
    /// No weight: the plain connection.
    pub const NONE: Self = Self {
        c: 0.0,
        tilt: DVec3::ZERO,
    };

    /// The two copies' dampings of one end vertex whose pair average is `e^(-C |(p + p') / 2|^2)`
    /// (module docs), for the standard normal vector `u` drawn for it: `(C, s u)` and
    /// `(C, -s u)`, `s = sqrt(C / 2)`.
    pub fn pair(big_c: f64, u: DVec3) -> [Self; 2] {
        let tilt = (0.5 * big_c).sqrt() * u;
        [
            Self { c: big_c, tilt },
            Self {
                c: big_c,
                tilt: -tilt,
            },
        ]
    }

    /// The aperture `a` with its plane waves weighted by `e^(tilt . psi)`.
    #[inline]
    pub(crate) fn tilted(&self, a: &ComplexVmf) -> ComplexVmf {
        let t = self.tilt.to_array().map(|x| Complex64::new(x, 0.0));
        Tilt(t).tilted(a)
    }

    /// The weight of a leg endpoint's one plane wave `psi` for the path direction `w` (source
    /// form), `mu = psi . w`.
    #[inline]
    pub(crate) fn leg(&self, mu: f64, psi: DVec3, w: DVec3) -> f64 {
        if *self == Self::NONE {
            return 1.0;
        }
        (self.tilt.dot(psi - w) - self.c * (1.0 - mu)).exp()
    }
}

/// A complex weight `e^(tilt . psi)` of plane waves: single scattering's tilts
/// ([`Endpoints::single_tilted`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Tilt(pub(crate) [Complex64; 3]);

impl Tilt {
    /// The aperture `a` with its plane waves weighted by `e^(tilt . psi)`.
    #[inline]
    pub(crate) fn tilted(&self, a: &ComplexVmf) -> ComplexVmf {
        let mut out = *a;
        if self.0 != [Complex64::new(0.0, 0.0); 3] {
            for (m, t) in out.mu.iter_mut().zip(self.0) {
                *m += t;
            }
        }
        out
    }

    /// `x e^(tilt . psi)` for a leg endpoint's one plane wave `psi` (`x` itself, bitwise, for
    /// a zero tilt).
    #[inline]
    pub(crate) fn weigh(&self, x: Complex64, psi: DVec3) -> Complex64 {
        if self.0 == [Complex64::new(0.0, 0.0); 3] {
            return x;
        }
        let t = self.0;
        x * (t[0] * psi.x + t[1] * psi.y + t[2] * psi.z).exp()
    }
}

impl<M: Medium> Endpoints<'_, M> {
    /// [`Endpoints::scatter`] at the point of `legs`, each plane wave `psi` (source form) of
    /// every connection weighted by one [`Damping`] of `dampings` (`e^(-c (1 - psi . w))
    /// e^(tilt . (psi - w))`, `w` the path direction in source form; a Gaussian average over a
    /// displacement of the point, see [`Damping`]): the values of `dampings[l]` go to
    /// `out_re[l n..(l + 1) n]`, `out_im[..]`, `n = len()`; the beams' integrals of every
    /// damping go through one batch. For a leg endpoint `psi` is its leg direction (a sensor's
    /// reversed); [`Damping::NONE`] gives [`Endpoints::scatter`]'s values.
    ///
    /// # Panics
    /// As [`Endpoints::scatter`]; if the outputs hold fewer than `dampings.len() * len()` values.
    pub fn scatter_damped<P: PhaseFunction>(
        &self,
        legs: &Legs,
        phase: &P,
        dirs: impl Fn(DVec3) -> (DVec3, DVec3),
        dampings: &[Damping],
        out_re: &mut [f64],
        out_im: &mut [f64],
    ) {
        let n = self.len();
        let total = dampings.len() * n;
        assert!(
            out_re.len() >= total && out_im.len() >= total,
            "outputs too short"
        );
        let sign = match self.side {
            Side::Source => 1.0,
            Side::Sensor => -1.0,
        };
        for i in 0..n {
            let gaussian = matches!(self.ends[i], Kind::Gaussian(_));
            let (w_in, w_out) = dirs(legs.dir(i));
            let x = if gaussian {
                Complex64::new(0.0, 0.0)
            } else {
                legs.amp(i) * phase.amplitude_between(w_in, w_out)
            };
            let (mu, psi, w) = (w_in.dot(w_out), sign * legs.dir(i), sign * w_out);
            let w = if sign > 0.0 { w } else { -w_in };
            for (l, d) in dampings.iter().enumerate() {
                let y = if gaussian { x } else { x * d.leg(mu, psi, w) };
                out_re[l * n + i] = y.re;
                out_im[l * n + i] = y.im;
            }
        }
        if !self.gaussian {
            return;
        }
        let w = self.source_form(&dirs);
        let sink = &mut |owner: usize, v: Complex64| {
            out_re[owner] += v.re;
            out_im[owner] += v.im;
        };
        let items = dampings.iter().map(|d| (legs, d));
        self.push_beams(items, lobes(phase), w, sink);
    }

    /// [`Endpoints::single`] with the plane waves `psi` of both endpoints (source form: a
    /// sensor's viewing direction reversed) weighted by `e^(tilt . psi)` for a complex vector
    /// `tilt` (an imaginary one, `-i k Delta`, moves the scattering point by `-Delta` in the
    /// phases of both beams' plane waves: the single-scattering copies of the spatio-temporal
    /// estimator, `e^(i k (psi - e) . Delta)` being the change of a single-scattering path's
    /// phase). A zero `tilt` gives [`Endpoints::single`]'s value bitwise.
    ///
    /// # Panics
    /// As [`Endpoints::single`].
    #[allow(clippy::too_many_arguments)]
    pub fn single_tilted<P: PhaseFunction>(
        &self,
        in1: &Legs,
        s: usize,
        sensors: &Endpoints<'_, M>,
        out1: &Legs,
        v: usize,
        phase: &P,
        tilt: [Complex64; 3],
    ) -> Complex64 {
        let three = self.three;
        let t = Tilt(tilt);
        let mut sum = Complex64::new(0.0, 0.0);
        let sink = &mut |_, x| sum += x;
        let mut batch = Batch::new(three);
        match (&self.ends[s], &sensors.ends[v]) {
            (Kind::Gaussian(_), Kind::Gaussian(bv)) => {
                let lobes = lobes(phase);
                let (a_s, a_v) = (t.tilted(&in1.aperture[s]), t.tilted(&out1.aperture[v]));
                near::push_single_both(
                    &mut batch,
                    0,
                    &a_v,
                    lobes,
                    |m| lobes[m].1.exp(),
                    |m| near::convolved(&a_s, three, lobes[m].0, -bv.axis),
                    || (near::integral(&a_s, three), near::integral(&a_v, three)),
                    sink,
                )
            }
            _ => self.push_single_leg(&mut batch, 0, (in1, s), (sensors, out1, v), phase, &t, sink),
        }
        batch.flush(sink);
        sum
    }
}

impl<M: Medium> Endpoints<'_, M> {
    /// [`Endpoints::single_tilted`] for every tilt of `tilts`, into `out` (resized to
    /// `tilts.len()`), equal to it tilt by tilt to rounding: the beams' integrals of every tilt
    /// go through one batch (between two beams when every lobe of `phase` is isotropic, whose
    /// value is the product of the two fields; otherwise tilt by tilt).
    ///
    /// # Panics
    /// As [`Endpoints::single`].
    #[allow(clippy::too_many_arguments)]
    pub fn single_tilted_many<P: PhaseFunction>(
        &self,
        in1: &Legs,
        s: usize,
        sensors: &Endpoints<'_, M>,
        out1: &Legs,
        v: usize,
        phase: &P,
        tilts: &[[Complex64; 3]],
        out: &mut Vec<Complex64>,
    ) {
        out.clear();
        out.resize(tilts.len(), Complex64::new(0.0, 0.0));
        let one = Complex64::new(1.0, 0.0);
        let mut batch = Batch::new(self.three);
        match (&self.ends[s], &sensors.ends[v]) {
            (Kind::Gaussian(_), Kind::Gaussian(_)) => {
                let lobes = lobes(phase);
                if lobes.iter().any(|&(gamma, _)| gamma != 0.0) {
                    for (o, &t) in out.iter_mut().zip(tilts) {
                        *o = self.single_tilted(in1, s, sensors, out1, v, phase, t);
                    }
                    return;
                }
                // Isotropic lobes: `sum_m e^(l_m)` times the product of the tilted fields.
                // The batch hands each owner its value in the order pushed: the source's
                // field (`2 m`) just before the sensor's (`2 m + 1`).
                let mut source_field = Complex64::new(0.0, 0.0);
                let sink = &mut |i: usize, x: Complex64| {
                    if i.is_multiple_of(2) {
                        source_field = x;
                    } else {
                        for &(_, l) in lobes {
                            out[i / 2] += l.exp() * source_field * x;
                        }
                    }
                };
                for (m, &t) in tilts.iter().enumerate() {
                    let t = Tilt(t);
                    let (a_s, a_v) = (t.tilted(&in1.aperture[s]), t.tilted(&out1.aperture[v]));
                    batch.push(2 * m, one, a_s.log_scale, a_s.mu, sink);
                    batch.push(2 * m + 1, one, a_v.log_scale, a_v.mu, sink);
                }
                batch.flush(sink);
            }
            _ => {
                let sink = &mut |i: usize, x: Complex64| out[i] += x;
                for (m, &t) in tilts.iter().enumerate() {
                    let (ends, t) = ((sensors, out1, v), &Tilt(t));
                    self.push_single_leg(&mut batch, m, (in1, s), ends, phase, t, sink);
                }
                batch.flush(sink);
            }
        }
    }
}

#[cfg(test)]
mod tests;
