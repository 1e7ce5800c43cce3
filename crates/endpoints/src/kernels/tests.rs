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

/// The kernels dispatched at run time to the CPU's vector instructions give bitwise the
/// values of the same loops compiled for the baseline instruction set (what a portable build
/// without dispatch ran).
#[test]
fn dispatched_kernels_are_bitwise_the_baseline_loops() {
    let b = Aabb::new(DVec3::new(-3.0, 1.0, -0.5), DVec3::new(5.0, 2.5, 4.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.7, 0.2).unwrap();
    let g = BoxMedium::of(&m).unwrap();
    let (src, sen) = endpoints(&b, false);
    let mut next = uniform(3);
    let mut checked = 0;
    for set in [
        Endpoints::sources(&m, 300.0, &src),
        Endpoints::sensors(&m, 300.0, &sen),
    ] {
        let sign = match set.side {
            Side::Source => -1.0,
            Side::Sensor => 1.0,
        };
        for _ in 0..50 {
            let x = m.bounds().lerp([next(), next(), next()]);
            for run in &set.runs {
                let n = run.len;
                let mut a = vec![vec![0.0; n]; 5];
                let mut b = vec![vec![0.0; n]; 5];
                let (ok_a, ok_b) = match &run.kind {
                    RunKind::Plane(f) => {
                        let [ar, ai, ..] = &mut a[..] else {
                            unreachable!()
                        };
                        let [br, bi, ..] = &mut b[..] else {
                            unreachable!()
                        };
                        (f.connect(&g, x, ar, ai), f.connect_lanes(&g, x, br, bi))
                    }
                    RunKind::Point(p) => {
                        let [ar, ai, ax, ay, az] = &mut a[..] else {
                            unreachable!()
                        };
                        let [br, bi, bx, by, bz] = &mut b[..] else {
                            unreachable!()
                        };
                        (
                            p.connect::<true>(&g, 300.0, sign, x, ar, ai, [ax, ay, az]),
                            p.connect_lanes::<true>(&g, 300.0, sign, x, br, bi, [bx, by, bz]),
                        )
                    }
                    RunKind::Gaussian => continue,
                };
                assert_eq!(ok_a, ok_b);
                for (va, vb) in a.iter().zip(&b) {
                    for (x, y) in va.iter().zip(vb) {
                        assert_eq!(x.to_bits(), y.to_bits());
                    }
                }
                checked += n;
            }
        }
    }
    assert_eq!(checked, 2 * 50 * 60);
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
    let m =
        HomogeneousBox::new(Aabb::centered(DVec3::ZERO, DVec3::ONE).unwrap(), 1.0, 0.0).unwrap();
    let s = [Sensor::far_field(DVec3::Z).unwrap()];
    let (a, b) = (
        Endpoints::sensors(&m, 1.0, &s),
        Endpoints::sensors(&m, 1.0, &s),
    );
    let mut legs = a.legs();
    b.connect(DVec3::ZERO, &mut legs);
}

/// Gaussian connections in the narrow-aperture limit (`gamma = 1e7`): a beam is the plane
/// wave along its axis times the focal phase `e^(-i k a . f)`, a Gaussian sensor the
/// far-field sensor along its viewing axis times `e^(i k a_v . v)`; so `scatter` and
/// `single` equal the plane-wave and far-field values times those phases, with the
/// attenuation along the axis, for an isotropic and a lobed amplitude, in 3D and flatland
/// (error of order `k^2 |x - f|^2 / gamma`); and the media without box kernels agree.
#[test]
fn narrow_gaussian_connections_are_plane_waves_times_focal_phases() {
    use crate::GaussianBeam;
    use speckle_phase::{Phase, PhaseFunction};
    let k = 5.0;
    let lobed = speckle_vmf::VmfMixture::new(vec![(0.0, 0.3), (6.0, 1.0), (-1.5, 0.2)]).unwrap();
    let b3 = Aabb::new(DVec3::new(-2.0, -1.5, -1.0), DVec3::new(2.0, 1.0, 1.5)).unwrap();
    let b2 = Aabb::flat(glam::DVec2::new(-2.0, -1.0), glam::DVec2::new(2.0, 1.5)).unwrap();
    let cases = [
        (
            b3,
            false,
            Phase::Isotropic,
            DVec3::new(0.3, -0.2, 0.9).normalize(),
        ),
        (
            b3,
            false,
            Phase::Vmf(std::sync::Arc::new(lobed)),
            DVec3::new(-0.1, 0.4, 0.9).normalize(),
        ),
        (b2, true, Phase::FlatIsotropic, DVec3::new(0.6, 0.8, 0.0)),
    ];
    let mut next = uniform(3);
    for (b, flat, phase, a) in cases {
        let m = HomogeneousBox::new(b, 0.6, 0.1).unwrap();
        let f = if flat {
            DVec3::new(0.2, -0.3, 0.0)
        } else {
            DVec3::new(0.2, -0.3, 0.4)
        };
        let a_v = if flat {
            DVec3::new(-0.28, 0.96, 0.0)
        } else {
            DVec3::new(0.5, 0.1, 0.86).normalize()
        };
        let q = if flat {
            DVec3::new(-0.4, 0.5, 0.0)
        } else {
            DVec3::new(-0.4, 0.5, 0.1)
        };
        let g = 1e7;
        let src = [
            Source::GaussianBeam(GaussianBeam::new("s", f, a, g).unwrap()),
            Source::plane_wave(a).unwrap(),
        ];
        let sen = [
            Sensor::GaussianBeam(GaussianBeam::new("v", q, a_v, g).unwrap()),
            Sensor::far_field(a_v).unwrap(),
        ];
        let (es, ev) = (
            Endpoints::sources(&m, k, &src),
            Endpoints::sensors(&m, k, &sen),
        );
        let (mut ls, mut lv) = (es.legs(), ev.legs());
        let focal_s = Complex64::from_polar(1.0, -k * a.dot(f));
        let focal_v = Complex64::from_polar(1.0, k * a_v.dot(q));
        let mut worst = 0.0f64;
        for _ in 0..50 {
            let x = m.bounds().lerp([next(), next(), next()]);
            let w = unit_vector(&mut next, flat);
            es.connect(x, &mut ls);
            ev.connect(x, &mut lv);
            let (mut r, mut i) = ([0.0; 2], [0.0; 2]);
            es.scatter(&ls, &phase, |d| (d, w), &mut r, &mut i);
            let got = Complex64::new(r[0], i[0]);
            let want = Complex64::new(r[1], i[1]) * focal_s;
            worst = worst.max((got - want).norm() / want.norm().max(1e-3));
            ev.scatter(&lv, &phase, |d| (w, d), &mut r, &mut i);
            let got = Complex64::new(r[0], i[0]);
            let want = Complex64::new(r[1], i[1]) * focal_v;
            worst = worst.max((got - want).norm() / want.norm().max(1e-3));
            let plain = es.single(&ls, 1, &ev, &lv, 1, &phase);
            for (s, v, phase_factor) in
                [(0, 0, focal_s * focal_v), (0, 1, focal_s), (1, 0, focal_v)]
            {
                let got = es.single(&ls, s, &ev, &lv, v, &phase);
                let want = plain * phase_factor;
                worst = worst.max((got - want).norm() / want.norm().max(1e-3));
            }
        }
        eprintln!(
            "flat {flat}, g = {:.2}: worst relative deviation {worst:.2e}",
            phase.mean_cosine()
        );
        assert!(worst < 1e-4, "{worst:e}");
        // A grid of one material in 3D takes the medium's own optical depths (scalar route).
        if !flat {
            use speckle_medium::Material;
            let grid = VoxelGrid::from_materials(
                b,
                [2, 1, 1],
                vec![0, 1],
                vec![Material::single(0.6, 0.1), Material::single(1.0, 0.4)],
            )
            .unwrap();
            assert!(BoxMedium::of(&grid).is_none());
            let es = Endpoints::sources(&grid, k, &src);
            let mut ls = es.legs();
            let x = DVec3::new(0.5, 0.2, 0.3);
            es.connect(x, &mut ls);
            let (mut r, mut i) = ([0.0; 2], [0.0; 2]);
            es.scatter(&ls, &phase, |d| (d, a), &mut r, &mut i);
            let (got, want) = (
                Complex64::new(r[0], i[0]),
                Complex64::new(r[1], i[1]) * focal_s,
            );
            assert!((got - want).norm() < 1e-4 * want.norm(), "{got} {want}");
        }
    }
}

/// Every pair's single scattering at once (`single_pairs`: one batch, the two-beam
/// convolutions shared by sensors of one axis, the fields formed once) equals the pair-by-pair
/// values bitwise, for beams with shared and distinct axes mixed with leg endpoints, in 3D and
/// flatland, with an isotropic lobe among anisotropic ones.
#[test]
fn all_pairs_single_scattering_is_the_pairs_one_by_one() {
    use speckle_phase::Phase;
    use speckle_vmf::VmfMixture;
    let phase = Phase::Vmf(std::sync::Arc::new(
        VmfMixture::new(vec![(0.0, 0.3), (8.0, 1.0), (-1.5, 0.2)]).unwrap(),
    ));
    for flat in [false, true] {
        let b = if flat {
            Aabb::flat(glam::DVec2::splat(-6.0), glam::DVec2::splat(6.0)).unwrap()
        } else {
            Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 6.0)).unwrap()
        };
        let m = HomogeneousBox::from_mean_free_path(b, 5.0, 1.0).unwrap();
        let tilt = if flat {
            DVec3::new(0.3, 1.0, 0.0)
        } else {
            DVec3::new(0.3, 0.0, 1.0)
        };
        let up = if flat { DVec3::Y } else { DVec3::Z };
        let beam =
            |f: DVec3, a: DVec3| crate::GaussianBeam::new("b", f, a.normalize(), 9.0).unwrap();
        let sources = vec![
            Source::GaussianBeam(beam(DVec3::new(1.0, -3.0, 0.0), up)),
            Source::plane_wave(up).unwrap(),
            Source::GaussianBeam(beam(DVec3::new(-1.0, -2.0, 0.0), tilt)),
        ];
        let sensors = vec![
            Sensor::GaussianBeam(beam(DVec3::new(0.0, 3.0, 0.0), up)),
            Sensor::GaussianBeam(beam(DVec3::new(1.5, 3.0, 0.0), up)),
            Sensor::far_field(tilt.normalize()).unwrap(),
            Sensor::GaussianBeam(beam(DVec3::new(-1.0, 2.0, 0.0), tilt)),
        ];
        let (src, sen) = (
            Endpoints::sources(&m, 6.0, &sources),
            Endpoints::sensors(&m, 6.0, &sensors),
        );
        let (mut ls, mut lv) = (src.legs(), sen.legs());
        let mut scratch = crate::SingleScratch::default();
        let mut next = uniform(17);
        for _ in 0..40 {
            let x = m.bounds().lerp([next(), next(), next()]);
            src.connect(x, &mut ls);
            sen.connect(x, &mut lv);
            let pairs = (0..12).map(|i| (i, i / 4, i % 4));
            src.single_pairs(&ls, &sen, &lv, &phase, 12, pairs, &mut scratch);
            for (i, got) in scratch.values().iter().enumerate() {
                let want = src.single(&ls, i / 4, &sen, &lv, i % 4, &phase);
                assert!(want.norm() > 0.0);
                assert_eq!(
                    (got.re.to_bits(), got.im.to_bits()),
                    (want.re.to_bits(), want.im.to_bits()),
                    "pair {i} at {x}: {got} against {want}"
                );
            }
        }
    }
}

