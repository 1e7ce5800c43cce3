//! Light tracing: paths emitted by the sources, in the absolute units of
//! `docs/conventions.md`, entering the medium through its faces (refracted or reflected at a
//! mismatched interface), and splitting and Russian roulette by a weight window.

use crate::PathRng;
use crate::tracer::{AtFace, Tracer, VertexSink, Walker};
use glam::DVec3;
use speckle_medium::Medium;
use speckle_phase::PhaseFunction;

/// Where the light of a light-tracing path comes from ([`Tracer::trace_emitted`]), in the
/// absolute units of `docs/conventions.md`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Emission {
    /// An isotropic point source of unit radiant intensity (`e^{ikr}/r`: power `4 pi`), inside,
    /// on or outside the medium's box.
    Point(DVec3),
    /// A plane wave of unit intensity along the unit direction (a face at incidence `theta`
    /// receives the power `cos(theta)` per unit area).
    Plane(DVec3),
    /// A disc on a face of the medium's box emitting unit power (outside the face) with uniform
    /// radiance within a cone: the tip of a multimode fibre ([`Disc`]).
    Disc(Disc),
}

/// A disc on a face of the medium's box that emits unit power, outside the face, with the same
/// radiance at every point of the disc and every direction of a cone about its axis (a
/// multimode fibre's tip; at the full aperture a Lambertian disc). Light reflected by a
/// mismatched face at entry is lost, as from any source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disc {
    /// The centre, on a face of the box.
    pub center: DVec3,
    /// The face's outward normal: a coordinate axis, `+-x`, `+-y` or `+-z`.
    pub normal: DVec3,
    /// The cone's axis (unit): the direction the light travels along into the medium. The cone
    /// lies within the face's inward hemisphere: `-axis . normal >= sin_max`.
    pub axis: DVec3,
    /// The disc's radius.
    pub radius: f64,
    /// The sine of the cone's half-angle (outside the face), in `(0, 1]`.
    pub sin_max: f64,
}

impl Disc {
    /// A point of the disc (uniform), a direction of the cone, and the weight of the pair for
    /// unit power (1 when the axis is the inward normal, where directions are sampled by the
    /// radiance's `cos` itself; else `cos / E[cos]` over directions uniform in the cone), from
    /// four uniform variates.
    pub fn sample(&self, u: [f64; 4]) -> (DVec3, DVec3, f64) {
        let n = self.normal;
        // Two face axes (exact zeros along the normal keep the point on the face).
        let (t1, t2) = if n.x != 0.0 {
            (DVec3::Y, DVec3::Z)
        } else if n.y != 0.0 {
            (DVec3::Z, DVec3::X)
        } else {
            (DVec3::X, DVec3::Y)
        };
        let r = self.radius * u[0].sqrt();
        let (s, c) = (std::f64::consts::TAU * u[1]).sin_cos();
        let point = self.center + r * (c * t1 + s * t2);
        let sin2 = self.sin_max * self.sin_max;
        let (s, c) = (std::f64::consts::TAU * u[3]).sin_cos();
        if self.axis == -n {
            // Density cos / (pi sin2) in the cone: sin^2 uniform on [0, sin2].
            let st2 = u[2] * sin2;
            let (st, ct) = (st2.sqrt(), (1.0 - st2).max(0.0).sqrt());
            return (point, ct * self.axis + st * (c * t1 + s * t2), 1.0);
        }
        // Uniform in the cone (solid angle `2 pi (1 - cos_max)`), weighted by the cosine to
        // the inward normal over its mean, `(axis . m) pi sin2 / solid angle` (the part of the
        // cosine across the axis averages to zero).
        let one_minus_cos = sin2 / (1.0 + (1.0 - sin2).max(0.0).sqrt());
        let ct = 1.0 - u[2] * one_minus_cos;
        let st = (1.0 - ct * ct).max(0.0).sqrt();
        let (a1, a2) = self.axis.any_orthonormal_pair();
        let dir = ct * self.axis + st * (c * a1 + s * a2);
        let solid = std::f64::consts::TAU * one_minus_cos;
        let mean_cos = -self.axis.dot(n) * std::f64::consts::PI * sin2 / solid;
        (point, dir, (-dir.dot(n)).max(0.0) / mean_cos)
    }
}

/// A sink whose per-path state can be saved at a split and restored for each copy
/// ([`Tracer::trace_emitted_split`]).
pub trait ForkSink: VertexSink {
    /// The saved state.
    type Saved;
    /// The state now (after the vertex where the path splits).
    fn save(&self) -> Self::Saved;
    /// Restores a saved state before a copy continues.
    fn restore(&mut self, saved: &Self::Saved);
}

