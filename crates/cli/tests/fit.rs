//! End-to-end tests of `speckle fit` (issue 26): a fit of synthetic data written by the
//! project's own `g1` (the estimate near the truth, the outputs numpy reads), `--data` in place
//! of `fit.data`, and bad input (measurement files, `[fit]` fields) exiting with code 2 naming
//! the field, line and column before any render.

mod common;
use common::*;

/// A small tissue-like cube with a point source and a fibre, fitting the diffusion and beta.
const SCENE: &str = r#"
name = "f"
wavelength = 500e-7

[medium]
size = [1.0, 1.0, 1.0]
center = [0.0, 0.0, 0.5]
sigma_s = 20.0
sigma_a = 0.1

[phase]
type = "hg"
g = 0.8

[[sources]]
type = "point"
position = [-0.1, 0.0, 0.0]

[[sensors]]
type = "detector"
position = [0.1, 0.0, 0.0]
radius = 0.05
numerical_aperture = 0.5

[motion]
diffusion = {diffusion}
lags = [0.0, 1e-7, 2e-7, 5e-7, 1e-6, 2e-6, 5e-6, 1e-5, 2e-5, 5e-5]

[render]
paths = {paths}
seed = {seed}

[fit]
{data}
quantity = "g2"
{parameters}
"#;

const PARAMETERS: &str = r#"
[[fit.parameters]]
field = "motion.diffusion"
range = [1e-9, 1e-5]
[[fit.parameters]]
field = "beta"
range = [0.05, 1.0]
"#;

fn scene(diffusion: &str, paths: u64, seed: u64, data: &str, parameters: &str) -> String {
    SCENE
        .replace("{diffusion}", diffusion)
        .replace("{paths}", &paths.to_string())
        .replace("{seed}", &seed.to_string())
        .replace("{data}", data)
        .replace("{parameters}", parameters)
}