/// `scatter_many` at several points gives bitwise `scatter` point by point, for a set mixing
/// Gaussian beams with leg endpoints, sources and sensors, 3D and flatland.
#[test]
fn scattering_at_many_points_is_scattering_at_each() {
    use speckle_phase::Phase;
    use speckle_vmf::VmfMixture;
    let phase = Phase::Vmf(std::sync::Arc::new(
        VmfMixture::new(vec![(0.0, 0.3), (8.0, 1.0), (-1.5, 0.2)]).unwrap(),
    ));
    for flat in [false, true] {
        let b = if flat {
            Aabb::flat(glam::DVec2::splat(-6.0), glam::DVec2::splat(6.0)).unwrap()
        } else {
            Aabb::centered(DVec3::ZERO, DVec3::new(12.0, 12.0, 6.0)).unwrap()
        };
        let m = HomogeneousBox::from_mean_free_path(b, 5.0, 1.0).unwrap();
        let up = if flat { DVec3::Y } else { DVec3::Z };
        let beam = |f: DVec3| crate::GaussianBeam::new("b", f, up, 9.0).unwrap();
        let sources = vec![
            Source::GaussianBeam(beam(DVec3::new(1.0, -3.0, 0.0))),
            Source::plane_wave(up).unwrap(),
            Source::GaussianBeam(beam(DVec3::new(-1.0, -2.0, 0.0))),
        ];
        let sensors = vec![
            Sensor::far_field(up).unwrap(),
            Sensor::GaussianBeam(beam(DVec3::new(0.0, 3.0, 0.0))),
        ];
        let mut next = uniform(23);
        for set in [
            Endpoints::sources(&m, 6.0, &sources),
            Endpoints::sensors(&m, 6.0, &sensors),
        ] {
            let n = set.len();
            let w = unit_vector(&mut next, flat);
            let dirs = |d: DVec3| (d, w);
            // Seven points (a partly filled last chunk of integrals).
            let legs: Vec<Legs> = (0..7)
                .map(|_| {
                    let mut l = set.legs();
                    set.connect(m.bounds().lerp([next(), next(), next()]), &mut l);
                    l
                })
                .collect();
            let mut many = vec![(vec![0.0; n], vec![0.0; n]); legs.len()];
            let refs: Vec<&Legs> = legs.iter().collect();
            let mut outs: Vec<(&mut [f64], &mut [f64])> = many
                .iter_mut()
                .map(|(re, im)| (&mut re[..], &mut im[..]))
                .collect();
            set.scatter_many(&refs, &phase, dirs, &mut outs);
            for (l, (re, im)) in legs.iter().zip(&many) {
                let (mut r, mut i) = (vec![0.0; n], vec![0.0; n]);
                set.scatter(l, &phase, dirs, &mut r, &mut i);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!((bits(re), bits(im)), (bits(&r), bits(&i)));
                assert!(r.iter().all(|x| *x != 0.0));
            }
        }
    }
}

