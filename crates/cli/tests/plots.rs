//! Plots a reader can trust (issue 28, item 6): the SVG figures of `speckle g1` (`g1` and
//! `g2`) and `speckle tracking` read back, their x-axis tick labels distinct neighbour by neighbour and the time
//! axis carrying the unit a scene declares (`units = { length = "cm", time = "s" }`), on a
//! logarithmic axis when the lags span decades; and multi-tau lag grids (`lags = { multi_tau =
//! { .. } }`), which render bitwise as the same lags given as a list.

mod common;
use common::*;

/// The texts of an SVG document with their attributes: `(attributes, content)`.
fn texts(svg: &str) -> Vec<(String, String)> {
    let mut out = vec![];
    let mut rest = svg;
    while let Some(start) = rest.find("<text") {
        let tail = &rest[start..];
        let open_end = tail.find('>').expect("a text element closes its tag");
        let close = tail.find("</text>").expect("a text element ends");
        let attributes = tail[5..open_end].to_string();
        let content = tail[open_end + 1..close].trim().replace("&apos;", "'");
        out.push((attributes, content));
        rest = &tail[close + 7..];
    }
    out
}

/// The value of attribute `name` in `attributes`.
fn attribute<'a>(attributes: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let i = attributes.find(&key)? + key.len();
    let j = attributes[i..].find('"')?;
    Some(&attributes[i..i + j])
}

/// The x axis of a figure: its label and its tick labels from left to right (the centred texts
/// of the lowest row below the plot, the label being the one drawn above its baseline).
fn x_axis(svg: &str) -> (String, Vec<String>) {
    let t = texts(svg);
    let label = t
        .iter()
        .find(|(a, _)| attribute(a, "dy") == Some("-0.5ex"))
        .map(|(_, c)| c.clone())
        .expect("an x-axis label");
    let mut ticks: Vec<(f64, f64, String)> = t
        .iter()
        .filter(|(a, _)| {
            attribute(a, "text-anchor") == Some("middle")
                && attribute(a, "dy") == Some("0.76em")
                && attribute(a, "transform").is_none()
        })
        .map(|(a, c)| {
            let num = |k| attribute(a, k).unwrap().parse::<f64>().unwrap();
            (num("y"), num("x"), c.clone())
        })
        .collect();
    let row = ticks.iter().map(|t| t.0).fold(f64::MIN, f64::max);
    ticks.retain(|t| t.0 == row);
    ticks.sort_by(|a, b| a.1.total_cmp(&b.1));
    (label, ticks.into_iter().map(|t| t.2).collect())
}

/// Checks an x axis: at least three ticks, neighbours distinct, and the time unit in the label
/// (linear axis) or on every tick (logarithmic axis).
fn check_time_axis(svg: &str, what: &str) -> bool {
    let (label, ticks) = x_axis(svg);
    println!("{what}: {label}: {ticks:?}");
    assert!(ticks.len() >= 3, "{what}: {ticks:?}");
    for w in ticks.windows(2) {
        assert_ne!(w[0], w[1], "{what}: neighbouring tick labels {ticks:?}");
    }
    let log = label.contains("log scale");
    if log {
        assert!(ticks.iter().all(|t| t.ends_with('s')), "{what}: {ticks:?}");
    } else {
        assert!(
            ["(s)", "(ms)", "(us)", "(ns)"]
                .iter()
                .any(|u| label.contains(u)),
            "{what}: no unit in {label:?}"
        );
    }
    log
}

/// The shipped DCS scene (units declared) with its lags replaced by `lags`.
fn dcs(dir: &std::path::Path, lags: &str) -> String {
    let text = stdout(&speckle(dir, &["example", "dcs"]));
    assert!(text.contains("units = { length = \"cm\", time = \"s\" }"));
    let start = text.find("\nlags = ").unwrap() + 1;
    let end = start + text[start..].find('\n').unwrap();
    format!("{}lags = {lags}{}", &text[..start], &text[end..])
}

