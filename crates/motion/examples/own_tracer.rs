//! `g1` from your own path tracer, with `speckle-motion` alone.
//!
//! A minimal tracer (its own random numbers, geometry and sampling; nothing else of speckle)
//! estimates the temporal field correlation `g1(t)` of the light a slab of drifting Brownian
//! scatterers sends into one far-field direction:
//!
//! - a plane wave along `+z` lights the face `z = 0` of a box (`x, y` in `[-W/2, W/2]`, `z` in
//!   `[0, L]`) of isotropic scatterers (`sigma_s`, `sigma_a`); light tracing from the face, the
//!   weight multiplied by the albedo at each collision, Russian roulette below 0.1;
//! - at every vertex `x_b` a next-event connection to the far-field direction `v`: the
//!   contribution `w rho e^{-sigma_t d}` (`rho = 1 / 4 pi`, `d` the distance out of the box along
//!   `v`), forward paths only (no coherent backscattering: `v` is a transmission direction);
//! - the decorrelation of each contribution at lag `t` (Bar et al. 2023, Eq. 14), in the hybrid
//!   exact-drift scheme: copy 1 connects its end vertices from `x - t U / 2`, copy 2 from
//!   `x + t U / 2`, with their exact legs `A_1 conj(A_2)` (the fields of the plane wave at `x_1`
//!   and of the far-field leg from `x_b`, attenuated, relative to their intensity at rest); the
//!   interior vertices from
//!   [`MotionState`] (started at `x1`, advanced at each vertex; its drift sum telescopes the
//!   interior); the end vertices' Brownian transfers `w1 - i` and `v - w_in` ([`first_transfer`],
//!   [`last_transfer`] with the endpoints' [`source_gradient`] and [`sensor_gradient`]), a
//!   single-scattering path's `v - i` ([`single_transfer`]); a path whose vertex the flow takes
//!   out of the box at either time contributes nothing at that lag.
//!
//! `g1(t) = sum c F(t) / sum c` over every contribution `c` and its complex factor `F(t)`, with
//! the standard errors of its parts by the jackknife over 32 batches of paths. The workspace's test
//! `tests/embed_g1.rs` runs [`g1`] against `speckle_estimators::render_correlation` on the same
//! scene. Run it:
//!
//! `cargo run --release -p speckle-motion --example own_tracer`

use speckle_motion::glam::DVec3;
use speckle_motion::num_complex::Complex64;
use speckle_motion::{
    Motion, MotionState, first_transfer, gamma, last_transfer, sensor_gradient, single_transfer,
    source_gradient,
};

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
    // The end vertices' Brownian factors (their drift is in the displaced connections below).
    let brownian = Motion::brownian(s.diffusion).expect("a valid diffusion");
    let (i, v, k) = (DVec3::Z, s.sensor, s.k);
    let (gs, gv) = (source_gradient(i), sensor_gradient(v));
    // The field of the two legs of a contribution whose first vertex is `a` and last `b`: the
    // plane wave `e^{i k i . a}` attenuated from the face, the far-field leg `e^{-i k v . b}`
    // attenuated to the box's exit.
    let legs = |a: DVec3, b: DVec3| {
        let att = (-0.5 * sigma_t * (a.z + s.exit_distance(b, v))).exp();
        Complex64::from_polar(att, k * (i.dot(a) - v.dot(b)))
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
    // Whether every vertex so far lies in the box at both times of each lag (a scatterer that
    // the flow takes out of the box is not in the medium then).
    let mut inside = vec![true; lags.len()];
    for b in 1u32.. {
        x += dir * (-(1.0 - rng.next_f64()).ln() / sigma_t);
        if !s.inside(x) {
            return;
        }
        w *= albedo;
        if b == 1 {
            state = MotionState::start(m);
            x1 = x;
        } else {
            state.advance(b, m, dir);
        }
        // The next-event connection to the far field, at rest (the flights sampled the
        // attenuation to x1: the weight carries it), and the legs' intensity at rest, which the
        // displaced connections below are relative to.
        let c = w * rho * (-sigma_t * s.exit_distance(x, v)).exp();
        let rest = legs(x1, x).norm_sqr();
        *den += c;
        for ((out, &t), inside) in num.iter_mut().zip(lags).zip(&mut inside) {
            // Copy 1 (read at -t/2) connects its end vertices from x - t U / 2, copy 2 from
            // x + t U / 2, each with its exact legs (the hybrid exact-drift scheme).
            let half = 0.5 * t * s.drift;
            *inside = *inside && s.inside(x - half) && s.inside(x + half);
            if !*inside {
                continue;
            }
            let ends = legs(x1 - half, x - half) * legs(x1 + half, x + half).conj() / rest;
            let f = if b == 1 {
                gamma(k, &brownian, single_transfer(gs + gv, gs + gv), t)
            } else {
                gamma(k, &brownian, first_transfer(state.w1, gs, gs), t)
                    * state.interior(k, t)
                    * gamma(k, &brownian, last_transfer(dir, gv, gv), t)
            };
            *out += c * ends * f;
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
    let s = Setup::example();
    let (g, se) = g1(&s, &LAGS, 400_000, 1);
    println!(
        "g1 of a slab of drifting Brownian scatterers, 20 degrees off the axis in transmission:"
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
