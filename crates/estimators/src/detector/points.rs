//! Point detectors ([`Detector::point`]): next-event connections from every vertex, and
//! *branches* (a last vertex sampled around the point), weighed by the balance heuristic.
//!
//! No path leaves through a point, so a point detector is read by connections alone. A vertex
//! `x` (weight `W`, arrived along `w_in`, particle type of phase function `rho`) connects to the
//! point `c` at distance `r` along `w` with
//!
//! `N(x) = W rho(w_in -> w) e^{-tau(x, c)} T_F R(w') / r^2`,
//!
//! `T_F` the Fresnel transmittance of the face and `R(w')` the detector's weight of the direction
//! `w'` it leaves along ([`Detector::read_point`]: `w' . n` for flux, 1 for fluence, 0 outside the
//! aperture). Its `1 / r^2` makes the variance of next-event estimation infinite (`int r^-4 r^2
//! dr` diverges where vertices lie next to the point). A *branch* from `x` samples a vertex `y`
//! around the point instead, with density
//!
//! `q(y) = s e^{-s |y - c|} / (2 pi |y - c|^2)`
//!
//! (directions uniform over the medium's side of the face, distances exponential at the
//! extinction `s` next to the point), tried with the probability `P(x) = min(1, exp(REACH - s
//! |x - c|))` (an unbiased roulette: far from the point its connection carries `e^{-tau}`), and
//! the path continues `x -> y -> c`. A path `.. x, y` that ends with the connection `y -> c` is so
//! sampled in two ways: by the flight from `x` to `y` (volume density `a = rho_x(w_in -> w_xy)
//! sigma_s(y) e^{-tau(x, y)} / |x - y|^2`, also the throughput of that segment, so the flight
//! keeps the weight `W`), and by the branch from `x` (density `b = P(x) q(y)`). The balance
//! heuristic weighs the connection from a flight's vertex `y` by `a / (a + b)` and makes a
//! branch add `W a N_y / (a + b)` (`N_y` the connection from `y` without `W`; the branch's
//! `1 / (P q)` cancels against the weight's numerator). Near the point `b` grows as `1 / r^2`
//! and takes over, `N_y / q` is bounded, and the variance stays finite. A flight that a face
//! reflected is not a straight segment, which a branch never samples: its connection keeps the
//! weight 1, as does that of the first vertex (no branch leads to it).
//!
//! Far from the point a vertex's connection is rouletted too: with probability `min(1, exp(D -
//! s |x - c|))` (`D` = [`super::NEXT_EVENT_DEPTH`]) in a medium of uniform extinction, and
//! weighed by its inverse.

use super::NEXT_EVENT_DEPTH;
use glam::DVec3;
use speckle_endpoints::Detector;
use speckle_medium::{Interface, Medium};
use speckle_phase::PhaseFunction;

/// The optical distance from a point within which a branch to it is always tried (beyond, with
/// probability `exp(REACH - tau)`).
pub(super) const REACH: f64 = 3.0;

/// The branch sampler of one point detector (see the module docs).
#[derive(Debug, Clone, Copy)]
pub(super) struct PointBranch {
    center: DVec3,
    /// The face's inward normal and two tangents.
    inward: DVec3,
    t1: DVec3,
    t2: DVec3,
    /// The extinction next to the point, the rate of the sampled distances.
    rate: f64,
}

impl PointBranch {
    /// The sampler of `det` (a point detector) in `medium`; `None` where the medium next to it
    /// does not attenuate (its connections then have no `e^{-tau}` to sample).
    pub(super) fn new<M: Medium>(det: &Detector, medium: &M) -> Option<Self> {
        let inward = -det.normal();
        let nudge = 1e-9 * medium.bounds().size().max_element();
        let rate = medium.sigma_t(det.center() + nudge * inward);
        if !(rate > 0.0 && rate.is_finite()) {
            return None;
        }
        let (t1, t2) = inward.any_orthonormal_pair();
        Some(Self {
            center: det.center(),
            inward,
            t1,
            t2,
            rate,
        })
    }

    /// The probability `P(x)` of a branch from `x`.
    #[inline]
    pub(super) fn probability(&self, x: DVec3) -> f64 {
        (REACH - self.rate * (x - self.center).length())
            .exp()
            .min(1.0)
    }

    /// The density `q(y)` of a branch vertex (0 on the outer side of the face).
    #[inline]
    pub(super) fn pdf(&self, y: DVec3) -> f64 {
        let off = y - self.center;
        if off.dot(self.inward) <= 0.0 {
            return 0.0;
        }
        let r2 = off.length_squared();
        self.rate * (-self.rate * r2.sqrt()).exp() / (std::f64::consts::TAU * r2)
    }

