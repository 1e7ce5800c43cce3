//! End-to-end tests of the `speckle` binary: malformed scenes are rejected with the field named
//! and exit code 2, renders write loadable `.npy` and JSON files, and a cancelled render writes
//! nothing.

use std::path::Path;
use std::process::Command;

mod common;
use common::*;

/// A tiny valid scene: 2 plane waves, a 3 x 2 far-field image (J = 12).
const TINY: &str = r#"
name = "tiny"
wavelength = 1.0

[medium]
size = [8.0, 8.0, 3.0]
mean_free_path = 4.0
albedo = 0.9

[phase]
type = "hg"
g = 0.4

[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 3.0]

[[sensors]]
type = "far_grid"
theta_x_deg = [-5.0, 5.0]
theta_y_deg = [-2.0, 2.0]
nx = 3
ny = 2

[render]
paths = 4000
seed = 5
realizations = 3
paths_per_realization = 500

[output]
dir = "res"
png_realizations = 2
"#;

/// A minimal valid scene whose parts the malformed cases replace.
fn scene(
    top: &str,
    medium: &str,
    phase: &str,
    sources: &str,
    sensors: &str,
    render: &str,
) -> String {
    format!(
        "{top}\n[medium]\n{medium}\n[phase]\n{phase}\n{sources}\n{sensors}\n[render]\n{render}\n"
    )
}

const TOP: &str = "wavelength = 1.0";
const MEDIUM: &str = "size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0";
const PHASE: &str = "type = \"hg\"\ng = 0.5";
const SOURCES: &str = "[[sources]]\ntype = \"plane\"\ndirection = [0.0, 0.0, 1.0]";
const SENSORS: &str = "[[sensors]]\ntype = \"far\"\ndirection = [0.0, 0.0, 1.0]";
const RENDER: &str = "paths = 100";

const TOP_2D: &str = "dimension = 2\nwavelength = 1.0";
const MEDIUM_2D: &str = "size = [4.0, 4.0, 0.0]\nmean_free_path = 2.0";
const SOURCES_2D: &str = "[[sources]]\ntype = \"plane\"\ndirection = [0.0, 1.0, 0.0]";
const SENSORS_2D: &str = "[[sensors]]\ntype = \"far\"\ndirection = [0.0, 1.0, 0.0]";

