//! Next-event connections of path vertices to all sources and sensors (Eqs. 31, 38).
//!
//! Per path, the legs from the sources and to the sensors at `x1` are computed once; per vertex
//! `x_b`, once per source and once per sensor, by the vectorised kernels of [`Endpoints`]. The
//! `J` pair values are then products of these per-endpoint terms, so the cost per vertex is
//! `O(S + V)` exponentials and sines and `O(J)` complex multiplies.
//!
//! A connector works on one [`Tile`] of the pair list: all of it for the covariance, and blocks
//! of at most a few ten thousand pairs for large field renders, so that the per-vertex pair
//! loop runs over arrays that stay in the core's cache and a work item holds only its block.
//! When the pairs are the full grid of [`crate::Pair::all`] a tile is a block of sources times a
//! block of sensors, and the pair loops are contiguous structure-of-arrays loops.

use crate::{Coherence, Scene};
use glam::DVec3;
use num_complex::Complex64;
use speckle_endpoints::{Endpoints, Legs, SingleScratch};
use speckle_medium::Medium;
use speckle_phase::PhaseFunction;
use std::ops::Range;

mod sums;
pub(crate) use sums::Exact;
pub use sums::NEAR_FIELD_KEY;
use sums::two_sets;

/// A complex vector stored as two real arrays (vectorises better than `[Complex64]`).
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Cvec {
    pub re: Vec<f64>,
    pub im: Vec<f64>,
}

impl Cvec {
    pub fn zeros(n: usize) -> Self {
        Self {
            re: vec![0.0; n],
            im: vec![0.0; n],
        }
    }

    #[inline]
    pub(crate) fn get(&self, i: usize) -> Complex64 {
        Complex64::new(self.re[i], self.im[i])
    }
}

/// A block of a scene's pair list.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Tile {
    /// The pairs `(s, v)`, `s` in `sources`, `v` in `sensors`, of a scene whose pair list is
    /// the full source-major grid (`Pair::all`); local index
    /// `(s - sources.start) * sensors.len() + (v - sensors.start)`.
    Grid {
        sources: Range<usize>,
        sensors: Range<usize>,
    },
    /// The entries `pairs` of the scene's pair list, in order.
    List { pairs: Range<usize> },
}

impl Tile {
    /// The whole pair list as one tile (local index = pair index).
    pub fn whole<M, P>(scene: &Scene<M, P>) -> Self
    where
        M: Medium,
        P: PhaseFunction,
    {
        if is_grid(scene) {
            Self::Grid {
                sources: 0..scene.sources().len(),
                sensors: 0..scene.sensors().len(),
            }
        } else {
            Self::List {
                pairs: 0..scene.len(),
            }
        }
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        match self {
            Self::Grid { sources, sensors } => sources.len() * sensors.len(),
            Self::List { pairs } => pairs.len(),
        }
    }

    /// An upper bound of the number of endpoints the tile connects to.
    pub fn endpoints(&self) -> usize {
        match self {
            Self::Grid { sources, sensors } => sources.len() + sensors.len(),
            Self::List { pairs } => 2 * pairs.len(),
        }
    }
}

/// Whether the pairs of `scene` are exactly `Pair::all(S, V)`.
pub(crate) fn is_grid<M: Medium, P: PhaseFunction>(scene: &Scene<M, P>) -> bool {
    let (ns, nv) = (scene.sources().len(), scene.sensors().len());
    scene.len() == ns * nv
        && scene
            .pairs()
            .iter()
            .enumerate()
            .all(|(j, p)| p.source == j / nv && p.sensor == j % nv)
}

/// `0..n` cut into `parts` contiguous ranges whose lengths differ by at most one.
fn split(n: usize, parts: usize) -> Vec<Range<usize>> {
    let parts = parts.clamp(1, n.max(1));
    (0..parts)
        .map(|p| (p * n / parts)..((p + 1) * n / parts))
        .collect()
}

