//! The sub-path tracer.

use crate::beam::BeamSampler;
use crate::first::{FirstDirectionSampler, FirstVertexSampler};
use crate::mixture::{Component, EndpointMixture};
use crate::{Beam, BeamStrategy, Coherence, FirstDirection, FirstVertex, PathError, PathRng};
use glam::DVec3;
use speckle_medium::{Interface, Medium};
use speckle_phase::PhaseFunction;

/// Most point components of the first-vertex mixture for points outside the medium
/// ([`Tracer::with_point_endpoints`]).
pub const MAX_OUTSIDE_COMPONENTS: usize = 64;

/// Most beam components of the first-vertex mixture that also sample first directions
/// ([`Tracer::with_endpoints`]): their direction density, a vMF pair mixture per beam, costs
/// tens of exponentials at every vertex. With more distinct beams (a `gaussian_grid` camera),
/// only the sources' beams sample directions (none with more source beams than this); the
/// others are position components.
pub const MAX_BEAM_COMPONENTS: usize = 16;

/// Most beam components of the first-vertex mixture ([`Tracer::with_endpoints`]). A position
/// component costs one exponential per vertex, less than the connection the estimator makes to
/// the same beam, and a table of a few kilobytes; with more distinct beams the sensors' are left
/// out, and with more source beams than this, all are.
pub const MAX_POSITION_BEAMS: usize = 4096;

/// How sub-paths are sampled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TracerConfig {
    /// Strategy for `x1`.
    pub first_vertex: FirstVertex,
    /// Strategy for the first direction.
    pub first_direction: FirstDirection,
    /// How first vertices and directions follow focused Gaussian beams
    /// ([`Tracer::with_endpoints`]).
    pub beams: BeamStrategy,
    /// Paths stop after this many vertices. The default (`u32::MAX`) never truncates; a smaller
    /// value drops the contribution of longer paths (a bias the caller accepts).
    pub max_vertices: u32,
}

impl Default for TracerConfig {
    fn default() -> Self {
        Self {
            first_vertex: FirstVertex::Uniform,
            first_direction: FirstDirection::Uniform,
            beams: BeamStrategy::default(),
            max_vertices: u32::MAX,
        }
    }
}

/// A vertex `x_b`, `b >= 2`, of a sub-path, with what next-event estimation needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Vertex {
    /// Vertex index `b >= 2`.
    pub index: u32,
    /// The first vertex `x1`.
    pub x1: DVec3,
    /// Unit direction from `x1` to `x2`.
    pub w12: DVec3,
    /// This vertex `x_b`.
    pub x: DVec3,
    /// Unit direction arriving at `x_b`.
    pub w_in: DVec3,
    /// The direction in which `x_{b-1}` scattered the path: `w_in` unless the flight was
    /// reflected by a face on the way ([`Tracer::with_interface`]).
    pub w_prev_out: DVec3,
    /// Particle type at `x1` (always 0 in a single-type medium).
    pub type1: usize,
    /// Particle type at `x_b`, the same particle that scatters the path onwards (always 0 in
    /// a single-type medium).
    pub ty: usize,
    /// Throughput over sampling density, `sigma_s(x1) / (q_o(x1) p(w1))` (Eq. 36 without the
    /// forward/reversed factor 1/2).
    pub weight: f64,
    /// The factor on `weight` of a contribution that sums the forward and the reversed terms
    /// (Eq. 36): exactly 1/2 when the vertices are sampled in this order and in reverse with
    /// the same density (or, with a first-vertex density that is not symmetric, an unbiased
    /// equal split), and with point endpoints next to the medium or Gaussian beams the balance
    /// heuristic `q(x) / (q(x) + q(x^r))` of the joint densities of the first vertex and
    /// direction in the two orders ([`Tracer::with_endpoints`]).
    pub both_orders: f64,
    /// The length of the path's flights from `x1` to `x_b` (along reflections off the faces).
    pub length: f64,
}

impl Vertex {
    /// The weight of this vertex's contribution: `both_orders * weight` with forward and
    /// reversed terms, `weight` with forward terms only (which a tracer with point endpoints
    /// does not support: see [`Tracer::needs_reversed_paths`]).
    #[inline]
    pub fn weight_for(&self, coherence: Coherence) -> f64 {
        match coherence {
            Coherence::ForwardAndReversed => self.both_orders * self.weight,
            Coherence::ForwardOnly => self.weight,
        }
    }
}

