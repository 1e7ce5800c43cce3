//! Directions on the unit sphere.

use glam::DVec3;
use std::f64::consts::PI;

/// Density `1 / (4 pi)` of the uniform distribution on the unit sphere.
pub const UNIFORM_SPHERE_PDF: f64 = 1.0 / (4.0 * PI);

/// A uniform unit direction from two uniform variates (density [`UNIFORM_SPHERE_PDF`]).
pub fn uniform_sphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    DVec3::new(r * c, r * s, z)
}

/// Two unit vectors completing the unit vector `n` to a right-handed orthonormal basis
/// (Duff et al. 2017, "Building an orthonormal basis, revisited").
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1.0f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            DVec3::Z,
            -DVec3::Z,
            DVec3::X,
            DVec3::new(0.3, -0.4, 0.1).normalize(),
        ] {
            let (t, b) = orthonormal_basis(n);
            for (p, q) in [(t, b), (t, n), (b, n)] {
                assert!(p.dot(q).abs() < 1e-14);
            }
            assert!((t.cross(b) - n).length() < 1e-14);
        }
    }

    #[test]
    fn uniform_sphere_is_unit() {
        let d = uniform_sphere([0.25, 0.8]);
        assert!((d.length() - 1.0).abs() < 1e-15 && (d.z - 0.5).abs() < 1e-15);
    }
}
