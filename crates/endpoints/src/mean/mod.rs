//! The speckle mean (Bar et al. 2019, Eq. 20, and its far-field form, App. Eq. 48 of the HTML
//! version).
//!
//! - A point endpoint on either side: the mean is the attenuated direct path,
//!   `m = tau(i, v) mu(i -> v)` (Eq. 20): point to point `tau e^{ikr}/r`, plane wave to point
//!   `tau e^{ik i.q}`, point to far field `tau e^{-ik v.p}`, with `tau` from the optical depth
//!   along the straight line.
//! - Plane wave to far field: every path's first scatterer `x` contributes the incident phase,
//!   the scatterer's amplitude and the mean field from `x` to the sensor:
//!   `m = n sqrt(c_s) s(i.v) int e^{ik (i - v).x} T(x) dx` over the medium, with `T(x)` the
//!   attenuation of the legs (below). The factor `n sqrt(c_s)` is not a bulk parameter; it is
//!   closed with the optical theorem for the forward amplitude
//!   (`n sqrt(c_s) s(1) = i k sigma_t / (4 pi)`, which makes the mean field decay as
//!   `e^{-sigma_t d / 2}`, the attenuation the estimators use):
//!   `n sqrt(c_s) s(i.v) = (i k sigma_t / (4 pi)) s(i.v) / s(1)`. The mean is significant only
//!   within about `lambda / size` of the forward and specular directions.
//!
//! # Which legs are attenuated
//!
//! The box is, for the mean field, a body of effective wavenumber `k_eff = k + i sigma_t / 2`.
//! Its exact far field is the free-space radiation of `<u>` (the mean field inside), and `<u>`
//! is the beam that crosses the box, `e^{ik i.x} tau_in(x)`, plus waves reflected at the faces
//! with amplitude `O(sigma_t / k)`. Those reflections are negligible when their radiation is out
//! of phase with the sensor, but not when it is in phase. So:
//!
//! - **Transmission** (the sensor leg leaves through a face the incident wave does not enter):
//!   `T = tau_out(x) = e^{-sigma_t d_out(x) / 2}`, `d_out` the distance from `x` to the boundary
//!   along `v`. The forward-scattered wavelets are the beam's extinction; for a slab at normal
//!   incidence this is exactly the coherent field `e^{-sigma_t L / 2}` behind it (an area `A`
//!   has the forward amplitude `(i k A / 2 pi)(1 - e^{-sigma_t L / 2})`, Babinet's black-screen
//!   limit). Attenuating both legs would give `(sigma_t L / 2) e^{-sigma_t L / 2}` instead of
//!   `1 - e^{-sigma_t L / 2}`.
//! - **Reflection** (the sensor leg leaves through a face `F` the incident wave enters,
//!   `i . n_F < 0`): `T = tau_in(x) tau_out(x) = e^{-sigma_t (d_in(x) + d_out(x)) / 2}`,
//!   `d_in` the distance from `x` to the boundary along `-i`. The echo of the back face has
//!   crossed the medium twice. 1D check: a slab of depth `L` has the Fresnel reflection
//!   `r = r01 (1 - e^{2 i k_eff L}) / (1 - r01^2 e^{2 i k_eff L})`,
//!   `r01 = (k - k_eff) / (k + k_eff) ~ -i sigma_t / (4 k)`; the volume integral with both legs
//!   gives `r01 (1 - e^{(2ik - sigma_t) L})` to first order in `sigma_t / k`, one leg gives
//!   `e^{(2ik - sigma_t / 2) L}` for the back face (0.62 of `r` for `sigma_t = 1/4`, `L = 4`,
//!   `lambda = 1`).
//!
//! At exact normal backscatter from a `W x W x L` box (front face at depth `z0` along `i`):
//! `m = (i k sigma_t / 4 pi) (s(-1) / s(1)) W^2 e^{2ik z0} (1 - e^{(2ik - sigma_t) L}) /
//! (sigma_t - 2ik)`, to leading order in `sigma_t / k` (isotropic, `lambda = 1`, `2L` a whole
//! number of wavelengths, `z0 = 0`): `-(sigma_t W^2 / 4k)(1 - e^{-sigma_t L})`. At oblique
//! incidence `theta` on a wide slab, the specular amplitude is
//! `-(sigma_t W^2 / (8 pi cos theta))(1 - e^{2ik L cos theta - sigma_t L / cos theta})` to
//! leading order, the small-contrast Fresnel value `r ~ -i sigma_t / (4 k cos^2 theta)`.
//! The per-face switch is continuous in `v`: a face's contribution vanishes as `v` becomes
//! parallel to it. It is not continuous in `x` (the integrand jumps where the exit face changes)
//! nor in `i` as `i` becomes parallel to an exit face; it is a first-order model of the
//! neighbourhood of the forward and specular directions, where the mean lives.
//!
//! # Evaluation
//!
//! Each point is written `x = y - t v`, `y` on the face `F` where the ray along `v` exits,
//! `t = d_out(x)`, `dx = |n_F . v| dy dt`. Along `t`, `d_in(y - t v) = min_a (c_a + s_a t)` over
//! the axes `a` that `i` crosses, a concave piecewise-linear function, so the `t` integral is a
//! sum of closed-form exponential integrals between the breakpoints where the minimising face
//! changes. The face integral is a composite 4-point Gauss-Legendre quadrature with 48 to 512
//! panels per axis (no wider than about one radian of phase where 512 suffice); relative
//! accuracy about 1e-4 (tested against brute-force volume quadratures, with the exit face and
//! `d_in` found by tracing).
//!
//! Flatland: point legs spread as `1 / sqrt(r)`, and the optical theorem for the amplitude
//! convention `u = A e^{ikR} / sqrt(R)` gives `n sqrt(c_s) s(1) = (sigma_t / 2) sqrt(k / 2 pi)
//! e^{3 i pi / 4}` (a line of scatterers radiates `sqrt(2 pi / k) e^{i pi / 4}` times its forward
//! amplitude per unit length into the forward plane wave). The area integral runs over the exit
//! edges with the same 1D rule and the same per-edge choice of legs.

