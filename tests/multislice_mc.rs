//! Multi-slice beam propagation (`speckle::wave::render_multislice`) against the Monte Carlo
//! (`render_intensity`) on flatland slabs far wider than the Foldy-Lax solver can take, in
//! absolute units with no fitted factor (Bar et al. 2020, Fig. 11 right; issue 28).
//!
//! Units: both renderers take the same `Scene` and report the far-field amplitude's convention
//! of `docs/conventions.md` (`u(R v) = A e^{ikR} / sqrt(R)`), so the multi-slice covariance
//! diagonal (centred over configurations) and the Monte Carlo's `total` (the speckle
//! covariance, the mean excluded) are compared directly, as `tests/wave_validation.rs` compares
//! the Foldy-Lax solver with the Monte Carlo.
//!
//! Far-field sensors every `step` degrees (wider than the speckle grain `lambda / W` rad, so
//! nearly independent within one configuration) are pooled into bins of `|theta|`; per
//! configuration, a bin's value is the mean centred intensity `|u - <u>|^2 R / (R - 1)` of its
//! sensors, and its standard error comes from the spread over configurations. The Monte
//! Carlo's value is the mean of its sensors' intensities, with the mean of their standard
//! errors as a conservative standard error (its sensors see the same paths and are correlated).
//!
//! Three Monte Carlo renders of the same scene:
//! - **all paths** (`Coherence::ForwardOnly`, the ladder; in transmission the reversed terms
//!   are negligible for a slab hundreds of wavelengths wide): what the exact solution would
//!   give;
//! - **depth-monotone paths** (a [`PathFactor`] that zeroes a path once one of its flights
//!   travels backwards, `w . d <= 0`): the paths that a forward-only method can represent;
//! - **depth-monotone within the aperture**: the same, with every interior flight also weighted
//!   by the square of multi-slice's screen aperture (full up to 75 degrees from the axis,
//!   `cos^2` to 0 at 85: light a screen sends wider never joins the grid).
//!
//! The difference "all minus depth-monotone" is the Monte Carlo's share of the intensity in
//! paths that ever travel backwards: exactly what multi-slice drops.
//!
//! - `multislice_is_the_depth_monotone_monte_carlo_on_a_wide_slab` (CI, about 12 s): a 300 x
//!   75 wavelength slab at optical depth 1 (about 470 scatterers per configuration), 60
//!   configurations, multi-slice with no aperture (90 degrees); every `|theta|` bin of 10
//!   degrees from 1 to 80 agrees with the depth-monotone Monte Carlo within 4.5 combined SE
//!   (measured: largest 1.75), and multi-slice is below the full Monte Carlo by more than 5 SE
//!   wherever the backward share exceeds 10 SE (measured: the share is 28-30% at every angle,
//!   multi-slice 15 to 23 SE below).
//! - `heavy_slab_od_*` (ignored; `--ignored --test-threads=1`, 2.5-6 minutes each on 2 cores):
//!   the shipped slab at optical depths 0.5, 1 and 2 with multi-slice's default 85 degree
//!   aperture, 100 configurations of 1600 to 6300 scatterers. The aperture drops the interior
//!   light a screen sends beyond 75-85 degrees but also the extinction of such light by the
//!   scatterers it would reach, so multi-slice lies between the depth-monotone Monte Carlo
//!   with and without the aperture weight; the check takes the nearer end, up to 70 degrees.
//!   Beyond, multi-slice rises above both (at 70-80 degrees and optical depth 1, 109 against
//!   95 and 89): an outgoing wave that wide is extinguished by the downstream scatterers it
//!   excites through the grid, which the aperture cuts, while the Monte Carlo attenuates the
//!   last flight fully. With no aperture (the CI case) the 70-80 degree bin agrees too.
//!
//! `cargo test --profile ci --test multislice_mc -- --nocapture` prints the tables;
//! `docs/experiments-2020.md` ("Multi-slice on a slab of thousands of wavelengths") has the
//! heavy cases' numbers.

mod common_slab;

use common_slab::slab;
use speckle::estimators::{
    Coherence, CovarianceEstimate, CovarianceOptions, NoProgress, render_intensity_with,
};
use speckle::medium::DVec3;
use speckle::paths::{NoFactor, PathFactor, Vertex};
use speckle::wave::{MultisliceOptions, render_multislice};
use std::time::Instant;

/// Zeroes a path once a flight travels against the incident direction `+y` and, with an
/// aperture `(pass, cut)` (radians from `+y`), weights every flight by the square of
/// multi-slice's screen aperture: 1 up to `pass`, `cos^2` in the angle to 0 at `cut`.
struct ForwardPaths {
    aperture: Option<(f64, f64)>,
}

