//! Branches to point endpoints: last vertices sampled around the points, weighed against the
//! sub-path's own vertices by the balance heuristic of all techniques.
//!
//! With point endpoints in or next to the medium, a path `x_1 .. x_B` is sampled by four
//! techniques: the sub-path in either order (`x_1` from the first-vertex mixture, the rest by
//! flights and the phase function; [`Vertex::both_orders`]), and either order with its last
//! vertex instead sampled around the points (a *branch* from `x_{B-1}`, handed to
//! [`VertexSink::branch`]). The two orders alone put the `1/r^2` of each endpoint's leg into the
//! density at one end only: a path whose first vertex lies next to the source and whose last
//! lies next to the sensor (a thin slab, a source and a sensor a few mean free paths apart)
//! keeps the product of both, and the estimator's variance diverges (logarithmically: its
//! standard error did not fall as `1/sqrt(N)`). A branch samples both ends next to their
//! endpoints at once; its own singularity, the `1/r^2` of the connection `x_{B-1} -> x_B`, is
//! that of a flight, which the sub-path's technique samples.
//!
//! Around point `k` a branch is tried from `x` with probability
//! `P_k(x) = min(1, exp(REACH - rate_k |x - p_k|))` (an unbiased roulette: far from a point,
//! its branch connects through `exp(-sigma_t d)` and is rarely worth its cost), and its vertex
//! `y` is drawn from the point's component of the mixture, density `q_k(y)`. The density of a
//! branch vertex is `Q_p(y | x) = sum_k P_k(x) q_k(y)`. With `f(x -> y) = sigma_s(y)
//! exp(-tau(x, y)) / |x - y|^2` the volume density of a flight and its roulette (`|x - y|` in
//! flatland), and `D_{B-1}` the density of the direction sampled at `x_{B-1}` (the phase
//! function, or at `x_1` the mixture's direction density `Q(x_1, w_12) / q_o(x_1)`), the
//! densities of a path relative to the forward sub-path's are
//!
//! - reversed sub-path: `R_r = Q(x_B, -w_in) sigma_s(x_1) / (Q(x_1, w_12) sigma_s(x_B))`;
//! - forward branch: `R_c = Q_p(x_B | x_{B-1}) / (D_{B-1} f(x_{B-1} -> x_B))`;
//! - reversed branch: `R_cr = R_r Q_p(x_1 | x_2) / (D'_2 f(x_2 -> x_1))`, `D'_2` the phase
//!   function at `x_2` between `w_12` and `w_23` (or, for `B = 2`, `Q(x_2, -w_12) / q_o(x_2)`);
//!
//! and a technique's vertex carries `both_orders = R_t / (1 + R_r + R_c + R_cr)` (`R_t = 1` for
//! the forward sub-path) on the weight of its own density.

use super::{Tracer, Walker};
use crate::mixture::EndpointMixture;
use crate::{PathRng, Vertex, VertexSink};
use glam::DVec3;
use speckle_medium::Medium;
use speckle_phase::{Dimension, PhaseFunction};

/// Optical distance from a point within which a branch to it is always tried (beyond, with
/// probability `exp(REACH - tau)`).
const REACH: f64 = 3.0;