/// A sub-path leaving the medium: the flight from its last vertex `x_b` crossed the boundary of
/// the medium's box at `point`, travelling along `dir` (light tracing: what a detector on the
/// boundary registers).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exit {
    /// Index `b >= 1` of the last vertex.
    pub index: u32,
    /// The first vertex `x1`.
    pub x1: DVec3,
    /// Unit direction from `x1` to the next vertex (or to the exit when `index == 1`).
    pub w12: DVec3,
    /// The last vertex `x_b`.
    pub x: DVec3,
    /// Unit direction arriving at `x_b` (zero when `index == 1`: the caller knows the source leg).
    pub w_in: DVec3,
    /// The direction in which `x_b` scattered the path (the exit flight's direction, unless it
    /// was reflected by faces on the way).
    pub w_out: DVec3,
    /// The direction of the light leaving the medium: inside the box, then refracted outside
    /// when the faces refract ([`Tracer::with_interface`]).
    pub dir: DVec3,
    /// Fresnel reflections off the faces between `x_b` and the exit.
    pub reflections: u32,
    /// Where the flight crosses the medium's boundary.
    pub point: DVec3,
    /// Particle type at `x_b`.
    pub ty: usize,
    /// The path weight `sigma_s(x1) / (q_o(x1) p(w1))` (forward order; see [`Vertex::weight`]):
    /// the exit flight and the roulette at earlier vertices are sampled with the densities of
    /// the throughput, so the exit carries the same weight as the vertices.
    pub weight: f64,
    /// The length of the path's flights from `x1` to the exit `point` (along reflections).
    pub length: f64,
}

/// Where a flight that reaches a face of the box goes ([`Tracer::at_face`]).
pub(crate) enum AtFace {
    /// Back into the medium from `point` along `dir`.
    Reflected { point: DVec3, dir: DVec3 },
    /// Out of the medium at `point` along `dir` (refracted).
    Leaves { point: DVec3, dir: DVec3 },
}

/// Receives the vertices of a sub-path as they are sampled.
pub trait VertexSink {
    /// Light tracing ([`Tracer::trace_emitted`]): the direction in which the emitted light
    /// arrives at the first vertex and the length of its flights inside the medium to it,
    /// given just before [`VertexSink::first`]. The default ignores them.
    #[inline]
    fn arrival(&mut self, _dir: DVec3, _length: f64) {}
    /// The first vertex `x1` with the particle type there, and the single-scattering weight
    /// `sigma_s(x1) / q_o(x1)`.
    fn first(&mut self, x1: DVec3, ty: usize, weight: f64, rng: &mut PathRng);
    /// A vertex `x_b`, `b >= 2`.
    fn vertex(&mut self, v: &Vertex, rng: &mut PathRng);
    /// The path leaves the medium ([`Exit`]); it ends there. The default ignores it.
    #[inline]
    fn exit(&mut self, _exit: &Exit, _rng: &mut PathRng) {}
    /// Asked before every flight: `false` ends the path there (a cancelled render stops inside
    /// a long path instead of finishing it). The default always continues.
    #[inline]
    fn keep_going(&mut self) -> bool {
        true
    }
    /// Whether this sink takes branch vertices ([`VertexSink::branch`]), asked once per path.
    /// The tracer then samples, with point endpoints next to the medium, last vertices around
    /// the points as well, and weighs every vertex by the balance heuristic of all its
    /// techniques (see [`Tracer::with_point_endpoints`]). The default is `false`: vertices keep
    /// the heuristic of the two orders alone.
    #[inline]
    fn branches(&self) -> bool {
        false
    }
    /// A branch: the path `x_1 .. x_b, v.x` that leaves the sub-path at its last vertex `x_b`
    /// (the one handed to [`VertexSink::first`] or [`VertexSink::vertex`] last) for a vertex
    /// sampled around a point endpoint. It contributes as a vertex does ([`Vertex::weight`],
    /// [`Vertex::both_orders`]), but the sub-path goes on from `x_b`: the sink's per-path state
    /// must be as it was before the call. Only called when [`VertexSink::branches`] is true.
    #[inline]
    fn branch(&mut self, _v: &Vertex, _rng: &mut PathRng) {}
}