/// The pair list of `scene` cut into tiles of at most about `max_pairs` pairs (a grid into
/// blocks of at most `sqrt(max_pairs)` sources times the rest in sensors, so that few legs are
/// computed twice; a list into consecutive ranges). Depends only on the scene, never on the
/// number of threads.
pub(crate) fn tiles<M: Medium, P: PhaseFunction>(
    scene: &Scene<M, P>,
    max_pairs: usize,
) -> Vec<Tile> {
    let max_pairs = max_pairs.max(1);
    if is_grid(scene) {
        let (ns, nv) = (scene.sources().len(), scene.sensors().len());
        let per_source = ns.min(max_pairs.isqrt().max(1));
        let per_sensor = (max_pairs / per_source).clamp(1, nv);
        let sensor_blocks = split(nv, nv.div_ceil(per_sensor));
        split(ns, ns.div_ceil(per_source))
            .into_iter()
            .flat_map(|sources| {
                sensor_blocks.iter().map(move |sensors| Tile::Grid {
                    sources: sources.clone(),
                    sensors: sensors.clone(),
                })
            })
            .collect()
    } else {
        split(scene.len(), scene.len().div_ceil(max_pairs))
            .into_iter()
            .map(|pairs| Tile::List { pairs })
            .collect()
    }
}

/// Local endpoint indices of the pairs of a tile.
enum PairMap {
    /// Every (source, sensor) combination, source-major.
    Grid { sensors: usize },
    /// Listed pairs.
    List { source: Vec<u32>, sensor: Vec<u32> },
}

impl PairMap {
    /// The local source and sensor of local pair `i`.
    fn ends(&self, i: usize) -> (usize, usize) {
        match self {
            Self::Grid { sensors } => (i / sensors, i % sensors),
            Self::List { source, sensor } => (source[i] as usize, sensor[i] as usize),
        }
    }

    /// The number of pairs, with `sources` local sources.
    fn len(&self, sources: usize) -> usize {
        match self {
            Self::Grid { sensors } => sources * sensors,
            Self::List { source, .. } => source.len(),
        }
    }
}

/// Most entries `types * pairs` of the table of first-vertex amplitudes.
const MAX_TABLE: usize = 1 << 22;

/// The connections of one path to every source and sensor of a tile: the legs at its first
/// vertex `x1` and at its current vertex `x_b`, and their scattering values (Eq. 38). The
/// connector keeps one; the spatio-temporal estimator keeps one per displaced copy of a path.
pub(crate) struct Ends {
    /// Legs from the sources to `x1` and from `x1` to the sensors.
    pub in1: Legs,
    pub out1: Legs,
    /// Legs from the sources to `x_b` and from `x_b` to the sensors.
    pub in_b: Legs,
    pub out_b: Legs,
    /// `upsilon(i -> x1) s(i . w12)` per source.
    pub fwd_src: Cvec,
    /// `upsilon(x1 -> v) s(-w12 . v)` per sensor.
    pub rev_sens: Cvec,
    /// `upsilon(x_b -> v) s(w_in . v)` per sensor.
    pub fwd_sens: Cvec,
    /// `upsilon(i -> x_b) s(-i . w_in)` per source.
    pub rev_src: Cvec,
    /// With the exact attenuation of Gaussian beams: the draws' stream and the values of draw
    /// set 1 (the fields above hold set 0; `speckle_endpoints::NearField`). `None` otherwise.
    pub exact: Option<Exact>,
}

impl Ends {
    /// Scratch space for the endpoints `src` and `sen`.
    pub fn new<M: Medium>(src: &Endpoints<M>, sen: &Endpoints<M>) -> Self {
        Self {
            in1: src.legs(),
            out1: sen.legs(),
            in_b: src.legs(),
            out_b: sen.legs(),
            fwd_src: Cvec::zeros(src.len()),
            rev_sens: Cvec::zeros(sen.len()),
            fwd_sens: Cvec::zeros(sen.len()),
            rev_src: Cvec::zeros(src.len()),
            exact: None,
        }
    }