#[test]
fn g1_and_tracking_plots_have_distinct_ticks_and_units() {
    let dir = tempfile::tempdir().unwrap();
    // Lags over two decades: a logarithmic axis with SI-prefixed ticks.
    let cases = [
        ("[0.0, 2e-7, 5e-7, 1e-6, 2e-6, 5e-6, 1e-5, 2e-5]", true),
        // Five lags from 0 to 2e-5: a linear axis in us (the old plot read 0.0, 0.0, 0.00001).
        ("[0.0, 5e-6, 1e-5, 1.5e-5, 2e-5]", false),
        // Close lags: still distinct.
        ("[1e-6, 1.01e-6, 1.02e-6, 1.03e-6]", false),
    ];
    for (i, (lags, log)) in cases.iter().enumerate() {
        let s = write(dir.path(), &format!("g{i}.toml"), &dcs(dir.path(), lags));
        let out = format!("o{i}");
        let o = speckle(
            dir.path(),
            &[
                "g1",
                s.to_str().unwrap(),
                "--paths",
                "4000",
                "-q",
                "--out",
                &out,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let svg = std::fs::read_to_string(dir.path().join(format!("o{i}/dcs.g1.svg"))).unwrap();
        assert_eq!(check_time_axis(&svg, lags), *log, "{lags}");
        // g2 as DCS users read it, on the same axis, when there is a zero lag.
        let g2 = dir.path().join(format!("o{i}/dcs.g2.svg"));
        assert_eq!(g2.exists(), lags.starts_with("[0.0"), "{lags}");
        if g2.exists() {
            let svg = std::fs::read_to_string(g2).unwrap();
            assert!(svg.contains("beta = 1"));
            assert_eq!(check_time_axis(&svg, lags), *log, "{lags}");
        }
    }
    // Tracking's three curves share the axis.
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../scenes/tracking.toml"
    ))
    .unwrap();
    let s = write(dir.path(), "t.toml", &text);
    let o = speckle(
        dir.path(),
        &[
            "tracking",
            s.to_str().unwrap(),
            "--paths",
            "4000",
            "-q",
            "--out",
            "t",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let svg = std::fs::read_dir(dir.path().join("t"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "svg"))
        .expect("tracking writes a plot");
    check_time_axis(&std::fs::read_to_string(svg).unwrap(), "tracking");
}

#[test]
fn a_multi_tau_grid_renders_as_its_lags_listed() {
    let dir = tempfile::tempdir().unwrap();
    let grid = "{ multi_tau = { first = 1e-7, last = 2e-5, per_octave = 4 } }";
    let s = write(dir.path(), "m.toml", &dcs(dir.path(), grid));
    let run = |scene: &std::path::Path, out: &str| {
        let o = speckle(
            dir.path(),
            &[
                "g1",
                scene.to_str().unwrap(),
                "--paths",
                "4000",
                "-q",
                "--out",
                out,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let o = dir.path().join(out);
        (
            npy_f64(&o.join("dcs.lags.npy")),
            std::fs::read(o.join("dcs.g1.npy")).unwrap(),
            std::fs::read_to_string(o.join("dcs.g1.svg")).unwrap(),
        )
    };
    let (lags, g1, svg) = run(&s, "grid");
    // 0, 1 .. 8 steps of 1e-7, then 4 per octave: 10 .. 16, 20 .. 32, .., 160, 192.
    let steps: Vec<u64> = vec![
        0, 1, 2, 3, 4, 5, 6, 7, 8, 10, 12, 14, 16, 20, 24, 28, 32, 40, 48, 56, 64, 80, 96, 112,
        128, 160, 192,
    ];
    let want: Vec<f64> = steps.iter().map(|k| 1e-7 * *k as f64).collect();
    assert_eq!(lags, want);
    assert!(
        check_time_axis(&svg, "multi-tau"),
        "the grid's axis is logarithmic"
    );
    let list: Vec<String> = lags.iter().map(|t| format!("{t:?}")).collect();
    let s = write(
        dir.path(),
        "l.toml",
        &dcs(dir.path(), &format!("[{}]", list.join(", "))),
    );
    let (listed, g1_listed, _) = run(&s, "list");
    assert_eq!(listed, lags);
    assert_eq!(g1_listed, g1, "bitwise the same g1");
    // Bad grids exit 2 naming the key.
    for (grid, field) in [
        (
            "{ multi_tau = { first = 0.0, last = 1e-5, per_octave = 8 } }",
            "motion.lags.multi_tau.first",
        ),
        (
            "{ multi_tau = { first = 1e-6, last = 1e-7, per_octave = 8 } }",
            "motion.lags.multi_tau.last",
        ),
        (
            "{ multi_tau = { first = 1e-6, last = 1e-5, per_octave = 0 } }",
            "motion.lags.multi_tau.per_octave",
        ),
        (
            "{ multi_tau = { first = 1e-9, last = 1e9, per_octave = 8 } }",
            "motion.lags.multi_tau.last",
        ),
        (
            "{ multitau = { first = 1e-6, last = 1e-5, per_octave = 8 } }",
            "motion.lags",
        ),
    ] {
        let s = write(dir.path(), "bad.toml", &dcs(dir.path(), grid));
        let o = speckle(
            dir.path(),
            &["g1", s.to_str().unwrap(), "-q", "--out", "bad"],
        );
        assert_eq!(o.status.code(), Some(2), "{grid}: {}", stderr(&o));
        assert!(stderr(&o).contains(field), "{grid}: {}", stderr(&o));
    }
    // A unit the project does not know.
    let text = dcs(dir.path(), "[0.0, 1e-6]").replace("time = \"s\"", "time = \"sec\"");
    let s = write(dir.path(), "unit.toml", &text);
    let o = speckle(
        dir.path(),
        &["g1", s.to_str().unwrap(), "-q", "--out", "bad"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("units.time"), "{}", stderr(&o));
}

/// Checks a study figure's x axis: at least three ticks, neighbours distinct, and `unit` in the
/// label.
fn check_axis(svg: &str, what: &str, unit: &str) {
    let (label, ticks) = x_axis(svg);
    println!("{what}: {label}: {ticks:?}");
    assert!(ticks.len() >= 3, "{what}: {ticks:?}");
    for w in ticks.windows(2) {
        assert_ne!(w[0], w[1], "{what}: neighbouring tick labels {ticks:?}");
    }
    assert!(label.contains(unit), "{what}: no {unit} in {label:?}");
}

/// The memory-tilt figures of the shipped Figs. 10b (reflection, angles to 240 mdeg) and 10e
/// (mixtures, to 25 mdeg), at a few paths: distinct ticks, the tilt's unit, one legend entry per
/// row and no C1 curve in reflection.
#[test]
fn memory_tilt_plots_have_distinct_ticks_and_units() {
    let dir = tempfile::tempdir().unwrap();
    for (file, rows, c1) in [
        ("fig10b_memory_albedo", 5, false),
        ("fig10e_memory_mixtures", 4, true),
    ] {
        let text = std::fs::read_to_string(format!(
            "{}/../../scenes/{file}.toml",
            env!("CARGO_MANIFEST_DIR")
        ))
        .unwrap();
        let s = write(dir.path(), &format!("{file}.toml"), &text);
        let o = speckle(
            dir.path(),
            &[
                "memory-tilt",
                s.to_str().unwrap(),
                "--paths",
                "3200",
                "-q",
                "--out",
                "m",
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let svg =
            std::fs::read_to_string(dir.path().join(format!("m/{file}.memory_tilt.svg"))).unwrap();
        check_axis(&svg, file, "millidegrees");
        let legend = texts(&svg)
            .iter()
            .filter(|(_, c)| c.contains("g = ") || c.contains("HG(") || c == "isotropic")
            .count();
        assert_eq!(legend, rows, "{file}: legend entries");
        assert_eq!(svg.contains("C1 (diffusion)"), c1, "{file}");
    }
}