/// Samples sub-paths in a medium with a phase function (Alg. 1, with roulette at every `b >= 2`).
///
/// In a medium of several particle types (Bar et al. 2019, App. A.1, Alg. 3/4) each vertex draws
/// the type of its particle with probability `beta_iota(x)` ([`Medium::sample_type`]), and the
/// path leaves the vertex along a direction sampled from that type's phase function, so the
/// direction density is the bulk phase function `sum beta_iota |s_iota|^2`. A single-type medium
/// draws no types (its random streams are those of a tracer without types).
#[derive(Debug, Clone)]
pub struct Tracer<'a, M, P> {
    pub(crate) medium: &'a M,
    pub(crate) phases: &'a [P],
    typed: bool,
    first_vertex: FirstVertexSampler,
    first_direction: FirstDirectionSampler,
    points: Option<EndpointMixture>,
    beams: BeamStrategy,
    pub(crate) max_vertices: u32,
    /// Whether vertices carry the balance heuristic of both orders ([`Vertex::both_orders`]).
    both_orders: bool,
    /// A refractive-index mismatch at the box's faces.
    pub(crate) interface: Option<Interface>,
}

impl<'a, M: Medium, P: PhaseFunction> Tracer<'a, M, P> {
    /// A tracer for `medium` and `phase` with the given strategies.
    pub fn new(medium: &'a M, phase: &'a P, config: TracerConfig) -> Result<Self, PathError> {
        Self::with_types(medium, std::slice::from_ref(phase), config)
    }

    /// A tracer for a medium of several particle types: `phases[iota]` is the phase function of
    /// type `iota`, one per [`Medium::particle_types`].
    pub fn with_types(
        medium: &'a M,
        phases: &'a [P],
        config: TracerConfig,
    ) -> Result<Self, PathError> {
        if config.max_vertices == 0 {
            return Err(PathError::InvalidMaxVertices);
        }
        if phases.len() != medium.particle_types() {
            return Err(PathError::TypeCount {
                medium: medium.particle_types(),
                phases: phases.len(),
            });
        }
        let dimension = medium.dimension();
        if let Some(p) = phases.iter().find(|p| p.dimension() != dimension) {
            return Err(PathError::DimensionMismatch {
                medium: dimension,
                phase: p.dimension(),
            });
        }
        Ok(Self {
            medium,
            phases,
            typed: phases.len() > 1,
            first_vertex: FirstVertexSampler::new(config.first_vertex, medium)?,
            first_direction: FirstDirectionSampler::new(config.first_direction, dimension)?,
            points: None,
            beams: config.beams,
            max_vertices: config.max_vertices,
            both_orders: true,
            interface: None,
        })
    }

    /// Adds to the first-vertex strategy one component around each of `points` (the point
    /// sources and sensors of a scene) that lies in the medium's box or within one extinction
    /// length of it (`1 / sigma_t`, at the box point nearest to it): with `n` such points the
    /// first vertex is sampled from the configured strategy with probability `1 / (n + 1)` and
    /// from around each point with probability `1 / (n + 1)` each, at distance `r` with density
    /// `sigma_t exp(-sigma_t r)` in a uniform direction. When the scene has no other endpoints
    /// (`others` false) and every point is near, the configured strategy gets no share: the
    /// point components alone cover the medium, with the `exp(-sigma_t r) / r^2` of a point's
    /// own leg (diffuse correlation spectroscopy, where a volume strategy mostly samples paths
    /// that reach neither endpoint).
    ///
    /// Every vertex then weighs its forward and reversed terms by the balance heuristic of the
    /// two orders ([`Vertex::both_orders`]), so that the last vertex, too, is in effect sampled
    /// from around a point sensor: the `1/r^2` of a point endpoint's connection, which gives
    /// the plain estimator infinite variance next to the endpoint, is cancelled by the density
    /// at both ends of a path. With an anisotropic phase function a point component also draws
    /// the first direction from the phase function about the ray from its point. A sink that
    /// takes branches ([`VertexSink::branches`]) also receives, from every vertex, last vertices
    /// sampled around the points, and every vertex then carries the balance heuristic of four
    /// techniques (`tracer/branch.rs`): the two orders alone leave a path whose two ends lie
    /// next to two points with both `1/r^2` factors, and a diverging variance. Points farther away are left to the plain strategy, and without
    /// any near point the tracer is unchanged (bitwise). Every vertex evaluates the density of
    /// every component: when more than [`MAX_OUTSIDE_COMPONENTS`] points are near, only those in
    /// or on the medium's box (which need it) get components.
    pub fn with_point_endpoints(self, points: &[DVec3], others: bool) -> Self {
        self.with_endpoints(points, &[], &[], 1.0, others)
    }

