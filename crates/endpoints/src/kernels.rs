//! Sources, sensors and their connections to a point in the medium (Eqs. 13, 19, 24-25): one
//! at a time ([`Source::leg`], [`Sensor::leg`]), or to a whole list at once with the vectorised
//! kernels of [`Endpoints`].

use crate::{EndpointError, fastmath};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::{Dimension, Medium, field_attenuation};

/// An illumination.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Source {
    /// A plane wave `exp(i k d . x)` propagating along the unit vector `direction`.
    PlaneWave {
        /// Propagation direction (unit).
        direction: DVec3,
    },
    /// An isotropic point source `exp(i k |x - p|) / |x - p|` at `position` (in flatland,
    /// `exp(i k |x - p|) / sqrt(|x - p|)`, the far-zone form of a Hankel-function source).
    Point {
        /// Position of the source.
        position: DVec3,
    },
}

/// A sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sensor {
    /// The far-field amplitude `A(v)` in the unit direction `direction`, defined by
    /// `u(R v) = A(v) exp(i k R) / R` as `R -> infinity` (`notes/conventions.md`); in flatland
    /// `u(R v) = A(v) exp(i k R) / sqrt(R)`.
    FarField {
        /// Viewing direction (unit), pointing from the medium to the sensor.
        direction: DVec3,
    },
    /// The field value at `position`.
    Point {
        /// Position of the sensor.
        position: DVec3,
    },
}

/// Geometric spreading of a spherical (3D, `1 / r`) or cylindrical (flatland, `1 / sqrt(r)`)
/// wave over the distance `r`.
#[inline]
pub(crate) fn spreading(dimension: Dimension, r: f64) -> f64 {
    match dimension {
        Dimension::Three => 1.0 / r,
        Dimension::Two => 1.0 / r.sqrt(),
    }
}

fn in_plane(field: &'static str, v: DVec3, dimension: Dimension) -> Result<(), EndpointError> {
    if dimension == Dimension::Two && v.z != 0.0 {
        return Err(EndpointError::InvalidInput {
            field: field.into(),
            reason: format!("{v} must have z = 0 in a flatland scene"),
        });
    }
    Ok(())
}

fn unit(field: &'static str, v: DVec3) -> Result<DVec3, EndpointError> {
    let len = v.length();
    if v.is_finite() && len > 0.0 && len.is_finite() {
        Ok(v / len)
    } else {
        Err(EndpointError::InvalidInput {
            field: field.into(),
            reason: format!("direction {v} must be finite and non-zero"),
        })
    }
}

fn point<M: Medium>(field: &'static str, p: DVec3, m: &M) -> Result<DVec3, EndpointError> {
    in_plane(field, p, m.dimension())?;
    if !p.is_finite() {
        return Err(EndpointError::InvalidInput {
            field: field.into(),
            reason: format!("position {p} must be finite"),
        });
    }
    if m.bounds().contains(p) {
        return Err(EndpointError::InvalidInput {
            field: field.into(),
            reason: format!(
                "position {p} lies in or on the medium; point endpoints must be outside it (next to \
                 the endpoint the 1/r^2 connection gives the estimator infinite variance)"
            ),
        });
    }
    Ok(p)
}

impl Source {
    /// A plane wave along `direction` (normalised; rejects zero or non-finite vectors).
    pub fn plane_wave(direction: DVec3) -> Result<Self, EndpointError> {
        Ok(Self::PlaneWave {
            direction: unit("source.direction", direction)?,
        })
    }

    /// Checks the source against a medium: directions unit, points outside the medium, and both
    /// in the plane `z = 0` in flatland.
    pub fn validated<M: Medium>(self, m: &M) -> Result<Self, EndpointError> {
        Ok(match self {
            Self::PlaneWave { direction } => Self::PlaneWave {
                direction: {
                    in_plane("source.direction", direction, m.dimension())?;
                    unit("source.direction", direction)?
                },
            },
            Self::Point { position } => Self::Point {
                position: point("source.position", position, m)?,
            },
        })
    }

