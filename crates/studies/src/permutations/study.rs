//! The throughputs of three-vertex paths in flatland, the Fig. 15 phase maps and the Fig. 16
//! integrals (Eq. 58) of a [`PermutationsStudy`].

use super::PermutationsStudy;
use crate::StudyError;
use crate::memory::Array;
use glam::DVec2;
use serde_json::{Value, json};
use speckle_phase::Complex64;
use speckle_stats::jackknife::jackknife;
use speckle_stats::{PathRng, Progress, run_ordered};
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::time::Instant;

/// The six orders in which the second path visits `(x_1, x_2, x_3)` (0-based): forward,
/// reversed, then the four that the covariance's path integral neglects.
pub const PERMUTATIONS: [[usize; 3]; 6] = [
    [0, 1, 2],
    [2, 1, 0],
    [1, 0, 2],
    [0, 2, 1],
    [1, 2, 0],
    [2, 0, 1],
];

/// The names of [`PERMUTATIONS`], in the paper's 1-based numbering.
pub const NAMES: [&str; 6] = ["forward 123", "reversed 321", "213", "132", "231", "312"];

/// `k` with lengths in wavelengths.
const K: f64 = TAU;
/// The flatland isotropic amplitude `s = 1 / sqrt(2 pi)` cubed (three vertices).
const S3: f64 = 0.063_493_635_934_240_97;

/// The optical length of the path `i -> x_a -> x_b -> x_c -> v`: `i.x_a + |x_b - x_a| +
/// |x_c - x_b| - v.x_c` (the phase of its throughput over `k`).
pub fn optical_length(i: DVec2, v: DVec2, x: [DVec2; 3]) -> f64 {
    i.dot(x[0]) + x[0].distance(x[1]) + x[1].distance(x[2]) - v.dot(x[2])
}

/// The flatland throughput of `i -> x_a -> x_b -> x_c -> v` (lengths in wavelengths):
/// `e^{ik i.x_a} s G(x_a, x_b) s G(x_b, x_c) s e^{-ik v.x_c}`, `G(r) = e^{ikr} / sqrt(r)`,
/// `s = 1 / sqrt(2 pi)`, no attenuation (Eqs. 23-25 with `tau = 1`).
pub fn throughput(i: DVec2, v: DVec2, x: [DVec2; 3]) -> Complex64 {
    let amplitude = S3 / (x[0].distance(x[1]) * x[1].distance(x[2])).sqrt();
    Complex64::from_polar(amplitude, K * optical_length(i, v, x))
}

/// `x` visited in the order `p`.
fn order(x: [DVec2; 3], p: [usize; 3]) -> [DVec2; 3] {
    [x[p[0]], x[p[1]], x[p[2]]]
}

/// The pairwise throughput `mu(x) mu(x_P)^*`, its phase as `k (L(x) - L(x_P))` (the lengths
/// subtracted before the multiplication by `k`, which keeps the rounding of a phase of `k L ~
/// 1e3` rad out of the difference).
fn pair(i: DVec2, v: DVec2, x: [DVec2; 3], p: [usize; 3]) -> Complex64 {
    let y = order(x, p);
    let amplitude = S3 * S3
        / (x[0].distance(x[1]) * x[1].distance(x[2]) * y[0].distance(y[1]) * y[1].distance(y[2]))
            .sqrt();
    Complex64::from_polar(
        amplitude,
        K * (optical_length(i, v, x) - optical_length(i, v, y)),
    )
}

/// `a` wrapped to `(-pi, pi]`.
fn wrap(a: f64) -> f64 {
    let w = a - TAU * (a / TAU).round();
    if w <= -PI { w + TAU } else { w }
}

/// How much the phase of a Fig. 15 map varies over `x_3`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapStats {
    /// Largest `|wrap(phi - phi_0)|` over the map, `phi_0` its first pixel's (radians): 0 for
    /// a constant phase, at most `pi`.
    pub deviation: f64,
    /// Largest range of the phase along a row of pixels, unwrapped from neighbour to neighbour
    /// (radians): the variation the wrapped `deviation` cannot show.
    pub excursion: f64,
    /// `|mean e^{i phi}|` over the map: 1 for a constant phase, near 0 when it winds.
    pub mean_phasor: f64,
}

