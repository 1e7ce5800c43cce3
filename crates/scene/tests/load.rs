//! Loading scene files: generators expand in order with their defaults filled in, flatland
//! scenes stay in the plane, tables load relative to the scene, overrides are validated like
//! the file's values. (The CLI's tests check the error messages of malformed scenes.)

use speckle_endpoints::{Sensor, Source};
use speckle_medium::{DVec3, Dimension, Medium};
use speckle_phase::{Phase, PhaseFunction};
use speckle_scene::schema::SensorSpec;
use speckle_scene::{LoadError, Overrides, Problem, load_str};
use std::path::Path;

const OK: &str = r#"
wavelength = 1.0
[medium]
size = [10, 10, 4]
mean_free_path = 5
[[sources]]
type = "plane_tilts"
tilts_deg = [0, 90]
[[sensors]]
type = "far_grid"
theta_x_deg = [-10, 10]
theta_y_deg = [0, 0]
nx = 3
ny = 1
"#;

fn load(text: &str) -> Result<Problem, LoadError> {
    load_str(text, "t.toml", Path::new("."), "t", &Overrides::default())
}

#[test]
fn generators_expand_in_order() {
    let p = load(OK).unwrap();
    assert_eq!((p.n_sources(), p.n_sensors(), p.pairs()), (2, 3, 6));
    let Source::PlaneWave { direction } = p.scene.sources()[1] else {
        panic!()
    };
    assert!((direction - DVec3::X).length() < 1e-12);
    let Sensor::FarField { direction } = p.scene.sensors()[0] else {
        panic!()
    };
    assert!(direction.x < 0.0 && direction.y.abs() < 1e-15);
    assert!((direction.x.atan2(direction.z).to_degrees() + 10.0).abs() < 1e-9);
    assert!(p.grid.is_none());
    assert_eq!(p.name, "t");
    assert_eq!(p.sources[1].tilt_deg, Some(90.0));
}

fn far_directions(p: &Problem) -> Vec<DVec3> {
    p.scene
        .sensors()
        .iter()
        .map(|s| match *s {
            Sensor::FarField { direction } => direction,
            Sensor::Point { .. } | Sensor::GaussianBeam(_) => panic!("not a far-field sensor"),
        })
        .collect()
}

#[test]
fn far_arc_expands_in_angle_order() {
    // 3D defaults: +z rotated about +y, so positive angles lean towards +x.
    let text = OK.replace(
        "type = \"far_grid\"\ntheta_x_deg = [-10, 10]\ntheta_y_deg = [0, 0]\nnx = 3\nny = 1",
        "type = \"far_arc\"\nangles_deg = [-30, 60]\nn = 4\n[[sensors]]\n\
         type = \"far_arc\"\ncenter = [1, 0, 0]\naxis = [0, 0, 2]\n\
         angles_deg = [45, 90]\nn = 1",
    );
    let p = load(&text).unwrap();
    let d = far_directions(&p);
    assert_eq!(d.len(), 5);
    for (k, deg) in [-30.0f64, 0.0, 30.0, 60.0].into_iter().enumerate() {
        let (s, c) = deg.to_radians().sin_cos();
        assert!(
            (d[k] - DVec3::new(s, 0.0, c)).length() < 1e-12,
            "{k}: {}",
            d[k]
        );
        assert_eq!(p.sensors[k].angle_deg, Some(deg), "{k}");
        assert_eq!(p.sensors[k].k, Some(k));
    }
    // n = 1 gives the first angle, about the given (normalised) axis.
    let h = 0.5f64.sqrt();
    assert!((d[4] - DVec3::new(h, h, 0.0)).length() < 1e-12, "{}", d[4]);
    assert_eq!(p.sensors[4].angle_deg, Some(45.0));
    // The defaults are filled in for the sidecar.
    let SensorSpec::FarArc { center, axis, .. } = &p.file.sensors[0] else {
        panic!()
    };
    assert_eq!(
        (*center, *axis),
        (Some([0.0, 0.0, 1.0]), Some([0.0, 1.0, 0.0]))
    );
    // The sidecar's description of a sensor.
    let json = serde_json::to_value(&p.sensors[1]).unwrap();
    assert_eq!(
        json,
        serde_json::json!({"entry": 0, "type": "far", "direction": d[1].to_array(),
                           "k": 1, "angle_deg": 0.0})
    );
}

