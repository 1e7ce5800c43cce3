//! The identity of a run: a hash of everything that determines its numbers, so that shards of
//! different runs are never merged.

use crate::{Kind, covariance_options, field_options, wave_options};
use speckle_scene::Problem;
use std::fmt::Write;

/// 64-bit FNV-1a, fed through `fmt::Write` so that a scene's description is hashed without
/// being held in memory.
struct Fnv(u64);

impl Fnv {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}

impl Write for Fnv {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        for b in s.bytes() {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
        Ok(())
    }
}

/// The run hash of a render of `kind` of `p` (16 hexadecimal digits): of the crate version,
/// the kind, the validated scene in full (medium, every phase function's tables, wavelength,
/// sources, sensors, pairs, as their `Debug` forms, which print every number exactly) and the
/// renderer's options (path counts, seed, coherence, sampling strategies). Not of the name or
/// the output settings, which do not change the numbers. Two shards merge only if their hashes
/// agree; a merge also checks that the scene, rebuilt from the shard, still hashes the same
/// (an input table that changed since is refused).
pub fn run_hash(p: &Problem, kind: Kind) -> String {
    let mut h = Fnv::new();
    let options = match kind {
        Kind::Covariance | Kind::Intensity => format!("{:?}", covariance_options(p)),
        Kind::Fields => format!("{:?}", field_options(p)),
        Kind::Wave => format!("{:?}", wave_options(p)),
    };
    // Writing into the hasher cannot fail.
    let _ = write!(
        h,
        "speckle-run 1\n{}\n{}\n{options}\n{:?}",
        env!("CARGO_PKG_VERSION"),
        kind.tag(),
        p.scene
    );
    format!("{:016x}", h.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use speckle_scene::{Overrides, examples, load_str};

    fn problem(over: Overrides) -> Problem {
        let text = examples::example("default").unwrap();
        load_str(text, "default", std::path::Path::new("."), "default", &over).unwrap()
    }

    #[test]
    fn the_hash_changes_with_what_changes_the_numbers_only() {
        let base = run_hash(&problem(Overrides::default()), Kind::Covariance);
        assert_eq!(base.len(), 16);
        assert_eq!(
            base,
            run_hash(&problem(Overrides::default()), Kind::Covariance)
        );
        let other = |o: Overrides, k: Kind| run_hash(&problem(o), k);
        assert_ne!(base, other(Overrides::default(), Kind::Intensity));
        let seed = Overrides {
            seed: Some(2),
            ..Default::default()
        };
        assert_ne!(base, other(seed, Kind::Covariance));
        let paths = Overrides {
            paths: Some(1001),
            ..Default::default()
        };
        assert_ne!(base, other(paths, Kind::Covariance));
        let forward = Overrides {
            forward_only: true,
            ..Default::default()
        };
        assert_ne!(base, other(forward, Kind::Covariance));
        // Output settings and field settings do not change a covariance.
        let out = Overrides {
            out: Some("elsewhere".into()),
            no_png: true,
            realizations: Some(3),
            ..Default::default()
        };
        assert_eq!(base, other(out, Kind::Covariance));
    }
}