impl<M: Medium, P: PhaseFunction> Tracer<'_, M, P> {
    /// Whether paths handed to `sink` branch: point components and a sink that takes
    /// branches (never with a refracting interface, whose flights are not straight).
    #[inline]
    pub(super) fn branching<S: VertexSink>(&self, sink: &S) -> bool {
        self.both_orders
            && self.interface.is_none()
            && self.points.as_ref().is_some_and(|p| !p.points.is_empty())
            && sink.branches()
    }

    /// The probability of a branch from `x` to point `k`.
    #[inline]
    fn branch_probability(p: &EndpointMixture, k: usize, x: DVec3) -> f64 {
        let tau = p.rates[k] * (x - p.points[k]).length();
        (REACH - tau).exp().min(1.0)
    }

    /// The density `Q_p(y | x)` of a branch vertex `y` from `x`.
    #[inline]
    fn branch_density(p: &EndpointMixture, x: DVec3, y: DVec3) -> f64 {
        (0..p.points.len())
            .map(|k| Self::branch_probability(p, k, x) * p.point_pdf(k, y))
            .sum()
    }

    /// The volume density `f(a -> b) = sigma_s(b) exp(-tau(a, b)) / |a - b|^2` of a flight
    /// from `a` ending at `b` (roulette included; `/ |a - b|` in flatland).
    #[inline]
    fn flight_density(&self, a: DVec3, b: DVec3) -> f64 {
        let d = (b - a).length();
        let geometry = match self.medium.dimension() {
            Dimension::Three => d * d,
            Dimension::Two => d,
        };
        self.medium.sigma_s(b) * (-self.medium.optical_depth(a, b)).exp() / geometry
    }

    /// `R_c + R_cr` of the sub-path's vertex `next` (reached from `w.here` along `dir`, with
    /// `p_rev = Q(next, -dir)` and `reversed = R_r`); keeps the path's constants of the reversed
    /// branch in `w` as `x2` and `x3` become known (`w.b` is already the index of `next`).
    #[inline]
    pub(super) fn branch_ratios(
        &self,
        p: &EndpointMixture,
        w: &mut Walker,
        next: DVec3,
        dir: DVec3,
        p_rev: f64,
        reversed: f64,
    ) -> f64 {
        let flight = self.flight_density(w.here, next);
        let sigma1 = self.medium.sigma_s(w.x1);
        let direction = if w.b == 2 {
            sigma1 / w.weight / w.q1_marginal
        } else {
            self.phases[w.ty].pdf_direction(w.w_in, dir)
        };
        let forward = Self::branch_density(p, w.here, next) / (direction * flight);
        let crossed = match w.b {
            2 => {
                // f(x2 -> x1) has sigma_s(x1) where f(x1 -> x2) has sigma_s(x2).
                let back_flight = flight * sigma1 / self.medium.sigma_s(next);
                w.back = Self::branch_density(p, next, w.x1) / back_flight;
                w.back * self.first_pdf(next) / p_rev
            }
            3 => {
                w.crossed = w.back / self.phases[w.ty].pdf_direction(w.w12, dir);
                w.crossed
            }
            _ => w.crossed,
        };
        forward + reversed * crossed
    }

    /// The branches from the first vertex `x1` (type `type1`, single-scattering weight
    /// `w_single`): paths `x1, y`.
    pub(super) fn branch_first<S: VertexSink>(
        &self,
        x1: DVec3,
        type1: usize,
        w_single: f64,
        rng: &mut PathRng,
        sink: &mut S,
    ) {
        if self.max_vertices < 2 {
            return;
        }
        let Some(p) = &self.points else {
            return;
        };
        let sigma1 = self.medium.sigma_s(x1);
        let q1_marginal = sigma1 / w_single;
        for k in 0..p.points.len() {
            let Some((y, ty)) = self.branch_vertex(p, k, x1, rng) else {
                continue;
            };
            let d = (y - x1).length();
            let w = (y - x1) / d;
            let flight = self.flight_density(x1, y);
            let density = Self::branch_density(p, x1, y);
            let q1 = self.joint_pdf(x1, w, type1);
            let q_rev = self.joint_pdf(y, -w, ty);
            let sigma_y = self.medium.sigma_s(y);
            // Relative to the forward sub-path x1 -> y (direction density q1 / q_o(x1)).
            let forward = density * q1_marginal / (q1 * flight);
            let reversed = q_rev * sigma1 / (q1 * sigma_y);
            let back = Self::branch_density(p, y, x1) / (flight * sigma1 / sigma_y);
            let crossed = reversed * back * self.first_pdf(y) / q_rev;
            let total = 1.0 + reversed + forward + crossed;
            if !total.is_finite() || forward <= 0.0 {
                continue;
            }
            sink.branch(
                &Vertex {
                    index: 2,
                    x1,
                    w12: w,
                    x: y,
                    w_in: w,
                    w_prev_out: w,
                    type1,
                    ty,
                    weight: w_single * flight / density,
                    both_orders: forward / total,
                    length: d,
                },
                rng,
            );
        }
    }

    /// The branches from the walker's last vertex `x_b`, `b >= 2`: paths `x1 .. x_b, y`.
    pub(super) fn branch_at<S: VertexSink>(&self, w: &Walker, rng: &mut PathRng, sink: &mut S) {
        if w.b >= self.max_vertices {
            return;
        }
        let Some(p) = &self.points else {
            return;
        };
        for k in 0..p.points.len() {
            let Some((y, ty)) = self.branch_vertex(p, k, w.here, rng) else {
                continue;
            };
            let d = (y - w.here).length();
            let dir = (y - w.here) / d;
            let flight = self.flight_density(w.here, y);
            let density = Self::branch_density(p, w.here, y);
            let phase = self.phases[w.ty].pdf_direction(w.w_in, dir);
            let sigma_y = self.medium.sigma_s(y);
            let forward = density / (phase * flight);
            let reversed = w.weight * self.joint_pdf(y, -dir, ty) / sigma_y;
            let crossed = if w.b == 2 {
                w.back / self.phases[w.ty].pdf_direction(w.w12, dir)
            } else {
                w.crossed
            };
            let total = 1.0 + reversed + forward + reversed * crossed;
            if !total.is_finite() || forward <= 0.0 {
                continue;
            }
            sink.branch(
                &Vertex {
                    index: w.b + 1,
                    x1: w.x1,
                    w12: w.w12,
                    x: y,
                    w_in: dir,
                    w_prev_out: dir,
                    type1: w.type1,
                    ty,
                    weight: w.weight * phase * flight / density,
                    both_orders: forward / total,
                    length: w.length + d,
                },
                rng,
            );
        }
    }

    /// A branch vertex around point `k` from `x` (with its particle type), or `None` where the
    /// roulette ends the branch or the sample lies outside the scattering medium.
    #[inline]
    fn branch_vertex(
        &self,
        p: &EndpointMixture,
        k: usize,
        x: DVec3,
        rng: &mut PathRng,
    ) -> Option<(DVec3, usize)> {
        let chance = Self::branch_probability(p, k, x);
        if chance < 1.0 && rng.next_f64() >= chance {
            return None;
        }
        let y = p.sample_point(k, rng.next_3());
        if !self.medium.contains(y) || self.medium.sigma_s(y) <= 0.0 || y == x {
            return None;
        }
        Some((y, self.sample_type(y, rng)))
    }
}
