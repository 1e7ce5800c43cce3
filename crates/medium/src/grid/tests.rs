use super::*;
use crate::testing::{
    KS_CRITICAL_0_001, chi_square_bound, chi_square_stat, ks_distance, uniform_stream,
};
use crate::{Dimension, HomogeneousBox};
use glam::DVec2;

fn field_of(e: MediumError) -> (String, String) {
    match e {
        MediumError::InvalidParameter { field, reason } => (field, reason),
        other => panic!("unexpected error {other:?}"),
    }
}

fn point_in(next: &mut impl FnMut() -> f64, lo: DVec3, hi: DVec3) -> DVec3 {
    lo + DVec3::new(next(), next(), next()) * (hi - lo)
}

fn direction(next: &mut impl FnMut() -> f64) -> DVec3 {
    let z = 1.0 - 2.0 * next();
    let phi = std::f64::consts::TAU * next();
    let r = (1.0 - z * z).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

fn flat_direction(next: &mut impl FnMut() -> f64) -> DVec3 {
    let phi = std::f64::consts::TAU * next();
    DVec3::new(phi.cos(), phi.sin(), 0.0)
}

fn test_box() -> Aabb {
    Aabb::new(DVec3::new(-1.0, -2.0, 0.5), DVec3::new(3.0, 1.0, 2.5)).unwrap()
}

/// A 5 x 4 x 3 grid of random coefficients, a quarter of the voxels empty or non-scattering.
fn random_grid(seed: u64) -> VoxelGrid {
    let mut next = uniform_stream(seed);
    let dims = [5, 4, 3];
    let n = 60;
    let materials: Vec<Material> = (0..n)
        .map(|i| match i % 4 {
            0 => Material::vacuum(),
            1 => Material::single(0.0, 2.0 * next()),
            _ => Material::single(2.0 * next(), next()),
        })
        .collect();
    let ids = (0..n as u32).collect();
    VoxelGrid::from_materials(test_box(), dims, ids, materials).unwrap()
}

/// Midpoint rule for `int sigma_t` along `a -> b` with `m` steps, and the bound of its error:
/// the integrand is piecewise constant, so only the steps that straddle a voxel face (at most
/// one per face crossed, `nx + ny + nz + 2` in all with the box faces) are off, by at most
/// `max sigma_t` times a step.
fn brute_depth(g: &VoxelGrid, a: DVec3, b: DVec3, m: usize) -> (f64, f64) {
    let d = b - a;
    let h = d.length() / m as f64;
    let sum: f64 = (0..m)
        .map(|k| g.sigma_t(a + (k as f64 + 0.5) / m as f64 * d))
        .sum();
    let faces = (g.dims().iter().sum::<usize>() + 2) as f64;
    (sum * h, faces * g.majorant() * h + 1e-12)
}

fn escape_and_depths(m: &dyn Medium, x: DVec3, dir: DVec3, n: usize, seed: u64) -> (f64, Vec<f64>) {
    let mut next = uniform_stream(seed);
    let mut depths = Vec::with_capacity(n);
    for _ in 0..n {
        if let Some(d) = m.sample_flight(x, dir, &mut next) {
            depths.push(d);
        }
    }
    ((n - depths.len()) as f64 / n as f64, depths)
}

#[test]
fn constant_grid_matches_homogeneous_box() {
    let b = test_box();
    let (ss, sa) = (0.7, 0.3);
    let h = HomogeneousBox::new(b, ss, sa).unwrap();
    let dens =
        VoxelGrid::from_densities(b, [5, 4, 3], vec![1.0; 60], Material::single(ss, sa), 0.0)
            .unwrap();
    // Two identical materials: exercises the per-voxel material ids.
    let mats = VoxelGrid::from_materials(
        b,
        [5, 4, 3],
        (0..60).map(|i| i % 2).collect(),
        vec![Material::single(ss, sa), Material::single(ss, sa)],
    )
    .unwrap();
    let regular = dens.clone().with_tracking(Tracking::Regular);
    let lo = b.min() - 2.0;
    let hi = b.max() + 2.0;
    let mut next = uniform_stream(1);
    let mut worst: f64 = 0.0;
    for g in [&dens, &mats] {
        assert_eq!(g.uniform_sigma_t(), h.uniform_sigma_t());
        assert!((g.scattering_volume() / h.scattering_volume() - 1.0).abs() < 1e-14);
        for _ in 0..10_000 {
            let (p, q) = (point_in(&mut next, lo, hi), point_in(&mut next, lo, hi));
            let (og, oh) = (g.optical_depth(p, q), h.optical_depth(p, q));
            assert!((og - oh).abs() <= 1e-12 * oh, "{p} {q}: {og} vs {oh}");
            let dir = direction(&mut next);
            let (rg, rh) = (
                g.optical_depth_to_infinity(p, dir),
                h.optical_depth_to_infinity(p, dir),
            );
            assert!((rg - rh).abs() <= 1e-12 * rh, "{p} {dir}: {rg} vs {rh}");
            if oh > 0.0 {
                worst = worst.max((og / oh - 1.0).abs());
            }
            assert_eq!(g.sigma_t(p), h.sigma_t(p));
            assert_eq!(g.sigma_s(p), h.sigma_s(p));
        }
        // Axis-parallel segments on voxel planes (x = 0.6 is a plane, y = -0.5 is one too).
        for (p, q) in [
            (DVec3::new(-3.0, -0.5, 1.0), DVec3::new(5.0, -0.5, 1.0)),
            (DVec3::new(0.6, -0.5, -1.0), DVec3::new(0.6, -0.5, 4.0)),
            (DVec3::new(3.0, 1.0, 2.5), DVec3::new(-1.0, -2.0, 0.5)),
            (DVec3::new(-1.0, -2.0, 0.5), DVec3::new(-1.0, 1.0, 0.5)),
        ] {
            let (og, oh) = (g.optical_depth(p, q), h.optical_depth(p, q));
            assert!((og - oh).abs() <= 1e-12 * oh, "{p} {q}: {og} vs {oh}");
            assert!(oh > 0.0);
        }
    }
    eprintln!("constant grid vs homogeneous: worst relative optical-depth gap {worst:e}");

    // Delta tracking needs no acceptance draw where sigma_t is the majorant: the same stream
    // gives the same flights as the homogeneous box, bitwise.
    let mut pick = uniform_stream(2);
    for i in 0..20_000 {
        let x = b.lerp([pick(), pick(), pick()]);
        let dir = direction(&mut pick);
        let mut s1 = uniform_stream(100 + i);
        let mut s2 = uniform_stream(100 + i);
        assert_eq!(
            dens.sample_flight(x, dir, &mut s1),
            h.sample_flight(x, dir, &mut s2)
        );
        assert_eq!(s1(), s2(), "same number of variates drawn");
    }

    // Escape fraction through the slab along z from the bottom face: exp(-sigma_t L), L = 2.
    let x = DVec3::new(1.0, -0.5, 0.5);
    let n = 200_000;
    let expect = (-(ss + sa) * 2.0f64).exp();
    let se = (expect * (1.0 - expect) / n as f64).sqrt();
    for (name, g) in [("delta", &dens), ("regular", &regular)] {
        let (p, _) = escape_and_depths(g, x, DVec3::Z, n, 3);
        eprintln!(
            "constant grid {name}: escape {p:.5} vs {expect:.5} ({:.2} SE)",
            (p - expect) / se
        );
        assert!((p - expect).abs() < 4.0 * se, "{name}: {p} vs {expect}");
    }
}

/// Optical depth at distance `t` along the two-layer test path, and its total.
fn layered_tau(t: f64, l1: f64, l2: f64, s1: f64, s2: f64) -> f64 {
    s1 * t.min(l1) + s2 * (t - l1).clamp(0.0, l2)
}

#[test]
fn two_layers_exact_depth_and_flight_distribution() {
    // z in [0, 1.5): sigma_t = 0.4; z in [1.5, 3]: sigma_t = 1. Split along x and y too, so
    // that the DDA crosses planes with no change.
    let b = Aabb::new(DVec3::ZERO, DVec3::new(2.0, 2.0, 3.0)).unwrap();
    let dims = [2, 3, 2];
    let ids = (0..12).map(|i| (i % 2) as u32).collect();
    let mats = vec![Material::single(0.25, 0.15), Material::single(0.5, 0.5)];
    let g = VoxelGrid::from_materials(b, dims, ids, mats).unwrap();
    let (s1, s2) = (0.4, 1.0);
    assert_eq!(g.uniform_sigma_t(), None);
    assert_eq!(g.majorant(), 1.0);

    // Exact transmittance along a slanted segment that starts and ends outside.
    let (p, q) = (DVec3::new(0.5, 0.7, -1.0), DVec3::new(1.2, 1.1, 4.0));
    let d = q - p;
    let per_z = d.length() / d.z;
    let exact = (s1 * 1.5 + s2 * 1.5) * per_z;
    let od = g.optical_depth(p, q);
    assert!(
        ((-od).exp() / (-exact).exp() - 1.0).abs() < 1e-12,
        "{od} vs {exact}"
    );
    assert!((g.optical_depth(q, p) - exact).abs() < 1e-12 * exact);
    let r = g.optical_depth_to_infinity(p, d.normalize());
    assert!((r - exact).abs() < 1e-12 * exact);

    // Flights from the bottom face upwards, from the top face downwards and from the inner face.
    let dir = DVec3::new(0.3, -0.2, 1.0).normalize();
    let k = 1.0 / dir.z; // path length per unit of z
    let n = 100_000;
    let cases = [
        (
            "up",
            DVec3::new(1.0, 1.0, 0.0),
            dir,
            (1.5 * k, s1),
            (1.5 * k, s2),
        ),
        (
            "down",
            DVec3::new(1.0, 1.0, 3.0),
            -dir,
            (1.5 * k, s2),
            (1.5 * k, s1),
        ),
        (
            "from the interface",
            DVec3::new(1.0, 1.0, 1.5),
            -dir,
            (1.5 * k, s1),
            (0.0, 0.0),
        ),
    ];
    for tracking in [Tracking::Delta, Tracking::Regular, Tracking::Local] {
        let g = g.clone().with_tracking(tracking);
        for (i, (name, x, dir, (l1, a1), (l2, a2))) in cases.into_iter().enumerate() {
            let total = a1 * l1 + a2 * l2;
            let expect = (-total).exp();
            let (p, depths) = escape_and_depths(&g, x, dir, n, 10 + i as u64);
            let se = (expect * (1.0 - expect) / n as f64).sqrt();
            // First-collision distance given a collision: F(t) = (1 - e^-tau(t)) / (1 - e^-tau).
            let ks = ks_distance(depths, |t| {
                -(-layered_tau(t, l1, l2, a1, a2)).exp_m1() / -(-total).exp_m1()
            });
            eprintln!(
                "two layers {tracking:?} {name}: escape {p:.5} vs {expect:.5} ({:.2} SE), \
                 KS sqrt(n) D = {ks:.3}",
                (p - expect) / se
            );
            assert!(
                (p - expect).abs() < 4.0 * se,
                "{tracking:?} {name}: {p} vs {expect}"
            );
            assert!(ks < KS_CRITICAL_0_001, "{tracking:?} {name}: KS {ks}");
        }
    }
}

#[test]
fn dda_matches_brute_force_on_a_random_grid() {
    let g = random_grid(7);
    let b = test_box();
    let (lo, hi) = (b.min() - 1.0, b.max() + 1.0);
    let mut next = uniform_stream(8);
    let m = 20_000;
    let mut worst: f64 = 0.0;
    for i in 0..400 {
        let p = point_in(&mut next, lo, hi);
        let mut q = point_in(&mut next, lo, hi);
        // Every fourth segment parallel to an axis, and some of those on voxel planes.
        if i % 4 == 0 {
            let a = i / 4 % 3;
            let mut q2 = p;
            q2[a] = q[a];
            if i % 8 == 0 {
                let other = (a + 1) % 3;
                let k = (i / 8) % g.dims()[other];
                q2[other] = g.voxels().plane(other, k);
                let mut p2 = p;
                p2[other] = q2[other];
                let (od, (bf, tol)) = (g.optical_depth(p2, q2), brute_depth(&g, p2, q2, m));
                assert!(
                    (od - bf).abs() <= tol,
                    "{p2} {q2}: {od} vs {bf} (tol {tol})"
                );
            }
            q = q2;
        }
        let od = g.optical_depth(p, q);
        let (bf, tol) = brute_depth(&g, p, q, m);
        assert!((od - bf).abs() <= tol, "{p} {q}: {od} vs {bf} (tol {tol})");
        worst = worst.max((od - bf).abs() / tol);
        // Symmetric, and a ray is a long segment.
        let back = g.optical_depth(q, p);
        // (Plus an absolute 1e-14: a segment that touches the box at one end only gets a
        // rounding-sized length from the clipping, in either direction.)
        assert!(
            (back - od).abs() <= 1e-12 * od + 1e-14,
            "{i} {p} {q}: {od} vs {back}"
        );
        let dir = (q - p).normalize();
        let far = g.optical_depth(p, p + 50.0 * dir);
        assert!((g.optical_depth_to_infinity(p, dir) - far).abs() <= 1e-12 * far + 1e-14);
    }
    eprintln!("DDA vs midpoint rule: worst |gap| / bound = {worst:.3}");
}

#[test]
fn dda_edge_cases() {
    let g = random_grid(9);
    let m = 20_000;
    let check = |p: DVec3, q: DVec3| {
        let od = g.optical_depth(p, q);
        let (bf, tol) = brute_depth(&g, p, q, m);
        assert!((od - bf).abs() <= tol, "{p} {q}: {od} vs {bf} (tol {tol})");
        od
    };
    // Along x through the edge where the planes y = -0.5 and z = 1.1666.. meet.
    let z = g.voxels().plane(2, 1);
    check(DVec3::new(-2.0, -0.5, z), DVec3::new(4.0, -0.5, z));
    // Starting exactly on an inner face, moving down; and moving up.
    let x = g.voxels().plane(0, 2);
    check(DVec3::new(x, 0.3, 1.0), DVec3::new(-1.0, 0.1, 2.0));
    check(DVec3::new(x, 0.3, 1.0), DVec3::new(3.0, 0.1, 2.0));
    // Diagonal through voxel corners.
    check(g.bounds().min(), g.bounds().max());
    check(g.bounds().max(), g.bounds().min());
    // On the box faces.
    check(DVec3::new(-1.0, -2.0, 0.5), DVec3::new(3.0, -2.0, 0.5));
    check(DVec3::new(3.0, 1.0, 0.5), DVec3::new(3.0, 1.0, 2.5));
    // Outside: parallel to a face, beside the box, touching a corner only.
    assert_eq!(
        g.optical_depth(DVec3::new(-2.0, 1.5, 1.0), DVec3::new(5.0, 1.5, 1.0)),
        0.0
    );
    assert_eq!(
        g.optical_depth(DVec3::new(-3.0, 0.0, 1.0), DVec3::new(-2.0, 0.0, 1.0)),
        0.0
    );
    assert_eq!(
        g.optical_depth(DVec3::new(-2.0, -3.0, 0.5), DVec3::new(-1.0, -2.0, 0.5)),
        0.0
    );
    assert_eq!(
        g.optical_depth_to_infinity(DVec3::new(5.0, 0.0, 1.0), DVec3::X),
        0.0
    );
    // A point segment.
    assert_eq!(g.optical_depth(DVec3::ONE, DVec3::ONE), 0.0);
    // The ray from inside along -y exits through the face y = -2.
    let p = DVec3::new(0.1, 0.9, 2.0);
    let r = g.optical_depth_to_infinity(p, -DVec3::Y);
    let (bf, tol) = brute_depth(&g, p, DVec3::new(0.1, -2.0, 2.0), m);
    assert!((r - bf).abs() <= tol);
}

#[test]
fn scatterers_follow_sigma_s() {
    let g = random_grid(11);
    let total: f64 = g.voxel_sigma_s().iter().sum();
    let cell = g.voxel_size();
    assert!(
        (g.scattering_volume() - total * cell.x * cell.y * cell.z).abs()
            < 1e-13 * g.scattering_volume()
    );
    let p: Vec<f64> = g.voxel_sigma_s().iter().map(|s| s / total).collect();
    let n = 300_000;
    let mut next = uniform_stream(12);
    let mut counts = vec![0u64; p.len()];
    let (mut fx, mut fy) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let x = g.sample_scatterer([next(), next(), next()]);
        let v = g.voxel_of(x).expect("inside the box");
        assert!(g.sigma_s(x) > 0.0);
        counts[v] += 1;
        // Position inside the voxel, from the recycled u[0] (x) and from u[1] (y).
        let c = (x - g.bounds().min()) / cell;
        fx.push(c.x.fract());
        fy.push(c.y.fract());
    }
    let (stat, dof) = chi_square_stat(&counts, &p);
    let ks_x = ks_distance(fx, |t| t.clamp(0.0, 1.0));
    let ks_y = ks_distance(fy, |t| t.clamp(0.0, 1.0));
    eprintln!(
        "scatterers: chi2 {stat:.1} on {dof} dof (bound {:.1}); KS x {ks_x:.3}, y {ks_y:.3}",
        chi_square_bound(dof)
    );
    assert!(stat < chi_square_bound(dof));
    assert!(ks_x < KS_CRITICAL_0_001 && ks_y < KS_CRITICAL_0_001);
    // The ends of the unit interval stay in scattering voxels.
    for u in [[0.0, 0.0, 0.0], [ONE_BELOW; 3], [1.0, 1.0, 1.0]] {
        let x = g.sample_scatterer(u);
        assert!(g.sigma_s(x) > 0.0, "{u:?} -> {x}");
    }
}

