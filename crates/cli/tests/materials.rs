//! End-to-end tests of the material commands and scene entries: `speckle mie`,
//! `speckle fit-phase`, `[[medium.particles]]` (Mie types), `[medium.grid]` voxel grids from
//! `.npy` files, and phase mixtures. Bad input exits with code 2 and names the field.

use std::path::Path;
use std::process::Output;

mod common;
use common::*;

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A `.npy` file (version 1.0, C order) of little-endian values with the given dtype.
fn npy(shape: &str, descr: &str, body: &[u8]) -> Vec<u8> {
    let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}\n");
    let mut v = b"\x93NUMPY\x01\x00".to_vec();
    v.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    v.extend_from_slice(dict.as_bytes());
    v.extend_from_slice(body);
    v
}

const ENDS: &str = r#"
[[sources]]
type = "plane"
direction = [0.0, 0.0, 1.0]

[[sensors]]
type = "far_arc"
angles_deg = [0.0, 170.0]
n = 4

[render]
paths = 2000
"#;

fn scene(medium: &str) -> String {
    format!("name = \"m\"\nwavelength = 0.532\n{medium}\n{ENDS}")
}

const PARTICLES: &str = r#"
[medium]
size = [20.0, 20.0, 5.0]
host_index = 1.33

[[medium.particles]]
radius = 0.1
index = [1.196, 0.0]
volume_fraction = 0.01

[[medium.particles]]
radius = 0.5
index = [1.196, 0.001]
number_density = 0.004
"#;

const LAYERS: &str = r#"
[medium]
size = [4.0, 4.0, 2.0]

[medium.grid]
file = "layers.npy"
kind = "materials"

[[medium.materials]]
sigma_s = 0.5
sigma_a = 0.1
phase = { type = "hg", g = 0.5 }

[[medium.materials]]
mean_free_path = 0.7
phase = { type = "hg_mixture", weights = [0.5, 0.5], g = [0.8, -0.8] }
"#;

fn setup(dir: &Path) {
    let ids: Vec<u8> = [0i32, 1].iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(dir.join("layers.npy"), npy("(1, 1, 2)", "<i4", &ids)).unwrap();
    let dens: Vec<u8> = [1.0f64, 0.5, 2.0, 0.0]
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .collect();
    std::fs::write(dir.join("dens.npy"), npy("(2, 1, 2)", "<f8", &dens)).unwrap();
    std::fs::write(dir.join("floats.npy"), npy("(1, 1, 2)", "<f8", &dens[..16])).unwrap();
    std::fs::write(dir.join("wrong.npy"), npy("(2, 2)", "<i4", &[0; 16])).unwrap();
}

#[test]
fn particle_and_grid_scenes_render() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let density = r#"
[medium]
size = [4.0, 4.0, 2.0]
sigma_s = 1.0
sigma_a = 0.1

[medium.grid]
file = "dens.npy"
kind = "density"
"#;
    for (name, medium) in [("p", PARTICLES), ("g", LAYERS), ("d", density)] {
        std::fs::write(dir.path().join(format!("{name}.toml")), scene(medium)).unwrap();
        let file = format!("{name}.toml");
        let o = speckle(dir.path(), &["check", &file]);
        assert!(o.status.success(), "{name}: {}", text(&o));
        let o = speckle(dir.path(), &["covariance", &file, "-q", "--no-png"]);
        assert!(o.status.success(), "{name}: {}", text(&o));
        assert!(dir.path().join("out/m.cov.npy").exists());
    }
    // The check of the particle scene reports both Mie types and the host wavelength.
    let o = speckle(dir.path(), &["check", "p.toml"]);
    let t = text(&o);
    assert!(
        t.contains("particles[1]") && t.contains("0.4 in the host"),
        "{t}"
    );
}

