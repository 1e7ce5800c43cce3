//! The fuzz target over the scene parser and builders (see the crate documentation).
//!
//! - `corpus_and_variants`: every corpus scene and 300 variants (a few seconds; CI);
//! - `shard_variants`: the genuine shards of every sharded render and 300 variants (CI);
//! - `long_run` (ignored): `SPECKLE_FUZZ_SECONDS` seconds (default 1800) from the seed
//!   `SPECKLE_FUZZ_SEED` (default 1), two thirds on scenes and one third on shard files;
//!   prints the count of inputs tried.
//!
//! A finding prints the input that caused it (add it to `corpus/` once fixed).

use speckle_fuzz::shards::run_shards;
use speckle_fuzz::{run, sandbox};

fn report(t: &speckle_fuzz::Tally) {
    for (f, input) in &t.findings {
        eprintln!("FINDING {f:?}\n--- input ---\n{input}--- end ---");
    }
    assert!(
        t.findings.is_empty(),
        "{} findings in {} inputs",
        t.findings.len(),
        t.inputs
    );
}

#[test]
fn corpus_and_variants() {
    let root = tempfile::tempdir().unwrap();
    let base = sandbox(root.path());
    let t = run(7, 300, 600.0, &base);
    eprintln!("{} inputs", t.inputs);
    assert_eq!(t.inputs, 300);
    report(&t);
}

#[test]
fn shard_variants() {
    let root = tempfile::tempdir().unwrap();
    let base = sandbox(root.path());
    let t = run_shards(7, 300, 600.0, &base);
    eprintln!("{} shard inputs", t.inputs);
    assert_eq!(t.inputs, 300);
    report(&t);
}

#[test]
#[ignore]
fn long_run() {
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let (seconds, seed) = (
        env("SPECKLE_FUZZ_SECONDS", 1800.0),
        env("SPECKLE_FUZZ_SEED", 1.0),
    );
    let root = tempfile::tempdir().unwrap();
    let base = sandbox(root.path());
    let t = run(seed as u64, u64::MAX, seconds * 2.0 / 3.0, &base);
    println!(
        "fuzz: {} scene inputs in {:.0} s (seed {seed}), {} findings",
        t.inputs,
        seconds * 2.0 / 3.0,
        t.findings.len()
    );
    // Each part's findings are printed as soon as it ends (a shard finding used to hide the
    // scene part's; and the shard part takes a third of the time).
    print_findings(&t);
    let s = run_shards(seed as u64, u64::MAX, seconds / 3.0, &base);
    println!(
        "fuzz: {} shard inputs in {:.0} s (seed {seed}), {} findings",
        s.inputs,
        seconds / 3.0,
        s.findings.len()
    );
    print_findings(&s);
    report(&s);
    report(&t);
}

/// Prints every finding of `t` with its input.
fn print_findings(t: &speckle_fuzz::Tally) {
    for (f, input) in &t.findings {
        eprintln!("FINDING {f:?}\n--- input ---\n{input}--- end ---");
    }
}
