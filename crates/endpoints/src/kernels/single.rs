//! Single scattering at a path's first vertex for pairs of endpoints (Eq. 41's integrand; with
//! Gaussian beams the aperture integrals of Eqs. 15-18): one pair at a time
//! ([`Endpoints::single`]) or every pair of a connector at once ([`Endpoints::single_pairs`]),
//! whose beams' integrals go through one batch and whose two-beam convolutions are formed once
//! per source, lobe and sensor axis rather than once per pair.

use super::damping::Tilt;
use super::{Damping, Endpoints, Legs, lobes};
use crate::Kind;
use crate::gaussian::near::{self, Batch, Convolved};
use num_complex::Complex64;
use speckle_medium::Medium;
use speckle_phase::PhaseFunction;

/// Scratch space of [`Endpoints::single_pairs`], kept between paths so that nothing is
/// allocated per path; it holds the pairs' values after each call.
#[derive(Debug, Clone, Default)]
pub struct SingleScratch {
    values: Vec<Complex64>,
    /// The beams' fields at the point, sources then sensors (zero for leg endpoints).
    fields: Vec<Complex64>,
    /// `e^(l_m)` per amplitude lobe.
    scales: Vec<f64>,
    /// Per source, lobe and sensor axis, the source's convolution with the lobe.
    convolved: Vec<Option<Convolved>>,
}

impl SingleScratch {
    /// The values of the pairs of the last [`Endpoints::single_pairs`], by pair index.
    pub fn values(&self) -> &[Complex64] {
        &self.values
    }
}

