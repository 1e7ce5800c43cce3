//! The embedded study files: `speckle example NAME` prints them (they are not scenes).

/// `(name, TOML text)` of the memory-spectrum studies of Bar et al. 2019, Fig. 11a and 11b.
pub const STUDIES: &[(&str, &str)] = &[
    (
        "fig11a_memory_small",
        include_str!("../scenes/fig11a_memory_small.toml"),
    ),
    (
        "fig11b_memory_large",
        include_str!("../scenes/fig11b_memory_large.toml"),
    ),
];

/// The text of the study called `name`.
pub fn study(name: &str) -> Option<&'static str> {
    speckle_scene::examples::find(STUDIES, name)
}

/// The names of the studies.
pub fn names() -> Vec<&'static str> {
    speckle_scene::examples::keys(STUDIES)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_study_is_valid_and_named_after_itself() {
        for (name, text) in STUDIES {
            let s = crate::memory::load_str(text, name, name, &Default::default())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(&s.name, name);
            assert_eq!(study(name), Some(*text));
        }
    }
}
