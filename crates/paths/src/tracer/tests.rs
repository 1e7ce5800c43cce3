//! Unit tests of the tracer.

use super::*;
use speckle_medium::{Aabb, HomogeneousBox};
use speckle_phase::Phase;

struct Count {
    single: f64,
    vertices: Vec<f64>,
}
impl VertexSink for Count {
    fn first(&mut self, _x1: DVec3, _ty: usize, weight: f64, _rng: &mut PathRng) {
        self.single += weight;
    }
    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        let i = v.index as usize - 2;
        if self.vertices.len() <= i {
            self.vertices.resize(i + 1, 0.0);
        }
        self.vertices[i] += v.weight;
    }
}

#[test]
fn weights_match_the_scattering_volume() {
    // The mean single-scattering weight is V = sigma_s |box|; a second vertex occurs with
    // probability P2 (flight stays inside, survives roulette), and the weight there is 4 pi V.
    let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 3.0, 4.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.5, 0.25).unwrap();
    let t = Tracer::new(&m, &Phase::Isotropic, TracerConfig::default()).unwrap();
    let mut c = Count {
        single: 0.0,
        vertices: vec![],
    };
    let n = 20_000;
    for i in 0..n {
        t.trace(&mut PathRng::new(5, i), &mut c);
    }
    let v = 0.5 * 24.0;
    assert!((c.single / n as f64 - v).abs() < 1e-9 * v);
    let w2 = c.vertices[0] / n as f64 / (4.0 * std::f64::consts::PI * v);
    // Survival to x2 is at most the albedo 2/3.
    assert!(w2 > 0.1 && w2 < 2.0 / 3.0, "{w2}");
}

#[test]
fn a_camera_mixture_weighs_first_vertices_by_its_density() {
    // E[sigma_s / p(x1)] = sigma_s |box| for any density p that covers the box. Past the
    // beam cap (a line camera of 18 pixels and two sources) the density must be the one
    // sampled: shares by kind (a third each for the volume, the sources' beams and the
    // pixels'), positions for the pixels, directions for the sources. Writing the volume's
    // share as 1 / (n + 1) in the density, as below the cap, moves the mean by a factor of
    // several, and a beam density 10% high by 5 SE.
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(10.0, 10.0, 3.0)).unwrap();
    let sigma_s = 1.0 / 3.0;
    let m = HomogeneousBox::new(b, sigma_s, 0.0).unwrap();
    let beam = |x: f64, z: f64, axis: DVec3| Beam {
        focus: DVec3::new(x, 0.0, z),
        axis,
        concentration: 16.0,
    };
    let sources = [beam(0.0, -1.5, DVec3::Z), beam(1.0, -1.5, DVec3::Z)];
    let camera: Vec<Beam> = (0..18)
        .map(|i| beam(0.2 * i as f64 - 1.0, 1.5, -DVec3::Z))
        .collect();
    let cfg = TracerConfig {
        beams: BeamStrategy::PositionAndDirection,
        ..TracerConfig::default()
    };
    let t = Tracer::new(&m, &Phase::Isotropic, cfg)
        .unwrap()
        .with_endpoints(&[], &sources, &camera, std::f64::consts::TAU, true);
    let p = t.points.as_ref().unwrap();
    assert_eq!((p.volume, p.groups.len()), (1.0 / 3.0, 2));
    struct Moments(f64, f64);
    impl VertexSink for Moments {
        fn first(&mut self, _x1: DVec3, _ty: usize, w: f64, _rng: &mut PathRng) {
            self.0 += w;
            self.1 += w * w;
        }
        fn vertex(&mut self, _v: &Vertex, _rng: &mut PathRng) {}
    }
    let mut s = Moments(0.0, 0.0);
    let n = 100_000;
    for i in 0..n {
        t.trace(&mut PathRng::new(9, i), &mut s);
    }
    let n = n as f64;
    let mean = s.0 / n;
    let se = ((s.1 / n - mean * mean) / n).sqrt();
    let v = sigma_s * 300.0;
    assert!(se < 0.01 * v, "unresolved: {mean} +- {se}");
    assert!((mean - v).abs() < 4.5 * se, "{mean} +- {se} against {v}");
}