/// A weight window for [`Tracer::trace_emitted_split`]: the target weight of a path at each
/// point (the window is `[target / 2, 2 target]`), and limits on the copies.
pub struct WeightWindow<'w> {
    /// The target weight at a point; not finite or not positive: no window there.
    pub target: &'w (dyn Fn(DVec3) -> f64 + Sync),
    /// Most copies a path splits into at one vertex.
    pub max_split: u32,
    /// Most particles (the path and its copies) of one path.
    pub max_particles: u32,
}

/// A particle of a split path: where it is, and what its sink and stream were.
struct Particle<T> {
    walker: Walker,
    /// The direction onwards when already sampled (the first flight), else sampled from the
    /// phase function about the direction of arrival.
    dir: Option<DVec3>,
    /// A copy's own stream (`None`: the path's).
    rng: Option<PathRng>,
    saved: Option<T>,
}

impl<'a, M: Medium, P: PhaseFunction> Tracer<'a, M, P> {
    /// Samples one path of light tracing from `emission` (analog emission, [`Emission`]): the
    /// light enters the medium (refracted, or reflected away with the Fresnel probability, at a
    /// mismatched face, [`Tracer::with_interface`]), its first flight (reflected by the faces on
    /// the way) ends at the first vertex `x1`, whose weight is the emitted power times the
    /// albedo there (no roulette at `x1`), and `w12` follows from the phase function about the
    /// direction of arrival, which the sink receives first ([`VertexSink::arrival`]). Returns
    /// the number of vertices (0 when the light leaves unscattered).
    pub fn trace_emitted<S: VertexSink>(
        &self,
        emission: Emission,
        rng: &mut PathRng,
        sink: &mut S,
    ) -> u32 {
        let Some((x1, type1, w12, weight)) = self.emit(emission, rng, sink) else {
            return 0;
        };
        self.walk(x1, type1, w12, weight, rng, sink)
    }

    /// [`Tracer::trace_emitted`] with splitting and Russian roulette by a weight window
    /// ([`WeightWindow`]): where the path's weight exceeds twice the window's target at a
    /// vertex it is split into copies of equal weight (each its own random stream, from the
    /// path's), where it falls below half the target it survives with the probability
    /// `weight / target` at the target weight. Both keep every expectation (each copy, and each
    /// survivor, carries the weight it stands for), so any target function gives an unbiased
    /// estimate; a target that falls towards the detectors (the reciprocal of an importance)
    /// spends the paths where they count. The sink's state is saved at each split and restored
    /// for each copy ([`ForkSink`]); the copies' contributions add to the path's.
    pub fn trace_emitted_split<S: ForkSink>(
        &self,
        emission: Emission,
        window: &WeightWindow<'_>,
        rng: &mut PathRng,
        sink: &mut S,
    ) -> u32 {
        let Some((x1, type1, w12, weight)) = self.emit(emission, rng, sink) else {
            return 0;
        };
        self.walk_split(x1, type1, w12, weight, window, rng, sink)
    }

    /// The emission and first flight of [`Tracer::trace_emitted`]: the first vertex, its type,
    /// the first direction and the weight, the sink told of the arrival and the first vertex;
    /// `None` when the light leaves unscattered.
    fn emit<S: VertexSink>(
        &self,
        emission: Emission,
        rng: &mut PathRng,
        sink: &mut S,
    ) -> Option<(DVec3, usize, DVec3, f64)> {
        let bounds = self.medium.bounds();
        let (mut x, mut dir, power) = match emission {
            Emission::Point(p) => {
                let d = self.medium.dimension();
                let dir = d.sample_uniform_direction(rng.next_2());
                let power = 1.0 / d.uniform_direction_pdf();
                if bounds.contains(p) {
                    (p, dir, power)
                } else {
                    let (t0, _) = bounds.clip(p, dir, 0.0, f64::INFINITY)?;
                    let normal = bounds.entry_normal(p, dir);
                    let inside = self.enter(dir, normal, rng)?;
                    (p + t0 * dir, inside, power)
                }
            }
            Emission::Plane(d) => {
                // A face lit by the wave receives the power |d . n| times its area.
                let size = bounds.size();
                let mut faces = [(DVec3::ZERO, 0.0); 3];
                for (a, face) in faces.iter_mut().enumerate() {
                    let area = size[(a + 1) % 3] * size[(a + 2) % 3];
                    let mut n = DVec3::ZERO;
                    n[a] = if d[a] > 0.0 { -1.0 } else { 1.0 };
                    *face = (n, (d[a].abs() * area).max(0.0));
                }
                let total: f64 = faces.iter().map(|f| f.1).sum();
                if total.is_nan() || total <= 0.0 {
                    return None;
                }
                let mut c = rng.next_f64() * total;
                let mut k = 0;
                while k < 2 && c >= faces[k].1 {
                    c -= faces[k].1;
                    k += 1;
                }
                let (normal, _) = faces[k];
                let mut x = bounds.lerp(rng.next_3());
                x[k] = if normal[k] < 0.0 {
                    bounds.min()[k]
                } else {
                    bounds.max()[k]
                };
                let inside = self.enter(d, normal, rng)?;
                (x, inside, total)
            }
            Emission::Disc(disc) => {
                let (u, v) = (rng.next_2(), rng.next_2());
                let (x, dir, weight) = disc.sample([u[0], u[1], v[0], v[1]]);
                let inside = self.enter(dir, disc.normal, rng)?;
                (x, inside, weight)
            }
        };
        // The first flight, reflected by the faces on the way, and its length.
        let mut length = 0.0;
        let x1 = loop {
            match self.medium.sample_flight(x, dir, &mut || rng.next_f64()) {
                Some(t) => {
                    length += t;
                    break x + t * dir;
                }
                None => match self.at_face(x, dir, rng) {
                    AtFace::Reflected { point, dir: d } => {
                        length += (point - x).length();
                        (x, dir) = (point, d);
                    }
                    AtFace::Leaves { .. } => return None,
                },
            }
        };
        let weight = power * self.medium.albedo(x1);
        if weight.is_nan() || weight <= 0.0 {
            return None;
        }
        let type1 = self.sample_type(x1, rng);
        sink.arrival(dir, length);
        sink.first(x1, type1, weight, rng);
        let w12 = self.phases[type1].sample_direction(dir, rng.next_2());
        Some((x1, type1, w12, weight))
    }

