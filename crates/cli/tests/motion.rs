//! End-to-end tests of `speckle g1` and the `[motion]` table: the zero lag of `g1` is bitwise
//! the intensity render of the same scene and seed, `g1(0) = 1`, the correlation decays with
//! the lag, `g2 = 1 + |g1|^2`, the contrast falls from 1; bad input exits with code 2 and
//! names the field; field sequences start at the static fields.

mod common;
use common::*;

const SCENE: &str = r#"
name = "m"
wavelength = 1.0

[medium]
size = [12.0, 12.0, 4.0]
mean_free_path = 2.0

[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]

[[sensors]]
type = "far"
direction = [0.0, 0.0, 1.0]

[[sensors]]
type = "far"
direction = [0.3, 0.0, 1.0]

[render]
paths = 3000
seed = 4
"#;

#[test]
fn g1_zero_lag_is_the_intensity_and_decays() {
    let dir = tempfile::tempdir().unwrap();
    let motion = "\n[motion]\ndiffusion = 0.002\nlags = [0.0, 1.0, 4.0]\n";
    let scene = write(dir.path(), "m.toml", &format!("{SCENE}{motion}"));
    let s = scene.to_str().unwrap();
    let o = speckle(dir.path(), &["g1", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = speckle(
        dir.path(),
        &["intensity", s, "--out", "out", "-q", "--no-png"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    let c = npy_f64(&out.join("m.correlation.npy"));
    let g = npy_f64(&out.join("m.g1.npy"));
    let i = npy_f64(&out.join("m.intensity.npy"));
    assert_eq!(npy_f64(&out.join("m.lags.npy")), vec![0.0, 1.0, 4.0]);
    assert!(out.join("m.g1.json").exists() && out.join("m.correlation_stderr.npy").exists());
    // (J, L) complex: pair j, lag l at 2 (j L + l).
    for j in 0..2 {
        let at = |l: usize| (c[2 * (3 * j + l)], c[2 * (3 * j + l) + 1]);
        assert_eq!(at(0).0.to_bits(), i[j].to_bits(), "pair {j}");
        assert_eq!(g[2 * (3 * j)], 1.0);
        let norm = |(re, im): (f64, f64)| (re * re + im * im).sqrt();
        assert!(
            norm(at(2)) < norm(at(1)) && norm(at(1)) < at(0).0,
            "pair {j}: {c:?}"
        );
    }
    // g2 = 1 + |g1|^2; the contrast of an exposure equal to each lag starts at 1 and falls as
    // the speckle decorrelates; the plot is written.
    let g2 = npy_f64(&out.join("m.g2.npy"));
    let k = npy_f64(&out.join("m.contrast.npy"));
    assert_eq!((g2.len(), k.len()), (6, 6));
    for e in 0..6 {
        let g1_sq = g[2 * e] * g[2 * e] + g[2 * e + 1] * g[2 * e + 1];
        assert!((g2[e] - 1.0 - g1_sq).abs() < 1e-15, "g2[{e}]");
    }
    for j in 0..2 {
        let k = &k[3 * j..3 * j + 3];
        assert!(
            k[0] == 1.0 && k[1] < 1.0 && k[2] < k[1] && k[2] > 0.0,
            "{k:?}"
        );
    }
    let svg = std::fs::read_to_string(out.join("m.g1.svg")).unwrap();
    assert!(svg.contains("|g1(t)|") && svg.contains("pair 1"), "{svg}");
}

/// `speckle g1 --reference`: the reference at the scene's lags (rows matched by lag, in any
/// order, a header and comments skipped), `|g1|` of the pooled renders with jackknife errors,
/// the deviation `(|g1| - reference) / se`, the curve in the plot and the summary; a reference
/// that cannot be compared exits with code 2 naming what is wrong, before any render.
#[test]
fn g1_compares_with_a_reference_curve() {
    let dir = tempfile::tempdir().unwrap();
    let motion = "\n[motion]\ndiffusion = 0.002\nlags = [0.0, 1.0, 4.0]\n";
    let two_pairs = format!("{SCENE}{motion}");
    // One pair: `pairs` comes before the first table.
    let text = two_pairs.replacen(
        "wavelength = 1.0\n",
        "wavelength = 1.0\npairs = [[0, 0]]\n",
        1,
    );
    let scene = write(dir.path(), "m.toml", &text);
    let s = scene.to_str().unwrap();
    let csv = "# a reference\nt_s,C,g1\n4.0,0.1,0.5\n0.0,0.2,1.0\n\n1.0,0.15,0.9\n2.0,0.1,0.7\n";
    let reference = write(dir.path(), "ref.csv", csv);
    let r = reference.to_str().unwrap();
    let o = speckle(
        dir.path(),
        &[
            "g1",
            s,
            "--reference",
            r,
            "--groups",
            "4",
            "--out",
            "out",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    assert_eq!(
        npy_f64(&out.join("m.g1_reference.npy")),
        vec![1.0, 0.9, 0.5]
    );
    let g = npy_f64(&out.join("m.g1.npy"));
    let se = npy_f64(&out.join("m.g1_abs_stderr.npy"));
    let z = npy_f64(&out.join("m.g1_deviation.npy"));
    assert_eq!((se[0], z[0]), (0.0, 0.0));
    for l in 1..3 {
        let abs = g[2 * l].hypot(g[2 * l + 1]);
        assert!(
            se[l] > 0.0 && se[l] < 0.1 * abs,
            "lag {l}: {abs} +- {}",
            se[l]
        );
        let want = (abs - [1.0, 0.9, 0.5][l]) / se[l];
        assert!(
            (z[l] - want).abs() <= 1e-9 * want.abs(),
            "lag {l}: {} vs {want}",
            z[l]
        );
    }
    let svg = std::fs::read_to_string(out.join("m.g1.svg")).unwrap();
    assert!(svg.contains("reference (ref.csv)") && svg.contains("jackknife"));
    let json = std::fs::read_to_string(out.join("m.g1.json")).unwrap();
    assert!(
        json.contains("\"groups\": 4") && json.contains("\"column\": \"g1\""),
        "{json}"
    );
    // Without --reference, --groups is refused; so is one render.
    for args in [
        vec!["--groups", "4"],
        vec!["--reference", r, "--groups", "1"],
    ] {
        let o = speckle(dir.path(), &[&["g1", s, "-q"][..], &args].concat());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
    }
    // References that cannot be compared.
    let two_pairs = write(dir.path(), "two.toml", &two_pairs);
    for (scene, csv, wanted) in [
        (
            s,
            "t,g1\n0.0,1.0\n1.0,0.9\n",
            "no row at motion.lags[2] = 4",
        ),
        (s, "t,g1\n0.0,0.2\n1.0,0.9\n4.0,0.5\n", "1 at lag 0"),
        (
            s,
            "t,g1\n0.0,1.0\n1.0,abc\n4.0,0.5\n",
            "line 3: not a finite number",
        ),
        (s, "t,g1\n0.0,1.0\n1.0,0.9,3\n", "line 3: 3 columns"),
        (s, "t,g1\n", "no rows of numbers"),
        (
            two_pairs.to_str().unwrap(),
            "t,g1\n0.0,1.0\n1.0,0.9\n4.0,0.5\n",
            "has 2",
        ),
    ] {
        let bad = write(dir.path(), "bad.csv", csv);
        let o = speckle(
            dir.path(),
            &[
                "g1",
                scene,
                "--reference",
                bad.to_str().unwrap(),
                "--out",
                "bad",
                "-q",
            ],
        );
        assert_eq!(o.status.code(), Some(2), "{csv}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(wanted) && stderr(&o).contains("bad.csv"),
            "{csv}: {}",
            stderr(&o)
        );
        assert!(!dir.path().join("bad").exists(), "{csv}: wrote files");
    }
    let o = speckle(dir.path(), &["g1", s, "--reference", "missing.csv", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("missing.csv"), "{}", stderr(&o));
}

#[test]
fn bad_motion_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    for (motion, field) in [
        ("[motion]\nlags = []\n", "motion.lags"),
        (
            "[motion]\ndiffusion = -1.0\nlags = [0.0]\n",
            "motion.diffusion",
        ),
        (
            "[motion]\ndrift = [0.0, nan, 0.0]\nlags = [0.0]\n",
            "motion.drift[1]",
        ),
        ("[motion]\nlags = [0.0, inf]\n", "motion.lags[1]"),
        (
            "[motion]\ndiffusion = 1e300\nlags = [0.0, 1e10]\n",
            "motion.lags",
        ),
        (
            "[motion]\nlags = [0.0]\n[[motion.materials]]\ndiffusion = 1.0\n[[motion.materials]]\n",
            "motion.materials",
        ),
        ("[motion]\nlags = [0.0]\nspeed = 3.0\n", "speed"),
    ] {
        let scene = write(dir.path(), "bad.toml", &format!("{SCENE}\n{motion}"));
        let o = speckle(dir.path(), &["g1", scene.to_str().unwrap(), "-q"]);
        assert_eq!(o.status.code(), Some(2), "{motion}: {}", stderr(&o));
        assert!(stderr(&o).contains(field), "{motion}: {}", stderr(&o));
    }
    // g1 of a static scene.
    let scene = write(dir.path(), "static.toml", SCENE);
    let o = speckle(dir.path(), &["g1", scene.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("motion"), "{}", stderr(&o));
}

/// `speckle field-sequence`: a `(R, T, n_sources, n_sensors)` complex array, its times and a
/// sidecar; the frame at time 0 is bitwise `speckle fields` of the same scene and seed, later
/// frames differ; the same output on 1 and 3 threads; a scene without `[motion]` or with a
/// negative frame time exits with code 2 naming the field, and writes nothing; with a sensor
/// grid, one PNG frame per (realization up to `--png-realizations`, source, time), none with
/// `--no-png`.
#[test]
fn field_sequence_starts_at_the_static_fields() {
    let dir = tempfile::tempdir().unwrap();
    let motion = "\n[motion]\ndiffusion = 0.002\nlags = [0.0, 1.0, 4.0]\n";
    let render = "realizations = 3\npaths_per_realization = 200\n";
    let text = format!("{SCENE}{render}{motion}");
    let scene = write(dir.path(), "m.toml", &text);
    let s = scene.to_str().unwrap();
    for (out, threads) in [("a", "1"), ("b", "3")] {
        let args = [
            "field-sequence",
            s,
            "--out",
            out,
            "-q",
            "--threads",
            threads,
        ];
        let o = speckle(dir.path(), &args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let o = speckle(
        dir.path(),
        &[
            "fields",
            s,
            "--out",
            "f",
            "-q",
            "--no-png",
            "--threads",
            "2",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let seq = npy_f64(&a.join("m.field_sequence.npy"));
    assert_eq!(seq, npy_f64(&b.join("m.field_sequence.npy")));
    assert_eq!(npy_f64(&a.join("m.times.npy")), vec![0.0, 1.0, 4.0]);
    assert!(a.join("m.field_sequence.json").exists() && a.join("m.mean.npy").exists());
    let fields = npy_f64(&dir.path().join("f").join("m.fields.npy"));
    // (R, T, 1, 2) complex: realization r, time l, sensor d at 2 ((r T + l) 2 + d).
    let (nt, j) = (3, 2);
    for r in 0..3 {
        for d in 0..j {
            let at = |l: usize| 2 * ((r * nt + l) * j + d);
            let f = 2 * (r * j + d);
            assert_eq!(seq[at(0)].to_bits(), fields[f].to_bits(), "r {r} d {d}");
            assert_eq!(seq[at(0) + 1].to_bits(), fields[f + 1].to_bits());
            assert_ne!(seq[at(2)], fields[f]);
        }
    }
    let header = std::fs::read(a.join("m.field_sequence.npy")).unwrap();
    let header = String::from_utf8_lossy(&header[..100]).to_string();
    assert!(header.contains("(3, 3, 1, 2)"), "{header}");
    // Refusals.
    let bad = write(
        dir.path(),
        "bad.toml",
        &format!("{SCENE}\n[motion]\ndiffusion = 0.002\nlags = [0.0, -1.0]\n"),
    );
    let o = speckle(
        dir.path(),
        &["field-sequence", bad.to_str().unwrap(), "--out", "x", "-q"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("motion.lags[1]"), "{}", stderr(&o));
    let still = write(dir.path(), "static.toml", SCENE);
    let o = speckle(
        dir.path(),
        &[
            "field-sequence",
            still.to_str().unwrap(),
            "--out",
            "x",
            "-q",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("motion"), "{}", stderr(&o));
    assert!(!dir.path().join("x").join("m.field_sequence.npy").exists());
    // A sensor grid: one PNG frame per (realization up to png_realizations, source, time), and
    // none with --no-png.
    let grid = SCENE.replace(
        "[[sensors]]\ntype = \"far\"\ndirection = [0.0, 0.0, 1.0]\n\n[[sensors]]\ntype = \"far\"\n\
         direction = [0.3, 0.0, 1.0]\n",
        "[[sensors]]\ntype = \"far_grid\"\ntheta_x_deg = [-5.0, 5.0]\ntheta_y_deg = [-2.0, 2.0]\n\
         nx = 3\nny = 2\n",
    );
    assert!(grid.contains("far_grid"));
    let grid = write(dir.path(), "g.toml", &format!("{grid}{render}{motion}"));
    let g = grid.to_str().unwrap();
    let o = speckle(
        dir.path(),
        &[
            "field-sequence",
            g,
            "--out",
            "p",
            "-q",
            "--png-realizations",
            "2",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let pngs = |d: &str| {
        let mut v: Vec<String> = std::fs::read_dir(dir.path().join(d))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
            .filter(|f| f.ends_with(".png"))
            .collect();
        v.sort();
        v
    };
    let want: Vec<String> = (0..2)
        .flat_map(|r| (0..3).map(move |l| format!("m.field_sequence.r{r}.s0.t{l}.png")))
        .collect();
    assert_eq!(pngs("p"), want);
    let o = speckle(
        dir.path(),
        &["field-sequence", g, "--out", "q", "-q", "--no-png"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(pngs("q").is_empty());
    assert!(dir.path().join("q").join("m.field_sequence.npy").exists());
}

#[test]
fn map_zero_lag_is_the_first_covariance_row_and_decays() {
    let dir = tempfile::tempdir().unwrap();
    let motion =
        "\n[motion]\ndiffusion = 0.002\ndrift = [0.05, 0.0, 0.0]\nlags = [0.0, 1.0, 4.0]\n";
    let scene = write(dir.path(), "m.toml", &format!("{SCENE}{motion}"));
    let s = scene.to_str().unwrap();
    let o = speckle(dir.path(), &["map", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = speckle(
        dir.path(),
        &["covariance", s, "--out", "out", "-q", "--no-png"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    // (K, L) = (2, 3) complex: [k][l] = (re, im).
    let m = npy_f64(&out.join("m.map.npy"));
    let se = npy_f64(&out.join("m.map_stderr.npy"));
    let c = npy_f64(&out.join("m.cov.npy"));
    assert_eq!(m.len(), 2 * 3 * 2);
    for k in 0..2 {
        // Zero lag: the covariance's first row, C[0, k], from the same paths.
        let (mr, mi) = (m[k * 6], m[k * 6 + 1]);
        let (cr, ci) = (c[2 * k], c[2 * k + 1]);
        let scale = c[0];
        assert!(
            (mr - cr).abs() <= 1e-12 * scale && (mi - ci).abs() <= 1e-12 * scale,
            "pair {k}: map {mr} {mi}, covariance {cr} {ci}"
        );
    }
    // C[0, 0](t) decays in magnitude well beyond its errors.
    let norm = |k: usize, l: usize| m[k * 6 + 2 * l].hypot(m[k * 6 + 2 * l + 1]);
    assert!(norm(0, 2) + 4.0 * se[4].hypot(se[5]) < norm(0, 0));
    let png = std::fs::read(out.join("m.map.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("m.map.json")).unwrap()).unwrap();
    assert_eq!(meta["files"]["shape"], serde_json::json!([2, 3]));
    // No [motion] table: exit 2 naming it.
    let plain = write(dir.path(), "p.toml", SCENE);
    let o = speckle(dir.path(), &["map", plain.to_str().unwrap(), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("motion"), "{}", stderr(&o));
}

#[test]
fn shaping_writes_its_curves_and_names_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let motion = "\n[motion]\ndiffusion = 0.002\nlags = [0.0, 1.0, 2.0]\n";
    let tilts = "\n[[sources]]\ntype = \"plane_tilts\"\ntilts_deg = [5.0, 10.0, 15.0]\n";
    let scene = write(
        dir.path(),
        "m.toml",
        &format!("{SCENE}{tilts}{motion}").replace(
            "paths = 3000",
            "realizations = 64\npaths_per_realization = 50",
        ),
    );
    let s = scene.to_str().unwrap();
    let o = speckle(
        dir.path(),
        &[
            "shaping",
            s,
            "--learn",
            "2",
            "--no-mean",
            "--out",
            "out",
            "-q",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    // (T, 2): value and standard error, from the last learning frame on.
    let e = npy_f64(&out.join("m.shaping_enhancement.npy"));
    let c = npy_f64(&out.join("m.shaping_focus_correlation.npy"));
    assert_eq!((e.len(), c.len()), (4, 4));
    assert!(e[0] > 1.5, "4 modes focus: enhancement {}", e[0]);
    assert_eq!(c[0], 1.0);
    assert_eq!(npy_f64(&out.join("m.shaping_times.npy")), vec![0.0, 1.0]);
    assert!(out.join("m.shaping.svg").exists());
    for (args, field) in [
        (vec!["--learn", "0"], "learn"),
        (vec!["--learn", "4"], "learn"),
        (vec!["--target", "2"], "target"),
    ] {
        let mut all = vec!["shaping", s, "-q"];
        all.extend(args);
        let o = speckle(dir.path(), &all);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(field), "{}", stderr(&o));
    }
}

/// `speckle tracking`: its first curve is bitwise the correlation of `speckle g1`, the files
/// and plot are written with the documented shapes, and what it cannot track exits with code 2
/// naming the field (the statistics are checked in `tests/tracking.rs`).
#[test]
fn tracking_writes_three_curves_and_names_bad_settings() {
    let dir = tempfile::tempdir().unwrap();
    let points = SCENE
        .replace(
            "type = \"plane\"\ndirection = [0.0, 0.0, 1.0]",
            "type = \"point\"\nposition = [-1.0, 0.0, -4.0]",
        )
        .replace(
            "[[sensors]]\ntype = \"far\"\ndirection = [0.3, 0.0, 1.0]\n",
            "",
        )
        .replace(
            "type = \"far\"\ndirection = [0.0, 0.0, 1.0]",
            "type = \"point\"\nposition = [1.0, 0.0, 4.0]",
        );
    let motion = "\n[motion]\ndiffusion = 0.002\ndrift = [0.3, 0.0, 0.0]\nlags = [0.0, 1.0, 2.0]\n";
    let scene = write(dir.path(), "m.toml", &format!("{points}{motion}"));
    let s = scene.to_str().unwrap();
    let o = speckle(dir.path(), &["tracking", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("largest deviation"), "{}", stdout(&o));
    let o = speckle(dir.path(), &["g1", s, "--out", "out", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("out");
    // (3, L) complex: curve c, lag l at 2 (c L + l).
    let t = npy_f64(&out.join("m.tracking_correlation.npy"));
    let g = npy_f64(&out.join("m.correlation.npy"));
    assert_eq!(t.len(), 2 * 3 * 3);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&t[..6]), bits(&g));
    assert_eq!(
        npy_f64(&out.join("m.tracking_lags.npy")),
        vec![0.0, 1.0, 2.0]
    );
    let n = npy_f64(&out.join("m.tracking_normalised.npy"));
    assert_eq!(n[6], 1.0, "the U = 0 curve is normalised by its zero lag");
    let svg = std::fs::read_to_string(out.join("m.tracking.svg")).unwrap();
    assert!(
        svg.contains("no tracking") && svg.contains("U = 0"),
        "{svg}"
    );
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("m.tracking.json")).unwrap())
            .unwrap();
    assert_eq!(meta["files"]["shape"], serde_json::json!([3, 3]));
    assert!(meta["summary"]["max_deviation_tracking_vs_u0_in_combined_se"].is_number());
    for (text, field) in [
        (
            format!("{points}{motion}").replace("drift = [0.3, 0.0, 0.0]\n", ""),
            "motion.drift",
        ),
        (format!("{SCENE}{motion}"), "sensors"),
        (points.clone(), "motion"),
    ] {
        let bad = write(dir.path(), "bad.toml", &text);
        let o = speckle(dir.path(), &["tracking", bad.to_str().unwrap(), "-q"]);
        assert_eq!(o.status.code(), Some(2), "{field}");
        assert!(stderr(&o).contains(field), "{field}: {}", stderr(&o));
    }
}

/// `speckle wave` with `[motion]` solves the moving scatterers exactly and writes `C[j, j](t)`
/// in the layout of `speckle g1`'s `correlation.npy`: the two agree entry by entry (real and
/// imaginary parts, within 4.5 combined standard errors) on the flatland scene of the 2023
/// paper's Fig. 7, three sensors of it; lags that do not start at 0 and increase, and
/// `--shard`, are refused naming the field.
#[test]
fn wave_with_motion_agrees_with_g1() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenes/spatiotemporal_2d.toml"
    ))
    .unwrap()
    .replace("nx = 21", "nx = 3")
    .replace("step_x = [0.1, 0.0, 0.0]", "step_x = [0.5, 0.0, 0.0]");
    let s = write(dir.path(), "st.toml", &text);
    let s = s.to_str().unwrap();
    let o = speckle(
        dir.path(),
        &["wave", s, "--configurations", "400", "-q", "--out", "o"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = speckle(
        dir.path(),
        &["g1", s, "--paths", "40000", "-q", "--out", "o"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("o");
    let w = npy_f64(&out.join("spatiotemporal_2d.wave_correlation.npy"));
    let ws = npy_f64(&out.join("spatiotemporal_2d.wave_correlation_stderr.npy"));
    let g = npy_f64(&out.join("spatiotemporal_2d.correlation.npy"));
    let gs = npy_f64(&out.join("spatiotemporal_2d.correlation_stderr.npy"));
    assert_eq!(w.len(), 2 * 3 * 21);
    assert_eq!(w.len(), g.len());
    let mut worst: f64 = 0.0;
    for i in 0..w.len() {
        let se = ws[i].hypot(gs[i]);
        if se > 0.0 {
            worst = worst.max((w[i] - g[i]).abs() / se);
        }
    }
    println!("largest deviation {worst:.2} combined SE");
    assert!(worst < 4.5, "{worst}");
    // The correlation decays over the lags (the test is of moving scatterers).
    assert!(w[2 * 20] < 0.2 * w[0], "{} -> {}", w[0], w[40]);
    let g1 = npy_f64(&out.join("spatiotemporal_2d.wave_g1.npy"));
    assert_eq!((g1[0], g1[1]), (1.0, 0.0));
    // Lags the solver cannot step through, and shards.
    let bad = text.replace("lags = [0.0, 0.1,", "lags = [0.1, 0.0,");
    let b = write(dir.path(), "bad.toml", &bad);
    let o = speckle(
        dir.path(),
        &["wave", b.to_str().unwrap(), "-q", "--out", "b"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("motion.lags"), "{}", stderr(&o));
    let o = speckle(
        dir.path(),
        &["wave", s, "--shard", "1/2", "-q", "--out", "b"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("shard"), "{}", stderr(&o));
    assert!(!dir.path().join("b").exists());
}
