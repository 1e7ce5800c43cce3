//! A refractive-index mismatch at the faces of the medium's box: Fresnel reflection and
//! refraction (Snell's law) of light reaching a face from inside.
//!
//! Unpolarised light: the reflectance is the mean of the `s` and `p` Fresnel reflectances,
//! `R = (r_s^2 + r_p^2) / 2` with `r_s = (n1 cos_i - n2 cos_t) / (n1 cos_i + n2 cos_t)` and
//! `r_p = (n2 cos_i - n1 cos_t) / (n2 cos_i + n1 cos_t)`, `n1 sin_i = n2 sin_t` (Born and Wolf,
//! Sec. 1.5); beyond the critical angle (`n1 > n2`) the reflection is total. This is the model
//! of MCX (`isreflect = 1`) and of adding-doubling's boundary conditions.

use glam::DVec3;

/// The interface between the medium (index `inside`) and what surrounds its box (index
/// `outside`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Interface {
    inside: f64,
    outside: f64,
}

impl Interface {
    /// An interface; `None` unless both indices are finite and at least 1.
    pub fn new(inside: f64, outside: f64) -> Option<Self> {
        let ok = |n: f64| n.is_finite() && n >= 1.0;
        (ok(inside) && ok(outside)).then_some(Self { inside, outside })
    }

    /// The index of the medium.
    pub fn inside(&self) -> f64 {
        self.inside
    }

    /// The index outside the box.
    pub fn outside(&self) -> f64 {
        self.outside
    }

    /// Whether the indices are equal (no reflection, no refraction).
    pub fn is_matched(&self) -> bool {
        self.inside == self.outside
    }

    /// The unpolarised Fresnel reflectance for light inside reaching the face at `cos_i` (the
    /// cosine to the face's normal, in `(0, 1]`): 1 beyond the critical angle.
    #[inline]
    pub fn reflectance(&self, cos_i: f64) -> f64 {
        reflectance(self.inside, self.outside, cos_i)
    }

    /// The direction outside of light leaving along `dir` through a face of outward normal
    /// `normal` (`dir . normal > 0`), or `None` when it is totally reflected.
    #[inline]
    pub fn refract(&self, dir: DVec3, normal: DVec3) -> Option<DVec3> {
        refract(self.inside / self.outside, dir, normal)
    }
}

/// The unpolarised Fresnel reflectance from index `n1` into index `n2` at the cosine of
/// incidence `cos_i`.
#[inline]
pub fn reflectance(n1: f64, n2: f64, cos_i: f64) -> f64 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    if n1 == n2 {
        return 0.0;
    }
    let sin_t = n1 / n2 * (1.0 - cos_i * cos_i).max(0.0).sqrt();
    if sin_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// The refracted direction of `dir` through a surface of unit normal `normal` (pointing to the
/// side it enters, `dir . normal > 0`) with the ratio of indices `eta = n1 / n2`; `None` beyond
/// the critical angle.
#[inline]
pub fn refract(eta: f64, dir: DVec3, normal: DVec3) -> Option<DVec3> {
    let cos_i = dir.dot(normal);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((eta * dir + (cos_t - eta * cos_i) * normal).normalize())
}

/// The mirror image of `dir` in a surface of unit normal `normal`.
#[inline]
pub fn reflect(dir: DVec3, normal: DVec3) -> DVec3 {
    dir - 2.0 * dir.dot(normal) * normal
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_critical_angle_and_snell() {
        let i = Interface::new(1.4, 1.0).unwrap();
        let r0 = (0.4f64 / 2.4).powi(2);
        assert!((i.reflectance(1.0) - r0).abs() < 1e-15);
        // Total reflection beyond asin(1 / 1.4) (44.4 degrees), and from outside none.
        let critical = (1.0f64 / 1.4).asin();
        assert_eq!(i.reflectance((critical + 1e-6).cos()), 1.0);
        assert!(i.reflectance((critical - 1e-3).cos()) < 1.0);
        assert_eq!(
            reflectance(1.0, 1.4, 0.01).min(1.0),
            reflectance(1.0, 1.4, 0.01)
        );
        assert!(
            i.refract(
                DVec3::new((critical + 1e-6).sin(), 0.0, (critical + 1e-6).cos()),
                DVec3::Z
            )
            .is_none()
        );
        // Snell's law and the plane of incidence.
        let d = DVec3::new(0.3, 0.2, 0.9).normalize();
        let t = i.refract(d, DVec3::Z).unwrap();
        let sin = |v: DVec3| (1.0 - v.z * v.z).sqrt();
        assert!((1.4 * sin(d) - sin(t)).abs() < 1e-14);
        assert!((d.x * t.y - d.y * t.x).abs() < 1e-14 && t.z > 0.0);
        assert!((t.length() - 1.0).abs() < 1e-15);
        // Reciprocity: the reflectance is the same from both sides along the same ray.
        let back = reflectance(1.0, 1.4, t.z);
        assert!((back - i.reflectance(d.z)).abs() < 1e-14);
        // Matched: nothing reflects, nothing bends.
        let m = Interface::new(1.33, 1.33).unwrap();
        assert!(m.is_matched() && m.reflectance(0.3) == 0.0);
        assert!((m.refract(d, DVec3::Z).unwrap() - d).length() < 1e-15);
        assert_eq!(reflect(d, DVec3::Z), DVec3::new(d.x, d.y, -d.z));
        assert!(Interface::new(0.9, 1.0).is_none() && Interface::new(1.0, f64::NAN).is_none());
    }

    #[test]
    fn the_hemispherical_reflectance_matches_its_closed_form_at_n_1_5() {
        // The diffuse (cosine-weighted) reflectance from outside onto glass of n = 1.5 is
        // 0.0918 (a textbook value: 1 - r_d = 0.908 for n = 1.5, e.g. Walter et al. 2007);
        // inside, the internal diffuse reflectance is 1 - (1 - 0.0918) / 1.5^2 = 0.5964.
        let n = 400_000;
        let (mut outside, mut inside) = (0.0, 0.0);
        for k in 0..n {
            // mu^2 uniform: cosine-weighted directions, 2 int R mu dmu by the midpoint rule.
            let mu = ((k as f64 + 0.5) / n as f64).sqrt();
            outside += reflectance(1.0, 1.5, mu);
            inside += reflectance(1.5, 1.0, mu);
        }
        let (outside, inside) = (outside / n as f64, inside / n as f64);
        assert!((outside - 0.0918).abs() < 2e-4, "{outside}");
        assert!(
            (inside - (1.0 - (1.0 - outside) / 2.25)).abs() < 1e-6,
            "{inside}"
        );
    }
}