    /// The walk of [`Tracer::trace_emitted_split`]: particles from a stack, each as
    /// [`Tracer::walk`] with the weight window applied at every vertex it reaches.
    #[allow(clippy::too_many_arguments)]
    fn walk_split<S: ForkSink>(
        &self,
        x1: DVec3,
        type1: usize,
        w12: DVec3,
        weight: f64,
        window: &WeightWindow<'_>,
        rng: &mut PathRng,
        sink: &mut S,
    ) -> u32 {
        let mut pending: Vec<Particle<S::Saved>> = vec![];
        let mut particles = 1u32;
        let mut vertices = 1u32;
        // The particle being followed: from x1 along w12, with the path's own stream.
        let mut p = Particle {
            walker: Walker::start(x1, type1, w12, weight),
            dir: Some(w12),
            rng: None,
            saved: None,
        };
        loop {
            let mut own = p.rng.take();
            let r = match own.as_mut() {
                Some(own) => own,
                None => &mut *rng,
            };
            let mut w = p.walker;
            let dir = match p.dir {
                Some(d) => d,
                None => self.phases[w.ty].sample_direction(w.w_in, r.next_2()),
            };
            // The weight window at each new vertex.
            let split = |w: &mut Walker, rng: &mut PathRng, sink: &mut S| {
                let target = (window.target)(w.here);
                if !(target > 0.0 && target.is_finite()) {
                    return true;
                }
                if w.weight > 2.0 * target && particles < window.max_particles {
                    let room = window.max_particles - particles;
                    let m = ((w.weight / target).ceil() as u32)
                        .min(window.max_split)
                        .min(room + 1);
                    if m > 1 {
                        w.weight /= f64::from(m);
                        for _ in 1..m {
                            pending.push(Particle {
                                walker: *w,
                                dir: None,
                                rng: Some(PathRng::new(rng.next_u64(), 0)),
                                saved: Some(sink.save()),
                            });
                        }
                        particles += m - 1;
                    }
                } else if w.weight < 0.5 * target {
                    if rng.next_f64() >= w.weight / target {
                        return false;
                    }
                    w.weight = target;
                }
                true
            };
            vertices += self.walk_from(&mut w, dir, r, sink, split);
            let Some(next) = pending.pop() else {
                break;
            };
            p = next;
            if let Some(s) = p.saved.take() {
                sink.restore(&s);
            }
        }
        vertices
    }

    /// Light from outside crossing a face of outward normal `normal` along `dir`: the direction
    /// inside, or `None` when it is reflected away (with the Fresnel probability of a
    /// mismatched interface).
    #[inline]
    fn enter(&self, dir: DVec3, normal: DVec3, rng: &mut PathRng) -> Option<DVec3> {
        let Some(i) = self.interface else {
            return Some(dir);
        };
        let cos = -dir.dot(normal);
        let r = speckle_medium::boundary::reflectance(i.outside(), i.inside(), cos);
        if rng.next_f64() < r {
            return None;
        }
        speckle_medium::boundary::refract(i.outside() / i.inside(), dir, -normal)
    }
}