    /// A branch vertex from three uniform variates (density [`PointBranch::pdf`]).
    #[inline]
    pub(super) fn sample(&self, u: [f64; 3]) -> DVec3 {
        // Uniform on the inward hemisphere: cos uniform on (0, 1].
        let cos = 1.0 - u[0];
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let (s, c) = (std::f64::consts::TAU * u[1]).sin_cos();
        let dir = cos * self.inward + sin * (c * self.t1 + s * self.t2);
        let r = -(1.0 - u[2]).ln() / self.rate;
        self.center + r * dir
    }
}

/// The probability with which a vertex at `x` connects to the point of `det` (see the module
/// docs): 1 within optical depth [`NEXT_EVENT_DEPTH`] of it, or in a medium whose extinction
/// varies.
#[inline]
pub(super) fn connection_probability<M: Medium>(medium: &M, det: &Detector, x: DVec3) -> f64 {
    match medium.uniform_sigma_t() {
        Some(s) => (NEXT_EVENT_DEPTH - s * (x - det.center()).length())
            .exp()
            .min(1.0),
        None => 1.0,
    }
}

/// The connection `N` of the module docs from a vertex at `x` (arrived along `w_in`, phase
/// function `rho`) to the point of `det`, without the path's weight: `(N, w, r)`, `w` the
/// direction to the point and `r` its distance; `None` where it adds nothing.
#[inline]
pub(super) fn connect<M: Medium, P: PhaseFunction>(
    medium: &M,
    interface: Option<Interface>,
    rho: &P,
    det: &Detector,
    x: DVec3,
    w_in: DVec3,
) -> Option<(f64, DVec3, f64)> {
    let to = det.center() - x;
    let r2 = to.length_squared();
    if r2.is_nan() || r2 <= 0.0 {
        return None;
    }
    let r = r2.sqrt();
    let w = to / r;
    let cos = w.dot(det.normal());
    let (transmitted, outside) = match interface {
        None => (1.0, Some(w)),
        Some(i) => (1.0 - i.reflectance(cos), i.refract(w, det.normal())),
    };
    let reading = det.read_point(outside?);
    if reading <= 0.0 {
        return None;
    }
    let n = rho.pdf_direction(w_in, w)
        * (-medium.optical_depth(x, det.center())).exp()
        * transmitted
        * reading
        / r2;
    (n > 0.0 && n.is_finite()).then_some((n, w, r))
}

/// The volume density `a` of a flight from `x` (arrived along `w_in`, phase function `rho`)
/// ending at `y` after the roulette on the albedo there (see the module docs).
#[inline]
pub(super) fn flight_density<M: Medium, P: PhaseFunction>(
    medium: &M,
    rho: &P,
    x: DVec3,
    w_in: DVec3,
    y: DVec3,
) -> f64 {
    let to = y - x;
    let d2 = to.length_squared();
    rho.pdf_direction(w_in, to / d2.sqrt())
        * medium.sigma_s(y)
        * (-medium.optical_depth(x, y)).exp()
        / d2
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_endpoints::Weighting;
    use speckle_medium::{Aabb, HomogeneousBox};

    /// The branch sampler draws from its density: the mean of `f / q` over its samples is the
    /// integral of `f` over the half-space, for an `f` known in closed form.
    #[test]
    fn branch_vertices_have_the_density_they_are_weighed_by() {
        let b = Aabb::new(DVec3::splat(-10.0), DVec3::new(10.0, 10.0, 0.0)).unwrap();
        let m = HomogeneousBox::new(b, 2.0, 0.0).unwrap();
        let det =
            Detector::point("s", &m, DVec3::ZERO, 1.0, None, 1.0, Weighting::Fluence).unwrap();
        let p = PointBranch::new(&det, &m).unwrap();
        assert_eq!(p.rate, 2.0);
        // f(y) = exp(-|y|^2): its integral over the half-space is pi^(3/2) / 2.
        let n = 400_000;
        let mut rng = speckle_stats::PathRng::new(7, 0);
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let y = p.sample(rng.next_3());
            assert!(y.z < 0.0);
            let v = (-y.length_squared()).exp() / p.pdf(y);
            s += v;
            s2 += v * v;
        }
        let mean = s / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        let want = std::f64::consts::PI.powf(1.5) / 2.0;
        assert!(
            (mean - want).abs() < 4.0 * se,
            "{mean} +- {se} against {want}"
        );
        assert!(se < 0.01 * want);
        // The outer side has no density; the probability is 1 within REACH.
        assert_eq!(p.pdf(DVec3::new(0.1, 0.0, 0.1)), 0.0);
        assert_eq!(p.probability(DVec3::new(0.0, 0.0, -1.0)), 1.0);
        let far = p.probability(DVec3::new(0.0, 0.0, -3.0));
        assert!((far - (REACH - 6.0).exp()).abs() < 1e-15);
    }
}
