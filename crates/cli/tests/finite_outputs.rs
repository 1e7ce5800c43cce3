//! No NaN or infinite result with exit code 0 (issue 27, item 3): the reproducers of the issue
//! (`g1` and `map` of a focused beam with `motion.diffusion = 1e40`, `g1` with `lags = [0,
//! 5e-324]`, the studies with lengths of 1e-300 or 1e300 um) each exit with code 2, name the
//! input (the scene's field, or the study file and the array) and write nothing. Also the
//! field names and number formats of item 7 for the studies' slabs.
//!
//! Run time (release, 2 cores): about 10 s (the studies render a few hundred paths each).

mod common;

use common::{speckle, stderr, write};
use std::path::Path;

/// A focused beam into a slab and two far-field sensors, with moving scatterers.
const BEAM: &str = r#"
name = "gb"
wavelength = 1.0
[medium]
size = [12.0, 12.0, 4.0]
mean_free_path = 2.0
[[sources]]
type = "gaussian_beam"
focus = [0.0, 0.0, -2.0]
axis = [0.0, 0.0, 1.0]
numerical_aperture = 0.5
[[sensors]]
type = "far"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far"
direction = [0.3, 0.0, 1.0]
[render]
paths = 3000
seed = 4
[motion]
diffusion = 0.002
lags = [0.0, 1.0, 4.0]
"#;

/// Runs `args` in `dir` and checks exit code 2, a message with each of `says`, and no `out`.
fn refused(dir: &Path, args: &[&str], says: &[&str]) {
    let o = speckle(dir, args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
    for s in says {
        assert!(e.contains(s), "{args:?}: expected {s:?} in: {e}");
    }
    assert!(!dir.join("out").exists(), "{args:?} wrote output");
}

/// A shipped study file with `key = value` in place of its line for `key` (or before its first
/// table, if it has none), written to `dir`.
fn study(dir: &Path, file: &str, edits: &[(&str, &str)]) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(file);
    let mut text = std::fs::read_to_string(path).unwrap();
    for (key, value) in edits {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("{key} = ")))
            .map(str::to_string);
        text = match line {
            Some(line) => text.replacen(&line, &format!("{key} = {value}"), 1),
            None => text.replacen("\n[", &format!("\n{key} = {value}\n["), 1),
        };
    }
    // Refocus images are not needed for the focus curve.
    if let Some(at) = text.find("\n[images]") {
        text.truncate(at);
    }
    write(dir, file, &text);
    file.to_string()
}

