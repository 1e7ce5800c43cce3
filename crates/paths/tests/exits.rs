//! Light tracing (`Tracer::trace_emitted`) and exits from the medium (`VertexSink::exit`), with
//! and without a refractive-index mismatch at the faces (`Tracer::with_interface`).
//!
//! - The power that reaches a first collision, in a lossless medium (albedo 1, so `first`
//!   receives the emitted power): for a point source inside a box, `4 pi` times the mean over
//!   directions of `1 - e^{-sigma t(w)}`, `t` the distance to the box along `w` (a quadrature
//!   over the sphere); for a plane wave at normal incidence on a slab of optical depth `tau`
//!   and faces of Fresnel reflectance `r0`, the face area times
//!   `(1 - r0)(1 - e^-tau) / (1 - r0 e^-tau)` (the passes of the ballistic beam between the
//!   faces), and without the mismatch `1 - e^-tau`. Tolerance 4.5 standard errors of 200 000
//!   paths; a missing entry reflection moves the slab's value by 19 SE, a missing internal one
//!   by 5.
//! - A fibre source ([`speckle_paths::Disc`]) on a slab too thick for any light to cross
//!   unscattered, faces of index 1.4 in air: unit power times the part transmitted into the
//!   medium, `int (1 - R(w)) (w . m) dw / int (w . m) dw` over its cone (a quadrature about the
//!   cone's axis), for the axis along the inward normal `m` and tilted; 4.5 standard errors of
//!   200 000 paths. Leaving out the Fresnel loss moves it by 77 and 58 SE.
//! - The fibre's samples themselves: points uniform on the disc (`E r^2 = R^2 / 2`) and the
//!   weighted mean direction `int w (w . m) dw / int (w . m) dw` over the cone (quadrature),
//!   about the normal and tilted, within 4.5 SE of 400 000 samples; weighing a tilted cone's
//!   directions uniformly (a missing cosine) moves its mean by over 100 SE.
//! - Exits lie on the boundary, leave it outwards, and obey Snell's law when the faces refract.

use glam::DVec3;
use speckle_medium::{Aabb, HomogeneousBox, Interface, Medium};
use speckle_paths::{Disc, Emission, Exit, PathRng, Tracer, TracerConfig, Vertex, VertexSink};
use speckle_phase::Phase;

#[derive(Default)]
struct Record {
    sum: f64,
    sq: f64,
    exits: u64,
    bad_exits: Vec<String>,
}

struct Sink<'a> {
    r: &'a mut Record,
    b: Aabb,
    interface: Option<Interface>,
}

impl VertexSink for Sink<'_> {
    fn first(&mut self, _x1: DVec3, _ty: usize, w: f64, _rng: &mut PathRng) {
        self.r.sum += w;
        self.r.sq += w * w;
    }
    fn vertex(&mut self, _v: &Vertex, _rng: &mut PathRng) {}
    fn exit(&mut self, e: &Exit, _rng: &mut PathRng) {
        self.r.exits += 1;
        let (lo, hi) = (self.b.min(), self.b.max());
        let tol = 1e-12;
        let normal = (0..3).find_map(|a| {
            let mut n = DVec3::ZERO;
            if (e.point[a] - lo[a]).abs() < tol && e.dir[a] < 0.0 {
                n[a] = -1.0;
                Some(n)
            } else if (e.point[a] - hi[a]).abs() < tol && e.dir[a] > 0.0 {
                n[a] = 1.0;
                Some(n)
            } else {
                None
            }
        });
        let Some(n) = normal else {
            self.r.bad_exits.push(format!("off the boundary: {e:?}"));
            return;
        };
        if let (Some(i), 0) = (self.interface, e.reflections) {
            let sin = |w: DVec3| (1.0 - w.dot(n).powi(2)).max(0.0).sqrt();
            let snell = i.inside() * sin(e.w_out) - i.outside() * sin(e.dir);
            if snell.abs() > 1e-12 {
                self.r.bad_exits.push(format!("Snell {snell}: {e:?}"));
            }
        }
    }
}

