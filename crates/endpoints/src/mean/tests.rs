//! Unit tests of the speckle mean: closed forms, brute-force volume quadratures and the
//! Gaussian-beam limit.

use super::quadrature::{box_integral, box_integral_refined};
use super::*;
use speckle_medium::{Aabb, HomogeneousBox};
use speckle_phase::Phase;

/// A box of the given size with `sigma_s = 0.2`, `sigma_a = 0.05`, HG 0.3, wavelength 1.
struct Setup {
    medium: HomogeneousBox,
    phases: [Phase; 1],
    src: Source,
    sen: Sensor,
}

fn scene(src: Source, sen: Sensor, size: DVec3) -> Setup {
    let b = Aabb::centered(DVec3::ZERO, size).unwrap();
    let medium = HomogeneousBox::new(b, 0.2, 0.05).unwrap();
    Setup {
        medium,
        phases: [Phase::hg(0.3).unwrap()],
        src,
        sen,
    }
}

fn speckle_mean(s: &Setup) -> Complex64 {
    mean_field(&s.medium, &s.phases, 2.0 * PI, s.src, s.sen).unwrap()
}

/// The mean of a Gaussian beam tends, as its aperture narrows, to the mean of the plane wave
/// along its axis times the focal phase `e^(-i k a . f)` (point sensors in and behind the
/// box, a tilted axis); and it is reciprocal: a beam source read at a point equals a point
/// source read by the beam as a sensor (its source form), bitwise.
#[test]
fn gaussian_mean_tends_to_the_plane_wave_mean_and_is_reciprocal() {
    use crate::GaussianBeam;
    let k = 2.0 * PI;
    let a = DVec3::new(0.2, -0.1, 1.0).normalize();
    let f = DVec3::new(0.3, 0.2, -2.5);
    let size = DVec3::new(4.0, 4.0, 2.0);
    for q in [DVec3::new(0.1, 0.0, 0.3), DVec3::new(0.4, 0.3, 2.0)] {
        let plane = scene(
            Source::plane_wave(a).unwrap(),
            Sensor::Point { position: q },
            size,
        );
        let want = speckle_mean(&plane) * Complex64::from_polar(1.0, -k * a.dot(f));
        let mut errors = vec![];
        for gamma in [1e5, 1e6, 1e7] {
            let b = GaussianBeam::new("source", f, a, gamma).unwrap();
            let s = scene(Source::GaussianBeam(b), Sensor::Point { position: q }, size);
            let got = speckle_mean(&s);
            errors.push((got - want).norm() / want.norm());
            let back = scene(
                Source::Point { position: q },
                Sensor::GaussianBeam(b.reversed()),
                size,
            );
            assert_eq!(speckle_mean(&back), got);
        }
        // The error k^2 |q - f|^2 / gamma falls tenfold per decade.
        assert!(
            errors[2] < 2e-3 && errors[1] < 0.2 * errors[0],
            "{errors:?}"
        );
    }
}

#[test]
fn forward_mean_of_a_box_is_babinet_times_extinction() {
    // Normal incidence, forward sensor: m = (i k A / 2 pi)(1 - e^{-sigma_t L / 2}).
    let size = DVec3::new(6.0, 4.0, 3.0);
    let s = scene(
        Source::PlaneWave {
            direction: DVec3::Z,
        },
        Sensor::FarField {
            direction: DVec3::Z,
        },
        size,
    );
    let m = speckle_mean(&s);
    let k = 2.0 * PI;
    let expect = Complex64::new(0.0, k * 24.0 / (2.0 * PI)) * (1.0 - (-0.25f64 * 3.0 / 2.0).exp());
    assert!(
        (m - expect).norm() < 1e-10 * expect.norm(),
        "{m} vs {expect}"
    );
}

