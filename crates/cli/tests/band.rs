//! `speckle covariance --band R`: the band of an image's covariance, its files and sidecar,
//! and what it refuses (the values against the dense render: `tests/band.rs`).

mod common;
use common::*;

const SCENE: &str = r#"
name = "b"
wavelength = 1.0
[medium]
size = [20.0, 20.0, 2.0]
mean_free_path = 4.0
[phase]
type = "hg"
g = 0.5
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]
[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.5, 2.5]
nx = 9
ny = 5
[render]
paths = 2000
"#;

#[test]
fn band_writes_its_array_and_refuses_what_it_cannot_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(d, "b.toml", SCENE);
    let o = speckle(d, &["covariance", "b.toml", "--band", "2", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.join("out");
    let header = std::fs::read(out.join("b.cov_band.npy")).unwrap();
    let text = String::from_utf8_lossy(&header[..128]);
    assert!(
        text.contains("'descr': '<c16'") && text.contains("'shape': (1, 5, 9, 1, 5, 5)"),
        "{text}"
    );
    let v = npy_f64(&out.join("b.cov_band.npy"));
    assert_eq!(v.len(), 2 * 5 * 9 * 5 * 5);
    // Pixel (0, 0): its own intensity at offset (0, 0) is positive, offsets above it NaN.
    let at = |y: usize, x: usize, dy: usize, dx: usize| v[2 * (((y * 9 + x) * 5 + dy) * 5 + dx)];
    assert!(at(0, 0, 2, 2) > 0.0 && at(0, 0, 0, 2).is_nan() && at(0, 0, 2, 0).is_nan());
    assert!(at(4, 8, 2, 2) > 0.0 && at(4, 8, 4, 2).is_nan());
    let json = std::fs::read_to_string(out.join("b.cov_band.json")).unwrap();
    for want in [
        "edge_correlation",
        "mean_correlation_by_offset",
        "\"radius\": 2",
    ] {
        assert!(json.contains(want), "{want}: {json}");
    }
    assert!(!out.join("b.cov.npy").exists());
    // A radius across the image; a scene without an image of sensors; shards.
    let o = speckle(d, &["covariance", "b.toml", "--band", "9", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("band"), "{}", stderr(&o));
    let grid =
        "type = \"far_grid\"\ntheta_x_deg = [-5.0, 5.0]\ntheta_y_deg = [-2.5, 2.5]\nnx = 9\nny = 5";
    assert!(SCENE.contains(grid));
    write(
        d,
        "f.toml",
        &SCENE.replace(grid, "type = \"far\"\ndirection = [0.0, 0.0, 1.0]"),
    );
    let o = speckle(d, &["covariance", "f.toml", "--band", "1", "-q"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("sensors: --band needs"),
        "{}",
        stderr(&o)
    );
    let o = speckle(
        d,
        &[
            "covariance",
            "b.toml",
            "--band",
            "1",
            "--shard",
            "1/2",
            "-q",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("shard"), "{}", stderr(&o));
}

/// `--band auto`: the radius is the last pixel offset at which a pilot's correlation curve of
/// the central pixel reaches `--epsilon` (recorded in the sidecar); against the dense covariance
/// of the same scene and paths, every dropped entry's `|C| / sqrt(I I)` is below `epsilon`
/// within five of its standard errors (the largest is printed). The slab's sharp edges give
/// the correlation side lobes (a `sinc`) that a Gaussian grain would drop. Bad `--epsilon` and
/// `--band` values are refused naming them.
#[test]
fn band_auto_keeps_what_a_pilot_sees_above_epsilon() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let wide = SCENE
        .replace("size = [20.0, 20.0, 2.0]", "size = [60.0, 60.0, 2.0]")
        .replace("theta_x_deg = [-5.0, 5.0]", "theta_x_deg = [-4.0, 4.0]")
        .replace("theta_y_deg = [-2.5, 2.5]", "theta_y_deg = [-4.0, 4.0]")
        .replace("nx = 9", "nx = 17")
        .replace("ny = 5", "ny = 17")
        .replace("paths = 2000", "paths = 20000\nseed = 3");
    write(d, "w.toml", &wide);
    let eps: f64 = 0.05;
    let o = speckle(
        d,
        &[
            "covariance",
            "w.toml",
            "--band",
            "auto",
            "--epsilon",
            "0.05",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    println!("{}", stdout(&o).lines().next().unwrap_or(""));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("out/b.cov_band.json")).unwrap())
            .unwrap();
    let s = &json["summary"];
    let r = s["radius"].as_u64().unwrap() as usize;
    let auto = &s["auto"];
    assert_eq!(auto["epsilon"].as_f64(), Some(eps));
    let curve = |axis: &str| -> Vec<f64> {
        auto[axis]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect()
    };
    let (cx, cy) = (curve("pilot_correlation_x"), curve("pilot_correlation_y"));
    assert_eq!((cx.len(), cy.len()), (16, 16));
    // The radius is the last offset at or above epsilon on either axis.
    let last = |c: &[f64]| c.iter().rposition(|&v| v >= eps).map_or(0, |k| k + 1);
    assert_eq!(r, last(&cx).max(last(&cy)).max(1), "{auto}");
    assert!((2..16).contains(&r), "radius {r}: {auto}");
    // The dense covariance of the same paths: what the band dropped.
    let o = speckle(d, &["covariance", "w.toml", "-q", "--no-png"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let c = npy_f64(&d.join("out/b.cov.npy"));
    let se = npy_f64(&d.join("out/b.cov_stderr.npy"));
    let (n, j) = (17usize, 289usize);
    let at = |v: &[f64], p: usize, q: usize| (v[2 * (p * j + q)], v[2 * (p * j + q) + 1]);
    let (mut largest, mut worst) = (0.0f64, f64::NEG_INFINITY);
    for p in 0..j {
        for q in 0..j {
            let (dy, dx) = ((p / n).abs_diff(q / n), (p % n).abs_diff(q % n));
            if dy <= r && dx <= r {
                continue;
            }
            let norm = (at(&c, p, p).0 * at(&c, q, q).0).sqrt();
            let (re, im) = at(&c, p, q);
            let (sr, si) = at(&se, p, q);
            let rho = re.hypot(im) / norm;
            largest = largest.max(rho);
            worst = worst.max(rho - 5.0 * sr.hypot(si) / norm);
        }
    }
    println!("radius {r}: largest dropped correlation {largest:.4} (epsilon {eps})");
    assert!(
        worst <= eps,
        "a dropped entry above epsilon by 5 SE: {worst}"
    );
    // Bad values name the argument.
    for (args, want) in [
        (&["--band", "auto", "--epsilon", "1.5"][..], "--epsilon"),
        (&["--band", "auto", "--epsilon", "nan"][..], "--epsilon"),
        (&["--band", "wide"][..], "--band"),
    ] {
        let mut all = vec!["covariance", "w.toml", "-q"];
        all.extend_from_slice(args);
        let o = speckle(d, &all);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    }
}