#[test]
fn flatland_paths_stay_in_the_plane_with_circle_weights() {
    // V = sigma_s * area; the weight at x2 and beyond is 2 pi V (uniform first angle).
    struct InPlane(u64, f64);
    impl VertexSink for InPlane {
        fn first(&mut self, x1: DVec3, _ty: usize, _w: f64, _rng: &mut PathRng) {
            assert_eq!(x1.z, 0.0);
        }
        fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
            assert!(v.x.z == 0.0 && v.w_in.z == 0.0 && v.w12.z == 0.0);
            self.0 += 1;
            self.1 = v.weight;
        }
    }
    let b = Aabb::flat(glam::DVec2::ZERO, glam::DVec2::new(2.0, 3.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.5, 0.0).unwrap();
    for p in [Phase::FlatIsotropic, Phase::flat_hg(0.6).unwrap()] {
        let t = Tracer::new(&m, &p, TracerConfig::default()).unwrap();
        let mut sink = InPlane(0, 0.0);
        for i in 0..2000 {
            t.trace(&mut PathRng::new(3, i), &mut sink);
        }
        assert!(sink.0 > 100);
        let expect = 2.0 * std::f64::consts::PI * 0.5 * 6.0;
        assert!((sink.1 - expect).abs() < 1e-12 * expect);
    }
    // A 3D phase function in a flatland medium, and the reverse, are refused.
    let e = Tracer::new(&m, &Phase::Isotropic, TracerConfig::default()).unwrap_err();
    assert!(matches!(e, PathError::DimensionMismatch { .. }), "{e}");
    let m3 = HomogeneousBox::new(Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap(), 1.0, 0.0).unwrap();
    assert!(Tracer::new(&m3, &Phase::FlatIsotropic, TracerConfig::default()).is_err());
    // Out-of-plane strategy directions are refused.
    let cfg = TracerConfig {
        first_direction: FirstDirection::Phase { axis: DVec3::Z },
        ..TracerConfig::default()
    };
    let e = Tracer::new(&m, &Phase::FlatIsotropic, cfg).unwrap_err();
    assert!(matches!(e, PathError::NotInPlane { .. }), "{e}");
}

