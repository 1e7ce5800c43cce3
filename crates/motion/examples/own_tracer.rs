//! `g1` from your own path tracer, with `speckle-motion` (and, for a focused beam, the beam's
//! field from `speckle-vmf`).
//!
//! A minimal tracer (its own random numbers, geometry and sampling; nothing else of speckle)
//! estimates the temporal field correlation `g1(t)` of the light a slab of drifting Brownian
//! scatterers sends into one far-field direction:
//!
//! - a plane wave along `+z` (or a focused Gaussian beam along `+z`, [`Beam`]) lights the face
//!   `z = 0` of a box (`x, y` in `[-W/2, W/2]`, `z` in `[0, L]`) of isotropic scatterers
//!   (`sigma_s`, `sigma_a`); light tracing from the face, the weight multiplied by the albedo at
//!   each collision, Russian roulette below 0.1 (with a beam, the first vertex's weight also
//!   carries the beam's vacuum intensity `|u(x_1)|^2` there: the flight sampled the attenuation);
//! - at every vertex `x_b` a next-event connection to the far-field direction `v`: the
//!   contribution `w rho e^{-sigma_t d}` (`rho = 1 / 4 pi`, `d` the distance out of the box along
//!   `v`), forward paths only (no coherent backscattering: `v` is a transmission direction);
//! - the decorrelation of each contribution at lag `t` (Bar et al. 2023, Eq. 14), in the hybrid
//!   exact-drift scheme: copy 1 connects its end vertices from `x - t U / 2`, copy 2 from
//!   `x + t U / 2` ([`EndDisplacement::copies`]), with their exact legs `A_1 conj(A_2)` (the
//!   fields of the source at `x_1` and of the far-field leg from `x_b`, attenuated, relative to
//!   their intensity at rest); the interior vertices from [`MotionState`] (started at `x1`,
//!   advanced at each vertex; its drift sum telescopes the interior);
//! - with a plane wave, the end vertices' Brownian transfers `w1 - i` and `v - w_in` in closed
//!   form ([`first_transfer`], [`last_transfer`] with the endpoints' [`source_gradient`] and
//!   [`sensor_gradient`]), a single-scattering path's `v - i` ([`single_transfer`]);
//! - with a beam, which has no single leg direction, the end vertices' Brownian displacements
//!   sampled instead ([`EndDisplacement::sampled`]: one standard normal `z` per end vertex and
//!   path) and added to the drift of the copies' connections, the shared first and last
//!   segments changing by [`segment_phase`];
//! - a path whose vertex the flow takes out of the box at either time contributes nothing at
//!   that lag.
//!
//! `g1(t) = sum c F(t) / sum c` over every contribution `c` and its complex factor `F(t)`, with
//! the standard errors of its parts by the jackknife over 32 batches of paths. The workspace's test
//! `tests/embed_g1.rs` runs [`g1`] against `speckle_estimators::render_correlation` on the same
//! scenes. Run it:
//!
//! `cargo run --release -p speckle-motion --example own_tracer`

use speckle_motion::glam::DVec3;
use speckle_motion::num_complex::Complex64;
use speckle_motion::{
    EndDisplacement, Motion, MotionState, first_transfer, gamma, last_transfer, segment_phase,
    sensor_gradient, single_transfer, source_gradient,
};
use speckle_vmf::Aperture;

/// A focused Gaussian beam along `+z` (Bar et al. 2020, Eqs. 9-10): the superposition of plane
/// waves `int m(w) e^{i k w . (x - f)} dw` with the vMF mask `m(w) ~ e^{gamma z . w}`, attenuated
/// by `e^{-sigma_t z / 2}` at depth `z` (the constant-attenuation connection of the paper's
/// Eq. 25, as the project's estimators connect beams).
#[derive(Debug, Clone, Copy)]
pub struct Beam {
    /// The focal point.
    pub focus: DVec3,
    /// The aperture's vMF concentration `gamma` (`4 / NA^2`).
    pub concentration: f64,
}