#[test]
fn flatland_generators_default_to_the_plane() {
    let text = r#"
dimension = 2
wavelength = 1.0
[medium]
size = [10, 6, 0]
center = [1, 0, 0]
mean_free_path = 5
[[sources]]
type = "plane_tilts"
tilts_deg = [0, 90]
[[sensors]]
type = "far_arc"
angles_deg = [0, 270]
n = 4
"#;
    let p = load(text).unwrap();
    assert_eq!(p.dimension(), Dimension::Two);
    let b = p.scene.medium().bounds();
    assert_eq!(
        (b.min().to_array(), b.max().to_array()),
        ([-4.0, -3.0, 0.0], [6.0, 3.0, 0.0])
    );
    assert!(matches!(p.scene.phase(), Phase::FlatIsotropic));
    // +y rotated counter-clockwise about +z: +y, -x, -y, +x; exactly z = 0.
    let want = [DVec3::Y, -DVec3::X, -DVec3::Y, DVec3::X];
    for (v, w) in far_directions(&p).iter().zip(want) {
        assert!((*v - w).length() < 1e-12 && v.z == 0.0, "{v} vs {w}");
    }
    let Source::PlaneWave { direction } = p.scene.sources()[1] else {
        panic!()
    };
    assert!((direction + DVec3::X).length() < 1e-12 && direction.z == 0.0);
    assert_eq!(p.pair_shape(), vec![2, 4]);
}

#[test]
fn flatland_tables_take_signed_angles_and_synonyms() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("a.csv"),
        "theta_deg,re_s,im_s\n0,1,0\n90,2,0.5\n180,0.5,0\n270,0.2,0\n360,1,0\n",
    )
    .unwrap();
    let text = r#"
dimension = 2
wavelength = 1.0
[medium]
size = [10, 6, 0]
mean_free_path = 5
[phase]
type = "tabulated"
file = "a.csv"
[[sources]]
type = "plane"
direction = [0, 1, 0]
[[sensors]]
type = "far"
direction = [1, 0, 0]
"#;
    let p = load_str(text, "t.toml", dir.path(), "t", &Overrides::default()).unwrap();
    let Phase::FlatTabulated(t) = p.scene.phase() else {
        panic!("{:?}", p.scene.phase())
    };
    // Asymmetric: +90 degrees (counter-clockwise) is the bright side.
    let inc = DVec3::X;
    assert!(
        t.amplitude_between(inc, DVec3::Y).norm()
            > 5.0 * t.amplitude_between(inc, -DVec3::Y).norm()
    );
}

#[test]
fn overrides_apply_before_validation() {
    let o = Overrides {
        paths: Some(0),
        ..Default::default()
    };
    let e = load_str(OK, "t.toml", Path::new("."), "t", &o).unwrap_err();
    assert_eq!(e.field(), Some("render.paths"), "{e}");
    assert!(
        e.to_string()
            .starts_with("t.toml: render.paths: must be >= 2"),
        "{e}"
    );
    let o = Overrides {
        seed: Some(9),
        forward_only: true,
        out: Some("elsewhere".into()),
        ..Default::default()
    };
    let p = load_str(OK, "t.toml", Path::new("."), "t", &o).unwrap();
    assert_eq!(p.render.seed, 9);
    assert_eq!(p.render.coherence, speckle_paths::Coherence::ForwardOnly);
    assert_eq!(p.out_dir(), Path::new("elsewhere"));
}

#[test]
fn the_summary_and_the_sidecar_describe_the_scene() {
    let p = load(OK).unwrap();
    let s = p.summary("not computed");
    assert!(
        s.contains("  pairs J              6 (all combinations"),
        "{s}"
    );
    assert!(
        s.contains("  wave                 200 configurations; not computed"),
        "{s}"
    );
    let meta = p.sidecar(
        "check",
        serde_json::json!({}),
        serde_json::json!({}),
        serde_json::json!({}),
    );
    assert_eq!(meta["derived"]["n_sources"], 2);
    assert_eq!(meta["derived"]["mean_free_path"], 5.0);
    assert_eq!(
        meta["scene"]["sources"][0]["axis"],
        serde_json::json!([0.0, 1.0, 0.0])
    );
    // The expanded endpoints and pairs are tables beside the sidecar (issue 14).
    assert_eq!(meta["sources"]["count"], 2);
    assert_eq!(meta["sources"]["file"], "t.check.sources.npy");
    assert_eq!(meta["pairs"]["count"], 6);
    let tables = p.tables("check");
    let names: Vec<&str> = tables.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "t.check.pairs.npy",
            "t.check.sources.npy",
            "t.check.sensors.npy"
        ]
    );
    let sources = speckle_scene::npy::decode_real(&tables[1].1).unwrap();
    assert_eq!(sources.shape, vec![2, 7]);
    // Row 1: entry 0, a plane wave (kind 0), tilted by 90 degrees (column p).
    assert_eq!(&sources.data[7..9], &[0.0, 0.0]);
    assert_eq!(sources.data[7 + 5], 90.0);
    let pairs = speckle_scene::npy::decode_real(&tables[0].1).unwrap();
    assert_eq!(pairs.shape, vec![6, 2]);
    assert!(pairs.integer);
    assert_eq!(&pairs.data[2..4], &[0.0, 1.0]);
    assert_eq!(
        meta["derived"]["phase_mean_cosine"],
        p.scene.phase().mean_cosine()
    );
    assert!(meta["derived"]["medium_info"].is_null());
}

