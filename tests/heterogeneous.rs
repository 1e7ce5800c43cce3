//! Heterogeneous voxel media under the unchanged estimators (Bar et al. 2019, Sec. 5.1: "all
//! estimators run unchanged" on a medium that answers tracking queries).
//!
//! - A grid filled with one constant material gives the covariance of the homogeneous box
//!   (coherent backscattering included) within standard errors: delta tracking, exact voxel
//!   traversal for next-event attenuation and sigma_s-weighted first vertices together.
//! - A two-layer grid: the single-scattering intensities (Eq. 41) of far-field sensors in
//!   transmission and reflection match a deterministic quadrature of
//!   `rho(i . v) int sigma_s(x) exp(-od_in(x) - od_out(x)) dx`, with the layer optical depths
//!   clipped by hand here (not through the grid); and the speckle mean of a point source seen
//!   by a point sensor through both layers is `exp(-(sigma_1 L_1 + sigma_2 L_2) / 2) e^{ikr}/r`.
//!
//! Tolerances: 4.5 standard errors per entry; fixed seeds. Run time (release, 2 cores): ~5 s.

use speckle::estimators::{
    Coherence, CovarianceOptions, NoProgress, Pair, Scene, Sensor, Source, render_covariance,
    render_single_scattering,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox, Material, Medium, VoxelGrid};
use speckle::phase::{Phase, PhaseFunction};

const LAMBDA: f64 = 0.1;

fn dir(theta: f64) -> DVec3 {
    DVec3::new(theta.sin(), 0.0, theta.cos())
}

fn endpoints() -> (Vec<Source>, Vec<Sensor>) {
    let sources = vec![
        Source::plane_wave(dir(0.1)).unwrap(),
        Source::plane_wave(dir(0.1 + 0.5 * LAMBDA / 4.0)).unwrap(),
    ];
    let sensors = [0.3, 0.8, 2.5, 3.0]
        .iter()
        .map(|&t| Sensor::far_field(dir(t)).unwrap())
        .collect();
    (sources, sensors)
}

fn scene<M: Medium>(m: M) -> Scene<M, Phase> {
    let (sources, sensors) = endpoints();
    Scene::new(
        m,
        Phase::hg(0.5).unwrap(),
        LAMBDA,
        sources,
        sensors,
        Pair::all(2, 4),
    )
    .unwrap()
}

fn slab() -> Aabb {
    Aabb::centered(DVec3::ZERO, DVec3::new(4.0, 4.0, 2.0)).unwrap()
}