/// The parts of a minimal valid scene, in the order of [`scene`]'s arguments.
type Parts = [&'static str; 6];
const VALID_3D: Parts = [TOP, MEDIUM, PHASE, SOURCES, SENSORS, RENDER];
const VALID_2D: Parts = [TOP_2D, MEDIUM_2D, PHASE, SOURCES_2D, SENSORS_2D, RENDER];

/// One editor per part of `base`: `editors(base)[i](text)` is the scene with part `i` replaced.
fn editors(base: Parts) -> [impl Fn(&str) -> String; 6] {
    std::array::from_fn(|i| {
        move |text: &str| {
            let mut p: [&str; 6] = base;
            p[i] = text;
            scene(p[0], p[1], p[2], p[3], p[4], p[5])
        }
    })
}

#[test]
fn the_bases_of_the_malformed_cases_are_valid() {
    let dir = tempfile::tempdir().unwrap();
    for (base, dimension) in [(VALID_3D, "3"), (VALID_2D, "2 (flatland")] {
        let p = write(dir.path(), "ok.toml", &editors(base)[0](base[0]));
        let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = stdout(&o);
        assert!(out.contains("pairs J              1"), "{out}");
        assert!(
            out.contains(&format!("dimension            {dimension}")),
            "{out}"
        );
    }
}

#[test]
fn malformed_scenes_name_the_field_and_exit_with_2() {
    let [t, m, p, so, se, r] = editors(VALID_3D);
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "nan wavelength",
            t("wavelength = nan"),
            "wavelength: must be finite and > 0 (got NaN)",
        ),
        (
            "negative wavelength",
            t("wavelength = -1.0"),
            "wavelength: must be finite",
        ),
        (
            "missing wavelength",
            t("name = \"x\""),
            "missing field `wavelength`",
        ),
        ("string wavelength", t("wavelength = \"1\""), "wavelength"),
        (
            "unknown top-level key",
            t("wavelength = 1.0\nwavelenght = 1.0"),
            "wavelenght",
        ),
        (
            "bad name",
            t("wavelength = 1.0\nname = \"../x\""),
            "name: must be",
        ),
        (
            "infinite mean free path",
            m("size = [4.0, 4.0, 2.0]\nmean_free_path = inf"),
            "medium.mean_free_path: must be finite and > 0 (got inf)",
        ),
        (
            "negative mean free path",
            m("size = [4.0, 4.0, 2.0]\nmean_free_path = -1.0"),
            "medium.mean_free_path: must be finite and > 0 (got -1)",
        ),
        (
            "negative sigma_s",
            m("size = [4.0, 4.0, 2.0]\nsigma_s = -0.1"),
            "medium.sigma_s",
        ),
        (
            "negative sigma_a",
            m("size = [4.0, 4.0, 2.0]\nsigma_s = 0.1\nsigma_a = -0.1"),
            "medium.sigma_a",
        ),
        (
            "nan sigma_a",
            m("size = [4.0, 4.0, 2.0]\nsigma_s = 0.1\nsigma_a = nan"),
            "medium.sigma_a",
        ),
        (
            "albedo above one",
            m("size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0\nalbedo = 1.5"),
            "medium.albedo",
        ),
        (
            "two parametrisations",
            m("size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0\nsigma_s = 0.5"),
            "medium.mean_free_path: cannot be combined",
        ),
        (
            "no coefficients",
            m("size = [4.0, 4.0, 2.0]"),
            "medium: no coefficients",
        ),
        (
            "negative size",
            m("size = [4.0, 4.0, -2.0]\nmean_free_path = 2.0"),
            "medium.size[2]",
        ),
        (
            "short size",
            m("size = [4.0, 4.0]\nmean_free_path = 2.0"),
            "medium.size",
        ),
        (
            "unknown medium key",
            m("size = [4.0, 4.0, 2.0]\nsigm_s = 0.5"),
            "medium.sigm_s",
        ),
        (
            "g of one",
            p("type = \"hg\"\ng = 1.0"),
            "phase.g: must be finite with |g| < 1",
        ),
        ("g below minus one", p("type = \"hg\"\ng = -1.5"), "phase.g"),
        ("nan g", p("type = \"hg\"\ng = nan"), "phase.g"),
        (
            "isotropic with g",
            p("type = \"isotropic\"\ng = 0.5"),
            "phase.g",
        ),
        ("unknown phase type", p("type = \"mie\""), "phase.type"),
        (
            "missing tabulated file",
            p("type = \"tabulated\"\nfile = \"nope.csv\""),
            "phase.file: cannot read",
        ),
        (
            "malformed tabulated file",
            p("type = \"tabulated\"\nfile = \"bad.csv\""),
            "phase.file: ",
        ),
        ("no sources", so(""), "sources: at least one source"),
        (
            "empty source list",
            scene(
                "wavelength = 1.0\nsources = []",
                MEDIUM,
                PHASE,
                "",
                SENSORS,
                RENDER,
            ),
            "sources: at least one source",
        ),
        (
            "zero direction",
            so("[[sources]]\ntype = \"plane\"\ndirection = [0.0, 0.0, 0.0]"),
            "sources[0].direction: must be a non-zero vector",
        ),
        (
            "nan direction",
            so("[[sources]]\ntype = \"plane\"\ndirection = [0.0, nan, 1.0]"),
            "sources[0].direction[1]",
        ),
        (
            "bad source type",
            so("[[sources]]\ntype = \"planar\"\ndirection = [0.0, 0.0, 1.0]"),
            "sources[0].type",
        ),
        (
            "misspelt source key",
            so("[[sources]]\ntype = \"plane\"\ndirektion = [0.0, 0.0, 1.0]"),
            "sources[0].direktion",
        ),
        (
            "point source inside the medium, forward paths only",
            scene(
                TOP,
                MEDIUM,
                PHASE,
                "[[sources]]\ntype = \"point\"\nposition = [0.0, 0.0, 0.5]",
                SENSORS,
                "coherence = \"forward_only\"",
            ),
            "render.coherence: a point source or sensor at [0.0, 0.0, 0.5] lies in or on the medium",
        ),
        (
            "empty tilt list",
            so("[[sources]]\ntype = \"plane_tilts\"\ntilts_deg = []"),
            "sources[0].tilts_deg",
        ),
        ("no sensors", se(""), "sensors: at least one sensor"),
        (
            "grid angle of 90 degrees",
            se(
                "[[sensors]]\ntype = \"far_grid\"\ntheta_x_deg = [-10.0, 90.0]\n\
                 theta_y_deg = [0.0, 0.0]\nnx = 3\nny = 1",
            ),
            "sensors[0].theta_x_deg[1]",
        ),
        (
            "empty grid",
            se(
                "[[sensors]]\ntype = \"far_grid\"\ntheta_x_deg = [-10.0, 10.0]\n\
                 theta_y_deg = [0.0, 0.0]\nnx = 0\nny = 1",
            ),
            "sensors[0].nx",
        ),
        ("zero paths", r("paths = 0"), "render.paths: must be >= 2"),
        ("negative seed", r("seed = -3"), "render.seed"),
        (
            "zero realizations",
            r("realizations = 0"),
            "render.realizations",
        ),
        (
            "unknown coherence",
            r("coherence = \"both\""),
            "render.coherence",
        ),
        (
            "zero max_vertices",
            r("max_vertices = 0"),
            "render.max_vertices",
        ),
        (
            "exponential depth without a direction",
            scene(
                TOP,
                MEDIUM,
                PHASE,
                "[[sources]]\ntype = \"point\"\nposition = [0.0, 0.0, -9.0]",
                SENSORS,
                "first_vertex = \"exponential_depth\"",
            ),
            "render.first_vertex",
        ),
        (
            "pair index out of range",
            t("wavelength = 1.0\npairs = [[0, 0], [0, 3]]"),
            "pairs[1]: sensor index 3 is out of range",
        ),
        (
            "negative pair index",
            t("wavelength = 1.0\npairs = [[0, -1]]"),
            "pairs[0][1]",
        ),
        (
            "empty pair list",
            t("wavelength = 1.0\npairs = []"),
            "pairs: must not be empty",
        ),
        ("malformed TOML", t("wavelength = 1.0\n[medium"), "line 2"),
        (
            "duplicate key",
            m("size = [4.0, 4.0, 2.0]\nmean_free_path = 2.0\nmean_free_path = 3.0"),
            "duplicate key",
        ),
    ];
    assert!(cases.len() >= 15);
    expect_input_errors(
        &cases,
        &[("bad.csv", "theta_deg,re,im\n0,1,0\n90,one,0\n180,1,0\n")],
    );
}

