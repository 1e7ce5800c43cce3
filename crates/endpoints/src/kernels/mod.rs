//! Connections of a medium point to a whole list of sources or sensors at once (Eqs. 24-25),
//! vectorised per run of endpoints of one kind, and the scattering connections
//! `Upsilon(x, w)` the estimators build on them.

use crate::gaussian::near;
use crate::{Kind, Leg, Sensor, Side, Source, plane, point};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Dimension, Medium};
use speckle_phase::PhaseFunction;
use speckle_vmf::ComplexVmf;

/// The medium as the fast kernels see it: extinction `sigma_t` inside its bounding box, vacuum
/// outside.
#[derive(Debug, Clone, Copy)]
pub(crate) struct BoxMedium {
    pub(crate) center: DVec3,
    pub(crate) half: DVec3,
    /// `sigma_t / 2`: the field attenuates as `exp(-sigma_t d / 2)`.
    pub(crate) half_sigma_t: f64,
}

impl BoxMedium {
    /// The box form of `m` when its extinction is uniform (`Medium::uniform_sigma_t`) and its
    /// optical depths along a few probe rays are those of a uniformly filled bounding box; `None`
    /// otherwise (the connections then call the medium for every leg).
    fn of<M: Medium>(m: &M) -> Option<Self> {
        let sigma_t = m.uniform_sigma_t()?;
        let b = m.bounds();
        let g = Self {
            center: 0.5 * (b.min() + b.max()),
            half: 0.5 * b.size(),
            half_sigma_t: 0.5 * sigma_t,
        };
        let flat = m.dimension() == Dimension::Two;
        let z = |v: f64| if flat { 0.0 } else { v };
        let probes = [
            (DVec3::new(0.5, 0.5, 0.5), DVec3::new(1.0, 0.0, 0.0)),
            (DVec3::new(0.2, 0.7, 0.4), DVec3::new(-0.6, 0.8, 0.0)),
            (DVec3::new(0.9, 0.1, 0.6), DVec3::new(0.3, -0.4, z(0.866))),
            (DVec3::new(0.3, 0.6, 0.1), DVec3::new(0.0, 0.6, z(-0.8))),
        ];
        for (u, d) in probes {
            let (x, d) = (b.lerp(u.to_array()), d.normalize());
            let depth = |got: f64, want: f64| (got - want).abs() <= 1e-9 * (1.0 + want.abs());
            let far = -2.0 * g.far_exponent(x, d);
            let p = x + 4.0 * b.size().length() * d;
            let point = 2.0 * g.half_sigma_t * g.chord_fraction(x, p - x) * (p - x).length();
            if !depth(m.optical_depth_to_infinity(x, d), far)
                || !depth(m.optical_depth(x, p), point)
            {
                return None;
            }
        }
        Some(g)
    }

    /// `-sigma_t / 2` times the distance from `x` (inside the box) to its boundary along `e`
    /// (scalar form of the directional kernel, for the probes).
    pub(crate) fn far_exponent(&self, x: DVec3, e: DVec3) -> f64 {
        let c = self.center - x;
        (0..3)
            .map(|a| {
                let (q, r) = plane::far_coefficients(e[a], self.half[a], self.half_sigma_t);
                c[a] * q + r
            })
            .fold(f64::NEG_INFINITY, f64::max)
            .min(0.0)
    }

    /// Whether `x` lies in the box, or outside it by no more than a rounding error of a vertex
    /// position (`1e-9` of the box size), where the kernels are still exact.
    #[inline]
    pub(crate) fn holds(&self, x: DVec3) -> bool {
        let slack = 1e-9 * (self.half.max_element() + 1.0);
        ((x - self.center).abs() - self.half).max_element() <= slack
    }

    /// The fraction of the segment from `x` (inside the box) to `x + w` that lies inside.
    #[inline(always)]
    pub(crate) fn chord_fraction(&self, x: DVec3, w: DVec3) -> f64 {
        let c = self.center - x;
        let mut s = 1.0;
        for a in 0..3 {
            // Exit parameter through the face the segment heads for: (c + h sgn w) / w. A zero
            // component gives +inf or NaN (flatland z: 0 / 0), which the comparison skips.
            let t = (c[a] + self.half[a].copysign(w[a])) / w[a];
            s = if t < s { t } else { s };
        }
        s
    }
}