/// The slab and the measurement.
#[derive(Debug, Clone, Copy)]
pub struct Setup {
    /// Width `W` of the box in `x` and `y`.
    pub width: f64,
    /// Thickness `L` along `z`.
    pub thickness: f64,
    /// Scattering coefficient.
    pub sigma_s: f64,
    /// Absorption coefficient.
    pub sigma_a: f64,
    /// The far-field direction `v` (unit).
    pub sensor: DVec3,
    /// Wavenumber `k = 2 pi / lambda`.
    pub k: f64,
    /// Every scatterer's Brownian diffusion coefficient.
    pub diffusion: f64,
    /// Every scatterer's drift velocity `U`.
    pub drift: DVec3,
    /// A focused beam instead of the plane wave.
    pub beam: Option<Beam>,
}

impl Setup {
    /// A slab 10 x 10 x 2 mean free paths of albedo 0.95, viewed 20 degrees off the axis in
    /// transmission, `k = 2 pi`, `D` giving `|g1|` about 0.5 at the last of [`LAGS`], and a
    /// drift along `x` that turns `g1`'s phase by `k t (v - i) . U`, 0.26 rad at the last lag.
    pub fn example() -> Self {
        let a = 20f64.to_radians();
        Self {
            width: 10.0,
            thickness: 2.0,
            sigma_s: 0.95,
            sigma_a: 0.05,
            sensor: DVec3::new(a.sin(), 0.0, a.cos()),
            k: std::f64::consts::TAU,
            diffusion: 1e-3,
            drift: DVec3::new(0.03, 0.0, 0.0),
            beam: None,
        }
    }

    /// [`Setup::example`] lit by a beam of numerical aperture 0.5 (`gamma = 16`) focused one
    /// mean free path deep on the axis.
    pub fn beam_example() -> Self {
        Self {
            beam: Some(Beam {
                focus: DVec3::new(0.0, 0.0, 1.0),
                concentration: 16.0,
            }),
            ..Self::example()
        }
    }

    fn inside(&self, x: DVec3) -> bool {
        let h = 0.5 * self.width;
        x.x.abs() <= h && x.y.abs() <= h && (0.0..=self.thickness).contains(&x.z)
    }

    /// The distance from `x` (inside) out of the box along the unit `d`.
    fn exit_distance(&self, x: DVec3, d: DVec3) -> f64 {
        let h = 0.5 * self.width;
        let (lo, hi) = (DVec3::new(-h, -h, 0.0), DVec3::new(h, h, self.thickness));
        (0..3)
            .filter(|&a| d[a] != 0.0)
            .map(|a| {
                let face = if d[a] > 0.0 { hi[a] } else { lo[a] };
                (face - x[a]) / d[a]
            })
            .fold(f64::INFINITY, f64::min)
    }
}

/// The time lags of the example.
pub const LAGS: [f64; 5] = [0.0, 0.5, 1.0, 2.0, 4.0];

/// A small counter-based generator (splitmix64): the tracer's own random numbers.
struct Rng(u64);

impl Rng {
    fn new(seed: u64, path: u64) -> Self {
        Self(seed ^ path.wrapping_mul(0x9e37_79b9_7f4a_7c15))
    }
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
    /// A standard normal vector (Box-Muller).
    fn normal(&mut self) -> DVec3 {
        let mut pair = || {
            let r = (-2.0 * (1.0 - self.next_f64()).ln()).sqrt();
            let (s, c) = (std::f64::consts::TAU * self.next_f64()).sin_cos();
            (r * c, r * s)
        };
        let ((a, b), (c, _)) = (pair(), pair());
        DVec3::new(a, b, c)
    }
    fn direction(&mut self) -> DVec3 {
        let z = 2.0 * self.next_f64() - 1.0;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (s, c) = (std::f64::consts::TAU * self.next_f64()).sin_cos();
        DVec3::new(r * c, r * s, z)
    }
}