#[test]
fn a_fit_recovers_the_diffusion_of_a_render_and_writes_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    // The measurement: g2 = 1 + 0.6 |g1|^2 of a render at D = 2e-7 (no noise but its own
    // Monte Carlo error), with standard errors of 0.005.
    let truth = write(
        dir.path(),
        "truth.toml",
        &scene("2e-7", 200_000, 9, "", PARAMETERS),
    );
    let o = speckle(
        dir.path(),
        &["g1", truth.to_str().unwrap(), "--out", "t", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let c = npy_f64(&dir.path().join("t/f.correlation.npy"));
    let lags = npy_f64(&dir.path().join("t/f.lags.npy"));
    let mut csv = String::from("lag,g2,stderr\n");
    for l in 1..lags.len() {
        let g1 = c[2 * l].hypot(c[2 * l + 1]) / c[0];
        csv += &format!("{},{},0.005\n", lags[l], 1.0 + 0.6 * g1 * g1);
    }
    write(dir.path(), "g2.csv", &csv);
    let s = write(
        dir.path(),
        "f.toml",
        &scene("1e-6", 100_000, 1, "data = \"g2.csv\"", PARAMETERS),
    );
    let o = speckle(
        dir.path(),
        &["fit", s.to_str().unwrap(), "--out", "out", "-q"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let est = npy_f64(&out.join("f.fit_estimates.npy"));
    let se = npy_f64(&out.join("f.fit_stderr.npy"));
    let iv = npy_f64(&out.join("f.fit_intervals.npy"));
    println!("{}\n{est:?} +- {se:?}", stdout(&o));
    // The truth within 4.5 standard errors (the Monte Carlo errors of both renders dominate).
    for (i, truth) in [2e-7, 0.6].into_iter().enumerate() {
        assert!(
            (est[i] - truth).abs() < 4.5 * se[i],
            "{i}: {} +- {}",
            est[i],
            se[i]
        );
        assert!(se[i] > 0.0 && se[i] < 0.2 * truth, "{i}: {}", se[i]);
        assert!(iv[2 * i] < est[i] && est[i] < iv[2 * i + 1]);
    }
    assert_eq!(
        npy_f64(&out.join("f.fit_residuals.npy")).len(),
        lags.len() - 1
    );
    let svg = std::fs::read_to_string(out.join("f.fit.svg")).unwrap();
    assert!(svg.contains("fitted model") && svg.contains("measured"));
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("f.fit.json")).unwrap()).unwrap();
    assert_eq!(
        meta["summary"]["parameters"][0]["field"],
        "motion.diffusion"
    );
    // --data replaces fit.data (here: the same file under another name).
    std::fs::copy(dir.path().join("g2.csv"), dir.path().join("other.csv")).unwrap();
    let o = speckle(
        dir.path(),
        &[
            "fit",
            s.to_str().unwrap(),
            "--data",
            "other.csv",
            "--out",
            "out2",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(npy_f64(&dir.path().join("out2/f.fit_estimates.npy")), est);
}

#[test]
fn bad_measurements_and_fit_fields_exit_2_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, data: &str, parameters: &str, csv: Option<&str>| {
        if let Some(csv) = csv {
            write(dir.path(), "m.csv", csv);
        }
        let s = write(
            dir.path(),
            name,
            &scene("1e-7", 1_000_000_000, 1, data, parameters),
        );
        speckle(
            dir.path(),
            &["fit", s.to_str().unwrap(), "--out", "o", "-q"],
        )
    };
    let data = "data = \"m.csv\"";
    for (csv, said) in [
        ("0,1.5\n1e-6,abc\n", "m.csv line 2, column 2"),
        (
            "1e-6,1.5\n1e-7,1.2\n1e-5,1.1\n",
            "line 2, column 1: lags must increase",
        ),
        ("1e-6,1.5\n2e-6,NaN\n3e-6,1\n", "line 2, column 2"),
        (
            "lag,g2\n1e-6,1.5,0.1\n2e-6,1.4\n",
            "line 3, column 1: every row",
        ),
        ("1e-6,1.5,-1\n2e-6,1.4,1\n", "line 1, column 3"),
        ("", "at least 2 rows"),
    ] {
        let o = run("a.toml", data, PARAMETERS, Some(csv));
        assert_eq!(o.status.code(), Some(2), "{csv:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("fit.data") && e.contains(said), "{csv:?}: {e}");
    }
    let csv = Some("1e-6,1.5\n2e-6,1.4\n3e-6,1.3\n");
    for (parameters, said) in [
        (
            "[[fit.parameters]]\nfield = \"medium.g\"\nrange = [0.1, 0.9]",
            "fit.parameters[0].field",
        ),
        (
            "[[fit.parameters]]\nfield = \"motion.diffusion\"\nrange = [1e-5, 1e-9]",
            "fit.parameters[0].range",
        ),
        (
            "[[fit.parameters]]\nfield = \"beta\"\nrange = [0.1, 2.0]",
            "fit.parameters[0].range",
        ),
        (
            "[[fit.parameters]]\nfield = \"scale\"\nrange = [0.1, 2.0]",
            "fit.parameters[0].field",
        ),
        (
            "[[fit.parameters]]\nfield = \"medium.sigma_a\"\nrange = [0.5, 2.0]",
            "fit.parameters[0].range",
        ),
        ("parameters = []", "fit.parameters"),
    ] {
        let o = run("b.toml", data, parameters, csv);
        assert_eq!(o.status.code(), Some(2), "{parameters}: {}", stderr(&o));
        assert!(stderr(&o).contains(said), "{parameters}: {}", stderr(&o));
    }
    // No measurement at all, and a measurement file outside the scene's folder.
    let o = run("c.toml", "", PARAMETERS, None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("fit.data"), "{}", stderr(&o));
    let o = run("d.toml", "data = \"/etc/passwd\"", PARAMETERS, None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("fit.data") && !stderr(&o).contains("root:"));
}
