//! The detector kind: a disc on a face of the medium's box that collects the light leaving the
//! medium through it within a numerical aperture, as the tip of an optical fibre or (with the
//! largest aperture) a bare photodiode does.
//!
//! Unlike the field endpoints of this crate, a detector is not a coherent sensor: it integrates
//! intensity over an area of many speckle grains and over a cone of directions, so it has a
//! reading and temporal correlations (`g1`, `g2`, `K(T)`) but no field covariance with other
//! endpoints. The estimators register it where paths leave the medium (light tracing:
//! `speckle_estimators::render_detectors`), so its estimate has bounded variance for any radius,
//! where a next-event connection to a point on the face collects only the vertices within about
//! a mean free path of it.
//!
//! # What a detector reads (docs/conventions.md, "Detectors")
//!
//! With `L(y, w)` the radiance (in the units of `|u|^2` per steradian: a point source of unit
//! amplitude radiates one unit per steradian) leaving the medium at `y` of the disc `A` along `w`,
//! `n` the face's outward normal and `a` the collection axis:
//!
//! - [`Weighting::Flux`] (the default; what a fibre or a photodiode measures, and what MCX's
//!   detector counts): `(1 / |A|) int_A int_{w . a >= cos theta_max} L(y, w) (w . n) dw dA`, the
//!   mean exitant irradiance over the disc within the aperture;
//! - [`Weighting::Fluence`]: `(1 / |A|) int_A int L(y, w) dw dA`, which for a small disc and the
//!   full aperture is the intensity `E |u|^2` a point sensor at the centre reads.
//!
//! The acceptance half-angle is `theta_max = asin(NA / n_out)`, measured outside the face, where
//! the index `n_out` is the host's (the boundary is index-matched: no refraction).
//!
//! A *point* detector ([`Detector::point`]) is the limit of a vanishing radius: the irradiance
//! (flux) or the fluence at one point of the face, `int L(y, w) (w . n) dw` or `int L(y, w)
//! dw` over the aperture. With the fluence weighting and the full aperture it reads what a
//! point sensor (a field endpoint) on the face reads, `E |u|^2` (forward paths; the coherent
//! backscattering term of a point source and a point sensor apart averages out), with an
//! estimator whose variance stays bounded.

use crate::{EndpointError, check};
use glam::DVec3;
use speckle_medium::{Dimension, Medium};

/// Relative tolerance (of the box's largest edge) within which a detector's centre counts as
/// lying on a face.
pub const ON_FACE_TOLERANCE: f64 = 1e-9;

/// How a [`Detector`] weighs the light it collects (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Weighting {
    /// The exitant flux through the disc per unit area (light counted as it crosses the face).
    #[default]
    Flux,
    /// The radiance integrated over directions (each crossing weighed by `1 / |cos|` to the
    /// face normal): the fluence at the face, what a point sensor there reads.
    Fluence,
}

/// A disc detector on a face of the medium's box (an optical fibre's tip). Build it with
/// [`Detector::new`], which validates it against the medium.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detector {
    center: DVec3,
    normal: DVec3,
    axis: DVec3,
    radius: f64,
    numerical_aperture: f64,
    outside_index: f64,
    cos_max: f64,
    weighting: Weighting,
    /// Distance from the face's plane within which an exit point lies on it.
    tol: f64,
}

impl Detector {
    /// A detector of `radius` centred at `center` on a face of `medium`'s box, collecting the
    /// light that leaves within the numerical aperture `numerical_aperture` about `axis` (the
    /// direction light travels into the detector; the face's outward normal when `None`), into
    /// an outside medium of index `outside_index`. Errors name `field` and its keys.
    #[allow(clippy::too_many_arguments)]
    pub fn new<M: Medium>(
        field: &str,
        medium: &M,
        center: DVec3,
        radius: f64,
        numerical_aperture: f64,
        axis: Option<DVec3>,
        outside_index: f64,
        weighting: Weighting,
    ) -> Result<Self, EndpointError> {
        // At least 1e-150: the reading divides by the area pi r^2, which underflows to 0
        // (a NaN reading) below about 1e-154 (a fuzz finding, issue 27).
        if !(radius.is_finite() && radius >= 1e-150) {
            return Err(check::invalid(
                format!("{field}.radius"),
                format!(
                    "must be finite and at least 1e-150 (got {radius:e}); leave it out for a \
                     point detector"
                ),
            ));
        }
        Self::build(
            field,
            medium,
            center,
            radius,
            numerical_aperture,
            axis,
            outside_index,
            weighting,
        )
    }