#[test]
fn types_follow_the_voxel_mix() {
    let b = Aabb::new(DVec3::ZERO, DVec3::new(3.0, 1.0, 1.0)).unwrap();
    let mats = vec![
        Material::new(1.0, 0.0, TypeMix::new(vec![0.2, 0.0, 0.8]).unwrap()),
        Material::new(0.5, 0.5, TypeMix::new(vec![0.0, 1.0, 0.0, 3.0]).unwrap()),
        Material::single(0.0, 1.0),
    ];
    let g = VoxelGrid::from_materials(b, [3, 1, 1], vec![1, 0, 2], mats.clone()).unwrap();
    assert_eq!(g.particle_types(), 4);
    let mut out = [7.0; 4];
    for (x, m) in [(0.5, &mats[1]), (1.5, &mats[0])] {
        let at = DVec3::new(x, 0.5, 0.5);
        g.type_probabilities(at, &mut out);
        let mut beta = m.types.beta().to_vec();
        beta.resize(4, 0.0);
        assert_eq!(out.to_vec(), beta);
        let n = 100_000;
        let mut next = uniform_stream(13);
        let mut counts = vec![0u64; 4];
        for _ in 0..n {
            counts[g.sample_type(at, next())] += 1;
        }
        let (stat, dof) = chi_square_stat(&counts, &beta);
        eprintln!("types at x = {x}: {counts:?}, chi2 {stat:.2} on {dof} dof");
        assert!(stat < chi_square_bound(dof));
    }
    // The density grid has the base mix everywhere.
    let d =
        VoxelGrid::from_densities(b, [3, 1, 1], vec![0.0, 1.0, 2.0], mats[1].clone(), 0.1).unwrap();
    assert_eq!(d.particle_types(), 4);
    assert_eq!(d.sample_type(DVec3::new(2.5, 0.5, 0.5), 0.1), 1);
    assert_eq!(d.sample_type(DVec3::new(2.5, 0.5, 0.5), 0.3), 3);
    // A particle mix as the base material: the density scales N_iota, not the host.
    use crate::{Concentration, ParticleMix, ParticleType};
    let mix = ParticleMix::new(
        vec![
            ParticleType::new(0.2, 0.1, 0.01, Concentration::VolumeFraction(0.01)),
            ParticleType::new(0.4, 0.5, 0.0, Concentration::VolumeFraction(0.02)),
        ],
        0.03,
    )
    .unwrap();
    let p = VoxelGrid::from_densities(
        b,
        [3, 1, 1],
        vec![0.0, 1.0, 2.0],
        mix.particle_material(),
        mix.host_sigma_a(),
    )
    .unwrap();
    let at = DVec3::new(1.5, 0.5, 0.5);
    assert!((p.sigma_s(at) - mix.sigma_s()).abs() <= 1e-15 * mix.sigma_s());
    assert!((p.sigma_t(at) - mix.sigma_t()).abs() <= 1e-15 * mix.sigma_t());
    assert_eq!(p.voxel_sigma_t()[0], 0.03);
    assert!((p.voxel_sigma_s()[2] - 2.0 * mix.sigma_s()).abs() <= 1e-15 * mix.sigma_s());
    let mut out = [0.0; 2];
    p.type_probabilities(at, &mut out);
    assert_eq!(out, [mix.beta()[0], mix.beta()[1]]);
    // Host absorption is not scaled by the density.
    assert_eq!(d.voxel_sigma_t(), &[0.1, 1.1, 2.1]);
}