#[test]
fn temporal_correlations_that_overflow_exit_with_2_naming_motion() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "gb.toml",
        &BEAM.replace("diffusion = 0.002", "diffusion = 1e40"),
    );
    for command in ["g1", "map"] {
        refused(
            d,
            &[command, "gb.toml", "--out", "out", "-q"],
            &["gb.toml: motion: ", "is not finite"],
        );
    }
    write(
        d,
        "lags.toml",
        &BEAM.replace("lags = [0.0, 1.0, 4.0]", "lags = [0.0, 5e-324]"),
    );
    refused(
        d,
        &["g1", "lags.toml", "--out", "out", "-q"],
        &["lags.toml: motion.lags[1]: ", "speckle contrast"],
    );
    // The same scenes with ordinary values render.
    write(d, "ok.toml", BEAM);
    let o = speckle(d, &["g1", "ok.toml", "--out", "ok", "-q", "--no-png"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn studies_whose_results_are_not_finite_exit_with_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // (command, study file, edits, --paths)
    type Case<'a> = (&'a str, &'a str, &'a [(&'a str, &'a str)], &'a str);
    let cases: [Case; 5] = [
        (
            "tilt-shift",
            "fig12_tilt_shift.toml",
            &[("thickness_um", "1e-300")],
            "200",
        ),
        (
            "memory-tilt",
            "fig6a_memory_tilt.toml",
            &[("thickness_um", "1e-300")],
            "320",
        ),
        (
            "refocus",
            "fig13_refocus.toml",
            &[("mean_free_path_um", "1e300")],
            "200",
        ),
        (
            "sampling-gain",
            "fig9_sampling_gain.toml",
            &[
                ("mean_free_path", "1e300"),
                ("reference_paths", "1600"),
                ("steps", "2"),
            ],
            "400",
        ),
        (
            "bruteforce",
            "fig7_bruteforce.toml",
            &[
                ("mean_free_path", "1e300"),
                ("near_paths", "1600"),
                ("biased_paths", "800"),
                ("timing_paths", "800"),
                ("chunk", "400"),
            ],
            "1600",
        ),
    ];
    for (command, file, edits, paths) in cases {
        let f = study(d, file, edits);
        refused(
            d,
            &[command, &f, "--out", "out", "--paths", paths, "-q"],
            &[
                &format!("{f}: (results): "),
                "the study's values give NaN or infinite numbers",
            ],
        );
    }
}

#[test]
fn study_slabs_name_their_field_and_print_short_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A slab of 1e300 x 1e300 x 1e300 um is refused naming `thickness_um` (was `medium`, with
    // the extents written out in 300 digits).
    let f = study(
        d,
        "fig6a_memory_tilt.toml",
        &[
            ("thickness_um", "1e300"),
            ("mean_free_path_um", "1e299"),
            ("lateral_factor", "1e10"),
        ],
    );
    let o = speckle(
        d,
        &["memory-tilt", &f, "--out", "out", "--paths", "320", "-q"],
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("thickness_um: gives a slab of inf x inf x 1.0000e300 um"),
        "{e}"
    );
    assert!(!e.contains("0000000000"), "{e}");
    let f = study(d, "fig7_bruteforce.toml", &[("concentration", "1e300")]);
    refused(
        d,
        &["bruteforce", &f, "--out", "out", "-q"],
        &["concentration: must be in [1, 1e4] (got 1e300)"],
    );
    let f = study(d, "fig13_refocus.toml", &[("thickness_um", "1e-300")]);
    refused(
        d,
        &["refocus", &f, "--out", "out", "--paths", "200", "-q"],
        &["delta_max_um: ", "L = 1.0000e-300 um"],
    );
}

/// Item 7: a focused beam's focus is named `focus` (was `position`), and a far arc whose
/// generated direction is lost names `angles_deg` (was `sensor.direction` with a NaN vector).
#[test]
fn endpoint_messages_name_the_field_given() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let beam_sensor = "[[sensors]]\ntype = \"gaussian_beam\"\nfocus = [0.0, -1e13, 2.0]\n\
                       concentration = 16.0\n";
    let arc = "[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0.0, 1e308]\nn = 3\n";
    let far = "[[sensors]]\ntype = \"far\"\ndirection = [0.0, 0.0, 1.0]\n";
    for (name, text, says) in [
        (
            "source.toml",
            BEAM.replace("focus = [0.0, 0.0, -2.0]", "focus = [1e13, 0.0, 0.0]"),
            "source.toml: sources[0].focus: 1e13 is more than",
        ),
        (
            "sensor.toml",
            BEAM.replacen(far, beam_sensor, 1),
            "sensor.toml: sensors[0].focus: 1e13 is more than",
        ),
        (
            "arc.toml",
            BEAM.replacen(far, arc, 1),
            "arc.toml: sensors[0].angles_deg: ",
        ),
    ] {
        write(d, name, &text);
        let o = speckle(d, &["check", name]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{name}: {e}");
        assert!(e.contains(says), "expected {says:?} in: {e}");
        assert!(!e.contains("position") && !e.contains("NaN"), "{e}");
    }
}

#[test]
fn a_point_sensor_on_its_point_source_refuses_the_mean_naming_sensors() {
    // A fuzz finding of the 30-minute run (seed 23): the DCS example with its sensor moved onto
    // its source. The direct field e^(ikr)/r of the speckle mean is infinite at r = 0:
    // `speckle mean` wrote `inf+NaNi` with exit 0. The commands that write the mean refuse it;
    // the paths' correlation is finite and renders.
    let dir = tempfile::tempdir().unwrap();
    let text = speckle::scene::examples::example("dcs")
        .unwrap()
        .replace("position = [-0.5, 0.0, 0.0]", "position = [0.5, 0.0, 0.0]")
        .replace("paths = 400000", "paths = 2000");
    let p = write(dir.path(), "same.toml", &text);
    let p = p.to_str().unwrap();
    for command in ["mean", "covariance", "fields"] {
        refused(
            dir.path(),
            &[command, p, "-q", "--out", "out"],
            &["sensors", "sensor 0 lies on source 0", "infinite"],
        );
    }
    let o = speckle(dir.path(), &["g1", p, "-q", "--out", "g1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // And 5e-324 apart (seed 24): 1 / r overflows.
    let near = text.replace(
        "position = [0.5, 0.0, 0.0]\n\n[[sensors]]",
        "position = [0.5, 0.0, 5e-324]\n\n[[sensors]]",
    );
    assert_ne!(near, text);
    let p = write(dir.path(), "near.toml", &near);
    refused(
        dir.path(),
        &["mean", p.to_str().unwrap(), "-q", "--out", "out"],
        &["sensors", "sensor 0 lies on source 0", "infinite"],
    );
}