    /// A *point* detector at `center` on a face of `medium`'s box: the limit of
    /// [`Detector::new`] as the radius goes to zero, the irradiance ([`Weighting::Flux`]) or the
    /// fluence ([`Weighting::Fluence`]) at that point of the face from the light leaving within
    /// the aperture. No path leaves through a point: its estimators connect vertices to it
    /// (next-event estimation and branches, `speckle_estimators::render_detectors`). Its
    /// [`Detector::radius`] and [`Detector::area`] are 0, and [`Detector::read`] is 0
    /// everywhere. Errors name `field` and its keys.
    #[allow(clippy::too_many_arguments)]
    pub fn point<M: Medium>(
        field: &str,
        medium: &M,
        center: DVec3,
        numerical_aperture: f64,
        axis: Option<DVec3>,
        outside_index: f64,
        weighting: Weighting,
    ) -> Result<Self, EndpointError> {
        Self::build(
            field,
            medium,
            center,
            0.0,
            numerical_aperture,
            axis,
            outside_index,
            weighting,
        )
    }

    /// [`Detector::new`] and [`Detector::point`] after the radius is checked.
    #[allow(clippy::too_many_arguments)]
    fn build<M: Medium>(
        field: &str,
        medium: &M,
        center: DVec3,
        radius: f64,
        numerical_aperture: f64,
        axis: Option<DVec3>,
        outside_index: f64,
        weighting: Weighting,
    ) -> Result<Self, EndpointError> {
        if medium.dimension() != Dimension::Three {
            return Err(check::invalid(
                field,
                "detectors need a 3D scene (dimension = 3)",
            ));
        }
        if !center.is_finite() {
            return Err(check::invalid(
                format!("{field}.position"),
                format!("must be finite (got {center})"),
            ));
        }
        if !(outside_index.is_finite() && outside_index >= 1.0) {
            return Err(check::invalid(
                format!("{field}.numerical_aperture"),
                format!("the outside index must be finite and >= 1 (got {outside_index})"),
            ));
        }
        if !(numerical_aperture.is_finite()
            && numerical_aperture > 0.0
            && numerical_aperture <= outside_index)
        {
            return Err(check::invalid(
                format!("{field}.numerical_aperture"),
                format!(
                    "must be in (0, n] with n = {outside_index}, the index outside the face \
                     (got {numerical_aperture})"
                ),
            ));
        }
        let b = medium.bounds();
        let tol = ON_FACE_TOLERANCE * b.size().max_element();
        let (lo, hi) = (b.min(), b.max());
        // The face the centre lies on: its axis and side.
        let face = (0..3).find_map(|a| {
            let inside = |c: usize| center[c] >= lo[c] - tol && center[c] <= hi[c] + tol;
            let others = (0..3).filter(|&c| c != a).all(inside);
            if !others {
                None
            } else if (center[a] - lo[a]).abs() <= tol {
                Some((a, -1.0))
            } else if (center[a] - hi[a]).abs() <= tol {
                Some((a, 1.0))
            } else {
                None
            }
        });
        let Some((a, side)) = face else {
            return Err(check::invalid(
                format!("{field}.position"),
                format!(
                    "{center} is on no face of the medium's box [{lo}, {hi}]: a detector sits \
                     on the boundary, where light leaves the medium"
                ),
            ));
        };
        let mut normal = DVec3::ZERO;
        normal[a] = side;
        let mut center = center;
        center[a] = if side < 0.0 { lo[a] } else { hi[a] };
        // The disc must lie on the face.
        for c in (0..3).filter(|&c| c != a) {
            if center[c] - radius < lo[c] - tol || center[c] + radius > hi[c] + tol {
                return Err(check::invalid(
                    format!("{field}.radius"),
                    format!(
                        "a disc of radius {radius} about {center} reaches past the edge of its \
                         face"
                    ),
                ));
            }
        }
        let axis = match axis {
            None => normal,
            Some(d) => {
                let d = unit_axis(field, d)?;
                if d.dot(normal) <= 0.0 {
                    return Err(check::invalid(
                        format!("{field}.axis"),
                        format!(
                            "must point out of the medium (light travels along it into the \
                             detector; the face's outward normal is {normal}, got {d})"
                        ),
                    ));
                }
                d
            }
        };
        let sin_max = numerical_aperture / outside_index;
        let cos_max = (1.0 - sin_max * sin_max).max(0.0).sqrt();
        Ok(Self {
            center,
            normal,
            axis,
            radius,
            numerical_aperture,
            outside_index,
            cos_max,
            weighting,
            tol,
        })
    }