mod quadrature;
#[cfg(test)]
mod tests;

use crate::point;
use crate::{EndpointError, Sensor, Source};
use glam::DVec3;
use num_complex::Complex64;
use quadrature::box_integral_refined;
use speckle_medium::{Dimension, Medium};
use speckle_phase::PhaseFunction;
use std::f64::consts::PI;

/// The speckle mean of the pair (`source`, `sensor`) in `medium`, whose particle types have the
/// amplitude functions `phases`, at wavenumber `k`.
pub fn mean_field<M: Medium, P: PhaseFunction>(
    m: &M,
    phases: &[P],
    k: f64,
    src: Source,
    sen: Sensor,
) -> Result<Complex64, EndpointError> {
    Ok(mean_field_cancellable(m, phases, k, src, sen, &|| false)?.expect("never cancelled"))
}

/// [`mean_field`], asking `cancelled` between the rows of its quadrature (a few hundred
/// microseconds apart); `None` once it says so.
pub fn mean_field_cancellable<M: Medium, P: PhaseFunction>(
    m: &M,
    phases: &[P],
    k: f64,
    src: Source,
    sen: Sensor,
    cancelled: &dyn Fn() -> bool,
) -> Result<Option<Complex64>, EndpointError> {
    Ok(Some(match (src, sen) {
        (Source::GaussianBeam(_), _) | (_, Sensor::GaussianBeam(_)) => beam_mean(m, k, src, sen),
        // A point endpoint on either side: the attenuated direct path (Eq. 20), which is the
        // other endpoint's leg evaluated at the point.
        (Source::Point { position: p }, Sensor::Point { position: q }) => {
            point::direct_mean(m, k, p, q)
        }
        (Source::PlaneWave { .. }, Sensor::Point { position: q }) => src.leg(m, k, q).amp,
        (Source::Point { position: p }, Sensor::FarField { .. }) => sen.leg(m, k, p).amp,
        (Source::PlaneWave { direction: i }, Sensor::FarField { direction: v }) => {
            let sigma_t = m
                .uniform_sigma_t()
                .ok_or_else(|| EndpointError::InvalidInput {
                    field: "medium".into(),
                    reason: "the far-field to far-field mean needs a medium of uniform \
                             extinction (its closed form integrates over a homogeneous box); \
                             render fields without the mean (render.add_mean = false)"
                        .into(),
                })?;
            // n sqrt(c_s) s(1), fixed by the optical theorem.
            let forward = match m.dimension() {
                Dimension::Three => Complex64::new(0.0, k * sigma_t / (4.0 * PI)),
                Dimension::Two => {
                    Complex64::from_polar(0.5 * sigma_t * (k / (2.0 * PI)).sqrt(), 0.75 * PI)
                }
            };
            let amp = forward * relative_amplitude(m, phases, i, v);
            let Some(integral) = box_integral_refined(m.bounds(), k, sigma_t, i, v, 1, cancelled)
            else {
                return Ok(None);
            };
            amp * integral
        }
    }))
}