/// Runs `speckle check` on every `(what, scene text, expected stderr excerpt)` case, next to the
/// given `(name, text)` files: each must exit with 2, name the field, not panic, write nothing.
fn expect_input_errors(cases: &[(&str, String, &str)], files: &[(&str, &str)]) {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in files {
        write(dir.path(), name, text);
    }
    let mut failures = Vec::new();
    for (what, text, expected) in cases {
        let path = write(dir.path(), "case.toml", text);
        let o = speckle(dir.path(), &["check", path.to_str().unwrap()]);
        let err = stderr(&o);
        if o.status.code() != Some(2) || !err.contains(expected) || err.contains("panicked") {
            failures.push(format!(
                "{what}: exit {:?}, expected `{expected}` in stderr:\n{err}",
                o.status.code()
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n---\n"));
    assert!(
        !dir.path().join("out").exists(),
        "check must not write anything"
    );
}

#[test]
fn malformed_flatland_scenes_name_the_field_and_exit_with_2() {
    let [t, m, p, so, se, r] = editors(VALID_2D);
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "dimension 4",
            t("dimension = 4\nwavelength = 1.0"),
            "dimension: must be 3 (the default) or 2",
        ),
        (
            "dimension 0",
            t("dimension = 0\nwavelength = 1.0"),
            "dimension: must be",
        ),
        (
            "fractional dimension",
            t("dimension = 2.5\nwavelength = 1.0"),
            "dimension",
        ),
        (
            "string dimension",
            t("dimension = \"2\"\nwavelength = 1.0"),
            "dimension",
        ),
        (
            "flat medium in 3D",
            t("dimension = 3\nwavelength = 1.0"),
            "medium.size[2]: must be finite and > 0 (got 0) (for flatland, set dimension = 2)",
        ),
        (
            "thick medium",
            m("size = [4.0, 4.0, 1.0]\nmean_free_path = 2.0"),
            "medium.size[2]: must be 0 in flatland",
        ),
        (
            "nan medium thickness",
            m("size = [4.0, 4.0, nan]\nmean_free_path = 2.0"),
            "medium.size[2]: must be finite",
        ),
        (
            "zero medium width",
            m("size = [0.0, 4.0, 0.0]\nmean_free_path = 2.0"),
            "medium.size[0]: must be finite and > 0",
        ),
        (
            "medium centre off the plane",
            m("size = [4.0, 4.0, 0.0]\ncenter = [0.0, 0.0, 1.0]\nmean_free_path = 2.0"),
            "medium.center[2]: must be 0 in flatland",
        ),
        (
            "plane wave off the plane",
            so("[[sources]]\ntype = \"plane\"\ndirection = [0.0, 1.0, 0.1]"),
            "sources[0].direction[2]: must be 0 in flatland",
        ),
        (
            "point source off the plane",
            so(&format!(
                "{SOURCES_2D}\n[[sources]]\ntype = \"point\"\nposition = [0.0, -9.0, 1.0]"
            )),
            "sources[1].position[2]: must be 0 in flatland",
        ),
        (
            "tilted plane waves off the plane",
            so("[[sources]]\ntype = \"plane_tilts\"\ndirection = [0, 0, 1]\ntilts_deg = [0]"),
            "sources[0].direction[2]: must be 0 in flatland",
        ),
        (
            "tilt axis in the plane",
            so("[[sources]]\ntype = \"plane_tilts\"\naxis = [0, 1, 0]\ntilts_deg = [0]"),
            "sources[0].axis: must be [0, 0, 1] or [0, 0, -1] in flatland",
        ),
        (
            "far sensor off the plane",
            se("[[sensors]]\ntype = \"far\"\ndirection = [1.0, 0.0, -1.0]"),
            "sensors[0].direction[2]: must be 0 in flatland",
        ),
        (
            "point sensor off the plane",
            se("[[sensors]]\ntype = \"point\"\nposition = [0.0, 9.0, 0.5]"),
            "sensors[0].position[2]",
        ),
        (
            "point grid origin off the plane",
            se("[[sensors]]\ntype = \"point_grid\"\norigin = [0, 9, 1]\n\
                step_x = [1, 0, 0]\nstep_y = [0, 1, 0]\nnx = 2\nny = 2"),
            "sensors[0].origin[2]",
        ),
        (
            "point grid step off the plane",
            se("[[sensors]]\ntype = \"point_grid\"\norigin = [0, 9, 0]\n\
                step_x = [1, 0, 0]\nstep_y = [0, 1, 0.5]\nnx = 2\nny = 2"),
            "sensors[0].step_y[2]",
        ),
        (
            "far grid in flatland",
            se("[[sensors]]\ntype = \"far_grid\"\ncenter = [0, 1, 0]\n\
                theta_x_deg = [-5, 5]\ntheta_y_deg = [0, 0]\nnx = 3\nny = 1"),
            "sensors[0]: far_grid is an image of 3D directions and has no flatland form; use \
             far_arc",
        ),
        (
            "far arc centre off the plane",
            se("[[sensors]]\ntype = \"far_arc\"\ncenter = [0, 1, 1]\n\
                angles_deg = [0, 90]\nn = 3"),
            "sensors[0].center[2]: must be 0 in flatland",
        ),
        (
            "far arc axis in the plane",
            se("[[sensors]]\ntype = \"far_arc\"\naxis = [1, 0, 0]\nangles_deg = [0, 90]\nn = 3"),
            "sensors[0].axis: must be [0, 0, 1] or [0, 0, -1]",
        ),
        (
            "zero far arc axis",
            se("[[sensors]]\ntype = \"far_arc\"\naxis = [0, 0, 0]\nangles_deg = [0, 90]\nn = 3"),
            "sensors[0].axis: must be a non-zero vector",
        ),
        (
            "empty far arc",
            se("[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0, 90]\nn = 0"),
            "sensors[0].n: must be in 1..=",
        ),
        (
            "negative far arc count",
            se("[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0, 90]\nn = -2"),
            "sensors[0].n: invalid value: integer `-2`",
        ),
        (
            "nan far arc angle",
            se("[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0, nan]\nn = 3"),
            "sensors[0].angles_deg[1]: must be finite",
        ),
        (
            "one far arc angle",
            se("[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0]\nn = 3"),
            "sensors[0].angles_deg: invalid length 1",
        ),
        (
            "far arc without a count",
            se("[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0, 90]"),
            "missing field `n`",
        ),
        (
            "misspelt far arc key",
            se("[[sensors]]\ntype = \"far_arc\"\nangles_deg = [0, 90]\nn = 3\ncentre = [0, 1, 0]"),
            "sensors[0].centre",
        ),
        (
            "strategy direction off the plane",
            r("first_vertex = \"exponential_depth\"\nfirst_vertex_direction = [0, 1, 1]"),
            "render.first_vertex_direction[2]: must be 0 in flatland",
        ),
        (
            "strategy axis off the plane",
            r("first_direction = \"phase\"\nfirst_direction_axis = [0, 0, 1]"),
            "render.first_direction_axis[2]: must be 0 in flatland",
        ),
        (
            "mu table in flatland",
            p("type = \"tabulated\"\nfile = \"mu.csv\""),
            "phase.file: ",
        ),
        (
            "mu table in flatland says why",
            p("type = \"tabulated\"\nfile = \"mu.csv\""),
            "cannot describe a flatland amplitude",
        ),
        (
            "flatland table beyond 2 pi",
            p("type = \"tabulated\"\nfile = \"wide.csv\""),
            "phase.file: ",
        ),
        (
            "flatland table beyond 2 pi says where",
            p("type = \"tabulated\"\nfile = \"wide.csv\""),
            "row 3 has an angle outside [0, 2 pi] (7 theta_rad)",
        ),
        (
            "unknown embedded table",
            p("type = \"tabulated\"\nfile = \"embedded:nope.csv\""),
            "phase.file: no embedded table called \"nope.csv\"",
        ),
    ];
    let wide = "theta_rad,re,im\n0,1,0\n3,1,0\n7,1,0\n";
    expect_input_errors(
        &cases,
        &[("mu.csv", "mu,re,im\n-1,1,0\n1,1,0\n"), ("wide.csv", wide)],
    );
}

#[test]
fn far_arc_and_tagged_tables_name_their_keys_in_3d() {
    let [_, _, p, so, se, _] = editors(VALID_3D);
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "string g",
            p("type = \"hg\"\ng = \"0.5\""),
            "phase.g: invalid type",
        ),
        (
            "negative grid count",
            se("[[sensors]]\ntype = \"far_grid\"\ntheta_x_deg = [-1, 1]\n\
                theta_y_deg = [0, 0]\nnx = 3\nny = -1"),
            "sensors[0].ny: invalid value",
        ),
        (
            "string tilt",
            so("[[sources]]\ntype = \"plane_tilts\"\ntilts_deg = [\"1\"]"),
            "sources[0].tilts_deg: invalid type",
        ),
        (
            "axis along the centre",
            se("[[sensors]]\ntype = \"far_arc\"\naxis = [0, 0, -3]\nangles_deg = [0, 9]\nn = 2"),
            "sensors[0].axis: must not be parallel to the center",
        ),
        (
            "zero centre",
            se("[[sensors]]\ntype = \"far_arc\"\ncenter = [0, 0, 0]\nangles_deg = [0, 9]\nn = 2"),
            "sensors[0].center: must be a non-zero vector",
        ),
        (
            "tilt axis along the direction",
            so("[[sources]]\ntype = \"plane_tilts\"\naxis = [0, 0, 1]\ntilts_deg = [0]"),
            "sources[0].axis: must not be parallel",
        ),
    ];
    expect_input_errors(&cases, &[]);
}

