use super::*;
use crate::{Sensor, Source};
use speckle_medium::{Aabb, HomogeneousBox};

/// `scatter_damped` with the two copies' [`Damping::pair`], averaged over the standard normal
/// `u`, is the Gaussian average over a displacement `Delta ~ N(0, sigma^2 I)` of copy 1's
/// connection at `x - Delta / 2` times the conjugate of copy 2's at `x + Delta / 2` and the
/// path segment's phase change (`e^(i k w . Delta)` for a source's outgoing `w`,
/// `e^(-i k w . Delta)` for a sensor's arrival `w`), `C = k^2 sigma^2 / 2`, for every pair of
/// endpoints of a set (the copies of off-diagonal entries connect to different ones): both
/// averages by product Gauss-Hermite rules (20 nodes per axis, converged far below the
/// tolerance for these smooth integrands: `k sigma = 1.7`), for Gaussian beams, plane waves and
/// far-field sensors, 3D and flatland. The medium's mean free path is `10^4`, so the displaced
/// points' attenuation (to first order the same for both copies) moves the average by less
/// than `1e-5` of it: the tolerance is `1e-4` of the largest value (measured: `1e-7`). Each
/// copy damped alone (no tilt) misses by 3-7% of the largest value, one copy damped by `2 C`
/// (the average over one displaced copy) by 12-24%.
/// A nearly clear 12 x 12 x 6 box (12 x 12 in flatland; mean free path 1e4) and its `up`
/// axis, the beams' direction.
fn clear_box(flat: bool) -> (HomogeneousBox, DVec3) {
    let b = if flat {
        Aabb::flat(glam::DVec2::splat(-6.0), glam::DVec2::splat(6.0)).unwrap()
    } else {
        Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 6.0)).unwrap()
    };
    let m = HomogeneousBox::from_mean_free_path(b, 1e4, 1.0).unwrap();
    (m, if flat { DVec3::Y } else { DVec3::Z })
}

#[test]
fn damped_pairs_are_the_gaussian_average_of_displaced_copies() {
    use speckle_phase::Phase;
    use speckle_vmf::VmfMixture;
    let phase = Phase::Vmf(std::sync::Arc::new(
        VmfMixture::new(vec![(0.0, 0.3), (5.0, 1.0), (-1.5, 0.2)]).unwrap(),
    ));
    let hermite = hermite_rule(20);
    let k = 6.0;
    let sigma = 1.7 / k;
    let big_c = 0.5 * k * k * sigma * sigma;
    for flat in [false, true] {
        let (m, up) = clear_box(flat);
        let beam = |f: DVec3, g: f64| crate::GaussianBeam::new("b", f, up, g).unwrap();
        let sources = vec![
            Source::GaussianBeam(beam(DVec3::new(0.3, -0.2, 0.0), 9.0)),
            Source::plane_wave((up + 0.3 * DVec3::X).normalize()).unwrap(),
            Source::GaussianBeam(beam(DVec3::new(-0.2, 0.1, 0.0), 4.0)),
        ];
        let sensors = vec![
            Sensor::far_field(up).unwrap(),
            Sensor::GaussianBeam(beam(DVec3::new(0.0, 0.4, 0.0), 9.0)),
        ];
        // Scattering by about 53 degrees from the axis.
        let w = if flat {
            DVec3::new(0.8, 0.6, 0.0)
        } else {
            DVec3::new(0.8, 0.0, 0.6)
        };
        let axes: usize = if flat { 2 } else { 3 };
        // The product rule's nodes: a standard normal vector and its weight.
        let nodes: Vec<(DVec3, f64)> = (0..hermite.len().pow(axes as u32))
            .map(|idx| {
                let (mut z, mut weight, mut rest) = (DVec3::ZERO, 1.0, idx);
                for a in 0..axes {
                    let (x, wx) = hermite[rest % hermite.len()];
                    rest /= hermite.len();
                    z[a] = std::f64::consts::SQRT_2 * x;
                    weight *= wx / std::f64::consts::PI.sqrt();
                }
                (z, weight)
            })
            .collect();
        for (set, sign) in [
            (Endpoints::sources(&m, k, &sources), 1.0),
            (Endpoints::sensors(&m, k, &sensors), -1.0),
        ] {
            let n = set.len();
            let dirs = |d: DVec3| if sign > 0.0 { (d, w) } else { (w, d) };
            let x = DVec3::new(0.2, 0.1, if flat { 0.0 } else { -0.3 });
            let mut legs = set.legs();
            let value = |re: &[f64], im: &[f64], i: usize| Complex64::new(re[i], im[i]);
            // The displaced copies' average.
            let mut want = vec![Complex64::new(0.0, 0.0); n * n];
            let (mut r1, mut i1, mut r2, mut i2) =
                (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
            for &(z, weight) in &nodes {
                let delta = sigma * z;
                set.connect(x - 0.5 * delta, &mut legs);
                set.scatter(&legs, &phase, dirs, &mut r1, &mut i1);
                set.connect(x + 0.5 * delta, &mut legs);
                set.scatter(&legs, &phase, dirs, &mut r2, &mut i2);
                let turn = Complex64::from_polar(weight, sign * k * w.dot(delta));
                for a in 0..n {
                    for c in 0..n {
                        want[a * n + c] += value(&r1, &i1, a) * value(&r2, &i2, c).conj() * turn;
                    }
                }
            }
            // The damped pairs' average over `u`, and two wrong ones.
            set.connect(x, &mut legs);
            let pair_average = |pair: &dyn Fn(DVec3) -> [Damping; 2]| {
                let mut got = vec![Complex64::new(0.0, 0.0); n * n];
                let (mut re, mut im) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
                for &(u, weight) in &nodes {
                    set.scatter_damped(&legs, &phase, dirs, &pair(u), &mut re, &mut im);
                    for a in 0..n {
                        for c in 0..n {
                            let v = value(&re, &im, a) * value(&re, &im, n + c).conj();
                            got[a * n + c] += weight * v;
                        }
                    }
                }
                got
            };
            let got = pair_average(&|u| Damping::pair(big_c, u));
            let untilted = pair_average(&|_| Damping::pair(big_c, DVec3::ZERO));
            let one_copy = pair_average(&|_| {
                [
                    Damping {
                        c: 2.0 * big_c,
                        tilt: DVec3::ZERO,
                    },
                    Damping::NONE,
                ]
            });
            let largest = want.iter().map(|v| v.norm()).fold(0.0, f64::max);
            let off = |v: &[Complex64]| {
                v.iter()
                    .zip(&want)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max)
                    / largest
            };
            assert!(
                off(&got) <= 1e-4,
                "flat {flat} side {sign}: {got:?} against {want:?}"
            );
            assert!(off(&untilted) > 1e-2, "{}", off(&untilted));
            assert!(off(&one_copy) > 1e-2, "{}", off(&one_copy));
        }
    }
}