#[test]
fn uniform_sigma_t_only_for_constant_extinction() {
    let b = test_box();
    // Same sigma_t, different albedo: uniform.
    let mats = vec![Material::single(0.5, 0.5), Material::single(1.0, 0.0)];
    let g = VoxelGrid::from_materials(b, [2, 1, 1], vec![0, 1], mats).unwrap();
    assert_eq!(g.uniform_sigma_t(), Some(1.0));
    assert_eq!(random_grid(3).uniform_sigma_t(), None);
}

#[test]
fn flatland_grid() {
    let b = Aabb::flat(DVec2::new(0.0, -1.0), DVec2::new(4.0, 2.0)).unwrap();
    assert!(
        VoxelGrid::from_densities(b, [4, 3, 2], vec![1.0; 24], Material::single(1.0, 0.0), 0.0)
            .is_err()
    );
    let mut next = uniform_stream(21);
    let dens: Vec<f64> = (0..12)
        .map(|i| if i == 5 { 0.0 } else { 0.6 * next() })
        .collect();
    let g = VoxelGrid::from_densities(b, [4, 3, 1], dens, Material::single(0.8, 0.2), 0.0).unwrap();
    assert_eq!(g.dimension(), Dimension::Two);
    assert_eq!(g.voxel_size(), DVec3::new(1.0, 1.0, 0.0));
    // Voxel (ix, iy) = (1, 2) is index 1 * 3 + 2.
    assert_eq!(g.voxel_of(DVec3::new(1.5, 1.5, 0.0)), Some(5));
    assert_eq!(g.sigma_t(DVec3::new(1.5, 1.5, 0.0)), 0.0);
    assert_eq!(g.sigma_t(DVec3::new(1.5, 1.5, 0.1)), 0.0);
    // In-plane optical depths against the midpoint rule; off-plane segments see only a point.
    let (lo, hi) = (DVec3::new(-1.0, -2.0, 0.0), DVec3::new(5.0, 3.0, 0.0));
    for _ in 0..300 {
        let (p, q) = (point_in(&mut next, lo, hi), point_in(&mut next, lo, hi));
        let od = g.optical_depth(p, q);
        let (bf, tol) = brute_depth(&g, p, q, 20_000);
        assert!((od - bf).abs() <= tol, "{p} {q}: {od} vs {bf}");
        let dir = flat_direction(&mut next);
        let far = g.optical_depth(p, p + 20.0 * dir);
        assert!((g.optical_depth_to_infinity(p, dir) - far).abs() <= 1e-12 * far + 1e-14);
    }
    assert_eq!(
        g.optical_depth(DVec3::new(1.0, 0.0, -1.0), DVec3::new(1.0, 0.0, 1.0)),
        0.0
    );
    // Scatterers lie in the plane, in proportion to sigma_s.
    let total: f64 = g.voxel_sigma_s().iter().sum();
    assert!((g.scattering_volume() - total).abs() < 1e-13 * total); // unit cells
    let p: Vec<f64> = g.voxel_sigma_s().iter().map(|s| s / total).collect();
    let mut counts = vec![0u64; 12];
    for _ in 0..120_000 {
        let x = g.sample_scatterer([next(), next(), next()]);
        assert_eq!(x.z, 0.0);
        counts[g.voxel_of(x).unwrap()] += 1;
    }
    let (stat, dof) = chi_square_stat(&counts, &p);
    eprintln!("flatland scatterers: chi2 {stat:.1} on {dof} dof");
    assert!(stat < chi_square_bound(dof));
    // Flights: along x at y = 0.5 (row iy = 1) from x = 0.
    let row: f64 = (0..4).map(|ix| g.voxel_sigma_t()[ix * 3 + 1]).sum();
    let expect = (-row).exp();
    let n = 100_000;
    let se = (expect * (1.0 - expect) / n as f64).sqrt();
    for tracking in [Tracking::Delta, Tracking::Regular, Tracking::Local] {
        let g = g.clone().with_tracking(tracking);
        let (esc, _) = escape_and_depths(&g, DVec3::new(0.0, 0.5, 0.0), DVec3::X, n, 22);
        eprintln!(
            "flatland {tracking:?}: escape {esc:.5} vs {expect:.5} ({:.2} SE)",
            (esc - expect) / se
        );
        assert!((esc - expect).abs() < 4.0 * se);
        // Leaving the plane: escapes at once.
        let mut s = uniform_stream(1);
        assert_eq!(
            g.sample_flight(DVec3::new(1.0, 0.5, 0.0), DVec3::Z, &mut s),
            None
        );
    }
    // A constant flatland grid matches the flatland homogeneous box.
    let c = VoxelGrid::from_densities(b, [4, 3, 1], vec![1.0; 12], Material::single(0.8, 0.2), 0.0)
        .unwrap();
    let h = HomogeneousBox::new(b, 0.8, 0.2).unwrap();
    assert_eq!(c.uniform_sigma_t(), h.uniform_sigma_t());
    for _ in 0..1000 {
        let (p, q) = (point_in(&mut next, lo, hi), point_in(&mut next, lo, hi));
        let (oc, oh) = (c.optical_depth(p, q), h.optical_depth(p, q));
        assert!((oc - oh).abs() <= 1e-12 * oh);
    }
}

