//! Malformed scenes, through the binary: every field's bad values are rejected with the field
//! named and exit code 2 (3D and flatland, generators, tagged tables), from one valid scene whose
//! parts each case replaces.

mod common;
use common::*;

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