#[test]
fn oblique_far_field_mean_matches_brute_force() {
    let size = DVec3::new(2.0, 1.5, 1.0);
    let i = DVec3::new(0.2, 0.1, 1.0).normalize();
    let v = DVec3::new(0.25, 0.05, 1.0).normalize();
    let s = scene(
        Source::PlaneWave { direction: i },
        Sensor::FarField { direction: v },
        size,
    );
    let b = *s.medium.bounds();
    let (k, st) = (2.0 * PI, 0.25);
    let got = box_integral(&b, k, st, i, v);
    // Brute-force midpoint rule in 3D.
    let n = 120;
    let mut acc = Complex64::new(0.0, 0.0);
    for a in 0..n {
        for c in 0..n {
            for d in 0..n {
                let u = [
                    (a as f64 + 0.5) / n as f64,
                    (c as f64 + 0.5) / n as f64,
                    (d as f64 + 0.5) / n as f64,
                ];
                let x = b.lerp(u);
                acc += Complex64::from_polar(
                    (-0.5 * st * b.exit_distance(x, v)).exp(),
                    k * (i - v).dot(x),
                );
            }
        }
    }
    acc *= b.volume() / (n * n * n) as f64;
    assert!((got - acc).norm() < 2e-4 * acc.norm(), "{got} vs {acc}");
}

/// A lossless box of isotropic scatterers lit by `i`, one far-field sensor `v`.
fn lossless(b: Aabb, mean_free_path: f64, i: DVec3, v: DVec3) -> Setup {
    Setup {
        medium: HomogeneousBox::from_mean_free_path(b, mean_free_path, 1.0).unwrap(),
        phases: [Phase::isotropic(b.dimension())],
        src: Source::PlaneWave { direction: i },
        sen: Sensor::FarField { direction: v },
    }
}

fn mean_of(s: &Setup) -> Complex64 {
    speckle_mean(s)
}

/// `int_0^L e^{(2ik - a) s} ds = (1 - e^{(2ik - a) L}) / (a - 2ik)`: the depth integral at
/// normal backscatter with attenuation rate `a` (`sigma_t` for both legs, `sigma_t / 2` for
/// one).
fn depth_integral(k: f64, a: f64, l: f64) -> Complex64 {
    let z = Complex64::new(-a, 2.0 * k);
    (1.0 - (z * l).exp()) / Complex64::new(a, -2.0 * k)
}

/// An error estimate of [`box_integral`] from halving its panels twice:
/// `|Q_1 - Q_2| + |Q_2 - Q_4|`. Composite Gauss-Legendre converges as `h^2` across the
/// kinks of the integrand, but erratically (the change from one halving alone can be half
/// the error), hence two.
fn quadrature_error(b: &Aabb, k: f64, st: f64, i: DVec3, v: DVec3) -> f64 {
    let q = |r| box_integral_refined(b, k, st, i, v, r, &|| false).unwrap();
    let (q1, q2, q4) = (q(1), q(2), q(4));
    (q1 - q2).norm() + (q2 - q4).norm()
}

