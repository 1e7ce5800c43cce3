//! Single scattering agrees with Eq. 41 evaluated by deterministic quadrature, per entry, within
//! 4 standard errors.
//!
//! The reference is an independent deterministic quadrature over the box (iterated composite
//! Gauss-Legendre in z, y, x, panels of a quarter or an eighth of a wavelength, split at the kinks
//! of the attenuation, where a segment's exit face changes, so that it converges fast) of
//! `C[(i1,v1),(i2,v2)] = s(i1.v1) s(i2.v2)^* int sigma_s ups(i1->x) ups(x->v1) (ups(i2->x) ups(x->v2))^* dx`
//! (Bar et al. 2019, Eq. 41, absolute units of `docs/conventions.md`), with the attenuations and
//! phases computed here from the geometry (plane wave: `exp(-sigma_t d/2) exp(i k i.x)` with `d`
//! the distance from `x` back along `-i` to the boundary; far field: `exp(-sigma_t d/2)
//! exp(-i k v.x)` with `d` along `+v`; point endpoints: the part of the segment inside the box,
//! `exp(i k r)/r`), and the Henyey-Greenstein amplitude `sqrt(rho)` written here too. The
//! quadrature is itself checked against closed forms for normal incidence.
//!
//! It is compared with `render_covariance(..).single` and with `render_single_scattering`
//! (uniform and exponential-depth first vertices), entry by entry, real and imaginary parts
//! separately: `|MC - reference| < 4 SE`, with SE the estimators' batch-means standard error.
//! Diagonal imaginary parts are zero by construction and skipped. The quadrature is checked to
//! have converged: halving the panel size changes every entry by less than 0.05 SE of the
//! estimates it is compared with, so its error moves no z-score by more than about 0.05.

mod common_a;

use common_a::{BoxGeom, composite_rule, hg_density};
use num_complex::Complex64;
use rayon::prelude::*;
use speckle::estimators::{
    CMatrix, Coherence, CovarianceOptions, MatrixEstimate, NoProgress, Pair, Scene, Sensor, Source,
    render_covariance, render_single_scattering,
};
use speckle::medium::{Aabb, DVec3, HomogeneousBox};
use speckle::paths::{FirstVertex, TracerConfig};
use speckle::phase::Phase;
use std::f64::consts::TAU;

/// Wavelength, in the length unit of the boxes.
const LAMBDA: f64 = 1.0;

/// A reference endpoint on the illumination side.
#[derive(Debug, Clone, Copy)]
enum RefSource {
    Plane(DVec3),
    Point(DVec3),
}

/// A reference endpoint on the sensor side.
#[derive(Debug, Clone, Copy)]
enum RefSensor {
    Far(DVec3),
    Point(DVec3),
}

/// The physical problem, described once for both the library and the reference.
struct Problem {
    size: DVec3,
    sigma_s: f64,
    sigma_a: f64,
    g: f64,
    sources: Vec<RefSource>,
    sensors: Vec<RefSensor>,
}

impl Problem {
    fn geom(&self) -> BoxGeom {
        BoxGeom::centered(DVec3::ZERO, self.size)
    }

    fn pairs(&self) -> Vec<(usize, usize)> {
        (0..self.sources.len())
            .flat_map(|s| (0..self.sensors.len()).map(move |v| (s, v)))
            .collect()
    }

    fn scene(&self) -> Scene<HomogeneousBox, Phase> {
        let aabb = Aabb::centered(DVec3::ZERO, self.size).unwrap();
        let medium = HomogeneousBox::new(aabb, self.sigma_s, self.sigma_a).unwrap();
        let sources = self
            .sources
            .iter()
            .map(|s| match *s {
                RefSource::Plane(d) => Source::plane_wave(d).unwrap(),
                RefSource::Point(p) => Source::Point { position: p },
            })
            .collect();
        let sensors = self
            .sensors
            .iter()
            .map(|s| match *s {
                RefSensor::Far(d) => Sensor::far_field(d).unwrap(),
                RefSensor::Point(p) => Sensor::Point { position: p },
            })
            .collect();
        let pairs = self
            .pairs()
            .into_iter()
            .map(|(source, sensor)| Pair { source, sensor })
            .collect();
        Scene::new(
            medium,
            Phase::hg(self.g).unwrap(),
            LAMBDA,
            sources,
            sensors,
            pairs,
        )
        .unwrap()
    }