    /// [`Tracer::with_point_endpoints`] with, in addition, one component per distinct focused
    /// Gaussian beam of `sources` and `sensors` (in their source form) when the configured
    /// [`BeamStrategy`] is not `Off`, for wavenumber `k`: first vertices from the beam's
    /// Gaussian structure (Bar et al. 2020, Eqs. 33-36) and, with
    /// [`BeamStrategy::PositionAndDirection`], first directions from the vMF pair mixture of
    /// `|Upsilon|^2` (Sec. 6) mixed with the phase function about the beam's axis. Beams always
    /// leave the volume strategy its share `1 / (n + 1)` (`n` components): the beam model is a
    /// proposal, not the throughput. With more than [`MAX_BEAM_COMPONENTS`] beams the shares go
    /// by kind instead: the volume, the points, the sources' beams and the sensors' beams each
    /// have an equal share, split equally within the kind. The weights use the exact density of
    /// the whole mixture, evaluated for both orders of every path ([`Vertex::both_orders`]);
    /// unlike point components, beams do not need reversed paths. Every vertex evaluates every
    /// beam's density: beyond [`MAX_BEAM_COMPONENTS`] distinct beams only the sources' sample
    /// directions (few illuminators, many pixels: the paper samples the first segment for that
    /// reason) and the others only positions, which covers the foci of every pixel of a camera
    /// (leaving them out gave the fields rare paths of large weight near the pixels' foci);
    /// beyond [`MAX_POSITION_BEAMS`] only the sources' beams are kept, and none beyond that many
    /// sources.
    pub fn with_endpoints(
        mut self,
        points: &[DVec3],
        sources: &[Beam],
        sensors: &[Beam],
        k: f64,
        others: bool,
    ) -> Self {
        let m = self.medium;
        let b = m.bounds();
        let mut near = vec![];
        let mut far = false;
        // The points already taken, by their coordinates (hashed: a camera grid of a million
        // points next to the medium was a linear scan per point). The key of a point is what
        // `==` compares: -0 and +0 are one coordinate; a point with a NaN coordinate equals
        // none, so it has no key and is always taken.
        let mut seen = std::collections::HashSet::new();
        let key = |p: DVec3| (!p.is_nan()).then(|| p.to_array().map(|c| (c + 0.0).to_bits()));
        for &p in points {
            let nearest = p.clamp(b.min(), b.max());
            let rate = match m.uniform_sigma_t() {
                Some(s) => s,
                None => m.sigma_t(nearest),
            };
            // A void next to the point: any fixed rate is unbiased; one over the box's size.
            let rate = if rate > 0.0 && rate.is_finite() {
                rate
            } else {
                1.0 / b.size().length()
            };
            if (p - nearest).length() * rate > 1.0 {
                far = true;
            } else if key(p).is_none_or(|k| seen.insert(k)) {
                near.push((p, rate, p == nearest));
            }
        }
        // Every vertex evaluates the density of every component: beyond a few dozen points
        // (a camera grid next to the medium) only those in or on the medium, which need it
        // for a finite variance, are kept; the others go back to the plain strategy.
        if near.len() > MAX_OUTSIDE_COMPONENTS {
            far |= near.iter().any(|(_, _, inside)| !inside);
            near.retain(|(_, _, inside)| *inside);
        }
        let (near, rates): (Vec<_>, Vec<_>) = near.into_iter().map(|(p, r, _)| (p, r)).unzip();
        // The distinct beams of `list`, or None past `cap` of them (a camera of millions of
        // pixels is not scanned to the end).
        let distinct = |list: &[Beam], cap: usize| {
            let mut unique: Vec<Beam> = vec![];
            for b in list {
                if !unique.contains(b) {
                    if unique.len() == cap {
                        return None;
                    }
                    unique.push(*b);
                }
            }
            Some(unique)
        };
        let off = self.beams == BeamStrategy::Off;
        let cap = MAX_POSITION_BEAMS;
        // The beams: the sources' (distinct) first, then the sensors' not among them.
        let (unique, n_sources) = match (off, distinct(sources, cap)) {
            (false, Some(s)) => {
                let n = s.len();
                let all = distinct(&[sources, sensors].concat(), cap);
                (all.unwrap_or(s), n)
            }
            _ => (vec![], 0),
        };
        // Which beams also sample directions: all of them, or past the cap the sources'.
        let directed = if unique.len() <= MAX_BEAM_COMPONENTS {
            unique.len()
        } else if n_sources <= MAX_BEAM_COMPONENTS {
            n_sources
        } else {
            0
        };
        let lobes = self.phases[0].amplitude_lobes();
        let directions = self.beams == BeamStrategy::PositionAndDirection;
        let beams: Vec<BeamSampler> = unique
            .iter()
            .enumerate()
            .map(|(i, b)| BeamSampler::new(b, m, k, lobes, directions && i < directed))
            .collect();
        let (np, nb) = (near.len(), beams.len());
        let n = np + nb;
        // Up to MAX_BEAM_COMPONENTS beams every strategy has an equal share: each beam component
        // follows its own beam's intensity. A larger set (a camera, a grid of foci) covers a
        // region rather than matching any one beam (the sum of many pixels' intensities is
        // flat in depth where each pixel's density falls), and equal shares would starve the
        // few sources and the volume. There each kind, the volume, the points, the sources'
        // beams and the sensors' beams, has an equal share, split equally within the kind.
        let (volume, groups) = if !(others || far || nb > 0) {
            (0.0, EndpointMixture::one_group(n, 0.0))
        } else if nb > MAX_BEAM_COMPONENTS {
            let ends: Vec<usize> = [np, np + n_sources.min(nb), n]
                .into_iter()
                .scan(0, |start, end| {
                    let nonempty = end > *start;
                    *start = end;
                    Some(nonempty.then_some(end))
                })
                .flatten()
                .collect();
            let share = 1.0 / (ends.len() + 1) as f64;
            (share, ends.into_iter().map(|e| (e, share)).collect())
        } else {
            let volume = 1.0 / (n + 1) as f64;
            (volume, EndpointMixture::one_group(n, volume))
        };
        self.points = (n > 0).then(|| EndpointMixture {
            volume,
            groups,
            points: near,
            rates,
            beams,
            dimension: m.dimension(),
            point_directions: np > 0 && self.phases.iter().any(|p| !is_isotropic(p)),
        });
        self
    }