/// Traces path `n` and adds its contributions at every lag to `num` and their sum at rest to
/// `den`.
fn trace(s: &Setup, seed: u64, n: u64, lags: &[f64], num: &mut [Complex64], den: &mut f64) {
    let mut rng = Rng::new(seed, n);
    let sigma_t = s.sigma_s + s.sigma_a;
    let albedo = s.sigma_s / sigma_t;
    let rho = 1.0 / (4.0 * std::f64::consts::PI);
    let m = Motion::new(s.diffusion, s.drift).expect("a valid motion");
    // The end vertices' Brownian factors in closed form (plane wave; their drift is in the
    // displaced connections below).
    let brownian = Motion::brownian(s.diffusion).expect("a valid diffusion");
    let (i, v, k) = (DVec3::Z, s.sensor, s.k);
    let (gs, gv) = (source_gradient(i), sensor_gradient(v));
    let aperture = s
        .beam
        .map(|b| Aperture::new(b.concentration, DVec3::Z).expect("a valid beam"));
    // The source's field at `a`, attenuated by `e^{-tau}` (`tau = sigma_t a_z / 2`, or 0 for the
    // vacuum field): the plane wave `e^{i k i . a}`, or the beam.
    let source = |a: DVec3, tau: f64| match (s.beam, &aperture) {
        (Some(b), Some(ap)) => ap.weighted(k, b.focus, a, tau).ln_sphere_integral().exp(),
        _ => Complex64::from_polar((-tau).exp(), k * i.dot(a)),
    };
    // The field of the two legs of a contribution whose first vertex is `a` and last `b`: the
    // source's field at `a` attenuated from the face, the far-field leg `e^{-i k v . b}`
    // attenuated to the box's exit.
    let legs = |a: DVec3, b: DVec3| {
        let sensor = Complex64::from_polar(
            (-0.5 * sigma_t * s.exit_distance(b, v)).exp(),
            -k * v.dot(b),
        );
        source(a, 0.5 * sigma_t * a.z) * sensor
    };
    // Entry at a uniform point of the lit face (weight: its area), first flight.
    let h = 0.5 * s.width;
    let mut x = DVec3::new(
        (2.0 * rng.next_f64() - 1.0) * h,
        (2.0 * rng.next_f64() - 1.0) * h,
        0.0,
    );
    let mut dir = i;
    let mut w = s.width * s.width;
    let mut state = MotionState::default();
    let mut x1 = x;
    // With a beam: the standard normal vectors of the first and the current vertex.
    let (mut z1, mut zb) = (DVec3::ZERO, DVec3::ZERO);
    // Whether every vertex so far lies in the box at both times of each lag (a scatterer that
    // the flow takes out of the box is not in the medium then).
    let mut inside = vec![true; lags.len()];
    for b in 1u32.. {
        x += dir * (-(1.0 - rng.next_f64()).ln() / sigma_t);
        if !s.inside(x) {
            return;
        }
        w *= albedo;
        if s.beam.is_some() {
            zb = rng.normal();
        }
        if b == 1 {
            state = MotionState::start(m);
            x1 = x;
            z1 = zb;
            // The flight sampled the attenuation to x1; the beam's vacuum intensity there is
            // the rest of the source's weight.
            w *= source(x1, 0.0).norm_sqr();
        } else {
            state.advance(b, m, dir);
        }
        // The next-event connection to the far field, at rest, and the legs' intensity at rest,
        // which the displaced connections below are relative to.
        let c = w * rho * (-sigma_t * s.exit_distance(x, v)).exp();
        let rest = legs(x1, x).norm_sqr();
        *den += c;
        for ((out, &t), inside) in num.iter_mut().zip(lags).zip(&mut inside) {
            let drift = EndDisplacement::drift(&m, t);
            *inside = *inside && drift.copies(x).iter().all(|&p| s.inside(p));
            if !*inside {
                continue;
            }
            let f = if s.beam.is_some() {
                // Copy 1 (read at -t/2) connects its end vertices from x - Delta / 2, copy 2
                // from x + Delta / 2, Delta = t U + sqrt(2 D t) z sampled.
                let (first, last) = (
                    EndDisplacement::sampled(&m, t, z1),
                    EndDisplacement::sampled(&m, t, zb),
                );
                let ([a1, a2], [b1, b2]) = (first.copies(x1), last.copies(x));
                let ends = legs(a1, b1) * legs(a2, b2).conj() / rest;
                if b == 1 {
                    ends
                } else {
                    ends * state.interior(k, t) * segment_phase(k, state.w1, &first, dir, &last)
                }
            } else {
                // The drift alone displaces the copies; Brownian transfers in closed form.
                let ([a1, a2], [b1, b2]) =
                    (EndDisplacement::drift(&m, t).copies(x1), drift.copies(x));
                let ends = legs(a1, b1) * legs(a2, b2).conj() / rest;
                if b == 1 {
                    ends * gamma(k, &brownian, single_transfer(gs + gv, gs + gv), t)
                } else {
                    ends * gamma(k, &brownian, first_transfer(state.w1, gs, gs), t)
                        * state.interior(k, t)
                        * gamma(k, &brownian, last_transfer(dir, gv, gv), t)
                }
            };
            *out += c * f;
        }
        // Scatter isotropically; roulette on small weights.
        dir = rng.direction();
        if w < 0.1 {
            if rng.next_f64() >= w / 0.1 {
                return;
            }
            w = 0.1;
        }
    }
}