    /// `ups(i -> x)` and the propagation direction at `x`.
    fn ups_in(&self, b: &BoxGeom, x: DVec3, s: RefSource) -> (Complex64, DVec3) {
        let (k, st) = (TAU / LAMBDA, self.sigma_s + self.sigma_a);
        match s {
            RefSource::Plane(d) => {
                let d = d.normalize();
                let tau = (-0.5 * st * b.exit(x, -d)).exp();
                (Complex64::from_polar(tau, k * d.dot(x)), d)
            }
            RefSource::Point(p) => {
                let r = (x - p).length();
                let tau = (-0.5 * st * b.inside_length_to(x, p)).exp();
                (Complex64::from_polar(tau / r, k * r), (x - p) / r)
            }
        }
    }

    /// `ups(x -> v)` and the direction leaving `x`.
    fn ups_out(&self, b: &BoxGeom, x: DVec3, v: RefSensor) -> (Complex64, DVec3) {
        let (k, st) = (TAU / LAMBDA, self.sigma_s + self.sigma_a);
        match v {
            RefSensor::Far(d) => {
                let d = d.normalize();
                let tau = (-0.5 * st * b.exit(x, d)).exp();
                (Complex64::from_polar(tau, -k * d.dot(x)), d)
            }
            RefSensor::Point(q) => {
                let r = (q - x).length();
                let tau = (-0.5 * st * b.inside_length_to(x, q)).exp();
                (Complex64::from_polar(tau / r, k * r), (q - x) / r)
            }
        }
    }

    /// Planes across which the integrand has a kink: where the face through which an
    /// attenuation segment leaves the box changes. For a fixed exit direction `e` it is the plane
    /// `t_a = t_b` through the box edge shared by the exit faces of axes `a` and `b`; for a point
    /// endpoint `p`, the plane through `p` and that edge.
    fn kink_planes(&self, b: &BoxGeom) -> Vec<PlaneEq> {
        let mut out = Vec::new();
        let mut direction = |e: DVec3| {
            let e = e.normalize();
            let axes: Vec<(usize, f64)> = (0..3)
                .filter(|&a| e[a] != 0.0)
                .map(|a| (a, if e[a] > 0.0 { b.hi[a] } else { b.lo[a] }))
                .collect();
            for (i, &(a, ba)) in axes.iter().enumerate() {
                for &(c, bc) in &axes[i + 1..] {
                    // (B_a - x_a) e_c = (B_c - x_c) e_a.
                    let mut n = DVec3::ZERO;
                    n[a] = -e[c];
                    n[c] = e[a];
                    out.push(PlaneEq {
                        n,
                        c: bc * e[a] - ba * e[c],
                    });
                }
            }
        };
        let mut points = Vec::new();
        for s in &self.sources {
            match *s {
                RefSource::Plane(d) => direction(-d),
                RefSource::Point(p) => points.push(p),
            }
        }
        for v in &self.sensors {
            match *v {
                RefSensor::Far(d) => direction(d),
                RefSensor::Point(q) => points.push(q),
            }
        }
        for p in points {
            // Only faces that p lies beyond can be crossed by a segment from inside to p.
            let axes: Vec<(usize, f64)> = (0..3)
                .filter_map(|a| {
                    if p[a] > b.hi[a] {
                        Some((a, b.hi[a]))
                    } else if p[a] < b.lo[a] {
                        Some((a, b.lo[a]))
                    } else {
                        None
                    }
                })
                .collect();
            for (i, &(a, ba)) in axes.iter().enumerate() {
                for &(c, bc) in &axes[i + 1..] {
                    // (B_a - x_a)(p_c - x_c) = (B_c - x_c)(p_a - x_a): the quadratic terms cancel.
                    let mut n = DVec3::ZERO;
                    n[a] = bc - p[c];
                    n[c] = p[a] - ba;
                    out.push(PlaneEq {
                        n,
                        c: bc * p[a] - ba * p[c],
                    });
                }
            }
        }
        out
    }

    /// The integrand vector `F_j(x) = s(i_j . v_j) ups(i_j -> x) ups(x -> v_j)`.
    fn integrand(&self, b: &BoxGeom, x: DVec3, pairs: &[(usize, usize)], f: &mut [Complex64]) {
        let ins: Vec<_> = self.sources.iter().map(|s| self.ups_in(b, x, *s)).collect();
        let outs: Vec<_> = self
            .sensors
            .iter()
            .map(|v| self.ups_out(b, x, *v))
            .collect();
        for (fj, &(s, v)) in f.iter_mut().zip(pairs) {
            let (ui, di) = ins[s];
            let (uo, dout) = outs[v];
            *fj = ui * uo * hg_density(self.g, di.dot(dout)).sqrt();
        }
    }