    /// A tracer for forward estimators only (light tracing to detectors), which never read
    /// [`Vertex::both_orders`]: it is then NaN, and the mixture's density in the reversed order
    /// is not evaluated at every vertex (a third of a tissue path's cost). Paths, weights and
    /// exits are unchanged.
    pub fn without_both_orders(mut self) -> Self {
        self.both_orders = false;
        self
    }

    /// Makes the faces of the medium's box reflect and refract (Fresnel, unpolarised): a flight
    /// that reaches a face is reflected with the probability `R(cos_i)` (1 beyond the critical
    /// angle) and continues from the face without a vertex, or else leaves refracted
    /// ([`Exit::dir`]). Weights are unchanged (the reflection is sampled with its own
    /// probability). Only estimators that follow the path's directions through reflections
    /// ([`Vertex::w_prev_out`], [`Exit::w_out`]) and connect nothing across a face may use it:
    /// the detector estimators. A matched interface changes nothing.
    pub fn with_interface(mut self, interface: Interface) -> Self {
        self.interface = (!interface.is_matched()).then_some(interface);
        self
    }

    /// Whether contributions must sum forward and reversed terms
    /// ([`Coherence::ForwardAndReversed`]): true with point endpoints next to the medium, whose
    /// sampling at the last vertex is the reversed order of the path. A caller with forward
    /// paths only must not add point endpoints ([`Vertex::weight_for`]).
    pub fn needs_reversed_paths(&self) -> bool {
        self.points.as_ref().is_some_and(|p| !p.points.is_empty())
    }