    /// The legs at the first vertex `x1` (and, with the exact attenuation, the draws there).
    pub fn start<M: Medium>(&mut self, src: &Endpoints<M>, sen: &Endpoints<M>, x1: DVec3) {
        src.connect(x1, &mut self.in1);
        sen.connect(x1, &mut self.out1);
        if let Some(e) = &mut self.exact {
            let next = &mut || e.rng.next_f64();
            src.draw_attenuation(x1, &mut self.in1, next);
            sen.draw_attenuation(x1, &mut self.out1, next);
        }
    }

    /// The scattering values at `x1` once the first direction `w12` is known (amplitude
    /// `phase` of the particle at `x1`).
    pub fn second<M: Medium, P: PhaseFunction>(
        &mut self,
        src: &Endpoints<M>,
        sen: &Endpoints<M>,
        phase: &P,
        w12: DVec3,
    ) {
        let out = &mut self.fwd_src;
        src.scatter(&self.in1, phase, |d| (d, w12), &mut out.re, &mut out.im);
        let out = &mut self.rev_sens;
        sen.scatter(&self.out1, phase, |d| (-w12, d), &mut out.re, &mut out.im);
        if let Some(e) = &mut self.exact {
            let (in1, out1) = (&self.in1, &self.out1);
            two_sets(&mut self.fwd_src, &mut e.fwd_src, |set, o| {
                src.correct_scatter(in1, set, phase, |d| (d, w12), &mut o.re, &mut o.im)
            });
            two_sets(&mut self.rev_sens, &mut e.rev_sens, |set, o| {
                sen.correct_scatter(out1, set, phase, |d| (-w12, d), &mut o.re, &mut o.im)
            });
        }
    }

    /// [`Ends::second`] for every copy of `copies` (the displaced copies of a path, each
    /// [`start`](Ends::start)ed at its own first vertex), the Gaussian beams' integrals of all
    /// copies in one batch; bitwise the copies' own [`Ends::second`].
    pub fn second_copies<M: Medium, P: PhaseFunction>(
        copies: &mut [Ends],
        src: &Endpoints<M>,
        sen: &Endpoints<M>,
        phase: &P,
        w12: DVec3,
    ) {
        if !(src.has_gaussian() || sen.has_gaussian()) || copies.iter().any(|e| e.exact.is_some()) {
            for e in copies {
                e.second(src, sen, phase, w12);
            }
            return;
        }
        let (legs, mut outs): (Vec<&Legs>, Vec<_>) = copies
            .iter_mut()
            .map(|e| (&e.in1, (&mut e.fwd_src.re[..], &mut e.fwd_src.im[..])))
            .unzip();
        src.scatter_many(&legs, phase, |d| (d, w12), &mut outs);
        let (legs, mut outs): (Vec<&Legs>, Vec<_>) = copies
            .iter_mut()
            .map(|e| (&e.out1, (&mut e.rev_sens.re[..], &mut e.rev_sens.im[..])))
            .unzip();
        sen.scatter_many(&legs, phase, |d| (-w12, d), &mut outs);
    }