/// Nodes and weights of the `n`-point Gauss-Hermite rule (weight `e^(-x^2)`), by Newton's
/// method on the orthonormal Hermite recurrence from Golub-Welsch-free starting guesses.
fn hermite_rule(n: usize) -> Vec<(f64, f64)> {
    let pi4 = std::f64::consts::PI.powf(-0.25);
    let mut half: Vec<(f64, f64)> = Vec::with_capacity(n);
    let mut z = 0.0;
    let nf = n as f64;
    for i in 0..n / 2 {
        z = match i {
            0 => (2.0 * nf + 1.0).sqrt() - 1.85575 * (2.0 * nf + 1.0).powf(-1.0 / 6.0),
            1 => z - 1.14 * nf.powf(0.426) / z,
            2 => 1.86 * z - 0.86 * half[0].0,
            3 => 1.91 * z - 0.91 * half[1].0,
            _ => 2.0 * z - half[i - 2].0,
        };
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p1, mut p2) = (pi4, 0.0);
            for j in 1..=n {
                let p3 = p2;
                p2 = p1;
                let jf = j as f64;
                p1 = z * (2.0 / jf).sqrt() * p2 - ((jf - 1.0) / jf).sqrt() * p3;
            }
            dp = (2.0 * nf).sqrt() * p2;
            let dz = p1 / dp;
            z -= dz;
            if dz.abs() < 1e-15 {
                break;
            }
        }
        half.push((z, 2.0 / (dp * dp)));
    }
    let mut all: Vec<(f64, f64)> = half.iter().map(|&(x, w)| (-x, w)).collect();
    all.extend(half.iter().rev().copied());
    all
}