fn map_stats(phases: &[f64], n: usize) -> MapStats {
    let first = phases[0];
    let deviation = phases
        .iter()
        .map(|&p| wrap(p - first).abs())
        .fold(0.0, f64::max);
    let mut excursion: f64 = 0.0;
    for row in phases.chunks_exact(n) {
        let (mut u, mut lo, mut hi) = (0.0, 0.0f64, 0.0f64);
        for w in row.windows(2) {
            u += wrap(w[1] - w[0]);
            lo = lo.min(u);
            hi = hi.max(u);
        }
        excursion = excursion.max(hi - lo);
    }
    let sum = phases.iter().fold(Complex64::new(0.0, 0.0), |s, &p| {
        s + Complex64::from_polar(1.0, p)
    });
    MapStats {
        deviation,
        excursion,
        mean_phasor: sum.norm() / phases.len() as f64,
    }
}

/// One viewing direction's maps and integrals.
#[derive(Debug, Clone)]
pub struct ViewResult {
    /// Its angle from backscattering, degrees.
    pub offset_deg: f64,
    /// The direction `v`.
    pub v: DVec2,
    /// Fig. 15: the phase of `mu(x) mu(x_P)^*` in `(-pi, pi]`, `[permutation][row][column]`,
    /// `x_3` at the cell centre `((column + 1/2) h, (row + 1/2) h)`, `h = side / pixels`.
    pub phases: Vec<f64>,
    /// Each map's variation.
    pub stats: [MapStats; 6],
    /// Fig. 16: `I_P / I_id` per permutation.
    pub ratio: [Complex64; 6],
    /// Jackknife standard errors of its real and imaginary parts.
    pub ratio_se: [(f64, f64); 6],
    /// `|I_P / I_id|`.
    pub magnitude: [f64; 6],
    /// Its jackknife standard error.
    pub magnitude_se: [f64; 6],
    /// `I_id = iint |mu|^2 dx_2 dx_3` (wavelengths^2 x the flatland units of `mu`), with its
    /// standard error.
    pub identity: (f64, f64),
}

/// The result of a study: one entry per viewing direction.
#[derive(Debug, Clone)]
pub struct Permutations {
    /// In the order of `view_offsets_deg`.
    pub views: Vec<ViewResult>,
    /// The share of samples with both `x_2` and `x_3` inside the square.
    pub accepted: f64,
    /// Wall time, seconds.
    pub wall: f64,
}

impl PermutationsStudy {
    /// The plane wave's direction `i`.
    pub fn illumination(&self) -> DVec2 {
        let a = self.file.illumination_deg.to_radians();
        DVec2::new(a.cos(), a.sin())
    }

    /// The viewing direction `-i` turned by `offset_deg`.
    pub fn view(&self, offset_deg: f64) -> DVec2 {
        let a = (self.file.illumination_deg + 180.0 + offset_deg).to_radians();
        // At 0 offset exactly -i, so that backscattering is exact.
        if offset_deg == 0.0 {
            -self.illumination()
        } else {
            DVec2::new(a.cos(), a.sin())
        }
    }

    /// Rough memory and time on `threads` threads.
    pub fn estimate(&self, threads: usize) -> speckle_scene::cost::Estimate {
        let f = &self.file;
        let views = f.view_offsets_deg.len() as f64;
        let maps = views * 6.0 * (f.pixels * f.pixels) as f64;
        speckle_scene::cost::Estimate {
            bytes: 8.0 * maps * 3.0 + 1e6,
            memory_field: "pixels".into(),
            seconds: (2e-8 * maps + 2.5e-7 * views * f.render.samples as f64)
                / threads.max(1) as f64,
            time_field: "render.samples".into(),
            vertices_per_path: 0.0,
        }
    }