#[test]
fn normal_backscatter_matches_the_effective_medium_closed_form() {
    // Issue "coherent mean in reflection": a W x W x L box centred at the origin, lossless
    // isotropic, lit along z, sensor at exact backscatter. Both legs are attenuated:
    // m = (i k sigma / 4 pi) W^2 e^{-ikL} (1 - e^{(2ik - sigma) L}) / (sigma - 2ik)
    // (front face at z0 = -L/2, phase e^{2ik z0}). The integrand is constant over the exit
    // face and the depth integral is closed form, so the quadrature is exact up to the
    // rounding of its sum of up to 7e5 equal terms: tolerance 1e-10 relative (about
    // 1e6 f64 epsilons; 3e-12 observed). Runs in milliseconds.
    let k = 2.0 * PI;
    for (w, l, mfp) in [(16.0, 4.0, 4.0), (16.0, 4.3, 4.0), (5.0, 1.7, 0.8)] {
        let b = Aabb::centered(DVec3::ZERO, DVec3::new(w, w, l)).unwrap();
        let m = mean_of(&lossless(b, mfp, DVec3::Z, -DVec3::Z));
        let sigma = 1.0 / mfp;
        let expect = Complex64::new(0.0, k * sigma / (4.0 * PI))
            * w
            * w
            * Complex64::from_polar(1.0, -k * l)
            * depth_integral(k, sigma, l);
        assert!(
            (m - expect).norm() < 1e-10 * expect.norm(),
            "{w} x {w} x {l}: {m} vs {expect}"
        );
        // The exit leg alone (the old rule) is a different number: 0.62 of it for the
        // issue's box.
        let old = Complex64::new(0.0, k * sigma / (4.0 * PI))
            * w
            * w
            * Complex64::from_polar(1.0, -k * l)
            * depth_integral(k, 0.5 * sigma, l);
        assert!((m - old).norm() > 0.1 * m.norm());
        if l == 4.0 {
            // The issue's leading-order form, -(sigma W^2 / 4k)(1 - e^{-sigma L}), holds for
            // lambda = 1 and 2L a whole number of wavelengths; the exact ratio is
            // 1 / (1 + i sigma / 2k), within sigma / 2k of 1.
            let issue = -sigma * w * w / (4.0 * k) * (1.0 - (-sigma * l).exp());
            assert!((m / issue - 1.0).norm() <= sigma / (2.0 * k));
            assert!((old.norm() / m.norm() - 0.6225).abs() < 1e-3);
        }
    }
}

#[test]
fn flatland_normal_backscatter_matches_the_closed_form() {
    // A W x L rectangle: m = (sigma / 2) sqrt(k / 2 pi) e^{3 i pi / 4} W e^{-ikL}
    // (1 - e^{(2ik - sigma) L}) / (sigma - 2ik). Exact up to rounding as in 3D (the sum has
    // at most 2048 terms here: tolerance 1e-12).
    let k = 2.0 * PI;
    for (w, l, mfp) in [(40.0, 8.0, 4.0), (10.0, 3.3, 2.0)] {
        let b = Aabb::flat(
            glam::DVec2::new(-0.5 * w, -0.5 * l),
            glam::DVec2::new(0.5 * w, 0.5 * l),
        )
        .unwrap();
        let m = mean_of(&lossless(b, mfp, DVec3::Y, -DVec3::Y));
        let sigma = 1.0 / mfp;
        let expect = Complex64::from_polar(0.5 * sigma * (k / (2.0 * PI)).sqrt(), 0.75 * PI)
            * w
            * Complex64::from_polar(1.0, -k * l)
            * depth_integral(k, sigma, l);
        assert!(
            (m - expect).norm() < 1e-12 * expect.norm(),
            "{w} x {l}: {m} vs {expect}"
        );
    }
}