    /// The source with far-field direction negated, as a sensor (for reciprocity).
    pub fn reciprocal(&self) -> Sensor {
        match *self {
            Self::PlaneWave { direction } => Sensor::FarField {
                direction: -direction,
            },
            Self::Point { position } => Sensor::Point { position },
        }
    }

    /// The incoming leg at `x`: `upsilon(i -> x) = tau xi` and the propagation direction at `x`.
    #[inline]
    pub fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        match *self {
            Self::PlaneWave { direction } => {
                // xi(i -> x) = exp(i k i.x); the wave crossed the medium from the boundary along i.
                let att = field_attenuation(m.optical_depth_to_infinity(x, -direction));
                Leg {
                    amp: Complex64::from_polar(att, k * direction.dot(x)),
                    dir: direction,
                }
            }
            Self::Point { position } => {
                let d = x - position;
                let r = d.length();
                let att = field_attenuation(m.optical_depth(position, x));
                Leg {
                    amp: Complex64::from_polar(att * spreading(m.dimension(), r), k * r),
                    dir: d / r,
                }
            }
        }
    }
}

impl Sensor {
    /// A far-field sensor along `direction` (normalised; rejects zero or non-finite vectors).
    pub fn far_field(direction: DVec3) -> Result<Self, EndpointError> {
        Ok(Self::FarField {
            direction: unit("sensor.direction", direction)?,
        })
    }

    /// Checks the sensor against a medium: directions unit, points outside the medium, and both
    /// in the plane `z = 0` in flatland.
    pub fn validated<M: Medium>(self, m: &M) -> Result<Self, EndpointError> {
        Ok(match self {
            Self::FarField { direction } => Self::FarField {
                direction: {
                    in_plane("sensor.direction", direction, m.dimension())?;
                    unit("sensor.direction", direction)?
                },
            },
            Self::Point { position } => Self::Point {
                position: point("sensor.position", position, m)?,
            },
        })
    }

    /// The sensor with far-field direction negated, as a source (for reciprocity).
    pub fn reciprocal(&self) -> Source {
        match *self {
            Self::FarField { direction } => Source::PlaneWave {
                direction: -direction,
            },
            Self::Point { position } => Source::Point { position },
        }
    }

    /// The outgoing leg from `x`: `upsilon(x -> v) = tau xi` and the unit direction leaving `x`.
    #[inline]
    pub fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        match *self {
            Self::FarField { direction } => {
                // xi(x -> v) = exp(-i k v.x), attenuated from x to the boundary along v.
                let att = field_attenuation(m.optical_depth_to_infinity(x, direction));
                Leg {
                    amp: Complex64::from_polar(att, -k * direction.dot(x)),
                    dir: direction,
                }
            }
            Self::Point { position } => {
                let d = position - x;
                let r = d.length();
                let att = field_attenuation(m.optical_depth(x, position));
                Leg {
                    amp: Complex64::from_polar(att * spreading(m.dimension(), r), k * r),
                    dir: d / r,
                }
            }
        }
    }
}

/// One connection between an endpoint and a point in the medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Leg {
    /// Complex volumetric throughput `tau * xi` of the segment.
    pub amp: Complex64,
    /// Unit propagation direction of the segment at the medium point (into it for a source,
    /// out of it for a sensor).
    pub dir: DVec3,
}

/// One (source, sensor) pair, the index set of covariance entries and field pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Pair {
    /// Index into the scene's sources.
    pub source: usize,
    /// Index into the scene's sensors.
    pub sensor: usize,
}