impl ForwardPaths {
    fn flight(&self, w: DVec3) -> f64 {
        if w.y <= 0.0 {
            return 0.0;
        }
        let Some((pass, cut)) = self.aperture else {
            return 1.0;
        };
        let angle = w.x.abs().atan2(w.y);
        if angle <= pass {
            1.0
        } else if angle >= cut {
            0.0
        } else {
            let x = (angle - pass) / (cut - pass);
            (0.5 * std::f64::consts::PI * x).cos().powi(4)
        }
    }
}

impl PathFactor for ForwardPaths {
    type State = f64;
    type Value = f64;
    fn start(&self, state: &mut f64, _x1: DVec3, _ty: usize) -> f64 {
        *state = 1.0;
        1.0
    }
    fn vertex(&self, state: &mut f64, v: &Vertex) -> f64 {
        *state *= self.flight(v.w_in);
        *state
    }
}

/// One bin of `|theta|`: multi-slice and the three Monte Carlo renders, each with its SE.
#[derive(Debug, Clone, Copy)]
struct Bin {
    lo: f64,
    hi: f64,
    ms: (f64, f64),
    all: (f64, f64),
    monotone: (f64, f64),
    aperture: (f64, f64),
}

impl Bin {
    /// `(a - b) / sqrt(sa^2 + sb^2)`.
    fn z(a: (f64, f64), b: (f64, f64)) -> f64 {
        (a.0 - b.0) / a.1.hypot(b.1)
    }
}

/// A comparison's settings.
struct Case {
    width: f64,
    depth: f64,
    mean_free_path: f64,
    /// Sensors every `step` degrees from `-max` to `max` (|theta| >= `min`).
    step: f64,
    min: f64,
    max: f64,
    /// Bin width in degrees.
    bin: f64,
    /// Multi-slice's screen aperture in degrees ([`MultisliceOptions::aperture`]).
    aperture: f64,
    configurations: usize,
    paths: u64,
    seed: u64,
}

fn compare(c: &Case) -> Vec<Bin> {
    let n = (c.max / c.step).round() as i64;
    let degrees: Vec<f64> = (-n..=n)
        .map(|i| i as f64 * c.step)
        .filter(|d| d.abs() >= c.min - 1e-9)
        .collect();
    let scene = slab(c.width, c.depth, c.mean_free_path, &degrees);
    let t = Instant::now();
    let mut options = MultisliceOptions::new(&scene, c.configurations, c.seed);
    options.aperture = c.aperture;
    let ms = render_multislice(&scene, &options, &NoProgress).unwrap();
    let t_ms = t.elapsed();
    let mc_options = CovarianceOptions {
        paths: c.paths,
        seed: c.seed + 1,
        coherence: Coherence::ForwardOnly,
        ..Default::default()
    };
    let t = Instant::now();
    let all = render_intensity_with(&scene, &mc_options, &NoFactor, &NoProgress).unwrap();
    let t_mc = t.elapsed();
    let monotone = render_intensity_with(
        &scene,
        &mc_options,
        &ForwardPaths { aperture: None },
        &NoProgress,
    )
    .unwrap();
    // The aperture-weighted render only where the aperture cuts (below 90 degrees).
    let cut = options.aperture.to_radians();
    let pass = (options.aperture - speckle::wave::APERTURE_ROLLOFF).to_radians();
    let aperture = (c.aperture < 90.0).then(|| {
        render_intensity_with(
            &scene,
            &mc_options,
            &ForwardPaths {
                aperture: Some((pass, cut)),
            },
            &NoProgress,
        )
        .unwrap()
    });
    println!(
        "slab {} x {} (optical depth {:.2}), {:.0} scatterers per configuration: multi-slice {} \
         configurations in {t_ms:.2?}, Monte Carlo {} paths in {t_mc:.2?} per render",
        c.width,
        c.depth,
        c.depth / c.mean_free_path,
        ms.mean_scatterers,
        c.configurations,
        c.paths
    );
    let r = c.configurations as f64;
    let bins = (c.max / c.bin).ceil() as usize;
    let mut out = Vec::new();
    for b in 0..bins {
        let (lo, hi) = (b as f64 * c.bin, (b + 1) as f64 * c.bin);
        let members: Vec<usize> = degrees
            .iter()
            .enumerate()
            .filter(|(_, d)| d.abs() >= lo && d.abs() < hi)
            .map(|(j, _)| j)
            .collect();
        if members.is_empty() {
            continue;
        }
        let m = members.len() as f64;
        let per_config: Vec<f64> = (0..c.configurations)
            .map(|row| {
                members
                    .iter()
                    .map(|&j| (ms.fields.get(row, j) - ms.mean[j]).norm_sqr())
                    .sum::<f64>()
                    * r
                    / ((r - 1.0) * m)
            })
            .collect();
        let mean = per_config.iter().sum::<f64>() / r;
        let var = per_config.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (r - 1.0);
        let mc = |e: &CovarianceEstimate| {
            let v = members
                .iter()
                .map(|&j| e.total.value.get(j, 0).re)
                .sum::<f64>();
            let s = members
                .iter()
                .map(|&j| e.total.std_error.get(j, 0).re)
                .sum::<f64>();
            (v / m, s / m)
        };
        out.push(Bin {
            lo,
            hi,
            ms: (mean, (var / r).sqrt()),
            all: mc(&all),
            monotone: mc(&monotone),
            aperture: mc(aperture.as_ref().unwrap_or(&monotone)),
        });
    }
    println!(
        "  |theta| deg  multi-slice       MC all paths      MC depth-monotone  \
         MC monotone+aperture  z(MS-all) z(MS-mono+ap) backward share"
    );
    for b in &out {
        println!(
            "  {:4.0}-{:<4.0} {:8.3} +- {:6.3} {:8.3} +- {:6.3} {:8.3} +- {:6.3} {:8.3} +- {:6.3} \
             {:8.2} {:8.2} {:6.1}%",
            b.lo,
            b.hi,
            b.ms.0,
            b.ms.1,
            b.all.0,
            b.all.1,
            b.monotone.0,
            b.monotone.1,
            b.aperture.0,
            b.aperture.1,
            Bin::z(b.ms, b.all),
            Bin::z(b.ms, b.aperture),
            100.0 * (1.0 - b.monotone.0 / b.all.0)
        );
    }
    out
}