    /// [`Ends::at`] for every copy `c` of `copies` at its own point `xs[c]`, all reached along
    /// `w_in` (the displaced copies of a path's vertex), the Gaussian beams' integrals of all
    /// copies in one batch; bitwise the copies' own [`Ends::at`].
    #[allow(clippy::too_many_arguments)]
    pub fn at_copies<M: Medium, P: PhaseFunction>(
        copies: &mut [Ends],
        src: &Endpoints<M>,
        sen: &Endpoints<M>,
        phase: &P,
        xs: &[DVec3],
        w_in: DVec3,
        coherence: Coherence,
    ) {
        if !(src.has_gaussian() || sen.has_gaussian()) || copies.iter().any(|e| e.exact.is_some()) {
            for (e, &x) in copies.iter_mut().zip(xs) {
                e.at(src, sen, phase, x, w_in, coherence);
            }
            return;
        }
        let reversed = coherence == Coherence::ForwardAndReversed;
        for (e, &x) in copies.iter_mut().zip(xs) {
            sen.connect(x, &mut e.out_b);
            if reversed {
                src.connect(x, &mut e.in_b);
            }
        }
        let (legs, mut outs): (Vec<&Legs>, Vec<_>) = copies
            .iter_mut()
            .map(|e| (&e.out_b, (&mut e.fwd_sens.re[..], &mut e.fwd_sens.im[..])))
            .unzip();
        sen.scatter_many(&legs, phase, |d| (w_in, d), &mut outs);
        if reversed {
            let (legs, mut outs): (Vec<&Legs>, Vec<_>) = copies
                .iter_mut()
                .map(|e| (&e.in_b, (&mut e.rev_src.re[..], &mut e.rev_src.im[..])))
                .unzip();
            src.scatter_many(&legs, phase, |d| (d, -w_in), &mut outs);
        }
    }

    /// The legs and scattering values at the vertex `x` reached along `w_in` (amplitude
    /// `phase` of the particle there); the source side only with reversed paths.
    #[allow(clippy::too_many_arguments)]
    pub fn at<M: Medium, P: PhaseFunction>(
        &mut self,
        src: &Endpoints<M>,
        sen: &Endpoints<M>,
        phase: &P,
        x: DVec3,
        w_in: DVec3,
        coherence: Coherence,
    ) {
        let reversed = coherence == Coherence::ForwardAndReversed;
        sen.connect(x, &mut self.out_b);
        let out = &mut self.fwd_sens;
        sen.scatter(&self.out_b, phase, |d| (w_in, d), &mut out.re, &mut out.im);
        if reversed {
            src.connect(x, &mut self.in_b);
            let out = &mut self.rev_src;
            src.scatter(&self.in_b, phase, |d| (d, -w_in), &mut out.re, &mut out.im);
        }
        if let Some(e) = &mut self.exact {
            let next = &mut || e.rng.next_f64();
            sen.draw_attenuation(x, &mut self.out_b, next);
            let out_b = &self.out_b;
            two_sets(&mut self.fwd_sens, &mut e.fwd_sens, |set, o| {
                sen.correct_scatter(out_b, set, phase, |d| (w_in, d), &mut o.re, &mut o.im)
            });
            if reversed {
                src.draw_attenuation(x, &mut self.in_b, next);
                let in_b = &self.in_b;
                two_sets(&mut self.rev_src, &mut e.rev_src, |set, o| {
                    src.correct_scatter(in_b, set, phase, |d| (d, -w_in), &mut o.re, &mut o.im)
                });
            }
        }
    }
}

/// Scratch space for the connections of one path at a time to the pairs of one tile;
/// allocated once per work item.
pub(crate) struct Connector<'s, M, P> {
    scene: &'s Scene<M, P>,
    sources: Endpoints<'s, M>,
    sensors: Endpoints<'s, M>,
    pairs: PairMap,
    /// Particle type at `x1` of the current path.
    type1: usize,
    /// The current path's legs and scattering values.
    ends: Ends,
    /// Per particle type, `s(i . v)` per pair, when every endpoint is directional (plane waves
    /// and far-field sensors); empty otherwise.
    first_amp: Vec<Cvec>,
    /// The `J` pair values of the current vertex (only for [`Connector::new`]).
    pub(crate) a: Vec<Complex64>,
    /// With the exact attenuation of Gaussian beams ([`Connector::with_exact_attenuation`]):
    /// the pair values of draw set 1 (`a` holds set 0's), else empty.
    pub(crate) b: Vec<Complex64>,
    /// Scratch for [`Connector::push_moment`]: `(a + b) / 2` and `(a - b) / 2`.
    halves: (Vec<Complex64>, Vec<Complex64>),
    /// Scratch for the single scattering of Gaussian beams ([`Endpoints::single_pairs`]).
    single: SingleScratch,
}