    /// The Fig. 15 maps and the Fig. 16 integrals of every viewing direction; `progress`
    /// counts samples and may cancel.
    pub fn render(&self, progress: &dyn Progress) -> Result<Permutations, StudyError> {
        let start = Instant::now();
        let f = &self.file;
        let i = self.illumination();
        let vs: Vec<DVec2> = f.view_offsets_deg.iter().map(|&o| self.view(o)).collect();
        let (x1, x2) = (DVec2::from(f.x1), DVec2::from(f.x2));
        let (n, h) = (f.pixels, f.side / f.pixels as f64);
        let maps: Vec<Vec<f64>> = vs
            .iter()
            .map(|&v| {
                let mut m = Vec::with_capacity(6 * n * n);
                for p in PERMUTATIONS {
                    for r in 0..n {
                        for c in 0..n {
                            let x3 = DVec2::new((c as f64 + 0.5) * h, (r as f64 + 0.5) * h);
                            let y = order([x1, x2, x3], p);
                            // The magnitudes are positive: the phase is k (L - L_P).
                            let d = optical_length(i, v, [x1, x2, x3]) - optical_length(i, v, y);
                            m.push(Complex64::from_polar(1.0, K * d).arg());
                        }
                    }
                }
                m
            })
            .collect();
        // Fig. 16: sums per group, [view][permutation].
        let groups = f.render.groups;
        let total = f.render.samples;
        let range =
            |g: usize| (g as u64 * total / groups as u64)..((g as u64 + 1) * total / groups as u64);
        let mut sums: Vec<(Vec<[Complex64; 6]>, u64)> = Vec::with_capacity(groups);
        let done = run_ordered(
            groups,
            16 * 6 * vs.len() + 8,
            |g| {
                if progress.cancelled() {
                    return None;
                }
                let s = self.sample_group(range(g), i, &vs);
                progress.advance(range(g).end - range(g).start);
                Some(s)
            },
            |_, s| sums.push(s),
        );
        if !done {
            return Err(speckle_estimators::EstimatorError::Cancelled.into());
        }
        let accepted = sums.iter().map(|s| s.1).sum::<u64>() as f64 / total as f64;
        let nv = vs.len();
        // Per view and permutation: Re, Im, |.| of I_P / I_id; per view: I_id.
        let statistic = |skip: Option<usize>| -> Vec<f64> {
            let mut out = Vec::with_capacity(nv * 19);
            let kept: u64 = (0..groups)
                .filter(|&g| Some(g) != skip)
                .map(|g| range(g).end - range(g).start)
                .sum();
            for w in 0..nv {
                let mut t = [Complex64::new(0.0, 0.0); 6];
                for (g, s) in sums.iter().enumerate() {
                    if Some(g) != skip {
                        for (a, b) in t.iter_mut().zip(&s.0[w]) {
                            *a += b;
                        }
                    }
                }
                for z in t {
                    let r = z / t[0].re;
                    out.extend([r.re, r.im, r.norm()]);
                }
                out.push(t[0].re / kept as f64);
            }
            out
        };
        let (value, se) = jackknife(groups, statistic);
        let views = vs
            .iter()
            .zip(maps)
            .enumerate()
            .map(|(w, (&v, phases))| {
                let at = |j: usize| w * 19 + j;
                let stats =
                    std::array::from_fn(|p| map_stats(&phases[p * n * n..(p + 1) * n * n], n));
                ViewResult {
                    offset_deg: f.view_offsets_deg[w],
                    v,
                    phases,
                    stats,
                    ratio: std::array::from_fn(|p| {
                        Complex64::new(value[at(3 * p)], value[at(3 * p + 1)])
                    }),
                    ratio_se: std::array::from_fn(|p| (se[at(3 * p)], se[at(3 * p + 1)])),
                    magnitude: std::array::from_fn(|p| value[at(3 * p + 2)]),
                    magnitude_se: std::array::from_fn(|p| se[at(3 * p + 2)]),
                    identity: (value[at(18)], se[at(18)]),
                }
            })
            .collect();
        Ok(Permutations {
            views,
            accepted,
            wall: start.elapsed().as_secs_f64(),
        })
    }

