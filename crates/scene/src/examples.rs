//! The example scenes of `scenes/` (and of `crates/scene/scenes/`), embedded in the library, and
//! the data files they use.
//!
//! Design decision: an embedded scene must work from any directory, so the tables it needs are
//! embedded too and named in the scene as `file = "embedded:NAME"` (see [`data`]); no file is
//! written next to a printed scene. A user who wants to edit a table replaces that line with the
//! path of a copy.

/// `(name, TOML text)` of every embedded example scene; the first is the default.
pub const EXAMPLES: &[(&str, &str)] = &[
    ("default", include_str!("../../../scenes/default.toml")),
    (
        "memory_effect",
        include_str!("../../../scenes/memory_effect.toml"),
    ),
    (
        "backscatter",
        include_str!("../../../scenes/backscatter.toml"),
    ),
    (
        "fields_image",
        include_str!("../../../scenes/fields_image.toml"),
    ),
    (
        "point_sensors",
        include_str!("../../../scenes/point_sensors.toml"),
    ),
    (
        "mudiff_cbs_2d",
        include_str!("../scenes/mudiff_cbs_2d.toml"),
    ),
    ("beads", include_str!("../../../scenes/beads.toml")),
    ("dcs", include_str!("../../../scenes/dcs.toml")),
    (
        "tissue_fibre",
        include_str!("../../../scenes/tissue_fibre.toml"),
    ),
    ("head", include_str!("../../../scenes/head.toml")),
    ("dcs_fit", include_str!("../../../scenes/dcs_fit.toml")),
    (
        "spatiotemporal_2d",
        include_str!("../../../scenes/spatiotemporal_2d.toml"),
    ),
];

/// `(name, text)` of the embedded data files, which scenes name as `embedded:NAME`.
pub const DATA: &[(&str, &str)] = &[
    (
        "mudiff_cbs_2d/amplitude_function.csv",
        include_str!("../../../validation/data/mudiff_cbs_2d/amplitude_function.csv"),
    ),
    (
        "dcs_fit/g2.csv",
        include_str!("../../../validation/data/dcs_fit/g2.csv"),
    ),
];

/// The text of the entry of `table` called `name`.
pub fn find(table: &[(&str, &'static str)], name: &str) -> Option<&'static str> {
    table.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The names of the entries of `table`.
pub fn keys(table: &[(&'static str, &str)]) -> Vec<&'static str> {
    table.iter().map(|(n, _)| *n).collect()
}

/// The text of the example scene called `name`.
pub fn example(name: &str) -> Option<&'static str> {
    find(EXAMPLES, name)
}

/// The names of all example scenes.
pub fn names() -> Vec<&'static str> {
    keys(EXAMPLES)
}

/// The text of the embedded data file called `name` (without the `embedded:` prefix).
pub fn data(name: &str) -> Option<&'static str> {
    find(DATA, name)
}

/// The names of all embedded data files.
pub fn data_names() -> Vec<&'static str> {
    keys(DATA)
}

/// Loads the embedded example `name` as if it were a file of that name in the current
/// directory (its `<embedded NAME.toml>` origin names it in errors).
pub fn load(
    name: &str,
    overrides: &crate::schema::Overrides,
) -> Option<Result<crate::Problem, crate::LoadError>> {
    let text = example(name)?;
    let cwd = std::env::current_dir().unwrap_or_default();
    let origin = format!("<embedded {name}.toml>");
    Some(crate::load::load_str(text, &origin, &cwd, name, overrides))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_example_is_valid_and_named_after_itself() {
        for (name, _) in EXAMPLES {
            let p = load(name, &Default::default())
                .unwrap()
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&p.name, name);
        }
        assert!(load("nope", &Default::default()).is_none());
    }
}