    /// A fibre *source* of `radius` centred at `center` on a face of `medium`'s box: the same
    /// disc and aperture as a detector, emitting (unit power, uniform radiance) along `axis`
    /// into the medium (the face's inward normal when `None`) instead of collecting. The
    /// returned detector's [`Detector::axis`] is the reverse of the emission axis (a fibre is
    /// the same disc and cone whichever way the light goes), its weighting [`Weighting::Flux`].
    /// The cone must lie within the face's inward hemisphere (`axis . inward >= NA / n`): an
    /// error names `field.axis` otherwise. Errors name `field` and its keys.
    pub fn fibre_source<M: Medium>(
        field: &str,
        medium: &M,
        center: DVec3,
        radius: f64,
        numerical_aperture: f64,
        axis: Option<DVec3>,
        outside_index: f64,
    ) -> Result<Self, EndpointError> {
        let mut d = Self::new(
            field,
            medium,
            center,
            radius,
            numerical_aperture,
            None,
            outside_index,
            Weighting::Flux,
        )?;
        if let Some(a) = axis {
            let a = unit_axis(field, a)?;
            let sin_max = numerical_aperture / outside_index;
            if -a.dot(d.normal) < sin_max {
                return Err(check::invalid(
                    format!("{field}.axis"),
                    format!(
                        "a fibre source's cone (half-angle asin({sin_max})) about its axis {a} \
                         must lie within the medium's side of its face (inward normal {}): the \
                         axis must point into the medium within {:.4} degrees of the normal",
                        -d.normal,
                        sin_max.acos().to_degrees()
                    ),
                ));
            }
            d.axis = -a;
        }
        Ok(d)
    }

    /// The centre of the disc (on the face).
    pub fn center(&self) -> DVec3 {
        self.center
    }

    /// The outward normal of the detector's face.
    pub fn normal(&self) -> DVec3 {
        self.normal
    }

    /// The collection axis (unit, pointing out of the medium).
    pub fn axis(&self) -> DVec3 {
        self.axis
    }

    /// The radius of the disc.
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The numerical aperture.
    pub fn numerical_aperture(&self) -> f64 {
        self.numerical_aperture
    }

    /// The index of the medium outside the face, in which the aperture is defined.
    pub fn outside_index(&self) -> f64 {
        self.outside_index
    }

    /// The cosine of the acceptance half-angle about the axis.
    pub fn cos_acceptance(&self) -> f64 {
        self.cos_max
    }

    /// How the detector weighs what it collects.
    pub fn weighting(&self) -> Weighting {
        self.weighting
    }

    /// The area of the disc, `pi r^2`.
    pub fn area(&self) -> f64 {
        std::f64::consts::PI * self.radius * self.radius
    }

    /// A point of the disc, uniform (density `1 / |A|`), from two uniform variates.
    #[inline]
    pub fn sample_point(&self, u: [f64; 2]) -> DVec3 {
        let (t1, t2) = self.tangents();
        let r = self.radius * u[0].sqrt();
        let (sin, cos) = (std::f64::consts::TAU * u[1]).sin_cos();
        self.center + r * (cos * t1 + sin * t2)
    }

