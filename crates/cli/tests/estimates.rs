//! The cost estimates against measured runs (issue 27, item 8): the time every render prints
//! before it starts (and by which the guard refuses) must hold within a stated factor on
//! reference scenes whose time different parts dominate: the paths, the merges of a large
//! `J x J` covariance's batches and its files, the closed-form mean, the sums of a large
//! intensity render, temporal correlations.
//!
//! The estimates are the speeds of one machine (`speckle_scene::cost`), so a test on another
//! machine cannot hold them to absolute times. What it can hold is their consistency: the
//! ratio of measured to estimated time must be the same, within a factor 3 either way, on every
//! reference scene (a missing or misjudged part of a command's cost, like the 7x and 23x of the
//! issue, breaks it whatever the machine). The ratios themselves are printed (about 0.7-1.9 on
//! the reference machine). All in one test, so that no other test of this file runs beside it.

use speckle::scene::Overrides;
use speckle::scene::cost::Command as Cost;
use std::path::Path;
use std::time::Instant;

mod common;
use common::*;

/// A Gaussian-beam source and a `n x n` grid of beam sensors over a thin slab: `J = n^2`.
fn beam_grid(n: usize, paths: u64) -> String {
    format!(
        r#"
name = "beams"
wavelength = 1.0
[medium]
size = [20.0, 20.0, 6.0]
mean_free_path = 10.0
[phase]
type = "isotropic"
[[sources]]
type = "gaussian_beam"
focus = [0.0, 0.0, -3.0]
concentration = 16.0
[[sensors]]
type = "gaussian_grid"
origin = [-5.0, -5.0, 3.0]
step_x = [0.25, 0.0, 0.0]
step_y = [0.0, 0.25, 0.0]
nx = {n}
ny = {n}
concentration = 16.0
[render]
paths = {paths}
seed = 1
"#
    )
}

/// Seconds of `speckle <command> <scene> --threads 2 -q --out o`, and the estimate of the same
/// command on 2 threads (with the pilot's vertices for detectors, as the command does).
fn measure(dir: &Path, scene: &str, command: &str, cost: Cost) -> (f64, f64) {
    let path = write(dir, "s.toml", scene);
    let p = speckle::scene::load_file(&path, &Overrides::default()).unwrap();
    let measured = speckle::runs::detectors::measured_vertices(&p);
    let estimate = p.estimate_with(cost, 2, measured).unwrap().seconds;
    let start = Instant::now();
    let o = speckle(
        dir,
        &[
            command,
            path.to_str().unwrap(),
            "--threads",
            "2",
            "-q",
            "--out",
            "o",
        ],
    );
    let took = start.elapsed().as_secs_f64();
    assert!(o.status.success(), "{command}: {}", stderr(&o));
    (took, estimate)
}

#[test]
fn time_estimates_hold_within_a_factor_three_of_one_another() {
    let dir = tempfile::tempdir().unwrap();
    let example = |name: &str| speckle::scene::examples::example(name).unwrap().to_string();
    let grid = example("default")
        .replace("nx = 16", "nx = 300")
        .replace("ny = 16", "ny = 300")
        .replace("paths = 40000", "paths = 300");
    // Four fibres up to 3 cm away: the weight window multiplies the paths several times, which
    // only the pilot of the estimate counts (`speckle_estimators::detector_vertices_per_path`).
    let head = example("head").replace("paths = 200000", "paths = 6000");
    let dcs = example("dcs").replace("paths = 400000", "paths = 200000");
    let cases: Vec<(&str, String, &str, Cost)> = vec![
        (
            "paths and means",
            example("default"),
            "covariance",
            Cost::Covariance,
        ),
        ("closed-form means", example("default"), "mean", Cost::Mean),
        (
            "batch merges",
            beam_grid(40, 200),
            "covariance",
            Cost::Covariance,
        ),
        ("intensity sums", grid, "intensity", Cost::Intensity),
        ("temporal", dcs, "g1", Cost::G1),
        ("fibre detector", example("tissue_fibre"), "g1", Cost::G1),
        ("split paths, layers", head, "g1", Cost::G1),
        ("fields", example("default"), "fields", Cost::Fields),
    ];
    let mut ratios = Vec::new();
    for (what, scene, command, cost) in &cases {
        // The shorter of two runs: a run's synced writes can wait for the write-back of
        // earlier files (one run of the batch-merge case took 3x its time so).
        let (first, estimate) = measure(dir.path(), scene, command, *cost);
        let took = first.min(measure(dir.path(), scene, command, *cost).0);
        println!("{what} ({command}): measured {took:.2} s, estimated {estimate:.2} s");
        ratios.push((*what, took / estimate));
    }
    let mut sorted: Vec<f64> = ratios.iter().map(|r| r.1).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[sorted.len() / 2];
    println!("measured / estimated: {ratios:?}");
    for (what, r) in &ratios {
        assert!(
            *r < 3.0 * median && *r > median / 3.0,
            "{what}: measured / estimated {r:.2} against the median {median:.2}: {ratios:?}"
        );
    }
}

#[test]
fn the_pilot_of_endless_paths_stops_at_its_budget() {
    // The pilot that counts a detector render's vertices traces at most
    // `speckle_estimators::PILOT_VERTICES`: on the fuzz corpus's scalp of 4.3e9 /cm (paths of
    // about 1e10 vertices) `speckle check` must still end promptly (a hang before the budget;
    // 1 s here) and cost `g1` by the expected path length: days.
    let scene = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../fuzz/corpus/finding_dense_scalp.toml"
    );
    let mut child = bin()
        .args(["check", scene])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed().as_secs() > 120 {
            child.kill().unwrap();
            panic!("speckle check did not end within 120 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let line = out
        .lines()
        .find(|l| l.contains("cost of g1"))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(line.contains("days"), "{line}");
}
