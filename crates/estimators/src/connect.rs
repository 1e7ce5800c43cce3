//! Next-event connections of path vertices to all sources and sensors (Eqs. 31, 38).
//!
//! Per path, the legs from the sources and to the sensors at `x1` are computed once; per vertex
//! `x_b`, once per source and once per sensor. The `J` pair values are then products of these
//! per-endpoint terms, so the cost per vertex is `O(S + V)` exponentials and `O(J)` complex
//! multiplies.

use crate::{Coherence, Leg, Scene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_phase::PhaseFunction;

/// Scratch space for the connections of one path at a time; allocated once per batch.
pub(crate) struct Connector<'s, M, P> {
    scene: &'s Scene<M, P>,
    k: f64,
    /// Particle type at `x1` of the current path.
    type1: usize,
    in1: Vec<Leg>,
    out1: Vec<Leg>,
    /// `upsilon(i -> x1) s(i . w12)` per source.
    fwd_src: Vec<Complex64>,
    /// `upsilon(x1 -> v) s(-w12 . v)` per sensor.
    rev_sens: Vec<Complex64>,
    /// `upsilon(x_b -> v) s(w_in . v)` per sensor.
    fwd_sens: Vec<Complex64>,
    /// `upsilon(i -> x_b) s(-i . w_in)` per source.
    rev_src: Vec<Complex64>,
    /// The `J` pair values of the current vertex.
    pub(crate) a: Vec<Complex64>,
}

impl<'s, M: Medium, P: PhaseFunction> Connector<'s, M, P> {
    pub(crate) fn new(scene: &'s Scene<M, P>) -> Self {
        let (ns, nv) = (scene.sources().len(), scene.sensors().len());
        let zero = Complex64::new(0.0, 0.0);
        let leg = Leg {
            amp: zero,
            dir: DVec3::Z,
        };
        Self {
            scene,
            k: scene.wavenumber(),
            type1: 0,
            in1: vec![leg; ns],
            out1: vec![leg; nv],
            fwd_src: vec![zero; ns],
            rev_sens: vec![zero; nv],
            fwd_sens: vec![zero; nv],
            rev_src: vec![zero; ns],
            a: vec![zero; scene.len()],
        }
    }

    /// Starts a path at `x1`, where a particle of type `ty` scatters, and fills `a` with the
    /// single-scattering values `F_j = upsilon(i_j -> x1) s(i_j -> v_j) upsilon(x1 -> v_j)`
    /// (Eq. 41's integrand, with the amplitude `s_ty` of that particle).
    pub(crate) fn first(&mut self, x1: DVec3, ty: usize) {
        self.type1 = ty;
        let (m, k) = (self.scene.medium(), self.k);
        for (leg, s) in self.in1.iter_mut().zip(self.scene.sources()) {
            *leg = s.leg(m, k, x1);
        }
        for (leg, v) in self.out1.iter_mut().zip(self.scene.sensors()) {
            *leg = v.leg(m, k, x1);
        }
        let phase = &self.scene.phases()[ty];
        for (a, p) in self.a.iter_mut().zip(self.scene.pairs()) {
            let (i, o) = (&self.in1[p.source], &self.out1[p.sensor]);
            *a = i.amp * o.amp * phase.amplitude_between(i.dir, o.dir);
        }
    }

    /// Fixes the first direction `w12` of the current path (call once, at its second vertex).
    pub(crate) fn second(&mut self, w12: DVec3) {
        let phase = &self.scene.phases()[self.type1];
        for (f, leg) in self.fwd_src.iter_mut().zip(&self.in1) {
            *f = leg.amp * phase.amplitude_between(leg.dir, w12);
        }
        for (r, leg) in self.rev_sens.iter_mut().zip(&self.out1) {
            *r = leg.amp * phase.amplitude_between(-w12, leg.dir);
        }
    }

    /// Fills `a` with the next-event values of vertex `x_b`, where a particle of type `ty`
    /// scatters, reached along `w_in` (Eq. 38; with types, Eq. 48 of App. A.1 for the sampled
    /// types of `x1` and `x_b`).
    pub(crate) fn vertex(&mut self, x: DVec3, w_in: DVec3, ty: usize, coherence: Coherence) {
        let (m, k) = (self.scene.medium(), self.k);
        let phase = &self.scene.phases()[ty];
        for (f, v) in self.fwd_sens.iter_mut().zip(self.scene.sensors()) {
            let leg = v.leg(m, k, x);
            *f = leg.amp * phase.amplitude_between(w_in, leg.dir);
        }
        match coherence {
            Coherence::ForwardOnly => {
                for (a, p) in self.a.iter_mut().zip(self.scene.pairs()) {
                    *a = self.fwd_src[p.source] * self.fwd_sens[p.sensor];
                }
            }
            Coherence::ForwardAndReversed => {
                for (r, s) in self.rev_src.iter_mut().zip(self.scene.sources()) {
                    let leg = s.leg(m, k, x);
                    *r = leg.amp * phase.amplitude_between(leg.dir, -w_in);
                }
                for (a, p) in self.a.iter_mut().zip(self.scene.pairs()) {
                    *a = self.fwd_src[p.source] * self.fwd_sens[p.sensor]
                        + self.rev_src[p.source] * self.rev_sens[p.sensor];
                }
            }
        }
    }
}

/// The factor on `weight * a a^H` for a vertex `b >= 2`: 1/2 with reversed paths (Eq. 36: each
/// vertex set is sampled in both orders), 1 with forward paths only.
pub(crate) fn coherence_factor(c: Coherence) -> f64 {
    match c {
        Coherence::ForwardAndReversed => 0.5,
        Coherence::ForwardOnly => 1.0,
    }
}