/// The speckle mean of a pair with a focused Gaussian beam (Bar et al. 2020; its App. A.1 is
/// missing, this is our reconstruction): the ballistic coherent field. Inside the medium the
/// mean field is the vacuum field with every plane wave of the aperture attenuated by
/// `e^(-sigma_t d / 2)` over the distance `d` it has crossed (the effective medium of the module
/// docs, without the face reflections of order `sigma_t / k`), and, as in the near-field
/// covariance, that attenuation is taken constant over the aperture (Eq. 25): evaluated along
/// one ray, the aperture's central direction. So the mean is the pair's exact vacuum reading
/// (`crate::direct_field`: the closed-form plane-wave superposition of Eqs. 9-10) times
/// `e^(-tau / 2)` with the optical depth `tau`:
///
/// - beam source to point sensor `q`: from the boundary to `q` along the source's axis (the
///   attenuation the covariance gives the beam at a medium point); point source `p` to beam
///   sensor: from `p` to the boundary along the sensor's viewing axis (its reciprocal);
/// - beam source to far-field sensor `v`: the whole line through the focus along `v` (the
///   stationary ray of the outgoing amplitude, exact in direction); plane wave `d` to beam
///   sensor: the whole line through the sensor's focus along `d`;
/// - beam to beam: the whole line through the midpoint of the two foci along the peak of the
///   product of the two masks, `gamma_s a_s + gamma_v a_v` (the source's axis where that
///   vanishes: a sensor facing the source, whose vacuum reading is then of order
///   `e^(-2 gamma)`).
///
/// The relative error of the constant attenuation is of order `sigma_t delta_d / 2`, with
/// `delta_d` the spread of the crossed distances over the aperture (vanishing as the aperture
/// narrows); in reflection the coherent face reflections (the specular mean of the far-field
/// form, relative size about `sigma_t / (4 k)`) are left out.
fn beam_mean<M: Medium>(m: &M, k: f64, src: Source, sen: Sensor) -> Complex64 {
    let dim = m.dimension();
    let depth_to = |x: DVec3, d: DVec3| m.optical_depth_to_infinity(x, d);
    let line = |x: DVec3, d: DVec3| depth_to(x, d) + depth_to(x, -d);
    let (vacuum, tau) = match (src, sen) {
        (Source::GaussianBeam(b), Sensor::Point { position: q }) => {
            (b.field(dim, k, q), depth_to(q, -b.axis))
        }
        (Source::Point { position: p }, Sensor::GaussianBeam(s)) => {
            (s.reversed().field(dim, k, p), depth_to(p, s.axis))
        }
        (Source::GaussianBeam(b), Sensor::FarField { direction: v }) => {
            (b.far_amplitude(dim, k, v), line(b.focus, v))
        }
        (Source::PlaneWave { direction: d }, Sensor::GaussianBeam(s)) => {
            (s.reversed().far_amplitude(dim, k, -d), line(s.focus, d))
        }
        (Source::GaussianBeam(b), Sensor::GaussianBeam(s)) => {
            let peak = b.concentration * b.axis + s.concentration * s.axis;
            let size = b.concentration + s.concentration;
            let dir = if size > 0.0 && peak.length() > 1e-9 * size {
                peak.normalize()
            } else {
                b.axis
            };
            (
                s.reversed().read_beam(dim, k, &b),
                line(0.5 * (b.focus + s.focus), dir),
            )
        }
        _ => unreachable!("a pair with a gaussian_beam endpoint"),
    };
    vacuum * (-0.5 * tau).exp()
}

/// `s(i . v) / s(1)`, the amplitude relative to the forward one. With several particle types it
/// is `sum_iota beta_iota s_iota(i . v) / s_iota(1)` (App. A.1, Eq. 48 with each type's forward
/// amplitude fixed by the optical theorem), with `beta` taken at the centre of the medium: exact
/// when the types share one albedo and `beta` is uniform, and in any case exact forward, where the
/// far-field mean lives.
fn relative_amplitude<M: Medium, P: PhaseFunction>(
    m: &M,
    phases: &[P],
    i: DVec3,
    v: DVec3,
) -> Complex64 {
    let ratio = |p: &P| p.amplitude_between(i, v) / p.amplitude_between(i, i);
    if phases.len() == 1 {
        return ratio(&phases[0]);
    }
    let mut beta = vec![0.0; phases.len()];
    m.type_probabilities(m.bounds().lerp([0.5; 3]), &mut beta);
    phases.iter().zip(&beta).map(|(p, b)| *b * ratio(p)).sum()
}