impl Pair {
    /// Every (source, sensor) combination, source-major: entry `j = source * n_sensors + sensor`,
    /// so a field vector reshapes to `(n_sources, n_sensors)`.
    pub fn all(n_sources: usize, n_sensors: usize) -> Vec<Pair> {
        (0..n_sources)
            .flat_map(|source| (0..n_sensors).map(move |sensor| Pair { source, sensor }))
            .collect()
    }
}

/// A source or a sensor, the two sides of a path.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Endpoint {
    Source(Source),
    Sensor(Sensor),
}

impl Endpoint {
    #[inline]
    fn leg<M: Medium>(&self, m: &M, k: f64, x: DVec3) -> Leg {
        match self {
            Self::Source(s) => s.leg(m, k, x),
            Self::Sensor(v) => v.leg(m, k, x),
        }
    }

    /// For a plane wave or a far-field sensor: the leg direction, the direction along which the
    /// leg leaves the medium from `x`, and the vector `kappa` of the phase `kappa . x`.
    fn directional(&self, k: f64) -> Option<(DVec3, DVec3, DVec3)> {
        match *self {
            Self::Source(Source::PlaneWave { direction: i }) => Some((i, -i, k * i)),
            Self::Sensor(Sensor::FarField { direction: v }) => Some((v, v, -k * v)),
            _ => None,
        }
    }

    fn position(&self) -> Option<DVec3> {
        match *self {
            Self::Source(Source::Point { position }) | Self::Sensor(Sensor::Point { position }) => {
                Some(position)
            }
            _ => None,
        }
    }
}

/// The medium as the fast kernels see it: extinction `sigma_t` inside its bounding box, vacuum
/// outside.
#[derive(Debug, Clone, Copy)]
struct BoxMedium {
    center: DVec3,
    half: DVec3,
    /// `sigma_t / 2`: the field attenuates as `exp(-sigma_t d / 2)`.
    half_sigma_t: f64,
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
    /// (scalar form of the far-field kernel, for the probes).
    fn far_exponent(&self, x: DVec3, e: DVec3) -> f64 {
        let c = self.center - x;
        (0..3)
            .map(|a| {
                let (q, r) = far_coefficients(e[a], self.half[a], self.half_sigma_t);
                c[a] * q + r
            })
            .fold(f64::NEG_INFINITY, f64::max)
            .min(0.0)
    }

    /// The fraction of the segment from `x` (inside the box) to `x + w` that lies inside.
    #[inline(always)]
    fn chord_fraction(&self, x: DVec3, w: DVec3) -> f64 {
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

/// Coefficients `(q, r)` of one axis of the far-field attenuation exponent: for a unit exit
/// direction with component `e`, the distance from `x` to the face it heads for is
/// `t = (c + h sgn e) / e` (`c = center - x`, `h` the half size), so `-sigma_t t / 2 = c q + r`
/// with `q = -sigma_t / (2 e)` and `r = -sigma_t h / (2 |e|)`; an axis with `e = 0` never exits:
/// `q = 0`, `r = -inf`.
fn far_coefficients(e: f64, h: f64, half_sigma_t: f64) -> (f64, f64) {
    if e == 0.0 {
        (0.0, f64::NEG_INFINITY)
    } else {
        (-half_sigma_t / e, -half_sigma_t * h / e.abs())
    }
}

/// Directional endpoints (plane waves, far-field sensors), structure of arrays: the phase is
/// `kx x + ky y + kz z`, the attenuation exponent `max_a (c_a q_a + r_a)`.
#[derive(Debug, Clone, Default)]
struct FarRun {
    k: [Vec<f64>; 3],
    q: [Vec<f64>; 3],
    r: [Vec<f64>; 3],
}

/// Point endpoints, structure of arrays of their positions.
#[derive(Debug, Clone, Default)]
struct PointRun {
    p: [Vec<f64>; 3],
}

#[derive(Debug, Clone)]
enum RunKind {
    Far(FarRun),
    Point(PointRun),
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
/// use speckle_estimators::{Sensor, fastmath::Endpoints};
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
    ends: Vec<Endpoint>,
    geometry: Option<BoxMedium>,
    three: bool,
    /// `+1` for sensors (legs leave `x` towards a point sensor), `-1` for sources.
    side: f64,
    runs: Vec<Run>,
    id: u64,
}

/// The legs from one medium point to every endpoint of an [`Endpoints`] set, structure of
/// arrays: complex throughputs `tau xi` ([`Leg::amp`]) and unit directions ([`Leg::dir`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Legs {
    pub(crate) re: Vec<f64>,
    pub(crate) im: Vec<f64>,
    pub(crate) dir: [Vec<f64>; 3],
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
        let ends = sources.iter().map(|&s| Endpoint::Source(s)).collect();
        Self::new(medium, k, ends, -1.0)
    }