/// `gaussian_beam` sources and sensors: focus (inside the medium allowed), axis default `+z`
/// (`+y` in flatland), concentration or numerical aperture (`gamma = 4 / NA^2`), the sensor's
/// source form reversed; errors name the field.
#[test]
fn gaussian_beams_load_and_name_their_fields() {
    let scene = |src: &str, sen: &str, dim: u8| {
        format!(
            "wavelength = 1.0\ndimension = {dim}\n[medium]\nsize = [10, 10, {}]\n\
             mean_free_path = 5\n[[sources]]\ntype = \"gaussian_beam\"\n{src}\n\
             [[sensors]]\ntype = \"gaussian_beam\"\n{sen}\n",
            if dim == 3 { "4" } else { "0" }
        )
    };
    let p = load(&scene(
        "focus = [0, 0, -2]\nnumerical_aperture = 0.5",
        "focus = [1, 0, 0.5]\naxis = [0, 0.6, 0.8]\nconcentration = 3",
        3,
    ))
    .unwrap();
    let Source::GaussianBeam(b) = p.scene.sources()[0] else {
        panic!("a gaussian beam source");
    };
    assert_eq!(
        (b.focus, b.axis, b.concentration),
        (DVec3::new(0.0, 0.0, -2.0), DVec3::Z, 16.0)
    );
    let Sensor::GaussianBeam(s) = p.scene.sensors()[0] else {
        panic!("a gaussian beam sensor");
    };
    assert_eq!((s.axis, s.concentration), (DVec3::new(0.0, 0.6, 0.8), 3.0));
    assert_eq!(
        p.scene.sensors()[0].reciprocal(),
        Source::GaussianBeam(s.reversed())
    );
    let flat = load(&scene(
        "focus = [0, -1, 0]\nconcentration = 2",
        "focus = [0, 1, 0]\nconcentration = 2",
        2,
    ))
    .unwrap();
    let Source::GaussianBeam(b) = flat.scene.sources()[0] else {
        panic!("a gaussian beam source");
    };
    assert_eq!(b.axis, DVec3::Y);
    let err = |src: &str, sen: &str, dim: u8| load(&scene(src, sen, dim)).unwrap_err().to_string();
    let ok_sen = "focus = [0, 0, 3]\nconcentration = 1";
    for (src, field) in [
        ("focus = [0, 0, 1]", "sources[0].concentration"),
        (
            "focus = [0, 0, 1]\nconcentration = 1\nnumerical_aperture = 0.5",
            "sources[0].concentration",
        ),
        (
            "focus = [0, 0, 1]\nconcentration = -1",
            "sources[0].concentration",
        ),
        (
            "focus = [0, 0, 1]\nnumerical_aperture = 1.5",
            "sources[0].numerical_aperture",
        ),
        (
            "focus = [0, 0, 1]\naxis = [0, 0, 0]\nconcentration = 1",
            "sources[0].axis",
        ),
        ("focus = [0, nan, 1]\nconcentration = 1", "sources[0].focus"),
    ] {
        let e = err(src, ok_sen, 3);
        assert!(e.contains(field), "{src}: {e}");
    }
    let e = err(
        "focus = [0, 0, 1]\nconcentration = 1",
        "focus = [0, 0, 3]\naxis = [0, 0, 1]\nconcentration = 1",
        2,
    );
    assert!(
        e.contains("sources[0].focus") || e.contains("sensors[0]"),
        "{e}"
    );
}