/// The prepared structure-of-arrays data of a run of endpoints of one kind.
#[derive(Debug, Clone)]
enum RunKind {
    Plane(plane::Run),
    Point(point::Run),
    /// Gaussian beams: no leg, a weighted aperture per medium point ([`Legs`]).
    Gaussian,
}

impl RunKind {
    /// An empty run of the kind of `k`.
    fn of(k: &Kind) -> Self {
        match k {
            Kind::Plane(_) => Self::Plane(plane::Run::default()),
            Kind::Point(_) => Self::Point(point::Run::default()),
            Kind::Gaussian(_) => Self::Gaussian,
        }
    }

    /// Appends `k` (of this run's kind).
    fn push(&mut self, g: &BoxMedium, wavenumber: f64, k: &Kind) {
        match (self, *k) {
            (Self::Plane(run), Kind::Plane(d)) => run.push(g, wavenumber, d),
            (Self::Point(run), Kind::Point(p)) => run.push(p),
            (Self::Gaussian, Kind::Gaussian(_)) => {}
            _ => unreachable!("runs hold endpoints of one kind"),
        }
    }
}

/// Whether two endpoints share a kind (and so a run).
fn same_kind(a: &Kind, b: &Kind) -> bool {
    std::mem::discriminant(a) == std::mem::discriminant(b)
}

/// A maximal range of endpoints of one kind.
#[derive(Debug, Clone)]
struct Run {
    start: usize,
    len: usize,
    kind: RunKind,
}

static NEXT_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// A list of sources or of sensors, prepared for connecting many medium points to all of them
/// (Eqs. 24-25): the per-endpoint terms are precomputed once and stored as structure of
/// arrays, so that [`Endpoints::connect`] runs one vectorised loop per run of endpoints of the
/// same kind, with the branch-free [`crate::fastmath`] exponential and sine/cosine.
///
/// In a medium of uniform extinction inside its bounding box (a [`speckle_medium::HomogeneousBox`],
/// a constant [`speckle_medium::VoxelGrid`]) a far-field leg costs a few multiplies for the
/// distance to the boundary (`t = min_a (c_a + h_a sgn e_a) / e_a`, `c = center - x`, with the
/// per-direction factors precomputed), one `exp` and one `sin_cos`; a point leg adds a square
/// root and four divisions. Other media are called for every leg
/// ([`Source::leg`], [`Sensor::leg`]). The values agree with [`Source::leg`] and
/// [`Sensor::leg`] to rounding, not bitwise: the phase `k L` is summed in another order (a
/// difference of a few ulp of `k L`, `1e-12` rad at `k L = 1e4`), and `exp`, `sin_cos` are
/// those of [`crate::fastmath`] (1 and 2 ulp from the standard library).
///
/// ```
/// use speckle_endpoints::{Endpoints, Sensor};
/// use speckle_medium::{Aabb, DVec3, HomogeneousBox};
/// let m = HomogeneousBox::new(Aabb::centered(DVec3::ZERO, DVec3::splat(2.0)).unwrap(), 1.0, 0.0)
///     .unwrap();
/// let sensors = vec![
///     Sensor::far_field(DVec3::new(0.1, 0.0, 1.0)).unwrap(),
///     Sensor::Point { position: DVec3::new(0.0, 0.0, 5.0) },
/// ];
/// let set = Endpoints::sensors(&m, 6.0, &sensors);
/// let mut legs = set.legs();
/// let x = DVec3::new(0.2, -0.3, 0.1);
/// set.connect(x, &mut legs);
/// for (i, s) in sensors.iter().enumerate() {
///     let exact = s.leg(&m, 6.0, x);
///     assert!((legs.amp(i) - exact.amp).norm() < 1e-14);
///     assert!((legs.dir(i) - exact.dir).length() < 1e-14);
/// }
/// ```
#[derive(Debug, Clone)]
pub struct Endpoints<'m, M> {
    medium: &'m M,
    k: f64,
    /// The endpoints in source form.
    ends: Vec<Kind>,
    geometry: Option<BoxMedium>,
    three: bool,
    side: Side,
    runs: Vec<Run>,
    /// Whether any endpoint is a Gaussian beam.
    gaussian: bool,
    /// How Gaussian connections attenuate their plane waves ([`Endpoints::set_near_field`]).
    near_field: crate::NearField,
    /// Per endpoint, the index of its axis among the distinct axes of the set's Gaussian beams
    /// (single scattering between beams depends on the sensor's through its axis only); `0`
    /// for the others; empty without Gaussian beams.
    axis_class: Vec<u32>,
    /// The number of distinct axes.
    axis_classes: usize,
    /// Per endpoint, a Gaussian beam's prepared lens and fit directions; `None` for the others;
    /// empty without Gaussian beams.
    prepared: Vec<Option<Box<crate::attenuation::Prepared>>>,
    id: u64,
}