#[test]
fn flights_from_outside_cross_the_vacuum() {
    let b = Aabb::new(DVec3::ZERO, DVec3::ONE).unwrap();
    let g = VoxelGrid::from_densities(
        b,
        [1, 1, 2],
        vec![1.0, 1.0],
        Material::single(2.0, 0.0),
        0.0,
    )
    .unwrap();
    let mut s = uniform_stream(3);
    assert_eq!(
        g.sample_flight(DVec3::new(0.5, 0.5, -1.0), -DVec3::Z, &mut s),
        None
    );
    let n = 50_000;
    let (p, depths) = escape_and_depths(&g, DVec3::new(0.5, 0.5, -1.0), DVec3::Z, n, 4);
    let expect = (-2.0f64).exp();
    assert!((p - expect).abs() < 4.0 * (expect * (1.0 - expect) / n as f64).sqrt());
    assert!(depths.iter().all(|&d| (1.0..=2.0).contains(&d)));
}

#[test]
fn rejects_bad_grids() {
    let b = test_box();
    let base = Material::single(1.0, 0.1);
    let dens = |dims: [usize; 3], d: Vec<f64>| {
        field_of(VoxelGrid::from_densities(b, dims, d, base.clone(), 0.0).unwrap_err())
    };
    assert_eq!(dens([0, 2, 2], vec![]).0, "dims");
    assert_eq!(dens([1 << 40, 1 << 40, 1], vec![]).0, "dims");
    assert_eq!(dens([1 << 10, 1 << 10, 1 << 8], vec![]).0, "dims");
    let (f, r) = dens([2, 3, 4], vec![1.0; 23]);
    assert_eq!(f, "densities");
    assert!(
        r.contains("(nx, ny, nz) = (2, 3, 4)") && r.contains("24"),
        "{r}"
    );
    for (v, at) in [(f64::NAN, 5), (-1.0, 0), (f64::INFINITY, 23), (1e300, 7)] {
        let mut d = vec![1.0; 24];
        d[at] = v;
        let (f, r) = if v == 1e300 {
            field_of(
                VoxelGrid::from_densities(b, [2, 3, 4], d, Material::single(1e10, 0.0), 0.0)
                    .unwrap_err(),
            )
        } else {
            dens([2, 3, 4], d)
        };
        assert_eq!(f, format!("densities[{at}]"));
        let (ix, iy, iz) = unflatten([2, 3, 4], at);
        assert!(r.contains(&format!("({ix}, {iy}, {iz})")), "{r}");
    }
    assert_eq!(dens([2, 3, 4], vec![0.0; 24]).0, "densities");
    let with_base = |m: Material, host: f64| {
        field_of(VoxelGrid::from_densities(b, [1, 1, 1], vec![1.0], m, host).unwrap_err()).0
    };
    assert_eq!(
        with_base(Material::single(f64::NAN, 0.0), 0.0),
        "base.sigma_s"
    );
    assert_eq!(with_base(Material::single(0.0, 1.0), 0.0), "base.sigma_s");
    assert_eq!(with_base(Material::single(1.0, -1.0), 0.0), "base.sigma_a");
    assert_eq!(with_base(Material::single(1.0, 0.0), -0.5), "host_sigma_a");
    // A flatland grid needs nz = 1.
    let flat = Aabb::flat(DVec2::ZERO, DVec2::ONE).unwrap();
    let e = VoxelGrid::from_densities(flat, [2, 2, 2], vec![1.0; 8], base.clone(), 0.0);
    assert_eq!(field_of(e.unwrap_err()).0, "dims");
    // Flatland shapes are reported as (nx, ny).
    let e = VoxelGrid::from_densities(flat, [2, 3, 1], vec![1.0; 8], base.clone(), 0.0);
    assert!(field_of(e.unwrap_err()).1.contains("(nx, ny) = (2, 3)"));

    let mats = |ids: Vec<u32>, m: Vec<Material>| {
        field_of(VoxelGrid::from_materials(b, [2, 2, 1], ids, m).unwrap_err())
    };
    assert_eq!(mats(vec![0; 4], vec![]).0, "materials");
    assert_eq!(
        mats(
            vec![0; 4],
            vec![base.clone(), Material::single(1.0, f64::NAN)]
        )
        .0,
        "materials[1].sigma_a"
    );
    assert_eq!(
        mats(vec![0; 4], vec![Material::single(-1.0, 0.0)]).0,
        "materials[0].sigma_s"
    );
    assert_eq!(
        mats(vec![0; 4], vec![Material::single(f64::MAX, f64::MAX)]).0,
        "materials[0]"
    );
    let (f, r) = mats(vec![0, 1, 0, 2], vec![base.clone(), base.clone()]);
    assert_eq!(f, "ids[3]");
    assert!(r.contains("id 2") && r.contains("(1, 1, 0)"), "{r}");
    assert_eq!(mats(vec![0; 5], vec![base.clone()]).0, "ids");
    assert_eq!(
        mats(
            vec![0, 1, 1, 0],
            vec![Material::vacuum(), Material::single(0.0, 3.0)]
        )
        .0,
        "ids"
    );
    // The sum of sigma_s over the voxels overflows.
    assert_eq!(
        mats(vec![0; 4], vec![Material::single(1e308, 0.0)]).0,
        "sigma_s"
    );
    // A box too thin for its voxel count.
    let thin = Aabb::new(DVec3::ZERO, DVec3::new(1.0, 1.0, 1e-310)).unwrap();
    let e = VoxelGrid::from_densities(thin, [1, 1, 2], vec![1.0; 2], base, 0.0);
    assert_eq!(field_of(e.unwrap_err()).0, "bounds");
}