impl<M: Medium> Endpoints<'_, M> {
    /// The single-scattering value at the point `x1` both sets were just
    /// [`connect`](Endpoints::connect)ed to, for source `s` of this set (its legs `in1`) and
    /// sensor `v` of `sensors` (legs `out1`): `upsilon(i -> x1) s(i -> v) upsilon(x1 -> v)` for
    /// leg endpoints (Eq. 41's integrand); with a Gaussian beam on one side, its exact
    /// `Upsilon(x1, w)` towards (from) the other endpoint's leg direction times that leg's
    /// throughput; with Gaussian beams on both sides, Eq. 18 with the convolution approximation
    /// of Eqs. 31-32 for non-isotropic lobes (exact for isotropic ones; see
    /// `gaussian::near::push_single_both`).
    ///
    /// # Panics
    /// As [`Endpoints::scatter`], for a Gaussian endpoint whose phase has no vMF lobes.
    pub fn single<P: PhaseFunction>(
        &self,
        in1: &Legs,
        s: usize,
        sensors: &Endpoints<'_, M>,
        out1: &Legs,
        v: usize,
        phase: &P,
    ) -> Complex64 {
        self.single_tilted(
            in1,
            s,
            sensors,
            out1,
            v,
            phase,
            [Complex64::new(0.0, 0.0); 3],
        )
    }

    /// [`Endpoints::single`] for every pair `(i, s, v)` of `pairs` (pair `i` between source `s`
    /// of this set and sensor `v` of `sensors`, `i < n`), into `scratch`
    /// ([`SingleScratch::values`], indexed by `i`; pairs not listed are zero). The values equal
    /// the pair-by-pair ones to rounding. Between two beams, the source's convolution with each
    /// lobe is formed once per source, lobe and distinct sensor axis, and the beams' fields once
    /// per path.
    ///
    /// # Panics
    /// As [`Endpoints::single`]; if a pair index is `n` or more.
    #[allow(clippy::too_many_arguments)]
    pub fn single_pairs<P: PhaseFunction>(
        &self,
        in1: &Legs,
        sensors: &Endpoints<'_, M>,
        out1: &Legs,
        phase: &P,
        n: usize,
        pairs: impl Iterator<Item = (usize, usize, usize)>,
        scratch: &mut SingleScratch,
    ) {
        let three = self.three;
        let SingleScratch {
            values,
            fields,
            scales,
            convolved,
        } = scratch;
        values.clear();
        values.resize(n, Complex64::new(0.0, 0.0));
        let both = self.gaussian && sensors.gaussian;
        let lobes: &[(f64, f64)] = if both { lobes(phase) } else { &[] };
        scales.clear();
        scales.extend(lobes.iter().map(|&(_, l)| l.exp()));
        // Every beam's field (integral of its aperture), sources then sensors.
        let ns = self.len();
        fields.clear();
        fields.resize(ns + sensors.len(), Complex64::new(0.0, 0.0));
        if both {
            let sink = &mut |i: usize, x: Complex64| fields[i] = x;
            let mut batch = Batch::new(three);
            let one = Complex64::new(1.0, 0.0);
            for (set, legs, offset) in [(self, in1, 0), (sensors, out1, ns)] {
                for (i, e) in set.ends.iter().enumerate() {
                    if let Kind::Gaussian(_) = e {
                        let a = &legs.aperture[i];
                        batch.push(offset + i, one, a.log_scale, a.mu, sink);
                    }
                }
            }
            batch.flush(sink);
        }
        let (nl, classes) = (lobes.len(), sensors.axis_classes);
        convolved.clear();
        convolved.resize(ns * nl * classes, None);
        let sink = &mut |i: usize, x: Complex64| values[i] += x;
        let mut batch = Batch::new(three);
        for (i, s, v) in pairs {
            match (&self.ends[s], &sensors.ends[v]) {
                (Kind::Gaussian(_), Kind::Gaussian(bv)) => {
                    let cache = &mut convolved[(s * nl) * classes..(s + 1) * nl * classes];
                    let class = sensors.axis_class[v] as usize;
                    let a_s = &in1.aperture[s];
                    near::push_single_both(
                        &mut batch,
                        i,
                        &out1.aperture[v],
                        lobes,
                        |m| scales[m],
                        |m| {
                            *cache[m * classes + class].get_or_insert_with(|| {
                                near::convolved(a_s, three, lobes[m].0, -bv.axis)
                            })
                        },
                        || (fields[s], fields[ns + v]),
                        sink,
                    )
                }
                _ => {
                    let ends = (sensors, out1, v);
                    let none = &Tilt([Complex64::new(0.0, 0.0); 3]);
                    self.push_single_leg(&mut batch, i, (in1, s), ends, phase, none, sink)
                }
            }
        }
        batch.flush(sink);
    }

    /// Queues the single-scattering value of source `s` and sensor `v`, not both Gaussian
    /// beams, for `owner` on `batch` (directly for two leg endpoints), the plane waves `psi`
    /// (source form) weighted by `tilt`'s `e^(tilt . psi)`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn push_single_leg<P: PhaseFunction>(
        &self,
        batch: &mut Batch,
        owner: usize,
        (in1, s): (&Legs, usize),
        (sensors, out1, v): (&Endpoints<'_, M>, &Legs, usize),
        phase: &P,
        tilt: &Tilt,
        sink: &mut impl FnMut(usize, Complex64),
    ) {
        let none = &Damping::NONE;
        match (&self.ends[s], &sensors.ends[v]) {
            (Kind::Gaussian(_), Kind::Gaussian(_)) => {
                unreachable!("two beams: gaussian::near::push_single_both")
            }
            (Kind::Gaussian(_), _) => near::push_upsilon(
                batch,
                owner,
                tilt.weigh(out1.amp(v), -out1.dir(v)),
                &tilt.tilted(&in1.aperture[s]),
                lobes(phase),
                none,
                out1.dir(v),
                sink,
            ),
            (_, Kind::Gaussian(_)) => near::push_upsilon(
                batch,
                owner,
                tilt.weigh(in1.amp(s), in1.dir(s)),
                &tilt.tilted(&out1.aperture[v]),
                lobes(phase),
                none,
                -in1.dir(s),
                sink,
            ),
            _ => {
                let x = in1.amp(s) * out1.amp(v) * phase.amplitude_between(in1.dir(s), out1.dir(v));
                let x = tilt.weigh(tilt.weigh(x, in1.dir(s)), -out1.dir(v));
                batch.push_value(owner, x, sink)
            }
        }
    }
}