/// The checks shared by the CI and heavy cases, on the bins below `max_angle` degrees:
/// multi-slice agrees within 4.5 combined SE with the depth-monotone Monte Carlo (`bracket`
/// false) or with the nearer end of the interval between the depth-monotone Monte Carlo with
/// and without the aperture (`bracket` true, multi-slice's default 85 degree aperture: see the
/// module docs); and wherever the backward share (all paths minus the restricted render with
/// the aperture) exceeds 10 combined SE, multi-slice falls below the full Monte Carlo by more
/// than 5.
fn check(bins: &[Bin], bracket: bool, max_angle: f64) {
    let mut departures = 0;
    for b in bins.iter().filter(|b| b.hi <= max_angle + 1e-9) {
        let z = if bracket {
            let (lo, hi) = (b.aperture, b.monotone);
            if b.ms.0 < lo.0 {
                Bin::z(b.ms, lo)
            } else if b.ms.0 > hi.0 {
                Bin::z(b.ms, hi)
            } else {
                0.0
            }
        } else {
            Bin::z(b.ms, b.monotone)
        };
        assert!(
            z.abs() < 4.5,
            "{}-{} deg: multi-slice {:?} against the depth-monotone Monte Carlo {:?} (with the \
             aperture {:?}): z {z:.2}",
            b.lo,
            b.hi,
            b.ms,
            b.monotone,
            b.aperture
        );
        let share = (b.all.0 - b.monotone.0.max(b.aperture.0)) / b.ms.1.hypot(b.all.1);
        if share > 10.0 {
            departures += 1;
            let z = Bin::z(b.all, b.ms);
            assert!(
                z > 5.0,
                "{}-{} deg: the backward share is {share:.1} SE but multi-slice is only {z:.2} \
                 SE below the Monte Carlo",
                b.lo,
                b.hi
            );
        }
    }
    assert!(departures > 0, "no bin with a large backward share");
}

/// CI: a 300 x 75 wavelength slab at optical depth 1 (about 470 scatterers, far beyond what
/// the tests of `tests/multislice.rs` give the Foldy-Lax solver), multi-slice with no aperture
/// (90 degrees: every screen's field joins the grid at any angle), so that it represents every
/// depth-monotone path, and the Monte Carlo.
#[test]
fn multislice_is_the_depth_monotone_monte_carlo_on_a_wide_slab() {
    let bins = compare(&Case {
        width: 300.0,
        depth: 75.0,
        mean_free_path: 75.0,
        step: 0.5,
        min: 1.0,
        max: 80.0,
        bin: 10.0,
        aperture: 90.0,
        configurations: 60,
        paths: 100_000,
        seed: 28,
    });
    check(&bins, false, 80.0);
}

/// The shipped slab (`scenes/fig11_multislice_slab.toml`, 2000 x 500 wavelengths) at optical
/// depth `od`, multi-slice with its default aperture (85 degrees); bins up to 70 degrees (see
/// the module docs: beyond, the aperture also weakens the extinction of the outgoing light).
fn heavy(od: f64) {
    let bins = compare(&Case {
        width: 2000.0,
        depth: 500.0,
        mean_free_path: 500.0 / od,
        step: 0.25,
        min: 1.0,
        max: 80.0,
        bin: 10.0,
        aperture: 85.0,
        configurations: 100,
        paths: 200_000,
        seed: 2020,
    });
    check(&bins, true, 70.0);
}

#[test]
#[ignore]
fn heavy_slab_od_half() {
    heavy(0.5);
}

#[test]
#[ignore]
fn heavy_slab_od_1() {
    heavy(1.0);
}

#[test]
#[ignore]
fn heavy_slab_od_2() {
    heavy(2.0);
}