fn first_power(
    m: &HomogeneousBox,
    interface: Option<Interface>,
    emission: Emission,
    seed: u64,
) -> (f64, f64, Record) {
    let phase = Phase::hg(0.7).unwrap();
    let mut t = Tracer::new(m, &phase, TracerConfig::default()).unwrap();
    if let Some(i) = interface {
        t = t.with_interface(i);
    }
    let mut r = Record::default();
    let n = 200_000u64;
    for k in 0..n {
        let mut sink = Sink {
            r: &mut r,
            b: *m.bounds(),
            interface,
        };
        t.trace_emitted(emission, &mut PathRng::new(seed, k), &mut sink);
    }
    let nf = n as f64;
    let mean = r.sum / nf;
    let se = ((r.sq / nf - mean * mean) / nf).sqrt();
    (mean, se, r)
}

#[test]
fn a_point_source_inside_a_box_reaches_its_first_collisions_with_the_power_that_collides() {
    let b = Aabb::new(DVec3::new(-1.0, -0.5, 0.0), DVec3::new(1.0, 0.5, 0.8)).unwrap();
    let sigma = 1.3;
    let m = HomogeneousBox::new(b, sigma, 0.0).unwrap();
    let p = DVec3::new(0.2, -0.1, 0.3);
    // 4 pi E_w[1 - exp(-sigma t(w))] by the midpoint rule in (cos theta, phi).
    let (nu, nphi) = (800, 1600);
    let mut expect = 0.0;
    for i in 0..nu {
        let mu = -1.0 + 2.0 * (i as f64 + 0.5) / nu as f64;
        let s = (1.0 - mu * mu).sqrt();
        for j in 0..nphi {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / nphi as f64;
            let w = DVec3::new(s * phi.cos(), s * phi.sin(), mu);
            expect += 1.0 - (-sigma * b.exit_distance(p, w)).exp();
        }
    }
    expect *= 4.0 * std::f64::consts::PI / (nu * nphi) as f64;
    let (mean, se, r) = first_power(&m, None, Emission::Point(p), 3);
    assert!(r.bad_exits.is_empty(), "{:?}", &r.bad_exits[..1]);
    assert!(se < 0.01 * expect);
    assert!(
        (mean - expect).abs() < 4.5 * se,
        "{mean} +- {se} against {expect}"
    );
}

#[test]
fn a_plane_wave_enters_a_slab_with_its_fresnel_passes() {
    let (w, d) = (3.0, 0.5);
    let b = Aabb::new(DVec3::new(-w, -w, 0.0), DVec3::new(w, w, d)).unwrap();
    let sigma = 2.4; // optical depth 1.2
    let m = HomogeneousBox::new(b, sigma, 0.0).unwrap();
    let area = 4.0 * w * w;
    let tau = (-sigma * d).exp();
    let n = 1.4;
    let r0 = ((n - 1.0) / (n + 1.0)) * ((n - 1.0) / (n + 1.0));
    let cases = [
        (None, area * (1.0 - tau)),
        (
            Interface::new(n, 1.0),
            area * (1.0 - r0) * (1.0 - tau) / (1.0 - r0 * tau),
        ),
    ];
    for (interface, expect) in cases {
        let (mean, se, r) = first_power(&m, interface, Emission::Plane(DVec3::Z), 4);
        assert!(r.bad_exits.is_empty(), "{:?}", &r.bad_exits[..1]);
        assert!(r.exits > 1000);
        assert!(se < 0.01 * expect);
        assert!(
            (mean - expect).abs() < 4.5 * se,
            "{interface:?}: {mean} +- {se} against {expect}"
        );
    }
}