/// The legs from one medium point to every endpoint of an [`Endpoints`] set, structure of
/// arrays: complex throughputs `tau xi` ([`Leg::amp`]) and unit directions ([`Leg::dir`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Legs {
    re: Vec<f64>,
    im: Vec<f64>,
    dir: [Vec<f64>; 3],
    /// The weighted apertures `a~(w; x)` of the Gaussian endpoints (unused for the others).
    pub(crate) aperture: Vec<ComplexVmf>,
    /// The two sets of directions drawn from the Gaussian endpoints' masks for the exact
    /// attenuation ([`Endpoints::draw_attenuation`]; unused for the others).
    pub(crate) draws: [Vec<crate::attenuation::Draw>; 2],
    /// The control variates' fits of the Gaussian endpoints ([`crate::NearField::Exact`]).
    pub(crate) fits: Vec<crate::attenuation::Fit>,
    owner: u64,
}

impl Legs {
    /// Real parts of the throughputs, one per leg.
    #[inline]
    pub fn re(&self) -> &[f64] {
        &self.re
    }

    /// Imaginary parts of the throughputs, one per leg.
    #[inline]
    pub fn im(&self) -> &[f64] {
        &self.im
    }

    /// Number of legs.
    pub fn len(&self) -> usize {
        self.re.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.re.is_empty()
    }

    /// The throughput of leg `i`.
    #[inline]
    pub fn amp(&self, i: usize) -> Complex64 {
        Complex64::new(self.re[i], self.im[i])
    }

    /// The unit direction of leg `i`.
    #[inline]
    pub fn dir(&self, i: usize) -> DVec3 {
        DVec3::new(self.dir[0][i], self.dir[1][i], self.dir[2][i])
    }

    /// The id of the endpoint set that made these legs.
    pub(crate) fn owner(&self) -> u64 {
        self.owner
    }

    /// Leg `i`.
    pub fn leg(&self, i: usize) -> Leg {
        Leg {
            amp: self.amp(i),
            dir: self.dir(i),
        }
    }
}

impl<'m, M: Medium> Endpoints<'m, M> {
    /// The sources `sources` in `medium` at wavenumber `k`.
    pub fn sources(medium: &'m M, k: f64, sources: &[Source]) -> Self {
        Self::new(
            medium,
            k,
            sources.iter().map(Source::kind).collect(),
            Side::Source,
        )
    }

    /// The sensors `sensors` in `medium` at wavenumber `k`.
    pub fn sensors(medium: &'m M, k: f64, sensors: &[Sensor]) -> Self {
        Self::new(
            medium,
            k,
            sensors.iter().map(Sensor::kind).collect(),
            Side::Sensor,
        )
    }