    /// The first-vertex density at `x`, in the box.
    #[inline]
    fn first_pdf(&self, x: DVec3) -> f64 {
        match &self.points {
            // Points alone: the volume strategy's density is not needed.
            Some(p) if p.volume == 0.0 => p.pdf(0.0, x),
            Some(p) => p.pdf(self.first_vertex.pdf(self.medium, x), x),
            None => self.first_vertex.pdf(self.medium, x),
        }
    }

    /// The joint density of the first vertex `x` and first direction `w` where a particle of
    /// type `ty` scatters (`x` in the box).
    #[inline]
    fn joint_pdf(&self, x: DVec3, w: DVec3, ty: usize) -> f64 {
        let phase = &self.phases[ty];
        let base = self.first_direction.pdf(phase, w);
        match &self.points {
            Some(p) if p.samples_directions() => {
                let v = if p.volume == 0.0 {
                    0.0
                } else {
                    self.first_vertex.pdf(self.medium, x)
                };
                p.joint_pdf(v, base, phase, x, w)
            }
            _ => self.first_pdf(x) * base,
        }
    }

    /// The medium.
    pub fn medium(&self) -> &'a M {
        self.medium
    }

    /// The phase function of particle type 0 (the only one in a single-type medium).
    pub fn phase(&self) -> &'a P {
        &self.phases[0]
    }

    /// The phase functions, one per particle type.
    pub fn phases(&self) -> &'a [P] {
        self.phases
    }

    /// The particle type at `x` (drawing a variate only in a medium of several types).
    #[inline]
    pub(crate) fn sample_type(&self, x: DVec3, rng: &mut PathRng) -> usize {
        if self.typed {
            self.medium.sample_type(x, rng.next_f64())
        } else {
            0
        }
    }

    /// Samples only a first vertex and returns it with its particle type and single-scattering
    /// weight `sigma_s(x1) / q_o(x1)` (for estimators of single scattering alone, Eq. 41), or
    /// `None` where the sample starts no path: a point sampled around a point endpoint that
    /// lies outside the medium ([`Tracer::with_point_endpoints`]), whose contribution is zero.
    #[inline]
    pub fn sample_first_vertex(&self, rng: &mut PathRng) -> Option<(DVec3, usize, f64)> {
        self.sample_first(rng).map(|(x, ty, w, _)| (x, ty, w))
    }

    /// [`Tracer::sample_first_vertex`] with the density there and the component that sampled it.
    #[inline]
    fn sample_first(&self, rng: &mut PathRng) -> Option<(DVec3, usize, f64, Component)> {
        let (x1, q, from) = match &self.points {
            None => {
                let (x, q) = self.first_vertex.sample(self.medium, rng.next_3());
                (x, q, Component::Volume)
            }
            Some(p) => {
                let c = rng.next_f64();
                let (x, from) = if c < p.volume {
                    let x = self.first_vertex.sample(self.medium, rng.next_3()).0;
                    (x, Component::Volume)
                } else {
                    p.sample_component(c, rng.next_3())
                };
                if !self.medium.contains(x) || self.medium.sigma_s(x) <= 0.0 {
                    return None;
                }
                (x, self.first_pdf(x), from)
            }
        };
        let ty = self.sample_type(x1, rng);
        Some((x1, ty, self.medium.sigma_s(x1) / q, from))
    }

    /// Samples one sub-path, handing every vertex to `sink`; returns the number of vertices
    /// (0 where the sample starts no path, see [`Tracer::sample_first_vertex`]).
    pub fn trace<S: VertexSink>(&self, rng: &mut PathRng, sink: &mut S) -> u32 {
        let Some((x1, type1, w_single, from)) = self.sample_first(rng) else {
            return 0;
        };
        sink.first(x1, type1, w_single, rng);
        let branching = self.branching(sink);
        if branching {
            self.branch_first(x1, type1, w_single, rng, sink);
        }
        let Some((w12, weight)) = self.sample_first_direction(x1, type1, w_single, from, rng)
        else {
            return 1;
        };
        let mut w = Walker::start(x1, type1, w12, weight);
        w.branching = branching;
        w.q1_marginal = self.medium.sigma_s(x1) / w_single;
        1 + self.walk_from(&mut w, w12, rng, sink, |w, rng, sink| {
            if branching {
                self.branch_at(w, rng, sink);
            }
            true
        })
    }

    /// The first direction `w12` of a path from `x1` (type `type1`, single-scattering weight
    /// `w_single`, sampled by component `from`) and the path's weight `sigma_s(x1) / q(x1, w12)`
    /// with the joint density `q` of the first vertex and direction; `None` where that density
    /// vanishes.
    #[inline]
    fn sample_first_direction(
        &self,
        x1: DVec3,
        type1: usize,
        w_single: f64,
        from: Component,
        rng: &mut PathRng,
    ) -> Option<(DVec3, f64)> {
        let phase1 = &self.phases[type1];
        let joint = self.points.as_ref().is_some_and(|p| p.samples_directions());
        if joint {
            // The direction from the strategy of the sampling component, the weight from the
            // joint density of the whole mixture.
            let w12 = match (from, &self.points) {
                (Component::Beam(j), Some(p)) if p.beams[j].samples_directions() => {
                    let c = rng.next_f64();
                    p.beams[j].sample_direction(phase1, x1, c, rng.next_2())
                }
                (Component::Point(k), Some(p)) if p.point_directions => {
                    phase1.sample_direction(p.ray(k, x1), rng.next_2())
                }
                _ => self.first_direction.sample(phase1, rng.next_2()).0,
            };
            let p = self.joint_pdf(x1, w12, type1);
            if p <= 0.0 || !p.is_finite() {
                return None;
            }
            Some((w12, self.medium.sigma_s(x1) / p))
        } else {
            let (w12, p_w) = self.first_direction.sample(phase1, rng.next_2());
            if p_w <= 0.0 {
                return None;
            }
            Some((w12, w_single / p_w))
        }
    }

    /// A flight from `x` along `dir` that reaches the box's boundary: reflected back in with
    /// the Fresnel probability of the interface (one variate drawn only with an interface), or
    /// leaving it, refracted.
    #[inline]
    pub(crate) fn at_face(&self, x: DVec3, dir: DVec3, rng: &mut PathRng) -> AtFace {
        let bounds = self.medium.bounds();
        let point = x + bounds.exit_distance(x, dir) * dir;
        let Some(i) = self.interface else {
            return AtFace::Leaves { point, dir };
        };
        let normal = bounds.exit_normal(x, dir);
        if rng.next_f64() < i.reflectance(dir.dot(normal)) {
            let dir = speckle_medium::boundary::reflect(dir, normal);
            return AtFace::Reflected { point, dir };
        }
        let dir = i.refract(dir, normal).unwrap_or(dir);
        AtFace::Leaves { point, dir }
    }

    /// Follows a path from its first vertex `x1` (particle type `type1`) along `w12` with the
    /// weight `weight`: flights, roulette, vertices and the exit, as [`Tracer::trace`] after
    /// its first vertex; returns the number of vertices.
    pub(crate) fn walk<S: VertexSink>(
        &self,
        x1: DVec3,
        type1: usize,
        w12: DVec3,
        weight: f64,
        rng: &mut PathRng,
        sink: &mut S,
    ) -> u32 {
        let mut w = Walker::start(x1, type1, w12, weight);
        1 + self.walk_from(&mut w, w12, rng, sink, |_, _, _| true)
    }

    /// Follows the walker `w` from its last vertex along `dir` to the path's end: flights (and
    /// reflections at the faces), roulette on the albedo, vertices handed to `sink`, the exit;
    /// after each new vertex `at_vertex` may change the walker (its weight: splitting and
    /// roulette of light tracing) or end it (`false`). Returns the vertices added.
    pub(crate) fn walk_from<S: VertexSink>(
        &self,
        w: &mut Walker,
        mut dir: DVec3,
        rng: &mut PathRng,
        sink: &mut S,
        mut at_vertex: impl FnMut(&mut Walker, &mut PathRng, &mut S) -> bool,
    ) -> u32 {
        // Where the flight starts, the direction the last vertex scattered into, and the
        // reflections since.
        let (mut x, mut scattered, mut reflections) = (w.here, dir, 0u32);
        let mut added = 0;
        while w.b < self.max_vertices && sink.keep_going() {
            let Some(d) = self.medium.sample_flight(x, dir, &mut || rng.next_f64()) else {
                let (point, leaving) = match self.at_face(x, dir, rng) {
                    AtFace::Reflected { point, dir: d } => {
                        w.length += (point - x).length();
                        (x, dir) = (point, d);
                        reflections += 1;
                        continue;
                    }
                    AtFace::Leaves { point, dir } => (point, dir),
                };
                sink.exit(
                    &Exit {
                        index: w.b,
                        x1: w.x1,
                        w12: w.w12,
                        x: w.here,
                        w_in: w.w_in,
                        w_out: scattered,
                        dir: leaving,
                        point,
                        ty: w.ty,
                        weight: w.weight,
                        reflections,
                        length: w.length + (point - x).length(),
                    },
                    rng,
                );
                break;
            };
            let next = x + d * dir;
            // Russian roulette on the albedo at the new vertex.
            if rng.next_f64() >= self.medium.albedo(next) {
                break;
            }
            w.b += 1;
            w.length += d;
            added += 1;
            let ty = self.sample_type(next, rng);
            let both_orders = match &self.points {
                _ if !self.both_orders => f64::NAN,
                None => 0.5,
                // q(x^r) / q(x) = weight / w_rev, w_rev = sigma_s(x_b) / (q_o(x_b) p(-w_in)):
                // the interior densities of the two orders are equal (flights and roulette
                // give sigma_s at every vertex but the first, phase functions are symmetric).
                Some(p) => {
                    let p_rev = self.joint_pdf(next, -dir, ty);
                    let reversed = w.weight * p_rev / self.medium.sigma_s(next);
                    let branches = if w.branching {
                        self.branch_ratios(p, w, next, dir, p_rev, reversed)
                    } else {
                        0.0
                    };
                    1.0 / (1.0 + reversed + branches)
                }
            };
            sink.vertex(
                &Vertex {
                    index: w.b,
                    x1: w.x1,
                    w12: w.w12,
                    x: next,
                    w_in: dir,
                    w_prev_out: scattered,
                    type1: w.type1,
                    ty,
                    weight: w.weight,
                    both_orders,
                    length: w.length,
                },
                rng,
            );
            (w.here, w.w_in, w.ty) = (next, dir, ty);
            if !at_vertex(w, rng, sink) {
                break;
            }
            dir = self.phases[ty].sample_direction(dir, rng.next_2());
            x = next;
            scattered = dir;
            reflections = 0;
        }
        added
    }
}