#[test]
fn oblique_specular_reflection_matches_fresnel() {
    // A wide slab (W_x = 20000, depth 40, mean free path 50) lit at 30 degrees, sensor in
    // the specular direction, against the exact Fresnel reflection of a slab of index
    // k_eff / k, k_eff = k + i sigma / 2, with the Kirchhoff far field of the reflected
    // wave over the face: A = (k cos / 2 pi i) W_x W_y e^{2ik cos z0} r. The volume model
    // agrees with it to first order in sigma / k; tolerance: the first neglected order,
    // sigma / (k cos^2), plus the edge strips (the width L tan of both ends of W_x, where
    // the legs leave or enter through the side faces) and the quadrature
    // ([`quadrature_error`]). The exit-leg-only value must miss by more. About 2 s.
    let k = 2.0 * PI;
    let (wx, wy, l, mfp) = (20_000.0, 1.0, 40.0, 50.0);
    let sigma = 1.0 / mfp;
    let (sin, cos) = 30f64.to_radians().sin_cos();
    let i = DVec3::new(sin, 0.0, cos);
    let v = DVec3::new(sin, 0.0, -cos);
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(wx, wy, l)).unwrap();
    let m = mean_of(&lossless(b, mfp, i, v));
    let pref = Complex64::new(0.0, k * sigma / (4.0 * PI));
    let quad = quadrature_error(&b, k, sigma, i, v) * pref.norm() / m.norm();
    // Fresnel (continuous field and normal derivative at both faces).
    let keff = Complex64::new(k, 0.5 * sigma);
    let (kz, kz2) = (k * cos, (keff * keff - k * k * sin * sin).sqrt());
    let r01 = (kz - kz2) / (kz + kz2);
    let e = (Complex64::new(0.0, 2.0) * kz2 * l).exp();
    let r = r01 * (1.0 - e) / (1.0 - r01 * r01 * e);
    let face = Complex64::from_polar(k * cos * wx * wy / (2.0 * PI), -0.5 * PI - k * l * cos);
    let fresnel = face * r;
    let tol = sigma / (k * cos * cos) + 2.0 * l * sin / cos / wx + quad;
    let dev = (m - fresnel).norm() / fresnel.norm();
    // The exit leg alone on the infinite slab: back-face attenuation e^{-sigma L / 2 cos}.
    let z1 = Complex64::new(-0.5 * sigma / cos, 2.0 * k * cos);
    let old =
        pref * wx * wy * Complex64::from_polar(1.0, -k * l * cos) * (1.0 - (z1 * l).exp()) / -z1;
    let dev_old = (old - fresnel).norm() / fresnel.norm();
    println!(
        "specular: {m:.6} vs Fresnel {fresnel:.6}: {dev:.2e} (tolerance {tol:.2e}, quadrature {quad:.1e}); exit leg only {old:.6}: {dev_old:.2e}"
    );
    assert!(dev < tol, "{dev} vs {tol}");
    assert!(dev_old > tol, "{dev_old} vs {tol}");
}

/// Midpoint rule over an `n^3` grid (`n^2` in flatland) of the integrand of the module docs,
/// found by tracing: the exit face of the ray along `v` decides the legs, `d_in` is the
/// distance along `-i`.
/// With `per_face = false`, the exit leg alone everywhere (the rule before the fix).
fn brute_force(
    b: &Aabb,
    k: f64,
    st: f64,
    (i, v): (DVec3, DVec3),
    n: usize,
    per_face: bool,
) -> Complex64 {
    let flat = b.dimension() == Dimension::Two;
    let nz = if flat { 1 } else { n };
    let (lo, hi) = (b.min(), b.max());
    let mut acc = Complex64::new(0.0, 0.0);
    for a in 0..n {
        for c in 0..n {
            for d in 0..nz {
                let u = [
                    (a as f64 + 0.5) / n as f64,
                    (c as f64 + 0.5) / n as f64,
                    (d as f64 + 0.5) / nz as f64,
                ];
                let mut x = b.lerp(u);
                if flat {
                    x.z = lo.z;
                }
                // Trace along v: the nearest boundary plane is the exit face.
                let (mut d_out, mut face) = (f64::INFINITY, 0);
                for ax in 0..3 {
                    let t = if v[ax] > 0.0 {
                        (hi[ax] - x[ax]) / v[ax]
                    } else if v[ax] < 0.0 {
                        (lo[ax] - x[ax]) / v[ax]
                    } else {
                        continue;
                    };
                    if t < d_out {
                        (d_out, face) = (t, ax);
                    }
                }
                let enters = per_face && i[face] * v[face] < 0.0;
                let d_in = if enters { b.exit_distance(x, -i) } else { 0.0 };
                acc +=
                    Complex64::from_polar((-0.5 * st * (d_out + d_in)).exp(), k * (i - v).dot(x));
            }
        }
    }
    acc * b.measure() / (n * n * nz) as f64
}

