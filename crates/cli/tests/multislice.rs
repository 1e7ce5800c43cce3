//! `speckle wave --multislice`: multi-slice beam propagation through the exact solver's
//! configurations, written in `speckle wave`'s layout as `<name>.multislice_*`; the same bytes
//! for any thread count; scenes and arguments it cannot take refused with exit code 2, naming
//! the field. A few seconds.

mod common;
use common::*;

const SLAB: &str = r#"
name = "slab"
dimension = 2
wavelength = 1.0

[medium]
size = [20.0, 2.5, 0.0]
center = [0.0, 0.0, 0.0]
mean_free_path = 10.0
albedo = 1.0

[phase]
type = "isotropic"

[[sources]]
type = "plane_tilts"
direction = [0.0, 1.0, 0.0]
tilts_deg = [0.0]

[[sensors]]
type = "far_arc"
center = [0.0, 1.0, 0.0]
axis = [0.0, 0.0, 1.0]
angles_deg = [SENSORS]
n = 5

[render]
paths = 1000
seed = 3
configurations = 40
"#;

#[test]
fn multislice_renders_in_the_wave_layout() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "slab.toml",
        &SLAB.replace("SENSORS", "-20.0, 20.0"),
    );
    let mut bytes = Vec::new();
    for threads in ["1", "2"] {
        let out = format!("out{threads}");
        let o = speckle(
            dir.path(),
            &[
                "wave",
                "slab.toml",
                "--multislice",
                "--slice",
                "0.1",
                "--out",
                &out,
                "--threads",
                threads,
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let d = dir.path().join(&out);
        for f in [
            "slab.multislice_cov.npy",
            "slab.multislice_cov_stderr.npy",
            "slab.multislice_mean.npy",
            "slab.multislice_mean_stderr.npy",
            "slab.multislice_fields.npy",
            "slab.multislice.json",
        ] {
            assert!(d.join(f).is_file(), "{f} missing: {}", stdout(&o));
        }
        let meta: serde_json::Value =
            serde_json::from_slice(&std::fs::read(d.join("slab.multislice.json")).unwrap())
                .unwrap();
        let render = &meta["render"];
        assert!(render["solver"].as_str().unwrap().contains("multislice"));
        assert_eq!(render["slice"].as_f64(), Some(0.1));
        assert_eq!(render["configurations"].as_u64(), Some(40));
        // 40 configurations of 5 complex fields.
        assert_eq!(
            npy_f64(&d.join("slab.multislice_fields.npy")).len(),
            40 * 5 * 2
        );
        bytes.push(std::fs::read(d.join("slab.multislice_fields.npy")).unwrap());
    }
    assert_eq!(bytes[0], bytes[1], "the thread count changed the fields");
}

#[test]
fn multislice_refuses_what_it_cannot_model() {
    let dir = tempfile::tempdir().unwrap();
    // A reflection sensor: the pair is named.
    write(
        dir.path(),
        "back.toml",
        &SLAB.replace("SENSORS", "160.0, 200.0"),
    );
    let o = speckle(dir.path(), &["wave", "back.toml", "--multislice"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("pairs[0]"), "{}", stderr(&o));
    // A bad slice thickness is the library's to refuse, naming it.
    write(
        dir.path(),
        "slab.toml",
        &SLAB.replace("SENSORS", "-20.0, 20.0"),
    );
    let o = speckle(
        dir.path(),
        &["wave", "slab.toml", "--multislice", "--slice=-1"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("slice"), "{}", stderr(&o));
    // `--slice` needs `--multislice`.
    let o = speckle(dir.path(), &["wave", "slab.toml", "--slice", "0.1"]);
    assert!(!o.status.success());
}