#[test]
fn material_input_errors_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path());
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "radius",
            scene(&PARTICLES.replacen("radius = 0.1", "radius = -0.1", 1)),
            "medium.particles[0].radius",
        ),
        (
            "both concentrations",
            scene(&PARTICLES.replacen(
                "volume_fraction = 0.01",
                "volume_fraction = 0.01\nnumber_density = 1.0",
                1,
            )),
            "medium.particles[0]",
        ),
        (
            "index",
            scene(&PARTICLES.replacen("[1.196, 0.001]", "[1.196, -0.1]", 1)),
            "medium.particles[1].index[1]",
        ),
        (
            "packing",
            scene(&PARTICLES.replacen("volume_fraction = 0.01", "volume_fraction = 0.9", 1)),
            "medium.particles",
        ),
        (
            "phase with particles",
            scene(&format!("[phase]\ntype = \"hg\"\ng = 0.5\n{PARTICLES}")),
            "phase",
        ),
        (
            "coefficients with particles",
            scene(&PARTICLES.replacen("host_index = 1.33", "host_index = 1.33\nsigma_s = 1.0", 1)),
            "medium.particles",
        ),
        (
            "grid shape",
            scene(&LAYERS.replacen("layers.npy", "wrong.npy", 1)),
            "medium.grid.file",
        ),
        (
            "float ids",
            scene(&LAYERS.replacen("layers.npy", "floats.npy", 1)),
            "medium.grid.file",
        ),
        (
            "missing file",
            scene(&LAYERS.replacen("layers.npy", "nope.npy", 1)),
            "medium.grid.file",
        ),
        (
            "id out of range",
            scene(&LAYERS.replacen(
                "[[medium.materials]]\nmean_free_path = 0.7\nphase = { type = \"hg_mixture\", weights = [0.5, 0.5], g = [0.8, -0.8] }",
                "",
                1,
            )),
            "medium.grid",
        ),
        (
            "material coefficient",
            scene(&LAYERS.replacen("sigma_a = 0.1", "sigma_a = -0.1", 1)),
            "medium.materials[0].sigma_a",
        ),
        (
            "mixture g",
            scene(&LAYERS.replacen("g = [0.8, -0.8]", "g = [0.8, -1.0]", 1)),
            "medium.materials[1].phase",
        ),
        (
            "mixture lengths",
            scene(&LAYERS.replacen("g = [0.8, -0.8]", "g = [0.8]", 1)),
            "medium.materials[1].phase.g",
        ),
        (
            "materials without a grid",
            scene(
                "[medium]\nsize = [4.0, 4.0, 2.0]\nsigma_s = 1.0\n[[medium.materials]]\nsigma_s = 1.0",
            ),
            "medium.materials",
        ),
        (
            "host index",
            scene(&PARTICLES.replacen("host_index = 1.33", "host_index = 0.0", 1)),
            "medium.host_index",
        ),
        (
            "vmf alpha",
            scene(
                "[medium]\nsize = [4.0, 4.0, 2.0]\nsigma_s = 1.0\n[phase]\ntype = \"vmf\"\ngamma = [0.0, 5.0]\nalpha = [1.0, -1.0]",
            ),
            "phase",
        ),
    ];
    for (what, text_, field) in &cases {
        std::fs::write(dir.path().join("bad.toml"), text_).unwrap();
        let o = speckle(dir.path(), &["check", "bad.toml"]);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{what}: {t}");
        assert!(t.contains(field), "{what}: expected {field:?} in {t}");
        assert!(!t.contains("panicked"), "{what}: {t}");
    }
}

#[test]
fn mie_and_fit_phase_write_files_a_scene_can_use() {
    let dir = tempfile::tempdir().unwrap();
    let o = speckle(
        dir.path(),
        &[
            "mie",
            "--radius",
            "0.5",
            "--index",
            "1.2",
            "--host-index",
            "1.33",
            "--wavelength",
            "0.532",
            "--out",
            "o",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("Q_sca"));
    // The amplitude table is a valid tabulated phase function of a scene.
    let s = scene(
        "[medium]\nsize = [20.0, 20.0, 5.0]\nsigma_s = 0.05\n[phase]\ntype = \"tabulated\"\nfile = \"o/mie.mie_amplitude.csv\"",
    );
    std::fs::write(dir.path().join("t.toml"), s).unwrap();
    let o = speckle(dir.path(), &["check", "t.toml"]);
    assert!(o.status.success(), "{}", text(&o));
    // An HG fit converges with g kept, and its [phase] table loads in a scene.
    let o = speckle(dir.path(), &["fit-phase", "--hg", "0.9", "--out", "o"]);
    let t = text(&o);
    assert!(o.status.success() && t.contains("converged"), "{t}");
    let table = std::fs::read_to_string(dir.path().join("o/fit.vmf.toml")).unwrap();
    let s = scene(&format!(
        "[medium]\nsize = [20.0, 20.0, 5.0]\nsigma_s = 0.05\n{table}"
    ));
    std::fs::write(dir.path().join("v.toml"), s).unwrap();
    let o = speckle(dir.path(), &["check", "v.toml"]);
    let t = text(&o);
    assert!(
        o.status.success() && t.contains("mean cosine 0.9000"),
        "{t}"
    );
    // The scene renders the mixture itself (Phase::Vmf, not a table): its mean cosine is the
    // fit's closed-form g, bitwise (the table carries 18 significant digits).
    let o = speckle(dir.path(), &["covariance", "v.toml", "-q", "--no-png"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(dir.path().join("out/m.cov.npy").exists());
    let json = |p: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(p)).unwrap()).unwrap()
    };
    let g_fit = json("o/fit.vmf.json")["g_fit"].as_f64().unwrap();
    let g_scene = json("out/m.cov.json")["derived"]["phase_mean_cosine"]
        .as_f64()
        .unwrap();
    assert_eq!(g_scene, g_fit);
    // Bad input: exit 2 naming the option.
    for (args, field) in [
        (&["fit-phase", "--hg", "1.0"][..], "--hg"),
        (&["fit-phase"][..], "--hg/--mie-radius/--table"),
        (
            &["fit-phase", "--hg", "0.5", "--tolerance", "0"][..],
            "--tolerance",
        ),
        (
            &[
                "mie",
                "--radius",
                "0",
                "--index",
                "1.2",
                "--wavelength",
                "0.5",
            ][..],
            "--radius",
        ),
        (
            &[
                "mie",
                "--radius",
                "1",
                "--index",
                "1.2",
                "--wavelength",
                "0.5",
                "--volume-fraction",
                "2",
            ][..],
            "--volume-fraction",
        ),
    ] {
        let o = speckle(dir.path(), args);
        let t = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {t}");
        assert!(t.contains(field), "{args:?}: expected {field:?} in {t}");
    }
}