    /// The sensors `sensors` in `medium` at wavenumber `k`.
    pub fn sensors(medium: &'m M, k: f64, sensors: &[Sensor]) -> Self {
        let ends = sensors.iter().map(|&s| Endpoint::Sensor(s)).collect();
        Self::new(medium, k, ends, 1.0)
    }

    fn new(medium: &'m M, k: f64, ends: Vec<Endpoint>, side: f64) -> Self {
        let geometry = BoxMedium::of(medium);
        let mut runs: Vec<Run> = vec![];
        if let Some(g) = geometry {
            for (i, e) in ends.iter().enumerate() {
                let far = e.directional(k).is_some();
                let same = runs
                    .last()
                    .is_some_and(|r| matches!(r.kind, RunKind::Far(_)) == far);
                if !same {
                    let kind = if far {
                        RunKind::Far(FarRun::default())
                    } else {
                        RunKind::Point(PointRun::default())
                    };
                    runs.push(Run {
                        start: i,
                        len: 0,
                        kind,
                    });
                }
                let run = runs.last_mut().expect("a run was pushed");
                run.len += 1;
                match (&mut run.kind, e.directional(k), e.position()) {
                    (RunKind::Far(f), Some((_, exit, kappa)), _) => {
                        for a in 0..3 {
                            let (q, r) = far_coefficients(exit[a], g.half[a], g.half_sigma_t);
                            f.k[a].push(kappa[a]);
                            f.q[a].push(q);
                            f.r[a].push(r);
                        }
                    }
                    (RunKind::Point(p), None, Some(pos)) => {
                        for a in 0..3 {
                            p.p[a].push(pos[a]);
                        }
                    }
                    _ => unreachable!("runs hold endpoints of one kind"),
                }
            }
        }
        Self {
            medium,
            k,
            ends,
            geometry,
            three: medium.dimension() == Dimension::Three,
            side,
            runs,
            id: NEXT_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// Number of endpoints.
    pub fn len(&self) -> usize {
        self.ends.len()
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.ends.is_empty()
    }

    /// Whether every endpoint is a plane wave or a far-field sensor (their leg directions do
    /// not depend on the medium point).
    pub fn all_directional(&self) -> bool {
        self.ends.iter().all(|e| e.directional(self.k).is_some())
    }

    /// A buffer for [`Endpoints::connect`] of this set (the constant directions of plane waves
    /// and far-field sensors are filled in here, once).
    pub fn legs(&self) -> Legs {
        let n = self.len();
        let mut legs = Legs {
            re: vec![0.0; n],
            im: vec![0.0; n],
            dir: [vec![0.0; n], vec![0.0; n], vec![0.0; n]],
            owner: self.id,
        };
        for (i, e) in self.ends.iter().enumerate() {
            if let Some((d, _, _)) = e.directional(self.k) {
                for a in 0..3 {
                    legs.dir[a][i] = d[a];
                }
            }
        }
        legs
    }

    /// Connects the point `x` inside the medium (vertices on its boundary, or outside it by a
    /// rounding error, are fine) to every endpoint: `legs` (made by
    /// [`Endpoints::legs`] of this set) receives `upsilon(i -> x)` for sources,
    /// `upsilon(x -> v)` for sensors, and the leg directions.
    ///
    /// # Panics
    /// If `legs` was made by another set.
    pub fn connect(&self, x: DVec3, legs: &mut Legs) {
        assert_eq!(legs.owner, self.id, "legs of another endpoint set");
        let Some(g) = self.geometry else {
            for (i, e) in self.ends.iter().enumerate() {
                let leg = e.leg(self.medium, self.k, x);
                legs.re[i] = leg.amp.re;
                legs.im[i] = leg.amp.im;
                for a in 0..3 {
                    legs.dir[a][i] = leg.dir[a];
                }
            }
            return;
        };
        debug_assert!(
            self.medium.bounds().contains(x),
            "{x} is outside the medium"
        );
        for run in &self.runs {
            let range = run.start..run.start + run.len;
            let (re, im) = (&mut legs.re[range.clone()], &mut legs.im[range.clone()]);
            let in_range = match &run.kind {
                RunKind::Far(f) => far_legs(&g, f, x, re, im),
                RunKind::Point(p) => {
                    let [dx, dy, dz] = &mut legs.dir;
                    let dir = [
                        &mut dx[range.clone()],
                        &mut dy[range.clone()],
                        &mut dz[range],
                    ];
                    if self.three {
                        point_legs::<true>(&g, p, self.k, self.side, x, re, im, dir)
                    } else {
                        point_legs::<false>(&g, p, self.k, self.side, x, re, im, dir)
                    }
                }
            };
            if !in_range {
                // A phase beyond the sin_cos kernel's range (|k L| > 2^23): redo the run with
                // the standard library.
                for i in run.start..run.start + run.len {
                    let leg = self.ends[i].leg(self.medium, self.k, x);
                    legs.re[i] = leg.amp.re;
                    legs.im[i] = leg.amp.im;
                }
            }
        }
    }
}

/// The far-field kernel: `re + i im = exp(max_a(c_a q_a + r_a)) exp(i kappa . x)`. Returns
/// false if a phase was out of the range of the vectorised `sin_cos`.
#[inline(never)]
fn far_legs(g: &BoxMedium, f: &FarRun, x: DVec3, re: &mut [f64], im: &mut [f64]) -> bool {
    let n = re.len();
    let c = g.center - x;
    let (kx, ky, kz) = (&f.k[0][..n], &f.k[1][..n], &f.k[2][..n]);
    let (qx, qy, qz) = (&f.q[0][..n], &f.q[1][..n], &f.q[2][..n]);
    let (rx, ry, rz) = (&f.r[0][..n], &f.r[1][..n], &f.r[2][..n]);
    let im = &mut im[..n];
    let mut in_range = true;
    for i in 0..n {
        // Attenuation exponent -sigma_t t / 2 (t: distance to the boundary, Eq. 24).
        let ex = c.x * qx[i] + rx[i];
        let ey = c.y * qy[i] + ry[i];
        let ez = c.z * qz[i] + rz[i];
        let e = if ex > ey { ex } else { ey };
        let e = if ez > e { ez } else { e };
        let e = if e > 0.0 { 0.0 } else { e };
        // Phase: k i.x for a plane wave, -k v.x for a far-field sensor (Eqs. 19, 25).
        let phase = kx[i] * x.x + ky[i] * x.y + kz[i] * x.z;
        let att = fastmath::exp(e);
        let (s, co) = fastmath::sin_cos_reduced(phase);
        in_range &= fastmath::in_sin_cos_range(phase);
        re[i] = att * co;
        im[i] = att * s;
    }
    in_range
}

/// The point-endpoint kernel: distance `r`, direction, chord through the box, and
/// `exp(-sigma_t L / 2) spreading(r) exp(i k r)` (Eq. 13 with `1/r`, or `1/sqrt(r)` in
/// flatland). `side` is `+1` for sensors (direction `p - x`), `-1` for sources (`x - p`).
/// Returns false if a phase was out of the range of the vectorised `sin_cos`.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
fn point_legs<const THREE: bool>(
    g: &BoxMedium,
    p: &PointRun,
    k: f64,
    side: f64,
    x: DVec3,
    re: &mut [f64],
    im: &mut [f64],
    dir: [&mut [f64]; 3],
) -> bool {
    let n = re.len();
    let (px, py, pz) = (&p.p[0][..n], &p.p[1][..n], &p.p[2][..n]);
    let im = &mut im[..n];
    let [dx, dy, dz] = dir;
    let (dx, dy, dz) = (&mut dx[..n], &mut dy[..n], &mut dz[..n]);
    let mut in_range = true;
    for i in 0..n {
        // w = p - x; for a sensor the leg runs along w, for a source along -w. Both cross the
        // same chord of the box, from x to where the segment leaves it.
        let w = DVec3::new(px[i] - x.x, py[i] - x.y, pz[i] - x.z);
        let r = (w.x * w.x + w.y * w.y + w.z * w.z).sqrt();
        let inv = 1.0 / r;
        let unit = side * inv;
        let depth_half = g.half_sigma_t * g.chord_fraction(x, w) * r;
        let spread = if THREE { inv } else { inv.sqrt() };
        let att = fastmath::exp(-depth_half) * spread;
        let phase = k * r;
        let (s, co) = fastmath::sin_cos_reduced(phase);
        in_range &= fastmath::in_sin_cos_range(phase);
        re[i] = att * co;
        im[i] = att * s;
        dx[i] = w.x * unit;
        dy[i] = w.y * unit;
        dz[i] = w.z * unit;
    }
    in_range
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_medium::{Aabb, HomogeneousBox, VoxelGrid};

    fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut rng = speckle_stats::PathRng::new(seed, 0);
        move || rng.next_f64()
    }

    fn unit_vector(next: &mut impl FnMut() -> f64, flat: bool) -> DVec3 {
        let phi = std::f64::consts::TAU * next();
        if flat {
            return DVec3::new(phi.cos(), phi.sin(), 0.0);
        }
        let z = 2.0 * next() - 1.0;
        let s = (1.0 - z * z).sqrt();
        DVec3::new(s * phi.cos(), s * phi.sin(), z)
    }

    /// Largest differences (throughput, direction) of `Endpoints::connect` from the scalar
    /// `leg` of every endpoint, over `points` points of the medium.
    fn compare<M: Medium>(m: &M, k: f64, sources: &[Source], sensors: &[Sensor]) -> (f64, f64) {
        let mut next = uniform(11);
        let (src, sen) = (
            Endpoints::sources(m, k, sources),
            Endpoints::sensors(m, k, sensors),
        );
        let (mut ls, mut lv) = (src.legs(), sen.legs());
        let (mut amp, mut dir) = (0.0f64, 0.0f64);
        for _ in 0..200 {
            let x = m.bounds().lerp([next(), next(), next()]);
            src.connect(x, &mut ls);
            sen.connect(x, &mut lv);
            for (i, s) in sources.iter().enumerate() {
                let l = s.leg(m, k, x);
                amp = amp.max((ls.amp(i) - l.amp).norm() / l.amp.norm().max(1e-300));
                dir = dir.max((ls.dir(i) - l.dir).length());
            }
            for (i, v) in sensors.iter().enumerate() {
                let l = v.leg(m, k, x);
                amp = amp.max((lv.amp(i) - l.amp).norm() / l.amp.norm().max(1e-300));
                dir = dir.max((lv.dir(i) - l.dir).length());
            }
        }
        (amp, dir)
    }

    fn endpoints(b: &Aabb, flat: bool) -> (Vec<Source>, Vec<Sensor>) {
        let mut next = uniform(5);
        let far = b.size().length() * 3.0;
        let c = 0.5 * (b.min() + b.max());
        let mut src = vec![];
        let mut sen = vec![];
        for n in 0..60 {
            let d = unit_vector(&mut next, flat);
            // Runs of each kind, both sides, some axis-aligned directions (zero components).
            if n % 10 < 6 {
                let d = if n % 10 == 0 {
                    DVec3::X
                } else if n % 10 == 1 {
                    -DVec3::Y
                } else {
                    d
                };
                src.push(Source::plane_wave(d).unwrap());
                sen.push(Sensor::far_field(-d).unwrap());
            } else {
                src.push(Source::Point {
                    position: c + far * d,
                });
                sen.push(Sensor::Point {
                    position: c - far * d,
                });
            }
        }
        (src, sen)
    }

    #[test]
    fn box_kernels_match_the_scalar_legs() {
        // A 3D box and a flatland rectangle, k L up to about 1e4.
        let b3 = Aabb::new(DVec3::new(-3.0, 1.0, -0.5), DVec3::new(5.0, 2.5, 4.0)).unwrap();
        let b2 = Aabb::flat(glam::DVec2::new(-2.0, 0.0), glam::DVec2::new(6.0, 3.0)).unwrap();
        for (b, flat) in [(b3, false), (b2, true)] {
            let m = HomogeneousBox::new(b, 0.7, 0.2).unwrap();
            assert!(BoxMedium::of(&m).is_some(), "the box kernels apply");
            let (src, sen) = endpoints(&b, flat);
            let (amp, dir) = compare(&m, 300.0, &src, &sen);
            eprintln!("flat {flat}: relative throughput error {amp:.2e}, direction {dir:.2e}");
            assert!(amp < 1e-12 && dir < 1e-14, "{amp:e} {dir:e}");
        }
    }

    #[test]
    fn other_media_use_the_scalar_legs() {
        // A voxel grid of varying extinction is called leg by leg: bitwise the scalar values.
        use speckle_medium::Material;
        let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 3.0, 1.0)).unwrap();
        let mats = vec![Material::single(0.5, 0.5), Material::single(2.0, 0.0)];
        let g = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
        assert!(BoxMedium::of(&g).is_none());
        let (src, sen) = endpoints(&b, false);
        assert_eq!(compare(&g, 20.0, &src, &sen), (0.0, 0.0));
        // A grid of one extinction is a box for the kernels.
        let mats = vec![Material::single(0.5, 0.5), Material::single(1.0, 0.0)];
        let g = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
        assert!(BoxMedium::of(&g).is_some());
        let (amp, dir) = compare(&g, 20.0, &src, &sen);
        assert!(amp < 1e-12 && dir < 1e-14, "{amp:e} {dir:e}");
    }

    #[test]
    fn huge_phases_fall_back_to_the_standard_library() {
        // k |x| beyond 2^23 rad: still right.
        let b = Aabb::centered(DVec3::ZERO, DVec3::splat(2.0)).unwrap();
        let m = HomogeneousBox::new(b, 0.1, 0.0).unwrap();
        let (src, sen) = endpoints(&b, false);
        let (amp, _) = compare(&m, 3e7, &src, &sen);
        assert!(amp < 1e-8, "{amp:e}");
    }

    #[test]
    #[should_panic(expected = "legs of another endpoint set")]
    fn legs_belong_to_their_set() {
        let m = HomogeneousBox::new(Aabb::centered(DVec3::ZERO, DVec3::ONE).unwrap(), 1.0, 0.0)
            .unwrap();
        let s = [Sensor::far_field(DVec3::Z).unwrap()];
        let (a, b) = (
            Endpoints::sensors(&m, 1.0, &s),
            Endpoints::sensors(&m, 1.0, &s),
        );
        let mut legs = a.legs();
        b.connect(DVec3::ZERO, &mut legs);
    }
}
