//! The first-vertex mixture around a scene's endpoints: point endpoints and focused Gaussian
//! beams beside the volume strategy.

use crate::beam::BeamSampler;
use glam::DVec3;
use speckle_phase::{Dimension, PhaseFunction};

/// The first-vertex mixture of a medium with endpoints to sample around: point endpoints inside
/// the medium or next to it, and focused Gaussian beams. With probability `volume` the volume
/// strategy ([`FirstVertexSampler`]), otherwise one of the components, by groups (`groups`:
/// each group has a probability, split equally among its components; usually one group of
/// all): a point `x1 = p + r w` around one of the `points`, `w` uniform on the sphere
/// (circle) and `r` exponential at `rate`, density `rate exp(-rate r) / (4 pi r^2)` (flatland
/// `/ (2 pi r)`) over all space, or a point from one of the `beams` ([`BeamSampler`]). Points
/// that land outside the medium's box start no path (their contribution, zero, is counted).
/// The `1/r^2` of the point density cancels the `1/r^2` of a point endpoint's connection, which
/// near the endpoint would otherwise give the estimator infinite variance
/// (`shared/notes/spatiotemporal-2023.md`, Build 3 of issue 12).
///
/// With an anisotropic phase function (`point_directions`), a point component also samples the
/// first direction, from the phase function about the ray from its point to `x1`: the endpoint's
/// connection to `x1` carries the amplitude `s(w_p . w12)` (and, at the other end of a reversed
/// path, `s(w_p . -w_in)`), which a uniform first direction leaves unsampled. With `g = 0.9`
/// that amplitude squared varies by a factor of 7 000 over the sphere.
#[derive(Debug, Clone)]
pub(crate) struct EndpointMixture {
    pub(crate) points: Vec<DVec3>,
    pub(crate) rates: Vec<f64>,
    pub(crate) beams: Vec<BeamSampler>,
    /// Probability of the volume strategy (0: the components alone).
    pub(crate) volume: f64,
    /// Groups of components, points first and then beams in order: `(end, probability)`, the
    /// components from the previous group's end to `end` sharing `probability` equally. The
    /// probabilities sum to `1 - volume`.
    pub(crate) groups: Vec<(usize, f64)>,
    pub(crate) dimension: Dimension,
    /// Whether the point components sample first directions from the phase function about the
    /// ray from their point (anisotropic phase functions; isotropic ones keep the configured
    /// direction strategy, which a point's ray cannot improve).
    pub(crate) point_directions: bool,
}

/// Which strategy sampled a first vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Component {
    Volume,
    Point(usize),
    Beam(usize),
}

impl EndpointMixture {
    /// One group of all components (`points` then `beams`) beside the volume's share.
    pub(crate) fn one_group(n: usize, volume: f64) -> Vec<(usize, f64)> {
        vec![(n, 1.0 - volume)]
    }

