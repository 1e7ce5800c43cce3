//! The endpoints' exact fields in free space, for the exact wave solver (`speckle-wave`): the
//! incident field of a source at a point, a sensor's reading of the field radiated by one point
//! scatterer, and a sensor's reading of a source's own field. The solver supplies the free-space
//! physics ([`FreeSpace`]: its Green's function and normalisations); the kinds say what they
//! are in it, here, so that the solver needs no case per kind.

use crate::{Sensor, Source, plane};
use glam::DVec3;
use num_complex::Complex64;
use speckle_medium::Dimension;

/// Free-space scalar wave physics at one wavenumber, in 3D or flatland, as the exact solver
/// defines it.
pub trait FreeSpace {
    /// The wavenumber `k`.
    fn wavenumber(&self) -> f64;
    /// 3D or flatland (the fields of Gaussian beams integrate over the sphere or the circle).
    fn dimension(&self) -> Dimension;
    /// The field at distance `r > 0` of the point source of the Monte Carlo convention:
    /// `e^{ikr} / r` in 3D, `sqrt(pi k / 2) e^{i pi/4} H0^(1)(kr)` in flatland (whose far zone
    /// is `e^{ikr} / sqrt(r)`).
    fn point_source(&self, r: f64) -> Complex64;
    /// The field at distance `r > 0` of a point scatterer excited by a unit field:
    /// `tau G(r)`.
    fn scattered(&self, r: f64) -> Complex64;
    /// The far-field amplitude of a point scatterer at the origin excited by a unit field:
    /// `f = tau g`, with `G(R v - o) ~ g e^{-ik v.o} e^{ikR} / R^{(d-1)/2}`.
    fn scattering_amplitude(&self) -> Complex64;
}

/// The incident (vacuum) field of `source` at `x`; `None` where it is singular (`x` on a point
/// source).
#[inline]
pub fn incident_field(source: &Source, fs: &impl FreeSpace, x: DVec3) -> Option<Complex64> {
    match *source {
        Source::PlaneWave { direction } => Some(plane::incident(fs.wavenumber(), direction, x)),
        Source::Point { position } => {
            let r = (x - position).length();
            (r > 0.0).then(|| fs.point_source(r))
        }
        // The plane-wave superposition of Eqs. 9-10 in closed form (finite everywhere).
        Source::GaussianBeam(b) => Some(b.field(fs.dimension(), fs.wavenumber(), x)),
    }
}

/// What `sensor` reads of the field radiated by a point scatterer at `o` excited by a unit
/// field: `f e^{-ik v.o}` for a far-field sensor `v`, `tau G(|q - o|)` for a point sensor at
/// `q`, `f int m(w) e^{ik w.(q - o)} dw` (Eq. 9 over the far-field amplitudes `f e^{-ik w.o}`)
/// for a Gaussian sensor focused at `q`; `None` where it is singular (`o` on a point sensor).
#[inline]
pub fn sensor_response(sensor: &Sensor, fs: &impl FreeSpace, o: DVec3) -> Option<Complex64> {
    match *sensor {
        // A(v) = sum_n f e^{-ik v.o_n} psi_n (f = tau g, the far-field factor).
        Sensor::FarField { direction } => Some(
            fs.scattering_amplitude()
                * Complex64::from_polar(1.0, -fs.wavenumber() * direction.dot(o)),
        ),
        // u(q) = u_inc(q) + sum_n tau G(q - o_n) psi_n.
        Sensor::Point { position } => {
            let r = (position - o).length();
            (r > 0.0).then(|| fs.scattered(r))
        }
        // The lens reads the far-field amplitudes f e^{-ik w.o}: f times its source form's
        // field at o.
        Sensor::GaussianBeam(b) => {
            Some(fs.scattering_amplitude() * b.reversed().field(fs.dimension(), fs.wavenumber(), o))
        }
    }
}

/// What `sensor` reads of `source`'s own (unscattered) field: its value at a point sensor, its
/// far-field amplitude (`e^{-ik v.p}` for a point source, [`crate::GaussianBeam::far_amplitude`]
/// for a beam) at a far-field sensor, nothing for a plane wave and a far-field sensor, and for a
/// Gaussian sensor `int m(w) e^{ik w.q} A(w) dw` over the source's far-field amplitude `A`
/// (a point source: its source form's field at the point; a plane wave along `d`, whose `A` is
/// `(2 pi / ik) delta(w - d)` in the limit of a beam: the source form's far-field amplitude
/// along `-d`; a beam: the closed form of the product of the two masks); `None` where it is
/// singular (a point source on a point sensor).
pub fn direct_field(source: &Source, sensor: &Sensor, fs: &impl FreeSpace) -> Option<Complex64> {
    let (dim, k) = (fs.dimension(), fs.wavenumber());
    match (*source, *sensor) {
        (_, Sensor::Point { position }) => incident_field(source, fs, position),
        (Source::Point { position }, Sensor::FarField { direction }) => Some(
            Complex64::from_polar(1.0, -fs.wavenumber() * direction.dot(position)),
        ),
        (Source::PlaneWave { .. }, Sensor::FarField { .. }) => Some(Complex64::new(0.0, 0.0)),
        (Source::GaussianBeam(b), Sensor::FarField { direction }) => {
            Some(b.far_amplitude(dim, k, direction))
        }
        (Source::Point { position }, Sensor::GaussianBeam(s)) => {
            Some(s.reversed().field(dim, k, position))
        }
        (Source::PlaneWave { direction }, Sensor::GaussianBeam(s)) => {
            Some(s.reversed().far_amplitude(dim, k, -direction))
        }
        (Source::GaussianBeam(b), Sensor::GaussianBeam(s)) => {
            Some(s.reversed().read_beam(dim, k, &b))
        }
    }
}