/// `g1` at `lags` from `paths` paths of seed `seed` (complex: drift turns its phase), and the
/// standard errors of its real and imaginary parts (the jackknife over 32 batches of paths).
pub fn g1(s: &Setup, lags: &[f64], paths: u64, seed: u64) -> (Vec<Complex64>, Vec<Complex64>) {
    const BATCHES: u64 = 32;
    let nl = lags.len();
    let mut sums = vec![(vec![Complex64::ZERO; nl], 0.0); BATCHES as usize];
    for n in 0..paths {
        let (num, den) = &mut sums[(n * BATCHES / paths) as usize];
        trace(s, seed, n, lags, num, den);
    }
    let total: Vec<Complex64> = (0..nl).map(|l| sums.iter().map(|b| b.0[l]).sum()).collect();
    let den: f64 = sums.iter().map(|b| b.1).sum();
    let g: Vec<Complex64> = total.iter().map(|t| t / den).collect();
    let k = BATCHES as f64;
    let se = (0..nl)
        .map(|l| {
            let loo: Vec<Complex64> = sums
                .iter()
                .map(|b| (total[l] - b.0[l]) / (den - b.1))
                .collect();
            let mean = loo.iter().sum::<Complex64>() / k;
            let var = |f: fn(&Complex64) -> f64| {
                (k - 1.0) / k * loo.iter().map(|x| (f(x) - f(&mean)).powi(2)).sum::<f64>()
            };
            Complex64::new(var(|z| z.re).sqrt(), var(|z| z.im).sqrt())
        })
        .collect();
    (g, se)
}

#[allow(dead_code)] // the workspace's test includes this file as a module
fn main() {
    for (s, light) in [
        (Setup::example(), "a plane wave"),
        (Setup::beam_example(), "a beam of NA 0.5 focused 1 mfp deep"),
    ] {
        print_g1(&s, light);
    }
}

fn print_g1(s: &Setup, light: &str) {
    let (g, se) = g1(s, &LAGS, 400_000, 1);
    println!(
        "g1 of a slab of drifting Brownian scatterers lit by {light}, 20 degrees off the axis \
         in transmission:"
    );
    for ((t, g), se) in LAGS.iter().zip(&g).zip(&se) {
        println!(
            "  t = {t:>4}: g1 = {:.4} {:+.4}i (+- {:.4}, {:.4}), |g1| = {:.4}",
            g.re,
            g.im,
            se.re,
            se.im,
            g.norm()
        );
    }
}