#[test]
fn grid_is_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<VoxelGrid>();
    check::<HomogeneousBox>();
}

#[test]
fn a_grid_with_an_extreme_layer_tracks_regularly_and_its_flights_end() {
    // Fuzz finding (issue 27): the head scene with 1e15 /cm of absorption in its CSF hung:
    // delta tracking against that majorant takes 1e16 null collisions per flight. Such a grid
    // tracks regularly (MAX_DELTA_COLLISIONS); flights from the first layer stop at the dense
    // layer's face, within 1e-12 of it, or pass the lighter layers; ordinary grids keep delta
    // tracking (their outputs are unchanged).
    let b = Aabb::new(DVec3::ZERO, DVec3::new(10.0, 10.0, 4.0)).unwrap();
    let mats = |dense: f64| {
        vec![
            Material::single(66.0, 0.2),
            Material::single(1.0, dense),
            Material::single(110.0, 0.2),
        ]
    };
    let g = VoxelGrid::from_materials(b, [1, 1, 3], vec![0, 1, 2], mats(1e15)).unwrap();
    assert_eq!(g.tracking(), Tracking::Regular);
    let ordinary = VoxelGrid::from_materials(b, [1, 1, 3], vec![0, 1, 2], mats(0.03)).unwrap();
    assert_eq!(ordinary.tracking(), Tracking::Delta);
    let mut next = uniform_stream(5);
    let start = std::time::Instant::now();
    for _ in 0..10_000 {
        // From inside the first layer towards the dense one (cell 4/3 thick).
        let x = DVec3::new(5.0, 5.0, 1.3);
        let dir = DVec3::new(0.01, 0.0, 1.0).normalize();
        if let Some(t) = g.sample_flight(x, dir, &mut next) {
            let z = x.z + t * dir.z;
            assert!(z < 4.0 / 3.0 + 1e-12, "passed the dense layer: z = {z}");
        }
    }
    // 10 000 flights take microseconds each; a hang would not return at all.
    assert!(start.elapsed().as_secs() < 10);
}