    /// Eq. 41 by iterated composite Gauss-Legendre (`order` nodes per panel, panels at most `h`
    /// long) over z, then y, then x. Each 1D integration is split at the projections of the
    /// vertices of the arrangement of kink planes and box faces (z), of the lines they cut from
    /// the section (y), and at the kinks themselves (x), so that every panel sees a smooth
    /// integrand and the rule converges fast.
    fn quadrature(&self, h: f64, order: usize) -> CMatrix {
        let b = self.geom();
        let eps = 1e-9;
        let kinks = self.kink_planes(&b);
        let mut all = kinks.clone();
        for a in 0..3 {
            for bound in [b.lo[a], b.hi[a]] {
                let mut n = DVec3::ZERO;
                n[a] = 1.0;
                all.push(PlaneEq { n, c: bound });
            }
        }
        let inside = |x: DVec3| (0..3).all(|a| x[a] >= b.lo[a] - eps && x[a] <= b.hi[a] + eps);
        // z: vertices of the arrangement.
        let mut zs = vec![b.lo.z, b.hi.z];
        for i in 0..all.len() {
            for j in i + 1..all.len() {
                for k in j + 1..all.len() {
                    if let Some(x) = intersect3(&all[i], &all[j], &all[k]).filter(|x| inside(*x)) {
                        zs.push(x.z);
                    }
                }
            }
        }
        let rule_z = split_rule(zs, b.lo.z, b.hi.z, h, order);
        let pairs = self.pairs();
        let j = pairs.len();
        let zero = Complex64::new(0.0, 0.0);
        let planes: Vec<Vec<Complex64>> = rule_z
            .par_iter()
            .map(|&(z, wz)| {
                // y: intersections of the lines the planes cut from the section z.
                let lines: Vec<(f64, f64, f64)> = all
                    .iter()
                    .filter(|p| p.n.x != 0.0 || p.n.y != 0.0)
                    .map(|p| (p.n.x, p.n.y, p.c - p.n.z * z))
                    .collect();
                let mut ys = vec![b.lo.y, b.hi.y];
                for (i, l1) in lines.iter().enumerate() {
                    for l2 in &lines[i + 1..] {
                        let det = l1.0 * l2.1 - l1.1 * l2.0;
                        if det.abs() < 1e-12 {
                            continue;
                        }
                        let x = (l1.2 * l2.1 - l1.1 * l2.2) / det;
                        let y = (l1.0 * l2.2 - l1.2 * l2.0) / det;
                        if inside(DVec3::new(x, y, z)) {
                            ys.push(y);
                        }
                    }
                }
                let rule_y = split_rule(ys, b.lo.y, b.hi.y, h, order);
                let mut acc = vec![zero; j * j];
                let mut f = vec![zero; j];
                for &(y, wy) in &rule_y {
                    // x: the kinks on this line.
                    let xs = kinks
                        .iter()
                        .filter(|p| p.n.x != 0.0)
                        .map(|p| (p.c - p.n.y * y - p.n.z * z) / p.n.x)
                        .collect();
                    for (x, wx) in split_rule(xs, b.lo.x, b.hi.x, h, order) {
                        self.integrand(&b, DVec3::new(x, y, z), &pairs, &mut f);
                        let w = wx * wy * wz * self.sigma_s;
                        for r in 0..j {
                            let fr = f[r] * w;
                            for c in 0..j {
                                acc[r * j + c] += fr * f[c].conj();
                            }
                        }
                    }
                }
                acc
            })
            .collect();
        let mut total = vec![zero; j * j];
        for p in planes {
            for (t, a) in total.iter_mut().zip(p) {
                *t += a;
            }
        }
        CMatrix::from_vec(j, j, total)
    }
}

/// A plane `n . x = c`.
#[derive(Debug, Clone, Copy)]
struct PlaneEq {
    n: DVec3,
    c: f64,
}

/// The common point of three planes, if they meet in one point.
fn intersect3(a: &PlaneEq, b: &PlaneEq, c: &PlaneEq) -> Option<DVec3> {
    let (bc, ca, ab) = (b.n.cross(c.n), c.n.cross(a.n), a.n.cross(b.n));
    let det = a.n.dot(bc);
    (det.abs() > 1e-12 * a.n.length() * b.n.length() * c.n.length())
        .then(|| (a.c * bc + b.c * ca + c.c * ab) / det)
}

/// A composite Gauss-Legendre rule on `[lo, hi]`, split at the breakpoints inside it, with
/// panels at most `h` long.
fn split_rule(mut cuts: Vec<f64>, lo: f64, hi: f64, h: f64, order: usize) -> Vec<(f64, f64)> {
    cuts.retain(|c| *c > lo && *c < hi);
    cuts.push(lo);
    cuts.push(hi);
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 1e-12);
    let mut out = Vec::new();
    for w in cuts.windows(2) {
        let panels = ((w[1] - w[0]) / h).ceil().max(1.0) as usize;
        out.extend(composite_rule(w[0], w[1], panels, order));
    }
    out
}