#[test]
fn point_components_are_kept_for_points_in_the_medium_beyond_the_cap() {
    let b = Aabb::new(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
    let m = HomogeneousBox::new(b, 1.0, 0.0).unwrap();
    let t = || Tracer::new(&m, &Phase::Isotropic, TracerConfig::default()).unwrap();
    // A camera grid half an extinction length above the box: components up to the cap.
    let grid: Vec<DVec3> = (0..MAX_OUTSIDE_COMPONENTS + 1)
        .map(|i| DVec3::new(0.05 * i as f64, 1.0, 2.5))
        .collect();
    let few = t().with_point_endpoints(&grid[..MAX_OUTSIDE_COMPONENTS], true);
    assert_eq!(
        few.points.as_ref().unwrap().points.len(),
        MAX_OUTSIDE_COMPONENTS
    );
    assert!(!t().with_point_endpoints(&grid, true).needs_reversed_paths());
    // Beyond the cap a point on the face keeps its component, and the volume its share.
    let mut with_face = grid.clone();
    with_face.push(DVec3::new(1.0, 1.0, 2.0));
    let p = t().with_point_endpoints(&with_face, false).points.unwrap();
    assert_eq!(p.points, vec![DVec3::new(1.0, 1.0, 2.0)]);
    assert!(p.volume > 0.0);
    // Points alone, all near: no volume share; a far point restores it.
    let alone = t().with_point_endpoints(&grid[..2], false).points.unwrap();
    assert_eq!(alone.volume, 0.0);
    let far = [grid[0], DVec3::new(0.0, 0.0, 9.0)];
    assert_eq!(
        t().with_point_endpoints(&far, false).points.unwrap().volume,
        0.5
    );
}

#[test]
fn beam_components_are_distinct_capped_and_need_no_reversed_paths() {
    let b = Aabb::new(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
    let m = HomogeneousBox::new(b, 1.0, 0.0).unwrap();
    let t = |beams| {
        let cfg = TracerConfig {
            beams,
            ..TracerConfig::default()
        };
        Tracer::new(&m, &Phase::Isotropic, cfg).unwrap()
    };
    let beam = |x: f64| Beam {
        focus: DVec3::new(x, 2.0, 0.0),
        axis: DVec3::Z,
        concentration: 16.0,
    };
    let k = std::f64::consts::TAU;
    // A source and a sensor with the same source form count once; the volume keeps 1/(n+1).
    let one = t(BeamStrategy::Position).with_endpoints(&[], &[beam(1.0)], &[beam(1.0)], k, false);
    assert!(!one.needs_reversed_paths());
    let p = one.points.as_ref().unwrap();
    assert_eq!((p.beams.len(), p.volume), (1, 0.5));
    // Off: no mixture at all (the tracer is the plain one).
    let off = t(BeamStrategy::Off).with_endpoints(&[], &[beam(1.0)], &[], k, true);
    assert!(off.points.is_none());
    // Which beams sample directions (the isotropic phase function has one lobe).
    let directed = |t: &Tracer<_, _>| {
        let p = t.points.as_ref().unwrap();
        let d = p.beams.iter().filter(|b| b.samples_directions()).count();
        (p.beams.len(), d)
    };
    // A camera of sensors beyond the cap: every beam a position component, the sources'
    // also sampling directions.
    let camera: Vec<Beam> = (0..MAX_BEAM_COMPONENTS)
        .map(|i| beam(0.1 * i as f64))
        .collect();
    let src = [beam(3.0), beam(3.5)];
    let capped = t(BeamStrategy::PositionAndDirection).with_endpoints(&[], &src, &camera, k, true);
    assert_eq!(directed(&capped), (MAX_BEAM_COMPONENTS + 2, 2));
    // Shares by kind: the volume, the sources' beams, the camera's.
    let p = capped.points.as_ref().unwrap();
    let third = 1.0 / 3.0;
    assert_eq!(p.volume, third);
    assert_eq!(p.groups, [(2, third), (MAX_BEAM_COMPONENTS + 2, third)]);
    let kept = t(BeamStrategy::PositionAndDirection).with_endpoints(
        &[],
        &src,
        &camera[..MAX_BEAM_COMPONENTS - 2],
        k,
        true,
    );
    assert_eq!(directed(&kept), (MAX_BEAM_COMPONENTS, MAX_BEAM_COMPONENTS));
    let volume = kept.points.as_ref().unwrap().volume;
    assert_eq!(volume, 1.0 / (MAX_BEAM_COMPONENTS + 1) as f64);
    // More sources than the cap: positions only.
    let many_sources = [&camera[..], &src[..1]].concat();
    let many =
        t(BeamStrategy::PositionAndDirection).with_endpoints(&[], &many_sources, &[], k, true);
    assert_eq!(directed(&many), (MAX_BEAM_COMPONENTS + 1, 0));
    // Past the position cap: the sources' beams alone, and none past it in sources.
    let huge: Vec<Beam> = (0..=MAX_POSITION_BEAMS)
        .map(|i| beam(1e-3 * i as f64))
        .collect();
    let big = t(BeamStrategy::PositionAndDirection).with_endpoints(&[], &src, &huge, k, true);
    assert_eq!(directed(&big), (2, 2));
    let none = t(BeamStrategy::Position).with_endpoints(&[], &huge, &[], k, true);
    assert!(none.points.is_none());
}

#[test]
fn rejects_bad_configuration() {
    let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
    let m = HomogeneousBox::new(b, 1.0, 0.0).unwrap();
    let p = Phase::Isotropic;
    let cfg = |fv, fd, n| TracerConfig {
        first_vertex: fv,
        first_direction: fd,
        beams: BeamStrategy::Off,
        max_vertices: n,
    };
    use FirstDirection as D;
    use FirstVertex as V;
    assert!(Tracer::new(&m, &p, cfg(V::Uniform, D::Uniform, 0)).is_err());
    let bad = DVec3::new(f64::NAN, 0.0, 1.0);
    assert!(
        Tracer::new(
            &m,
            &p,
            cfg(V::ExponentialDepth { direction: bad }, D::Uniform, 9)
        )
        .is_err()
    );
    assert!(Tracer::new(&m, &p, cfg(V::Uniform, D::Phase { axis: DVec3::ZERO }, 9)).is_err());
}

/// The point components after de-duplication are those of the former linear scan (the first of
/// each group of points equal by `==`, in order; -0 equal to +0; a NaN point never equal),
/// bitwise, for a small list with repeats; and a grid of 10^5 points, given twice, keeps each
/// once (a linear scan per point took seconds there, and minutes for 10^6 points).
#[test]
fn equal_points_get_one_component_each_as_by_a_linear_scan() {
    let b = Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.5, 0.1).unwrap();
    let t = || Tracer::new(&m, &Phase::Isotropic, TracerConfig::default()).unwrap();
    let p = |x: f64, y: f64, z: f64| DVec3::new(x, y, z);
    let list = [
        p(0.5, 0.0, 0.0),
        p(0.5, -0.0, 0.0),
        p(-1.0, 1.0, 0.5),
        p(0.5, 0.0, -0.0),
        p(f64::NAN, 0.0, 0.0),
        p(f64::NAN, 0.0, 0.0),
        p(-1.0, 1.0, 0.5),
        p(0.0, 0.0, 1.0),
        p(1.0, 1.0, 1.0),
        p(0.0, 0.0, 1.0),
    ];
    let mut linear: Vec<DVec3> = vec![];
    for q in list {
        if !linear.contains(&q) {
            linear.push(q);
        }
    }
    let bits = |v: &[DVec3]| -> Vec<[u64; 3]> {
        v.iter().map(|q| q.to_array().map(f64::to_bits)).collect()
    };
    let got = t().with_point_endpoints(&list, true).points.unwrap().points;
    assert_eq!(linear.len(), 6);
    assert_eq!(bits(&got), bits(&linear));
    // A 316 x 316 grid in the medium, twice.
    let grid: Vec<DVec3> = (0..316 * 316)
        .map(|i| {
            p(
                -1.5 + 0.01 * (i % 316) as f64,
                -1.5 + 0.01 * (i / 316) as f64,
                0.5,
            )
        })
        .collect();
    let twice = [&grid[..], &grid[..]].concat();
    let got = t()
        .with_point_endpoints(&twice, true)
        .points
        .unwrap()
        .points;
    assert_eq!(bits(&got), bits(&grid));
}

#[test]
fn point_components_sample_first_directions_about_their_rays() {
    // E[f(w12) sigma_s(x1) / q(x1, w12)] over first vertices and directions (zero where no
    // path starts) is sigma_s |box| int f dw for the joint density q sampled, here with
    // f = (1 + w . e)^2 (16 pi / 3 over the sphere, 3 pi over the circle). With g = 0.9 the
    // point components draw w12 from the phase function about the ray from their point:
    // evaluating the density as the uniform one instead moves the mean by 58 SE, about the
    // reversed ray by a factor of 20. (Backward directions, rarely drawn, carry large weights:
    // the standard error is 3% of the mean at 400 000 samples.) 3D and flatland, a point inside the box
    // and one on a face, with and without the volume's share; an isotropic phase function
    // keeps the configured direction strategy (no point directions).
    let cases = [
        (
            Aabb::new(DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, 1.0, 2.0)).unwrap(),
            vec![DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 0.5, 1.0)],
            Phase::hg(0.9).unwrap(),
            16.0 * std::f64::consts::PI / 3.0,
        ),
        (
            Aabb::flat(glam::DVec2::new(-1.0, 0.0), glam::DVec2::new(1.0, 2.0)).unwrap(),
            vec![DVec3::new(0.3, 0.0, 0.0), DVec3::new(-0.2, 1.0, 0.0)],
            Phase::flat_hg(0.9).unwrap(),
            3.0 * std::f64::consts::PI,
        ),
    ];
    let e = DVec3::new(0.6, 0.8, 0.0);
    for (b, points, phase, sphere) in cases {
        let sigma_s = 1.5;
        let m = HomogeneousBox::new(b, sigma_s, 0.1).unwrap();
        for others in [false, true] {
            let t = Tracer::new(&m, &phase, TracerConfig::default())
                .unwrap()
                .with_point_endpoints(&points, others);
            assert!(t.points.as_ref().unwrap().point_directions);
            let n = 400_000;
            let (mut acc, mut acc2) = (0.0, 0.0);
            for i in 0..n {
                let mut rng = PathRng::new(17, i);
                let Some((x1, ty, w1, from)) = t.sample_first(&mut rng) else {
                    continue;
                };
                if let Some((w12, w)) = t.sample_first_direction(x1, ty, w1, from, &mut rng) {
                    let w = w * (1.0 + w12.dot(e)).powi(2);
                    acc += w;
                    acc2 += w * w;
                }
            }
            let n = n as f64;
            let mean = acc / n;
            let se = ((acc2 / n - mean * mean) / n).sqrt();
            let expected = sigma_s * b.measure() * sphere;
            assert!(se < 0.04 * expected, "unresolved: {mean} +- {se}");
            assert!(
                (mean - expected).abs() < 4.5 * se,
                "{} others {others}: {mean} +- {se} against {expected}",
                phase.dimension()
            );
        }
    }
    let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
    let m = HomogeneousBox::new(b, 1.0, 0.0).unwrap();
    let t = Tracer::new(&m, &Phase::Isotropic, TracerConfig::default())
        .unwrap()
        .with_point_endpoints(&[DVec3::splat(0.5)], false);
    assert!(!t.points.unwrap().point_directions);
}