/// A 5 x 4 x 3 grid of one material (sigma_s 0.9, sigma_a 0.1) against the box: all 36
/// covariance entries (real and imaginary parts) within 4.5 combined SE, 400k paths each.
#[test]
fn constant_grid_gives_the_homogeneous_covariance() {
    let ids = vec![0u32; 5 * 4 * 3];
    let grid = VoxelGrid::from_materials(slab(), [5, 4, 3], ids, vec![Material::single(0.9, 0.1)])
        .unwrap();
    let boxed = HomogeneousBox::new(slab(), 0.9, 0.1).unwrap();
    let o = |seed| CovarianceOptions {
        paths: 400_000,
        seed,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let a = render_covariance(&scene(grid), &o(1), &NoProgress).unwrap();
    let b = render_covariance(&scene(boxed), &o(2), &NoProgress).unwrap();
    let j = 8;
    let mut worst: f64 = 0.0;
    for r in 0..j {
        for c in r..j {
            let ((va, sa), (vb, sb)) = (a.total.get(r, c), b.total.get(r, c));
            let zr = (va.re - vb.re) / sa.re.hypot(sb.re);
            let zi = if r == c {
                0.0
            } else {
                (va.im - vb.im) / sa.im.hypot(sb.im)
            };
            eprintln!("C[{r},{c}]: grid {va:.5} vs box {vb:.5}: z = ({zr:+.2}, {zi:+.2})");
            worst = worst.max(zr.abs()).max(zi.abs());
        }
    }
    eprintln!("constant grid vs box: max |z| = {worst:.2}");
    assert!(worst < 4.5);
}

/// The two layers: z in [-1, 0] has (sigma_s, sigma_a) = (0.5, 0.1), z in [0, 1] has (1.5, 0).
const LAYERS: [(f64, f64, f64, f64); 2] = [(-1.0, 0.0, 0.5, 0.1), (0.0, 1.0, 1.5, 0.0)];

fn two_layers() -> VoxelGrid {
    let materials = LAYERS
        .iter()
        .map(|&(_, _, s, a)| Material::single(s, a))
        .collect();
    VoxelGrid::from_materials(slab(), [1, 1, 2], vec![0, 1], materials).unwrap()
}

/// Optical depth from `x` along `d` to the boundary of the box `[-2, 2]^2 x [-1, 1]`, layer by
/// layer (clipping the ray's z range against each layer).
fn od_to_boundary(x: DVec3, d: DVec3) -> f64 {
    let (lo, hi) = (DVec3::new(-2.0, -2.0, -1.0), DVec3::new(2.0, 2.0, 1.0));
    let mut t_exit = f64::INFINITY;
    for k in 0..3 {
        if d[k] > 0.0 {
            t_exit = t_exit.min((hi[k] - x[k]) / d[k]);
        } else if d[k] < 0.0 {
            t_exit = t_exit.min((lo[k] - x[k]) / d[k]);
        }
    }
    let (z0, z1) = (x.z, x.z + t_exit * d.z);
    LAYERS
        .iter()
        .map(|&(a, b, s, ab)| {
            let inside = if d.z.abs() < 1e-300 {
                if (a..b).contains(&x.z) { t_exit } else { 0.0 }
            } else {
                let (lo, hi) = (z0.min(z1).max(a), z0.max(z1).min(b));
                (hi - lo).max(0.0) / d.z.abs()
            };
            (s + ab) * inside
        })
        .sum()
}

/// Gauss-Legendre nodes and weights on [-1, 1], 4 points.
const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

fn composite(a: f64, b: f64, panels: usize) -> Vec<(f64, f64)> {
    let h = (b - a) / panels as f64;
    (0..panels)
        .flat_map(|p| {
            let c = a + (p as f64 + 0.5) * h;
            GL4.iter()
                .map(move |&(x, w)| (c + 0.5 * h * x, 0.5 * h * w))
        })
        .collect()
}

/// `int sigma_s(x) exp(-od_in(x) - od_out(x)) dx` over the two-layer box for a plane wave along
/// `i` and a far-field sensor along `v`.
fn single_scattering_integral(i: DVec3, v: DVec3) -> f64 {
    let xy = composite(-2.0, 2.0, 48);
    let mut total = 0.0;
    for &(a, b, s, _) in &LAYERS {
        for &(z, wz) in &composite(a, b, 24) {
            for &(x, wx) in &xy {
                for &(y, wy) in &xy {
                    let p = DVec3::new(x, y, z);
                    let od = od_to_boundary(p, -i) + od_to_boundary(p, v);
                    total += wx * wy * wz * s * (-od).exp();
                }
            }
        }
    }
    total
}

/// Single-scattering intensities through the two layers, transmission (0.3, 0.8 rad) and
/// reflection (2.5, 3.0 rad), 400k first vertices (SE 0.1-0.2%), against the layer-by-layer
/// quadrature (4-point Gauss-Legendre on 48 x 48 x 24 panels per layer).
#[test]
fn two_layer_single_scattering_matches_quadrature() {
    let s = scene(two_layers());
    let est = render_single_scattering(
        &s,
        &CovarianceOptions {
            paths: 400_000,
            seed: 3,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap();
    let hg = Phase::hg(0.5).unwrap();
    let (sources, sensors) = endpoints();
    let Source::PlaneWave { direction: i } = sources[0] else {
        unreachable!()
    };
    let mut worst: f64 = 0.0;
    for (j, sensor) in sensors.iter().enumerate() {
        let Sensor::FarField { direction: v } = *sensor else {
            unreachable!()
        };
        let expect = hg.density(i.dot(v)) * single_scattering_integral(i, v);
        let (value, se) = est.get(j, j);
        let z = (value.re - expect) / se.re;
        eprintln!(
            "sensor {j}: MC {:.6} +- {:.6} vs quadrature {expect:.6}: z = {z:+.2}",
            value.re, se.re
        );
        worst = worst.max(z.abs());
    }
    assert!(worst < 4.5, "max |z| = {worst}");
}

/// The speckle mean of a point source seen by a point sensor across both layers is the
/// ballistic field `exp(-od / 2) e^{ikr} / r` with `od = sigma_t1 L_1 + sigma_t2 L_2` along the
/// line of sight (Eq. 20, exact: no sampling involved).
#[test]
fn two_layer_mean_field_is_the_layered_transmittance() {
    let (p, q) = (DVec3::new(0.3, -0.2, -3.0), DVec3::new(-0.4, 0.5, 2.5));
    let s = Scene::new(
        two_layers(),
        Phase::hg(0.5).unwrap(),
        LAMBDA,
        vec![Source::Point { position: p }],
        vec![Sensor::Point { position: q }],
        Pair::all(1, 1),
    )
    .unwrap();
    let m = s.mean(Pair::all(1, 1)[0]).unwrap();
    let d = (q - p).normalize();
    // Path length inside each layer: dz / cos.
    let len = 1.0 / d.z.abs();
    let od = (0.5 + 0.1) * len + 1.5 * len;
    let r = (q - p).length();
    let k = std::f64::consts::TAU / LAMBDA;
    let expect = speckle::phase::Complex64::from_polar((-0.5 * od).exp() / r, k * r);
    eprintln!("mean {m:.6e} vs {expect:.6e}");
    assert!((m - expect).norm() < 1e-12 * expect.norm());
}