/// Largest per-part z-score of `est` against `reference` (diagonal imaginary parts skipped);
/// panics with the entry if one reaches 4.
fn check(name: &str, est: &MatrixEstimate, reference: &CMatrix) -> f64 {
    let j = reference.rows();
    let mut worst: f64 = 0.0;
    for r in 0..j {
        for c in 0..j {
            let (v, se) = est.get(r, c);
            let e = reference.get(r, c);
            let zr = (v.re - e.re).abs() / se.re;
            let zi = if r == c {
                0.0
            } else {
                (v.im - e.im).abs() / se.im
            };
            let z = zr.max(zi);
            assert!(
                z < 4.0,
                "{name}: entry ({r},{c}) = {v} +- {se} vs quadrature {e}: z = {z:.2}"
            );
            worst = worst.max(z);
        }
    }
    let rel = (0..j)
        .map(|r| est.std_error.get(r, r).re / reference.get(r, r).re)
        .fold(0.0, f64::max);
    eprintln!(
        "{name}: max z-score {worst:.2} over {j}x{j} entries (diagonal relative SE <= {rel:.1e})"
    );
    worst
}

/// The quadrature at panel sizes `h` and `h/2` agree to 0.05 SE of every estimate; returns the
/// finer one.
fn converged_quadrature(p: &Problem, h: f64, ests: &[&MatrixEstimate]) -> CMatrix {
    let coarse = p.quadrature(h, 4);
    let fine = p.quadrature(h / 2.0, 4);
    let j = fine.rows();
    let mut worst: f64 = 0.0;
    for r in 0..j {
        for c in 0..j {
            let d = fine.get(r, c) - coarse.get(r, c);
            for e in ests {
                let se = e.std_error.get(r, c);
                worst = worst.max(d.re.abs() / se.re);
                if r != c {
                    worst = worst.max(d.im.abs() / se.im);
                }
            }
        }
    }
    eprintln!("quadrature change on halving the panels: {worst:.4} SE");
    assert!(
        worst < 0.05,
        "the quadrature has not converged: halving the panels moves an entry by {worst} SE"
    );
    fine
}

/// Compares all three single-scattering estimates of `p` with the quadrature.
fn compare(label: &str, p: &Problem, paths_cov: u64, paths_single: u64) -> f64 {
    let uniform = p.scene();
    let cov = render_covariance(
        &uniform,
        &CovarianceOptions {
            paths: paths_cov,
            seed: 11,
            coherence: Coherence::ForwardAndReversed,
            ..Default::default()
        },
        &NoProgress,
    )
    .unwrap()
    .single;
    let single_opts = CovarianceOptions {
        paths: paths_single,
        seed: 12,
        coherence: Coherence::ForwardAndReversed,
        ..Default::default()
    };
    let single = render_single_scattering(&uniform, &single_opts, &NoProgress).unwrap();
    let single_exp = render_single_scattering(
        &uniform,
        &CovarianceOptions {
            seed: 13,
            sampling: TracerConfig {
                first_vertex: FirstVertex::ExponentialDepth {
                    direction: DVec3::Z,
                },
                ..TracerConfig::default()
            },
            ..single_opts
        },
        &NoProgress,
    )
    .unwrap();
    // Panels of a quarter wavelength at most (the attenuation length is longer).
    let h = LAMBDA / 4.0;
    let reference = converged_quadrature(p, h, &[&cov, &single, &single_exp]);
    // Off-diagonal entries must be non-trivial for the test to say something about them.
    let j = reference.rows();
    let nontrivial = (0..j)
        .flat_map(|r| (0..j).map(move |c| (r, c)))
        .filter(|&(r, c)| {
            let e = reference.get(r, c);
            let se = single.std_error.get(r, c);
            r != c && e.re.abs() > 10.0 * se.re && e.im.abs() > 10.0 * se.im
        })
        .count();
    eprintln!("{label}: {nontrivial} off-diagonal entries with real and imaginary parts > 10 SE");
    assert!(
        nontrivial >= 4,
        "{label}: too few non-trivial off-diagonal entries"
    );
    let z1 = check(
        &format!("{label} render_covariance.single"),
        &cov,
        &reference,
    );
    let z2 = check(
        &format!("{label} render_single_scattering (uniform)"),
        &single,
        &reference,
    );
    let z3 = check(
        &format!("{label} render_single_scattering (exponential depth)"),
        &single_exp,
        &reference,
    );
    z1.max(z2).max(z3)
}