/// Whether `p` scatters isotropically: an amplitude of one lobe of concentration zero (the
/// phase functions without lobes are taken as anisotropic).
fn is_isotropic<P: PhaseFunction>(p: &P) -> bool {
    p.amplitude_lobes()
        .is_some_and(|l| l.iter().all(|&(gamma, _)| gamma == 0.0))
}

/// Where a walking path is: its first vertex and direction, its last vertex with the direction
/// it arrived along and the particle type there, its vertex count, its weight and the length of
/// its flights since `x1`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Walker {
    pub(crate) x1: DVec3,
    pub(crate) w12: DVec3,
    pub(crate) type1: usize,
    pub(crate) here: DVec3,
    pub(crate) w_in: DVec3,
    pub(crate) ty: usize,
    pub(crate) b: u32,
    pub(crate) weight: f64,
    pub(crate) length: f64,
    /// Whether the path branches ([`VertexSink::branches`]): its vertices weigh the branch
    /// techniques too.
    pub(crate) branching: bool,
    /// The marginal first-vertex density `q_o(x1)` (branching paths).
    pub(crate) q1_marginal: f64,
    /// `Q_p(x1 | x2) / f(x2 -> x1)` once `x2` is known: the reversed branch's density of `x1`
    /// over the flight it replaces, without the phase function at `x2` (branching paths).
    pub(crate) back: f64,
    /// `back / rho_2(w12 . w23)` once `x3` is known (branching paths).
    pub(crate) crossed: f64,
}

impl Walker {
    /// A path at its first vertex `x1`, about to leave along `w12`.
    pub(crate) fn start(x1: DVec3, type1: usize, w12: DVec3, weight: f64) -> Self {
        Self {
            x1,
            w12,
            type1,
            here: x1,
            w_in: DVec3::ZERO,
            ty: type1,
            b: 1,
            weight,
            length: 0.0,
            branching: false,
            q1_marginal: f64::NAN,
            back: f64::NAN,
            crossed: f64::NAN,
        }
    }
}

mod branch;
#[cfg(test)]
mod tests;