#[test]
fn bad_command_lines_exit_with_2() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    for (args, expected) in [
        (vec!["check", "missing.toml"], "cannot read the scene file"),
        (vec!["covariance", tiny, "--paths", "1"], "render.paths"),
        (vec!["intensity", tiny, "--paths", "1"], "render.paths"),
        (vec!["covariance", tiny, "--threads", "0"], "--threads"),
        (
            vec!["fields", tiny, "--realizations", "0"],
            "render.realizations",
        ),
        (vec!["example", "nope"], "no example called"),
        (vec!["render"], "unrecognized subcommand"),
    ] {
        let o = speckle(dir.path(), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{args:?}: {}", stderr(&o));
    }
    assert!(!dir.path().join("res").exists());
}

#[test]
fn a_valid_tabulated_phase_loads_relative_to_the_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("sub")).unwrap();
    write(
        &dir.path().join("sub"),
        "amp.csv",
        "# a forward-peaked amplitude\ntheta_deg,re,im\n0,2,0\n60,1,0.5\n120,0.5,0\n180,0.4,0\n",
    );
    let text = scene(
        TOP,
        MEDIUM,
        "type = \"tabulated\"\nfile = \"amp.csv\"",
        SOURCES,
        SENSORS,
        RENDER,
    );
    let p = write(&dir.path().join("sub"), "tab.toml", &text);
    let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("tabulated amp.csv"), "{}", stdout(&o));
}

