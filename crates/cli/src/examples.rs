//! The example scenes of `scenes/` (and of `crates/cli/scenes/`), embedded in the binary, and the
//! data files they use.
//!
//! Design decision: an embedded scene must work from any directory, so the tables it needs are
//! embedded too and named in the scene as `file = "embedded:NAME"` (see [`data`]); no file is
//! written next to a printed scene. A user who wants to edit a table replaces that line with the
//! path of a copy.

/// `(name, TOML text)` of every embedded example; the first is the default.
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
        include_str!("../../scene/scenes/mudiff_cbs_2d.toml"),
    ),
    ("beads", include_str!("../../../scenes/beads.toml")),
];

/// `(name, TOML text)` of the embedded memory-spectrum studies (`speckle memory-spectrum`; a
/// format of their own, `memory::StudyFile`). `speckle example NAME` prints them too; they are
/// not in [`EXAMPLES`], whose entries are scenes.
pub const STUDIES: &[(&str, &str)] = &[
    (
        "fig11a_memory_small",
        include_str!("../../studies/scenes/fig11a_memory_small.toml"),
    ),
    (
        "fig11b_memory_large",
        include_str!("../../studies/scenes/fig11b_memory_large.toml"),
    ),
];

/// `(name, text)` of the embedded data files, which scenes name as `embedded:NAME`.
pub const DATA: &[(&str, &str)] = &[(
    "mudiff_cbs_2d/amplitude_function.csv",
    include_str!("../../../validation/data/mudiff_cbs_2d/amplitude_function.csv"),
)];

/// The text of the entry of `table` called `name`.
fn find(table: &[(&str, &'static str)], name: &str) -> Option<&'static str> {
    table.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The names of the entries of `table`.
fn keys(table: &[(&'static str, &str)]) -> Vec<&'static str> {
    table.iter().map(|(n, _)| *n).collect()
}

/// The text of the example called `name`.
pub fn example(name: &str) -> Option<&'static str> {
    find(EXAMPLES, name).or_else(|| find(STUDIES, name))
}

/// The names of the memory-spectrum studies.
pub fn study_names() -> Vec<&'static str> {
    keys(STUDIES)
}

/// The names of all examples.
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Overrides, load_str};
    use std::path::Path;

    #[test]
    fn every_example_is_valid_and_named_after_itself() {
        for (name, text) in EXAMPLES {
            let l = load_str(text, name, Path::new("."), name, &Overrides::default())
                .unwrap_or_else(|e| panic!("{name}: {}", e.0));
            assert_eq!(&l.name, name);
        }
    }

    #[test]
    fn every_study_is_valid_and_named_after_itself() {
        for (name, text) in STUDIES {
            let s = crate::memory::load_str(text, name, name, &Default::default())
                .unwrap_or_else(|e| panic!("{name}: {}", e.0));
            assert_eq!(&s.name, name);
        }
    }
}