/// Single scattering with the imaginary tilt `-i k Delta` of both endpoints' plane waves is
/// single scattering at the point moved by `-Delta` (in a medium of mean free path `10^4`,
/// whose attenuation changes by less than `1e-5` over the move: tolerance `1e-4` of the
/// value), and `single_tilted_many` is `single_tilted` tilt by tilt (to `1e-12`), for two
/// beams (isotropic and vMF lobes), a beam and a leg endpoint each way, and two leg endpoints,
/// 3D and flatland.
#[test]
fn tilted_single_scattering_is_single_scattering_at_the_moved_point() {
    use speckle_phase::Phase;
    use speckle_vmf::VmfMixture;
    let vmf = Phase::Vmf(std::sync::Arc::new(
        VmfMixture::new(vec![(0.0, 0.3), (5.0, 1.0)]).unwrap(),
    ));
    let k = 6.0;
    for flat in [false, true] {
        let (m, up) = clear_box(flat);
        let iso = if flat {
            Phase::FlatIsotropic
        } else {
            Phase::Isotropic
        };
        let beam = |f: DVec3, a: DVec3| crate::GaussianBeam::new("b", f, a, 9.0).unwrap();
        let sources = vec![
            Source::GaussianBeam(beam(DVec3::new(0.3, -0.2, 0.0), up)),
            Source::plane_wave((up + 0.3 * DVec3::X).normalize()).unwrap(),
        ];
        let sensors = vec![
            Sensor::GaussianBeam(beam(DVec3::new(0.0, 0.4, 0.0), up)),
            Sensor::far_field((up + 0.5 * DVec3::X).normalize()).unwrap(),
        ];
        let (es, ev) = (
            Endpoints::sources(&m, k, &sources),
            Endpoints::sensors(&m, k, &sensors),
        );
        let x = DVec3::new(0.2, 0.1, if flat { 0.0 } else { -0.3 });
        let delta = if flat {
            DVec3::new(0.07, -0.05, 0.0)
        } else {
            DVec3::new(0.07, -0.05, 0.04)
        };
        let (mut ls, mut lv) = (es.legs(), ev.legs());
        let tilt = |d: DVec3| d.to_array().map(|c| Complex64::new(0.0, -k * c));
        for phase in [&iso, &vmf] {
            if flat && std::ptr::eq(phase, &vmf) {
                continue;
            }
            for s in 0..2 {
                for v in 0..2 {
                    es.connect(x - delta, &mut ls);
                    ev.connect(x - delta, &mut lv);
                    let moved = es.single(&ls, s, &ev, &lv, v, phase);
                    es.connect(x, &mut ls);
                    ev.connect(x, &mut lv);
                    let got = es.single_tilted(&ls, s, &ev, &lv, v, phase, tilt(delta));
                    assert!(
                        (got - moved).norm() <= 1e-4 * moved.norm(),
                        "flat {flat} ({s}, {v}): {got} against {moved}"
                    );
                    let tilts: Vec<_> = [delta, -delta, 2.0 * delta, DVec3::ZERO]
                        .iter()
                        .map(|&d| tilt(d))
                        .collect();
                    let mut many = Vec::new();
                    es.single_tilted_many(&ls, s, &ev, &lv, v, phase, &tilts, &mut many);
                    for (a, &t) in many.iter().zip(&tilts) {
                        let b = es.single_tilted(&ls, s, &ev, &lv, v, phase, t);
                        assert!((a - b).norm() <= 1e-12 * b.norm(), "{a} against {b}");
                    }
                }
            }
        }
    }
}

/// At lags far into the decorrelation (`C = 10^7`, a tilt of norm `8 10^3`, where `e^(tilt .
/// psi)` alone overflows) every damped connection is finite and at most the bound
/// `e^(|u|^2 / 4)` times the undamped scale, and the pair's product is finite, for beams and
/// leg endpoints, both sides.
#[test]
fn huge_dampings_stay_finite() {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 6.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 2.0, 1.0).unwrap();
    let beam = crate::GaussianBeam::new("b", DVec3::ZERO, DVec3::Z, 9.0).unwrap();
    let sources = vec![
        Source::GaussianBeam(beam),
        Source::plane_wave(DVec3::new(0.2, 0.0, 1.0)).unwrap(),
    ];
    let sensors = vec![
        Sensor::far_field(DVec3::Z).unwrap(),
        Sensor::GaussianBeam(beam),
    ];
    let phase = speckle_phase::Phase::Isotropic;
    let u = DVec3::new(3.0, -2.5, 1.5);
    for w in [DVec3::Z, DVec3::new(0.6, 0.0, 0.8), -DVec3::Z] {
        for set in [
            Endpoints::sources(&m, 6.0, &sources),
            Endpoints::sensors(&m, 6.0, &sensors),
        ] {
            let n = set.len();
            let mut legs = set.legs();
            set.connect(DVec3::new(0.1, 0.2, -0.3), &mut legs);
            let (mut re, mut im) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
            let pair = Damping::pair(1e7, u);
            set.scatter_damped(&legs, &phase, |d| (d, w), &pair, &mut re, &mut im);
            for i in 0..n {
                let (a, b) = (
                    Complex64::new(re[i], im[i]),
                    Complex64::new(re[n + i], im[n + i]),
                );
                let p = a * b.conj();
                assert!(a.is_finite() && b.is_finite() && p.is_finite(), "{a} {b}");
                assert!(a.norm() <= 1e3 * (0.25 * u.length_squared()).exp(), "{a}");
            }
        }
    }
}