/// A parsed `.npy` header: (descr, fortran_order, shape) and the data offset.
fn npy_header(bytes: &[u8]) -> (String, bool, Vec<usize>, usize) {
    assert_eq!(&bytes[..6], b"\x93NUMPY", "magic");
    assert_eq!(bytes[6], 1, "version 1.0");
    let len = u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    let offset = 10 + len;
    assert_eq!(offset % 16, 0, "data aligned");
    let h = std::str::from_utf8(&bytes[10..offset]).unwrap();
    assert!(h.ends_with('\n'));
    let field = |key: &str| {
        let start = h.find(&format!("'{key}': ")).unwrap() + key.len() + 4;
        &h[start..]
    };
    let descr = field("descr")[1..].split('\'').next().unwrap().to_string();
    let fortran = field("fortran_order").starts_with("True");
    let shape_text = field("shape");
    let shape = shape_text[1..shape_text.find(')').unwrap()]
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap())
        .collect();
    (descr, fortran, shape, offset)
}

/// The shape and the float64 numbers of a `.npy` file of dtype `descr` (`<c16`: re, im, ...).
fn load_npy_as(path: &Path, descr: &str) -> (Vec<usize>, Vec<f64>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (found, fortran, shape, offset) = npy_header(&bytes);
    assert_eq!(found, descr, "{}", path.display());
    assert!(!fortran);
    let per = if descr == "<c16" { 2 } else { 1 };
    let n: usize = shape.iter().product();
    assert_eq!(bytes.len() - offset, 8 * per * n, "{}", path.display());
    let data = bytes[offset..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    (shape, data)
}

/// The shape and the numbers of an int64 `.npy` file.
fn load_i8(path: &Path) -> (Vec<usize>, Vec<i64>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let (descr, fortran, shape, offset) = npy_header(&bytes);
    assert_eq!(descr, "<i8", "{}", path.display());
    assert!(!fortran);
    let data = bytes[offset..]
        .chunks_exact(8)
        .map(|c| i64::from_le_bytes(c.try_into().unwrap()))
        .collect();
    (shape, data)
}

fn load_npy(path: &Path) -> (Vec<usize>, Vec<(f64, f64)>) {
    let (shape, data) = load_npy_as(path, "<c16");
    (shape, data.chunks_exact(2).map(|c| (c[0], c[1])).collect())
}

fn load_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

#[test]
fn covariance_writes_npy_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let o = speckle(dir.path(), &["covariance", tiny.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    for kind in ["cov", "cov_single", "cov_multiple", "cov_stderr"] {
        let (shape, data) = load_npy(&res.join(format!("tiny.{kind}.npy")));
        assert_eq!(shape, vec![12, 12], "{kind}");
        assert!(data.iter().all(|(a, b)| a.is_finite() && b.is_finite()));
    }
    let (_, cov) = load_npy(&res.join("tiny.cov.npy"));
    // Intensities are positive and the matrix is Hermitian.
    for i in 0..12 {
        assert!(cov[i * 12 + i].0 > 0.0);
        for j in 0..12 {
            let (a, b) = (cov[i * 12 + j], cov[j * 12 + i]);
            assert!((a.0 - b.0).abs() <= 1e-9 * a.0.abs().max(1.0) && (a.1 + b.1).abs() <= 1e-9);
        }
    }
    let (shape, _) = load_npy(&res.join("tiny.mean.npy"));
    assert_eq!(shape, vec![12]);
    assert!(res.join("tiny.cov.png").exists());
    let meta = load_json(&res.join("tiny.cov.json"));
    assert_eq!(meta["command"], "covariance");
    assert_eq!(meta["render"]["paths"], 4000);
    assert_eq!(meta["render"]["seed"], 5);
    assert_eq!(meta["render"]["coherence"], "forward_and_reversed");
    // The pairs and endpoints are tables beside the sidecar.
    assert_eq!(meta["pairs"]["count"], 12);
    assert_eq!(meta["pairs"]["file"], "tiny.cov.pairs.npy");
    let (shape, pairs) = load_i8(&res.join("tiny.cov.pairs.npy"));
    assert_eq!(shape, vec![12, 2]);
    assert_eq!(&pairs[14..16], &[1, 1], "pair 7: source 1, sensor 1");
    assert_eq!(meta["sources"]["count"], 2);
    assert_eq!(meta["sensors"]["count"], 6);
    let (shape, _) = load_npy_as(&res.join("tiny.cov.sensors.npy"), "<f8");
    assert_eq!(shape, vec![6, 7]);
    assert_eq!(meta["scene"]["medium"]["mean_free_path"], 4.0);
    assert_eq!(meta["derived"]["pairs"], 12);
    assert!(meta["summary"]["mean_diagonal_total"].as_f64().unwrap() > 0.0);
    assert!(meta["reproducibility"]["speckle_cli_version"].is_string());
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&res)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    for (threads, out) in [("1", "t1"), ("2", "t2"), ("3", "t3")] {
        let o = speckle(
            dir.path(),
            &["covariance", tiny, "-q", "--threads", threads, "--out", out],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let a = std::fs::read(dir.path().join("t1/tiny.cov.npy")).unwrap();
    for out in ["t2", "t3"] {
        let b = std::fs::read(dir.path().join(out).join("tiny.cov.npy")).unwrap();
        assert!(a == b, "{out} differs from t1");
    }
}

#[test]
fn fields_single_and_mean_write_their_files() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    let o = speckle(dir.path(), &["fields", tiny, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, _) = load_npy(&res.join("tiny.fields.npy"));
    assert_eq!(shape, vec![3, 2, 6]);
    // PNGs for the first two realizations and both illuminations, none for the third.
    for r in 0..3 {
        for s in 0..2 {
            let p = res.join(format!("tiny.r{r}.s{s}.png"));
            assert_eq!(p.exists(), r < 2, "{}", p.display());
        }
    }
    let png = std::fs::read(res.join("tiny.r0.s0.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let meta = load_json(&res.join("tiny.fields.json"));
    assert_eq!(meta["render"]["realizations"], 3);
    assert_eq!(meta["sensor_grid"]["nx"], 3);
    assert_eq!(meta["sensor_grid"]["ny"], 2);

    let o = speckle(dir.path(), &["single", tiny, "-q", "--paths", "500"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&res.join("tiny.single.npy"));
    assert_eq!(shape, vec![12, 12]);
    assert_eq!(
        load_json(&res.join("tiny.single.json"))["render"]["paths"],
        500
    );

    let o = speckle(dir.path(), &["mean", tiny, "--out", "m"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&dir.path().join("m/tiny.mean.npy"));
    assert_eq!(shape, vec![12]);

    // Explicit pairs give a (R, J) field array.
    let explicit = TINY.replace(
        "wavelength = 1.0",
        "wavelength = 1.0\npairs = [[0, 0], [1, 5]]",
    );
    let p = write(dir.path(), "explicit.toml", &explicit);
    let o = speckle(
        dir.path(),
        &["fields", p.to_str().unwrap(), "-q", "--out", "e"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&dir.path().join("e/tiny.fields.npy"));
    assert_eq!(shape, vec![3, 2]);
}

#[test]
fn a_cancelled_render_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let tiny = tiny.to_str().unwrap();
    for args in [
        vec!["covariance", tiny, "--paths", "2000000"],
        vec!["intensity", tiny, "--paths", "20000000"],
        vec!["single", tiny, "--paths", "20000000"],
        vec!["fields", tiny, "--realizations", "64"],
    ] {
        let mut args = args;
        args.extend(["-q", "--cancel-after-paths", "1"]);
        let o = speckle(dir.path(), &args);
        assert_eq!(o.status.code(), Some(130), "{args:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("no output was written"),
            "{}",
            stderr(&o)
        );
        assert!(!dir.path().join("res").exists(), "{args:?} wrote output");
    }
}

#[cfg(unix)]
#[test]
fn ctrl_c_stops_a_render_and_writes_nothing() {
    use std::time::{Duration, Instant};
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let mut child = Command::new(env!("CARGO_BIN_EXE_speckle"))
        .args(["covariance", tiny.to_str().unwrap(), "-q"])
        .args(["--paths", "1000000000"])
        .current_dir(dir.path())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(700));
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(kill.success());
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "the render did not stop"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(status.code(), Some(130));
    assert!(!dir.path().join("res").exists());
}

#[test]
fn every_example_prints_and_checks() {
    let dir = tempfile::tempdir().unwrap();
    let o = speckle(dir.path(), &["example", "--list"]);
    assert!(o.status.success());
    let names: Vec<String> = stdout(&o).lines().map(str::to_string).collect();
    assert!(names.len() >= 5 && names[0] == "default", "{names:?}");
    for name in &names {
        let o = speckle(dir.path(), &["example", name]);
        assert!(o.status.success());
        // The embedded text is the file in scenes/ (or in crates/scene/scenes/).
        let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
        let file = [
            crate_dir.join("../../scenes"),
            crate_dir.join("../scene/scenes"),
        ]
        .iter()
        .map(|d| d.join(format!("{name}.toml")))
        .find(|f| f.exists())
        .unwrap_or_else(|| panic!("no scene file for the example {name}"));
        assert_eq!(stdout(&o), std::fs::read_to_string(&file).unwrap());
        let p = write(dir.path(), &format!("{name}.toml"), &stdout(&o));
        let o = speckle(dir.path(), &["check", p.to_str().unwrap()]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    }
}

/// A tiny flatland scene: 2 tilted plane waves (default +y about +z), a 5-direction far arc with
/// default centre and axis, and a point sensor (J = 12); an asymmetric table with the mu-diff
/// header names.
const TINY_2D: &str = r#"
name = "flat"
dimension = 2
wavelength = 1.0

[medium]
size = [6.0, 6.0, 0.0]
mean_free_path = 3.0
albedo = 0.9

[phase]
type = "tabulated"
file = "amp.csv"

[[sources]]
type = "plane_tilts"
tilts_deg = [0.0, 10.0]

[[sensors]]
type = "far_arc"
angles_deg = [90.0, 270.0]
n = 5

[[sensors]]
type = "point"
position = [0.0, 10.0, 0.0]

[render]
paths = 3000
seed = 3

[output]
dir = "res"
"#;

#[test]
fn flatland_intensity_writes_float64_arrays_and_far_arc_angles() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "amp.csv",
        "theta_rad,re_s,im_s\n0,1,0\n1.5,0.8,0.3\n3.14159,0.3,0\n4.5,0.2,-0.1\n",
    );
    let p = write(dir.path(), "flat.toml", TINY_2D);
    let p = p.to_str().unwrap();
    let o = speckle(dir.path(), &["intensity", p, "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, intensity) = load_npy_as(&res.join("flat.intensity.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    assert!(
        intensity.iter().all(|v| v.is_finite() && *v > 0.0),
        "{intensity:?}"
    );
    let (shape, se) = load_npy_as(&res.join("flat.intensity_stderr.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    assert!(se.iter().zip(&intensity).all(|(s, v)| *s > 0.0 && s < v));
    let (shape, single) = load_npy_as(&res.join("flat.intensity_single.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    assert!(single.iter().all(|v| v.is_finite()));

    let meta = load_json(&res.join("flat.intensity.json"));
    assert_eq!(meta["command"], "intensity");
    assert_eq!(meta["derived"]["dimension"], 2);
    assert_eq!(meta["files"]["intensity"], "flat.intensity.npy");
    assert_eq!(
        meta["files"]["intensity_stderr"],
        "flat.intensity_stderr.npy"
    );
    assert_eq!(meta["render"]["paths"], 3000);
    assert!(
        meta["units"]["far_field_sensor"]
            .as_str()
            .unwrap()
            .contains("sqrt(R)")
    );
    // The defaults are recorded: +y tilted about +z.
    assert_eq!(
        meta["scene"]["sources"][0]["direction"],
        serde_json::json!([0.0, 1.0, 0.0])
    );
    assert_eq!(
        meta["scene"]["sensors"][0]["axis"],
        serde_json::json!([0.0, 0.0, 1.0])
    );
    // Rows of the endpoint tables: entry, kind, x, y, z, p, q.
    let (shape, sources) = load_npy_as(&res.join("flat.intensity.sources.npy"), "<f8");
    assert_eq!(shape, vec![2, 7]);
    let tilted = &sources[7 + 2..7 + 5];
    let a = 10f64.to_radians();
    assert!((tilted[0] + a.sin()).abs() < 1e-12, "{tilted:?}");
    // The arc: +y rotated counter-clockwise by 90, 135, ..., 270 degrees, then the point.
    let (shape, sensors) = load_npy_as(&res.join("flat.intensity.sensors.npy"), "<f8");
    assert_eq!(shape, vec![6, 7]);
    for k in 0..5 {
        let s = &sensors[7 * k..7 * k + 7];
        let deg = 90.0 + 45.0 * k as f64;
        assert_eq!(s[1], 2.0, "far field: {s:?}");
        assert_eq!(s[5], deg, "{s:?}");
        assert_eq!(s[6], k as f64);
        let (sin, cos) = deg.to_radians().sin_cos();
        assert!(
            (s[2] + sin).abs() < 1e-12 && (s[3] - cos).abs() < 1e-12,
            "{s:?}"
        );
        assert_eq!(s[4], 0.0);
    }
    assert_eq!(sensors[7 * 5 + 1], 1.0, "a point sensor");

    // The same seed gives the covariance's diagonal exactly.
    let o = speckle(
        dir.path(),
        &["covariance", p, "-q", "--out", "c", "--no-png"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, cov) = load_npy(&dir.path().join("c/flat.cov.npy"));
    for (j, v) in intensity.iter().enumerate() {
        assert_eq!(cov[j * 12 + j].0, *v, "pair {j}");
    }

    // Explicit pairs give a (J,) array.
    let explicit = TINY_2D.replace(
        "wavelength = 1.0",
        "wavelength = 1.0\npairs = [[0, 0], [1, 5], [1, 2]]",
    );
    let p = write(dir.path(), "explicit.toml", &explicit);
    let o = speckle(
        dir.path(),
        &[
            "intensity",
            p.to_str().unwrap(),
            "-q",
            "--out",
            "e",
            "--paths",
            "500",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy_as(&dir.path().join("e/flat.intensity_stderr.npy"), "<f8");
    assert_eq!(shape, vec![3]);
}

#[test]
fn intensity_of_a_sensor_grid_writes_an_image_per_source() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write(dir.path(), "tiny.toml", TINY);
    let o = speckle(
        dir.path(),
        &["intensity", tiny.to_str().unwrap(), "-q", "--paths", "500"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.path().join("res");
    let (shape, _) = load_npy_as(&res.join("tiny.intensity.npy"), "<f8");
    assert_eq!(shape, vec![2, 6]);
    for s in 0..2 {
        let png = std::fs::read(res.join(format!("tiny.intensity.s{s}.png"))).unwrap();
        assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    }
    let meta = load_json(&res.join("tiny.intensity.json"));
    assert_eq!(meta["derived"]["dimension"], 3);
    assert_eq!(meta["files"]["png"]["files"].as_array().unwrap().len(), 2);
}

/// A tiny flatland scene for the wave solver: a 10 x 4 wavelength box, mean free path 4
/// (about 16 isotropic scatterers per configuration), a plane wave, 3 far-field directions.
const WAVE_2D: &str = r#"
name = "wave2d"
dimension = 2
wavelength = 1.0

[medium]
size = [10.0, 4.0, 0.0]
mean_free_path = 4.0

[[sources]]
type = "plane"
direction = [0.0, 1.0, 0.0]

[[sensors]]
type = "far_arc"
angles_deg = [-20.0, 20.0]
n = 3

[render]
paths = 2000
seed = 9
configurations = 20

[output]
dir = "res"
"#;

#[test]
fn wave_writes_npy_and_json_independent_of_threads() {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "wave2d.toml", WAVE_2D);
    let p = p.to_str().unwrap();
    for (threads, out) in [("1", "t1"), ("2", "t2")] {
        let o = speckle(
            dir.path(),
            &["wave", p, "-q", "--threads", threads, "--out", out],
        );
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let res = dir.path().join("t1");
    let arrays = [
        ("wave_cov", vec![3, 3]),
        ("wave_cov_stderr", vec![3, 3]),
        ("wave_mean", vec![3]),
        ("wave_mean_stderr", vec![3]),
        ("wave_fields", vec![20, 1, 3]),
    ];
    for (kind, want) in &arrays {
        let file = format!("wave2d.{kind}.npy");
        let (shape, data) = load_npy(&res.join(&file));
        assert_eq!(&shape, want, "{kind}");
        assert!(data.iter().all(|(a, b)| a.is_finite() && b.is_finite()));
        let other = std::fs::read(dir.path().join("t2").join(&file)).unwrap();
        assert!(
            std::fs::read(res.join(&file)).unwrap() == other,
            "{file} depends on the thread count"
        );
    }
    // A covariance: Hermitian with positive intensities.
    let (_, cov) = load_npy(&res.join("wave2d.wave_cov.npy"));
    for i in 0..3 {
        assert!(cov[i * 3 + i].0 > 0.0 && cov[i * 3 + i].1 == 0.0);
        for j in 0..3 {
            let (a, b) = (cov[i * 3 + j], cov[j * 3 + i]);
            assert!((a.0 - b.0).abs() <= 1e-12 * a.0.abs().max(1.0) && (a.1 + b.1).abs() <= 1e-12);
        }
    }
    assert!(res.join("wave2d.wave_cov.png").exists());
    let meta = load_json(&res.join("wave2d.wave.json"));
    assert_eq!(meta["command"], "wave");
    assert_eq!(meta["render"]["configurations"], 20);
    assert_eq!(meta["render"]["seed"], 9);
    assert_eq!(meta["files"]["wave_cov"], "wave2d.wave_cov.npy");
    // n |V| = sigma_s |V| / (4 / k) = 0.25 * 40 * 2 pi / 4 = 5 pi.
    let expected = meta["render"]["expected_scatterers"].as_f64().unwrap();
    assert!(
        (expected - 5.0 * std::f64::consts::PI).abs() < 1e-9,
        "{expected}"
    );
    let mean = meta["render"]["mean_scatterers"].as_f64().unwrap();
    assert!(mean > 0.5 * expected && mean < 1.5 * expected, "{mean}");
    let leftovers: Vec<_> = std::fs::read_dir(&res)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");

    // Without -q, the cost is announced before solving.
    let o = speckle(dir.path(), &["wave", p, "--no-png", "--out", "t3"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("about 15.7 scatterers"),
        "{}",
        stdout(&o)
    );
    assert!(!dir.path().join("t3/wave2d.wave_cov.png").exists());

    // The Monte Carlo covariance has the same pairs in the same order.
    let o = speckle(dir.path(), &["covariance", p, "-q", "--out", "t1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&res.join("wave2d.cov.npy"));
    assert_eq!(shape, vec![3, 3]);

    // A sensor grid gives intensity images of the first `png_realizations` configurations.
    let iso = TINY
        .replace("albedo = 0.9\n", "")
        .replace("type = \"hg\"\ng = 0.4", "type = \"isotropic\"");
    let g = write(dir.path(), "grid.toml", &iso);
    let args = ["wave", g.to_str().unwrap(), "-q", "--configurations", "3"];
    let o = speckle(dir.path(), &[&args[..], &["--out", "g"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let (shape, _) = load_npy(&dir.path().join("g/tiny.wave_fields.npy"));
    assert_eq!(shape, vec![3, 2, 6]);
    for r in 0..3 {
        for s in 0..2 {
            let png = dir.path().join(format!("g/tiny.wave.r{r}.s{s}.png"));
            assert_eq!(png.exists(), r < 2, "{}", png.display());
        }
    }

    // A cancelled wave render writes nothing.
    let o = speckle(
        dir.path(),
        &[
            "wave",
            p,
            "-q",
            "--configurations",
            "100000",
            "--cancel-after-paths",
            "1",
        ],
    );
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(!dir.path().join("res").exists());
}

#[test]
fn wave_rejects_what_it_does_not_model_and_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        (
            WAVE_2D.replace(
                "mean_free_path = 4.0",
                "mean_free_path = 4.0\n[phase]\ntype = \"hg\"\ng = 0.3",
            ),
            vec![],
            "wave2d.toml: phase: the wave solver models isotropic point scatterers",
        ),
        (
            WAVE_2D.replace("mean_free_path = 4.0", "sigma_s = 0.25\nsigma_a = 0.01"),
            vec![],
            "wave2d.toml: medium.sigma_a: must be 0",
        ),
        (
            WAVE_2D.replace("configurations = 20", "configurations = 1"),
            vec![],
            "render.configurations: must be >= 2",
        ),
        (
            WAVE_2D.to_string(),
            vec!["--configurations", "1"],
            "render.configurations: must be >= 2",
        ),
        (
            WAVE_2D.replace("[10.0, 4.0, 0.0]", "[1000.0, 1000.0, 0.0]"),
            vec![],
            "wave2d.toml: medium: the box holds",
        ),
    ];
    for (text, extra, expected) in cases {
        let p = write(dir.path(), "wave2d.toml", &text);
        let mut args = vec!["wave", p.to_str().unwrap(), "-q"];
        args.extend(extra);
        let o = speckle(dir.path(), &args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{expected}: {}", stderr(&o));
    }
    assert!(!dir.path().join("res").exists());
}