    /// The sums of `mu(x) mu(x_P)^* / (p(x_2) p(x_3))` over the samples `n` of `samples`
    /// (each from `PathRng::new(seed, n)`), per view and permutation, and how many samples
    /// fell inside. `x_2 = x_1 + r (cos t, sin t)` with `t` uniform and `r` uniform in `[0,
    /// R(x_1)]`, `R` the distance to the square's farthest corner, so `p(x_2) = 1 / (2 pi R
    /// r_12)`: the `1 / r` of the two shared segments cancels and the weights of the forward
    /// and reversed orders are constant; `x_3` likewise about `x_2`. A sample outside the
    /// square adds 0.
    fn sample_group(
        &self,
        samples: std::ops::Range<u64>,
        i: DVec2,
        vs: &[DVec2],
    ) -> (Vec<[Complex64; 6]>, u64) {
        let f = &self.file;
        let side = f.side;
        let inside = |x: DVec2| (0.0..=side).contains(&x.x) && (0.0..=side).contains(&x.y);
        let far = |x: DVec2| x.max(DVec2::splat(side) - x).length();
        let x1 = DVec2::from(f.x1);
        let r1 = far(x1);
        let mut sums = vec![[Complex64::new(0.0, 0.0); 6]; vs.len()];
        let mut accepted = 0;
        for s in samples {
            let mut rng = PathRng::new(f.render.seed, s);
            let [a, b] = rng.next_2();
            let [c, d] = rng.next_2();
            let r12 = r1 * a;
            let x2 = x1 + r12 * DVec2::from_angle(TAU * b);
            if r12 == 0.0 || !inside(x2) {
                continue;
            }
            let r2 = far(x2);
            let r23 = r2 * c;
            let x3 = x2 + r23 * DVec2::from_angle(TAU * d);
            if r23 == 0.0 || !inside(x3) {
                continue;
            }
            accepted += 1;
            let inverse_pdf = TAU * TAU * r1 * r2 * r12 * r23;
            for (sum, &v) in sums.iter_mut().zip(vs) {
                for (t, p) in sum.iter_mut().zip(PERMUTATIONS) {
                    *t += pair(i, v, [x1, x2, x3], p) * inverse_pdf;
                }
            }
        }
        (sums, accepted)
    }
}

impl Permutations {
    /// The output arrays (float64, C order).
    pub fn arrays(&self, s: &PermutationsStudy) -> Vec<Array> {
        let (nv, n) = (self.views.len(), s.file.pixels);
        let per_view = |f: &dyn Fn(&ViewResult) -> Vec<f64>| -> Vec<f64> {
            self.views.iter().flat_map(f).collect()
        };
        vec![
            Array {
                key: "phases",
                shape: vec![nv, 6, n, n],
                data: per_view(&|v| v.phases.clone()),
                content: "Fig. 15: arg(mu(x) mu(x_P)^*) in (-pi, pi] [view, permutation, row, \
                          column], x_3 = ((column + 1/2) h, (row + 1/2) h), h = side / pixels",
            },
            Array {
                key: "map_stats",
                shape: vec![nv, 6, 3],
                data: per_view(&|v| {
                    v.stats
                        .iter()
                        .flat_map(|m| [m.deviation, m.excursion, m.mean_phasor])
                        .collect()
                }),
                content: "per map: largest wrapped deviation from the first pixel (rad), \
                          largest unwrapped range along a row (rad), |mean exp(i phase)|",
            },
            Array {
                key: "ratios",
                shape: vec![nv, 6],
                data: per_view(&|v| v.magnitude.to_vec()),
                content: "Fig. 16: |I_P / I_id|, I_P = iint mu(x) mu(x_P)^* dx_2 dx_3 \
                          [view, permutation]",
            },
            Array {
                key: "ratios_stderr",
                shape: vec![nv, 6],
                data: per_view(&|v| v.magnitude_se.to_vec()),
                content: "jackknife standard errors of ratios",
            },
            Array {
                key: "ratios_complex",
                shape: vec![nv, 6, 2],
                data: per_view(&|v| v.ratio.iter().flat_map(|z| [z.re, z.im]).collect()),
                content: "I_P / I_id: real and imaginary parts [view, permutation, part]",
            },
            Array {
                key: "ratios_complex_stderr",
                shape: vec![nv, 6, 2],
                data: per_view(&|v| v.ratio_se.iter().flat_map(|&(a, b)| [a, b]).collect()),
                content: "jackknife standard errors of ratios_complex",
            },
            Array {
                key: "identity_integral",
                shape: vec![nv, 2],
                data: per_view(&|v| vec![v.identity.0, v.identity.1]),
                content: "I_id = iint |mu|^2 dx_2 dx_3 (lengths in wavelengths) and its \
                          standard error [view, value | stderr]",
            },
            Array {
                key: "permutations",
                shape: vec![6, 3],
                data: PERMUTATIONS
                    .iter()
                    .flat_map(|p| p.map(|j| (j + 1) as f64))
                    .collect(),
                content: "the vertex order of the second path per permutation (1-based)",
            },
        ]
    }