#[test]
fn reflection_far_field_mean_matches_brute_force() {
    // Oblique reflection, where the sensor leg exits through an entry face of the incident
    // wave (-y and -z: both legs) and through a face it does not enter (+x: exit leg only),
    // in 3D and flatland. The brute force converges as O(h) (the integrand jumps where the
    // exit face changes), so its error at n is estimated by its change from n/2 to n; the
    // quadrature's by halving its panels ([`quadrature_error`]). Tolerance: twice their sum.
    // The exit leg alone must miss by more than 10 tolerances. About 2 s.
    let k = 2.0 * PI;
    let st = 0.7;
    let b3 = Aabb::centered(DVec3::ZERO, DVec3::new(2.0, 1.5, 1.0)).unwrap();
    let b2 = Aabb::flat(glam::DVec2::new(-2.0, -0.6), glam::DVec2::new(1.5, 0.9)).unwrap();
    let cases = [
        (
            b3,
            DVec3::new(0.2, 0.1, 1.0).normalize(),
            DVec3::new(0.3, -0.2, -1.0).normalize(),
            200,
        ),
        (
            b2,
            DVec3::new(0.3, 1.0, 0.0).normalize(),
            DVec3::new(0.4, -1.0, 0.0).normalize(),
            4000,
        ),
    ];
    for (b, i, v, n) in cases {
        let got = box_integral(&b, k, st, i, v);
        let quad = quadrature_error(&b, k, st, i, v);
        let (coarse, fine) = (
            brute_force(&b, k, st, (i, v), n / 2, true),
            brute_force(&b, k, st, (i, v), n, true),
        );
        let old = brute_force(&b, k, st, (i, v), n / 2, false);
        let tol = 2.0 * (quad + (fine - coarse).norm());
        println!(
            "{:?}: {got:.6} vs brute force {fine:.6} ({coarse:.6} at n/2): {:.2e}, \
             tolerance {tol:.2e} (quadrature {quad:.1e}); exit leg only {old:.6}",
            b.dimension(),
            (got - fine).norm()
        );
        assert!((got - fine).norm() < tol);
        // The test tells the rules apart.
        assert!((old - fine).norm() > 10.0 * tol);
    }
}

#[test]
fn point_endpoint_means_are_attenuated_direct_paths() {
    let size = DVec3::new(2.0, 2.0, 2.0);
    let p = DVec3::new(0.0, 0.0, -3.0);
    let q = DVec3::new(0.0, 0.0, 4.0);
    let s = scene(
        Source::Point { position: p },
        Sensor::Point { position: q },
        size,
    );
    let m = speckle_mean(&s);
    // 2 units of medium with sigma_t = 0.25 on a 7-unit line.
    let expect = Complex64::from_polar((-0.25f64).exp() / 7.0, 2.0 * PI * 7.0);
    assert!((m - expect).norm() < 1e-12);
}

#[test]
fn an_incident_wave_almost_parallel_to_a_face_gives_a_finite_mean() {
    // Fuzz finding (issue 27): a plane wave along [1e19, 1, 0] (a component of 1e-19
    // across a face) on a flatland square of 100 wavelengths gave NaN and 1e260 means near
    // the forward direction: the distance to the face behind was computed with an error of
    // 1e5 box sizes. Such a component now counts as parallel; the mean is that of a
    // component of 1e-6 on the same side (the model's switch between the legs is not
    // continuous at exact parallel incidence: module docs) to its change over 1e-6 rad: at
    // most a phase of k L 1e-6 = 6.3e-4 across the box times the largest (forward) mean.
    let b = Aabb::flat(glam::DVec2::new(-50.0, -50.0), glam::DVec2::new(50.0, 50.0)).unwrap();
    let at = |iy: f64, a: f64| {
        let v = DVec3::new(a.cos(), a.sin(), 0.0);
        mean_of(&lossless(b, 50.0, DVec3::new(1.0, iy, 0.0).normalize(), v))
    };
    let forward = at(1e-6, 0.0).norm();
    for a in [-0.1f64, -0.08, -0.06, 0.0, 0.04] {
        let (tiny, small) = (at(1e-19, a), at(1e-6, a));
        assert!(tiny.is_finite(), "{a}: {tiny}");
        assert!(
            (tiny - small).norm() < 6.3e-4 * forward,
            "{a}: {tiny} vs {small} (forward {forward})"
        );
    }
}