/// Plane waves and far-field sensors: a 4 x 4 x 2 wavelength box, optical depth 1 across its
/// thickness, albedo 0.8, HG g = 0.5, two illuminations 8 degrees apart and three sensors
/// (two in transmission, close to each other, one in reflection).
#[test]
fn plane_waves_and_far_field_sensors_match_eq41() {
    let p = Problem {
        size: DVec3::new(4.0, 4.0, 2.0),
        sigma_s: 0.4,
        sigma_a: 0.1,
        g: 0.5,
        sources: vec![
            RefSource::Plane(DVec3::Z),
            RefSource::Plane(DVec3::new(
                8f64.to_radians().sin(),
                0.0,
                8f64.to_radians().cos(),
            )),
        ],
        sensors: vec![
            RefSensor::Far(DVec3::new(0.2, 0.1, 1.0)),
            RefSensor::Far(DVec3::new(0.25, 0.05, 1.0)),
            RefSensor::Far(DVec3::new(-0.3, 0.0, -1.0)),
        ],
    };
    let z = compare("plane/far", &p, 1 << 20, 1 << 22);
    eprintln!("plane/far: max z-score {z:.2}");
}

/// Point endpoints outside the box: a point source below it and a plane wave; a point sensor
/// above it, a far-field sensor in reflection, and a point sensor beyond an upper edge (its
/// segments leave through the top or a side face).
#[test]
fn point_endpoints_match_eq41() {
    let p = Problem {
        size: DVec3::new(4.0, 4.0, 2.0),
        sigma_s: 0.4,
        sigma_a: 0.1,
        g: 0.5,
        sources: vec![
            RefSource::Point(DVec3::new(1.0, -0.5, -4.0)),
            RefSource::Plane(DVec3::Z),
        ],
        sensors: vec![
            RefSensor::Point(DVec3::new(0.5, 0.5, 5.0)),
            RefSensor::Far(DVec3::new(0.1, 0.0, -1.0)),
            RefSensor::Point(DVec3::new(3.0, 1.0, 3.0)),
        ],
    };
    let z = compare("point", &p, 1 << 20, 1 << 22);
    eprintln!("point: max z-score {z:.2}");
}

/// The quadrature itself reproduces closed forms of Eq. 41 for normal incidence on a box:
/// transmission `v = i = +z`, `C = sigma_s rho(1) |V| exp(-sigma_t T)`; reflection `v = -z`,
/// `C = sigma_s rho(-1) A (1 - exp(-2 sigma_t T)) / (2 sigma_t)`; and their cross term
/// `C = sigma_s s(-1) s(1) A exp(-sigma_t T / 2) e^{2 i k z0} (e^{(2 i k - sigma_t) T} - 1) / (2 i k - sigma_t)`
/// (face area `A`, thickness `T`, entrance face at `z0`).
#[test]
fn quadrature_matches_closed_forms() {
    let p = Problem {
        size: DVec3::new(3.0, 2.0, 1.5),
        sigma_s: 0.4,
        sigma_a: 0.1,
        g: 0.5,
        sources: vec![RefSource::Plane(DVec3::Z)],
        sensors: vec![RefSensor::Far(-DVec3::Z), RefSensor::Far(DVec3::Z)],
    };
    let q = p.quadrature(LAMBDA / 8.0, 6);
    let (st, t, area, z0): (f64, f64, f64, f64) = (0.5, 1.5, 6.0, -0.75);
    let k = TAU / LAMBDA;
    let rho = |mu: f64| hg_density(p.g, mu);
    let refl = p.sigma_s * rho(-1.0) * area * (1.0 - (-2.0 * st * t).exp()) / (2.0 * st);
    let trans = p.sigma_s * rho(1.0) * area * t * (-st * t).exp();
    let a = Complex64::new(-st, 2.0 * k);
    let cross = p.sigma_s
        * (rho(-1.0) * rho(1.0)).sqrt()
        * area
        * (-0.5 * st * t).exp()
        * Complex64::from_polar(1.0, 2.0 * k * z0)
        * ((a * t).exp() - 1.0)
        / a;
    for (got, want) in [
        (q.get(0, 0), Complex64::new(refl, 0.0)),
        (q.get(1, 1), Complex64::new(trans, 0.0)),
        (q.get(0, 1), cross),
    ] {
        assert!(
            (got - want).norm() < 1e-10 * want.norm(),
            "quadrature {got} vs closed form {want}"
        );
    }
}