impl<'s, M: Medium, P: PhaseFunction> Connector<'s, M, P> {
    /// A connector for all pairs of `scene`, whose [`Connector::first`] and
    /// [`Connector::vertex`] fill `a` (indexed by pair).
    pub(crate) fn new(scene: &'s Scene<M, P>) -> Self {
        let mut c = Self::for_tile(scene, &Tile::whole(scene));
        c.a = vec![Complex64::new(0.0, 0.0); scene.len()];
        c
    }

    /// A connector for the pairs of `tile`, for [`Connector::add_first`] and
    /// [`Connector::add_vertex`].
    pub(crate) fn for_tile(scene: &'s Scene<M, P>, tile: &Tile) -> Self {
        let (m, k) = (scene.medium(), scene.wavenumber());
        let (sources, sensors, pairs) = match tile {
            Tile::Grid { sources, sensors } => (
                Endpoints::sources(m, k, &scene.sources()[sources.clone()]),
                Endpoints::sensors(m, k, &scene.sensors()[sensors.clone()]),
                PairMap::Grid {
                    sensors: sensors.len(),
                },
            ),
            Tile::List { pairs } => {
                let pairs = &scene.pairs()[pairs.clone()];
                let (src, s_idx) = compact(scene.sources().len(), pairs.iter().map(|p| p.source));
                let (sen, v_idx) = compact(scene.sensors().len(), pairs.iter().map(|p| p.sensor));
                let src: Vec<_> = src.iter().map(|&s| scene.sources()[s]).collect();
                let sen: Vec<_> = sen.iter().map(|&v| scene.sensors()[v]).collect();
                (
                    Endpoints::sources(m, k, &src),
                    Endpoints::sensors(m, k, &sen),
                    PairMap::List {
                        source: s_idx,
                        sensor: v_idx,
                    },
                )
            }
        };
        // The scene's near-field model; the sampled remainder of `NearField::Exact` only with
        // two draw sets (`with_exact_attenuation`): one estimate alone takes its control variate.
        let (mut sources, mut sensors) = (sources, sensors);
        let near_field = match scene.near_field() {
            speckle_endpoints::NearField::Exact => speckle_endpoints::NearField::Fitted,
            other => other,
        };
        sources.set_near_field(near_field);
        sensors.set_near_field(near_field);
        let n = tile.len();
        let mut c = Self {
            scene,
            ends: Ends::new(&sources, &sensors),
            sources,
            sensors,
            pairs,
            type1: 0,
            first_amp: vec![],
            a: vec![],
            b: vec![],
            halves: Default::default(),
            single: SingleScratch::default(),
        };
        let types = scene.phases().len();
        if c.sources.all_directional()
            && c.sensors.all_directional()
            && types.saturating_mul(n) <= MAX_TABLE
        {
            // s(i . v) of far-field pairs depends only on the pair and the type at x1.
            let table = scene
                .phases()
                .iter()
                .map(|phase| {
                    let mut t = Cvec::zeros(n);
                    c.for_pairs(|i, s, v| {
                        let a = phase.amplitude_between(c.ends.in1.dir(s), c.ends.out1.dir(v));
                        t.re[i] = a.re;
                        t.im[i] = a.im;
                    });
                    t
                })
                .collect();
            c.first_amp = table;
        }
        c
    }

