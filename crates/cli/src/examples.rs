//! The example scenes of `scenes/`, embedded in the binary.

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
];

/// The text of the example called `name`.
pub fn example(name: &str) -> Option<&'static str> {
    EXAMPLES.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The names of all examples.
pub fn names() -> Vec<&'static str> {
    EXAMPLES.iter().map(|(n, _)| *n).collect()
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
}