/// `drift_rates`: where it gives a leg a rate, the leg along the segment is its leg at the
/// centre times `exp(beta s)` (the scalar legs of the medium, to rounding); where it gives
/// none, the leg changes exit face along the segment and the exponential would be wrong (the
/// test sees both cases), and `drift_log_ratio` gives it point by point. Point endpoints and
/// voxel media of varying extinction are refused.
#[test]
fn drift_rates_give_the_legs_along_a_line() {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(8.0, 6.0, 4.0)).unwrap();
    let m = HomogeneousBox::from_mean_free_path(b, 1.5, 1.0).unwrap();
    let k = 7.0;
    let mut next = uniform(23);
    let sources: Vec<Source> = (0..6)
        .map(|_| Source::plane_wave(unit_vector(&mut next, false)).unwrap())
        .collect();
    let sensors: Vec<Sensor> = (0..6)
        .map(|_| Sensor::far_field(unit_vector(&mut next, false)).unwrap())
        .collect();
    let (src, sen) = (
        Endpoints::sources(&m, k, &sources),
        Endpoints::sensors(&m, k, &sensors),
    );
    assert!(src.directional_in_box() && sen.directional_in_box());
    let (mut exponential, mut bent_wrong, mut segments) = (0, 0, 0);
    let mut rates = vec![None; 6];
    for _ in 0..400 {
        let x = b.lerp([next(), next(), next()]);
        let u = unit_vector(&mut next, false) * (0.5 + next());
        let reach = 1.5 * next();
        let source_leg = |x: DVec3, i: usize| sources[i].leg(&m, k, x).amp;
        let sensor_leg = |x: DVec3, i: usize| sensors[i].leg(&m, k, x).amp;
        type LegOf<'a> = &'a dyn Fn(DVec3, usize) -> Complex64;
        let sides: [(&Endpoints<_>, LegOf); 2] = [(&src, &source_leg), (&sen, &sensor_leg)];
        for (set, legs_of) in sides {
            if !set.drift_rates(x, u, reach, &mut rates) {
                // Only segments that leave the box are refused.
                assert!(!(b.contains(x - reach * u) && b.contains(x + reach * u)));
                continue;
            }
            segments += 1;
            for (i, rate) in rates.iter().enumerate() {
                // The centre's rate of the modulus (one-sided difference) where there is none.
                let h = 1e-6;
                let r = (legs_of(x + h * u, i).norm() / legs_of(x, i).norm()).ln() / h;
                let mut miss = 0.0f64;
                for n in 0..=10 {
                    let s = reach * (n as f64 / 5.0 - 1.0);
                    let want = legs_of(x + s * u, i);
                    let tol = 1e-12 * (1.0 + (k * s * u.length()).abs()) * want.norm();
                    let ratio = set.drift_log_ratio(i, x, u, s).unwrap().exp();
                    let point = legs_of(x, i) * ratio;
                    assert!(
                        (point - want).norm() <= tol,
                        "leg {i} at s = {s}: {point} vs {want}"
                    );
                    match rate {
                        Some(beta) => {
                            let got = legs_of(x, i) * (beta * s).exp();
                            assert!(
                                (got - want).norm() <= tol,
                                "leg {i} at s = {s}: {got} vs {want}"
                            );
                        }
                        None => {
                            let got = legs_of(x, i).norm() * (r * s).exp();
                            miss = miss.max((got - want.norm()).abs() / want.norm());
                        }
                    }
                }
                match rate {
                    Some(_) => exponential += 1,
                    None if miss > 1e-6 => bent_wrong += 1,
                    None => {}
                }
            }
        }
    }
    assert!(
        segments > 150 && exponential > 1000 && bent_wrong > 50,
        "{segments} {exponential} {bent_wrong}"
    );
    // Other kinds and media are refused.
    let point = [Sensor::point(DVec3::new(0.0, 0.0, 3.0))];
    let p = Endpoints::sensors(&m, k, &point);
    assert!(!p.directional_in_box());
    assert!(!p.drift_rates(DVec3::ZERO, DVec3::X, 0.1, &mut rates));
    use speckle_medium::Material;
    let mats = vec![Material::single(0.5, 0.5), Material::single(2.0, 0.0)];
    let v = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
    let f = Endpoints::sources(&v, k, &sources);
    assert!(!f.directional_in_box());
    assert!(!f.drift_rates(DVec3::ZERO, DVec3::X, 0.1, &mut rates));
    assert!(f.drift_log_ratio(0, DVec3::ZERO, DVec3::X, 0.1).is_none());
}