/// Sums, per path length, `both_orders * weight * (h(x1, x_B) + h(x_B, x1))` over the vertices
/// (and branches, when it takes them) of the sub-paths handed to it.
struct Techniques {
    branches: bool,
    h: fn(DVec3, DVec3) -> f64,
    x1: DVec3,
    sums: [f64; 4],
    squares: [f64; 4],
    path: [f64; 4],
}

impl Techniques {
    fn add(&mut self, v: &Vertex) {
        let i = (v.index as usize).min(4) - 1;
        let x = v.both_orders * v.weight * ((self.h)(self.x1, v.x) + (self.h)(v.x, self.x1));
        self.path[i] += x;
    }
    fn end_path(&mut self) {
        for i in 0..4 {
            self.sums[i] += self.path[i];
            self.squares[i] += self.path[i] * self.path[i];
            self.path[i] = 0.0;
        }
    }
}

impl VertexSink for Techniques {
    fn first(&mut self, x1: DVec3, _ty: usize, weight: f64, _rng: &mut PathRng) {
        self.x1 = x1;
        self.path[0] += weight * 2.0 * (self.h)(x1, x1);
    }
    fn vertex(&mut self, v: &Vertex, _rng: &mut PathRng) {
        self.add(v);
    }
    fn branches(&self) -> bool {
        self.branches
    }
    fn branch(&mut self, v: &Vertex, _rng: &mut PathRng) {
        self.add(v);
    }
}