    /// The sources of the tile, as the connector connects them.
    pub(crate) fn sources(&self) -> &Endpoints<'s, M> {
        &self.sources
    }

    /// The sensors of the tile, as the connector connects them.
    pub(crate) fn sensors(&self) -> &Endpoints<'s, M> {
        &self.sensors
    }

    /// The local source and sensor of local pair `i`.
    pub(crate) fn pair_ends(&self, i: usize) -> (usize, usize) {
        self.pairs.ends(i)
    }

    /// Calls `f(i, s, v)` for every local pair `i` with local source `s` and sensor `v`.
    fn for_pairs(&self, mut f: impl FnMut(usize, usize, usize)) {
        match &self.pairs {
            PairMap::Grid { sensors } => {
                for s in 0..self.sources.len() {
                    for v in 0..*sensors {
                        f(s * sensors + v, s, v);
                    }
                }
            }
            PairMap::List { source, sensor } => {
                for (i, (&s, &v)) in source.iter().zip(sensor).enumerate() {
                    f(i, s as usize, v as usize);
                }
            }
        }
    }

    /// The amplitude `s(i . v)` of single scattering by a particle of type `ty` between the
    /// leg directions `ds`, `dv` of local pair `pair`: the far-field table's value where there
    /// is one (the same value: it depends on the pair only), else computed.
    #[inline]
    pub(crate) fn first_amplitude(
        &self,
        ty: usize,
        pair: usize,
        ds: DVec3,
        dv: DVec3,
    ) -> Complex64 {
        match self.first_amp.get(ty) {
            Some(t) => t.get(pair),
            None => self.scene.phases()[ty].amplitude_between(ds, dv),
        }
    }

    /// The current path's legs and scattering values.
    pub(crate) fn ends(&self) -> &Ends {
        &self.ends
    }

    /// Starts a path at `x1`, where a particle of type `ty` scatters: the legs at `x1`.
    pub(crate) fn start(&mut self, x1: DVec3, ty: usize) {
        self.type1 = ty;
        self.ends.start(&self.sources, &self.sensors, x1);
    }

    /// Calls `emit(i, z F_i)` for every pair `i` of the tile, with the single-scattering
    /// values `F_i = upsilon(i -> x1) s(i -> v) upsilon(x1 -> v)` of the current path (Eq. 41's
    /// integrand, with the amplitude `s_ty` of the particle at `x1`).
    fn single(&mut self, z: Complex64, emit: impl FnMut(usize, Complex64)) {
        self.single_set(z, None, emit);
    }

    /// [`Connector::single`], with the exact attenuation's correction of draw set `set` added
    /// to the Gaussian beams' values when `set` is given.
    fn single_set(
        &mut self,
        z: Complex64,
        set: Option<usize>,
        mut emit: impl FnMut(usize, Complex64),
    ) {
        let (in1, out1) = (&self.ends.in1, &self.ends.out1);
        let table = self.first_amp.get(self.type1);
        let phase = &self.scene.phases()[self.type1];
        if self.sources.has_gaussian() || self.sensors.has_gaussian() {
            // Aperture integrals (Eqs. 15-18): the endpoints' own single-scattering value, every
            // pair's at once.
            let (src, sen, pairs) = (&self.sources, &self.sensors, &self.pairs);
            let n = pairs.len(src.len());
            let each = (0..n).map(|i| {
                let (s, v) = pairs.ends(i);
                (i, s, v)
            });
            src.single_pairs(in1, sen, out1, phase, n, each, &mut self.single);
            for (i, &f) in self.single.values().iter().enumerate() {
                let (s, v) = pairs.ends(i);
                let mut f = f;
                if let Some(set) = set {
                    f += src.correct_single(in1, s, sen, out1, v, phase, set);
                }
                emit(i, z * f)
            }
            return;
        }
        let f = |i: usize, s: usize, v: usize| {
            let amp = match table {
                Some(t) => t.get(i),
                None => phase.amplitude_between(in1.dir(s), out1.dir(v)),
            };
            (z * in1.amp(s)) * (out1.amp(v) * amp)
        };
        self.for_pairs(|i, s, v| emit(i, f(i, s, v)));
    }

    /// Starts a path at `x1` (particle type `ty`) and fills `a` with the single-scattering
    /// values `F_j` (Eq. 41's integrand).
    pub(crate) fn first(&mut self, x1: DVec3, ty: usize) {
        self.start(x1, ty);
        self.fill_first();
    }

    /// Fills `a` with the single-scattering values `F_j` of the path started by
    /// [`Connector::start`].
    pub(crate) fn fill_first(&mut self) {
        let one = Complex64::new(1.0, 0.0);
        let mut a = std::mem::take(&mut self.a);
        if self.two_sets() {
            let mut b = std::mem::take(&mut self.b);
            self.single_set(one, Some(0), |i, f| a[i] = f);
            self.single_set(one, Some(1), |i, f| b[i] = f);
            self.b = b;
        } else {
            self.single(one, |i, f| a[i] = f);
        }
        self.a = a;
    }

    /// Starts a path at `x1` (particle type `ty`) and adds `z F_j` to `u` (local pair order).
    pub(crate) fn add_first(&mut self, x1: DVec3, ty: usize, z: Complex64, u: &mut Cvec) {
        self.start(x1, ty);
        let (in1, out1) = (&self.ends.in1, &self.ends.out1);
        match (&self.pairs, self.first_amp.get(ty)) {
            (PairMap::Grid { sensors: nv }, Some(t)) => {
                // The hot case of far-field images: contiguous rows, vectorised.
                let nv = *nv;
                let (or, oi) = (&out1.re()[..nv], &out1.im()[..nv]);
                for s in 0..in1.len() {
                    let al = z * in1.amp(s);
                    let row = s * nv..(s + 1) * nv;
                    let (tr, ti) = (&t.re[row.clone()], &t.im[row.clone()]);
                    let (ur, ui) = (&mut u.re[row.clone()], &mut u.im[row]);
                    for v in 0..nv {
                        // u += (z upsilon(i -> x1)) (upsilon(x1 -> v) s(i . v))
                        let br = or[v] * tr[v] - oi[v] * ti[v];
                        let bi = or[v] * ti[v] + oi[v] * tr[v];
                        ur[v] += al.re * br - al.im * bi;
                        ui[v] += al.re * bi + al.im * br;
                    }
                }
            }
            _ => self.single(z, |i, f| {
                u.re[i] += f.re;
                u.im[i] += f.im;
            }),
        }
    }

    /// Fixes the first direction `w12` of the current path (call once, at its second vertex).
    pub(crate) fn second(&mut self, w12: DVec3) {
        let phase = &self.scene.phases()[self.type1];
        self.ends.second(&self.sources, &self.sensors, phase, w12);
    }

    /// Computes the per-endpoint values of vertex `x_b`, where a particle of type `ty`
    /// scatters, reached along `w_in` (Eq. 38; with types, Eq. 48 of App. A.1 for the sampled
    /// types of `x1` and `x_b`).
    pub(crate) fn legs_at(&mut self, x: DVec3, w_in: DVec3, ty: usize, coherence: Coherence) {
        let phase = &self.scene.phases()[ty];
        self.ends
            .at(&self.sources, &self.sensors, phase, x, w_in, coherence);
    }

    /// Fills `a` with the next-event values of vertex `x_b` (particle type `ty`, reached along
    /// `w_in`): `a_j = fwd_src F_sens (+ rev_src R_sens)` (Eq. 38).
    pub(crate) fn vertex(&mut self, x: DVec3, w_in: DVec3, ty: usize, coherence: Coherence) {
        self.legs_at(x, w_in, ty, coherence);
        self.fill_vertex(coherence);
    }

    /// Fills `a` with the next-event values of the vertex whose legs [`Connector::legs_at`]
    /// computed.
    pub(crate) fn fill_vertex(&mut self, coherence: Coherence) {
        let reversed = coherence == Coherence::ForwardAndReversed;
        let e = &self.ends;
        let (fs, fv, rs, rv) = (&e.fwd_src, &e.fwd_sens, &e.rev_src, &e.rev_sens);
        let mut a = std::mem::take(&mut self.a);
        self.for_pairs(|i, s, v| {
            let mut x = fs.get(s) * fv.get(v);
            if reversed {
                x += rs.get(s) * rv.get(v);
            }
            a[i] = x;
        });
        if let Some(e) = &e.exact {
            let (fs, fv, rs, rv) = (&e.fwd_src, &e.fwd_sens, &e.rev_src, &e.rev_sens);
            let mut b = std::mem::take(&mut self.b);
            self.for_pairs(|i, s, v| {
                let mut x = fs.get(s) * fv.get(v);
                if reversed {
                    x += rs.get(s) * rv.get(v);
                }
                b[i] = x;
            });
            self.b = b;
        }
        self.a = a;
    }

    /// Adds `z a` to `u` (local pair order) for the next-event values `a` of vertex `x_b`
    /// (particle type `ty`, reached along `w_in`; Eq. 38).
    pub(crate) fn add_vertex(
        &mut self,
        x: DVec3,
        w_in: DVec3,
        ty: usize,
        coherence: Coherence,
        z: Complex64,
        u: &mut Cvec,
    ) {
        self.legs_at(x, w_in, ty, coherence);
        let reversed = coherence == Coherence::ForwardAndReversed;
        let e = &self.ends;
        let (fs, fv, rs, rv) = (&e.fwd_src, &e.fwd_sens, &e.rev_src, &e.rev_sens);
        match &self.pairs {
            PairMap::Grid { sensors: nv } => {
                let nv = *nv;
                let (fvr, fvi) = (&fv.re[..nv], &fv.im[..nv]);
                let (rvr, rvi) = (&rv.re[..nv], &rv.im[..nv]);
                for s in 0..fs.re.len() {
                    // u_sv += (z fwd_src_s) F_v + (z rev_src_s) R_v
                    let al = z * fs.get(s);
                    let row = s * nv..(s + 1) * nv;
                    let (ur, ui) = (&mut u.re[row.clone()], &mut u.im[row]);
                    if reversed {
                        let be = z * rs.get(s);
                        for v in 0..nv {
                            ur[v] +=
                                al.re * fvr[v] - al.im * fvi[v] + be.re * rvr[v] - be.im * rvi[v];
                            ui[v] +=
                                al.re * fvi[v] + al.im * fvr[v] + be.re * rvi[v] + be.im * rvr[v];
                        }
                    } else {
                        for v in 0..nv {
                            ur[v] += al.re * fvr[v] - al.im * fvi[v];
                            ui[v] += al.re * fvi[v] + al.im * fvr[v];
                        }
                    }
                }
            }
            PairMap::List { source, sensor } => {
                for (i, (&s, &v)) in source.iter().zip(sensor).enumerate() {
                    let (s, v) = (s as usize, v as usize);
                    let mut x = fs.get(s) * fv.get(v);
                    if reversed {
                        x += rs.get(s) * rv.get(v);
                    }
                    let x = z * x;
                    u.re[i] += x.re;
                    u.im[i] += x.im;
                }
            }
        }
    }
}

/// The distinct values of `idx` (each below `n`) in increasing order, and every entry of `idx`
/// as an index into that list.
fn compact(n: usize, idx: impl Iterator<Item = usize> + Clone) -> (Vec<usize>, Vec<u32>) {
    let mut used = vec![false; n];
    for i in idx.clone() {
        used[i] = true;
    }
    let mut local = vec![u32::MAX; n];
    let mut list = vec![];
    for (i, _) in used.iter().enumerate().filter(|(_, u)| **u) {
        local[i] = list.len() as u32;
        list.push(i);
    }
    (list, idx.map(|i| local[i]).collect())
}