    /// A summary for the terminal.
    pub fn text(&self, s: &PermutationsStudy) -> String {
        let mut t = String::new();
        for v in &self.views {
            let _ = writeln!(
                t,
                "{}: view {:+} deg from backscattering: |I_P / I_id| +- SE, and the phase map's \
                 range over x3",
                s.name, v.offset_deg
            );
            for (p, name) in NAMES.iter().enumerate() {
                let _ = writeln!(
                    t,
                    "  {name:>12}: {:.4e} +- {:.1e}; map deviation {:.2e} rad, row range {:.1} rad",
                    v.magnitude[p], v.magnitude_se[p], v.stats[p].deviation, v.stats[p].excursion
                );
            }
        }
        t
    }

    /// The sidecar, with `files` (what the caller wrote, by key).
    pub fn describe(&self, s: &PermutationsStudy, files: Value, threads: usize) -> Value {
        let i = s.illumination();
        json!({
            "command": "permutations",
            "study_file": s.origin,
            "study": serde_json::to_value(&s.file).unwrap_or(Value::Null),
            "model": "flatland, lengths in wavelengths (k = 2 pi): mu = e^{ik i.x_a} s \
                      e^{ik r_ab}/sqrt(r_ab) s e^{ik r_bc}/sqrt(r_bc) s e^{-ik v.x_c}, \
                      isotropic s = 1/sqrt(2 pi), no attenuation",
            "illumination": [i.x, i.y],
            "permutations": NAMES,
            "render": {
                "samples": s.file.render.samples,
                "groups": s.file.render.groups,
                "seed": s.file.render.seed,
                "sampling": "x_2 about x_1 and x_3 about x_2 with density 1 / (2 pi R r), R \
                             the distance to the square's farthest corner; outside adds 0; \
                             sample n from PathRng::new(seed, n)",
                "accepted": self.accepted,
                "threads": threads,
                "wall_time_s": self.wall,
            },
            "views": self.views.iter().map(|v| json!({
                "offset_deg": v.offset_deg,
                "direction": [v.v.x, v.v.y],
                "ratio": v.magnitude,
                "ratio_stderr": v.magnitude_se,
                "ratio_re": v.ratio.map(|z| z.re),
                "ratio_im": v.ratio.map(|z| z.im),
                "identity_integral": [v.identity.0, v.identity.1],
                "map_deviation_rad": v.stats.map(|m| m.deviation),
                "map_row_range_rad": v.stats.map(|m| m.excursion),
                "map_mean_phasor": v.stats.map(|m| m.mean_phasor),
            })).collect::<Vec<_>>(),
            "files": files,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pair_is_the_product_of_throughputs() {
        let (i, v) = (DVec2::new(0.6, 0.8), DVec2::new(-0.28, 0.96));
        let x = [
            DVec2::new(1.0, 2.0),
            DVec2::new(3.5, -1.0),
            DVec2::new(-2.0, 0.5),
        ];
        for p in PERMUTATIONS {
            let want = throughput(i, v, x) * throughput(i, v, order(x, p)).conj();
            assert!(
                (pair(i, v, x, p) - want).norm() < 1e-12 * want.norm(),
                "{p:?}"
            );
        }
        assert!((S3 - (TAU).powf(-1.5)).abs() < 1e-17);
    }

    #[test]
    fn wrap_is_in_range() {
        for a in [-7.0, -PI, -1.0, 0.0, PI, 4.0, 1e3] {
            let w = wrap(a);
            let turns = (a - w) / TAU;
            assert!(
                w > -PI && w <= PI && (turns - turns.round()).abs() < 1e-9,
                "{a}"
            );
        }
    }
}