#[test]
fn render_beams_loads_names_its_field_and_reaches_the_sidecar() {
    use speckle_paths::BeamStrategy;
    let with = |v: &str| format!("{OK}[render]\nbeams = {v}\n");
    // The default follows the beams in position and direction.
    let p = load(OK).unwrap();
    assert_eq!(p.render.sampling.beams, BeamStrategy::PositionAndDirection);
    for (v, want, name) in [
        ("\"off\"", BeamStrategy::Off, "off"),
        ("\"position\"", BeamStrategy::Position, "position"),
        (
            "\"position_and_direction\"",
            BeamStrategy::PositionAndDirection,
            "position_and_direction",
        ),
    ] {
        let p = load(&with(v)).unwrap();
        assert_eq!(p.render.sampling.beams, want);
        assert_eq!(p.render.tracer_json()["beams"], name);
    }
    for bad in ["\"sometimes\"", "1", "true"] {
        let e = load(&with(bad)).unwrap_err().to_string();
        assert!(e.contains("render.beams"), "{bad}: {e}");
    }
}

#[test]
fn render_nearfield_loads_names_its_field_and_reaches_the_scene_and_sidecar() {
    use speckle_endpoints::NearField;
    let with = |v: &str| format!("{OK}[render]\nnearfield = {v}\n");
    // The default fits each plane wave's own attenuation.
    let p = load(OK).unwrap();
    assert_eq!(p.render.near_field, NearField::Fitted);
    assert_eq!(p.scene.near_field(), NearField::Fitted);
    for (v, want) in [
        ("exact", NearField::Exact),
        ("fitted", NearField::Fitted),
        ("paper", NearField::Paper),
    ] {
        let p = load(&with(&format!("\"{v}\""))).unwrap();
        assert_eq!((p.render.near_field, p.scene.near_field()), (want, want));
        assert_eq!(p.render.paths_json(1, 0.0)["nearfield"], v);
    }
    for bad in ["\"axial\"", "1", "true"] {
        let e = load(&with(bad)).unwrap_err().to_string();
        assert!(e.contains("render.nearfield"), "{bad}: {e}");
    }
}

#[test]
fn the_estimates_of_commands_that_compute_means_include_them() {
    // Issue 27, item 8: the closed-form mean of a large far grid, estimated at hours by
    // `speckle mean`, was not counted in the estimates of the commands that compute it.
    use speckle_scene::cost::Command;
    let text = |add_mean: bool| {
        format!(
            "wavelength = 1.0\n[medium]\nsize = [40.0, 40.0, 10.0]\nmean_free_path = 5.0\n\
             [[sources]]\ntype = \"plane\"\ndirection = [0.0, 0.0, 1.0]\n[[sensors]]\n\
             type = \"far_grid\"\ntheta_x_deg = [-5.0, 5.0]\ntheta_y_deg = [-5.0, 5.0]\n\
             nx = 300\nny = 300\n[render]\npaths = 100\nrealizations = 2\n\
             paths_per_realization = 10\nadd_mean = {add_mean}\n[output]\npng = false\n"
        )
    };
    let p = load(&text(true)).unwrap();
    let mean = p.estimate(Command::Mean, 1).unwrap().seconds;
    let with_mean = p.estimate(Command::Fields, 1).unwrap();
    let without = load(&text(false))
        .unwrap()
        .estimate(Command::Fields, 1)
        .unwrap();
    let covariance = p.estimate(Command::Covariance, 1).unwrap();
    assert!(
        mean > 100.0 * without.seconds,
        "{mean} against {}",
        without.seconds
    );
    assert!(with_mean.seconds >= mean && covariance.seconds >= mean);
    assert_eq!(with_mean.time_field, "sensors");
    // The intensity computes no mean.
    assert!(p.estimate(Command::Intensity, 1).unwrap().seconds < mean);
}

#[test]
fn a_dense_layer_sets_the_path_length_whatever_the_grids_mean() {
    // Issue 27, a fuzz finding: a scalp of 4.3e9 /cm scattering (albedo 1 - 4e-11) over a CSF
    // of 1e15 /cm absorption. At the grid's mean extinction and albedo a path has about one
    // vertex; in the scalp, where the source's paths start, about 1e10. The estimate must see
    // the layer: far beyond a day, so the guard refuses the render.
    let text = include_str!("../../fuzz/corpus/finding_dense_scalp.toml");
    let p = load(text).unwrap();
    let e = p
        .estimate(speckle_scene::cost::Command::Intensity, 1)
        .unwrap();
    assert!(e.vertices_per_path > 1e9, "{}", e.vertices_per_path);
    assert!(
        e.seconds > speckle_scene::cost::MAX_SECONDS,
        "{}",
        e.seconds
    );
    // The shipped head: its layers give the same order as its mean (about a thousand vertices
    // per path, capped by absorption).
    let head = load(speckle_scene::examples::example("head").unwrap()).unwrap();
    let v = head.vertices_per_path();
    assert!(v > 100.0 && v < 1e4, "{v}");
}