    /// Two unit vectors spanning the face's plane.
    #[inline]
    fn tangents(&self) -> (DVec3, DVec3) {
        let n = self.normal;
        // The normal is an axis: the other two axes span the face.
        if n.x != 0.0 {
            (DVec3::Y, DVec3::Z)
        } else if n.y != 0.0 {
            (DVec3::Z, DVec3::X)
        } else {
            (DVec3::X, DVec3::Y)
        }
    }

    /// The depth of `x` (in the medium) below the detector's face, and its lateral distance
    /// beyond the disc's rim (0 over the disc): the two legs of [`Detector::distance_bound`].
    #[inline]
    pub fn depth_and_offset(&self, x: DVec3) -> (f64, f64) {
        let off = x - self.center;
        let depth = off.dot(self.normal);
        let lateral = (off - depth * self.normal).length();
        (depth.abs(), (lateral - self.radius).max(0.0))
    }

    /// A lower bound of the distance from `x` (in the medium) to the disc.
    #[inline]
    pub fn distance_bound(&self, x: DVec3) -> f64 {
        let off = x - self.center;
        let depth = off.dot(self.normal);
        let lateral = (off - depth * self.normal).length();
        depth.hypot((lateral - self.radius).max(0.0))
    }

    /// The detector's weight of light leaving the medium at `point` (on the boundary) along the
    /// unit direction `dir`: 0 outside the disc or the aperture, else `1 / |A|` (flux) or
    /// `1 / (|A| dir . n)` (fluence), so that the sum over exits of path weight times this is
    /// the reading of the module docs.
    #[inline]
    pub fn read(&self, point: DVec3, dir: DVec3) -> f64 {
        let cos_n = dir.dot(self.normal);
        if cos_n <= 0.0 || dir.dot(self.axis) < self.cos_max {
            return 0.0;
        }
        let off = point - self.center;
        // On the face's plane (the exit point of a flight through another face is not).
        if off.dot(self.normal).abs() > self.tol {
            return 0.0;
        }
        if self.is_point() || off.length_squared() > self.radius * self.radius {
            return 0.0;
        }
        match self.weighting {
            Weighting::Flux => 1.0 / self.area(),
            Weighting::Fluence => 1.0 / (self.area() * cos_n),
        }
    }

    /// Whether this is a point detector ([`Detector::point`]).
    #[inline]
    pub fn is_point(&self) -> bool {
        self.radius == 0.0
    }

    /// A point detector's weight of light leaving the medium at its point along the unit `dir`
    /// (per unit of the solid angle it arrives in, seen from the point): 0 outside the
    /// aperture, else `dir . n` (flux: the irradiance) or 1 (fluence), so that a vertex at `r`
    /// whose light reaches the point with radiance `L` adds `L` times this over `r^2`. For a
    /// disc it is `read` times the area times `dir . n` at the centre, whatever the radius.
    #[inline]
    pub fn read_point(&self, dir: DVec3) -> f64 {
        let cos_n = dir.dot(self.normal);
        if cos_n <= 0.0 || dir.dot(self.axis) < self.cos_max {
            return 0.0;
        }
        match self.weighting {
            Weighting::Flux => cos_n,
            Weighting::Fluence => 1.0,
        }
    }
}