#[test]
fn branches_and_sub_paths_share_each_path_by_the_balance_heuristic() {
    // Every technique estimates the same sums over paths of 2, 3 and 4+ vertices of
    // `h(x1, x_B) + h(x_B, x1)` times the throughput, with or without branches, when the
    // weights of a path's techniques sum to one. `h` peaks at a point inside the box (first
    // vertex) and at one on a face (last vertex), where the branches' share is largest: leaving
    // out the reversed branch (`R_cr`) or the forward one (`R_c`) from the heuristic moves the
    // sums by 10-50 SE. HG g = 0.5 with the points sampling directions, and isotropic.
    let b = Aabb::new(DVec3::new(-2.0, -2.0, 0.0), DVec3::new(2.0, 2.0, 2.0)).unwrap();
    let m = HomogeneousBox::new(b, 0.8, 0.2).unwrap();
    let points = [DVec3::new(0.3, 0.2, 0.8), DVec3::new(-0.4, 0.1, 2.0)];
    fn h(a: DVec3, b: DVec3) -> f64 {
        let p0 = DVec3::new(0.3, 0.2, 0.8);
        let p1 = DVec3::new(-0.4, 0.1, 2.0);
        (-2.0 * (a - p0).length() - 2.0 * (b - p1).length()).exp()
    }
    for phase in [Phase::hg(0.5).unwrap(), Phase::Isotropic] {
        let t = Tracer::new(&m, &phase, TracerConfig::default())
            .unwrap()
            .with_point_endpoints(&points, false);
        let run = |branches: bool| {
            let mut s = Techniques {
                branches,
                h,
                x1: DVec3::ZERO,
                sums: [0.0; 4],
                squares: [0.0; 4],
                path: [0.0; 4],
            };
            let n = 1_000_000;
            for i in 0..n {
                t.trace(&mut PathRng::new(31, i), &mut s);
                s.end_path();
            }
            let n = n as f64;
            let mean = s.sums.map(|x| x / n);
            let se: Vec<f64> = (0..4)
                .map(|i| ((s.squares[i] / n - mean[i] * mean[i]) / n).sqrt())
                .collect();
            (mean, se)
        };
        let ((a, sa), (c, sc)) = (run(false), run(true));
        // Single scattering has one technique: the same paths, bitwise.
        assert_eq!(a[0], c[0]);
        for i in 1..4 {
            let z = (a[i] - c[i]) / sa[i].hypot(sc[i]);
            eprintln!(
                "B = {}: sub-paths {:.5e} +- {:.1e}, with branches {:.5e} +- {:.1e}, z {z:.2}",
                i + 1,
                a[i],
                sa[i],
                c[i],
                sc[i]
            );
            assert!(sc[i] < 0.02 * c[i], "unresolved");
            assert!(z.abs() < 4.5, "B = {}: z {z}", i + 1);
        }
    }
}
