//! Unit tests of the sampling study: validation errors naming the field, the shipped study,
//! distinct seeds.

use super::*;
use crate::memory::StudyOverrides;
use speckle_scene::LoadError;

const GOOD: &str = "[[cases]]\nname = \"box\"\nsize = [6.0, 3.0]\nmean_free_path = 3.0\n\
                    amplitude = [[0.0, 0.2], [6.0, 1.0]]\n";

fn load(text: &str) -> Result<SamplingStudy, LoadError> {
    load_sampling_str(text, "t.toml", "t", &StudyOverrides::default())
}

fn refused(text: &str, field: &str) {
    let e = load(text).unwrap_err().to_string();
    assert!(e.contains(field), "{field} not named: {e}");
}

#[test]
fn bad_input_names_the_field() {
    let s = load(GOOD).unwrap();
    assert_eq!(s.paths, vec![2000, 8000, 32000]);
    assert_eq!(s.strategies.len(), 3);
    refused(
        &GOOD.replace("3.0\nampl", "-3.0\nampl"),
        "cases[0].mean_free_path",
    );
    refused(
        &GOOD.replace("[6.0, 3.0]", "[1.0, 3.0]"),
        "cases[0].size[0]",
    );
    refused(&format!("{GOOD}dimension = 2\n"), "cases[0].amplitude");
    refused(&format!("{GOOD}dimension = 4\n"), "cases[0].dimension");
    refused(&GOOD.replace("0.2]", "-0.2]"), "cases[0].amplitude");
    refused(
        &format!("strategies = [\"off\", \"off\"]\n{GOOD}"),
        "strategies[1]",
    );
    refused(
        &format!("strategies = [\"sideways\"]\n{GOOD}"),
        "strategies",
    );
    refused(&format!("{GOOD}[render]\nsteps = 0\n"), "render.steps");
    refused(&format!("{GOOD}[render]\nratio = 1\n"), "render.ratio");
    refused(&format!("{GOOD}[render]\npaths = 100\n"), "render.paths");
    refused(
        &format!("{GOOD}[render]\nreference_paths = 2\n"),
        "render.reference_paths",
    );
    refused("strategies = []\n", "cases");
}

#[test]
fn the_shipped_study_loads() {
    let s = load(include_str!(
        "../../../../../scenes/fig9_sampling_gain.toml"
    ))
    .unwrap();
    assert_eq!((s.cases.len(), s.paths.len()), (2, 3));
    assert!(s.cases[0].reflection && !s.cases[1].reflection);
}

#[test]
fn seeds_are_distinct() {
    let s = load(&format!("{GOOD}{}", GOOD.replace("box", "box2"))).unwrap();
    let mut seeds = vec![];
    for c in 0..2 {
        for st in 0..3 {
            for k in 0..3 {
                seeds.push(s.seed(c, st, k));
            }
        }
        seeds.push(s.seed(c, 0, 3));
    }
    let n = seeds.len();
    seeds.sort_unstable();
    seeds.dedup();
    assert_eq!(seeds.len(), n);
}