/// The unit vector along `d`, or an error naming `field.axis` when `d` is not finite or zero.
fn unit_axis(field: &str, d: DVec3) -> Result<DVec3, EndpointError> {
    let n = d.length();
    if !(d.is_finite() && n > 0.0) {
        return Err(check::invalid(
            format!("{field}.axis"),
            format!("must be a finite non-zero vector (got {d})"),
        ));
    }
    Ok(d / n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_medium::{Aabb, HomogeneousBox};

    fn cube() -> HomogeneousBox {
        let b = Aabb::new(DVec3::new(-0.5, -0.5, 0.0), DVec3::new(0.5, 0.5, 1.0)).unwrap();
        HomogeneousBox::new(b, 10.0, 0.0).unwrap()
    }

    fn det(c: DVec3, r: f64, na: f64, axis: Option<DVec3>) -> Result<Detector, EndpointError> {
        Detector::new("sensors[0]", &cube(), c, r, na, axis, 1.0, Weighting::Flux)
    }

    #[test]
    fn finds_its_face_and_reads_within_disc_and_aperture() {
        let d = det(DVec3::new(0.25, 0.0, 0.0), 0.05, 0.5, None).unwrap();
        assert_eq!(d.normal(), -DVec3::Z);
        assert!((d.cos_acceptance() - 0.75f64.sqrt()).abs() < 1e-15);
        let a = d.area();
        let down = -DVec3::Z;
        assert_eq!(d.read(DVec3::new(0.27, 0.02, 0.0), down), 1.0 / a);
        // Outside the disc, the aperture (30 degrees), or leaving inwards.
        assert_eq!(d.read(DVec3::new(0.31, 0.0, 0.0), down), 0.0);
        let tilted = DVec3::new(0.6, 0.0, -0.8);
        assert_eq!(d.read(DVec3::new(0.25, 0.0, 0.0), tilted), 0.0);
        assert_eq!(d.read(DVec3::new(0.25, 0.0, 0.0), DVec3::Z), 0.0);
        // A point of another face in line with the disc is not on it.
        assert_eq!(d.read(DVec3::new(0.25, 0.0, 1.0), down), 0.0);
        // Fluence weighs by 1 / cos.
        let f = Detector::new(
            "d",
            &cube(),
            DVec3::new(0.25, 0.0, 0.0),
            0.05,
            1.0,
            None,
            1.0,
            Weighting::Fluence,
        )
        .unwrap();
        let w = DVec3::new(0.6, 0.0, -0.8);
        assert!((f.read(DVec3::new(0.25, 0.0, 0.0), w) - 1.0 / (a * 0.8)).abs() < 1e-12);
    }

    #[test]
    fn samples_the_disc_uniformly_and_bounds_distances() {
        let d = det(DVec3::new(0.25, 0.0, 0.0), 0.05, 0.5, None).unwrap();
        let n = 20_000;
        let (mut r2, mut x) = (0.0, 0.0);
        for i in 0..n {
            let u = [
                (i as f64 + 0.5) / n as f64,
                ((i * 7919) % n) as f64 / n as f64,
            ];
            let p = d.sample_point(u);
            assert_eq!(p.z, 0.0);
            let off = p - d.center();
            assert!(off.length() <= d.radius() * (1.0 + 1e-12));
            r2 += off.length_squared();
            x += off.x;
        }
        // E r^2 = R^2 / 2 for a uniform disc; E x = 0.
        let r2 = r2 / n as f64;
        assert!((r2 / (0.5 * 0.05 * 0.05) - 1.0).abs() < 1e-3, "{r2}");
        assert!((x / n as f64).abs() < 1e-4);
        // The bound never exceeds the distance to any point of the disc.
        for x in [
            DVec3::new(0.25, 0.0, 0.3),
            DVec3::new(0.4, 0.1, 0.02),
            DVec3::new(0.26, 0.0, 0.0),
        ] {
            let b = d.distance_bound(x);
            for i in 0..200 {
                let p = d.sample_point([(i as f64 + 0.5) / 200.0, (i % 13) as f64 / 13.0]);
                assert!(b <= (p - x).length() + 1e-15);
            }
        }
        assert!((d.distance_bound(DVec3::new(0.25, 0.0, 0.3)) - 0.3).abs() < 1e-15);
        assert!((d.distance_bound(DVec3::new(0.4, 0.0, 0.0)) - 0.1).abs() < 1e-12);
    }

    #[test]
    fn a_point_detector_is_the_limit_of_a_disc() {
        let c = DVec3::new(0.25, 0.0, 0.0);
        let p = Detector::point("s", &cube(), c, 0.5, None, 1.0, Weighting::Flux).unwrap();
        assert!(p.is_point() && p.area() == 0.0 && p.radius() == 0.0);
        assert_eq!(p.normal(), -DVec3::Z);
        // No exit reads it, even at its point.
        assert_eq!(p.read(c, -DVec3::Z), 0.0);
        assert_eq!(p.sample_point([0.3, 0.7]), c);
        // Its weight per solid angle is a small disc's reading times its area and the cosine.
        let d = det(c, 1e-3, 0.5, None).unwrap();
        let w = DVec3::new(0.3, 0.0, -0.9).normalize();
        let disc = d.read(c, w) * d.area() * w.dot(d.normal());
        assert!((p.read_point(w) - disc).abs() < 1e-12, "{disc}");
        // Outside the aperture (30 degrees) or inwards: nothing.
        assert_eq!(p.read_point(DVec3::new(0.6, 0.0, -0.8)), 0.0);
        assert_eq!(p.read_point(DVec3::Z), 0.0);
        let f = Detector::point("s", &cube(), c, 1.0, None, 1.0, Weighting::Fluence).unwrap();
        assert_eq!(f.read_point(DVec3::new(0.6, 0.0, -0.8)), 1.0);
        // The same checks as a disc's, naming the field.
        let e = Detector::point(
            "s",
            &cube(),
            DVec3::new(0.25, 0.0, 0.3),
            0.5,
            None,
            1.0,
            Weighting::Flux,
        );
        assert!(e.unwrap_err().to_string().starts_with("s.position"));
        let e = Detector::point("s", &cube(), c, 1.5, None, 1.0, Weighting::Flux);
        assert!(
            e.unwrap_err()
                .to_string()
                .starts_with("s.numerical_aperture")
        );
    }

    #[test]
    fn refuses_bad_input_naming_the_field() {
        let on = DVec3::new(0.25, 0.0, 0.0);
        let msg = |r: Result<Detector, EndpointError>| r.unwrap_err().to_string();
        assert!(msg(det(on, 0.0, 0.5, None)).starts_with("sensors[0].radius"));
        assert!(msg(det(on, -1.0, 0.5, None)).starts_with("sensors[0].radius"));
        assert!(msg(det(on, f64::NAN, 0.5, None)).starts_with("sensors[0].radius"));
        // A radius whose area underflows (a NaN reading before).
        assert!(msg(det(on, 1e-300, 0.5, None)).starts_with("sensors[0].radius"));
        for na in [0.0, -0.1, 1.01, f64::NAN, f64::INFINITY] {
            let m = msg(det(on, 0.05, na, None));
            assert!(m.starts_with("sensors[0].numerical_aperture"), "{m}");
        }
        let m = msg(det(DVec3::new(0.25, 0.0, 0.3), 0.05, 0.5, None));
        assert!(
            m.starts_with("sensors[0].position") && m.contains("no face"),
            "{m}"
        );
        let m = msg(det(DVec3::new(0.25, 0.0, -0.1), 0.05, 0.5, None));
        assert!(m.starts_with("sensors[0].position"), "{m}");
        let m = msg(det(DVec3::new(0.48, 0.0, 0.0), 0.05, 0.5, None));
        assert!(
            m.starts_with("sensors[0].radius") && m.contains("edge"),
            "{m}"
        );
        let m = msg(det(on, 0.05, 0.5, Some(DVec3::Z)));
        assert!(m.starts_with("sensors[0].axis"), "{m}");
        let m = msg(det(on, 0.05, 0.5, Some(DVec3::ZERO)));
        assert!(m.starts_with("sensors[0].axis"), "{m}");
        let nan = DVec3::new(f64::NAN, 0.0, 0.0);
        assert!(msg(det(nan, 0.05, 0.5, None)).starts_with("sensors[0].position"));
        let flat = HomogeneousBox::new(
            Aabb::flat(glam::DVec2::ZERO, glam::DVec2::ONE).unwrap(),
            1.0,
            0.0,
        )
        .unwrap();
        let e = Detector::new(
            "d",
            &flat,
            DVec3::ZERO,
            0.1,
            0.5,
            None,
            1.0,
            Weighting::Flux,
        );
        assert!(e.unwrap_err().to_string().contains("3D"));
    }
}