#[test]
fn a_fibre_source_launches_unit_power_less_its_fresnel_reflection() {
    let w = 20.0;
    let b = Aabb::new(DVec3::new(-w, -w, 0.0), DVec3::new(w, w, 2.0)).unwrap();
    // Optical depth 60 across: light that enters collides.
    let m = HomogeneousBox::new(b, 30.0, 0.0).unwrap();
    let (n_in, n_out) = (1.4, 1.0);
    let interface = Interface::new(n_in, n_out);
    let inward = DVec3::Z;
    let sin_max: f64 = 0.6;
    let tilt = 0.5f64; // radians; the cone (36.9 degrees) stays within the hemisphere
    for axis in [inward, DVec3::new(tilt.sin(), 0.0, tilt.cos())] {
        // The quadrature in (theta, phi) about the axis.
        let (a1, a2) = axis.any_orthonormal_pair();
        let (nt, np) = (600, 600);
        let (mut num, mut den) = (0.0, 0.0);
        let theta_max = sin_max.asin();
        for i in 0..nt {
            let th = theta_max * (i as f64 + 0.5) / nt as f64;
            for j in 0..np {
                let ph = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
                let d = th.cos() * axis + th.sin() * (ph.cos() * a1 + ph.sin() * a2);
                let c = d.dot(inward);
                let r = speckle_medium::boundary::reflectance(n_out, n_in, c);
                num += (1.0 - r) * c * th.sin();
                den += c * th.sin();
            }
        }
        let expect = num / den;
        let disc = Disc {
            center: DVec3::new(0.3, -0.2, 0.0),
            normal: -DVec3::Z,
            axis,
            radius: 0.4,
            sin_max,
        };
        let (mean, se, r) = first_power(&m, interface, Emission::Disc(disc), 5);
        assert!(r.bad_exits.is_empty(), "{:?}", &r.bad_exits[..1]);
        assert!(se < 0.01 * expect && expect < 0.99);
        assert!(
            (mean - expect).abs() < 4.5 * se,
            "axis {axis}: {mean} +- {se} against {expect}"
        );
    }
}

#[test]
fn a_fibre_source_samples_its_disc_uniformly_and_its_cone_by_the_cosine() {
    let m = DVec3::X; // inward normal of the face x = 0
    let sin_max: f64 = 0.7;
    let theta_max = sin_max.asin();
    for tilt in [0.0f64, 0.6] {
        let axis = DVec3::new(tilt.cos(), tilt.sin(), 0.0);
        let disc = Disc {
            center: DVec3::new(0.0, 0.1, -0.2),
            normal: -m,
            axis,
            radius: 0.3,
            sin_max,
        };
        // The cosine-weighted mean direction over the cone, by quadrature about the axis.
        let (a1, a2) = axis.any_orthonormal_pair();
        let (nt, np) = (800, 800);
        let (mut num, mut den) = (DVec3::ZERO, 0.0);
        for i in 0..nt {
            let th = theta_max * (i as f64 + 0.5) / nt as f64;
            for j in 0..np {
                let ph = std::f64::consts::TAU * (j as f64 + 0.5) / np as f64;
                let d = th.cos() * axis + th.sin() * (ph.cos() * a1 + ph.sin() * a2);
                num += d * d.dot(m) * th.sin();
                den += d.dot(m) * th.sin();
            }
        }
        let expect = num / den;
        let mut rng = PathRng::new(17, 0);
        let n = 400_000;
        let (mut s, mut sq) = ([0.0f64; 5], [0.0f64; 5]);
        for _ in 0..n {
            let (u, v) = (rng.next_2(), rng.next_2());
            let (p, d, w) = disc.sample([u[0], u[1], v[0], v[1]]);
            assert_eq!(p.x, 0.0);
            assert!(d.dot(axis) >= theta_max.cos() - 1e-12 && w >= 0.0);
            let r2 = (p - disc.center).length_squared() / (0.5 * 0.09);
            for (k, x) in [w, w * d.x, w * d.y, w * d.z, r2].into_iter().enumerate() {
                s[k] += x;
                sq[k] += x * x;
            }
        }
        let nf = n as f64;
        for (k, want) in [1.0, expect.x, expect.y, expect.z, 1.0]
            .into_iter()
            .enumerate()
        {
            let mean = s[k] / nf;
            let se = ((sq[k] / nf - mean * mean) / nf).sqrt().max(1e-12);
            assert!(
                (mean - want).abs() < 4.5 * se,
                "tilt {tilt}, moment {k}: {mean} +- {se} against {want}"
            );
        }
    }
}