    fn new(medium: &'m M, k: f64, ends: Vec<Kind>, side: Side) -> Self {
        let geometry = BoxMedium::of(medium);
        let mut runs: Vec<Run> = vec![];
        if let Some(g) = geometry {
            for (i, e) in ends.iter().enumerate() {
                let same = i > 0 && same_kind(&ends[i - 1], e);
                if !same {
                    runs.push(Run {
                        start: i,
                        len: 0,
                        kind: RunKind::of(e),
                    });
                }
                let run = runs.last_mut().expect("a run was pushed");
                run.len += 1;
                run.kind.push(&g, k, e);
            }
        }
        // Per-endpoint data of Gaussian beams only where there are some (a set of far-field
        // sensors can be a megapixel image).
        let gaussian = ends.iter().any(|e| matches!(e, Kind::Gaussian(_)));
        let gaussians = if gaussian { ends.as_slice() } else { &[] };
        let mut classes = std::collections::HashMap::new();
        let axis_class = gaussians
            .iter()
            .map(|e| match e {
                Kind::Gaussian(b) => {
                    let next = classes.len() as u32;
                    *classes
                        .entry(b.axis.to_array().map(f64::to_bits))
                        .or_insert(next)
                }
                _ => 0,
            })
            .collect();
        let three = medium.dimension() == Dimension::Three;
        let prepared = gaussians
            .iter()
            .map(|e| match e {
                Kind::Gaussian(b) => Some(Box::new(crate::attenuation::Prepared::new(
                    b, three, geometry,
                ))),
                _ => None,
            })
            .collect();
        Self {
            medium,
            k,
            prepared,
            axis_class,
            axis_classes: classes.len(),
            gaussian,
            ends,
            geometry,
            three,
            side,
            runs,
            near_field: crate::NearField::Paper,
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// Number of endpoints.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// The set with the near-field model `near_field` for its Gaussian beams' connections:
    /// [`crate::NearField::Paper`] (Eq. 25, the default of a new set: every Gaussian connection
    /// is then a deterministic closed form) or [`crate::NearField::Exact`], whose closed form is
    /// the control variate that [`Endpoints::draw_attenuation`] and
    /// [`Endpoints::correct_scatter`] complete (module docs of `attenuation.rs`).
    pub fn set_near_field(&mut self, near_field: crate::NearField) {
        self.near_field = near_field;
    }

    /// The near-field model of the set's Gaussian connections.
    pub fn near_field(&self) -> crate::NearField {
        self.near_field
    }

    /// The endpoints in source form.
    pub(crate) fn kinds(&self) -> &[Kind] {
        &self.ends
    }

    /// The box form of the medium, when the kernels use it.
    pub(crate) fn geometry(&self) -> Option<BoxMedium> {
        self.geometry
    }

    /// Gaussian endpoint `i`'s prepared lens and fit directions.
    ///
    /// # Panics
    /// If endpoint `i` is not a Gaussian beam.
    pub(crate) fn prepared(&self, i: usize) -> &crate::attenuation::Prepared {
        self.prepared[i].as_ref().expect("a Gaussian endpoint")
    }

    /// The medium.
    pub(crate) fn medium(&self) -> &M {
        self.medium
    }

    /// The wavenumber.
    pub(crate) fn wavenumber(&self) -> f64 {
        self.k
    }

    /// Whether the medium is 3D.
    pub(crate) fn is_three(&self) -> bool {
        self.three
    }

    /// The set's id (its legs carry it).
    pub(crate) fn id(&self) -> u64 {
        self.id
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// Whether every endpoint is a plane wave or a far-field sensor (their leg directions do
    /// not depend on the medium point).
    pub fn all_directional(&self) -> bool {
        self.ends.iter().all(|e| matches!(e, Kind::Plane(_)))
    }

    /// Whether any endpoint is a focused Gaussian beam (whose connections integrate over its
    /// aperture instead of following one leg).
    pub fn has_gaussian(&self) -> bool {
        self.gaussian
    }

    /// A buffer for [`Endpoints::connect`] of this set (the constant directions of plane waves
    /// and far-field sensors are filled in here, once).
    pub fn legs(&self) -> Legs {
        let n = self.len();
        let mut legs = Legs {
            re: vec![0.0; n],
            im: vec![0.0; n],
            dir: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            aperture: if self.gaussian {
                vec![ComplexVmf::new(Complex64::new(0.0, 0.0), [Complex64::new(0.0, 0.0); 3]); n]
            } else {
                vec![]
            },
            draws: if self.gaussian {
                [vec![Default::default(); n], vec![Default::default(); n]]
            } else {
                Default::default()
            },
            fits: if self.gaussian {
                vec![Default::default(); n]
            } else {
                vec![]
            },
            owner: self.id,
        };
        for (i, e) in self.ends.iter().enumerate() {
            if let Kind::Plane(d) = *e {
                let d = self.side.direction(d);
                for a in 0..3 {
                    legs.dir[a][i] = d[a];
                }
            }
        }
        legs
    }

    /// Connects the point `x` to every endpoint: `legs` (made by [`Endpoints::legs`] of this
    /// set) receives `upsilon(i -> x)` for sources, `upsilon(x -> v)` for sensors, and the leg
    /// directions; a Gaussian beam receives its weighted aperture at `x` instead (Eqs. 26-27,
    /// attenuated along its axis, Eq. 25), and its throughput and direction are left at 0.
    /// Points inside the medium (or on its boundary) take the vectorised kernels; a
    /// point outside it (a vertex displaced by a drift, `speckle-motion`) the medium's own
    /// optical depths.
    ///
    /// # Panics
    /// If `legs` was made by another set.
    pub fn connect(&self, x: DVec3, legs: &mut Legs) {
        assert_eq!(legs.owner, self.id, "legs of another endpoint set");
        let g = match self.geometry {
            Some(g) if g.holds(x) => g,
            _ => {
                for i in 0..self.ends.len() {
                    self.scalar_leg(i, x, legs);
                }
                return;
            }
        };
        let sign = match self.side {
            Side::Source => -1.0,
            Side::Sensor => 1.0,
        };
        for run in &self.runs {
            let range = run.start..run.start + run.len;
            let (re, im) = (&mut legs.re[range.clone()], &mut legs.im[range.clone()]);
            let in_range = match &run.kind {
                RunKind::Plane(f) => f.connect(&g, x, re, im),
                RunKind::Gaussian => {
                    for i in range {
                        if let Kind::Gaussian(b) = &self.ends[i] {
                            self.gaussian_aperture(i, b, x, legs);
                        }
                    }
                    true
                }
                RunKind::Point(p) => {
                    let [dx, dy, dz] = &mut legs.dir;
                    let dir = [
                        &mut dx[range.clone()],
                        &mut dy[range.clone()],
                        &mut dz[range],
                    ];
                    if self.three {
                        p.connect::<true>(&g, self.k, sign, x, re, im, dir)
                    } else {
                        p.connect::<false>(&g, self.k, sign, x, re, im, dir)
                    }
                }
            };
            if !in_range {
                // A phase beyond the sin_cos kernel's range (|k L| > 2^23): redo the run with
                // the standard library.
                for i in run.start..run.start + run.len {
                    let leg = self.ends[i].leg(self.medium, self.k, x, self.side);
                    legs.re[i] = leg.amp.re;
                    legs.im[i] = leg.amp.im;
                }
            }
        }
    }

    /// Whether every endpoint is directional (a plane wave or a far-field sensor) in a
    /// homogeneous box: then [`Self::drift_rates`] and [`Self::drift_log_ratio`] apply.
    pub fn directional_in_box(&self) -> bool {
        self.geometry.is_some()
            && self
                .runs
                .iter()
                .all(|r| matches!(r.kind, RunKind::Plane(_)))
    }

    /// The rates `beta_i = d/ds ln leg_i(x + s u)` of every endpoint's leg along the line
    /// `x + s u`, `|s| <= reach`, into `out` (at least `len()` long), for a set that is
    /// [`Self::directional_in_box`] and a segment inside the box (else false). `out[i]` is
    /// `None` where the leg leaves the box through different faces along the segment (its
    /// attenuation has a kink there; [`Self::drift_log_ratio`] gives it point by point), else
    /// `Some(beta_i)`, and then `leg_i(x + s u) = leg_i(x) exp(beta_i s)` exactly on the
    /// segment (`plane.rs`, `Run::rate`). The spatio-temporal estimator uses it for drift: the
    /// copies of an end vertex at every lag lie on one such line, so their connections are one
    /// exponential in the lag instead of one connection per copy.
    pub fn drift_rates(
        &self,
        x: DVec3,
        u: DVec3,
        reach: f64,
        out: &mut [Option<Complex64>],
    ) -> bool {
        let Some(g) = self.geometry else {
            return false;
        };
        let inside = g.holds(x - reach * u) && g.holds(x + reach * u);
        if !(reach.is_finite() && u.is_finite() && inside && self.directional_in_box()) {
            return false;
        }
        for run in &self.runs {
            let RunKind::Plane(p) = &run.kind else {
                return false;
            };
            for j in 0..run.len {
                out[run.start + j] = p.rate(j, &g, x, u, reach);
            }
        }
        true
    }

    /// `ln(leg_i(x + s u) / leg_i(x))` for endpoint `i` of a set that is
    /// [`Self::directional_in_box`], with `x` and `x + s u` in the box (`None` otherwise).
    pub fn drift_log_ratio(&self, i: usize, x: DVec3, u: DVec3, s: f64) -> Option<Complex64> {
        let g = self.geometry?;
        if !(g.holds(x) && g.holds(x + s * u)) {
            return None;
        }
        let run = self
            .runs
            .iter()
            .find(|r| (r.start..r.start + r.len).contains(&i))?;
        match &run.kind {
            RunKind::Plane(p) => Some(p.log_ratio(i - run.start, &g, x, u, s)),
            _ => None,
        }
    }

    /// Leg `i` at `x` by the scalar (medium-calling) route.
    fn scalar_leg(&self, i: usize, x: DVec3, legs: &mut Legs) {
        if let Kind::Gaussian(b) = &self.ends[i] {
            self.gaussian_aperture(i, b, x, legs);
            return;
        }
        let leg = self.ends[i].leg(self.medium, self.k, x, self.side);
        legs.re[i] = leg.amp.re;
        legs.im[i] = leg.amp.im;
        for a in 0..3 {
            legs.dir[a][i] = leg.dir[a];
        }
    }

    /// The scattering connections `Upsilon(x, w)` of every endpoint at the point whose `legs`
    /// were just [`connect`](Self::connect)ed: `out_i = amp_i s(dirs(dir_i))`, where `dirs` maps
    /// the leg direction to the (incoming, outgoing) directions of the scattering at `x` (for a
    /// source leg arriving along `d` and leaving along the path direction `w`: `(d, w)`; for a
    /// sensor leg leaving along `d`, reached along the path direction `w`: `(w, d)`). Writes
    /// `out_re`, `out_im` (at least `len()` long).
    ///
    /// A Gaussian beam has no leg direction: its connection is the aperture integral
    /// `Upsilon(x, w)` of Eqs. 15-16 in closed form (exact for the amplitude's vMF lobes,
    /// [`PhaseFunction::amplitude_lobes`]), with the path direction read from `dirs`: the
    /// outgoing one for a source, the incoming one for a sensor.
    ///
    /// # Panics
    /// For a Gaussian beam when `phase` has no vMF lobes (the estimators check
    /// [`crate::check_near_field`] first).
    #[inline]
    pub fn scatter<P: PhaseFunction>(
        &self,
        legs: &Legs,
        phase: &P,
        dirs: impl Fn(DVec3) -> (DVec3, DVec3),
        out_re: &mut [f64],
        out_im: &mut [f64],
    ) {
        if self.gaussian {
            self.scatter_many(&[legs], phase, dirs, &mut [(out_re, out_im)]);
        } else {
            self.leg_values(legs, phase, &dirs, out_re, out_im);
        }
    }

    /// The scattering values of the leg endpoints of `legs` into `re`, `im` (zero for Gaussian
    /// beams, whose values [`Endpoints::scatter_many`] adds).
    #[inline]
    fn leg_values<P: PhaseFunction>(
        &self,
        legs: &Legs,
        phase: &P,
        dirs: &impl Fn(DVec3) -> (DVec3, DVec3),
        re: &mut [f64],
        im: &mut [f64],
    ) {
        let n = legs.len();
        let (re, im) = (&mut re[..n], &mut im[..n]);
        for i in 0..n {
            let x = if self.gaussian && matches!(self.ends[i], Kind::Gaussian(_)) {
                Complex64::new(0.0, 0.0)
            } else {
                let (w_in, w_out) = dirs(legs.dir(i));
                legs.amp(i) * phase.amplitude_between(w_in, w_out)
            };
            re[i] = x.re;
            im[i] = x.im;
        }
    }

    /// [`Endpoints::scatter`] at several points at once, all reached along the same path
    /// directions `dirs` (the displaced copies of a vertex, `speckle-motion`): `legs[c]`
    /// [`connect`](Self::connect)ed at point `c`, its values into `outs[c]` (real and imaginary
    /// parts). The Gaussian beams' integrals of every point go through one batch; the values
    /// are bitwise those of [`Endpoints::scatter`] point by point.
    ///
    /// # Panics
    /// As [`Endpoints::scatter`]; if `legs` and `outs` differ in length.
    pub fn scatter_many<P: PhaseFunction>(
        &self,
        legs: &[&Legs],
        phase: &P,
        dirs: impl Fn(DVec3) -> (DVec3, DVec3),
        outs: &mut [(&mut [f64], &mut [f64])],
    ) {
        assert_eq!(legs.len(), outs.len(), "one output per point");
        // Leg endpoints directly; every beam and lobe of every point queued on one batch.
        for (l, (re, im)) in legs.iter().zip(outs.iter_mut()) {
            self.leg_values(l, phase, &dirs, re, im);
        }
        if !self.gaussian {
            return;
        }
        let n = self.len();
        let w = self.source_form(&dirs);
        let sink = &mut |owner: usize, v: Complex64| {
            let (re, im) = &mut outs[owner / n];
            re[owner % n] += v.re;
            im[owner % n] += v.im;
        };
        let none = &crate::Damping::NONE;
        self.push_beams(legs.iter().map(|l| (*l, none)), lobes(phase), w, sink);
    }

    /// The path direction at a point in source form, from the (incoming, outgoing) directions
    /// of `dirs` (as [`Endpoints::scatter`] reads them): the outgoing one for a source, minus
    /// the incoming one for a sensor.
    #[inline]
    pub(crate) fn source_form(&self, dirs: &impl Fn(DVec3) -> (DVec3, DVec3)) -> DVec3 {
        let (w_in, w_out) = dirs(DVec3::ZERO);
        match self.side {
            Side::Source => w_out,
            Side::Sensor => -w_in,
        }
    }

    /// Evaluates into `sink` the connections of every Gaussian beam `i` for every item `c` of
    /// `items` (its legs and damping) towards the source-form direction `w`, for owner
    /// `c len() + i`, in one batch.
    pub(crate) fn push_beams<'l>(
        &self,
        items: impl Iterator<Item = (&'l Legs, &'l crate::Damping)>,
        lobes: &[(f64, f64)],
        w: DVec3,
        sink: &mut impl FnMut(usize, Complex64),
    ) {
        let (n, one) = (self.len(), Complex64::new(1.0, 0.0));
        let mut batch = near::Batch::new(self.three);
        for (c, (l, d)) in items.enumerate() {
            for i in 0..n {
                if let Kind::Gaussian(_) = &self.ends[i] {
                    let a = &l.aperture[i];
                    near::push_upsilon(&mut batch, c * n + i, one, a, lobes, d, w, sink);
                }
            }
        }
        batch.flush(sink);
    }
}

/// The vMF lobes of `phase`, which a Gaussian connection needs.
pub(crate) fn lobes<P: PhaseFunction>(phase: &P) -> &[(f64, f64)] {
    phase
        .amplitude_lobes()
        .expect("a Gaussian connection needs a phase with vMF lobes (check_near_field)")
}

mod damping;
mod single;
pub use damping::Damping;
pub use single::SingleScratch;

#[cfg(test)]
mod tests;