    /// The groups with their component ranges and per-component probabilities.
    fn ranges(&self) -> impl Iterator<Item = (std::ops::Range<usize>, f64)> + '_ {
        let mut start = 0;
        self.groups.iter().map(move |&(end, p)| {
            let r = start..end;
            start = end;
            let each = p / r.len() as f64;
            (r, each)
        })
    }

    /// Whether some component samples first directions from its own strategy.
    #[inline]
    pub(crate) fn samples_directions(&self) -> bool {
        (self.point_directions && !self.points.is_empty())
            || self.beams.iter().any(BeamSampler::samples_directions)
    }

    /// The unit ray from point `k` to `x` (any unit vector in the plane at the point itself).
    #[inline]
    pub(crate) fn ray(&self, k: usize, x: DVec3) -> DVec3 {
        (x - self.points[k]).try_normalize().unwrap_or(DVec3::X)
    }

    /// The density of the first direction `w` at `x` from the component around point `k`: the
    /// phase function about its ray with `point_directions`, else the configured `base`.
    #[inline]
    fn point_direction_pdf<P: PhaseFunction>(
        &self,
        k: usize,
        base: f64,
        phase: &P,
        x: DVec3,
        w: DVec3,
    ) -> f64 {
        if self.point_directions {
            phase.pdf_direction(self.ray(k, x), w)
        } else {
            base
        }
    }

    /// The density of the component around point `k` at `x`.
    #[inline]
    pub(crate) fn point_pdf(&self, k: usize, x: DVec3) -> f64 {
        let r = (x - self.points[k]).length();
        let rate = self.rates[k];
        let radial = rate * (-rate * r).exp();
        match self.dimension {
            Dimension::Three => radial / (4.0 * std::f64::consts::PI * r * r),
            Dimension::Two => radial / (std::f64::consts::TAU * r),
        }
    }

    /// The sums over the components in `r` of `point` over the points (by index) and of `beam`
    /// over the beams, as two sums (points, then beams).
    #[inline]
    fn sums(
        &self,
        r: std::ops::Range<usize>,
        point: impl Fn(usize) -> f64,
        beam: impl Fn(&BeamSampler) -> f64,
    ) -> (f64, f64) {
        let np = self.points.len();
        let points: f64 = (r.start.min(np)..r.end.min(np)).map(point).sum();
        let (b0, b1) = (r.start.max(np) - np, r.end.max(np) - np);
        let beams = if b0 == b1 {
            0.0
        } else {
            self.beams[b0..b1].iter().map(beam).sum::<f64>()
        };
        (points, beams)
    }

    /// The mixture density at `x` (inside the box), given the volume strategy's density there.
    #[inline]
    pub(crate) fn pdf(&self, volume_pdf: f64, x: DVec3) -> f64 {
        let mut total = self.volume * volume_pdf;
        for (r, each) in self.ranges() {
            let (points, beams) = self.sums(r, |k| self.point_pdf(k, x), |b| b.pdf(x));
            let all = if beams == 0.0 { points } else { points + beams };
            total += each * all;
        }
        total
    }

    /// The joint density of the first vertex `x` and first direction `w` when components sample
    /// directions: `volume q_o(x) p(w) + sum over groups of each component's probability times
    /// (sum_points q_k(x) p_k(w | x) + sum_beams q_j(x) p_j(w | x))`, with `p` the configured
    /// direction density `base` (and `p_k` too without `point_directions`).
    #[inline]
    pub(crate) fn joint_pdf<P: PhaseFunction>(
        &self,
        volume_pdf: f64,
        base: f64,
        phase: &P,
        x: DVec3,
        w: DVec3,
    ) -> f64 {
        let mut total = self.volume * volume_pdf * base;
        for (r, each) in self.ranges() {
            let point = |k| {
                let q = self.point_pdf(k, x);
                if q == 0.0 {
                    0.0
                } else {
                    q * self.point_direction_pdf(k, base, phase, x, w)
                }
            };
            let (points, beams) = self.sums(r, point, |b| {
                let q = b.pdf(x);
                if q == 0.0 {
                    0.0
                } else if b.samples_directions() {
                    q * b.direction_pdf(phase, x, w)
                } else {
                    q * base
                }
            });
            total += each * (points + beams);
        }
        total
    }

    /// A point sampled from one of the components, chosen by `c` in `[volume, 1)` (a group by
    /// its probability, then a component of it), with three variates, and which component it
    /// came from.
    #[inline]
    pub(crate) fn sample_component(&self, c: f64, u: [f64; 3]) -> (DVec3, Component) {
        let mut start = 0;
        let mut below = self.volume;
        let mut k = 0;
        for (g, &(end, p)) in self.groups.iter().enumerate() {
            if c < below + p || g + 1 == self.groups.len() {
                let n = end - start;
                k = start + (((c - below) / p * n as f64) as usize).min(n - 1);
                break;
            }
            below += p;
            start = end;
        }
        if k >= self.points.len() {
            let j = k - self.points.len();
            return (self.beams[j].sample(u), Component::Beam(j));
        }
        (self.sample_point(k, u), Component::Point(k))
    }

    /// A point from the component around point `k` (three variates): `p + r w`, `w` uniform
    /// on the sphere (circle), `r` exponential at the component's rate.
    #[inline]
    pub(crate) fn sample_point(&self, k: usize, u: [f64; 3]) -> DVec3 {
        let w = self.dimension.sample_uniform_direction([u[0], u[1]]);
        let r = -(-u[2]).ln_1p() / self.rates[k];
        self.points[k] + r * w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::first::{FirstVertex, FirstVertexSampler};
    use speckle_medium::{Aabb, HomogeneousBox};

    #[test]
    fn point_mixture_densities_integrate_to_their_mass_in_the_box() {
        // E[1 / q(x); x in box] over mixture samples is the box's measure: `pdf` is the density
        // `sample_point` draws from, in 3D and flatland (one point inside the box, one on a
        // face, so that some samples leave it).
        let cases = [
            (
                Aabb::new(DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 2.0)).unwrap(),
                [DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 0.5, 1.0)],
                Dimension::Three,
            ),
            (
                Aabb::flat(glam::DVec2::new(-1.0, 0.0), glam::DVec2::new(1.0, 2.0)).unwrap(),
                [DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 1.0, 0.0)],
                Dimension::Two,
            ),
        ];
        for (b, points, dimension) in cases {
            let m = HomogeneousBox::new(b, 1.5, 0.0).unwrap();
            let vol = FirstVertexSampler::new(FirstVertex::Uniform, &m).unwrap();
            let mix = EndpointMixture {
                points: points.to_vec(),
                rates: vec![1.5, 0.7],
                beams: vec![],
                volume: 1.0 / 3.0,
                groups: EndpointMixture::one_group(2, 1.0 / 3.0),
                dimension,
                point_directions: false,
            };
            let n = 400_000;
            let (mut acc, mut acc2) = (0.0, 0.0);
            let mut rng = crate::PathRng::new(9, 0);
            for _ in 0..n {
                let c = rng.next_f64();
                let x = if c < mix.volume {
                    vol.sample(&m, rng.next_3()).0
                } else {
                    mix.sample_component(c, rng.next_3()).0
                };
                if b.contains(x) {
                    let y = 1.0 / mix.pdf(vol.pdf(&m, x), x);
                    acc += y;
                    acc2 += y * y;
                }
            }
            let measure = b.measure();
            let mean = acc / n as f64;
            let se = ((acc2 / n as f64 - mean * mean) / n as f64).sqrt();
            assert!(
                (mean - measure).abs() < 4.0 * se,
                "{dimension}: {mean} +- {se} vs {measure}"
            );
            assert!(se < 0.01 * measure, "{se}");
        }
    }
}
